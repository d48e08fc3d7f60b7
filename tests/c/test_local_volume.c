/*
 * test_local_volume.c - paper 5.2: the local volume change of each region, computed by the
 * core with the shared side quads cancelled and the tops moved into the bone frame in closed
 * form, equals the explicit sum of every prism (rest and deformed triangle in the bone's local
 * frame, three side quads each split in four at its centroid), on a closed cylinder and on the
 * open giraffe, deformed by skinning and by noise so that nothing cancels by symmetry.
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

typedef struct vec3 {
	double x, y, z;
} vec3;

static vec3 cross(vec3 a, vec3 b)
{
	return (vec3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
static double dot(vec3 a, vec3 b)
{
	return a.x * b.x + a.y * b.y + a.z * b.z;
}
static double vol6(vec3 a, vec3 b, vec3 c)
{
	return dot(a, cross(b, c));
}

/* p -> M^-1 p for an affine row-major matrix. */
static vec3 to_local(const float *m, const float *p)
{
	double a[9] = {m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]};
	double det = a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) +
	             a[2] * (a[3] * a[7] - a[4] * a[6]);
	double inv[9] = {(a[4] * a[8] - a[5] * a[7]) / det, (a[2] * a[7] - a[1] * a[8]) / det,
	                 (a[1] * a[5] - a[2] * a[4]) / det, (a[5] * a[6] - a[3] * a[8]) / det,
	                 (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
	                 (a[3] * a[7] - a[4] * a[6]) / det, (a[1] * a[6] - a[0] * a[7]) / det,
	                 (a[0] * a[4] - a[1] * a[3]) / det};
	double d[3] = {p[0] - m[3], p[1] - m[7], p[2] - m[11]};
	return (vec3){inv[0] * d[0] + inv[1] * d[1] + inv[2] * d[2], inv[3] * d[0] + inv[4] * d[1] + inv[5] * d[2],
	              inv[6] * d[0] + inv[7] * d[1] + inv[8] * d[2]};
}

static double det3(const float *m)
{
	return m[0] * ((double)m[5] * m[10] - (double)m[6] * m[9]) - m[1] * ((double)m[4] * m[10] - (double)m[6] * m[8]) +
	       m[2] * ((double)m[4] * m[9] - (double)m[5] * m[8]);
}

/* 6 x the signed volume of the closed prism between rest r[3] and deformed q[3]. */
static double prism6(const vec3 *q, const vec3 *r)
{
	double v = vol6(q[0], q[1], q[2]) + vol6(r[0], r[2], r[1]);
	for (int c = 0; c < 3; ++c) {
		vec3 a = q[c], b = q[(c + 1) % 3], ra = r[c], rb = r[(c + 1) % 3];
		vec3 m = {(a.x + ra.x + rb.x + b.x) / 4, (a.y + ra.y + rb.y + b.y) / 4, (a.z + ra.z + rb.z + b.z) / 4};
		v += vol6(a, ra, m) + vol6(ra, rb, m) + vol6(rb, b, m) + vol6(b, a, m);
	}
	return v;
}

/* Compares the core's region changes with the explicit prism sum; returns the largest
 * relative difference (to the region's reference volume). */
static double compare_with_explicit(const test_rig *rig, const float *deformed, const float *posed)
{
	lvp_diagnostic diag;
	lvp_binding *binding = test_bind_rig(rig, NULL);
	if (!binding)
		return INFINITY;
	int32_t s = lvp_region_count(binding);
	double *changes = calloc((size_t)s, sizeof(double)), *references = calloc((size_t)s, sizeof(double));
	double *explicit_sum = calloc((size_t)s, sizeof(double));
	int32_t *triangle_regions = malloc(sizeof(int32_t) * (size_t)rig->triangle_count);
	CHECK_OK(lvp_region_volume_changes(changes, references, binding, deformed, posed, NULL, &diag), diag);
	lvp_get_segmentation(binding, NULL, triangle_regions);
	for (int32_t t = 0; t < rig->triangle_count; ++t) {
		int32_t region = triangle_regions[t];
		if (region < 0)
			continue;
		vec3 q[3], r[3];
		for (int c = 0; c < 3; ++c) {
			int32_t k = rig->triangles[3 * t + c];
			q[c] = to_local(posed + 16 * region, deformed + 3 * k);
			r[c] = to_local(rig->rest_matrices + 16 * region, rig->positions + 3 * k);
		}
		explicit_sum[region] += prism6(q, r) / 6.0 * det3(rig->rest_matrices + 16 * region);
	}
	double worst = 0.0;
	int32_t compared = 0;
	for (int32_t region = 0; region < s; ++region) {
		if (!(references[region] > 0.0))
			continue;
		++compared;
		double difference = fabs(changes[region] - explicit_sum[region]) / references[region];
		worst = difference > worst ? difference : worst;
	}
	CHECK(compared > 0);
	free(changes);
	free(references);
	free(explicit_sum);
	free(triangle_regions);
	lvp_free(binding);
	return worst;
}

/* Skinning by the pose plus a deterministic wobble, so no side quad cancels by symmetry. */
static float *deform(const test_rig *rig, const float *posed, double wobble)
{
	float *skin = malloc(sizeof(float) * 16 * (size_t)rig->bone_count);
	float *out = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	test_skin_matrices(skin, rig, posed);
	lvp_weights weights = test_rig_weights(rig);
	lvp_diagnostic diag;
	CHECK_OK(lvp_skin_linear(out, rig->positions, rig->vertex_count, &weights, skin, rig->bone_count, &diag), diag);
	for (int32_t i = 0; i < 3 * rig->vertex_count; ++i)
		out[i] += (float)(wobble * sin(1.7 * i + 0.3));
	free(skin);
	return out;
}

static void test_cylinder_prisms_match_explicit_sum(void)
{
	test_rig rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	float rotations[8] = {0, 0, 0, 0, 0.6f, 0.0f, 0.8f, (float)(70 * PI / 180)};
	float posed[32];
	test_pose(posed, &rig, rotations);
	float *deformed = deform(&rig, posed, 0.02);
	double worst = compare_with_explicit(&rig, deformed, posed);
	printf("  cylinder: largest |cheap - explicit| = %.2e of the region's reference volume\n", worst);
	CHECK(worst < 1e-5);
	free(deformed);
	test_rig_free(&rig);
}

static void test_giraffe_prisms_match_explicit_sum(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	float *rotations = calloc((size_t)rig.bone_count * 4, sizeof(float));
	const char *bent[] = {"gi_neckC4", "gi_L_elbow", "gi_R_knee", "gi_tailB"};
	for (int i = 0; i < 4; ++i) {
		int32_t bone = test_find_bone(&rig, bent[i]);
		CHECK(bone >= 0);
		if (bone < 0)
			continue;
		rotations[4 * bone + 0] = 1.0f;
		rotations[4 * bone + 1] = 0.3f;
		rotations[4 * bone + 3] = 0.8f;
	}
	float *posed = malloc(sizeof(float) * 16 * (size_t)rig.bone_count);
	test_pose(posed, &rig, rotations);
	float *deformed = deform(&rig, posed, 0.001);
	double worst = compare_with_explicit(&rig, deformed, posed);
	printf("  giraffe: largest |cheap - explicit| = %.2e of the region's reference volume\n", worst);
	CHECK(worst < 1e-4);
	free(deformed);
	free(posed);
	free(rotations);
	test_rig_free(&rig);
}

/* A rigid motion of the whole mesh changes no local volume. */
static void test_rigid_motion_changes_nothing(void)
{
	test_rig rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	float posed[32];
	float rotations[8] = {0, 0, 1, 0.7f, 0, 0, 0, 0};
	test_pose(posed, &rig, rotations);
	float *deformed = deform(&rig, posed, 0.0);
	lvp_diagnostic diag;
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	double changes[2], references[2];
	CHECK_OK(lvp_region_volume_changes(changes, references, binding, deformed, posed, NULL, &diag), diag);
	CHECK(fabs(changes[0]) < 1e-5 * references[0] && fabs(changes[1]) < 1e-5 * references[1]);
	lvp_free(binding);
	free(deformed);
	test_rig_free(&rig);
}

/* lvp_correct visits only the dynamic part of the mesh: triangles whose corners follow their
 * region's bone rigidly enter the region sums through their rest sums, moved by the bone in
 * closed form. On a chain turned, moved and scaled as a whole and bent at one joint (most
 * triangles static, no bone matrix the identity), the volume and region change it measures
 * before correcting must be those of the full computation (to float rounding of the terms). */
static void test_static_triangles_enter_through_rest_sums(void)
{
	test_rig rig = test_make_chain(8, 1.0f, 0.3f, 24, 12, 0.5f);
	float rotations[32] = {0};
	rotations[0] = 0.48f, rotations[1] = 0.6f, rotations[2] = 0.64f, rotations[3] = 0.9f; /* the whole chain */
	rotations[4 * 4] = 1.0f, rotations[4 * 4 + 3] = (float)(60 * PI / 180);             /* one joint */
	float posed[8 * 16];
	test_pose(posed, &rig, rotations);
	for (int i = 0; i < 8; ++i) { /* and moved and scaled, as Blender's bones can be */
		for (int row = 0; row < 3; ++row)
			for (int column = 0; column < 3; ++column)
				posed[16 * i + 4 * row + column] *= 1.15f;
		posed[16 * i + 3] += 2.5f, posed[16 * i + 7] -= 1.0f;
	}
	float *deformed = deform(&rig, posed, 0.0);
	lvp_diagnostic diag;
	lvp_binding *binding = test_bind_rig(&rig, NULL);
	if (!binding)
		return;
	double changes[8], references[8], volume = 0.0;
	CHECK_OK(lvp_region_volume_changes(changes, references, binding, deformed, posed, NULL, &diag), diag);
	CHECK_OK(lvp_mesh_volume(&volume, deformed, rig.vertex_count, rig.triangles, rig.triangle_count, &diag), diag);
	float *offsets = malloc(sizeof(float) * 3 * (size_t)rig.vertex_count);
	lvp_frame_stats stats;
	CHECK_OK(lvp_correct(NULL, offsets, binding, deformed, posed, NULL, NULL, &stats, &diag), diag);
	double volume_difference = fabs(stats.volume_before - volume) / fabs(volume);
	int32_t worst = stats.worst_region;
	CHECK(worst >= 0 && worst < 8);
	double region_difference = worst >= 0 && worst < 8 ? fabs(stats.worst_region_change_before -
	                                                          changes[worst] / references[worst]) : INFINITY;
	printf("  chain bent at one joint: volume before %.9g (full %.9g), region %d change %.6f%% (full %.6f%%)\n",
	       stats.volume_before, volume, (int)worst, 100 * stats.worst_region_change_before,
	       worst >= 0 && worst < 8 ? 100 * changes[worst] / references[worst] : NAN);
	CHECK(volume_difference < 1e-6);
	CHECK(region_difference < 1e-6);
	CHECK(fabs(stats.worst_region_change_before) > 1e-3); /* the bend did change it */
	free(offsets);
	lvp_free(binding);
	free(deformed);
	test_rig_free(&rig);
}

int main(void)
{
	RUN(test_cylinder_prisms_match_explicit_sum);
	RUN(test_giraffe_prisms_match_explicit_sum);
	RUN(test_rigid_motion_changes_nothing);
	RUN(test_static_triangles_enter_through_rest_sums);
	return check_failures() != 0;
}
