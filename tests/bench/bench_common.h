/*
 * bench_common.h - what the core's benchmarks share (bench_core.c, bench_keep_apart.c): wall time,
 * medians, and the poses they time (a chain bent at one joint or all, the giraffe at five joints).
 */
#ifndef LVP_BENCH_COMMON_H
#define LVP_BENCH_COMMON_H

#include "lvp.h"
#include "support/test_meshes.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifndef PI
#define PI 3.14159265358979323846
#endif
/* Poses a benchmark's animation goes through: the case's bend at 100, 95 and 90 %. */
#define POSES 3

static double now(void)
{
	struct timespec t;
	clock_gettime(CLOCK_MONOTONIC, &t);
	return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int compare_doubles(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

/* The median of `values` (sorted in place). */
static double median(double *values, int count)
{
	qsort(values, (size_t)count, sizeof(double), compare_doubles);
	return count % 2 ? values[count / 2] : 0.5 * (values[count / 2 - 1] + values[count / 2]);
}

/* Axis-angle rotations (bone_count*4) bending a chain's middle joint, or every joint, by `degrees`. */
static float *chain_pose(int32_t bone_count, int bend_all, double degrees)
{
	float *rotations = calloc((size_t)bone_count * 4, sizeof(float));
	for (int32_t i = 1; i < bone_count; ++i) {
		if (!bend_all && i != bone_count / 2)
			continue;
		rotations[4 * i] = 1.0f;
		rotations[4 * i + 3] = (float)(degrees * PI / 180.0);
	}
	return rotations;
}

/* The giraffe bent 45 degrees at three neck joints, an elbow and a knee. */
static float *giraffe_pose(const test_rig *rig)
{
	float *rotations = calloc((size_t)rig->bone_count * 4, sizeof(float));
	const char *bent[] = {"gi_neckC7", "gi_neckC4", "gi_neckC2", "gi_L_elbow", "gi_R_knee"};
	for (int i = 0; i < 5; ++i) {
		int32_t bone = test_find_bone(rig, bent[i]);
		if (bone < 0)
			continue;
		const float *m = rig->rest_matrices + 16 * bone;
		for (int c = 0; c < 3; ++c)
			rotations[4 * bone + c] = m[4 * c]; /* world +X in the joint's frame */
		rotations[4 * bone + 3] = (float)(45.0 * PI / 180.0);
	}
	return rotations;
}

/* The animation of `rotations` (bone_count*4, axis and angle): posed[pose] its bone frames (every other bone from
 * the second scaled by `stretch`) and skinned[pose] the rest skinned by them, each allocated here. */
static void pose_animation(const test_rig *rig, const float *rotations, float stretch, float *posed[POSES],
                           float *skinned[POSES])
{
	int32_t n = rig->vertex_count, b = rig->bone_count;
	float *skin = malloc(sizeof(float) * 16 * (size_t)b), *scaled = malloc(sizeof(float) * 4 * (size_t)b);
	lvp_weights weights = test_rig_weights(rig);
	for (int pose = 0; pose < POSES; ++pose) {
		memcpy(scaled, rotations, sizeof(float) * 4 * (size_t)b);
		for (int32_t i = 0; i < b; ++i)
			scaled[4 * i + 3] *= 1.0f - 0.05f * (float)pose;
		posed[pose] = malloc(sizeof(float) * 16 * (size_t)b);
		skinned[pose] = malloc(sizeof(float) * 3 * (size_t)n);
		test_pose(posed[pose], rig, scaled);
		for (int32_t i = 1; i < b && stretch != 1.0f; i += 2)
			test_scale_bone(posed[pose] + 16 * i, stretch, stretch, stretch);
		test_skin_matrices(skin, rig, posed[pose]);
		lvp_skin_linear(skinned[pose], rig->positions, n, &weights, skin, b, NULL);
	}
	free(skin);
	free(scaled);
}

#endif
