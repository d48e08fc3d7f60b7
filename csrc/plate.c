/*
 * plate.c - the relaxed skin around fold-over's presses settled as a thin plate. Fold-over's relaxation
 * (foldover.c, lvp__relax_pressed) averages offsets with their neighbours' and presses back what
 * crosses: a membrane. Held at one vertex by the contact plane, a membrane settles into a cone whose
 * tip stands out of its neighbours by a share of the press that more passes do not lower, and a coarse
 * mesh's press is an edge or two at a single vertex. A plate bends smoothly onto what holds it.
 *
 * The plate is the zone's offsets x minimising the bending sum |L x|^2 (L: the relaxation's weighted
 * Laplacian, over every vertex whose Laplacian reads a free vertex), plus a screening term lambda |x - m|^2
 * that ties it to the membrane's offsets m: the plate reaches about LVP__PLATE_REACH_SHARE of the
 * smoothing's rings around a press (the scale where the two terms weigh alike), and leaves longer scales,
 * the bulge the correction put there, as the membrane left them. Without that tie the settled plate
 * flattened the bulges of a whole body's relaxation zone. The pressed vertices and the skin outside the
 * zone are held. Solved by conjugate gradients, serially, so any thread count gives the same bits.
 */
#include "binding.h"

#include <stdlib.h>

/* The plate reaches this share of the offsets' smoothing passes (in rings) around a press: lambda is
 * (1 / (share * passes))^4, where a wave of that length bends as much as it strays from the membrane. */
#define LVP__PLATE_REACH_SHARE 0.5
/* Conjugate gradients stop when the residual is this share of the first one's: the plate is a smoothing,
 * wanted to a percent, not a solution to the last bit. */
#define LVP__PLATE_TOLERANCE 1e-2
/* And after at most this many iterations whatever the residual, a bound on a frame's time. */
#define LVP__PLATE_MOST_ITERATIONS 200

enum {
	LVP__PLATE_FREE = 1, /* the plate moves it */
	LVP__PLATE_ROW = 2,  /* its Laplacian reads a free vertex: in the bending sum */
	LVP__PLATE_READ = 4  /* a row reads it: plate.offsets and plate.direction hold it */
};

/* out = A v on the free vertices: A = L^T L + screen I over the rows, v read where a row reads it (zero off
 * the free vertices for a direction). plate.laplacian is scratch. */
static void lvp__plate_product(lvp_binding *binding, const double *v, double screen, double *out)
{
	const lvp__smoothing *weights = &binding->relaxation;
	lvp__plate *plate = &binding->fold.plate;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	for (int32_t r = 0; r < plate->row_count; ++r) {
		int32_t k = plate->rows[r];
		double sum[3] = {0.0, 0.0, 0.0};
		if (weights->offsets[k + 1] > weights->offsets[k]) {
			/* As a smoothing pass reads it: a neighbour outside the dynamic set has no offset. */
			for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e) {
				int32_t j = weights->neighbours[e];
				if (dynamic[j])
					for (int c = 0; c < 3; ++c)
						sum[c] += 2.0 * weights->halves[e] * v[3 * j + c];
			}
			for (int c = 0; c < 3; ++c)
				sum[c] -= v[3 * k + c];
		}
		for (int c = 0; c < 3; ++c)
			plate->laplacian[3 * r + c] = sum[c];
	}
	for (int32_t f = 0; f < plate->free_count; ++f) {
		int32_t k = plate->free[f];
		for (int c = 0; c < 3; ++c)
			out[3 * k + c] = screen * v[3 * k + c];
	}
	/* L^T: each row's Laplacian back onto the free vertices it read, in the rows' order. */
	for (int32_t r = 0; r < plate->row_count; ++r) {
		int32_t k = plate->rows[r];
		const double *lap = plate->laplacian + 3 * r;
		if (weights->offsets[k + 1] == weights->offsets[k])
			continue;
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e) {
			int32_t j = weights->neighbours[e];
			if (plate->role[j] & LVP__PLATE_FREE)
				for (int c = 0; c < 3; ++c)
					out[3 * j + c] += 2.0 * weights->halves[e] * lap[c];
		}
		if (plate->role[k] & LVP__PLATE_FREE)
			for (int c = 0; c < 3; ++c)
				out[3 * k + c] -= lap[c];
	}
}

static void lvp__plate_mark(lvp__plate *plate, int32_t k, uint8_t role, int32_t *list, int32_t *count)
{
	if (!(plate->role[k] & role)) {
		plate->role[k] |= role;
		list[(*count)++] = k;
	}
}

/* Lists the free vertices (the zone's not held), the rows and what the rows read; loads the offsets of
 * what is read and clears the direction there. Returns the number of free vertices. */
static int32_t lvp__plate_begin(lvp_binding *binding, const float *positions, const int32_t *zone, int32_t count)
{
	const lvp__smoothing *weights = &binding->relaxation;
	lvp__plate *plate = &binding->fold.plate;
	plate->free_count = plate->row_count = plate->read_count = 0;
	for (int32_t z = 0; z < count; ++z)
		if (!binding->fold.held[zone[z]])
			lvp__plate_mark(plate, zone[z], LVP__PLATE_FREE, plate->free, &plate->free_count);
	for (int32_t f = 0; f < plate->free_count; ++f) {
		int32_t k = plate->free[f];
		lvp__plate_mark(plate, k, LVP__PLATE_ROW, plate->rows, &plate->row_count);
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e)
			lvp__plate_mark(plate, weights->neighbours[e], LVP__PLATE_ROW, plate->rows, &plate->row_count);
	}
	for (int32_t r = 0; r < plate->row_count; ++r) {
		int32_t k = plate->rows[r];
		lvp__plate_mark(plate, k, LVP__PLATE_READ, plate->read, &plate->read_count);
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e)
			lvp__plate_mark(plate, weights->neighbours[e], LVP__PLATE_READ, plate->read, &plate->read_count);
	}
	for (int32_t i = 0; i < plate->read_count; ++i) {
		int32_t k = plate->read[i];
		for (int c = 0; c < 3; ++c) {
			plate->offsets[3 * k + c] = binding->frame_map.vertex_dynamic[k]
			                                ? (double)binding->step.positions[3 * k + c] - positions[3 * k + c]
			                                : 0.0;
			plate->direction[3 * k + c] = 0.0;
		}
	}
	return plate->free_count;
}

/* The free members of each of the relaxation's tie clusters (smoothing_ties.c) given their mean of v: the plate
 * moves a cluster as one point, as the membrane's passes do. Its members' own Laplacians, each read alone, would
 * part the ends of a needle's short edge, and its thin triangles turn on edge, a crease each. */
static void lvp__plate_tie(lvp_binding *binding, double *v)
{
	const lvp__smoothing *weights = &binding->relaxation;
	const uint8_t *role = binding->fold.plate.role;
	for (int32_t tie = 0; tie < weights->tie_count; ++tie) {
		double mean[3] = {0.0, 0.0, 0.0};
		int32_t count = 0;
		for (int32_t i = weights->tie_offsets[tie]; i < weights->tie_offsets[tie + 1]; ++i) {
			int32_t k = weights->tie_members[i];
			if (role[k] & LVP__PLATE_FREE) {
				++count;
				for (int c = 0; c < 3; ++c)
					mean[c] += v[3 * k + c];
			}
		}
		for (int32_t i = weights->tie_offsets[tie]; count > 1 && i < weights->tie_offsets[tie + 1]; ++i) {
			int32_t k = weights->tie_members[i];
			if (role[k] & LVP__PLATE_FREE)
				for (int c = 0; c < 3; ++c)
					v[3 * k + c] = mean[c] / count;
		}
	}
}

/* plate.role back to zero (what lvp__plate_begin marked: the free vertices and rows are read too). */
static void lvp__plate_end(lvp__plate *plate)
{
	for (int32_t i = 0; i < plate->read_count; ++i)
		plate->role[plate->read[i]] = 0;
}

static double lvp__plate_dot(const lvp__plate *plate, const double *a, const double *b)
{
	double sum = 0.0;
	for (int32_t f = 0; f < plate->free_count; ++f)
		for (int c = 0; c < 3; ++c)
			sum += a[3 * plate->free[f] + c] * b[3 * plate->free[f] + c];
	return sum;
}

void lvp__settle_as_plate(lvp_binding *binding, const float *positions, const int32_t *zone, int32_t count,
                          int32_t smoothing_passes)
{
	lvp__plate *plate = &binding->fold.plate;
	if (!plate->role || smoothing_passes <= 0) /* no relaxation lists (lvp__relaxation_begin), or no smoothing */
		return;
	if (lvp__plate_begin(binding, positions, zone, count) == 0) {
		lvp__plate_end(plate);
		return;
	}
	double *x = plate->offsets, *d = plate->direction, *q = plate->product, *r = plate->residual;
	double screen = pow(1.0 / (LVP__PLATE_REACH_SHARE * smoothing_passes), 4.0);
	/* From the membrane's offsets, where the screening term is zero: the residual is the bending's pull. */
	lvp__plate_product(binding, x, 0.0, q);
	for (int32_t f = 0; f < plate->free_count; ++f)
		for (int c = 0; c < 3; ++c)
			r[3 * plate->free[f] + c] = -q[3 * plate->free[f] + c];
	lvp__plate_tie(binding, r);
	for (int32_t f = 0; f < plate->free_count; ++f)
		for (int c = 0; c < 3; ++c)
			d[3 * plate->free[f] + c] = r[3 * plate->free[f] + c];
	double rr = lvp__plate_dot(plate, r, r), first = rr;
	for (int32_t it = 0; it < LVP__PLATE_MOST_ITERATIONS && rr > LVP__PLATE_TOLERANCE * LVP__PLATE_TOLERANCE * first;
	     ++it) {
		lvp__plate_product(binding, d, screen, q);
		double curvature = lvp__plate_dot(plate, d, q);
		if (!(curvature > 0.0) || !isfinite(curvature))
			break;
		double alpha = rr / curvature;
		for (int32_t f = 0; f < plate->free_count; ++f)
			for (int c = 0; c < 3; ++c) {
				int32_t i = 3 * plate->free[f] + c;
				x[i] += alpha * d[i];
				r[i] -= alpha * q[i];
			}
		lvp__plate_tie(binding, r);
		double next = lvp__plate_dot(plate, r, r);
		for (int32_t f = 0; f < plate->free_count; ++f)
			for (int c = 0; c < 3; ++c) {
				int32_t i = 3 * plate->free[f] + c;
				d[i] = r[i] + next / rr * d[i];
			}
		rr = next;
	}
	for (int32_t f = 0; f < plate->free_count; ++f) {
		int32_t k = plate->free[f];
		if (isfinite(x[3 * k]) && isfinite(x[3 * k + 1]) && isfinite(x[3 * k + 2]))
			for (int c = 0; c < 3; ++c)
				binding->step.positions[3 * k + c] = (float)(positions[3 * k + c] + x[3 * k + c]);
	}
	lvp__plate_end(plate);
}

bool lvp__plate_alloc(lvp__plate *plate, int32_t vertex_count)
{
	bool ok = true;
	size_t n = (size_t)vertex_count + 1;
	plate->role = lvp__calloc(n, 1, &ok);
	plate->free = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->rows = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->read = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->offsets = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->direction = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->product = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->residual = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->laplacian = lvp__calloc(3 * n, sizeof(double), &ok);
	return ok;
}

void lvp__plate_free(lvp__plate *plate)
{
	free(plate->role);
	free(plate->free);
	free(plate->rows);
	free(plate->read);
	free(plate->offsets);
	free(plate->direction);
	free(plate->product);
	free(plate->residual);
	free(plate->laplacian);
}
