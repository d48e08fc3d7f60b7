/*
 * test_contact.c - keeping skin apart (lvp.h, CONTACT) on a tube of eight bones: bent 70 degrees at
 * one joint, the correction pushes the inside of the bend through itself where plain skinning does
 * not, and keep_apart takes that back with the volume still restored, by fading the offsets as the
 * skin approaches the skin in front of it (no offset shortened after the fact, and the offsets as
 * smooth as without it); bent 71 degrees at every joint, where the chain folds into itself and the
 * correction crosses more than plain skinning does, never more crossing pairs than plain skinning
 * (the crossing test takes what the fade leaves: it never gives up); with fold-over too, bent 100 and
 * 140 degrees at one joint, never more crossing pairs than plain skinning or fold-over alone; wound the
 * other way, kept apart the same, bit for bit; and on one to four threads, the same bits. (The giraffe's
 * 28 single-joint poses: test_giraffe.c; a hand closing: tests/blender/test_fold_over_hand.py.)
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* The tube bent `degrees` at its middle joint, or at every joint. */
static test_posed_rig make_tube(double degrees, bool every_joint)
{
	test_rig rig = test_make_chain(8, 1.0f, 0.3f, 32, 20, 0.5f);
	float *rotations = calloc((size_t)rig.bone_count * 4, sizeof(float));
	for (int32_t i = 1; i < rig.bone_count; ++i) {
		if (!every_joint && i != rig.bone_count / 2)
			continue;
		rotations[4 * i] = 1.0f;
		rotations[4 * i + 3] = (float)(degrees * PI / 180.0);
	}
	test_posed_rig tube;
	CHECK(test_pose_rig(rig, rotations, &tube) == 0);
	free(rotations);
	return tube;
}

/* Corrects the tube (the whole mesh restored), keep_apart and fold_over on or off, with that many smoothing
 * passes, into r_positions. */
static lvp_frame_stats correct_smoothed(lvp_binding *binding, const test_posed_rig *tube, int keep_apart,
                                        int fold_over, int smoothing, float *r_positions)
{
	lvp_frame_options options = lvp_frame_default_options();
	options.restore = LVP_RESTORE_WHOLE_MESH;
	options.keep_apart = keep_apart;
	options.fold_over = fold_over;
	options.smoothing_passes = smoothing;
	lvp_frame_stats stats;
	memset(&stats, 0, sizeof(stats));
	lvp_diagnostic diag;
	CHECK_OK(lvp_correct(r_positions, NULL, binding, tube->skinned, tube->posed, NULL, &options, &stats, &diag), diag);
	return stats;
}

static lvp_frame_stats correct_with(lvp_binding *binding, const test_posed_rig *tube, int keep_apart, int fold_over,
                                    float *r_positions)
{
	return correct_smoothed(binding, tube, keep_apart, fold_over, 0, r_positions);
}

static lvp_frame_stats correct(lvp_binding *binding, const test_posed_rig *tube, int keep_apart, float *r_positions)
{
	return correct_with(binding, tube, keep_apart, 0, r_positions);
}

/* The offsets of `corrected` against the skinning, into a new array. */
static float *offsets_of(const test_posed_rig *tube, const float *corrected)
{
	size_t values = 3 * (size_t)tube->rig.vertex_count;
	float *offsets = malloc(sizeof(float) * values);
	for (size_t i = 0; i < values; ++i)
		offsets[i] = corrected[i] - tube->skinned[i];
	return offsets;
}

static void test_one_joint_kept_apart(void)
{
	test_posed_rig tube = make_tube(70.0, false);
	size_t values = 3 * (size_t)tube.rig.vertex_count;
	float *crossing = malloc(sizeof(float) * values), *apart = malloc(sizeof(float) * values);
	lvp_binding *binding = test_bind_rig(&tube.rig, NULL);
	if (binding) {
		lvp_frame_stats without = correct(binding, &tube, 0, crossing);
		lvp_frame_stats with = correct(binding, &tube, 1, apart);
		int64_t plain = test_count_intersecting_pairs(tube.skinned, tube.rig.triangles, tube.rig.triangle_count);
		int64_t before = test_count_intersecting_pairs(crossing, tube.rig.triangles, tube.rig.triangle_count);
		int64_t after = test_count_intersecting_pairs(apart, tube.rig.triangles, tube.rig.triangle_count);
		float *offsets_without = offsets_of(&tube, crossing), *offsets_with = offsets_of(&tube, apart);
		double rough_without = test_roughness(&tube.rig, offsets_without);
		double rough_with = test_roughness(&tube.rig, offsets_with);
		printf("  crossing triangle pairs: plain skinning %lld, corrected %lld, kept apart %lld (%d vertices "
		       "held back, %d shortened); roughness %.3f / %.3f of the largest offset; volume %+.4f%% / %+.4f%%\n",
		       (long long)plain, (long long)before, (long long)after, with.kept_apart_vertices,
		       with.shortened_vertices, rough_without,
		       rough_with, 100 * (without.volume_after / without.volume_rest - 1.0),
		       100 * (with.volume_after / with.volume_rest - 1.0));
		CHECK(before > plain);
		CHECK(after <= plain);
		/* The offsets faded before any pair crossed: nothing left for the crossing test to shorten,
		 * and the fade is as smooth as the offsets themselves. */
		CHECK(with.shortened_vertices == 0 && with.crossing_triangles == 0);
		CHECK(without.shortened_vertices == 0 && without.kept_apart_vertices == 0);
		/* The statistics say so all the same: the fade held the inside of the bend back. */
		CHECK(with.kept_apart_vertices > 0 && with.kept_apart_vertices < tube.rig.vertex_count);
		CHECK(rough_with <= 0.25 && rough_with <= rough_without + 0.02);
		CHECK(fabs(with.volume_after / with.volume_rest - 1.0) < 1e-4);
		free(offsets_without);
		free(offsets_with);
	}
	lvp_free(binding);
	free(crossing);
	free(apart);
	test_posed_rig_free(&tube);
}

static void test_every_joint_kept_apart(void)
{
	test_posed_rig tube = make_tube(71.0, true);
	size_t values = 3 * (size_t)tube.rig.vertex_count;
	float *crossing = malloc(sizeof(float) * values), *apart = malloc(sizeof(float) * values);
	lvp_binding *binding = test_bind_rig(&tube.rig, NULL);
	if (binding) {
		lvp_frame_stats without = correct(binding, &tube, 0, crossing);
		lvp_frame_stats with = correct(binding, &tube, 1, apart);
		int64_t plain = test_count_intersecting_pairs(tube.skinned, tube.rig.triangles, tube.rig.triangle_count);
		int64_t before = test_count_intersecting_pairs(crossing, tube.rig.triangles, tube.rig.triangle_count);
		int64_t after = test_count_intersecting_pairs(apart, tube.rig.triangles, tube.rig.triangle_count);
		printf("  every joint at 71 degrees: %d of %d triangles crossing anew after the fade; crossing pairs "
		       "plain %lld, corrected %lld, kept apart %lld (%d vertices shortened); volume %+.4f%% / %+.4f%%\n",
		       with.crossing_triangles, tube.rig.triangle_count, (long long)plain, (long long)before,
		       (long long)after, with.shortened_vertices, 100 * (without.volume_after / without.volume_rest - 1.0),
		       100 * (with.volume_after / with.volume_rest - 1.0));
		CHECK(with.crossing_triangles > 0); /* what rays along the offsets cannot see, the test takes */
		CHECK(before > plain);
		CHECK(after <= plain);
		CHECK(with.shortened_vertices > 0);
		CHECK(with.kept_apart_vertices >= with.shortened_vertices);
		CHECK(fabs(with.volume_after / with.volume_rest - 1.0) < 1e-3);
	}
	lvp_free(binding);
	free(crossing);
	free(apart);
	test_posed_rig_free(&tube);
}

/* With fold-over too, bent 100 and 140 degrees (plain skinning crosses itself from about 75): never more
 * crossing pairs than plain skinning or fold-over alone (vertices fold-over holds where skinning crosses
 * itself keep their place; shortened as any, 82 and 162 pairs came back where fold-over alone has none).
 * Two angles: the exact count of crossing pairs is the cost here. */
static void test_with_fold_over(void)
{
	for (int degrees = 100; degrees <= 140; degrees += 40) {
		test_posed_rig tube = make_tube(degrees, false);
		size_t values = 3 * (size_t)tube.rig.vertex_count;
		float *folded = malloc(sizeof(float) * values), *apart = malloc(sizeof(float) * values);
		lvp_binding *binding = test_bind_rig(&tube.rig, NULL);
		if (binding) {
			correct_with(binding, &tube, 0, 1, folded);
			lvp_frame_stats with = correct_with(binding, &tube, 1, 1, apart);
			int64_t plain = test_count_intersecting_pairs(tube.skinned, tube.rig.triangles, tube.rig.triangle_count);
			int64_t fold = test_count_intersecting_pairs(folded, tube.rig.triangles, tube.rig.triangle_count);
			int64_t after = test_count_intersecting_pairs(apart, tube.rig.triangles, tube.rig.triangle_count);
			printf("  %3d degrees: crossing pairs plain %lld, fold-over %lld, and kept apart %lld (%d folded, %d "
			       "shortened); volume %+.4f%%\n", degrees, (long long)plain, (long long)fold, (long long)after,
			       with.folded_vertices, with.shortened_vertices, 100 * (with.volume_after / with.volume_rest - 1.0));
			CHECK(after <= plain && after <= fold);
			CHECK(fabs(with.volume_after / with.volume_rest - 1.0) < 2e-3);
		}
		lvp_free(binding);
		free(folded);
		free(apart);
		test_posed_rig_free(&tube);
	}
}

/* The tube with every triangle wound the other way (a mirrored or imported mesh whose faces turn inward),
 * bent from 70 to 90 degrees where its inside closes on itself: kept apart the same, bit for bit. The
 * room in front of a vertex is the skin's, whichever way its triangles turn; while the ball's touch of a
 * triangle's plane was asked about the normal turned towards the vertex, skin facing it counted only at
 * its edges, and the two windings held back 207 and 153 vertices at 80 degrees. */
static void test_either_winding_kept_apart_alike(void)
{
	for (int degrees = 70; degrees <= 90; degrees += 5) {
		test_posed_rig tube = make_tube(degrees, false), turned = make_tube(degrees, false);
		for (int32_t t = 0; t < turned.rig.triangle_count; ++t) {
			int32_t corner = turned.rig.triangles[3 * t + 1];
			turned.rig.triangles[3 * t + 1] = turned.rig.triangles[3 * t + 2];
			turned.rig.triangles[3 * t + 2] = corner;
		}
		size_t values = 3 * (size_t)tube.rig.vertex_count;
		float *apart = malloc(sizeof(float) * values), *turned_apart = malloc(sizeof(float) * values);
		lvp_binding *binding = test_bind_rig(&tube.rig, NULL), *turned_binding = test_bind_rig(&turned.rig, NULL);
		if (binding && turned_binding) {
			lvp_frame_stats with = correct(binding, &tube, 1, apart);
			lvp_frame_stats turned_with = correct(turned_binding, &turned, 1, turned_apart);
			printf("  %d degrees: %d vertices held back, %d wound the other way\n", degrees, with.kept_apart_vertices,
			       turned_with.kept_apart_vertices);
			CHECK(with.kept_apart_vertices > 0);
			CHECK(with.kept_apart_vertices == turned_with.kept_apart_vertices);
			CHECK(memcmp(apart, turned_apart, sizeof(float) * values) == 0);
		}
		lvp_free(binding);
		lvp_free(turned_binding);
		free(apart);
		free(turned_apart);
		test_posed_rig_free(&tube);
		test_posed_rig_free(&turned);
	}
}

/* Keep Skin Apart and fold-over on one to four threads: the same bits (lvp.h, thread_count). The tube bent 71 degrees
 * at every joint, where the crossing test shortens offsets after the fades, and 110 degrees, where fold-over presses
 * too: the clearance searches, the fades, the hierarchy's refits and the crossing rounds all run on the threads. */
static void test_any_thread_count_alike(void)
{
	static const struct {
		double degrees;
		int fold_over, smoothing;
	} cases[] = {{71.0, 0, 0}, {71.0, 0, 6}, {110.0, 1, 6}};
	for (size_t c = 0; c < sizeof(cases) / sizeof(cases[0]); ++c) {
		test_posed_rig tube = make_tube(cases[c].degrees, true);
		size_t values = 3 * (size_t)tube.rig.vertex_count;
		float *corrected[4];
		lvp_frame_stats stats[4];
		memset(stats, 0, sizeof(stats));
		for (int threads = 1; threads <= 4; ++threads) {
			lvp_bind_options bind_options = lvp_bind_default_options();
			bind_options.thread_count = threads;
			corrected[threads - 1] = calloc(values, sizeof(float));
			lvp_binding *binding = test_bind_rig(&tube.rig, &bind_options);
			if (!binding)
				continue;
			stats[threads - 1] = correct_smoothed(binding, &tube, 1, cases[c].fold_over, cases[c].smoothing,
			                                      corrected[threads - 1]);
			lvp_free(binding);
		}
		printf("  %.0f degrees at every joint%s, smoothing %d: %d vertices shortened, %d folded\n", cases[c].degrees,
		       cases[c].fold_over ? ", fold-over" : "", cases[c].smoothing, stats[0].shortened_vertices,
		       stats[0].folded_vertices);
		CHECK(stats[0].shortened_vertices > 0); /* the crossing rounds ran */
		CHECK(!cases[c].fold_over || stats[0].folded_vertices > 0);
		for (int threads = 2; threads <= 4; ++threads)
			CHECK(memcmp(corrected[0], corrected[threads - 1], sizeof(float) * values) == 0);
		for (int threads = 1; threads <= 4; ++threads)
			free(corrected[threads - 1]);
		test_posed_rig_free(&tube);
	}
}

int main(void)
{
	RUN(test_one_joint_kept_apart);
	RUN(test_every_joint_kept_apart);
	RUN(test_with_fold_over);
	RUN(test_either_winding_kept_apart_alike);
	RUN(test_any_thread_count_alike);
	return check_failures() != 0;
}
