/*
 * region_system.c - the storage and the solve of the coupled region system of a correction step
 * (correction.c: sum_t M_st mu_t = rhs_s over the active regions).
 *
 * The unknowns are groups of regions (lvp.h, GROUPS; a region alone is a group of one), each
 * named by its first region, its leader: a group's row sums its regions' volume answers, its
 * column is what its one multiplier does through all of them.
 *
 * Which regions couple is known at bind: region t's multiplier moves the vertices that bone t
 * weights, and region s's volume answers at the corners of its triangles, so M_st can be nonzero
 * only when some corner of s's triangles has a weight of t. On a skeleton that is a few
 * neighbours per region (the bones a joint blends), so the system is stored by its profile, not
 * densely: the regions are ordered once at bind to keep coupled ones close (reverse
 * Cuthill-McKee on the coupling graph: a chain of bones becomes a band of width one, a bone that
 * blends with many, such as a head under a face rig's bones, comes after most of them and makes
 * an arrow),
 * and a step lays out its active regions in that order. Row i is stored from its first coupled
 * column to the diagonal, column i from its first coupled row to above the diagonal (one first
 * index for both: the coupling is taken both ways). An LU without pivoting keeps its fill inside
 * that profile, so a step costs what its band costs, not m^3, and the memory is that of the
 * profile, not m^2.
 *
 * Without pivoting, a pivot that comes out negligible against its row's diagonal means a system
 * the LU cannot trust (near singular, as where no multipliers tell regions apart, or one that
 * would need rows swapped); the step is then solved in damped least squares, on the normal
 * equations, whose matrix is symmetric positive definite and needs no pivoting.
 */
#include "binding.h"

#include <stdlib.h>

/* A pivot of the LU smaller than this share of its row's diagonal fails the solve (and sends
 * the step to least squares). */
#define LVP__PIVOT_SHARE 1e-9

/* The damping of least squares: (J^T J + lambda diag(J^T J)) mu = J^T rhs. */
#define LVP__DAMPING 1e-9

/* ---- the profile ------------------------------------------------------------------------------ */

/* Offsets of rows and columns [0, count) of a profile whose first[] is set, in storage order
 * (row i's lower part and diagonal, then column i's upper part), as far as `capacity` cells
 * go. Returns how many rows fit; sets count and cells to them. */
static int32_t lvp__lay_out(lvp__profile *profile, int32_t count, int64_t capacity)
{
	int64_t cells = 0;
	int32_t i = 0;
	for (; i < count; ++i) {
		int64_t width = i - profile->first[i], row_cells = 2 * width + 1;
		if (cells + row_cells > capacity)
			break;
		profile->lower[i] = (int32_t)(cells - profile->first[i]);
		profile->upper[i] = (int32_t)(cells + width + 1 - profile->first[i]);
		cells += row_cells;
	}
	profile->count = i;
	profile->cells = (int32_t)cells;
	return i;
}

/* Solves a x = b in place (a: the profile's cells, overwritten by its LU; x: b on entry), by LU
 * without pivoting (Doolittle, row by row: row i of L and column i of U only read rows and
 * columns before i, inside the profile). Returns false when a pivot is negligible against its
 * diagonal or the solution is not finite. */
static bool lvp__profile_solve(double *a, const lvp__profile *profile, double *x)
{
	const int32_t *first = profile->first, *lower = profile->lower, *upper = profile->upper;
	int32_t m = profile->count;
	for (int32_t i = 0; i < m; ++i) {
		double *row = a + lower[i], *column = a + upper[i]; /* row[j] = L_ij, column[j] = U_ji */
		int32_t first_i = first[i];
		for (int32_t j = first_i; j < i; ++j) {
			const double *row_j = a + lower[j], *column_j = a + upper[j];
			int32_t from = first[j] > first_i ? first[j] : first_i;
			double u = column[j], l = row[j];
			for (int32_t k = from; k < j; ++k) {
				u -= row_j[k] * column[k];
				l -= row[k] * column_j[k];
			}
			column[j] = u;
			row[j] = l / row_j[j];
		}
		double diagonal = row[i], pivot = diagonal;
		for (int32_t k = first_i; k < i; ++k)
			pivot -= row[k] * column[k];
		if (!(fabs(pivot) > LVP__PIVOT_SHARE * fabs(diagonal)))
			return false;
		row[i] = pivot;
	}
	for (int32_t i = 0; i < m; ++i) {
		const double *row = a + lower[i];
		double sum = x[i];
		for (int32_t k = first[i]; k < i; ++k)
			sum -= row[k] * x[k];
		x[i] = sum;
	}
	for (int32_t i = m - 1; i >= 0; --i) {
		const double *column = a + upper[i];
		x[i] /= a[lower[i] + i];
		if (!isfinite(x[i]))
			return false;
		for (int32_t k = first[i]; k < i; ++k)
			x[k] -= column[k] * x[i];
	}
	return true;
}

/* ---- at bind: the groups, the coupling and the order ------------------------------------------ */

/* The groups (lvp.h, GROUPS): region r belongs with the regions whose caller bones have its
 * bone's bone_groups value, in its part; the first of them leads. Without bone_groups (or in the
 * global mode) every region leads a group of itself. */
static bool lvp__build_groups(lvp_binding *binding, const int32_t *bone_groups)
{
	int32_t s = binding->region_count;
	lvp__region_system *system = &binding->system;
	bool ok = true;
	system->group_leader = lvp__calloc((size_t)s, sizeof(int32_t), &ok);
	system->group_offsets = lvp__calloc((size_t)s + 1, sizeof(int32_t), &ok);
	system->group_regions = lvp__calloc((size_t)s, sizeof(int32_t), &ok);
	uint64_t *keys = bone_groups ? lvp__calloc((size_t)s, sizeof(uint64_t), &ok) : NULL;
	if (!ok) {
		free(keys);
		return false;
	}
	for (int32_t r = 0; r < s; ++r)
		system->group_leader[r] = r;
	if (keys) {
		/* (group, part) in the high half, the region in the low: sorted, each group's regions are
		 * one run in region order, its leader first. */
		uint64_t parts = (uint64_t)binding->parts.count;
		for (int32_t r = 0; r < s; ++r) {
			uint64_t group = (uint64_t)bone_groups[lvp__caller_bone(binding, r)];
			keys[r] = ((group * parts + (uint64_t)lvp__region_part(binding, r)) << 32) | (uint64_t)r;
		}
		qsort(keys, (size_t)s, sizeof(uint64_t), lvp__compare_u64);
		for (int32_t i = 1; i < s; ++i)
			if (keys[i] >> 32 == keys[i - 1] >> 32)
				system->group_leader[keys[i] & 0xffffffffu] = system->group_leader[keys[i - 1] & 0xffffffffu];
		free(keys);
	}
	for (int32_t r = 0; r < s; ++r)
		system->group_offsets[system->group_leader[r] + 1]++;
	for (int32_t r = 0; r < s; ++r)
		system->group_offsets[r + 1] += system->group_offsets[r];
	int32_t *fill = lvp__calloc((size_t)s, sizeof(int32_t), &ok);
	if (!ok)
		return false;
	for (int32_t r = 0; r < s; ++r) { /* in region order: the leader first */
		int32_t leader = system->group_leader[r];
		system->group_regions[system->group_offsets[leader] + fill[leader]++] = r;
	}
	free(fill);
	return true;
}

/* The groups coupled with each group, both ways, between leaders (coupling_offsets, coupling): t
 * reaching a corner of s's triangles (reach.c), or s one of t's, for some regions s and t of the
 * two groups. Every region of a vertex's reach counts, and its own region, whatever the map
 * (lvp_set_map can change which of them reach it: correction.c, lvp__vertex_support). */
static bool lvp__build_coupling(lvp_binding *binding)
{
	int32_t s = binding->region_count;
	binding->system.coupling_offsets = calloc((size_t)s + 1, sizeof(int32_t));
	int32_t *seen = malloc(sizeof(int32_t) * (size_t)(s > 0 ? s : 1));
	size_t count = 0, capacity = 64;
	uint64_t *pairs = malloc(sizeof(uint64_t) * capacity);
	bool ok = binding->system.coupling_offsets && seen && pairs;
	for (int32_t r = 0; r < s && ok; ++r)
		seen[r] = -1;
	for (int32_t r = 0; r < s && ok && binding->reach.offsets; ++r) {
		seen[r] = r;
		for (int32_t c = binding->mesh.region_corner_offsets[r]; c < binding->mesh.region_corner_offsets[r + 1] && ok;
		     ++c) {
			int32_t k = binding->mesh.region_corners[c];
			/* the regions that reach it, then its own region (a vertex without weight has one too) */
			for (int32_t w = binding->reach.offsets[k]; w <= binding->reach.offsets[k + 1]; ++w) {
				int32_t t = w < binding->reach.offsets[k + 1] ? binding->reach.regions[w]
				                                              : binding->mesh.vertex_region[k];
				if (t < 0 || t >= s || seen[t] == r)
					continue;
				seen[t] = r;
				int32_t row = binding->system.group_leader[r], column = binding->system.group_leader[t];
				if (row == column)
					continue;
				if (count + 2 > capacity) {
					uint64_t *grown = realloc(pairs, sizeof(uint64_t) * capacity * 2);
					if (!grown) {
						ok = false;
						break;
					}
					pairs = grown;
					capacity *= 2;
				}
				pairs[count++] = (uint64_t)row * (uint64_t)s + (uint64_t)column;
				pairs[count++] = (uint64_t)column * (uint64_t)s + (uint64_t)row;
			}
		}
	}
	if (ok) {
		qsort(pairs, count, sizeof(uint64_t), lvp__compare_u64);
		size_t unique = 0;
		for (size_t i = 0; i < count; ++i)
			if (i == 0 || pairs[i] != pairs[i - 1])
				pairs[unique++] = pairs[i];
		binding->system.coupling = malloc(sizeof(int32_t) * (unique > 0 ? unique : 1));
		ok = binding->system.coupling != NULL;
		for (size_t i = 0; i < unique && ok; ++i) {
			binding->system.coupling[i] = (int32_t)(pairs[i] % (uint64_t)s);
			binding->system.coupling_offsets[pairs[i] / (uint64_t)s + 1]++;
		}
		for (int32_t r = 0; r < s && ok; ++r)
			binding->system.coupling_offsets[r + 1] += binding->system.coupling_offsets[r];
	}
	free(seen);
	free(pairs);
	return ok;
}

/* solve_order: reverse Cuthill-McKee over the coupling. Each connected set of regions starts from
 * its least coupled region (the end of a chain) and is walked breadth first, each region's new
 * neighbours taken least coupled first; the whole order is then reversed, which keeps the band of
 * Cuthill-McKee and shrinks its profile (a region coupled with many comes after them). */
static bool lvp__order_regions(lvp_binding *binding)
{
	int32_t s = binding->region_count, *order = binding->system.solve_order;
	const int32_t *offsets = binding->system.coupling_offsets;
	int32_t *by_degree = malloc(sizeof(int32_t) * (size_t)(s > 0 ? s : 1));
	int32_t *counts = calloc((size_t)s + 1, sizeof(int32_t));
	uint8_t *placed_already = calloc((size_t)s + 1, 1);
	bool ok = by_degree && counts && placed_already;
	if (ok) {
		/* The regions by coupling count (a counting sort, stable): where each set starts. */
		for (int32_t r = 0; r < s; ++r)
			counts[offsets[r + 1] - offsets[r]]++;
		for (int32_t d = 0, sum = 0; d <= s; ++d) {
			int32_t here = counts[d];
			counts[d] = sum;
			sum += here;
		}
		for (int32_t r = 0; r < s; ++r)
			by_degree[counts[offsets[r + 1] - offsets[r]]++] = r;
		int32_t placed = 0;
		for (int32_t c = 0; c < s; ++c) {
			int32_t start = by_degree[c];
			if (placed_already[start])
				continue;
			placed_already[start] = 1;
			order[placed++] = start;
			for (int32_t head = placed - 1; head < placed; ++head) {
				int32_t r = order[head], first_new = placed;
				for (int32_t e = offsets[r]; e < offsets[r + 1]; ++e) {
					int32_t t = binding->system.coupling[e];
					if (placed_already[t])
						continue;
					placed_already[t] = 1;
					/* insertion by coupling count, ties in region order (coupling is sorted) */
					int32_t degree = offsets[t + 1] - offsets[t], at = placed++;
					while (at > first_new && offsets[order[at - 1] + 1] - offsets[order[at - 1]] > degree) {
						order[at] = order[at - 1];
						--at;
					}
					order[at] = t;
				}
			}
		}
		for (int32_t i = 0; i < s / 2; ++i) {
			int32_t t = order[i];
			order[i] = order[s - 1 - i];
			order[s - 1 - i] = t;
		}
	}
	free(by_degree);
	free(counts);
	free(placed_already);
	return ok;
}

/* first[i] of the system over active[0..m) (active_index set): the first active region coupled
 * with region i, or i. */
static void lvp__system_firsts(lvp_binding *binding, int32_t m)
{
	for (int32_t i = 0; i < m; ++i) {
		int32_t r = binding->step.active[i], first = i;
		for (int32_t e = binding->system.coupling_offsets[r]; e < binding->system.coupling_offsets[r + 1]; ++e) {
			int32_t j = binding->step.active_index[binding->system.coupling[e]];
			first = j >= 0 && j < first ? j : first;
		}
		binding->system.profile.first[i] = first;
	}
}

/* The normal equations' profile for the system's (row r of the system spans columns first[r] to
 * row_last[r]; the normal matrix couples every two columns of one row): lays it out within
 * normal_capacity; returns whether it fits. */
static bool lvp__normal_layout(lvp_binding *binding)
{
	const lvp__profile *system = &binding->system.profile;
	lvp__profile *normal = &binding->system.normal_profile;
	int32_t m = system->count, *last = binding->system.row_last;
	for (int32_t r = 0; r < m; ++r) {
		last[r] = r;
		normal->first[r] = r;
	}
	for (int32_t j = 0; j < m; ++j)
		for (int32_t r = system->first[j]; r < j; ++r)
			last[r] = j;
	for (int32_t r = 0; r < m; ++r)
		for (int32_t b = system->first[r]; b <= last[r]; ++b)
			normal->first[b] = system->first[r] < normal->first[b] ? system->first[r] : normal->first[b];
	return lvp__lay_out(normal, m, binding->system.normal_capacity) == m;
}

lvp_result lvp__build_region_system(lvp_binding *binding, const int32_t *bone_groups, lvp_diagnostic *r_diag)
{
	int32_t s = binding->region_count;
	size_t n = s > 0 ? (size_t)s : 1;
	binding->system.solve_order = malloc(sizeof(int32_t) * n);
	binding->system.profile.first = malloc(sizeof(int32_t) * n);
	binding->system.profile.lower = malloc(sizeof(int32_t) * n);
	binding->system.profile.upper = malloc(sizeof(int32_t) * n);
	binding->system.normal_profile.first = malloc(sizeof(int32_t) * n);
	binding->system.normal_profile.lower = malloc(sizeof(int32_t) * n);
	binding->system.normal_profile.upper = malloc(sizeof(int32_t) * n);
	binding->system.row_last = malloc(sizeof(int32_t) * n);
	binding->system.still = malloc(n);
	binding->system.column_gain = malloc(sizeof(double) * n);
	binding->system.row_sums = malloc(sizeof(double) * n);
	binding->system.rhs = malloc(sizeof(double) * n);
	binding->system.solution = malloc(sizeof(double) * n);
	binding->system.row_values = malloc(sizeof(double) * n);
	binding->system.place = malloc(sizeof(lvp__system_place) * n);
	bool ok = binding->system.solve_order && binding->system.profile.first && binding->system.profile.lower &&
	          binding->system.profile.upper && binding->system.normal_profile.first &&
	          binding->system.normal_profile.lower && binding->system.normal_profile.upper &&
	          binding->system.row_last && binding->system.still && binding->system.column_gain &&
	          binding->system.row_sums && binding->system.rhs && binding->system.solution &&
	          binding->system.row_values && binding->system.place;
	ok = ok && lvp__build_groups(binding, bone_groups) && lvp__build_coupling(binding) && lvp__order_regions(binding);
	if (ok) {
		/* The capacities: the profiles of every region active at once (a step's, of fewer
		 * regions, is never larger: compacting an order only brings coupled regions closer),
		 * up to LVP__SYSTEM_CELLS each. */
		for (int32_t i = 0; i < s; ++i) {
			binding->step.active[i] = binding->system.solve_order[i];
			binding->step.active_index[binding->system.solve_order[i]] = i;
		}
		lvp__system_firsts(binding, s);
		binding->system.capacity = LVP__SYSTEM_CELLS;
		binding->system.normal_capacity = LVP__SYSTEM_CELLS;
		if (lvp__lay_out(&binding->system.profile, s, LVP__SYSTEM_CELLS) == s) {
			binding->system.capacity = binding->system.profile.cells;
			if (lvp__normal_layout(binding))
				binding->system.normal_capacity = binding->system.normal_profile.cells;
		}
		for (int32_t i = 0; i < s; ++i)
			binding->step.active_index[i] = -1;
		binding->system.profile.count = binding->system.normal_profile.count = 0;
		binding->system.profile.cells = binding->system.normal_profile.cells = 0;
		size_t system = (size_t)binding->system.capacity, block = LVP__ASSEMBLY_BLOCK(system, n);
		binding->system.matrix = malloc(sizeof(double) * system);
		binding->system.factor = malloc(sizeof(double) * system);
		binding->system.normal = malloc(sizeof(double) * (size_t)binding->system.normal_capacity);
		binding->system.assembly = malloc(sizeof(double) * block * LVP__ASSEMBLY_CHUNKS);
		binding->system.assembly_block = block;
		ok = binding->system.matrix && binding->system.factor && binding->system.normal && binding->system.assembly;
	}
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "out of memory while binding (the region system of %d regions).", (int)s);
	return lvp_success;
}

/* ---- per step ----------------------------------------------------------------------------------- */

int32_t lvp__system_layout(lvp_binding *binding, int32_t m)
{
	lvp__system_firsts(binding, m);
	const lvp__profile *p = &binding->system.profile;
	int32_t held = lvp__lay_out(&binding->system.profile, m, binding->system.capacity);
	lvp__system_place outside = {held, INT32_MAX, 0, 0};
	for (int32_t r = 0; r < binding->region_count; ++r)
		binding->system.place[r] = outside;
	for (int32_t i = 0; i < held; ++i) {
		lvp__system_place place = {i, p->first[i], p->lower[i], p->upper[i]};
		int32_t first, last; /* every region of the group answers to its place */
		lvp__group_range(binding, binding->step.active[i], &first, &last);
		for (int32_t g = first; g < last; ++g)
			binding->system.place[binding->system.group_regions[g]] = place;
	}
	return held;
}

void lvp__sum_system(lvp_binding *binding)
{
	const lvp__profile *p = &binding->system.profile;
	double *system = binding->system.matrix;
	bool by_rows = lvp__assembled_by_rows(binding);
	memset(system, 0, sizeof(double) * (size_t)p->cells);
	for (int32_t chunk = 0; chunk < binding->system.assembly_chunks; ++chunk) {
		const double *sums = binding->system.assembly + (size_t)chunk * binding->system.assembly_block;
		if (!by_rows) {
			for (int32_t c = 0; c < p->cells; ++c)
				system[c] += sums[c];
			continue;
		}
		/* Row by row: what is outside the profile there is zero (binding.h, coupling). */
		size_t stride = (size_t)p->count + 1;
		for (int32_t i = 0; i < p->count; ++i)
			for (int32_t j = p->first[i]; j < i; ++j) {
				system[p->lower[i] + j] += sums[i * stride + j];
				system[p->upper[i] + j] += sums[j * stride + i];
			}
		for (int32_t i = 0; i < p->count; ++i)
			system[p->lower[i] + i] += sums[i * stride + i];
	}
	/* Each block's gains follow its sums (binding.h, LVP__ASSEMBLY_BLOCK). */
	size_t gains_at = lvp__assembly_gains_at(binding);
	memset(binding->system.column_gain, 0, sizeof(double) * (size_t)p->count);
	for (int32_t chunk = 0; chunk < binding->system.assembly_chunks; ++chunk) {
		const double *gains = binding->system.assembly + (size_t)chunk * binding->system.assembly_block + gains_at;
		for (int32_t j = 0; j < p->count; ++j)
			binding->system.column_gain[j] += gains[j];
	}
}

void lvp__system_row_sums(lvp_binding *binding)
{
	double *r_sums = binding->system.row_sums;
	const lvp__profile *p = &binding->system.profile;
	const double *a = binding->system.matrix;
	for (int32_t i = 0; i < p->count; ++i) {
		double sum = 0.0;
		for (int32_t j = p->first[i]; j <= i; ++j)
			sum += a[p->lower[i] + j];
		r_sums[i] = sum;
	}
	for (int32_t j = 0; j < p->count; ++j)
		for (int32_t i = p->first[j]; i < j; ++i)
			r_sums[i] += a[p->upper[j] + i];
}

/* Regions that cannot move (zero map around them: a negligible diagonal) are taken out of the
 * system: their row and column zero, their diagonal 1, their right-hand side 0. */
static void lvp__take_out_still_regions(lvp_binding *binding, double largest_diagonal)
{
	const lvp__profile *p = &binding->system.profile;
	double *a = binding->system.matrix;
	bool any = false;
	for (int32_t i = 0; i < p->count; ++i) {
		binding->system.still[i] = !(fabs(a[p->lower[i] + i]) > 1e-12 * largest_diagonal);
		any = any || binding->system.still[i];
	}
	if (!any)
		return;
	for (int32_t i = 0; i < p->count; ++i) {
		for (int32_t j = p->first[i]; j < i; ++j) {
			if (binding->system.still[i] || binding->system.still[j])
				a[p->lower[i] + j] = a[p->upper[i] + j] = 0.0;
		}
		if (binding->system.still[i]) {
			a[p->lower[i] + i] = 1.0;
			binding->system.rhs[i] = 0.0;
		}
	}
}

/* The damped least-squares solution of the system (J, after the still regions are out) into
 * solution: (J^T J + lambda diag(J^T J)) mu = J^T rhs, the normal matrix summed row by row of J
 * over the row's span. Returns false when its profile does not fit or it cannot be solved. */
static bool lvp__least_squares(lvp_binding *binding)
{
	if (!lvp__normal_layout(binding))
		return false;
	const lvp__profile *p = &binding->system.profile, *np = &binding->system.normal_profile;
	const double *a = binding->system.matrix, *rhs = binding->system.rhs;
	double *normal = binding->system.normal, *x = binding->system.row_values, *solution = binding->system.solution;
	int32_t m = p->count;
	memset(normal, 0, sizeof(double) * (size_t)np->cells);
	memset(solution, 0, sizeof(double) * (size_t)m);
	for (int32_t r = 0; r < m; ++r) {
		int32_t from = p->first[r], to = binding->system.row_last[r];
		for (int32_t c = from; c <= r; ++c)
			x[c] = a[p->lower[r] + c];
		for (int32_t c = r + 1; c <= to; ++c)
			x[c] = p->first[c] <= r ? a[p->upper[c] + r] : 0.0;
		for (int32_t i = from; i <= to; ++i) {
			if (x[i] == 0.0)
				continue;
			solution[i] += x[i] * rhs[r];
			double *normal_row = normal + np->lower[i]; /* columns from..i of row i */
			for (int32_t j = from; j <= i; ++j)
				normal_row[j] += x[i] * x[j];
		}
	}
	for (int32_t i = 0; i < m; ++i) {
		for (int32_t j = np->first[i]; j < i; ++j)
			normal[np->upper[i] + j] = normal[np->lower[i] + j]; /* symmetric */
		normal[np->lower[i] + i] *= 1.0 + LVP__DAMPING;
	}
	return lvp__profile_solve(normal, np, solution);
}

bool lvp__solve_system(lvp_binding *binding, double largest_diagonal)
{
	const lvp__profile *p = &binding->system.profile;
	if (p->count == 0)
		return false;
	lvp__take_out_still_regions(binding, largest_diagonal);
	memcpy(binding->system.factor, binding->system.matrix, sizeof(double) * (size_t)p->cells);
	memcpy(binding->system.solution, binding->system.rhs, sizeof(double) * (size_t)p->count);
	return lvp__profile_solve(binding->system.factor, p, binding->system.solution) || lvp__least_squares(binding);
}

void lvp__region_system_free(lvp__region_system *system)
{
	void *arrays[] = {system->group_leader, system->group_offsets, system->group_regions,
	                  system->coupling_offsets, system->coupling, system->solve_order, system->profile.first,
	                  system->profile.lower, system->profile.upper, system->normal_profile.first,
	                  system->normal_profile.lower, system->normal_profile.upper, system->place, system->matrix,
	                  system->factor, system->normal, system->assembly, system->column_gain, system->row_sums,
	                  system->rhs, system->solution, system->row_values, system->row_last, system->still};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
