/*
 * diffusion_thickness.c - rows of bone weights blended over a distance that follows the flesh
 * (diffusion.h, lvp__diffusion_blend_by_thickness; lvp.h, SMOOTHING BY THICKNESS).
 *
 * One blending distance for a whole character is wrong somewhere: what fits a finger leaves a hip
 * creased, and what fits a hip spreads a finger's bones over its whole length, while a distance
 * taken from the mesh's size changes with whatever else the mesh holds (a tail, a weapon, arms out
 * or down). Heat weights (Baran and Popovic 2007) screen their diffusion by the distance to the
 * nearest bone, so their blends follow the flesh's thickness; here each bone's thickness is
 * measured once (the median distance from it of the skin that is mostly its own), the rows are
 * blended over a ladder of lengths, and each vertex takes the mix of the two rungs around the length
 * its bones ask for, or its own depth under the skin when that is more: the skin of a palm's edge lies
 * three or four times deeper than its finger's flesh is thick, and blended over the finger's
 * thickness its weight fell from finger to palm within a centimetre, a fold as the finger bent. The
 * rungs are ordinary blends (diffusion_levels.c), so weight still flows only along edges, and the
 * length a vertex asks for is read from the widest rung's rows, which change smoothly over the surface
 * (and its depth from a distance to its bone, continuous but for where its strongest bone changes):
 * neighbouring vertices take nearly the same mix.
 */
#include "diffusion.h"

#include <stdlib.h>
#include <string.h>

/* Each rung of the ladder blends over this many times the length of the one below: a vertex between
 * two rungs mixes blends that differ little. */
#define LVP__RUNG_RATIO 1.4142135623730951
/* Rungs at most; a wider range of thicknesses spaces them further apart. */
#define LVP__MAX_RUNGS 24

static int lvp__compare_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

/* thickness[i]: the median of distances[k] over the vertices whose row starts with bone i, 0 for a bone
 * that is no vertex's strongest. Returns false when memory runs out. */
static bool lvp__bone_thickness(double *thickness, const lvp__diffusion *rows, int32_t vertex_count,
                                const double *distances)
{
	int32_t bone_count = rows->bone_count;
	int32_t *starts = calloc((size_t)bone_count + 1, sizeof(int32_t));
	double *sorted = malloc(sizeof(double) * ((size_t)vertex_count + 1));
	if (!starts || !sorted) {
		free(starts);
		free(sorted);
		return false;
	}
	for (int32_t k = 0; k < vertex_count; ++k)
		if (rows->counts[k] > 0)
			++starts[rows->bones[(int64_t)k * rows->stride] + 1];
	for (int32_t i = 0; i < bone_count; ++i)
		starts[i + 1] += starts[i];
	for (int32_t k = 0; k < vertex_count; ++k)
		if (rows->counts[k] > 0)
			sorted[starts[rows->bones[(int64_t)k * rows->stride]]++] = distances[k];
	/* The fill moved each start to the next bone's: walk them back down. */
	for (int32_t i = bone_count; i > 0; --i)
		starts[i] = starts[i - 1];
	starts[0] = 0;
	for (int32_t i = 0; i < bone_count; ++i) {
		int32_t count = starts[i + 1] - starts[i];
		thickness[i] = 0.0;
		if (count == 0)
			continue;
		qsort(sorted + starts[i], (size_t)count, sizeof(double), lvp__compare_double);
		thickness[i] = sorted[starts[i] + (count - 1) / 2];
	}
	free(starts);
	free(sorted);
	return true;
}

/* The length vertex k asks for by its bones: share times the thickness of the bones of its row, weighted
 * by their weights, over the bones that have a thickness (`fallback` when none has). */
static double lvp__wanted_length(const lvp__diffusion *rows, int32_t k, const double *thickness, double share,
                                 double fallback)
{
	const int32_t *bones = rows->bones + (int64_t)k * rows->stride;
	const float *values = rows->values + (int64_t)k * rows->stride;
	double sum = 0.0, weights = 0.0;
	for (int32_t j = 0; j < rows->counts[k]; ++j)
		if (thickness[bones[j]] > 0.0) {
			sum += (double)values[j] * thickness[bones[j]];
			weights += (double)values[j];
		}
	return weights > 0.0 ? share * sum / weights : fallback;
}

/* Adds `share` times row k of `rows` to vertex k's mix (at most 2 stride bones: two rungs). */
static void lvp__add_to_mix(int32_t *mix_counts, int32_t *mix_bones, double *mix_values, const lvp__diffusion *rows,
                            int32_t k, double share)
{
	int32_t stride = rows->stride, room = 2 * stride;
	int32_t *bones = mix_bones + (int64_t)k * room;
	double *values = mix_values + (int64_t)k * room;
	for (int32_t j = 0; j < rows->counts[k]; ++j) {
		int32_t bone = rows->bones[(int64_t)k * stride + j], at = 0;
		while (at < mix_counts[k] && bones[at] != bone)
			++at;
		if (at == mix_counts[k]) {
			bones[at] = bone;
			values[at] = 0.0;
			++mix_counts[k];
		}
		values[at] += share * (double)rows->values[(int64_t)k * stride + j];
	}
}

/* The steps of rung `rung`, which blends over low * ratio^rung. The mesh's sampling alone spreads a border
 * over about an edge (weights are interpolated across it): the steps add what is missing, widths adding in
 * quadrature, so that a coarse mesh blends over the distance a fine one does; at least one step, so that no
 * border stays a jump. */
static int32_t lvp__rung_steps(double low, double ratio, int32_t rung, double edge)
{
	double length = low * pow(ratio, (double)rung), missing = length * length - edge * edge;
	return missing > 0.0 ? lvp__diffusion_steps(sqrt(missing), edge, INT32_MAX) : 1;
}

/* How much of rung `rung` a vertex at `place` on the ladder takes: of the two rungs around it, the lower
 * 1 - (place - lower), the upper the rest; 0 of any other. */
static double lvp__rung_share(double place, int32_t rung)
{
	double lower = floor(place), upper_share = place - lower;
	if ((int32_t)lower == rung)
		return 1.0 - upper_share;
	return (int32_t)lower + 1 == rung ? upper_share : 0.0;
}

/* Adds the rows, as blended for `rung`, to the mix of each vertex that takes that rung. */
static void lvp__mix_rung(int32_t *mix_counts, int32_t *mix_bones, double *mix_values, const lvp__diffusion *rows,
                          const double *place, int32_t vertex_count, int32_t rung)
{
	for (int32_t k = 0; k < vertex_count; ++k) {
		double share = lvp__rung_share(place[k], rung);
		if (share > 0.0)
			lvp__add_to_mix(mix_counts, mix_bones, mix_values, rows, k, share);
	}
}

/* Marks in r_wanted the vertices that take `rung`; returns whether any does. */
static bool lvp__takers(uint8_t *r_wanted, const double *place, int32_t vertex_count, int32_t rung)
{
	bool any = false;
	for (int32_t k = 0; k < vertex_count; ++k) {
		r_wanted[k] = lvp__rung_share(place[k], rung) > 0.0;
		any = any || r_wanted[k];
	}
	return any;
}

bool lvp__diffusion_blend_by_thickness(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count,
                                       const double *distances, const double *depths, double share)
{
	int32_t stride = diffusion->stride, bone_count = diffusion->bone_count;
	size_t n = (size_t)vertex_count, entries = n * (size_t)stride;
	double edge = lvp__mean_edge_length(diffusion, positions, vertex_count);
	double *thickness = malloc(sizeof(double) * ((size_t)bone_count + 1));
	if (!thickness)
		return false;
	if (!lvp__bone_thickness(thickness, diffusion, vertex_count, distances)) {
		free(thickness);
		return false;
	}
	double least = INFINITY, most = 0.0;
	for (int32_t i = 0; i < bone_count; ++i)
		if (thickness[i] > 0.0) {
			least = thickness[i] < least ? thickness[i] : least;
			most = thickness[i] > most ? thickness[i] : most;
		}
	double deepest = most; /* the ladder reaches the deepest skin too */
	for (int32_t k = 0; k < vertex_count; ++k)
		deepest = depths[k] > deepest ? depths[k] : deepest;
	if (!(most > 0.0) || !(edge > 0.0)) {
		free(thickness); /* every vertex on its bone, or no edge: nothing to blend over */
		return true;
	}
	/* The rungs blend over edge * ratio^j, lengths that the bones' thicknesses choose among but do not
	 * move: a piece with thicker or thinner bones adds rungs. Blends shorter than an edge take one step
	 * all the same. */
	double low = share * least > edge ? share * least : edge, high = share * deepest > low ? share * deepest : low;
	int32_t lowest = (int32_t)floor(log(low / edge) / log(LVP__RUNG_RATIO) + 1e-9);
	int32_t highest = (int32_t)ceil(log(high / edge) / log(LVP__RUNG_RATIO) - 1e-9);
	if (highest - lowest + 1 > LVP__MAX_RUNGS)
		lowest = highest - LVP__MAX_RUNGS + 1; /* the thinnest bones blend over a little more than asked */
	int32_t rungs = highest - lowest + 1;
	low = edge * pow(LVP__RUNG_RATIO, (double)lowest);
	double ratio = LVP__RUNG_RATIO;

	int32_t room = 2 * stride;
	int32_t *raw_counts = malloc(sizeof(int32_t) * n), *raw_bones = malloc(sizeof(int32_t) * entries);
	float *raw_values = malloc(sizeof(float) * entries);
	double *place = malloc(sizeof(double) * n), *mix_values = malloc(sizeof(double) * n * (size_t)room);
	int32_t *mix_counts = calloc(n, sizeof(int32_t)), *mix_bones = malloc(sizeof(int32_t) * n * (size_t)room);
	double *accum = calloc((size_t)bone_count, sizeof(double));
	int32_t *touched = malloc(sizeof(int32_t) * (size_t)room);
	uint8_t *wanted = malloc(n);
	bool ok = raw_counts && raw_bones && raw_values && place && mix_values && mix_counts && mix_bones && accum &&
	          touched && wanted;
	if (ok)
		lvp__copy_rows(raw_counts, raw_bones, raw_values, diffusion->counts, diffusion->bones, diffusion->values,
		               vertex_count, stride);
	/* The widest rung first, everywhere: its rows say which length each vertex asks for. Then each other
	 * rung from the unblended rows, blended only where the vertices that take it need (a rung no vertex
	 * takes is not blended at all): the narrow ones near the thin bones, the wide ones near the thick. */
	for (int32_t turn = 0; ok && turn < rungs; ++turn) {
		int32_t rung = turn == 0 ? rungs - 1 : turn - 1;
		if (turn > 0) {
			if (!lvp__takers(wanted, place, vertex_count, rung))
				continue;
			lvp__copy_rows(diffusion->counts, diffusion->bones, diffusion->values, raw_counts, raw_bones, raw_values,
			               vertex_count, stride);
		}
		ok = lvp__diffusion_blend(diffusion, positions, vertex_count, lvp__rung_steps(low, ratio, rung, edge),
		                          turn == 0 ? NULL : wanted, NULL);
		if (ok && turn == 0)
			for (int32_t k = 0; k < vertex_count; ++k) {
				double wanted_length = lvp__wanted_length(diffusion, k, thickness, share, share * most);
				if (share * depths[k] > wanted_length)
					wanted_length = share * depths[k];
				double at = rungs > 1 && wanted_length > low ? log(wanted_length / low) / log(ratio) : 0.0;
				place[k] = at < (double)(rungs - 1) ? at : (double)(rungs - 1);
			}
		if (ok)
			lvp__mix_rung(mix_counts, mix_bones, mix_values, diffusion, place, vertex_count, rung);
	}
	if (ok)
		for (int32_t k = 0; k < vertex_count; ++k) {
			const int32_t *bones = mix_bones + (int64_t)k * room;
			const double *values = mix_values + (int64_t)k * room;
			for (int32_t j = 0; j < mix_counts[k]; ++j) {
				accum[bones[j]] = values[j];
				touched[j] = bones[j];
			}
			diffusion->counts[k] =
			    lvp__diffusion_finish_row(diffusion->bones + (int64_t)k * stride,
			                              diffusion->values + (int64_t)k * stride, stride, accum, touched,
			                              mix_counts[k]);
		}
	free(thickness);
	free(raw_counts);
	free(raw_bones);
	free(raw_values);
	free(place);
	free(mix_values);
	free(mix_counts);
	free(mix_bones);
	free(accum);
	free(touched);
	free(wanted);
	return ok;
}
