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

/* out = A v on the free vertices: A = L^T L + screen I over the rows, v by local number (zero off the free
 * vertices for a direction; a neighbour outside the dynamic set reads zero, as it has no offset in a smoothing
 * pass). Each row's Laplacian goes back onto the free vertices it read as soon as it is summed, in the rows'
 * order. */
static void lvp__plate_product(lvp__plate *plate, const double *v, double screen, double *out)
{
	const int32_t *starts = plate->row_starts, *columns = plate->columns;
	const float *weights = plate->weights;
	int32_t free_count = plate->free_count;
	for (int32_t i = 0; i < 3 * free_count; ++i)
		out[i] = screen * v[i];
	for (int32_t r = 0; r < plate->row_count; ++r) {
		int32_t begin = starts[r], end = starts[r + 1];
		if (end == begin)
			continue;
		double x = 0.0, y = 0.0, z = 0.0;
		for (int32_t e = begin; e < end; ++e) {
			const double *at = v + 3 * columns[e];
			double w = weights[e];
			x += w * at[0];
			y += w * at[1];
			z += w * at[2];
		}
		const double *own = v + 3 * plate->rows[r];
		x -= own[0];
		y -= own[1];
		z -= own[2];
		/* L^T */
		for (int32_t e = begin; e < end; ++e)
			if (columns[e] < free_count) {
				double *to = out + 3 * columns[e], w = weights[e];
				to[0] += w * x;
				to[1] += w * y;
				to[2] += w * z;
			}
		if (plate->rows[r] < free_count) {
			double *to = out + 3 * plate->rows[r];
			to[0] -= x;
			to[1] -= y;
			to[2] -= z;
		}
	}
}

static void lvp__plate_mark(lvp__plate *plate, int32_t k, uint8_t role, int32_t *list, int32_t *count)
{
	if (!(plate->role[k] & role)) {
		plate->role[k] |= role;
		list[(*count)++] = k;
	}
}

/* Lists the free vertices (the zone's not held), the rows and what the rows read, and numbers what is read
 * for the solve: the free vertices first, in their list's order, then the rest. Lays out the rows' Laplacians
 * by those numbers (rows then holds each row's own number), loads the offsets of what is read and clears the
 * direction there. Returns the number of free vertices. */
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
	for (int32_t f = 0; f < plate->free_count; ++f)
		plate->number[plate->free[f]] = f;
	for (int32_t i = 0, next = plate->free_count; i < plate->read_count; ++i)
		if (!(plate->role[plate->read[i]] & LVP__PLATE_FREE))
			plate->number[plate->read[i]] = next++;
	int32_t written = 0;
	for (int32_t r = 0; r < plate->row_count; ++r) {
		int32_t k = plate->rows[r];
		plate->row_starts[r] = written;
		for (int32_t e = weights->offsets[k]; e < weights->offsets[k + 1]; ++e) {
			plate->columns[written] = plate->number[weights->neighbours[e]];
			plate->weights[written++] = 2.0f * weights->halves[e];
		}
		plate->rows[r] = plate->number[k];
	}
	plate->row_starts[plate->row_count] = written;
	for (int32_t i = 0; i < plate->read_count; ++i) {
		int32_t k = plate->read[i], at = plate->number[k];
		for (int c = 0; c < 3; ++c) {
			plate->offsets[3 * at + c] = binding->frame_map.vertex_dynamic[k]
			                                 ? (double)binding->step.positions[3 * k + c] - positions[3 * k + c]
			                                 : 0.0;
			plate->direction[3 * at + c] = 0.0;
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
	const int32_t *number = binding->fold.plate.number;
	for (int32_t tie = 0; tie < weights->tie_count; ++tie) {
		double mean[3] = {0.0, 0.0, 0.0};
		int32_t count = 0;
		for (int32_t i = weights->tie_offsets[tie]; i < weights->tie_offsets[tie + 1]; ++i) {
			int32_t k = weights->tie_members[i];
			if (role[k] & LVP__PLATE_FREE) {
				++count;
				for (int c = 0; c < 3; ++c)
					mean[c] += v[3 * number[k] + c];
			}
		}
		for (int32_t i = weights->tie_offsets[tie]; count > 1 && i < weights->tie_offsets[tie + 1]; ++i) {
			int32_t k = weights->tie_members[i];
			if (role[k] & LVP__PLATE_FREE)
				for (int c = 0; c < 3; ++c)
					v[3 * number[k] + c] = mean[c] / count;
		}
	}
}

/* plate.role back to zero (what lvp__plate_begin marked: the free vertices and rows are read too). */
static void lvp__plate_end(lvp__plate *plate)
{
	for (int32_t i = 0; i < plate->read_count; ++i)
		plate->role[plate->read[i]] = 0;
}

/* a . b over the free vertices (the first free_count by local number), summed in four lanes: one running sum
 * waits on each addition before the next, and the conjugate gradients take two such products an iteration. */
static double lvp__plate_dot(const lvp__plate *plate, const double *a, const double *b)
{
	double lane[4] = {0.0, 0.0, 0.0, 0.0};
	int32_t count = 3 * plate->free_count, i = 0;
	for (; i + 4 <= count; i += 4)
		for (int l = 0; l < 4; ++l)
			lane[l] += a[i + l] * b[i + l];
	for (; i < count; ++i)
		lane[0] += a[i] * b[i];
	return (lane[0] + lane[1]) + (lane[2] + lane[3]);
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
	/* By local number: x and d over what the rows read, q and r over the free vertices. */
	double *x = plate->offsets, *d = plate->direction, *q = plate->product, *r = plate->residual;
	int32_t free_values = 3 * plate->free_count;
	double screen = pow(1.0 / (LVP__PLATE_REACH_SHARE * smoothing_passes), 4.0);
	/* From the membrane's offsets, where the screening term is zero: the residual is the bending's pull. */
	lvp__plate_product(plate, x, 0.0, q);
	for (int32_t i = 0; i < free_values; ++i)
		r[i] = -q[i];
	lvp__plate_tie(binding, r);
	for (int32_t i = 0; i < free_values; ++i)
		d[i] = r[i];
	double rr = lvp__plate_dot(plate, r, r), first = rr;
	for (int32_t it = 0; it < LVP__PLATE_MOST_ITERATIONS && rr > LVP__PLATE_TOLERANCE * LVP__PLATE_TOLERANCE * first;
	     ++it) {
		lvp__plate_product(plate, d, screen, q);
		double curvature = lvp__plate_dot(plate, d, q);
		if (!(curvature > 0.0) || !isfinite(curvature))
			break;
		double alpha = rr / curvature;
		for (int32_t i = 0; i < free_values; ++i) {
			x[i] += alpha * d[i];
			r[i] -= alpha * q[i];
		}
		lvp__plate_tie(binding, r);
		double next = lvp__plate_dot(plate, r, r);
		for (int32_t i = 0; i < free_values; ++i)
			d[i] = r[i] + next / rr * d[i];
		rr = next;
	}
	for (int32_t f = 0; f < plate->free_count; ++f) {
		int32_t k = plate->free[f];
		if (isfinite(x[3 * f]) && isfinite(x[3 * f + 1]) && isfinite(x[3 * f + 2]))
			for (int c = 0; c < 3; ++c)
				binding->step.positions[3 * k + c] = (float)(positions[3 * k + c] + x[3 * f + c]);
	}
	lvp__plate_end(plate);
}

bool lvp__plate_alloc(lvp__plate *plate, int32_t vertex_count, int32_t entry_count)
{
	bool ok = true;
	size_t n = (size_t)vertex_count + 1, entries = (size_t)entry_count + 1;
	plate->role = lvp__calloc(n, 1, &ok);
	plate->free = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->rows = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->read = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->number = lvp__calloc(n, sizeof(int32_t), &ok);
	plate->row_starts = lvp__calloc(n + 1, sizeof(int32_t), &ok);
	plate->columns = lvp__calloc(entries, sizeof(int32_t), &ok);
	plate->weights = lvp__calloc(entries, sizeof(float), &ok);
	plate->offsets = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->direction = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->product = lvp__calloc(3 * n, sizeof(double), &ok);
	plate->residual = lvp__calloc(3 * n, sizeof(double), &ok);
	return ok;
}

void lvp__plate_free(lvp__plate *plate)
{
	free(plate->role);
	free(plate->free);
	free(plate->rows);
	free(plate->read);
	free(plate->number);
	free(plate->row_starts);
	free(plate->columns);
	free(plate->weights);
	free(plate->offsets);
	free(plate->direction);
	free(plate->product);
	free(plate->residual);
}
