/*
 * test_mesh.c - mesh geometry (paper 3.1): signed volume, volume gradient and vertex normals, on meshes
 * built here: a unit cube, a tetrahedron, UV spheres; and every error path of the three functions.
 */
#include "lvp.h"
#include "support/check.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

typedef struct mesh {
	int32_t vertex_count, triangle_count;
	float *positions;
	int32_t *triangles;
} mesh;

static mesh mesh_alloc(int32_t vertex_count, int32_t triangle_count)
{
	mesh m = {vertex_count, triangle_count, calloc((size_t)vertex_count * 3, sizeof(float)),
	          calloc((size_t)triangle_count * 3, sizeof(int32_t))};
	return m;
}

static void mesh_free(mesh *m)
{
	free(m->positions);
	free(m->triangles);
	memset(m, 0, sizeof(*m));
}

/* The unit cube [0,1]^3, two counter-clockwise triangles per face seen from outside. */
static mesh make_cube(void)
{
	static const float corners[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
	                                    {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
	static const int32_t faces[12][3] = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}, {0, 1, 5}, {0, 5, 4},
	                                     {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6}, {3, 0, 4}, {3, 4, 7}};
	mesh m = mesh_alloc(8, 12);
	memcpy(m.positions, corners, sizeof(corners));
	memcpy(m.triangles, faces, sizeof(faces));
	return m;
}

/* The tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1) moved by offset; volume 1/6. */
static mesh make_tetrahedron(float ox, float oy, float oz)
{
	static const float corners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
	static const int32_t faces[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
	mesh m = mesh_alloc(4, 4);
	for (int v = 0; v < 4; ++v) {
		m.positions[3 * v + 0] = corners[v][0] + ox;
		m.positions[3 * v + 1] = corners[v][1] + oy;
		m.positions[3 * v + 2] = corners[v][2] + oz;
	}
	memcpy(m.triangles, faces, sizeof(faces));
	return m;
}

/* A UV sphere of the given radius centred at the origin: `segments` around, `rings` from pole to pole,
 * vertices on the sphere, triangles counter-clockwise seen from outside. */
static mesh make_uv_sphere(float radius, int segments, int rings)
{
	int32_t vertex_count = 2 + segments * (rings - 1);
	int32_t triangle_count = 2 * segments * (rings - 1);
	mesh m = mesh_alloc(vertex_count, triangle_count);
	float *p = m.positions;
	*p++ = 0, *p++ = 0, *p++ = radius; /* north pole: 0 */
	for (int r = 1; r < rings; ++r) {
		double theta = PI * r / rings;
		for (int s = 0; s < segments; ++s) {
			double phi = 2.0 * PI * s / segments;
			*p++ = (float)(radius * sin(theta) * cos(phi));
			*p++ = (float)(radius * sin(theta) * sin(phi));
			*p++ = (float)(radius * cos(theta));
		}
	}
	*p++ = 0, *p++ = 0, *p++ = -radius; /* south pole: last */
	int32_t south = vertex_count - 1;
	int32_t *t = m.triangles;
#define RING(r, s) (1 + ((r) - 1) * segments + ((s) % segments))
	for (int s = 0; s < segments; ++s) {
		*t++ = 0, *t++ = RING(1, s), *t++ = RING(1, s + 1);
		*t++ = south, *t++ = RING(rings - 1, s + 1), *t++ = RING(rings - 1, s);
	}
	for (int r = 1; r < rings - 1; ++r)
		for (int s = 0; s < segments; ++s) {
			int32_t a = RING(r, s), b = RING(r, s + 1), c = RING(r + 1, s), d = RING(r + 1, s + 1);
			*t++ = a, *t++ = c, *t++ = d;
			*t++ = a, *t++ = d, *t++ = b;
		}
#undef RING
	return m;
}

static double volume_of(const mesh *m)
{
	double v = NAN;
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_mesh_volume(&v, m->positions, m->vertex_count, m->triangles, m->triangle_count, &diag), diag);
	return v;
}

/* ---- volume -------------------------------------------------------------------------------------- */

static void test_cube_volume_is_exactly_one(void)
{
	mesh m = make_cube();
	CHECK(volume_of(&m) == 1.0);
	mesh_free(&m);
}

static void test_tetrahedron_volume_is_exactly_one_sixth(void)
{
	mesh m = make_tetrahedron(0, 0, 0);
	CHECK(volume_of(&m) == 1.0 / 6.0);
	mesh_free(&m);
	/* Moved off the origin: the terms change, the sum does not (integer products are exact). */
	m = make_tetrahedron(2, -3, 5);
	CHECK(volume_of(&m) == 1.0 / 6.0);
	mesh_free(&m);
}

static void test_inward_winding_gives_negative_volume(void)
{
	mesh m = make_cube();
	for (int32_t t = 0; t < m.triangle_count; ++t) {
		int32_t swap = m.triangles[3 * t + 1];
		m.triangles[3 * t + 1] = m.triangles[3 * t + 2];
		m.triangles[3 * t + 2] = swap;
	}
	CHECK(volume_of(&m) == -1.0);
	mesh_free(&m);
}

/* The sphere's vertices are on the sphere, so the polyhedron lies inside it and contains the ball whose
 * radius is its smallest face-plane distance: the volume must fall between those two balls. */
static void test_fine_sphere_volume_within_discretization_bound(void)
{
	const double radius = 1.5;
	mesh m = make_uv_sphere((float)radius, 96, 48);
	double inner = INFINITY;
	for (int32_t t = 0; t < m.triangle_count; ++t) {
		const float *a = m.positions + 3 * m.triangles[3 * t], *b = m.positions + 3 * m.triangles[3 * t + 1],
		            *c = m.positions + 3 * m.triangles[3 * t + 2];
		double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
		double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
		double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
		double distance = (n[0] * a[0] + n[1] * a[1] + n[2] * a[2]) / length;
		CHECK(distance > 0.0); /* outward */
		if (distance < inner)
			inner = distance;
	}
	double v = volume_of(&m), ball = 4.0 / 3.0 * PI * radius * radius * radius;
	double inner_ball = 4.0 / 3.0 * PI * inner * inner * inner;
	/* float vertex coordinates can sit a hair outside the sphere: allow their rounding */
	CHECK(v <= ball * (1.0 + 1e-6));
	CHECK(v >= inner_ball);
	CHECK(fabs(v - ball) / ball < 2e-3);
	mesh_free(&m);
}

/* ---- gradient ------------------------------------------------------------------------------------ */

/* A closed, irregular mesh: a coarse sphere stretched into an ellipsoid and jittered, off the origin. */
static mesh make_irregular_closed_mesh(void)
{
	mesh m = make_uv_sphere(1.0f, 10, 7);
	for (int32_t v = 0; v < m.vertex_count; ++v) {
		float *p = m.positions + 3 * v;
		p[0] = p[0] * 1.7f + 0.3f + 0.05f * sinf(3.1f * (float)v);
		p[1] = p[1] * 0.8f - 1.2f + 0.04f * cosf(1.7f * (float)v);
		p[2] = p[2] * 1.1f + 2.0f + 0.03f * sinf(5.3f * (float)v);
	}
	return m;
}

/* The volume gradient of m, 3 floats a vertex (the caller frees it). */
static float *gradient_of(const mesh *m)
{
	float *gradient = malloc(sizeof(float) * 3 * (size_t)m->vertex_count);
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_volume_gradient(gradient, m->positions, m->vertex_count, m->triangles, m->triangle_count, &diag),
	         diag);
	return gradient;
}

/* V is affine in each vertex coordinate (every triangle holds a vertex once), so a central difference is
 * exact up to rounding, whatever the step. */
static void test_gradient_matches_central_differences(void)
{
	mesh m = make_irregular_closed_mesh();
	float *gradient = gradient_of(&m);
	double largest = 0.0;
	for (int32_t i = 0; i < 3 * m.vertex_count; ++i)
		largest = fmax(largest, fabs(gradient[i]));
	CHECK(largest > 0.0);
	for (int32_t i = 0; i < 3 * m.vertex_count; ++i) {
		float original = m.positions[i];
		m.positions[i] = original + 0.01f;
		double plus_at = m.positions[i], plus = volume_of(&m);
		m.positions[i] = original - 0.01f;
		double minus_at = m.positions[i], minus = volume_of(&m);
		m.positions[i] = original;
		double difference = (plus - minus) / (plus_at - minus_at);
		CHECK_NEAR(gradient[i], difference, 1e-6 * largest);
	}
	free(gradient);
	mesh_free(&m);
}

/* Euler's theorem for the degree-3 homogeneous V: sum_k <p_k, grad_k V> = 3 V on a closed mesh. */
static void test_gradient_satisfies_euler_identity(void)
{
	mesh m = make_irregular_closed_mesh();
	float *gradient = gradient_of(&m);
	double sum = 0.0;
	for (int32_t i = 0; i < 3 * m.vertex_count; ++i)
		sum += (double)m.positions[i] * gradient[i];
	double v = volume_of(&m);
	CHECK_NEAR(sum, 3.0 * v, 1e-5 * fabs(v));
	free(gradient);
	mesh_free(&m);
}

/* On an open mesh (the cube without its top) the gradient does not depend on where the origin is. */
static void test_gradient_is_translation_invariant_on_open_mesh(void)
{
	mesh m = make_cube();
	/* the top face is triangles 2 and 3: drop them by moving the rest up */
	memmove(m.triangles + 6, m.triangles + 12, sizeof(int32_t) * 3 * 8);
	m.triangle_count = 10;
	float before[24], after[24];
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_volume_gradient(before, m.positions, 8, m.triangles, m.triangle_count, &diag), diag);
	for (int i = 0; i < 24; ++i)
		m.positions[i] += (float)(i % 3 + 1) * 4.0f;
	CHECK_OK(lvp_volume_gradient(after, m.positions, 8, m.triangles, m.triangle_count, &diag), diag);
	for (int i = 0; i < 24; ++i)
		CHECK_NEAR(after[i], before[i], 1e-6);
	mesh_free(&m);
}

/* ---- normals ------------------------------------------------------------------------------------- */

static void test_normals_are_unit_and_outward(void)
{
	mesh m = make_uv_sphere(2.0f, 24, 12);
	float *normals = malloc(sizeof(float) * 3 * (size_t)m.vertex_count);
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_vertex_normals(normals, m.positions, m.vertex_count, m.triangles, m.triangle_count, &diag), diag);
	for (int32_t v = 0; v < m.vertex_count; ++v) {
		const float *n = normals + 3 * v, *p = m.positions + 3 * v;
		CHECK_NEAR(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6);
		/* on a sphere the normal is close to the radial direction */
		CHECK((n[0] * p[0] + n[1] * p[1] + n[2] * p[2]) / 2.0 > 0.98);
	}
	free(normals);
	mesh_free(&m);

	m = make_cube();
	float cube_normals[24];
	CHECK_OK(lvp_vertex_normals(cube_normals, m.positions, 8, m.triangles, 12, &diag), diag);
	for (int v = 0; v < 8; ++v) { /* outward: away from the centre (0.5, 0.5, 0.5) */
		const float *p = m.positions + 3 * v, *n = cube_normals + 3 * v;
		CHECK((p[0] - 0.5f) * n[0] + (p[1] - 0.5f) * n[1] + (p[2] - 0.5f) * n[2] > 0.5f);
	}
	mesh_free(&m);
}

static void test_isolated_and_degenerate_vertices_get_zero_normal(void)
{
	/* the cube, plus vertex 8 in no triangle and vertices 9, 10 in a zero-area triangle only */
	mesh cube = make_cube();
	float positions[33];
	int32_t triangles[39];
	memcpy(positions, cube.positions, sizeof(float) * 24);
	memcpy(triangles, cube.triangles, sizeof(int32_t) * 36);
	const float extra[9] = {5, 5, 5, 7, 7, 7, 8, 8, 8};
	memcpy(positions + 24, extra, sizeof(extra));
	triangles[36] = 9, triangles[37] = 10, triangles[38] = 10;
	float normals[33], gradient[33];
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_vertex_normals(normals, positions, 11, triangles, 13, &diag), diag);
	CHECK_OK(lvp_volume_gradient(gradient, positions, 11, triangles, 13, &diag), diag);
	for (int i = 24; i < 33; ++i) {
		CHECK(normals[i] == 0.0f);
		CHECK(gradient[i] == 0.0f);
	}
	double v = NAN;
	CHECK_OK(lvp_mesh_volume(&v, positions, 11, triangles, 13, &diag), diag);
	CHECK(v == 1.0); /* neither changes the volume */
	mesh_free(&cube);
}

/* ---- errors -------------------------------------------------------------------------------------- */

typedef enum which { VOLUME, GRADIENT, NORMALS } which;

/* Calls one of the three functions; its float output (gradient or normals) is pre-filled with a
 * sentinel that must survive a failure. */
static lvp_result call(which f, bool null_output, const float *positions, int32_t vertex_count,
                       const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *diag)
{
	float output[64];
	double volume = 12345.0;
	for (int i = 0; i < 64; ++i)
		output[i] = 777.0f;
	lvp_result r;
	if (f == VOLUME)
		r = lvp_mesh_volume(null_output ? NULL : &volume, positions, vertex_count, triangles, triangle_count, diag);
	else if (f == GRADIENT)
		r = lvp_volume_gradient(null_output ? NULL : output, positions, vertex_count, triangles, triangle_count, diag);
	else
		r = lvp_vertex_normals(null_output ? NULL : output, positions, vertex_count, triangles, triangle_count, diag);
	if (r != lvp_success) {
		CHECK(volume == 12345.0);
		for (int i = 0; i < 64; ++i)
			CHECK(output[i] == 777.0f);
	}
	return r;
}

static void test_error_paths_name_the_argument(void)
{
	static const char *const outputs[3] = {"r_volume", "r_gradient", "r_normals"};
	mesh m = make_cube();
	for (int f = VOLUME; f <= NORMALS; ++f) {
		lvp_diagnostic diag;
		memset(&diag, 0, sizeof(diag));
		CHECK_ERROR(call(f, true, m.positions, 8, m.triangles, 12, &diag), &diag,
		            lvp_error_null_argument, outputs[f], -1);
		CHECK_ERROR(call(f, false, NULL, 8, m.triangles, 12, &diag), &diag, lvp_error_null_argument, "positions", -1);
		CHECK_ERROR(call(f, false, m.positions, 8, NULL, 12, &diag), &diag, lvp_error_null_argument, "triangles", -1);
		CHECK_ERROR(call(f, false, m.positions, 0, m.triangles, 12, &diag), &diag,
		            lvp_error_invalid_size, "vertex_count", -1);
		CHECK_ERROR(call(f, false, m.positions, -5, m.triangles, 12, &diag), &diag, lvp_error_invalid_size,
		            "vertex_count", -1);
		CHECK_ERROR(call(f, false, m.positions, LVP_MAX_VERTICES + 1, m.triangles, 12, &diag), &diag,
		            lvp_error_invalid_size, "vertex_count", -1);
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, 0, &diag), &diag, lvp_error_invalid_size,
		            "triangle_count", -1);
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, -1, &diag), &diag, lvp_error_invalid_size,
		            "triangle_count", -1);

		/* one vertex fewer: triangle corners that name vertex 7 are out of range */
		CHECK_ERROR(call(f, false, m.positions, 7, m.triangles, 12, &diag), &diag, lvp_error_index_out_of_range,
		            "triangles", 11);
		m.triangles[4] = -1;
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, 12, &diag), &diag, lvp_error_index_out_of_range,
		            "triangles", 4);
		m.triangles[4] = 8;
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, 12, &diag), &diag, lvp_error_index_out_of_range,
		            "triangles", 4);
		m.triangles[4] = 3;

		m.positions[13] = NAN;
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, 12, &diag), &diag,
		            lvp_error_not_finite, "positions", 13);
		m.positions[13] = -INFINITY;
		CHECK_ERROR(call(f, false, m.positions, 8, m.triangles, 12, &diag), &diag,
		            lvp_error_not_finite, "positions", 13);
		m.positions[13] = 0.0f;
		CHECK(call(f, false, m.positions, 8, m.triangles, 12, &diag) == lvp_success);
		/* no diagnostic wanted: still the right result */
		CHECK(call(f, false, NULL, 8, m.triangles, 12, NULL) == lvp_error_null_argument);
	}
	mesh_free(&m);
}

/* Coordinates so large that area vectors overflow a float still give unit normals. */
static void test_huge_coordinates_keep_unit_normals(void)
{
	mesh m = make_cube();
	for (int i = 0; i < 24; ++i)
		m.positions[i] = m.positions[i] * 1e30f - 5e29f;
	float normals[24];
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_vertex_normals(normals, m.positions, 8, m.triangles, 12, &diag), diag);
	for (int v = 0; v < 8; ++v) {
		const float *n = normals + 3 * v;
		CHECK_NEAR(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 1e-6);
	}
	mesh_free(&m);
}

int main(void)
{
	RUN(test_cube_volume_is_exactly_one);
	RUN(test_tetrahedron_volume_is_exactly_one_sixth);
	RUN(test_inward_winding_gives_negative_volume);
	RUN(test_fine_sphere_volume_within_discretization_bound);
	RUN(test_gradient_matches_central_differences);
	RUN(test_gradient_satisfies_euler_identity);
	RUN(test_gradient_is_translation_invariant_on_open_mesh);
	RUN(test_normals_are_unit_and_outward);
	RUN(test_isolated_and_degenerate_vertices_get_zero_normal);
	RUN(test_error_paths_name_the_argument);
	RUN(test_huge_coordinates_keep_unit_normals);
	return check_failures() != 0;
}
