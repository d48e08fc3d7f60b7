/*
 * local_volume.c - paper 5.2: the volume change of each region, as the sum of the prisms
 * spanned by its rest and deformed triangles in the local frame of the region's bone, the
 * side quads split in four at their centroid (Botsch and Kobbelt 2003). Also the mesh pass
 * (3.1) that every correction iteration starts with: normals, gradients, region sums.
 *
 * Why it is cheap: a prism's volume is that of its closed surface (divergence formula): top
 * (deformed) triangle, bottom (rest) triangle reversed, and three side quads. Summed over a
 * region, the side quads of an edge shared by two triangles of the region are the same four
 * points in opposite orders and cancel exactly, so only the region's border edges are
 * visited. The tops are summed in world space and moved into the bone frame in closed form:
 * with T the posed bone frame (translation t), sum q_i . (q_j x q_k) over the local corners
 * q = T^-1 p equals sum (p_i - t) . ((p_j - p_i) x (p_k - p_i)) / det(T). The bottoms are a
 * rest constant.
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

/* ---- the mesh pass ------------------------------------------------------------------------ */

/* The origin of region r's bone frame this frame (global mode: the rest centroid). */
static lvp__vec3 lvp__posed_origin(const lvp_binding *binding, int32_t r)
{
	if (binding->mode != LVP_MODE_LOCAL)
		return binding->measure.global_origin;
	const double *m = binding->rig.posed[r].m;
	return lvp__v(m[3], m[7], m[11]);
}

/* The origin region's sums are taken about in the last mesh pass (0 for the triangles without
 * region). */
static lvp__vec3 lvp__region_origin(const lvp_binding *binding, int32_t region)
{
	if (region < 0)
		return lvp__v(0.0, 0.0, 0.0);
	return binding->measure.origin[region];
}


/* The same with cr / 6 (each corner's share of the gradient). */
static inline double lvp__triangle_terms(float r_gradient[3], const float *positions, const int32_t *corners,
                                         const float *o)
{
	double volume6 = lvp__triangle_cross(r_gradient, positions, corners, o);
	r_gradient[0] *= 1.0f / 6.0f;
	r_gradient[1] *= 1.0f / 6.0f;
	r_gradient[2] *= 1.0f / 6.0f;
	return volume6;
}

/* Vertex k's normal and g from its volume gradient (gx, gy, gz): its direction, and its length,
 * <n_k, grad_k V> = |grad_k V|. */
static inline void lvp__set_normal(lvp_binding *binding, int32_t k, float gx, float gy, float gz)
{
	float length = sqrtf(gx * gx + gy * gy + gz * gz);
	float inverse = length > 0.0f ? 1.0f / length : 0.0f;
	binding->measure.normals[3 * k] = gx * inverse;
	binding->measure.normals[3 * k + 1] = gy * inverse;
	binding->measure.normals[3 * k + 2] = gz * inverse;
	binding->measure.vertex_g[k] = length;
}

/* The sum of the last mesh pass's gradients of the triangles around vertex k, into r_g. */
static inline void lvp__gather_gradient(const lvp_binding *binding, int32_t k, float r_g[3])
{
	const float *triangle_gradient = binding->measure.triangle_gradient;
	float gx = 0.0f, gy = 0.0f, gz = 0.0f;
	for (int32_t i = binding->mesh.vertex_corner_offsets[k]; i < binding->mesh.vertex_corner_offsets[k + 1]; ++i) {
		const float *g = triangle_gradient + 3 * binding->mesh.vertex_triangles[i];
		gx += g[0];
		gy += g[1];
		gz += g[2];
	}
	r_g[0] = gx;
	r_g[1] = gy;
	r_g[2] = gz;
}

/* Normal, g and the slots' <n, gradient> of vertex k from its slot gradients. */
static inline void lvp__vertex_terms(lvp_binding *binding, int32_t k)
{
	const float *slot_gradient = binding->measure.slot_gradient;
	int32_t first = binding->mesh.slot_offsets[k], last = binding->mesh.slot_offsets[k + 1];
	float gx = 0.0f, gy = 0.0f, gz = 0.0f;
	for (int32_t i = first; i < last; ++i) {
		gx += slot_gradient[3 * i];
		gy += slot_gradient[3 * i + 1];
		gz += slot_gradient[3 * i + 2];
	}
	lvp__set_normal(binding, k, gx, gy, gz);
	const float *n = binding->measure.normals + 3 * k;
	for (int32_t i = first; i < last; ++i)
		binding->measure.slot_g[i] =
		    n[0] * slot_gradient[3 * i] + n[1] * slot_gradient[3 * i + 1] + n[2] * slot_gradient[3 * i + 2];
}


/* 6 x the rest volume term of triangle t about o, and its cr. */
static double lvp__rest_terms(lvp__vec3 *r_area6, const float *rest, const int32_t *corners, lvp__vec3 o)
{
	lvp__vec3 p0 = lvp__load(rest + 3 * corners[0]);
	lvp__vec3 p1 = lvp__load(rest + 3 * corners[1]);
	lvp__vec3 p2 = lvp__load(rest + 3 * corners[2]);
	*r_area6 = lvp__cross(lvp__sub(p1, p0), lvp__sub(p2, p0));
	return lvp__dot(lvp__sub(p0, o), *r_area6);
}
/* The static triangles' part of region r's sums this frame (see lvp__find_dynamic_set). */
static void lvp__add_static_part(lvp_binding *binding, int32_t r, double *r_volume6, double r_area6[3])
{
	const lvp__region_sums *rest = &binding->dynamic.static_rest[r];
	const double *m = binding->rig.skin[r].m;
	/* cof(L): columns c1 x c2, c2 x c0, c0 x c1 of L's columns c0, c1, c2 */
	lvp__vec3 c0 = lvp__v(m[0], m[4], m[8]), c1 = lvp__v(m[1], m[5], m[9]), c2 = lvp__v(m[2], m[6], m[10]);
	lvp__vec3 k0 = lvp__cross(c1, c2), k1 = lvp__cross(c2, c0), k2 = lvp__cross(c0, c1);
	lvp__vec3 area = lvp__add(lvp__add(lvp__scale(k0, rest->area6[0]), lvp__scale(k1, rest->area6[1])),
	                          lvp__scale(k2, rest->area6[2]));
	lvp__vec3 exact_origin = lvp__transform_point(&binding->rig.skin[r], lvp__rest_origin(binding, r));
	const float *o = binding->measure.origin_float + 3 * r;
	lvp__vec3 delta = lvp__sub(exact_origin, lvp__v(o[0], o[1], o[2]));
	*r_volume6 += lvp__dot(c0, k0) * rest->volume6 + lvp__dot(delta, area);
	r_area6[0] += area.x;
	r_area6[1] += area.y;
	r_area6[2] += area.z;
}

/* The mesh pass and the vertex gradients run in loops that each write only their own outputs,
 * so they can be split over threads with results independent of the split: pieces of the
 * dynamic triangles (their terms, and the piece's sums), vertices (gradients gathered from
 * their corners; only when a correction step follows). A piece is up to LVP__GRAIN consecutive
 * dynamic triangles of one region, cut at fixed places (every LVP__GRAIN from the region's
 * first), and each region adds its pieces' sums in order: the same sums for any threads, and
 * a region larger than the others does not leave a thread idle. */
static void lvp__piece_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__loop_context *c = context;
	lvp_binding *binding = c->binding;
	const int32_t *dynamic = binding->dynamic.triangles, *triangles = binding->mesh.triangles;
	float *triangle_gradient = binding->measure.triangle_gradient,
	      *triangle_volume6 = binding->measure.triangle_volume6;
	for (int32_t piece = begin; piece < end; ++piece) {
		/* origin_float's last entry: triangles without region, origin 0 */
		const float *o = binding->measure.origin_float + 3 * binding->measure.piece_region[piece];
		double volume6 = 0.0, ax = 0.0, ay = 0.0, az = 0.0;
		for (int32_t i = binding->measure.piece_first[piece]; i < binding->measure.piece_first[piece + 1]; ++i) {
			int32_t t = dynamic[i];
			/* Summed from a local copy, not read back from the array just written: two 4-byte stores read
			 * back as one 8-byte load cannot be forwarded, and Clang's code (the shipped Linux and macOS
			 * modules) stalled there for more than half of this loop's time. */
			float g[3];
			float v = (float)lvp__triangle_terms(g, c->positions, triangles + 3 * t, o);
			triangle_gradient[3 * t] = g[0];
			triangle_gradient[3 * t + 1] = g[1];
			triangle_gradient[3 * t + 2] = g[2];
			triangle_volume6[t] = v;
			volume6 += v;
			ax += g[0];
			ay += g[1];
			az += g[2];
		}
		lvp__region_sums *sums = &binding->measure.piece_sums[piece];
		sums->volume6 = volume6;
		sums->area6[0] = ax; /* the sums of cr / 6, times 6 per region below */
		sums->area6[1] = ay;
		sums->area6[2] = az;
	}
}

/* The pieces of this frame's dynamic triangles (see above). */
static void lvp__cut_pieces(lvp_binding *binding)
{
	int32_t count = 0;
	for (int32_t r = 0; r <= binding->region_count; ++r)
		for (int32_t i = binding->dynamic.region_offsets[r]; i < binding->dynamic.region_offsets[r + 1];
		     i += LVP__GRAIN) {
			binding->measure.piece_first[count] = i;
			binding->measure.piece_region[count++] = r;
		}
	binding->measure.piece_first[count] = binding->dynamic.region_offsets[binding->region_count + 1];
	binding->measure.piece_count = count;
}

/* Each region's sums: its pieces' in order, and its static triangles'. */
static void lvp__region_sums_from_pieces(lvp_binding *binding)
{
	int32_t s = binding->region_count, piece = 0;
	for (int32_t r = 0; r <= s; ++r) {
		double volume6 = 0.0, ax = 0.0, ay = 0.0, az = 0.0;
		for (; piece < binding->measure.piece_count && binding->measure.piece_region[piece] == r; ++piece) {
			const lvp__region_sums *sums = &binding->measure.piece_sums[piece];
			volume6 += sums->volume6;
			ax += sums->area6[0];
			ay += sums->area6[1];
			az += sums->area6[2];
		}
		double area6[3] = {6.0 * ax, 6.0 * ay, 6.0 * az};
		if (r < s && binding->dynamic.static_count[r] > 0)
			lvp__add_static_part(binding, r, &volume6, area6);
		binding->measure.sums[r].volume6 = volume6;
		memcpy(binding->measure.sums[r].area6, area6, sizeof(area6));
	}
}

/* Every triangle around a dynamic vertex is dynamic, so its gradients are complete. Only the
 * vertices that can move need them: a step reads no other vertex's normal or g. */
static void lvp__vertex_loop(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = ((lvp__loop_context *)context)->binding;
	float *slot_gradient = binding->measure.slot_gradient;
	const float *triangle_gradient = binding->measure.triangle_gradient;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		int32_t first = binding->mesh.vertex_corner_offsets[k], last = binding->mesh.vertex_corner_offsets[k + 1];
		int32_t slot_first = binding->mesh.slot_offsets[k];
		if (binding->mesh.slot_offsets[k + 1] - slot_first == 1) {
			lvp__gather_gradient(binding, k, slot_gradient + 3 * slot_first); /* inside a region: one slot */
		} else {
			for (int32_t slot = slot_first; slot < binding->mesh.slot_offsets[k + 1]; ++slot)
				slot_gradient[3 * slot] = slot_gradient[3 * slot + 1] = slot_gradient[3 * slot + 2] = 0.0f;
			for (int32_t i = first; i < last; ++i) {
				const float *g = triangle_gradient + 3 * binding->mesh.vertex_triangles[i];
				float *sg = slot_gradient + 3 * binding->mesh.vertex_corner_slot[i];
				sg[0] += g[0];
				sg[1] += g[1];
				sg[2] += g[2];
			}
		}
		lvp__vertex_terms(binding, k);
	}
}

void lvp__mesh_pass(lvp_binding *binding, const float *positions)
{
	lvp__loop_context context = {binding, positions};
	/* The triangle terms are taken about float origins; every other use of the origins (the
	 * whole-mesh volume, the update pass) takes the same rounded points, so all agree exactly. */
	for (int32_t r = 0; r <= binding->region_count; ++r) {
		lvp__vec3 o = r < binding->region_count ? lvp__posed_origin(binding, r) : lvp__v(0.0, 0.0, 0.0);
		binding->measure.origin_float[3 * r] = (float)o.x;
		binding->measure.origin_float[3 * r + 1] = (float)o.y;
		binding->measure.origin_float[3 * r + 2] = (float)o.z;
		if (r < binding->region_count)
			binding->measure.origin[r] = lvp__v((float)o.x, (float)o.y, (float)o.z);
	}
	lvp__cut_pieces(binding);
	lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.region_offsets[binding->region_count + 1]),
	                  lvp__piece_loop, &context, binding->measure.piece_count, 1);
	lvp__region_sums_from_pieces(binding);
	/* gathered by lvp__vertex_gradients() or lvp__vertex_normals() when a step needs them */
	binding->measure.vertex_terms_current = binding->measure.normals_current = false;
}

void lvp__update_pass(lvp_binding *binding, const float *positions, const int32_t *moved, int32_t moved_count)
{
	/* The triangles around the moved vertices, each once. */
	int32_t dirty = 0;
	for (int32_t i = 0; i < moved_count; ++i) {
		int32_t k = moved[i];
		for (int32_t c = binding->mesh.vertex_corner_offsets[k]; c < binding->mesh.vertex_corner_offsets[k + 1]; ++c) {
			int32_t t = binding->mesh.vertex_triangles[c];
			if (!binding->measure.triangle_dirty[t]) {
				binding->measure.triangle_dirty[t] = 1;
				binding->measure.dirty_triangles[dirty++] = t;
			}
		}
	}
	/* Replace their terms in the region sums and the slot gradients. */
	int32_t touched = 0;
	for (int32_t i = 0; i < dirty; ++i) {
		int32_t t = binding->measure.dirty_triangles[i];
		binding->measure.triangle_dirty[t] = 0;
		int32_t r = binding->mesh.triangle_region[t];
		int32_t sum_index = r < 0 ? binding->region_count : r;
		float g[3];
		float *old = binding->measure.triangle_gradient + 3 * t;
		double v = lvp__triangle_terms(g, positions, binding->mesh.triangles + 3 * t,
		                               binding->measure.origin_float + 3 * sum_index);
		lvp__region_sums *sums = &binding->measure.sums[sum_index];
		sums->volume6 += v - binding->measure.triangle_volume6[t];
		float d[3] = {g[0] - old[0], g[1] - old[1], g[2] - old[2]};
		for (int c = 0; c < 3; ++c) {
			sums->area6[c] += 6.0 * d[c];
			old[c] = g[c];
		}
		binding->measure.triangle_volume6[t] = v;
		if (!binding->measure.vertex_terms_current) {
			binding->measure.normals_current = false; /* gathered afresh from the triangles when needed */
			continue;
		}
		for (int c = 0; c < 3; ++c) {
			float *sg = binding->measure.slot_gradient + 3 * binding->mesh.corner_slot[3 * t + c];
			sg[0] += d[0];
			sg[1] += d[1];
			sg[2] += d[2];
			int32_t k = binding->mesh.triangles[3 * t + c];
			if (!binding->measure.vertex_dirty[k] && lvp__can_move(binding, k)) { /* no other needs a normal */
				binding->measure.vertex_dirty[k] = 1;
				binding->measure.dirty_vertices[touched++] = k;
			}
		}
	}
	for (int32_t i = 0; i < touched; ++i) {
		int32_t k = binding->measure.dirty_vertices[i];
		binding->measure.vertex_dirty[k] = 0;
		lvp__vertex_terms(binding, k);
	}
}

double lvp__pass_volume(const lvp_binding *binding, const float *positions)
{
	double volume6 = 0.0;
	for (int32_t r = 0; r <= binding->region_count; ++r) {
		lvp__vec3 o = lvp__region_origin(binding, r < binding->region_count ? r : -1);
		const lvp__region_sums *sums = &binding->measure.sums[r];
		volume6 += sums->volume6 + o.x * sums->area6[0] + o.y * sums->area6[1] + o.z * sums->area6[2];
	}
	return (volume6 + lvp__cap_volume6(binding, positions)) / 6.0;
}

void lvp__pass_part_volumes(const lvp_binding *binding, const float *positions, double *r_volumes)
{
	if (binding->parts.count == 1) {
		r_volumes[0] = lvp__pass_volume(binding, positions);
		return;
	}
	memset(r_volumes, 0, sizeof(double) * (size_t)binding->parts.count);
	for (int32_t r = 0; r <= binding->region_count; ++r) {
		int32_t region = r < binding->region_count ? r : -1;
		lvp__vec3 o = lvp__region_origin(binding, region);
		const lvp__region_sums *sums = &binding->measure.sums[r];
		r_volumes[lvp__region_part(binding, region)] +=
		    sums->volume6 + o.x * sums->area6[0] + o.y * sums->area6[1] + o.z * sums->area6[2];
	}
	const int32_t *caps = binding->borders.cap_part_offsets;
	for (int32_t p = 0; p < binding->parts.count; ++p)
		r_volumes[p] = (r_volumes[p] + lvp__cap_range_volume6(binding, positions, caps[p], caps[p + 1])) / 6.0;
}
/* ---- rest side and region changes ----------------------------------------------------------- */

void lvp__rest_constants(lvp_binding *binding, const float *rest_positions, lvp__region_sums *r_totals)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	for (int32_t r = 0; r < binding->region_count; ++r) {
		lvp__vec3 o = lvp__rest_origin(binding, r), area = lvp__v(0.0, 0.0, 0.0);
		double volume6 = 0.0;
		for (int32_t t = binding->mesh.region_triangle_offsets[r]; t < binding->mesh.region_triangle_offsets[r + 1];
		     ++t) {
			lvp__vec3 cr;
			volume6 += lvp__rest_terms(&cr, rest, binding->mesh.triangles + 3 * t, o);
			area = lvp__add(area, cr);
		}
		r_totals[r].volume6 = volume6;
		r_totals[r].area6[0] = area.x;
		r_totals[r].area6[1] = area.y;
		r_totals[r].area6[2] = area.z;
	}
}


const lvp__region_sums *lvp__frame_rest(lvp_binding *binding, const float *rest_positions)
{
	if (rest_positions) {
		lvp__rest_constants(binding, rest_positions, binding->measure.frame_totals);
		lvp__borders_rest(binding, rest_positions);
		return binding->measure.frame_totals;
	}
	lvp__borders_rest(binding, NULL);
	return binding->measure.rest_totals;
}

void lvp__reference_volumes(lvp_binding *binding)
{
	const float *rest = binding->rest_positions;
	if (binding->mode == LVP_MODE_GLOBAL) {
		/* The whole (closed) mesh: its volume, or for a flat one the cube of its size. */
		lvp__vec3 lo = lvp__load(rest), hi = lo, centroid = lvp__v(0, 0, 0);
		double volume6 = 0.0;
		for (int32_t k = 0; k < binding->vertex_count; ++k) {
			lvp__vec3 p = lvp__load(rest + 3 * k);
			centroid = lvp__add(centroid, p);
			lo = lvp__v(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
			hi = lvp__v(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
		}
		binding->measure.global_origin = lvp__scale(centroid, 1.0 / binding->vertex_count);
		for (int32_t t = 0; t < binding->triangle_count; ++t) {
			lvp__vec3 p0 =
			    lvp__sub(lvp__load(rest + 3 * binding->mesh.triangles[3 * t]), binding->measure.global_origin);
			lvp__vec3 p1 =
			    lvp__sub(lvp__load(rest + 3 * binding->mesh.triangles[3 * t + 1]), binding->measure.global_origin);
			lvp__vec3 p2 =
			    lvp__sub(lvp__load(rest + 3 * binding->mesh.triangles[3 * t + 2]), binding->measure.global_origin);
			volume6 += lvp__vol6(p0, p1, p2);
		}
		double size = lvp__length(lvp__sub(hi, lo));
		double volume = fabs(volume6 / 6.0);
		binding->measure.reference_volume[0] = volume > 1e-6 * size * size * size ? volume : size * size * size;
		return;
	}
	/* A region is open, so it has no volume of its own: its reference is the volume of the
	 * cones from its triangles to its bone, sum area * distance(centroid, bone) / 3. */
	for (int32_t r = 0; r < binding->region_count; ++r) {
		double volume = 0.0;
		for (int32_t t = binding->mesh.region_triangle_offsets[r]; t < binding->mesh.region_triangle_offsets[r + 1];
		     ++t) {
			lvp__vec3 p0 = lvp__load(rest + 3 * binding->mesh.triangles[3 * t]);
			lvp__vec3 p1 = lvp__load(rest + 3 * binding->mesh.triangles[3 * t + 1]);
			lvp__vec3 p2 = lvp__load(rest + 3 * binding->mesh.triangles[3 * t + 2]);
			double area = 0.5 * lvp__length(lvp__cross(lvp__sub(p1, p0), lvp__sub(p2, p0)));
			lvp__vec3 centroid = lvp__scale(lvp__add(lvp__add(p0, p1), p2), 1.0 / 3.0);
			volume += area * lvp__bone_distance(binding, r, centroid) / 3.0;
		}
		binding->measure.reference_volume[r] = volume;
	}
}

typedef struct lvp__change_context {
	lvp_binding *binding;
	const float *positions;
	const lvp__region_sums *rest_totals;
	double *r_change;
} lvp__change_context;

/* What the side quads of region r's border edges are measured with this frame (lvp__border_side). */
typedef struct lvp__border_frame {
	const lvp__mat4 *to_local; /* world -> the region's bone frame */
	double gradient_scale;     /* local 6 x volume -> world, in the top part's gradient units */
	int32_t bone_class;
	lvp__vec3 origin;          /* of the region's sums (lvp__mesh_pass) */
} lvp__border_frame;

static lvp__border_frame lvp__border_frame_of(const lvp_binding *binding, int32_t r)
{
	/* side gradients: local frame, 6 x volume -> world, in the units of the top part's gradient
	 * (which the correction multiplies by kappa); q = L p => dV/dp = L^T dV/dq */
	lvp__border_frame frame = {&binding->rig.posed_inverse[r], binding->rig.rest_det[r] / binding->rig.kappa[r] / 6.0,
	                           binding->frame_map.skin_class[r], binding->measure.origin[r]};
	return frame;
}

/* 6 x the volume of the side quad over border half-edge i (local units), and with r_gradient (6
 * floats) the border terms of the region's volume gradient at its two ends. Zero, and no gradient,
 * when both ends are static with the region's bone: rest and posed edge are the same in the bone's
 * frame, the quad is flat, and neither end moves this frame. */
static inline double lvp__border_side(const lvp_binding *binding, const lvp__border_frame *frame, int32_t i,
                                      const float *positions, float *r_gradient)
{
	int32_t a = binding->borders.edges[2 * i], b = binding->borders.edges[2 * i + 1];
	if (lvp__carried_rigidly(binding, a, frame->bone_class) && lvp__carried_rigidly(binding, b, frame->bone_class))
		return 0.0;
	lvp__vec3 pa = lvp__load(positions + 3 * a), pb = lvp__load(positions + 3 * b);
	lvp__vec3 qa = lvp__transform_point(frame->to_local, pa), qb = lvp__transform_point(frame->to_local, pb);
	const lvp__vec3 *rest = binding->borders.rest + 2 * i;
	lvp__vec3 local[2];
	double side6 = lvp__side_quad6(&local[0], &local[1], qa, qb, rest[0], rest[1]);
	if (!r_gradient)
		return side6;
	/* The top's gradient was taken in its translation-invariant form, exact only where a vertex's
	 * fan is closed; on the border the fan is open and the exact gradient about the frame origin o
	 * differs by (p_k - o) x (p_end - p_start) / 6, which is this half-edge's share for both of its
	 * ends. */
	lvp__vec3 o = frame->origin;
	lvp__vec3 top_share = lvp__scale(lvp__cross(lvp__sub(pb, o), lvp__sub(pa, o)), 1.0 / 6.0);
	const double *m = frame->to_local->m;
	double scale = frame->gradient_scale;
	for (int end = 0; end < 2; ++end) {
		lvp__vec3 g = local[end];
		r_gradient[3 * end] = (float)(scale * (m[0] * g.x + m[4] * g.y + m[8] * g.z) + top_share.x);
		r_gradient[3 * end + 1] = (float)(scale * (m[1] * g.x + m[5] * g.y + m[9] * g.z) + top_share.y);
		r_gradient[3 * end + 2] = (float)(scale * (m[2] * g.x + m[6] * g.y + m[10] * g.z) + top_share.z);
	}
	return side6;
}

/* Regions [first, last): each writes only its change. */
static void lvp__region_change_loop(void *context, int32_t first, int32_t last)
{
	const lvp__change_context *c = context;
	lvp_binding *binding = c->binding;
	for (int32_t r = first; r < last; ++r) {
		if (binding->rig.region_skipped[r]) {
			c->r_change[r] = 0.0;
			continue;
		}
		/* Top part in rest-world units: kappa * sum (p_i - t) . cr / 6, kappa = det(rest)/det(posed). */
		double top = binding->rig.kappa[r] * binding->measure.sums[r].volume6 / 6.0;
		double sides6 = 0.0;
		if (binding->borders.offsets[r + 1] > binding->borders.offsets[r]) {
			lvp__border_frame frame = lvp__border_frame_of(binding, r);
			for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i)
				sides6 += lvp__border_side(binding, &frame, i, c->positions, NULL);
			/* local units -> rest-world units */
			sides6 *= binding->rig.rest_det[r];
		}
		c->r_change[r] = top + sides6 / 6.0 - c->rest_totals[r].volume6 / 6.0;
	}
}

void lvp__region_changes(lvp_binding *binding, const float *positions, const lvp__region_sums *rest_totals,
                         double *r_change)
{
	lvp__change_context context = {binding, positions, rest_totals, r_change};
	/* a border edge costs about as much as 8 triangles of the mesh pass */
	int64_t work = 8 * (int64_t)binding->borders.offsets[binding->region_count];
	lvp__parallel_for(LVP__POOL_FOR(binding, work), lvp__region_change_loop, &context, binding->region_count, 1);
}

/* Regions [first, last): the border terms of their volume gradients at step.positions
 * (borders.gradient), each region writing only its own border edges'. */
static void lvp__border_gradient_loop(void *context, int32_t first, int32_t last)
{
	lvp_binding *binding = ((lvp__loop_context *)context)->binding;
	for (int32_t r = first; r < last; ++r) {
		if (binding->rig.region_skipped[r] || binding->borders.offsets[r + 1] == binding->borders.offsets[r])
			continue;
		lvp__border_frame frame = lvp__border_frame_of(binding, r);
		for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i)
			lvp__border_side(binding, &frame, i, binding->step.positions, binding->borders.gradient + 6 * i);
	}
}

/* The border terms of the regions' volume gradients at step.positions (lvp__border_side), added to
 * the slots' <n, gradient> of the border vertices that can move (no step reads the others'). Each
 * such vertex's slots are first recomputed from its slot gradients, so that the border terms of an
 * earlier measurement are not counted again. Without them the corrections of a narrow weight band,
 * whose vertices are mostly on a region border, would be underestimated and converge slowly. */
static void lvp__add_border_gradients(lvp_binding *binding)
{
	lvp__loop_context context = {binding, NULL};
	int64_t work = 8 * (int64_t)binding->borders.offsets[binding->region_count]; /* as lvp__region_changes */
	lvp__parallel_for(LVP__POOL_FOR(binding, work), lvp__border_gradient_loop, &context, binding->region_count, 1);
	int32_t touched = 0;
	for (int32_t r = 0; r < binding->region_count; ++r) {
		if (binding->rig.region_skipped[r])
			continue;
		for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i)
			for (int end = 0; end < 2; ++end) {
				int32_t k = binding->borders.edges[2 * i + end];
				if (lvp__can_move(binding, k) && !binding->measure.vertex_dirty[k]) {
					binding->measure.vertex_dirty[k] = 1;
					binding->measure.dirty_vertices[touched++] = k;
					lvp__vertex_terms(binding, k);
				}
			}
	}
	for (int32_t r = 0; r < binding->region_count; ++r) {
		if (binding->rig.region_skipped[r])
			continue;
		for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i)
			for (int end = 0; end < 2; ++end) {
				int32_t k = binding->borders.edges[2 * i + end];
				int32_t slot = binding->borders.slots[2 * i + end];
				if (!lvp__can_move(binding, k) || slot < 0)
					continue;
				const float *n = binding->measure.normals + 3 * k, *g = binding->borders.gradient + 6 * i + 3 * end;
				binding->measure.slot_g[slot] += n[0] * g[0] + n[1] * g[1] + n[2] * g[2];
			}
	}
	for (int32_t i = 0; i < touched; ++i)
		binding->measure.vertex_dirty[binding->measure.dirty_vertices[i]] = 0;
}

/* The normals and g of the dynamic vertices [begin, end) that can move, from their triangles'
 * gradients, without the slots (lvp__vertex_normals). */
static void lvp__normal_loop(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = ((lvp__loop_context *)context)->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		float g[3];
		lvp__gather_gradient(binding, k, g);
		lvp__set_normal(binding, k, g[0], g[1], g[2]);
	}
}

void lvp__vertex_normals(lvp_binding *binding)
{
	if (binding->measure.vertex_terms_current || binding->measure.normals_current)
		return;
	lvp__loop_context context = {binding, NULL};
	lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.vertex_count), lvp__normal_loop, &context,
	                  binding->dynamic.vertex_count, LVP__GRAIN);
	binding->measure.normals_current = true;
}

void lvp__vertex_gradients(lvp_binding *binding)
{
	if (!binding->measure.vertex_terms_current) {
		lvp__loop_context context = {binding, NULL};
		lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.vertex_count), lvp__vertex_loop, &context,
		                  binding->dynamic.vertex_count, LVP__GRAIN);
		binding->measure.vertex_terms_current = binding->measure.normals_current = true;
	}
	lvp__add_border_gradients(binding);
}

bool lvp__measure_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count, f = (size_t)binding->triangle_count, s = (size_t)binding->region_count;
	size_t slots = (size_t)binding->mesh.slot_count, pieces = f / LVP__GRAIN + s + 2;
	lvp__measure *measure = &binding->measure;
	bool ok = true;
	measure->rest_totals = lvp__calloc(s, sizeof(lvp__region_sums), &ok);
	measure->frame_totals = lvp__calloc(s, sizeof(lvp__region_sums), &ok);
	measure->reference_volume = lvp__calloc(s, sizeof(double), &ok);
	measure->origin = lvp__calloc(s, sizeof(lvp__vec3), &ok);
	measure->origin_float = lvp__calloc((s + 1) * 3, sizeof(float), &ok);
	measure->sums = lvp__calloc(s + 1, sizeof(lvp__region_sums), &ok);
	measure->piece_first = lvp__calloc(pieces + 1, sizeof(int32_t), &ok);
	measure->piece_region = lvp__calloc(pieces, sizeof(int32_t), &ok);
	measure->piece_sums = lvp__calloc(pieces, sizeof(lvp__region_sums), &ok);
	measure->triangle_gradient = lvp__calloc(f * 3, sizeof(float), &ok);
	measure->triangle_volume6 = lvp__calloc(f, sizeof(float), &ok);
	measure->normals = lvp__calloc(n * 3, sizeof(float), &ok);
	measure->vertex_g = lvp__calloc(n, sizeof(float), &ok);
	measure->slot_gradient = lvp__calloc(slots * 3, sizeof(float), &ok);
	measure->slot_g = lvp__calloc(slots, sizeof(float), &ok);
	measure->triangle_dirty = lvp__calloc(f, sizeof(uint8_t), &ok);
	measure->dirty_triangles = lvp__calloc(f, sizeof(int32_t), &ok);
	measure->vertex_dirty = lvp__calloc(n, sizeof(uint8_t), &ok);
	measure->dirty_vertices = lvp__calloc(n, sizeof(int32_t), &ok);
	return ok;
}

void lvp__measure_free(lvp__measure *measure)
{
	void *arrays[] = {measure->rest_totals, measure->frame_totals, measure->reference_volume, measure->origin,
	                  measure->origin_float, measure->sums, measure->piece_first, measure->piece_region,
	                  measure->piece_sums, measure->triangle_gradient, measure->triangle_volume6, measure->normals,
	                  measure->vertex_g, measure->slot_gradient, measure->slot_g, measure->triangle_dirty,
	                  measure->dirty_triangles, measure->vertex_dirty, measure->dirty_vertices};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
