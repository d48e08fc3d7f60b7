/*
 * skinning.c - linear blend skinning (Rohmer, Hahmann, Cani 2008, eq. 6) and dual quaternion skinning
 * (Kavan, Collins, Zara, O'Sullivan 2008) in the form of Blender's Armature modifier "Preserve Volume".
 *
 * Both take sparse influences and the skin matrices posed_i * rest_i^-1. The matrices are affine: their
 * last row is ignored (taken as 0 0 0 1), as Blender's bone matrices always are. Weights are divided by
 * their sum, so they need not be normalized; a vertex whose weights sum to zero keeps its rest position,
 * as in Blender.
 */
#include "lvp_internal.h"

#include <stdint.h>
#include <stdlib.h>

/* [a, a + a_bytes) and [b, b + b_bytes) share a byte. Compared as integers: relational operators on
 * pointers into different objects are undefined in C. */
static bool lvp__overlaps(const void *a, size_t a_bytes, const void *b, size_t b_bytes)
{
	if (!a || !b || a_bytes == 0 || b_bytes == 0)
		return false;
	uintptr_t a0 = (uintptr_t)a, b0 = (uintptr_t)b;
	return a0 < b0 + b_bytes && b0 < a0 + a_bytes;
}

/* Everything both skinning functions need to trust their input; nothing is written before it passes. */
static lvp_result lvp__check_skinning(const float *r_positions, const float *rest_positions, int32_t vertex_count,
                                      const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                                      lvp_diagnostic *r_diag)
{
	if (!r_positions)
		return lvp__fail(r_diag, lvp_error_null_argument, "r_positions", -1,
		                 "r_positions is NULL; pass a buffer of vertex_count*3 floats.");
	if (vertex_count <= 0 || vertex_count > LVP_MAX_VERTICES)
		return lvp__fail(r_diag, lvp_error_invalid_size, "vertex_count", -1,
		                 "vertex_count is %d; it must be between 1 and %d.", (int)vertex_count, LVP_MAX_VERTICES);
	if (bone_count <= 0 || bone_count > LVP_MAX_BONES)
		return lvp__fail(r_diag, lvp_error_invalid_size, "bone_count", -1,
		                 "bone_count is %d; it must be between 1 and %d.", (int)bone_count, LVP_MAX_BONES);
	lvp_result result;
	if ((result = lvp__check_float_array(rest_positions, (int64_t)vertex_count * 3, "rest_positions", r_diag)))
		return result;
	if ((result = lvp__check_float_array(skin_matrices, (int64_t)bone_count * 16, "skin_matrices", r_diag)))
		return result;
	if ((result = lvp__check_weights(weights, vertex_count, bone_count, r_diag)))
		return result;
	/* The output is written vertex by vertex while the inputs are still read: an overlap would feed
	 * skinned positions back in. */
	size_t out_bytes = sizeof(float) * 3 * (size_t)vertex_count;
	size_t influences = (size_t)weights->offsets[vertex_count];
	struct {
		const void *pointer;
		size_t bytes;
		const char *name;
	} inputs[] = {
	    {rest_positions, out_bytes, "rest_positions"},
	    {skin_matrices, sizeof(float) * 16 * (size_t)bone_count, "skin_matrices"},
	    {weights->offsets, sizeof(int32_t) * ((size_t)vertex_count + 1), "weights.offsets"},
	    {weights->bones, sizeof(int32_t) * influences, "weights.bones"},
	    {weights->values, sizeof(float) * influences, "weights.values"},
	};
	for (size_t i = 0; i < sizeof(inputs) / sizeof(inputs[0]); ++i)
		if (lvp__overlaps(r_positions, out_bytes, inputs[i].pointer, inputs[i].bytes))
			return lvp__fail(r_diag, lvp_error_invalid_option, "r_positions", -1,
			                 "r_positions overlaps %s; skinning needs a separate output buffer.", inputs[i].name);
	return lvp_success;
}

lvp_result lvp_skin_linear(float *r_positions, const float *rest_positions, int32_t vertex_count,
                           const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                           lvp_diagnostic *r_diag)
{
	lvp_result result =
	    lvp__check_skinning(r_positions, rest_positions, vertex_count, weights, skin_matrices, bone_count, r_diag);
	if (result != lvp_success)
		return result;
	for (int32_t k = 0; k < vertex_count; ++k) {
		const float *rest = rest_positions + 3 * (int64_t)k;
		float *out = r_positions + 3 * (int64_t)k;
		int32_t begin = weights->offsets[k], end = weights->offsets[k + 1];
		/* Blending the transformed points costs the same as blending the matrices and reads each
		 * matrix once. Sums of floats cannot overflow a double. */
		lvp__vec3 p = lvp__load(rest), sum = lvp__v(0.0, 0.0, 0.0);
		double weight_sum = 0.0;
		for (int32_t e = begin; e < end; ++e) {
			double w = weights->values[e];
			if (w == 0.0)
				continue;
			lvp__mat4 m = lvp__mat4_load(skin_matrices + 16 * (int64_t)weights->bones[e]);
			sum = lvp__add(sum, lvp__scale(lvp__transform_point(&m, p), w));
			weight_sum += w;
		}
		if (!(weight_sum > 0.0)) {
			out[0] = rest[0], out[1] = rest[1], out[2] = rest[2];
			continue;
		}
		sum = lvp__scale(sum, 1.0 / weight_sum);
		out[0] = (float)sum.x, out[1] = (float)sum.y, out[2] = (float)sum.z;
	}
	return lvp_success;
}

/* ---- dual quaternion skinning --------------------------------------------------------------------- */

/* Quaternions are (w, x, y, z). */
typedef struct lvp__quat {
	double w, x, y, z;
} lvp__quat;

/* One bone, split as skin matrix = [R X | t]: R a rotation (the quaternion real), t the translation
 * (carried by the dual part), X = R^-1 * (3x3 part) the scale and shear applied before R. */
typedef struct lvp__dq_bone {
	lvp__quat real, dual;
	double scale[9]; /* X, row-major */
} lvp__dq_bone;

/* Eigen-decomposition of a symmetric 4x4 matrix by cyclic Jacobi rotations; r_vectors receives the
 * eigenvectors as columns, the diagonal of a the eigenvalues. Four dimensions converge in a few sweeps. */
static void lvp__jacobi4(double a[4][4], double r_vectors[4][4])
{
	for (int i = 0; i < 4; ++i)
		for (int j = 0; j < 4; ++j)
			r_vectors[i][j] = i == j ? 1.0 : 0.0;
	for (int sweep = 0; sweep < 32; ++sweep) {
		double off = 0.0, diagonal = 0.0;
		for (int i = 0; i < 4; ++i) {
			diagonal += a[i][i] * a[i][i];
			for (int j = i + 1; j < 4; ++j)
				off += a[i][j] * a[i][j];
		}
		if (!(off > 1e-32 * diagonal))
			return;
		for (int p = 0; p < 4; ++p)
			for (int q = p + 1; q < 4; ++q) {
				if (a[p][q] == 0.0)
					continue;
				/* The rotation that zeroes a[p][q] (Golub and Van Loan, algorithm 8.4.1). */
				double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
				double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
				double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
				for (int k = 0; k < 4; ++k) {
					double akp = a[k][p], akq = a[k][q];
					a[k][p] = c * akp - s * akq;
					a[k][q] = s * akp + c * akq;
				}
				for (int k = 0; k < 4; ++k) {
					double apk = a[p][k], aqk = a[q][k];
					a[p][k] = c * apk - s * aqk;
					a[q][k] = s * apk + c * aqk;
				}
				for (int k = 0; k < 4; ++k) {
					double vkp = r_vectors[k][p], vkq = r_vectors[k][q];
					r_vectors[k][p] = c * vkp - s * vkq;
					r_vectors[k][q] = s * vkp + c * vkq;
				}
			}
	}
}

/* The rotation nearest to the 3x3 matrix a (row-major), i.e. maximizing trace(R^T a), as a unit
 * quaternion: the dominant eigenvector of Horn's 4x4 matrix (Horn 1987; Bar-Itzhack 2000). Unlike an
 * iterated polar decomposition it needs no inverse, so collapsed (zero-scale) bones and mirrored ones
 * still get a proper rotation, and R * (R^T a) = a holds exactly whatever it picks. */
static lvp__quat lvp__nearest_rotation(const double a[9])
{
	/* Horn's S_uv = sum r_u r'_v for r' = a r, i.e. S = a^T. */
	double sxx = a[0], sxy = a[3], sxz = a[6];
	double syx = a[1], syy = a[4], syz = a[7];
	double szx = a[2], szy = a[5], szz = a[8];
	double n[4][4] = {
	    {sxx + syy + szz, syz - szy, szx - sxz, sxy - syx},
	    {syz - szy, sxx - syy - szz, sxy + syx, szx + sxz},
	    {szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy},
	    {sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz},
	};
	double vectors[4][4];
	lvp__jacobi4(n, vectors);
	int best = 0;
	for (int i = 1; i < 4; ++i)
		if (n[i][i] > n[best][best])
			best = i;
	lvp__quat q = {vectors[0][best], vectors[1][best], vectors[2][best], vectors[3][best]};
	double length = sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
	if (!(length > 0.0)) {
		q.w = 1.0, q.x = q.y = q.z = 0.0;
		return q;
	}
	/* q and -q are the same rotation; w >= 0 makes the choice deterministic (blending still aligns every
	 * quaternion to the vertex's strongest bone). */
	if (q.w < 0.0)
		length = -length;
	q.w /= length, q.x /= length, q.y /= length, q.z /= length;
	return q;
}

/* Row-major rotation matrix of a unit quaternion. */
static void lvp__quat_to_matrix(double r_m[9], lvp__quat q)
{
	double xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
	double xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z;
	double wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
	r_m[0] = 1.0 - 2.0 * (yy + zz), r_m[1] = 2.0 * (xy - wz), r_m[2] = 2.0 * (xz + wy);
	r_m[3] = 2.0 * (xy + wz), r_m[4] = 1.0 - 2.0 * (xx + zz), r_m[5] = 2.0 * (yz - wx);
	r_m[6] = 2.0 * (xz - wy), r_m[7] = 2.0 * (yz + wx), r_m[8] = 1.0 - 2.0 * (xx + yy);
}

/* X = R^T a for the rotation r (row-major). */
static void lvp__unrotated(double r_x[9], const double r[9], const double a[9])
{
	for (int i = 0; i < 3; ++i)
		for (int j = 0; j < 3; ++j)
			r_x[3 * i + j] = r[i] * a[j] + r[3 + i] * a[3 + j] + r[6 + i] * a[6 + j];
}

void lvp__split_rotation(double r_x[9], const double a[9])
{
	double r[9];
	lvp__quat_to_matrix(r, lvp__nearest_rotation(a));
	lvp__unrotated(r_x, r, a);
}

static lvp__dq_bone lvp__dq_from_matrix(const float *matrix)
{
	lvp__dq_bone bone;
	double a[9] = {matrix[0], matrix[1], matrix[2], matrix[4], matrix[5], matrix[6], matrix[8], matrix[9], matrix[10]};
	lvp__vec3 t = lvp__v(matrix[3], matrix[7], matrix[11]);
	bone.real = lvp__nearest_rotation(a);
	double r[9];
	lvp__quat_to_matrix(r, bone.real);
	lvp__unrotated(bone.scale, r, a);
	/* dual = 1/2 (0, t) * real */
	lvp__quat q = bone.real;
	bone.dual.w = -0.5 * (t.x * q.x + t.y * q.y + t.z * q.z);
	bone.dual.x = 0.5 * (q.w * t.x + t.y * q.z - t.z * q.y);
	bone.dual.y = 0.5 * (q.w * t.y + t.z * q.x - t.x * q.z);
	bone.dual.z = 0.5 * (q.w * t.z + t.x * q.y - t.y * q.x);
	return bone;
}

lvp_result lvp_skin_dual_quaternion(float *r_positions, const float *rest_positions, int32_t vertex_count,
                                    const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                                    lvp_diagnostic *r_diag)
{
	lvp_result result =
	    lvp__check_skinning(r_positions, rest_positions, vertex_count, weights, skin_matrices, bone_count, r_diag);
	if (result != lvp_success)
		return result;
	lvp__dq_bone *bones = malloc(sizeof(lvp__dq_bone) * (size_t)bone_count);
	if (!bones)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "skin_matrices", -1,
		                 "could not allocate %d dual quaternions.", (int)bone_count);
	for (int32_t i = 0; i < bone_count; ++i)
		bones[i] = lvp__dq_from_matrix(skin_matrices + 16 * (int64_t)i);

	for (int32_t k = 0; k < vertex_count; ++k) {
		const float *rest = rest_positions + 3 * (int64_t)k;
		float *out = r_positions + 3 * (int64_t)k;
		int32_t begin = weights->offsets[k], end = weights->offsets[k + 1];
		/* The strongest bone fixes the hemisphere: every other rotation is blended along the shorter
		 * arc to it, as Blender does (ties go to the first influence listed). */
		int32_t pivot = -1;
		double weight_sum = 0.0;
		for (int32_t e = begin; e < end; ++e) {
			weight_sum += weights->values[e];
			if (weights->values[e] > 0.0f && (pivot < 0 || weights->values[e] > weights->values[pivot]))
				pivot = e;
		}
		if (pivot < 0 || !(weight_sum > 0.0)) {
			out[0] = rest[0], out[1] = rest[1], out[2] = rest[2];
			continue;
		}
		lvp__quat pq = bones[weights->bones[pivot]].real;
		lvp__quat real = {0, 0, 0, 0}, dual = {0, 0, 0, 0};
		double x[9] = {0};
		for (int32_t e = begin; e < end; ++e) {
			double w = weights->values[e] / weight_sum;
			if (w == 0.0)
				continue;
			const lvp__dq_bone *b = &bones[weights->bones[e]];
			for (int j = 0; j < 9; ++j)
				x[j] += w * b->scale[j];
			double hemisphere = pq.w * b->real.w + pq.x * b->real.x + pq.y * b->real.y + pq.z * b->real.z;
			double s = hemisphere < 0.0 ? -w : w;
			real.w += s * b->real.w, real.x += s * b->real.x, real.y += s * b->real.y, real.z += s * b->real.z;
			dual.w += s * b->dual.w, dual.x += s * b->dual.x, dual.y += s * b->dual.y, dual.z += s * b->dual.z;
		}
		/* Never zero: aligned to the pivot, the blend's component along it is at least the pivot's
		 * own weight. */
		double length = sqrt(real.w * real.w + real.x * real.x + real.y * real.y + real.z * real.z);
		double inv = 1.0 / length;
		lvp__vec3 v0 = lvp__v(real.x * inv, real.y * inv, real.z * inv), ve = lvp__v(dual.x * inv, dual.y * inv,
		                                                                                dual.z * inv);
		double w0 = real.w * inv, we = dual.w * inv;
		lvp__vec3 p = lvp__load(rest);
		/* Scale and shear first, in the rest frame, then the blended rigid motion. */
		p = lvp__v(x[0] * p.x + x[1] * p.y + x[2] * p.z, x[3] * p.x + x[4] * p.y + x[5] * p.z,
		           x[6] * p.x + x[7] * p.y + x[8] * p.z);
		lvp__vec3 uv = lvp__cross(v0, p);
		p = lvp__add(p, lvp__add(lvp__scale(uv, 2.0 * w0), lvp__scale(lvp__cross(v0, uv), 2.0)));
		/* Translation of the normalized dual quaternion: 2 (w0 ve - we v0 + v0 x ve); the part of the
		 * dual along the real, which a blend introduces, drops out of this form. */
		lvp__vec3 t = lvp__scale(lvp__add(lvp__sub(lvp__scale(ve, w0), lvp__scale(v0, we)), lvp__cross(v0, ve)), 2.0);
		p = lvp__add(p, t);
		out[0] = (float)p.x, out[1] = (float)p.y, out[2] = (float)p.z;
	}
	free(bones);
	return lvp_success;
}
