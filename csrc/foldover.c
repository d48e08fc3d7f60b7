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

/* f > 0: closer (relative to bone length) to bone j than to bone s. */
static inline double lvp__side(lvp__vec3 p, lvp__vec3 s_head, lvp__vec3 s_tail, double s_length, lvp__vec3 j_head,
                               lvp__vec3 j_tail, double j_length)
{
	return lvp__segment_distance(p, s_head, s_tail) / s_length - lvp__segment_distance(p, j_head, j_tail) / j_length;
}

/* Whether two bones move differently this frame (only then can skin fold between them). */
static bool lvp__bends(const lvp_binding *binding, int32_t s, int32_t j)
{
	const double *a = binding->skin[s].m, *b = binding->skin[j].m;
	double scale = 1.0;
	for (int i = 0; i < 12; ++i)
		scale = fmax(scale, fabs(a[i]));
	for (int i = 0; i < 12; ++i)
		if (fabs(a[i] - b[i]) > 1e-6 * scale)
			return true;
	return false;
}

int32_t lvp__fold_over(lvp_binding *binding, const float *rest_positions)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	float *work = binding->work_positions;
	int32_t moved = 0;
	for (int32_t s = 0; s < binding->region_count; ++s) {
		double ls = binding->bone_length[s];
		if (binding->region_skipped[s] || !(ls > 0.0))
			continue;
		for (int32_t n = binding->neighbour_offsets[s]; n < binding->neighbour_offsets[s + 1]; ++n) {
			int32_t j = binding->neighbour_bones[n];
			double lj = binding->bone_length[j];
			if (!(lj > 0.0) || !lvp__bends(binding, s, j))
				continue;
			lvp__vec3 sh = binding->posed_heads[s], st = binding->posed_tails[s];
			lvp__vec3 jh = binding->posed_heads[j], jt = binding->posed_tails[j];
			for (int32_t i = binding->region_vertex_offsets[s]; i < binding->region_vertex_offsets[s + 1]; ++i) {
				int32_t k = binding->region_vertices[i];
				/* Only vertices that were on their own side at rest can cross. */
				lvp__vec3 r = lvp__load(rest + 3 * k);
				if (lvp__side(r, binding->heads[s], binding->tails[s], ls, binding->heads[j], binding->tails[j], lj) >= 0.0)
					continue;
				lvp__vec3 p = lvp__load(work + 3 * k);
				if (lvp__side(p, sh, st, ls, jh, jt, lj) <= 0.0)
					continue;
				lvp__vec3 target;
				lvp__closest_on_segment(&target, p, sh, st);
				lvp__vec3 path = lvp__sub(target, p);
				/* f > 0 at p; on bone s itself f <= 0. Bisect for the contact surface, keeping
				 * the end that is on the vertex's own side. */
				double inside = 1.0, outside = 0.0;
				if (lvp__side(target, sh, st, ls, jh, jt, lj) > 0.0)
					continue; /* bone s runs through j's side here: no contact surface on the path */
				for (int step = 0; step < 48 && inside - outside > 1e-7; ++step) {
					double middle = 0.5 * (inside + outside);
					if (lvp__side(lvp__add(p, lvp__scale(path, middle)), sh, st, ls, jh, jt, lj) > 0.0)
						outside = middle;
					else
						inside = middle;
				}
				lvp__vec3 q = lvp__add(p, lvp__scale(path, inside));
				work[3 * k] = (float)q.x;
				work[3 * k + 1] = (float)q.y;
				work[3 * k + 2] = (float)q.z;
				moved += !binding->frozen[k];
				binding->frozen[k] = 1;
			}
		}
	}
	return moved;
}
