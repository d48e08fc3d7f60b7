/*
 * test_support.c - tests of the test geometry itself (support/test_meshes.h): if the cylinder,
 * the finger, the giraffe, the kinematics or the intersection count were wrong, every test of
 * the core built on them would be wrong with them. Uses nothing from csrc/ but lvp.h's types,
 * and its own reference skinning, so it stays valid while the core changes.
 */
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* ---- helpers ----------------------------------------------------------------------------- */

static double signed_volume(const float *p, const int32_t *t, int32_t triangle_count)
{
	double v = 0.0;
	for (int32_t i = 0; i < triangle_count; ++i) {
		const float *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
		v += a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) + a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]) +
		     a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
	}
	return v / 6.0;
}

/* Directed edges without their exact opposite (once): 0 for a closed, consistently wound mesh.
 * O(F^2), fine for test meshes of a few thousand triangles. */
static int32_t border_edge_count(const int32_t *t, int32_t triangle_count)
{
	int32_t count = 0;
	for (int32_t i = 0; i < triangle_count; ++i)
		for (int e = 0; e < 3; ++e) {
			int32_t a = t[3 * i + e], b = t[3 * i + (e + 1) % 3], found = 0;
			for (int32_t j = 0; j < triangle_count; ++j)
				for (int f = 0; f < 3; ++f)
					found += t[3 * j + f] == b && t[3 * j + (f + 1) % 3] == a;
			count += found != 1;
		}
	return count;
}

static void check_weights_normalized(const test_rig *rig)
{
	int32_t bad = 0;
	for (int32_t k = 0; k < rig->vertex_count; ++k) {
		double sum = 0.0;
		for (int32_t e = rig->weight_offsets[k]; e < rig->weight_offsets[k + 1]; ++e) {
			bad += rig->weight_values[e] <= 0.0f; /* zero weights are not stored */
			bad += rig->weight_bones[e] < 0 || rig->weight_bones[e] >= rig->bone_count;
			sum += rig->weight_values[e];
		}
		bad += fabs(sum - 1.0) > 1e-5;
	}
	CHECK(bad == 0);
}

/* Plain linear blend skinning (eq. 6), written out here so that these tests do not depend on
 * the core they are meant to test. */
static void reference_skin(float *r_positions, const test_rig *rig, const float *skin)
{
	for (int32_t k = 0; k < rig->vertex_count; ++k) {
		const float *p = rig->positions + 3 * k;
		double acc[3] = {0, 0, 0}, sum = 0.0;
		for (int32_t e = rig->weight_offsets[k]; e < rig->weight_offsets[k + 1]; ++e) {
			const float *m = skin + 16 * rig->weight_bones[e];
			double w = rig->weight_values[e];
			sum += w;
			for (int r = 0; r < 3; ++r)
				acc[r] += w * ((double)m[4 * r] * p[0] + (double)m[4 * r + 1] * p[1] + (double)m[4 * r + 2] * p[2] +
				               m[4 * r + 3]);
		}
		for (int r = 0; r < 3; ++r)
			r_positions[3 * k + r] = sum > 0.0 ? (float)(acc[r] / sum) : p[r];
	}
}

static void transform_point(double *r, const float *m, const float *p)
{
	for (int i = 0; i < 3; ++i)
		r[i] = (double)m[4 * i] * p[0] + (double)m[4 * i + 1] * p[1] + (double)m[4 * i + 2] * p[2] + m[4 * i + 3];
}

/* Poses the rig with local rotations, skins it with reference_skin and counts crossings. */
static int64_t bent_intersections(const test_rig *rig, const float *rotations)
{
	float *posed = malloc(sizeof(float) * 16 * (size_t)rig->bone_count);
	float *skin = malloc(sizeof(float) * 16 * (size_t)rig->bone_count);
	float *skinned = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	test_pose(posed, rig, rotations);
	test_skin_matrices(skin, rig, posed);
	reference_skin(skinned, rig, skin);
	int64_t pairs = test_count_intersecting_pairs(skinned, rig->triangles, rig->triangle_count);
	free(posed);
	free(skin);
	free(skinned);
	return pairs;
}

/* ---- the cylinder, the chain, the finger -------------------------------------------------- */

static void test_cylinder_is_the_papers(void)
{
	test_rig rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	CHECK(rig.vertex_count == 258);
	CHECK(rig.triangle_count == 2 * 16 * 15 + 2 * 16);
	CHECK(rig.bone_count == 2);
	CHECK(border_edge_count(rig.triangles, rig.triangle_count) == 0);
	/* A 16-gon prism: (n/2) r^2 sin(2 pi / n) L exactly, 2.6 % under pi r^2 L. */
	double volume = signed_volume(rig.positions, rig.triangles, rig.triangle_count);
	CHECK_NEAR(volume, 8.0 * 0.25 * sin(2.0 * PI / 16.0) * 4.0, 1e-5);
	CHECK_NEAR(volume, PI * 0.25 * 4.0, 0.03 * PI * 0.25 * 4.0);
	check_weights_normalized(&rig);
	/* The band is [0.7, 3.3]: rings below it follow bone 0 alone, rings above it bone 1. */
	int32_t misplaced = 0;
	for (int32_t k = 0; k < rig.vertex_count; ++k) {
		float z = rig.positions[3 * k + 2];
		int32_t first = rig.weight_offsets[k], n = rig.weight_offsets[k + 1] - first;
		if (z < 0.7f)
			misplaced += !(n == 1 && rig.weight_bones[first] == 0);
		else if (z > 3.3f)
			misplaced += !(n == 1 && rig.weight_bones[first] == 1);
		else
			misplaced += n != 2;
	}
	CHECK(misplaced == 0);
	/* The middle ring (z = 2 lies between rings 7 and 8) splits its weight evenly around 0.5. */
	CHECK_NEAR(rig.weight_values[rig.weight_offsets[7 * 16] + 1], (7.0 * 4.0 / 15.0 - 0.7) / 2.6, 1e-6);
	/* Blender's frame of a bone pointing up +Z: local Y along the bone, origin at the head. */
	const float *m = rig.rest_matrices + 16;
	CHECK(m[1] == 0.0f && m[5] == 0.0f && m[9] == 1.0f && m[3] == 0.0f && m[7] == 0.0f && m[11] == 2.0f);
	CHECK(rig.heads[5] == 2.0f && rig.tails[5] == 4.0f && rig.parents[1] == 0 && rig.parents[0] == -1);
	CHECK(test_count_intersecting_pairs(rig.positions, rig.triangles, rig.triangle_count) == 0);
	test_rig_free(&rig);
}

static void test_chain(void)
{
	test_rig rig = test_make_chain(5, 1.0f, 0.2f, 12, 4, 0.5f);
	CHECK(rig.vertex_count == 12 * 21 + 2);
	CHECK(rig.bone_count == 5);
	CHECK(border_edge_count(rig.triangles, rig.triangle_count) == 0);
	CHECK(signed_volume(rig.positions, rig.triangles, rig.triangle_count) > 0.0);
	check_weights_normalized(&rig);
	/* A ring on a joint (z = 2) blends bones 1 and 2 evenly; one mid-bone (z = 2.5) is rigid. */
	int32_t k = 8 * 12, m = 10 * 12;
	CHECK(rig.weight_offsets[k + 1] - rig.weight_offsets[k] == 2);
	CHECK_NEAR(rig.weight_values[rig.weight_offsets[k]], 0.5, 1e-6);
	CHECK(rig.weight_offsets[m + 1] - rig.weight_offsets[m] == 1 && rig.weight_bones[rig.weight_offsets[m]] == 2);
	test_rig_free(&rig);
}

static void test_finger_folds_under_plain_skinning(void)
{
	test_rig rig = test_make_finger();
	CHECK(rig.bone_count == 3);
	CHECK(border_edge_count(rig.triangles, rig.triangle_count) == 0);
	CHECK(signed_volume(rig.positions, rig.triangles, rig.triangle_count) > 0.0);
	check_weights_normalized(&rig);
	CHECK_NEAR(rig.tails[3 * 2 + 1], 2.2, 1e-6);
	CHECK(test_count_intersecting_pairs(rig.positions, rig.triangles, rig.triangle_count) == 0);
	/* The angle documented in test_meshes.h: both knuckles at 100 degrees cross the skin, and
	 * only at the knuckles (the count is the sum of each knuckle bent alone), so a fix of the
	 * two neighbouring-bone contacts can bring it to zero. */
	float angle = (float)(100.0 * PI / 180.0);
	float both[12] = {0, 0, 0, 0, 1, 0, 0, angle, 1, 0, 0, angle};
	float first[12] = {0, 0, 0, 0, 1, 0, 0, angle, 0, 0, 0, 0};
	float second[12] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, angle};
	int64_t crossing = bent_intersections(&rig, both);
	printf("  finger, both knuckles at 100 degrees, plain skinning: %lld intersecting pairs\n", (long long)crossing);
	CHECK(crossing > 0);
	CHECK(crossing == bent_intersections(&rig, first) + bent_intersections(&rig, second));
	/* A gentle bend stays clean. */
	float gentle[12] = {0, 0, 0, 0, 1, 0, 0, (float)(30.0 * PI / 180.0), 1, 0, 0, (float)(30.0 * PI / 180.0)};
	CHECK(bent_intersections(&rig, gentle) == 0);
	test_rig_free(&rig);
}

/* ---- kinematics ----------------------------------------------------------------------------- */

static void test_pose_without_rotation_is_rest(void)
{
	test_rig rig = test_make_finger();
	float posed[48], zero[12] = {0};
	test_pose(posed, &rig, zero);
	CHECK(memcmp(posed, rig.rest_matrices, sizeof(posed)) == 0);
	test_pose(posed, &rig, NULL);
	CHECK(memcmp(posed, rig.rest_matrices, sizeof(posed)) == 0);
	float skin[48];
	test_skin_matrices(skin, &rig, posed);
	int bad = 0;
	for (int i = 0; i < 3; ++i)
		for (int k = 0; k < 16; ++k)
			bad += fabsf(skin[16 * i + k] - (k % 5 == 0 ? 1.0f : 0.0f)) > 1e-6f;
	CHECK(bad == 0);
	test_rig_free(&rig);
}

static void test_pose_turns_about_the_head(void)
{
	test_rig rig = test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f);
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(PI / 2.0)};
	float posed[32], skin[32];
	test_pose(posed, &rig, rotations);
	CHECK(memcmp(posed, rig.rest_matrices, 16 * sizeof(float)) == 0); /* bone 0 did not move */
	/* Local X is world X; +90 degrees takes local Y (world +Z) to local Z (world -Y). */
	float local_tail[3] = {0, 2, 0};
	double tail[3];
	transform_point(tail, posed + 16, local_tail);
	CHECK_NEAR(tail[0], 0.0, 1e-6);
	CHECK_NEAR(tail[1], -2.0, 1e-6);
	CHECK_NEAR(tail[2], 2.0, 1e-6);
	test_skin_matrices(skin, &rig, posed);
	transform_point(tail, skin + 16, rig.tails + 3);
	CHECK_NEAR(tail[1], -2.0, 1e-6);
	CHECK_NEAR(tail[2], 2.0, 1e-6);
	transform_point(tail, skin + 16, rig.heads + 3); /* the head stays where it was */
	CHECK_NEAR(tail[1], 0.0, 1e-6);
	CHECK_NEAR(tail[2], 2.0, 1e-6);
	test_rig_free(&rig);

	/* Children are carried: turning the root of a 3-bone chain swings the whole chain. */
	rig = test_make_chain(3, 1.0f, 0.2f, 8, 2, 0.5f);
	float root_turn[12] = {1, 0, 0, (float)(PI / 2.0), 0, 0, 0, 0, 0, 0, 0, 0};
	float chain_posed[48], chain_skin[48];
	test_pose(chain_posed, &rig, root_turn);
	test_skin_matrices(chain_skin, &rig, chain_posed);
	transform_point(tail, chain_skin + 32, rig.tails + 6);
	CHECK_NEAR(tail[0], 0.0, 1e-6);
	CHECK_NEAR(tail[1], -3.0, 1e-6);
	CHECK_NEAR(tail[2], 0.0, 1e-6);
	/* posed = skin * rest for every bone */
	int bad = 0;
	for (int i = 0; i < 3; ++i) {
		double head[3];
		transform_point(head, chain_skin + 16 * i, rig.heads + 3 * i);
		bad += fabs(head[0] - chain_posed[16 * i + 3]) > 1e-6 || fabs(head[1] - chain_posed[16 * i + 7]) > 1e-6 ||
		       fabs(head[2] - chain_posed[16 * i + 11]) > 1e-6;
	}
	CHECK(bad == 0);
	test_rig_free(&rig);
}

/* ---- the giraffe ---------------------------------------------------------------------------- */

static void test_giraffe_loads(void)
{
	test_rig rig;
	CHECK(test_load_giraffe(&rig, "data/giraffe") == 0);
	if (check_failures())
		return;
	CHECK(rig.vertex_count == 1673);
	CHECK(rig.bone_count == 59);
	/* 1614 quads, 18 triangles, 16 pentagons, 4 hexagons, 2 octagons, 2 nonagons, fanned. */
	CHECK(rig.triangle_count == 3336);
	check_weights_normalized(&rig);
	double volume = signed_volume(rig.positions, rig.triangles, rig.triangle_count);
	printf("  giraffe: %d vertices, %d triangles, %d bones, volume %.6f\n", rig.vertex_count, rig.triangle_count,
	       rig.bone_count, volume);
	CHECK_NEAR(volume, 0.0164, 0.0002);
	CHECK(border_edge_count(rig.triangles, rig.triangle_count) == 8); /* the README's 8 open edges */
	CHECK(test_find_bone(&rig, "gi_head") == 12);
	CHECK(test_find_bone(&rig, "gi_L_knee") == 38);
	CHECK(test_find_bone(&rig, "no_such_bone") == -1);
	CHECK(rig.parents[0] == -1 && rig.parents[12] == 11 && rig.parents[38] == 37);
	/* The tail rule: the spine top (7) aims at the neck (8), not a shoulder blade; the pelvis
	 * (3) at the spine (4); the head (12) at its end (13), not the jaw. */
	CHECK(memcmp(rig.tails + 3 * 7, rig.heads + 3 * 8, 3 * sizeof(float)) == 0);
	CHECK(memcmp(rig.tails + 3 * 3, rig.heads + 3 * 4, 3 * sizeof(float)) == 0);
	CHECK(memcmp(rig.tails + 3 * 12, rig.heads + 3 * 13, 3 * sizeof(float)) == 0);
	/* Every bone that carries weight has a length; every head lies in the model's box. */
	int bad = 0;
	for (int32_t e = 0; e < rig.weight_offsets[rig.vertex_count]; ++e) {
		const float *h = rig.heads + 3 * rig.weight_bones[e], *t = rig.tails + 3 * rig.weight_bones[e];
		bad += h[0] == t[0] && h[1] == t[1] && h[2] == t[2];
	}
	for (int32_t j = 0; j < rig.bone_count; ++j)
		bad += fabsf(rig.heads[3 * j]) > 0.12f || rig.heads[3 * j + 1] < -0.01f || rig.heads[3 * j + 1] > 1.0f;
	CHECK(bad == 0);
	/* Rest frames are rigid (rotation + translation) and the head is their origin. */
	bad = 0;
	for (int32_t j = 0; j < rig.bone_count; ++j) {
		const float *m = rig.rest_matrices + 16 * j;
		for (int a = 0; a < 3; ++a)
			for (int b = 0; b < 3; ++b) {
				double dot = 0.0;
				for (int r = 0; r < 3; ++r)
					dot += (double)m[4 * r + a] * m[4 * r + b];
				bad += fabs(dot - (a == b)) > 1e-5;
			}
		bad += m[3] != rig.heads[3 * j] || m[7] != rig.heads[3 * j + 1] || m[11] != rig.heads[3 * j + 2];
	}
	CHECK(bad == 0);
	float *posed = malloc(sizeof(float) * 16 * 59);
	test_pose(posed, &rig, NULL);
	CHECK(memcmp(posed, rig.rest_matrices, sizeof(float) * 16 * 59) == 0);
	free(posed);
	CHECK(test_count_intersecting_pairs(rig.positions, rig.triangles, rig.triangle_count) == 0);
	test_rig_free(&rig);
	CHECK(test_load_giraffe(&rig, "data/no_such_directory") != 0);
}

static void test_read_file_reads_whole_files(void)
{
	size_t size = 0;
	char *text = test_read_file("data/giraffe/skeleton_connectivity_parent", &size);
	CHECK(text != NULL);
	if (text) {
		CHECK(size == 162 && strlen(text) == size);
		CHECK(strncmp(text, "-1 0 1 2", 8) == 0);
	}
	free(text);
	text = test_read_file("data/giraffe/mesh.obj", &size);
	CHECK(text && size == 149976);
	free(text);
	CHECK(test_read_file("data/giraffe/missing", &size) == NULL);
}

/* ---- the exact intersection count ----------------------------------------------------------- */

/* Two triangles from six points. */
static int64_t pair_count(const float *a, const float *b, const float *c, const float *d, const float *e,
                          const float *f)
{
	float p[18];
	const float *v[6] = {a, b, c, d, e, f};
	for (int i = 0; i < 6; ++i)
		memcpy(p + 3 * i, v[i], 3 * sizeof(float));
	int32_t t[6] = {0, 1, 2, 3, 4, 5};
	return test_count_intersecting_pairs(p, t, 2);
}

/* Two triangles with shared corners: t lists six indices into p. */
static int64_t shared_count(const float *p, const int32_t *t)
{
	return test_count_intersecting_pairs(p, t, 2);
}

static void test_intersections_of_two_triangles(void)
{
	static const float o[3] = {0, 0, 0}, x[3] = {2, 0, 0}, y[3] = {0, 2, 0};
	/* A vertical triangle through the interior of the horizontal one. */
	static const float d[3] = {0.2f, 0.2f, -1}, e[3] = {0.2f, 0.2f, 1}, f[3] = {3, 3, 0};
	CHECK(pair_count(o, x, y, d, e, f) == 1);
	/* The same, lifted away. */
	static const float d5[3] = {0.2f, 0.2f, 4}, e5[3] = {0.2f, 0.2f, 6}, f5[3] = {3, 3, 5};
	CHECK(pair_count(o, x, y, d5, e5, f5) == 0);
	/* Boxes overlap, triangles do not: the vertical one passes beyond the hypotenuse. */
	static const float g[3] = {1.5f, 1.5f, -1}, h[3] = {1.5f, 1.5f, 1}, k[3] = {3, 3, 0};
	CHECK(pair_count(o, x, y, g, h, k) == 0);
	/* Touching counts: a corner exactly on the other's edge; then one float step above it. */
	static const float on[3] = {1, 0, 0}, up1[3] = {1, 1, 1}, up2[3] = {1, -1, 1};
	CHECK(pair_count(o, x, y, on, up1, up2) == 1);
	float above[3] = {1, 0, nextafterf(0.0f, 1.0f)};
	CHECK(pair_count(o, x, y, above, up1, up2) == 0);
	/* Coplanar, overlapping, no shared corner. */
	static const float c1[3] = {0.5f, 0.5f, 0}, c2[3] = {3, 0.5f, 0}, c3[3] = {0.5f, 3, 0};
	CHECK(pair_count(o, x, y, c1, c2, c3) == 1);
	/* Coplanar, one inside the other. */
	static const float i1[3] = {0.1f, 0.1f, 0}, i2[3] = {0.5f, 0.1f, 0}, i3[3] = {0.1f, 0.5f, 0};
	CHECK(pair_count(o, x, y, i1, i2, i3) == 1);
	/* Coplanar, apart. */
	static const float a1[3] = {1.5f, 1.5f, 0}, a2[3] = {3, 1.5f, 0}, a3[3] = {1.5f, 3, 0};
	CHECK(pair_count(o, x, y, a1, a2, a3) == 0);
	/* Zero-area triangles are ignored. */
	static const float l1[3] = {0.5f, 0.5f, -1}, l2[3] = {0.5f, 0.5f, 0}, l3[3] = {0.5f, 0.5f, 1};
	CHECK(pair_count(o, x, y, l1, l2, l3) == 0);
}

static void test_intersections_with_shared_corners(void)
{
	/* 0, 1, 2: the horizontal triangle; the rest are other corners. */
	static const float p[] = {
	    0,    0,    0,  2, 0, 0, 0, 2, 0, /* 0 1 2 */
	    0.5f, -0.5f, 0.7f,                /* 3: folded down along edge 01 */
	    0.3f, 0.8f, 0,                    /* 4: coplanar, same side of 01 as 2 */
	    0.5f, -0.5f, 0,                   /* 5: coplanar, other side of 01 */
	    1,    0.5f, -1,   0.5f, 1, 1,     /* 6 7: with 0, a triangle piercing 012 away from 0 */
	    -1,   0,    1,    0, -1, 1,       /* 8 9: with 0, a triangle touching 012 only at 0 */
	    0.5f, 0.5f, 0,    1, 2, 0,        /* 10 11: with 0, coplanar and overlapping near 0 */
	    -1,   -0.5f, 0,   -0.5f, -1, 0,   /* 12 13: with 0, coplanar in the opposite corner */
	};
	const int32_t edge_folded[6] = {0, 1, 2, 1, 0, 3};
	const int32_t edge_flat_over[6] = {0, 1, 2, 1, 0, 4};
	const int32_t edge_flat_beside[6] = {0, 1, 2, 1, 0, 5};
	const int32_t vertex_crossing[6] = {0, 1, 2, 0, 6, 7};
	const int32_t vertex_touching[6] = {0, 1, 2, 0, 8, 9};
	const int32_t vertex_coplanar_over[6] = {0, 1, 2, 0, 10, 11};
	const int32_t vertex_coplanar_apart[6] = {0, 1, 2, 0, 12, 13};
	const int32_t same[6] = {0, 1, 2, 2, 0, 1};
	CHECK(shared_count(p, edge_folded) == 0);
	CHECK(shared_count(p, edge_flat_over) == 1);
	CHECK(shared_count(p, edge_flat_beside) == 0);
	CHECK(shared_count(p, vertex_crossing) == 1);
	CHECK(shared_count(p, vertex_touching) == 0);
	CHECK(shared_count(p, vertex_coplanar_over) == 1);
	CHECK(shared_count(p, vertex_coplanar_apart) == 0);
	CHECK(shared_count(p, same) == 1);
}

static void test_closed_sphere_has_no_intersection(void)
{
	/* A UV sphere: poles 0 and 1, then `rings` rings of `around` vertices. */
	enum { around = 24, rings = 11 };
	float p[3 * (2 + around * rings)];
	int32_t t[3 * (2 * around * rings)];
	p[0] = p[1] = 0, p[2] = -1, p[3] = p[4] = 0, p[5] = 1;
	for (int i = 0; i < rings; ++i)
		for (int j = 0; j < around; ++j) {
			double theta = PI * (i + 1) / (rings + 1), phi = 2.0 * PI * j / around;
			float *v = p + 3 * (2 + i * around + j);
			v[0] = (float)(sin(theta) * cos(phi)), v[1] = (float)(sin(theta) * sin(phi)), v[2] = (float)-cos(theta);
		}
	int32_t n = 0;
	for (int j = 0; j < around; ++j) {
		int32_t a = 2 + j, b = 2 + (j + 1) % around;
		int32_t c = 2 + (rings - 1) * around + j, d = 2 + (rings - 1) * around + (j + 1) % around;
		t[3 * n] = 0, t[3 * n + 1] = b, t[3 * n + 2] = a, ++n;
		t[3 * n] = 1, t[3 * n + 1] = c, t[3 * n + 2] = d, ++n;
		for (int i = 0; i + 1 < rings; ++i) {
			int32_t a0 = 2 + i * around + j, a1 = 2 + i * around + (j + 1) % around;
			t[3 * n] = a0, t[3 * n + 1] = a1, t[3 * n + 2] = a1 + around, ++n;
			t[3 * n] = a0, t[3 * n + 1] = a1 + around, t[3 * n + 2] = a0 + around, ++n;
		}
	}
	CHECK(border_edge_count(t, n) == 0);
	CHECK(signed_volume(p, t, n) > 0.0);
	CHECK(test_count_intersecting_pairs(p, t, n) == 0);
	/* Push one vertex through the opposite side: now the skin crosses itself. */
	p[3 * (2 + 5 * around)] = -1.5f;
	p[3 * (2 + 5 * around) + 1] = 0.0f;
	p[3 * (2 + 5 * around) + 2] = 0.0f;
	CHECK(test_count_intersecting_pairs(p, t, n) > 0);
}

int main(void)
{
	RUN(test_cylinder_is_the_papers);
	RUN(test_chain);
	RUN(test_finger_folds_under_plain_skinning);
	RUN(test_pose_without_rotation_is_rest);
	RUN(test_pose_turns_about_the_head);
	RUN(test_giraffe_loads);
	RUN(test_read_file_reads_whole_files);
	RUN(test_intersections_of_two_triangles);
	RUN(test_intersections_with_shared_corners);
	RUN(test_closed_sphere_has_no_intersection);
	return check_failures() != 0;
}
