/*
 * weld.c - vertices at the same rest position are one point of the skin (lvp.h, SEAMS).
 *
 * Meshes from glTF, FBX or caches are split along their UV seams and hard edges: one vertex per
 * (position, normal, UV), so a closed surface arrives with open borders along every seam. Taken
 * as they come, the copies of one point get normals from half of their triangles only, regions
 * and parts end at every seam, and a seam can open into a crack. So bind finds the points (the
 * distinct rest positions, compared bit for bit), and every stage works on them: the welded
 * mesh. Each frame the caller's positions are gathered into the points (each point takes its
 * first vertex's), and each point's offset is given to all of its vertices.
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

typedef struct lvp__sort_key {
	uint32_t bits[3];
	int32_t vertex;
} lvp__sort_key;

/* The bits of a coordinate, with -0 as +0 (they are the same position). */
static uint32_t lvp__position_bits(float value)
{
	uint32_t bits;
	if (value == 0.0f)
		value = 0.0f;
	memcpy(&bits, &value, sizeof(bits));
	return bits;
}

static int lvp__compare_keys(const void *a, const void *b)
{
	const lvp__sort_key *x = a, *y = b;
	for (int c = 0; c < 3; ++c)
		if (x->bits[c] != y->bits[c])
			return x->bits[c] < y->bits[c] ? -1 : 1;
	return x->vertex < y->vertex ? -1 : (x->vertex > y->vertex);
}

static int lvp__compare_pairs(const void *a, const void *b)
{
	const int32_t *x = a, *y = b;
	if (x[0] != y[0])
		return x[0] < y[0] ? -1 : 1;
	return x[1] < y[1] ? -1 : (x[1] > y[1]);
}

static int32_t lvp__weld_root(int32_t *parent, int32_t k)
{
	while (parent[k] != k) {
		parent[k] = parent[parent[k]];
		k = parent[k];
	}
	return k;
}

/* Joins the vertices at one position that a seam split: those with neighbours at one position
 * too (a copy of an edge). Vertices of separate shells that only touch at a point stay apart.
 * keys: the vertices sorted by position; place[k]: the index of k's position. parent: union-find,
 * by smaller index. pairs: scratch of 2 per directed edge. */
static void lvp__join_seam_copies(int32_t *parent, const lvp__sort_key *keys, const int32_t *place, int32_t n,
                                  const int32_t *neighbour_offsets, const int32_t *neighbours, int32_t *pairs)
{
	for (int32_t begin = 0, end; begin < n; begin = end) {
		for (end = begin + 1; end < n && place[keys[end].vertex] == place[keys[begin].vertex]; ++end)
			;
		if (end - begin < 2)
			continue;
		int32_t count = 0; /* (neighbour's position, vertex) for each vertex at this position */
		for (int32_t i = begin; i < end; ++i) {
			int32_t k = keys[i].vertex;
			for (int32_t e = neighbour_offsets[k]; e < neighbour_offsets[k + 1]; ++e) {
				pairs[2 * count] = place[neighbours[e]];
				pairs[2 * count + 1] = k;
				++count;
			}
		}
		qsort(pairs, (size_t)count, 2 * sizeof(int32_t), lvp__compare_pairs);
		for (int32_t i = 1; i < count; ++i) {
			if (pairs[2 * i] != pairs[2 * i - 2])
				continue;
			int32_t a = lvp__weld_root(parent, pairs[2 * i - 1]), b = lvp__weld_root(parent, pairs[2 * i + 1]);
			if (a < b)
				parent[b] = a;
			else if (b < a)
				parent[a] = b;
		}
	}
}

/* vertex_point and point_first, numbering the points by their first vertex; false when out of
 * memory. */
static bool lvp__number_points(lvp__weld *weld, int32_t *r_point_count, const float *positions, int32_t n,
                               const int32_t *triangles, int32_t triangle_count)
{
	size_t slots = (size_t)(n > 0 ? n : 1), directed = 6 * (size_t)triangle_count + 1;
	/* pairs: 2 per directed edge, and before that the neighbour lists' fill, one per vertex (a mesh of
	 * loose vertices has more vertices than its triangles have edges) */
	size_t pair_slots = 2 * directed > slots ? 2 * directed : slots;
	lvp__sort_key *keys = malloc(sizeof(lvp__sort_key) * slots);
	int32_t *place = malloc(sizeof(int32_t) * slots);
	int32_t *neighbour_offsets = calloc(slots + 1, sizeof(int32_t));
	int32_t *neighbours = malloc(sizeof(int32_t) * directed);
	int32_t *pairs = malloc(sizeof(int32_t) * pair_slots);
	bool ok = keys && place && neighbour_offsets && neighbours && pairs;
	if (ok) {
		for (int32_t k = 0; k < n; ++k) {
			for (int c = 0; c < 3; ++c)
				keys[k].bits[c] = lvp__position_bits(positions[3 * k + c]);
			keys[k].vertex = k;
		}
		qsort(keys, (size_t)n, sizeof(lvp__sort_key), lvp__compare_keys);
		for (int32_t i = 0, at = -1; i < n; ++i) {
			if (i == 0 || memcmp(keys[i].bits, keys[i - 1].bits, sizeof(keys[i].bits)) != 0)
				++at;
			place[keys[i].vertex] = at;
		}
		/* Each vertex's neighbours along the triangles' edges (repeats do no harm). */
		for (int32_t i = 0; i < 3 * triangle_count; ++i)
			neighbour_offsets[triangles[i] + 1] += 2;
		for (int32_t k = 0; k < n; ++k)
			neighbour_offsets[k + 1] += neighbour_offsets[k];
		int32_t *fill = pairs; /* scratch until the pairs are needed */
		memcpy(fill, neighbour_offsets, sizeof(int32_t) * (size_t)n);
		for (int32_t t = 0; t < triangle_count; ++t)
			for (int c = 0; c < 3; ++c) {
				int32_t k = triangles[3 * t + c];
				neighbours[fill[k]++] = triangles[3 * t + (c + 1) % 3];
				neighbours[fill[k]++] = triangles[3 * t + (c + 2) % 3];
			}
		int32_t *parent = weld->vertex_point; /* union-find until the points are numbered */
		for (int32_t k = 0; k < n; ++k)
			parent[k] = k;
		lvp__join_seam_copies(parent, keys, place, n, neighbour_offsets, neighbours, pairs);
		int32_t *point_of_root = place; /* the positions are no longer needed */
		int32_t points = 0;
		for (int32_t k = 0; k < n; ++k) {
			int32_t root = lvp__weld_root(parent, k); /* the smallest index: k itself, or seen before */
			if (root == k) {
				point_of_root[k] = points;
				weld->point_first[points++] = k;
			}
			parent[k] = root;
		}
		for (int32_t k = 0; k < n; ++k)
			weld->vertex_point[k] = point_of_root[parent[k]];
		*r_point_count = points;
	}
	free(keys);
	free(place);
	free(neighbour_offsets);
	free(neighbours);
	free(pairs);
	return ok;
}

/* The caller's vertices of each point, in order (for giving each point's offset to all of them). */
static void lvp__list_copies(lvp__weld *weld, int32_t points)
{
	int32_t n = weld->caller_vertex_count;
	for (int32_t k = 0; k < n; ++k)
		++weld->copy_offsets[weld->vertex_point[k] + 1];
	for (int32_t p = 0; p < points; ++p)
		weld->copy_offsets[p + 1] += weld->copy_offsets[p];
	int32_t *fill = weld->copy_offsets; /* advanced below, then moved back */
	for (int32_t k = 0; k < n; ++k)
		weld->copies[fill[weld->vertex_point[k]]++] = k;
	for (int32_t p = points; p > 0; --p)
		fill[p] = fill[p - 1];
	fill[0] = 0;
}

lvp_result lvp__find_points(lvp__weld *weld, lvp__welded_mesh *r_mesh, const float *positions, int32_t vertex_count,
                            const int32_t *triangles, int32_t triangle_count, const lvp_weights *weights,
                            lvp_diagnostic *r_diag)
{
	memset(weld, 0, sizeof(*weld));
	memset(r_mesh, 0, sizeof(*r_mesh));
	weld->caller_vertex_count = vertex_count;
	size_t n = (size_t)(vertex_count > 0 ? vertex_count : 1);
	weld->vertex_point = malloc(sizeof(int32_t) * n);
	weld->point_first = malloc(sizeof(int32_t) * n);
	int32_t points = 0;
	if (!weld->vertex_point || !weld->point_first ||
	    !lvp__number_points(weld, &points, positions, vertex_count, triangles, triangle_count))
		goto out_of_memory;
	if (points == vertex_count) { /* no two vertices coincide: the caller's mesh as it is */
		lvp__weld_free(weld);
		return lvp_success;
	}

	weld->copy_offsets = calloc((size_t)points + 1, sizeof(int32_t));
	weld->copies = malloc(sizeof(int32_t) * n);
	weld->positions = malloc(sizeof(float) * 3 * (size_t)points);
	weld->rest = malloc(sizeof(float) * 3 * (size_t)points);
	r_mesh->positions = malloc(sizeof(float) * 3 * (size_t)points);
	r_mesh->triangles = malloc(sizeof(int32_t) * 3 * (size_t)(triangle_count > 0 ? triangle_count : 1));
	if (!weld->copy_offsets || !weld->copies || !weld->positions || !weld->rest || !r_mesh->positions ||
	    !r_mesh->triangles)
		goto out_of_memory;
	lvp__list_copies(weld, points);
	weld->point_count = r_mesh->vertex_count = points;
	lvp__gather(r_mesh->positions, weld, positions);
	for (int32_t i = 0; i < 3 * triangle_count; ++i)
		r_mesh->triangles[i] = weld->vertex_point[triangles[i]];

	/* Each point is skinned as its first vertex is (its copies' weights are the same where a
	 * mesh was only split at seams). */
	if (weights) {
		int32_t entries = 0;
		for (int32_t p = 0; p < points; ++p) {
			int32_t k = weld->point_first[p];
			entries += weights->offsets[k + 1] - weights->offsets[k];
		}
		r_mesh->weight_offsets = malloc(sizeof(int32_t) * ((size_t)points + 1));
		r_mesh->weight_bones = malloc(sizeof(int32_t) * (size_t)(entries > 0 ? entries : 1));
		r_mesh->weight_values = malloc(sizeof(float) * (size_t)(entries > 0 ? entries : 1));
		if (!r_mesh->weight_offsets || !r_mesh->weight_bones || !r_mesh->weight_values)
			goto out_of_memory;
		r_mesh->weight_offsets[0] = 0;
		for (int32_t p = 0; p < points; ++p) {
			int32_t k = weld->point_first[p], begin = weights->offsets[k], count = weights->offsets[k + 1] - begin;
			int32_t at = r_mesh->weight_offsets[p];
			memcpy(r_mesh->weight_bones + at, weights->bones + begin, sizeof(int32_t) * (size_t)count);
			memcpy(r_mesh->weight_values + at, weights->values + begin, sizeof(float) * (size_t)count);
			r_mesh->weight_offsets[p + 1] = at + count;
		}
		r_mesh->weights.offsets = r_mesh->weight_offsets;
		r_mesh->weights.bones = r_mesh->weight_bones;
		r_mesh->weights.values = r_mesh->weight_values;
	}
	return lvp_success;

out_of_memory:
	lvp__weld_free(weld);
	lvp__welded_mesh_free(r_mesh);
	return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
	                 "out of memory while finding the coincident vertices of %d vertices.", (int)vertex_count);
}

void lvp__gather(float *r_points, const lvp__weld *weld, const float *vertex_values)
{
	for (int32_t p = 0; p < weld->point_count; ++p)
		memcpy(r_points + 3 * p, vertex_values + 3 * weld->point_first[p], sizeof(float) * 3);
}

lvp_result lvp__frame_points(lvp_binding *binding, const float **positions, const float **rest_positions,
                             lvp_diagnostic *r_diag)
{
	int64_t values = (int64_t)binding->weld.caller_vertex_count * 3;
	lvp_result result = lvp__check_float_array(*positions, values, "positions", r_diag);
	if (result)
		return result;
	if (*rest_positions && (result = lvp__check_float_array(*rest_positions, values, "rest_positions", r_diag)))
		return result;
	if (!binding->weld.vertex_point)
		return lvp_success;
	lvp__gather(binding->weld.positions, &binding->weld, *positions);
	*positions = binding->weld.positions;
	if (*rest_positions) {
		lvp__gather(binding->weld.rest, &binding->weld, *rest_positions);
		*rest_positions = binding->weld.rest;
	}
	return lvp_success;
}

void lvp__weld_free(lvp__weld *weld)
{
	free(weld->vertex_point);
	free(weld->point_first);
	free(weld->copy_offsets);
	free(weld->copies);
	free(weld->positions);
	free(weld->rest);
	int32_t caller_vertex_count = weld->caller_vertex_count;
	memset(weld, 0, sizeof(*weld));
	weld->caller_vertex_count = weld->point_count = caller_vertex_count;
}

void lvp__welded_mesh_free(lvp__welded_mesh *mesh)
{
	free(mesh->positions);
	free(mesh->triangles);
	free(mesh->weight_offsets);
	free(mesh->weight_bones);
	free(mesh->weight_values);
	memset(mesh, 0, sizeof(*mesh));
}
