/*
 * offset_smoothing.c - the correction's offsets smoothed over the surface (lvp.h, OFFSET SMOOTHING;
 * docs/method.md, Smoothing the offsets). Each vertex moves along its own normal, and where the
 * skin folds (the inside of a finger closing, a palm under bent fingers) neighbouring normals
 * differ by tens of degrees: offsets of the same size along them open creases between the
 * vertices. A pass gives each vertex that can move half its own offset and half the weighted mean
 * of its neighbours' (a vertex that cannot move counts with no offset), a vector mean, so directions
 * blend as sizes do; the correction then restores the volume the smoothing took.
 *
 * The weights are the mesh's, fixed at bind: each triangle a neighbour shares with the vertex weighs
 * it 1 + cot of the triangle's angle opposite their edge (0 when that angle is right or obtuse). The
 * cotangents are those of the surface's Dirichlet energy: across the small angles of a long thin
 * triangle they tie its corners' offsets to the straight line between them, which is what keeps
 * the triangle from tilting (with equal weights, the irregular triangles of decimated and game
 * meshes tilted into creases under offsets smooth over the rings). The 1 keeps every neighbour in
 * the mean where the angles are right or obtuse, as on the triangulated quads of a remesh, whose
 * diagonals the cotangents alone would leave out. Vertices so tied that they move as one point are
 * then averaged as one (smoothing_ties.c).
 *
 * Every third pass, counted back from the last, weighs the neighbours equally instead. On quads
 * several times longer along a limb than around it (a body modelled as a box and subdivided) the
 * cotangents tie each vertex to its ring around the limb and leave its neighbours along the limb a
 * small share, so a bulge the map puts on one ring of a joint stayed a ridge one ring wide whatever
 * the passes (the roughness QUALITY.md reads, against the plain mean of the neighbours): equal
 * weights carry it along the limb. The two passes of the mesh's weights after each tie again what
 * the equal weights pulled apart: a pass whose cotangent across a short edge is in the tens shrinks
 * the difference between its ends to a few hundredths. Every other pass equal left more creases at
 * Fold-Over's presses on the coarse modelled human, every pass equal four times as many at its
 * knees, and the cotangents capped at 2 or 4 dozens more at the needles of metaball bodies
 * (BENCHMARKS.md).
 *
 * Fold-over's relaxation of pressed skin (foldover.c, lvp__relax_pressed) averages with the same weights
 * but ties more (binding.relaxation): which neighbour dominates a vertex is decided there on mean value
 * weights (lvp__mean_value_share), which grow as an edge shortens, so the ends of any edge much shorter than
 * those around it (a needle's, a fifth of the mean edge and less, which metaball and marching-cubes meshes
 * leave by the hundred) are tied into one point, where the cotangents tie only edges a few hundredths of the
 * mean long. Each press moves a vertex by as far as it crossed, a needle's two ends by different amounts,
 * and one pass of the relaxation between presses left them apart: thin triangles turned on edge along the
 * contact line (the 8,080-vertex metaball body at 150 degrees: 127 creases, 98 of them at needles). Averaging
 * by the mean value weights as well, or tying so in the frame's smoothing too, made the offsets rougher as
 * the roughness reads them, against the plain mean of the neighbours (the low-poly horse 0.30 -> 0.41 of the
 * largest offset, the decimated hand at the fist 0.27 -> 0.31).
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

/* A frame's smoothing weighs the neighbours equally on every this many passes, counted back from its last
 * (which weighs them as the mesh does): see the top of this file. */
#define LVP__EQUAL_PASS_EVERY 3

/* The weight a triangle gives neighbour j of vertex k (both its corners) at rest in the offsets'
 * smoothing: 1 + the cotangent of its third corner's angle, that part 0 where the angle is right or
 * obtuse. A triangle of no area has no angle and weighs 1; the bound keeps a near-degenerate one's
 * weight a float. */
static float lvp__cotangent_share(const float *rest, const int32_t triangle[3], int32_t k, int32_t j)
{
	int32_t l = triangle[0] != k && triangle[0] != j ? triangle[0]
	          : (triangle[1] != k && triangle[1] != j ? triangle[1] : triangle[2]);
	lvp__vec3 corner = lvp__load(rest + 3 * (int64_t)l);
	lvp__vec3 a = lvp__sub(lvp__load(rest + 3 * (int64_t)k), corner);
	lvp__vec3 b = lvp__sub(lvp__load(rest + 3 * (int64_t)j), corner);
	double sine = lvp__length(lvp__cross(a, b)), cosine = lvp__dot(a, b);
	double cotangent = sine > 0.0 ? cosine / sine : 0.0;
	return (float)(1.0 + fmin(fmax(cotangent, 0.0), 1e6));
}

/* The weight on which the relaxation's ties are decided: the triangle's mean value weight, tan(theta / 2) /
 * |x_j - x_k| with theta its angle at k (Floater 2003), times the sum of its two edges at k (on a fan of like
 * triangles, the mean value weights themselves; a thin triangle, short at k, weighs less than a full one). It
 * grows as the edge kj shortens, whatever the angle across it. tan(theta / 2) = |a x b| / (|a| |b| + <a, b>)
 * for the edges a (to j) and b leaving k. A triangle of no area weighs as the bound does (a straight angle: k
 * on the line between the others; a zero angle: nothing); an edge of no length counts as a millionth of the
 * triangle's other edge at k, so that it ties j to k outright, and one with both edges at k of no length
 * weighs nothing. */
static float lvp__mean_value_share(const float *rest, const int32_t triangle[3], int32_t k, int32_t j)
{
	int32_t l = triangle[0] != k && triangle[0] != j ? triangle[0]
	          : (triangle[1] != k && triangle[1] != j ? triangle[1] : triangle[2]);
	lvp__vec3 at = lvp__load(rest + 3 * (int64_t)k);
	lvp__vec3 a = lvp__sub(lvp__load(rest + 3 * (int64_t)j), at), b = lvp__sub(lvp__load(rest + 3 * (int64_t)l), at);
	double la = lvp__length(a), lb = lvp__length(b);
	double sine = lvp__length(lvp__cross(a, b)), below = la * lb + lvp__dot(a, b);
	double half_tangent = below > 1e-12 * la * lb ? sine / below : 1e6, edges = la + lb;
	return edges > 0.0 ? (float)(fmin(half_tangent, 1e6) * edges / fmax(la, 1e-6 * edges)) : 0.0f;
}

/* What the passes read besides the final lists: smoothing.halves from their shares, fixed at bind so that
 * a pass only multiplies and adds, and room for the list of the vertices they walk (smoothing.movable). */
static lvp_result lvp__prepare_passes(lvp_binding *binding, lvp__smoothing *smoothing, lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count;
	bool ok = true;
	smoothing->halves = lvp__calloc((size_t)smoothing->offsets[n] + 1, sizeof(float), &ok);
	smoothing->movable = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok);
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	for (int32_t k = 0; k < n; ++k) {
		double total = 0.0;
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
			total += smoothing->shares[e];
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
			smoothing->halves[e] = total > 0.0 ? (float)(0.5 * smoothing->shares[e] / total) : 0.0f;
	}
	return lvp_success;
}

/* One smoothing's lists, each neighbour's share (lvp__cotangent_share) summed over the triangles it shares
 * with the vertex, and its ties: decided on the same shares, or with tie_by_mean_value on the triangles'
 * mean value weights (lvp__mean_value_share), which are listed alongside and dropped after. */
static lvp_result lvp__build_lists(lvp_binding *binding, lvp__smoothing *smoothing, bool tie_by_mean_value,
                                   lvp_diagnostic *r_diag)
{
	const lvp__mesh *mesh = &binding->mesh;
	int32_t n = binding->vertex_count;
	int64_t corners = mesh->vertex_corner_offsets[n];
	bool ok = true;
	smoothing->offsets = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok);
	smoothing->neighbours = lvp__calloc((size_t)(2 * corners) + 1, sizeof(int32_t), &ok);
	smoothing->shares = lvp__calloc((size_t)(2 * corners) + 1, sizeof(float), &ok);
	float *tie_shares = tie_by_mean_value ? lvp__calloc((size_t)(2 * corners) + 1, sizeof(float), &ok) : NULL;
	if (!ok) {
		free(tie_shares);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	}
	const float *rest = binding->rest_positions;
	int32_t written = 0;
	for (int32_t k = 0; k < n; ++k) {
		int32_t first = written;
		/* The other corners of k's triangles; a vertex named again adds its share to its entry. */
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
			const int32_t *triangle = mesh->triangles + 3 * (int64_t)mesh->vertex_triangles[c];
			for (int i = 0; i < 3; ++i) {
				int32_t j = triangle[i], e = first;
				if (j == k)
					continue;
				while (e < written && smoothing->neighbours[e] != j)
					++e;
				if (e == written)
					smoothing->neighbours[written++] = j;
				smoothing->shares[e] += lvp__cotangent_share(rest, triangle, k, j);
				if (tie_shares)
					tie_shares[e] += lvp__mean_value_share(rest, triangle, k, j);
			}
		}
		smoothing->offsets[k + 1] = written;
	}
	lvp_result result = lvp__tie_smoothing(binding, smoothing, tie_shares, r_diag);
	free(tie_shares);
	return result ? result : lvp__prepare_passes(binding, smoothing, r_diag);
}

lvp_result lvp__build_smoothing(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	return lvp__build_lists(binding, &binding->smoothing, false, r_diag);
}

lvp_result lvp__relaxation_begin(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	if (binding->relaxation.offsets)
		return lvp_success;
	lvp_result result = lvp__build_lists(binding, &binding->relaxation, true, r_diag);
	if (!result && !lvp__plate_alloc(&binding->fold.plate, binding->vertex_count,
	                                 binding->relaxation.offsets[binding->vertex_count]))
		result = lvp_error_out_of_memory;
	if (!result)
		return lvp_success;
	/* nothing half built is taken for built at the next frame */
	lvp__smoothing_free(&binding->relaxation);
	memset(&binding->relaxation, 0, sizeof(binding->relaxation));
	lvp__plate_free(&binding->fold.plate);
	memset(&binding->fold.plate, 0, sizeof(binding->fold.plate));
	if (result != lvp_error_out_of_memory)
		return result;
	return lvp__fail(r_diag, result, "binding", -1, "could not allocate fold-over's relaxation of %d vertices.",
	                 (int)binding->vertex_count);
}

void lvp__smoothing_free(lvp__smoothing *smoothing)
{
	free(smoothing->offsets);
	free(smoothing->neighbours);
	free(smoothing->shares);
	free(smoothing->halves);
	free(smoothing->movable);
	free(smoothing->tie_offsets);
	free(smoothing->tie_members);
}

typedef struct lvp__smoothing_pass {
	lvp_binding *binding;
	const lvp__smoothing *smoothing; /* the weights: binding.smoothing, or binding.relaxation */
	const float *positions; /* the frame's input points */
	const float *from;      /* the offsets a pass reads */
	float *to;              /* and writes */
	bool equal_weights;     /* this pass weighs every neighbour alike (LVP__EQUAL_PASS_EVERY) */
} lvp__smoothing_pass;

/* step.smoothing_offsets of the dynamic vertices in [begin, end): where the steps put them, less
 * where the skinning did. */
static void lvp__take_offsets_range(void *context, int32_t begin, int32_t end)
{
	const lvp__smoothing_pass *pass = context;
	lvp_binding *binding = pass->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		for (int c = 0; c < 3; ++c)
			binding->step.smoothing_offsets[3 * k + c] =
			    binding->step.positions[3 * k + c] - pass->positions[3 * k + c];
	}
}

/* One pass over the vertices that can move in [begin, end) of smoothing.movable, from the offsets
 * `from` into `to`: each takes half its own and half the weighted mean of its neighbours' (or their plain
 * mean, equal_weights). Each reads `from` only and writes its own entry of `to`, so the result does not
 * depend on threads. */
static void lvp__smooth_range(void *context, int32_t begin, int32_t end)
{
	const lvp__smoothing_pass *pass = context;
	lvp_binding *binding = pass->binding;
	const lvp__smoothing *smoothing = pass->smoothing;
	const float *from = pass->from;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = smoothing->movable[v];
		const float *own = from + 3 * k;
		float *out = pass->to + 3 * k;
		/* A neighbour weighs what the triangles it shares with k give it (smoothing.halves): two
		 * inside the surface; one that cannot move counts with its offset, none when it is outside
		 * the dynamic set, whatever its entry holds. */
		if (smoothing->offsets[k + 1] == smoothing->offsets[k]) {
			memcpy(out, own, 3 * sizeof(float));
			continue;
		}
		float x = 0.5f * own[0], y = 0.5f * own[1], z = 0.5f * own[2];
		float equal_half =
		    pass->equal_weights ? 0.5f / (float)(smoothing->offsets[k + 1] - smoothing->offsets[k]) : 0.0f;
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e) {
			int32_t j = smoothing->neighbours[e];
			if (!dynamic[j])
				continue;
			float half = pass->equal_weights ? equal_half : smoothing->halves[e];
			x += half * from[3 * j];
			y += half * from[3 * j + 1];
			z += half * from[3 * j + 2];
		}
		out[0] = x;
		out[1] = y;
		out[2] = z;
	}
}

/* The smoothed offsets (`from`) into step.smoothing_offsets and onto the input points:
 * step.positions of the dynamic vertices in [begin, end). */
static void lvp__put_offsets(void *context, int32_t begin, int32_t end)
{
	const lvp__smoothing_pass *pass = context;
	lvp_binding *binding = pass->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		for (int c = 0; c < 3; ++c) {
			float offset = pass->from[3 * k + c];
			binding->step.smoothing_offsets[3 * k + c] = offset;
			binding->step.positions[3 * k + c] = pass->positions[3 * k + c] + offset;
		}
	}
}

void lvp__take_offsets(lvp_binding *binding, const float *positions)
{
	int32_t count = binding->dynamic.vertex_count;
	lvp__smoothing_pass pass = {binding, &binding->smoothing, positions, NULL, NULL, false};
	lvp__parallel_for(LVP__POOL_FOR(binding, count), lvp__take_offsets_range, &pass, count, LVP__GRAIN);
}

/* Lists the dynamic vertices that can move in smoothing.movable (whatever_the_map: those fold-over does not
 * hold), their number returned; every other dynamic vertex keeps its offset through the passes, so it is
 * copied into `to` once. */
static int32_t lvp__list_movable(lvp_binding *binding, lvp__smoothing *smoothing, const float *from, float *to,
                                 bool whatever_the_map)
{
	int32_t count = 0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (whatever_the_map ? !binding->fold.held[k] : lvp__can_move(binding, k))
			smoothing->movable[count++] = k;
		else
			memcpy(to + 3 * k, from + 3 * k, 3 * sizeof(float));
	}
	return count;
}

/* The rim of the moving skin (frame_map.rim: vertices the bind map lets move that this frame's map does not,
 * beside ones it moves), but for vertices fold-over holds, takes the offsets that leave the least roughness as
 * QUALITY.md measures it (a vertex's offset against the plain mean of its edge neighbours') summed in squares over
 * the rim and every vertex beside it: the moving skin's last ring, the rim and the still skin beyond, whose
 * offsets stay as they are (none outside the dynamic set). Each rim vertex k then solves
 *     o_k (1 + sum_v 1 / n_v^2) = m_k + sum_v (o_v - s_v / n_v) / n_v,
 * v over k's n_k neighbours, m_k the mean of their offsets, n_v a neighbour's count of neighbours and s_v the sum
 * of their offsets but k's: the least-squares system of the umbrella operator, symmetric and positive definite, so
 * the Gauss-Seidel sweeps (in the rim's order, from no offset, until none changes by more than LVP__RIM_TOLERANCE
 * of the largest) converge. The passes move only what the map moves, and without this the offsets rose from
 * nothing to their neighbours' within one edge, a cliff that on a coarse mesh is a large share of the moving
 * patch. On a one-dimensional ramp the values are the harmonic ones (half the offset beside them), which leave the
 * least roughness a ramp over one ring can (a quarter of the offset beside it; docs/method.md, Where the moving
 * skin ends); on a surface they also weigh the still skin beyond the rim, where the harmonic values of the
 * passes' weights left a cliff as steep as the one they took away (the still vertex beside three rim vertices of
 * the coarse modelled human's back). */
#define LVP__RIM_TOLERANCE 1e-3
#define LVP__RIM_SWEEPS 64 /* at most: each sweep lowers the summed squares, and a few leave what the tolerance asks */

/* The offset of vertex j in `offsets`: none outside the dynamic set, whatever its entry holds. */
static inline lvp__vec3 lvp__rim_offset_of(const uint8_t *dynamic, const float *offsets, int32_t j)
{
	return dynamic[j] ? lvp__load(offsets + 3 * (int64_t)j) : lvp__v(0.0, 0.0, 0.0);
}

/* The offset of rim vertex k that leaves the least summed squares of roughness around it, the others as they are
 * in `offsets` (see above). */
static lvp__vec3 lvp__rim_value(const lvp__smoothing *smoothing, const uint8_t *dynamic, const float *offsets,
                                int32_t k)
{
	int32_t count = smoothing->offsets[k + 1] - smoothing->offsets[k];
	lvp__vec3 sum = lvp__v(0.0, 0.0, 0.0);
	double diagonal = 1.0;
	for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e) {
		int32_t v = smoothing->neighbours[e];
		int32_t beside_v = smoothing->offsets[v + 1] - smoothing->offsets[v];
		if (beside_v == 0) /* k is v's neighbour as v is k's; a list without k would not be */
			continue;
		lvp__vec3 own = lvp__rim_offset_of(dynamic, offsets, v), others = lvp__v(0.0, 0.0, 0.0);
		for (int32_t f = smoothing->offsets[v]; f < smoothing->offsets[v + 1]; ++f)
			if (smoothing->neighbours[f] != k)
				others = lvp__add(others, lvp__rim_offset_of(dynamic, offsets, smoothing->neighbours[f]));
		sum = lvp__add(sum, lvp__scale(own, 1.0 / count));
		sum = lvp__add(sum, lvp__scale(lvp__sub(own, lvp__scale(others, 1.0 / beside_v)), 1.0 / beside_v));
		diagonal += 1.0 / ((double)beside_v * beside_v);
	}
	return lvp__scale(sum, 1.0 / diagonal);
}

static void lvp__feather_rim(lvp_binding *binding, float *offsets)
{
	const lvp__smoothing *smoothing = &binding->smoothing;
	const lvp__frame_map *frame_map = &binding->frame_map;
	const uint8_t *dynamic = frame_map->vertex_dynamic;
	for (int32_t i = 0; i < frame_map->rim_count; ++i)
		if (!binding->fold.held[frame_map->rim[i]])
			memset(offsets + 3 * (int64_t)frame_map->rim[i], 0, 3 * sizeof(float));
	for (int sweep = 0; sweep < LVP__RIM_SWEEPS; ++sweep) {
		double change = 0.0, largest = 0.0;
		for (int32_t i = 0; i < frame_map->rim_count; ++i) {
			int32_t k = frame_map->rim[i];
			if (binding->fold.held[k])
				continue;
			lvp__vec3 next = lvp__rim_value(smoothing, dynamic, offsets, k);
			float *now = offsets + 3 * (int64_t)k;
			change = fmax(change, lvp__length(lvp__sub(next, lvp__load(now))));
			largest = fmax(largest, lvp__length(next));
			now[0] = (float)next.x;
			now[1] = (float)next.y;
			now[2] = (float)next.z;
		}
		if (change <= LVP__RIM_TOLERANCE * largest)
			break;
	}
}

void lvp__feather_rim_again(lvp_binding *binding, const float *positions)
{
	const lvp__frame_map *frame_map = &binding->frame_map;
	lvp__take_offsets(binding, positions);
	lvp__feather_rim(binding, binding->step.smoothing_offsets);
	for (int32_t i = 0; i < frame_map->rim_count; ++i) {
		int64_t k = frame_map->rim[i];
		if (binding->fold.held[k])
			continue;
		for (int c = 0; c < 3; ++c)
			binding->step.positions[3 * k + c] = positions[3 * k + c] + binding->step.smoothing_offsets[3 * k + c];
	}
}

void lvp__smooth_offsets(lvp_binding *binding, const float *positions, int32_t passes, lvp__smoothing_kind kind)
{
	int32_t count = binding->dynamic.vertex_count;
	bool whatever_the_map = kind == LVP__SMOOTH_RELAXATION;
	lvp__smoothing *smoothing = whatever_the_map ? &binding->relaxation : &binding->smoothing;
	lvp__smoothing_pass pass = {binding, smoothing, positions, binding->step.smoothing_offsets,
	                            binding->step.smoothing_scratch, false};
	lvp__take_offsets(binding, positions);
	int32_t movable = lvp__list_movable(binding, smoothing, pass.from, pass.to, whatever_the_map);
	for (int32_t i = 0; i < passes; ++i) {
		/* Fold-over's relaxation keeps its own weights throughout: its ties are what it is for. So
		 * do the peaks beside its contacts (LVP__SMOOTH_BY_THE_MESH). */
		int32_t from_last = passes - 1 - i;
		pass.equal_weights =
		    kind == LVP__SMOOTH_FRAME && from_last % LVP__EQUAL_PASS_EVERY == LVP__EQUAL_PASS_EVERY - 1;
		lvp__parallel_for(LVP__POOL_FOR(binding, movable), lvp__smooth_range, &pass, movable, LVP__GRAIN);
		float *read = pass.to;
		pass.to = (float *)pass.from;
		pass.from = read;
	}
	if (!whatever_the_map)
		lvp__feather_rim(binding, (float *)pass.from);
	lvp__parallel_for(LVP__POOL_FOR(binding, count), lvp__put_offsets, &pass, count, LVP__GRAIN);
}
