/*
 * dynamic_set.c - which triangles and vertices a mesh pass visits this frame (local_volume.c).
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

/* A triangle whose three corners are moved by bones of its region's bone's skin class alone,
 * and that the correction never moves, is where its rest triangle is, moved by that bone:
 * (p0 - o) . cr = det(L) (r0 - o_rest) . cr_rest + delta . cof(L) cr_rest, where L is the
 * bone's linear part, cof(L) = det(L) L^-T maps rest area vectors to posed ones, and delta is
 * what the rounded origin o differs from the exact posed rest origin by. So a region's static
 * triangles enter its sums through their rest sums, and a pass visits only the dynamic rest:
 * in a pose bent at a few joints, a small part of the mesh. */
typedef struct lvp__dynamic_context {
	lvp_binding *binding;
	const float *rest;
	const lvp__region_sums *rest_totals;
	bool local;
} lvp__dynamic_context;

/* First phase, per region (the last: triangles without region): whether it is static, dynamic
 * or mixed, the static flag of each triangle of a mixed one, its number of dynamic triangles
 * (in region_offsets[r + 1], summed into offsets afterwards) and its static rest sums. */
static void lvp__classify_regions(void *context, int32_t begin, int32_t end)
{
	const lvp__dynamic_context *c = context;
	lvp_binding *binding = c->binding;
	int32_t s = binding->region_count;
	for (int32_t r = begin; r < end; ++r) {
		int32_t first = binding->mesh.region_triangle_offsets[r];
		int32_t last = r < s ? binding->mesh.region_triangle_offsets[r + 1] : binding->triangle_count;
		if (!(c->local && r < s && !binding->rig.region_skipped[r])) {
			binding->dynamic.region_state[r] = LVP__REGION_DYNAMIC;
			binding->dynamic.region_offsets[r + 1] = last - first;
			if (r < s) {
				memset(&binding->dynamic.static_rest[r], 0, sizeof(lvp__region_sums));
				binding->dynamic.static_count[r] = 0;
			}
			continue;
		}
		int32_t bone_class = binding->frame_map.skin_class[r];
		bool whole_region_static = true;
		for (int32_t i = binding->mesh.region_corner_offsets[r]; i < binding->mesh.region_corner_offsets[r + 1]; ++i) {
			int32_t k = binding->mesh.region_corners[i];
			if (!lvp__carried_rigidly(binding, k, bone_class)) {
				whole_region_static = false;
				break;
			}
		}
		if (whole_region_static) { /* the bone carries the region rigidly: nothing to visit */
			binding->dynamic.region_state[r] = LVP__REGION_STATIC;
			binding->dynamic.region_offsets[r + 1] = 0;
			binding->dynamic.static_rest[r] = c->rest_totals[r];
			binding->dynamic.static_count[r] = last - first;
			continue;
		}
		/* The dynamic triangles' rest terms, subtracted from the totals below: in float, like
		 * the posed terms of the passes, about the rounded origin, then moved to the exact one. */
		lvp__vec3 o_exact = lvp__rest_origin(binding, r);
		float o[3] = {(float)o_exact.x, (float)o_exact.y, (float)o_exact.z};
		double volume6 = 0.0, ax = 0.0, ay = 0.0, az = 0.0;
		int32_t dynamic = 0;
		for (int32_t t = first; t < last; ++t) {
			const int32_t *corners = binding->mesh.triangles + 3 * t;
			bool is_static = true;
			for (int i = 0; i < 3 && is_static; ++i)
				is_static = lvp__carried_rigidly(binding, corners[i], bone_class);
			binding->dynamic.triangle_static[t] = is_static;
			if (is_static)
				continue;
			++dynamic;
			float cr[3];
			volume6 += lvp__triangle_cross(cr, c->rest, corners, o);
			ax += cr[0];
			ay += cr[1];
			az += cr[2];
		}
		lvp__vec3 area = lvp__v(ax, ay, az);
		volume6 += lvp__dot(lvp__sub(lvp__v(o[0], o[1], o[2]), o_exact), area);
		binding->dynamic.region_state[r] = LVP__REGION_MIXED;
		binding->dynamic.region_offsets[r + 1] = dynamic;
		/* static = all - dynamic; none static: exactly zero, not the rounding of a difference */
		int32_t statics = (last - first) - dynamic;
		const lvp__region_sums *total = &c->rest_totals[r];
		lvp__region_sums *sums = &binding->dynamic.static_rest[r];
		binding->dynamic.static_count[r] = statics;
		sums->volume6 = statics ? total->volume6 - volume6 : 0.0;
		sums->area6[0] = statics ? total->area6[0] - area.x : 0.0;
		sums->area6[1] = statics ? total->area6[1] - area.y : 0.0;
		sums->area6[2] = statics ? total->area6[2] - area.z : 0.0;
	}
}

/* Second phase, per region: its dynamic triangles, in order, from its offset on. */
static void lvp__list_dynamic_triangles(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = ((const lvp__dynamic_context *)context)->binding;
	int32_t s = binding->region_count;
	for (int32_t r = begin; r < end; ++r) {
		int32_t first = binding->mesh.region_triangle_offsets[r];
		int32_t last = r < s ? binding->mesh.region_triangle_offsets[r + 1] : binding->triangle_count;
		int32_t *out = binding->dynamic.triangles + binding->dynamic.region_offsets[r];
		if (binding->dynamic.region_state[r] == LVP__REGION_DYNAMIC) {
			for (int32_t t = first; t < last; ++t)
				*out++ = t;
		} else if (binding->dynamic.region_state[r] == LVP__REGION_MIXED) {
			for (int32_t t = first; t < last; ++t)
				if (!binding->dynamic.triangle_static[t])
					*out++ = t;
		}
	}
}

void lvp__find_dynamic_set(lvp_binding *binding, const float *rest_positions, const lvp__region_sums *rest_totals,
                      bool all_dynamic)
{
	int32_t s = binding->region_count;
	bool local = binding->mode == LVP_MODE_LOCAL && !all_dynamic;
	/* From the bind rest, the set depends only on vertex_dynamic, vertex_class, skin_class and
	 * region_skipped; whatever changes one of them marks the set stale. In an animation
	 * the same bones move from frame to frame, so the set is usually last frame's. */
	bool reusable = local && !rest_positions;
	if (reusable && binding->dynamic.current)
		return;
	binding->dynamic.current = false;
	if (!local) {
		lvp__make_all_dynamic(binding);
	}
	lvp__dynamic_context context = {binding, rest_positions ? rest_positions : binding->rest_positions, rest_totals,
	                                local};
	lvp__pool *pool = LVP__POOL_FOR(binding, binding->triangle_count);
	lvp__parallel_for(pool, lvp__classify_regions, &context, s + 1, 1);
	binding->dynamic.region_offsets[0] = 0;
	for (int32_t r = 0; r <= s; ++r)
		binding->dynamic.region_offsets[r + 1] += binding->dynamic.region_offsets[r];
	lvp__parallel_for(pool, lvp__list_dynamic_triangles, &context, s + 1, 1);
	int32_t vertices = 0;
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		if (binding->frame_map.vertex_dynamic[k])
			binding->dynamic.vertices[vertices++] = k;
	binding->dynamic.vertex_count = vertices;
	binding->dynamic.current = reusable;
}

void lvp__dynamic_set_stale(lvp_binding *binding)
{
	binding->dynamic.current = false;
}

bool lvp__dynamic_set_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count, f = (size_t)binding->triangle_count, s = (size_t)binding->region_count;
	lvp__dynamic_set *dynamic = &binding->dynamic;
	bool ok = true;
	dynamic->triangles = lvp__calloc(f, sizeof(int32_t), &ok);
	dynamic->region_offsets = lvp__calloc(s + 2, sizeof(int32_t), &ok);
	dynamic->region_state = lvp__calloc(s + 1, sizeof(uint8_t), &ok);
	dynamic->triangle_static = lvp__calloc(f, sizeof(uint8_t), &ok);
	dynamic->vertices = lvp__calloc(n, sizeof(int32_t), &ok);
	dynamic->static_rest = lvp__calloc(s, sizeof(lvp__region_sums), &ok);
	dynamic->static_count = lvp__calloc(s, sizeof(int32_t), &ok);
	return ok;
}

void lvp__dynamic_set_free(lvp__dynamic_set *dynamic)
{
	free(dynamic->triangles);
	free(dynamic->region_offsets);
	free(dynamic->region_state);
	free(dynamic->triangle_static);
	free(dynamic->vertices);
	free(dynamic->static_rest);
	free(dynamic->static_count);
}
