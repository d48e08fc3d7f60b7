/*
 * mesh.c - mesh geometry of Rohmer, Hahmann, Cani 2008, section 3.1: the signed volume by the divergence
 * theorem, its per-vertex gradient, and unit area-weighted vertex normals.
 *
 * The three share one observation: for triangle (i, j, l), (p_j - p_i) x (p_l - p_i) is the same vector
 * whichever corner is written first (it is twice the area vector), so the gradient of every corner is
 * 1/6 of the summed area vectors of its triangles, and the normal is that sum normalized. Products are
 * formed in double from the float inputs, so a triangle's contribution is exact up to one rounding.
 */
#include "lvp_internal.h"

static lvp_result lvp__check_output(const void *output, const char *argument, lvp_diagnostic *r_diag)
{
	if (!output)
		return lvp__fail(r_diag, lvp_error_null_argument, argument, -1,
		                 "%s is NULL; pass a buffer for the result (see lvp.h for its size).", argument);
	return lvp_success;
}

/* Twice the area vector of triangle t: (p_j - p_i) x (p_l - p_i). */
static inline lvp__vec3 lvp__triangle_area2(const float *positions, const int32_t *triangle)
{
	lvp__vec3 a = lvp__load(positions + 3 * (int64_t)triangle[0]);
	lvp__vec3 b = lvp__load(positions + 3 * (int64_t)triangle[1]);
	lvp__vec3 c = lvp__load(positions + 3 * (int64_t)triangle[2]);
	return lvp__cross(lvp__sub(b, a), lvp__sub(c, a));
}

/* Sums the area vectors around every vertex, times scale, into r_sum (zeroed first). Accumulates in
 * float, the output type: a vertex has a handful of triangles, so the sum adds no error worth a double
 * buffer. */
static void lvp__accumulate_area_vectors(float *r_sum, const float *positions, int32_t vertex_count,
                                         const int32_t *triangles, int32_t triangle_count, double scale)
{
	memset(r_sum, 0, sizeof(float) * 3 * (size_t)vertex_count);
	for (int32_t t = 0; t < triangle_count; ++t) {
		const int32_t *tri = triangles + 3 * (int64_t)t;
		lvp__vec3 n = lvp__scale(lvp__triangle_area2(positions, tri), scale);
		for (int c = 0; c < 3; ++c) {
			float *s = r_sum + 3 * (int64_t)tri[c];
			s[0] += (float)n.x;
			s[1] += (float)n.y;
			s[2] += (float)n.z;
		}
	}
}

lvp_result lvp_mesh_volume(double *r_volume, const float *positions, int32_t vertex_count,
                           const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag)
{
	lvp_result result = lvp__check_output(r_volume, "r_volume", r_diag);
	if (result == lvp_success)
		result = lvp__check_mesh(positions, vertex_count, triangles, triangle_count, "positions", r_diag);
	if (result != lvp_success)
		return result;
	/* p_i . (p_j x p_k) on the raw coordinates (not relative to a corner) is the textbook form of eq. 1;
	 * summed in double it is exact for small integer coordinates (the unit cube gives exactly 1). */
	double sum = 0.0;
	for (int32_t t = 0; t < triangle_count; ++t) {
		const int32_t *tri = triangles + 3 * (int64_t)t;
		lvp__vec3 a = lvp__load(positions + 3 * (int64_t)tri[0]);
		lvp__vec3 b = lvp__load(positions + 3 * (int64_t)tri[1]);
		lvp__vec3 c = lvp__load(positions + 3 * (int64_t)tri[2]);
		sum += lvp__dot(a, lvp__cross(b, c));
	}
	*r_volume = sum / 6.0;
	return lvp_success;
}

lvp_result lvp_volume_gradient(float *r_gradient, const float *positions, int32_t vertex_count,
                               const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag)
{
	lvp_result result = lvp__check_output(r_gradient, "r_gradient", r_diag);
	if (result == lvp_success)
		result = lvp__check_mesh(positions, vertex_count, triangles, triangle_count, "positions", r_diag);
	if (result != lvp_success)
		return result;
	lvp__accumulate_area_vectors(r_gradient, positions, vertex_count, triangles, triangle_count, 1.0);
	for (int64_t i = 0; i < (int64_t)vertex_count * 3; ++i)
		r_gradient[i] = (float)((double)r_gradient[i] / 6.0);
	return lvp_success;
}

lvp_result lvp_vertex_normals(float *r_normals, const float *positions, int32_t vertex_count,
                              const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag)
{
	lvp_result result = lvp__check_output(r_normals, "r_normals", r_diag);
	if (result == lvp_success)
		result = lvp__check_mesh(positions, vertex_count, triangles, triangle_count, "positions", r_diag);
	if (result != lvp_success)
		return result;
	/* Area vectors grow with the square of the coordinates and overflow a float beyond about 1e19; the
	 * normal does not depend on the scale, so huge meshes are summed scaled down (ordinary ones are not
	 * touched, so their normals round exactly as they always did). */
	double extent = 0.0;
	for (int64_t i = 0; i < (int64_t)vertex_count * 3; ++i)
		extent = fmax(extent, fabs((double)positions[i]));
	double scale = extent > 1e15 ? 1.0 / (extent * extent) : 1.0;
	lvp__accumulate_area_vectors(r_normals, positions, vertex_count, triangles, triangle_count, scale);
	for (int64_t k = 0; k < vertex_count; ++k) {
		float *n = r_normals + 3 * k;
		double length = lvp__length(lvp__load(n));
		/* Isolated vertices and vertices whose triangles have no area keep the zero vector: there is no
		 * direction to give them, and callers treat a zero normal as "do not move". */
		if (!(length > 0.0))
			continue;
		n[0] = (float)(n[0] / length);
		n[1] = (float)(n[1] / length);
		n[2] = (float)(n[2] / length);
	}
	return lvp_success;
}
