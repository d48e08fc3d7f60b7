/*
 * offset_smoothing.c - the correction's offsets smoothed over the surface (lvp.h, OFFSET SMOOTHING;
 * docs/method.md, Smoothing the offsets). Each vertex moves along its own normal, and where the
 * skin folds (the inside of a finger closing, a palm under bent fingers) neighbouring normals
 * differ by tens of degrees: offsets of the same size along them open creases between the
 * vertices. A pass gives each vertex that can move half its own offset and half the mean of its
 * neighbours' (a vertex that cannot move counts with no offset), a vector mean, so directions
 * blend as sizes do; the correction then restores the volume the smoothing took.
 */
#include "binding.h"

typedef struct lvp__smoothing_pass {
	lvp_binding *binding;
	const float *positions; /* the frame's input points */
} lvp__smoothing_pass;

/* step.smoothing_offsets of the dynamic vertices in [begin, end): where the steps put them, less
 * where the skinning did. */
static void lvp__take_offsets(void *context, int32_t begin, int32_t end)
{
	const lvp__smoothing_pass *pass = context;
	lvp_binding *binding = pass->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		for (int c = 0; c < 3; ++c)
			binding->step.smoothing_offsets[3 * k + c] =
			    binding->step.positions[3 * k + c] - pass->positions[3 * k + c];
	}
}

/* One pass over the dynamic vertices in [begin, end) that can move: each reads the offsets taken
 * before the pass and writes only its own position, so the result does not depend on threads. */
static void lvp__smooth_range(void *context, int32_t begin, int32_t end)
{
	const lvp__smoothing_pass *pass = context;
	lvp_binding *binding = pass->binding;
	const lvp__mesh *mesh = &binding->mesh;
	const float *offsets = binding->step.smoothing_offsets;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		double sum[3] = {0.0, 0.0, 0.0};
		int32_t count = 0;
		/* Over the corners of its triangles: a neighbour counts once per triangle it shares with k,
		 * twice inside the surface, as the edge's two triangles weigh it. */
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
			const int32_t *corners = mesh->triangles + 3 * (int64_t)mesh->vertex_triangles[c];
			for (int i = 0; i < 3; ++i) {
				int32_t j = corners[i];
				if (j == k)
					continue;
				++count;
				if (dynamic[j])
					for (int a = 0; a < 3; ++a)
						sum[a] += offsets[3 * j + a];
			}
		}
		if (count == 0)
			continue;
		float *p = binding->step.positions + 3 * k;
		const float *own = offsets + 3 * k, *skinned = pass->positions + 3 * k;
		for (int a = 0; a < 3; ++a)
			p[a] = skinned[a] + (float)(0.5 * own[a] + 0.5 * sum[a] / count);
	}
}

void lvp__smooth_offsets(lvp_binding *binding, const float *positions, int32_t passes)
{
	lvp__smoothing_pass pass = {binding, positions};
	int32_t count = binding->dynamic.vertex_count;
	for (int32_t i = 0; i < passes; ++i) {
		lvp__parallel_for(LVP__POOL_FOR(binding, count), lvp__take_offsets, &pass, count, LVP__GRAIN);
		lvp__parallel_for(LVP__POOL_FOR(binding, count), lvp__smooth_range, &pass, count, LVP__GRAIN);
	}
}
