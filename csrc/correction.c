/*
 * correction.c - paper 3.2-3.3 (eq. 4, 5) and 5.3: the closed-form volume correction along
 * the normals, per region, repeated on re-measured volumes until every region is within the
 * tolerance (the paper's single pass leaves its linearization error; we do not stop there).
 *
 * With displacements rho_k n_k, rho_k = gamma_k (g_k / A_k) sum_t phi_kt mu_t (minimum of
 * sum A_k rho_k^2 / gamma_k, the displacement measured over the surface, along the directions
 * the map allows; A_k the rest vertex area, map.c), the linearized change of region s is
 * kappa_s sum_k g_sk rho_k, so the multipliers solve the small system
 *     sum_t M_st mu_t = -change_s,   M_st = kappa_s sum_k g_sk gamma_k (g_k / A_k) phi_kt,
 * over the regions whose volume changed. frame_map.gamma carries gamma_k / A_k (times the mean
 * area), so the code reads gamma g. With one region and equal areas this is eq. 5 exactly:
 * mu = -change / sum gamma g^2. Coupling matters where two regions' corrections overlap (the
 * weight band of a joint): solving the regions one by one would correct that band twice.
 */
#include "binding.h"

#include <stdlib.h>

/* A correction step that leaves more than this share of the error norm ends the coupled
 * iteration (lvp__volume_iterations). */
#define LVP__LEAST_GAIN 0.9
/* Halvings of a step through the map that leaves the volume further off (lvp__global_steps). */
#define LVP__STEP_HALVINGS 4

/* Rounds of (volume step, contact test) after the first contact test of fold-over prevention. */
#define LVP__FOLD_ROUNDS 4
/* Volume corrections again after shortening offsets to keep skin apart, at most. Each restores what
 * the check before it took, and the check after it takes less again; what the last check takes stays
 * lost, so where skin keeps meeting skin (a low-poly leg folded under a body, with fold-over) too few
 * cycles leave the volume short by a visible share. Where the checks stop shortening early, as they
 * do at most poses, the cycles left cost nothing. */
#define LVP__CONTACT_CYCLES 8
/* Rounds of fading the offsets that near other skin and restoring the volume elsewhere, at most
 * (clearance.c): restoring grows the faded offsets too, a little less each round; what the last
 * leaves beyond their room, the crossing test after them takes. */
#define LVP__CLEARANCE_CYCLES 3

static lvp_result lvp__check_frame_options(const lvp_frame_options *options, lvp_diagnostic *r_diag)
{
	if (options->max_iterations < 1 || options->max_iterations > 1000)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.max_iterations", -1,
		                 "options.max_iterations is %d; it must be between 1 and 1000.", (int)options->max_iterations);
	if (!(options->tolerance > 0.0f && options->tolerance < 1.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.tolerance", -1,
		                 "options.tolerance is %g; it must be above 0 and below 1 (a relative volume).",
		                 (double)options->tolerance);
	if (options->restore != LVP_RESTORE_EACH_REGION && options->restore != LVP_RESTORE_WHOLE_MESH)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.restore", -1,
		                 "options.restore is %d; use LVP_RESTORE_EACH_REGION (0) or LVP_RESTORE_WHOLE_MESH (1).",
		                 (int)options->restore);
	if (options->smoothing_passes < 0 || options->smoothing_passes > LVP_MAX_SMOOTHING_PASSES)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.smoothing_passes", -1,
		                 "options.smoothing_passes is %d; it must be between 0 (none, the paper's) and %d passes.",
		                 (int)options->smoothing_passes, LVP_MAX_SMOOTHING_PASSES);
	if (!(options->displacement_limit >= 0.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.displacement_limit", -1,
		                 "options.displacement_limit is %g; use 0 or infinity (no limit), or a distance above 0.",
		                 (double)options->displacement_limit);
	if (options->rigid_space) {
		lvp_result result = lvp__check_float_array(options->rigid_space, 16, "options.rigid_space", r_diag);
		if (result)
			return result;
		lvp__mat4 space = lvp__mat4_load(options->rigid_space), inverse;
		if (!lvp__mat4_invert_affine(&inverse, &space))
			return lvp__fail(r_diag, lvp_error_invalid_option, "options.rigid_space", -1,
			                 "options.rigid_space cannot be inverted (a zero or collapsed scale); pass the map from "
			                 "the mesh's coordinates to the armature's, or NULL.");
	}
	return lvp_success;
}


/* Moves vertex k by rho along its normal, remembering where it was in moved[slot] and
 * step_backup (lvp__undo_step). A single step moves a vertex by at most a quarter of the mesh's
 * size: a pose folded onto itself (a joint bent near 180 degrees) can make the linearization
 * meaningless, and no sane correction needs more in one step. */
static void lvp__move_vertex(lvp_binding *binding, int32_t k, float rho, int32_t slot)
{
	float limit = (float)(0.25 * binding->size);
	rho = rho > limit ? limit : (rho < -limit ? -limit : rho);
	float *p = binding->step.positions + 3 * k, *backup = binding->step.backup + 3 * slot;
	backup[0] = p[0];
	backup[1] = p[1];
	backup[2] = p[2];
	p[0] += rho * binding->measure.normals[3 * k];
	p[1] += rho * binding->measure.normals[3 * k + 1];
	p[2] += rho * binding->measure.normals[3 * k + 2];
	binding->step.moved[slot] = k;
}

/* Moves vertex k by mu times its smoothed offset (step.smoothing_offsets), remembering it as
 * lvp__move_vertex does, with the same bound on the step. */
static void lvp__move_vertex_along_offset(lvp_binding *binding, int32_t k, double mu, int32_t slot)
{
	const float *o = binding->step.smoothing_offsets + 3 * k;
	double d[3] = {mu * o[0], mu * o[1], mu * o[2]};
	double length = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), limit = 0.25 * binding->size;
	double scale = length > limit ? limit / length : 1.0;
	float *p = binding->step.positions + 3 * k, *backup = binding->step.backup + 3 * slot;
	for (int c = 0; c < 3; ++c) {
		backup[c] = p[c];
		p[c] += (float)(scale * d[c]);
	}
	binding->step.moved[slot] = k;
}

/* Puts the vertices of the last step back where they were. */
static void lvp__undo_step(lvp_binding *binding)
{
	for (int32_t i = 0; i < binding->step.moved_count; ++i)
		memcpy(binding->step.positions + 3 * binding->step.moved[i], binding->step.backup + 3 * i, sizeof(float) * 3);
}

/* The support of vertex k (binding.h, soft_support): the regions whose multipliers reach it,
 * each with its phi_kt (reach.c). Entries with phi <= 0 are none. Read where it is used, vertex by vertex,
 * so a step walks the dynamic vertices in order instead of each region's list of them. */
typedef struct lvp__support {
	const int32_t *regions;
	const float *phi;
	int32_t count;
} lvp__support;

static inline lvp__support lvp__vertex_support(const lvp_binding *binding, int32_t k)
{
	static const int32_t global_region = 0;
	static const float one = 1.0f;
	lvp__support support;
	if (binding->map.soft_support) {
		int32_t begin = binding->reach.offsets[k];
		support.regions = binding->reach.regions + begin;
		support.phi = binding->reach.phi + begin;
		support.count = binding->reach.offsets[k + 1] - begin;
	} else {
		support.regions = binding->mode == LVP_MODE_LOCAL ? binding->mesh.vertex_region + k : &global_region;
		support.phi = &one;
		support.count = 1;
	}
	return support;
}

/* What the solve sees of a group (lvp.h, GROUPS): the sums over its regions of their changes,
 * targets and reference volumes; it is left out when one of its regions is skipped (a singular
 * bone) or none of them can move. A region alone is a group of itself. */
typedef struct lvp__group_state {
	double change, target, reference, reference_change; /* reference_change: the bones' scales' */
	bool skipped, movable;
} lvp__group_state;

static lvp__group_state lvp__group_state_of(const lvp_binding *binding, int32_t leader)
{
	lvp__group_state state = {0.0, 0.0, 0.0, 0.0, false, false};
	int32_t first, last;
	lvp__group_range(binding, leader, &first, &last);
	for (int32_t g = first; g < last; ++g) {
		int32_t r = binding->system.group_regions[g];
		state.change += binding->step.change[r];
		state.target += binding->step.target[r];
		state.reference += binding->measure.reference_volume[r];
		state.reference_change += binding->stretch.change[r];
		state.skipped = state.skipped || binding->rig.region_skipped[r] || binding->step.given_up[r];
		state.movable = state.movable || binding->step.region_movable[r];
	}
	return state;
}

/* Whether region r leads its group (the others answer through it). */
static inline bool lvp__leads(const lvp_binding *binding, int32_t r)
{
	return binding->system.group_leader[r] == r;
}

/* Whether region r leads a group the frame measures (not skipped or given up, with a reference
 * volume), with its state in *r_group. */
static bool lvp__measured_group(const lvp_binding *binding, int32_t r, lvp__group_state *r_group)
{
	if (!lvp__leads(binding, r))
		return false;
	*r_group = lvp__group_state_of(binding, r);
	return !r_group->skipped && r_group->reference > 0.0;
}

/* Moves the dynamic vertices [begin, end) by rho_k n_k, rho_k = gamma_k g_k sum_t phi_kt mu_t (gamma
 * the frame's map, 1 / A_k included)
 * over their support (the step's multipliers in applied_mu), or with step.along_offsets by their
 * part's multiplier times their smoothed offset, listing the moved ones from moved[begin] on;
 * chunk_moved of the chunk says how many. */
static void lvp__apply_loop(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = context;
	const double *applied_mu = binding->step.applied_mu;
	int32_t written = begin;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		if (binding->step.along_offsets) {
			double mu = binding->step.part_mu[binding->parts.vertex_part ? binding->parts.vertex_part[k] : 0];
			const float *o = binding->step.smoothing_offsets + 3 * k;
			if (mu != 0.0 && (o[0] != 0.0f || o[1] != 0.0f || o[2] != 0.0f))
				lvp__move_vertex_along_offset(binding, k, mu, written++);
			continue;
		}
		double sum = 0.0;
		if (binding->step.uniform_step) {
			sum = (double)binding->step.touched_phi[v] * binding->step.uniform_mu;
		} else {
			lvp__support support = lvp__vertex_support(binding, k);
			for (int32_t i = 0; i < support.count; ++i)
				if (support.phi[i] > 0.0f)
					sum += support.phi[i] * applied_mu[support.regions[i]];
		}
		float rho = (float)((double)binding->frame_map.gamma[k] * binding->measure.vertex_g[k] * sum);
		if (rho != 0.0f)
			lvp__move_vertex(binding, k, rho, written++);
	}
	binding->step.chunk_moved[begin / LVP__GRAIN] = written - begin;
}

/* applied_mu of every region of the groups the given leaders lead: the leader's mu, or zero. */
static void lvp__set_applied(lvp_binding *binding, const int32_t *leaders, int32_t count, bool on)
{
	for (int32_t j = 0; j < count; ++j) {
		int32_t first, last;
		lvp__group_range(binding, leaders[j], &first, &last);
		for (int32_t g = first; g < last; ++g) {
			int32_t r = binding->system.group_regions[g];
			binding->step.applied_mu[r] = on ? binding->step.mu[leaders[j]] : 0.0;
			if (on)
				binding->step.moved_by[r] += fabs(binding->step.mu[leaders[j]]);
		}
	}
}

/* Moves step.positions by the multipliers of the given groups (in mu[], by leader), remembering the step
 * (lvp__undo_step). Only dynamic vertices can move (their map is zero otherwise). Split over
 * the threads in chunks of dynamic vertices; the moved list is then closed up in chunk order,
 * the same for any threads. */
static void lvp__apply_multipliers(lvp_binding *binding, const int32_t *regions, int32_t count)
{
	lvp__set_applied(binding, regions, count, true);
	int32_t dynamic = binding->dynamic.vertex_count, chunks = (dynamic + LVP__GRAIN - 1) / LVP__GRAIN;
	for (int32_t i = 0; i < chunks; ++i)
		binding->step.chunk_moved[i] = -1; /* a serial run is one call over all chunks */
	lvp__parallel_for(LVP__POOL_FOR(binding, dynamic), lvp__apply_loop, binding, dynamic, LVP__GRAIN);
	binding->step.moved_count = 0;
	for (int32_t i = 0; i < chunks; ++i) {
		int32_t moved = binding->step.chunk_moved[i], first = i * LVP__GRAIN, to = binding->step.moved_count;
		if (moved <= 0)
			continue;
		if (first != to) {
			memmove(binding->step.moved + to, binding->step.moved + first, sizeof(int32_t) * (size_t)moved);
			memmove(binding->step.backup + 3 * to, binding->step.backup + 3 * first, sizeof(float) * 3 * (size_t)moved);
		}
		binding->step.moved_count += moved;
	}
	lvp__set_applied(binding, regions, count, false);
}

typedef struct lvp__assembly_context {
	lvp_binding *binding;
	int32_t chunk_size;
} lvp__assembly_context;

/* Past the groups the system holds: the diagonal of columns [begin, end) and what they do to
 * the whole mesh (by leader). Only where a step's profile would take more than
 * LVP__SYSTEM_CELLS (binding.h). */
static void lvp__assemble_diagonals(lvp_binding *binding, int32_t begin, int32_t end)
{
	for (int32_t j = begin; j < end; ++j)
		binding->step.diagonal[binding->step.active[j]] = binding->step.total_gain[binding->step.active[j]] = 0.0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		lvp__support support = lvp__vertex_support(binding, k);
		double g = binding->measure.vertex_g[k], gain = (double)binding->frame_map.gamma[k] * g;
		for (int32_t i = 0; i < support.count; ++i) {
			int32_t t = binding->system.group_leader[support.regions[i]];
			int32_t j = binding->step.active_index[t];
			if (j < begin || j >= end)
				continue;
			double weight = gain * support.phi[i];
			binding->step.total_gain[t] += weight * g;
			for (int32_t slot = binding->mesh.slot_offsets[k]; slot < binding->mesh.slot_offsets[k + 1]; ++slot) {
				int32_t s = binding->mesh.slot_region[slot];
				if (s >= 0 && binding->system.group_leader[s] == t)
					binding->step.diagonal[t] += binding->rig.kappa[s] * binding->measure.slot_g[slot] * weight;
			}
		}
	}
}

/* The region system's partial sums over the dynamic vertices [first, last), into one block of
 * binding->system.assembly (binding.h): row s, column t gathers what region t's multiplier does to region
 * s, sum_k kappa_s <n_k, grad_k V_s> gamma_k g_k phi_kt, for the regions of the system (by their
 * place in it, binding.h); the gains, sum_k gamma_k g_k^2 phi_kt, what each column's multiplier
 * does to the whole mesh. Whatever falls outside the system (a region not active, or past the
 * regions it holds) goes to a spare row, cell or gain, so the loop does not branch on it.
 * by_rows: the block is (count + 1)^2 sums, row by row (a small system: the cheapest to index),
 * else the cells of the profile and a spare one. The gains follow the sums. */
static inline void lvp__assemble_range(const lvp_binding *binding, double *sums, int32_t first, int32_t last,
                                       bool by_rows)
{
	int32_t held = binding->system.profile.count, cells = binding->system.profile.cells, stride = held + 1;
	/* Read once: the stores below are doubles, which the compiler must otherwise assume may
	 * change what the binding points to. */
	const lvp__system_place *place = binding->system.place;
	const int32_t *dynamic = binding->dynamic.vertices;
	const int32_t *slot_offsets = binding->mesh.slot_offsets, *slot_region = binding->mesh.slot_region;
	const float *slot_g = binding->measure.slot_g, *vertex_g = binding->measure.vertex_g;
	const double *kappa = binding->rig.kappa;
	const lvp__system_place outside = {held, INT32_MAX, 0, 0}; /* the triangles without region */
	double *gains = sums + lvp__assembly_gains_at(binding);
	memset(sums, 0, sizeof(double) * (size_t)(gains + stride - sums));
	for (int32_t v = first; v < last; ++v) {
		int32_t k = dynamic[v];
		if (!lvp__can_move(binding, k))
			continue;
		lvp__support support = lvp__vertex_support(binding, k);
		double g = vertex_g[k], gain = (double)binding->frame_map.gamma[k] * g;
		for (int32_t slot = slot_offsets[k]; slot < slot_offsets[k + 1]; ++slot) {
			int32_t s = slot_region[slot];
			lvp__system_place row = s >= 0 ? place[s] : outside;
			bool first_slot = slot == slot_offsets[k], in_system = row.index < held;
			if (!first_slot && !in_system)
				continue; /* nothing for this slot; the first one also carries the gains */
			double coefficient = in_system ? kappa[s] * slot_g[slot] : 0.0;
			double *row_sums = sums + (size_t)row.index * (size_t)stride;
			for (int32_t i = 0; i < support.count; ++i) {
				lvp__system_place column = place[support.regions[i]];
				double weight = gain * support.phi[i];
				if (first_slot)
					gains[column.index] += weight * g;
				if (by_rows)
					row_sums[column.index] += coefficient * weight;
				else if (in_system)
					sums[lvp__system_cell(row, column, cells)] += coefficient * weight;
			}
		}
	}
}

/* The assembly of chunks [begin, end) of the dynamic vertices (lvp__assemble_step), each into its
 * block. */
static void lvp__assemble_chunks(void *context, int32_t begin, int32_t end)
{
	const lvp__assembly_context *c = context;
	const lvp_binding *binding = c->binding;
	for (int32_t chunk = begin; chunk < end; ++chunk) {
		double *sums = binding->system.assembly + (size_t)chunk * binding->system.assembly_block;
		int32_t first = chunk * c->chunk_size, last = first + c->chunk_size;
		last = last < binding->dynamic.vertex_count ? last : binding->dynamic.vertex_count;
		if (lvp__assembled_by_rows(binding))
			lvp__assemble_range(binding, sums, first, last, true);
		else
			lvp__assemble_range(binding, sums, first, last, false);
	}
}

static double lvp__error_norm(lvp_binding *binding);

/* The change of the whole mesh, or of each of its separate parts (binding.h), holes capped, from
 * the last measurement: part_change. */
static void lvp__part_changes(lvp_binding *binding)
{
	lvp__pass_part_volumes(binding, binding->step.positions, binding->parts.change);
	for (int32_t p = 0; p < binding->parts.count; ++p)
		binding->parts.change[p] -= binding->parts.rest_volume[p];
}

/* Whether some part is off its rest volume by more than the tolerance (after lvp__part_changes). */
static bool lvp__parts_off(const lvp_binding *binding, double tolerance)
{
	for (int32_t p = 0; p < binding->parts.count; ++p)
		if (fabs(binding->parts.change[p]) > tolerance * binding->parts.scale[p])
			return true;
	return false;
}

/* Sum of the parts' squared relative changes (after lvp__part_changes). */
static double lvp__parts_error(const lvp_binding *binding)
{
	double sum = 0.0;
	for (int32_t p = 0; p < binding->parts.count; ++p) {
		double off = binding->parts.change[p] / binding->parts.scale[p];
		sum += off * off;
	}
	return sum;
}

/* The multiplier added to every active region's of a part (one for the whole mesh when nothing is
 * split), so that the part's volume, answering with its true gradient (total_gain), is restored
 * to first order after the regions' own step mu: part_uniform. Added this way, the uniform part
 * never goes through the region system, which is badly conditioned where many regions overlap
 * (a shoulder). */
static void lvp__uniform_multipliers(lvp_binding *binding, int32_t m)
{
	lvp__part_changes(binding);
	double *total = binding->step.part_total, *gain = binding->step.part_gain;
	for (int32_t p = 0; p < binding->parts.count; ++p) {
		total[p] = binding->parts.change[p];
		gain[p] = 0.0;
	}
	for (int32_t i = 0; i < m; ++i) {
		int32_t t = binding->step.active[i], p = lvp__region_part(binding, t);
		total[p] += binding->step.total_gain[t] * binding->step.mu[t];
		gain[p] += binding->step.total_gain[t];
	}
	for (int32_t p = 0; p < binding->parts.count; ++p) {
		double mu = gain[p] > 0.0 ? -total[p] / gain[p] : 0.0;
		binding->parts.uniform[p] = isfinite(mu) ? mu : 0.0;
	}
}

/* The system of a correction step over the active regions (active[0..m)), and what equal
 * multipliers do to each (uniform_gain). Returns the error norm of the measured state. */
static double lvp__assemble_step(lvp_binding *binding, int32_t m)
{
	const int32_t *active = binding->step.active;
	int32_t held = lvp__system_layout(binding, m);
	for (int32_t i = 0; i < m; ++i)
		binding->step.region_touched[active[i]] = 1;

	/* Assemble in chunks of the dynamic vertices (binding.h), split over the worker threads,
	 * then add the chunks' blocks in order. */
	int32_t dynamic = binding->dynamic.vertex_count;
	int32_t chunk_size = (dynamic + LVP__ASSEMBLY_CHUNKS - 1) / LVP__ASSEMBLY_CHUNKS;
	chunk_size = chunk_size > LVP__GRAIN ? chunk_size : LVP__GRAIN;
	int32_t chunks = (dynamic + chunk_size - 1) / chunk_size;
	lvp__assembly_context context = {binding, chunk_size};
	lvp__parallel_for(LVP__POOL_FOR(binding, binding->step.movable_entries), lvp__assemble_chunks, &context, chunks, 1);
	binding->system.assembly_chunks = chunks;
	lvp__sum_system(binding);
	for (int32_t j = 0; j < held; ++j)
		binding->step.total_gain[active[j]] = binding->system.column_gain[j];
	if (m > held)
		lvp__assemble_diagonals(binding, held, m);
	/* What equal multipliers do to each region: its row of the system (past the regions the
	 * system holds, its diagonal). */
	lvp__system_row_sums(binding);
	for (int32_t i = 0; i < m; ++i)
		binding->step.uniform_gain[active[i]] =
		    i < held ? binding->system.row_sums[i] : binding->step.diagonal[active[i]];
	return lvp__error_norm(binding);
}

/* Solves the assembled system and moves step.positions. */
static void lvp__take_step(lvp_binding *binding, int32_t m)
{
	const int32_t *active = binding->step.active;
	const lvp__profile *profile = &binding->system.profile;
	int32_t held = profile->count;
	/* The regions' own step, towards their targets; each region's diagonal for the per-region
	 * fallback. */
	double largest_diagonal = 0.0;
	for (int32_t i = 0; i < held; ++i) {
		double diagonal = binding->system.matrix[profile->lower[i] + i];
		largest_diagonal = fmax(largest_diagonal, fabs(diagonal));
		binding->step.diagonal[active[i]] = diagonal;
		lvp__group_state group = lvp__group_state_of(binding, active[i]);
		binding->system.rhs[i] = group.target - group.change;
	}
	bool solved = lvp__solve_system(binding, largest_diagonal);
	for (int32_t i = 0; i < m; ++i) {
		int32_t t = active[i];
		double diagonal = binding->step.diagonal[t], mu;
		if (i < held && solved)
			mu = binding->system.solution[i];
		else { /* past the groups the system holds, or a system not solved: the group's own eq. 5 step */
			lvp__group_state group = lvp__group_state_of(binding, t);
			mu = diagonal > 1e-12 * largest_diagonal ? (group.target - group.change) / diagonal : 0.0;
		}
		binding->step.mu[t] = isfinite(mu) ? mu : 0.0;
	}
	memset(binding->parts.uniform, 0, sizeof(double) * (size_t)binding->parts.count);
	if (binding->step.spread_total) {
		/* Each region's target moves by what the uniform part does to it (uniform_gain: its row
		 * of the system, which has no term from another part's regions). */
		lvp__uniform_multipliers(binding, m);
		for (int32_t i = 0; i < m; ++i) {
			int32_t t = active[i];
			double uniform = binding->parts.uniform[lvp__region_part(binding, t)];
			binding->step.mu[t] += uniform;
			binding->step.target[t] += binding->step.uniform_gain[t] * uniform;
		}
	}
	lvp__apply_multipliers(binding, active, m);
}

/* The groups to correct, by leader (lvp.h, GROUPS; a region alone is a group of one). When some
 * group is off its target by more than the tolerance (or, spreading the whole mesh's change, the
 * whole mesh or one of its parts is off its rest volume): that group, and every group already
 * corrected this frame (so that a corrected group is held at its volume while its neighbours are
 * fixed, instead of being let go and disturbed again). Groups the map cannot move are left out.
 * Returns the number of active groups, 0 when all are within tolerance. */
static int32_t lvp__collect_active(lvp_binding *binding, double tolerance)
{
	int32_t m = 0;
	bool any_off = false;
	if (binding->step.spread_total) {
		lvp__part_changes(binding);
		any_off = lvp__parts_off(binding, tolerance);
	}
	for (int32_t r = 0; r < binding->region_count; ++r)
		binding->step.active_index[r] = -1;
	for (int32_t i = 0; i < binding->region_count; ++i) {
		int32_t r = binding->system.solve_order[i]; /* the system's order (region_system.c) */
		lvp__group_state group;
		if (!lvp__measured_group(binding, r, &group) || !group.movable)
			continue;
		bool off = fabs(group.change - group.target) > tolerance * group.reference;
		any_off = any_off || off;
		if (off || binding->step.region_touched[r]) {
			binding->step.active_index[r] = m;
			binding->step.active[m++] = r;
		}
	}
	if (!any_off) {
		for (int32_t i = 0; i < m; ++i)
			binding->step.active_index[binding->step.active[i]] = -1;
		return 0;
	}
	return m;
}

/* Which regions have a vertex in their support that this frame's map lets move (binding.h).
 * Such a vertex is dynamic: the walk is over the dynamic set of the last measurement. */
static void lvp__movable_regions(lvp_binding *binding)
{
	memset(binding->step.region_movable, 0, (size_t)binding->region_count);
	int32_t entries = 0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!(binding->frame_map.gamma[k] > 0.0f))
			continue;
		lvp__support support = lvp__vertex_support(binding, k);
		for (int32_t i = 0; i < support.count; ++i) {
			if (support.phi[i] > 0.0f) {
				binding->step.region_movable[support.regions[i]] = 1;
				++entries;
			}
		}
	}
	binding->step.movable_entries = entries;
}

/* Measures step.positions: the mesh pass, enough for the whole mesh's and the parts' volumes; the
 * regions' changes are left to lvp__measure_changes, for steps that read them. */
static void lvp__measure_sums(lvp_binding *binding, const float *rest_positions, const lvp__region_sums *totals)
{
	lvp__find_dynamic_set(binding, rest_positions, totals, false);
	lvp__mesh_pass(binding, binding->step.positions);
	binding->step.change_stale = true;
}

/* Measures step.positions (mesh pass and region changes). */
static void lvp__measure_positions(lvp_binding *binding, const float *rest_positions, const lvp__region_sums *totals)
{
	lvp__measure_sums(binding, rest_positions, totals);
	lvp__region_changes(binding, binding->step.positions, totals, binding->step.change);
	binding->step.change_stale = false;
}

/* The regions' changes of step.positions, when the last steps measured only the parts' volumes. */
static void lvp__measure_changes(lvp_binding *binding, const lvp__region_sums *totals)
{
	if (!binding->step.change_stale)
		return;
	lvp__region_changes(binding, binding->step.positions, totals, binding->step.change);
	binding->step.change_stale = false;
}

/* The region sums again after a step that moved only binding->step.moved: only their triangles are
 * visited, or, when they are most of the dynamic set, the whole set again (streaming and threaded).
 * Enough for the whole mesh's and the parts' volumes; not for the regions' changes. */
static void lvp__remeasure_sums(lvp_binding *binding)
{
	if (2 * binding->step.moved_count >= binding->dynamic.vertex_count)
		lvp__mesh_pass(binding, binding->step.positions);
	else
		lvp__update_pass(binding, binding->step.positions, binding->step.moved, binding->step.moved_count);
}

/* Measures again after a step (lvp__remeasure_sums), the regions' changes included. */
static void lvp__remeasure(lvp_binding *binding, const lvp__region_sums *totals)
{
	lvp__remeasure_sums(binding);
	lvp__region_changes(binding, binding->step.positions, totals, binding->step.change);
	binding->step.change_stale = false;
}

/* Sum over the groups of their squared relative distance to their targets, and, spreading
 * the whole mesh's change, the whole mesh's (or each part's) squared relative change: what the
 * iterations decrease. */
static double lvp__error_norm(lvp_binding *binding)
{
	double sum = 0.0;
	for (int32_t r = 0; r < binding->region_count; ++r) {
		lvp__group_state group;
		if (!lvp__measured_group(binding, r, &group))
			continue;
		double off = (group.change - group.target) / group.reference;
		sum += off * off;
	}
	if (binding->step.spread_total) {
		lvp__part_changes(binding);
		sum += lvp__parts_error(binding);
	}
	return sum;
}

/* Correct, re-measure, correct... from a measured state, at most `budget` steps; leaves the
 * last measurement of step.positions. Returns the number of steps taken; *r_first_active
 * receives the number of regions corrected by the first one. A step that makes the regions
 * worse overall is undone and ends the iteration, with *r_failed set. So does a step that
 * removes less than a tenth of the error, but it is kept: a Newton step that achieves so little
 * will not be followed by better ones (seen on degenerate input: the fuzzer's). */
static int32_t lvp__volume_iterations(lvp_binding *binding, const lvp_frame_options *options,
                                      const float *rest_positions, const lvp__region_sums *totals, int32_t budget,
                                      int32_t *r_first_active, bool *r_failed)
{
	int32_t steps = 0;
	*r_first_active = 0;
	*r_failed = false;
	while (steps < budget) {
		int32_t m = lvp__collect_active(binding, options->tolerance);
		if (m == 0)
			break;
		if (steps == 0)
			*r_first_active = m;
		lvp__vertex_gradients(binding);
		double before = lvp__assemble_step(binding, m);
		lvp__take_step(binding, m);
		++steps;
		lvp__remeasure(binding, totals);
		double after = lvp__error_norm(binding);
		if (!(after < before)) {
			lvp__undo_step(binding);
			for (int32_t i = 0; i < m; ++i) { /* and the targets it moved */
				int32_t t = binding->step.active[i];
				binding->step.target[t] -=
				    binding->step.uniform_gain[t] * binding->parts.uniform[lvp__region_part(binding, t)];
			}
			lvp__measure_positions(binding, rest_positions, totals);
			*r_failed = true;
			break;
		}
		if (!(after < LVP__LEAST_GAIN * before)) {
			*r_failed = true;
			break;
		}
	}
	for (int32_t r = 0; r < binding->region_count; ++r)
		binding->step.active_index[r] = -1;
	return steps;
}

/* Per dynamic vertex that can move, the sum of its phi over the touched groups (step.touched_phi);
 * zero for the others. With one part every touched group takes the same multiplier, so a vertex
 * moves by gamma g times this sum times it, and the walk over its support is done once per call of
 * lvp__global_steps instead of twice per step. Dynamic vertices [begin, end), each its own. */
static void lvp__touched_phi_loop(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = context;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		double sum = 0.0;
		if (lvp__can_move(binding, k)) {
			lvp__support support = lvp__vertex_support(binding, k);
			for (int32_t i = 0; i < support.count; ++i)
				if (support.phi[i] > 0.0f &&
				    binding->step.region_touched[binding->system.group_leader[support.regions[i]]])
					sum += support.phi[i];
		}
		binding->step.touched_phi[v] = (float)sum;
	}
}

/* A vertex's share of what one multiplier does to the whole mesh's volume (one part), by its place v
 * in the dynamic set. */
typedef double (*lvp__gain_term)(const lvp_binding *binding, int32_t v);

typedef struct lvp__gain_sum {
	lvp_binding *binding;
	lvp__gain_term term;
} lvp__gain_sum;

/* Chunks [begin, end) of LVP__GRAIN dynamic vertices: the sum of the term over each into
 * step.chunk_gain. */
static void lvp__gain_chunks(void *context, int32_t begin, int32_t end)
{
	const lvp__gain_sum *gain = context;
	lvp_binding *binding = gain->binding;
	for (int32_t chunk = begin; chunk < end; ++chunk) {
		int32_t first = chunk * LVP__GRAIN, last = first + LVP__GRAIN;
		last = last < binding->dynamic.vertex_count ? last : binding->dynamic.vertex_count;
		double sum = 0.0;
		for (int32_t v = first; v < last; ++v)
			sum += gain->term(binding, v);
		binding->step.chunk_gain[chunk] = sum;
	}
}

/* The term summed over the dynamic vertices: by chunks in parallel, then the chunks in order, so
 * the same for any threads. */
static double lvp__gain_over_dynamic(lvp_binding *binding, lvp__gain_term term)
{
	lvp__gain_sum gain = {binding, term};
	int32_t chunks = (binding->dynamic.vertex_count + LVP__GRAIN - 1) / LVP__GRAIN;
	lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.vertex_count), lvp__gain_chunks, &gain, chunks, 1);
	double sum = 0.0;
	for (int32_t chunk = 0; chunk < chunks; ++chunk)
		sum += binding->step.chunk_gain[chunk];
	return sum;
}

/* gamma_k g_k^2 touched_phi_k of dynamic vertex v (eq. 5's denominator, one part). */
static double lvp__map_gain(const lvp_binding *binding, int32_t v)
{
	float phi = binding->step.touched_phi[v];
	if (!(phi > 0.0f)) /* g is of the vertices that can move only */
		return 0.0;
	int32_t k = binding->dynamic.vertices[v];
	double g = binding->measure.vertex_g[k];
	return (double)binding->frame_map.gamma[k] * g * g * phi;
}

/* g_k <n_k, o_k> of dynamic vertex v (its volume gradient against its smoothed offset), or 0 for
 * one that cannot move. */
static double lvp__offset_gain(const lvp_binding *binding, int32_t v)
{
	int32_t k = binding->dynamic.vertices[v];
	if (!lvp__can_move(binding, k))
		return 0.0;
	const float *n = binding->measure.normals + 3 * k, *o = binding->step.smoothing_offsets + 3 * k;
	return (double)binding->measure.vertex_g[k] * ((double)n[0] * o[0] + (double)n[1] * o[1] + (double)n[2] * o[2]);
}

/* What one multiplier of every vertex's smoothed offset does to each part's volume (sum over its
 * vertices of g_k <n_k, o_k>), into system. */
static void lvp__offset_gains(lvp_binding *binding, bool one_part, double *system)
{
	memset(system, 0, sizeof(double) * (size_t)binding->parts.count);
	if (one_part) {
		system[0] = lvp__gain_over_dynamic(binding, lvp__offset_gain);
		return;
	}
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v)
		system[binding->parts.vertex_part[binding->dynamic.vertices[v]]] += lvp__offset_gain(binding, v);
}

/* What one multiplier of every touched group does to each part's volume (eq. 5's denominator: sum
 * over the vertices of gamma_k g_k^2 times their phi of the touched groups), into system. With one
 * part, summed by chunks of the dynamic vertices (in parallel), then the chunks in order. */
static void lvp__whole_mesh_gains(lvp_binding *binding, bool one_part, double *system)
{
	memset(system, 0, sizeof(double) * (size_t)binding->parts.count);
	if (one_part) {
		system[0] = lvp__gain_over_dynamic(binding, lvp__map_gain);
		return;
	}
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (!lvp__can_move(binding, k))
			continue;
		double g = binding->measure.vertex_g[k], gain = (double)binding->frame_map.gamma[k] * g * g;
		lvp__support support = lvp__vertex_support(binding, k);
		for (int32_t i = 0; i < support.count; ++i) {
			int32_t group = binding->system.group_leader[support.regions[i]];
			if (support.phi[i] > 0.0f && binding->step.region_touched[group])
				system[lvp__region_part(binding, support.regions[i])] += gain * support.phi[i];
		}
	}
}

/* One step of lvp__global_steps, with the multipliers it set (step.mu of the touched regions, step.part_mu along
 * the offsets), and the parts' changes measured after it. */
static void lvp__apply_global_step(lvp_binding *binding, int32_t touched, bool one_part, bool along_offsets)
{
	binding->step.uniform_step = one_part && !along_offsets;
	binding->step.uniform_mu = binding->step.mu[binding->step.active[0]];
	binding->step.along_offsets = along_offsets;
	/* Along the offsets no region's multiplier is applied (nor counted in moved_by: the steps that made the
	 * offsets were). */
	lvp__apply_multipliers(binding, binding->step.active, along_offsets ? 0 : touched);
	binding->step.uniform_step = binding->step.along_offsets = false;
	lvp__remeasure_sums(binding);
	lvp__part_changes(binding);
}

/* One multiplier per part (one for the whole mesh when nothing is split) spread over the regions
 * touched this frame (eq. 5 with the sum of their maps, each step after the first scaled by how the
 * skin answered the one before) removes what is left of the part's change, holes capped: the whole
 * of LVP_RESTORE_WHOLE_MESH, and the second phase of the fallback of lvp__correct_volumes() once
 * every region is within tolerance of its rest volume. The steps read the parts' volumes only; the
 * regions' changes are measured once, after the last. along_offsets: each part's multiplier scales
 * its vertices' smoothed offsets (step.smoothing_offsets) instead (lvp__restore_smoothed). */
static int32_t lvp__global_steps(lvp_binding *binding, const lvp_frame_options *options, int32_t budget,
                                 const float *rest_positions, const lvp__region_sums *totals, bool along_offsets)
{
	int32_t steps = 0, touched = 0;
	for (int32_t r = 0; r < binding->region_count; ++r)
		if (binding->step.region_touched[r])
			binding->step.active[touched++] = r;
	double *system = binding->step.part_gain, *change_before = binding->step.part_total;
	double *response = binding->step.part_response;
	for (int32_t p = 0; p < binding->parts.count; ++p)
		response[p] = 1.0;
	bool one_part = binding->parts.count == 1, regions_measured = !binding->step.change_stale;
	while (steps < budget && touched > 0) {
		lvp__part_changes(binding);
		if (!lvp__parts_off(binding, options->tolerance))
			break;
		if (steps == 0 && one_part && !along_offsets) /* what the steps through the map apply */
			lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.vertex_count), lvp__touched_phi_loop, binding,
			                  binding->dynamic.vertex_count, LVP__GRAIN);
		memcpy(change_before, binding->parts.change, sizeof(double) * (size_t)binding->parts.count);
		double before = lvp__parts_error(binding);
		lvp__vertex_normals(binding);
		bool any = false;
		if (along_offsets) {
			lvp__offset_gains(binding, one_part, system);
			/* The offsets point out where the volume was lost and in where it was gained, so
			 * the gain has the sign of the correction; a multiplier of -1 or less would turn
			 * the offsets round, which the map's steps do better. */
			for (int32_t p = 0; p < binding->parts.count; ++p) {
				double mu = system[p] != 0.0 ? -binding->parts.change[p] / (system[p] * response[p]) : 0.0;
				binding->step.part_mu[p] = isfinite(mu) && mu > -1.0 ? mu : 0.0;
				any = any || binding->step.part_mu[p] != 0.0;
			}
		} else {
			lvp__whole_mesh_gains(binding, one_part, system);
			for (int32_t j = 0; j < touched; ++j) {
				int32_t t = binding->step.active[j], p = lvp__region_part(binding, t);
				binding->step.mu[t] = system[p] > 0.0 ? -binding->parts.change[p] / (system[p] * response[p]) : 0.0;
				any = any || system[p] > 0.0;
			}
		}
		if (!any)
			break;
		lvp__apply_global_step(binding, touched, one_part, along_offsets);
		++steps;
		regions_measured = false;
		/* A step through the map that leaves the volume further off went too far for the linear
		 * response (skin moved along normals that turn by more than the step can follow): it is
		 * undone and tried again at half the multipliers, a few times. */
		for (int halving = 0; halving < LVP__STEP_HALVINGS && !along_offsets && !(lvp__parts_error(binding) < before);
		     ++halving) {
			lvp__undo_step(binding);
			for (int32_t j = 0; j < touched; ++j)
				binding->step.mu[binding->step.active[j]] *= 0.5;
			lvp__apply_global_step(binding, touched, one_part, false);
		}
		if (!(lvp__parts_error(binding) < before)) { /* no better: the step is undone, and that is all */
			lvp__undo_step(binding);
			lvp__measure_positions(binding, rest_positions, totals);
			regions_measured = true;
			break;
		}
		/* The skin's true response is not the linear one (the normals turn as it moves): the next
		 * step is scaled by what this one achieved of what it predicted, a secant step, so that the
		 * volume ends well inside the tolerance rather than at its edge. */
		for (int32_t p = 0; p < binding->parts.count; ++p) {
			double achieved = change_before[p] != 0.0 ? 1.0 - binding->parts.change[p] / change_before[p] : 1.0;
			response[p] *= fmin(fmax(achieved, 0.25), 4.0);
		}
	}
	binding->step.change_stale = !regions_measured;
	return steps;
}

/* Whether some bone's posed frame changes volume against its rest frame by more than 1e-4, or
 * some bone is stretched against a bone it blends with (squash and stretch, an inflated limb).
 * The whole mesh then has no rest volume to go back to, and restoring it would squeeze the
 * scaled volume out through the joints: such frames correct each region to the change its
 * bones' scales give it (stretch.c), and nothing else. */
static bool lvp__bones_scale(const lvp_binding *binding)
{
	if (binding->stretch.any)
		return true;
	for (int32_t r = 0; r < binding->region_count; ++r)
		if (!binding->rig.region_skipped[r] && fabs(binding->rig.kappa[r] - 1.0) > 1e-4)
			return true;
	return false;
}

/* Whether this frame restores the whole mesh alone (lvp.h, RESTORE): asked for, in local mode, no
 * bone scales (then each region's scaled volume is the target) and no group given up (whose loss
 * the whole mesh's multiplier would push into the others: DEGRADING). */
static bool lvp__restores_whole_mesh(const lvp_binding *binding, const lvp_frame_options *options)
{
	return options->restore == LVP_RESTORE_WHOLE_MESH && binding->mode == LVP_MODE_LOCAL &&
	       !lvp__bones_scale(binding) && !binding->step.any_given_up;
}

/* Marks every group the map can move (and not given up) as touched, the set the whole mesh's
 * multiplier is spread over (lvp__global_steps); returns how many. All of them, not only those
 * whose estimate is off: which groups take part then never switches from frame to frame, and
 * where nothing bends the map is zero anyway.
 * Also measures each part's tolerance against the flesh that bent, not the whole part: the sum of
 * the references of the groups off their targets by more than the tolerance, when that is smaller.
 * A wrist bent 40 degrees on a whole body loses 7 % of the hand's region but 0.007 % of the body,
 * which the body's own tolerance (0.01 %) would leave as it is. */
static int32_t lvp__touch_movable_groups(lvp_binding *binding, double tolerance)
{
	int32_t count = 0;
	double *bent = binding->step.part_total;
	memset(bent, 0, sizeof(double) * (size_t)binding->parts.count);
	for (int32_t r = 0; r < binding->region_count; ++r) {
		lvp__group_state group;
		if (!lvp__measured_group(binding, r, &group) || !group.movable)
			continue;
		binding->step.region_touched[r] = 1;
		++count;
		if (fabs(group.change - group.target) > tolerance * group.reference)
			bent[lvp__region_part(binding, r)] += group.reference;
	}
	for (int32_t p = 0; p < binding->parts.count; ++p)
		if (bent[p] > 0.0)
			binding->parts.scale[p] = fmin(binding->parts.scale[p], bent[p]);
	return count;
}

/* The volume correction, from a measured state. The local volumes are estimates (5.2): summed
 * over a closed surface they differ from the true change by what each region border sees from
 * two bone frames (second order in the bend, 0.4 % of the cylinder at 90 degrees), and regions
 * the correction cannot move, or triangles without a region, change too. So each step adds to
 * the regions' own step (towards their targets, zero at first) one multiplier for all of them
 * that restores the whole mesh's volume, measured with its true gradient, and moves each
 * region's target by what it does to that region: the regions end at their targets and the
 * whole mesh at its rest volume, in the same steps. Where a step makes things worse (many
 * regions overlapping, as at a shoulder, and most of the whole mesh's change missed by the
 * region changes: the uniform part leaves the range where the linearization holds) it is
 * undone, and the correction goes on in two phases: the regions to their targets, then one
 * multiplier for the whole mesh (lvp__global_steps). Returns the number of steps;
 * *r_first_active: the regions corrected by the first. smoothing_follows: the offsets are smoothed
 * next and the volume corrected again after that, so restoring the whole mesh takes one step here
 * (the smoothing moves the skin by more than what a second step would remove, and the steps after
 * it remove what is left), and the regions' changes are left of the positions before that step
 * (the caller measures the positions afresh); else they are measured at the end. */
static int32_t lvp__correct_volumes(lvp_binding *binding, const lvp_frame_options *options,
                                    const float *rest_positions, const lvp__region_sums *totals,
                                    int32_t *r_first_active, bool smoothing_follows)
{
	if (lvp__restores_whole_mesh(binding, options)) {
		*r_first_active = lvp__touch_movable_groups(binding, options->tolerance);
		int32_t steps = lvp__global_steps(binding, options, smoothing_follows ? 1 : options->max_iterations,
		                                  rest_positions, totals, false);
		if (!smoothing_follows)
			lvp__measure_changes(binding, totals);
		return steps;
	}
	/* With a group given up, the whole mesh is not restored: its loss would be pushed into the
	 * groups still corrected. */
	bool failed, whole_mesh = binding->mode == LVP_MODE_LOCAL && !lvp__bones_scale(binding) &&
	                          !binding->step.any_given_up;
	binding->step.spread_total = whole_mesh;
	int32_t steps = lvp__volume_iterations(binding, options, rest_positions, totals, options->max_iterations,
	                                       r_first_active, &failed);
	binding->step.spread_total = false;
	if (!failed || !whole_mesh)
		return steps;
	int32_t ignored;
	steps += lvp__volume_iterations(binding, options, rest_positions, totals, options->max_iterations - steps,
	                                &ignored, &failed);
	steps += lvp__global_steps(binding, options, options->max_iterations - steps, rest_positions, totals, false);
	lvp__measure_changes(binding, totals);
	return steps;
}

/* The volume the smoothing took, restored. Restoring the whole mesh, along the smoothed offsets
 * themselves: each part's offsets grow by one factor, so the shape the smoothing gave is kept
 * (through the map the volume would go back where the map peaks, and on a coarse mesh, where a
 * vertex's weights differ much from its neighbours', put back the peak the smoothing took
 * away); what they cannot restore (a part whose offsets do not change its volume) goes through
 * the map. Each region to its own volume, through the map as before the smoothing. */
static int32_t lvp__restore_smoothed(lvp_binding *binding, const lvp_frame_options *options,
                                     const float *rest_positions, const lvp__region_sums *totals)
{
	int32_t ignored;
	if (!lvp__restores_whole_mesh(binding, options)) {
		lvp__measure_changes(binding, totals);
		return lvp__correct_volumes(binding, options, rest_positions, totals, &ignored, false);
	}
	int32_t steps = lvp__global_steps(binding, options, options->max_iterations, rest_positions, totals, true);
	steps += lvp__global_steps(binding, options, options->max_iterations - steps, rest_positions, totals, false);
	lvp__measure_changes(binding, totals);
	return steps;
}

/* The volume that the crossing test's shortening took (or the rim's feathering after the fades added), restored
 * again: along the offsets as they are (the shape the smoothing and the fade gave them, each growing as little as
 * it was shortened), or with fold-over through the map, which fold-over faded at its contacts: growing along the
 * offsets, the skin beside a contact would be pushed back through it, a crossing of the skinning's own that no
 * test of new crossings sees. */
static int32_t lvp__restore_after_fade(lvp_binding *binding, const lvp_frame_options *options,
                                       const float *positions, const float *rest_positions,
                                       const lvp__region_sums *totals)
{
	lvp__movable_regions(binding);
	lvp__measure_positions(binding, rest_positions, totals);
	if (options->fold_over) {
		int32_t ignored;
		return lvp__correct_volumes(binding, options, rest_positions, totals, &ignored, false);
	}
	lvp__take_offsets(binding, positions);
	return lvp__restore_smoothed(binding, options, rest_positions, totals);
}

/* The volume a fade at the clearances took (clearance.c), restored along the faded offsets smoothed as
 * the frame's offsets are (lvp__smooth_offsets, the frame's passes). The fade multiplies the offsets by
 * shares that rise by up to LVP__SHARE_SLOPE a ring, and grown as they were, the offsets kept that slope
 * as roughness, about that share of their size on top of their own: where skin lies against skin over a
 * wide patch (an arm hanging against the chest, a calf on a thigh) the faded skin's rim stood out of
 * the skin around it. Smoothed, the faded offsets rise a little towards the skin they approach; the next
 * fade takes that back, and after the last the crossing test (whose restores are not smoothed: each
 * would push again what the test just shortened). */
static int32_t lvp__restore_fade_smoothed(lvp_binding *binding, const lvp_frame_options *options,
                                          const float *positions, const float *rest_positions,
                                          const lvp__region_sums *totals)
{
	lvp__movable_regions(binding);
	lvp__measure_positions(binding, rest_positions, totals);
	if (options->smoothing_passes > 0) {
		lvp__smooth_offsets(binding, positions, options->smoothing_passes, LVP__SMOOTH_FRAME);
		lvp__measure_sums(binding, rest_positions, totals);
	} else {
		lvp__take_offsets(binding, positions);
	}
	return lvp__restore_smoothed(binding, options, rest_positions, totals);
}

/* Keeping skin apart: the offsets that near other skin in front of them fade (clearance.c), and
 * the volume they no longer carry is restored along the others (lvp__restore_fade_smoothed), a few
 * rounds, as restoring grows the faded offsets too. */
static int32_t lvp__restore_short_of_contact(lvp_binding *binding, const lvp_frame_options *options,
                                             const float *positions, const float *rest_positions,
                                             const lvp__region_sums *totals)
{
	int32_t steps = 0, cycle = 0;
	for (; cycle < LVP__CLEARANCE_CYCLES; ++cycle) {
		lvp__measure_clearance(binding, positions, cycle > 0);
		if (!lvp__fade_at_clearance(binding, positions))
			break;
		steps += lvp__restore_fade_smoothed(binding, options, positions, rest_positions, totals);
	}
	/* The restores grew the moving skin's offsets, up to eightfold where the fade left it little room, and not
	 * the rim's, which the smoothing feathered against the offsets before them: where the volume went to the
	 * end of the moving skin (a coarse body's arms against its chest, the fade sending the volume to the top
	 * of the shoulder), the offsets stood on the rim as a ledge. It is feathered against them again, and the
	 * volume that adds taken back along the offsets. */
	if (cycle > 0 && binding->frame_map.rim_count > 0) {
		lvp__feather_rim_again(binding, positions);
		steps += lvp__restore_after_fade(binding, options, positions, rest_positions, totals);
	}
	return steps;
}

/* A group's change against the change its bones' scales give it, relative to its reference. */
static double lvp__relative_change(const lvp__group_state *group)
{
	return (group->change - group->reference_change) / group->reference;
}

/* The group (by leader) furthest from its volume, and how far (*r_relative). */
static int32_t lvp__worst_region(const lvp_binding *binding, double *r_relative)
{
	int32_t worst = -1;
	double largest = -1.0;
	for (int32_t r = 0; r < binding->region_count; ++r) {
		lvp__group_state group;
		if (!lvp__measured_group(binding, r, &group))
			continue;
		double relative = lvp__relative_change(&group);
		if (fabs(relative) > largest) {
			largest = fabs(relative);
			worst = r;
			*r_relative = relative;
		}
	}
	return worst;
}

static int32_t lvp__count_skipped(const lvp_binding *binding)
{
	int32_t skipped = 0;
	for (int32_t r = 0; r < binding->region_count; ++r)
		skipped += binding->rig.region_skipped[r] != 0;
	return skipped;
}

/* The offsets (step.positions - positions, of the points) and the corrected positions of every
 * caller vertex: a point's offset goes to each of its vertices (weld.c). Only dynamic points can
 * have moved; every other vertex is its input. Returns the largest offset's length. */
static double lvp__write_output(const lvp_binding *binding, float *r_positions, float *r_offsets,
                                const float *caller_positions, const float *positions)
{
	const lvp__weld *weld = &binding->weld;
	size_t values = 3 * (size_t)weld->caller_vertex_count;
	if (r_offsets)
		memset(r_offsets, 0, sizeof(float) * values);
	if (r_positions && r_positions != caller_positions)
		memcpy(r_positions, caller_positions, sizeof(float) * values);
	double largest = 0.0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t p = binding->dynamic.vertices[v];
		const float *in = positions + 3 * p, *out = binding->step.positions + 3 * p;
		float offset[3] = {out[0] - in[0], out[1] - in[1], out[2] - in[2]};
		double length2 = (double)offset[0] * offset[0] + (double)offset[1] * offset[1] + (double)offset[2] * offset[2];
		if (length2 > largest) /* not fmax: a call per vertex where libm's is not inlined */
			largest = length2;
		/* The point's vertices, its first (whose input it is, exactly) first; a point is its vertex
		 * when nothing is welded. Another copy keeps its own input, moved by the point's offset. */
		int32_t first = weld->copies ? weld->copy_offsets[p] : 0, last = weld->copies ? weld->copy_offsets[p + 1] : 1;
		for (int32_t i = first; i < last; ++i) {
			int32_t k = weld->copies ? weld->copies[i] : p;
			for (int c = 0; c < 3; ++c) {
				if (r_offsets)
					r_offsets[3 * k + c] = offset[c];
				if (r_positions)
					r_positions[3 * k + c] = i == first ? out[c] : caller_positions[3 * k + c] + offset[c];
			}
		}
	}
	return sqrt(largest);
}

/* The largest distance between a and b over the vertices. */
static double lvp__largest_displacement(const lvp_binding *binding, const float *a, const float *b)
{
	double largest = 0.0;
	for (int32_t k = 0; k < 3 * binding->vertex_count; k += 3) {
		double dx = (double)a[k] - b[k], dy = (double)a[k + 1] - b[k + 1], dz = (double)a[k + 2] - b[k + 2];
		largest = fmax(largest, dx * dx + dy * dy + dz * dz);
	}
	return sqrt(largest);
}

/* Fold-over's volume step: the map faded at the contacts found since the last (only the fade changes
 * what can move), the positions measured, the volume corrected with the pressed skin held. */
static int32_t lvp__volume_step_at_contacts(lvp_binding *binding, const lvp_frame_options *options,
                                            const float *rest_positions, const lvp__region_sums *totals)
{
	int32_t ignored;
	if (lvp__fade_map_at_contact(binding))
		lvp__movable_regions(binding);
	lvp__measure_positions(binding, rest_positions, totals);
	return lvp__correct_volumes(binding, options, rest_positions, totals, &ignored, false);
}

/* The volume fold-over's last relaxation took, restored: through the map faded at the contacts, as
 * the rounds restore it, but that step moves each vertex by its volume gradient, largest where the
 * fold squeezes the skin least, and beside the contacts, where no smoothing follows, one vertex came
 * out of it well ahead of its neighbours (the coarse metaball body's knee at 150 degrees: 0.44 edge
 * lengths out of their surface). So the step itself, from where the relaxation left the skin, is
 * smoothed as the frame's offsets are (the held skin still), and the volume that takes restored along
 * the smoothed step. */
static int32_t lvp__restore_relaxed(lvp_binding *binding, const lvp_frame_options *options,
                                    const float *rest_positions, const lvp__region_sums *totals)
{
	float *relaxed = binding->fold.saved;
	memcpy(relaxed, binding->step.positions, sizeof(float) * 3 * (size_t)binding->vertex_count);
	int32_t steps = lvp__volume_step_at_contacts(binding, options, rest_positions, totals);
	lvp__smooth_offsets(binding, relaxed, options->smoothing_passes, LVP__SMOOTH_FRAME);
	lvp__measure_sums(binding, rest_positions, totals);
	return steps + lvp__restore_smoothed(binding, options, rest_positions, totals);
}

/* Fold-over prevention (paper 5.4): the contact test, then the extra volume step with the moved
 * vertices held on the contact surface (which turns the compression into a bulge); the bulge may
 * push other vertices across, so the two alternate a few rounds, each moved vertex staying held.
 * After each contact test the pressed skin is relaxed with the skin around it (lvp__relax_pressed,
 * as many passes as the offsets' smoothing), and the volume that takes is restored at the end, what
 * that pushes across pressed in turn. Adds to stats->iterations and stats->folded_vertices. */
static void lvp__prevent_fold_over(lvp_binding *binding, const lvp_frame_options *options, const float *positions,
                                   const float *rest_positions, const lvp__region_sums *totals,
                                   lvp_frame_stats *stats)
{
	int32_t n = binding->vertex_count;
	lvp__begin_fold_over(binding, rest_positions);
	int32_t moved = lvp__fold_over(binding, rest_positions);
	stats->folded_vertices = moved;
	/* The frame's first press is its deepest: the rounds after it press what their volume steps push
	 * across, a little. */
	int32_t relax_passes = lvp__relaxation_rings(binding, options->smoothing_passes);
	bool relaxed =
	    lvp__relax_pressed(binding, positions, rest_positions, totals, relax_passes, options->smoothing_passes);
	/* A round may move no vertex more than twice as far as the correction before it (volume
	 * steps and the first contacts) moved any: further, it is diverging (the map faded at the
	 * contacts leaves the volume too few places to go), and the frame keeps the round before. */
	double bound = 2.0 * lvp__largest_displacement(binding, positions, binding->step.positions);
	for (int round = 0; round < LVP__FOLD_ROUNDS && moved > 0; ++round) {
		memcpy(binding->fold.saved, binding->step.positions, sizeof(float) * 3 * (size_t)n);
		stats->iterations += lvp__volume_step_at_contacts(binding, options, rest_positions, totals);
		if (lvp__largest_displacement(binding, binding->fold.saved, binding->step.positions) > bound) {
			memcpy(binding->step.positions, binding->fold.saved, sizeof(float) * 3 * (size_t)n);
			break;
		}
		moved = lvp__fold_over(binding, rest_positions);
		stats->folded_vertices += moved;
		relaxed |= lvp__relax_pressed(binding, positions, rest_positions, totals, relax_passes,
		                              options->smoothing_passes);
	}
	if (relaxed) {
		/* The volume the relaxation took comes back through the map, where it peaks beside the
		 * contacts: those peaks are smoothed over the relaxation's rings (the held skin keeping its
		 * place; by the mesh's weights alone: an equal pass, which weighs a neighbour a long quad
		 * away as much as one beside, left creases along the contact line and skin crossing again),
		 * the volume restored along the smoothed offsets, and what that carries across a plane
		 * pressed back. That press is relaxed as the rounds' are: left as it was, the rim it put on
		 * the plane met the free skin beside it at an angle, creases along the contact line (the
		 * flanks of a thigh that its calf presses, the sides of a finger at the fist). The volume
		 * that relaxation takes comes back through the map once more, where the contacts faded it,
		 * so little crosses again, that step smoothed (lvp__restore_relaxed), and what crosses is
		 * pressed back. */
		stats->iterations += lvp__volume_step_at_contacts(binding, options, rest_positions, totals);
		lvp__smooth_offsets(binding, positions, relax_passes, LVP__SMOOTH_BY_THE_MESH);
		lvp__measure_sums(binding, rest_positions, totals);
		stats->iterations += lvp__restore_smoothed(binding, options, rest_positions, totals);
		stats->folded_vertices += lvp__fold_over(binding, rest_positions);
		if (lvp__relax_pressed(binding, positions, rest_positions, totals, relax_passes,
		                       options->smoothing_passes)) {
			stats->iterations += lvp__restore_relaxed(binding, options, rest_positions, totals);
			stats->folded_vertices += lvp__fold_over(binding, rest_positions);
		}
	}
	lvp__measure_positions(binding, rest_positions, totals);
}

/* One attempt at the frame's correction, from the input positions: the volume steps, then
 * fold-over when asked. Adds its steps to stats->iterations, sets the active regions and folded
 * vertices, and on the first attempt the volume and the worst group before correction. Groups
 * given up (step.given_up) are left out. */
static void lvp__correct_attempt(lvp_binding *binding, const lvp_frame_options *options, int32_t attempt,
                                 const float *positions, const float *rest_positions,
                                 const lvp__region_sums *totals, lvp_frame_stats *stats)
{
	int32_t n = binding->vertex_count;
	memcpy(binding->step.positions, positions, sizeof(float) * 3 * (size_t)n);
	memset(binding->step.moved_by, 0, sizeof(double) * (size_t)binding->region_count);
	memset(binding->step.region_touched, 0, (size_t)binding->region_count);
	if (attempt > 0)
		lvp__build_frame_map(binding, rest_positions); /* undoes the fades of fold-over's contacts */
	lvp__measure_positions(binding, rest_positions, totals);
	/* Each region aims at zero change, or where bones are stretched against each other at the
	 * change their stretch alone gives it (stretch.c; zero without stretch). */
	lvp__stretch_targets(binding, rest_positions, options->rigid_space, options->tolerance);
	memcpy(binding->step.target, binding->stretch.change, sizeof(double) * (size_t)binding->region_count);
	lvp__movable_regions(binding);
	if (attempt == 0) {
		stats->volume_before = lvp__pass_volume(binding, binding->step.positions);
		stats->worst_region = lvp__worst_region(binding, &stats->worst_region_change_before);
	}

	int32_t first_active = 0;
	/* max_iterations bounds all the steps of the frame: 1 is the paper's single local pass. */
	bool smoothing = options->smoothing_passes > 0 && binding->mode == LVP_MODE_LOCAL;
	stats->iterations += lvp__correct_volumes(binding, options, rest_positions, totals, &first_active, smoothing);
	stats->active_regions = first_active;
	if (smoothing) {
		/* Offsets along normals that turn fast (folds) open creases, and a coarse mesh's map changes
		 * much from one vertex to the next: smoothed, then the volume the smoothing took restored
		 * along the smoothed offsets (lvp__restore_smoothed). */
		lvp__smooth_offsets(binding, positions, options->smoothing_passes, LVP__SMOOTH_FRAME);
		lvp__measure_sums(binding, rest_positions, totals);
		stats->iterations += lvp__restore_smoothed(binding, options, rest_positions, totals);
	}
	stats->folded_vertices = 0;
	if (options->fold_over && binding->mode == LVP_MODE_LOCAL) {
		lvp__prevent_fold_over(binding, options, positions, rest_positions, totals, stats);
		/* Vertices the smoothing ties into one point, which fold-over's steps moved one by one, move
		 * as one point again, but for those it holds on a contact plane (smoothing_ties.c); the volume
		 * their mean takes is restored through the map as fold-over restores it, which moves them a
		 * little apart again, by far less. */
		if (binding->smoothing.tie_count > 0) {
			lvp__move_ties_as_one(binding, positions); /* the step measures the positions it starts from */
			stats->iterations += lvp__volume_step_at_contacts(binding, options, rest_positions, totals);
			lvp__move_ties_as_one(binding, positions);
			lvp__measure_positions(binding, rest_positions, totals);
		}
	}
	stats->shortened_vertices = 0;
	stats->kept_apart_vertices = 0;
	stats->crossing_triangles = 0;
	if (options->keep_apart && binding->mode == LVP_MODE_LOCAL) {
		lvp__contact_fit_skinning(binding, positions);
		/* The fade is for skin that fold-over leaves alone: with fold-over, skin near other skin is
		 * where its contacts moved it out of the skinning's own crossings, and fading it would bring
		 * them back (the hand at the fist: 25 pairs where fold-over alone leaves none). */
		if (!options->fold_over)
			stats->iterations += lvp__restore_short_of_contact(binding, options, positions, rest_positions, totals);
		/* Offsets that would still push skin through skin are shortened (contact.c). What they could
		 * not carry is restored again along the offsets as they are now (the shortened ones grow as
		 * little as they were shortened; the map, for the steps that fall back to it, faded as much;
		 * those that fold-over put on a contact surface still held), and that correction is checked
		 * in turn, until one shortens nothing (a bent tail: twice). */
		int32_t shortened = lvp__keep_skin_apart(binding, positions, true, false);
		stats->crossing_triangles = binding->contact.crossed;
		for (int cycle = 0; cycle < LVP__CONTACT_CYCLES && shortened > 0; ++cycle) {
			lvp__fade_map_where_shortened(binding);
			stats->iterations += lvp__restore_after_fade(binding, options, positions, rest_positions, totals);
			if (lvp__still_where_kept_apart(binding))
				break; /* the restore moved no vertex: the check before left nothing to shorten there */
			shortened = lvp__keep_skin_apart(binding, positions, false, options->fold_over);
		}
		lvp__kept_apart_counts(binding, !options->fold_over, &stats->shortened_vertices, &stats->kept_apart_vertices);
		if (stats->shortened_vertices > 0) /* each check leaves the positions it shortened unmeasured */
			lvp__measure_positions(binding, rest_positions, totals);
	}
	stats->bones_scale = lvp__bones_scale(binding);
	memset(binding->fold.held, 0, (size_t)n);
}

/* The group furthest from its target, relative to its reference volume, when more than 0.1 % off;
 * else -1. Asked when an attempt moved nothing at all: a group the correction cannot restore (a
 * joint folded onto itself) has its steps undone as making things worse, and with them every
 * other group's. */
static int32_t lvp__group_furthest_off(const lvp_binding *binding)
{
	int32_t worst = -1;
	double largest = 1e-3;
	for (int32_t r = 0; r < binding->region_count; ++r) {
		lvp__group_state group;
		if (!lvp__measured_group(binding, r, &group) || !group.movable)
			continue;
		double off = fabs(group.change - group.target) / group.reference;
		if (off > largest) {
			largest = off;
			worst = r;
		}
	}
	return worst;
}

/* What an attempt did to the dynamic vertices (only they can have moved, binding.h): whether it
 * moved any, whether every one is finite, and the one moved farthest beyond `limit` (0: none), or
 * the first that is not finite; -1 when there is none. */
typedef struct lvp__attempt_scan {
	int32_t farthest;
	bool moved, finite;
} lvp__attempt_scan;

static lvp__attempt_scan lvp__scan_attempt(const lvp_binding *binding, const float *positions, double limit)
{
	lvp__attempt_scan scan = {-1, false, true};
	double largest = limit > 0.0 ? limit * limit : INFINITY;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		const float *p = binding->step.positions + 3 * k, *in = positions + 3 * k;
		double dx = (double)p[0] - in[0], dy = (double)p[1] - in[1], dz = (double)p[2] - in[2];
		double d = dx * dx + dy * dy + dz * dz;
		scan.moved = scan.moved || d != 0.0;
		if (!isfinite(d)) { /* the inputs are finite (checked): this position is not */
			scan.farthest = k;
			scan.finite = false;
			break;
		}
		if (d > largest) {
			largest = d;
			scan.farthest = k;
		}
	}
	return scan;
}

/* The group (by leader) to give up after an attempt, or -1 when there is none. Where some offset is
 * not finite or beyond the limit (scan.farthest): the group whose multipliers moved that vertex
 * most, phi times the |mu| its steps applied (step.moved_by). Where the attempt moved nothing at
 * all: the group furthest from its target (lvp__group_furthest_off). */
static int32_t lvp__group_to_give_up(const lvp_binding *binding, lvp__attempt_scan scan, bool whole_mesh,
                                     bool *r_diverged)
{
	int32_t farthest = scan.farthest;
	if (binding->mode != LVP_MODE_LOCAL)
		return -1;
	*r_diverged = farthest >= 0;
	if (farthest < 0) /* restoring the whole mesh, no group's steps hold back another's */
		return scan.moved || whole_mesh ? -1 : lvp__group_furthest_off(binding);
	lvp__support support = lvp__vertex_support(binding, farthest);
	int32_t culprit = -1;
	double most = 0.0;
	for (int32_t i = 0; i < support.count; ++i) {
		int32_t r = support.regions[i];
		double share = (double)support.phi[i] * binding->step.moved_by[r];
		if (isnan(share))
			share = INFINITY;
		if (!binding->step.given_up[r] && share > most) {
			most = share;
			culprit = binding->system.group_leader[r];
		}
	}
	return culprit;
}

lvp_result lvp_correct(float *r_positions, float *r_offsets, lvp_binding *binding, const float *positions,
                       const float *bone_matrices, const float *rest_positions, const lvp_frame_options *options,
                       lvp_frame_stats *r_stats, lvp_diagnostic *r_diag)
{
	if (!binding)
		return lvp__fail(r_diag, lvp_error_null_argument, "binding", -1, "binding is NULL; call lvp_bind() first.");
	if (!r_positions && !r_offsets)
		return lvp__fail(r_diag, lvp_error_null_argument, "r_positions", -1,
		                 "r_positions and r_offsets are both NULL; pass at least one output buffer.");
	lvp_frame_options defaults = lvp_frame_default_options();
	if (!options)
		options = &defaults;
	lvp_result result = lvp__check_frame_options(options, r_diag);
	if (result)
		return result;
	const float *caller_positions = positions; /* positions and rest_positions: the points' from here on */
	if ((result = lvp__frame_points(binding, &positions, &rest_positions, r_diag)) ||
	    (result = lvp__prepare_frame(binding, bone_matrices, r_diag)))
		return result;

	int32_t n = binding->vertex_count;
	const lvp__region_sums *totals = lvp__frame_rest(binding, rest_positions);
	lvp__use_rigid_shortcut(binding, true); /* the frame before may have had it off */
	lvp__build_frame_map(binding, rest_positions);

	lvp_frame_stats stats;
	memset(&stats, 0, sizeof(stats));
	/* The measurement carries the rigid vertices' part of each region in closed form, from the
	 * rest and the bones (local_volume.c): right only where the positions are that skinning.
	 * Where they are not (bone frames that are not what moved the mesh, weights that changed
	 * since the bind), the frame is measured from the positions alone, and says so. */
	if (!lvp__rigid_vertices_hold(binding, positions, rest_positions, &stats.unskinned_distance)) {
		lvp__use_rigid_shortcut(binding, false);
		lvp__build_frame_map(binding, rest_positions);
	}
	if (options->keep_apart && binding->mode == LVP_MODE_LOCAL && (result = lvp__contact_begin(binding, r_diag)))
		return result;
	if (options->fold_over && binding->mode == LVP_MODE_LOCAL && (result = lvp__relaxation_begin(binding, r_diag)))
		return result;
	stats.worst_region = -1;
	stats.given_up_region = -1;
	stats.volume_rest = rest_positions ? lvp__volume_of(binding, rest_positions) : binding->rest_volume;

	/* The whole mesh's volume at this frame's rest, or each separate part's (binding.h). */
	if (binding->parts.count == 1)
		binding->parts.rest_volume[0] = stats.volume_rest;
	else if (rest_positions)
		lvp__volumes_of_parts(binding, rest_positions, binding->parts.rest_volume);
	else
		memcpy(binding->parts.rest_volume, binding->parts.bind_volume, sizeof(double) * (size_t)binding->parts.count);
	/* What a part's change is measured against: its volume, or for an open, flat part (no volume
	 * to speak of beside its regions' reference volumes, the cones from its skin to its bones) the
	 * sum of those. Not the mesh's size: a stray vertex far away would make a closed part look
	 * flat and its whole loss within tolerance. A part without references: the cube of the size. */
	double cube = binding->size * binding->size * binding->size, *scale = binding->parts.scale;
	memset(scale, 0, sizeof(double) * (size_t)binding->parts.count);
	for (int32_t r = 0; r < binding->region_count; ++r)
		if (!binding->rig.region_skipped[r])
			scale[lvp__region_part(binding, r)] += binding->measure.reference_volume[r];
	for (int32_t p = 0; p < binding->parts.count; ++p) {
		double volume = fabs(binding->parts.rest_volume[p]), references = scale[p];
		if (references > 0.0)
			scale[p] = volume > 1e-3 * references ? volume : references;
		else
			scale[p] = volume > 1e-6 * cube ? volume : cube;
	}

	/* Where an attempt moves some vertex beyond the limit (a joint folded onto itself, a region
	 * the correction cannot restore), the group that moved it most is given up for this frame and
	 * the frame corrected again without it: that region keeps the skinning, the rest stays
	 * corrected (lvp.h, DEGRADING). */
	memset(binding->step.given_up, 0, (size_t)binding->region_count);
	binding->step.any_given_up = false;
	lvp__attempt_scan scan;
	for (int32_t attempt = 0;; ++attempt) {
		lvp__correct_attempt(binding, options, attempt, positions, rest_positions, totals, &stats);
		scan = lvp__scan_attempt(binding, positions, (double)options->displacement_limit);
		/* Fold-over moves skin by contacts, not by the groups' multipliers: giving groups up would
		 * not undo it. Its caller corrects again without it (the add-on does). */
		if (attempt == LVP_MAX_GIVEN_UP || !(options->displacement_limit > 0.0f) || options->fold_over)
			break;
		bool diverged = false;
		bool whole_mesh = lvp__restores_whole_mesh(binding, options);
		int32_t culprit = lvp__group_to_give_up(binding, scan, whole_mesh, &diverged);
		if (culprit < 0)
			break;
		int32_t first, last;
		lvp__group_range(binding, culprit, &first, &last);
		for (int32_t g = first; g < last; ++g)
			binding->step.given_up[binding->system.group_regions[g]] = 1;
		binding->step.any_given_up = true;
		if (stats.given_up_regions++ == 0) {
			stats.given_up_region = lvp__caller_bone(binding, culprit);
			stats.given_up_diverged = diverged;
		}
	}
	/* Whatever the pose, never hand back a NaN: if anything went non-finite, the frame passes
	 * through unchanged and says so. Only dynamic vertices can have moved (binding.h); the
	 * others are the input, which was checked. */
	if (!scan.finite) {
		memcpy(binding->step.positions, positions, sizeof(float) * 3 * (size_t)n);
		lvp__measure_positions(binding, rest_positions, totals);
		stats.passed_through = 1;
	}
	stats.volume_after = lvp__pass_volume(binding, binding->step.positions);
	if (stats.worst_region >= 0) {
		lvp__group_state worst = lvp__group_state_of(binding, stats.worst_region);
		stats.worst_region_change_after = lvp__relative_change(&worst);
		stats.worst_region = lvp__caller_bone(binding, stats.worst_region); /* its bone, in local mode */
	}
	stats.skipped_regions = lvp__count_skipped(binding);

	double largest = lvp__write_output(binding, r_positions, r_offsets, caller_positions, positions);
	stats.max_displacement = largest;
	if (r_stats)
		*r_stats = stats;
	return lvp_success;
}

lvp_result lvp_region_volume_changes(double *r_changes, double *r_references, lvp_binding *binding,
                                     const float *positions, const float *bone_matrices,
                                     const float *rest_positions, lvp_diagnostic *r_diag)
{
	if (!binding)
		return lvp__fail(r_diag, lvp_error_null_argument, "binding", -1, "binding is NULL; call lvp_bind() first.");
	if (!r_changes)
		return lvp__fail(r_diag, lvp_error_null_argument, "r_changes", -1,
		                 "r_changes is NULL; pass region_count doubles.");
	lvp_result result;
	if ((result = lvp__frame_points(binding, &positions, &rest_positions, r_diag)) ||
	    (result = lvp__prepare_frame(binding, bone_matrices, r_diag)))
		return result;
	const lvp__region_sums *totals = lvp__frame_rest(binding, rest_positions);
	lvp__find_dynamic_set(binding, rest_positions, totals, true);
	lvp__mesh_pass(binding, positions);
	lvp__region_changes(binding, positions, totals, binding->step.change);
	/* Per caller's region: the sum over the separate parts of its bone (binding.h). */
	int32_t regions = lvp_region_count(binding);
	memset(r_changes, 0, sizeof(double) * (size_t)regions);
	if (r_references)
		memset(r_references, 0, sizeof(double) * (size_t)regions);
	for (int32_t r = 0; r < binding->region_count; ++r) {
		r_changes[lvp__caller_bone(binding, r)] += binding->step.change[r];
		if (r_references)
			r_references[lvp__caller_bone(binding, r)] += binding->measure.reference_volume[r];
	}
	return lvp_success;
}

bool lvp__step_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count, s = (size_t)binding->region_count;
	size_t parts = (size_t)binding->parts.count;
	lvp__step *step = &binding->step;
	bool ok = true;
	step->positions = lvp__calloc(n * 3, sizeof(float), &ok);
	step->moved = lvp__calloc(n, sizeof(int32_t), &ok);
	step->backup = lvp__calloc(n * 3, sizeof(float), &ok);
	step->smoothing_offsets = lvp__calloc(n * 3, sizeof(float), &ok);
	step->smoothing_scratch = lvp__calloc(n * 3, sizeof(float), &ok);
	step->chunk_moved = lvp__calloc(n / LVP__GRAIN + 1, sizeof(int32_t), &ok);
	step->change = lvp__calloc(s, sizeof(double), &ok);
	step->target = lvp__calloc(s, sizeof(double), &ok);
	step->uniform_gain = lvp__calloc(s, sizeof(double), &ok);
	step->total_gain = lvp__calloc(s, sizeof(double), &ok);
	step->diagonal = lvp__calloc(s, sizeof(double), &ok);
	step->region_movable = lvp__calloc(s, sizeof(uint8_t), &ok);
	step->region_touched = lvp__calloc(s, sizeof(uint8_t), &ok);
	step->active = lvp__calloc(s, sizeof(int32_t), &ok);
	step->active_index = lvp__calloc(s, sizeof(int32_t), &ok);
	step->mu = lvp__calloc(s, sizeof(double), &ok);
	step->applied_mu = lvp__calloc(s, sizeof(double), &ok);
	step->moved_by = lvp__calloc(s, sizeof(double), &ok);
	step->given_up = lvp__calloc(s, sizeof(uint8_t), &ok);
	step->part_total = lvp__calloc(parts, sizeof(double), &ok);
	step->part_gain = lvp__calloc(parts, sizeof(double), &ok);
	step->part_response = lvp__calloc(parts, sizeof(double), &ok);
	step->part_mu = lvp__calloc(parts, sizeof(double), &ok);
	step->touched_phi = lvp__calloc(n, sizeof(float), &ok);
	step->chunk_gain = lvp__calloc(n / LVP__GRAIN + 1, sizeof(double), &ok);
	return ok;
}

void lvp__step_free(lvp__step *step)
{
	void *arrays[] = {step->positions, step->moved, step->backup, step->smoothing_offsets, step->smoothing_scratch,
	                  step->chunk_moved,
	                  step->change, step->target,
	                  step->uniform_gain, step->total_gain, step->diagonal, step->region_movable,
	                  step->region_touched, step->active, step->active_index, step->mu, step->applied_mu,
	                  step->moved_by, step->given_up, step->part_total, step->part_gain, step->part_response,
	                  step->part_mu,
	                  step->touched_phi, step->chunk_gain};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
