/*
 * test_intersect.c - exact count of intersecting triangle pairs (test_count_intersecting_pairs).
 *
 * Every decision is the sign of an orientation determinant (orient3d, or orient2d on a
 * coordinate plane), evaluated with Shewchuk's static filter in double precision and, when the
 * filter cannot vouch for the sign, again in GMP rationals: float coordinates are exact doubles,
 * so the sign is always the true one. No intersection point is ever computed.
 *
 * Two closed triangles intersect exactly when an edge of one meets the other (if their
 * intersection is a segment, its ends lie on edges; if one contains the other, its edges are
 * inside), so the whole test is six closed segment-triangle tests. Pairs that share mesh
 * vertices (by index) are decided so that the shared part does not count:
 *   - an edge (a, b, c) / (a, b, d): if not coplanar, the planes meet in the line ab, so the
 *     triangles meet only on ab: no. If coplanar, they overlap exactly when c and d lie on the
 *     same side of ab (a fold flattened onto itself).
 *   - a vertex (a, b, c) / (a, d, e): a line through a vertex of a triangle leaves the triangle
 *     through the opposite edge, so the triangles share more than a exactly when the shorter
 *     of their overlapping rays from a ends on an opposite edge that lies in the other
 *     triangle: bc meets (a, d, e) or de meets (a, b, c). This holds coplanar or not.
 *   - all three: the same triangle twice, which intersects.
 * Candidate pairs come from a sort-and-sweep of bounding boxes along the longest axis of the
 * mesh, so a typical mesh costs O(F log F) plus its few overlapping neighbours, not O(F^2).
 */
#include "support/test_meshes.h"

/* GMP's rationals. The Windows test build has no GMP library to link: it compiles GMP's own
 * mini-gmp (mini-gmp.c, mini-mpq.c from Debian's gmp source) with LVP_TEST_MINI_GMP, which has
 * every mpq_ function used here, exactly (but not mpq_inits / mpq_clears). */
#if defined(LVP_TEST_MINI_GMP)
#include "mini-mpq.h"
#else
#include <gmp.h>
#endif
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- exact predicates ----------------------------------------------------------------- */

#define TEST_EPSILON 1.1102230246251565e-16 /* 2^-53, half an ulp of 1 */

static int test__sign_mpq(const mpq_t x)
{
	int s = mpq_sgn(x);
	return (s > 0) - (s < 0);
}

/* det [a-d; b-d; c-d] in rationals. */
static int test__orient3d_exact(const double *a, const double *b, const double *c, const double *d)
{
	mpq_t m[9], t, u, det;
	const double *rows[3] = {a, b, c};
	for (int i = 0; i < 9; ++i)
		mpq_init(m[i]);
	mpq_init(t);
	mpq_init(u);
	mpq_init(det);
	for (int r = 0; r < 3; ++r)
		for (int k = 0; k < 3; ++k) {
			mpq_set_d(t, rows[r][k]);
			mpq_set_d(u, d[k]);
			mpq_sub(m[3 * r + k], t, u);
		}
	/* Expansion along the first row. */
	static const int cofactor[3][4] = {{4, 8, 5, 7}, {5, 6, 3, 8}, {3, 7, 4, 6}};
	for (int k = 0; k < 3; ++k) {
		mpq_mul(t, m[cofactor[k][0]], m[cofactor[k][1]]);
		mpq_mul(u, m[cofactor[k][2]], m[cofactor[k][3]]);
		mpq_sub(t, t, u);
		mpq_mul(t, t, m[k]);
		mpq_add(det, det, t);
	}
	int s = test__sign_mpq(det);
	for (int i = 0; i < 9; ++i)
		mpq_clear(m[i]);
	mpq_clear(t);
	mpq_clear(u);
	mpq_clear(det);
	return s;
}

/* Sign of det [a-d; b-d; c-d]: positive when d lies below the plane of a, b, c seen with a, b, c
 * counter-clockwise. Only signs are compared with each other, so the convention only needs to
 * be consistent. */
static int test__orient3d(const double *a, const double *b, const double *c, const double *d)
{
	double adx = a[0] - d[0], ady = a[1] - d[1], adz = a[2] - d[2];
	double bdx = b[0] - d[0], bdy = b[1] - d[1], bdz = b[2] - d[2];
	double cdx = c[0] - d[0], cdy = c[1] - d[1], cdz = c[2] - d[2];
	double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
	double cdxady = cdx * ady, adxcdy = adx * cdy;
	double adxbdy = adx * bdy, bdxady = bdx * ady;
	double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
	double permanent = (fabs(bdxcdy) + fabs(cdxbdy)) * fabs(adz) + (fabs(cdxady) + fabs(adxcdy)) * fabs(bdz) +
	                   (fabs(adxbdy) + fabs(bdxady)) * fabs(cdz);
	/* Shewchuk's o3derrboundA: valid because float inputs can neither overflow nor underflow
	 * in these products once widened to double. */
	double bound = (7.0 + 56.0 * TEST_EPSILON) * TEST_EPSILON * permanent;
	if (det > bound)
		return 1;
	if (-det > bound)
		return -1;
	return test__orient3d_exact(a, b, c, d);
}

/* Sign of the 2D orientation of a, b, c projected on coordinates (i, j). */
static int test__orient2d(const double *a, const double *b, const double *c, int i, int j)
{
	double left = (a[i] - c[i]) * (b[j] - c[j]);
	double right = (a[j] - c[j]) * (b[i] - c[i]);
	double det = left - right;
	double bound = (3.0 + 16.0 * TEST_EPSILON) * TEST_EPSILON * (fabs(left) + fabs(right));
	if (det > bound)
		return 1;
	if (-det > bound)
		return -1;
	mpq_t x[4], t, u;
	for (int k = 0; k < 4; ++k)
		mpq_init(x[k]);
	mpq_init(t);
	mpq_init(u);
	const double *pairs[4][2] = {{a, c}, {b, c}, {a, c}, {b, c}};
	const int axes[4] = {i, j, j, i};
	for (int k = 0; k < 4; ++k) {
		mpq_set_d(t, pairs[k][0][axes[k]]);
		mpq_set_d(u, pairs[k][1][axes[k]]);
		mpq_sub(x[k], t, u);
	}
	mpq_mul(t, x[0], x[1]);
	mpq_mul(u, x[2], x[3]);
	mpq_sub(t, t, u);
	int s = test__sign_mpq(t);
	for (int k = 0; k < 4; ++k)
		mpq_clear(x[k]);
	mpq_clear(t);
	mpq_clear(u);
	return s;
}

/* The coordinate plane (i, j) on which triangle a, b, c projects without collapsing; -1 when
 * it collapses on all three, i.e. when the triangle has zero area. */
static int test__projection(const double *a, const double *b, const double *c, int *r_i, int *r_j)
{
	for (int drop = 2; drop >= 0; --drop) {
		int i = (drop + 1) % 3, j = (drop + 2) % 3;
		int s = test__orient2d(a, b, c, i, j);
		if (s != 0) {
			*r_i = i, *r_j = j;
			return s;
		}
	}
	return 0;
}

/* Closed 2D point-in-triangle (the triangle is not degenerate in this projection). */
static int test__point_in_triangle_2d(const double *p, const double *a, const double *b, const double *c, int i,
                                      int j)
{
	int s1 = test__orient2d(a, b, p, i, j), s2 = test__orient2d(b, c, p, i, j), s3 = test__orient2d(c, a, p, i, j);
	return !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0));
}

/* Is x between a and b (inclusive) on coordinates i and j? For points known to be collinear. */
static int test__between_2d(const double *x, const double *a, const double *b, int i, int j)
{
	return fmin(a[i], b[i]) <= x[i] && x[i] <= fmax(a[i], b[i]) && fmin(a[j], b[j]) <= x[j] && x[j] <= fmax(a[j], b[j]);
}

/* Closed 2D segment-segment intersection; both segments have distinct ends. */
static int test__segments_2d(const double *p, const double *q, const double *a, const double *b, int i, int j)
{
	int o1 = test__orient2d(p, q, a, i, j), o2 = test__orient2d(p, q, b, i, j);
	int o3 = test__orient2d(a, b, p, i, j), o4 = test__orient2d(a, b, q, i, j);
	if (o1 == 0 && o2 == 0) /* collinear: overlap of the two intervals */
		return test__between_2d(a, p, q, i, j) || test__between_2d(b, p, q, i, j) ||
		       test__between_2d(p, a, b, i, j) || test__between_2d(q, a, b, i, j);
	return o1 * o2 <= 0 && o3 * o4 <= 0;
}

/* Closed segment pq against closed, non-degenerate triangle abc, in 3D. */
static int test__segment_triangle(const double *p, const double *q, const double *a, const double *b, const double *c)
{
	int sp = test__orient3d(a, b, c, p), sq = test__orient3d(a, b, c, q);
	if (sp * sq > 0)
		return 0;
	if (sp == 0 && sq == 0) {
		int i = 0, j = 1;
		test__projection(a, b, c, &i, &j);
		return test__point_in_triangle_2d(p, a, b, c, i, j) || test__point_in_triangle_2d(q, a, b, c, i, j) ||
		       test__segments_2d(p, q, a, b, i, j) || test__segments_2d(p, q, b, c, i, j) ||
		       test__segments_2d(p, q, c, a, i, j);
	}
	/* pq crosses (or touches) the plane at one point: it is in the triangle when the line pq
	 * passes every edge on the same side (zero: through the edge). */
	int s1 = test__orient3d(p, q, a, b), s2 = test__orient3d(p, q, b, c), s3 = test__orient3d(p, q, c, a);
	return !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0));
}

/* ---- pairs ------------------------------------------------------------------------------ */

typedef struct test__tri {
	double key; /* box[0] on the sweep axis, so qsort needs no global */
	int32_t v[3];
	double box[2][3]; /* min, max */
} test__tri;

static int test__pair_intersects(const double *x, const test__tri *t1, const test__tri *t2)
{
	/* Reorder both so the shared vertices come first, in the same order. */
	int32_t a[3], b[3];
	int shared = 0, used_b[3] = {0, 0, 0};
	for (int i = 0; i < 3; ++i)
		for (int j = 0; j < 3; ++j)
			if (!used_b[j] && t1->v[i] == t2->v[j]) {
				a[shared] = t1->v[i];
				b[shared] = t2->v[j];
				used_b[j] = 1;
				++shared;
				break;
			}
	if (shared == 3)
		return 1;
	int na = shared, nb = shared;
	for (int i = 0; i < 3; ++i) {
		int is_shared = 0;
		for (int k = 0; k < shared; ++k)
			is_shared |= t1->v[i] == a[k];
		if (!is_shared)
			a[na++] = t1->v[i];
	}
	for (int j = 0; j < 3; ++j)
		if (!used_b[j])
			b[nb++] = t2->v[j];
	const double *A[3] = {x + 3 * a[0], x + 3 * a[1], x + 3 * a[2]};
	const double *B[3] = {x + 3 * b[0], x + 3 * b[1], x + 3 * b[2]};
	if (shared == 2) {
		if (test__orient3d(A[0], A[1], A[2], B[2]) != 0)
			return 0;
		int i = 0, j = 1;
		test__projection(A[0], A[1], A[2], &i, &j);
		return test__orient2d(A[0], A[1], A[2], i, j) == test__orient2d(A[0], A[1], B[2], i, j);
	}
	if (shared == 1)
		return test__segment_triangle(A[1], A[2], B[0], B[1], B[2]) ||
		       test__segment_triangle(B[1], B[2], A[0], A[1], A[2]);
	for (int e = 0; e < 3; ++e)
		if (test__segment_triangle(A[e], A[(e + 1) % 3], B[0], B[1], B[2]) ||
		    test__segment_triangle(B[e], B[(e + 1) % 3], A[0], A[1], A[2]))
			return 1;
	return 0;
}

static int test__compare_tri(const void *a, const void *b)
{
	double x = ((const test__tri *)a)->key, y = ((const test__tri *)b)->key;
	return (x > y) - (x < y);
}

int64_t test_count_intersecting_pairs(const float *positions, const int32_t *triangles, int32_t triangle_count)
{
	if (!positions || !triangles || triangle_count <= 0)
		return 0;
	/* The vertex count is not given: size the double copy by the largest index used. */
	int32_t vertex_count = 0;
	for (int64_t i = 0; i < 3 * (int64_t)triangle_count; ++i)
		if (triangles[i] >= vertex_count)
			vertex_count = triangles[i] + 1;
	double *x = malloc((size_t)(vertex_count ? vertex_count : 1) * 3 * sizeof(double));
	test__tri *tris = malloc((size_t)triangle_count * sizeof(test__tri));
	if (!x || !tris) {
		fprintf(stderr, "test_count_intersecting_pairs: out of memory\n");
		abort();
	}
	for (int64_t i = 0; i < 3 * (int64_t)vertex_count; ++i)
		x[i] = positions[i];
	int32_t count = 0;
	double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
	for (int32_t f = 0; f < triangle_count; ++f) {
		test__tri t;
		int ok = 1;
		for (int k = 0; k < 3; ++k) {
			t.v[k] = triangles[3 * f + k];
			if (t.v[k] < 0)
				ok = 0;
		}
		if (!ok)
			continue;
		for (int k = 0; k < 3 && ok; ++k)
			for (int c = 0; c < 3; ++c)
				ok &= isfinite(x[3 * t.v[k] + c]);
		int i, j;
		/* Zero-area triangles (including repeated corners) are ignored, as documented. */
		if (!ok || test__projection(x + 3 * t.v[0], x + 3 * t.v[1], x + 3 * t.v[2], &i, &j) == 0)
			continue;
		for (int c = 0; c < 3; ++c) {
			t.box[0][c] = fmin(fmin(x[3 * t.v[0] + c], x[3 * t.v[1] + c]), x[3 * t.v[2] + c]);
			t.box[1][c] = fmax(fmax(x[3 * t.v[0] + c], x[3 * t.v[1] + c]), x[3 * t.v[2] + c]);
			lo[c] = fmin(lo[c], t.box[0][c]);
			hi[c] = fmax(hi[c], t.box[1][c]);
		}
		tris[count++] = t;
	}
	int axis = 0;
	for (int c = 1; c < 3; ++c)
		if (hi[c] - lo[c] > hi[axis] - lo[axis])
			axis = c;
	for (int32_t i = 0; i < count; ++i)
		tris[i].key = tris[i].box[0][axis];
	qsort(tris, (size_t)count, sizeof(test__tri), test__compare_tri);
	int64_t pairs = 0;
	for (int32_t i = 0; i < count; ++i)
		for (int32_t j = i + 1; j < count && tris[j].box[0][axis] <= tris[i].box[1][axis]; ++j) {
			int overlap = 1;
			for (int c = 0; c < 3; ++c)
				overlap &= tris[j].box[0][c] <= tris[i].box[1][c] && tris[i].box[0][c] <= tris[j].box[1][c];
			if (overlap && test__pair_intersects(x, &tris[i], &tris[j]))
				++pairs;
		}
	free(tris);
	free(x);
	return pairs;
}
