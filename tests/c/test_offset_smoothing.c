/*
 * test_offset_smoothing.c - the offsets smoothed over the surface (lvp.h, OFFSET SMOOTHING): on the
 * finger of test_foldover.c bent 100 degrees at both knuckles, where the inside of each knuckle
 * folds and neighbouring normals turn fast, 2 passes leave the offsets less rough (each offset
 * against the mean of its neighbours', over the largest), the volume restored as closely, and the
 * skin that follows one bone rigidly unmoved; on quads ten times longer along a cylinder than around
 * it, a ridge carried along; on a chain of 41,000 vertices bent at every joint, the same offsets for
 * any number of threads.
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

/* The offsets of the correction (the whole mesh restored, `passes` of smoothing) into r_offsets. */
static lvp_frame_stats correct(lvp_binding *binding, const float *posed, const float *skinned, int passes,
                               float *r_offsets)
{
	lvp_frame_options options = lvp_frame_default_options();
	options.restore = LVP_RESTORE_WHOLE_MESH;
	options.smoothing_passes = passes;
	lvp_frame_stats stats;
	memset(&stats, 0, sizeof(stats));
	lvp_diagnostic diag;
	CHECK_OK(lvp_correct(NULL, r_offsets, binding, skinned, posed, NULL, &options, &stats, &diag), diag);
	return stats;
}

static double length3(const float *v)
{
	return sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
}

static void test_smoother_finger(void)
{
	test_rig rig = test_make_finger();
	float rotations[12] = {0, 0, 0, 0, 1, 0, 0, (float)(100 * PI / 180), 1, 0, 0, (float)(100 * PI / 180)};
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	size_t values = 3 * (size_t)rig.vertex_count;
	float *plain = calloc(values, sizeof(float)), *smoothed = calloc(values, sizeof(float));
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	if (binding && posed && skinned) {
		lvp_frame_stats without = correct(binding, posed, skinned, 0, plain);
		lvp_frame_stats with = correct(binding, posed, skinned, 2, smoothed);
		double rough_without = test_roughness(&rig, plain), rough_with = test_roughness(&rig, smoothed);
		double error_without = without.volume_after / without.volume_rest - 1.0;
		double error_with = with.volume_after / with.volume_rest - 1.0;
		printf("  finger at 100/100 degrees: roughness %.3f -> %.3f of the largest offset; volume %+.4f%% -> "
		       "%+.4f%% (plain skinning %+.2f%%), %d -> %d steps\n",
		       rough_without, rough_with, 100 * error_without, 100 * error_with,
		       100 * (with.volume_before / with.volume_rest - 1.0), without.iterations, with.iterations);
		CHECK(rough_with < 0.8 * rough_without);
		CHECK(fabs(error_with) < 2e-4);
		int32_t moved_only_smoothed = 0;
		for (int32_t k = 0; k < rig.vertex_count; ++k)
			moved_only_smoothed += length3(plain + 3 * k) == 0.0 && length3(smoothed + 3 * k) != 0.0;
		CHECK(moved_only_smoothed == 0); /* what follows one bone rigidly stays where skinning put it */
	}
	lvp_free(binding);
	free(plain);
	free(smoothed);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

/* More passes, smoother offsets, until the offsets take the shape the skin that can move allows
 * (0.20 of the largest offset here, from 16 passes on: the skin around is held where skinning put
 * it): the volume the passes take is restored along the smoothed offsets themselves (each grows by
 * one factor), so it does not come back where the map peaks and undo the smoothing there; the
 * volume is restored as closely whatever the passes. */
static void test_more_passes_smoother(void)
{
	test_rig rig = test_make_finger();
	float rotations[12] = {0, 0, 0, 0, 1, 0, 0, (float)(100 * PI / 180), 1, 0, 0, (float)(100 * PI / 180)};
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	float *offsets = calloc(3 * (size_t)rig.vertex_count, sizeof(float));
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	if (binding && posed && skinned) {
		static const int passes[] = {0, 2, 6, 16, 64};
		double before = INFINITY;
		for (size_t i = 0; i < sizeof(passes) / sizeof(passes[0]); ++i) {
			lvp_frame_stats stats = correct(binding, posed, skinned, passes[i], offsets);
			double rough = test_roughness(&rig, offsets), error = stats.volume_after / stats.volume_rest - 1.0;
			printf("  %2d passes: roughness %.3f of the largest offset, volume %+.4f%%\n", passes[i], rough,
			       100 * error);
			CHECK(passes[i] <= 6 ? rough < 0.9 * before : rough < before + 0.01);
			CHECK(fabs(error) < 2e-4);
			before = rough;
		}
	}
	lvp_free(binding);
	free(offsets);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

/* The paper's cylinder bent 90 degrees, and the same with a twin ring 2 % of the ring spacing above
 * every odd ring: the twins' short edges have cotangents in the tens across them, which tie each pair
 * into one point; the passes must still bring that point to its ring as they bring any vertex, so the
 * twinned cylinder's offsets are nearly as smooth as the plain one's (its rings are spaced unevenly,
 * which the roughness, a mean over each vertex's neighbours, sees too). */
static void test_short_edges_smoothed_as_any(void)
{
	test_rig plain_rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	test_rig twin_rig = test_make_cylinder_twinned(16, 16, 0.5f, 4.0f, 2.6f, 0.02f);
	test_rig *rigs[2] = {&plain_rig, &twin_rig};
	double rough[2] = {0.0, 0.0};
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(90 * PI / 180)};
	for (int i = 0; i < 2; ++i) {
		float *posed = NULL, *skinned = NULL;
		CHECK(test_pose_and_skin(rigs[i], rotations, &posed, &skinned) == 0);
		float *offsets = calloc(3 * (size_t)rigs[i]->vertex_count, sizeof(float));
		lvp_binding *binding = test_bind_rig(rigs[i], NULL);
		if (binding && posed && skinned && offsets) {
			lvp_frame_stats stats = correct(binding, posed, skinned, 6, offsets);
			rough[i] = test_roughness(rigs[i], offsets);
			printf("  %s cylinder (%d vertices) at 90 degrees, 6 passes: roughness %.3f of the largest offset, "
			       "volume %+.4f%%\n",
			       i ? "twinned" : "plain", rigs[i]->vertex_count, rough[i],
			       100 * (stats.volume_after / stats.volume_rest - 1.0));
			CHECK(fabs(stats.volume_after / stats.volume_rest - 1.0) < 2e-4);
		}
		lvp_free(binding);
		free(offsets);
		free(posed);
		free(skinned);
	}
	/* Each pair moving as one point but lagging its ring left them 1.7 times as rough. */
	CHECK(rough[1] > 0.0 && rough[1] < 1.5 * rough[0]);
	test_rig_free(&plain_rig);
	test_rig_free(&twin_rig);
}

/* A cylinder of quads ten times longer along it than around it (64 around, 8 rings), as a limb of a body
 * modelled as a box and subdivided, its weights blending over one ring at the joint, bent 90 degrees: the
 * mesh's weights tie each vertex to its ring, and the bulge the map puts on that ring stays a ridge one ring
 * wide (6 passes of them alone leave 0.86 of the roughness before the passes); the passes with equal weights
 * carry it along the cylinder (0.76). */
static void test_long_quads_smoothed_along(void)
{
	test_rig rig = test_make_cylinder(64, 8, 0.5f, 4.0f, 1.0f);
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(90 * PI / 180)};
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	float *offsets = calloc(3 * (size_t)rig.vertex_count, sizeof(float));
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	if (binding && posed && skinned && offsets) {
		double rough[2];
		static const int passes[2] = {0, 6};
		for (int i = 0; i < 2; ++i) {
			lvp_frame_stats stats = correct(binding, posed, skinned, passes[i], offsets);
			rough[i] = test_roughness(&rig, offsets);
			printf("  long quads (%d vertices) at 90 degrees, %d passes: roughness %.3f of the largest offset, "
			       "volume %+.4f%%\n",
			       rig.vertex_count, passes[i], rough[i], 100 * (stats.volume_after / stats.volume_rest - 1.0));
			CHECK(fabs(stats.volume_after / stats.volume_rest - 1.0) < 2e-4);
		}
		CHECK(rough[1] < 0.8 * rough[0]);
	}
	lvp_free(binding);
	free(offsets);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

static void test_same_for_any_thread_count(void)
{
	/* Enough moving vertices (every joint bent) for the passes to be split between threads. */
	test_rig rig = test_make_chain(8, 1.0f, 0.3f, 64, 80, 1.0f);
	float *rotations = calloc((size_t)rig.bone_count * 4, sizeof(float));
	for (int32_t i = 1; i < rig.bone_count; ++i) {
		rotations[4 * i] = 1.0f;
		rotations[4 * i + 3] = (float)(40 * PI / 180);
	}
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	size_t values = 3 * (size_t)rig.vertex_count;
	float *one = calloc(values, sizeof(float)), *four = calloc(values, sizeof(float));
	lvp_bind_options options = lvp_bind_default_options();
	lvp_binding *single = test_bind_rig(&rig, &options);
	options.thread_count = 4;
	lvp_binding *threaded = test_bind_rig(&rig, &options);
	if (single && threaded && posed && skinned) {
		correct(single, posed, skinned, 3, one);
		correct(threaded, posed, skinned, 3, four);
		int32_t moved = 0;
		for (int32_t k = 0; k < rig.vertex_count; ++k)
			moved += length3(one + 3 * k) > 0.0;
		printf("  %d vertices, %d of them moved by the correction\n", rig.vertex_count, moved);
		CHECK(moved > 8 * 4096); /* LVP__GRAIN: below that the passes run on one thread */
		CHECK(memcmp(one, four, sizeof(float) * values) == 0);
	}
	lvp_free(single);
	lvp_free(threaded);
	free(one);
	free(four);
	free(rotations);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

int main(void)
{
	RUN(test_smoother_finger);
	RUN(test_more_passes_smoother);
	RUN(test_short_edges_smoothed_as_any);
	RUN(test_long_quads_smoothed_along);
	RUN(test_same_for_any_thread_count);
	return check_failures() != 0;
}
