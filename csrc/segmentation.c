/*
 * segmentation.c - paper 5.2 (regions by largest weight) and the correction maps of 4.2, 4.3
 * (eq. 7) and 5.3 (eq. 8), with the rule that spreads each region's multiplier over the
 * vertices it may move (see CORRECTION MAPS in lvp.h for why it is the skinning weight).
 */
#include "binding.h"

#include <stdlib.h>

/* Largest normalized weight of vertex k and its bone (ties: lower bone index); -1 if none. */
static int32_t lvp__main_bone(const lvp_binding *binding, int32_t k, float *r_max)
{
	int32_t best = -1;
	float best_weight = 0.0f;
	for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
		float w = binding->rig.weight_values[e];
		int32_t bone = binding->rig.weight_bones[e];
		if (w > best_weight || (w == best_weight && w > 0.0f && bone < best)) {
			best = bone;
			best_weight = w;
		}
	}
	*r_max = best_weight;
	return best;
}

/* The region of a triangle: the bone with the largest sum of weights over its three corners
 * (ties: lower bone index); -1 when no corner has weight. A bone appears at most once per corner
 * in sane data; duplicates simply add, as Blender adds duplicate groups. The sums are gathered
 * in r_sums (bone_count, zero before and after), so a vertex with many weights costs their count,
 * not its square. */
static int32_t lvp__triangle_bone(const lvp_binding *binding, const int32_t *corners, double *r_sums)
{
	for (int c = 0; c < 3; ++c)
		for (int32_t e = binding->rig.weight_offsets[corners[c]]; e < binding->rig.weight_offsets[corners[c] + 1]; ++e)
			r_sums[binding->rig.weight_bones[e]] += binding->rig.weight_values[e];
	int32_t best = -1;
	double best_sum = 0.0;
	for (int c = 0; c < 3; ++c) {
		for (int32_t e = binding->rig.weight_offsets[corners[c]]; e < binding->rig.weight_offsets[corners[c] + 1]; ++e) {
			int32_t bone = binding->rig.weight_bones[e];
			double sum = r_sums[bone];
			if (binding->rig.weight_values[e] > 0.0f && (sum > best_sum || (sum == best_sum && bone < best))) {
				best = bone;
				best_sum = sum;
			}
		}
	}
	for (int c = 0; c < 3; ++c)
		for (int32_t e = binding->rig.weight_offsets[corners[c]]; e < binding->rig.weight_offsets[corners[c] + 1]; ++e)
			r_sums[binding->rig.weight_bones[e]] = 0.0;
	return best;
}

/* Regions of vertices and triangles, triangles sorted by region (counting sort, stable). */
static lvp_result lvp__assign_regions(lvp_binding *binding, const int32_t *triangles_in, lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count, f = binding->triangle_count, s = binding->region_count;
	bool local = binding->mode == LVP_MODE_LOCAL;
	int32_t weighted = 0;
	for (int32_t k = 0; k < n; ++k) {
		float max_weight = 0.0f;
		int32_t bone = binding->rig.weight_offsets ? lvp__main_bone(binding, k, &max_weight) : -1;
		binding->mesh.max_weight[k] = max_weight;
		binding->mesh.vertex_region[k] = local ? bone : 0;
		weighted += bone >= 0;
	}
	if (local && weighted == 0)
		return lvp__fail(r_diag, lvp_error_no_weights, "weights", -1,
		                 "no vertex has a skinning weight above zero; weight the mesh to its bones (or compute "
		                 "automatic weights) before binding.");

	int32_t *region_of = malloc(sizeof(int32_t) * (size_t)f);
	int32_t *count = calloc((size_t)s + 2, sizeof(int32_t));
	double *sums = calloc((size_t)binding->bone_count + 1, sizeof(double));
	if (!region_of || !count || !sums) {
		free(region_of);
		free(count);
		free(sums);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while segmenting.");
	}
	for (int32_t t = 0; t < f; ++t) {
		region_of[t] = local ? lvp__triangle_bone(binding, triangles_in + 3 * t, sums) : 0;
		++count[(region_of[t] < 0 ? s : region_of[t]) + 1];
	}
	free(sums);
	for (int32_t r = 0; r <= s; ++r)
		count[r + 1] += count[r];
	for (int32_t r = 0; r <= s; ++r)
		binding->mesh.region_triangle_offsets[r] = count[r];
	for (int32_t t = 0; t < f; ++t) {
		int32_t r = region_of[t] < 0 ? s : region_of[t];
		int32_t at = count[r]++;
		memcpy(binding->mesh.triangles + 3 * at, triangles_in + 3 * t, sizeof(int32_t) * 3);
		binding->mesh.triangle_original[at] = t;
		binding->mesh.triangle_region[at] = region_of[t];
	}
	free(region_of);
	free(count);
	return lvp_success;
}

/* Slots: per vertex, the distinct regions of the triangles around it, so that the gradient of
 * each region's volume can be accumulated separately where regions meet. */
static lvp_result lvp__build_slots(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count, f = binding->triangle_count;
	int32_t *corner_offsets = calloc((size_t)n + 1, sizeof(int32_t));
	int32_t *corners = malloc(sizeof(int32_t) * (size_t)f * 3);
	if (!corner_offsets || !corners) {
		free(corner_offsets);
		free(corners);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	for (int32_t c = 0; c < 3 * f; ++c)
		++corner_offsets[binding->mesh.triangles[c] + 1];
	for (int32_t k = 0; k < n; ++k)
		corner_offsets[k + 1] += corner_offsets[k];
	for (int32_t c = 0; c < 3 * f; ++c)
		corners[corner_offsets[binding->mesh.triangles[c]]++] = c;
	for (int32_t k = n; k > 0; --k)
		corner_offsets[k] = corner_offsets[k - 1];
	corner_offsets[0] = 0;

	/* Two passes over each vertex's corners: count the distinct regions, then assign. */
	binding->mesh.slot_offsets[0] = 0;
	for (int32_t k = 0; k < n; ++k) {
		int32_t distinct = 0;
		for (int32_t i = corner_offsets[k]; i < corner_offsets[k + 1]; ++i) {
			int32_t region = binding->mesh.triangle_region[corners[i] / 3];
			bool seen = false;
			for (int32_t j = corner_offsets[k]; j < i && !seen; ++j)
				seen = binding->mesh.triangle_region[corners[j] / 3] == region;
			distinct += !seen;
		}
		binding->mesh.slot_offsets[k + 1] = binding->mesh.slot_offsets[k] + distinct;
	}
	binding->mesh.slot_count = binding->mesh.slot_offsets[n];
	size_t slots = (size_t)binding->mesh.slot_count;
	binding->mesh.slot_region = malloc(sizeof(int32_t) * (slots ? slots : 1));
	binding->measure.slot_gradient = calloc((slots ? slots : 1) * 3, sizeof(float));
	binding->measure.slot_g = calloc(slots ? slots : 1, sizeof(float));
	if (!binding->mesh.slot_region || !binding->measure.slot_gradient || !binding->measure.slot_g) {
		free(corner_offsets);
		free(corners);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	for (int32_t k = 0; k < n; ++k) {
		int32_t first = binding->mesh.slot_offsets[k], used = 0;
		for (int32_t i = corner_offsets[k]; i < corner_offsets[k + 1]; ++i) {
			int32_t region = binding->mesh.triangle_region[corners[i] / 3];
			int32_t slot = -1;
			for (int32_t j = 0; j < used && slot < 0; ++j)
				if (binding->mesh.slot_region[first + j] == region)
					slot = first + j;
			if (slot < 0) {
				slot = first + used++;
				binding->mesh.slot_region[slot] = region;
			}
			binding->mesh.corner_slot[corners[i]] = slot;
		}
	}
	/* Kept, as (triangle, slot) per corner around each vertex: the mesh pass gathers each
	 * vertex's gradient through them, the incremental pass finds the triangles of moved
	 * vertices. */
	binding->mesh.vertex_corner_offsets = corner_offsets;
	binding->mesh.vertex_corner_slot = malloc(sizeof(int32_t) * (size_t)(3 * f > 0 ? 3 * f : 1));
	if (!binding->mesh.vertex_corner_slot) {
		free(corners);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	for (int32_t i = 0; i < 3 * f; ++i) {
		binding->mesh.vertex_corner_slot[i] = binding->mesh.corner_slot[corners[i]];
		corners[i] /= 3;
	}
	binding->mesh.vertex_triangles = corners;
	return lvp_success;
}

/* Per region: its vertices, and its neighbouring bones (bones sharing influence with it, in
 * either direction), which are the candidates of fold-over detection (5.4). */
static lvp_result lvp__build_neighbours(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count, s = binding->region_count;
	int32_t *offsets = binding->mesh.region_vertex_offsets;
	memset(offsets, 0, sizeof(int32_t) * ((size_t)s + 1));
	for (int32_t k = 0; k < n; ++k)
		if (binding->mesh.vertex_region[k] >= 0)
			++offsets[binding->mesh.vertex_region[k] + 1];
	for (int32_t r = 0; r < s; ++r)
		offsets[r + 1] += offsets[r];
	int32_t *fill = malloc(sizeof(int32_t) * (size_t)s);
	binding->mesh.neighbour_offsets = calloc((size_t)s + 1, sizeof(int32_t));
	int32_t *marker = malloc(sizeof(int32_t) * (size_t)(s > 0 ? s : 1));
	int32_t *directed_offsets = calloc((size_t)s + 1, sizeof(int32_t));
	if (!fill || !binding->mesh.neighbour_offsets || !marker || !directed_offsets) {
		free(fill);
		free(marker);
		free(directed_offsets);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	memcpy(fill, offsets, sizeof(int32_t) * (size_t)s);
	for (int32_t k = 0; k < n; ++k)
		if (binding->mesh.vertex_region[k] >= 0)
			binding->mesh.region_vertices[fill[binding->mesh.vertex_region[k]]++] = k;
	free(fill);

	if (binding->mode != LVP_MODE_LOCAL) {
		free(marker);
		free(directed_offsets);
		binding->mesh.neighbour_bones = malloc(sizeof(int32_t));
		binding->fold.contact = calloc(1, 1);
		return binding->mesh.neighbour_bones && binding->fold.contact
		           ? lvp_success
		           : lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory.");
	}

	/* Directed lists D(r) = bones influencing some vertex of region r, found with a marker. */
	for (int32_t r = 0; r < s; ++r)
		marker[r] = -1;
	for (int pass = 0; pass < 2; ++pass) {
		int32_t *directed = pass ? malloc(sizeof(int32_t) * (size_t)(directed_offsets[s] ? directed_offsets[s] : 1))
		                         : NULL;
		if (pass && !directed) {
			free(marker);
			free(directed_offsets);
			return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
		}
		for (int32_t r = 0; r < s; ++r) {
			int32_t found = 0;
			for (int32_t i = offsets[r]; i < offsets[r + 1]; ++i) {
				int32_t k = binding->mesh.region_vertices[i];
				for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
					int32_t bone = binding->rig.weight_bones[e];
					if (bone == r || binding->rig.weight_values[e] <= 0.0f || marker[bone] == r + pass * s)
						continue;
					marker[bone] = r + pass * s;
					if (pass)
						directed[directed_offsets[r] + found] = bone;
					++found;
				}
			}
			if (!pass)
				directed_offsets[r + 1] = found;
		}
		if (!pass) {
			for (int32_t r = 0; r < s; ++r)
				directed_offsets[r + 1] += directed_offsets[r];
			for (int32_t r = 0; r < s; ++r)
				marker[r] = -1;
			continue;
		}
		/* Symmetric closure N(r) = D(r) + {t : r in D(t)}: at most twice the directed size. */
		int32_t total = directed_offsets[s];
		binding->mesh.neighbour_bones = malloc(sizeof(int32_t) * (size_t)(2 * total > 0 ? 2 * total : 1));
		int32_t *reverse_offsets = calloc((size_t)s + 1, sizeof(int32_t));
		int32_t *reverse = malloc(sizeof(int32_t) * (size_t)(total > 0 ? total : 1));
		if (!binding->mesh.neighbour_bones || !reverse_offsets || !reverse) {
			free(directed);
			free(reverse_offsets);
			free(reverse);
			free(marker);
			free(directed_offsets);
			return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
		}
		for (int32_t i = 0; i < total; ++i)
			++reverse_offsets[directed[i] + 1];
		for (int32_t r = 0; r < s; ++r)
			reverse_offsets[r + 1] += reverse_offsets[r];
		for (int32_t r = 0; r < s; ++r)
			for (int32_t i = directed_offsets[r]; i < directed_offsets[r + 1]; ++i)
				reverse[reverse_offsets[directed[i]]++] = r;
		for (int32_t r = s; r > 0; --r)
			reverse_offsets[r] = reverse_offsets[r - 1];
		reverse_offsets[0] = 0;
		for (int32_t r = 0; r < s; ++r)
			marker[r] = -1;
		int32_t written = 0;
		for (int32_t r = 0; r < s; ++r) {
			binding->mesh.neighbour_offsets[r] = written;
			for (int32_t i = directed_offsets[r]; i < directed_offsets[r + 1]; ++i)
				if (marker[directed[i]] != r) {
					marker[directed[i]] = r;
					binding->mesh.neighbour_bones[written++] = directed[i];
				}
			for (int32_t i = reverse_offsets[r]; i < reverse_offsets[r + 1]; ++i)
				if (marker[reverse[i]] != r) {
					marker[reverse[i]] = r;
					binding->mesh.neighbour_bones[written++] = reverse[i];
				}
		}
		binding->mesh.neighbour_offsets[s] = written;
		free(directed);
		free(reverse_offsets);
		free(reverse);
	}
	free(marker);
	free(directed_offsets);
	int32_t entries = binding->mesh.neighbour_offsets[s];
	binding->fold.contact = calloc((size_t)(entries > 0 ? entries : 1), 1);
	if (!binding->fold.contact)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	return lvp_success;
}

lvp_result lvp__segment(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	/* The caller's triangles were copied unsorted into binding->mesh.triangles; sort from a copy. */
	size_t bytes = sizeof(int32_t) * 3 * (size_t)binding->triangle_count;
	int32_t *input = malloc(bytes);
	if (!input)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while segmenting.");
	memcpy(input, binding->mesh.triangles, bytes);
	lvp_result result = lvp__assign_regions(binding, input, r_diag);
	free(input);
	if (result)
		return result;
	if ((result = lvp__build_slots(binding, r_diag)))
		return result;
	return lvp__build_neighbours(binding, r_diag);
}

/* ---- correction maps ----------------------------------------------------------------------- */

lvp_result lvp__check_map_options(const lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag)
{
	if ((unsigned)map->map > (unsigned)LVP_MAP_UNIFORM)
		return lvp__fail(r_diag, lvp_error_invalid_option, "map.map", -1,
		                 "map.map is %d; use ORGANIC, RUBBER, BOUNDARY_FADE, PAINTED or UNIFORM.", (int)map->map);
	if (!(map->alpha >= 0.0f && map->alpha <= 64.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "map.alpha", -1,
		                 "map.alpha is %g; it must be a number between 0 and 64.", (double)map->alpha);
	if (!(map->beta >= 0.0f && map->beta <= 64.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "map.beta", -1,
		                 "map.beta is %g; it must be a number between 0 and 64.", (double)map->beta);
	if (map->map == LVP_MAP_PAINTED) {
		lvp_result result = lvp__check_float_array(map->painted, binding->vertex_count, "map.painted", r_diag);
		if (result)
			return result;
		for (int32_t k = 0; k < binding->vertex_count; ++k)
			if (map->painted[k] < 0.0f)
				return lvp__fail(r_diag, lvp_error_negative_weight, "map.painted", k,
				                 "map.painted[%d] is %g; a painted correction map must be >= 0.", (int)k,
				                 (double)map->painted[k]);
	}
	if ((map->region_bone_offsets == NULL) != (map->region_bones == NULL))
		return lvp__fail(r_diag, lvp_error_null_argument,
		                 map->region_bones ? "map.region_bone_offsets" : "map.region_bones", -1,
		                 "map.region_bone_offsets and map.region_bones go together: pass both or neither.");
	if (map->region_bone_offsets) {
		const int32_t *offsets = map->region_bone_offsets;
		int32_t b = binding->caller_bone_count;
		if (offsets[0] != 0)
			return lvp__fail(r_diag, lvp_error_invalid_size, "map.region_bone_offsets", 0,
			                 "map.region_bone_offsets[0] is %d; compressed rows start at 0.", (int)offsets[0]);
		for (int32_t r = 0; r < b; ++r)
			if (offsets[r + 1] < offsets[r])
				return lvp__fail(r_diag, lvp_error_invalid_size, "map.region_bone_offsets", r + 1,
				                 "map.region_bone_offsets must not decrease (entry %d).", (int)(r + 1));
		for (int32_t i = 0; i < offsets[b]; ++i)
			if (map->region_bones[i] < 0 || map->region_bones[i] >= b)
				return lvp__fail(r_diag, lvp_error_index_out_of_range, "map.region_bones", i,
				                 "map.region_bones[%d] is %d, outside the %d bones.", (int)i, (int)map->region_bones[i],
				                 (int)b);
	}
	return lvp_success;
}

/* Rest distance from vertex k to the nearest bone segment it may depend on (Fig. 11). */
static double lvp__vertex_distance(const lvp_binding *binding, int32_t k, const int32_t *bones, int32_t bone_count)
{
	lvp__vec3 p = lvp__load(binding->rest_positions + 3 * k);
	double best = INFINITY;
	for (int32_t i = 0; i < bone_count; ++i) {
		int32_t bone = bones ? bones[i] : i;
		double d = lvp__segment_distance(p, binding->rig.heads[bone], binding->rig.tails[bone]);
		best = d < best ? d : best;
	}
	return isfinite(best) ? best : 0.0;
}

/* log(x^exponent), with 0^0 = 1 and x <= 0 giving -infinity (a zero map). */
static double lvp__log_power(double x, double exponent)
{
	return exponent == 0.0 ? 0.0 : (x > 0.0 ? exponent * log(x) : -INFINITY);
}

/* log gamma_k for vertex k with largest weight w and rest bone distance d (lvp.h, maps). */
static double lvp__log_map(const lvp_map_options *map, double w, double d, int32_t k)
{
	switch (map->map) {
	case LVP_MAP_ORGANIC:
		return lvp__log_power(1.0 - w, map->alpha) + lvp__log_power(d, map->beta);
	case LVP_MAP_RUBBER:
		return lvp__log_power(1.0 - w, map->alpha);
	case LVP_MAP_BOUNDARY_FADE:
		return lvp__log_power(2.0 * w - 1.0, map->alpha) + lvp__log_power(d, map->beta);
	case LVP_MAP_PAINTED:
		return map->painted[k] > 0.0f ? log((double)map->painted[k]) : -INFINITY;
	case LVP_MAP_UNIFORM:
		break;
	}
	return 0.0;
}

lvp_result lvp__build_map(lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag)
{
	lvp_result result = lvp__check_map_options(binding, map, r_diag);
	if (result)
		return result;
	/* The restriction and the distances are in the caller's bones: copies of them for separate
	 * parts (binding.h) have the same segments. */
	int32_t n = binding->vertex_count, b = binding->caller_bone_count;
	bool local = binding->mode == LVP_MODE_LOCAL;

	/* Keep a copy of the Fig. 11 restriction (the caller's arrays are not kept). */
	free(binding->map.region_bone_offsets);
	free(binding->map.region_bones);
	binding->map.region_bone_offsets = NULL;
	binding->map.region_bones = NULL;
	if (map->region_bone_offsets) {
		int32_t total = map->region_bone_offsets[b];
		binding->map.region_bone_offsets = malloc(sizeof(int32_t) * ((size_t)b + 1));
		binding->map.region_bones = malloc(sizeof(int32_t) * (size_t)(total > 0 ? total : 1));
		if (!binding->map.region_bone_offsets || !binding->map.region_bones)
			return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory.");
		memcpy(binding->map.region_bone_offsets, map->region_bone_offsets, sizeof(int32_t) * ((size_t)b + 1));
		memcpy(binding->map.region_bones, map->region_bones, sizeof(int32_t) * (size_t)total);
	}
	binding->map.options = *map;
	binding->map.options.painted = NULL;
	binding->map.options.region_bone_offsets = binding->map.region_bone_offsets;
	binding->map.options.region_bones = binding->map.region_bones;

	/* The map is built as a logarithm and normalized to a maximum of 1 before it is stored: only
	 * its shape matters (the multipliers absorb its scale), and d^beta of a far vertex would
	 * overflow a float (or a double) for large coordinates or exponents. */
	double largest = -INFINITY;
	for (int32_t k = 0; k < n; ++k) {
		int32_t region = lvp__caller_bone(binding, binding->mesh.vertex_region[k]);
		double distance = 0.0;
		if (b > 0) {
			const int32_t *bones = NULL;
			int32_t count = b;
			if (binding->map.region_bone_offsets && local && region >= 0 &&
			    binding->map.region_bone_offsets[region + 1] > binding->map.region_bone_offsets[region]) {
				bones = binding->map.region_bones + binding->map.region_bone_offsets[region];
				count = binding->map.region_bone_offsets[region + 1] - binding->map.region_bone_offsets[region];
			}
			distance = lvp__vertex_distance(binding, k, bones, count);
		}
		binding->map.distance[k] = (float)distance;
		double log_gamma = lvp__log_map(map, binding->mesh.max_weight[k], distance, k);
		/* Unweighted vertices belong to no region in local mode: they never move. */
		if (local && region < 0)
			log_gamma = -INFINITY;
		binding->map.log_gamma[k] = log_gamma;
		largest = log_gamma > largest ? log_gamma : largest;
	}
	for (int32_t k = 0; k < n; ++k)
		binding->map.gamma[k] = isfinite(largest) ? (float)exp(binding->map.log_gamma[k] - largest) : 0.0f;

	/* Which regions' multipliers reach a vertex, and with which phi (correction.c,
	 * lvp__vertex_support): its bones, by weight, or only its region under the boundary fade. */
	binding->map.soft_support = local && map->map != LVP_MAP_BOUNDARY_FADE;
	return lvp_success;
}
