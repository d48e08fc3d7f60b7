/*
 * test_multigrid.c - bone heat's preconditioner (csrc/screened_multigrid.c, diffusion.h lvp__multigrid): a
 * cycle is a symmetric, positive definite operator (what conjugate gradients need), conjugate gradients
 * with it reach the system's solution, and their iterations grow by a few each time the mesh's edges halve,
 * where the diagonal's alone double.
 */
#include "diffusion.h"
#include "support/check.h"

#include <math.h>
#include <stdlib.h>

/* A screened Laplacian over a side x side grid of vertices split into triangles (edges along both axes and one
 * diagonal), its couplings varying from edge to edge, its screening weak (the fall-off `side` edges long,
 * as on deep skin) and strong on the first row (where a bone's skin is); the grid's outer ring tied to zero
 * beyond (as a patch's rim is). */
typedef struct grid_system {
	int32_t n, *offsets, *columns;
	double *coupling, *diagonal;
} grid_system;

static double pseudo_random(uint32_t *state)
{
	*state = *state * 1664525u + 1013904223u;
	return (double)(*state >> 8) / 16777216.0;
}

static void grid_system_make(grid_system *s, int32_t side)
{
	int32_t n = side * side;
	s->n = n;
	s->offsets = calloc((size_t)n + 1, sizeof(int32_t));
	s->columns = malloc(sizeof(int32_t) * 6 * (size_t)n);
	s->coupling = malloc(sizeof(double) * 6 * (size_t)n);
	s->diagonal = calloc((size_t)n, sizeof(double));
	static const int steps[6][2] = {{-1, 0}, {1, 0}, {0, -1}, {0, 1}, {-1, -1}, {1, 1}};
	int32_t written = 0;
	for (int32_t y = 0; y < side; ++y)
		for (int32_t x = 0; x < side; ++x) {
			int32_t k = y * side + x;
			s->offsets[k] = written;
			double sum = 0.0;
			for (int i = 0; i < 6; ++i) {
				int32_t nx = x + steps[i][0], ny = y + steps[i][1];
				if (nx < 0 || ny < 0 || nx >= side || ny >= side) {
					sum += 0.5; /* a neighbour beyond the rim, at zero */
					continue;
				}
				int32_t j = ny * side + nx;
				/* the same coupling seen from both ends: seeded by the edge, not the vertex */
				int32_t lo = j < k ? j : k, hi = j < k ? k : j;
				uint32_t seed = (uint32_t)(lo * 7919 + hi * 104729);
				double c = i >= 4 ? 0.25 : 0.5 + pseudo_random(&seed);
				s->columns[written] = j;
				s->coupling[written++] = c;
				sum += c;
			}
			double screen = y == 0 ? 100.0 : 1.0 / ((double)side * side);
			s->diagonal[k] = sum + screen;
		}
	s->offsets[n] = written;
}

static void grid_system_free(grid_system *s)
{
	free(s->offsets);
	free(s->columns);
	free(s->coupling);
	free(s->diagonal);
}

static void apply(const grid_system *s, const double *v, double *out)
{
	for (int32_t i = 0; i < s->n; ++i) {
		double sum = s->diagonal[i] * v[i];
		for (int32_t e = s->offsets[i]; e < s->offsets[i + 1]; ++e)
			sum -= s->coupling[e] * v[s->columns[e]];
		out[i] = sum;
	}
}

static double dot(const double *a, const double *b, int32_t n)
{
	double sum = 0.0;
	for (int32_t i = 0; i < n; ++i)
		sum += a[i] * b[i];
	return sum;
}

/* Conjugate gradients from zero until the residual is 1e-10 of b's; with the multigrid when `grid`, else the
 * diagonal. Returns the iterations. */
static int solve(const grid_system *s, lvp__multigrid *grid, const double *b, double *x)
{
	int32_t n = s->n;
	double *r = malloc(sizeof(double) * (size_t)n), *z = malloc(sizeof(double) * (size_t)n);
	double *p = malloc(sizeof(double) * (size_t)n), *q = malloc(sizeof(double) * (size_t)n);
	for (int32_t i = 0; i < n; ++i) {
		x[i] = 0.0;
		r[i] = b[i];
	}
	if (grid)
		lvp__multigrid_apply(grid, r, z);
	else
		for (int32_t i = 0; i < n; ++i)
			z[i] = r[i] / s->diagonal[i];
	memcpy(p, z, sizeof(double) * (size_t)n);
	double rz = dot(r, z, n), stop = 1e-20 * dot(b, b, n);
	int iteration = 0;
	for (; iteration < 20000 && dot(r, r, n) > stop; ++iteration) {
		apply(s, p, q);
		double alpha = rz / dot(p, q, n);
		for (int32_t i = 0; i < n; ++i) {
			x[i] += alpha * p[i];
			r[i] -= alpha * q[i];
		}
		if (grid)
			lvp__multigrid_apply(grid, r, z);
		else
			for (int32_t i = 0; i < n; ++i)
				z[i] = r[i] / s->diagonal[i];
		double next = dot(r, z, n);
		for (int32_t i = 0; i < n; ++i)
			p[i] = z[i] + next / rz * p[i];
		rz = next;
	}
	free(r);
	free(z);
	free(p);
	free(q);
	return iteration;
}

static void test_a_cycle_is_symmetric_and_positive(void)
{
	grid_system s;
	grid_system_make(&s, 40);
	lvp__multigrid grid;
	CHECK(lvp__multigrid_build(&grid, s.n, s.offsets, s.columns, s.coupling, s.diagonal));
	CHECK(grid.level_count >= 3);
	int32_t n = s.n;
	double *u = malloc(sizeof(double) * (size_t)n), *v = malloc(sizeof(double) * (size_t)n);
	double *mu = malloc(sizeof(double) * (size_t)n), *mv = malloc(sizeof(double) * (size_t)n);
	uint32_t state = 7;
	for (int trial = 0; trial < 4; ++trial) {
		for (int32_t i = 0; i < n; ++i) {
			u[i] = pseudo_random(&state) - 0.5;
			v[i] = pseudo_random(&state) - 0.5;
		}
		lvp__multigrid_apply(&grid, u, mu);
		lvp__multigrid_apply(&grid, v, mv);
		double umv = dot(u, mv, n), vmu = dot(v, mu, n);
		CHECK(fabs(umv - vmu) <= 1e-12 * sqrt(dot(u, u, n) * dot(mv, mv, n)));
		CHECK(dot(u, mu, n) > 0.0 && dot(v, mv, n) > 0.0);
	}
	free(u);
	free(v);
	free(mu);
	free(mv);
	lvp__multigrid_free(&grid);
	grid_system_free(&s);
}

static void test_iterations_grow_slowly_with_density(void)
{
	int sides[3] = {24, 48, 96}, with_grid[3], with_diagonal[3];
	for (int c = 0; c < 3; ++c) {
		grid_system s;
		grid_system_make(&s, sides[c]);
		double *b = malloc(sizeof(double) * (size_t)s.n), *x = malloc(sizeof(double) * (size_t)s.n);
		double *reference = malloc(sizeof(double) * (size_t)s.n);
		for (int32_t i = 0; i < s.n; ++i)
			b[i] = i < sides[c] ? 100.0 * (i < sides[c] / 2 ? 1.0 : 0.25) : 0.0; /* the bone's skin, two shares */
		lvp__multigrid grid;
		CHECK(lvp__multigrid_build(&grid, s.n, s.offsets, s.columns, s.coupling, s.diagonal));
		with_grid[c] = solve(&s, &grid, b, x);
		with_diagonal[c] = solve(&s, NULL, b, reference);
		double largest = 0.0;
		for (int32_t i = 0; i < s.n; ++i)
			largest = fmax(largest, fabs(x[i] - reference[i]));
		CHECK(largest < 1e-7); /* the same solution as the diagonal's, to the solves' tolerance */
		printf("  %d x %d vertices: %d iterations with the multigrid, %d with the diagonal alone, %d levels\n",
		       sides[c], sides[c], with_grid[c], with_diagonal[c], grid.level_count);
		lvp__multigrid_free(&grid);
		free(b);
		free(x);
		free(reference);
		grid_system_free(&s);
	}
	for (int c = 0; c + 1 < 3; ++c) {
		CHECK(with_grid[c + 1] <= with_grid[c] + 6);
		CHECK(with_diagonal[c + 1] * 10 > with_diagonal[c] * 17); /* what the multigrid is for */
	}
	CHECK(with_grid[2] * 5 < with_diagonal[2]);
}

/* Systems with no coarsening to speak of: vertices apart (no couplings; 600 of them, too many to factor, are
 * swept), one vertex, none. A cycle is then the exact inverse of the diagonal. */
static void test_graphs_without_aggregates(void)
{
	int32_t n = 600;
	int32_t *offsets = calloc((size_t)n + 1, sizeof(int32_t));
	double *diagonal = malloc(sizeof(double) * (size_t)n), *r = malloc(sizeof(double) * (size_t)n);
	double *z = malloc(sizeof(double) * (size_t)n);
	for (int32_t i = 0; i < n; ++i) {
		diagonal[i] = 1.0 + i;
		r[i] = 2.0 + 2.0 * i;
	}
	int32_t sizes[4] = {600, 300, 1, 0};
	for (int c = 0; c < 4; ++c) {
		lvp__multigrid grid;
		CHECK(lvp__multigrid_build(&grid, sizes[c], offsets, NULL, NULL, diagonal));
		CHECK((grid.factor != NULL) == (sizes[c] <= 512));
		lvp__multigrid_apply(&grid, r, z);
		for (int32_t i = 0; i < sizes[c]; ++i)
			CHECK_NEAR(z[i], 2.0, 1e-12);
		lvp__multigrid_free(&grid);
	}
	/* A vertex tied to nothing with no diagonal (skin of degenerate triangles only) is left at zero, not NaN. */
	diagonal[1] = 0.0;
	lvp__multigrid grid;
	CHECK(lvp__multigrid_build(&grid, 3, offsets, NULL, NULL, diagonal));
	lvp__multigrid_apply(&grid, r, z);
	CHECK(z[1] == 0.0);
	CHECK_NEAR(z[0], 2.0, 1e-12);
	CHECK_NEAR(z[2], 2.0, 1e-12);
	lvp__multigrid_free(&grid);
	free(offsets);
	free(diagonal);
	free(r);
	free(z);
}

int main(void)
{
	RUN(test_a_cycle_is_symmetric_and_positive);
	RUN(test_iterations_grow_slowly_with_density);
	RUN(test_graphs_without_aggregates);
	return check_failures() != 0;
}
