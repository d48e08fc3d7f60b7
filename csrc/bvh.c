/*
 * bvh.c - binned-SAH bounding volume hierarchy over mesh triangles, and the queries against it: segments,
 * for the exact visibility test of automatic weights (Rohmer, Hahmann, Cani 2008, section 5.1: "ray
 * tracing against the mesh is the exact alternative"); boxes and the tree against itself, refitted to a
 * pose, for keeping skin apart (contact.c). See bvh.h for the algorithm, memory and performance.
 */
#include "bvh.h"

#include <float.h>
#include <stdlib.h>

#define LVP__BVH_BINS 16
#define LVP__BVH_MAX_LEAF 8
#define LVP__BVH_SMALL_LEAF 4     /* this many triangles or fewer: always a leaf */
#define LVP__BVH_SAH_DEPTH 40     /* deeper nodes split at the median: depth <= 40 + log2(F) < 72 */
#define LVP__BVH_STACK 96
#define LVP__BVH_TRAVERSAL_COST 1.0f
#define LVP__BVH_HINT_LEVELS 3 /* a query's hint is the blocking leaf's ancestor this many levels up */

typedef struct lvp__box {
	float lo[3], hi[3];
} lvp__box;

static void lvp__box_empty(lvp__box *box)
{
	for (int a = 0; a < 3; ++a)
		box->lo[a] = FLT_MAX, box->hi[a] = -FLT_MAX;
}

static void lvp__box_grow(lvp__box *box, const lvp__box *other)
{
	for (int a = 0; a < 3; ++a) {
		box->lo[a] = lvp__minf(box->lo[a], other->lo[a]);
		box->hi[a] = lvp__maxf(box->hi[a], other->hi[a]);
	}
}

static float lvp__box_half_area(const lvp__box *box)
{
	float dx = box->hi[0] - box->lo[0], dy = box->hi[1] - box->lo[1], dz = box->hi[2] - box->lo[2];
	if (dx < 0.0f)
		return 0.0f; /* empty */
	return dx * dy + dy * dz + dz * dx;
}

/* Stores a node's box padded by a millionth of its size and of its distance to the origin: the
 * triangle test accepts points a hair outside a triangle (its edge epsilon, and rounding), and the box
 * test runs in float; a box must never be tighter than what the test can hit. */
static void lvp__store_box(lvp__bvh_node *node, const lvp__box *box)
{
	for (int axis = 0; axis < 3; ++axis) {
		float far = lvp__maxf(fabsf(box->lo[axis]), fabsf(box->hi[axis]));
		float pad = (box->hi[axis] - box->lo[axis]) * 1e-6f + far * 1e-6f + 1e-30f;
		node->lo[axis] = box->lo[axis] - pad;
		node->hi[axis] = box->hi[axis] + pad;
	}
}

/* Scratch of the build: per triangle of the order, its box and its centroid. */
typedef struct lvp__build {
	lvp__box *boxes;  /* indexed by triangle slot */
	float *centroids; /* 3 per triangle slot */
	int32_t *order;   /* triangle slots, partitioned in place */
} lvp__build;

static float lvp__centroid(const lvp__build *build, int32_t slot, int axis)
{
	return build->centroids[3 * (int64_t)slot + axis];
}

static void lvp__swap_slots(int32_t *order, int32_t i, int32_t j)
{
	int32_t swap = order[i];
	order[i] = order[j];
	order[j] = swap;
}

/* Reorders order[begin, end) so that order[mid] has the median centroid along axis and everything before
 * it is not greater (Hoare quickselect; equal keys split evenly, so coincident centroids still halve). */
static void lvp__select_median(const lvp__build *build, int32_t begin, int32_t end, int32_t mid, int axis)
{
	int32_t *order = build->order;
	while (end - begin > 1) {
		/* Median of three moved to the middle slot; Hoare's scheme with the pivot taken from the lower
		 * middle of [begin, end) always leaves both parts non-empty. */
		int32_t a = begin, b = begin + (end - 1 - begin) / 2, c = end - 1;
		if (lvp__centroid(build, order[b], axis) < lvp__centroid(build, order[a], axis))
			lvp__swap_slots(order, a, b);
		if (lvp__centroid(build, order[c], axis) < lvp__centroid(build, order[b], axis)) {
			lvp__swap_slots(order, b, c);
			if (lvp__centroid(build, order[b], axis) < lvp__centroid(build, order[a], axis))
				lvp__swap_slots(order, a, b);
		}
		float pivot = lvp__centroid(build, order[b], axis);
		int32_t i = begin - 1, j = end;
		for (;;) {
			do
				++i;
			while (lvp__centroid(build, order[i], axis) < pivot);
			do
				--j;
			while (lvp__centroid(build, order[j], axis) > pivot);
			if (i >= j)
				break;
			lvp__swap_slots(order, i, j);
		}
		/* [begin, j] <= pivot <= [j + 1, end) */
		if (mid <= j)
			end = j + 1;
		else
			begin = j + 1;
	}
}

/* The bin of a centroid, in double so that no float overflow can reach the integer conversion. */
static inline int lvp__bin(float centroid, float lo, double scale)
{
	double x = ((double)centroid - lo) * scale;
	return x > 0.0 ? (x < LVP__BVH_BINS ? (int)x : LVP__BVH_BINS - 1) : 0;
}

/* Chooses where to split order[begin, end) by the binned surface area heuristic. Returns false when a
 * leaf is cheaper (or the centroids coincide); otherwise partitions and sets *r_mid. */
static bool lvp__split_sah(int32_t *r_mid, const lvp__build *build, int32_t begin, int32_t end,
                           const lvp__box *centroid_box, float node_half_area)
{
	int32_t count = end - begin;
	float best_cost = FLT_MAX;
	int best_axis = -1, best_bin = 0;
	for (int axis = 0; axis < 3; ++axis) {
		float lo = centroid_box->lo[axis], extent = centroid_box->hi[axis] - lo;
		if (!(extent > 0.0f))
			continue;
		double bin_scale = LVP__BVH_BINS / ((double)centroid_box->hi[axis] - lo);
		lvp__box bins[LVP__BVH_BINS];
		int32_t counts[LVP__BVH_BINS] = {0};
		for (int b = 0; b < LVP__BVH_BINS; ++b)
			lvp__box_empty(&bins[b]);
		for (int32_t i = begin; i < end; ++i) {
			int32_t slot = build->order[i];
			int b = lvp__bin(lvp__centroid(build, slot, axis), lo, bin_scale);
			++counts[b];
			lvp__box_grow(&bins[b], &build->boxes[slot]);
		}
		/* Sweep from the right, then from the left, evaluating the cost of each bin boundary. */
		float right_area[LVP__BVH_BINS];
		int32_t right_count[LVP__BVH_BINS];
		lvp__box box;
		lvp__box_empty(&box);
		int32_t n = 0;
		for (int b = LVP__BVH_BINS - 1; b > 0; --b) {
			lvp__box_grow(&box, &bins[b]);
			n += counts[b];
			right_area[b] = lvp__box_half_area(&box);
			right_count[b] = n;
		}
		lvp__box_empty(&box);
		n = 0;
		for (int b = 0; b < LVP__BVH_BINS - 1; ++b) {
			lvp__box_grow(&box, &bins[b]);
			n += counts[b];
			if (n == 0 || right_count[b + 1] == 0)
				continue;
			float cost = lvp__box_half_area(&box) * (float)n + right_area[b + 1] * (float)right_count[b + 1];
			if (cost < best_cost)
				best_cost = cost, best_axis = axis, best_bin = b;
		}
	}
	if (best_axis < 0)
		return false;
	float split_cost = LVP__BVH_TRAVERSAL_COST + best_cost / fmaxf(node_half_area, FLT_MIN);
	if (split_cost >= (float)count && count <= LVP__BVH_MAX_LEAF)
		return false;
	float lo = centroid_box->lo[best_axis];
	double bin_scale = LVP__BVH_BINS / ((double)centroid_box->hi[best_axis] - lo);
	int32_t i = begin, j = end - 1;
	while (i <= j) {
		int b = lvp__bin(lvp__centroid(build, build->order[i], best_axis), lo, bin_scale);
		if (b <= best_bin) {
			++i;
		} else {
			lvp__swap_slots(build->order, i, j);
			--j;
		}
	}
	*r_mid = i;
	return i > begin && i < end;
}

lvp_result lvp__bvh_build(lvp__bvh *r_bvh, const float *positions, const int32_t *triangles, int32_t triangle_count,
                          lvp_diagnostic *r_diag)
{
	memset(r_bvh, 0, sizeof(*r_bvh));
	size_t f = (size_t)triangle_count;
	size_t node_capacity = 2 * f + 1;
	lvp__bvh bvh = {0};
	lvp__build build = {0};
	bvh.nodes = malloc(sizeof(lvp__bvh_node) * node_capacity);
	bvh.parents = malloc(sizeof(int32_t) * node_capacity);
	bvh.triangles = malloc(sizeof(lvp__bvh_triangle) * (f ? f : 1));
	void *scratch = malloc((sizeof(lvp__box) + 3 * sizeof(float) + sizeof(int32_t)) * (f ? f : 1));
	if (!bvh.nodes || !bvh.parents || !bvh.triangles || !scratch) {
		free(bvh.nodes);
		free(bvh.parents);
		free(bvh.triangles);
		free(scratch);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "triangles", -1,
		                 "could not allocate the bounding volume hierarchy of %d triangles.", (int)triangle_count);
	}
	build.boxes = scratch;
	build.centroids = (float *)(build.boxes + f);
	build.order = (int32_t *)(build.centroids + 3 * f);

	/* Slots are the triangles with an area: a zero-area triangle cannot stop a path. */
	int32_t slots = 0;
	for (int32_t t = 0; t < triangle_count; ++t) {
		const int32_t *tri = triangles + 3 * (int64_t)t;
		lvp__vec3 a = lvp__load(positions + 3 * (int64_t)tri[0]);
		lvp__vec3 n = lvp__cross(lvp__sub(lvp__load(positions + 3 * (int64_t)tri[1]), a),
		                         lvp__sub(lvp__load(positions + 3 * (int64_t)tri[2]), a));
		if (n.x == 0.0 && n.y == 0.0 && n.z == 0.0)
			continue;
		lvp__bvh_triangle *out = &bvh.triangles[slots];
		lvp__box *box = &build.boxes[slots];
		lvp__box_empty(box);
		for (int c = 0; c < 3; ++c) {
			const float *p = positions + 3 * (int64_t)tri[c];
			out->vertices[c] = tri[c];
			for (int axis = 0; axis < 3; ++axis) {
				out->corners[c][axis] = p[axis];
				box->lo[axis] = lvp__minf(box->lo[axis], p[axis]);
				box->hi[axis] = lvp__maxf(box->hi[axis], p[axis]);
			}
		}
		out->source = t;
		memcpy(out->lo, box->lo, sizeof(out->lo));
		memcpy(out->hi, box->hi, sizeof(out->hi));
		for (int axis = 0; axis < 3; ++axis)
			build.centroids[3 * (int64_t)slots + axis] = 0.5f * box->lo[axis] + 0.5f * box->hi[axis];
		build.order[slots] = slots;
		++slots;
	}

	struct {
		int32_t node, begin, end, depth;
	} stack[LVP__BVH_STACK];
	int top = 0;
	bvh.node_count = 1;
	bvh.parents[0] = -1;
	if (slots > 0)
		stack[top++].node = 0, stack[0].begin = 0, stack[0].end = slots, stack[0].depth = 0;
	else
		memset(&bvh.nodes[0], 0, sizeof(bvh.nodes[0])); /* an empty leaf; queries check the count */
	while (top > 0) {
		--top;
		int32_t node = stack[top].node, begin = stack[top].begin, end = stack[top].end, depth = stack[top].depth;
		lvp__box box, centroid_box;
		lvp__box_empty(&box);
		lvp__box_empty(&centroid_box);
		for (int32_t i = begin; i < end; ++i) {
			int32_t slot = build.order[i];
			lvp__box_grow(&box, &build.boxes[slot]);
			for (int axis = 0; axis < 3; ++axis) {
				float c = lvp__centroid(&build, slot, axis);
				centroid_box.lo[axis] = lvp__minf(centroid_box.lo[axis], c);
				centroid_box.hi[axis] = lvp__maxf(centroid_box.hi[axis], c);
			}
		}
		lvp__bvh_node *out = &bvh.nodes[node];
		lvp__store_box(out, &box);
		int32_t count = end - begin, mid = -1;
		if (count > LVP__BVH_SMALL_LEAF) {
			bool split = false;
			if (depth < LVP__BVH_SAH_DEPTH)
				split = lvp__split_sah(&mid, &build, begin, end, &centroid_box, lvp__box_half_area(&box));
			if (!split && count > LVP__BVH_MAX_LEAF) {
				int axis = 0;
				for (int a = 1; a < 3; ++a)
					if (centroid_box.hi[a] - centroid_box.lo[a] > centroid_box.hi[axis] - centroid_box.lo[axis])
						axis = a;
				mid = begin + count / 2;
				lvp__select_median(&build, begin, end, mid, axis);
				split = true;
			}
			if (!split)
				mid = -1;
		}
		if (mid < 0) {
			out->index = begin;
			out->count = count;
			continue;
		}
		int32_t left = bvh.node_count;
		bvh.node_count += 2;
		bvh.parents[left] = bvh.parents[left + 1] = node;
		out->index = left;
		out->count = 0;
		stack[top].node = left + 1, stack[top].begin = mid, stack[top].end = end, stack[top].depth = depth + 1;
		++top;
		stack[top].node = left, stack[top].begin = begin, stack[top].end = mid, stack[top].depth = depth + 1;
		++top;
	}

	/* Put the triangles in leaf order, so a leaf reads one contiguous block. */
	lvp__bvh_triangle *sorted = malloc(sizeof(lvp__bvh_triangle) * (f ? f : 1));
	if (!sorted) {
		free(bvh.nodes);
		free(bvh.parents);
		free(bvh.triangles);
		free(scratch);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "triangles", -1,
		                 "could not allocate the bounding volume hierarchy of %d triangles.", (int)triangle_count);
	}
	for (int32_t i = 0; i < slots; ++i)
		sorted[i] = bvh.triangles[build.order[i]];
	free(bvh.triangles);
	free(scratch);
	bvh.triangles = sorted;
	bvh.triangle_count = slots;
	*r_bvh = bvh;
	return lvp_success;
}

/* A triangle's corners and box moved to `positions`. */
static void lvp__refit_triangle(lvp__bvh_triangle *tri, const float *positions)
{
	for (int c = 0; c < 3; ++c)
		memcpy(tri->corners[c], positions + 3 * (int64_t)tri->vertices[c], sizeof(float) * 3);
	for (int axis = 0; axis < 3; ++axis) {
		tri->lo[axis] = lvp__minf(lvp__minf(tri->corners[0][axis], tri->corners[1][axis]), tri->corners[2][axis]);
		tri->hi[axis] = lvp__maxf(lvp__maxf(tri->corners[0][axis], tri->corners[1][axis]), tri->corners[2][axis]);
	}
}

/* A node's box from what is below it: a leaf's from its triangles' boxes, padded (the padding is
 * recomputed from the unpadded boxes of the triangles only at the leaves); an inner node's, the
 * merge of its children's padded boxes, which stays at least as wide as a box must be. Children
 * come after their parent (lvp__bvh_build appends them), so visiting nodes from the last to the
 * first sees both children of a node before the node. */
static void lvp__refit_node(lvp__bvh *bvh, int32_t index)
{
	lvp__bvh_node *node = &bvh->nodes[index];
	lvp__box box;
	lvp__box_empty(&box);
	if (node->count > 0) {
		for (int32_t i = node->index; i < node->index + node->count; ++i)
			for (int axis = 0; axis < 3; ++axis) {
				box.lo[axis] = lvp__minf(box.lo[axis], bvh->triangles[i].lo[axis]);
				box.hi[axis] = lvp__maxf(box.hi[axis], bvh->triangles[i].hi[axis]);
			}
		lvp__store_box(node, &box);
		return;
	}
	for (int child = 0; child < 2; ++child) {
		const lvp__bvh_node *c = &bvh->nodes[node->index + child];
		for (int axis = 0; axis < 3; ++axis) {
			box.lo[axis] = lvp__minf(box.lo[axis], c->lo[axis]);
			box.hi[axis] = lvp__maxf(box.hi[axis], c->hi[axis]);
		}
	}
	memcpy(node->lo, box.lo, sizeof(box.lo));
	memcpy(node->hi, box.hi, sizeof(box.hi));
}

/* The nodes of a refit: `nodes` listed from the last to the first (lvp__bvh_refit_nodes), or, NULL, every node of
 * the hierarchy in that order. */
typedef struct lvp__refit_pass {
	lvp__bvh *bvh;
	const float *positions;
	const int32_t *nodes;
	int32_t count;
} lvp__refit_pass;

static inline int32_t lvp__refit_node_at(const lvp__refit_pass *pass, int32_t i)
{
	return pass->nodes ? pass->nodes[i] : pass->count - 1 - i;
}

/* The listed leaves in [begin, end): their triangles and boxes (each writes only its own). */
static void lvp__refit_leaves(void *context, int32_t begin, int32_t end)
{
	const lvp__refit_pass *pass = context;
	lvp__bvh *bvh = pass->bvh;
	for (int32_t i = begin; i < end; ++i) {
		int32_t index = lvp__refit_node_at(pass, i);
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count == 0)
			continue;
		for (int32_t t = node->index; t < node->index + node->count; ++t)
			lvp__refit_triangle(&bvh->triangles[t], pass->positions);
		lvp__refit_node(bvh, index);
	}
}

/* Listed nodes a task of the leaves' refit takes at a time. */
#define LVP__BVH_REFIT_GRAIN 512

/* The leaves on the pool's threads, then the inner nodes, each after its children (listed before it). */
static void lvp__refit(lvp__refit_pass *pass, lvp__pool *pool)
{
	lvp__parallel_for(pool, lvp__refit_leaves, pass, pass->count, LVP__BVH_REFIT_GRAIN);
	for (int32_t i = 0; i < pass->count; ++i) {
		int32_t index = lvp__refit_node_at(pass, i);
		if (pass->bvh->nodes[index].count == 0)
			lvp__refit_node(pass->bvh, index);
	}
}

void lvp__bvh_refit_nodes(lvp__bvh *bvh, const float *positions, const int32_t *nodes, int32_t count, lvp__pool *pool)
{
	lvp__refit_pass pass = {bvh, positions, nodes, count};
	lvp__refit(&pass, pool);
}

void lvp__bvh_refit(lvp__bvh *bvh, const float *positions, lvp__pool *pool)
{
	if (bvh->triangle_count == 0)
		return;
	lvp__refit_pass pass = {bvh, positions, NULL, bvh->node_count};
	lvp__refit(&pass, pool);
}

void lvp__bvh_free(lvp__bvh *bvh)
{
	if (!bvh)
		return;
	free(bvh->nodes);
	free(bvh->parents);
	free(bvh->triangles);
	memset(bvh, 0, sizeof(*bvh));
}

/* The segment, prepared once per query: in float for the box tests, the parametric range in double for
 * the triangle tests. */
typedef struct lvp__segment {
	/* The box's low and high planes are measured from origin_lo and origin_hi: both the origin, except
	 * along an axis the segment does not move along (inverse 1e30: no NaN), where they straddle it so
	 * that a segment lying in a box's face plane is inside, not on an empty slab. */
	float origin_lo[3], origin_hi[3], inverse[3];
	float near, far;             /* the range, widened a little */
	float slack;                 /* what rounding the origin to float can move a slab by, in t */
	double t_min, t_max;
} lvp__segment;

/* Whether the segment meets a node's box; *r_near receives where it enters. Branch-free slabs in float:
 * the entry and exit are each off by a few float roundings, so the test is widened by 1e-6 of their size
 * and never culls a box the segment touches (culling too little only costs a triangle test, which is
 * exact). */
static inline bool lvp__segment_box(float *r_near, const lvp__bvh_node *node, const lvp__segment *s)
{
	float x0 = (node->lo[0] - s->origin_lo[0]) * s->inverse[0], x1 = (node->hi[0] - s->origin_hi[0]) * s->inverse[0];
	float y0 = (node->lo[1] - s->origin_lo[1]) * s->inverse[1], y1 = (node->hi[1] - s->origin_hi[1]) * s->inverse[1];
	float z0 = (node->lo[2] - s->origin_lo[2]) * s->inverse[2], z1 = (node->hi[2] - s->origin_hi[2]) * s->inverse[2];
	float near = lvp__maxf(lvp__maxf(lvp__minf(x0, x1), lvp__minf(y0, y1)), lvp__maxf(lvp__minf(z0, z1), s->near));
	float far = lvp__minf(lvp__minf(lvp__maxf(x0, x1), lvp__maxf(y0, y1)), lvp__minf(lvp__maxf(z0, z1), s->far));
	*r_near = near;
	return near <= far + 1e-6f * (fabsf(near) + fabsf(far)) + s->slack;
}

static inline bool lvp__hits_triangle(const lvp__bvh_triangle *tri, lvp__vec3 from, lvp__vec3 direction,
                                      const lvp__segment *s, int32_t skip_vertex)
{
	if (tri->vertices[0] == skip_vertex || tri->vertices[1] == skip_vertex || tri->vertices[2] == skip_vertex)
		return false;
	double t;
	return lvp__segment_triangle(&t, from, direction, tri->corners, s->t_min, s->t_max);
}

/* Depth-first search of the subtree at start, nearer child first, skipping the subtree at skip. Returns
 * the leaf that holds a crossed triangle, or -1. */
static int32_t lvp__traverse(const lvp__bvh *bvh, int32_t start, int32_t skip, lvp__vec3 from, lvp__vec3 direction,
                             const lvp__segment *s, int32_t skip_vertex)
{
	float near;
	if (!lvp__segment_box(&near, &bvh->nodes[start], s))
		return -1;
	int32_t stack[LVP__BVH_STACK];
	int top = 0;
	stack[top++] = start;
	while (top > 0) {
		int32_t index = stack[--top];
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count > 0) {
			for (int32_t i = node->index; i < node->index + node->count; ++i)
				if (lvp__hits_triangle(&bvh->triangles[i], from, direction, s, skip_vertex))
					return index;
			continue;
		}
		/* Both children tested here, the nearer one visited first: the first wall the path meets ends the
		 * query, and it is usually near the start. */
		int32_t left = node->index, right = left + 1;
		float near_left, near_right;
		bool hit_left = left != skip && lvp__segment_box(&near_left, &bvh->nodes[left], s);
		bool hit_right = right != skip && lvp__segment_box(&near_right, &bvh->nodes[right], s);
		if (hit_left && hit_right) {
			bool left_first = near_left <= near_right;
			stack[top++] = left_first ? right : left;
			stack[top++] = left_first ? left : right;
		} else if (hit_left) {
			stack[top++] = left;
		} else if (hit_right) {
			stack[top++] = right;
		}
	}
	return -1;
}

/* The segment from + t (to - from), t in [t_min, t_max], prepared for the box and triangle tests. */
static lvp__segment lvp__prepare_segment(lvp__vec3 from, lvp__vec3 direction, double t_min, double t_max)
{
	double d[3] = {direction.x, direction.y, direction.z};
	double o[3] = {from.x, from.y, from.z};
	lvp__segment s = {{0}, {0}, {0}, (float)t_min, (float)t_max, 0.0f, t_min, t_max};
	s.near -= 1e-6f * (fabsf(s.near) + 1.0f);
	s.far += 1e-6f * (fabsf(s.far) + 1.0f);
	double slack = 0.0;
	for (int axis = 0; axis < 3; ++axis) {
		float origin = (float)o[axis];
		s.origin_lo[axis] = s.origin_hi[axis] = origin;
		if (fabs(d[axis]) > 1e-30) {
			double inverse = 1.0 / d[axis];
			s.inverse[axis] = (float)inverse;
			/* zero for the mesh's own vertices, which are floats already */
			slack = fmax(slack, fabs(o[axis] - (double)origin) * fabs(inverse));
		} else {
			/* a few ulps either side, and at least 1e-29 so that 1e30 times it is far outside [0, 1] */
			float straddle = fabsf(origin) * 0x1p-21f + 1e-29f;
			s.inverse[axis] = 1e30f;
			s.origin_lo[axis] = origin + straddle;
			s.origin_hi[axis] = origin - straddle;
		}
	}
	s.slack = (float)(2.0 * slack);
	return s;
}

bool lvp__bvh_segment_hits(const lvp__bvh *bvh, lvp__vec3 from, lvp__vec3 to, double t_min, double t_max,
                           int32_t skip_vertex, int32_t *io_hint)
{
	if (bvh->triangle_count == 0)
		return false;
	lvp__vec3 direction = lvp__sub(to, from);
	lvp__segment s = lvp__prepare_segment(from, direction, t_min, t_max);
	/* Neighbouring queries are usually blocked by the same patch of wall: search the subtree that held
	 * the last blocker first, then the rest of the tree. */
	int32_t hint = io_hint && *io_hint > 0 && *io_hint < bvh->node_count ? *io_hint : -1;
	int32_t leaf = hint >= 0 ? lvp__traverse(bvh, hint, -1, from, direction, &s, skip_vertex) : -1;
	if (leaf < 0)
		leaf = lvp__traverse(bvh, 0, hint, from, direction, &s, skip_vertex);
	if (leaf < 0)
		return false;
	if (io_hint) {
		for (int up = 0; up < LVP__BVH_HINT_LEVELS && bvh->parents[leaf] > 0; ++up)
			leaf = bvh->parents[leaf];
		*io_hint = leaf;
	}
	return true;
}

/* The walk both searches below take: down into the nodes whose boxes may_hold accepts (test_context),
 * visit(context, triangle) for the triangles of the leaves reached, until a visit returns true. Inlined
 * into each, where may_hold is known. */
static inline void lvp__descend(const lvp__bvh *bvh, lvp__bvh_box_test may_hold, void *test_context,
                                lvp__bvh_visit visit, void *context)
{
	if (bvh->triangle_count == 0)
		return;
	int32_t stack[LVP__BVH_STACK];
	int top = 0;
	stack[top++] = 0;
	while (top > 0) {
		const lvp__bvh_node *node = &bvh->nodes[stack[--top]];
		if (!may_hold(test_context, node->lo, node->hi))
			continue;
		if (node->count == 0) {
			stack[top++] = node->index + 1;
			stack[top++] = node->index;
			continue;
		}
		for (int32_t i = node->index; i < node->index + node->count; ++i)
			if (visit(context, &bvh->triangles[i]))
				return;
	}
}

/* The box of lvp__bvh_overlapping, read at every node (a visit may narrow it). */
typedef struct lvp__query_box {
	const float *lo, *hi;
} lvp__query_box;

static bool lvp__overlaps_query_box(void *context, const float lo[3], const float hi[3])
{
	const lvp__query_box *box = context;
	return !(lo[0] > box->hi[0] || hi[0] < box->lo[0] || lo[1] > box->hi[1] || hi[1] < box->lo[1] ||
	         lo[2] > box->hi[2] || hi[2] < box->lo[2]);
}

void lvp__bvh_overlapping(const lvp__bvh *bvh, const float lo[3], const float hi[3], lvp__bvh_visit visit,
                          void *context)
{
	lvp__query_box box = {lo, hi};
	lvp__descend(bvh, lvp__overlaps_query_box, &box, visit, context);
}

void lvp__bvh_search(const lvp__bvh *bvh, lvp__bvh_box_test may_hold, lvp__bvh_visit visit, void *context)
{
	lvp__descend(bvh, may_hold, context, visit, context);
}

static float lvp__node_half_area(const lvp__bvh_node *node)
{
	float dx = node->hi[0] - node->lo[0], dy = node->hi[1] - node->lo[1], dz = node->hi[2] - node->lo[2];
	return dx * dy + dy * dz + dz * dx;
}

static inline bool lvp__nodes_overlap(const lvp__bvh_node *a, const lvp__bvh_node *b)
{
	return !((a->lo[0] > b->hi[0]) | (a->hi[0] < b->lo[0]) | (a->lo[1] > b->hi[1]) | (a->hi[1] < b->lo[1]) |
	         (a->lo[2] > b->hi[2]) | (a->hi[2] < b->lo[2]));
}

static inline bool lvp__triangles_overlap(const lvp__bvh_triangle *a, const lvp__bvh_triangle *b)
{
	return !((a->lo[0] > b->hi[0]) | (a->hi[0] < b->lo[0]) | (a->lo[1] > b->hi[1]) | (a->hi[1] < b->lo[1]) |
	         (a->lo[2] > b->hi[2]) | (a->hi[2] < b->lo[2]));
}

/* visit(context, a, b) when the two triangles' boxes overlap: most pairs of two leaves' triangles do
 * not, and are passed over here rather than through a call. */
static inline void lvp__visit_if_overlapping(const lvp__bvh_triangle *a, const lvp__bvh_triangle *b,
                                             lvp__bvh_visit_pair visit, void *context)
{
	if (lvp__triangles_overlap(a, b))
		visit(context, a, b);
}

/* Pushes the pair of nodes (a, b) for lvp__overlaps_from when it may hold a pair to visit: one of them marked
 * (when `marked` is given), and for two different nodes, boxes that overlap. Tested here rather than when
 * the pair is taken, so that pairs that hold nothing are never pushed (most of a traversal's pairs). */
static inline void lvp__push_pair(int32_t *stack, int *top, const lvp__bvh *bvh, const uint8_t *marked, int32_t a,
                                  int32_t b)
{
	if (marked && !marked[a] && !marked[b])
		return;
	if (a != b && !lvp__nodes_overlap(&bvh->nodes[a], &bvh->nodes[b]))
		return;
	stack[(*top)++] = a;
	stack[(*top)++] = b;
}

/* The pairs of triangles under nodes a and b (under a alone when a == b) whose boxes overlap. */
static void lvp__overlaps_from(const lvp__bvh *bvh, const uint8_t *marked, const uint8_t *skipped, int32_t first_a,
                               int32_t first_b, lvp__bvh_visit_pair visit, void *context)
{
	/* Pairs of nodes to visit, (a, a) standing for the pairs within a, each pushed only when it may hold a
	 * pair to visit (lvp__push_pair). A pop pushes at most three pairs, each one level deeper on one side;
	 * a pair's two depths sum to less than 2 * 72. */
	int32_t stack[2 * 4 * 2 * LVP__BVH_STACK];
	int top = 0;
	lvp__push_pair(stack, &top, bvh, marked, first_a, first_b);
	while (top > 0) {
		int32_t b = stack[--top], a = stack[--top];
		const lvp__bvh_node *na = &bvh->nodes[a], *nb = &bvh->nodes[b];
		if (a == b) {
			if (skipped && skipped[a])
				continue;
			if (na->count > 0) {
				for (int32_t i = na->index; i < na->index + na->count; ++i)
					for (int32_t j = i + 1; j < na->index + na->count; ++j)
						lvp__visit_if_overlapping(&bvh->triangles[i], &bvh->triangles[j], visit, context);
				continue;
			}
			int32_t left = na->index, right = left + 1;
			lvp__push_pair(stack, &top, bvh, marked, left, left);
			lvp__push_pair(stack, &top, bvh, marked, right, right);
			lvp__push_pair(stack, &top, bvh, marked, left, right);
			continue;
		}
		if (na->count > 0 && nb->count > 0) {
			for (int32_t i = na->index; i < na->index + na->count; ++i)
				for (int32_t j = nb->index; j < nb->index + nb->count; ++j)
					lvp__visit_if_overlapping(&bvh->triangles[i], &bvh->triangles[j], visit, context);
			continue;
		}
		/* Split the inner node (the larger one when both are). */
		bool split_a = nb->count > 0 || (na->count == 0 && lvp__node_half_area(na) >= lvp__node_half_area(nb));
		const lvp__bvh_node *split = split_a ? na : nb;
		int32_t other = split_a ? b : a;
		lvp__push_pair(stack, &top, bvh, marked, split->index, other);
		lvp__push_pair(stack, &top, bvh, marked, split->index + 1, other);
	}
}

/* Levels of the tree above the subtrees searched each on its own: up to 64 tasks. */
#define LVP__BVH_TASK_DEPTH 6

typedef struct lvp__overlap_tasks {
	const lvp__bvh *bvh;
	const uint8_t *marked, *skipped;
	lvp__bvh_visit_pair visit;
	void *context;
	const int32_t *first, *second; /* the pairs of nodes of the phase running */
} lvp__overlap_tasks;

static void lvp__overlap_task(void *context, int32_t begin, int32_t end)
{
	const lvp__overlap_tasks *tasks = context;
	for (int32_t i = begin; i < end; ++i)
		lvp__overlaps_from(tasks->bvh, tasks->marked, tasks->skipped, tasks->first[i], tasks->second[i], tasks->visit,
		                   tasks->context);
}

void lvp__bvh_self_overlaps(const lvp__bvh *bvh, const uint8_t *marked, const uint8_t *skipped, lvp__pool *pool,
                            lvp__bvh_visit_pair visit, void *context)
{
	if (bvh->triangle_count == 0)
		return;
	/* The subtrees LVP__BVH_TASK_DEPTH levels down (or leaves above that) share no triangle, so they
	 * are searched at once; then, level by level from the deepest, the pairs between the two
	 * children of each node above them, which share none either. */
	enum { SUBTREES = 1 << LVP__BVH_TASK_DEPTH };
	int32_t subtrees[SUBTREES], subtree_count = 0;
	int32_t lefts[LVP__BVH_TASK_DEPTH][SUBTREES / 2], rights[LVP__BVH_TASK_DEPTH][SUBTREES / 2];
	int32_t level_count[LVP__BVH_TASK_DEPTH] = {0};
	int32_t stack[2 * (LVP__BVH_TASK_DEPTH + 1)];
	int top = 0;
	stack[top++] = 0;
	stack[top++] = 0;
	while (top > 0) {
		int32_t depth = stack[--top], node = stack[--top];
		const lvp__bvh_node *n = &bvh->nodes[node];
		if (skipped && skipped[node])
			continue; /* neither its own pairs nor those between its children */
		if (n->count > 0 || depth == LVP__BVH_TASK_DEPTH) {
			subtrees[subtree_count++] = node;
			continue;
		}
		lefts[depth][level_count[depth]] = n->index;
		rights[depth][level_count[depth]++] = n->index + 1;
		stack[top++] = n->index + 1, stack[top++] = depth + 1;
		stack[top++] = n->index, stack[top++] = depth + 1;
	}
	lvp__overlap_tasks tasks = {bvh, marked, skipped, visit, context, subtrees, subtrees};
	lvp__parallel_for(pool, lvp__overlap_task, &tasks, subtree_count, 1);
	for (int depth = LVP__BVH_TASK_DEPTH - 1; depth >= 0; --depth) {
		tasks.first = lefts[depth];
		tasks.second = rights[depth];
		lvp__parallel_for(pool, lvp__overlap_task, &tasks, level_count[depth], 1);
	}
}
