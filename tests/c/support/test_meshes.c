/*
 * test_meshes.c - built test geometry (the paper's cylinder, bone chains, a finger), forward
 * kinematics and small helpers over test_rig. The giraffe loader is in giraffe_loader.c, the exact
 * intersection count in test_intersect.c. Contract: test_meshes.h.
 */
#include "support/test_meshes.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TEST_PI 3.14159265358979323846

/* Test code: running out of memory is not a case worth handling gracefully, but it must not
 * turn into a NULL dereference that looks like a bug in the core. */
static void *test__alloc(size_t count, size_t size)
{
	void *p = calloc(count ? count : 1, size);
	if (!p) {
		fprintf(stderr, "test_meshes: out of memory (%zu x %zu bytes)\n", count, size);
		abort();
	}
	return p;
}

void test_rig_free(test_rig *rig)
{
	if (!rig)
		return;
	free(rig->positions);
	free(rig->triangles);
	free(rig->weight_offsets);
	free(rig->weight_bones);
	free(rig->weight_values);
	free(rig->rest_matrices);
	free(rig->heads);
	free(rig->tails);
	free(rig->parents);
	free(rig->names);
	memset(rig, 0, sizeof(*rig));
}

lvp_weights test_rig_weights(const test_rig *rig)
{
	lvp_weights w = {rig->weight_offsets, rig->weight_bones, rig->weight_values};
	return w;
}

lvp_skeleton test_rig_skeleton(const test_rig *rig)
{
	lvp_skeleton s = {rig->bone_count, rig->rest_matrices, rig->heads, rig->tails, rig->parents};
	return s;
}

int32_t test_find_bone(const test_rig *rig, const char *name)
{
	if (!rig->names || !name)
		return -1;
	for (int32_t i = 0; i < rig->bone_count; ++i)
		if (strcmp(rig->names[i], name) == 0)
			return i;
	return -1;
}

char *test_read_file(const char *path, size_t *r_size)
{
	FILE *file = fopen(path, "rb");
	if (!file)
		return NULL;
	/* Read in chunks rather than trusting ftell, so pipes and growing files work too. */
	size_t size = 0, capacity = 4096;
	char *data = malloc(capacity + 1);
	while (data) {
		size_t got = fread(data + size, 1, capacity - size, file);
		size += got;
		if (size < capacity)
			break;
		char *bigger = realloc(data, capacity * 2 + 1);
		if (!bigger) {
			free(data);
			data = NULL;
			break;
		}
		data = bigger;
		capacity *= 2;
	}
	int failed = ferror(file);
	fclose(file);
	if (!data || failed) {
		free(data);
		return NULL;
	}
	data[size] = '\0';
	if (r_size)
		*r_size = size;
	return data;
}

/* ---- tubes ------------------------------------------------------------------------------ */

/* A closed tube along +Z: `ring_count` rings of `around` vertices (ring-major, vertex j of ring i
 * at index i*around + j, angle 2 pi j / around counter-clockwise seen from +Z), then one centre
 * vertex per cap: the first at (0, 0, cap0_z), the second at (0, 0, cap1_z). Triangles wind
 * counter-clockwise seen from outside. Fills positions and triangles of r_rig. */
static void test__build_tube(test_rig *r_rig, int around, int ring_count, const double *ring_z,
                             const double *ring_radius, double cap0_z, double cap1_z)
{
	int32_t vertex_count = around * ring_count + 2;
	int32_t triangle_count = 2 * around * (ring_count - 1) + 2 * around;
	float *p = test__alloc((size_t)vertex_count * 3, sizeof(float));
	int32_t *t = test__alloc((size_t)triangle_count * 3, sizeof(int32_t));
	for (int i = 0; i < ring_count; ++i)
		for (int j = 0; j < around; ++j) {
			double angle = 2.0 * TEST_PI * j / around;
			float *v = p + 3 * (i * around + j);
			v[0] = (float)(ring_radius[i] * cos(angle));
			v[1] = (float)(ring_radius[i] * sin(angle));
			v[2] = (float)ring_z[i];
		}
	int32_t c0 = around * ring_count, c1 = c0 + 1;
	p[3 * c0 + 2] = (float)cap0_z;
	p[3 * c1 + 2] = (float)cap1_z;
	int32_t *out = t;
	for (int i = 0; i + 1 < ring_count; ++i)
		for (int j = 0; j < around; ++j) {
			int32_t a0 = i * around + j, a1 = i * around + (j + 1) % around;
			int32_t b0 = a0 + around, b1 = a1 + around;
			/* (tangent along +angle) x (+Z) points outward. */
			*out++ = a0, *out++ = a1, *out++ = b1;
			*out++ = a0, *out++ = b1, *out++ = b0;
		}
	int32_t last = (ring_count - 1) * around;
	for (int j = 0; j < around; ++j) {
		int32_t a0 = j, a1 = (j + 1) % around;
		*out++ = c0, *out++ = a1, *out++ = a0; /* faces -Z */
		*out++ = c1, *out++ = last + a0, *out++ = last + a1; /* faces +Z */
	}
	r_rig->vertex_count = vertex_count;
	r_rig->triangle_count = triangle_count;
	r_rig->positions = p;
	r_rig->triangles = t;
}

/* Weights for a straight chain of bones along one axis: bone i covers [joints[i], joints[i+1]]
 * of the axial coordinate s, and around every inner joint j (between bones j-1 and j) the weight
 * of bone j rises linearly from 0 to 1 over a band of width `band` centred on the joint. The
 * bands must not overlap. Zero weights are not stored. */
static void test__chain_weights(test_rig *rig, const double *axial, const double *joints, double band)
{
	int32_t n = rig->vertex_count, b = rig->bone_count;
	rig->weight_offsets = test__alloc((size_t)n + 1, sizeof(int32_t));
	rig->weight_bones = test__alloc((size_t)n * 2, sizeof(int32_t));
	rig->weight_values = test__alloc((size_t)n * 2, sizeof(float));
	int32_t count = 0;
	for (int32_t k = 0; k < n; ++k) {
		double s = axial[k];
		int32_t bone = 0;
		double w = 1.0; /* weight of `bone`; the rest goes to bone - 1 */
		for (int32_t j = 1; j < b; ++j) {
			double start = joints[j] - 0.5 * band;
			if (s < start)
				break;
			bone = j;
			w = fmin((s - start) / band, 1.0);
		}
		rig->weight_offsets[k] = count;
		if (w < 1.0) {
			rig->weight_bones[count] = bone - 1;
			rig->weight_values[count++] = (float)(1.0 - w);
		}
		if (w > 0.0) {
			rig->weight_bones[count] = bone;
			rig->weight_values[count++] = (float)w;
		}
	}
	rig->weight_offsets[n] = count;
}

/* A row-major 4x4 frame: rotation columns x_axis, y_axis, z_axis, translation origin. */
static void test__frame(float *r_m, const double *x_axis, const double *y_axis, const double *z_axis,
                        const double *origin)
{
	for (int r = 0; r < 3; ++r) {
		r_m[4 * r + 0] = (float)x_axis[r];
		r_m[4 * r + 1] = (float)y_axis[r];
		r_m[4 * r + 2] = (float)z_axis[r];
		r_m[4 * r + 3] = (float)origin[r];
	}
	r_m[12] = r_m[13] = r_m[14] = 0.0f;
	r_m[15] = 1.0f;
}

/* Bones along +Z from joints[i] to joints[i+1], each parented to the previous one, with Blender's
 * frame for a bone pointing up +Z with zero roll: local X = world X, local Y = world Z (along the
 * bone), local Z = world -Y. */
static void test__chain_skeleton_z(test_rig *rig, const double *joints)
{
	int32_t b = rig->bone_count;
	rig->rest_matrices = test__alloc((size_t)b * 16, sizeof(float));
	rig->heads = test__alloc((size_t)b * 3, sizeof(float));
	rig->tails = test__alloc((size_t)b * 3, sizeof(float));
	rig->parents = test__alloc((size_t)b, sizeof(int32_t));
	static const double x_axis[3] = {1, 0, 0}, y_axis[3] = {0, 0, 1}, z_axis[3] = {0, -1, 0};
	for (int32_t i = 0; i < b; ++i) {
		double head[3] = {0, 0, joints[i]};
		test__frame(rig->rest_matrices + 16 * i, x_axis, y_axis, z_axis, head);
		rig->heads[3 * i + 2] = (float)joints[i];
		rig->tails[3 * i + 2] = (float)joints[i + 1];
		rig->parents[i] = i - 1;
	}
}

/* A cylinder of radius `radius` along +Z from 0 to `length`, its rings at ring_z (count of them, the
 * first at 0, the last at length), two bones meeting at length/2 blended over `band` (test_make_cylinder).
 * Frees ring_z. */
static test_rig test__cylinder_of_rings(int around, double *ring_z, int count, float radius, float length,
                                        float band)
{
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	double *ring_radius = test__alloc((size_t)count, sizeof(double));
	for (int i = 0; i < count; ++i)
		ring_radius[i] = radius;
	test__build_tube(&rig, around, count, ring_z, ring_radius, 0.0, length);
	rig.bone_count = 2;
	double joints[3] = {0.0, 0.5 * length, length};
	test__chain_skeleton_z(&rig, joints);
	double *axial = test__alloc((size_t)rig.vertex_count, sizeof(double));
	for (int32_t k = 0; k < rig.vertex_count; ++k)
		axial[k] = rig.positions[3 * k + 2];
	test__chain_weights(&rig, axial, joints, band);
	free(axial);
	free(ring_z);
	free(ring_radius);
	return rig;
}

test_rig test_make_cylinder(int around, int along, float radius, float length, float band)
{
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	if (around < 3 || along < 2)
		return rig;
	double *ring_z = test__alloc((size_t)along, sizeof(double));
	for (int i = 0; i < along; ++i)
		ring_z[i] = (double)length * i / (along - 1);
	return test__cylinder_of_rings(around, ring_z, along, radius, length, band);
}

test_rig test_make_cylinder_twinned(int around, int along, float radius, float length, float band, float gap)
{
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	if (around < 3 || along < 3 || !(gap > 0.0f && gap < 1.0f))
		return rig;
	int count = along + (along - 1) / 2, written = 0;
	double *ring_z = test__alloc((size_t)count, sizeof(double));
	double spacing = (double)length / (along - 1);
	for (int i = 0; i < along; ++i) {
		ring_z[written++] = spacing * i;
		if (i % 2 == 1 && i < along - 1)
			ring_z[written++] = spacing * (i + (double)gap);
	}
	return test__cylinder_of_rings(around, ring_z, written, radius, length, band);
}

test_rig test_make_chain(int bone_count, float bone_length, float radius, int around, int rings_per_bone,
                         float band)
{
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	if (bone_count < 1 || around < 3 || rings_per_bone < 1 || !(band > 0.0f && band <= 1.0f))
		return rig;
	int ring_count = rings_per_bone * bone_count + 1;
	double *ring_z = test__alloc((size_t)ring_count, sizeof(double));
	double *ring_radius = test__alloc((size_t)ring_count, sizeof(double));
	for (int i = 0; i < ring_count; ++i) {
		ring_z[i] = (double)bone_length * i / rings_per_bone;
		ring_radius[i] = radius;
	}
	double total = (double)bone_length * bone_count;
	test__build_tube(&rig, around, ring_count, ring_z, ring_radius, 0.0, total);
	rig.bone_count = bone_count;
	double *joints = test__alloc((size_t)bone_count + 1, sizeof(double));
	for (int i = 0; i <= bone_count; ++i)
		joints[i] = (double)bone_length * i;
	test__chain_skeleton_z(&rig, joints);
	double *axial = test__alloc((size_t)rig.vertex_count, sizeof(double));
	for (int32_t k = 0; k < rig.vertex_count; ++k)
		axial[k] = rig.positions[3 * k + 2];
	test__chain_weights(&rig, axial, joints, (double)band * bone_length);
	free(axial);
	free(joints);
	free(ring_z);
	free(ring_radius);
	return rig;
}

/* The finger's proportions. The bands are short (a real knuckle bends over a short stretch of
 * skin), which is what lets plain skinning fold the inside of the bend through itself. */
#define FINGER_RADIUS 0.22
#define FINGER_BAND 0.2
#define FINGER_AROUND 16
#define FINGER_TUBE_RINGS 40 /* rings on the straight part, from y = 0 to the tip's equator */
#define FINGER_TIP_RINGS 4   /* rings on the rounded tip, between its equator and its pole */

test_rig test_make_finger(void)
{
	static const double lengths[3] = {1.0, 0.7, 0.5};
	double joints[4] = {0.0, lengths[0], lengths[0] + lengths[1], lengths[0] + lengths[1] + lengths[2]};
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	/* Built along +Z, then turned so the finger points along +Y. */
	int ring_count = FINGER_TUBE_RINGS + FINGER_TIP_RINGS;
	double ring_z[FINGER_TUBE_RINGS + FINGER_TIP_RINGS], ring_radius[FINGER_TUBE_RINGS + FINGER_TIP_RINGS];
	double equator = joints[3] - FINGER_RADIUS;
	for (int i = 0; i < FINGER_TUBE_RINGS; ++i) {
		ring_z[i] = equator * i / (FINGER_TUBE_RINGS - 1);
		ring_radius[i] = FINGER_RADIUS;
	}
	for (int i = 1; i <= FINGER_TIP_RINGS; ++i) {
		double phi = 0.5 * TEST_PI * i / (FINGER_TIP_RINGS + 1);
		ring_z[FINGER_TUBE_RINGS + i - 1] = equator + FINGER_RADIUS * sin(phi);
		ring_radius[FINGER_TUBE_RINGS + i - 1] = FINGER_RADIUS * cos(phi);
	}
	test__build_tube(&rig, FINGER_AROUND, ring_count, ring_z, ring_radius, 0.0, joints[3]);
	/* (x, y, z) -> (x, z, -y) is a rotation (determinant +1), so the winding stays outward. */
	double *axial = test__alloc((size_t)rig.vertex_count, sizeof(double));
	for (int32_t k = 0; k < rig.vertex_count; ++k) {
		float *v = rig.positions + 3 * k;
		float y = v[1];
		v[1] = v[2];
		v[2] = -y;
		if (v[2] == 0.0f)
			v[2] = 0.0f; /* no negative zeros: keeps printed coordinates tidy */
		axial[k] = v[1];
	}
	rig.bone_count = 3;
	rig.rest_matrices = test__alloc(3 * 16, sizeof(float));
	rig.heads = test__alloc(3 * 3, sizeof(float));
	rig.tails = test__alloc(3 * 3, sizeof(float));
	rig.parents = test__alloc(3, sizeof(int32_t));
	rig.names = test__alloc(3, sizeof(*rig.names));
	static const double x_axis[3] = {1, 0, 0}, y_axis[3] = {0, 1, 0}, z_axis[3] = {0, 0, 1};
	for (int i = 0; i < 3; ++i) {
		double head[3] = {0, joints[i], 0};
		test__frame(rig.rest_matrices + 16 * i, x_axis, y_axis, z_axis, head);
		rig.heads[3 * i + 1] = (float)joints[i];
		rig.tails[3 * i + 1] = (float)joints[i + 1];
		rig.parents[i] = i - 1;
		snprintf(rig.names[i], sizeof(rig.names[i]), "phalanx%d", i + 1);
	}
	test__chain_weights(&rig, axial, joints, FINGER_BAND);
	free(axial);
	return rig;
}

void test_shift_finger_bands(test_rig *rig, double shift)
{
	/* The knuckles are the heads of the second and third phalanges; the finger runs along +Y. */
	double joints[4] = {rig->heads[1], rig->heads[4] - shift, rig->heads[7] - shift, rig->tails[7]};
	double *axial = test__alloc((size_t)rig->vertex_count, sizeof(double));
	for (int32_t k = 0; k < rig->vertex_count; ++k)
		axial[k] = rig->positions[3 * k + 1];
	free(rig->weight_offsets);
	free(rig->weight_bones);
	free(rig->weight_values);
	test__chain_weights(rig, axial, joints, FINGER_BAND);
	free(axial);
}

/* ---- forward kinematics ------------------------------------------------------------------ */

static void test__mat_load(double *r_m, const float *m)
{
	for (int i = 0; i < 16; ++i)
		r_m[i] = m[i];
}

void test_multiply_matrices_double(double r_m[16], const double a[16], const double b[16])
{
	double out[16];
	for (int r = 0; r < 4; ++r)
		for (int c = 0; c < 4; ++c)
			out[4 * r + c] =
			    a[4 * r] * b[c] + a[4 * r + 1] * b[4 + c] + a[4 * r + 2] * b[8 + c] + a[4 * r + 3] * b[12 + c];
	memcpy(r_m, out, sizeof(out));
}

static void test__mat_identity(double *r_m)
{
	memset(r_m, 0, 16 * sizeof(double));
	r_m[0] = r_m[5] = r_m[10] = r_m[15] = 1.0;
}

/* General 4x4 inverse by Gauss-Jordan with partial pivoting; identity when singular (the test
 * rigs are never singular, and a defined result is better than NaNs spreading). */
static void test__mat_inverse(double *r_m, const double *m)
{
	double a[4][8];
	for (int r = 0; r < 4; ++r)
		for (int c = 0; c < 8; ++c)
			a[r][c] = c < 4 ? m[4 * r + c] : (c - 4 == r ? 1.0 : 0.0);
	for (int c = 0; c < 4; ++c) {
		int pivot = c;
		for (int r = c + 1; r < 4; ++r)
			if (fabs(a[r][c]) > fabs(a[pivot][c]))
				pivot = r;
		if (a[pivot][c] == 0.0) {
			test__mat_identity(r_m);
			return;
		}
		for (int k = 0; k < 8; ++k) {
			double t = a[c][k];
			a[c][k] = a[pivot][k];
			a[pivot][k] = t;
		}
		double inv = 1.0 / a[c][c];
		for (int k = 0; k < 8; ++k)
			a[c][k] *= inv;
		for (int r = 0; r < 4; ++r)
			if (r != c && a[r][c] != 0.0) {
				double f = a[r][c];
				for (int k = 0; k < 8; ++k)
					a[r][k] -= f * a[c][k];
			}
	}
	for (int r = 0; r < 4; ++r)
		for (int c = 0; c < 4; ++c)
			r_m[4 * r + c] = a[r][c + 4];
}

/* Rotation by `angle` about the unit `axis` through the origin (Rodrigues). */
static void test__mat_rotation(double *r_m, double x, double y, double z, double angle)
{
	double c = cos(angle), s = sin(angle), t = 1.0 - c;
	test__mat_identity(r_m);
	r_m[0] = t * x * x + c, r_m[1] = t * x * y - s * z, r_m[2] = t * x * z + s * y;
	r_m[4] = t * x * y + s * z, r_m[5] = t * y * y + c, r_m[6] = t * y * z - s * x;
	r_m[8] = t * x * z - s * y, r_m[9] = t * y * z + s * x, r_m[10] = t * z * z + c;
}

void test_pose(float *r_posed, const test_rig *rig, const float *local_rotations)
{
	int32_t b = rig->bone_count;
	/* delta[i] = T_i * rest_i^-1, the world motion of bone i. A bone without rotation copies
	 * its parent's delta unchanged, so with no rotation at all every delta is exactly the
	 * identity and T_i = rest_i bit for bit. */
	double *delta = test__alloc((size_t)b * 16, sizeof(double));
	char *done = test__alloc((size_t)b, 1);
	int32_t remaining = b;
	/* Parents usually come first (one pass); any other order takes one pass per level. */
	while (remaining > 0) {
		int32_t progress = 0;
		for (int32_t i = 0; i < b; ++i) {
			if (done[i])
				continue;
			int32_t parent = rig->parents ? rig->parents[i] : -1;
			if (parent >= 0 && parent < b && parent != i && !done[parent])
				continue;
			double *d = delta + 16 * i;
			if (parent >= 0 && parent < b && parent != i)
				memcpy(d, delta + 16 * parent, 16 * sizeof(double));
			else
				test__mat_identity(d);
			const float *q = local_rotations ? local_rotations + 4 * i : NULL;
			double len = q ? sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2]) : 0.0;
			if (q && len > 0.0 && q[3] != 0.0f) {
				double rest[16], rest_inv[16], rot[16], world[16];
				test__mat_load(rest, rig->rest_matrices + 16 * i);
				test__mat_inverse(rest_inv, rest);
				test__mat_rotation(rot, q[0] / len, q[1] / len, q[2] / len, q[3]);
				/* The axis is in the bone's rest frame, whose origin is the head: conjugating by
				 * the rest frame turns it about the head in world space. */
				test_multiply_matrices_double(world, rest, rot);
				test_multiply_matrices_double(world, world, rest_inv);
				test_multiply_matrices_double(d, d, world);
			}
			done[i] = 1;
			++progress;
			--remaining;
		}
		if (progress == 0) {
			/* A cycle in the parents: treat the rest as roots rather than loop forever. */
			for (int32_t i = 0; i < b; ++i)
				if (!done[i]) {
					test__mat_identity(delta + 16 * i);
					done[i] = 1;
					--remaining;
				}
		}
	}
	for (int32_t i = 0; i < b; ++i) {
		double rest[16], posed[16];
		test__mat_load(rest, rig->rest_matrices + 16 * i);
		test_multiply_matrices_double(posed, delta + 16 * i, rest);
		for (int k = 0; k < 16; ++k)
			r_posed[16 * i + k] = (float)posed[k];
	}
	free(done);
	free(delta);
}

void test_multiply_matrices(float r[16], const float a[16], const float b[16])
{
	double x[16], y[16], product[16];
	test__mat_load(x, a);
	test__mat_load(y, b);
	test_multiply_matrices_double(product, x, y);
	for (int k = 0; k < 16; ++k)
		r[k] = (float)product[k];
}

void test_scale_bone(float posed_bone[16], double sx, double sy, double sz)
{
	const double scale[3] = {sx, sy, sz};
	for (int row = 0; row < 3; ++row)
		for (int col = 0; col < 3; ++col)
			posed_bone[4 * row + col] *= (float)scale[col];
}

void test_skin_matrices(float *r_skin, const test_rig *rig, const float *posed)
{
	for (int32_t i = 0; i < rig->bone_count; ++i) {
		double rest[16], rest_inv[16], p[16], s[16];
		test__mat_load(rest, rig->rest_matrices + 16 * i);
		test__mat_load(p, posed + 16 * i);
		test__mat_inverse(rest_inv, rest);
		test_multiply_matrices_double(s, p, rest_inv);
		for (int k = 0; k < 16; ++k)
			r_skin[16 * i + k] = (float)s[k];
	}
}

int test_pose_and_skin(const test_rig *rig, const float *local_rotations, float **r_posed, float **r_skinned)
{
	int32_t b = rig->bone_count;
	float *skin = malloc(sizeof(float) * 16 * (size_t)b);
	*r_posed = malloc(sizeof(float) * 16 * (size_t)b);
	*r_skinned = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	test_pose(*r_posed, rig, local_rotations);
	test_skin_matrices(skin, rig, *r_posed);
	lvp_weights weights = test_rig_weights(rig);
	lvp_result result = lvp_skin_linear(*r_skinned, rig->positions, rig->vertex_count, &weights, skin, b, NULL);
	free(skin);
	return result == lvp_success ? 0 : -1;
}

int test_pose_rig(test_rig rig, const float *local_rotations, test_posed_rig *r)
{
	r->rig = rig;
	return test_pose_and_skin(&r->rig, local_rotations, &r->posed, &r->skinned);
}

void test_posed_rig_free(test_posed_rig *p)
{
	test_rig_free(&p->rig);
	free(p->posed);
	free(p->skinned);
}

test_rig test_split_at_seams(const test_rig *rig, int32_t **r_original)
{
	int32_t n = rig->vertex_count, f = rig->triangle_count, b = rig->bone_count;
	int32_t *copy_of = malloc(sizeof(int32_t) * 4 * (size_t)n); /* (vertex, island) -> split vertex */
	int32_t *original = malloc(sizeof(int32_t) * 4 * (size_t)n);
	for (int32_t i = 0; i < 4 * n; ++i)
		copy_of[i] = -1;
	test_rig split = *rig;
	split.triangles = malloc(sizeof(int32_t) * 3 * (size_t)f);
	int32_t count = n;
	for (int32_t k = 0; k < n; ++k)
		original[k] = k;
	for (int32_t t = 0; t < f; ++t) {
		float cx = 0.0f, cy = 0.0f;
		for (int c = 0; c < 3; ++c) {
			cx += rig->positions[3 * rig->triangles[3 * t + c]];
			cy += rig->positions[3 * rig->triangles[3 * t + c] + 1];
		}
		int island = (cx >= 0.0f) + 2 * (cy >= 0.0f);
		for (int c = 0; c < 3; ++c) {
			int32_t k = rig->triangles[3 * t + c];
			int32_t *slot = &copy_of[4 * k + island];
			if (*slot < 0) {
				bool used = false;
				for (int other = 0; other < 4; ++other)
					used = used || copy_of[4 * k + other] >= 0;
				*slot = used ? count : k;
				if (used)
					original[count++] = k;
			}
			split.triangles[3 * t + c] = *slot;
		}
	}
	split.vertex_count = count;
	split.positions = malloc(sizeof(float) * 3 * (size_t)count);
	split.weight_offsets = malloc(sizeof(int32_t) * ((size_t)count + 1));
	int32_t entries = 0;
	for (int32_t k = 0; k < count; ++k)
		entries += rig->weight_offsets[original[k] + 1] - rig->weight_offsets[original[k]];
	split.weight_bones = malloc(sizeof(int32_t) * (size_t)entries);
	split.weight_values = malloc(sizeof(float) * (size_t)entries);
	split.weight_offsets[0] = 0;
	for (int32_t k = 0; k < count; ++k) {
		int32_t o = original[k], begin = rig->weight_offsets[o], length = rig->weight_offsets[o + 1] - begin;
		memcpy(split.positions + 3 * k, rig->positions + 3 * o, sizeof(float) * 3);
		memcpy(split.weight_bones + split.weight_offsets[k], rig->weight_bones + begin, sizeof(int32_t) * (size_t)length);
		memcpy(split.weight_values + split.weight_offsets[k], rig->weight_values + begin, sizeof(float) * (size_t)length);
		split.weight_offsets[k + 1] = split.weight_offsets[k] + length;
	}
	split.rest_matrices = malloc(sizeof(float) * 16 * (size_t)b);
	split.heads = malloc(sizeof(float) * 3 * (size_t)b);
	split.tails = malloc(sizeof(float) * 3 * (size_t)b);
	split.parents = malloc(sizeof(int32_t) * (size_t)b);
	split.names = NULL;
	if (rig->names) {
		split.names = malloc(sizeof(*rig->names) * (size_t)b);
		memcpy(split.names, rig->names, sizeof(*rig->names) * (size_t)b);
	}
	memcpy(split.rest_matrices, rig->rest_matrices, sizeof(float) * 16 * (size_t)b);
	memcpy(split.heads, rig->heads, sizeof(float) * 3 * (size_t)b);
	memcpy(split.tails, rig->tails, sizeof(float) * 3 * (size_t)b);
	memcpy(split.parents, rig->parents, sizeof(int32_t) * (size_t)b);
	free(copy_of);
	*r_original = original;
	return split;
}

static double test_length3(const float *v)
{
	return sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
}

double test_largest_distance(const float *a, const float *b, int32_t count)
{
	double largest = 0.0;
	for (int32_t k = 0; k < count; ++k) {
		double d2 = 0.0;
		for (int c = 0; c < 3; ++c) {
			double d = (double)a[3 * k + c] - (b ? (double)b[3 * k + c] : 0.0);
			d2 += d * d;
		}
		largest = fmax(largest, sqrt(d2));
	}
	return largest;
}

double test_roughness(const test_rig *rig, const float *offsets)
{
	int32_t n = rig->vertex_count;
	double *sum = calloc((size_t)n * 3, sizeof(double)), largest = test_largest_distance(offsets, NULL, n), worst = 0.0;
	int32_t *count = calloc((size_t)n, sizeof(int32_t));
	for (int32_t t = 0; t < rig->triangle_count; ++t)
		for (int e = 0; e < 3; ++e) {
			int32_t a = rig->triangles[3 * t + e], b = rig->triangles[3 * t + (e + 1) % 3];
			for (int c = 0; c < 3; ++c) {
				sum[3 * a + c] += offsets[3 * b + c];
				sum[3 * b + c] += offsets[3 * a + c];
			}
			++count[a];
			++count[b];
		}
	for (int32_t k = 0; k < n; ++k) {
		if (count[k] == 0)
			continue;
		float difference[3];
		for (int c = 0; c < 3; ++c)
			difference[c] = (float)(offsets[3 * k + c] - sum[3 * k + c] / count[k]);
		worst = fmax(worst, test_length3(difference));
	}
	free(sum);
	free(count);
	return largest > 0.0 ? worst / largest : 0.0;
}
