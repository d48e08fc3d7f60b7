/*
 * reach.c - how far each region's correction reaches (lvp.h, BULGE WIDTH): phi_ks of the
 * correction. Without a bulge width it is the skinning weight (phi_ks = omega_ks), and a region's
 * bulge is as wide as the band where its weights blend; an automatic-weights band a few edges wide
 * then gives a ridge. With one, the weight rows are diffused over the surface, at each vertex
 * over about bulge_width times the flesh's thickness there (its rest distance to its bones), so
 * the correction spreads over the flesh around the joint, a finger's as a thigh's, whatever the
 * band. Weight flows along edges only (diffusion.c): it never jumps to a separate piece or across
 * a gap, and each part keeps its own regions.
 */
#include "binding.h"
#include "diffusion.h"

#include <stdlib.h>
#include <string.h>

/* Most diffusion steps at bind: the steps grow with (thickness / edge length)^2, so a dense mesh
 * of thick flesh is widened less than asked rather than bound slowly (lvp.h, PERFORMANCE). */
#define LVP__REACH_MOST_STEPS 32
/* Fewest steps of any vertex's blend: the fewest after which a weight that one vertex alone
 * carried, diffused, stands out of its neighbours' mean by at most a quarter of its height, the
 * roughness QUALITY.md allows (on a regular mesh of six neighbours a vertex: 1 step leaves 0.50,
 * 2 leave 0.43, 3 leave 0.23; tests/bench/diffused_spike.py). Where the flesh is no more than an
 * edge or two thick (a low-poly character) or the edges along a limb are several times its edges
 * around it (quads modelled long), its own width would blend a vertex's row with its ring only
 * partly: rows keep their strongest bones, and a bone bending nearby then reaches some vertices
 * and not their neighbours, the bulge rising and falling from one vertex to the next, narrower
 * than the mesh can show smoothly. */
#define LVP__REACH_LEAST_STEPS 3.0
/* Entries below this fraction of their row's largest are dropped: they would cost each frame
 * and move nothing. */
#define LVP__REACH_FLOOR 1e-2f

void lvp__reach_free(lvp__reach *reach)
{
	if (reach->own) {
		free(reach->offsets);
		free(reach->regions);
		free(reach->phi);
		free(reach->largest);
	}
	memset(reach, 0, sizeof(*reach));
}

/* The reach is the weights (no bulge width, the global mode, or no weights). */
static void lvp__reach_is_weights(lvp_binding *binding)
{
	lvp__reach_free(&binding->reach);
	binding->reach.offsets = binding->rig.weight_offsets;
	binding->reach.regions = binding->rig.weight_bones;
	binding->reach.phi = binding->rig.weight_values;
	binding->reach.largest = binding->mesh.max_weight;
}

/* Vertex k's row of weights, strongest first, kept to the diffusion's stride. */
static void lvp__load_row(lvp__diffusion *diffusion, const lvp_binding *binding, int32_t k)
{
	int32_t stride = diffusion->stride, length = 0;
	int32_t *bones = diffusion->bones + (int64_t)k * stride;
	float *values = diffusion->values + (int64_t)k * stride;
	for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
		float w = binding->rig.weight_values[e];
		int32_t bone = binding->rig.weight_bones[e];
		if (!(w > 0.0f) || (length == stride && !(w > values[length - 1])))
			continue;
		int32_t at = length < stride ? length++ : length - 1;
		while (at > 0 && values[at - 1] < w) {
			bones[at] = bones[at - 1];
			values[at] = values[at - 1];
			--at;
		}
		bones[at] = bone;
		values[at] = w;
	}
	diffusion->counts[k] = length;
}

/* Per vertex, how fast its row diffuses (1 for the vertex that needs the most steps), filled into
 * r_rates; returns the steps. A vertex needs lvp__blend_steps(width * thickness, edge), its edge
 * the mean length of its own edges, and at least LVP__REACH_LEAST_STEPS. */
static int32_t lvp__reach_rates(float *r_rates, const lvp_binding *binding, const lvp__diffusion *diffusion,
                                double width)
{
	int32_t n = binding->vertex_count;
	double most = 0.0;
	for (int32_t k = 0; k < n; ++k) {
		r_rates[k] = 0.0f;
		if (binding->mesh.vertex_region[k] < 0)
			continue; /* never moves, and gives nothing to its neighbours */
		lvp__vec3 p = lvp__load(binding->rest_positions + 3 * k);
		double thickness = INFINITY, edges = 0.0;
		for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
			int32_t bone = binding->rig.weight_bones[e];
			thickness = fmin(thickness, lvp__bone_distance(binding, bone, p));
		}
		int32_t begin = diffusion->neighbour_offsets[k], end = diffusion->neighbour_offsets[k + 1];
		for (int32_t e = begin; e < end; ++e)
			edges += lvp__length(lvp__sub(lvp__load(binding->rest_positions + 3 * diffusion->neighbours[e]), p));
		if (end == begin || !(edges > 0.0) || !isfinite(thickness))
			continue;
		double steps =
		    fmax(lvp__blend_steps(width * thickness, edges / (double)(end - begin)), LVP__REACH_LEAST_STEPS);
		r_rates[k] = (float)steps;
		most = fmax(most, steps);
	}
	int32_t steps = most < LVP__REACH_MOST_STEPS ? (int32_t)ceil(most) : LVP__REACH_MOST_STEPS;
	for (int32_t k = 0; k < n && steps > 0; ++k)
		r_rates[k] = fminf(1.0f, r_rates[k] / (float)steps);
	return steps;
}

/* Copies the diffused rows into the reach, each without its negligible entries and renormalized. */
static bool lvp__store_rows(lvp__reach *reach, const lvp__diffusion *diffusion, int32_t n)
{
	int64_t total = 0;
	reach->offsets[0] = 0;
	for (int32_t k = 0; k < n; ++k) {
		const float *values = diffusion->values + (int64_t)k * diffusion->stride;
		int32_t kept = 0;
		while (kept < diffusion->counts[k] && values[kept] >= LVP__REACH_FLOOR * values[0])
			++kept;
		total += kept;
		if (total > INT32_MAX)
			return false;
		reach->offsets[k + 1] = (int32_t)total;
	}
	reach->regions = malloc(sizeof(int32_t) * (size_t)(total > 0 ? total : 1));
	reach->phi = malloc(sizeof(float) * (size_t)(total > 0 ? total : 1));
	if (!reach->regions || !reach->phi)
		return false;
	for (int32_t k = 0; k < n; ++k) {
		const int32_t *bones = diffusion->bones + (int64_t)k * diffusion->stride;
		const float *values = diffusion->values + (int64_t)k * diffusion->stride;
		int32_t begin = reach->offsets[k], count = reach->offsets[k + 1] - begin;
		double sum = 0.0;
		for (int32_t j = 0; j < count; ++j)
			sum += values[j];
		for (int32_t j = 0; j < count; ++j) {
			reach->regions[begin + j] = bones[j];
			reach->phi[begin + j] = (float)(values[j] / sum);
		}
		reach->largest[k] = count > 0 ? reach->phi[begin] : 0.0f;
	}
	return true;
}

lvp_result lvp__build_reach(lvp_binding *binding, float bulge_width, lvp_diagnostic *r_diag)
{
	lvp__reach_is_weights(binding);
	if (!(bulge_width > 0.0f) || binding->mode != LVP_MODE_LOCAL || !binding->rig.weight_offsets ||
	    binding->bone_count == 0)
		return lvp_success;
	/* Rows of the 8 strongest bones: room for the joints around a vertex, and the cost of a step
	 * bounded (artist weights can name 15 bones, a third of them under 1 %). */
	int32_t n = binding->vertex_count;
	int32_t stride = binding->bone_count < LVP__DIFFUSION_ROW ? binding->bone_count : LVP__DIFFUSION_ROW;

	lvp__diffusion diffusion = {0};
	lvp__reach reach = {0};
	reach.own = true;
	reach.offsets = malloc(sizeof(int32_t) * ((size_t)n + 1));
	reach.largest = malloc(sizeof(float) * ((size_t)n > 0 ? (size_t)n : 1));
	float *rates = malloc(sizeof(float) * ((size_t)n > 0 ? (size_t)n : 1));
	bool ok = reach.offsets && reach.largest && rates &&
	          lvp__diffusion_init(&diffusion, binding->mesh.triangles, n, binding->triangle_count, binding->bone_count,
	                              stride);
	if (ok) {
		for (int32_t k = 0; k < n; ++k)
			lvp__load_row(&diffusion, binding, k);
		int32_t steps = lvp__reach_rates(rates, binding, &diffusion, (double)bulge_width);
		for (int32_t step = 0; step < steps; ++step)
			lvp__diffusion_step(&diffusion, n, rates, binding->pool);
		ok = lvp__store_rows(&reach, &diffusion, n);
	}
	lvp__diffusion_free(&diffusion);
	free(rates);
	if (!ok) {
		lvp__reach_free(&reach);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "options.bulge_width", -1,
		                 "out of memory while spreading the correction of %d vertices; bind with "
		                 "options.bulge_width 0 to do without.",
		                 (int)n);
	}
	binding->reach = reach;
	return lvp_success;
}
