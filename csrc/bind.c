/*
 * bind.c - lvp_bind(): validation of everything at the boundary, then each stage's memory and
 * bind-time constants in the order they depend on each other, so that lvp_correct() never
 * allocates. The stages (docs/architecture.md): rig.c (weights and bones), parts.c (separate
 * parts), segmentation.c (5.2 regions), map.c (the maps of 4.2-5.3), borders.c (region borders
 * and holes), dynamic_set.c and local_volume.c (5.2 prisms), frame_map.c (the map of each frame,
 * 5.3), correction.c (3.2-3.3), region_system.c (the coupled regions' system of a step),
 * stretch.c (bones scaled against each other) and foldover.c (5.4).
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
	free(binding->rest_positions);
	lvp__weld_free(&binding->weld);
	lvp__rig_free(&binding->rig);
	lvp__bone_lines_free(&binding->lines);
	lvp__mesh_free(&binding->mesh);
	lvp__reach_free(&binding->reach);
	lvp__map_free(&binding->map);
	lvp__frame_map_free(&binding->frame_map);
	lvp__borders_free(&binding->borders);
	lvp__dynamic_set_free(&binding->dynamic);
	lvp__measure_free(&binding->measure);
	lvp__region_system_free(&binding->system);
	lvp__stretch_free(&binding->stretch);
	lvp__fold_free(&binding->fold);
	lvp__contact_free(&binding->contact);
	lvp__part_volumes_free(&binding->parts);
	lvp__smoothing_free(&binding->smoothing);
	lvp__smoothing_free(&binding->relaxation);
	lvp__step_free(&binding->step);
	free(binding);
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
	if (!(options->bulge_width >= 0.0f && options->bulge_width <= LVP_MAX_BULGE_WIDTH))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.bulge_width", -1,
		                 "options.bulge_width is %g; use 0 (the weights' band) to %g times the flesh's thickness.",
		                 (double)options->bulge_width, (double)LVP_MAX_BULGE_WIDTH);
	return lvp_success;
}

static lvp_result lvp__bind_out_of_memory(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	lvp_result result = lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
	                              "out of memory while binding %d vertices and %d triangles.",
	                              (int)binding->vertex_count, (int)binding->triangle_count);
	lvp_free(binding);
	return result;
}

static bool lvp__map_needs_skeleton(lvp_map map)
{
	return map == LVP_MAP_ORGANIC || map == LVP_MAP_RUBBER || map == LVP_MAP_BOUNDARY_FADE;
}



static lvp_result lvp__bind_points(lvp_binding **r_binding, lvp__weld *weld, const float *rest_positions,
                                   int32_t vertex_count, const int32_t *triangles, int32_t triangle_count,
                                   const lvp_weights *weights, const lvp_skeleton *skeleton,
                                   const lvp_bind_options *options, bool has_skeleton, lvp_diagnostic *r_diag);

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
	if (options->bone_groups && options->mode == LVP_MODE_LOCAL)
		for (int32_t i = 0; i < skeleton->bone_count; ++i)
			if (options->bone_groups[i] < 0 || options->bone_groups[i] >= skeleton->bone_count)
				return lvp__fail(r_diag, lvp_error_index_out_of_range, "options.bone_groups", i,
				                 "options.bone_groups[%d] is %d; a group is named by a value in [0, %d), the "
				                 "bone count (bones with the same value form one group).",
				                 (int)i, (int)options->bone_groups[i], (int)skeleton->bone_count);

	/* Vertices at the same rest position are one point (weld.c): from here on, bind works on the
	 * points, and so does every frame. */
	lvp__weld weld;
	lvp__welded_mesh welded;
	if ((result = lvp__find_points(&weld, &welded, rest_positions, vertex_count, triangles, triangle_count,
	                               has_skeleton ? weights : NULL, r_diag)))
		return result;
	if (weld.vertex_point) {
		rest_positions = welded.positions;
		vertex_count = welded.vertex_count;
		triangles = welded.triangles;
		if (has_skeleton)
			weights = &welded.weights;
	}
	result = lvp__bind_points(r_binding, &weld, rest_positions, vertex_count, triangles, triangle_count, weights,
	                          skeleton, options, has_skeleton, r_diag);
	lvp__welded_mesh_free(&welded);
	return result;
}

/* lvp_bind on the points (weld.c), its inputs checked; takes weld, also on failure. */
static lvp_result lvp__bind_points(lvp_binding **r_binding, lvp__weld *weld, const float *rest_positions,
                                   int32_t vertex_count, const int32_t *triangles, int32_t triangle_count,
                                   const lvp_weights *weights, const lvp_skeleton *skeleton,
                                   const lvp_bind_options *options, bool has_skeleton, lvp_diagnostic *r_diag)
{
	lvp_result result;
	/* Separate parts that bend get their own bones, so their own regions (parts.c). */
	lvp__parts parts;
	memset(&parts, 0, sizeof(parts));
	parts.part_count = 1;
	if (has_skeleton &&
	    (result = lvp__split_parts(&parts, weights, vertex_count, triangles, triangle_count, skeleton->bone_count,
	                               options->mode == LVP_MODE_LOCAL, r_diag))) {
		lvp__weld_free(weld);
		return result;
	}

	lvp_binding *binding = calloc(1, sizeof(lvp_binding));
	if (!binding) {
		lvp__parts_free(&parts);
		lvp__weld_free(weld);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory.");
	}
	binding->weld = *weld;
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

	bool ok = true;
	binding->rest_positions = lvp__calloc((size_t)vertex_count * 3, sizeof(float), &ok);
	ok = ok && lvp__rig_alloc(binding, has_skeleton ? weights : NULL) && lvp__mesh_alloc(binding) &&
	     lvp__map_alloc(binding) && lvp__frame_map_alloc(binding) && lvp__borders_alloc(binding) &&
	     lvp__dynamic_set_alloc(binding) && lvp__part_volumes_alloc(binding) && lvp__step_alloc(binding);
	if (!ok)
		return lvp__bind_out_of_memory(binding, r_diag);
	memcpy(binding->rest_positions, rest_positions, sizeof(float) * 3 * (size_t)vertex_count);
	memcpy(binding->mesh.triangles, triangles, sizeof(int32_t) * 3 * (size_t)triangle_count);
	if (has_skeleton) {
		lvp__rig_copy(binding, weights, skeleton);
		if (!lvp__build_bone_lines(binding, skeleton, options->bone_groups))
			return lvp__bind_out_of_memory(binding, r_diag);
	}

	if ((result = lvp__segment(binding, r_diag))) {
		lvp_free(binding);
		return result;
	}
	if (!lvp__measure_alloc(binding) || !lvp__fold_alloc(binding))
		return lvp__bind_out_of_memory(binding, r_diag);
	/* The workers also share the bind's diffusion (reach.c). */
	if (lvp__pool_create(&binding->pool, options->thread_count) != lvp_success) {
		lvp_free(binding);
		return lvp__fail(r_diag, lvp_error_thread, "options.thread_count", -1,
		                 "the %d worker threads could not be started; use fewer threads (or 1).",
		                 (int)options->thread_count - 1);
	}
	if ((result = lvp__build_reach(binding, options->bulge_width, r_diag)) ||
	    (result = lvp__build_borders(binding, r_diag)) ||
	    (result = lvp__build_region_corners(binding, r_diag)) ||
	    (result = lvp__build_region_system(
	         binding, options->mode == LVP_MODE_LOCAL ? options->bone_groups : NULL, r_diag)) ||
	    (result = lvp__build_stretch_pairs(binding, r_diag)) ||
	    (result = lvp__build_smoothing(binding, r_diag)) ||
	    (result = lvp__build_map(binding, &options->map, r_diag))) {
		lvp_free(binding);
		return result;
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
	lvp__frame_map_stale(binding); /* the flags depend on the map */
	return lvp__build_map(binding, map, r_diag);
}

int32_t lvp_vertex_count(const lvp_binding *binding)
{
	return binding ? binding->weld.caller_vertex_count : 0;
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
		for (int32_t k = 0; k < binding->weld.caller_vertex_count; ++k)
			r_vertex_regions[k] = lvp__caller_bone(binding, binding->mesh.vertex_region[lvp__vertex_point(binding, k)]);
	if (r_triangle_regions)
		for (int32_t t = 0; t < binding->triangle_count; ++t)
			r_triangle_regions[binding->mesh.triangle_original[t]] =
			    lvp__caller_bone(binding, binding->mesh.triangle_region[t]);
}

void lvp_get_correction_map(const lvp_binding *binding, float *r_map)
{
	if (!binding || !r_map)
		return;
	for (int32_t k = 0; k < binding->weld.caller_vertex_count; ++k)
		r_map[k] = binding->map.gamma[lvp__vertex_point(binding, k)];
}
