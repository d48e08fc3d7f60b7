/*
 * test_weights.c - automatic skinning weights (paper 5.1) on meshes built here: two fingers side by side,
 * a body with a hooked horn, bones on and off the surface. The visibility tests, the rigid fallback, the
 * pruning against a brute-force reference, the capacity contract, zero-length bones and every error path.
 */
#include "bvh.h" /* the exact test's segment-triangle primitive, for the brute force */
#include "lvp.h"
#include "support/check.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* ---- geometry ------------------------------------------------------------------------------------ */

typedef struct builder {
	int32_t vertex_count, triangle_count, bone_count;
	float positions[3 * 8192];
	int32_t triangles[3 * 16384];
	float heads[3 * 16], tails[3 * 16], rest_matrices[16 * 16];
} builder;

static int32_t add_vertex(builder *b, double x, double y, double z)
{
	float *p = b->positions + 3 * b->vertex_count;
	p[0] = (float)x, p[1] = (float)y, p[2] = (float)z;
	return b->vertex_count++;
}

static void add_triangle(builder *b, int32_t i, int32_t j, int32_t k)
{
	int32_t *t = b->triangles + 3 * b->triangle_count++;
	t[0] = i, t[1] = j, t[2] = k;
}

/* A closed tube of radius r around the polyline centres[0..count), each ring perpendicular to its
 * tangent, with a fan cap at both ends (cap centres added last, start then end). binormal must be
 * perpendicular to every tangent (the tubes here lie in planes). Oriented outward. Returns the index of
 * its first vertex. */
static int32_t add_tube(builder *b, const double (*centres)[3], int count, double radius, int around,
                        const double binormal[3])
{
	int32_t first = b->vertex_count, first_triangle = b->triangle_count;
	for (int i = 0; i < count; ++i) {
		const double *c = centres[i], *prev = centres[i > 0 ? i - 1 : 0], *next = centres[i < count - 1 ? i + 1 : i];
		double t[3] = {next[0] - prev[0], next[1] - prev[1], next[2] - prev[2]};
		double n[3] = {binormal[1] * t[2] - binormal[2] * t[1], binormal[2] * t[0] - binormal[0] * t[2],
		               binormal[0] * t[1] - binormal[1] * t[0]};
		double length = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
		for (int a = 0; a < around; ++a) {
			double phi = 2.0 * PI * a / around, cn = cos(phi) * radius / length, cb = sin(phi) * radius;
			add_vertex(b, c[0] + cn * n[0] + cb * binormal[0], c[1] + cn * n[1] + cb * binormal[1],
			           c[2] + cn * n[2] + cb * binormal[2]);
		}
	}
	for (int i = 0; i + 1 < count; ++i)
		for (int a = 0; a < around; ++a) {
			int32_t p = first + i * around + a, q = first + i * around + (a + 1) % around;
			add_triangle(b, p, q, q + around);
			add_triangle(b, p, q + around, p + around);
		}
	int32_t start = add_vertex(b, centres[0][0], centres[0][1], centres[0][2]);
	int32_t end = add_vertex(b, centres[count - 1][0], centres[count - 1][1], centres[count - 1][2]);
	int32_t last = first + (count - 1) * around;
	for (int a = 0; a < around; ++a) {
		add_triangle(b, start, first + (a + 1) % around, first + a);
		add_triangle(b, end, last + a, last + (a + 1) % around);
	}
	/* orient outward: flip the tube if its own volume is negative */
	double volume = 0.0;
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_mesh_volume(&volume, b->positions, b->vertex_count, b->triangles + 3 * first_triangle,
	                         b->triangle_count - first_triangle, &diag),
	         diag);
	if (volume < 0.0)
		for (int32_t t = first_triangle; t < b->triangle_count; ++t) {
			int32_t swap = b->triangles[3 * t + 1];
			b->triangles[3 * t + 1] = b->triangles[3 * t + 2];
			b->triangles[3 * t + 2] = swap;
		}
	return first;
}

static void add_bone(builder *b, double hx, double hy, double hz, double tx, double ty, double tz)
{
	int32_t i = b->bone_count++;
	float *h = b->heads + 3 * i, *t = b->tails + 3 * i, *m = b->rest_matrices + 16 * i;
	h[0] = (float)hx, h[1] = (float)hy, h[2] = (float)hz;
	t[0] = (float)tx, t[1] = (float)ty, t[2] = (float)tz;
	memset(m, 0, sizeof(float) * 16);
	m[0] = m[5] = m[10] = m[15] = 1.0f;
	m[3] = h[0], m[7] = h[1], m[11] = h[2];
}

static lvp_skeleton skeleton_of(const builder *b)
{
	lvp_skeleton s = {b->bone_count, b->rest_matrices, b->heads, b->tails, NULL};
	return s;
}

static const double y_axis[3] = {0, 1, 0};

/* Two fingers along +Z, radius 0.2, centres 0.5 apart (a gap of 0.1), each with its bone on its axis.
 * Finger 0 is vertices [0, *r_split), finger 1 the rest. */
static void make_fingers(builder *b, int32_t *r_split)
{
	memset(b, 0, sizeof(*b));
	for (int f = 0; f < 2; ++f) {
		double x = f == 0 ? -0.25 : 0.25, centres[9][3];
		for (int i = 0; i < 9; ++i)
			centres[i][0] = x, centres[i][1] = 0.0, centres[i][2] = 2.0 * i / 8.0;
		add_tube(b, (const double(*)[3])centres, 9, 0.2, 16, y_axis);
		if (f == 0)
			*r_split = b->vertex_count;
		add_bone(b, x, 0, 0, x, 0, 2);
	}
}

/* A body tube along +Z (radius 0.3, z in [0, 2], bones 0: z 0-1 and 1: z 1-2) with a hooked horn (radius
 * 0.08) that leaves the body sideways at z = 1.2, curls up and points back at the body at z = 1.8, where
 * its tip is 0.25 from the body. *r_tip is the horn's tip (its end cap's centre), whose normal faces the
 * body: it sees no bone, by either test. */
static void make_horned_body(builder *b, int32_t *r_tip)
{
	memset(b, 0, sizeof(*b));
	double body[11][3];
	for (int i = 0; i < 11; ++i)
		body[i][0] = 0.0, body[i][1] = 0.0, body[i][2] = 2.0 * i / 10.0;
	add_tube(b, (const double(*)[3])body, 11, 0.3, 16, y_axis);
	double horn[20][3];
	int n = 0;
	for (int i = 0; i < 5; ++i) /* the straight base, from inside the body */
		horn[n][0] = 0.55 * i / 5.0, horn[n][1] = 0.0, horn[n][2] = 1.2, ++n;
	for (int i = 0; i <= 12; ++i) { /* half a circle of radius 0.3 about (0.55, 0, 1.5) */
		double theta = PI * i / 12.0;
		horn[n][0] = 0.55 + 0.3 * sin(theta), horn[n][1] = 0.0, horn[n][2] = 1.5 - 0.3 * cos(theta), ++n;
	}
	int32_t first = add_tube(b, (const double(*)[3])horn, n, 0.08, 12, y_axis);
	*r_tip = first + n * 12 + 1;
	add_bone(b, 0, 0, 0, 0, 0, 1);
	add_bone(b, 0, 0, 1, 0, 0, 2);
}

/* ---- calling ------------------------------------------------------------------------------------- */

typedef struct result {
	int32_t *offsets, *bones;
	float *values;
	int64_t capacity;
} result;

static lvp_auto_weights_options options_with(lvp_visibility visibility)
{
	lvp_auto_weights_options o = lvp_auto_weights_default_options();
	o.visibility = visibility;
	return o;
}

static result compute(const builder *b, const lvp_auto_weights_options *o)
{
	result r;
	r.capacity = lvp_auto_weights_bound(b->vertex_count, b->bone_count, o);
	r.offsets = malloc(sizeof(int32_t) * ((size_t)b->vertex_count + 1));
	r.bones = malloc(sizeof(int32_t) * (size_t)r.capacity);
	r.values = malloc(sizeof(float) * (size_t)r.capacity);
	lvp_skeleton s = skeleton_of(b);
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_auto_weights(r.offsets, r.bones, r.values, r.capacity, b->positions, b->vertex_count, b->triangles,
	                          b->triangle_count, &s, o, &diag),
	         diag);
	return r;
}

static void result_free(result *r)
{
	free(r->offsets);
	free(r->bones);
	free(r->values);
}

static float weight_of(const result *r, int32_t vertex, int32_t bone)
{
	for (int32_t e = r->offsets[vertex]; e < r->offsets[vertex + 1]; ++e)
		if (r->bones[e] == bone)
			return r->values[e];
	return 0.0f;
}

/* The row contract: offsets well formed, bones distinct and in range, weights > 0, sorted by decreasing
 * weight, summing to 1, at most max_influences. */
static void check_rows(const builder *b, const result *r, const lvp_auto_weights_options *o)
{
	CHECK(r->offsets[0] == 0);
	CHECK(r->offsets[b->vertex_count] <= r->capacity);
	for (int32_t v = 0; v < b->vertex_count; ++v) {
		int32_t begin = r->offsets[v], end = r->offsets[v + 1];
		CHECK(end > begin);
		if (o->max_influences > 0)
			CHECK(end - begin <= o->max_influences);
		double sum = 0.0;
		for (int32_t e = begin; e < end; ++e) {
			CHECK(r->bones[e] >= 0 && r->bones[e] < b->bone_count);
			CHECK(r->values[e] > 0.0f);
			if (e > begin)
				CHECK(r->values[e] <= r->values[e - 1]);
			for (int32_t f = begin; f < e; ++f)
				CHECK(r->bones[f] != r->bones[e]);
			sum += r->values[e];
		}
		CHECK_NEAR(sum, 1.0, 1e-6);
	}
}

/* ---- visibility ---------------------------------------------------------------------------------- */

/* Every vertex of finger 0 on the side that faces finger 1 (and symmetrically). */
static bool faces_the_other_finger(const builder *b, int32_t v, int32_t split)
{
	float x = b->positions[3 * v];
	return v < split ? x > -0.25f + 0.1f : x < 0.25f - 0.1f;
}

static void test_fingers_neighbour_bone_only_without_visibility(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t split;
	make_fingers(b, &split);
	const lvp_visibility modes[3] = {LVP_VISIBILITY_NONE, LVP_VISIBILITY_NORMAL, LVP_VISIBILITY_EXACT};
	for (int m = 0; m < 3; ++m) {
		lvp_auto_weights_options o = options_with(modes[m]);
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		int facing = 0, facing_with_neighbour = 0, any_with_neighbour = 0;
		for (int32_t v = 0; v < b->vertex_count; ++v) {
			int32_t own = v < split ? 0 : 1;
			float neighbour = weight_of(&r, v, 1 - own);
			CHECK(weight_of(&r, v, own) > 0.5f);
			any_with_neighbour += neighbour > 0.0f;
			if (faces_the_other_finger(b, v, split)) {
				++facing;
				facing_with_neighbour += neighbour > 0.0f;
			}
		}
		CHECK(facing >= 40);
		if (modes[m] == LVP_VISIBILITY_NONE) {
			CHECK(facing_with_neighbour == facing); /* the paper's problem: fingers glued together */
		} else {
			CHECK(facing_with_neighbour == 0);
		}
		if (modes[m] == LVP_VISIBILITY_EXACT)
			CHECK(any_with_neighbour == 0); /* no path to the other bone stays inside the body */
		result_free(&r);
	}
	free(b);
}

/* A horn tip that sees no bone follows its closest bone rigidly; without visibility it blends. */
static void test_horn_tip_gets_rigid_fallback(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t tip;
	make_horned_body(b, &tip);
	CHECK_NEAR(b->positions[3 * tip], 0.55, 1e-6);
	CHECK_NEAR(b->positions[3 * tip + 2], 1.8, 1e-6);
	const lvp_visibility modes[3] = {LVP_VISIBILITY_NONE, LVP_VISIBILITY_NORMAL, LVP_VISIBILITY_EXACT};
	for (int m = 0; m < 3; ++m) {
		lvp_auto_weights_options o = options_with(modes[m]);
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		int32_t count = r.offsets[tip + 1] - r.offsets[tip];
		if (modes[m] == LVP_VISIBILITY_NONE) {
			CHECK(count == 2);
		} else {
			CHECK(count == 1);
			CHECK(r.bones[r.offsets[tip]] == 1); /* the closest bone: 0.55 away, bone 0 is 0.97 away */
			CHECK(r.values[r.offsets[tip]] == 1.0f);
		}
		result_free(&r);
	}
	free(b);
}

/* Brute-force visibility of every (vertex, bone) pair: the normal test from the public normals, the
 * exact one against every triangle. r_visible: vertex_count * bone_count. */
static void brute_force_visibility(bool *r_visible, const builder *b, const float *normals,
                                   const lvp_auto_weights_options *o)
{
	for (int32_t v = 0; v < b->vertex_count; ++v) {
		lvp__vec3 p = lvp__load(b->positions + 3 * v), n = lvp__load(normals + 3 * v);
		for (int32_t i = 0; i < b->bone_count; ++i) {
			lvp__vec3 c;
			lvp__closest_on_segment(&c, p, lvp__load(b->heads + 3 * i), lvp__load(b->tails + 3 * i));
			lvp__vec3 path = lvp__sub(c, p);
			double d = lvp__length(path);
			bool visible = true;
			if (d > 0.0 && o->visibility == LVP_VISIBILITY_NORMAL && lvp__length(n) > 0.0)
				visible = lvp__dot(path, n) / d <= o->normal_cos_max;
			if (d > 0.0 && o->visibility == LVP_VISIBILITY_EXACT)
				for (int32_t f = 0; f < b->triangle_count && visible; ++f) {
					const int32_t *tri = b->triangles + 3 * f;
					if (tri[0] == v || tri[1] == v || tri[2] == v)
						continue;
					float corners[3][3];
					for (int k = 0; k < 3; ++k)
						memcpy(corners[k], b->positions + 3 * tri[k], sizeof(float) * 3);
					double hit;
					if (lvp__segment_triangle(&hit, p, path, (const float(*)[3])corners, 1e-6, 1.0 - 1e-6))
						visible = false;
				}
			r_visible[v * b->bone_count + i] = visible;
		}
	}
}

/* Reference weights of vertex v from the brute-force visibility: normalized, pruned by min_weight, cut to
 * max_influences and renormalized, as lvp.h specifies. r_bones/r_values: room for bone_count. */
static int32_t reference_row(int32_t *r_bones, double *r_values, const builder *b, const bool *visible, int32_t v,
                             const lvp_auto_weights_options *o)
{
	lvp__vec3 p = lvp__load(b->positions + 3 * v);
	double weight[16] = {0}, closest_d = INFINITY, sum = 0.0;
	int32_t closest = -1;
	for (int32_t i = 0; i < b->bone_count; ++i) {
		lvp__vec3 h = lvp__load(b->heads + 3 * i), t = lvp__load(b->tails + 3 * i), c;
		double length = lvp__length(lvp__sub(t, h));
		if (length == 0.0)
			continue;
		lvp__closest_on_segment(&c, p, h, t);
		double d = lvp__length(lvp__sub(c, p));
		if (d < closest_d)
			closest_d = d, closest = i;
		if (visible[v * b->bone_count + i])
			weight[i] = pow((o->by_length ? length : 1.0) / fmax(d, 1e-6 * length), o->alpha), sum += weight[i];
	}
	if (sum == 0.0) {
		r_bones[0] = closest, r_values[0] = 1.0;
		return 1;
	}
	int32_t count = 0;
	for (;;) { /* selection by decreasing weight, ties to the lower bone */
		int32_t best = -1;
		for (int32_t i = 0; i < b->bone_count; ++i)
			if (weight[i] > 0.0 && (best < 0 || weight[i] > weight[best]))
				best = i;
		if (best < 0 || weight[best] / sum < o->min_weight || (o->max_influences > 0 && count == o->max_influences))
			break;
		r_bones[count] = best, r_values[count++] = weight[best];
		weight[best] = 0.0;
	}
	if (count == 0) {
		int32_t best = 0;
		for (int32_t i = 1; i < b->bone_count; ++i)
			if (weight[i] > weight[best])
				best = i;
		r_bones[0] = best, r_values[0] = 1.0, count = 1;
	}
	double kept = 0.0;
	for (int32_t j = 0; j < count; ++j)
		kept += r_values[j];
	for (int32_t j = 0; j < count; ++j)
		r_values[j] /= kept;
	return count;
}

/* The fingers and the horned body together with four bones (one per finger, two in the body): bones that
 * hide behind other parts, and others that do not. */
static void make_mixed_scene(builder *b)
{
	int32_t split, tip;
	builder *horned = malloc(sizeof(builder));
	make_horned_body(horned, &tip);
	make_fingers(b, &split);
	/* move the fingers beside the body, then append the body and its bones */
	for (int32_t v = 0; v < b->vertex_count; ++v)
		b->positions[3 * v] += 1.4f, b->positions[3 * v + 1] += 0.3f;
	for (int32_t i = 0; i < b->bone_count; ++i)
		b->heads[3 * i] += 1.4f, b->tails[3 * i] += 1.4f, b->heads[3 * i + 1] += 0.3f, b->tails[3 * i + 1] += 0.3f;
	int32_t base = b->vertex_count;
	memcpy(b->positions + 3 * base, horned->positions, sizeof(float) * 3 * (size_t)horned->vertex_count);
	for (int32_t t = 0; t < 3 * horned->triangle_count; ++t)
		b->triangles[3 * b->triangle_count + t] = horned->triangles[t] + base;
	b->vertex_count += horned->vertex_count;
	b->triangle_count += horned->triangle_count;
	for (int32_t i = 0; i < horned->bone_count; ++i)
		add_bone(b, horned->heads[3 * i], horned->heads[3 * i + 1], horned->heads[3 * i + 2], horned->tails[3 * i],
		         horned->tails[3 * i + 1], horned->tails[3 * i + 2]);
	free(horned);
}

/* lvp_auto_weights against the brute force, for both tests and many pruning settings: the exact test
 * through the hierarchy must see what the all-triangle test sees, and taking bones strongest first
 * (deciding visibility only while it matters) must give what testing every bone gives. */
static void compare_with_brute_force(const builder *b, int *r_hidden)
{
	float *normals = malloc(sizeof(float) * 3 * (size_t)b->vertex_count);
	lvp_diagnostic diag = {0};
	CHECK_OK(lvp_vertex_normals(normals, b->positions, b->vertex_count, b->triangles, b->triangle_count, &diag), diag);
	const float min_weights[4] = {0.0f, 0.01f, 0.1f, 0.45f};
	const int32_t max_influences[4] = {0, 1, 2, 3};
	const float alphas[2] = {2.0f, 1.5f};
	int hidden_somewhere = 0;
	bool *visible = malloc(sizeof(bool) * (size_t)b->vertex_count * (size_t)b->bone_count);
	for (int vis = 0; vis < 2; ++vis) {
		lvp_auto_weights_options brute = options_with(vis ? LVP_VISIBILITY_EXACT : LVP_VISIBILITY_NORMAL);
		brute_force_visibility(visible, b, normals, &brute);
		for (int a = 0; a < 4; ++a) /* each alpha with and without the bones' lengths */
			for (int mw = 0; mw < 4; ++mw)
				for (int mi = 0; mi < 4; ++mi) {
					lvp_auto_weights_options o = brute;
					o.alpha = alphas[a / 2], o.by_length = a % 2 == 0, o.min_weight = min_weights[mw];
					o.max_influences = max_influences[mi];
					result r = compute(b, &o);
					check_rows(b, &r, &o);
					int mismatches = 0;
					for (int32_t v = 0; v < b->vertex_count; ++v) {
						int32_t bones[16];
						double values[16];
						int32_t count = reference_row(bones, values, b, visible, v, &o);
						bool same = count == r.offsets[v + 1] - r.offsets[v];
						for (int32_t j = 0; same && j < count; ++j)
							same = bones[j] == r.bones[r.offsets[v] + j] &&
							       fabs(values[j] - r.values[r.offsets[v] + j]) < 1e-6;
						mismatches += !same;
						if (!same && mismatches <= 3)
							fprintf(stderr, "    vertex %d (visibility %d, alpha %g, by length %d, min_weight %g, max %d)\n",
							        (int)v, (int)o.visibility, (double)o.alpha, (int)o.by_length, (double)o.min_weight,
							        (int)o.max_influences);
						if (o.min_weight == 0.0f && o.max_influences == 0)
							hidden_somewhere += count < b->bone_count;
					}
					CHECK(mismatches == 0);
					result_free(&r);
				}
	}
	*r_hidden = hidden_somewhere;
	free(visible);
	free(normals);
}

static void test_matches_brute_force_reference(void)
{
	builder *b = malloc(sizeof(builder));
	make_mixed_scene(b);
	int hidden;
	compare_with_brute_force(b, &hidden);
	CHECK(hidden > 100); /* the scene does exercise the visibility tests */
	free(b);
}

/* The same on skeletons drawn at random around the scene: many bones, most of them hidden from most
 * vertices, some outside the body, some crossing it. */
static void test_matches_brute_force_on_random_skeletons(void)
{
	builder *b = malloc(sizeof(builder));
	uint32_t state = 12345u;
	for (int seed = 0; seed < 3; ++seed) {
		make_mixed_scene(b);
		b->bone_count = 0;
		for (int i = 0; i < 12; ++i) {
			double c[6];
			for (int j = 0; j < 6; ++j) {
				state = state * 1664525u + 1013904223u;
				c[j] = (double)(state >> 8) / (double)(1u << 24);
			}
			add_bone(b, -0.4 + 2.2 * c[0], -0.4 + 0.8 * c[1], 2.0 * c[2], -0.4 + 2.2 * c[3], -0.4 + 0.8 * c[4],
			         2.0 * c[5]);
		}
		int hidden;
		compare_with_brute_force(b, &hidden);
		CHECK(hidden > 100);
	}
	free(b);
}

/* The normal test works from the volume's sign: a mesh wound inward gets the same weights. */
static void test_inward_winding_is_detected(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t split;
	make_fingers(b, &split);
	for (int facing = 0; facing < 2; ++facing) { /* the distance along the normal needs it outward too */
		lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
		o.facing = facing;
		result outward = compute(b, &o);
		for (int32_t t = 0; t < b->triangle_count; ++t) {
			int32_t swap = b->triangles[3 * t + 1];
			b->triangles[3 * t + 1] = b->triangles[3 * t + 2];
			b->triangles[3 * t + 2] = swap;
		}
		result inward = compute(b, &o);
		CHECK(memcmp(outward.offsets, inward.offsets, sizeof(int32_t) * ((size_t)b->vertex_count + 1)) == 0);
		int32_t total = outward.offsets[b->vertex_count];
		CHECK(memcmp(outward.bones, inward.bones, sizeof(int32_t) * (size_t)total) == 0);
		CHECK(memcmp(outward.values, inward.values, sizeof(float) * (size_t)total) == 0);
		result_free(&outward);
		result_free(&inward);
	}
	free(b);
}

/* ---- bones --------------------------------------------------------------------------------------- */

/* A zero-length bone never receives weight, even right inside a finger, unless the skeleton has no
 * other bone: then it is every vertex's rigid fallback. */
static void test_zero_length_bone_gets_no_weight(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t split;
	make_fingers(b, &split);
	add_bone(b, -0.25, 0, 1, -0.25, 0, 1);
	for (int vis = 0; vis < 3; ++vis) {
		lvp_auto_weights_options o = options_with((lvp_visibility)vis);
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		for (int32_t e = 0; e < r.offsets[b->vertex_count]; ++e)
			CHECK(r.bones[e] != 2);
		result_free(&r);
	}
	b->bone_count = 0;
	add_bone(b, 0.3, 0.1, 1, 0.3, 0.1, 1);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_EXACT);
	result r = compute(b, &o);
	for (int32_t v = 0; v < b->vertex_count; ++v)
		CHECK(r.offsets[v + 1] - r.offsets[v] == 1 && r.bones[r.offsets[v]] == 0 && r.values[r.offsets[v]] == 1.0f);
	result_free(&r);
	free(b);
}

/* d = 0: a vertex on a bone weighs (almost) only on it, and one on the joint of two bones is shared
 * evenly, without a division by zero. Isolated vertices (no normal) are placed there. */
static void test_vertex_on_a_bone(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t tip;
	make_horned_body(b, &tip);
	int32_t on_bone = add_vertex(b, 0, 0, 0.4), on_joint = add_vertex(b, 0, 0, 1);
	for (int vis = 0; vis < 3; ++vis) {
		lvp_auto_weights_options o = options_with((lvp_visibility)vis);
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		CHECK(r.offsets[on_bone + 1] - r.offsets[on_bone] == 1);
		CHECK(r.bones[r.offsets[on_bone]] == 0);
		CHECK(weight_of(&r, on_joint, 0) == 0.5f);
		CHECK(weight_of(&r, on_joint, 1) == 0.5f);
		result_free(&r);
	}
	free(b);
}

/* Awkward but valid input never fails or reads out of bounds: all triangles of zero area, hundreds of
 * copies of one triangle (coincident centroids, so the hierarchy must split by count), coordinates near
 * the float range. */
static void test_degenerate_geometry_is_handled(void)
{
	builder *b = malloc(sizeof(builder));
	memset(b, 0, sizeof(*b));
	for (int i = 0; i < 600; ++i)
		add_vertex(b, 0.1 * (i % 3), 0.2 * (i % 7), 0.3 * (i % 3 == 1));
	for (int i = 0; i < 600; ++i)
		add_triangle(b, 0, 1, 2); /* the same triangle over and over */
	for (int i = 3; i + 2 < 600; i += 3)
		add_triangle(b, i, i, i + 1); /* zero area */
	add_bone(b, 0, 0, -1, 0, 0, 1);
	add_bone(b, 1, 1, -1, 1, 1, 1);
	for (int vis = 0; vis < 3; ++vis) {
		lvp_auto_weights_options o = options_with((lvp_visibility)vis);
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		result_free(&r);
	}
	/* only zero-area triangles: nothing can hide a bone */
	b->triangle_count = 0;
	for (int i = 0; i < 100; ++i)
		add_triangle(b, i, i + 1, i + 1);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_EXACT);
	result r = compute(b, &o);
	check_rows(b, &r, &o);
	result_free(&r);
	/* huge coordinates */
	int32_t split;
	make_fingers(b, &split);
	for (int32_t i = 0; i < 3 * b->vertex_count; ++i)
		b->positions[i] *= 1e37f;
	for (int32_t i = 0; i < 3 * b->bone_count; ++i)
		b->heads[i] *= 1e37f, b->tails[i] *= 1e37f;
	for (int vis = 0; vis < 3; ++vis) {
		o = options_with((lvp_visibility)vis);
		r = compute(b, &o);
		check_rows(b, &r, &o);
		result_free(&r);
	}
	free(b);
}

/* ---- smoothing ----------------------------------------------------------------------------------- */

/* The largest change of any bone's weight across an edge of the mesh. */
static double largest_edge_jump(const builder *b, const result *r)
{
	double worst = 0.0;
	for (int32_t t = 0; t < b->triangle_count; ++t)
		for (int c = 0; c < 3; ++c) {
			int32_t u = b->triangles[3 * t + c], v = b->triangles[3 * t + (c + 1) % 3];
			for (int32_t bone = 0; bone < b->bone_count; ++bone) {
				double jump = fabs((double)weight_of(r, u, bone) - (double)weight_of(r, v, bone));
				worst = jump > worst ? jump : worst;
			}
		}
	return worst;
}

/* A straight arm (a tube of radius 0.2 along z in [0, 3], rings 0.1 apart) on three bones of length 1. The
 * sharp weights of a high alpha jump across the rings next to each joint; smoothed, they change gradually,
 * and each bone still holds the middle of its own segment. */
static void test_smoothing_makes_weights_continuous(void)
{
	builder *b = malloc(sizeof(builder));
	memset(b, 0, sizeof(*b));
	double centres[31][3];
	for (int i = 0; i < 31; ++i)
		centres[i][0] = 0.0, centres[i][1] = 0.0, centres[i][2] = 0.1 * i;
	add_tube(b, (const double(*)[3])centres, 31, 0.2, 16, y_axis);
	for (int i = 0; i < 3; ++i)
		add_bone(b, 0, 0, i, 0, 0, i + 1);
	int32_t isolated = add_vertex(b, 0.0, 0.5, 1.5); /* no edge: it keeps its own weights */
	for (int vis = 0; vis < 3; ++vis) {
		lvp_auto_weights_options o = options_with((lvp_visibility)vis);
		o.alpha = 16.0f;
		result sharp = compute(b, &o);
		o.smoothing_iterations = 5;
		result smooth = compute(b, &o);
		check_rows(b, &smooth, &o);
		double before = largest_edge_jump(b, &sharp), after = largest_edge_jump(b, &smooth);
		CHECK(before > 0.3);
		CHECK(after < 0.6 * before); /* 0.36 -> 0.20 */
		for (int32_t v = 0; v < 31 * 16; ++v) {
			double z = b->positions[3 * v + 2];
			for (int i = 0; i < 3; ++i)
				if (fabs(z - (i + 0.5)) < 0.15)
					CHECK(weight_of(&smooth, v, i) > 0.95f);
		}
		CHECK(smooth.offsets[isolated + 1] - smooth.offsets[isolated] == sharp.offsets[isolated + 1] -
		                                                                     sharp.offsets[isolated]);
		CHECK(weight_of(&smooth, isolated, 1) == weight_of(&sharp, isolated, 1));
		/* Through the clusters (lvp__diffusion_blend) the isolated vertex is a cluster of its own. */
		o.smoothing_iterations = 500;
		result blended = compute(b, &o);
		check_rows(b, &blended, &o);
		CHECK(weight_of(&blended, isolated, 1) == weight_of(&sharp, isolated, 1));
		result_free(&sharp);
		result_free(&smooth);
		result_free(&blended);
	}
	free(b);
}

/* Vertices around a ring of an arm of that radius with rings `spacing` apart: edges around about as long
 * as along. */
static int arm_around(double spacing, double radius)
{
	return (int)lround(8.0 * radius / spacing);
}

/* A straight arm of three bones along z from 0 to 3, of that radius, with rings `spacing` apart and as many
 * around as keep its triangles' shape: every edge scales with spacing. */
static void add_arm(builder *b, double spacing, double radius, double x)
{
	int rings = (int)lround(3.0 / spacing) + 1;
	double(*centres)[3] = malloc(sizeof(double[3]) * (size_t)rings);
	for (int i = 0; i < rings; ++i)
		centres[i][0] = x, centres[i][1] = 0.0, centres[i][2] = spacing * i;
	add_tube(b, (const double(*)[3])centres, rings, radius, arm_around(spacing, radius), y_axis);
	free(centres);
	for (int i = 0; i < 3; ++i)
		add_bone(b, x, 0, i, x, 0, i + 1);
}

/* The straight arm of test_smoothing_makes_weights_continuous (radius 0.2). */
static void make_arm(builder *b, double spacing)
{
	memset(b, 0, sizeof(*b));
	add_arm(b, spacing, 0.2, 0.0);
}

/* How wide the blend of bones `first` and first + 1 (the first joint of an arm of that radius whose
 * vertices start at `vertex`) is along the arm: the integral over z of 4 w0 w1 (1 where they are even, 0
 * where one holds alone), along the line of the rings' first vertices. */
static double arm_blend_width(const result *r, double spacing, double radius, int32_t vertex, int32_t first)
{
	int around = arm_around(spacing, radius), rings = (int)lround(3.0 / spacing) + 1;
	double width = 0.0;
	for (int i = 0; i < rings && spacing * i < 2.0; ++i) {
		int32_t v = vertex + i * around;
		width += 4.0 * (double)weight_of(r, v, first) * (double)weight_of(r, v, first + 1) * spacing;
	}
	return width;
}

/* arm_blend_width of make_arm's arm. */
static double blend_width(const result *r, double spacing)
{
	return arm_blend_width(r, spacing, 0.2, 0, 0);
}

/* smoothing_length blends over about the same distance on the arm at two resolutions, where a fixed number
 * of steps blends over half the distance on the mesh twice as dense. */
static void test_smoothing_length_follows_the_resolution(void)
{
	builder *coarse = malloc(sizeof(builder)), *fine = malloc(sizeof(builder));
	make_arm(coarse, 0.1);
	make_arm(fine, 0.05);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	o.smoothing_iterations = 10;
	result coarse_steps = compute(coarse, &o), fine_steps = compute(fine, &o);
	double coarse_width = blend_width(&coarse_steps, 0.1), fine_width = blend_width(&fine_steps, 0.05);
	CHECK(fine_width < 0.75 * coarse_width); /* 0.45 -> 0.29 */
	o.smoothing_iterations = 0;
	o.smoothing_length = 0.35f;
	result coarse_length = compute(coarse, &o), fine_length = compute(fine, &o);
	check_rows(fine, &fine_length, &o);
	double coarse_blend = blend_width(&coarse_length, 0.1), fine_blend = blend_width(&fine_length, 0.05);
	CHECK(fine_blend > 0.8 * coarse_blend && fine_blend < 1.25 * coarse_blend); /* 0.49 -> 0.47 */
	result_free(&coarse_steps);
	result_free(&fine_steps);
	result_free(&coarse_length);
	result_free(&fine_length);
	free(coarse);
	free(fine);
}

/* A blend of many steps' worth (about 100 on the arm with rings 0.035 apart, through the clusters of
 * lvp__diffusion_blend) is as wide as the same length blended by a few ordinary steps on the arm with rings
 * 0.1 apart (13), continuous, and each bone still holds the middle of its segment. */
static void test_smoothing_of_many_steps(void)
{
	builder *coarse = malloc(sizeof(builder)), *fine = malloc(sizeof(builder));
	make_arm(coarse, 0.1);
	make_arm(fine, 0.035);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	result sharp = compute(fine, &o);
	o.smoothing_length = 0.5f;
	result few = compute(coarse, &o), many = compute(fine, &o);
	check_rows(fine, &many, &o);
	double few_blend = blend_width(&few, 0.1), many_blend = blend_width(&many, 0.035);
	printf("  blend over 0.5: %.3f wide with 13 steps on rings 0.1 apart, %.3f with many steps' worth on rings "
	       "0.035 apart; largest jump across an edge %.3f (unsmoothed %.3f)\n",
	       few_blend, many_blend, largest_edge_jump(fine, &many), largest_edge_jump(fine, &sharp));
	CHECK(many_blend > 0.8 * few_blend && many_blend < 1.25 * few_blend);
	CHECK(largest_edge_jump(fine, &many) < 0.5 * largest_edge_jump(fine, &sharp));
	/* Along the arm, the weights of the many steps follow those of the few: at each ring of the arm 0.1
	 * apart, within 0.05 of them (interpolated between the two rings 0.035 apart around it); in the middle
	 * of each segment its bone holds among them. */
	int32_t fine_around = (int32_t)lround(1.6 / 0.035), coarse_around = 16;
	double worst = 0.0, middle = 1.0;
	for (int32_t ring = 0; ring <= 30; ++ring) {
		double z = 0.1 * ring, at = z / 0.035;
		int32_t below = (int32_t)floor(at), above = below + 1 < (int32_t)lround(3.0 / 0.035) ? below + 1 : below;
		double t = at - below;
		for (int32_t bone = 0; bone < 3; ++bone) {
			double a = weight_of(&few, ring * coarse_around, bone);
			double b = (1.0 - t) * weight_of(&many, below * fine_around, bone) + t * weight_of(&many, above * fine_around, bone);
			worst = fmax(worst, fabs(a - b));
			if (fabs(z - (bone + 0.5)) < 0.01)
				middle = fmin(middle, b);
		}
	}
	printf("  along the arm: at most %.3f apart; the middle of each segment %.3f its bone's\n", worst, middle);
	CHECK(worst < 0.05);
	CHECK(middle > 0.9);
	result_free(&sharp);
	result_free(&few);
	result_free(&many);
	free(coarse);
	free(fine);
}

/* Weight flows along edges only: the two fingers (separate pieces, 0.1 apart) are weighted as each alone,
 * bit for bit, though the smoothing changes both; with a few steps and with many (through clusters,
 * lvp__diffusion_blend). */
static void test_smoothing_keeps_separate_pieces_apart(void)
{
	builder *both = malloc(sizeof(builder)), *alone = malloc(sizeof(builder));
	int32_t split;
	make_fingers(both, &split);
	*alone = *both;
	alone->vertex_count = split;
	alone->triangle_count = 0;
	for (int32_t t = 0; t < both->triangle_count; ++t)
		if (both->triangles[3 * t] < split)
			add_triangle(alone, both->triangles[3 * t], both->triangles[3 * t + 1], both->triangles[3 * t + 2]);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NONE); /* each finger takes both bones */
	result raw = compute(both, &o);
	const int32_t steps[2] = {20, 100};
	for (int i = 0; i < 2; ++i) {
		o.smoothing_iterations = steps[i];
		result together = compute(both, &o), separate = compute(alone, &o);
		check_rows(both, &together, &o);
		CHECK(memcmp(together.offsets, separate.offsets, sizeof(int32_t) * ((size_t)split + 1)) == 0);
		int32_t total = separate.offsets[split];
		CHECK(memcmp(together.bones, separate.bones, sizeof(int32_t) * (size_t)total) == 0);
		CHECK(memcmp(together.values, separate.values, sizeof(float) * (size_t)total) == 0);
		int32_t changed = 0;
		for (int32_t v = 0; v < split; ++v)
			changed += fabsf(weight_of(&raw, v, 1) - weight_of(&together, v, 1)) > 1e-3f;
		CHECK(changed > split / 4);
		result_free(&together);
		result_free(&separate);
	}
	result_free(&raw);
	free(both);
	free(alone);
}

/* smoothing_thickness blends each joint over a distance that follows its flesh: side by side, an arm twice
 * as thick blends its joints over about twice the distance, and the same arm at twice the resolution over
 * the same distance; the weights stay continuous and each bone holds the middle of its segment. */
static void test_smoothing_follows_the_thickness(void)
{
	builder *b = malloc(sizeof(builder)), *fine = malloc(sizeof(builder));
	memset(b, 0, sizeof(*b));
	add_arm(b, 0.05, 0.1, 0.0);
	int32_t thick_arm = b->vertex_count;
	add_arm(b, 0.05, 0.2, 2.0);
	memset(fine, 0, sizeof(*fine));
	add_arm(fine, 0.025, 0.1, 0.0);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	result sharp = compute(b, &o);
	o.smoothing_thickness = 1.5f;
	result both = compute(b, &o), thin_fine = compute(fine, &o);
	check_rows(b, &both, &o);
	check_rows(fine, &thin_fine, &o);
	double thin = arm_blend_width(&both, 0.05, 0.1, 0, 0), thick = arm_blend_width(&both, 0.05, 0.2, thick_arm, 3);
	double finer = arm_blend_width(&thin_fine, 0.025, 0.1, 0, 0);
	printf("  blend over 1.5 times the thickness: %.3f on the arm of radius 0.1, %.3f on the one of 0.2 (%.2fx), "
	       "%.3f on the thin one twice as dense; largest jump across an edge %.3f (unsmoothed %.3f)\n",
	       thin, thick, thick / thin, finer, largest_edge_jump(b, &both), largest_edge_jump(b, &sharp));
	CHECK(thick > 1.6 * thin && thick < 2.5 * thin);
	CHECK(finer > 0.8 * thin && finer < 1.25 * thin);
	CHECK(largest_edge_jump(b, &both) < 0.6 * largest_edge_jump(b, &sharp));
	/* The middle of each segment stays its bone's: at z = 0.5, 1.5, 2.5 on either arm. */
	const int32_t arms[2] = {0, thick_arm};
	const double radii[2] = {0.1, 0.2};
	for (int arm = 0; arm < 2; ++arm)
		for (int bone = 0; bone < 3; ++bone) {
			int32_t v = arms[arm] + (int32_t)lround((bone + 0.5) / 0.05) * arm_around(0.05, radii[arm]);
			CHECK(weight_of(&both, v, 3 * arm + bone) > 0.9f);
		}
	result_free(&sharp);
	result_free(&both);
	result_free(&thin_fine);
	free(b);
	free(fine);
}

/* A thicker separate piece (a weapon, a tail, another character in the mesh) barely changes how an arm is
 * weighted by its thickness, where a blend length taken from the mesh's size would double; the same for
 * 1 and 2 threads is not asked (auto weights run on one). */
static void test_smoothing_by_thickness_is_local(void)
{
	builder *alone = malloc(sizeof(builder)), *with = malloc(sizeof(builder));
	memset(alone, 0, sizeof(*alone));
	add_arm(alone, 0.05, 0.1, 0.0);
	*with = *alone;
	add_arm(with, 0.05, 0.4, 3.0);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	o.smoothing_thickness = 1.5f;
	result a = compute(alone, &o), w = compute(with, &o);
	double by_itself = arm_blend_width(&a, 0.05, 0.1, 0, 0), beside = arm_blend_width(&w, 0.05, 0.1, 0, 0);
	printf("  the thin arm's blend %.3f alone, %.3f beside an arm four times as thick\n", by_itself, beside);
	CHECK(beside > 0.9 * by_itself && beside < 1.1 * by_itself);
	result_free(&a);
	result_free(&w);
	free(alone);
	free(with);
}

/* Bone heat (options.heat): each joint blends over a distance that follows the depth of its skin, as heat weights
 * do: an arm twice as thick over about twice the distance, the same arm twice as dense over the same
 * distance; the weights are continuous (their jumps across edges shrink as the edges do, where the nearest
 * bone's stay one), each bone holds the middle of
 * its segment, and an arm beside another piece (a thicker arm: no edge joins them) is weighted bit for bit
 * as alone, since a bone's heat flows along edges only. The horned body's hooked horn, which sees no bone
 * from its tip, is weighted through its skin: every row as the contract says, the same bits on three threads
 * as on one. */
static void test_heat_blends_by_the_skin_s_depth(void)
{
	builder *b = malloc(sizeof(builder)), *fine = malloc(sizeof(builder)), *alone = malloc(sizeof(builder));
	memset(b, 0, sizeof(*b));
	add_arm(b, 0.05, 0.1, 0.0);
	int32_t thick_arm = b->vertex_count;
	add_arm(b, 0.05, 0.2, 2.0);
	memset(fine, 0, sizeof(*fine));
	add_arm(fine, 0.025, 0.1, 0.0);
	memset(alone, 0, sizeof(*alone));
	add_arm(alone, 0.05, 0.1, 0.0);
	for (int vis = 0; vis < 3; ++vis) {
		lvp_auto_weights_options o = options_with((lvp_visibility)vis);
		o.alpha = 16.0f;
		o.by_length = 0;
		o.facing = 1;
		result sharp = compute(b, &o);
		o.heat = 1;
		result both = compute(b, &o), thin_fine = compute(fine, &o), by_itself = compute(alone, &o);
		check_rows(b, &both, &o);
		check_rows(fine, &thin_fine, &o);
		double thin = arm_blend_width(&both, 0.05, 0.1, 0, 0), thick = arm_blend_width(&both, 0.05, 0.2, thick_arm, 3);
		double finer = arm_blend_width(&thin_fine, 0.025, 0.1, 0, 0);
		double jump = largest_edge_jump(alone, &by_itself), finer_jump = largest_edge_jump(fine, &thin_fine);
		printf("  bone heat, %s test: blend %.3f on the arm of radius 0.1, %.3f on the one of 0.2 (%.2fx), %.3f on "
		       "the thin one twice as dense; largest jump across an edge %.3f, twice as dense %.3f (nearest bone "
		       "%.3f)\n",
		       vis == 0 ? "normal" : (vis == 1 ? "exact" : "no visibility"), thin, thick, thick / thin, finer, jump,
		       finer_jump, largest_edge_jump(b, &sharp));
		CHECK(thin > 0.02);
		CHECK(thick > 1.6 * thin && thick < 2.5 * thin);
		CHECK(finer > 0.8 * thin && finer < 1.25 * thin);
		CHECK(jump < 0.8 * largest_edge_jump(b, &sharp));
		CHECK(finer_jump < 0.7 * jump); /* continuous: the jumps shrink with the edges (0.63x) */
		const int32_t arms[2] = {0, thick_arm};
		const double radii[2] = {0.1, 0.2};
		for (int arm = 0; arm < 2; ++arm)
			for (int bone = 0; bone < 3; ++bone) {
				int32_t v = arms[arm] + (int32_t)lround((bone + 0.5) / 0.05) * arm_around(0.05, radii[arm]);
				CHECK(weight_of(&both, v, 3 * arm + bone) > 0.9f);
			}
		int32_t entries = by_itself.offsets[alone->vertex_count];
		CHECK(memcmp(both.offsets, by_itself.offsets, sizeof(int32_t) * ((size_t)alone->vertex_count + 1)) == 0);
		CHECK(memcmp(both.bones, by_itself.bones, sizeof(int32_t) * (size_t)entries) == 0);
		CHECK(memcmp(both.values, by_itself.values, sizeof(float) * (size_t)entries) == 0);
		result_free(&sharp);
		result_free(&both);
		result_free(&thin_fine);
		result_free(&by_itself);
	}
	int32_t tip;
	make_horned_body(alone, &tip);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_EXACT);
	o.heat = 1;
	result horned = compute(alone, &o);
	check_rows(alone, &horned, &o);
	/* The bones solved on three threads: the same bits. */
	o.thread_count = 3;
	result threaded = compute(alone, &o);
	int32_t total = horned.offsets[alone->vertex_count];
	CHECK(memcmp(horned.offsets, threaded.offsets, sizeof(int32_t) * ((size_t)alone->vertex_count + 1)) == 0);
	CHECK(memcmp(horned.bones, threaded.bones, sizeof(int32_t) * (size_t)total) == 0);
	CHECK(memcmp(horned.values, threaded.values, sizeof(float) * (size_t)total) == 0);
	result_free(&horned);
	result_free(&threaded);
	free(b);
	free(fine);
	free(alone);
}

/* Splits edge (p, q) at s = p + t (q - p): each triangle around the edge becomes two, wound as it was. */
static int32_t split_edge(builder *b, int32_t p, int32_t q, double t)
{
	const float *a = b->positions + 3 * p, *c = b->positions + 3 * q;
	int32_t s = add_vertex(b, a[0] + t * (c[0] - a[0]), a[1] + t * (c[1] - a[1]), a[2] + t * (c[2] - a[2]));
	int32_t count = b->triangle_count;
	for (int32_t f = 0; f < count; ++f) {
		int32_t *corners = b->triangles + 3 * f;
		for (int i = 0; i < 3; ++i) {
			int32_t from = corners[i], to = corners[(i + 1) % 3], third = corners[(i + 2) % 3];
			if ((from == p && to == q) || (from == q && to == p)) {
				corners[(i + 1) % 3] = s; /* (from, s, third) */
				add_triangle(b, s, to, third);
				break;
			}
		}
	}
	return s;
}

/* A sliver (an edge a fiftieth as long as the edges around it, as metaballs leave) across the blend of an
 * arm's joint, and a chain of four more beyond it: their ends take one row, where the steps, which count
 * edges and not lengths, would have left the ends of any edge, even one this short, rows a step apart. */
static void test_a_sliver_s_ends_share_one_row(void)
{
	builder *b = malloc(sizeof(builder));
	memset(b, 0, sizeof(*b));
	add_arm(b, 0.05, 0.1, 0.0);
	int around = arm_around(0.05, 0.1);
	int32_t p = 20 * around, next_ring = p + around; /* z = 1.0, the first joint, and z = 1.05 */
	int32_t s = split_edge(b, p, next_ring, 0.02);
	int32_t chain[4] = {split_edge(b, s, next_ring, 0.02), 0, 0, 0}; /* a chain of slivers beyond it */
	for (int i = 1; i < 4; ++i)
		chain[i] = split_edge(b, chain[i - 1], next_ring, 0.02);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	o.smoothing_thickness = 1.5f;
	result r = compute(b, &o);
	check_rows(b, &r, &o);
	printf("  bone 1 across the slivers %.4f / %.4f, across the ordinary edge beyond them %.4f / %.4f\n",
	       weight_of(&r, p, 1), weight_of(&r, chain[3], 1), weight_of(&r, chain[3], 1), weight_of(&r, next_ring, 1));
	CHECK(weight_of(&r, p, 0) > 0.1f && weight_of(&r, p, 1) > 0.1f); /* in the blend */
	CHECK(r.offsets[p + 1] - r.offsets[p] == r.offsets[s + 1] - r.offsets[s]);
	const int32_t ends[5] = {s, chain[0], chain[1], chain[2], chain[3]};
	for (int i = 0; i < 5; ++i)
		for (int32_t e = 0; e < r.offsets[p + 1] - r.offsets[p]; ++e) {
			CHECK(r.bones[r.offsets[p] + e] == r.bones[r.offsets[ends[i]] + e]);
			CHECK(r.values[r.offsets[p] + e] == r.values[r.offsets[ends[i]] + e]);
		}
	CHECK(weight_of(&r, next_ring, 1) > weight_of(&r, chain[3], 1) + 0.01f); /* an ordinary edge blends on */
	result_free(&r);
	free(b);
}

/* ---- the distance along the skin's normal -------------------------------------------------------- */

/* A closed tube of radius 0.3 and `around` sides along z in [0, 2] (21 rings 0.1 apart) into b (emptied
 * first), bone 0 on its axis and bone 1 inside it near the +x side, x = 0.2 from z = 0.5 to 1.5. Returns the
 * tube's first vertex. */
static int32_t make_tube_with_side_bone(builder *b, int around)
{
	memset(b, 0, sizeof(*b));
	double centres[21][3];
	for (int i = 0; i < 21; ++i)
		centres[i][0] = 0.0, centres[i][1] = 0.0, centres[i][2] = 0.1 * i;
	int32_t first = add_tube(b, (const double(*)[3])centres, 21, 0.3, around, y_axis);
	add_bone(b, 0, 0, 0, 0, 0, 2);
	add_bone(b, 0.2, 0, 0.5, 0.2, 0, 1.5);
	return first;
}

/* options.facing: a tube around bone 0 on its axis, bone 1 inside it near the +x side (a hip's bone
 * close under the skin above a thigh's, deeper). By the straight distance, bone 1 takes the skin out to
 * 70.5 degrees either side of +x; measured along the normal, only the skin that faces away from it
 * (straight over it, to about 60 degrees), and the skin at 67.5 degrees, which bone 1 lies off to the
 * side of, goes to bone 0 beneath it. */
static void test_facing_distance_gives_skin_to_the_bone_beneath(void)
{
	builder *b = malloc(sizeof(builder));
	make_tube_with_side_bone(b, 16);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NORMAL);
	o.alpha = 16.0f;
	o.by_length = 0;
	o.smoothing_thickness = 0.0f;
	result straight = compute(b, &o);
	o.facing = 1;
	result facing = compute(b, &o);
	check_rows(b, &facing, &o);
	int ring = 0;
	for (int32_t v = 0; v < b->vertex_count; ++v) {
		const float *p = b->positions + 3 * v;
		if (fabsf(p[2] - 1.0f) > 0.01f || hypotf(p[0], p[1]) < 0.1f)
			continue;
		double degrees = fabs(atan2(p[1], p[0])) * 180.0 / PI;
		bool straight_one = straight.bones[straight.offsets[v]] == 1, facing_one = facing.bones[facing.offsets[v]] == 1;
		CHECK(straight_one == (degrees < 70.5));
		CHECK(facing_one == (degrees < 60.0));
		++ring;
	}
	CHECK(ring == 16);
	result_free(&straight);
	result_free(&facing);
	free(b);
}

/* Facing Distance on a coarse tube (six sides: each vertex normal 30 degrees from its faces' normals), a bone on
 * its axis and one off to the side: with no visibility test the normal counts as far as the triangles around
 * agree with it (cos 30 degrees), with the exact test wholly, as heat weights count it. The weights of the ring
 * in the middle against the formula of lvp.h (options.facing), for both. */
static void test_facing_counts_wholly_with_the_exact_test(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t first = make_tube_with_side_bone(b, 6);
	const double closest[2][3] = {{0.0, 0.0, 1.0}, {0.2, 0.0, 1.0}};
	const lvp_visibility tests[2] = {LVP_VISIBILITY_NONE, LVP_VISIBILITY_EXACT};
	const double trusts[2] = {cos(PI / 6.0), 1.0};
	float side_weight[2] = {0.0f, 0.0f};
	for (int m = 0; m < 2; ++m) {
		lvp_auto_weights_options o = options_with(tests[m]);
		o.alpha = 16.0f, o.by_length = 0, o.facing = 1, o.max_influences = 0, o.min_weight = 1e-6f;
		result r = compute(b, &o);
		check_rows(b, &r, &o);
		for (int a = 0; a < 6; ++a) {
			int32_t v = first + 10 * 6 + a;
			const float *p = b->positions + 3 * v;
			double radial = hypot(p[0], p[1]), n[3] = {p[0] / radial, p[1] / radial, 0.0}, weight[2];
			for (int i = 0; i < 2; ++i) {
				double toward[3] = {closest[i][0] - p[0], closest[i][1] - p[1], closest[i][2] - p[2]};
				double distance = sqrt(toward[0] * toward[0] + toward[1] * toward[1] + toward[2] * toward[2]);
				double share = 0.5 * (1.001 - (toward[0] * n[0] + toward[1] * n[1] + toward[2] * n[2]) / distance);
				weight[i] = pow((1.0 - trusts[m] * (1.0 - share)) / distance, 16.0);
			}
			CHECK_NEAR(weight_of(&r, v, 1), weight[1] / (weight[0] + weight[1]), 2e-3);
		}
		side_weight[m] = weight_of(&r, first + 10 * 6 + 1, 1); /* 60 degrees round from the side bone */
		result_free(&r);
	}
	printf("  facing, the vertex 60 degrees from the side bone: its weight %.3f with no test, %.3f exact\n",
	       (double)side_weight[0], (double)side_weight[1]);
	CHECK(side_weight[0] > 0.5f && side_weight[1] < 0.5f); /* the trust decides which bone the vertex is */
	free(b);
}

/* ---- sizes --------------------------------------------------------------------------------------- */

static void test_bound(void)
{
	lvp_auto_weights_options o = lvp_auto_weights_default_options();
	CHECK(lvp_auto_weights_bound(100, 60, &o) == 400);
	CHECK(lvp_auto_weights_bound(100, 60, NULL) == 400);
	CHECK(lvp_auto_weights_bound(100, 3, &o) == 300);
	o.max_influences = 0, o.min_weight = 0.0f;
	CHECK(lvp_auto_weights_bound(100, 60, &o) == 6000);
	o.min_weight = 0.25f; /* at most 4 weights can reach 1/4, one more for rounding */
	CHECK(lvp_auto_weights_bound(100, 60, &o) == 500);
	CHECK(lvp_auto_weights_bound(0, 60, &o) == 0);
	CHECK(lvp_auto_weights_bound(100, 0, &o) == 0);
	CHECK(lvp_auto_weights_bound(-1, 60, &o) == 0);
}

static void test_capacity_too_small_is_an_error(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t split;
	make_fingers(b, &split);
	lvp_auto_weights_options o = options_with(LVP_VISIBILITY_NONE);
	result full = compute(b, &o);
	int32_t needed = full.offsets[b->vertex_count], n = b->vertex_count;
	CHECK(needed > n && needed < full.capacity); /* some vertices have two bones, not all four */
	int32_t *offsets = malloc(sizeof(int32_t) * ((size_t)n + 1)), *bones = malloc(sizeof(int32_t) * (size_t)needed);
	float *values = malloc(sizeof(float) * (size_t)needed);
	lvp_skeleton s = skeleton_of(b);
	for (int32_t i = 0; i <= n; ++i)
		offsets[i] = -7;
	for (int32_t i = 0; i < needed; ++i)
		bones[i] = -7, values[i] = -7.0f;
	lvp_diagnostic diag = {0};
	lvp_result got = lvp_auto_weights(offsets, bones, values, needed - 1, b->positions, n, b->triangles,
	                                  b->triangle_count, &s, &o, &diag);
	CHECK(got == lvp_error_invalid_size);
	CHECK(diag.argument && strcmp(diag.argument, "capacity") == 0);
	char number[32];
	snprintf(number, sizeof(number), "need %d", (int)needed);
	CHECK(strstr(diag.message, number) != NULL);
	for (int32_t i = 0; i <= n; ++i) /* untouched */
		CHECK(offsets[i] == -7);
	for (int32_t i = 0; i < needed; ++i)
		CHECK(bones[i] == -7 && values[i] == -7.0f);
	/* exactly enough: the same rows as with the bound */
	CHECK_OK(lvp_auto_weights(offsets, bones, values, needed, b->positions, n, b->triangles, b->triangle_count, &s, &o,
	                          &diag),
	         diag);
	CHECK(memcmp(offsets, full.offsets, sizeof(int32_t) * ((size_t)n + 1)) == 0);
	CHECK(memcmp(bones, full.bones, sizeof(int32_t) * (size_t)needed) == 0);
	CHECK(memcmp(values, full.values, sizeof(float) * (size_t)needed) == 0);
	CHECK(lvp_auto_weights(offsets, bones, values, 0, b->positions, n, b->triangles, b->triangle_count, &s, &o,
	                       &diag) == lvp_error_invalid_size);
	CHECK(lvp_auto_weights(offsets, bones, values, -1, b->positions, n, b->triangles, b->triangle_count, &s, &o,
	                       &diag) == lvp_error_invalid_size);
	free(offsets);
	free(bones);
	free(values);
	result_free(&full);
	free(b);
}

/* ---- errors -------------------------------------------------------------------------------------- */

static void test_error_paths_name_the_argument(void)
{
	builder *b = malloc(sizeof(builder));
	int32_t split;
	make_fingers(b, &split);
	int32_t n = b->vertex_count, f = b->triangle_count;
	int32_t offsets[1024], bones[4096];
	float values[4096];
	int64_t cap = 4096;
	lvp_skeleton s = skeleton_of(b), broken;
	lvp_auto_weights_options o = lvp_auto_weights_default_options(), bad;
	lvp_diagnostic d;
	memset(&d, 0, sizeof(d));
	const float *p = b->positions;
	const int32_t *t = b->triangles;
	CHECK(n < 1024);
	CHECK_ERROR(lvp_auto_weights(NULL, bones, values, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_null_argument,
	            "r_offsets", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, NULL, values, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_null_argument,
	            "r_bones", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, bones, NULL, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_null_argument,
	            "r_values", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, NULL, n, t, f, &s, &o, &d), &d, lvp_error_null_argument,
	            "positions", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, NULL, f, &s, &o, &d), &d, lvp_error_null_argument,
	            "triangles", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, 0, t, f, &s, &o, &d), &d, lvp_error_invalid_size,
	            "vertex_count", -1);
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, 0, &s, &o, &d), &d, lvp_error_invalid_size,
	            "triangle_count", -1);
	int64_t first_last = 0; /* the first corner that names the last vertex */
	while (t[first_last] != n - 1)
		++first_last;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n - 1, t, f, &s, &o, &d), &d,
	            lvp_error_index_out_of_range, "triangles", first_last);
	b->positions[10] = NAN;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_not_finite,
	            "positions", 10);
	b->positions[10] = 0.0f;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, NULL, &o, &d), &d, lvp_error_null_argument,
	            "skeleton", -1);
	broken = s, broken.bone_count = 0;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &broken, &o, &d), &d, lvp_error_invalid_size,
	            "skeleton.bone_count", -1);
	broken = s, broken.tails = NULL;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &broken, &o, &d), &d, lvp_error_null_argument,
	            "skeleton.tails", -1);
	b->heads[4] = INFINITY;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_not_finite,
	            "skeleton.heads", 4);
	b->heads[4] = 0.0f;
	b->rest_matrices[16 + 5] = 0.0f; /* bone 1's rest matrix loses its y axis */
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &o, &d), &d, lvp_error_singular_matrix,
	            "skeleton.rest_matrices", 1);
	b->rest_matrices[16 + 5] = 1.0f;
	const struct {
		const char *argument;
		float alpha, cos_max, min_weight;
		int visibility, max_influences;
	} options[] = {
	    {"options.alpha", 0.0f, 0.0f, 0.01f, 0, 4},          {"options.alpha", -1.0f, 0.0f, 0.01f, 0, 4},
	    {"options.alpha", NAN, 0.0f, 0.01f, 0, 4},           {"options.alpha", INFINITY, 0.0f, 0.01f, 0, 4},
	    {"options.visibility", 2.0f, 0.0f, 0.01f, 3, 4},     {"options.visibility", 2.0f, 0.0f, 0.01f, -1, 4},
	    {"options.normal_cos_max", 2.0f, 1.5f, 0.01f, 0, 4}, {"options.normal_cos_max", 2.0f, NAN, 0.01f, 0, 4},
	    {"options.max_influences", 2.0f, 0.0f, 0.01f, 0, -1}, {"options.min_weight", 2.0f, 0.0f, -0.1f, 0, 4},
	    {"options.min_weight", 2.0f, 0.0f, 1.5f, 0, 4},      {"options.min_weight", 2.0f, 0.0f, NAN, 0, 4},
	};
	for (size_t i = 0; i < sizeof(options) / sizeof(options[0]); ++i) {
		bad = o;
		bad.alpha = options[i].alpha, bad.normal_cos_max = options[i].cos_max, bad.min_weight = options[i].min_weight;
		bad.visibility = (lvp_visibility)options[i].visibility, bad.max_influences = options[i].max_influences;
		CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d,
		            lvp_error_invalid_option, options[i].argument, -1);
	}
	const int32_t bad_iterations[] = {-1, LVP_MAX_SMOOTHING_ITERATIONS + 1};
	for (size_t i = 0; i < 2; ++i) {
		bad = o;
		bad.smoothing_iterations = bad_iterations[i];
		CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d,
		            lvp_error_invalid_option, "options.smoothing_iterations", -1);
	}
	const float bad_lengths[] = {-1.0f, NAN, INFINITY};
	for (size_t i = 0; i < 3; ++i) {
		bad = o;
		bad.smoothing_length = bad_lengths[i];
		CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d,
		            lvp_error_invalid_option, "options.smoothing_length", -1);
	}
	const float bad_thickness[] = {-1.0f, NAN, INFINITY, 17.0f};
	for (size_t i = 0; i < 4; ++i) {
		bad = o;
		bad.smoothing_thickness = bad_thickness[i];
		CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d,
		            lvp_error_invalid_option, "options.smoothing_thickness", -1);
	}
	bad = o;
	bad.heat = 2;
	CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d, lvp_error_invalid_option,
	            "options.heat", -1);
	const int32_t bad_threads[2] = {0, LVP_MAX_THREADS + 1};
	for (int i = 0; i < 2; ++i) {
		bad = o;
		bad.thread_count = bad_threads[i];
		CHECK_ERROR(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, &bad, &d), &d,
		            lvp_error_invalid_option, "options.thread_count", -1);
	}
	/* NULL options are the defaults */
	CHECK_OK(lvp_auto_weights(offsets, bones, values, cap, p, n, t, f, &s, NULL, &d), d);
	CHECK(lvp_auto_weights(NULL, bones, values, cap, p, n, t, f, &s, &o, NULL) == lvp_error_null_argument);
	free(b);
}

int main(void)
{
	RUN(test_fingers_neighbour_bone_only_without_visibility);
	RUN(test_horn_tip_gets_rigid_fallback);
	RUN(test_matches_brute_force_reference);
	RUN(test_matches_brute_force_on_random_skeletons);
	RUN(test_inward_winding_is_detected);
	RUN(test_zero_length_bone_gets_no_weight);
	RUN(test_vertex_on_a_bone);
	RUN(test_degenerate_geometry_is_handled);
	RUN(test_smoothing_makes_weights_continuous);
	RUN(test_smoothing_keeps_separate_pieces_apart);
	RUN(test_smoothing_length_follows_the_resolution);
	RUN(test_smoothing_of_many_steps);
	RUN(test_smoothing_follows_the_thickness);
	RUN(test_smoothing_by_thickness_is_local);
	RUN(test_a_sliver_s_ends_share_one_row);
	RUN(test_heat_blends_by_the_skin_s_depth);
	RUN(test_facing_distance_gives_skin_to_the_bone_beneath);
	RUN(test_facing_counts_wholly_with_the_exact_test);
	RUN(test_bound);
	RUN(test_capacity_too_small_is_an_error);
	RUN(test_error_paths_name_the_argument);
	return check_failures() != 0;
}
