/*
 * test_subdivide.c - midpoint subdivision of a skinned mesh, to make the benchmark's large
 * meshes from real ones (the giraffe at 100k and 1M vertices).
 */
#include "test_meshes.h"

#include <stdlib.h>
#include <string.h>

typedef struct edge_entry {
	int64_t key;
	int32_t vertex;
} edge_entry;

static int compare_entries(const void *a, const void *b)
{
	int64_t x = ((const edge_entry *)a)->key, y = ((const edge_entry *)b)->key;
	return (x > y) - (x < y);
}

static int32_t find_midpoint(const edge_entry *entries, int32_t count, int64_t key)
{
	int32_t lo = 0, hi = count - 1;
	while (lo <= hi) {
		int32_t mid = (lo + hi) / 2;
		if (entries[mid].key == key)
			return entries[mid].vertex;
		if (entries[mid].key < key)
			lo = mid + 1;
		else
			hi = mid - 1;
	}
	return -1;
}

static int64_t edge_key(int32_t a, int32_t b)
{
	return a < b ? (int64_t)a << 32 | b : (int64_t)b << 32 | a;
}

/* Adds weight w * (bones, values of vertex k) into a small dense accumulator. */
static void accumulate(int32_t *bones, float *values, int32_t *count, const test_rig *rig, int32_t k, float w)
{
	for (int32_t e = rig->weight_offsets[k]; e < rig->weight_offsets[k + 1]; ++e) {
		int32_t i = 0;
		while (i < *count && bones[i] != rig->weight_bones[e])
			++i;
		if (i == *count) {
			bones[i] = rig->weight_bones[e];
			values[i] = 0.0f;
			++*count;
		}
		values[i] += w * rig->weight_values[e];
	}
}

static test_rig subdivide_once(const test_rig *rig)
{
	int32_t n = rig->vertex_count, f = rig->triangle_count;
	edge_entry *entries = malloc(sizeof(edge_entry) * (size_t)f * 3);
	int32_t count = 0;
	for (int32_t t = 0; t < f; ++t)
		for (int c = 0; c < 3; ++c) {
			entries[count].key = edge_key(rig->triangles[3 * t + c], rig->triangles[3 * t + (c + 1) % 3]);
			entries[count++].vertex = 0;
		}
	qsort(entries, (size_t)count, sizeof(edge_entry), compare_entries);
	int32_t unique = 0;
	for (int32_t i = 0; i < count; ++i)
		if (i == 0 || entries[i].key != entries[i - 1].key) {
			entries[unique] = entries[i];
			entries[unique].vertex = n + unique;
			++unique;
		}
	test_rig out = *rig;
	out.vertex_count = n + unique;
	out.triangle_count = 4 * f;
	out.positions = malloc(sizeof(float) * 3 * (size_t)out.vertex_count);
	out.triangles = malloc(sizeof(int32_t) * 3 * (size_t)out.triangle_count);
	memcpy(out.positions, rig->positions, sizeof(float) * 3 * (size_t)n);
	/* weights: every old vertex keeps its row, every midpoint averages its edge's two rows */
	int32_t capacity = rig->weight_offsets[n];
	for (int32_t i = 0; i < unique; ++i) {
		int32_t a = (int32_t)(entries[i].key >> 32), b = (int32_t)(entries[i].key & 0xffffffff);
		capacity += rig->weight_offsets[a + 1] - rig->weight_offsets[a] + rig->weight_offsets[b + 1] -
		            rig->weight_offsets[b];
	}
	int32_t *bones = malloc(sizeof(int32_t) * (size_t)rig->bone_count);
	float *values = malloc(sizeof(float) * (size_t)rig->bone_count);
	out.weight_offsets = malloc(sizeof(int32_t) * ((size_t)out.vertex_count + 1));
	out.weight_bones = malloc(sizeof(int32_t) * (size_t)capacity);
	out.weight_values = malloc(sizeof(float) * (size_t)capacity);
	memcpy(out.weight_offsets, rig->weight_offsets, sizeof(int32_t) * ((size_t)n + 1));
	memcpy(out.weight_bones, rig->weight_bones, sizeof(int32_t) * (size_t)rig->weight_offsets[n]);
	memcpy(out.weight_values, rig->weight_values, sizeof(float) * (size_t)rig->weight_offsets[n]);
	int32_t written = rig->weight_offsets[n];
	for (int32_t i = 0; i < unique; ++i) {
		int32_t a = (int32_t)(entries[i].key >> 32), b = (int32_t)(entries[i].key & 0xffffffff);
		for (int c = 0; c < 3; ++c)
			out.positions[3 * (n + i) + c] = 0.5f * (rig->positions[3 * a + c] + rig->positions[3 * b + c]);
		int32_t row = 0;
		accumulate(bones, values, &row, rig, a, 0.5f);
		accumulate(bones, values, &row, rig, b, 0.5f);
		memcpy(out.weight_bones + written, bones, sizeof(int32_t) * (size_t)row);
		memcpy(out.weight_values + written, values, sizeof(float) * (size_t)row);
		written += row;
		out.weight_offsets[n + i + 1] = written;
	}
	for (int32_t t = 0; t < f; ++t) {
		const int32_t *v = rig->triangles + 3 * t;
		int32_t m[3];
		for (int c = 0; c < 3; ++c)
			m[c] = find_midpoint(entries, unique, edge_key(v[c], v[(c + 1) % 3]));
		int32_t *o = out.triangles + 12 * t;
		int32_t corners[12] = {v[0], m[0], m[2], v[1], m[1], m[0], v[2], m[2], m[1], m[0], m[1], m[2]};
		memcpy(o, corners, sizeof(corners));
	}
	free(entries);
	free(bones);
	free(values);
	/* the skeleton is shared: copy it so that each rig owns its arrays */
	size_t b = (size_t)rig->bone_count;
	out.rest_matrices = malloc(sizeof(float) * 16 * b);
	out.heads = malloc(sizeof(float) * 3 * b);
	out.tails = malloc(sizeof(float) * 3 * b);
	out.parents = malloc(sizeof(int32_t) * b);
	memcpy(out.rest_matrices, rig->rest_matrices, sizeof(float) * 16 * b);
	memcpy(out.heads, rig->heads, sizeof(float) * 3 * b);
	memcpy(out.tails, rig->tails, sizeof(float) * 3 * b);
	memcpy(out.parents, rig->parents, sizeof(int32_t) * b);
	if (rig->names) {
		out.names = malloc(sizeof(*rig->names) * b);
		memcpy(out.names, rig->names, sizeof(*rig->names) * b);
	}
	return out;
}

test_rig test_subdivide(const test_rig *rig, int levels)
{
	test_rig current = subdivide_once(rig);
	for (int level = 1; level < levels; ++level) {
		test_rig next = subdivide_once(&current);
		test_rig_free(&current);
		current = next;
	}
	return current;
}
