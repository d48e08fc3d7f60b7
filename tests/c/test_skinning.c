/*
 * test_skinning.c - linear blend skinning (paper eq. 6) and dual quaternion skinning, on a tube built
 * here: identity and rigid motions, the candy-wrapper twist, weight normalization, scaled and mirrored
 * bones, hemisphere alignment, and every error path.
 */
#include "lvp.h"
#include "support/check.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

typedef lvp_result (*skin_function)(float *, const float *, int32_t, const lvp_weights *, const float *, int32_t,
                                    lvp_diagnostic *);

/* A tube skinned to two bones along +Z: `around` x `rings` side vertices from z = 0 to z = length (no
 * caps: skinning does not look at triangles). Bone 0 covers z < length/2, bone 1 the rest; weights blend
 * linearly over `band` centred on the joint, and zero weights are not stored. */
typedef struct tube {
	int32_t vertex_count;
	float *positions;
	int32_t *offsets, *bones;
	float *values;
	float radius, length;
	int around, rings;
} tube;

static tube make_tube(int around, int rings, float radius, float length, float band)
{
	tube t = {around * rings, NULL, NULL, NULL, NULL, radius, length, around, rings};
	t.positions = malloc(sizeof(float) * 3 * (size_t)t.vertex_count);
	t.offsets = malloc(sizeof(int32_t) * ((size_t)t.vertex_count + 1));
	t.bones = malloc(sizeof(int32_t) * 2 * (size_t)t.vertex_count);
	t.values = malloc(sizeof(float) * 2 * (size_t)t.vertex_count);
	int32_t e = 0;
	for (int r = 0; r < rings; ++r) {
		float z = length * (float)r / (float)(rings - 1);
		float w1 = (z - (length - band) / 2.0f) / band;
		w1 = w1 < 0.0f ? 0.0f : (w1 > 1.0f ? 1.0f : w1);
		for (int a = 0; a < around; ++a) {
			int32_t v = r * around + a;
			double phi = 2.0 * PI * a / around;
			t.positions[3 * v] = (float)(radius * cos(phi));
			t.positions[3 * v + 1] = (float)(radius * sin(phi));
			t.positions[3 * v + 2] = z;
			t.offsets[v] = e;
			if (w1 < 1.0f)
				t.bones[e] = 0, t.values[e++] = 1.0f - w1;
			if (w1 > 0.0f)
				t.bones[e] = 1, t.values[e++] = w1;
		}
	}
	t.offsets[t.vertex_count] = e;
	return t;
}

static void tube_free(tube *t)
{
	free(t->positions);
	free(t->offsets);
	free(t->bones);
	free(t->values);
}

static lvp_weights tube_weights(const tube *t)
{
	lvp_weights w = {t->offsets, t->bones, t->values};
	return w;
}

/* Every vertex on one bone only, with weight 1. The tube's rows have room for it: at least one influence
 * a vertex. */
static void tube_weigh_rigidly(tube *t, int32_t bone)
{
	for (int32_t v = 0; v < t->vertex_count; ++v)
		t->offsets[v] = v, t->bones[v] = bone, t->values[v] = 1.0f;
	t->offsets[t->vertex_count] = t->vertex_count;
}

/* Row-major 4x4: rotation by angle about the unit axis, then a scale diag(sx, sy, sz) applied first,
 * then the translation. */
static void make_matrix(float r_m[16], double ax, double ay, double az, double angle, double sx, double sy,
                        double sz, double tx, double ty, double tz)
{
	double length = sqrt(ax * ax + ay * ay + az * az);
	if (length > 0)
		ax /= length, ay /= length, az /= length;
	double c = cos(angle), s = sin(angle), k = 1.0 - c;
	double r[9] = {c + ax * ax * k,      ax * ay * k - az * s, ax * az * k + ay * s,
	               ay * ax * k + az * s, c + ay * ay * k,      ay * az * k - ax * s,
	               az * ax * k - ay * s, az * ay * k + ax * s, c + az * az * k};
	double scale[3] = {sx, sy, sz}, t[3] = {tx, ty, tz};
	for (int i = 0; i < 3; ++i) {
		for (int j = 0; j < 3; ++j)
			r_m[4 * i + j] = (float)(r[3 * i + j] * scale[j]);
		r_m[4 * i + 3] = (float)t[i];
	}
	r_m[12] = r_m[13] = r_m[14] = 0.0f;
	r_m[15] = 1.0f;
}

static void identity(float r_m[16])
{
	make_matrix(r_m, 0, 0, 1, 0, 1, 1, 1, 0, 0, 0);
}

static void transform(double r_p[3], const float m[16], const float *p)
{
	for (int i = 0; i < 3; ++i)
		r_p[i] = (double)m[4 * i] * p[0] + (double)m[4 * i + 1] * p[1] + (double)m[4 * i + 2] * p[2] + m[4 * i + 3];
}

static float *skin(skin_function f, const tube *t, const lvp_weights *weights, const float *matrices, int32_t bones)
{
	float *out = malloc(sizeof(float) * 3 * (size_t)t->vertex_count);
	lvp_diagnostic diag = {0};
	CHECK_OK(f(out, t->positions, t->vertex_count, weights, matrices, bones, &diag), diag);
	return out;
}

static const skin_function methods[2] = {lvp_skin_linear, lvp_skin_dual_quaternion};

/* ---- behaviour ----------------------------------------------------------------------------------- */

static void test_identity_matrices_leave_the_mesh(void)
{
	tube t = make_tube(12, 9, 0.5f, 4.0f, 2.6f);
	lvp_weights w = tube_weights(&t);
	float matrices[32];
	identity(matrices);
	identity(matrices + 16);
	for (int m = 0; m < 2; ++m) {
		float *out = skin(methods[m], &t, &w, matrices, 2);
		for (int32_t i = 0; i < 3 * t.vertex_count; ++i)
			CHECK_NEAR(out[i], t.positions[i], 1e-6);
		free(out);
	}
	tube_free(&t);
}

static void test_single_rigid_bone_moves_the_mesh_rigidly(void)
{
	tube t = make_tube(12, 9, 0.5f, 4.0f, 2.6f);
	tube_weigh_rigidly(&t, 1);
	lvp_weights w = tube_weights(&t);
	/* several rotations, including a half turn about a skew axis (the quaternion's w is 0) */
	const double cases[4][4] = {{0.3, -0.5, 0.8, 1.1}, {0, 0, 1, PI}, {1, 1, 1, PI}, {0.2, 0.9, -0.1, 2.9}};
	for (int c = 0; c < 4; ++c) {
		float matrices[32];
		identity(matrices);
		make_matrix(matrices + 16, cases[c][0], cases[c][1], cases[c][2], cases[c][3], 1, 1, 1, 0.7, -2.0, 3.5);
		for (int m = 0; m < 2; ++m) {
			float *out = skin(methods[m], &t, &w, matrices, 2);
			for (int32_t v = 0; v < t.vertex_count; ++v) {
				double expected[3];
				transform(expected, matrices + 16, t.positions + 3 * v);
				for (int i = 0; i < 3; ++i)
					CHECK_NEAR(out[3 * v + i], expected[i], 2e-6);
			}
			free(out);
		}
	}
	tube_free(&t);
}

static double ring_radius(const float *positions, const tube *t, int ring, double *r_min)
{
	double max = 0.0, min = INFINITY;
	for (int a = 0; a < t->around; ++a) {
		const float *p = positions + 3 * (ring * t->around + a);
		double r = sqrt((double)p[0] * p[0] + (double)p[1] * p[1]);
		max = fmax(max, r), min = fmin(min, r);
	}
	*r_min = min;
	return max;
}

/* The candy wrapper: bone 1 twisted half a turn about the tube's axis. Linear blending averages the two
 * rotations and collapses the middle ring onto the axis; dual quaternions rotate it by a quarter turn
 * and keep every ring's radius. */
static void test_twist_collapses_linear_blend_but_not_dual_quaternions(void)
{
	tube t = make_tube(16, 33, 0.5f, 4.0f, 2.0f);
	lvp_weights w = tube_weights(&t);
	float matrices[32];
	identity(matrices);
	make_matrix(matrices + 16, 0, 0, 1, PI, 1, 1, 1, 0, 0, 0);
	float *linear = skin(lvp_skin_linear, &t, &w, matrices, 2);
	float *dual = skin(lvp_skin_dual_quaternion, &t, &w, matrices, 2);
	int middle = t.rings / 2;
	double min_radius, radius = ring_radius(linear, &t, middle, &min_radius);
	CHECK(radius < 0.05 * t.radius);
	for (int ring = 0; ring < t.rings; ++ring) {
		double max_r = ring_radius(dual, &t, ring, &min_radius);
		CHECK_NEAR(max_r, t.radius, 1e-5);
		CHECK_NEAR(min_radius, t.radius, 1e-5);
	}
	/* the middle ring turned by a quarter turn (either way), not by zero or half a turn */
	const float *p = dual + 3 * (middle * t.around);
	CHECK_NEAR(fabs(p[1]), t.radius, 1e-5);
	free(linear);
	free(dual);
	tube_free(&t);
}

static void test_weights_are_normalized_by_their_sum(void)
{
	tube t = make_tube(12, 17, 0.5f, 4.0f, 2.6f);
	lvp_weights w = tube_weights(&t);
	float matrices[32];
	make_matrix(matrices, 0, 1, 0, 0.4, 1, 1, 1, 0.1, 0.2, 0.3);
	make_matrix(matrices + 16, 1, 0, 0, 1.3, 1, 1, 1, 0, 2, -1);
	int32_t total = t.offsets[t.vertex_count];
	float *scaled = malloc(sizeof(float) * (size_t)total);
	lvp_weights ws = {t.offsets, t.bones, scaled};
	/* every weight of a vertex scaled by the same factor (a different one per vertex): the weights no
	 * longer sum to one, and the result must not change */
	for (int32_t v = 0; v < t.vertex_count; ++v)
		for (int32_t e = t.offsets[v]; e < t.offsets[v + 1]; ++e)
			scaled[e] = t.values[e] * (0.25f + 0.5f * (float)(v % 5));
	for (int m = 0; m < 2; ++m) {
		float *reference = skin(methods[m], &t, &w, matrices, 2);
		float *out = skin(methods[m], &t, &ws, matrices, 2);
		for (int32_t i = 0; i < 3 * t.vertex_count; ++i)
			CHECK_NEAR(out[i], reference[i], 2e-6);
		free(reference);
		free(out);
	}
	free(scaled);
	/* weights 3 and 1: a quarter of the way from bone 0's motion to bone 1's, for linear blending */
	int32_t offsets[2] = {0, 2}, bones[2] = {0, 1};
	float values[2] = {3.0f, 1.0f}, rest[3] = {0.3f, -0.2f, 1.1f}, out[3];
	lvp_weights single = {offsets, bones, values};
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_skin_linear(out, rest, 1, &single, matrices, 2, &diag), diag);
	double a[3], b[3];
	transform(a, matrices, rest);
	transform(b, matrices + 16, rest);
	for (int i = 0; i < 3; ++i)
		CHECK_NEAR(out[i], 0.75 * a[i] + 0.25 * b[i], 1e-6);
	tube_free(&t);
}

static void test_vertices_without_weight_keep_rest_position(void)
{
	tube t = make_tube(8, 5, 0.5f, 4.0f, 2.6f);
	/* vertex 0: no influence; vertex 1: only zero weights */
	int32_t offsets[41], bones[40];
	float values[40];
	offsets[0] = 0, offsets[1] = 0;
	bones[0] = 1, values[0] = 0.0f, bones[1] = 0, values[1] = 0.0f;
	offsets[2] = 2;
	for (int32_t v = 2; v < t.vertex_count; ++v)
		bones[offsets[v]] = 1, values[offsets[v]] = 1.0f, offsets[v + 1] = offsets[v] + 1;
	lvp_weights w = {offsets, bones, values};
	float matrices[32];
	identity(matrices);
	make_matrix(matrices + 16, 0, 1, 0, 1.0, 2, 2, 2, 5, 5, 5);
	for (int m = 0; m < 2; ++m) {
		float *out = skin(methods[m], &t, &w, matrices, 2);
		for (int i = 0; i < 6; ++i)
			CHECK(out[i] == t.positions[i]);
		double moved[3];
		transform(moved, matrices + 16, t.positions + 6);
		CHECK_NEAR(out[6], moved[0], 1e-5);
		free(out);
	}
	tube_free(&t);
}

/* Scale and shear are blended linearly and applied before the rigid part: a single scaled bone gives
 * exactly its matrix, and two bones with the same uniform scale scale the whole blend. */
static void test_dual_quaternions_apply_bone_scale(void)
{
	tube t = make_tube(12, 17, 0.5f, 4.0f, 2.6f);
	lvp_weights w = tube_weights(&t);
	float matrices[32];
	make_matrix(matrices, 0.2, 1, 0.3, 0.7, 2.0, 0.5, 1.5, 1, -1, 0.5);
	memcpy(matrices + 16, matrices, sizeof(float) * 16);
	float *out = skin(lvp_skin_dual_quaternion, &t, &w, matrices, 2);
	for (int32_t v = 0; v < t.vertex_count; ++v) {
		double expected[3];
		transform(expected, matrices, t.positions + 3 * v);
		for (int i = 0; i < 3; ++i)
			CHECK_NEAR(out[3 * v + i], expected[i], 1e-5);
	}
	free(out);

	/* uniform scale 2 on both bones, bone 1 also turned about the axis: every ring's radius doubles */
	make_matrix(matrices, 0, 0, 1, 0, 2, 2, 2, 0, 0, 0);
	make_matrix(matrices + 16, 0, 0, 1, 1.2, 2, 2, 2, 0, 0, 0);
	out = skin(lvp_skin_dual_quaternion, &t, &w, matrices, 2);
	for (int ring = 0; ring < t.rings; ++ring) {
		double min_radius, max_radius = ring_radius(out, &t, ring, &min_radius);
		CHECK_NEAR(max_radius, 2.0 * t.radius, 1e-5);
		CHECK_NEAR(min_radius, 2.0 * t.radius, 1e-5);
	}
	free(out);
	tube_free(&t);
}

/* Mirrored and collapsed (zero-scale) bones have no rotation to speak of; the split into rotation and
 * residual must still reproduce the matrix exactly. */
static void test_dual_quaternions_reproduce_mirrored_and_collapsed_bones(void)
{
	tube t = make_tube(12, 9, 0.5f, 4.0f, 2.6f);
	tube_weigh_rigidly(&t, 0);
	lvp_weights w = tube_weights(&t);
	const double scales[4][3] = {{-1, 1, 1}, {0, 1, 1}, {0, 0, 0}, {1, -2, 0.5}};
	for (int c = 0; c < 4; ++c) {
		float matrix[16];
		make_matrix(matrix, 0.5, -0.2, 1, 0.9, scales[c][0], scales[c][1], scales[c][2], 0.5, 0.25, -1);
		float *out = skin(lvp_skin_dual_quaternion, &t, &w, matrix, 1);
		for (int32_t v = 0; v < t.vertex_count; ++v) {
			double expected[3];
			transform(expected, matrix, t.positions + 3 * v);
			for (int i = 0; i < 3; ++i)
				CHECK_NEAR(out[3 * v + i], expected[i], 1e-5);
		}
		free(out);
	}
	tube_free(&t);
}

/* Rotations of +170 and -170 degrees about the axis are 20 degrees apart the short way: blended half and
 * half they give a half turn, not the identity a naive sum of quaternions would give. */
static void test_dual_quaternions_blend_along_the_shorter_arc(void)
{
	float rest[3] = {1, 0, 0.5f}, out[3];
	int32_t offsets[2] = {0, 2}, bones[2] = {0, 1};
	float values[2] = {0.5f, 0.5f};
	lvp_weights w = {offsets, bones, values};
	float matrices[32];
	make_matrix(matrices, 0, 0, 1, 170.0 * PI / 180.0, 1, 1, 1, 0, 0, 0);
	make_matrix(matrices + 16, 0, 0, 1, -170.0 * PI / 180.0, 1, 1, 1, 0, 0, 0);
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_skin_dual_quaternion(out, rest, 1, &w, matrices, 2, &diag), diag);
	CHECK_NEAR(out[0], -1.0, 1e-6);
	CHECK_NEAR(out[1], 0.0, 1e-6);
	CHECK_NEAR(out[2], 0.5, 1e-6);
}

/* ---- errors -------------------------------------------------------------------------------------- */

static void test_error_paths_name_the_argument(void)
{
	tube t = make_tube(4, 5, 0.5f, 4.0f, 2.6f);
	int32_t n = t.vertex_count;
	float matrices[32];
	identity(matrices);
	identity(matrices + 16);
	float *out = malloc(sizeof(float) * 3 * (size_t)n);
	for (int m = 0; m < 2; ++m) {
		skin_function f = methods[m];
		lvp_weights w = tube_weights(&t), broken;
		lvp_diagnostic diag;
		memset(&diag, 0, sizeof(diag));
		for (int32_t i = 0; i < 3 * n; ++i)
			out[i] = 777.0f;
		CHECK_ERROR(f(NULL, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_null_argument, "r_positions", -1);
		CHECK_ERROR(f(out, NULL, n, &w, matrices, 2, &diag), &diag, lvp_error_null_argument, "rest_positions", -1);
		CHECK_ERROR(f(out, t.positions, n, NULL, matrices, 2, &diag), &diag, lvp_error_null_argument, "weights.offsets",
		            -1);
		broken = w, broken.offsets = NULL;
		CHECK_ERROR(f(out, t.positions, n, &broken, matrices, 2, &diag), &diag, lvp_error_null_argument,
		            "weights.offsets", -1);
		broken = w, broken.values = NULL;
		CHECK_ERROR(f(out, t.positions, n, &broken, matrices, 2, &diag), &diag, lvp_error_null_argument,
		            "weights.values", -1);
		CHECK_ERROR(f(out, t.positions, n, &w, NULL, 2, &diag), &diag, lvp_error_null_argument, "skin_matrices", -1);
		CHECK_ERROR(f(out, t.positions, 0, &w, matrices, 2, &diag), &diag, lvp_error_invalid_size, "vertex_count", -1);
		CHECK_ERROR(f(out, t.positions, -1, &w, matrices, 2, &diag), &diag, lvp_error_invalid_size, "vertex_count", -1);
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 0, &diag), &diag, lvp_error_invalid_size, "bone_count", -1);
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, LVP_MAX_BONES + 1, &diag), &diag, lvp_error_invalid_size,
		            "bone_count", -1);
		/* bone 1 exists only when bone_count is 2 */
		int32_t first_on_bone_1 = 0;
		while (t.bones[first_on_bone_1] != 1)
			++first_on_bone_1;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 1, &diag), &diag,
		            lvp_error_index_out_of_range, "weights.bones", first_on_bone_1);
		int32_t saved = t.offsets[3];
		t.offsets[3] = t.offsets[4] + 1;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 2, &diag), &diag,
		            lvp_error_invalid_size, "weights.offsets", 4);
		t.offsets[3] = saved;
		t.values[5] = -0.5f;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 2, &diag), &diag,
		            lvp_error_negative_weight, "weights.values", 5);
		t.values[5] = NAN;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_not_finite, "weights.values", 5);
		t.values[5] = 1.0f;
		t.positions[7] = INFINITY;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_not_finite, "rest_positions", 7);
		t.positions[7] = 0.0f;
		matrices[16 + 5] = NAN;
		CHECK_ERROR(f(out, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_not_finite, "skin_matrices", 21);
		matrices[16 + 5] = 1.0f;
		/* writing over the rest positions while reading them is refused */
		CHECK_ERROR(f(t.positions, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_invalid_option,
		            "r_positions", -1);
		CHECK_ERROR(f((float *)t.values, t.positions, n, &w, matrices, 2, &diag), &diag, lvp_error_invalid_option,
		            "r_positions", -1);
		for (int32_t i = 0; i < 3 * n; ++i)
			CHECK(out[i] == 777.0f); /* no failure wrote anything */
		CHECK(f(out, t.positions, n, &w, matrices, 2, NULL) == lvp_success);
		CHECK(f(NULL, t.positions, n, &w, matrices, 2, NULL) == lvp_error_null_argument);
	}
	free(out);
	tube_free(&t);
}

int main(void)
{
	RUN(test_identity_matrices_leave_the_mesh);
	RUN(test_single_rigid_bone_moves_the_mesh_rigidly);
	RUN(test_twist_collapses_linear_blend_but_not_dual_quaternions);
	RUN(test_weights_are_normalized_by_their_sum);
	RUN(test_vertices_without_weight_keep_rest_position);
	RUN(test_dual_quaternions_apply_bone_scale);
	RUN(test_dual_quaternions_reproduce_mirrored_and_collapsed_bones);
	RUN(test_dual_quaternions_blend_along_the_shorter_arc);
	RUN(test_error_paths_name_the_argument);
	return check_failures() != 0;
}
