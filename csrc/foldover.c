/*
 * foldover.c - paper 5.4: fold-over prevention. A vertex that the posed skeleton places
 * closer (in the 5.1 sense, distance over bone length) to a neighbouring bone than to its own
 * region's bone has crossed into the neighbour's flesh: it is moved back towards its own bone,
 * onto the contact surface d_s / l_s = d_j / l_j between the two regions. The paper walks
 * there in constant steps (which must be shorter than the flesh is thin, and stop short of or
 * past the surface); here the point on the path is found by bisection, so the vertex lands on
 * the contact surface to float precision whatever the flesh width.
 */
#include "binding.h"

#include <stdlib.h>

/* binding->fold.contact, per neighbour entry (s, j) of this frame: */
enum {
	LVP__CONTACT_NONE = 0, /* no skin crossed between s and j */
	LVP__CONTACT_FOUND,    /* skin crossed (of s into j, or of j into s); the map not faded yet */
	LVP__CONTACT_FADED,    /* and the map was faded there (lvp__fade_map_at_contact) */
};

/* f > 0: closer (relative to bone length) to bone j than to bone s. */
static inline double lvp__side(lvp__vec3 p, lvp__vec3 s_head, lvp__vec3 s_tail, double s_length, lvp__vec3 j_head,
                               lvp__vec3 j_tail, double j_length)
{
	return lvp__segment_distance(p, s_head, s_tail) / s_length - lvp__segment_distance(p, j_head, j_tail) / j_length;
}

/* Moves p (on bone j's side, f > 0) back across the contact surface f = 0 along the steepest
 * way, -grad f: where the two bones are straight near their joint the surface is the bisector
 * plane and this is the orthogonal projection onto it, which keeps the skin that crossed
 * untangled (a walk towards the bone would slide vertices along the surface and fold it). The
 * crossing point is bracketed by doubling the step, then bisected; the vertex ends `gap` past
 * it on its own side, so the skin of the two sides cannot touch. False if no crossing is found
 * within `limit`. */
static bool lvp__back_to_contact(lvp__vec3 *r_point, lvp__vec3 p, lvp__vec3 sh, lvp__vec3 st, double ls, lvp__vec3 jh,
                                 lvp__vec3 jt, double lj, double gap, double limit)
{
	lvp__vec3 cs, cj;
	lvp__closest_on_segment(&cs, p, sh, st);
	lvp__closest_on_segment(&cj, p, jh, jt);
	double ds = lvp__length(lvp__sub(p, cs)), dj = lvp__length(lvp__sub(p, cj));
	if (!(ds > 0.0) || !(dj > 0.0))
		return false;
	lvp__vec3 gradient =
	    lvp__sub(lvp__scale(lvp__sub(p, cs), 1.0 / (ds * ls)), lvp__scale(lvp__sub(p, cj), 1.0 / (dj * lj)));
	/* Each term of the gradient has length 1 / l. When they (nearly) cancel, the two bones lie on
	 * top of each other here (a joint folded to 180 degrees): there is no contact surface to
	 * project onto, and the direction would be rounding noise. */
	double length = lvp__length(gradient);
	if (!(length > 1e-6 * (1.0 / ls + 1.0 / lj)))
		return false;
	lvp__vec3 direction = lvp__scale(gradient, -1.0 / length);
	double f = lvp__side(p, sh, st, ls, jh, jt, lj);
	/* The contact surface is nearer than the farther bone, and no sane contact is further than
	 * a volume step may go (a quarter of the mesh's size): past that, the pose is not one skin
	 * can follow (bones sent far from their skin), and the vertex is left where it is. */
	double reach = fmin(2.0 * (ds + dj), limit);
	double outside = 0.0, inside = fmin(f / length, reach);
	int doublings = 0;
	while (lvp__side(lvp__add(p, lvp__scale(direction, inside)), sh, st, ls, jh, jt, lj) > 0.0) {
		outside = inside;
		inside *= 2.0;
		if (++doublings > 40 || inside > reach)
			return false;
	}
	for (int step = 0; step < 60 && inside - outside > 1e-9 * (inside + 1e-30); ++step) {
		double middle = 0.5 * (inside + outside);
		if (lvp__side(lvp__add(p, lvp__scale(direction, middle)), sh, st, ls, jh, jt, lj) > 0.0)
			outside = middle;
		else
			inside = middle;
	}
	*r_point = lvp__add(p, lvp__scale(direction, inside + gap));
	return true;
}

/* Whether two bones move differently this frame (only then can skin fold between them). */
static bool lvp__bends(const lvp_binding *binding, int32_t s, int32_t j)
{
	const double *a = binding->rig.skin[s].m, *b = binding->rig.skin[j].m;
	double scale = 1.0;
	for (int i = 0; i < 12; ++i)
		scale = fmax(scale, fabs(a[i]));
	for (int i = 0; i < 12; ++i)
		if (fabs(a[i] - b[i]) > 1e-6 * scale)
			return true;
	return false;
}

void lvp__clear_contacts(lvp_binding *binding)
{
	memset(binding->fold.contact, 0, (size_t)binding->mesh.neighbour_offsets[binding->region_count]);
}

/* Marks the contact of entry n of region s's neighbours, bone j, for both sides: the flesh of s
 * and of j is pressed together, whichever crossed. */
static void lvp__mark_contact(lvp_binding *binding, int32_t s, int32_t n, int32_t j)
{
	if (binding->fold.contact[n] == LVP__CONTACT_NONE)
		binding->fold.contact[n] = LVP__CONTACT_FOUND;
	for (int32_t m = binding->mesh.neighbour_offsets[j]; m < binding->mesh.neighbour_offsets[j + 1]; ++m)
		if (binding->mesh.neighbour_bones[m] == s && binding->fold.contact[m] == LVP__CONTACT_NONE)
			binding->fold.contact[m] = LVP__CONTACT_FOUND;
}

int32_t lvp__fold_over(lvp_binding *binding, const float *rest_positions)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	float *work = binding->step.positions;
	int32_t moved = 0;
	for (int32_t s = 0; s < binding->region_count; ++s) {
		double ls = binding->rig.bone_length[s] > 0.0 ? 1.0 : 0.0;
		if (binding->rig.region_skipped[s] || !(ls > 0.0))
			continue;
		for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n) {
			int32_t j = binding->mesh.neighbour_bones[n];
			double lj = binding->rig.bone_length[j] > 0.0 ? 1.0 : 0.0;
			if (!(lj > 0.0) || !lvp__bends(binding, s, j))
				continue;
			lvp__vec3 sh = binding->rig.posed_heads[s], st = binding->rig.posed_tails[s];
			lvp__vec3 jh = binding->rig.posed_heads[j], jt = binding->rig.posed_tails[j];
			double gap = 1e-4 * (binding->rig.bone_length[s] + binding->rig.bone_length[j]);
			for (int32_t i = binding->mesh.region_vertex_offsets[s]; i < binding->mesh.region_vertex_offsets[s + 1];
			     ++i) {
				int32_t k = binding->mesh.region_vertices[i];
				/* Only vertices that were on their own side at rest can cross. */
				lvp__vec3 r = lvp__load(rest + 3 * k);
				if (lvp__side(r, binding->rig.heads[s], binding->rig.tails[s], ls, binding->rig.heads[j],
				              binding->rig.tails[j], lj) >= 0.0)
					continue;
				lvp__vec3 p = lvp__load(work + 3 * k);
				if (lvp__side(p, sh, st, ls, jh, jt, lj) <= 0.0)
					continue;
				lvp__vec3 q;
				if (!lvp__back_to_contact(&q, p, sh, st, ls, jh, jt, lj, gap, 0.25 * binding->size))
					continue;
				work[3 * k] = (float)q.x;
				work[3 * k + 1] = (float)q.y;
				work[3 * k + 2] = (float)q.z;
				lvp__mark_contact(binding, s, n, j);
				moved += !binding->fold.held[k];
				binding->fold.held[k] = 1;
				lvp__make_dynamic(binding, k); /* off its bone's path now: the next pass visits it */
			}
		}
	}
	return moved;
}

static inline double lvp__smoothstep(double x)
{
	x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
	return x * x * (3.0 - 2.0 * x);
}

/* The concave side of the bend between two posed bones: from the joint (the middle of their
 * nearest ends), the unit direction between the two bones. False when they are (nearly)
 * straight. */
static bool lvp__concave_side(lvp__vec3 *r_joint, lvp__vec3 *r_direction, lvp__vec3 sh, lvp__vec3 st, lvp__vec3 jh,
                              lvp__vec3 jt)
{
	lvp__vec3 s_ends[2] = {sh, st}, j_ends[2] = {jh, jt};
	int best_s = 0, best_j = 0;
	double best = INFINITY;
	for (int a = 0; a < 2; ++a)
		for (int b = 0; b < 2; ++b) {
			double d = lvp__length(lvp__sub(s_ends[a], j_ends[b]));
			if (d < best) {
				best = d;
				best_s = a;
				best_j = b;
			}
		}
	lvp__vec3 joint = lvp__scale(lvp__add(s_ends[best_s], j_ends[best_j]), 0.5);
	lvp__vec3 us = lvp__sub(s_ends[1 - best_s], joint), uj = lvp__sub(j_ends[1 - best_j], joint);
	double ls = lvp__length(us), lj = lvp__length(uj);
	if (!(ls > 0.0) || !(lj > 0.0))
		return false;
	lvp__vec3 c = lvp__add(lvp__scale(us, 1.0 / ls), lvp__scale(uj, 1.0 / lj));
	double length = lvp__length(c);
	if (!(length > 1e-3))
		return false;
	*r_joint = joint;
	*r_direction = lvp__scale(c, 1.0 / length);
	return true;
}

/* Where skin crossed between two bones: the flesh pressed against their contact surface does not
 * bulge into it. The map is faded to zero there, over half the vertex's rest distance to its
 * bone, so the extra volume goes into the bulge beside the contact (paper Fig. 10d) instead of
 * pushing skin back across. Only on the concave side of the bend, faded in over the same width
 * from the joint: the contact surface also runs through the convex side and the flanks of the
 * joint, where nothing presses the skin, and holding it there left a ridge between held and
 * bulging skin. Only for pairs where skin crossed (a joint bent without contact keeps its
 * bulge), each once a frame. */
bool lvp__fade_map_at_contact(lvp_binding *binding)
{
	const float *work = binding->step.positions;
	bool faded = false;
	for (int32_t s = 0; s < binding->region_count; ++s) {
		if (binding->rig.region_skipped[s] || !(binding->rig.bone_length[s] > 0.0))
			continue;
		for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n) {
			if (binding->fold.contact[n] != LVP__CONTACT_FOUND)
				continue;
			binding->fold.contact[n] = LVP__CONTACT_FADED;
			faded = true;
			int32_t j = binding->mesh.neighbour_bones[n];
			lvp__vec3 sh = binding->rig.posed_heads[s], st = binding->rig.posed_tails[s];
			lvp__vec3 jh = binding->rig.posed_heads[j], jt = binding->rig.posed_tails[j];
			lvp__vec3 joint, concave;
			bool has_side = lvp__concave_side(&joint, &concave, sh, st, jh, jt);
			for (int32_t i = binding->mesh.region_vertex_offsets[s]; i < binding->mesh.region_vertex_offsets[s + 1];
			     ++i) {
				int32_t k = binding->mesh.region_vertices[i];
				if (!(binding->frame_map.gamma[k] > 0.0f))
					continue;
				double width = 0.5 * binding->map.distance[k];
				if (!(width > 0.0))
					continue; /* on the bone itself (where the map is zero anyway) */
				lvp__vec3 p = lvp__load(work + 3 * k);
				double fade = lvp__smoothstep(-lvp__side(p, sh, st, 1.0, jh, jt, 1.0) / width);
				double pressed = has_side ? lvp__smoothstep(lvp__dot(lvp__sub(p, joint), concave) / width) : 1.0;
				binding->frame_map.gamma[k] *= (float)(1.0 - (1.0 - fade) * pressed);
			}
		}
	}
	return faded;
}

bool lvp__fold_alloc(lvp_binding *binding)
{
	bool ok = true;
	binding->fold.contact = lvp__calloc((size_t)binding->mesh.neighbour_offsets[binding->region_count], 1, &ok);
	binding->fold.held = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	return ok;
}

void lvp__fold_free(lvp__fold *fold)
{
	free(fold->contact);
	free(fold->held);
}
