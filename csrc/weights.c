/*
 * weights.c - automatic skinning weights of Rohmer, Hahmann, Cani 2008, section 5.1:
 * omega_ki = (l_i / d_ki)^alpha with d_ki the distance from vertex k to the SEGMENT of bone i (or, without
 * options.by_length, (1 / d_ki)^alpha: lvp.h), a bone
 * ignored when the straight path from the vertex to its closest point on the bone leaves the body (the
 * paper's normal-angle test, or an exact test of the path against the mesh through a BVH), the rigid
 * fallback for vertices that see no bone, then normalization, pruning and renormalization.
 *
 * The normal test costs a dot product per (vertex, bone), so every bone is tested. With the exact test a
 * path costs a BVH query, so the candidate bones are taken strongest first from a heap and a path is
 * only cast while it could still change the row: once max_influences visible bones are certain to
 * survive min_weight, or every bone left is certain to fall below it, weaker bones cannot enter the row.
 * The output is what testing every bone would give (the tests check it against a brute force), but
 * a vertex casts a few paths instead of one per bone; and the triangle that hid a bone from the previous
 * vertex is tried first, since neighbours are usually hidden by the same wall.
 *
 * Optionally (smoothing_iterations, smoothing_length or smoothing_thickness > 0) the rows are then diffused
 * over the surface's edges, which makes them continuous; see "smoothing over the surface" below.
 */
#include "bvh.h"
#include "diffusion.h"
#include "lvp_internal.h"

#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>

/* Distances below this fraction of the bone's length count as this fraction: a vertex on a bone gets a
 * finite, overwhelming weight (1e12 times that of a bone one length away, for alpha = 2), and a vertex on
 * the joint of two bones is shared evenly between them, the limit of approaching the joint. */
#define LVP__DISTANCE_FLOOR 1e-6
/* Exact test: crossings within this fraction of the path from either end are ignored, so the triangles
 * that touch the start (duplicated seam vertices, neighbours grazed at the start) and a bone that touches
 * the surface do not hide anything. */
#define LVP__PATH_EPSILON 1e-6

lvp_auto_weights_options lvp_auto_weights_default_options(void)
{
	lvp_auto_weights_options options;
	options.alpha = 2.0f;
	options.by_length = 1;
	options.facing = 0;
	options.visibility = LVP_VISIBILITY_NORMAL;
	options.normal_cos_max = 0.0f;
	options.max_influences = 4;
	options.min_weight = 0.01f;
	options.smoothing_iterations = 0;
	options.smoothing_length = 0.0f;
	options.smoothing_thickness = 0.0f;
	options.heat = 0;
	options.thread_count = 1;
	return options;
}

/* Most influences one vertex can receive: all bones, at most max_influences, and at most 1/min_weight
 * (normalized weights of at least min_weight sum to at most 1; one more covers rounding). Never 0: the
 * rigid fallback always writes one. */
static int64_t lvp__row_bound(int32_t bone_count, const lvp_auto_weights_options *options)
{
	int64_t bound = bone_count;
	if (options->max_influences > 0 && options->max_influences < bound)
		bound = options->max_influences;
	if (options->min_weight > 0.0f && options->min_weight <= 1.0f) {
		double by_weight = floor(1.0 / (double)options->min_weight) + 1.0;
		if (by_weight < (double)bound)
			bound = (int64_t)by_weight;
	}
	return bound < 1 ? 1 : bound;
}

int64_t lvp_auto_weights_bound(int32_t vertex_count, int32_t bone_count, const lvp_auto_weights_options *options)
{
	if (vertex_count <= 0 || vertex_count > LVP_MAX_VERTICES || bone_count <= 0 || bone_count > LVP_MAX_BONES)
		return 0;
	lvp_auto_weights_options defaults = lvp_auto_weights_default_options();
	return (int64_t)vertex_count * lvp__row_bound(bone_count, options ? options : &defaults);
}

static lvp_result lvp__check_options(const lvp_auto_weights_options *o, lvp_diagnostic *r_diag)
{
	if (!(isfinite(o->alpha) && o->alpha > 0.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.alpha", -1,
		                 "options.alpha is %g; the weight exponent must be a finite number above 0 (default 2).",
		                 (double)o->alpha);
	if ((int)o->visibility < (int)LVP_VISIBILITY_NORMAL || (int)o->visibility > (int)LVP_VISIBILITY_NONE)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.visibility", -1,
		                 "options.visibility is %d; use LVP_VISIBILITY_NORMAL, _EXACT or _NONE.", (int)o->visibility);
	if (!(o->normal_cos_max >= -1.0f && o->normal_cos_max <= 1.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.normal_cos_max", -1,
		                 "options.normal_cos_max is %g; it is a cosine, in [-1, 1] (default 0).",
		                 (double)o->normal_cos_max);
	if (o->max_influences < 0)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.max_influences", -1,
		                 "options.max_influences is %d; use 0 for all bones or a positive count (default 4).",
		                 (int)o->max_influences);
	if (!(o->min_weight >= 0.0f && o->min_weight <= 1.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.min_weight", -1,
		                 "options.min_weight is %g; it is a normalized weight, in [0, 1] (default 0.01).",
		                 (double)o->min_weight);
	if (o->smoothing_iterations < 0 || o->smoothing_iterations > LVP_MAX_SMOOTHING_ITERATIONS)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.smoothing_iterations", -1,
		                 "options.smoothing_iterations is %d; use 0 (none) to %d (default 0).",
		                 (int)o->smoothing_iterations, LVP_MAX_SMOOTHING_ITERATIONS);
	if (!(isfinite(o->smoothing_length) && o->smoothing_length >= 0.0f))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.smoothing_length", -1,
		                 "options.smoothing_length is %g; it is a distance in the mesh's units, 0 (use "
		                 "smoothing_iterations) or above.",
		                 (double)o->smoothing_length);
	if (o->thread_count < 1 || o->thread_count > LVP_MAX_THREADS)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.thread_count", -1,
		                 "options.thread_count is %d; use 1 to %d threads (default 1).", (int)o->thread_count,
		                 LVP_MAX_THREADS);
	if (o->heat != 0 && o->heat != 1)
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.heat", -1,
		                 "options.heat is %d; use 0 (the weights of 5.1, smoothed as the options say) or 1 (bone "
		                 "heat).",
		                 (int)o->heat);
	if (!(o->smoothing_thickness >= 0.0f && o->smoothing_thickness <= LVP_MAX_SMOOTHING_THICKNESS))
		return lvp__fail(r_diag, lvp_error_invalid_option, "options.smoothing_thickness", -1,
		                 "options.smoothing_thickness is %g; it is a multiple of the flesh's thickness, 0 (use "
		                 "smoothing_length or smoothing_iterations) to %g.",
		                 (double)o->smoothing_thickness, (double)LVP_MAX_SMOOTHING_THICKNESS);
	return lvp_success;
}

typedef struct lvp__bone_segment {
	lvp__vec3 head, axis;  /* axis = tail - head */
	double inverse_length2; /* 1 / |axis|^2, 0 for a zero-length bone */
	double length2;
	double floor2; /* squared distance floor, see LVP__DISTANCE_FLOOR */
	lvp__vec3 middle; /* the ball around the bone: its middle and half its length */
	double half_length;
} lvp__bone_segment;

static inline lvp__vec3 lvp__closest_on_bone(const lvp__bone_segment *bone, lvp__vec3 p)
{
	double t = lvp__dot(lvp__sub(p, bone->head), bone->axis) * bone->inverse_length2;
	t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
	return lvp__add(bone->head, lvp__scale(bone->axis, t));
}

/* A bone that may weigh on the current vertex. key = (l / d)^2 (without by_length, (1 / d)^2) orders the bones exactly as their weights
 * do, whatever alpha; weight is (key / key of the strongest visible bone)^(alpha/2), set once that bone is
 * known, so it never overflows and the strongest visible bone weighs 1. */
typedef struct lvp__candidate {
	double key, weight;
	int32_t bone;
} lvp__candidate;

static inline bool lvp__stronger(const lvp__candidate *a, const lvp__candidate *b)
{
	return a->key > b->key || (a->key == b->key && a->bone < b->bone);
}

static void lvp__sift_down(lvp__candidate *heap, int32_t count, int32_t i)
{
	for (;;) {
		int32_t best = i, left = 2 * i + 1, right = left + 1;
		if (left < count && lvp__stronger(&heap[left], &heap[best]))
			best = left;
		if (right < count && lvp__stronger(&heap[right], &heap[best]))
			best = right;
		if (best == i)
			return;
		lvp__candidate swap = heap[i];
		heap[i] = heap[best];
		heap[best] = swap;
		i = best;
	}
}

static inline double lvp__relative_weight(double ratio, double alpha)
{
	/* ratio = (l_i d_top / (l_top d_i))^2 in (0, 1]; the common exponents skip pow(). */
	if (alpha == 2.0)
		return ratio;
	if (alpha == 1.0)
		return sqrt(ratio);
	if (alpha == 4.0)
		return ratio * ratio;
	if (alpha == 16.0) { /* the add-on's default */
		double r4 = (ratio * ratio) * (ratio * ratio);
		return r4 * r4;
	}
	return pow(ratio, 0.5 * alpha);
}

/* Everything a call needs, shared by the per-vertex routine. */
typedef struct lvp__weights_context {
	const float *positions;
	const float *normals; /* NORMAL test only, outward */
	const lvp__bone_segment *bones;
	int32_t bone_count;
	const lvp__bvh *bvh; /* EXACT test only */
	lvp_visibility visibility;
	double alpha, normal_cos_max, min_weight;
	bool by_length;         /* options.by_length */
	const float *facing_trust; /* options.facing: per vertex, how far its normal tells which way its skin
	                              faces (lvp__facing_trust), else NULL */
	int32_t max_influences; /* 0 = all */
	lvp__candidate *heap;   /* bone_count scratch */
	lvp__candidate *visible; /* bone_count scratch */
	int32_t *blockers;       /* EXACT: per bone, the BVH subtree that last hid it (-1), searched first next time */
} lvp__weights_context;

/* options.facing: the share of a bone's distance from vertex k that counts, (1.001 + cos) / 2 with cos
 * that of the angle between k's outward normal n and the path to k from the bone's closest point,
 * `toward` = closest - k of length `distance`, taken only as far as the normal can be trusted: a
 * share of 1 - trust (1 - (1.001 + cos) / 2). */
static inline double lvp__facing_share(lvp__vec3 n, double trust, lvp__vec3 toward, double distance)
{
	if (!(distance > 0.0) || !(trust > 0.0))
		return 1.0;
	return 1.0 - trust * (1.0 - 0.5 * (1.001 - lvp__dot(toward, n) / distance));
}

/* Into r_trust, how far each vertex's outward normal tells which way its skin faces, for options.facing:
 * the least cosine between it and the normals of the triangles around it (0 when negative), 1 on a
 * smooth surface, less where the triangles turn around a crease or a corner (a cap's rim, whose normal
 * leans half toward each side: it faces neither way); and 0 on an edge that is not two triangles' (an open
 * border, a fin on a body), where the surface has no inside to face away from. Returns false when memory
 * runs out. */
static bool lvp__facing_trust(float *r_trust, const float *positions, const float *normals, int32_t vertex_count,
                              const int32_t *triangles, int32_t triangle_count)
{
	uint64_t *edges = malloc(sizeof(uint64_t) * (3 * (size_t)triangle_count + 1));
	if (!edges)
		return false;
	for (int32_t k = 0; k < vertex_count; ++k)
		r_trust[k] = 1.0f;
	for (int32_t t = 0; t < triangle_count; ++t) {
		const int32_t *corners = triangles + 3 * (int64_t)t;
		lvp__vec3 a = lvp__load(positions + 3 * (int64_t)corners[0]);
		lvp__vec3 normal = lvp__cross(lvp__sub(lvp__load(positions + 3 * (int64_t)corners[1]), a),
		                              lvp__sub(lvp__load(positions + 3 * (int64_t)corners[2]), a));
		double area2 = lvp__length(normal);
		for (int i = 0; i < 3; ++i) {
			int32_t k = corners[i], next = corners[(i + 1) % 3];
			uint32_t low = (uint32_t)(k < next ? k : next), high = (uint32_t)(k < next ? next : k);
			edges[3 * (int64_t)t + i] = ((uint64_t)low << 32) | high;
			if (area2 > 0.0) {
				double cosine = lvp__dot(normal, lvp__load(normals + 3 * (int64_t)k)) / area2;
				r_trust[k] = fminf(r_trust[k], cosine > 0.0 ? (float)cosine : 0.0f);
			}
		}
	}
	size_t count = 3 * (size_t)triangle_count;
	qsort(edges, count, sizeof(uint64_t), lvp__compare_u64);
	for (size_t first = 0, last; first < count; first = last) {
		for (last = first + 1; last < count && edges[last] == edges[first]; ++last) {
		}
		if (last - first != 2) {
			r_trust[edges[first] >> 32] = 0.0f;
			r_trust[edges[first] & 0xffffffffu] = 0.0f;
		}
	}
	free(edges);
	return true;
}

/* The NORMAL test: whether the path `diff` (of squared length d2) from a vertex to its closest point on a bone
 * leaves through the skin, its angle with the vertex's unit outward normal n above the option's. A vertex on
 * the bone sees it. */
static inline bool lvp__normal_hides(const lvp__weights_context *ctx, lvp__vec3 n, lvp__vec3 diff, double d2)
{
	return d2 > 0.0 && lvp__dot(diff, n) > ctx->normal_cos_max * sqrt(d2); /* cos(path, n) = <diff, n> / d */
}

/* Whether the straight path from vertex k at p to its closest point on bone i stays inside the body. */
static bool lvp__path_is_inside(const lvp__weights_context *ctx, int32_t k, lvp__vec3 p, int32_t bone)
{
	lvp__vec3 c = lvp__closest_on_bone(&ctx->bones[bone], p);
	lvp__vec3 path = lvp__sub(c, p);
	if (path.x == 0.0 && path.y == 0.0 && path.z == 0.0)
		return true; /* the vertex is on the bone */
	return !lvp__bvh_segment_hits(ctx->bvh, p, c, LVP__PATH_EPSILON, 1.0 - LVP__PATH_EPSILON, k,
	                              &ctx->blockers[bone]);
}

/* Writes visible[0 .. kept) renormalized as the row; returns its length. */
static int32_t lvp__write_row(int32_t *r_bones, float *r_values, const lvp__candidate *visible, int32_t kept)
{
	double sum = 0.0;
	for (int32_t j = 0; j < kept; ++j)
		sum += visible[j].weight;
	for (int32_t j = 0; j < kept; ++j) {
		r_bones[j] = visible[j].bone;
		r_values[j] = (float)(visible[j].weight / sum);
	}
	return kept;
}

/* NORMAL and NONE: every candidate is visible, so the total is known at once. Keeps the candidates of
 * normalized weight >= min_weight, the strongest max_influences of them, in visible[] (by decreasing
 * weight, ties to the lower bone); returns how many. */
static int32_t lvp__select_known(const lvp__weights_context *ctx, lvp__candidate *candidates, int32_t count)
{
	double top = 0.0;
	for (int32_t j = 0; j < count; ++j)
		top = candidates[j].key > top ? candidates[j].key : top;
	double sum = 0.0;
	for (int32_t j = 0; j < count; ++j) {
		candidates[j].weight = lvp__relative_weight(candidates[j].key / top, ctx->alpha);
		sum += candidates[j].weight;
	}
	double threshold = ctx->min_weight * sum;
	int32_t room = ctx->max_influences > 0 && ctx->max_influences < count ? ctx->max_influences : count;
	lvp__candidate *visible = ctx->visible;
	int32_t kept = 0;
	for (int32_t j = 0; j < count; ++j) { /* insertion into a short sorted list; candidates are in bone order */
		double w = candidates[j].weight;
		if (!(w > 0.0) || w < threshold || (kept == room && !(w > visible[kept - 1].weight)))
			continue;
		int32_t at = kept < room ? kept++ : kept - 1;
		while (at > 0 && visible[at - 1].weight < w) {
			visible[at] = visible[at - 1];
			--at;
		}
		visible[at] = candidates[j];
	}
	if (kept == 0) {
		/* min_weight above every weight: the strongest bone stays, rather than none */
		for (int32_t j = 0; j < count; ++j)
			if (candidates[j].key == top) {
				visible[0] = candidates[j];
				return 1;
			}
	}
	return kept;
}

/* EXACT: bones are taken strongest first from a heap and their paths tested only while the answer can
 * still change. visible[] receives the visible ones in that order (non-increasing weight). The normalized
 * weight of visible[j] is its weight / total, with total the sum over every visible bone, known to lie in
 * [visible_sum, visible_sum + untested]; the bones kept by min_weight form a prefix of visible[], and
 * sure_kept counts the part of it certain to be kept. Returns the number kept, 0 if no bone is visible. */
static int32_t lvp__select_lazily(const lvp__weights_context *ctx, lvp__candidate *heap, int32_t count, int32_t k,
                                  lvp__vec3 p)
{
	for (int32_t i = count / 2 - 1; i >= 0; --i)
		lvp__sift_down(heap, count, i);
	lvp__candidate *visible = ctx->visible;
	int32_t visible_count = 0, sure_kept = 0, k_max = ctx->max_influences;
	double visible_sum = 0.0, untested = 0.0, mw = ctx->min_weight;
	while (count > 0) {
		lvp__candidate c = heap[0];
		heap[0] = heap[--count];
		lvp__sift_down(heap, count, 0);
		if (visible_count > 0)
			untested -= c.weight;
		if (!lvp__path_is_inside(ctx, k, p, c.bone))
			continue;
		if (visible_count == 0) {
			/* The strongest visible bone: weights are measured relative to it from now on. */
			c.weight = 1.0;
			untested = 0.0;
			for (int32_t j = 0; j < count; ++j) {
				heap[j].weight = lvp__relative_weight(heap[j].key / c.key, ctx->alpha);
				untested += heap[j].weight;
			}
		}
		visible[visible_count++] = c;
		visible_sum += c.weight;
		if (count == 0 || untested < 0.0)
			untested = 0.0;
		double upper = mw * (visible_sum + untested), lower = mw * visible_sum;
		/* A weight that underflowed to zero is never stored, whatever min_weight says. */
		while (sure_kept < visible_count && visible[sure_kept].weight >= upper && visible[sure_kept].weight > 0.0)
			++sure_kept;
		if (k_max > 0 && sure_kept >= k_max)
			break;
		bool decided = sure_kept == visible_count || visible[sure_kept].weight < lower ||
		               visible[sure_kept].weight == 0.0;
		if (decided && count > 0 && (heap[0].weight < lower || heap[0].weight == 0.0))
			break; /* every bone left would be pruned, whatever it sees */
	}
	if (visible_count == 0)
		return 0;
	int32_t kept = sure_kept;
	if (count == 0) {
		/* Every bone was decided: the total is exact. */
		kept = 0;
		while (kept < visible_count && visible[kept].weight >= mw * visible_sum && visible[kept].weight > 0.0)
			++kept;
	}
	if (k_max > 0 && kept > k_max)
		kept = k_max;
	return kept > 0 ? kept : 1; /* min_weight above every weight: the strongest bone stays, rather than none */
}

/* Computes the row of vertex k into r_bones/r_values (room for the row bound); returns its length. */
static int32_t lvp__vertex_weights(int32_t *r_bones, float *r_values, const lvp__weights_context *ctx, int32_t k)
{
	lvp__vec3 p = lvp__load(ctx->positions + 3 * (int64_t)k);
	lvp__vec3 n = ctx->normals ? lvp__load(ctx->normals + 3 * (int64_t)k) : lvp__v(0.0, 0.0, 0.0);
	/* A vertex without a normal (isolated, or only zero-area triangles) cannot be judged by its normal:
	 * every bone passes the test. */
	bool normal_test = ctx->visibility == LVP_VISIBILITY_NORMAL && (n.x != 0.0 || n.y != 0.0 || n.z != 0.0);
	lvp__candidate *candidates = ctx->heap;
	int32_t count = 0;
	/* The rigid fallback's bone: the closest bone with a length; a zero-length bone (a point) only when
	 * the skeleton has no other, since such bones never receive weight otherwise. */
	int32_t closest = -1, closest_point = -1;
	double closest_d2 = INFINITY, closest_point_d2 = INFINITY;
	for (int32_t i = 0; i < ctx->bone_count; ++i) {
		const lvp__bone_segment *bone = &ctx->bones[i];
		if (bone->length2 == 0.0) {
			lvp__vec3 diff = lvp__sub(bone->head, p);
			double d2 = lvp__dot(diff, diff);
			if (d2 < closest_point_d2)
				closest_point_d2 = d2, closest_point = i;
			continue;
		}
		lvp__vec3 diff = lvp__sub(lvp__closest_on_bone(bone, p), p);
		double d2 = lvp__dot(diff, diff);
		if (d2 < closest_d2)
			closest_d2 = d2, closest = i;
		if (normal_test && lvp__normal_hides(ctx, n, diff, d2))
			continue;
		double counted2 = d2 > bone->floor2 ? d2 : bone->floor2;
		if (ctx->facing_trust) {
			double share = lvp__facing_share(n, ctx->facing_trust[k], diff, sqrt(d2));
			counted2 /= share * share;
		}
		candidates[count].key = (ctx->by_length ? bone->length2 : 1.0) / counted2;
		candidates[count].bone = i;
		candidates[count].weight = 0.0;
		++count;
	}
	int32_t kept = 0;
	if (count > 0)
		kept = ctx->visibility == LVP_VISIBILITY_EXACT ? lvp__select_lazily(ctx, candidates, count, k, p)
		                                               : lvp__select_known(ctx, candidates, count);
	if (kept == 0) {
		/* The rigid fallback: a vertex that sees no bone (a horn) follows its closest bone. */
		r_bones[0] = closest >= 0 ? closest : closest_point;
		r_values[0] = 1.0f;
		return 1;
	}
	return lvp__write_row(r_bones, r_values, ctx->visible, kept);
}

/* ---- smoothing over the surface ----------------------------------------------------------------------
 *
 * The 5.1 weights change abruptly between neighbouring vertices wherever a bone's visibility flips or a bone
 * enters or leaves the strongest few; and with the paper's alpha = 2 they are so wide that a shin takes weight
 * from the thigh and the belly from the thighs, which loses volume at every bend. A high alpha keeps each
 * bone on its own flesh (close to the nearest visible bone), and the smoothing makes the borders between bones
 * continuous: each step replaces every row by the mean of its own and its edge neighbours' rows, kept to the
 * strongest LVP__DIFFUSION_ROW bones and renormalized (diffusion.c). Visibility decides the rows before the
 * smoothing, not during it: the normal test flips across the crotch and the armpit, and a bone barred from the
 * vertices it is hidden from there would leave a hard seam (both thighs at weight 1 across one edge) exactly
 * where the skin must blend. Each step widens a border by about one edge, so the width of the blend is counted
 * in edges, not in metres. */

/* The smoothed row of vertex k pruned as the options say (the strongest max_influences of weight at least
 * min_weight of the row's sum, the strongest alone when none is), renormalized; returns its length. */
static int32_t lvp__smoothed_row(int32_t *r_bones, float *r_values, const lvp__diffusion *smooth,
                                 const lvp__weights_context *ctx, int32_t k)
{
	const int32_t *bones = smooth->bones + (int64_t)k * smooth->stride;
	const float *values = smooth->values + (int64_t)k * smooth->stride;
	int32_t count = smooth->counts[k], kept = 0;
	double sum = 0.0, kept_sum = 0.0;
	for (int32_t j = 0; j < count; ++j)
		sum += values[j];
	while (kept < count && (ctx->max_influences == 0 || kept < ctx->max_influences) &&
	       values[kept] >= ctx->min_weight * sum && values[kept] > 0.0f)
		kept_sum += values[kept++];
	if (kept == 0)
		kept_sum = values[kept++];
	for (int32_t j = 0; j < kept; ++j) {
		r_bones[j] = bones[j];
		r_values[j] = (float)(values[j] / kept_sum);
	}
	return kept;
}

/* The distance from vertex k to bone i (to its head when it has no length) over its facing share with
 * options.facing; the straight distance into *r_straight. */
static double lvp__distance_to_bone(double *r_straight, const lvp__weights_context *ctx, int32_t k, int32_t i)
{
	lvp__vec3 p = lvp__load(ctx->positions + 3 * (int64_t)k);
	const lvp__bone_segment *bone = &ctx->bones[i];
	lvp__vec3 toward = lvp__sub(bone->length2 > 0.0 ? lvp__closest_on_bone(bone, p) : bone->head, p);
	double distance = lvp__length(toward);
	*r_straight = distance;
	if (ctx->facing_trust)
		distance /= lvp__facing_share(lvp__load(ctx->normals + 3 * (int64_t)k), ctx->facing_trust[k], toward,
		                              distance);
	return distance;
}

/* Vertex k's distance to bone i as bone heat measures it (lvp__heat_sources). */
static double lvp__heat_distance(const lvp__weights_context *ctx, int32_t i, lvp__vec3 p, lvp__vec3 n, int32_t k)
{
	const lvp__bone_segment *bone = &ctx->bones[i];
	lvp__vec3 diff = lvp__sub(lvp__closest_on_bone(bone, p), p);
	double d2 = lvp__dot(diff, diff), distance = sqrt(d2 > bone->floor2 ? d2 : bone->floor2);
	if (ctx->facing_trust)
		distance /= lvp__facing_share(n, ctx->facing_trust[k], diff, sqrt(d2));
	return distance;
}

/* Vertex k's sources for bone heat (HEAT in lvp.h; screened_diffusion.c), as Blender finds them: its distance
 * to the nearest bone with a length (over the facing share with options.facing), and the bones within a
 * ten-thousandth of it that the visibility test lets it see, shared evenly, into r_bones / r_values (at most
 * `room`); its screening 1 / d^2 times their number (0 when it sees none of them) and that distance into
 * r_screening and r_depth. Returns how many. */
static int32_t lvp__heat_sources(int32_t *r_bones, float *r_values, double *r_screening, double *r_depth,
                                 const lvp__weights_context *ctx, int32_t k, int32_t room)
{
	lvp__vec3 p = lvp__load(ctx->positions + 3 * (int64_t)k);
	lvp__vec3 n = ctx->normals ? lvp__load(ctx->normals + 3 * (int64_t)k) : lvp__v(0.0, 0.0, 0.0);
	bool normal_test = ctx->visibility == LVP_VISIBILITY_NORMAL && (n.x != 0.0 || n.y != 0.0 || n.z != 0.0);
	/* A bone's distance is at least the distance to the ball around it (a facing share only lengthens it): a
	 * bone whose ball lies farther than the nearest distance measured so far, by more than the sources'
	 * ten-thousandth (twice that, against rounding), can be neither the nearest nor a source, and is not
	 * measured. The bone whose ball is nearest is measured first. */
	lvp__candidate *distances = ctx->heap;
	int32_t count = 0, first = -1;
	for (int32_t i = 0; i < ctx->bone_count; ++i) {
		const lvp__bone_segment *bone = &ctx->bones[i];
		if (bone->length2 == 0.0)
			continue;
		double to_ball = lvp__length(lvp__sub(bone->middle, p)) - bone->half_length;
		distances[count].key = to_ball;
		distances[count++].bone = i;
		if (first < 0 || to_ball < distances[first].key)
			first = count - 1;
	}
	double nearest = INFINITY;
	if (first >= 0) {
		nearest = lvp__heat_distance(ctx, distances[first].bone, p, n, k);
		distances[first].key = nearest;
	}
	for (int32_t j = 0; j < count; ++j) {
		if (j == first)
			continue;
		if (distances[j].key > nearest * (1.0 + 2e-4)) {
			distances[j].key = INFINITY; /* not a source, by the bound */
			continue;
		}
		distances[j].key = lvp__heat_distance(ctx, distances[j].bone, p, n, k);
		nearest = distances[j].key < nearest ? distances[j].key : nearest;
	}
	int32_t sources = 0;
	for (int32_t j = 0; j < count && sources < room; ++j) {
		if (!(distances[j].key <= nearest * (1.0 + 1e-4)))
			continue;
		int32_t bone = distances[j].bone;
		if (normal_test) {
			lvp__vec3 diff = lvp__sub(lvp__closest_on_bone(&ctx->bones[bone], p), p);
			if (lvp__normal_hides(ctx, n, diff, lvp__dot(diff, diff)))
				continue;
		} else if (ctx->visibility == LVP_VISIBILITY_EXACT && !lvp__path_is_inside(ctx, k, p, bone)) {
			continue;
		}
		r_bones[sources++] = bone;
	}
	for (int32_t j = 0; j < sources; ++j)
		r_values[j] = 1.0f / (float)sources;
	*r_depth = nearest;
	*r_screening = sources > 0 ? (double)sources / (nearest * nearest) : 0.0;
	return sources;
}

/* Heat weights' own cut (Blender's heat_limit_weight): a weight below LVP__HEAT_CUT is dropped, one up to
 * twice that ramps from 0 to it, so that the long thin tails of the diffusion do not tie skin to bones far
 * away (each such tail, small as it is, pulls the skin of a joint as the bone turns). */
#define LVP__HEAT_CUT 0.025f

static float lvp__heat_cut(float weight)
{
	if (weight < LVP__HEAT_CUT)
		return 0.0f;
	return weight < 2.0f * LVP__HEAT_CUT ? 2.0f * (weight - LVP__HEAT_CUT) : weight;
}

/* Into r_normals, each vertex's normal as heat weights measure which way skin faces: the sum of its
 * triangles' unit normals (every triangle counting alike, however small), normalized, turned to agree with
 * `outward` (the area-weighted normals, turned outward already). */
static void lvp__heat_normals(float *r_normals, const float *outward, const float *positions, int32_t vertex_count,
                              const int32_t *triangles, int32_t triangle_count)
{
	memset(r_normals, 0, sizeof(float) * 3 * (size_t)vertex_count);
	for (int64_t t = 0; t < triangle_count; ++t) {
		const int32_t *v = triangles + 3 * t;
		lvp__vec3 a = lvp__load(positions + 3 * (int64_t)v[0]);
		lvp__vec3 normal = lvp__cross(lvp__sub(lvp__load(positions + 3 * (int64_t)v[1]), a),
		                              lvp__sub(lvp__load(positions + 3 * (int64_t)v[2]), a));
		double length = lvp__length(normal);
		if (!(length > 0.0))
			continue;
		for (int c = 0; c < 3; ++c) {
			float *n = r_normals + 3 * (int64_t)v[c];
			n[0] += (float)(normal.x / length);
			n[1] += (float)(normal.y / length);
			n[2] += (float)(normal.z / length);
		}
	}
	for (int32_t k = 0; k < vertex_count; ++k) {
		lvp__vec3 n = lvp__load(r_normals + 3 * (int64_t)k);
		double length = lvp__length(n);
		double scale = length > 0.0 ? (lvp__dot(n, lvp__load(outward + 3 * (int64_t)k)) < 0.0 ? -1.0 : 1.0) / length
		                            : 0.0;
		r_normals[3 * (int64_t)k] = (float)(scale * n.x);
		r_normals[3 * (int64_t)k + 1] = (float)(scale * n.y);
		r_normals[3 * (int64_t)k + 2] = (float)(scale * n.z);
	}
}

/* The sources of every vertex, on the pool's threads: each worker takes blocks of vertices until none is
 * left, with its own scratch (each vertex's sources are its own, wherever they are found). */
#define LVP__SOURCES_BLOCK 512
typedef struct lvp__sources_work {
	const lvp__weights_context *ctx;
	lvp__diffusion *rows;
	double *screening, *depths;
	int32_t vertex_count;
	atomic_int next_block;
	atomic_bool failed;
} lvp__sources_work;

static void lvp__sources_task(void *context, int32_t begin, int32_t end)
{
	lvp__sources_work *work = context;
	int32_t bones = work->ctx->bone_count, stride = work->rows->stride;
	for (int32_t item = begin; item < end; ++item) {
		lvp__weights_context mine = *work->ctx;
		mine.heap = malloc(sizeof(lvp__candidate) * ((size_t)bones + 1));
		mine.blockers = malloc(sizeof(int32_t) * ((size_t)bones + 1));
		if (!mine.heap || !mine.blockers) {
			atomic_store(&work->failed, true);
		} else {
			for (int32_t i = 0; i < bones; ++i)
				mine.blockers[i] = -1;
			for (;;) {
				int32_t first = atomic_fetch_add(&work->next_block, 1) * LVP__SOURCES_BLOCK;
				if (first >= work->vertex_count)
					break;
				int32_t last = work->vertex_count - first < LVP__SOURCES_BLOCK ? work->vertex_count
				                                                               : first + LVP__SOURCES_BLOCK;
				for (int32_t k = first; k < last; ++k)
					work->rows->counts[k] = lvp__heat_sources(
					    work->rows->bones + (int64_t)k * stride, work->rows->values + (int64_t)k * stride,
					    &work->screening[k], &work->depths[k], &mine, k, stride);
			}
		}
		free(mine.heap);
		free(mine.blockers);
	}
}

/* The rows of bone heat (HEAT in lvp.h): each vertex's sources, the screened diffusion, heat weights' cut;
 * a vertex that no bone's heat reaches (no source on its piece of skin) takes its row by 5.1, the rigid
 * fallback when it sees no bone. Returns false when memory runs out. */
static bool lvp__heat_weights(lvp__diffusion *rows, const lvp__weights_context *ctx, const int32_t *triangles,
                              int32_t vertex_count, int32_t triangle_count, int32_t thread_count)
{
	size_t n = (size_t)vertex_count;
	double *screening = malloc(sizeof(double) * 2 * (n + 1));
	float *normals = ctx->normals ? malloc(sizeof(float) * 3 * (n + 1)) : NULL;
	if (!screening || (ctx->normals && !normals)) {
		free(screening);
		free(normals);
		return false;
	}
	double *depths = screening + n + 1;
	lvp__weights_context heat = *ctx;
	if (normals) {
		lvp__heat_normals(normals, ctx->normals, ctx->positions, vertex_count, triangles, triangle_count);
		heat.normals = normals;
	}
	int32_t stride = rows->stride, workers = thread_count < 1 ? 1 : thread_count;
	lvp__pool *pool = NULL;
	lvp__sources_work work = {.ctx = &heat, .rows = rows, .screening = screening, .depths = depths,
	                          .vertex_count = vertex_count};
	atomic_init(&work.next_block, 0);
	atomic_init(&work.failed, false);
	bool ok = lvp__pool_create(&pool, workers) == lvp_success;
	if (ok) {
		lvp__parallel_for(pool, lvp__sources_task, &work, workers, 1);
		lvp__pool_destroy(pool);
		ok = !atomic_load(&work.failed);
	}
	ok = ok && lvp__diffusion_screened(rows, ctx->positions, triangles, vertex_count, triangle_count, screening,
	                                  depths, thread_count);
	free(screening);
	free(normals);
	lvp__weights_context raw = *ctx;
	raw.max_influences = stride;
	for (int32_t k = 0; ok && k < vertex_count; ++k) {
		int32_t *bones = rows->bones + (int64_t)k * stride;
		float *values = rows->values + (int64_t)k * stride;
		int32_t kept = 0;
		double sum = 0.0;
		for (int32_t j = 0; j < rows->counts[k]; ++j) {
			float cut = lvp__heat_cut(values[j]);
			if (cut > 0.0f) {
				bones[kept] = bones[j];
				values[kept++] = cut;
				sum += cut;
			}
		}
		for (int32_t j = 0; j < kept; ++j)
			values[j] = (float)(values[j] / sum);
		rows->counts[k] = kept > 0 ? kept : lvp__vertex_weights(bones, values, &raw, k);
	}
	return ok;
}

/* Blends the rows by the flesh's thickness (SMOOTHING BY THICKNESS in lvp.h): each vertex's distance from
 * its strongest bone (as options.facing measures it) and its depth under the skin, then
 * diffusion_thickness.c. */
static bool lvp__blend_by_thickness(lvp__diffusion *smooth, const lvp__weights_context *ctx, int32_t vertex_count,
                                    double share)
{
	double *distances = malloc(sizeof(double) * 2 * ((size_t)vertex_count + 1));
	if (!distances)
		return false;
	double *depths = distances + vertex_count + 1;
	double longest2 = 0.0;
	for (int32_t i = 0; i < ctx->bone_count; ++i)
		longest2 = ctx->bones[i].length2 > longest2 ? ctx->bones[i].length2 : longest2;
	for (int32_t k = 0; k < vertex_count; ++k) {
		double straight;
		distances[k] = lvp__distance_to_bone(&straight, ctx, k, smooth->bones[(int64_t)k * smooth->stride]);
		/* A bone seen from the skin counts at most twice its distance; one the rigid fallback took from
		 * behind the skin, far more. Skin deeper than the longest bone is long is no limb's flesh (a
		 * piece away from the skeleton): it would only widen the ladder of blends for everyone. */
		depths[k] = fmin(fmin(distances[k], 2.0 * straight), sqrt(longest2));
	}
	bool ok = lvp__diffusion_blend_by_thickness(smooth, ctx->positions, vertex_count, distances, depths, share);
	free(distances);
	return ok;
}

/* Fills the smoothing's rows with the 5.1 weights of ctx (kept to stride bones) and diffuses them as the
 * options say. Returns false when memory runs out. */
static bool lvp__smooth_weights(lvp__diffusion *smooth, lvp__weights_context *ctx, const int32_t *triangles,
                                int32_t vertex_count, int32_t triangle_count,
                                const lvp_auto_weights_options *options)
{
	int32_t stride = ctx->bone_count < LVP__DIFFUSION_ROW ? ctx->bone_count : LVP__DIFFUSION_ROW;
	if (!lvp__diffusion_init(smooth, triangles, vertex_count, triangle_count, ctx->bone_count, stride))
		return false;
	if (options->heat)
		return lvp__heat_weights(smooth, ctx, triangles, vertex_count, triangle_count, options->thread_count);
	/* The raw rows keep more bones than the output, so that the blend of a joint survives the diffusion. */
	lvp__weights_context raw = *ctx;
	raw.max_influences = stride;
	for (int32_t k = 0; k < vertex_count; ++k)
		smooth->counts[k] = lvp__vertex_weights(smooth->bones + (int64_t)k * stride,
		                                        smooth->values + (int64_t)k * stride, &raw, k);
	bool blended;
	if (options->smoothing_thickness > 0.0f) {
		blended = lvp__blend_by_thickness(smooth, ctx, vertex_count, (double)options->smoothing_thickness);
	} else {
		/* A length asks for as many steps as blend over it, however many: from a few dozen on they cost what
		 * a few do (lvp__diffusion_blend). */
		double length = (double)options->smoothing_length;
		int64_t steps = length > 0.0 ? lvp__diffusion_steps(length, lvp__mean_edge_length(smooth, ctx->positions,
		                                                                                      vertex_count),
		                                                    INT32_MAX)
		                             : options->smoothing_iterations;
		blended = lvp__diffusion_blend(smooth, ctx->positions, vertex_count, steps, NULL, NULL);
	}
	return blended && lvp__diffusion_share_slivers(smooth, ctx->positions, vertex_count);
}

lvp_result lvp_auto_weights(int32_t *r_offsets, int32_t *r_bones, float *r_values, int64_t capacity,
                            const float *positions, int32_t vertex_count, const int32_t *triangles,
                            int32_t triangle_count, const lvp_skeleton *skeleton,
                            const lvp_auto_weights_options *options, lvp_diagnostic *r_diag)
{
	if (!r_offsets || !r_bones || !r_values) {
		const char *name = !r_offsets ? "r_offsets" : (!r_bones ? "r_bones" : "r_values");
		return lvp__fail(r_diag, lvp_error_null_argument, name, -1,
		                 "%s is NULL; pass vertex_count+1 offsets and capacity bones and values.", name);
	}
	if (capacity < 0)
		return lvp__fail(r_diag, lvp_error_invalid_size, "capacity", -1,
		                 "capacity is %lld; it is the number of entries of r_bones and r_values (see "
		                 "lvp_auto_weights_bound()).",
		                 (long long)capacity);
	lvp_result result = lvp__check_mesh(positions, vertex_count, triangles, triangle_count, "positions", r_diag);
	if (result == lvp_success)
		result = lvp__check_skeleton(skeleton, r_diag);
	lvp_auto_weights_options defaults = lvp_auto_weights_default_options();
	if (!options)
		options = &defaults; /* NULL means the defaults */
	if (result == lvp_success)
		result = lvp__check_options(options, r_diag);
	if (result != lvp_success)
		return result;

	int32_t bone_count = skeleton->bone_count;
	int64_t row_bound = lvp__row_bound(bone_count, options);
	int64_t bound = (int64_t)vertex_count * row_bound;
	/* With room for the worst case the rows go straight to the caller's buffers: nothing can fail once
	 * they are written (short of more than INT32_MAX influences in all, which int32 offsets cannot
	 * address: that error leaves the outputs partly written). Otherwise the rows are staged, at most
	 * `capacity` of them, so that a call that runs out of room leaves the outputs untouched. */
	bool direct = capacity >= bound;
	int64_t limit = capacity < INT32_MAX ? capacity : INT32_MAX;
	size_t staged = direct ? 0 : (size_t)limit;
	bool normal_test = options->visibility == LVP_VISIBILITY_NORMAL;
	size_t n = (size_t)vertex_count, b = (size_t)bone_count, row = (size_t)row_bound;
	bool with_normals = normal_test || options->facing;
	size_t normal_bytes = with_normals ? sizeof(float) * 3 * n : 0;
	size_t trust_bytes = options->facing ? sizeof(float) * n : 0;
	size_t offset_bytes = direct ? 0 : sizeof(int32_t) * (n + 1);
	size_t bytes = (sizeof(lvp__bone_segment) + 2 * sizeof(lvp__candidate) + sizeof(int32_t)) * b + normal_bytes +
	               trust_bytes + offset_bytes + (sizeof(int32_t) + sizeof(float)) * (staged + row);
	unsigned char *memory = malloc(bytes);
	if (!memory)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "positions", -1,
		                 "could not allocate %zu bytes of work memory for the automatic weights.", bytes);
	/* Carve the block, 8-byte types first. */
	lvp__bone_segment *bones = (lvp__bone_segment *)memory;
	lvp__candidate *heap = (lvp__candidate *)(bones + b);
	lvp__candidate *visible = heap + b;
	int32_t *blockers = (int32_t *)(visible + b);
	unsigned char *cursor = (unsigned char *)(blockers + b);
	for (size_t i = 0; i < b; ++i)
		blockers[i] = -1;
	float *normals = with_normals ? (float *)cursor : NULL;
	cursor += normal_bytes;
	float *facing_trust = options->facing ? (float *)cursor : NULL;
	cursor += trust_bytes;
	int32_t *offsets = direct ? r_offsets : (int32_t *)cursor;
	cursor += offset_bytes;
	int32_t *out_bones = direct ? r_bones : (int32_t *)cursor;
	cursor += sizeof(int32_t) * staged;
	float *out_values = direct ? r_values : (float *)cursor;
	cursor += sizeof(float) * staged;
	int32_t *row_bones = (int32_t *)cursor; /* one row, for the rows that may not fit */
	float *row_values = (float *)(row_bones + row);

	for (int32_t i = 0; i < bone_count; ++i) {
		lvp__bone_segment *bone = &bones[i];
		bone->head = lvp__load(skeleton->heads + 3 * (int64_t)i);
		bone->axis = lvp__sub(lvp__load(skeleton->tails + 3 * (int64_t)i), bone->head);
		bone->length2 = lvp__dot(bone->axis, bone->axis);
		bone->inverse_length2 = bone->length2 > 0.0 ? 1.0 / bone->length2 : 0.0;
		bone->floor2 = LVP__DISTANCE_FLOOR * LVP__DISTANCE_FLOOR * bone->length2;
		bone->middle = lvp__add(bone->head, lvp__scale(bone->axis, 0.5));
		bone->half_length = 0.5 * sqrt(bone->length2);
	}

	lvp__bvh bvh = {0};
	if (with_normals) {
		double volume = 0.0;
		lvp_vertex_normals(normals, positions, vertex_count, triangles, triangle_count, NULL);
		lvp_mesh_volume(&volume, positions, vertex_count, triangles, triangle_count, NULL);
		/* Judged while the vertex normals are wound as the triangles' are. The exact test sees what the trust
		 * stands in for (the paths from a fin or a rim to the bone it does not cover leave the body): with it
		 * the normal counts wholly, as heat weights count it. */
		if (facing_trust && options->visibility == LVP_VISIBILITY_EXACT) {
			for (size_t k = 0; k < n; ++k)
				facing_trust[k] = 1.0f;
		} else if (facing_trust &&
		           !lvp__facing_trust(facing_trust, positions, normals, vertex_count, triangles, triangle_count)) {
			free(memory);
			return lvp__fail(r_diag, lvp_error_out_of_memory, "positions", -1,
			                 "could not allocate the edges of %d triangles to judge which way the skin faces; "
			                 "set options.facing to 0 to do without.",
			                 (int)triangle_count);
		}
		/* The test and the facing need outward normals: a mesh wound inward has a negative volume. */
		if (volume < 0.0)
			for (size_t i = 0; i < 3 * n; ++i)
				normals[i] = -normals[i];
	}
	if (options->visibility == LVP_VISIBILITY_EXACT) {
		result = lvp__bvh_build(&bvh, positions, triangles, triangle_count, r_diag);
		if (result != lvp_success) {
			free(memory);
			return result;
		}
	}

	lvp__weights_context ctx = {
	    .positions = positions,
	    .normals = normals,
	    .bones = bones,
	    .bone_count = bone_count,
	    .bvh = &bvh,
	    .visibility = options->visibility,
	    .alpha = options->alpha,
	    .by_length = options->by_length != 0,
	    .facing_trust = facing_trust,
	    .normal_cos_max = options->normal_cos_max,
	    .min_weight = options->min_weight,
	    .max_influences = options->max_influences,
	    .heap = heap,
	    .visible = visible,
	    .blockers = blockers,
	};
	lvp__diffusion smooth = {0};
	bool smoothed = options->heat || options->smoothing_iterations > 0 || options->smoothing_length > 0.0f ||
	                options->smoothing_thickness > 0.0f;
	if (smoothed && !lvp__smooth_weights(&smooth, &ctx, triangles, vertex_count, triangle_count, options)) {
		lvp__diffusion_free(&smooth);
		lvp__bvh_free(&bvh);
		free(memory);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "positions", -1,
		                 "could not allocate the work memory to smooth the automatic weights of %d vertices; "
		                 "set options.smoothing_iterations, smoothing_length and smoothing_thickness to 0 to do "
		                 "without.",
		                 (int)vertex_count);
	}
	int64_t total = 0;
	for (int32_t k = 0; k < vertex_count; ++k) {
		offsets[k] = (int32_t)(total <= limit ? total : limit);
		if (total + row_bound <= limit) {
			total += smoothed ? lvp__smoothed_row(out_bones + total, out_values + total, &smooth, &ctx, k)
			                  : lvp__vertex_weights(out_bones + total, out_values + total, &ctx, k);
			continue;
		}
		int32_t length = smoothed ? lvp__smoothed_row(row_bones, row_values, &smooth, &ctx, k)
		                          : lvp__vertex_weights(row_bones, row_values, &ctx, k);
		if (total + length <= limit) {
			memcpy(out_bones + total, row_bones, sizeof(int32_t) * (size_t)length);
			memcpy(out_values + total, row_values, sizeof(float) * (size_t)length);
		}
		total += length; /* past the limit, rows are still counted, to report the capacity needed */
	}
	lvp__diffusion_free(&smooth);
	lvp__bvh_free(&bvh);
	if (total > limit) {
		free(memory);
		if (total > INT32_MAX)
			return lvp__fail(r_diag, lvp_error_invalid_size, "capacity", -1,
			                 "the weights need %lld entries, more than int32 offsets can address; lower "
			                 "options.max_influences or raise options.min_weight.",
			                 (long long)total);
		return lvp__fail(r_diag, lvp_error_invalid_size, "capacity", -1,
		                 "capacity is %lld but these weights need %lld entries; size r_bones and r_values with "
		                 "at least %lld (lvp_auto_weights_bound() gives %lld, always enough).",
		                 (long long)capacity, (long long)total, (long long)total, (long long)bound);
	}
	offsets[vertex_count] = (int32_t)total;
	if (!direct) {
		memcpy(r_offsets, offsets, sizeof(int32_t) * (n + 1));
		memcpy(r_bones, out_bones, sizeof(int32_t) * (size_t)total);
		memcpy(r_values, out_values, sizeof(float) * (size_t)total);
	}
	free(memory);
	return lvp_success;
}
