/*
 * common.c - diagnostics, validation at the API boundary, and 4x4 matrix arithmetic.
 * Every public entry point validates its input here before touching it: an assert or an
 * out-of-bounds read inside Blender would take the artist's unsaved work with it.
 */
#include "lvp_internal.h"

#include <stdlib.h>
#include <string.h>

#include <stdarg.h>
#include <stdio.h>

const char *lvp_result_name(lvp_result result)
{
	static const char *const names[lvp_result_count] = {
	    "lvp_success",
	    "lvp_error_null_argument",
	    "lvp_error_invalid_size",
	    "lvp_error_index_out_of_range",
	    "lvp_error_not_finite",
	    "lvp_error_negative_weight",
	    "lvp_error_invalid_option",
	    "lvp_error_singular_matrix",
	    "lvp_error_mesh_not_closed",
	    "lvp_error_no_weights",
	    "lvp_error_out_of_memory",
	    "lvp_error_thread",
	};
	if ((unsigned)result >= (unsigned)lvp_result_count)
		return "lvp_error_unknown";
	return names[result];
}

lvp_result lvp__fail(lvp_diagnostic *r_diag, lvp_result result, const char *argument, int64_t index,
                     const char *format, ...)
{
	if (r_diag) {
		va_list args;
		r_diag->argument = argument;
		r_diag->index = index;
		va_start(args, format);
#if defined(__MINGW32__)
		/* msvcrt.dll's vsnprintf, which MinGW calls by default, knows no %zu (lvp_internal.h). */
		__mingw_vsnprintf(r_diag->message, sizeof(r_diag->message), format, args);
#else
		vsnprintf(r_diag->message, sizeof(r_diag->message), format, args);
#endif
		va_end(args);
	}
	return result;
}

lvp_result lvp__check_float_array(const float *values, int64_t count, const char *argument, lvp_diagnostic *r_diag)
{
	if (!values)
		return lvp__fail(r_diag, lvp_error_null_argument, argument, -1, "%s is NULL; pass %lld floats.", argument,
		                 (long long)count);
	/* Every frame passes a million floats through here: blocks are tested branch-free on the
	 * exponent bits (all ones: NaN or infinity), and only a bad block is searched. */
	for (int64_t start = 0; start < count; start += 4096) {
		int64_t end = count - start > 4096 ? start + 4096 : count;
		uint32_t bad = 0;
		for (int64_t i = start; i < end; ++i) {
			uint32_t bits;
			memcpy(&bits, values + i, sizeof(bits));
			bad |= (uint32_t)((bits & 0x7f800000u) == 0x7f800000u);
		}
		if (!bad)
			continue;
		for (int64_t i = start; i < end; ++i)
			if (!lvp__finite(values[i]))
				return lvp__fail(r_diag, lvp_error_not_finite, argument, i,
				                 "%s[%lld] is %s; every value must be a finite number (check the source data for "
				                 "NaN or infinite values).",
				                 argument, (long long)i, isnan(values[i]) ? "NaN" : "infinite");
	}
	return lvp_success;
}

lvp_result lvp__check_mesh(const float *positions, int32_t vertex_count, const int32_t *triangles,
                           int32_t triangle_count, const char *positions_argument, lvp_diagnostic *r_diag)
{
	if (vertex_count <= 0 || vertex_count > LVP_MAX_VERTICES)
		return lvp__fail(r_diag, lvp_error_invalid_size, "vertex_count", -1,
		                 "vertex_count is %d; it must be between 1 and %d.", (int)vertex_count, LVP_MAX_VERTICES);
	if (triangle_count <= 0 || triangle_count > LVP_MAX_TRIANGLES)
		return lvp__fail(r_diag, lvp_error_invalid_size, "triangle_count", -1,
		                 "triangle_count is %d; a mesh needs between 1 and %d triangles.", (int)triangle_count,
		                 LVP_MAX_TRIANGLES);
	if (!triangles)
		return lvp__fail(r_diag, lvp_error_null_argument, "triangles", -1,
		                 "triangles is NULL; pass triangle_count*3 vertex indices.");
	lvp_result result = lvp__check_float_array(positions, (int64_t)vertex_count * 3, positions_argument, r_diag);
	if (result != lvp_success)
		return result;
	for (int64_t i = 0; i < (int64_t)triangle_count * 3; ++i)
		if (triangles[i] < 0 || triangles[i] >= vertex_count)
			return lvp__fail(r_diag, lvp_error_index_out_of_range, "triangles", i,
			                 "triangles[%lld] (corner %d of triangle %lld) is %d, outside the %d vertices "
			                 "[0, %d).",
			                 (long long)i, (int)(i % 3), (long long)(i / 3), (int)triangles[i], (int)vertex_count,
			                 (int)vertex_count);
	return lvp_success;
}

lvp_result lvp__check_weights(const lvp_weights *weights, int32_t vertex_count, int32_t bone_count,
                              lvp_diagnostic *r_diag)
{
	if (!weights || !weights->offsets)
		return lvp__fail(r_diag, lvp_error_null_argument, "weights.offsets", -1,
		                 "the skinning weights are missing; pass vertex_count+1 offsets and the influences.");
	const int32_t *offsets = weights->offsets;
	if (offsets[0] != 0)
		return lvp__fail(r_diag, lvp_error_invalid_size, "weights.offsets", 0,
		                 "weights.offsets[0] is %d; compressed rows start at 0.", (int)offsets[0]);
	for (int32_t k = 0; k < vertex_count; ++k)
		if (offsets[k + 1] < offsets[k])
			return lvp__fail(r_diag, lvp_error_invalid_size, "weights.offsets", k + 1,
			                 "weights.offsets[%d] = %d is below weights.offsets[%d] = %d; offsets must not "
			                 "decrease.",
			                 (int)(k + 1), (int)offsets[k + 1], (int)k, (int)offsets[k]);
	int32_t total = offsets[vertex_count];
	if (total > 0 && (!weights->bones || !weights->values))
		return lvp__fail(r_diag, lvp_error_null_argument, weights->bones ? "weights.values" : "weights.bones", -1,
		                 "weights has %d influences but no %s array.", (int)total,
		                 weights->bones ? "values" : "bones");
	for (int32_t e = 0; e < total; ++e) {
		if (weights->bones[e] < 0 || weights->bones[e] >= bone_count)
			return lvp__fail(r_diag, lvp_error_index_out_of_range, "weights.bones", e,
			                 "weights.bones[%d] is %d, outside the %d bones [0, %d).", (int)e, (int)weights->bones[e],
			                 (int)bone_count, (int)bone_count);
		float w = weights->values[e];
		if (!lvp__finite(w))
			return lvp__fail(r_diag, lvp_error_not_finite, "weights.values", e,
			                 "weights.values[%d] is not a finite number.", (int)e);
		if (w < 0.0f)
			return lvp__fail(r_diag, lvp_error_negative_weight, "weights.values", e,
			                 "weights.values[%d] is %g; skinning weights must be >= 0.", (int)e, (double)w);
	}
	return lvp_success;
}

lvp_result lvp__check_skeleton(const lvp_skeleton *skeleton, lvp_diagnostic *r_diag)
{
	if (!skeleton)
		return lvp__fail(r_diag, lvp_error_null_argument, "skeleton", -1, "skeleton is NULL.");
	if (skeleton->bone_count <= 0 || skeleton->bone_count > LVP_MAX_BONES)
		return lvp__fail(r_diag, lvp_error_invalid_size, "skeleton.bone_count", -1,
		                 "skeleton.bone_count is %d; it must be between 1 and %d.", (int)skeleton->bone_count,
		                 LVP_MAX_BONES);
	int64_t n = skeleton->bone_count;
	lvp_result result;
	if ((result = lvp__check_float_array(skeleton->rest_matrices, n * 16, "skeleton.rest_matrices", r_diag)))
		return result;
	if ((result = lvp__check_float_array(skeleton->heads, n * 3, "skeleton.heads", r_diag)))
		return result;
	if ((result = lvp__check_float_array(skeleton->tails, n * 3, "skeleton.tails", r_diag)))
		return result;
	for (int64_t i = 0; skeleton->parents && i < n; ++i)
		if (skeleton->parents[i] < -1 || skeleton->parents[i] >= n || skeleton->parents[i] == i)
			return lvp__fail(r_diag, lvp_error_index_out_of_range, "skeleton.parents", i,
			                 "skeleton.parents[%lld] is %d; a bone's parent is another of the %lld bones "
			                 "(0 to %lld), or -1 for none.",
			                 (long long)i, (int)skeleton->parents[i], (long long)n, (long long)(n - 1));
	for (int64_t i = 0; i < n; ++i) {
		lvp__mat4 m = lvp__mat4_load(skeleton->rest_matrices + 16 * i), inverse;
		if (!lvp__mat4_invert_affine(&inverse, &m))
			return lvp__fail(r_diag, lvp_error_singular_matrix, "skeleton.rest_matrices", i,
			                 "the rest matrix of bone %lld cannot be inverted (zero scale or collapsed axes); "
			                 "give the bone a non-zero scale at rest.",
			                 (long long)i);
	}
	return lvp_success;
}

/* ---- matrices ----------------------------------------------------------------------------- */

lvp__mat4 lvp__mat4_load(const float *m)
{
	lvp__mat4 r;
	for (int i = 0; i < 16; ++i)
		r.m[i] = m[i];
	return r;
}

lvp__mat4 lvp__mat4_mul(const lvp__mat4 *a, const lvp__mat4 *b)
{
	lvp__mat4 r;
	for (int i = 0; i < 4; ++i)
		for (int j = 0; j < 4; ++j) {
			double s = 0.0;
			for (int k = 0; k < 4; ++k)
				s += a->m[4 * i + k] * b->m[4 * k + j];
			r.m[4 * i + j] = s;
		}
	return r;
}

double lvp__mat4_det3(const lvp__mat4 *a)
{
	const double *m = a->m;
	return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) +
	       m[2] * (m[4] * m[9] - m[5] * m[8]);
}

bool lvp__mat4_invert_affine(lvp__mat4 *r_inverse, const lvp__mat4 *a)
{
	const double *m = a->m;
	double det = lvp__mat4_det3(a);
	double scale = 1.0;
	for (int row = 0; row < 3; ++row)
		scale *= sqrt(m[4 * row] * m[4 * row] + m[4 * row + 1] * m[4 * row + 1] + m[4 * row + 2] * m[4 * row + 2]);
	if (!(fabs(det) > 1e-12 * scale) || !isfinite(det))
		return false;
	double inv = 1.0 / det;
	double *r = r_inverse->m;
	r[0] = (m[5] * m[10] - m[6] * m[9]) * inv;
	r[1] = (m[2] * m[9] - m[1] * m[10]) * inv;
	r[2] = (m[1] * m[6] - m[2] * m[5]) * inv;
	r[4] = (m[6] * m[8] - m[4] * m[10]) * inv;
	r[5] = (m[0] * m[10] - m[2] * m[8]) * inv;
	r[6] = (m[2] * m[4] - m[0] * m[6]) * inv;
	r[8] = (m[4] * m[9] - m[5] * m[8]) * inv;
	r[9] = (m[1] * m[8] - m[0] * m[9]) * inv;
	r[10] = (m[0] * m[5] - m[1] * m[4]) * inv;
	r[3] = -(r[0] * m[3] + r[1] * m[7] + r[2] * m[11]);
	r[7] = -(r[4] * m[3] + r[5] * m[7] + r[6] * m[11]);
	r[11] = -(r[8] * m[3] + r[9] * m[7] + r[10] * m[11]);
	r[12] = r[13] = r[14] = 0.0;
	r[15] = 1.0;
	return true;
}

int lvp__compare_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return (x > y) - (x < y);
}

int32_t lvp__union_root(int32_t *parent, int32_t k)
{
	while (parent[k] != k) {
		parent[k] = parent[parent[k]];
		k = parent[k];
	}
	return k;
}

void *lvp__calloc(size_t count, size_t size, bool *ok)
{
	if (!*ok)
		return NULL;
	void *p = calloc(count ? count : 1, size);
	if (!p)
		*ok = false;
	return p;
}
