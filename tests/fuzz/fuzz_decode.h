/*
 * fuzz_decode.h - turns arbitrary bytes into a small skinned mesh and runs every entry point of
 * lvp.h on it. Shared by the libFuzzer target (fuzz_lvp.c) and the regression test that replays
 * every input that once crashed (tests/c/test_fuzz_regressions.c), so both decode the same bytes
 * the same way. Header-only: `./build.sh fuzz` compiles fuzz_lvp.c alone with the core.
 *
 * INPUT FORMAT (every read past the end yields zero bytes, so every input decodes)
 *
 *   byte 0: source. Even: a generated tube (valid, closed, skinned: the correction runs deep),
 *           then byte-driven corruptions. Odd: everything raw from the bytes (mostly invalid).
 *   generated: around, rings, bones, bend angles, then a corruption count and that many
 *           (target, index, value) edits of positions, indices, weights, heads, tails, matrices.
 *   raw:    vertex, triangle and bone counts, then positions, triangles, per-vertex influence
 *           lists, rest frames, heads, tails, posed frames.
 *   then, for both: how each count is passed (true, one less, zero, negative), options for
 *           bind, the map, two frames and automatic weights, and which optional buffers are
 *           NULL, aliased or given.
 *   Floats come from a one-byte code: most codes are small multiples of 1/32; the rest are NaN,
 *   infinities, huge, tiny, denormal, negative zero or four raw bytes.
 *
 * WHAT IS CHECKED (besides ASan/UBSan/LeakSanitizer, which stop at the first fault)
 *
 *   - every lvp_result is a valid enum value;
 *   - a failing call fills its diagnostic (argument named, message terminated and not empty) and
 *     leaves its outputs untouched (lvp.h CONVENTIONS);
 *   - a binding reports the counts it was bound with, regions in [-1, region_count) and a
 *     correction map in [0, 1];
 *   - lvp_correct's stats count at most max_iterations passes without fold-over for each attempt
 *     (one, and one more for each group given up: lvp.h, DEGRADING; with fold-over, the volume
 *     steps that follow each contact test have their own budget); lvp_auto_weights writes
 *     well-formed rows.
 *   A violation prints what went wrong and aborts, which libFuzzer records as a crash.
 *
 * Build switches: -DFUZZ_TRACE prints every call's result (how deep an input gets);
 * -DFUZZ_SKIP_FOLD_OVER turns fold-over off, to fuzz everything else while a fold-over bug is open.
 *
 * Sizes passed to the core never exceed the buffers given: the harness must not lie about a
 * buffer's size, since no library can detect that. Everything else may be wrong.
 */
#ifndef LVP_FUZZ_DECODE_H
#define LVP_FUZZ_DECODE_H

#include "lvp.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FUZZ_MAX_AROUND 8
#define FUZZ_MAX_RINGS 6
#define FUZZ_MAX_BONES 6
#define FUZZ_MAX_RAW_VERTICES 40
#define FUZZ_MAX_RAW_TRIANGLES 48
#define FUZZ_MAX_INFLUENCES 4

/* ---- reading bytes ------------------------------------------------------------------------ */

typedef struct fuzz_reader {
	const uint8_t *data;
	size_t size, position;
} fuzz_reader;

static uint8_t fuzz_byte(fuzz_reader *r)
{
	return r->position < r->size ? r->data[r->position++] : 0;
}

static uint32_t fuzz_u32(fuzz_reader *r)
{
	uint32_t v = 0;
	for (int i = 0; i < 4; ++i)
		v |= (uint32_t)fuzz_byte(r) << (8 * i);
	return v;
}

/* A float from a one-byte code: 0..0xDF are (code - 112) / 32, i.e. -3.5 .. 3.47 in steps that
 * make exact coincidences (shared planes, zero areas) common; the rest are the awkward values. */
static float fuzz_float(fuzz_reader *r)
{
	uint8_t code = fuzz_byte(r);
	if (code < 0xE0)
		return ((int)code - 112) / 32.0f;
	switch (code) {
	case 0xE0: return NAN;
	case 0xE1: return INFINITY;
	case 0xE2: return -INFINITY;
	case 0xE3: return 1e30f;
	case 0xE4: return -1e30f;
	case 0xE5: return 1e-40f; /* denormal */
	case 0xE6: return -0.0f;
	case 0xE7: return 3.4028235e38f;
	case 0xE8: return 1e-30f;
	case 0xE9: return 1e4f;
	default: break;
	}
	if (code < 0xF0) { /* 0xEA..0xEF: four raw bytes, any bit pattern */
		uint32_t bits = fuzz_u32(r);
		float f;
		memcpy(&f, &bits, sizeof(f));
		return f;
	}
	return (code - 0xF0) * 1e-6f; /* tiny, for nearly degenerate geometry */
}

/* An index into [0, count) most of the time; sometimes just outside it, or far outside. */
static int32_t fuzz_index(fuzz_reader *r, int32_t count)
{
	uint8_t code = fuzz_byte(r);
	if (code == 0xFF)
		return INT32_MAX;
	if (code == 0xFE)
		return INT32_MIN;
	if (code >= 0xF0)
		return (int32_t)(code - 0xF8); /* -8 .. 5 */
	return count > 0 ? code % (count + 1) : code; /* == count now and then */
}

/* How a count is passed to the core: mostly as is; sometimes wrong in a way that never claims
 * more than the buffer holds. */
static int32_t fuzz_count(fuzz_reader *r, int32_t count)
{
	switch (fuzz_byte(r) % 16) {
	case 13: return count > 0 ? count - 1 : count;
	case 14: return 0;
	case 15: return -1 - (int32_t)fuzz_byte(r);
	default: return count;
	}
}

/* ---- the decoded case -------------------------------------------------------------------- */

typedef struct fuzz_case {
	int32_t vertex_count, triangle_count, bone_count; /* the true sizes of the arrays */
	float *positions;                                 /* vertex_count*3 */
	int32_t *triangles;                               /* triangle_count*3 */
	int32_t *weight_offsets;                          /* vertex_count+1 */
	int32_t weight_capacity;                          /* entries in weight_bones/values */
	int32_t *weight_bones;
	float *weight_values;
	float *rest_matrices, *heads, *tails; /* bone_count*16, *3, *3 */
	int32_t *parents;                     /* bone_count: see fuzz_parents */
	float *posed;                         /* bone_count*16: posed bone frames */
	float *skin;                          /* bone_count*16: posed * rest^-1, or posed when singular */
	float *deformed;                      /* vertex_count*3: this frame's positions */
	float *frame_rest;                    /* vertex_count*3: shape-keyed rest, or unused */
	float *painted;                       /* vertex_count */
	int32_t *region_offsets;              /* bone_count+1 */
	int32_t region_capacity;
	int32_t *region_bones;
} fuzz_case;

static void *fuzz_alloc(size_t count, size_t size)
{
	void *p = calloc(count ? count : 1, size);
	if (!p)
		abort(); /* the inputs are tiny: running out of memory here is a harness bug */
	return p;
}

static void fuzz_case_free(fuzz_case *c)
{
	free(c->positions);
	free(c->triangles);
	free(c->weight_offsets);
	free(c->weight_bones);
	free(c->weight_values);
	free(c->rest_matrices);
	free(c->heads);
	free(c->tails);
	free(c->parents);
	free(c->posed);
	free(c->skin);
	free(c->deformed);
	free(c->frame_rest);
	free(c->painted);
	free(c->region_offsets);
	free(c->region_bones);
	memset(c, 0, sizeof(*c));
}

static void fuzz_case_allocate(fuzz_case *c)
{
	c->positions = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	c->triangles = fuzz_alloc((size_t)c->triangle_count * 3, sizeof(int32_t));
	c->weight_offsets = fuzz_alloc((size_t)c->vertex_count + 1, sizeof(int32_t));
	c->rest_matrices = fuzz_alloc((size_t)c->bone_count * 16, sizeof(float));
	c->heads = fuzz_alloc((size_t)c->bone_count * 3, sizeof(float));
	c->tails = fuzz_alloc((size_t)c->bone_count * 3, sizeof(float));
	c->parents = fuzz_alloc((size_t)c->bone_count, sizeof(int32_t));
	c->posed = fuzz_alloc((size_t)c->bone_count * 16, sizeof(float));
	c->skin = fuzz_alloc((size_t)c->bone_count * 16, sizeof(float));
	c->deformed = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	c->frame_rest = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	c->painted = fuzz_alloc((size_t)c->vertex_count, sizeof(float));
	c->region_offsets = fuzz_alloc((size_t)c->bone_count + 1, sizeof(int32_t));
}

/* Row-major 4x4 helpers in double, for building frames and skin matrices. */
static void fuzz_mat_mul(float *r_m, const float *a, const float *b)
{
	for (int i = 0; i < 4; ++i)
		for (int j = 0; j < 4; ++j) {
			double s = 0.0;
			for (int k = 0; k < 4; ++k)
				s += (double)a[4 * i + k] * b[4 * k + j];
			r_m[4 * i + j] = (float)s;
		}
}

/* Inverse by Gauss-Jordan; returns 0 when singular or not finite. */
static int fuzz_mat_inverse(float *r_m, const float *m)
{
	double a[4][8];
	for (int i = 0; i < 4; ++i)
		for (int j = 0; j < 8; ++j)
			a[i][j] = j < 4 ? m[4 * i + j] : (j - 4 == i);
	for (int c = 0; c < 4; ++c) {
		int p = c;
		for (int i = c + 1; i < 4; ++i)
			if (fabs(a[i][c]) > fabs(a[p][c]))
				p = i;
		if (!(fabs(a[p][c]) > 1e-30))
			return 0;
		for (int j = 0; j < 8; ++j) {
			double t = a[c][j];
			a[c][j] = a[p][j];
			a[p][j] = t;
		}
		double inv = 1.0 / a[c][c];
		for (int j = 0; j < 8; ++j)
			a[c][j] *= inv;
		for (int i = 0; i < 4; ++i)
			if (i != c) {
				double f = a[i][c];
				for (int j = 0; j < 8; ++j)
					a[i][j] -= f * a[c][j];
			}
	}
	for (int i = 0; i < 4; ++i)
		for (int j = 0; j < 4; ++j) {
			if (!isfinite(a[i][j + 4]))
				return 0;
			r_m[4 * i + j] = (float)a[i][j + 4];
		}
	return 1;
}

/* Rotation by `angle` about world axis `axis` (0, 1, 2) through `center`. */
static void fuzz_rotation_about(float *r_m, int axis, double angle, const float *center)
{
	double c = cos(angle), s = sin(angle);
	double rot[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
	int u = (axis + 1) % 3, v = (axis + 2) % 3;
	rot[u][u] = c, rot[u][v] = -s, rot[v][u] = s, rot[v][v] = c;
	memset(r_m, 0, 16 * sizeof(float));
	for (int i = 0; i < 3; ++i) {
		double t = center[i];
		for (int j = 0; j < 3; ++j) {
			r_m[4 * i + j] = (float)rot[i][j];
			t -= rot[i][j] * center[j];
		}
		r_m[4 * i + 3] = (float)t;
	}
	r_m[15] = 1.0f;
}

/* Linear blend skinning written out in the harness, for the deformed positions of a valid case
 * (so the frame does not depend on the core's own skinning having succeeded). */
static void fuzz_skin(fuzz_case *c)
{
	for (int32_t k = 0; k < c->vertex_count; ++k) {
		const float *p = c->positions + 3 * k;
		double acc[3] = {0, 0, 0}, sum = 0.0;
		for (int32_t e = c->weight_offsets[k]; e < c->weight_offsets[k + 1]; ++e) {
			const float *m = c->skin + 16 * c->weight_bones[e];
			double w = c->weight_values[e];
			sum += w;
			for (int i = 0; i < 3; ++i)
				acc[i] += w * ((double)m[4 * i] * p[0] + (double)m[4 * i + 1] * p[1] + (double)m[4 * i + 2] * p[2] +
				               m[4 * i + 3]);
		}
		for (int i = 0; i < 3; ++i)
			c->deformed[3 * k + i] = sum > 0.0 ? (float)(acc[i] / sum) : p[i];
	}
}

/* A closed tube along +Z (radius 0.5, length 2) on a chain of bones with linear weight bands:
 * valid input on which the whole method runs, for the corruptions to start from. */
static void fuzz_decode_generated(fuzz_case *c, fuzz_reader *r)
{
	int around = 3 + fuzz_byte(r) % (FUZZ_MAX_AROUND - 2);
	int rings = 2 + fuzz_byte(r) % (FUZZ_MAX_RINGS - 1);
	int bones = 1 + fuzz_byte(r) % FUZZ_MAX_BONES;
	c->vertex_count = around * rings + 2;
	c->triangle_count = 2 * around * (rings - 1) + 2 * around;
	c->bone_count = bones;
	c->weight_capacity = 2 * c->vertex_count;
	fuzz_case_allocate(c);
	c->weight_bones = fuzz_alloc((size_t)c->weight_capacity, sizeof(int32_t));
	c->weight_values = fuzz_alloc((size_t)c->weight_capacity, sizeof(float));
	const double length = 2.0, radius = 0.5;
	for (int i = 0; i < rings; ++i)
		for (int j = 0; j < around; ++j) {
			double angle = 6.283185307179586 * j / around;
			float *p = c->positions + 3 * (i * around + j);
			p[0] = (float)(radius * cos(angle)), p[1] = (float)(radius * sin(angle));
			p[2] = (float)(length * i / (rings - 1));
		}
	int32_t c0 = around * rings;
	c->positions[3 * (c0 + 1) + 2] = (float)length;
	int32_t *t = c->triangles;
	for (int i = 0; i + 1 < rings; ++i)
		for (int j = 0; j < around; ++j) {
			int32_t a0 = i * around + j, a1 = i * around + (j + 1) % around;
			*t++ = a0, *t++ = a1, *t++ = a1 + around;
			*t++ = a0, *t++ = a1 + around, *t++ = a0 + around;
		}
	for (int j = 0; j < around; ++j) {
		int32_t last = (rings - 1) * around;
		*t++ = c0, *t++ = (j + 1) % around, *t++ = j;
		*t++ = c0 + 1, *t++ = last + j, *t++ = last + (j + 1) % around;
	}
	double bone_length = length / bones, band = 0.5 * bone_length;
	int32_t used = 0;
	for (int32_t k = 0; k < c->vertex_count; ++k) {
		double z = c->positions[3 * k + 2];
		int32_t bone = 0;
		double w = 1.0;
		for (int32_t j = 1; j < bones; ++j) {
			double start = j * bone_length - 0.5 * band;
			if (z < start)
				break;
			bone = j;
			w = fmin((z - start) / band, 1.0);
		}
		c->weight_offsets[k] = used;
		if (w < 1.0)
			c->weight_bones[used] = bone - 1, c->weight_values[used++] = (float)(1.0 - w);
		if (w > 0.0)
			c->weight_bones[used] = bone, c->weight_values[used++] = (float)w;
	}
	c->weight_offsets[c->vertex_count] = used;
	for (int32_t b = 0; b < bones; ++b) {
		/* Blender's frame for a bone along +Z: local Y along the bone. */
		float *m = c->rest_matrices + 16 * b;
		m[0] = 1, m[6] = -1, m[9] = 1, m[15] = 1;
		m[11] = (float)(b * bone_length);
		c->heads[3 * b + 2] = (float)(b * bone_length);
		c->tails[3 * b + 2] = (float)((b + 1) * bone_length);
	}
	/* Bend every joint about world X by a byte's worth of angle, carried down the chain. */
	float motion[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
	for (int32_t b = 0; b < bones; ++b) {
		float turn[16], next[16], head[3];
		double angle = ((int)fuzz_byte(r) - 128) * (3.141592653589793 / 128.0);
		/* The head moves with the bones above it. */
		for (int i = 0; i < 3; ++i)
			head[i] = motion[4 * i] * c->heads[3 * b] + motion[4 * i + 1] * c->heads[3 * b + 1] +
			          motion[4 * i + 2] * c->heads[3 * b + 2] + motion[4 * i + 3];
		fuzz_rotation_about(turn, 0, angle, head);
		fuzz_mat_mul(next, turn, motion);
		memcpy(motion, next, sizeof(motion));
		memcpy(c->skin + 16 * b, motion, sizeof(motion));
		fuzz_mat_mul(c->posed + 16 * b, motion, c->rest_matrices + 16 * b);
	}
	fuzz_skin(c);
	memcpy(c->frame_rest, c->positions, (size_t)c->vertex_count * 3 * sizeof(float));
	/* Corruptions: each one edit of one array element. */
	int edits = fuzz_byte(r) % 8;
	for (int e = 0; e < edits; ++e) {
		uint8_t target = fuzz_byte(r) % 13;
		uint8_t at = fuzz_byte(r);
		switch (target) {
		case 0: c->positions[at % (c->vertex_count * 3)] = fuzz_float(r); break;
		case 1: c->triangles[at % (c->triangle_count * 3)] = fuzz_index(r, c->vertex_count); break;
		case 2:
			if (used > 0)
				c->weight_values[at % used] = fuzz_float(r);
			break;
		case 3:
			if (used > 0)
				c->weight_bones[at % used] = fuzz_index(r, c->bone_count);
			break;
		case 4: c->heads[at % (bones * 3)] = fuzz_float(r); break;
		case 5: c->tails[at % (bones * 3)] = fuzz_float(r); break;
		case 6: c->rest_matrices[at % (bones * 16)] = fuzz_float(r); break;
		case 7: c->posed[at % (bones * 16)] = fuzz_float(r); break;
		case 8: c->deformed[at % (c->vertex_count * 3)] = fuzz_float(r); break;
		case 9: /* collapse a triangle onto one corner (zero area, repeated vertex) */
		{
			int32_t f = at % c->triangle_count;
			c->triangles[3 * f + 1] = c->triangles[3 * f];
			break;
		}
		case 10: /* collapse a whole ring onto its first vertex (many equal centroids) */
		{
			int32_t ring = at % rings;
			for (int j = 1; j < around; ++j)
				memcpy(c->positions + 3 * (ring * around + j), c->positions + 3 * ring * around, 3 * sizeof(float));
			break;
		}
		case 11: /* scale the rest mesh and the frame: tiny or huge models */
		{
			float scale = fuzz_float(r);
			for (int32_t i = 0; i < c->vertex_count * 3; ++i) {
				c->positions[i] *= scale;
				c->deformed[i] *= scale;
			}
			break;
		}
		default: /* turn every triangle inside out (inward winding, negative volume) */
			for (int32_t f = 0; f < c->triangle_count; ++f) {
				int32_t swap = c->triangles[3 * f + 1];
				c->triangles[3 * f + 1] = c->triangles[3 * f + 2];
				c->triangles[3 * f + 2] = swap;
			}
			break;
		}
	}
}

/* Everything from the bytes: counts, coordinates, indices, influence lists, frames. */
static void fuzz_decode_raw(fuzz_case *c, fuzz_reader *r)
{
	c->vertex_count = fuzz_byte(r) % (FUZZ_MAX_RAW_VERTICES + 1);
	c->triangle_count = fuzz_byte(r) % (FUZZ_MAX_RAW_TRIANGLES + 1);
	c->bone_count = fuzz_byte(r) % (FUZZ_MAX_BONES + 1);
	fuzz_case_allocate(c);
	for (int32_t i = 0; i < c->vertex_count * 3; ++i)
		c->positions[i] = fuzz_float(r);
	for (int32_t i = 0; i < c->triangle_count * 3; ++i)
		c->triangles[i] = fuzz_index(r, c->vertex_count);
	/* Influence lists: a count per vertex, then (bone, weight) pairs. */
	c->weight_capacity = c->vertex_count * FUZZ_MAX_INFLUENCES;
	c->weight_bones = fuzz_alloc((size_t)c->weight_capacity, sizeof(int32_t));
	c->weight_values = fuzz_alloc((size_t)c->weight_capacity, sizeof(float));
	int32_t used = 0;
	for (int32_t k = 0; k < c->vertex_count; ++k) {
		int n = fuzz_byte(r) % (FUZZ_MAX_INFLUENCES + 1);
		c->weight_offsets[k] = used;
		for (int i = 0; i < n; ++i) {
			c->weight_bones[used] = fuzz_index(r, c->bone_count);
			c->weight_values[used++] = fuzz_float(r);
		}
	}
	c->weight_offsets[c->vertex_count] = used;
	/* A broken CSR now and then: an inner offset out of order or negative. Never above the
	 * arrays' capacity: with the vertex count passed one short, that offset becomes the last
	 * one, which tells the core how many influences the arrays hold. */
	if (c->vertex_count > 1 && fuzz_byte(r) % 8 == 0) {
		int32_t value = (int32_t)fuzz_byte(r) - 128;
		c->weight_offsets[1 + fuzz_byte(r) % (c->vertex_count - 1)] =
		    value < c->weight_capacity ? value : c->weight_capacity;
	}
	if (fuzz_byte(r) % 16 == 0)
		c->weight_offsets[0] = 1;
	for (int32_t b = 0; b < c->bone_count; ++b) {
		float *m = c->rest_matrices + 16 * b;
		for (int i = 0; i < 3; ++i)
			c->heads[3 * b + i] = fuzz_float(r);
		for (int i = 0; i < 3; ++i)
			c->tails[3 * b + i] = fuzz_float(r);
		switch (fuzz_byte(r) % 4) {
		case 0: /* translation to the head */
			m[0] = m[5] = m[10] = m[15] = 1;
			m[3] = c->heads[3 * b], m[7] = c->heads[3 * b + 1], m[11] = c->heads[3 * b + 2];
			break;
		case 1: /* a rotation about a world axis, at the head */
			fuzz_rotation_about(m, fuzz_byte(r) % 3, fuzz_float(r), c->heads + 3 * b);
			break;
		case 2: /* any 16 numbers: singular, scaled, sheared, not finite */
			for (int i = 0; i < 16; ++i)
				m[i] = fuzz_float(r);
			break;
		default: /* all zero: singular */
			break;
		}
		float *p = c->posed + 16 * b;
		switch (fuzz_byte(r) % 4) {
		case 0: memcpy(p, m, 16 * sizeof(float)); break;
		case 1: {
			float turn[16];
			fuzz_rotation_about(turn, fuzz_byte(r) % 3, fuzz_float(r), c->heads + 3 * b);
			fuzz_mat_mul(p, turn, m);
			break;
		}
		case 2:
			for (int i = 0; i < 16; ++i)
				p[i] = fuzz_float(r);
			break;
		default: break; /* zero: a bone scaled to nothing */
		}
	}
	for (int32_t b = 0; b < c->bone_count; ++b) {
		float inverse[16];
		if (fuzz_mat_inverse(inverse, c->rest_matrices + 16 * b))
			fuzz_mat_mul(c->skin + 16 * b, c->posed + 16 * b, inverse);
		else
			memcpy(c->skin + 16 * b, c->posed + 16 * b, 16 * sizeof(float));
	}
	/* This frame: skinned by the harness when the weights allow it, else raw. */
	int valid_weights = c->weight_offsets[0] == 0;
	for (int32_t k = 0; k < c->vertex_count && valid_weights; ++k) {
		valid_weights &= c->weight_offsets[k] <= c->weight_offsets[k + 1];
		for (int32_t e = c->weight_offsets[k]; e < c->weight_offsets[k + 1] && valid_weights; ++e)
			valid_weights &= e >= 0 && e < used && c->weight_bones[e] >= 0 && c->weight_bones[e] < c->bone_count;
	}
	if (valid_weights && fuzz_byte(r) % 2 == 0)
		fuzz_skin(c);
	else
		for (int32_t i = 0; i < c->vertex_count * 3; ++i)
			c->deformed[i] = c->positions[i] + fuzz_float(r);
	for (int32_t i = 0; i < c->vertex_count * 3; ++i)
		c->frame_rest[i] = c->positions[i];
}

/* ---- contract checks ---------------------------------------------------------------------- */

static void fuzz_violation(const char *call, const char *what)
{
	fprintf(stderr, "fuzz: contract violation in %s: %s\n", call, what);
	abort();
}

/* A result must be a valid enum value, and a failure must come with a full diagnostic. */
static void fuzz_check_result(const char *call, lvp_result result, const lvp_diagnostic *diag)
{
#ifdef FUZZ_TRACE /* -DFUZZ_TRACE: see how deep an input gets */
	fprintf(stderr, "  %s -> %s%s%s\n", call, lvp_result_name(result), result ? ": " : "", result ? diag->message : "");
#endif
	if ((unsigned)result >= (unsigned)lvp_result_count)
		fuzz_violation(call, "result outside the lvp_result enum");
	if (strlen(lvp_result_name(result)) == 0)
		fuzz_violation(call, "empty result name");
	if (result == lvp_success)
		return;
	if (!diag->argument)
		fuzz_violation(call, "failure without diagnostic argument");
	if (!memchr(diag->message, '\0', sizeof(diag->message)))
		fuzz_violation(call, "diagnostic message not terminated");
	if (diag->message[0] == '\0')
		fuzz_violation(call, "empty diagnostic message");
}

/* A call given a NULL where a binding belongs must fail, and say so. */
static void fuzz_check_refused(const char *call, lvp_result result, const lvp_diagnostic *diag)
{
	if (result == lvp_success)
		fuzz_violation(call, "accepted a NULL binding");
	fuzz_check_result(call, result, diag);
}

#define FUZZ_CANARY 0xA5

static void fuzz_fill_canary(void *p, size_t bytes)
{
	memset(p, FUZZ_CANARY, bytes);
}

static void fuzz_check_canary(const char *call, const void *p, size_t bytes)
{
	const uint8_t *b = p;
	for (size_t i = 0; i < bytes; ++i)
		if (b[i] != FUZZ_CANARY)
			fuzz_violation(call, "an output was written although the call failed");
}

/* A fresh diagnostic, filled so that a failure that forgets to fill it is seen. */
static lvp_diagnostic fuzz_diag(void)
{
	lvp_diagnostic d;
	d.argument = NULL;
	d.index = 12345;
	d.message[0] = '\0';
	return d;
}

/* ---- options ------------------------------------------------------------------------------ */

/* A float option: the default, a small value, or anything at all (negative, NaN, huge). */
static float fuzz_option_float(fuzz_reader *r, float fallback)
{
	uint8_t mode = fuzz_byte(r) % 4;
	if (mode == 0)
		return fallback;
	if (mode == 1)
		return (fuzz_byte(r) % 16) * 0.25f;
	return fuzz_float(r);
}

static void fuzz_decode_map(lvp_map_options *map, fuzz_case *c, fuzz_reader *r, int32_t bone_count_passed)
{
	uint8_t kind = fuzz_byte(r);
	map->map = (lvp_map)(kind % 7); /* 5 and 6 are not maps */
	if (kind == 0xFF)
		map->map = (lvp_map)-1;
	map->alpha = fuzz_option_float(r, map->alpha);
	map->beta = fuzz_option_float(r, map->beta);
	uint8_t flags = fuzz_byte(r);
	map->painted = NULL;
	if (flags & 1) {
		for (int32_t k = 0; k < c->vertex_count; ++k)
			c->painted[k] = (flags & 2) ? fuzz_float(r) : (float)(fuzz_byte(r) % 5) * 0.25f;
		map->painted = c->painted;
	}
	map->region_bone_offsets = NULL;
	map->region_bones = NULL;
	/* A per-region restriction of the distance term: offsets sized by the bone count passed
	 * (what the core reads), a list sized by its last offset. */
	if ((flags & 4) && bone_count_passed >= 0 && bone_count_passed <= c->bone_count) {
		int32_t total = 0;
		c->region_offsets[0] = 0;
		for (int32_t s = 0; s < bone_count_passed; ++s) {
			total += fuzz_byte(r) % 3;
			c->region_offsets[s + 1] = total;
		}
		if ((flags & 8) && bone_count_passed > 1) /* out of order */
			c->region_offsets[1 + fuzz_byte(r) % (bone_count_passed - 1)] = (int32_t)fuzz_byte(r) - 100;
		if (flags & 16)
			c->region_offsets[0] = (int32_t)(fuzz_byte(r) % 3) - 1;
		free(c->region_bones);
		c->region_capacity = total;
		c->region_bones = fuzz_alloc((size_t)total, sizeof(int32_t));
		for (int32_t i = 0; i < total; ++i)
			c->region_bones[i] = fuzz_index(r, c->bone_count);
		map->region_bone_offsets = c->region_offsets;
		map->region_bones = (flags & 32) ? NULL : c->region_bones; /* one of the two NULL */
	}
#ifdef FUZZ_TRACE
	fprintf(stderr, "  map %d alpha %g beta %g painted %s regions %s\n", (int)map->map, (double)map->alpha,
	        (double)map->beta, map->painted ? "yes" : "no", map->region_bone_offsets ? "yes" : "no");
#endif
}

/* Rigid spaces (lvp_frame_options.rigid_space): none, uneven, singular, not finite. */
static const float fuzz_rigid_spaces[3][16] = {
    {1.3f, 0.2f, 0, 5, 0, 0.8f, 0, -2, 0, 0, 1, 0, 0, 0, 0, 1},
    {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1},
    {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, INFINITY, 0, 0, 0, 0, 1},
};

static lvp_frame_options fuzz_decode_frame(fuzz_reader *r)
{
	lvp_frame_options f = lvp_frame_default_options();
	uint8_t iterations = fuzz_byte(r);
	if (iterations % 4 != 0)
		f.max_iterations = (int32_t)(iterations % 12) - 1; /* -1 .. 10 */
	f.tolerance = fuzz_option_float(r, f.tolerance);
	/* One byte, as before rigid_space existed, so that the corpus decodes to the same cases. */
	uint8_t flags = fuzz_byte(r);
	f.fold_over = flags % 2;
	if ((flags >> 1) % 4 != 0)
		f.rigid_space = fuzz_rigid_spaces[(flags >> 1) % 4 - 1];
	/* A displacement limit (lvp.h, DEGRADING) from bits of the same byte: tiny (every group given
	 * up), about a mesh's size, or invalid. */
	uint8_t limit = (uint8_t)((flags >> 3) & 7);
	f.displacement_limit = limit == 1 ? 1e-4f : limit == 2 ? 0.5f : limit == 3 && (flags & 0x80) ? -1.0f : 0.0f;
	return f;
}

/* ---- the run ------------------------------------------------------------------------------ */

/* Checks what a live binding reports about itself. */
static void fuzz_check_binding(lvp_binding *binding, int32_t vertex_count, int32_t triangle_count)
{
	if (lvp_vertex_count(binding) != vertex_count || lvp_triangle_count(binding) != triangle_count)
		fuzz_violation("lvp_vertex_count/lvp_triangle_count", "counts differ from the ones bound");
	int32_t regions = lvp_region_count(binding);
	if (regions < 1 || regions > (lvp_bone_count(binding) > 1 ? lvp_bone_count(binding) : 1))
		fuzz_violation("lvp_region_count", "region count out of range");
	int32_t *vertex_regions = fuzz_alloc((size_t)vertex_count, sizeof(int32_t));
	int32_t *triangle_regions = fuzz_alloc((size_t)triangle_count, sizeof(int32_t));
	float *map = fuzz_alloc((size_t)vertex_count, sizeof(float));
	lvp_get_segmentation(binding, vertex_regions, NULL);
	lvp_get_segmentation(binding, NULL, triangle_regions);
	lvp_get_segmentation(binding, vertex_regions, triangle_regions);
	lvp_get_segmentation(binding, NULL, NULL);
	for (int32_t k = 0; k < vertex_count; ++k)
		if (vertex_regions[k] < -1 || vertex_regions[k] >= regions)
			fuzz_violation("lvp_get_segmentation", "vertex region out of range");
	for (int32_t f = 0; f < triangle_count; ++f)
		if (triangle_regions[f] < -1 || triangle_regions[f] >= regions)
			fuzz_violation("lvp_get_segmentation", "triangle region out of range");
	lvp_get_correction_map(binding, map);
	for (int32_t k = 0; k < vertex_count; ++k)
		/* The core rounds each value to float before dividing by the largest one, so 1 + 1 ulp
		 * is tolerated; anything more (or not a number) is a wrong map. */
		if (!(map[k] >= 0.0f && map[k] <= 1.0f + 1e-6f)) {
			char what[96];
			snprintf(what, sizeof(what), "map[%d] = %.9g, outside [0, 1]", (int)k, (double)map[k]);
			fuzz_violation("lvp_get_correction_map", what);
		}
	free(vertex_regions);
	free(triangle_regions);
	free(map);
}

/* The largest magnitude among `values`; infinity when one of them is NaN. */
static float fuzz_largest(const float *values, int64_t count)
{
	float largest = 0.0f;
	for (int64_t i = 0; i < count; ++i) {
		if (isnan(values[i]))
			return INFINITY;
		if (fabsf(values[i]) > largest)
			largest = fabsf(values[i]);
	}
	return largest;
}

/* Inputs of an ordinary scene: every coordinate and matrix entry within +-1e4. On those, a
 * successful frame must not write NaN or infinity into the artist's mesh. */
static int fuzz_ordinary_scale(const fuzz_case *c)
{
	float largest = fuzz_largest(c->positions, (int64_t)c->vertex_count * 3);
	float deformed = fuzz_largest(c->deformed, (int64_t)c->vertex_count * 3);
	float rest = fuzz_largest(c->rest_matrices, (int64_t)c->bone_count * 16);
	float posed = fuzz_largest(c->posed, (int64_t)c->bone_count * 16);
	float heads = fuzz_largest(c->heads, (int64_t)c->bone_count * 3);
	float tails = fuzz_largest(c->tails, (int64_t)c->bone_count * 3);
	float values[5] = {deformed, rest, posed, heads, tails};
	for (int i = 0; i < 5; ++i)
		largest = values[i] > largest ? values[i] : largest;
	return largest <= 1e4f;
}

/* Grows the box lo..hi by `count` points. */
static void fuzz_grow_box(double *lo, double *hi, const float *points, int32_t count)
{
	for (int32_t k = 0; k < count; ++k)
		for (int i = 0; i < 3; ++i) {
			lo[i] = fmin(lo[i], points[3 * k + i]);
			hi[i] = fmax(hi[i], points[3 * k + i]);
		}
}

/* The size of the scene a frame works in: the diagonal of the box around the rest, deformed and
 * frame-rest points and the bones (fold-over moves skin towards bones, wherever they are). */
static double fuzz_scene_size(const fuzz_case *c, int32_t vertex_count, const float *frame_rest)
{
	double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
	fuzz_grow_box(lo, hi, c->positions, vertex_count);
	fuzz_grow_box(lo, hi, c->deformed, vertex_count);
	if (frame_rest)
		fuzz_grow_box(lo, hi, frame_rest, vertex_count);
	fuzz_grow_box(lo, hi, c->heads, c->bone_count);
	fuzz_grow_box(lo, hi, c->tails, c->bone_count);
	double d2 = 0.0;
	for (int i = 0; i < 3; ++i)
		d2 += hi[i] > lo[i] ? (hi[i] - lo[i]) * (hi[i] - lo[i]) : 0.0;
	return sqrt(d2);
}

/* One frame through lvp_correct, with outputs chosen by `how`, checking the failure contract. */
static void fuzz_correct(lvp_binding *binding, fuzz_case *c, uint8_t how, const lvp_frame_options *options)
{
	size_t bytes = (size_t)c->vertex_count * 3 * sizeof(float);
	float *positions = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	float *out = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	float *offsets = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	float *before = fuzz_alloc((size_t)c->vertex_count * 3, sizeof(float));
	memcpy(positions, c->deformed, bytes);
	memcpy(before, c->deformed, bytes);
	fuzz_fill_canary(out, bytes);
	fuzz_fill_canary(offsets, bytes);
	int in_place = how & 1;
	float *r_positions = (how & 2) ? NULL : (in_place ? positions : out);
	float *r_offsets = (how & 4) ? offsets : NULL;
	const float *bones = (how & 8) ? NULL : c->posed;
	const float *rest = (how & 16) ? c->frame_rest : NULL;
	const lvp_frame_options *frame = (how & 32) ? NULL : options;
	lvp_frame_stats stats;
	lvp_diagnostic diag = fuzz_diag();
	lvp_result result = lvp_correct(r_positions, r_offsets, binding, positions, bones, rest, frame,
	                                (how & 64) ? NULL : &stats, &diag);
	fuzz_check_result("lvp_correct", result, &diag);
#ifdef FUZZ_TRACE
	if (result == lvp_success && !(how & 64))
		fprintf(stderr, "  how %d iterations %d folded %d before %.17g after %.17g\n", how, (int)stats.iterations,
		        (int)stats.folded_vertices, stats.volume_before, stats.volume_after);
#endif
	if (result != lvp_success) {
		if (!in_place || !r_positions)
			fuzz_check_canary("lvp_correct r_positions", out, bytes);
		if (memcmp(positions, before, bytes) != 0)
			fuzz_violation("lvp_correct", "positions changed although the call failed");
		if (r_offsets)
			fuzz_check_canary("lvp_correct r_offsets", offsets, bytes);
	} else {
		if (fuzz_ordinary_scale(c)) {
			int32_t n = lvp_vertex_count(binding);
			const float *written[2] = {r_positions, r_offsets};
			for (int w = 0; w < 2; ++w)
				if (written[w] && !isfinite(fuzz_largest(written[w], (int64_t)n * 3)))
					fuzz_violation("lvp_correct", "NaN or infinity written for ordinary finite input");
			/* A volume correction moves skin by about the flesh it restores, fold-over by at
			 * most the way to a bone: a vertex sent a hundred times the size of the whole
			 * scene away means the iteration diverged. */
			double size = fuzz_scene_size(c, n, rest);
			double moved = 0.0;
			for (int32_t i = 0; i < 3 * n; ++i) {
				if (r_offsets)
					moved = fmax(moved, fabs(r_offsets[i]));
				else if (r_positions)
					moved = fmax(moved, fabs((double)r_positions[i] - before[i]));
			}
			if (moved > 100.0 * size + 1e-3) {
				char what[160];
				snprintf(what, sizeof(what), "a vertex moved by %g in a scene of size %g (diverged)", moved, size);
				fuzz_violation("lvp_correct", what);
			}
		}
	}
	if (result == lvp_success && !(how & 64)) {
		int32_t cap = frame ? frame->max_iterations : lvp_frame_default_options().max_iterations;
		/* Fold-over alternates contact tests with volume steps that each have their own
		 * max_iterations (csrc/correction.c): only frames without it are held to the cap. */
		int fold = frame ? frame->fold_over : lvp_frame_default_options().fold_over;
		/* Each attempt after giving a group up (lvp.h, DEGRADING) is a volume correction with its
		 * own budget too. */
		int64_t budget = (int64_t)cap * (1 + (int64_t)stats.given_up_regions);
		if (stats.iterations < 0 || (!fold && stats.iterations > budget)) {
			char what[160];
			snprintf(what, sizeof(what),
			         "stats.iterations = %d, max_iterations = %d, given_up_regions = %d, fold_over = %d",
			         (int)stats.iterations, (int)cap, (int)stats.given_up_regions,
			         frame ? (int)frame->fold_over : 0);
			fuzz_violation("lvp_correct", what);
		}
	}
	/* And the same frame measured without correcting. */
	double *changes = fuzz_alloc((size_t)lvp_region_count(binding), sizeof(double));
	double *references = fuzz_alloc((size_t)lvp_region_count(binding), sizeof(double));
	diag = fuzz_diag();
	result = lvp_region_volume_changes(changes, (how & 128) ? NULL : references, binding, c->deformed, bones, rest,
	                                   &diag);
	fuzz_check_result("lvp_region_volume_changes", result, &diag);
	free(changes);
	free(references);
	free(positions);
	free(out);
	free(offsets);
	free(before);
}

/* The bones' parents, from the heads so that the corpus decodes as before: a bone hangs from the one
 * before it where its head's x is positive, from the first where it is negative, from none at 0 or
 * NaN; with flag 0x10 none are given. */
static const int32_t *fuzz_parents(fuzz_case *c, int32_t bone_count, uint8_t flags)
{
	if (flags & 0x10)
		return NULL;
	for (int32_t b = 0; b < bone_count; ++b) {
		float x = c->heads[3 * b];
		c->parents[b] = b == 0 ? -1 : x > 0.0f ? b - 1 : x < 0.0f ? 0 : -1;
	}
	return c->parents;
}

/* Binds with the given weights and runs frames, a map change and more frames. */
static void fuzz_bind_and_run(fuzz_case *c, fuzz_reader *r, const lvp_weights *weights, int32_t vertex_count,
                              int32_t triangle_count, int32_t bone_count)
{
	lvp_skeleton skeleton = {bone_count, c->rest_matrices, c->heads, c->tails, NULL};
	uint8_t flags = fuzz_byte(r);
	if (flags & 0x10)
		skeleton.rest_matrices = NULL;
	skeleton.parents = bone_count <= c->bone_count ? fuzz_parents(c, bone_count, flags) : NULL;
	lvp_bind_options options = lvp_bind_default_options();
	options.mode = (flags & 1) ? LVP_MODE_GLOBAL : LVP_MODE_LOCAL;
	if ((flags & 0x60) == 0x60)
		options.mode = (lvp_mode)2; /* not a mode */
	uint8_t threads = fuzz_byte(r);
	/* Mostly one thread (fast); sometimes two or three, or an invalid count. */
	options.thread_count = threads < 200   ? 1
	                       : threads < 240 ? 2 + threads % 2
	                                       : (threads % 2 ? 0 : LVP_MAX_THREADS + 1);
	/* A bulge width (lvp.h, BULGE WIDTH) from the same byte, so that the corpus decodes as before. */
	options.bulge_width = threads % 16 == 5 ? 1.0f : threads % 16 == 6 ? 2.5f : threads % 64 == 7 ? NAN : 0.0f;
	fuzz_decode_map(&options.map, c, r, bone_count);
	lvp_binding *binding = NULL;
	lvp_diagnostic diag = fuzz_diag();
	if ((flags & 0x80) && (flags & 0x60) == 0x40) {
		/* The calls that take a binding must refuse a missing one. */
		lvp_frame_options frame = lvp_frame_default_options();
		float out[3];
		double change;
		lvp_result missing = lvp_bind(NULL, c->positions, vertex_count, c->triangles, triangle_count, weights,
		                              &skeleton, &options, &diag);
		fuzz_check_refused("lvp_bind(NULL)", missing, &diag);
		diag = fuzz_diag();
		missing = lvp_correct(out, NULL, NULL, c->deformed, c->posed, NULL, &frame, NULL, &diag);
		fuzz_check_refused("lvp_correct(NULL)", missing, &diag);
		diag = fuzz_diag();
		missing = lvp_region_volume_changes(&change, NULL, NULL, c->deformed, c->posed, NULL, &diag);
		fuzz_check_refused("lvp_region_volume_changes(NULL)", missing, &diag);
		diag = fuzz_diag();
		missing = lvp_set_map(NULL, &options.map, &diag);
		fuzz_check_refused("lvp_set_map(NULL)", missing, &diag);
		lvp_free(NULL);
		diag = fuzz_diag();
	}
	lvp_result result = lvp_bind(&binding, c->positions, vertex_count, c->triangles, triangle_count,
	                             (flags & 2) ? NULL : weights, (flags & 4) ? NULL : &skeleton,
	                             (flags & 8) ? NULL : &options, &diag);
	fuzz_check_result("lvp_bind", result, &diag);
	if (result != lvp_success) {
		if (binding)
			fuzz_violation("lvp_bind", "a binding was returned with a failure");
		return;
	}
	if (!binding)
		fuzz_violation("lvp_bind", "success without a binding");
	fuzz_check_binding(binding, vertex_count, triangle_count);
	lvp_frame_options first = fuzz_decode_frame(r), second = fuzz_decode_frame(r);
	first.fold_over = 1;
	second.fold_over = 0;
#ifdef FUZZ_SKIP_FOLD_OVER /* -DFUZZ_SKIP_FOLD_OVER: fuzz the rest while a fold-over bug is open */
	first.fold_over = 0;
#endif
	fuzz_correct(binding, c, fuzz_byte(r), &first);
	fuzz_correct(binding, c, fuzz_byte(r), &second);
	/* An artist changes the map: then the same frames again. */
	lvp_map_options map = options.map;
	fuzz_decode_map(&map, c, r, bone_count);
	float *map_before = fuzz_alloc((size_t)vertex_count, sizeof(float));
	float *map_after = fuzz_alloc((size_t)vertex_count, sizeof(float));
	lvp_get_correction_map(binding, map_before);
	diag = fuzz_diag();
	result = lvp_set_map(binding, fuzz_byte(r) % 16 == 0 ? NULL : &map, &diag);
	fuzz_check_result("lvp_set_map", result, &diag);
	lvp_get_correction_map(binding, map_after);
	if (result != lvp_success && memcmp(map_before, map_after, (size_t)vertex_count * sizeof(float)) != 0)
		fuzz_violation("lvp_set_map", "the map changed although the call failed");
	free(map_before);
	free(map_after);
	fuzz_check_binding(binding, vertex_count, triangle_count);
	fuzz_correct(binding, c, fuzz_byte(r), &first);
	fuzz_correct(binding, c, fuzz_byte(r), &second);
	lvp_free(binding);
}

/* Decodes `data` and runs every entry point. Never returns early on bad data: the point is
 * that the core must say no cleanly. */
static void fuzz_run(const uint8_t *data, size_t size)
{
	fuzz_reader reader = {data, size, 0};
	fuzz_reader *r = &reader;
	fuzz_case c;
	memset(&c, 0, sizeof(c));
	if (fuzz_byte(r) % 2 == 0)
		fuzz_decode_generated(&c, r);
	else
		fuzz_decode_raw(&c, r);
	int32_t vertex_count = fuzz_count(r, c.vertex_count);
	int32_t triangle_count = fuzz_count(r, c.triangle_count);
	int32_t bone_count = fuzz_count(r, c.bone_count);
	lvp_weights weights = {c.weight_offsets, c.weight_bones, c.weight_values};
	size_t position_bytes = (size_t)c.vertex_count * 3 * sizeof(float);
	lvp_diagnostic diag;
	lvp_result result;

	/* Mesh geometry. */
	double volume;
	fuzz_fill_canary(&volume, sizeof(volume));
	diag = fuzz_diag();
	result = lvp_mesh_volume(&volume, c.positions, vertex_count, c.triangles, triangle_count, &diag);
	fuzz_check_result("lvp_mesh_volume", result, &diag);
	if (result != lvp_success)
		fuzz_check_canary("lvp_mesh_volume", &volume, sizeof(volume));
	float *vectors = fuzz_alloc((size_t)c.vertex_count * 3, sizeof(float));
	fuzz_fill_canary(vectors, position_bytes);
	diag = fuzz_diag();
	result = lvp_volume_gradient(vectors, c.positions, vertex_count, c.triangles, triangle_count, &diag);
	fuzz_check_result("lvp_volume_gradient", result, &diag);
	if (result != lvp_success)
		fuzz_check_canary("lvp_volume_gradient", vectors, position_bytes);
	fuzz_fill_canary(vectors, position_bytes);
	diag = fuzz_diag();
	result = lvp_vertex_normals(vectors, c.positions, vertex_count, c.triangles, triangle_count, &diag);
	fuzz_check_result("lvp_vertex_normals", result, &diag);
	if (result != lvp_success)
		fuzz_check_canary("lvp_vertex_normals", vectors, position_bytes);

	/* Skinning, both kinds, from the skin matrices. */
	float *skinned = fuzz_alloc((size_t)c.vertex_count * 3, sizeof(float));
	for (int dq = 0; dq < 2; ++dq) {
		fuzz_fill_canary(skinned, position_bytes);
		diag = fuzz_diag();
		uint8_t nulls = fuzz_byte(r);
		const lvp_weights *w = nulls % 16 == 1 ? NULL : &weights;
		const float *m = nulls % 16 == 2 ? NULL : c.skin;
		result = dq ? lvp_skin_dual_quaternion(skinned, c.positions, vertex_count, w, m, bone_count, &diag)
		            : lvp_skin_linear(skinned, c.positions, vertex_count, w, m, bone_count, &diag);
		fuzz_check_result(dq ? "lvp_skin_dual_quaternion" : "lvp_skin_linear", result, &diag);
		if (result != lvp_success)
			fuzz_check_canary(dq ? "lvp_skin_dual_quaternion" : "lvp_skin_linear", skinned, position_bytes);
	}

	/* Automatic weights, then a binding with them. */
	lvp_skeleton skeleton = {bone_count, c.rest_matrices, c.heads, c.tails, NULL};
	lvp_auto_weights_options auto_options = lvp_auto_weights_default_options();
	uint8_t auto_flags = fuzz_byte(r);
	auto_options.alpha = fuzz_option_float(r, auto_options.alpha);
	auto_options.visibility = (lvp_visibility)(fuzz_byte(r) % 4); /* 3 is not a visibility */
	auto_options.normal_cos_max = fuzz_option_float(r, auto_options.normal_cos_max);
	auto_options.max_influences = (int32_t)(fuzz_byte(r) % 8) - 1;
	auto_options.min_weight = fuzz_option_float(r, auto_options.min_weight);
	/* Smoothing from bits of the flags already read, so that the bytes after them decode as before. */
	uint8_t smoothing = (uint8_t)((auto_flags >> 4) & 3);
	if (smoothing == 1)
		auto_options.smoothing_iterations = 3;
	else if (smoothing == 2 && (auto_flags & 128))
		auto_options.smoothing_thickness = auto_options.alpha; /* any float the fuzzer gave, some invalid */
	else if (smoothing == 2)
		auto_options.smoothing_length = auto_options.alpha;
	else if (smoothing == 3)
		auto_options.smoothing_iterations = (auto_flags & 64) ? -1 : LVP_MAX_SMOOTHING_ITERATIONS;
	/* Bone heat, on one thread or two, from two more bits of the same flags. */
	auto_options.heat = (auto_flags >> 1) & 1;
	auto_options.thread_count = (auto_flags & 4) ? 2 : 1;
	const lvp_auto_weights_options *auto_used = (auto_flags & 1) ? NULL : &auto_options;
	int64_t bound = lvp_auto_weights_bound(vertex_count, bone_count, auto_used);
	int32_t *auto_offsets = fuzz_alloc((size_t)c.vertex_count + 1, sizeof(int32_t));
	int32_t *auto_bones = NULL;
	float *auto_values = NULL;
	if (bound >= 0 && bound <= (int64_t)(c.vertex_count + 1) * (FUZZ_MAX_BONES + 1)) {
		int64_t capacity = (auto_flags & 6) == 6 ? bound / 2 : bound; /* sometimes too small */
		auto_bones = fuzz_alloc((size_t)capacity, sizeof(int32_t));
		auto_values = fuzz_alloc((size_t)capacity, sizeof(float));
		size_t offset_bytes = ((size_t)c.vertex_count + 1) * sizeof(int32_t);
		fuzz_fill_canary(auto_offsets, offset_bytes);
		fuzz_fill_canary(auto_bones, (size_t)capacity * sizeof(int32_t));
		fuzz_fill_canary(auto_values, (size_t)capacity * sizeof(float));
		diag = fuzz_diag();
		result = lvp_auto_weights(auto_offsets, auto_bones, auto_values, capacity, c.positions, vertex_count,
		                          c.triangles, triangle_count, (auto_flags & 8) ? NULL : &skeleton, auto_used, &diag);
		fuzz_check_result("lvp_auto_weights", result, &diag);
		if (result != lvp_success) {
			fuzz_check_canary("lvp_auto_weights r_offsets", auto_offsets, offset_bytes);
			fuzz_check_canary("lvp_auto_weights r_bones", auto_bones, (size_t)capacity * sizeof(int32_t));
			fuzz_check_canary("lvp_auto_weights r_values", auto_values, (size_t)capacity * sizeof(float));
		} else {
			if (auto_offsets[0] != 0 || auto_offsets[vertex_count] > capacity)
				fuzz_violation("lvp_auto_weights", "offsets out of range");
			for (int32_t k = 0; k < vertex_count; ++k)
				if (auto_offsets[k] > auto_offsets[k + 1])
					fuzz_violation("lvp_auto_weights", "offsets decrease");
			for (int32_t e = 0; e < auto_offsets[vertex_count]; ++e)
				if (auto_bones[e] < 0 || auto_bones[e] >= bone_count || !(auto_values[e] >= 0.0f))
					fuzz_violation("lvp_auto_weights", "influence out of range");
			if (auto_flags & 16) {
				lvp_weights automatic = {auto_offsets, auto_bones, auto_values};
				fuzz_bind_and_run(&c, r, &automatic, vertex_count, triangle_count, bone_count);
			}
		}
	}

	/* The given weights. */
	fuzz_bind_and_run(&c, r, &weights, vertex_count, triangle_count, bone_count);

	free(auto_offsets);
	free(auto_bones);
	free(auto_values);
	free(vectors);
	free(skinned);
	fuzz_case_free(&c);
}

#endif
