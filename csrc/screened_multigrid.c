/*
 * screened_multigrid.c - the preconditioner of bone heat's conjugate gradients (screened_diffusion.c;
 * diffusion.h, lvp__multigrid): one W-cycle of aggregation multigrid over a bone's patch.
 *
 * With the diagonal alone as preconditioner, conjugate gradients take about as many iterations as the
 * weight's fall-off is long in edges: over a hundred for a bone of a dense body's trunk, where the skin
 * is deep. Here each vertex and its neighbours form an aggregate (then those aggregates' own aggregates,
 * and so on, down to a few dozen); each level's system is the one below summed over its aggregates
 * (Galerkin's, with the aggregate's weight constant over it), so a long, smooth fall-off that the finest
 * edges carry slowly is a few aggregates long at some level. A cycle sweeps Gauss-Seidel forward over a
 * level, hands what is left to the level below (twice: a W-cycle), and sweeps backward; the coarsest level
 * is solved exactly. That is a symmetric, positive definite operator, as conjugate gradients need, and a
 * fixed one (the same every iteration). On the bodies' trunks the iterations fall from over a hundred to
 * about fifteen, and grow by a few, not twofold, each time the edges halve (test_multigrid).
 *
 * Aggregates are formed in the patch's own order (the order its vertices were reached from the bone), the
 * sweeps run in that order: the same bits wherever the patch is solved.
 */
#include "diffusion.h"

#include <stdlib.h>
#include <string.h>

/* Coarsening stops at this many vertices (solved exactly, densely), or when a level would keep more than
 * LVP__MULTIGRID_SLOW_COARSENING of the one above (no aggregates to speak of: each vertex apart). */
#define LVP__MULTIGRID_COARSEST 64
#define LVP__MULTIGRID_SLOW_COARSENING 0.75
/* Past this many, the coarsest level is swept (forward, then backward) rather than factored. */
#define LVP__MULTIGRID_DENSE_LIMIT 512

void lvp__multigrid_free(lvp__multigrid *grid)
{
	for (int32_t l = 0; l < grid->level_count; ++l) {
		lvp__multigrid_level *level = &grid->levels[l];
		if (l > 0) { /* the finest level's system is the caller's */
			free(level->offsets);
			free(level->columns);
			free(level->coupling);
			free(level->diagonal);
		}
		free(level->aggregate);
		free(level->inverse);
		free(level->x);
		free(level->b);
		free(level->r);
		free(level->y);
		free(level->t);
	}
	free(grid->factor);
	memset(grid, 0, sizeof(*grid));
}

/* Each vertex's aggregate at the next level, into level->aggregate; returns how many aggregates. First, in
 * order, each vertex whose neighbours are all free starts an aggregate with them; then each vertex left
 * joins the first-pass aggregate of its most strongly coupled neighbour in one (the first such neighbour on
 * a tie); a vertex with no such neighbour starts its own. */
static int32_t lvp__aggregate(lvp__multigrid_level *level)
{
	int32_t n = level->n, count = 0;
	int32_t *of = level->aggregate;
	for (int32_t i = 0; i < n; ++i)
		of[i] = -1;
	for (int32_t i = 0; i < n; ++i) {
		if (of[i] >= 0)
			continue;
		bool free_around = true;
		for (int32_t e = level->offsets[i]; e < level->offsets[i + 1] && free_around; ++e)
			free_around = of[level->columns[e]] < 0;
		if (!free_around)
			continue;
		of[i] = count;
		for (int32_t e = level->offsets[i]; e < level->offsets[i + 1]; ++e)
			of[level->columns[e]] = count;
		++count;
	}
	int32_t formed = count;
	/* Vertices left join a neighbour's aggregate of the first pass: marked with -2 - aggregate until all have
	 * chosen, so that no choice rests on another of this pass. */
	for (int32_t i = 0; i < n; ++i) {
		if (of[i] != -1)
			continue;
		int32_t best = -1;
		double strongest = 0.0;
		for (int32_t e = level->offsets[i]; e < level->offsets[i + 1]; ++e) {
			int32_t a = of[level->columns[e]];
			if (a >= 0 && a < formed && (best < 0 || level->coupling[e] > strongest)) {
				best = a;
				strongest = level->coupling[e];
			}
		}
		of[i] = best >= 0 ? -2 - best : -1;
	}
	for (int32_t i = 0; i < n; ++i) {
		if (of[i] <= -2)
			of[i] = -2 - of[i];
		else if (of[i] == -1)
			of[i] = count++;
	}
	return count;
}

/* The next level's system: couplings between aggregates summed from their vertices' couplings, each
 * diagonal its vertices' diagonals less the couplings inside the aggregate (Galerkin's coarse operator
 * with a constant weight over each aggregate). */
static bool lvp__coarsen(const lvp__multigrid_level *fine, lvp__multigrid_level *coarse, int32_t count)
{
	int32_t n = fine->n, entries = fine->offsets[n];
	coarse->n = count;
	coarse->offsets = malloc(sizeof(int32_t) * ((size_t)count + 1));
	coarse->columns = malloc(sizeof(int32_t) * ((size_t)entries + 1));
	coarse->coupling = malloc(sizeof(double) * ((size_t)entries + 1));
	coarse->diagonal = malloc(sizeof(double) * (size_t)count);
	int32_t *member_offsets = malloc(sizeof(int32_t) * ((size_t)count + 1));
	int32_t *members = malloc(sizeof(int32_t) * ((size_t)n + 1));
	int32_t *place = malloc(sizeof(int32_t) * (size_t)count); /* a coarse column's entry in the row being made */
	bool ok = coarse->offsets && coarse->columns && coarse->coupling && coarse->diagonal && member_offsets &&
	          members && place;
	if (ok) {
		/* The aggregates' members, in order. */
		memset(member_offsets, 0, sizeof(int32_t) * ((size_t)count + 1));
		for (int32_t i = 0; i < n; ++i)
			++member_offsets[fine->aggregate[i] + 1];
		for (int32_t a = 0; a < count; ++a)
			member_offsets[a + 1] += member_offsets[a];
		memcpy(place, member_offsets, sizeof(int32_t) * (size_t)count);
		for (int32_t i = 0; i < n; ++i)
			members[place[fine->aggregate[i]]++] = i;
		for (int32_t a = 0; a < count; ++a)
			place[a] = -1;
		int32_t written = 0;
		for (int32_t a = 0; a < count; ++a) {
			coarse->offsets[a] = written;
			double diagonal = 0.0;
			for (int32_t m = member_offsets[a]; m < member_offsets[a + 1]; ++m) {
				int32_t i = members[m];
				diagonal += fine->diagonal[i];
				for (int32_t e = fine->offsets[i]; e < fine->offsets[i + 1]; ++e) {
					int32_t b = fine->aggregate[fine->columns[e]];
					if (b == a) {
						diagonal -= fine->coupling[e];
					} else if (place[b] < 0) {
						place[b] = written;
						coarse->columns[written] = b;
						coarse->coupling[written++] = fine->coupling[e];
					} else {
						coarse->coupling[place[b]] += fine->coupling[e];
					}
				}
			}
			coarse->diagonal[a] = diagonal;
			for (int32_t e = coarse->offsets[a]; e < written; ++e)
				place[coarse->columns[e]] = -1;
		}
		coarse->offsets[count] = written;
	}
	free(member_offsets);
	free(members);
	free(place);
	return ok;
}

/* A level's vectors and its diagonal's inverse (the sweeps multiply by it: a division in each vertex's
 * update would hold up the next one's); the finest level's x and b are the caller's (lvp__multigrid_apply's
 * z and r). */
static bool lvp__level_vectors(lvp__multigrid_level *level, bool finest)
{
	size_t n = (size_t)level->n + 1;
	level->t = malloc(sizeof(double) * n);
	level->inverse = malloc(sizeof(double) * n);
	if (!level->t || !level->inverse)
		return false;
	for (int32_t i = 0; i < level->n; ++i) /* a vertex tied to nothing (degenerate skin) is left at zero */
		level->inverse[i] = level->diagonal[i] > 0.0 ? 1.0 / level->diagonal[i] : 0.0;
	if (finest)
		return true;
	level->x = malloc(sizeof(double) * n);
	level->b = malloc(sizeof(double) * n);
	level->r = malloc(sizeof(double) * n);
	level->y = malloc(sizeof(double) * n);
	return level->x && level->b && level->r && level->y;
}

/* The coarsest system's Cholesky factor (dense, lower, row by row), or false when it is not positive
 * definite to the doubles' precision (then the level is swept instead). */
static bool lvp__factor_coarsest(lvp__multigrid *grid)
{
	const lvp__multigrid_level *level = &grid->levels[grid->level_count - 1];
	int32_t n = level->n;
	if (n > LVP__MULTIGRID_DENSE_LIMIT)
		return false;
	double *l = calloc((size_t)n * (size_t)n + 1, sizeof(double));
	if (!l)
		return false;
	for (int32_t i = 0; i < n; ++i) {
		l[(size_t)i * n + i] = level->diagonal[i];
		for (int32_t e = level->offsets[i]; e < level->offsets[i + 1]; ++e)
			l[(size_t)i * n + level->columns[e]] -= level->coupling[e];
	}
	for (int32_t j = 0; j < n; ++j) {
		double *row_j = l + (size_t)j * n;
		double pivot = row_j[j];
		for (int32_t k = 0; k < j; ++k)
			pivot -= row_j[k] * row_j[k];
		if (!(pivot > 1e-12 * level->diagonal[j])) {
			free(l);
			return false;
		}
		row_j[j] = sqrt(pivot);
		for (int32_t i = j + 1; i < n; ++i) {
			double *row_i = l + (size_t)i * n, sum = row_i[j];
			for (int32_t k = 0; k < j; ++k)
				sum -= row_i[k] * row_j[k];
			row_i[j] = sum / row_j[j];
		}
	}
	grid->factor = l;
	return true;
}

bool lvp__multigrid_build(lvp__multigrid *grid, int32_t n, const int32_t *offsets, const int32_t *columns,
                          const double *coupling, const double *diagonal)
{
	memset(grid, 0, sizeof(*grid));
	lvp__multigrid_level *finest = &grid->levels[0];
	finest->n = n;
	finest->offsets = (int32_t *)offsets;
	finest->columns = (int32_t *)columns;
	finest->coupling = (double *)coupling;
	finest->diagonal = (double *)diagonal;
	grid->level_count = 1;
	if (!lvp__level_vectors(finest, true))
		goto failed;
	while (grid->level_count < LVP__MULTIGRID_MAX_LEVELS && grid->levels[grid->level_count - 1].n >
	                                                            LVP__MULTIGRID_COARSEST) {
		lvp__multigrid_level *fine = &grid->levels[grid->level_count - 1];
		fine->aggregate = malloc(sizeof(int32_t) * ((size_t)fine->n + 1));
		if (!fine->aggregate)
			goto failed;
		int32_t count = lvp__aggregate(fine);
		if ((double)count > LVP__MULTIGRID_SLOW_COARSENING * (double)fine->n) {
			free(fine->aggregate);
			fine->aggregate = NULL;
			break;
		}
		lvp__multigrid_level *coarse = &grid->levels[grid->level_count++];
		if (!lvp__coarsen(fine, coarse, count) || !lvp__level_vectors(coarse, false))
			goto failed;
	}
	lvp__factor_coarsest(grid); /* without a factor the coarsest level is swept */
	return true;
failed:
	lvp__multigrid_free(grid);
	return false;
}

/* `start` plus vertex i's couplings times its neighbours' x, added in order. */
static inline double lvp__add_coupled(const lvp__multigrid_level *level, const double *x, int32_t i, double start)
{
	double sum = start;
	for (int32_t e = level->offsets[i]; e < level->offsets[i + 1]; ++e)
		sum += level->coupling[e] * x[level->columns[e]];
	return sum;
}

/* Vertex i's residual b - A x on the level. */
static inline double lvp__residual(const lvp__multigrid_level *level, const double *b, const double *x, int32_t i)
{
	return lvp__add_coupled(level, x, i, b[i] - level->diagonal[i] * x[i]);
}

/* Gauss-Seidel over the level, x updated in place against b: forward (first to last) or backward. */
static void lvp__sweep(const lvp__multigrid_level *level, const double *b, double *x, bool forward)
{
	int32_t n = level->n;
	for (int32_t s = 0; s < n; ++s) {
		int32_t i = forward ? s : n - 1 - s;
		x[i] = lvp__add_coupled(level, x, i, b[i]) * level->inverse[i];
	}
}

/* The coarsest level's x against b: exactly, or by a forward and a backward sweep from zero. */
static void lvp__solve_coarsest(const lvp__multigrid *grid, lvp__multigrid_level *level, const double *b, double *x)
{
	int32_t n = level->n;
	if (!grid->factor) {
		memset(x, 0, sizeof(double) * (size_t)n);
		lvp__sweep(level, b, x, true);
		lvp__sweep(level, b, x, false);
		return;
	}
	const double *l = grid->factor;
	double *y = level->t;
	for (int32_t i = 0; i < n; ++i) {
		double sum = b[i];
		for (int32_t k = 0; k < i; ++k)
			sum -= l[(size_t)i * n + k] * y[k];
		y[i] = sum / l[(size_t)i * n + i];
	}
	for (int32_t i = n - 1; i >= 0; --i) {
		double sum = y[i];
		for (int32_t k = i + 1; k < n; ++k)
			sum -= l[(size_t)k * n + i] * x[k];
		x[i] = sum / l[(size_t)i * n + i];
	}
}

/* One cycle at level l: x against b (the level's own vectors below it are the cycle's scratch). Down: a
 * forward sweep from zero; the residual, summed over each aggregate, is the next level's right-hand side,
 * which two cycles of that level answer (the second against what the first left; a W-cycle: one cycle's
 * error grows with the levels below it, two's does not). Up: each vertex takes its aggregate's correction,
 * then a backward sweep. */
static void lvp__cycle(lvp__multigrid *grid, int32_t l, const double *b, double *x)
{
	lvp__multigrid_level *level = &grid->levels[l];
	if (l == grid->level_count - 1) {
		lvp__solve_coarsest(grid, level, b, x);
		return;
	}
	lvp__multigrid_level *coarse = &grid->levels[l + 1];
	memset(x, 0, sizeof(double) * (size_t)level->n);
	lvp__sweep(level, b, x, true);
	memset(coarse->b, 0, sizeof(double) * (size_t)coarse->n);
	for (int32_t i = 0; i < level->n; ++i)
		coarse->b[level->aggregate[i]] += lvp__residual(level, b, x, i);
	lvp__cycle(grid, l + 1, coarse->b, coarse->x);
	for (int32_t i = 0; i < coarse->n; ++i)
		coarse->r[i] = lvp__residual(coarse, coarse->b, coarse->x, i);
	lvp__cycle(grid, l + 1, coarse->r, coarse->y);
	for (int32_t i = 0; i < level->n; ++i)
		x[i] += coarse->x[level->aggregate[i]] + coarse->y[level->aggregate[i]];
	lvp__sweep(level, b, x, false);
}

void lvp__multigrid_apply(lvp__multigrid *grid, const double *r, double *z)
{
	lvp__cycle(grid, 0, r, z);
}
