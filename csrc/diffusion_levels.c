/*
 * diffusion_levels.c - many steps of diffusion (diffusion.h, lvp__diffusion_blend) at the cost of a few.
 *
 * Explicit steps spread a border over about sqrt(2 steps) edges, so blending over a fixed distance costs
 * steps that grow with the square of the mesh's density: hundreds on a dense body. Here the rows are
 * averaged over clusters of nearby vertices (each cluster the vertices within a few edges of its seed,
 * grown breadth first through vertices no cluster has yet), the clusters' rows are diffused over the graph
 * of the clusters (two are adjacent when an edge joins them) as far as the asked steps would spread them,
 * measured by the distances between the clusters' centroids (through clusters of clusters when that is
 * many steps again), then every vertex takes its cluster's row and ordinary steps smooth the clusters'
 * borders, over about one cluster's spacing. The clusters are a few edges wide, so each level takes few
 * steps and has a fraction of the vertices of the one below: the whole costs a few steps of the finest,
 * however wide the blend. Clusters grow along edges and the clusters' graph follows edges: weight never reaches a separate
 * piece, as with the steps.
 */
#include "diffusion.h"

#include <stdlib.h>
#include <string.h>

/* The clusters: of_vertex[k] the cluster of vertex k; members of cluster c at member_offsets[c]... */
typedef struct lvp__clusters {
	int32_t count;
	int32_t *of_vertex;
	int32_t *member_offsets; /* count + 1 */
	int32_t *members;        /* grouped by cluster, each group in breadth-first order from its seed */
} lvp__clusters;

static void lvp__clusters_free(lvp__clusters *clusters)
{
	free(clusters->of_vertex);
	free(clusters->member_offsets);
	free(clusters->members);
}

/* Seeds in vertex order; each cluster takes the vertices within LVP__DIFFUSION_CLUSTER_RINGS edges of its
 * seed that no earlier cluster took, found breadth first through such vertices. Each vertex enters the
 * queue once, so the members are the queue itself. */
static bool lvp__find_clusters(lvp__clusters *clusters, const lvp__diffusion *fine, int32_t vertex_count)
{
	size_t n = (size_t)vertex_count;
	memset(clusters, 0, sizeof(*clusters));
	clusters->of_vertex = malloc(sizeof(int32_t) * (n ? n : 1));
	clusters->members = malloc(sizeof(int32_t) * (n ? n : 1));
	clusters->member_offsets = malloc(sizeof(int32_t) * (n + 1));
	int32_t *depth = malloc(sizeof(int32_t) * (n ? n : 1));
	if (!clusters->of_vertex || !clusters->members || !clusters->member_offsets || !depth) {
		free(depth);
		return false;
	}
	for (int32_t k = 0; k < vertex_count; ++k)
		clusters->of_vertex[k] = -1;
	int32_t *queue = clusters->members, tail = 0;
	for (int32_t seed = 0; seed < vertex_count; ++seed) {
		if (clusters->of_vertex[seed] >= 0)
			continue;
		int32_t cluster = clusters->count++, head = tail;
		clusters->member_offsets[cluster] = head;
		clusters->of_vertex[seed] = cluster;
		depth[seed] = 0;
		queue[tail++] = seed;
		while (head < tail) {
			int32_t v = queue[head++];
			if (depth[v] == LVP__DIFFUSION_CLUSTER_RINGS)
				continue;
			for (int32_t e = fine->neighbour_offsets[v]; e < fine->neighbour_offsets[v + 1]; ++e) {
				int32_t u = fine->neighbours[e];
				if (clusters->of_vertex[u] >= 0)
					continue;
				clusters->of_vertex[u] = cluster;
				depth[u] = depth[v] + 1;
				queue[tail++] = u;
			}
		}
	}
	clusters->member_offsets[clusters->count] = tail;
	free(depth);
	return true;
}

/* The clusters' graph into coarse's neighbour lists (each neighbour once, sorted). */
static bool lvp__cluster_graph(lvp__diffusion *coarse, const lvp__clusters *clusters, const lvp__diffusion *fine)
{
	int32_t m = clusters->count, *offsets = coarse->neighbour_offsets;
	/* Every fine edge that leaves its cluster, repeats included; compacted afterwards. */
	offsets[0] = 0;
	for (int32_t c = 0; c < m; ++c) {
		int32_t leaving = 0;
		for (int32_t i = clusters->member_offsets[c]; i < clusters->member_offsets[c + 1]; ++i) {
			int32_t v = clusters->members[i];
			for (int32_t e = fine->neighbour_offsets[v]; e < fine->neighbour_offsets[v + 1]; ++e)
				leaving += clusters->of_vertex[fine->neighbours[e]] != c;
		}
		offsets[c + 1] = offsets[c] + leaving;
	}
	int32_t *list = malloc(sizeof(int32_t) * ((size_t)offsets[m] + 1));
	if (!list)
		return false;
	for (int32_t c = 0; c < m; ++c) {
		int32_t at = offsets[c];
		for (int32_t i = clusters->member_offsets[c]; i < clusters->member_offsets[c + 1]; ++i) {
			int32_t v = clusters->members[i];
			for (int32_t e = fine->neighbour_offsets[v]; e < fine->neighbour_offsets[v + 1]; ++e) {
				int32_t other = clusters->of_vertex[fine->neighbours[e]];
				if (other != c)
					list[at++] = other;
			}
		}
	}
	lvp__compact_neighbour_lists(offsets, list, m);
	coarse->neighbours = list;
	return true;
}

/* Each cluster's row: the mean of its members' rows, kept to the strongest bones; and its centroid. */
static void lvp__restrict_rows(lvp__diffusion *coarse, float *r_centroids, const lvp__clusters *clusters,
                               const lvp__diffusion *fine, const float *positions)
{
	int32_t stride = fine->stride;
	for (int32_t c = 0; c < clusters->count; ++c) {
		int32_t first = clusters->member_offsets[c], last = clusters->member_offsets[c + 1], touched_count = 0;
		double share = 1.0 / (double)(last - first), centroid[3] = {0.0, 0.0, 0.0};
		for (int32_t i = first; i < last; ++i) {
			int32_t v = clusters->members[i];
			for (int a = 0; a < 3; ++a)
				centroid[a] += share * positions[3 * (int64_t)v + a];
			touched_count = lvp__diffusion_add_row(coarse->accum, coarse->touched, touched_count, fine, v, share);
		}
		for (int a = 0; a < 3; ++a)
			r_centroids[3 * (int64_t)c + a] = (float)centroid[a];
		coarse->counts[c] = lvp__diffusion_finish_row(coarse->bones + (int64_t)c * stride,
		                                              coarse->values + (int64_t)c * stride, stride, coarse->accum,
		                                              coarse->touched, touched_count);
	}
}

/* Every vertex takes its cluster's row. */
static void lvp__prolong_rows(lvp__diffusion *fine, const lvp__diffusion *coarse, const lvp__clusters *clusters,
                              int32_t vertex_count)
{
	int32_t stride = fine->stride;
	for (int32_t k = 0; k < vertex_count; ++k) {
		int32_t c = clusters->of_vertex[k], count = coarse->counts[c];
		memcpy(fine->bones + (int64_t)k * stride, coarse->bones + (int64_t)c * stride, sizeof(int32_t) * (size_t)count);
		memcpy(fine->values + (int64_t)k * stride, coarse->values + (int64_t)c * stride, sizeof(float) * (size_t)count);
		fine->counts[k] = count;
	}
}

bool lvp__diffusion_blend(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count, int64_t steps,
                          const uint8_t *wanted, lvp__pool *pool)
{
	if (steps < LVP__DIFFUSION_COARSE_FROM)
		return lvp__diffusion_steps_near(diffusion, vertex_count, steps, wanted, pool);
	double edge = lvp__mean_edge_length(diffusion, positions, vertex_count);
	double length = edge * sqrt(2.0 * (double)steps); /* what the steps would blend over (lvp__blend_steps) */
	lvp__clusters clusters;
	lvp__diffusion coarse = {0};
	float *centroids = NULL;
	bool ok = lvp__find_clusters(&clusters, diffusion, vertex_count) &&
	          lvp__diffusion_alloc(&coarse, clusters.count, diffusion->bone_count, diffusion->stride) &&
	          lvp__cluster_graph(&coarse, &clusters, diffusion) &&
	          (centroids = malloc(sizeof(float) * 3 * ((size_t)clusters.count + 1))) != NULL;
	if (ok) {
		lvp__restrict_rows(&coarse, centroids, &clusters, diffusion, positions);
		double spacing = lvp__mean_edge_length(&coarse, centroids, clusters.count);
		/* Many steps on the clusters too are taken through clusters of clusters: each level is a few
		 * times coarser, so the levels are few and the whole costs a few steps of the finest. */
		ok = lvp__diffusion_blend(&coarse, centroids, clusters.count, lvp__diffusion_steps(length, spacing, INT32_MAX),
		                          NULL, pool);
		lvp__prolong_rows(diffusion, &coarse, &clusters, vertex_count);
		/* The clusters' borders, a step of up to a cluster's spacing, smoothed over about that. */
		ok = ok && lvp__diffusion_steps_near(diffusion, vertex_count, lvp__diffusion_steps(spacing, edge, INT32_MAX),
		                                     wanted, pool);
	}
	free(centroids);
	lvp__diffusion_free(&coarse);
	lvp__clusters_free(&clusters);
	return ok;
}
