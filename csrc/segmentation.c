/*
 * segmentation.c - paper 5.2: regions by largest weight, the triangles sorted by region, and
 * the adjacency the other stages walk (slots, each region's corners, vertices and neighbouring
 * bones).
 */
#include "binding.h"

#include <stdlib.h>

int32_t lvp__main_bone(const lvp_binding *binding, int32_t k, float *r_max)
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
		for (int32_t e = binding->rig.weight_offsets[corners[c]]; e < binding->rig.weight_offsets[corners[c] + 1];
		     ++e) {
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
	if (!binding->mesh.slot_region) {
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
		return binding->mesh.neighbour_bones ? lvp_success
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

lvp_result lvp__build_region_corners(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t s = binding->region_count, n = binding->vertex_count;
	int32_t *seen = malloc(sizeof(int32_t) * (size_t)n);
	binding->mesh.region_corner_offsets = calloc((size_t)s + 1, sizeof(int32_t));
	if (!seen || !binding->mesh.region_corner_offsets) {
		free(seen);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	for (int pass = 0; pass < 2; ++pass) {
		int64_t count = 0;
		for (int32_t k = 0; k < n; ++k)
			seen[k] = -1;
		for (int32_t r = 0; r < s; ++r) {
			binding->mesh.region_corner_offsets[r] = (int32_t)count;
			for (int32_t i = 3 * binding->mesh.region_triangle_offsets[r];
			     i < 3 * binding->mesh.region_triangle_offsets[r + 1]; ++i) {
				int32_t k = binding->mesh.triangles[i];
				if (seen[k] == r)
					continue;
				seen[k] = r;
				if (pass)
					binding->mesh.region_corners[count] = k;
				++count;
			}
		}
		binding->mesh.region_corner_offsets[s] = (int32_t)count; /* at most 3 F, below LVP_MAX_TRIANGLES*3 */
		if (!pass && !(binding->mesh.region_corners = malloc(sizeof(int32_t) * (size_t)(count > 0 ? count : 1)))) {
			free(seen);
			return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
		}
	}
	free(seen);
	return lvp_success;
}

bool lvp__mesh_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count, f = (size_t)binding->triangle_count, s = (size_t)binding->region_count;
	lvp__mesh *mesh = &binding->mesh;
	bool ok = true;
	mesh->triangles = lvp__calloc(f * 3, sizeof(int32_t), &ok);
	mesh->triangle_original = lvp__calloc(f, sizeof(int32_t), &ok);
	mesh->triangle_region = lvp__calloc(f, sizeof(int32_t), &ok);
	mesh->region_triangle_offsets = lvp__calloc(s + 1, sizeof(int32_t), &ok);
	mesh->vertex_region = lvp__calloc(n, sizeof(int32_t), &ok);
	mesh->max_weight = lvp__calloc(n, sizeof(float), &ok);
	mesh->slot_offsets = lvp__calloc(n + 1, sizeof(int32_t), &ok);
	mesh->corner_slot = lvp__calloc(f * 3, sizeof(int32_t), &ok);
	mesh->region_vertex_offsets = lvp__calloc(s + 1, sizeof(int32_t), &ok);
	mesh->region_vertices = lvp__calloc(n, sizeof(int32_t), &ok);
	return ok;
}

void lvp__mesh_free(lvp__mesh *mesh)
{
	void *arrays[] = {mesh->triangles, mesh->triangle_original, mesh->triangle_region,
	                  mesh->region_triangle_offsets, mesh->vertex_region, mesh->max_weight, mesh->slot_offsets,
	                  mesh->slot_region, mesh->corner_slot, mesh->vertex_corner_offsets, mesh->vertex_triangles,
	                  mesh->vertex_corner_slot, mesh->region_corner_offsets, mesh->region_corners,
	                  mesh->region_vertex_offsets, mesh->region_vertices, mesh->neighbour_offsets,
	                  mesh->neighbour_bones};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
