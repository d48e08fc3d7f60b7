/*
 * lvp_internal.h - helpers shared by the files of the core (not part of the public API).
 * Vector and matrix arithmetic, input validation at the API boundary, diagnostics.
 */
#ifndef LVP_INTERNAL_H
#define LVP_INTERNAL_H

#include "lvp.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

/* ---- diagnostics ---------------------------------------------------------------------- */

/* Fills r_diag (when not NULL) and returns result. The message is printf-formatted, by C99's rules
 * (%zu included) on every platform: GCC for MinGW checks a plain `printf` format by the rules of
 * Microsoft's old msvcrt.dll, which has no %zu, so there the check is `gnu_printf`, and common.c
 * formats with MinGW's own C99 vsnprintf to match. */
lvp_result lvp__fail(lvp_diagnostic *r_diag, lvp_result result, const char *argument, int64_t index,
                     const char *format, ...)
#if defined(__MINGW32__)
    __attribute__((format(gnu_printf, 5, 6)))
#elif defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/* ---- validation (each returns lvp_success or a filled diagnostic) ---------------------- */

/* calloc of count items (at least one): on failure, or when *ok is already false, NULL and *ok
 * false, so that a list of allocations is checked once. */
void *lvp__calloc(size_t count, size_t size, bool *ok);
lvp_result lvp__check_float_array(const float *values, int64_t count, const char *argument, lvp_diagnostic *r_diag);
lvp_result lvp__check_mesh(const float *positions, int32_t vertex_count, const int32_t *triangles,
                           int32_t triangle_count, const char *positions_argument, lvp_diagnostic *r_diag);
/* Checks the CSR layout, the bone indices, finiteness and signs. */
lvp_result lvp__check_weights(const lvp_weights *weights, int32_t vertex_count, int32_t bone_count,
                              lvp_diagnostic *r_diag);
/* Checks counts, finiteness and that every rest matrix is invertible. */
lvp_result lvp__check_skeleton(const lvp_skeleton *skeleton, lvp_diagnostic *r_diag);

/* ---- 3-vectors ------------------------------------------------------------------------- */

typedef struct lvp__vec3 {
	double x, y, z;
} lvp__vec3;

static inline lvp__vec3 lvp__v(double x, double y, double z)
{
	lvp__vec3 r = {x, y, z};
	return r;
}
static inline lvp__vec3 lvp__load(const float *p)
{
	return lvp__v(p[0], p[1], p[2]);
}
static inline lvp__vec3 lvp__add(lvp__vec3 a, lvp__vec3 b)
{
	return lvp__v(a.x + b.x, a.y + b.y, a.z + b.z);
}
static inline lvp__vec3 lvp__sub(lvp__vec3 a, lvp__vec3 b)
{
	return lvp__v(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline lvp__vec3 lvp__scale(lvp__vec3 a, double s)
{
	return lvp__v(a.x * s, a.y * s, a.z * s);
}
static inline double lvp__dot(lvp__vec3 a, lvp__vec3 b)
{
	return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline lvp__vec3 lvp__cross(lvp__vec3 a, lvp__vec3 b)
{
	return lvp__v(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double lvp__length(lvp__vec3 a)
{
	return sqrt(lvp__dot(a, a));
}
/* 6 x the signed volume of the tetrahedron (0, a, b, c). */
static inline double lvp__vol6(lvp__vec3 a, lvp__vec3 b, lvp__vec3 c)
{
	return lvp__dot(a, lvp__cross(b, c));
}

/* Closest point to p on the segment [a, b] (a point when a == b); returns its parameter. */
static inline double lvp__closest_on_segment(lvp__vec3 *r_point, lvp__vec3 p, lvp__vec3 a, lvp__vec3 b)
{
	lvp__vec3 ab = lvp__sub(b, a);
	double len2 = lvp__dot(ab, ab);
	double t = len2 > 0.0 ? lvp__dot(lvp__sub(p, a), ab) / len2 : 0.0;
	t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
	*r_point = lvp__add(a, lvp__scale(ab, t));
	return t;
}

static inline double lvp__segment_distance(lvp__vec3 p, lvp__vec3 a, lvp__vec3 b)
{
	lvp__vec3 c;
	lvp__closest_on_segment(&c, p, a, b);
	return lvp__length(lvp__sub(p, c));
}

/* ---- 4x4 matrices, row-major, column vectors (see lvp.h) -------------------------------- */

typedef struct lvp__mat4 {
	double m[16];
} lvp__mat4;

lvp__mat4 lvp__mat4_load(const float *m);
lvp__mat4 lvp__mat4_mul(const lvp__mat4 *a, const lvp__mat4 *b);
/* Inverse of an affine matrix (last row 0 0 0 1 assumed). Returns false when the 3x3 part is
 * singular or badly conditioned (|det| below 1e-12 of the product of its row norms). */
bool lvp__mat4_invert_affine(lvp__mat4 *r_inverse, const lvp__mat4 *a);
double lvp__mat4_det3(const lvp__mat4 *a);

/* skinning.c: the 3x3 matrix a (row-major) split as a = R X, R the rotation nearest to a (polar
 * decomposition, also for singular or mirrored a), r_x = R^T a: the scale and shear applied
 * before R (symmetric when det a > 0). */
void lvp__split_rotation(double r_x[9], const double a[9]);

static inline lvp__vec3 lvp__transform_point(const lvp__mat4 *a, lvp__vec3 p)
{
	const double *m = a->m;
	return lvp__v(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
	              m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}
static inline lvp__vec3 lvp__transform_vector(const lvp__mat4 *a, lvp__vec3 p)
{
	const double *m = a->m;
	return lvp__v(m[0] * p.x + m[1] * p.y + m[2] * p.z, m[4] * p.x + m[5] * p.y + m[6] * p.z,
	              m[8] * p.x + m[9] * p.y + m[10] * p.z);
}

/* The transpose of a's linear part applied to p: (a v) . p = v . result, for every v. */
static inline lvp__vec3 lvp__transform_vector_transposed(const lvp__mat4 *a, lvp__vec3 p)
{
	const double *m = a->m;
	return lvp__v(m[0] * p.x + m[4] * p.y + m[8] * p.z, m[1] * p.x + m[5] * p.y + m[9] * p.z,
	              m[2] * p.x + m[6] * p.y + m[10] * p.z);
}

/* ---- small utilities -------------------------------------------------------------------- */

static inline bool lvp__finite(float v)
{
	return isfinite(v) != 0;
}

/* The lesser and greater of two values by comparison, not fmin/fmax, which compilers call out of line
 * to honour NaN rules: for values known not to be NaN (validated positions and what follows from them),
 * where a zero's sign changes no test. */
static inline float lvp__minf(float a, float b)
{
	return a < b ? a : b;
}
static inline float lvp__maxf(float a, float b)
{
	return a > b ? a : b;
}
static inline double lvp__min_d(double a, double b)
{
	return a < b ? a : b;
}
static inline double lvp__max_d(double a, double b)
{
	return a > b ? a : b;
}

/* qsort comparison of two uint64_t. */
int lvp__compare_u64(const void *a, const void *b);

/* The root of k's set in a union-find forest (parent[r] == r at a root), halving the path on the way. */
int32_t lvp__union_root(int32_t *parent, int32_t k);

#endif /* LVP_INTERNAL_H */
