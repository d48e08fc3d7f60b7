/*
 * bone_lines.c - where each bone runs through its flesh at rest: the lines the method measures
 * distances to (the organic map's d, the reach of a bulge, the flesh radius, the reference volume
 * of an open region) and the direction fold-over bends a bone about.
 *
 * They come from what defines the skinning, never from the caller's tails and rolls: Blender's
 * Armature modifier moves the skin by the heads, the weights and the bones' transforms alone,
 * while importers guess tails (glTF stores joints, not bones; FBX adds leaf bones) and game and
 * retargeted rigs roll bones anyhow. So:
 * - a bone with children runs from its head to each child's head: a palm to every knuckle, a
 *   pelvis to the spine and both hips, a phalanx to the next. Only children that carry skin count:
 *   a leaf bone that moves nothing (FBX's `_end` bones, an IK target) says nothing of the flesh;
 * - a bone without (a fingertip, the head, a toe) runs from its head into its own skin (the
 *   vertices it dominates, weighted by area so that the tessellation does not count): towards the
 *   skin's centroid (its principal axis when the head sits at the centroid), from where the skin
 *   ends behind the head to where it ends ahead, each end a flesh radius inside the skin;
 * - the joints of a B-Bone (bones of one group of more than one, lvp_bind_options.bone_groups)
 *   keep the caller's head and tail: the curve between them does move the skin;
 * - a bone whose caller gave it no length (the still bone of a masked Armature modifier) is a point.
 */
#include "binding.h"

#include <stdlib.h>

/* Per bone, what its own skin is made of, summed over the vertices it dominates. */
typedef struct lvp__skin_sums {
	double area;
	lvp__vec3 moment;   /* sum a p: the area-weighted centroid times the area */
	double second[6];   /* sum a p p^T about the head: xx, xy, xz, yy, yz, zz */
	double ahead, behind; /* the furthest skin along the axis from the head, ahead and behind */
	double radius;      /* sum a |p - the line|: the flesh radius times the area */
} lvp__skin_sums;

/* The dominant bone of point k (its largest weight; the first of equal ones), or -1. */
static int32_t lvp__dominant_bone(const lvp_binding *binding, int32_t k)
{
	int32_t best = -1;
	float most = 0.0f;
	for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e)
		if (binding->rig.weight_values[e] > most) {
			most = binding->rig.weight_values[e];
			best = binding->rig.weight_bones[e];
		}
	return best;
}

/* Each point's area: a third of its triangles'. */
static void lvp__point_areas(const lvp_binding *binding, double *r_area)
{
	const float *rest = binding->rest_positions;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		const int32_t *v = binding->mesh.triangles + 3 * t;
		lvp__vec3 a = lvp__load(rest + 3 * v[0]), b = lvp__load(rest + 3 * v[1]), c = lvp__load(rest + 3 * v[2]);
		double third = lvp__length(lvp__cross(lvp__sub(b, a), lvp__sub(c, a))) / 6.0;
		for (int i = 0; i < 3; ++i)
			r_area[v[i]] += third;
	}
}

/* The unit eigenvector of the largest eigenvalue of the symmetric matrix s (xx, xy, xz, yy, yz,
 * zz), by power iteration from the coordinate axis of the largest diagonal entry. */
static lvp__vec3 lvp__principal_axis(const double s[6])
{
	lvp__vec3 v = s[0] >= s[3] && s[0] >= s[5] ? lvp__v(1.0, 0.0, 0.0)
	              : (s[3] >= s[5] ? lvp__v(0.0, 1.0, 0.0) : lvp__v(0.0, 0.0, 1.0));
	for (int i = 0; i < 64; ++i) {
		lvp__vec3 w = lvp__v(s[0] * v.x + s[1] * v.y + s[2] * v.z, s[1] * v.x + s[3] * v.y + s[4] * v.z,
		                     s[2] * v.x + s[4] * v.y + s[5] * v.z);
		double length = lvp__length(w);
		if (!(length > 0.0))
			break;
		v = lvp__scale(w, 1.0 / length);
	}
	return v;
}

/* The direction a bone without children points in, from its head h into its skin. */
static lvp__vec3 lvp__skin_axis(const lvp__skin_sums *sums, lvp__vec3 h)
{
	lvp__vec3 centroid = lvp__scale(sums->moment, 1.0 / sums->area), towards = lvp__sub(centroid, h);
	/* The spread of the skin about its centroid: sum a (p - h)(p - h)^T less the centroid's part. */
	const lvp__vec3 c = towards;
	double a = sums->area, spread[6] = {sums->second[0] / a - c.x * c.x, sums->second[1] / a - c.x * c.y,
	                                    sums->second[2] / a - c.x * c.z, sums->second[3] / a - c.y * c.y,
	                                    sums->second[4] / a - c.y * c.z, sums->second[5] / a - c.z * c.z};
	double size = sqrt(fmax(0.0, spread[0] + spread[3] + spread[5]));
	if (lvp__length(towards) > 1e-3 * size)
		return lvp__scale(towards, 1.0 / lvp__length(towards));
	return lvp__principal_axis(spread); /* the head in the middle of its skin */
}

static bool lvp__same_point(lvp__vec3 a, lvp__vec3 b, double tolerance)
{
	return lvp__length(lvp__sub(a, b)) <= tolerance;
}

/* Whether internal bone i keeps its caller's segment: a joint of a B-Bone, or a point. */
static bool lvp__keeps_caller_segment(const lvp_binding *binding, const lvp_skeleton *skeleton,
                                      const int32_t *bone_groups, int32_t i)
{
	int32_t c = lvp__caller_bone(binding, i);
	if (lvp__same_point(binding->rig.heads[i], binding->rig.tails[i], 0.0))
		return true;
	if (!bone_groups)
		return false;
	for (int32_t j = 0; j < skeleton->bone_count; ++j)
		if (j != c && bone_groups[j] == bone_groups[c])
			return true;
	return false;
}

/* The heads of caller bone c's children that carry skin (carries, per caller bone) and lie away
 * from its head, each once: r_heads (when not NULL) gets them; returns how many. */
static int32_t lvp__child_heads(const lvp_skeleton *skeleton, const uint8_t *carries, int32_t c, double tolerance,
                                lvp__vec3 *r_heads)
{
	if (!skeleton->parents)
		return 0;
	lvp__vec3 head = lvp__load(skeleton->heads + 3 * c);
	int32_t count = 0;
	for (int32_t j = 0; j < skeleton->bone_count; ++j) {
		if (j == c || skeleton->parents[j] != c || !carries[j])
			continue;
		lvp__vec3 child = lvp__load(skeleton->heads + 3 * j);
		bool again = lvp__same_point(child, head, tolerance);
		/* A B-Bone child's joints share its head; listed once. */
		for (int32_t i = 0; i < j && !again; ++i)
			again = i != c && skeleton->parents[i] == c && carries[i] &&
			        lvp__same_point(lvp__load(skeleton->heads + 3 * i), child, tolerance);
		if (again)
			continue;
		if (r_heads)
			r_heads[count] = child;
		++count;
	}
	return count;
}

/* The skin sums of every bone without children (leaf[i]): area, moment and second moments, then,
 * along each one's axis (r_axis), how far its skin reaches and its flesh radius. */
static void lvp__sum_skins(const lvp_binding *binding, const uint8_t *leaf, const double *point_area,
                           const int32_t *dominant, lvp__skin_sums *sums, lvp__vec3 *r_axis)
{
	const float *rest = binding->rest_positions;
	for (int32_t k = 0; k < binding->vertex_count; ++k) {
		int32_t i = dominant[k];
		if (i < 0 || !leaf[i] || !(point_area[k] > 0.0))
			continue;
		double a = point_area[k];
		lvp__vec3 p = lvp__load(rest + 3 * k), d = lvp__sub(p, binding->rig.heads[i]);
		lvp__skin_sums *s = &sums[i];
		s->area += a;
		s->moment = lvp__add(s->moment, lvp__scale(p, a));
		double second[6] = {d.x * d.x, d.x * d.y, d.x * d.z, d.y * d.y, d.y * d.z, d.z * d.z};
		for (int e = 0; e < 6; ++e)
			s->second[e] += a * second[e];
	}
	for (int32_t i = 0; i < binding->bone_count; ++i)
		if (leaf[i] && sums[i].area > 0.0)
			r_axis[i] = lvp__skin_axis(&sums[i], binding->rig.heads[i]);
	for (int32_t k = 0; k < binding->vertex_count; ++k) {
		int32_t i = dominant[k];
		if (i < 0 || !leaf[i] || !(sums[i].area > 0.0) || !(point_area[k] > 0.0))
			continue;
		lvp__vec3 d = lvp__sub(lvp__load(rest + 3 * k), binding->rig.heads[i]);
		double along = lvp__dot(d, r_axis[i]);
		sums[i].ahead = fmax(sums[i].ahead, along);
		sums[i].behind = fmax(sums[i].behind, -along);
		sums[i].radius += point_area[k] * lvp__length(lvp__sub(d, lvp__scale(r_axis[i], along)));
	}
}

/* Fills lines->from/to of bone i with its segments and its end, counting them in lines->offsets
 * (the segments of the bones before it are in place). */
static void lvp__place_segments(lvp_binding *binding, const lvp_skeleton *skeleton, const uint8_t *carries,
                                int32_t i, bool keeps, const lvp__skin_sums *skin, lvp__vec3 axis, double tolerance,
                                lvp__vec3 *scratch)
{
	lvp__bone_lines *lines = &binding->lines;
	lvp__vec3 head = binding->rig.heads[i];
	int32_t at = lines->offsets[i];
	int32_t children =
	    keeps ? 0 : lvp__child_heads(skeleton, carries, lvp__caller_bone(binding, i), tolerance, scratch);
	lvp__vec3 end = head;
	if (keeps) {
		lines->from[at] = head;
		lines->to[at++] = end = binding->rig.tails[i];
	} else if (children > 0) {
		lvp__vec3 sum = lvp__v(0.0, 0.0, 0.0);
		for (int32_t c = 0; c < children; ++c) {
			lines->from[at] = head;
			lines->to[at++] = scratch[c];
			sum = lvp__add(sum, scratch[c]);
		}
		end = lvp__scale(sum, 1.0 / children);
	} else {
		double radius = skin->area > 0.0 ? skin->radius / skin->area : 0.0;
		lines->from[at] = lvp__add(head, lvp__scale(axis, -fmax(0.0, skin->behind - radius)));
		lines->to[at++] = end = lvp__add(head, lvp__scale(axis, fmax(0.0, skin->ahead - radius)));
	}
	lines->offsets[i + 1] = at;
	lines->end[i] = end;
	lines->length[i] = lvp__length(lvp__sub(end, head));
}

bool lvp__build_bone_lines(lvp_binding *binding, const lvp_skeleton *skeleton, const int32_t *bone_groups)
{
	int32_t b = binding->bone_count, n = binding->vertex_count;
	lvp__bone_lines *lines = &binding->lines;
	bool ok = true;
	/* Children's heads closer than this to the head are at the head (float noise of an importer). */
	double tolerance = 0.0;
	for (int32_t k = 0; k < n; ++k)
		tolerance = fmax(tolerance, lvp__length(lvp__load(binding->rest_positions + 3 * k)));
	for (int32_t i = 0; i < b; ++i)
		tolerance = fmax(tolerance, lvp__length(binding->rig.heads[i]));
	tolerance *= 1e-6;

	uint8_t *keeps = lvp__calloc((size_t)b, 1, &ok), *leaf = lvp__calloc((size_t)b, 1, &ok);
	uint8_t *carries = lvp__calloc((size_t)skeleton->bone_count, 1, &ok);
	for (int32_t e = 0; ok && e < binding->rig.weight_offsets[n]; ++e)
		if (binding->rig.weight_values[e] > 0.0f)
			carries[lvp__caller_bone(binding, binding->rig.weight_bones[e])] = 1;
	int32_t *dominant = lvp__calloc((size_t)n, sizeof(int32_t), &ok);
	double *point_area = lvp__calloc((size_t)n, sizeof(double), &ok);
	lvp__skin_sums *skins = lvp__calloc((size_t)b, sizeof(lvp__skin_sums), &ok);
	lvp__vec3 *axis = lvp__calloc((size_t)b, sizeof(lvp__vec3), &ok);
	lvp__vec3 *scratch = lvp__calloc((size_t)skeleton->bone_count, sizeof(lvp__vec3), &ok);
	lines->offsets = lvp__calloc((size_t)b + 1, sizeof(int32_t), &ok);
	lines->end = lvp__calloc((size_t)b, sizeof(lvp__vec3), &ok);
	lines->length = lvp__calloc((size_t)b, sizeof(double), &ok);
	int32_t segments = 0;
	for (int32_t i = 0; ok && i < b; ++i) {
		keeps[i] = lvp__keeps_caller_segment(binding, skeleton, bone_groups, i);
		int32_t children =
		    keeps[i] ? 0 : lvp__child_heads(skeleton, carries, lvp__caller_bone(binding, i), tolerance, NULL);
		leaf[i] = !keeps[i] && children == 0;
		segments += children > 0 ? children : 1;
	}
	lines->from = lvp__calloc((size_t)segments, sizeof(lvp__vec3), &ok);
	lines->to = lvp__calloc((size_t)segments, sizeof(lvp__vec3), &ok);
	if (ok) {
		for (int32_t k = 0; k < n; ++k)
			dominant[k] = lvp__dominant_bone(binding, k);
		lvp__point_areas(binding, point_area);
		lvp__sum_skins(binding, leaf, point_area, dominant, skins, axis);
		lines->reach = 0.0;
		for (int32_t i = 0; i < b; ++i) {
			lvp__place_segments(binding, skeleton, carries, i, keeps[i], &skins[i], axis[i], tolerance, scratch);
			lines->reach = fmax(lines->reach, lvp__length(binding->rig.heads[i]));
			for (int32_t s = lines->offsets[i]; s < lines->offsets[i + 1]; ++s)
				lines->reach = fmax(lines->reach, fmax(lvp__length(lines->from[s]), lvp__length(lines->to[s])));
		}
	}
	free(keeps);
	free(leaf);
	free(carries);
	free(dominant);
	free(point_area);
	free(skins);
	free(axis);
	free(scratch);
	return ok;
}

double lvp__bone_distance(const lvp_binding *binding, int32_t bone, lvp__vec3 p)
{
	const lvp__bone_lines *lines = &binding->lines;
	double best = INFINITY;
	for (int32_t s = lines->offsets[bone]; s < lines->offsets[bone + 1]; ++s)
		best = fmin(best, lvp__segment_distance(p, lines->from[s], lines->to[s]));
	return best;
}

void lvp__bone_lines_free(lvp__bone_lines *lines)
{
	free(lines->offsets);
	free(lines->from);
	free(lines->to);
	free(lines->end);
	free(lines->length);
}
