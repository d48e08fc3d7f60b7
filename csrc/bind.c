/*
 * bind.c - lvp_bind(): validation of everything at the boundary, copies of the rest data,
 * and the allocation of all per-frame memory, so that lvp_correct() never allocates.
 * The stages of the method are in segmentation.c (5.2 regions, maps of 4.2-5.3),
 * local_volume.c (5.2 prisms), frame_map.c (the map of each frame, 5.3), correction.c (3.2-3.3),
 * region_system.c (the coupled regions' system of a correction step), stretch.c (bones scaled
 * against each other) and foldover.c (5.4).
 */
#include "binding.h"

#include <stdlib.h>

lvp_bind_options lvp_bind_default_options(void)
{
	lvp_bind_options options;
	memset(&options, 0, sizeof(options));
	options.mode = LVP_MODE_LOCAL;
	options.map.map = LVP_MAP_ORGANIC;
	options.map.alpha = 1.0f;
	options.map.beta = 1.0f;
	options.map.deformation_weighted = 1;
	options.thread_count = 1;
	return options;
}

lvp_frame_options lvp_frame_default_options(void)
{
	lvp_frame_options options;
	memset(&options, 0, sizeof(options));
	options.max_iterations = 8;
	options.tolerance = 1e-4f;
	options.fold_over = 0;
	return options;
}

void lvp_free(lvp_binding *binding)
{
	if (!binding)
		return;
	lvp__pool_destroy(binding->pool);
	void *arrays[] = {
	    binding->rest_positions, binding->mesh.triangles, binding->mesh.triangle_original, binding->mesh.triangle_region,
	    binding->mesh.region_triangle_offsets, binding->rig.weight_offsets, binding->rig.weight_bones, binding->rig.weight_values,
	    binding->mesh.max_weight, binding->mesh.vertex_region, binding->rig.rest_matrices, binding->rig.rest_inverse, binding->rig.rest_det,
	    binding->rig.heads, binding->rig.tails, binding->rig.bone_length, binding->measure.rest_totals, binding->measure.reference_volume,
	    binding->mesh.slot_offsets, binding->mesh.slot_region, binding->mesh.vertex_corner_offsets, binding->mesh.vertex_triangles,
	    binding->mesh.vertex_corner_slot, binding->measure.origin_float, binding->frame_map.skin_class, binding->measure.triangle_gradient,
	    binding->measure.triangle_volume6, binding->measure.triangle_dirty, binding->measure.dirty_triangles, binding->measure.vertex_dirty,
	    binding->measure.dirty_vertices, binding->step.moved, binding->step.backup, binding->mesh.corner_slot, binding->borders.offsets,
	    binding->borders.edges, binding->borders.slots, binding->borders.gradient, binding->borders.rest,
	    binding->borders.cap_edges, binding->map.gamma, binding->frame_map.gamma, binding->map.log_gamma, binding->map.distance,
	    binding->map.region_bone_offsets,
	    binding->map.region_bones, binding->step.region_movable, binding->step.applied_mu, binding->mesh.neighbour_offsets,
	    binding->mesh.neighbour_bones, binding->fold.contact, binding->mesh.region_vertex_offsets, binding->mesh.region_vertices,
	    binding->step.positions,
	    binding->measure.normals, binding->measure.vertex_g, binding->measure.slot_gradient, binding->measure.slot_g, binding->fold.held, binding->measure.sums,
	    binding->measure.origin, binding->step.change, binding->step.target, binding->step.uniform_gain, binding->step.total_gain,
	    binding->measure.frame_totals, binding->rig.kappa, binding->frame_map.vertex_class, binding->frame_map.vertex_dynamic, binding->frame_map.chunk_changed,
	    binding->step.chunk_moved, binding->dynamic.triangles, binding->dynamic.region_offsets, binding->dynamic.vertices,
	    binding->dynamic.static_rest, binding->measure.piece_first, binding->measure.piece_region, binding->measure.piece_sums,
	    binding->dynamic.static_count, binding->rig.posed, binding->rig.posed_inverse, binding->rig.skin, binding->frame_map.skin_displacement,
	    binding->rig.posed_heads, binding->rig.posed_tails, binding->rig.region_skipped, binding->step.region_touched, binding->step.active,
	    binding->step.active_index, binding->system.coupling_offsets, binding->system.coupling, binding->system.solve_order,
	    binding->system.profile.first, binding->system.profile.lower, binding->system.profile.upper,
	    binding->system.normal_profile.first, binding->system.normal_profile.lower, binding->system.normal_profile.upper, binding->system.matrix,
	    binding->system.factor, binding->system.normal, binding->system.assembly, binding->system.rhs, binding->system.solution, binding->system.row_values,
	    binding->system.row_last, binding->system.still, binding->system.place, binding->step.mu,
	    binding->mesh.region_corner_offsets, binding->mesh.region_corners, binding->dynamic.region_state, binding->dynamic.triangle_static,
	    binding->rig.bone_source, binding->parts.region_part, binding->parts.vertex_part, binding->borders.cap_part_offsets,
	    binding->parts.bind_volume, binding->parts.rest_volume, binding->parts.scale, binding->parts.change,
	    binding->parts.uniform, binding->step.part_total, binding->step.part_gain, binding->stretch.offsets, binding->stretch.bones,
	    binding->stretch.centre, binding->stretch.linear, binding->stretch.bone_entry, binding->stretch.corner_offset,
	    binding->stretch.regions, binding->stretch.change, binding->stretch.bone_stretch, binding->stretch.bone_stretch_invertible,
	};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
	free(binding);
}

/* calloc with an overflow-checked count; the binding is freed by the caller on failure. */
static void *lvp__alloc(size_t count, size_t size, bool *ok)
{
	if (!*ok)
		return NULL;
	void *p = calloc(count ? count : 1, size);
	if (!p)
		*ok = false;
	return p;
}

static lvp_result lvp__check_bind_options(const lvp_bind_options *options, lvp_diagnostic *r_diag)
{
	if (options->mode != LVP_MODE_LOCAL && options->mode != LVP_MODE_GLOBAL)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.mode", -1,
		                 "options.mode is %d; use LVP_MODE_LOCAL or LVP_MODE_GLOBAL.", (int)options->mode);
	if (options->thread_count < 1 || options->thread_count > LVP_MAX_THREADS)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.thread_count", -1,
		                 "options.thread_count is %d; it must be between 1 and %d.", (int)options->thread_count,
		                 LVP_MAX_THREADS);
	return lvp_success;
}

static bool lvp__map_needs_skeleton(lvp_map map)
{
	return map == LVP_MAP_ORGANIC || map == LVP_MAP_RUBBER || map == LVP_MAP_BOUNDARY_FADE;
}

/* Copies the weights, normalized by their sum (as Blender's Armature modifier normalizes); the
 * bones are already in weight_bones (lvp__split_parts). */
static void lvp__copy_weights(lvp_binding *binding, const lvp_weights *weights)
{
	int32_t n = binding->vertex_count;
	memcpy(binding->rig.weight_offsets, weights->offsets, sizeof(int32_t) * (size_t)(n + 1));
	for (int32_t k = 0; k < n; ++k) {
		int32_t begin = weights->offsets[k], end = weights->offsets[k + 1];
		double sum = 0.0;
		for (int32_t e = begin; e < end; ++e)
			sum += weights->values[e];
		for (int32_t e = begin; e < end; ++e)
			binding->rig.weight_values[e] = sum > 0.0 ? (float)(weights->values[e] / sum) : 0.0f;
	}
}

/* The internal bones: each a copy of its caller's bone (binding.h). */
static void lvp__copy_skeleton(lvp_binding *binding, const lvp_skeleton *skeleton)
{
	binding->rig.reach = 0.0;
	for (int32_t i = 0; i < binding->bone_count; ++i) {
		int32_t source = lvp__caller_bone(binding, i);
		binding->rig.rest_matrices[i] = lvp__mat4_load(skeleton->rest_matrices + 16 * source);
		lvp__mat4_invert_affine(&binding->rig.rest_inverse[i], &binding->rig.rest_matrices[i]); /* checked before */
		binding->rig.rest_det[i] = lvp__mat4_det3(&binding->rig.rest_matrices[i]);
		binding->rig.heads[i] = lvp__load(skeleton->heads + 3 * source);
		binding->rig.tails[i] = lvp__load(skeleton->tails + 3 * source);
		binding->rig.bone_length[i] = lvp__length(lvp__sub(binding->rig.tails[i], binding->rig.heads[i]));
		binding->rig.reach =
		    fmax(binding->rig.reach, fmax(lvp__length(binding->rig.heads[i]), lvp__length(binding->rig.tails[i])));
	}
}

lvp_result lvp_bind(lvp_binding **r_binding, const float *rest_positions, int32_t vertex_count,
                    const int32_t *triangles, int32_t triangle_count, const lvp_weights *weights,
                    const lvp_skeleton *skeleton, const lvp_bind_options *options, lvp_diagnostic *r_diag)
{
	if (!r_binding)
		return lvp__fail(r_diag, lvp_error_null_argument, "r_binding", -1,
		                 "r_binding is NULL; pass the address of an lvp_binding pointer.");
	*r_binding = NULL;
	lvp_bind_options defaults = lvp_bind_default_options();
	if (!options)
		options = &defaults;
	lvp_result result = lvp__check_bind_options(options, r_diag);
	if (result)
		return result;
	if ((result = lvp__check_mesh(rest_positions, vertex_count, triangles, triangle_count, "rest_positions", r_diag)))
		return result;

	bool has_skeleton = options->mode == LVP_MODE_LOCAL || lvp__map_needs_skeleton(options->map.map) ||
	                    (skeleton && skeleton->bone_count > 0);
	if (options->mode == LVP_MODE_LOCAL && (!skeleton || !weights))
		return lvp__fail(r_diag, lvp_error_null_argument, skeleton ? "weights" : "skeleton", -1,
		                 "local volume preservation needs the skinning weights and the skeleton; pass both, or "
		                 "use LVP_MODE_GLOBAL with a UNIFORM or PAINTED map for a prop without bones.");
	if (has_skeleton) {
		if (!skeleton || !weights)
			return lvp__fail(r_diag, lvp_error_null_argument, skeleton ? "weights" : "skeleton", -1,
			                 "this correction map is built from the skinning weights and bones; pass both, or use "
			                 "a UNIFORM or PAINTED map.");
		if ((result = lvp__check_skeleton(skeleton, r_diag)))
			return result;
		if ((result = lvp__check_weights(weights, vertex_count, skeleton->bone_count, r_diag)))
			return result;
	}

	/* Separate parts that bend get their own bones, so their own regions (parts.c). */
	lvp__parts parts;
	memset(&parts, 0, sizeof(parts));
	parts.part_count = 1;
	if (has_skeleton &&
	    (result = lvp__split_parts(&parts, weights, vertex_count, triangles, triangle_count, skeleton->bone_count,
	                               options->mode == LVP_MODE_LOCAL, r_diag)))
		return result;

	bool ok = true;
	lvp_binding *binding = lvp__alloc(1, sizeof(lvp_binding), &ok);
	if (!binding) {
		lvp__parts_free(&parts);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory.");
	}
	binding->mode = options->mode;
	binding->vertex_count = vertex_count;
	binding->triangle_count = triangle_count;
	binding->rig.weight_bones = parts.weight_bones;
	binding->rig.bone_source = parts.bone_source;
	binding->parts.region_part = parts.bone_part; /* regions are internal bones in local mode */
	binding->parts.vertex_part = parts.vertex_part;
	binding->parts.count = parts.part_count;
	binding->caller_bone_count = has_skeleton ? skeleton->bone_count : 0;
	binding->bone_count = has_skeleton ? parts.bone_count : 0;
	binding->region_count = options->mode == LVP_MODE_LOCAL ? binding->bone_count : 1;

	size_t n = (size_t)vertex_count, f = (size_t)triangle_count, b = (size_t)binding->bone_count;
	size_t s = (size_t)binding->region_count;
	size_t e = has_skeleton ? (size_t)weights->offsets[vertex_count] : 0;

	binding->rest_positions = lvp__alloc(n * 3, sizeof(float), &ok);
	binding->mesh.triangles = lvp__alloc(f * 3, sizeof(int32_t), &ok);
	binding->mesh.triangle_original = lvp__alloc(f, sizeof(int32_t), &ok);
	binding->mesh.triangle_region = lvp__alloc(f, sizeof(int32_t), &ok);
	binding->mesh.region_triangle_offsets = lvp__alloc(s + 1, sizeof(int32_t), &ok);
	binding->mesh.max_weight = lvp__alloc(n, sizeof(float), &ok);
	binding->mesh.vertex_region = lvp__alloc(n, sizeof(int32_t), &ok);
	if (has_skeleton) {
		binding->rig.weight_offsets = lvp__alloc(n + 1, sizeof(int32_t), &ok);
		binding->rig.weight_values = lvp__alloc(e, sizeof(float), &ok);
		binding->rig.rest_matrices = lvp__alloc(b, sizeof(lvp__mat4), &ok);
		binding->rig.rest_inverse = lvp__alloc(b, sizeof(lvp__mat4), &ok);
		binding->rig.rest_det = lvp__alloc(b, sizeof(double), &ok);
		binding->rig.heads = lvp__alloc(b, sizeof(lvp__vec3), &ok);
		binding->rig.tails = lvp__alloc(b, sizeof(lvp__vec3), &ok);
		binding->rig.bone_length = lvp__alloc(b, sizeof(double), &ok);
		binding->rig.posed = lvp__alloc(b, sizeof(lvp__mat4), &ok);
		binding->rig.posed_inverse = lvp__alloc(b, sizeof(lvp__mat4), &ok);
		binding->rig.skin = lvp__alloc(b, sizeof(lvp__mat4), &ok);
		binding->frame_map.skin_displacement = lvp__alloc(b * 12, sizeof(float), &ok);
		binding->rig.posed_heads = lvp__alloc(b, sizeof(lvp__vec3), &ok);
		binding->rig.posed_tails = lvp__alloc(b, sizeof(lvp__vec3), &ok);
	}
	binding->measure.rest_totals = lvp__alloc(s, sizeof(lvp__region_sums), &ok);
	binding->measure.reference_volume = lvp__alloc(s, sizeof(double), &ok);
	binding->mesh.slot_offsets = lvp__alloc(n + 1, sizeof(int32_t), &ok);
	binding->mesh.corner_slot = lvp__alloc(f * 3, sizeof(int32_t), &ok);
	binding->map.gamma = lvp__alloc(n, sizeof(float), &ok);
	binding->frame_map.gamma = lvp__alloc(n, sizeof(float), &ok);
	binding->map.distance = lvp__alloc(n, sizeof(float), &ok);
	binding->map.log_gamma = lvp__alloc(n, sizeof(double), &ok);
	binding->step.region_movable = lvp__alloc(s, sizeof(uint8_t), &ok);
	binding->step.applied_mu = lvp__alloc(s, sizeof(double), &ok);
	binding->mesh.region_vertex_offsets = lvp__alloc(s + 1, sizeof(int32_t), &ok);
	binding->mesh.region_vertices = lvp__alloc(n, sizeof(int32_t), &ok);
	binding->step.positions = lvp__alloc(n * 3, sizeof(float), &ok);
	binding->measure.normals = lvp__alloc(n * 3, sizeof(float), &ok);
	binding->measure.vertex_g = lvp__alloc(n, sizeof(float), &ok);
	binding->measure.triangle_gradient = lvp__alloc(f * 3, sizeof(float), &ok);
	binding->measure.triangle_volume6 = lvp__alloc(f, sizeof(float), &ok);
	binding->measure.triangle_dirty = lvp__alloc(f, sizeof(uint8_t), &ok);
	binding->measure.dirty_triangles = lvp__alloc(f, sizeof(int32_t), &ok);
	binding->measure.vertex_dirty = lvp__alloc(n, sizeof(uint8_t), &ok);
	binding->measure.dirty_vertices = lvp__alloc(n, sizeof(int32_t), &ok);
	binding->step.moved = lvp__alloc(n, sizeof(int32_t), &ok);
	binding->step.backup = lvp__alloc(n * 3, sizeof(float), &ok);
	binding->fold.held = lvp__alloc(n, sizeof(uint8_t), &ok);
	binding->measure.sums = lvp__alloc(s + 1, sizeof(lvp__region_sums), &ok);
	binding->measure.origin = lvp__alloc(s, sizeof(lvp__vec3), &ok);
	binding->measure.origin_float = lvp__alloc((s + 1) * 3, sizeof(float), &ok);
	binding->frame_map.skin_class = lvp__alloc(b, sizeof(int32_t), &ok);
	binding->step.change = lvp__alloc(s, sizeof(double), &ok);
	binding->step.target = lvp__alloc(s, sizeof(double), &ok);
	binding->step.uniform_gain = lvp__alloc(s, sizeof(double), &ok);
	binding->step.total_gain = lvp__alloc(s, sizeof(double), &ok);
	binding->rig.kappa = lvp__alloc(s, sizeof(double), &ok);
	binding->measure.frame_totals = lvp__alloc(s, sizeof(lvp__region_sums), &ok);
	binding->frame_map.vertex_class = lvp__alloc(n, sizeof(int32_t), &ok);
	binding->frame_map.vertex_dynamic = lvp__alloc(n, sizeof(uint8_t), &ok);
	binding->frame_map.chunk_changed = lvp__alloc(n / LVP__GRAIN + 1, sizeof(uint8_t), &ok);
	binding->step.chunk_moved = lvp__alloc(n / LVP__GRAIN + 1, sizeof(int32_t), &ok);
	binding->dynamic.triangles = lvp__alloc(f, sizeof(int32_t), &ok);
	binding->dynamic.region_offsets = lvp__alloc(s + 2, sizeof(int32_t), &ok);
	binding->dynamic.region_state = lvp__alloc(s + 1, sizeof(uint8_t), &ok);
	binding->dynamic.triangle_static = lvp__alloc(f, sizeof(uint8_t), &ok);
	binding->dynamic.vertices = lvp__alloc(n, sizeof(int32_t), &ok);
	binding->dynamic.static_rest = lvp__alloc(s, sizeof(lvp__region_sums), &ok);
	size_t pieces = f / LVP__GRAIN + s + 2;
	binding->measure.piece_first = lvp__alloc(pieces + 1, sizeof(int32_t), &ok);
	binding->measure.piece_region = lvp__alloc(pieces, sizeof(int32_t), &ok);
	binding->measure.piece_sums = lvp__alloc(pieces, sizeof(lvp__region_sums), &ok);
	binding->dynamic.static_count = lvp__alloc(s, sizeof(int32_t), &ok);
	binding->rig.region_skipped = lvp__alloc(s, sizeof(uint8_t), &ok);
	binding->step.region_touched = lvp__alloc(s, sizeof(uint8_t), &ok);
	binding->step.active = lvp__alloc(s, sizeof(int32_t), &ok);
	binding->step.active_index = lvp__alloc(s, sizeof(int32_t), &ok);
	binding->step.mu = lvp__alloc(s, sizeof(double), &ok);
	size_t parts_count = (size_t)binding->parts.count;
	binding->borders.cap_part_offsets = lvp__alloc(parts_count + 1, sizeof(int32_t), &ok);
	binding->parts.bind_volume = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->parts.rest_volume = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->parts.scale = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->parts.change = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->parts.uniform = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->step.part_total = lvp__alloc(parts_count, sizeof(double), &ok);
	binding->step.part_gain = lvp__alloc(parts_count, sizeof(double), &ok);
	if (!ok) {
		lvp_free(binding);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "out of memory while binding %d vertices and %d triangles.", (int)vertex_count,
		                 (int)triangle_count);
	}
	memcpy(binding->rest_positions, rest_positions, sizeof(float) * n * 3);
	memcpy(binding->mesh.triangles, triangles, sizeof(int32_t) * f * 3);
	if (has_skeleton) {
		lvp__copy_weights(binding, weights);
		lvp__copy_skeleton(binding, skeleton);
	}

	if ((result = lvp__segment(binding, r_diag)) || (result = lvp__build_borders(binding, r_diag)) ||
	    (result = lvp__build_region_corners(binding, r_diag)) || (result = lvp__build_region_system(binding, r_diag)) ||
	    (result = lvp__build_stretch_pairs(binding, r_diag)) ||
	    (result = lvp__build_map(binding, &options->map, r_diag))) {
		lvp_free(binding);
		return result;
	}
	if (lvp__pool_create(&binding->pool, options->thread_count) != lvp_success) {
		lvp_free(binding);
		return lvp__fail(r_diag, lvp_error_thread, "options.thread_count", -1,
		                 "the %d worker threads could not be started; use fewer threads (or 1).",
		                 (int)options->thread_count - 1);
	}
	lvp__reference_volumes(binding);
	binding->rest_volume = lvp__volume_of(binding, binding->rest_positions);
	lvp__volumes_of_parts(binding, binding->rest_positions, binding->parts.bind_volume);
	lvp__vec3 lo = lvp__load(rest_positions), hi = lo;
	for (int32_t k = 1; k < vertex_count; ++k) {
		lvp__vec3 p = lvp__load(rest_positions + 3 * k);
		lo = lvp__v(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
		hi = lvp__v(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
	}
	binding->size = lvp__length(lvp__sub(hi, lo));
	lvp__rest_constants(binding, NULL, binding->measure.rest_totals);
	lvp__frame_rest(binding, NULL);
	*r_binding = binding;
	return lvp_success;
}

lvp_result lvp_set_map(lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag)
{
	if (!binding)
		return lvp__fail(r_diag, lvp_error_null_argument, "binding", -1, "binding is NULL.");
	if (!map)
		return lvp__fail(r_diag, lvp_error_null_argument, "map", -1, "map is NULL.");
	if (binding->bone_count == 0 && lvp__map_needs_skeleton(map->map))
		return lvp__fail(r_diag, lvp_error_invalid_option, "map.map", -1,
		                 "this binding has no skeleton; only UNIFORM and PAINTED maps are possible.");
	binding->frame_map.current = false; /* the flags depend on the map */
	return lvp__build_map(binding, map, r_diag);
}

int32_t lvp_vertex_count(const lvp_binding *binding)
{
	return binding ? binding->vertex_count : 0;
}
int32_t lvp_triangle_count(const lvp_binding *binding)
{
	return binding ? binding->triangle_count : 0;
}
int32_t lvp_bone_count(const lvp_binding *binding)
{
	return binding ? binding->caller_bone_count : 0;
}
int32_t lvp_region_count(const lvp_binding *binding)
{
	if (!binding)
		return 0;
	return binding->mode == LVP_MODE_LOCAL ? binding->caller_bone_count : binding->region_count;
}

int32_t lvp_flipped_edge_count(const lvp_binding *binding)
{
	return binding ? binding->borders.flipped_edge_count : 0;
}

void lvp_get_segmentation(const lvp_binding *binding, int32_t *r_vertex_regions, int32_t *r_triangle_regions)
{
	if (!binding)
		return;
	/* Regions are internal bones in local mode: answered as the caller's bones (binding.h). */
	if (r_vertex_regions)
		for (int32_t k = 0; k < binding->vertex_count; ++k)
			r_vertex_regions[k] = lvp__caller_bone(binding, binding->mesh.vertex_region[k]);
	if (r_triangle_regions)
		for (int32_t t = 0; t < binding->triangle_count; ++t)
			r_triangle_regions[binding->mesh.triangle_original[t]] = lvp__caller_bone(binding, binding->mesh.triangle_region[t]);
}

void lvp_get_correction_map(const lvp_binding *binding, float *r_map)
{
	if (!binding || !r_map)
		return;
	memcpy(r_map, binding->map.gamma, sizeof(float) * (size_t)binding->vertex_count);
}
