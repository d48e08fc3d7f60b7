/*
 * parts.c - separate parts of one mesh (a body and its clothes, limbs modelled apart, in one
 * object): regions are one per bone, so a bone's region would span every part it weights, and
 * the region's multiplier would keep the parts' summed volume while one part swells and the
 * other shrinks (the part further from the bone gets more of the organic map). Instead, every
 * connected part that bends gets its own copy of each bone it uses: an internal bone, whose
 * region is that bone's skin in that part alone (lvp.h, SEGMENTATION).
 */
#include "binding.h"

#include <stdlib.h>

/* part[k]: the smallest vertex index of k's connected part (vertices joined by triangles), or -1
 * for a vertex in no triangle. Union by smaller index, so the root of a part is its first vertex.
 * used: vertex_count bytes of scratch, left zero. */
static void lvp__connected_parts(int32_t *part, uint8_t *used, const int32_t *triangles, int32_t vertex_count,
                                 int32_t triangle_count)
{
	for (int32_t k = 0; k < vertex_count; ++k)
		part[k] = k;
	for (int32_t t = 0; t < triangle_count; ++t)
		for (int c = 1; c < 3; ++c) {
			int32_t a = lvp__union_root(part, triangles[3 * t]), b = lvp__union_root(part, triangles[3 * t + c]);
			if (a < b)
				part[b] = a;
			else if (b < a)
				part[a] = b;
		}
	for (int32_t k = 0; k < vertex_count; ++k)
		part[k] = lvp__union_root(part, k);
	/* Vertices in no triangle are their own root and no other vertex points at them. */
	for (int32_t i = 0; i < 3 * triangle_count; ++i)
		used[triangles[i]] = 1;
	for (int32_t k = 0; k < vertex_count; ++k) {
		if (!used[k])
			part[k] = -1;
		used[k] = 0;
	}
}

static uint64_t lvp__part_bone_key(int32_t part, int32_t bone)
{
	return (uint64_t)(uint32_t)part << 32 | (uint32_t)bone;
}

/* Index of key in the sorted keys[0..count), or -1. */
static int32_t lvp__find_key(const uint64_t *keys, int32_t count, uint64_t key)
{
	int32_t lo = 0, hi = count;
	while (lo < hi) {
		int32_t mid = lo + (hi - lo) / 2;
		if (keys[mid] < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo < count && keys[lo] == key ? lo : -1;
}

void lvp__parts_free(lvp__parts *parts)
{
	free(parts->weight_bones);
	free(parts->bone_source);
	free(parts->bone_part);
	free(parts->vertex_part);
	memset(parts, 0, sizeof(*parts));
}

lvp_result lvp__split_parts(lvp__parts *r_parts, const lvp_weights *weights, int32_t vertex_count,
                            const int32_t *triangles, int32_t triangle_count, int32_t bone_count, bool split,
                            lvp_diagnostic *r_diag)
{
	int32_t entries = weights->offsets[vertex_count];
	lvp__parts parts;
	memset(&parts, 0, sizeof(parts));
	parts.bone_count = bone_count;
	parts.part_count = 1;
	parts.weight_bones = malloc(sizeof(int32_t) * (size_t)(entries > 0 ? entries : 1));
	int32_t *part = malloc(sizeof(int32_t) * (size_t)vertex_count);
	int32_t *root_scratch = malloc(sizeof(int32_t) * (size_t)vertex_count); /* indexed by a part's root */
	uint8_t *bends = calloc((size_t)vertex_count, 1);
	uint64_t *keys = malloc(sizeof(uint64_t) * (size_t)(entries > 0 ? entries : 1));
	lvp_result result = lvp_success;
	if (!parts.weight_bones || !part || !root_scratch || !bends || !keys)
		goto out_of_memory;
	if (entries > 0)
		memcpy(parts.weight_bones, weights->bones, sizeof(int32_t) * (size_t)entries);
	if (!split)
		goto done;
	lvp__connected_parts(part, bends, triangles, vertex_count, triangle_count);

	/* A part bends when its vertices have weight on two bones or more; a part that one bone
	 * carries rigidly (an eye, a tooth) keeps no volume change to correct and is left alone.
	 * root_scratch: the first bone seen in each part. */
	for (int32_t k = 0; k < vertex_count; ++k)
		root_scratch[k] = -1;
	for (int32_t k = 0; k < vertex_count; ++k) {
		int32_t p = part[k];
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1] && p >= 0; ++e) {
			if (!(weights->values[e] > 0.0f))
				continue;
			if (root_scratch[p] < 0)
				root_scratch[p] = weights->bones[e];
			else if (root_scratch[p] != weights->bones[e])
				bends[p] = 1;
		}
	}
	int32_t first_bending = -1, bending = 0;
	for (int32_t k = 0; k < vertex_count; ++k)
		if (bends[k] && bending++ == 0)
			first_bending = k;
	if (bending < 2)
		goto done; /* one body: the internal bones are the caller's */

	/* The first part that bends keeps the caller's bones; every other one gets a new bone per
	 * bone it uses, numbered after the caller's in the order (part, bone), so that ties between
	 * bones still go to the lower caller index within a part (lvp.h, SEGMENTATION). */
	int32_t count = 0;
	for (int32_t k = 0; k < vertex_count; ++k) {
		int32_t p = part[k];
		if (p < 0 || !bends[p] || p == first_bending)
			continue;
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e)
			if (weights->values[e] > 0.0f)
				keys[count++] = lvp__part_bone_key(p, weights->bones[e]);
	}
	qsort(keys, (size_t)count, sizeof(uint64_t), lvp__compare_u64);
	int32_t unique = 0;
	for (int32_t i = 0; i < count; ++i)
		if (unique == 0 || keys[i] != keys[unique - 1])
			keys[unique++] = keys[i];
	/* Internal bones are bones to the rest of the core: at most LVP_MAX_BONES. Parts past that
	 * (thousands of bent hair cards) stay with the caller's bones, whole parts at a time. */
	if (bone_count + unique > LVP_MAX_BONES) {
		int32_t keep = LVP_MAX_BONES - bone_count;
		while (keep > 0 && keys[keep] >> 32 == keys[keep - 1] >> 32)
			--keep;
		unique = keep;
	}
	if (unique == 0)
		goto done;
	size_t internal = (size_t)bone_count + (size_t)unique;
	parts.bone_source = malloc(sizeof(int32_t) * internal);
	parts.bone_part = calloc(internal, sizeof(int32_t));
	parts.vertex_part = calloc((size_t)vertex_count, sizeof(int32_t));
	if (!parts.bone_source || !parts.bone_part || !parts.vertex_part)
		goto out_of_memory;
	/* Numbered parts: 0 for everything on the caller's bones, then the split parts in order.
	 * root_scratch: each split part's number (by its root), -1 elsewhere. */
	for (int32_t k = 0; k < vertex_count; ++k)
		root_scratch[k] = -1;
	for (int32_t i = 0; i < unique; ++i) {
		int32_t root = (int32_t)(keys[i] >> 32);
		if (root_scratch[root] < 0)
			root_scratch[root] = parts.part_count++;
		parts.bone_part[bone_count + i] = root_scratch[root];
		parts.bone_source[bone_count + i] = (int32_t)(keys[i] & 0xffffffffu);
	}
	for (int32_t i = 0; i < bone_count; ++i)
		parts.bone_source[i] = i;
	parts.bone_count = (int32_t)internal;
	/* Every entry of a split part, zero weights included, names its part's copy of the bone. */
	for (int32_t k = 0; k < vertex_count; ++k) {
		int32_t p = part[k];
		if (p < 0 || root_scratch[p] < 0)
			continue;
		parts.vertex_part[k] = root_scratch[p];
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e) {
			int32_t i = lvp__find_key(keys, unique, lvp__part_bone_key(p, weights->bones[e]));
			if (i >= 0)
				parts.weight_bones[e] = bone_count + i;
		}
	}
	goto done;

out_of_memory:
	result = lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	lvp__parts_free(&parts);
done:
	free(part);
	free(root_scratch);
	free(bends);
	free(keys);
	*r_parts = parts;
	return result;
}

bool lvp__part_volumes_alloc(lvp_binding *binding)
{
	size_t count = (size_t)binding->parts.count;
	lvp__part_volumes *parts = &binding->parts;
	bool ok = true;
	parts->bind_volume = lvp__calloc(count, sizeof(double), &ok);
	parts->rest_volume = lvp__calloc(count, sizeof(double), &ok);
	parts->scale = lvp__calloc(count, sizeof(double), &ok);
	parts->change = lvp__calloc(count, sizeof(double), &ok);
	parts->uniform = lvp__calloc(count, sizeof(double), &ok);
	return ok;
}

void lvp__part_volumes_free(lvp__part_volumes *parts)
{
	free(parts->region_part);
	free(parts->vertex_part);
	free(parts->bind_volume);
	free(parts->rest_volume);
	free(parts->scale);
	free(parts->change);
	free(parts->uniform);
}
