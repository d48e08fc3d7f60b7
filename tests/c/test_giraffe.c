/*
 * test_giraffe.c - the paper's giraffe (artist weights, 59 joints, 1673 vertices): bend the
 * neck down and fold the legs, correct, and compare the whole body's volume error before and
 * after (the paper reports 10 % -> 3 %). A leg far from every bent joint must not move at all.
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

typedef struct bend {
	const char *bone;
	float axis[3];
	float degrees;
} bend;

/* The giraffe stands with +Y up and faces +Z, so bends in its own plane turn about world +X:
 * the neck bent down through its three lower joints (the head goes forward and down), the front
 * left leg folded back at the elbow and the wrist, the hind right leg folded at the knee. */
static const bend pose[] = {
    {"gi_neckC7", {1, 0, 0}, 50}, {"gi_neckC4", {1, 0, 0}, 50}, {"gi_neckC2", {1, 0, 0}, 50},
    {"gi_L_elbow", {1, 0, 0}, 60}, {"gi_L_wrist", {1, 0, 0}, 90}, {"gi_R_knee", {1, 0, 0}, -80},
};

/* The far leg: the left hind leg, which no bend touches. */
static const char *far_leg[] = {"gi_T_L_hip", "gi_L_hip", "gi_L_knee", "gi_L_ankle", "gi_L_hphaA", "gi_L_hphaB",
                                "gi_L_hphaC", "gi_L_hphaC_end"};

static bool in_far_leg(const test_rig *rig, int32_t bone)
{
	for (size_t i = 0; i < sizeof(far_leg) / sizeof(far_leg[0]); ++i)
		if (test_find_bone(rig, far_leg[i]) == bone)
			return true;
	return false;
}

/* Whether all the bones of vertex k have the same skin matrix this frame (to float rounding). */
static bool moves_rigidly(const test_rig *rig, const float *skin, int32_t k)
{
	int32_t first = rig->weight_offsets[k];
	for (int32_t e = first + 1; e < rig->weight_offsets[k + 1]; ++e)
		for (int i = 0; i < 12; ++i)
			if (fabsf(skin[16 * rig->weight_bones[e] + i] - skin[16 * rig->weight_bones[first] + i]) > 1e-6f)
				return false;
	return true;
}

/* A frame of the giraffe: joint rotations (axis, angle per bone, in its rest frame) in, posed
 * matrices, skin matrices and skinned positions out, and room for the offsets. */
typedef struct giraffe_frame {
	float *rotations, *posed, *skin, *skinned, *offsets;
} giraffe_frame;

static giraffe_frame giraffe_frame_make(const test_rig *rig)
{
	giraffe_frame f;
	f.rotations = calloc((size_t)rig->bone_count * 4, sizeof(float));
	f.posed = malloc(sizeof(float) * 16 * (size_t)rig->bone_count);
	f.skin = malloc(sizeof(float) * 16 * (size_t)rig->bone_count);
	f.skinned = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	f.offsets = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	return f;
}

/* Poses the rig by f->rotations and skins it (linear blend). */
static void giraffe_frame_pose(giraffe_frame *f, const test_rig *rig)
{
	test_pose(f->posed, rig, f->rotations);
	test_skin_matrices(f->skin, rig, f->posed);
	lvp_weights weights = test_rig_weights(rig);
	lvp_diagnostic diag;
	CHECK_OK(lvp_skin_linear(f->skinned, rig->positions, rig->vertex_count, &weights, f->skin, rig->bone_count, &diag),
	         diag);
}

/* Poses the rig with one joint turned `degrees` about its rest frame's `axis` (0, 1, 2) and skins it. */
static void giraffe_frame_bend(giraffe_frame *f, const test_rig *rig, int32_t bone, int axis, double degrees)
{
	memset(f->rotations, 0, sizeof(float) * 4 * (size_t)rig->bone_count);
	f->rotations[4 * bone + axis] = 1.0f;
	f->rotations[4 * bone + 3] = (float)(degrees * PI / 180);
	giraffe_frame_pose(f, rig);
}

static void giraffe_frame_free(giraffe_frame *f)
{
	free(f->rotations);
	free(f->posed);
	free(f->skin);
	free(f->skinned);
	free(f->offsets);
}

static void test_giraffe_bend(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	int32_t n = rig.vertex_count;
	giraffe_frame frame = giraffe_frame_make(&rig);
	float *rotations = frame.rotations, *skin = frame.skin, *posed = frame.posed, *offsets = frame.offsets;
	for (size_t i = 0; i < sizeof(pose) / sizeof(pose[0]); ++i) {
		int32_t bone = test_find_bone(&rig, pose[i].bone);
		CHECK(bone >= 0);
		if (bone < 0)
			continue;
		/* world axis -> the joint's rest frame: the transpose of its rotation */
		const float *m = rig.rest_matrices + 16 * bone;
		for (int c = 0; c < 3; ++c)
			rotations[4 * bone + c] = m[c] * pose[i].axis[0] + m[4 + c] * pose[i].axis[1] + m[8 + c] * pose[i].axis[2];
		rotations[4 * bone + 3] = (float)(pose[i].degrees * PI / 180);
	}
	giraffe_frame_pose(&frame, &rig);
	const float *skinned = frame.skinned;
	lvp_diagnostic diag;

	printf("  giraffe, neck and legs bent: whole-body volume error (holes capped)\n");
	printf("  map       | plain SSD | one pass | iterated | worst region before -> after | passes\n");
	const lvp_map maps[2] = {LVP_MAP_ORGANIC, LVP_MAP_RUBBER};
	const char *names[2] = {"organic", "rubber"};
	for (int m = 0; m < 2; ++m) {
		lvp_bind_options options = lvp_bind_default_options();
		options.map.map = maps[m];
		lvp_binding *binding = test_bind_rig(&rig, &options);
		if (!binding)
			continue;
		lvp_frame_options one = lvp_frame_default_options();
		one.max_iterations = 1;
		lvp_frame_stats single, stats;
		CHECK_OK(lvp_correct(NULL, offsets, binding, skinned, posed, NULL, &one, &single, &diag), diag);
		CHECK_OK(lvp_correct(NULL, offsets, binding, skinned, posed, NULL, NULL, &stats, &diag), diag);
		double before = (stats.volume_before - stats.volume_rest) / stats.volume_rest;
		double after_one = (single.volume_after - single.volume_rest) / single.volume_rest;
		double after = (stats.volume_after - stats.volume_rest) / stats.volume_rest;
		printf("  %-9s | %8.2f%% | %7.3f%% | %7.4f%% | %s %+.2f%% -> %+.4f%% | %d\n", names[m], 100 * before,
		       100 * after_one, 100 * after, stats.worst_region >= 0 ? rig.names[stats.worst_region] : "-",
		       100 * stats.worst_region_change_before, 100 * stats.worst_region_change_after, (int)stats.iterations);
		/* Plain skinning loses volume on this pose; the paper's 3 % after is beaten by far. */
		CHECK(before < -0.005);
		CHECK(fabs(after_one) < 0.03);
		CHECK(fabs(after) < 0.001);
		CHECK(fabs(stats.worst_region_change_after) < fabs(stats.worst_region_change_before));

		/* The far leg does not move at all: every vertex whose main bone is in it and whose bones
		 * all move together (the artist's weights reach some leg vertices from the bent front
		 * elbow; those are near a bent joint in the rig's own sense and may move). */
		int32_t far_vertices = 0;
		double far_motion = 0.0;
		int32_t *regions = malloc(sizeof(int32_t) * (size_t)n);
		lvp_get_segmentation(binding, regions, NULL);
		for (int32_t k = 0; k < n; ++k) {
			if (regions[k] < 0 || !in_far_leg(&rig, regions[k]) || !moves_rigidly(&rig, skin, k))
				continue;
			++far_vertices;
			for (int c = 0; c < 3; ++c)
				far_motion = fmax(far_motion, fabs(offsets[3 * k + c]));
		}
		free(regions);
		printf("  %s: %d vertices of the left hind leg move rigidly under skinning; largest offset %g\n", names[m],
		       (int)far_vertices, far_motion);
		CHECK(far_vertices > 50);
		CHECK(far_motion == 0.0);
		lvp_free(binding);
	}
	giraffe_frame_free(&frame);
	test_rig_free(&rig);
}

/* Each major joint alone, bent 60 degrees both ways about each of its three axes: the correction
 * restores the whole body's volume every time. The shoulders are the hard case: fifteen regions
 * overlap there, and most of the body's change is what the region changes miss (lvp.h,
 * ALGORITHM 5), so a combined step can leave the linear range and the correction has to go on
 * in two phases. */
static void test_single_joints(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	const char *joints[] = {"gi_neckC7", "gi_neckC4", "gi_head",  "gi_L_shoulder", "gi_R_shoulder", "gi_L_elbow",
	                        "gi_L_hip",  "gi_L_knee", "gi_R_knee", "gi_tailA"};
	giraffe_frame frame = giraffe_frame_make(&rig);
	lvp_diagnostic diag;
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	int frames = 0, steps = 0, most_steps = 0;
	double worst_before = 0.0, worst_after = 0.0, largest_offset = 0.0;
	for (size_t j = 0; j < sizeof(joints) / sizeof(joints[0]) && binding; ++j) {
		int32_t bone = test_find_bone(&rig, joints[j]);
		CHECK(bone >= 0);
		for (int axis = 0; axis < 3 && bone >= 0; ++axis)
			for (int sign = -1; sign <= 1; sign += 2) {
				giraffe_frame_bend(&frame, &rig, bone, axis, sign * 60.0);
				lvp_frame_stats stats;
				CHECK_OK(lvp_correct(NULL, frame.offsets, binding, frame.skinned, frame.posed, NULL, NULL, &stats,
				                     &diag),
				         diag);
				double before = (stats.volume_before - stats.volume_rest) / stats.volume_rest;
				double after = (stats.volume_after - stats.volume_rest) / stats.volume_rest;
				CHECK(fabs(after) < 1e-3);
				CHECK(!stats.passed_through);
				++frames;
				steps += stats.iterations;
				most_steps = stats.iterations > most_steps ? stats.iterations : most_steps;
				worst_before = fmax(worst_before, fabs(before));
				worst_after = fmax(worst_after, fabs(after));
				largest_offset = fmax(largest_offset, stats.max_displacement);
			}
	}
	printf("  %d poses: plain skinning up to %.2f%% off, corrected up to %.4f%%, %.1f passes on average (at most "
	       "%d), largest offset %.3f\n",
	       frames, 100 * worst_before, 100 * worst_after, (double)steps / (frames ? frames : 1), most_steps,
	       largest_offset);
	CHECK(frames == 60);
	lvp_free(binding);
	giraffe_frame_free(&frame);
	test_rig_free(&rig);
}

/* LVP_RESTORE_WHOLE_MESH on the same single joints: one multiplier for the whole body gives the
 * volume back as exactly, with lower bulges and fewer triangles pushed through each other than
 * every region restored on its own (lvp.h, RESTORE). With options.keep_apart as well, no pose has
 * more crossing pairs than plain skinning, where without it some do, and the volume comes back as
 * exactly (lvp.h, CONTACT). Counted exactly, over all the poses. */
static void test_restoring_the_whole_mesh(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	const char *joints[] = {"gi_neckC7", "gi_neckC4", "gi_head", "gi_L_shoulder", "gi_L_elbow", "gi_L_knee", "gi_tailA"};
	enum { EACH_REGION, WHOLE_MESH, KEPT_APART, VARIANTS };
	int32_t n = rig.vertex_count;
	giraffe_frame frame = giraffe_frame_make(&rig);
	float *corrected = malloc(sizeof(float) * 3 * (size_t)n);
	lvp_diagnostic diag;
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	int64_t plain_pairs = 0, pairs[VARIANTS] = {0}, shortened = 0;
	int above_plain[VARIANTS] = {0}, poses = 0;
	double worst_after[VARIANTS] = {0.0}, largest_offset[VARIANTS] = {0.0};
	for (size_t j = 0; j < sizeof(joints) / sizeof(joints[0]) && binding; ++j) {
		int32_t bone = test_find_bone(&rig, joints[j]);
		CHECK(bone >= 0);
		for (int axis = 0; axis < 3 && bone >= 0; axis += 2)
			for (int sign = -1; sign <= 1; sign += 2) {
				giraffe_frame_bend(&frame, &rig, bone, axis, sign * 60.0);
				int64_t plain = test_count_intersecting_pairs(frame.skinned, rig.triangles, rig.triangle_count);
				plain_pairs += plain;
				++poses;
				for (int variant = 0; variant < VARIANTS; ++variant) {
					lvp_frame_options options = lvp_frame_default_options();
					options.restore = variant == EACH_REGION ? LVP_RESTORE_EACH_REGION : LVP_RESTORE_WHOLE_MESH;
					options.keep_apart = variant == KEPT_APART;
					lvp_frame_stats stats;
					CHECK_OK(lvp_correct(corrected, NULL, binding, frame.skinned, frame.posed, NULL, &options,
					                     &stats, &diag),
					         diag);
					worst_after[variant] =
					    fmax(worst_after[variant], fabs(stats.volume_after / stats.volume_rest - 1.0));
					largest_offset[variant] = fmax(largest_offset[variant], stats.max_displacement);
					int64_t crossing = test_count_intersecting_pairs(corrected, rig.triangles, rig.triangle_count);
					pairs[variant] += crossing;
					above_plain[variant] += crossing > plain;
					if (variant == KEPT_APART)
						shortened += stats.shortened_vertices;
					else
						CHECK(stats.shortened_vertices == 0);
				}
			}
	}
	printf("  intersecting triangle pairs over %d poses: plain skinning %lld, each region restored %lld (%d poses "
	       "above plain), the whole mesh %lld (%d), kept apart %lld (%d; %lld offsets shortened)\n  volume off at "
	       "most %.4f%% / %.4f%% / %.4f%%; largest offset %.3f / %.3f / %.3f\n",
	       poses, (long long)plain_pairs, (long long)pairs[EACH_REGION], above_plain[EACH_REGION],
	       (long long)pairs[WHOLE_MESH], above_plain[WHOLE_MESH], (long long)pairs[KEPT_APART],
	       above_plain[KEPT_APART], (long long)shortened, 100 * worst_after[EACH_REGION], 100 * worst_after[WHOLE_MESH],
	       100 * worst_after[KEPT_APART], largest_offset[EACH_REGION], largest_offset[WHOLE_MESH],
	       largest_offset[KEPT_APART]);
	CHECK(worst_after[WHOLE_MESH] < 1e-3);
	CHECK(pairs[WHOLE_MESH] < pairs[EACH_REGION]);
	CHECK(largest_offset[WHOLE_MESH] < largest_offset[EACH_REGION]);
	CHECK(above_plain[WHOLE_MESH] > 0);
	CHECK(above_plain[KEPT_APART] == 0);
	CHECK(worst_after[KEPT_APART] < 1e-3);
	lvp_frame_options bad = lvp_frame_default_options();
	bad.restore = 2;
	CHECK(lvp_correct(corrected, NULL, binding, frame.skinned, frame.posed, NULL, &bad, NULL, &diag) ==
	      lvp_error_invalid_option);
	CHECK(strstr(diag.message, "options.restore") != NULL);
	free(corrected);
	lvp_free(binding);
	giraffe_frame_free(&frame);
	test_rig_free(&rig);
}

/* lvp_correct keeps work from frame to frame (the dynamic set, while the same bones move), so
 * a frame's result must not depend on the frames before it: an animation played on one
 * binding gives, frame by frame, bit for bit what a fresh binding gives for that frame alone.
 * The frames change which bones move, turn fold-over on (which adds dynamic vertices and, at its
 * first frame, builds its relaxation's lists), pass a frame rest (a shape key), scale a bone to
 * zero (its region is skipped) and, at the end, set a map without the deformation weighting
 * (lvp_set_map), which moves vertices no bone bends. */
typedef struct animation_frame {
	const char *bone;
	float degrees;
	int fold_over, shape_key, collapsed_bone, unweighted_map;
} animation_frame;

static void test_frames_independent(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	static const animation_frame frames[] = {
	    {"gi_neckC7", 20, 0, 0, 0, 0},    {"gi_neckC7", 35, 0, 0, 0, 0},  {"gi_neckC7", 50, 0, 0, 0, 0},
	    {"gi_R_knee", -60, 0, 0, 0, 0},   {"gi_R_knee", -130, 1, 0, 0, 0}, {"gi_R_knee", -130, 0, 0, 0, 0},
	    {"gi_neckC7", 50, 0, 1, 0, 0},    {"gi_neckC7", 50, 0, 0, 0, 0},  {"gi_L_elbow", 60, 0, 0, 1, 0},
	    {"gi_L_elbow", 60, 0, 0, 0, 0},   {"gi_neckC7", 35, 0, 0, 0, 0},  {"gi_neckC7", 35, 0, 0, 0, 1},
	};
	int32_t n = rig.vertex_count;
	giraffe_frame frame = giraffe_frame_make(&rig);
	float *alone = malloc(sizeof(float) * 3 * (size_t)n), *rest = malloc(sizeof(float) * 3 * (size_t)n);
	for (int32_t i = 0; i < 3 * n; ++i) /* a shape key that swells the body by 2 % */
		rest[i] = 1.02f * rig.positions[i];
	lvp_diagnostic diag;
	lvp_binding *animated = test_bind_rig(&rig, NULL);
	int same = 0, folded = 0, count = (int)(sizeof(frames) / sizeof(frames[0]));
	lvp_bind_options bind_options = lvp_bind_default_options();
	for (int f = 0; f < count && animated; ++f) {
		if (frames[f].unweighted_map && bind_options.map.deformation_weighted) {
			bind_options.map.deformation_weighted = 0;
			CHECK_OK(lvp_set_map(animated, &bind_options.map, &diag), diag);
		}
		int32_t bone = test_find_bone(&rig, frames[f].bone);
		CHECK(bone >= 0);
		giraffe_frame_bend(&frame, &rig, bone, 0, frames[f].degrees);
		if (frames[f].collapsed_bone) /* the bone's own matrix scaled to zero */
			for (int c = 0; c < 12; ++c)
				if (c % 4 != 3)
					frame.posed[16 * bone + c] = 0.0f;
		lvp_frame_options options = lvp_frame_default_options();
		options.fold_over = frames[f].fold_over;
		options.keep_apart = f % 3 == 1; /* the contact test's tree is refitted, never rebuilt */
		const float *frame_rest = frames[f].shape_key ? rest : NULL;
		lvp_binding *fresh = test_bind_rig(&rig, &bind_options);
		lvp_frame_stats stats;
		CHECK_OK(lvp_correct(NULL, frame.offsets, animated, frame.skinned, frame.posed, frame_rest, &options, &stats,
		                     &diag),
		         diag);
		folded += stats.folded_vertices;
		CHECK_OK(lvp_correct(NULL, alone, fresh, frame.skinned, frame.posed, frame_rest, &options, NULL, &diag), diag);
		bool equal = memcmp(frame.offsets, alone, sizeof(float) * 3 * (size_t)n) == 0;
		CHECK(equal);
		same += equal;
		lvp_free(fresh);
	}
	printf("  %d of %d frames of an animation on one binding equal a fresh binding's, bit for bit (fold-over "
	       "moved %d vertices)\n",
	       same, count, folded);
	CHECK(folded > 0);
	lvp_free(animated);
	free(alone);
	free(rest);
	giraffe_frame_free(&frame);
	test_rig_free(&rig);
}

int main(void)
{
	RUN(test_giraffe_bend);
	RUN(test_single_joints);
	RUN(test_restoring_the_whole_mesh);
	RUN(test_frames_independent);
	return check_failures() != 0;
}
