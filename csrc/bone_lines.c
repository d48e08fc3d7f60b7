/*
 * bone_lines.c - where each bone runs through its flesh at rest: the lines the method measures
 * distances to (the organic map's d, the reach of a bulge, the flesh radius, the reference volume
 * of an open region) and the direction fold-over bends a bone about.
 *
 * They come from what defines the skinning, never from the caller's tails and rolls: Blender's
 * Armature modifier moves the skin by the heads, the weights and the bones' transforms alone,
 * while importers guess tails (glTF stores joints, not bones; FBX adds leaf bones) and game and
 * retargeted rigs roll bones anyhow. So:
 * - a bone with one child runs from its head to the child's head (a phalanx to the next). Only
 *   children that carry skin and lie away from the head count: a leaf bone that moves nothing
 *   (FBX's `_end` bones, an IK target) says nothing of the flesh;
 * - a bone with several runs from its head to their heads' mean: a palm down the middle of the
 *   hand, as a rig's own palm bone runs (a line to every knuckle put the palm's skin between the
 *   knuckles as near its bone as the knuckles, and the hand bulged elsewhere from frame to frame);
 * - a bone without (a fingertip, the head, a toe) runs from its head through the centroid of its
 *   own skin (the points it dominates, weighted by their area so that the tessellation does not
 *   count) to as far beyond it: to the tip of a finger whose skin reaches evenly from the joint
 *   to the tip; a bone that dominates no skin is a point at its head;
 * - the joints of a B-Bone (bones of one group of more than one, lvp_bind_options.bone_groups)
 *   keep the caller's head and tail: the curve between them does move the skin;
 * - a bone whose caller gave it no length (the still bone of a masked Armature modifier) is a point.
 */
#include "binding.h"

#include <stdlib.h>

/* Per bone, the area of the skin it dominates and that skin's area-weighted sum of positions: each
 * point counts with a third of its triangles' area. */
static void lvp__sum_skins(const lvp_binding *binding, double *r_area, lvp__vec3 *r_moment)
{
	const float *rest = binding->rest_positions;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		const int32_t *v = binding->mesh.triangles + 3 * t;
		lvp__vec3 p[3] = {lvp__load(rest + 3 * v[0]), lvp__load(rest + 3 * v[1]), lvp__load(rest + 3 * v[2])};
		double third = lvp__length(lvp__cross(lvp__sub(p[1], p[0]), lvp__sub(p[2], p[0]))) / 6.0;
		for (int i = 0; i < 3; ++i) {
			float unused;
			int32_t bone = lvp__main_bone(binding, v[i], &unused);
			if (bone < 0)
				continue;
			r_area[bone] += third;
			r_moment[bone] = lvp__add(r_moment[bone], lvp__scale(p[i], third));
		}
	}
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

/* Where internal bone i's line ends (lvp__bone_lines.end), from its caller's children (carries: per
 * caller bone, whether it carries skin) or its own skin (area, moment: lvp__sum_skins). */
static lvp__vec3 lvp__line_end(const lvp_binding *binding, const lvp_skeleton *skeleton, const uint8_t *carries,
                               int32_t i, double area, lvp__vec3 moment, double tolerance)
{
	lvp__vec3 head = binding->rig.heads[i];
	int32_t c = lvp__caller_bone(binding, i), children = 0;
	lvp__vec3 sum = lvp__v(0.0, 0.0, 0.0);
	for (int32_t j = 0; skeleton->parents && j < skeleton->bone_count; ++j) {
		if (j == c || skeleton->parents[j] != c || !carries[j])
			continue;
		lvp__vec3 child = lvp__load(skeleton->heads + 3 * j);
		bool again = lvp__same_point(child, head, tolerance);
		/* A B-Bone child's joints share its head: counted once. */
		for (int32_t k = 0; k < j && !again; ++k)
			again = k != c && skeleton->parents[k] == c && carries[k] &&
			        lvp__same_point(lvp__load(skeleton->heads + 3 * k), child, tolerance);
		if (!again) {
			sum = lvp__add(sum, child);
			++children;
		}
	}
	if (children > 0)
		return lvp__scale(sum, 1.0 / children);
	if (!(area > 0.0))
		return head;
	lvp__vec3 centroid = lvp__scale(moment, 1.0 / area);
	return lvp__add(head, lvp__scale(lvp__sub(centroid, head), 2.0));
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

	uint8_t *carries = lvp__calloc((size_t)skeleton->bone_count, 1, &ok);
	double *area = lvp__calloc((size_t)b, sizeof(double), &ok);
	lvp__vec3 *moment = lvp__calloc((size_t)b, sizeof(lvp__vec3), &ok);
	lines->end = lvp__calloc((size_t)b, sizeof(lvp__vec3), &ok);
	lines->length = lvp__calloc((size_t)b, sizeof(double), &ok);
	if (ok) {
		for (int32_t e = 0; e < binding->rig.weight_offsets[n]; ++e)
			if (binding->rig.weight_values[e] > 0.0f)
				carries[lvp__caller_bone(binding, binding->rig.weight_bones[e])] = 1;
		lvp__sum_skins(binding, area, moment);
		for (int32_t i = 0; i < b; ++i) {
			lines->end[i] = lvp__keeps_caller_segment(binding, skeleton, bone_groups, i)
			                    ? binding->rig.tails[i]
			                    : lvp__line_end(binding, skeleton, carries, i, area[i], moment[i], tolerance);
			lines->length[i] = lvp__length(lvp__sub(lines->end[i], binding->rig.heads[i]));
		}
	}
	free(carries);
	free(area);
	free(moment);
	return ok;
}

double lvp__bone_distance(const lvp_binding *binding, int32_t bone, lvp__vec3 p)
{
	return lvp__segment_distance(p, binding->rig.heads[bone], binding->lines.end[bone]);
}

void lvp__bone_lines_free(lvp__bone_lines *lines)
{
	free(lines->end);
	free(lines->length);
}
