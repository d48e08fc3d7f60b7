/*
 * diffusion_slivers.c - one row for the ends of an edge far shorter than the edges around it (diffusion.h,
 * lvp__diffusion_share_slivers; lvp.h, SMOOTHING BY THICKNESS). Metaballs, voxel remeshers and
 * decimation leave slivers: two vertices a millimetre apart among edges of centimetres. The diffusion's
 * steps count edges, not lengths, so a sliver's two ends blend as two vertices an edge apart do, and
 * their rows can differ by a twentieth of a bone's weight. Where the bones move apart (the buttock when
 * the legs spread) that difference moves one end centimetres further than the other, across a millimetre:
 * the skin folds through itself there, where weights smooth in space (heat weights) keep it flat. The
 * ends of such edges (and of chains of them) take the mean of their rows.
 */
#include "diffusion.h"

#include <stdlib.h>
#include <string.h>

/* An edge is a sliver's when it is shorter than this share of the mean length of the edges around its
 * two ends. */
#define LVP__SLIVER_SHARE 0.125

static double lvp__edge_length(const float *positions, int32_t a, int32_t b)
{
	lvp__vec3 d = lvp__sub(lvp__load(positions + 3 * (int64_t)a), lvp__load(positions + 3 * (int64_t)b));
	return sqrt(lvp__dot(d, d));
}

/* Each vertex's cluster root in `parent`, joined through sliver edges; returns how many edges joined two. */
static int32_t lvp__join_slivers(int32_t *parent, double *around, const lvp__diffusion *diffusion,
                                 const float *positions, int32_t vertex_count)
{
	const int32_t *offsets = diffusion->neighbour_offsets, *neighbours = diffusion->neighbours;
	for (int32_t k = 0; k < vertex_count; ++k) {
		double sum = 0.0;
		for (int32_t e = offsets[k]; e < offsets[k + 1]; ++e)
			sum += lvp__edge_length(positions, k, neighbours[e]);
		around[k] = offsets[k + 1] > offsets[k] ? sum / (double)(offsets[k + 1] - offsets[k]) : 0.0;
		parent[k] = k;
	}
	int32_t joined = 0;
	for (int32_t k = 0; k < vertex_count; ++k)
		for (int32_t e = offsets[k]; e < offsets[k + 1]; ++e) {
			int32_t u = neighbours[e];
			if (u < k || !(lvp__edge_length(positions, k, u) < LVP__SLIVER_SHARE * 0.5 * (around[k] + around[u])))
				continue;
			int32_t a = lvp__union_root(parent, k), b = lvp__union_root(parent, u);
			if (a != b) {
				parent[a < b ? b : a] = a < b ? a : b; /* the lower root stays: the clusters do not
				                                          depend on the order edges are met in */
				++joined;
			}
		}
	return joined;
}

bool lvp__diffusion_share_slivers(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count)
{
	size_t n = (size_t)vertex_count;
	int32_t *parent = malloc(sizeof(int32_t) * (n + 1));
	int32_t *offsets = calloc(n + 2, sizeof(int32_t));
	int32_t *members = malloc(sizeof(int32_t) * (n + 1));
	double *around = malloc(sizeof(double) * (n + 1));
	if (!parent || !offsets || !members || !around) {
		free(parent);
		free(offsets);
		free(members);
		free(around);
		return false;
	}
	if (lvp__join_slivers(parent, around, diffusion, positions, vertex_count) > 0) {
		/* The members of each cluster, by root (in vertex order); first every vertex's parent its root. */
		for (int32_t k = 0; k < vertex_count; ++k)
			parent[k] = lvp__union_root(parent, k);
		for (int32_t k = 0; k < vertex_count; ++k)
			++offsets[parent[k] + 2];
		for (size_t k = 2; k < n + 2; ++k)
			offsets[k] += offsets[k - 1];
		for (int32_t k = 0; k < vertex_count; ++k)
			members[offsets[parent[k] + 1]++] = k;
		int32_t stride = diffusion->stride, bones[LVP__DIFFUSION_MAX_ROW];
		float values[LVP__DIFFUSION_MAX_ROW];
		for (int32_t root = 0; root < vertex_count; ++root) {
			int32_t begin = offsets[root], end = offsets[root + 1], touched_count = 0;
			if (end - begin < 2)
				continue;
			double share = 1.0 / (double)(end - begin);
			for (int32_t i = begin; i < end; ++i)
				touched_count = lvp__diffusion_add_row(diffusion->accum, diffusion->touched, touched_count, diffusion,
				                                       members[i], share);
			int32_t count = lvp__diffusion_finish_row(bones, values, stride, diffusion->accum, diffusion->touched,
			                                          touched_count);
			for (int32_t i = begin; i < end; ++i) {
				int64_t at = (int64_t)members[i] * stride;
				memcpy(diffusion->bones + at, bones, sizeof(int32_t) * (size_t)count);
				memcpy(diffusion->values + at, values, sizeof(float) * (size_t)count);
				diffusion->counts[members[i]] = count;
			}
		}
	}
	free(parent);
	free(offsets);
	free(members);
	free(around);
	return true;
}
