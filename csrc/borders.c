/*
 * borders.c - the borders of each region, where its side quads do not cancel (paper 5.2, see
 * local_volume.c), and the mesh's own holes: the surplus half-edges of the whole mesh, capped by
 * cones so that the volume of an open mesh does not depend on the origin.
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

/* Half-edge key: (lo, hi, direction), direction 1 when the half-edge runs hi -> lo. */
static inline uint64_t lvp__edge_key(int32_t a, int32_t b)
{
	uint64_t lo = (uint64_t)(a < b ? a : b), hi = (uint64_t)(a < b ? b : a);
	return (lo << 27 | hi) << 1 | (uint64_t)(a > b);
}

/* The half-edges of triangles [begin, end) whose side quads do not cancel: equal numbers of
 * opposite half-edges between two vertices cancel pairwise, the surplus keeps its quads. Writes
 * them (a, b per half-edge) to r_edges and returns their number; *r_unpaired receives one edge
 * that is not exactly one half-edge each way (a hole or a non-manifold edge), or -1s; *r_flipped
 * (when not NULL) the number of edges with two half-edges the same way (two triangles wound
 * against each other: their normals disagree). */
static int32_t lvp__surplus_half_edges(int32_t *r_edges, int32_t r_unpaired[2], int32_t *r_flipped,
                                       const int32_t *triangles, int32_t begin, int32_t end, uint64_t *keys)
{
	int32_t count = 0, written = 0;
	r_unpaired[0] = r_unpaired[1] = -1;
	for (int32_t t = begin; t < end; ++t)
		for (int c = 0; c < 3; ++c) {
			int32_t a = triangles[3 * t + c], b = triangles[3 * t + (c + 1) % 3];
			if (a != b) /* a collapsed edge has a flat side quad */
				keys[count++] = lvp__edge_key(a, b);
		}
	qsort(keys, (size_t)count, sizeof(uint64_t), lvp__compare_u64);
	for (int32_t i = 0; i < count;) {
		uint64_t edge = keys[i] >> 1;
		int32_t forward = 0, backward = 0, j = i;
		for (; j < count && keys[j] >> 1 == edge; ++j)
			(keys[j] & 1) ? ++backward : ++forward;
		int32_t lo = (int32_t)(edge >> 27), hi = (int32_t)(edge & ((1u << 27) - 1));
		if (forward != 1 || backward != 1) {
			r_unpaired[0] = lo;
			r_unpaired[1] = hi;
		}
		if (r_flipped && forward + backward == 2 && forward != backward)
			++*r_flipped;
		int32_t surplus = forward > backward ? forward - backward : backward - forward;
		for (int32_t m = 0; m < surplus; ++m) {
			r_edges[2 * written] = forward > backward ? lo : hi;
			r_edges[2 * written + 1] = forward > backward ? hi : lo;
			++written;
		}
		i = j;
	}
	return written;
}

/* Sorts the cap edges by the part of their hole (binding.h, cap_part_offsets): a stable
 * counting sort by the part of their first vertex. */
static lvp_result lvp__sort_caps_by_part(lvp_binding *binding)
{
	int32_t parts = binding->parts.count, count = binding->borders.cap_edge_count;
	int32_t *offsets = binding->borders.cap_part_offsets;
	memset(offsets, 0, sizeof(int32_t) * ((size_t)parts + 1));
	if (!binding->parts.vertex_part) {
		offsets[parts] = count;
		return lvp_success;
	}
	int32_t *sorted = malloc(sizeof(int32_t) * 2 * (size_t)(count > 0 ? count : 1));
	if (!sorted)
		return lvp_error_out_of_memory;
	for (int32_t i = 0; i < count; ++i)
		++offsets[binding->parts.vertex_part[binding->borders.cap_edges[2 * i]] + 1];
	for (int32_t p = 0; p < parts; ++p)
		offsets[p + 1] += offsets[p];
	for (int32_t i = 0; i < count; ++i) {
		int32_t at = offsets[binding->parts.vertex_part[binding->borders.cap_edges[2 * i]]]++;
		sorted[2 * at] = binding->borders.cap_edges[2 * i];
		sorted[2 * at + 1] = binding->borders.cap_edges[2 * i + 1];
	}
	for (int32_t p = parts; p > 0; --p)
		offsets[p] = offsets[p - 1];
	offsets[0] = 0;
	free(binding->borders.cap_edges);
	binding->borders.cap_edges = sorted;
	return lvp_success;
}

lvp_result lvp__build_borders(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t s = binding->region_count, f = binding->triangle_count;
	size_t capacity = (size_t)f * 3;
	uint64_t *keys = malloc(sizeof(uint64_t) * capacity);
	binding->borders.offsets = calloc((size_t)s + 1, sizeof(int32_t));
	/* At most every half-edge is a border; shrunk below once counted. */
	binding->borders.edges = malloc(sizeof(int32_t) * 2 * capacity);
	binding->borders.cap_edges = malloc(sizeof(int32_t) * 2 * capacity);
	if (!keys || !binding->borders.offsets || !binding->borders.edges || !binding->borders.cap_edges) {
		free(keys);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	/* The mesh's own holes, capped for the volume statistics and the final global step. */
	int32_t unpaired[2];
	binding->borders.flipped_edge_count = 0;
	binding->borders.cap_edge_count =
	    lvp__surplus_half_edges(binding->borders.cap_edges, unpaired, &binding->borders.flipped_edge_count,
	                            binding->mesh.triangles, 0, f, keys);
	if (binding->mode == LVP_MODE_GLOBAL && unpaired[0] >= 0) {
		free(keys);
		return lvp__fail(r_diag, lvp_error_mesh_not_closed, "triangles", -1,
		                 "the edge between vertices %d and %d is not shared by exactly two triangles of opposite "
		                 "orientation; the global mode needs a closed, consistently oriented mesh (fill the holes "
		                 "and recalculate normals, or use the local mode).",
		                 (int)unpaired[0], (int)unpaired[1]);
	}
	int32_t written = 0;
	for (int32_t r = 0; r < s; ++r) {
		binding->borders.offsets[r] = written;
		written += lvp__surplus_half_edges(binding->borders.edges + 2 * written, unpaired, NULL,
		                                   binding->mesh.triangles, binding->mesh.region_triangle_offsets[r],
		                                   binding->mesh.region_triangle_offsets[r + 1], keys);
	}
	binding->borders.offsets[s] = written;
	free(keys);
	int32_t *shrunk = realloc(binding->borders.edges, sizeof(int32_t) * 2 * (size_t)(written > 0 ? written : 1));
	if (shrunk)
		binding->borders.edges = shrunk;
	shrunk = realloc(binding->borders.cap_edges,
	                 sizeof(int32_t) * 2 *
	                     (size_t)(binding->borders.cap_edge_count > 0 ? binding->borders.cap_edge_count : 1));
	if (shrunk)
		binding->borders.cap_edges = shrunk;
	if (lvp__sort_caps_by_part(binding) != lvp_success)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	/* Each border end's slot for the region (it is on one of the region's triangles, so it has one). */
	binding->borders.slots = malloc(sizeof(int32_t) * 2 * (size_t)(written > 0 ? written : 1));
	binding->borders.gradient = calloc((size_t)6 * (size_t)(written > 0 ? written : 1), sizeof(float));
	binding->borders.rest = malloc(sizeof(lvp__vec3) * 2 * (size_t)(written > 0 ? written : 1));
	if (!binding->borders.slots || !binding->borders.gradient || !binding->borders.rest)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	for (int32_t r = 0; r < s; ++r)
		for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i)
			for (int end = 0; end < 2; ++end)
				binding->borders.slots[2 * i + end] = lvp__find_slot(binding, binding->borders.edges[2 * i + end], r);
	return lvp_success;
}

/* 6 times the volume of the cones from the mesh's holes to one apex (the mean of the hole
 * vertices): added to the divergence sum, it closes the surface, so the volume of an open
 * mesh no longer depends on the origin. Zero for closed meshes. */
/* 6 x the volume of the cones from the mean of their first vertices to cap edges [begin, end). */
double lvp__cap_range_volume6(const lvp_binding *binding, const float *positions, int32_t begin, int32_t end)
{
	if (end <= begin)
		return 0.0;
	lvp__vec3 apex = lvp__v(0.0, 0.0, 0.0);
	for (int32_t i = begin; i < end; ++i)
		apex = lvp__add(apex, lvp__load(positions + 3 * binding->borders.cap_edges[2 * i]));
	apex = lvp__scale(apex, 1.0 / (end - begin));
	double volume6 = 0.0;
	for (int32_t i = begin; i < end; ++i) {
		lvp__vec3 a = lvp__load(positions + 3 * binding->borders.cap_edges[2 * i]);
		lvp__vec3 b = lvp__load(positions + 3 * binding->borders.cap_edges[2 * i + 1]);
		volume6 += lvp__vol6(b, a, apex);
	}
	return volume6;
}

double lvp__cap_volume6(const lvp_binding *binding, const float *positions)
{
	return lvp__cap_range_volume6(binding, positions, 0, binding->borders.cap_edge_count);
}

double lvp__volume_of(const lvp_binding *binding, const float *positions)
{
	/* About the origin, like lvp_mesh_volume() and the per-frame statistics (open meshes). */
	lvp__vec3 o = lvp__v(0.0, 0.0, 0.0);
	double volume6 = 0.0;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		lvp__vec3 p0 = lvp__sub(lvp__load(positions + 3 * binding->mesh.triangles[3 * t]), o);
		lvp__vec3 p1 = lvp__sub(lvp__load(positions + 3 * binding->mesh.triangles[3 * t + 1]), o);
		lvp__vec3 p2 = lvp__sub(lvp__load(positions + 3 * binding->mesh.triangles[3 * t + 2]), o);
		volume6 += lvp__vol6(p0, p1, p2);
	}
	return (volume6 + lvp__cap_volume6(binding, positions)) / 6.0;
}

void lvp__volumes_of_parts(const lvp_binding *binding, const float *positions, double *r_volumes)
{
	if (binding->parts.count == 1) {
		r_volumes[0] = lvp__volume_of(binding, positions);
		return;
	}
	memset(r_volumes, 0, sizeof(double) * (size_t)binding->parts.count);
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		lvp__vec3 p0 = lvp__load(positions + 3 * binding->mesh.triangles[3 * t]);
		lvp__vec3 p1 = lvp__load(positions + 3 * binding->mesh.triangles[3 * t + 1]);
		lvp__vec3 p2 = lvp__load(positions + 3 * binding->mesh.triangles[3 * t + 2]);
		r_volumes[lvp__region_part(binding, binding->mesh.triangle_region[t])] += lvp__vol6(p0, p1, p2);
	}
	const int32_t *caps = binding->borders.cap_part_offsets;
	for (int32_t p = 0; p < binding->parts.count; ++p)
		r_volumes[p] = (r_volumes[p] + lvp__cap_range_volume6(binding, positions, caps[p], caps[p + 1])) / 6.0;
}

/* The rest side of each border half-edge's side quad at `rest` (binding.h, borders.rest): the
 * same for every measurement of a frame. Regions without borders are skipped before their rest
 * frame is looked at: the global mode's one region has none, nor, without a skeleton, a frame. */
static void lvp__border_rest(lvp_binding *binding, const float *rest)
{
	for (int32_t r = 0; r < binding->region_count; ++r) {
		if (binding->borders.offsets[r + 1] == binding->borders.offsets[r])
			continue;
		const lvp__mat4 *to_local = &binding->rig.rest_inverse[r];
		for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i) {
			lvp__vec3 a = lvp__transform_point(to_local, lvp__load(rest + 3 * binding->borders.edges[2 * i]));
			lvp__vec3 b = lvp__transform_point(to_local, lvp__load(rest + 3 * binding->borders.edges[2 * i + 1]));
			binding->borders.rest[2 * i] = lvp__add(a, b);
			binding->borders.rest[2 * i + 1] = lvp__cross(a, b);
		}
	}
}

void lvp__borders_rest(lvp_binding *binding, const float *rest_positions)
{
	if (rest_positions) {
		lvp__border_rest(binding, rest_positions);
		binding->borders.rest_is_bind = false;
	} else if (!binding->borders.rest_is_bind) {
		lvp__border_rest(binding, binding->rest_positions);
		binding->borders.rest_is_bind = true;
	}
}

bool lvp__borders_alloc(lvp_binding *binding)
{
	bool ok = true;
	binding->borders.cap_part_offsets = lvp__calloc((size_t)binding->parts.count + 1, sizeof(int32_t), &ok);
	return ok;
}

void lvp__borders_free(lvp__borders *borders)
{
	free(borders->offsets);
	free(borders->edges);
	free(borders->slots);
	free(borders->gradient);
	free(borders->rest);
	free(borders->cap_edges);
	free(borders->cap_part_offsets);
}
