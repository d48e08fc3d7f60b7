/*
 * test_bulge_width.c - the bulge width (lvp.h, BULGE WIDTH) on a cylinder whose weights blend over a
 * band much narrower than its radius, as automatic weights often do: without it the whole lost
 * volume comes back in that band, a ridge; with it the same volume comes back as a lower, wider
 * and smoother bulge, and the ends still follow their bones.
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define RADIUS 0.5f
#define LENGTH 4.0f
#define BAND 0.2f

static test_posed_rig make_bent_tube(double degrees)
{
	test_posed_rig c;
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(degrees * PI / 180.0)};
	CHECK(test_pose_rig(test_make_cylinder(32, 64, RADIUS, LENGTH, BAND), rotations, &c) == 0);
	return c;
}

static double mesh_volume(const float *positions, const test_rig *rig)
{
	double v = 0.0;
	lvp_diagnostic diag;
	CHECK_OK(lvp_mesh_volume(&v, positions, rig->vertex_count, rig->triangles, rig->triangle_count, &diag), diag);
	return v;
}

static double length3(const float *v)
{
	return sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
}

/* What a correction did to the tube: its volume error, the largest offset, the length along the
 * tube (at rest) over which the skin moved (four standard deviations of the offsets' lengths
 * along it, the width of a bell that holds 95 % of them), the roughness (the largest
 * distance of an offset from its edge neighbours' mean, over the largest offset) and the largest
 * offset of the ends, more than a radius from the band. */
typedef struct bulge {
	double error, largest, extent, roughness, ends;
} bulge;

static bulge measure(const test_posed_rig *c, const float *corrected, const float *offsets)
{
	const test_rig *rig = &c->rig;
	int32_t n = rig->vertex_count;
	bulge m = {0.0, 0.0, 0.0, 0.0, 0.0};
	double rest = mesh_volume(rig->positions, rig);
	m.error = (mesh_volume(corrected, rig) - rest) / rest;
	for (int32_t k = 0; k < n; ++k)
		m.largest = fmax(m.largest, length3(offsets + 3 * k));
	double middle = LENGTH / 2, moved = 0.0, moment = 0.0, spread = 0.0;
	for (int32_t k = 0; k < n; ++k) {
		double z = rig->positions[3 * k + 2], d = length3(offsets + 3 * k);
		moved += d;
		moment += d * z;
		spread += d * z * z;
		if (fabs(z - middle) > BAND / 2 + RADIUS * 2.5)
			m.ends = fmax(m.ends, d);
	}
	moment /= moved;
	m.extent = 4.0 * sqrt(fmax(spread / moved - moment * moment, 0.0));
	m.roughness = test_roughness(rig, offsets);
	return m;
}

static bulge correct_tube(const test_posed_rig *c, float width, int threads, float *r_offsets)
{
	lvp_bind_options options = lvp_bind_default_options();
	options.bulge_width = width;
	options.thread_count = threads;
	lvp_binding *binding = test_bind_rig(&c->rig, &options);
	int32_t n = c->rig.vertex_count;
	float *corrected = malloc(sizeof(float) * 3 * (size_t)n);
	lvp_frame_stats stats;
	lvp_diagnostic diag;
	CHECK_OK(lvp_correct(corrected, r_offsets, binding, c->skinned, c->posed, NULL, NULL, &stats, &diag), diag);
	bulge m = measure(c, corrected, r_offsets);
	free(corrected);
	lvp_free(binding);
	return m;
}

static void test_a_narrow_band_bulges_as_wide_as_the_flesh(void)
{
	test_posed_rig c = make_bent_tube(70.0);
	int32_t n = c.rig.vertex_count;
	float *offsets = malloc(sizeof(float) * 3 * (size_t)n), *threaded = malloc(sizeof(float) * 3 * (size_t)n);
	printf("  tube r %.2f, weights blended over %.2f, bent 70 degrees:\n", RADIUS, BAND);
	printf("  bulge width | volume error | largest offset | moved over | roughness | ends moved\n");
	bulge band = correct_tube(&c, 0.0f, 1, offsets);
	bulge previous = band;
	const float widths[3] = {0.0f, 1.0f, 2.0f};
	for (int i = 0; i < 3; ++i) {
		bulge m = correct_tube(&c, widths[i], 1, offsets);
		printf("  %11.1f | %+11.5f%% | %14.4f | %10.3f | %9.3f | %.1e\n", (double)widths[i], 100 * m.error, m.largest,
		       m.extent, m.roughness, m.ends);
		CHECK(fabs(m.error) < 1e-4);
		CHECK(m.ends < 1e-3 * RADIUS); /* the ends follow their bones */
		if (i > 0) {
			/* Wider, lower and smoother as the width grows. */
			CHECK(m.extent > 1.3 * previous.extent);
			CHECK(m.largest < previous.largest);
			CHECK(m.roughness < previous.roughness);
		}
		previous = m;
	}
	/* As wide as the flesh: the bulge of width 1 spans most of the flesh's thickness (the radius),
	 * the band's a fraction of it. */
	bulge flesh = correct_tube(&c, 1.0f, 1, offsets);
	CHECK(band.extent < 0.3 * RADIUS);
	CHECK(flesh.extent > 0.6 * RADIUS);
	/* Any thread count gives the same offsets. */
	correct_tube(&c, 1.0f, 3, threaded);
	CHECK(memcmp(offsets, threaded, sizeof(float) * 3 * (size_t)n) == 0);
	free(offsets);
	free(threaded);
	test_posed_rig_free(&c);
}

/* At rest nothing moves, however wide the bulge may be. */
static void test_rest_pose_moves_nothing(void)
{
	test_posed_rig c = make_bent_tube(0.0);
	int32_t n = c.rig.vertex_count;
	float *offsets = malloc(sizeof(float) * 3 * (size_t)n);
	bulge m = correct_tube(&c, 2.0f, 1, offsets);
	double largest = 0.0;
	for (int32_t k = 0; k < 3 * n; ++k)
		largest = fmax(largest, fabs(offsets[k]));
	CHECK(largest == 0.0);
	CHECK(fabs(m.error) < 1e-6);
	free(offsets);
	test_posed_rig_free(&c);
}

static void test_the_width_is_checked(void)
{
	test_rig rig = test_make_cylinder(8, 8, RADIUS, LENGTH, BAND);
	lvp_weights weights = test_rig_weights(&rig);
	lvp_skeleton skeleton = test_rig_skeleton(&rig);
	const float bad[3] = {-0.5f, NAN, LVP_MAX_BULGE_WIDTH * 2.0f};
	for (int i = 0; i < 3; ++i) {
		lvp_bind_options options = lvp_bind_default_options();
		options.bulge_width = bad[i];
		lvp_binding *binding = NULL;
		lvp_diagnostic diag;
		lvp_result result = lvp_bind(&binding, rig.positions, rig.vertex_count, rig.triangles, rig.triangle_count,
		                             &weights, &skeleton, &options, &diag);
		CHECK(result == lvp_error_invalid_option);
		CHECK(binding == NULL);
		CHECK(strcmp(diag.argument, "options.bulge_width") == 0);
		CHECK(strstr(diag.message, "bulge_width") != NULL);
	}
	test_rig_free(&rig);
}

int main(void)
{
	RUN(test_a_narrow_band_bulges_as_wide_as_the_flesh);
	RUN(test_rest_pose_moves_nothing);
	RUN(test_the_width_is_checked);
	return check_failures() != 0;
}
