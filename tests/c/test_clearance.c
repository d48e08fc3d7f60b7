/*
 * test_clearance.c - Keep Skin Apart's clearance searches (clearance.c) against a brute force: after a
 * frame corrected with keep_apart, every clearance the core found is the least |x - p|^2 / <x - p, d>
 * over every triangle of the skinning that is not around the vertex, and every vertex left at INFINITY
 * has no such triangle within the reach it searched. The searches cull what they look at by the boxes of
 * the hierarchy, and where a ball is wider than the skin of its group, by the sheet each node's skin lies
 * in; the brute force takes every triangle whose bounding sphere meets the ball and finds its least by
 * its own means. A tube fine enough that its offsets span many edges (balls many triangles wide, the
 * sheets' cull) bent hard at every joint, where it folds into itself (clearances found), and a coarser
 * one bent less, whose balls are most of them narrower than a group's skin (the boxes' cull). A
 * white-box test: it reads the binding's contact state (binding.h).
 */
#include "binding.h"
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* |x|^2 / <x, d> (x relative to the vertex), INFINITY where x is not in front of it. */
static double diameter_of(const double x[3], const double d[3])
{
	double ahead = dot3(x, d);
	return ahead > 0.0 ? dot3(x, x) / ahead : INFINITY;
}

/* The least diameter over the segment pq: convex where <x, d> > 0, which holds on one interval of it
 * (the diameter is linear there); golden section over that interval, and its ends. */
static double segment_least(const double p[3], const double q[3], const double d[3])
{
	double ahead_p = dot3(p, d), ahead_q = dot3(q, d), lo = 0.0, hi = 1.0;
	if (ahead_p <= 0.0 && ahead_q <= 0.0)
		return INFINITY;
	if (ahead_p <= 0.0)
		lo = ahead_p / (ahead_p - ahead_q);
	if (ahead_q <= 0.0)
		hi = ahead_p / (ahead_p - ahead_q);
	double x[3];
#define AT(t) (x[0] = p[0] + (t) * (q[0] - p[0]), x[1] = p[1] + (t) * (q[1] - p[1]), \
               x[2] = p[2] + (t) * (q[2] - p[2]), diameter_of(x, d))
	const double ratio = 0.6180339887498949;
	double x1 = hi - ratio * (hi - lo), x2 = lo + ratio * (hi - lo), f1 = AT(x1), f2 = AT(x2);
	for (int i = 0; i < 100; ++i) {
		if (f1 <= f2) {
			hi = x2;
			x2 = x1;
			f2 = f1;
			x1 = hi - ratio * (hi - lo);
			f1 = AT(x1);
		} else {
			lo = x1;
			x1 = x2;
			f1 = f2;
			x2 = lo + ratio * (hi - lo);
			f2 = AT(x2);
		}
	}
	double least = fmin(fmin(f1, f2), fmin(diameter_of(p, d), diameter_of(q, d)));
#undef AT
	return least;
}

/* The least diameter over the triangle abc: on its edges, or inside it where the smallest ball tangent to d
 * at the vertex touches the triangle's plane (the diameter's level sets are those balls). */
static double triangle_least(const double a[3], const double b[3], const double c[3], const double d[3])
{
	double least = fmin(fmin(segment_least(a, b, d), segment_least(b, c, d)), segment_least(c, a, d));
	double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
	double m[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
	double norm = sqrt(dot3(m, m));
	for (int i = 0; i < 3; ++i)
		m[i] /= norm;
	double h = dot3(a, m), dm = dot3(d, m);
	/* The ball of diameter D, centre (D / 2) d, touches the plane <x, m> = h where |(D / 2) dm - h| = D / 2. */
	for (int side = -1; side <= 1; side += 2) {
		double denominator = dm + side;
		if (denominator == 0.0)
			continue;
		double D = 2.0 * h / denominator;
		if (!(D > 0.0))
			continue;
		double x[3];
		for (int i = 0; i < 3; ++i)
			x[i] = 0.5 * D * d[i] + side * 0.5 * D * m[i];
		/* inside the triangle: barycentric coordinates of x in abc */
		double r[3] = {x[0] - a[0], x[1] - a[1], x[2] - a[2]};
		double d11 = dot3(e1, e1), d12 = dot3(e1, e2), d22 = dot3(e2, e2), r1 = dot3(r, e1), r2 = dot3(r, e2);
		double det = d11 * d22 - d12 * d12, u = (d22 * r1 - d12 * r2) / det, v = (d11 * r2 - d12 * r1) / det;
		if (u >= 0.0 && v >= 0.0 && u + v <= 1.0)
			least = fmin(least, diameter_of(x, d));
	}
	return least;
}

typedef struct search_check {
	int searched, found, wide; /* wide: reaching past 4 mean edges, about the skin of a group of 32 triangles */
	double worst; /* the largest relative difference from the brute force */
} search_check;

/* Compares the clearances of the last frame corrected with the brute force. */
static search_check check_clearances(const lvp_binding *binding, const float *skinned, double mean_edge)
{
	const lvp__contact *contact = &binding->contact;
	search_check result = {0, 0, 0, 0.0};
	int32_t f = binding->triangle_count;
	const int32_t *triangles = binding->mesh.triangles;
	/* Each triangle's centroid and the sphere around it there; a negative radius for those of no area, which
	 * the hierarchy leaves out. */
	double *mids = malloc(sizeof(double) * 3 * (size_t)f), *spreads = malloc(sizeof(double) * (size_t)f);
	for (int32_t t = 0; t < f; ++t) {
		double x[3][3], e1[3], e2[3], n[3];
		for (int c = 0; c < 3; ++c)
			for (int i = 0; i < 3; ++i)
				x[c][i] = skinned[3 * triangles[3 * t + c] + i];
		for (int i = 0; i < 3; ++i) {
			mids[3 * t + i] = (x[0][i] + x[1][i] + x[2][i]) / 3.0;
			e1[i] = x[1][i] - x[0][i];
			e2[i] = x[2][i] - x[0][i];
		}
		n[0] = e1[1] * e2[2] - e1[2] * e2[1];
		n[1] = e1[2] * e2[0] - e1[0] * e2[2];
		n[2] = e1[0] * e2[1] - e1[1] * e2[0];
		spreads[t] = -1.0;
		if (dot3(n, n) == 0.0)
			continue;
		for (int c = 0; c < 3; ++c) {
			double r[3] = {x[c][0] - mids[3 * t], x[c][1] - mids[3 * t + 1], x[c][2] - mids[3 * t + 2]};
			spreads[t] = fmax(spreads[t], sqrt(dot3(r, r)) * (1.0 + 1e-9));
		}
	}
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		double reach = contact->clearance_reach[k];
		if (!(reach > 0.0))
			continue;
		++result.searched;
		result.wide += reach > 4.0 * mean_edge;
		double d[3], length = 0.0, p[3];
		for (int i = 0; i < 3; ++i) {
			d[i] = contact->clearance_direction[3 * k + i];
			length += d[i] * d[i];
			p[i] = skinned[3 * k + i];
		}
		for (int i = 0; i < 3; ++i)
			d[i] /= sqrt(length);
		double radius = 0.5 * reach, centre[3] = {p[0] + radius * d[0], p[1] + radius * d[1], p[2] + radius * d[2]};
		double least = INFINITY;
		for (int32_t t = 0; t < f; ++t) {
			const int32_t *corners = triangles + 3 * t;
			/* Only a triangle with area that meets the ball of the reach can give less than the reach. */
			double gap[3] = {mids[3 * t] - centre[0], mids[3 * t + 1] - centre[1], mids[3 * t + 2] - centre[2]};
			if (!(spreads[t] >= 0.0) || dot3(gap, gap) > (radius + spreads[t]) * (radius + spreads[t]) ||
			    corners[0] == k || corners[1] == k || corners[2] == k)
				continue;
			double x[3][3];
			for (int c = 0; c < 3; ++c)
				for (int i = 0; i < 3; ++i)
					x[c][i] = skinned[3 * corners[c] + i] - p[i];
			least = fmin(least, triangle_least(x[0], x[1], x[2], d));
		}
		double found = contact->clearance[k];
		if (isfinite(found)) {
			++result.found;
			double difference = fabs(found - least) / found;
			result.worst = fmax(result.worst, difference);
			if (!(difference < 1e-5))
				printf("  vertex %d: clearance %.9g, brute force %.9g (reach %.6g)\n", (int)k, found, least, reach);
			CHECK(difference < 1e-5);
		} else {
			if (!(least >= reach * (1.0 - 1e-5)))
				printf("  vertex %d: no clearance within %.6g, brute force %.9g\n", (int)k, reach, least);
			CHECK(least >= reach * (1.0 - 1e-5));
		}
	}
	free(mids);
	free(spreads);
	return result;
}

/* The mean length of the rig's triangle edges at rest. */
static double mean_edge(const test_rig *rig)
{
	double sum = 0.0;
	for (int32_t t = 0; t < rig->triangle_count; ++t)
		for (int e = 0; e < 3; ++e) {
			const float *a = rig->positions + 3 * rig->triangles[3 * t + e];
			const float *b = rig->positions + 3 * rig->triangles[3 * t + (e + 1) % 3];
			sum += sqrt((double)(a[0] - b[0]) * (a[0] - b[0]) + (double)(a[1] - b[1]) * (a[1] - b[1]) +
			            (double)(a[2] - b[2]) * (a[2] - b[2]));
		}
	return sum / (3.0 * rig->triangle_count);
}

/* A chain tube of `around` x `rings` per bone, bent `degrees` at every joint or at its middle one,
 * corrected with keep_apart; its searches checked. */
static search_check check_tube(int around, int rings, double degrees, bool every_joint)
{
	test_rig rig = test_make_chain(8, 1.0f, 0.3f, around, rings, 0.5f);
	float *rotations = calloc((size_t)rig.bone_count * 4, sizeof(float));
	for (int32_t i = 1; i < rig.bone_count; ++i)
		if (every_joint || i == rig.bone_count / 2) {
			rotations[4 * i] = 1.0f;
			rotations[4 * i + 3] = (float)(degrees * PI / 180.0);
		}
	test_posed_rig tube;
	CHECK(test_pose_rig(rig, rotations, &tube) == 0);
	free(rotations);
	search_check result = {0, 0, 0, 0.0};
	lvp_binding *binding = test_bind_rig(&tube.rig, NULL);
	if (binding) {
		float *corrected = malloc(sizeof(float) * 3 * (size_t)tube.rig.vertex_count);
		lvp_frame_options options = lvp_frame_default_options();
		options.restore = LVP_RESTORE_WHOLE_MESH;
		options.keep_apart = 1;
		lvp_frame_stats stats;
		lvp_diagnostic diag;
		CHECK_OK(lvp_correct(corrected, NULL, binding, tube.skinned, tube.posed, NULL, &options, &stats, &diag), diag);
		result = check_clearances(binding, tube.skinned, mean_edge(&tube.rig));
		printf("  %d x %d a bone, %.0f degrees%s: %d searched (%d reaching past 4 mean edges), %d found skin, "
		       "at most %.1e from the brute force\n",
		       around, rings, degrees, every_joint ? " at every joint" : "", result.searched, result.wide,
		       result.found, result.worst);
		free(corrected);
	}
	lvp_free(binding);
	test_posed_rig_free(&tube);
	return result;
}

static void test_wide_balls_folded(void)
{
	search_check result = check_tube(48, 40, 110.0, true);
	CHECK(result.found > 0);
	CHECK(result.wide > result.searched / 10);
}

static void test_narrow_balls(void)
{
	search_check result = check_tube(32, 20, 71.0, true);
	CHECK(result.found > 0);
	CHECK(result.searched > 2 * result.wide);
}

int main(void)
{
	RUN(test_wide_balls_folded);
	RUN(test_narrow_balls);
	return check_failures() != 0;
}
