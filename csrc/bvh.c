/*
 * bvh.c - binned-SAH bounding volume hierarchy over mesh triangles and segment queries against it, for the
 * exact visibility test of automatic weights (Rohmer, Hahmann, Cani 2008, section 5.1: "ray tracing
 * against the mesh is the exact alternative"). See bvh.h for the algorithm, memory and performance.
 */
#include "bvh.h"

#include <float.h>
#include <stdlib.h>

#define LVP__BVH_BINS 16
#define LVP__BVH_MAX_LEAF 8
#define LVP__BVH_SMALL_LEAF 2     /* below this many triangles, always a leaf */
#define LVP__BVH_SAH_DEPTH 40     /* deeper nodes split at the median: depth <= 40 + log2(F) < 72 */
#define LVP__BVH_STACK 96
#define LVP__BVH_TRAVERSAL_COST 1.0f

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
		box->lo[a] = fminf(box->lo[a], other->lo[a]);
		box->hi[a] = fmaxf(box->hi[a], other->hi[a]);
	}
}

static float lvp__box_half_area(const lvp__box *box)
{
	float dx = box->hi[0] - box->lo[0], dy = box->hi[1] - box->lo[1], dz = box->hi[2] - box->lo[2];
	if (dx < 0.0f)
		return 0.0f; /* empty */
	return dx * dy + dy * dz + dz * dx;
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
		float bin_scale = (float)LVP__BVH_BINS / extent;
		lvp__box bins[LVP__BVH_BINS];
		int32_t counts[LVP__BVH_BINS] = {0};
		for (int b = 0; b < LVP__BVH_BINS; ++b)
			lvp__box_empty(&bins[b]);
		for (int32_t i = begin; i < end; ++i) {
			int32_t slot = build->order[i];
			int b = (int)((lvp__centroid(build, slot, axis) - lo) * bin_scale);
			b = b < 0 ? 0 : (b >= LVP__BVH_BINS ? LVP__BVH_BINS - 1 : b);
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
	float bin_scale = (float)LVP__BVH_BINS / (centroid_box->hi[best_axis] - lo);
	int32_t i = begin, j = end - 1;
	while (i <= j) {
		int b = (int)((lvp__centroid(build, build->order[i], best_axis) - lo) * bin_scale);
		b = b < 0 ? 0 : (b >= LVP__BVH_BINS ? LVP__BVH_BINS - 1 : b);
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
	bvh.triangles = malloc(sizeof(lvp__bvh_triangle) * (f ? f : 1));
	void *scratch = malloc((sizeof(lvp__box) + 3 * sizeof(float) + sizeof(int32_t)) * (f ? f : 1));
	if (!bvh.nodes || !bvh.triangles || !scratch) {
		free(bvh.nodes);
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
				box->lo[axis] = fminf(box->lo[axis], p[axis]);
				box->hi[axis] = fmaxf(box->hi[axis], p[axis]);
			}
		}
		out->source = t;
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
				centroid_box.lo[axis] = fminf(centroid_box.lo[axis], c);
				centroid_box.hi[axis] = fmaxf(centroid_box.hi[axis], c);
			}
		}
		lvp__bvh_node *out = &bvh.nodes[node];
		memcpy(out->lo, box.lo, sizeof(box.lo));
		memcpy(out->hi, box.hi, sizeof(box.hi));
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

void lvp__bvh_free(lvp__bvh *bvh)
{
	if (!bvh)
		return;
	free(bvh->nodes);
	free(bvh->triangles);
	memset(bvh, 0, sizeof(*bvh));
}

/* Parametric interval of the segment inside a node's box, widened by a little so that a triangle lying
 * on the box's face is never culled by rounding (culling too little only costs a triangle test). */
static bool lvp__segment_box(const lvp__bvh_node *node, const double from[3], const double direction[3],
                             const double inverse[3], double t_min, double t_max)
{
	const double slack = 1e-9;
	double near = t_min - slack, far = t_max + slack;
	for (int axis = 0; axis < 3; ++axis) {
		double lo = node->lo[axis], hi = node->hi[axis];
		if (direction[axis] == 0.0) {
			if (from[axis] < lo || from[axis] > hi)
				return false;
			continue;
		}
		double t0 = (lo - from[axis]) * inverse[axis], t1 = (hi - from[axis]) * inverse[axis];
		if (t0 > t1) {
			double swap = t0;
			t0 = t1;
			t1 = swap;
		}
		double pad = slack * (fabs(t0) + fabs(t1)) + slack;
		near = fmax(near, t0 - pad);
		far = fmin(far, t1 + pad);
		if (near > far)
			return false;
	}
	return true;
}

bool lvp__bvh_segment_hits(const lvp__bvh *bvh, lvp__vec3 from, lvp__vec3 to, double t_min, double t_max,
                           int32_t skip_vertex)
{
	if (bvh->triangle_count == 0)
		return false;
	lvp__vec3 direction = lvp__sub(to, from);
	double o[3] = {from.x, from.y, from.z}, d[3] = {direction.x, direction.y, direction.z}, inverse[3];
	for (int axis = 0; axis < 3; ++axis)
		inverse[axis] = d[axis] != 0.0 ? 1.0 / d[axis] : 0.0;
	int32_t stack[LVP__BVH_STACK];
	int top = 0;
	stack[top++] = 0;
	while (top > 0) {
		const lvp__bvh_node *node = &bvh->nodes[stack[--top]];
		if (!lvp__segment_box(node, o, d, inverse, t_min, t_max))
			continue;
		if (node->count == 0) {
			stack[top++] = node->index;
			stack[top++] = node->index + 1;
			continue;
		}
		const lvp__bvh_triangle *tri = bvh->triangles + node->index;
		for (int32_t i = 0; i < node->count; ++i, ++tri) {
			if (tri->vertices[0] == skip_vertex || tri->vertices[1] == skip_vertex || tri->vertices[2] == skip_vertex)
				continue;
			double t;
			if (lvp__segment_triangle(&t, from, direction, tri->corners, t_min, t_max))
				return true;
		}
	}
	return false;
}
