/*
 * test_bone_lines.c - the correction follows the skinning, not the bones' tails (lvp.h, BONE
 * LINES). The same rig is given to the core with its tails pointing along the bones, across them,
 * at random, with the bones rolled at random (every rest and posed frame turned about its head
 * by the same rotation, so that the skinning is the same), and with an unweighted leaf bone at
 * each bone's tail (FBX's `_end` bones): the offsets must be the same, to 1e-3 of the largest, on
 * a finger bent until its skin crosses itself and on the paper's giraffe, with fold-over on (which
 * bends skin about the bones' lines; keeping skin apart reads none, and is tested with them in
 * tests/blender/test_bone_tails.py).
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* A deterministic pseudo-random number in [0, 1). */
static double next_random(uint64_t *state)
{
	*state = *state * 6364136223846793005ull + 1442695040888963407ull;
	return (double)(*state >> 11) / 9007199254740992.0;
}

static void random_unit(uint64_t *state, double r_unit[3])
{
	double length = 0.0;
	while (!(length > 0.1)) {
		for (int c = 0; c < 3; ++c)
			r_unit[c] = 2.0 * next_random(state) - 1.0;
		length = sqrt(r_unit[0] * r_unit[0] + r_unit[1] * r_unit[1] + r_unit[2] * r_unit[2]);
	}
	for (int c = 0; c < 3; ++c)
		r_unit[c] /= length;
}

/* A rotation by `angle` about the unit `axis`, as a 4x4 row-major matrix without translation. */
static void rotation_matrix(float r[16], const double axis[3], double angle)
{
	double c = cos(angle), s = sin(angle), t = 1.0 - c, x = axis[0], y = axis[1], z = axis[2];
	float m[16] = {(float)(t * x * x + c),     (float)(t * x * y - s * z), (float)(t * x * z + s * y), 0.0f,
	               (float)(t * x * y + s * z), (float)(t * y * y + c),     (float)(t * y * z - s * x), 0.0f,
	               (float)(t * x * z - s * y), (float)(t * y * z + s * x), (float)(t * z * z + c),     0.0f,
	               0.0f,                       0.0f,                       0.0f,                       1.0f};
	memcpy(r, m, sizeof(m));
}

static float *copy_floats(const float *values, size_t count)
{
	float *copy = malloc(sizeof(float) * (count ? count : 1));
	memcpy(copy, values, sizeof(float) * count);
	return copy;
}

/* How a variant differs from the rig as built. */
typedef enum tails_variant {
	TAILS_ACROSS,        /* every tail turned a right angle off the bone, about the rest frame's Z */
	TAILS_RANDOM,        /* every tail in a random direction, of a random length */
	TAILS_RANDOM_ROLLED, /* and every bone rolled about a random axis through its head */
	TAILS_LEAF_BONES     /* an unweighted child bone at each bone's tail, as FBX's leaf bones */
} tails_variant;

/* The posed rig p given to the core another way (see tails_variant), with the same skinning.
 * The variant's bones come first, in the same order; r_bone_count receives how many there are. */
static void variant_skeleton(const test_posed_rig *p, tails_variant variant, uint64_t *state, float **r_rest,
                             float **r_posed, float **r_tails, int32_t **r_parents, float **r_heads,
                             int32_t *r_bone_count)
{
	const test_rig *rig = &p->rig;
	int32_t b = rig->bone_count, count = variant == TAILS_LEAF_BONES ? 2 * b : b;
	float *rest = calloc((size_t)count * 16, sizeof(float)), *posed = calloc((size_t)count * 16, sizeof(float));
	float *heads = calloc((size_t)count * 3, sizeof(float)), *tails = calloc((size_t)count * 3, sizeof(float));
	int32_t *parents = calloc((size_t)count, sizeof(int32_t));
	memcpy(rest, rig->rest_matrices, sizeof(float) * 16 * (size_t)b);
	memcpy(posed, p->posed, sizeof(float) * 16 * (size_t)b);
	memcpy(heads, rig->heads, sizeof(float) * 3 * (size_t)b);
	memcpy(tails, rig->tails, sizeof(float) * 3 * (size_t)b);
	memcpy(parents, rig->parents, sizeof(int32_t) * (size_t)b);
	for (int32_t i = 0; i < b; ++i) {
		float *h = heads + 3 * i, *t = tails + 3 * i;
		double along[3] = {t[0] - h[0], t[1] - h[1], t[2] - h[2]};
		double length = sqrt(along[0] * along[0] + along[1] * along[1] + along[2] * along[2]);
		if (variant == TAILS_ACROSS) {
			/* The rest frame's Z turned onto the tail's side: across the bone. */
			double z[3] = {rest[16 * i + 2], rest[16 * i + 6], rest[16 * i + 10]};
			for (int c = 0; c < 3; ++c)
				t[c] = (float)(h[c] + length * z[c]);
		} else if (variant == TAILS_RANDOM || variant == TAILS_RANDOM_ROLLED) {
			double direction[3];
			random_unit(state, direction);
			double scale = length * (0.2 + 2.0 * next_random(state));
			for (int c = 0; c < 3; ++c)
				t[c] = (float)(h[c] + scale * direction[c]);
		}
		if (variant == TAILS_RANDOM_ROLLED) {
			double axis[3];
			random_unit(state, axis);
			float turn[16];
			rotation_matrix(turn, axis, 2.0 * PI * next_random(state));
			test_multiply_matrices(rest + 16 * i, rig->rest_matrices + 16 * i, turn);
			test_multiply_matrices(posed + 16 * i, p->posed + 16 * i, turn);
		}
		if (variant == TAILS_LEAF_BONES) {
			int32_t leaf = b + i;
			memcpy(rest + 16 * leaf, rest + 16 * i, sizeof(float) * 16);
			memcpy(posed + 16 * leaf, posed + 16 * i, sizeof(float) * 16);
			for (int c = 0; c < 3; ++c) {
				heads[3 * leaf + c] = t[c];
				tails[3 * leaf + c] = (float)(t[c] + 0.25 * along[c]);
				rest[16 * leaf + 4 * c + 3] = t[c];
				/* The leaf's posed frame: the parent's, moved to where the parent carries the tail. */
				posed[16 * leaf + 4 * c + 3] = posed[16 * i + 4 * c + 3] +
				                               posed[16 * i + 4 * c] * (t[0] - h[0]) +
				                               posed[16 * i + 4 * c + 1] * (t[1] - h[1]) +
				                               posed[16 * i + 4 * c + 2] * (t[2] - h[2]);
			}
			parents[leaf] = i;
		}
	}
	*r_rest = rest;
	*r_posed = posed;
	*r_tails = tails;
	*r_heads = heads;
	*r_parents = parents;
	*r_bone_count = count;
}

/* The offsets of p corrected with fold-over, the skeleton as given. */
static float *correct_with(const test_posed_rig *p, const float *rest, const float *posed, const float *heads,
                           const float *tails, const int32_t *parents, int32_t bone_count)
{
	const test_rig *rig = &p->rig;
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = {bone_count, rest, heads, tails, parents};
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	float *offsets = calloc((size_t)rig->vertex_count * 3, sizeof(float));
	CHECK_OK(lvp_bind(&binding, rig->positions, rig->vertex_count, rig->triangles, rig->triangle_count, &weights,
	                  &skeleton, NULL, &diag),
	         diag);
	if (!binding)
		return offsets;
	lvp_frame_options options = lvp_frame_default_options();
	options.fold_over = 1;
	CHECK_OK(lvp_correct(NULL, offsets, binding, p->skinned, posed, NULL, &options, NULL, &diag), diag);
	lvp_free(binding);
	return offsets;
}

/* Every variant of p against p as built. */
static void check_variants(const char *name, const test_posed_rig *p)
{
	static const char *variant_names[] = {"tails across", "tails at random", "tails and rolls at random",
	                                      "leaf bones"};
	const test_rig *rig = &p->rig;
	float *clean = correct_with(p, rig->rest_matrices, p->posed, rig->heads, rig->tails, rig->parents,
	                            rig->bone_count);
	double largest = test_largest_distance(clean, NULL, rig->vertex_count);
	printf("  %s: largest offset %.4g\n", name, largest);
	CHECK(largest > 0.0);
	uint64_t state = 20261127;
	for (int variant = TAILS_ACROSS; variant <= TAILS_LEAF_BONES; ++variant) {
		float *rest, *posed, *tails, *heads;
		int32_t *parents, count;
		variant_skeleton(p, (tails_variant)variant, &state, &rest, &posed, &tails, &parents, &heads, &count);
		float *offsets = correct_with(p, rest, posed, heads, tails, parents, count);
		double difference = test_largest_distance(clean, offsets, rig->vertex_count);
		printf("    %-26s offsets differ by %.2e of the largest\n", variant_names[variant], difference / largest);
		CHECK(difference <= 1e-3 * largest);
		free(offsets);
		free(rest);
		free(posed);
		free(tails);
		free(heads);
		free(parents);
	}
	free(clean);
}

static void test_finger_whichever_way_the_tails_point(void)
{
	float rotations[12] = {0, 0, 0, 0, 1, 0, 0, (float)(100 * PI / 180), 1, 0, 0, (float)(100 * PI / 180)};
	test_posed_rig p;
	CHECK(test_pose_rig(test_make_finger(), rotations, &p) == 0);
	check_variants("finger, both knuckles bent 100 degrees", &p);
	test_posed_rig_free(&p);
}

static void test_giraffe_whichever_way_the_tails_point(void)
{
	test_rig rig;
	if (test_load_giraffe(&rig, "data/giraffe") != 0) {
		CHECK(!"the giraffe loads");
		return;
	}
	static const struct {
		const char *bone;
		float degrees;
	} bends[] = {{"gi_neckC7", 50}, {"gi_neckC4", 50}, {"gi_L_elbow", 60}, {"gi_L_wrist", 90}, {"gi_R_knee", -80}};
	float *rotations = calloc((size_t)rig.bone_count * 4, sizeof(float));
	for (size_t i = 0; i < sizeof(bends) / sizeof(bends[0]); ++i) {
		int32_t bone = test_find_bone(&rig, bends[i].bone);
		CHECK(bone >= 0);
		if (bone < 0)
			continue;
		rotations[4 * bone] = 1.0f;
		rotations[4 * bone + 3] = (float)(bends[i].degrees * PI / 180);
	}
	test_posed_rig p;
	CHECK(test_pose_rig(rig, rotations, &p) == 0);
	check_variants("giraffe, neck and legs bent", &p);
	free(rotations);
	test_posed_rig_free(&p);
}

int main(void)
{
	RUN(test_finger_whichever_way_the_tails_point);
	RUN(test_giraffe_whichever_way_the_tails_point);
	return check_failures() != 0;
}
