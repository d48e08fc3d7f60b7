/*
 * test_bad_input.c - every kind of bad or awkward input gets its defined outcome (lvp.h,
 * FALLBACKS): a clear error naming the argument, outputs untouched, or the documented
 * fallback. Also the painted map and the per-region bone restriction of the organic map.
 */
#include "lvp.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

typedef struct scene {
	test_rig rig;
	float posed[32];
	float *skinned;
} scene;

static scene bent_cylinder(double degrees)
{
	scene s;
	s.rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(degrees * PI / 180.0)};
	float skin[32];
	test_pose(s.posed, &s.rig, rotations);
	test_skin_matrices(skin, &s.rig, s.posed);
	s.skinned = malloc(sizeof(float) * 3 * (size_t)s.rig.vertex_count);
	lvp_weights weights = test_rig_weights(&s.rig);
	lvp_skin_linear(s.skinned, s.rig.positions, s.rig.vertex_count, &weights, skin, 2, NULL);
	return s;
}

static void free_scene(scene *s)
{
	test_rig_free(&s->rig);
	free(s->skinned);
}

static lvp_result bind(lvp_binding **r_binding, const test_rig *rig, const lvp_bind_options *options,
                       lvp_diagnostic *r_diag)
{
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	return lvp_bind(r_binding, rig->positions, rig->vertex_count, rig->triangles, rig->triangle_count, &weights,
	                &skeleton, options, r_diag);
}

/* A failing bind names the argument, leaves *r_binding NULL. */
static void expect_bind_error(const test_rig *rig, const lvp_bind_options *options, lvp_result expected,
                              const char *argument)
{
	lvp_binding *binding = (lvp_binding *)&binding; /* not NULL: must be reset */
	lvp_diagnostic diag;
	memset(&diag, 0, sizeof(diag));
	lvp_result result = bind(&binding, rig, options, &diag);
	CHECK(result == expected);
	CHECK(binding == NULL);
	CHECK(diag.argument && strcmp(diag.argument, argument) == 0);
	CHECK(strlen(diag.message) > 20);
	if (result != expected || !diag.argument || strcmp(diag.argument, argument) != 0)
		printf("  got %s on %s: %s\n", lvp_result_name(result), diag.argument ? diag.argument : "-", diag.message);
	if (result == lvp_success)
		lvp_free(binding);
}

static void test_bind_errors_name_the_argument(void)
{
	scene s = bent_cylinder(0);
	test_rig *rig = &s.rig;

	int32_t saved = rig->triangles[7];
	rig->triangles[7] = rig->vertex_count;
	expect_bind_error(rig, NULL, lvp_error_index_out_of_range, "triangles");
	rig->triangles[7] = -1;
	expect_bind_error(rig, NULL, lvp_error_index_out_of_range, "triangles");
	rig->triangles[7] = saved;

	float position = rig->positions[5];
	rig->positions[5] = NAN;
	expect_bind_error(rig, NULL, lvp_error_not_finite, "rest_positions");
	rig->positions[5] = INFINITY;
	expect_bind_error(rig, NULL, lvp_error_not_finite, "rest_positions");
	rig->positions[5] = position;

	float weight = rig->weight_values[3];
	rig->weight_values[3] = -0.5f;
	expect_bind_error(rig, NULL, lvp_error_negative_weight, "weights.values");
	rig->weight_values[3] = weight;

	int32_t bone = rig->weight_bones[3];
	rig->weight_bones[3] = 2;
	expect_bind_error(rig, NULL, lvp_error_index_out_of_range, "weights.bones");
	rig->weight_bones[3] = bone;

	float matrix[16];
	memcpy(matrix, rig->rest_matrices + 16, sizeof(matrix));
	for (int i = 0; i < 3; ++i)
		for (int j = 0; j < 3; ++j)
			rig->rest_matrices[16 + 4 * i + j] = 0.0f;
	expect_bind_error(rig, NULL, lvp_error_singular_matrix, "skeleton.rest_matrices");
	memcpy(rig->rest_matrices + 16, matrix, sizeof(matrix));

	lvp_bind_options options = lvp_bind_default_options();
	options.map.alpha = -1.0f;
	expect_bind_error(rig, &options, lvp_error_invalid_option, "map.alpha");
	options = lvp_bind_default_options();
	options.thread_count = 0;
	expect_bind_error(rig, &options, lvp_error_invalid_option, "options.thread_count");
	int32_t groups[2] = {0, 2}; /* a group is named by a bone index */
	options = lvp_bind_default_options();
	options.bone_groups = groups;
	expect_bind_error(rig, &options, lvp_error_index_out_of_range, "options.bone_groups");
	options = lvp_bind_default_options();
	options.map.map = LVP_MAP_PAINTED; /* without the painted values */
	expect_bind_error(rig, &options, lvp_error_null_argument, "map.painted");

	/* no vertex weighted at all */
	int32_t *offsets = rig->weight_offsets;
	int32_t *empty = calloc((size_t)rig->vertex_count + 1, sizeof(int32_t));
	rig->weight_offsets = empty;
	expect_bind_error(rig, NULL, lvp_error_no_weights, "weights");
	rig->weight_offsets = offsets;
	free(empty);

	/* sizes */
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	CHECK(lvp_bind(&binding, rig->positions, 0, rig->triangles, rig->triangle_count, &weights, &skeleton, NULL,
	               &diag) == lvp_error_invalid_size);
	CHECK(strcmp(diag.argument, "vertex_count") == 0);
	CHECK(lvp_bind(&binding, rig->positions, rig->vertex_count, rig->triangles, -3, &weights, &skeleton, NULL,
	               &diag) == lvp_error_invalid_size);
	CHECK(strcmp(diag.argument, "triangle_count") == 0);
	CHECK(lvp_bind(&binding, NULL, rig->vertex_count, rig->triangles, rig->triangle_count, &weights, &skeleton,
	               NULL, &diag) == lvp_error_null_argument);
	CHECK(lvp_bind(NULL, rig->positions, rig->vertex_count, rig->triangles, rig->triangle_count, &weights,
	               &skeleton, NULL, &diag) == lvp_error_null_argument);
	free_scene(&s);
}

static void test_frame_errors_leave_outputs_untouched(void)
{
	scene s = bent_cylinder(60);
	int32_t n = s.rig.vertex_count;
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(bind(&binding, &s.rig, NULL, &diag), diag);
	float *out = malloc(sizeof(float) * 3 * (size_t)n);
	for (int32_t i = 0; i < 3 * n; ++i)
		out[i] = 12345.0f;
	s.skinned[40] = NAN;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, NULL, NULL, &diag) == lvp_error_not_finite);
	CHECK(strcmp(diag.argument, "positions") == 0 && diag.index == 40);
	s.skinned[40] = 0.0f;
	float matrix = s.posed[16 + 3];
	s.posed[16 + 3] = INFINITY;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, NULL, NULL, &diag) == lvp_error_not_finite);
	CHECK(strcmp(diag.argument, "bone_matrices") == 0);
	s.posed[16 + 3] = matrix;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, NULL, NULL, NULL, NULL, &diag) == lvp_error_null_argument);
	CHECK(lvp_correct(NULL, NULL, binding, s.skinned, s.posed, NULL, NULL, NULL, &diag) == lvp_error_null_argument);
	lvp_frame_options options = lvp_frame_default_options();
	options.max_iterations = 0;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, &options, NULL, &diag) ==
	      lvp_error_invalid_option);
	options = lvp_frame_default_options();
	options.tolerance = NAN;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, &options, NULL, &diag) ==
	      lvp_error_invalid_option);
	CHECK(strcmp(diag.argument, "options.tolerance") == 0);
	/* A rigid space that cannot be inverted, or is not finite (lvp.h, lvp_frame_options). */
	float space[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1};
	options = lvp_frame_default_options();
	options.rigid_space = space;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, &options, NULL, &diag) ==
	      lvp_error_invalid_option);
	CHECK(strcmp(diag.argument, "options.rigid_space") == 0);
	space[10] = NAN;
	CHECK(lvp_correct(out, NULL, binding, s.skinned, s.posed, NULL, &options, NULL, &diag) == lvp_error_not_finite);
	CHECK(strcmp(diag.argument, "options.rigid_space") == 0 && diag.index == 10);
	CHECK(lvp_correct(out, NULL, NULL, s.skinned, s.posed, NULL, NULL, NULL, &diag) == lvp_error_null_argument);
	for (int32_t i = 0; i < 3 * n; ++i)
		CHECK(out[i] == 12345.0f);
	free(out);
	lvp_free(binding);
	free_scene(&s);
}

/* A bone scaled to zero in the pose: its region is left as it is and counted, nothing breaks. */
static void test_singular_posed_bone_skips_its_region(void)
{
	scene s = bent_cylinder(60);
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(bind(&binding, &s.rig, NULL, &diag), diag);
	for (int i = 0; i < 3; ++i)
		for (int j = 0; j < 3; ++j)
			s.posed[16 + 4 * i + j] = 0.0f;
	float *offsets = malloc(sizeof(float) * 3 * (size_t)s.rig.vertex_count);
	lvp_frame_stats stats;
	CHECK_OK(lvp_correct(NULL, offsets, binding, s.skinned, s.posed, NULL, NULL, &stats, &diag), diag);
	CHECK(stats.skipped_regions == 1);
	for (int32_t i = 0; i < 3 * s.rig.vertex_count; ++i)
		CHECK(isfinite(offsets[i]));
	free(offsets);
	lvp_free(binding);
	free_scene(&s);
}

/* Awkward but valid meshes: an isolated vertex, a zero-area triangle, a triangle repeating a
 * vertex, an unweighted vertex, an open mesh (a cap removed), a zero-length bone. */
static void test_awkward_meshes_have_defined_outcomes(void)
{
	scene s = bent_cylinder(70);
	test_rig *rig = &s.rig;
	int32_t n = rig->vertex_count, f = rig->triangle_count;
	/* one extra isolated vertex, unweighted */
	float *positions = malloc(sizeof(float) * 3 * ((size_t)n + 1));
	float *skinned = malloc(sizeof(float) * 3 * ((size_t)n + 1));
	memcpy(positions, rig->positions, sizeof(float) * 3 * (size_t)n);
	memcpy(skinned, s.skinned, sizeof(float) * 3 * (size_t)n);
	positions[3 * n] = skinned[3 * n] = 5.0f;
	positions[3 * n + 1] = skinned[3 * n + 1] = 5.0f;
	positions[3 * n + 2] = skinned[3 * n + 2] = 5.0f;
	int32_t *offsets = malloc(sizeof(int32_t) * ((size_t)n + 2));
	memcpy(offsets, rig->weight_offsets, sizeof(int32_t) * ((size_t)n + 1));
	offsets[n + 1] = offsets[n];
	/* triangles: drop the 16 triangles of the last cap (open mesh), add a zero-area sliver
	 * and a triangle that repeats a vertex */
	int32_t kept = f - 16;
	int32_t *triangles = malloc(sizeof(int32_t) * 3 * ((size_t)kept + 2));
	memcpy(triangles, rig->triangles, sizeof(int32_t) * 3 * (size_t)kept);
	int32_t extra[6] = {0, 1, 1, 2, 3, 2};
	memcpy(triangles + 3 * kept, extra, sizeof(extra));
	/* a third, zero-length bone at the tip, unused */
	float matrices[48], heads[9], tails[9], posed[48];
	memcpy(matrices, rig->rest_matrices, sizeof(float) * 32);
	memcpy(matrices + 32, rig->rest_matrices + 16, sizeof(float) * 16);
	memcpy(heads, rig->heads, sizeof(float) * 6);
	memcpy(tails, rig->tails, sizeof(float) * 6);
	memcpy(heads + 6, rig->tails + 3, sizeof(float) * 3);
	memcpy(tails + 6, rig->tails + 3, sizeof(float) * 3);
	memcpy(posed, s.posed, sizeof(float) * 32);
	memcpy(posed + 32, s.posed + 16, sizeof(float) * 16);
	lvp_weights weights = {offsets, rig->weight_bones, rig->weight_values};
	lvp_skeleton skeleton = {3, matrices, heads, tails, NULL};
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(lvp_bind(&binding, positions, n + 1, triangles, kept + 2, &weights, &skeleton, NULL, &diag), diag);
	if (binding) {
		float *out = malloc(sizeof(float) * 3 * ((size_t)n + 1));
		lvp_frame_options options = lvp_frame_default_options();
		options.fold_over = 1;
		lvp_frame_stats stats;
		CHECK_OK(lvp_correct(out, NULL, binding, skinned, posed, NULL, &options, &stats, &diag), diag);
		CHECK(out[3 * n] == 5.0f && out[3 * n + 1] == 5.0f && out[3 * n + 2] == 5.0f); /* isolated: stays */
		for (int32_t i = 0; i < 3 * (n + 1); ++i)
			CHECK(isfinite(out[i]));
		/* the open mesh's volume (hole capped) is still restored */
		CHECK(fabs(stats.volume_after - stats.volume_rest) < 1e-3 * fabs(stats.volume_rest));
		int32_t regions[300];
		lvp_get_segmentation(binding, regions, NULL);
		CHECK(regions[n] == -1);
		free(out);
		lvp_free(binding);
	}
	/* The global mode refuses the open mesh, naming the triangles. */
	lvp_bind_options global = lvp_bind_default_options();
	global.mode = LVP_MODE_GLOBAL;
	CHECK(lvp_bind(&binding, positions, n + 1, triangles, kept, &weights, &skeleton, &global, &diag) ==
	      lvp_error_mesh_not_closed);
	CHECK(strcmp(diag.argument, "triangles") == 0);
	free(positions);
	free(skinned);
	free(offsets);
	free(triangles);
	free_scene(&s);
}

/* A skinned mesh joined with more loose vertices than four times its triangles' corners (a point cloud or an
 * edge-only hair guide in the same object): binds and corrects, the loose vertices where they were. The bind's
 * scratch for welding seam copies was sized by the triangles' directed edges alone (12 a triangle) and
 * overflowed. */
static void test_many_loose_vertices(void)
{
	scene s = bent_cylinder(70);
	test_rig *rig = &s.rig;
	int32_t n = rig->vertex_count, f = rig->triangle_count, loose = 12 * f + 50, total = n + loose;
	float *positions = malloc(sizeof(float) * 3 * (size_t)total), *skinned = malloc(sizeof(float) * 3 * (size_t)total);
	float *out = malloc(sizeof(float) * 3 * (size_t)total);
	int32_t *offsets = malloc(sizeof(int32_t) * ((size_t)total + 1));
	memcpy(positions, rig->positions, sizeof(float) * 3 * (size_t)n);
	memcpy(skinned, s.skinned, sizeof(float) * 3 * (size_t)n);
	memcpy(offsets, rig->weight_offsets, sizeof(int32_t) * ((size_t)n + 1));
	for (int32_t k = n; k < total; ++k) { /* unweighted, on a line beside the cylinder, two at each place */
		for (int axis = 0; axis < 3; ++axis)
			positions[3 * k + axis] = skinned[3 * k + axis] = axis == 0 ? 3.0f + 0.01f * (float)((k - n) / 2) : 0.5f;
		offsets[k + 1] = offsets[n];
	}
	lvp_weights weights = {offsets, rig->weight_bones, rig->weight_values};
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(lvp_bind(&binding, positions, total, rig->triangles, f, &weights, &skeleton, NULL, &diag), diag);
	if (binding) {
		lvp_frame_stats stats;
		CHECK_OK(lvp_correct(out, NULL, binding, skinned, s.posed, NULL, NULL, &stats, &diag), diag);
		CHECK(memcmp(out + 3 * (size_t)n, skinned + 3 * (size_t)n, sizeof(float) * 3 * (size_t)loose) == 0);
		CHECK(fabs(stats.volume_after - stats.volume_rest) < 1e-3 * fabs(stats.volume_rest));
		lvp_free(binding);
	}
	free(positions);
	free(skinned);
	free(out);
	free(offsets);
	free_scene(&s);
}

/* Triangles wound against their neighbours (faces whose normals were flipped) are counted, so
 * that the caller can say so: the local volumes across them are wrong. A mesh wound the other way
 * everywhere is consistent. */
static void test_flipped_triangles_are_counted(void)
{
	scene s = bent_cylinder(0);
	test_rig *rig = &s.rig;
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(bind(&binding, rig, NULL, &diag), diag);
	CHECK(lvp_flipped_edge_count(binding) == 0);
	lvp_free(binding);
	/* One side triangle flipped: its three edges each join it to an unflipped neighbour. */
	int32_t t = rig->triangle_count / 2, swap = rig->triangles[3 * t + 1];
	rig->triangles[3 * t + 1] = rig->triangles[3 * t + 2];
	rig->triangles[3 * t + 2] = swap;
	CHECK_OK(bind(&binding, rig, NULL, &diag), diag);
	CHECK(lvp_flipped_edge_count(binding) == 3);
	lvp_free(binding);
	/* All flipped (wound inward): consistent again. */
	for (int32_t k = 0; k < rig->triangle_count; ++k) {
		if (k == t)
			continue;
		swap = rig->triangles[3 * k + 1];
		rig->triangles[3 * k + 1] = rig->triangles[3 * k + 2];
		rig->triangles[3 * k + 2] = swap;
	}
	CHECK_OK(bind(&binding, rig, NULL, &diag), diag);
	CHECK(lvp_flipped_edge_count(binding) == 0);
	lvp_free(binding);
	CHECK(lvp_flipped_edge_count(NULL) == 0);
	free_scene(&s);
}

/* The painted map moves only what is painted; the Fig. 11 restriction changes the organic map. */
static void test_painted_map_and_region_restriction(void)
{
	scene s = bent_cylinder(60);
	int32_t n = s.rig.vertex_count;
	float *painted = calloc((size_t)n, sizeof(float));
	for (int32_t k = 0; k < n; ++k)
		if (s.rig.positions[3 * k + 1] > 0.2f) /* one side of the cylinder only */
			painted[k] = 1.0f;
	lvp_bind_options options = lvp_bind_default_options();
	options.map.map = LVP_MAP_PAINTED;
	options.map.painted = painted;
	options.map.deformation_weighted = 0;
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(bind(&binding, &s.rig, &options, &diag), diag);
	float *offsets = malloc(sizeof(float) * 3 * (size_t)n);
	lvp_frame_stats stats;
	CHECK_OK(lvp_correct(NULL, offsets, binding, s.skinned, s.posed, NULL, NULL, &stats, &diag), diag);
	int32_t moved_unpainted = 0, moved_painted = 0;
	for (int32_t k = 0; k < n; ++k) {
		bool moved = offsets[3 * k] != 0.0f || offsets[3 * k + 1] != 0.0f || offsets[3 * k + 2] != 0.0f;
		moved_unpainted += moved && painted[k] == 0.0f;
		moved_painted += moved && painted[k] > 0.0f;
	}
	CHECK(moved_unpainted == 0 && moved_painted > 0);
	CHECK(fabs(stats.volume_after - stats.volume_rest) < 1e-3 * stats.volume_rest);

	/* Fig. 11: measure region 1's distances to bone 0 only; the map changes there. */
	float *before = malloc(sizeof(float) * (size_t)n), *after = malloc(sizeof(float) * (size_t)n);
	lvp_map_options map = options.map;
	map.map = LVP_MAP_ORGANIC;
	map.painted = NULL;
	CHECK_OK(lvp_set_map(binding, &map, &diag), diag);
	lvp_get_correction_map(binding, before);
	int32_t region_offsets[3] = {0, 0, 1}, region_bones[1] = {0};
	map.region_bone_offsets = region_offsets;
	map.region_bones = region_bones;
	CHECK_OK(lvp_set_map(binding, &map, &diag), diag);
	lvp_get_correction_map(binding, after);
	int32_t changed = 0;
	int32_t *regions = malloc(sizeof(int32_t) * (size_t)n);
	lvp_get_segmentation(binding, regions, NULL);
	for (int32_t k = 0; k < n; ++k) {
		if (regions[k] == 0)
			CHECK(before[k] == 0.0f || fabs(before[k] - after[k]) < 0.6f); /* renormalized, same shape */
		changed += regions[k] == 1 && before[k] != after[k];
	}
	CHECK(changed > 0);
	map.region_bones = NULL; /* offsets without bones */
	CHECK(lvp_set_map(binding, &map, &diag) == lvp_error_null_argument);
	free(regions);
	free(before);
	free(after);
	free(offsets);
	free(painted);
	lvp_free(binding);
	free_scene(&s);
}

int main(void)
{
	RUN(test_bind_errors_name_the_argument);
	RUN(test_frame_errors_leave_outputs_untouched);
	RUN(test_singular_posed_bone_skips_its_region);
	RUN(test_awkward_meshes_have_defined_outcomes);
	RUN(test_many_loose_vertices);
	RUN(test_painted_map_and_region_restriction);
	RUN(test_flipped_triangles_are_counted);
	return check_failures() != 0;
}
