/*
 * map.c - the correction maps of paper 4.2, 4.3 (eq. 7) and 5.3 (eq. 8) at bind: where the
 * correction may move the skin, from the weights and the rest distance to the bones, with the
 * rule that spreads each region's multiplier over the vertices it may move (see CORRECTION MAPS
 * in lvp.h for why it is the skinning weight).
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

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
		lvp_result result =
		    lvp__check_float_array(map->painted, binding->weld.caller_vertex_count, "map.painted", r_diag);
		if (result)
			return result;
		for (int32_t k = 0; k < binding->weld.caller_vertex_count; ++k)
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
		double d = lvp__bone_distance(binding, bone, p);
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

/* area_weight: the mean rest vertex area over each vertex's own (a third of its triangles'). The
 * correction is the smallest displacement, measured over the surface (sum_k A_k rho_k^2 / gamma_k),
 * that restores the volume: rho_k = gamma_k (g_k / A_k) sum_t phi_kt mu_t. g_k grows with the
 * vertex's area, so without 1 / A_k the displacement follows the tessellation (a large triangle's
 * corners pushed further than a small one's: a ridge wherever the mesh is irregular); g_k / A_k
 * is how much the vertex's area has changed, which is smooth. */
static void lvp__area_weights(lvp_binding *binding)
{
	int32_t n = binding->vertex_count;
	float *area = binding->map.area_weight;
	memset(area, 0, sizeof(float) * (size_t)n);
	double total = 0.0;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		const int32_t *v = binding->mesh.triangles + 3 * t;
		lvp__vec3 a = lvp__load(binding->rest_positions + 3 * v[0]), b = lvp__load(binding->rest_positions + 3 * v[1]),
		          c = lvp__load(binding->rest_positions + 3 * v[2]);
		double third = lvp__length(lvp__cross(lvp__sub(b, a), lvp__sub(c, a))) / 6.0;
		for (int i = 0; i < 3; ++i)
			area[v[i]] += (float)third;
		total += 3.0 * third;
	}
	double mean = n > 0 ? total / n : 0.0;
	for (int32_t k = 0; k < n; ++k)
		area[k] = area[k] > 0.0f ? (float)(mean / area[k]) : 0.0f;
}

/* The pits of a computed map filled: a vertex whose map is zero although its row blends bones (the organic map's
 * d = 0: a bone's line passes through it) while more than half of the corners around it (its neighbours, counted
 * once per triangle) are not takes the mean over those corners, the zeros among them counted. On a low-poly game
 * animal a bone's line can pass through one vertex of skin that blends: left at zero it never moves while its
 * ring does, a pit that the offsets' smoothing deepens as it evens the skin around it (the low-poly horse of the
 * tests asleep, Keep Skin Apart on: roughness 0.50 of the largest offset, at the one vertex of 309 that a bone's
 * line passes through). A vertex whose row is one bone's stays still, as lvp.h promises of skin one bone carries:
 * filled too, the mocap bodies' volume before correction read 1e-6 off the positions' (test_mocap_characters).
 * The rubber map is zero only where a row is one bone's, a painted map is the artist's, and the boundary fade
 * is zero by design: only the organic map is filled. All pits are found before any is filled, so the result
 * does not depend on the vertices' order. */
static lvp_result lvp__fill_map_pits(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count;
	const lvp__mesh *mesh = &binding->mesh;
	float *gamma = binding->map.gamma;
	bool ok = true;
	float *filled = lvp__calloc((size_t)n + 1, sizeof(float), &ok);
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	for (int32_t k = 0; k < n; ++k) {
		if (gamma[k] > 0.0f || (binding->mode == LVP_MODE_LOCAL && mesh->vertex_region[k] < 0) ||
		    !(binding->reach.largest[k] < 1.0f))
			continue; /* moves already, unweighted (never moves), or carried by one bone alone */
		int32_t corners = 0, moving = 0;
		double sum = 0.0;
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
			const int32_t *triangle = mesh->triangles + 3 * (int64_t)mesh->vertex_triangles[c];
			for (int i = 0; i < 3; ++i)
				if (triangle[i] != k) {
					++corners;
					moving += gamma[triangle[i]] > 0.0f;
					sum += gamma[triangle[i]];
				}
		}
		if (2 * moving > corners)
			filled[k] = (float)(sum / corners);
	}
	for (int32_t k = 0; k < n; ++k)
		if (filled[k] > 0.0f)
			gamma[k] = filled[k];
	free(filled);
	return lvp_success;
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
		double log_gamma = lvp__log_map(map, binding->reach.largest[k], distance, lvp__point_vertex(binding, k));
		/* Unweighted vertices belong to no region in local mode: they never move. */
		if (local && region < 0)
			log_gamma = -INFINITY;
		binding->map.log_gamma[k] = log_gamma;
		largest = log_gamma > largest ? log_gamma : largest;
	}
	for (int32_t k = 0; k < n; ++k)
		binding->map.gamma[k] = isfinite(largest) ? (float)exp(binding->map.log_gamma[k] - largest) : 0.0f;
	if (map->map == LVP_MAP_ORGANIC) { /* the only computed map that is zero where a row blends bones */
		result = lvp__fill_map_pits(binding, r_diag);
		if (result)
			return result;
	}
	lvp__area_weights(binding);

	/* Which regions' multipliers reach a vertex, and with which phi (correction.c,
	 * lvp__vertex_support): its bones, by weight, or only its region under the boundary fade. */
	binding->map.soft_support = local && map->map != LVP_MAP_BOUNDARY_FADE;
	return lvp_success;
}

bool lvp__map_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count;
	bool ok = true;
	binding->map.area_weight = lvp__calloc(n, sizeof(float), &ok);
	binding->map.gamma = lvp__calloc(n, sizeof(float), &ok);
	binding->map.distance = lvp__calloc(n, sizeof(float), &ok);
	binding->map.log_gamma = lvp__calloc(n, sizeof(double), &ok);
	return ok;
}

void lvp__map_free(lvp__map *map)
{
	free(map->gamma);
	free(map->distance);
	free(map->log_gamma);
	free(map->area_weight);
	free(map->region_bone_offsets);
	free(map->region_bones);
}
