/*
 * clearance.c - the correction fades where skin approaches other skin (lvp.h, CONTACT; docs/method.md,
 * Keeping skin apart), before any pair of triangles is tested. Each vertex's offset points along its
 * (smoothed) normal; where plain skinning brings other skin in front of it (the inside of a bent
 * finger, a fingertip over the palm, a thigh against the buttock) the room in front of it, its
 * clearance, bounds how far it may go: half of it, as the skin opposite may come the same way.
 * Offsets well inside that bound are kept whole, longer ones approach it smoothly and never reach
 * it, and the shares kept are smoothed over the rings around so that no vertex is held back from its
 * neighbours' surface (a shard): the volume they do not carry goes elsewhere (correction.c). The
 * crossing test of contact.c takes what the fade cannot see: skin that plain skinning leaves touching,
 * whose corners all have room ahead.
 *
 * The clearance of a vertex at p moving along the unit direction d is the diameter of the largest
 * ball tangent to d at p that no other skin enters: min over the other skin's points q in front of p
 * of |q - p|^2 / <q - p, d>. Skin straight ahead counts at its distance, skin off to the side at
 * angle phi at its distance over cos phi, skin beside or behind not at all; unlike the distance
 * along a ray, it changes continuously with the pose (a ray leaving the other skin's silhouette
 * would drop it at once), so the fade has no jump. d is the offset's direction at the frame's first
 * search, kept through its later fades: a vertex searched again along its new direction, beside
 * neighbours whose clearances were found along their first, jumped between sub-frames where one
 * crossed the threshold of searching again and the other did not.
 *
 * A search tests the triangles whose boxes its ball may meet. Where offsets are long against the edges
 * (fine skin, a wide bulge), a ball spans many triangles and rests on nearly flat skin, tangent at its
 * vertex: the box of every patch of skin beneath it pokes up into it, and the triangles tested grew as
 * the square of the ball's width in edges, nearly none of them within the ball. Each node of the
 * hierarchy also bounds the slab its skin lies in (its sheet, lvp__fit_sheets), which meets such a ball
 * only near its vertex; groups whose balls are wider than their own skin gather and test the leaves by
 * it (lvp__sheet_may_meet). Both culls are conservative, so every search still sees each triangle its
 * ball may meet, and the clearances are the same either way (tests/c/test_clearance.c).
 */
#include "binding.h"

#include <stdlib.h>

/* A vertex whose clearance is more than this many times its offset keeps all of it (lvp__share_kept):
 * its clearance is wanted only below that. */
#define LVP__CLEARANCE_WANTED 4.0
/* Clearances are looked for up to this many times a vertex's offset, a quarter past what is wanted, so
 * that an offset the restore after a fade grows by less than that is not searched again; one that grows
 * more is, along the same direction (lvp__measure_clearance): every fade sees each clearance it needs,
 * exactly. The search's cost grows with the square of its reach (the skin around a vertex within it). */
#define LVP__CLEARANCE_REACH 5.0
/* How much a share may rise from one ring of the mesh to the next, at most: a vertex left no offset
 * holds its neighbours down over 1 / LVP__SHARE_SLOPE rings, one that keeps most of it only its own
 * ring: the roughness it adds to the offsets is about this share of their size. */
#define LVP__SHARE_SLOPE 0.2f
/* Passes that bring every share within the slope of its neighbours' (1 / LVP__SHARE_SLOPE), and passes
 * of averaging after them, which round the cones they leave. */
#define LVP__SLOPE_PASSES 5
#define LVP__AVERAGE_PASSES 3

typedef struct lvp__clearance_pass {
	lvp_binding *binding;
	const float *positions; /* the frame's input points (the skinning) */
	const float *from;      /* the shares a smoothing pass reads */
	float *to;              /* and writes */
	const uint8_t *roles;   /* per vertex, or NULL: what a smoothing pass does with each share (LVP__SHARE_*) */
	bool keep_floors;       /* averaging lowers shares, never raises one */
	const int32_t *near;    /* the vertices a smoothing pass walks (lvp__near_low_shares) */
} lvp__clearance_pass;

/* The offset of dynamic vertex k: where the steps put it, less where the skinning did. */
static inline lvp__vec3 lvp__offset_of(const lvp_binding *binding, const float *positions, int32_t k)
{
	return lvp__sub(lvp__load(binding->step.positions + 3 * k), lvp__load(positions + 3 * k));
}

static inline double lvp__axis(lvp__vec3 v, int axis)
{
	return axis == 0 ? v.x : (axis == 1 ? v.y : v.z);
}

/* |x|^2 / <x, d> for a point x (relative to the vertex) in front of it, else INFINITY. */
static inline double lvp__ball_diameter(lvp__vec3 x, lvp__vec3 d)
{
	double ahead = lvp__dot(x, d);
	return ahead > 0.0 ? lvp__dot(x, x) / ahead : INFINITY;
}

/* The least |x|^2 / <x, d> over the segment a + s (b - a), s in [0, 1] (relative to the vertex): at
 * an end, or where its derivative vanishes, C E s^2 + 2 C D s + 2 B D - E A = 0 with A = |a|^2,
 * B = <a, e>, C = |e|^2, D = <a, d>, E = <e, d>, e = b - a. */
static double lvp__segment_diameter(lvp__vec3 a, lvp__vec3 b, lvp__vec3 d)
{
	lvp__vec3 e = lvp__sub(b, a);
	double least = fmin(lvp__ball_diameter(a, d), lvp__ball_diameter(b, d));
	double A = lvp__dot(a, a), B = lvp__dot(a, e), C = lvp__dot(e, e), D = lvp__dot(a, d), E = lvp__dot(e, d);
	double qa = C * E, qb = 2.0 * C * D, qc = 2.0 * B * D - E * A;
	double roots[2];
	int count = 0;
	if (fabs(qa) > 1e-30 * (fabs(qb) + fabs(qc))) {
		double discriminant = qb * qb - 4.0 * qa * qc;
		if (discriminant >= 0.0) {
			double root = sqrt(discriminant);
			roots[count++] = (-qb + root) / (2.0 * qa);
			roots[count++] = (-qb - root) / (2.0 * qa);
		}
	} else if (qb != 0.0) {
		roots[count++] = -qc / qb;
	}
	for (int i = 0; i < count; ++i)
		if (roots[i] > 0.0 && roots[i] < 1.0)
			least = fmin(least, lvp__ball_diameter(lvp__add(a, lvp__scale(e, roots[i])), d));
	return least;
}

/* Whether no point of the segment ab (relative to the vertex) can give less than `bound`: |x|^2 is at
 * least the segment's squared distance and <x, d> at most its ends' larger (by a margin past rounding). */
static bool lvp__segment_beyond(lvp__vec3 a, lvp__vec3 b, lvp__vec3 d, double bound)
{
	double ahead = lvp__dot(a, d), ahead_b = lvp__dot(b, d);
	ahead = ahead > ahead_b ? ahead : ahead_b;
	if (!(ahead > 0.0))
		return true;
	lvp__vec3 e = lvp__sub(b, a);
	double length2 = lvp__dot(e, e), s = length2 > 0.0 ? -lvp__dot(a, e) / length2 : 0.0;
	s = s < 0.0 ? 0.0 : (s > 1.0 ? 1.0 : s);
	lvp__vec3 nearest = lvp__add(a, lvp__scale(e, s));
	return lvp__dot(nearest, nearest) >= bound * ahead * (1.0 + 1e-6);
}

/* The least |x|^2 / <x, d> over the triangle (corners relative to the vertex) when it is below `bound`
 * (else some value at least `bound`): the function is convex where <x, d> > 0 and grows without bound
 * toward <x, d> = 0, so its least is at a corner, on an edge, or where a ball tangent to d at the vertex
 * touches the triangle's plane inside it. Edges that cannot go below the bound are not searched. */
static double lvp__triangle_diameter(const lvp__vec3 x[3], lvp__vec3 d, double bound)
{
	double least = INFINITY;
	for (int i = 0; i < 3; ++i)
		if (!lvp__segment_beyond(x[i], x[(i + 1) % 3], d, bound))
			least = fmin(least, lvp__segment_diameter(x[i], x[(i + 1) % 3], d));
	lvp__vec3 normal = lvp__cross(lvp__sub(x[1], x[0]), lvp__sub(x[2], x[0]));
	double area2 = lvp__length(normal);
	if (!(area2 > 0.0))
		return least;
	normal = lvp__scale(normal, 1.0 / area2);
	/* The corners turn one way about the triangle's own normal: whether the touching point lies inside
	 * is asked about that one. About the normal turned to point from the vertex to the plane (below),
	 * every touch of a triangle facing the vertex would read as outside. */
	lvp__vec3 winding = normal;
	double h = lvp__dot(normal, x[0]);
	if (h < 0.0) {
		normal = lvp__scale(normal, -1.0);
		h = -h;
	}
	double tilt = 1.0 + lvp__dot(normal, d);
	if (!(h > 0.0) || !(tilt > 0.0))
		return least;
	/* The ball of diameter L centred at (L / 2) d touches the plane <n, x> = h where L = 2 h / (1 +
	 * <n, d>), at (L / 2)(d + n); that point counts when it lies in the triangle. */
	double diameter = 2.0 * h / tilt;
	if (!(diameter < least && diameter < bound))
		return least;
	lvp__vec3 touch = lvp__scale(lvp__add(d, normal), 0.5 * diameter);
	for (int i = 0; i < 3; ++i) {
		lvp__vec3 edge = lvp__sub(x[(i + 1) % 3], x[i]);
		if (lvp__dot(lvp__cross(edge, lvp__sub(touch, x[i])), winding) < 0.0)
			return least;
	}
	return fmin(least, diameter);
}

/* The squared distance from the origin (the vertex) to the triangle, through the closest point by the
 * triangle's regions: a corner, an edge, or the inside (Ericson, Real-Time Collision Detection, 5.1.5). */
static double lvp__distance2_to_triangle(const lvp__vec3 x[3])
{
	lvp__vec3 a = x[0], b = x[1], c = x[2];
	lvp__vec3 ab = lvp__sub(b, a), ac = lvp__sub(c, a);
	double d1 = -lvp__dot(ab, a), d2 = -lvp__dot(ac, a);
	if (d1 <= 0.0 && d2 <= 0.0)
		return lvp__dot(a, a);
	double d3 = -lvp__dot(ab, b), d4 = -lvp__dot(ac, b);
	if (d3 >= 0.0 && d4 <= d3)
		return lvp__dot(b, b);
	double vc = d1 * d4 - d3 * d2;
	if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
		lvp__vec3 q = lvp__add(a, lvp__scale(ab, d1 / (d1 - d3)));
		return lvp__dot(q, q);
	}
	double d5 = -lvp__dot(ab, c), d6 = -lvp__dot(ac, c);
	if (d6 >= 0.0 && d5 <= d6)
		return lvp__dot(c, c);
	double vb = d5 * d2 - d1 * d6;
	if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
		lvp__vec3 q = lvp__add(a, lvp__scale(ac, d2 / (d2 - d6)));
		return lvp__dot(q, q);
	}
	double va = d3 * d6 - d5 * d4;
	if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
		lvp__vec3 q = lvp__add(b, lvp__scale(lvp__sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
		return lvp__dot(q, q);
	}
	double sum = va + vb + vc;
	if (!(sum > 0.0))
		return 0.0; /* no area: no bound */
	lvp__vec3 q = lvp__add(a, lvp__add(lvp__scale(ab, vb / sum), lvp__scale(ac, vc / sum)));
	return lvp__dot(q, q);
}

/* One vertex's search: where it is, which way its offset points, the least diameter so far
 * (starting at the reach: beyond it, none is wanted), and the box searched: around the ball of that
 * diameter, narrowed as it drops. */
typedef struct lvp__clearance_search {
	lvp__vec3 from, direction;
	float from_f[3], direction_f[3]; /* the same in floats, for lvp__certainly_behind */
	int32_t vertex;
	double least;
	float lo[3], hi[3];
	/* The ball of the start (the reach) in floats, its radius a margin well past their rounding wider: any
	 * box that meets a ball of the search meets this one (lvp__meets_start_ball). */
	float start_centre[3], start_reach2;
	/* The ball of the least diameter: its centre, its radius a millionth wider, and a margin past the
	 * rounding of a distance from it (lvp__set_ball; read by lvp__outside_ball and lvp__sheet_may_meet). */
	lvp__vec3 centre;
	double radius, rounding;
} lvp__clearance_search;

/* The search's ball (lvp__clearance_search.centre) as its least diameter is now. */
static void lvp__set_ball(lvp__clearance_search *search)
{
	search->centre = lvp__add(search->from, lvp__scale(search->direction, 0.5 * search->least));
	search->radius = 0.5 * search->least * (1.0 + 1e-6);
	search->rounding =
	    1e-9 * (fabs(search->centre.x) + fabs(search->centre.y) + fabs(search->centre.z) + search->radius);
}

/* The box of the search narrowed to the ball of the least diameter found, a millionth wider (and a
 * rounding of the coordinates more), never wider than it was: skin outside it is outside that
 * ball, so its diameter is above the least by far more than rounding, and the search's answer is
 * what the whole box gives. Every ball narrower than the least, tangent at the vertex, lies inside
 * the ball of the least. */
static void lvp__narrow_search(lvp__clearance_search *search)
{
	lvp__set_ball(search);
	double half = 0.5 * search->least * (1.0 + 1e-6);
	double centre[3] = {search->from.x + search->direction.x * half, search->from.y + search->direction.y * half,
	                    search->from.z + search->direction.z * half};
	for (int axis = 0; axis < 3; ++axis) {
		double slack = half + 1e-12 * (fabs(centre[axis]) + half);
		float lo = (float)(centre[axis] - slack), hi = (float)(centre[axis] + slack);
		if ((double)lo > centre[axis] - slack)
			lo = nextafterf(lo, -INFINITY);
		if ((double)hi < centre[axis] + slack)
			hi = nextafterf(hi, INFINITY);
		search->lo[axis] = lo > search->lo[axis] ? lo : search->lo[axis];
		search->hi[axis] = hi < search->hi[axis] ? hi : search->hi[axis];
	}
}

/* Whether the boxes [a_lo, a_hi] and [b_lo, b_hi] have no point in common. */
static inline bool lvp__boxes_apart(const float a_lo[3], const float a_hi[3], const float b_lo[3], const float b_hi[3])
{
	return a_lo[0] > b_hi[0] || a_hi[0] < b_lo[0] || a_lo[1] > b_hi[1] || a_hi[1] < b_lo[1] || a_lo[2] > b_hi[2] ||
	       a_hi[2] < b_lo[2];
}

/* The squared distance from the point to the box [lo, hi] (0 inside it). */
static inline double lvp__box_distance2(lvp__vec3 point, const float lo[3], const float hi[3])
{
	double distance2 = 0.0;
	for (int axis = 0; axis < 3; ++axis) {
		double x = lvp__axis(point, axis);
		double gap = x < lo[axis] ? lo[axis] - x : (x > hi[axis] ? x - hi[axis] : 0.0);
		distance2 += gap * gap;
	}
	return distance2;
}

/* Whether the box [lo, hi] lies outside the box searched. */
static inline bool lvp__outside_search(const lvp__clearance_search *search, const float lo[3], const float hi[3])
{
	return lvp__boxes_apart(lo, hi, search->lo, search->hi);
}

/* Whether the box [lo, hi] lies outside the ball of the least diameter found (by a margin past
 * rounding): every point outside that ball gives more than the least (|x|^2 > least <x, d> there). */
static inline bool lvp__outside_ball(const lvp__clearance_search *search, const float lo[3], const float hi[3])
{
	double radius = 0.5 * search->least;
	return lvp__box_distance2(search->centre, lo, hi) > radius * radius * (1.0 + 1e-6);
}

/* Whether skin in the box [lo, hi] may come nearer than the least found (lvp__bvh_search's test). */
static bool lvp__box_may_hold(void *context, const float lo[3], const float hi[3])
{
	const lvp__clearance_search *search = context;
	return !lvp__outside_search(search, lo, hi) && !lvp__outside_ball(search, lo, hi);
}

/* Whether every corner of the triangle lies behind the vertex's tangent plane, <x, d> < 0, by a margin (a
 * hundred-thousandth of the corner's distance) far past the float rounding of this test (a few
 * ten-millionths of it): then no point of the triangle lies in front of the vertex. Most of the skin a
 * search finds is the vertex's own surface around it; this passes over what lies behind it in floats,
 * before the tests in doubles, which would pass over it too. */
static inline bool lvp__certainly_behind(const lvp__clearance_search *search, const lvp__bvh_triangle *triangle)
{
	for (int i = 0; i < 3; ++i) {
		float x = triangle->corners[i][0] - search->from_f[0], y = triangle->corners[i][1] - search->from_f[1],
		      z = triangle->corners[i][2] - search->from_f[2];
		float ahead = x * search->direction_f[0] + y * search->direction_f[1] + z * search->direction_f[2];
		if (!(ahead < -1e-5f * (fabsf(x) + fabsf(y) + fabsf(z))))
			return false;
	}
	return true;
}

static bool lvp__visit_clearance(void *context, const lvp__bvh_triangle *triangle)
{
	lvp__clearance_search *search = context;
	/* Its own triangles meet it, which is no contact: most of what a vertex's search visits, passed over
	 * before the box. */
	if (triangle->vertices[0] == search->vertex || triangle->vertices[1] == search->vertex ||
	    triangle->vertices[2] == search->vertex || lvp__certainly_behind(search, triangle) ||
	    !lvp__box_may_hold(search, triangle->lo, triangle->hi))
		return false;
	lvp__vec3 x[3];
	double ahead = 0.0, gap2 = 0.0;
	for (int i = 0; i < 3; ++i) {
		x[i] = lvp__sub(lvp__load(triangle->corners[i]), search->from);
		ahead = lvp__max_d(ahead, lvp__dot(x[i], search->direction));
	}
	/* Over the triangle |x|^2 is at least the squared distance to its box and <x, d> at most its
	 * corners' largest: a triangle beside or behind the vertex (most of what the search finds, the
	 * vertex's own skin around it) cannot make the least smaller, and is passed over. */
	for (int axis = 0; axis < 3; ++axis) {
		double lo = lvp__min_d(lvp__min_d(lvp__axis(x[0], axis), lvp__axis(x[1], axis)), lvp__axis(x[2], axis));
		double hi = lvp__max_d(lvp__max_d(lvp__axis(x[0], axis), lvp__axis(x[1], axis)), lvp__axis(x[2], axis));
		double gap = lo > 0.0 ? lo : (hi < 0.0 ? -hi : 0.0);
		gap2 += gap * gap;
	}
	if (!(ahead > 0.0) || gap2 >= search->least * ahead)
		return false;
	/* The same bound with the triangle's own distance, which the box's can fall far short of (a
	 * triangle of the skin around the vertex, tilted against the axes): most of those that pass above
	 * stop here, before the dearer search over the corners, edges and inside. Passed over only by a
	 * margin well past rounding, so that what remains gives the least it would have given. */
	if (lvp__distance2_to_triangle(x) >= search->least * ahead * (1.0 + 1e-6))
		return false;
	double diameter = lvp__triangle_diameter(x, search->direction, search->least);
	if (diameter < search->least) {
		search->least = diameter;
		lvp__narrow_search(search);
	}
	return false;
}

/* Per node of the hierarchy, its sheet (contact.sheets): the sum of its triangles' normals weighted by
 * their areas, that sum's direction (the axis), and the range of <x, axis> over its triangles. */
#define LVP__SHEET_SIZE 8
/* A descent's stack: the hierarchy is less than 72 deep (bvh.h), and one sibling waits per level. */
#define LVP__DESCENT_STACK 96

/* The axis of a sheet whose normals sum to `sum`: its direction, or any where they cancel (the range along
 * it still holds the skin, only wider). */
static inline lvp__vec3 lvp__sheet_axis(lvp__vec3 sum)
{
	double length = lvp__length(sum);
	return length > 0.0 ? lvp__scale(sum, 1.0 / length) : lvp__v(0.0, 0.0, 1.0);
}

/* Stores a node's sheet, its range widened by a margin well past the rounding of its sums. */
static void lvp__set_sheet(double *sheet, lvp__vec3 sum, lvp__vec3 axis, double low, double high)
{
	double margin = 1e-9 * (fabs(low) + fabs(high));
	sheet[0] = sum.x;
	sheet[1] = sum.y;
	sheet[2] = sum.z;
	sheet[3] = axis.x;
	sheet[4] = axis.y;
	sheet[5] = axis.z;
	sheet[6] = low - margin;
	sheet[7] = high + margin;
}

/* What fitting one node's sheet costs against a vertex's step of the correction (LVP__POOL_FOR counts
 * those): a leaf's few triangles, their normals and corners, as a refit's node (contact.c). And the nodes
 * a task takes at a time. */
#define LVP__SHEET_WORK 8
#define LVP__SHEET_GRAIN 512

/* The sheet of a leaf: its triangles' own normals and corners. */
static void lvp__fit_leaf_sheets(void *context, int32_t begin, int32_t end)
{
	lvp__contact *contact = context;
	const lvp__bvh *bvh = &contact->bvh;
	for (int32_t index = begin; index < end; ++index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count == 0)
			continue;
		lvp__vec3 sum = lvp__v(0.0, 0.0, 0.0);
		for (int32_t i = node->index; i < node->index + node->count; ++i) {
			const lvp__bvh_triangle *triangle = &bvh->triangles[i];
			lvp__vec3 a = lvp__load(triangle->corners[0]);
			sum = lvp__add(sum, lvp__cross(lvp__sub(lvp__load(triangle->corners[1]), a),
			                               lvp__sub(lvp__load(triangle->corners[2]), a)));
		}
		lvp__vec3 axis = lvp__sheet_axis(sum);
		double low = INFINITY, high = -INFINITY;
		for (int32_t i = node->index; i < node->index + node->count; ++i)
			for (int c = 0; c < 3; ++c) {
				double along = lvp__dot(lvp__load(bvh->triangles[i].corners[c]), axis);
				low = lvp__min_d(low, along);
				high = lvp__max_d(high, along);
			}
		lvp__set_sheet(contact->sheets + LVP__SHEET_SIZE * (int64_t)index, sum, axis, low, high);
	}
}

/* contact.sheets of the hierarchy as fitted to the skinning: the leaves on the pool's threads, then the
 * inner nodes, children before parents (a parent comes before its children in the node array). A
 * parent's range holds each child's, carried from the child's axis to its own through the child's box
 * (<x, a> = <x, a_c> + <x, a - a_c>, the last bounded over the box), and never wider than the child's
 * box along the axis. */
static void lvp__fit_sheets(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const lvp__bvh *bvh = &contact->bvh;
	lvp__parallel_for(LVP__POOL_FOR(binding, (int64_t)bvh->node_count * LVP__SHEET_WORK), lvp__fit_leaf_sheets,
	                  contact, bvh->node_count, LVP__SHEET_GRAIN);
	for (int32_t index = bvh->node_count - 1; index >= 0; --index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count > 0)
			continue;
		const double *left = contact->sheets + LVP__SHEET_SIZE * (int64_t)node->index;
		const double *right = left + LVP__SHEET_SIZE;
		lvp__vec3 sum = lvp__v(left[0] + right[0], left[1] + right[1], left[2] + right[2]);
		lvp__vec3 axis = lvp__sheet_axis(sum);
		double low = INFINITY, high = -INFINITY;
		for (int32_t child = node->index; child <= node->index + 1; ++child) {
			const lvp__bvh_node *box = &bvh->nodes[child];
			const double *child_sheet = contact->sheets + LVP__SHEET_SIZE * (int64_t)child;
			double box_low = 0.0, box_high = 0.0, tilt_low = 0.0, tilt_high = 0.0;
			for (int k = 0; k < 3; ++k) {
				double a = lvp__axis(axis, k), tilt = a - child_sheet[3 + k];
				box_low += a > 0.0 ? a * box->lo[k] : a * box->hi[k];
				box_high += a > 0.0 ? a * box->hi[k] : a * box->lo[k];
				tilt_low += tilt > 0.0 ? tilt * box->lo[k] : tilt * box->hi[k];
				tilt_high += tilt > 0.0 ? tilt * box->hi[k] : tilt * box->lo[k];
			}
			low = lvp__min_d(low, lvp__max_d(child_sheet[6] + tilt_low, box_low));
			high = lvp__max_d(high, lvp__min_d(child_sheet[7] + tilt_high, box_high));
		}
		lvp__set_sheet(contact->sheets + LVP__SHEET_SIZE * (int64_t)index, sum, axis, low, high);
	}
}

/* Vertices near each other are searched together: the triangles near any of them are found by one
 * descent of the hierarchy, then each vertex looks through those. A group is the vertices whose first
 * triangle lies under one subtree of at most this many triangles. */
#define LVP__GROUP_TRIANGLES 32
/* Triangles a group's descent may gather (on the stack of the thread searching it); past that, it gathers
 * again by its balls (lvp__gather_group), and past that again its vertices descend one by one. */
#define LVP__GROUP_CANDIDATES 1024
/* Vertices of a group searched together at most (the corners of its triangles). */
#define LVP__GROUP_SEARCHES (3 * LVP__GROUP_TRIANGLES)
/* Groups a task takes at a time. */
#define LVP__GROUP_GRAIN 16
/* What one vertex's search costs against a vertex's step of the correction (LVP__POOL_FOR counts
 * those): it looks through tens to hundreds of triangles, so a hand's few thousand moving vertices
 * are worth the threads where its steps are not. */
#define LVP__SEARCH_WORK 64
/* The same for a pass over the shares, which reads a vertex's neighbours (about six), and the vertices
 * such a pass takes at a time: a hand's few thousand shared among the threads. */
#define LVP__SHARE_WORK 4
#define LVP__SHARE_GRAIN 1024

/* The search of dynamic vertex k, up to LVP__CLEARANCE_REACH times its offset, and false when it needs
 * none: no offset (its clearance is INFINITY), or one whose wanted clearance lies within the reach
 * searched already this frame. The balls that reach no further lie in the box around the one of that
 * diameter. */
static bool lvp__start_search(const lvp__clearance_pass *pass, int32_t k, lvp__clearance_search *search)
{
	lvp__contact *contact = &pass->binding->contact;
	lvp__vec3 offset = lvp__offset_of(pass->binding, pass->positions, k);
	double length = lvp__length(offset);
	if (!(length > 0.0) || LVP__CLEARANCE_WANTED * length <= contact->clearance_reach[k])
		return false;
	double reach = LVP__CLEARANCE_REACH * length;
	float *direction = contact->clearance_direction + 3 * (int64_t)k;
	if (contact->clearance_reach[k] > 0.0f) { /* searched earlier this frame: along the same direction */
		lvp__vec3 kept = lvp__load(direction);
		search->direction = lvp__scale(kept, 1.0 / lvp__length(kept));
	} else {
		search->direction = lvp__scale(offset, 1.0 / length);
		direction[0] = (float)search->direction.x;
		direction[1] = (float)search->direction.y;
		direction[2] = (float)search->direction.z;
	}
	contact->clearance[k] = INFINITY;
	contact->clearance_reach[k] = (float)reach;
	search->from = lvp__load(pass->positions + 3 * k);
	for (int axis = 0; axis < 3; ++axis) {
		search->from_f[axis] = pass->positions[3 * k + axis];
		search->direction_f[axis] = (float)lvp__axis(search->direction, axis);
	}
	search->vertex = k;
	search->least = reach;
	lvp__set_ball(search);
	lvp__vec3 centre = search->centre;
	float lo[3] = {(float)(centre.x - 0.5 * reach), (float)(centre.y - 0.5 * reach), (float)(centre.z - 0.5 * reach)};
	float hi[3] = {(float)(centre.x + 0.5 * reach), (float)(centre.y + 0.5 * reach), (float)(centre.z + 0.5 * reach)};
	memcpy(search->lo, lo, sizeof(lo));
	memcpy(search->hi, hi, sizeof(hi));
	double size = fabs(centre.x) + fabs(centre.y) + fabs(centre.z) + 0.5 * reach;
	float start_reach = (float)(0.5 * reach + 1e-5 * size);
	search->start_centre[0] = (float)centre.x;
	search->start_centre[1] = (float)centre.y;
	search->start_centre[2] = (float)centre.z;
	search->start_reach2 = start_reach * start_reach;
	return true;
}

/* What a group's descent gathers: the triangles and their boxes by coordinate (lvp__near_candidates reads
 * them in one pass per vertex), or (by_sheets) the leaves of the hierarchy, few enough that each search
 * tests their boxes and sheets one by one. */
typedef struct lvp__candidates {
	const lvp__bvh_triangle *triangles[LVP__GROUP_CANDIDATES];
	int32_t leaves[LVP__GROUP_CANDIDATES];
	float lo[3][LVP__GROUP_CANDIDATES], hi[3][LVP__GROUP_CANDIDATES];
	int32_t count;
	bool overflow, by_sheets;
} lvp__candidates;

static bool lvp__gather_candidate(void *context, const lvp__bvh_triangle *triangle)
{
	lvp__candidates *candidates = context;
	if (candidates->count == LVP__GROUP_CANDIDATES) {
		candidates->overflow = true;
		return true;
	}
	for (int axis = 0; axis < 3; ++axis) {
		candidates->lo[axis][candidates->count] = triangle->lo[axis];
		candidates->hi[axis][candidates->count] = triangle->hi[axis];
	}
	candidates->triangles[candidates->count++] = triangle;
	return false;
}

/* Whether the box [lo, hi] may meet the start ball of the search (lvp__clearance_search.start_reach2). */
static inline bool lvp__meets_start_ball(const lvp__clearance_search *search, const float lo[3], const float hi[3])
{
	float distance2 = 0.0f;
	for (int axis = 0; axis < 3; ++axis) {
		float c = search->start_centre[axis];
		float gap = lo[axis] > c ? lo[axis] - c : (c > hi[axis] ? c - hi[axis] : 0.0f);
		distance2 += gap * gap;
	}
	return distance2 <= search->start_reach2;
}

/* A group's gathering by its balls rather than by the box around them (lvp__gather_group). */
typedef struct lvp__ball_gathering {
	lvp__candidates *candidates;
	const lvp__clearance_search *searches;
	int32_t count;
	const float *lo, *hi; /* the box around the group's balls */
} lvp__ball_gathering;

/* Whether the box [lo, hi] may meet any of the group's balls. */
static bool lvp__meets_a_ball(void *context, const float lo[3], const float hi[3])
{
	const lvp__ball_gathering *gathering = context;
	if (lvp__boxes_apart(lo, hi, gathering->lo, gathering->hi))
		return false;
	for (int32_t s = 0; s < gathering->count; ++s)
		if (lvp__meets_start_ball(&gathering->searches[s], lo, hi))
			return true;
	return false;
}

static bool lvp__gather_ball_candidate(void *context, const lvp__bvh_triangle *triangle)
{
	const lvp__ball_gathering *gathering = context;
	return lvp__gather_candidate(gathering->candidates, triangle);
}

/* Whether the skin under node `index` may meet the search's ball as it is now (lvp__clearance_search.least):
 * the ball cut to the node's sheet (contact.sheets, the slab its triangles lie in) lies in a cylinder
 * along the sheet's axis, and that in a sphere, which the node's box must meet. Where a wide ball rests
 * on nearly flat skin, tangent at its vertex, the boxes of the skin around poke up into it and the slab
 * does not: the slab meets the ball only within about the square root of the ball's diameter times the
 * slab's thickness of the vertex. Conservative by a margin well past rounding, as the box tests are. */
static bool lvp__sheet_may_meet(const lvp__contact *contact, const lvp__clearance_search *search, int32_t index)
{
	const double *sheet = contact->sheets + LVP__SHEET_SIZE * (int64_t)index;
	const lvp__bvh_node *node = &contact->bvh.nodes[index];
	double radius = search->radius;
	lvp__vec3 axis = lvp__v(sheet[3], sheet[4], sheet[5]);
	lvp__vec3 centre = search->centre;
	double height = lvp__dot(centre, axis);
	double low = lvp__max_d(sheet[6], height - radius), high = lvp__min_d(sheet[7], height + radius);
	if (low > high)
		return false;
	/* The widest cross-section of the ball within [low, high], and the sphere around that cylinder. */
	double widest = height < low ? low : (height > high ? high : height);
	double across2 = lvp__max_d(radius * radius - (widest - height) * (widest - height), 0.0);
	double half = 0.5 * (high - low);
	double bound = sqrt(across2 + half * half);
	lvp__vec3 middle = lvp__add(centre, lvp__scale(axis, 0.5 * (low + high) - height));
	bound += 1e-6 * bound + search->rounding;
	return lvp__box_distance2(middle, node->lo, node->hi) <= bound * bound;
}

/* Into `candidates` (by_sheets), the leaves of the hierarchy whose boxes meet the box [lo, hi] around
 * the group's balls and whose skin may meet one of them (lvp__sheet_may_meet), going down only into
 * nodes that may; past its room, overflow. */
static void lvp__gather_leaves(const lvp__contact *contact, const lvp__clearance_search *searches, int32_t count,
                               const float lo[3], const float hi[3], lvp__candidates *candidates)
{
	const lvp__bvh *bvh = &contact->bvh;
	int32_t stack[LVP__DESCENT_STACK], last = 0;
	int top = 0;
	stack[top++] = 0;
	while (top > 0) {
		int32_t index = stack[--top];
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (lvp__boxes_apart(node->lo, node->hi, lo, hi))
			continue;
		/* The ball that met the last node first: a node and the next one down lie mostly under the
		 * same balls. */
		bool meets = false;
		for (int32_t tried = 0, s = last; tried < count && !meets; ++tried, s = s + 1 < count ? s + 1 : 0) {
			meets = lvp__meets_start_ball(&searches[s], node->lo, node->hi) &&
			        lvp__sheet_may_meet(contact, &searches[s], index);
			if (meets)
				last = s;
		}
		if (!meets)
			continue;
		if (node->count == 0) {
			stack[top++] = node->index + 1;
			stack[top++] = node->index;
			continue;
		}
		if (candidates->count == LVP__GROUP_CANDIDATES) {
			candidates->overflow = true;
			return;
		}
		candidates->leaves[candidates->count++] = index;
	}
}

/* Into `candidates`, the triangles whose boxes meet the box [lo, hi] around the group's balls, or when
 * more than it holds, those whose boxes meet one of the balls. Each ball lies in the box around it, which
 * on fine skin (a ball many triangles wide) holds far more of the skin under the ball than the ball does:
 * past the candidates' room, the group is gathered again by the balls themselves, which costs a test of
 * each ball at every box it descends into, and only past that again do its vertices search one by one.
 * With by_sheets, the leaves whose sheets meet one of the balls instead (lvp__gather_leaves). */
static void lvp__gather_group(const lvp__contact *contact, const lvp__clearance_search *searches, int32_t count,
                              const float lo[3], const float hi[3], bool by_sheets, lvp__candidates *candidates)
{
	candidates->count = 0;
	candidates->overflow = false;
	candidates->by_sheets = by_sheets;
	if (by_sheets) {
		lvp__gather_leaves(contact, searches, count, lo, hi, candidates);
		return;
	}
	lvp__bvh_overlapping(&contact->bvh, lo, hi, lvp__gather_candidate, candidates);
	if (!candidates->overflow)
		return;
	candidates->count = 0;
	candidates->overflow = false;
	lvp__ball_gathering gathering = {candidates, searches, count, lo, hi};
	lvp__bvh_search(&contact->bvh, lvp__meets_a_ball, lvp__gather_ball_candidate, &gathering);
}

/* Into r_near (in the order gathered), the candidates whose boxes may meet the vertex's ball as it is at
 * the start of its search (lvp__clearance_search.start_reach2): one tight pass over the boxes, where most of
 * a group's candidates lie outside a vertex's ball. The search then tests those as it tests any triangle,
 * against the ball as it narrows: what this passes over, the larger ball of the start passed over already.
 * Returns their number. */
static int32_t lvp__near_candidates(const lvp__candidates *candidates, const lvp__clearance_search *search,
                                    int32_t *r_near)
{
	const float cx = search->start_centre[0], cy = search->start_centre[1], cz = search->start_centre[2];
	uint8_t meets[LVP__GROUP_CANDIDATES];
	/* The gap along an axis, max(lo - c, c - hi, 0), as sums and absolute values: no branch, so that the
	 * compiler tests four boxes at a time. */
	for (int32_t i = 0; i < candidates->count; ++i) {
		float distance2 = 0.0f;
		for (int axis = 0; axis < 3; ++axis) {
			float c = axis == 0 ? cx : (axis == 1 ? cy : cz);
			float below = candidates->lo[axis][i] - c, above = c - candidates->hi[axis][i];
			float gap = 0.5f * (below + above + fabsf(below - above));
			gap = 0.5f * (gap + fabsf(gap));
			distance2 += gap * gap;
		}
		meets[i] = distance2 <= search->start_reach2;
	}
	int32_t count = 0;
	for (int32_t i = 0; i < candidates->count; ++i) {
		r_near[count] = i;
		count += meets[i];
	}
	return count;
}

/* A vertex's search over its group's gathered triangles, or the triangles of its gathered leaves whose
 * boxes and sheets meet its ball, or (candidates NULL, or more than were gathered) through the hierarchy
 * on its own, going down only into boxes that meet its ball; then contact.clearance of its vertex
 * (lvp__start_search set it to INFINITY). */
static void lvp__search(lvp__contact *contact, lvp__clearance_search *search, const lvp__candidates *candidates)
{
	double reach = search->least;
	if (candidates && !candidates->overflow) {
		if (!candidates->by_sheets) {
			int32_t nearby[LVP__GROUP_CANDIDATES];
			int32_t count = lvp__near_candidates(candidates, search, nearby);
			for (int32_t c = 0; c < count; ++c)
				lvp__visit_clearance(search, candidates->triangles[nearby[c]]);
		} else {
			for (int32_t c = 0; c < candidates->count; ++c) {
				int32_t index = candidates->leaves[c];
				const lvp__bvh_node *leaf = &contact->bvh.nodes[index];
				if (!lvp__box_may_hold(search, leaf->lo, leaf->hi) || !lvp__sheet_may_meet(contact, search, index))
					continue;
				for (int32_t t = leaf->index; t < leaf->index + leaf->count; ++t)
					lvp__visit_clearance(search, &contact->bvh.triangles[t]);
			}
		}
	} else {
		lvp__bvh_search(&contact->bvh, lvp__box_may_hold, lvp__visit_clearance, search);
	}
	if (search->least < reach)
		contact->clearance[search->vertex] = (float)search->least;
}

/* contact.clearance of the dynamic vertices of groups [begin, end) (INFINITY: no skin so near, or no
 * offset). A vertex's search narrows as it finds skin (lvp__visit_clearance), and its answer is the
 * least over every triangle its box meets, whichever way the triangles come to it: the group's
 * gathering holds each of them. */
static void lvp__clearance_groups(void *context, int32_t begin, int32_t end)
{
	const lvp__clearance_pass *pass = context;
	lvp_binding *binding = pass->binding;
	lvp__contact *contact = &binding->contact;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	lvp__candidates gathered, *candidates = &gathered;
	lvp__clearance_search searches[LVP__GROUP_SEARCHES];
	for (int32_t g = begin; g < end; ++g) {
		int32_t count = 0;
		float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
		float skin_lo[3] = {INFINITY, INFINITY, INFINITY}, skin_hi[3] = {-INFINITY, -INFINITY, -INFINITY};
		double widest = 0.0;
		for (int32_t i = contact->group_offsets[g]; i < contact->group_offsets[g + 1]; ++i) {
			int32_t k = contact->group_vertices[i];
			for (int axis = 0; axis < 3; ++axis) {
				skin_lo[axis] = lvp__minf(skin_lo[axis], pass->positions[3 * k + axis]);
				skin_hi[axis] = lvp__maxf(skin_hi[axis], pass->positions[3 * k + axis]);
			}
			if (!dynamic[k] || !lvp__start_search(pass, k, &searches[count]))
				continue;
			if (count == LVP__GROUP_SEARCHES - 1) { /* a group of a larger leaf than the hierarchy makes: */
				lvp__search(contact, &searches[count], NULL); /* this one alone */
				continue;
			}
			for (int axis = 0; axis < 3; ++axis) {
				lo[axis] = lvp__minf(lo[axis], searches[count].lo[axis]);
				hi[axis] = lvp__maxf(hi[axis], searches[count].hi[axis]);
			}
			widest = lvp__max_d(widest, searches[count].least);
			++count;
		}
		if (count == 0)
			continue;
		/* Balls wider than the group's own skin hold far less of the skin around than their boxes do,
		 * and are gathered by the sheets (lvp__sheet_may_meet); narrower ones by the triangles' boxes,
		 * which are as tight there and cheaper to test. Either way each search sees every triangle
		 * its ball may meet, and gives the same clearance. */
		double span = lvp__max_d(lvp__max_d(skin_hi[0] - skin_lo[0], skin_hi[1] - skin_lo[1]), skin_hi[2] - skin_lo[2]);
		lvp__gather_group(contact, searches, count, lo, hi, widest > span, candidates);
		for (int32_t s = 0; s < count; ++s)
			lvp__search(contact, &searches[s], candidates);
	}
}

lvp_result lvp__clearance_begin(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	lvp__contact *contact = &binding->contact;
	const lvp__bvh *bvh = &contact->bvh;
	const lvp__mesh *mesh = &binding->mesh;
	int32_t nodes = bvh->node_count, n = binding->vertex_count;
	bool ok = true;
	int32_t *size = lvp__calloc((size_t)nodes, sizeof(int32_t), &ok);     /* triangles under each node */
	int32_t *group_of = lvp__calloc((size_t)nodes, sizeof(int32_t), &ok); /* each node's group, or -1 */
	int32_t *vertex_group = lvp__calloc((size_t)n, sizeof(int32_t), &ok);
	contact->group_offsets = lvp__calloc((size_t)nodes + 1, sizeof(int32_t), &ok);
	contact->sheets = lvp__calloc((size_t)nodes * LVP__SHEET_SIZE, sizeof(double), &ok);
	contact->group_vertices = lvp__calloc((size_t)n, sizeof(int32_t), &ok);
	if (!ok) {
		free(size);
		free(group_of);
		free(vertex_group);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "could not allocate the clearance search of %d vertices.", (int)n);
	}
	for (int32_t index = nodes - 1; index >= 0; --index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		size[index] = node->count > 0 ? node->count : size[node->index] + size[node->index + 1];
	}
	/* Groups: the highest subtrees of at most LVP__GROUP_TRIANGLES triangles (parents come first). */
	int32_t groups = 0;
	for (int32_t index = 0; index < nodes; ++index) {
		int32_t parent = bvh->parents[index];
		if (parent >= 0 && group_of[parent] >= 0)
			group_of[index] = group_of[parent];
		else
			group_of[index] = size[index] <= LVP__GROUP_TRIANGLES || bvh->nodes[index].count > 0 ? groups++ : -1;
	}
	for (int32_t k = 0; k < n; ++k) {
		vertex_group[k] = -1;
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
			int32_t leaf = contact->leaf_of[mesh->vertex_triangles[c]];
			if (leaf >= 0) {
				vertex_group[k] = group_of[leaf];
				break;
			}
		}
		if (vertex_group[k] >= 0)
			++contact->group_offsets[vertex_group[k] + 1];
	}
	for (int32_t g = 0; g < groups; ++g)
		contact->group_offsets[g + 1] += contact->group_offsets[g];
	int32_t *fill = size; /* reused: the next free slot of each group */
	for (int32_t g = 0; g < groups; ++g)
		fill[g] = contact->group_offsets[g];
	for (int32_t k = 0; k < n; ++k)
		if (vertex_group[k] >= 0)
			contact->group_vertices[fill[vertex_group[k]]++] = k;
	contact->group_count = groups;
	free(size);
	free(group_of);
	free(vertex_group);
	/* The smoothing's neighbour lists turned round: for each vertex, the vertices whose passes read it. */
	const lvp__smoothing *smoothing = &binding->smoothing;
	int32_t entries = smoothing->offsets[n];
	contact->reader_offsets = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok);
	contact->readers = lvp__calloc((size_t)entries + 1, sizeof(int32_t), &ok);
	contact->near = lvp__calloc((size_t)n, sizeof(int32_t), &ok);
	contact->near_seen = lvp__calloc((size_t)n, 1, &ok);
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "could not allocate the clearance search of %d vertices.", (int)n);
	for (int32_t e = 0; e < entries; ++e)
		++contact->reader_offsets[smoothing->neighbours[e] + 1];
	for (int32_t k = 0; k < n; ++k)
		contact->reader_offsets[k + 1] += contact->reader_offsets[k];
	int32_t *cursor = contact->near; /* reused: the next free slot of each vertex's readers */
	memcpy(cursor, contact->reader_offsets, sizeof(int32_t) * (size_t)n);
	for (int32_t k = 0; k < n; ++k)
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
			contact->readers[cursor[smoothing->neighbours[e]]++] = k;
	return lvp_success;
}

void lvp__measure_clearance(lvp_binding *binding, const float *positions, bool again)
{
	lvp__contact *contact = &binding->contact;
	lvp__pool *pool = LVP__POOL_FOR(binding, (int64_t)binding->dynamic.vertex_count * LVP__SEARCH_WORK);
	lvp__clearance_pass pass = {binding, positions, NULL, NULL, NULL, false, NULL};
	/* Vertices in no group (every triangle around them of no area) have no clearance to measure. */
	if (!again) { /* a new frame: nothing searched yet, the hierarchy fitted to the skinning anew */
		for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
			contact->clearance[binding->dynamic.vertices[v]] = INFINITY;
			contact->clearance_reach[binding->dynamic.vertices[v]] = 0.0f;
			contact->faded[binding->dynamic.vertices[v]] = 0;
		}
		lvp__fit_sheets(binding);
	}
	lvp__parallel_for(pool, lvp__clearance_groups, &pass, contact->group_count, LVP__GROUP_GRAIN);
}

/* The share of an offset of length m that a vertex keeps with clearance c: all of it up to a
 * quarter of c; beyond, a length that rises with m, joins the first smoothly (value and slope) and
 * never reaches half of c, h - h^2 / (4 m) with h = c / 2. */
static float lvp__share_kept(double m, double c)
{
	double h = 0.5 * c;
	if (!(m > 0.5 * h)) /* m <= c / LVP__CLEARANCE_WANTED */
		return 1.0f;
	return (float)((h - h * h / (4.0 * m)) / m);
}

/* contact.fade of the dynamic vertices in [begin, end): each one's share at its clearance. */
static void lvp__share_range(void *context, int32_t begin, int32_t end)
{
	const lvp__clearance_pass *pass = context;
	lvp_binding *binding = pass->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		double m = lvp__length(lvp__offset_of(binding, pass->positions, k));
		binding->contact.fade[k] = lvp__share_kept(m, binding->contact.clearance[k]);
		binding->contact.faded[k] |= binding->contact.fade[k] < 1.0f;
	}
}

/* The role of vertex k's share in a smoothing pass (LVP__SHARE_*). */
static inline int lvp__share_role(const lvp__clearance_pass *pass, int32_t k)
{
	return pass->roles ? pass->roles[k] : LVP__SHARE_SMOOTHED;
}

/* Whether neighbour j's share counts in a smoothing pass: it has an offset this frame, and is not
 * kept out. */
static inline bool lvp__share_counts(const lvp__clearance_pass *pass, const uint8_t *dynamic, int32_t j)
{
	return dynamic[j] && lvp__share_role(pass, j) != LVP__SHARE_KEPT;
}

/* One pass over the dynamic vertices in [begin, end), from `from` into `to`: the vertex's share, or
 * its least neighbour's and LVP__SHARE_SLOPE more when that is less. A kept vertex takes the slope
 * from every neighbour with an offset, kept or not (a kept patch comes down with the skin around it,
 * ring by ring), while the others do not read the kept ones' shares; a fixed one keeps its share. */
static void lvp__slope_range(void *context, int32_t begin, int32_t end)
{
	const lvp__clearance_pass *pass = context;
	const lvp_binding *binding = pass->binding;
	const lvp__smoothing *smoothing = &binding->smoothing;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = pass->near[v];
		int role = lvp__share_role(pass, k);
		bool kept = role == LVP__SHARE_KEPT;
		float least = pass->from[k];
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1] && role != LVP__SHARE_FIXED; ++e) {
			int32_t j = smoothing->neighbours[e];
			bool counts = kept ? dynamic[j] != 0 : lvp__share_counts(pass, dynamic, j);
			if (counts && pass->from[j] + LVP__SHARE_SLOPE < least)
				least = pass->from[j] + LVP__SHARE_SLOPE;
		}
		pass->to[k] = least;
	}
}

/* One pass over the dynamic vertices in [begin, end), from `from` into `to`: the mean of the share
 * of the vertex and those of its dynamic neighbours (with keep_floors, where that is less than its
 * own); kept and fixed vertices keep theirs. */
static void lvp__average_range(void *context, int32_t begin, int32_t end)
{
	const lvp__clearance_pass *pass = context;
	const lvp_binding *binding = pass->binding;
	const lvp__smoothing *smoothing = &binding->smoothing;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = pass->near[v];
		double sum = 0.0, count = 0.0;
		if (lvp__share_role(pass, k) == LVP__SHARE_SMOOTHED) {
			for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e) {
				int32_t j = smoothing->neighbours[e];
				if (lvp__share_counts(pass, dynamic, j)) {
					sum += smoothing->shares[e] * (double)pass->from[j];
					count += smoothing->shares[e];
				}
			}
		}
		/* The vertex weighs as a neighbour whose two triangles have right angles opposite it. */
		float mean = (float)((2.0 * pass->from[k] + sum) / (2.0 + count));
		pass->to[k] = pass->keep_floors ? fminf(mean, pass->from[k]) : mean;
	}
}

/* The offsets (step.positions, step.smoothing_offsets) and the map of the dynamic vertices in
 * [begin, end) scaled by their smoothed shares. */
static void lvp__apply_range(void *context, int32_t begin, int32_t end)
{
	const lvp__clearance_pass *pass = context;
	lvp_binding *binding = pass->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		float share = binding->contact.fade[k];
		lvp__vec3 offset = lvp__scale(lvp__offset_of(binding, pass->positions, k), share);
		float *p = binding->step.positions + 3 * k, *o = binding->step.smoothing_offsets + 3 * k;
		const float *skinned = pass->positions + 3 * k;
		o[0] = (float)offset.x;
		o[1] = (float)offset.y;
		o[2] = (float)offset.z;
		for (int c = 0; c < 3; ++c)
			p[c] = skinned[c] + o[c];
		binding->frame_map.gamma[k] *= share;
	}
}

/* Into contact.near, ring by ring, the dynamic vertices within as many rings of a share below 1 as the
 * smoothing has passes (ring 0: those below 1), and into r_ring_ends[r] how many lie within r rings: a pass
 * changes a share only where a share it reads differs from 1 (a slope from 1s, and a weighted mean of 1s
 * summed in one order, are 1 exactly), so after p passes only the shares within p rings can differ from 1,
 * and the others stay 1. The rings are walked backwards through the neighbour lists (contact.readers): the
 * vertices whose passes read a vertex of the ring before. */
static void lvp__near_low_shares(lvp_binding *binding, const float *shares,
                                 int32_t r_ring_ends[LVP__SLOPE_PASSES + LVP__AVERAGE_PASSES + 1])
{
	lvp__contact *contact = &binding->contact;
	const uint8_t *dynamic = binding->frame_map.vertex_dynamic;
	int32_t count = 0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		contact->near_seen[k] = shares[k] < 1.0f;
		if (shares[k] < 1.0f)
			contact->near[count++] = k;
	}
	r_ring_ends[0] = count;
	for (int32_t first = 0, ring = 1; ring <= LVP__SLOPE_PASSES + LVP__AVERAGE_PASSES; ++ring) {
		int32_t last = count;
		for (int32_t i = first; i < last; ++i) {
			int32_t j = contact->near[i];
			for (int32_t e = contact->reader_offsets[j]; e < contact->reader_offsets[j + 1]; ++e) {
				int32_t k = contact->readers[e];
				if (dynamic[k] && !contact->near_seen[k]) {
					contact->near_seen[k] = 1;
					contact->near[count++] = k;
				}
			}
		}
		first = last;
		r_ring_ends[ring] = count;
	}
}

void lvp__smooth_shares(lvp_binding *binding, float *shares, float *scratch, const uint8_t *roles, bool keep_floors)
{
	int32_t ring_ends[LVP__SLOPE_PASSES + LVP__AVERAGE_PASSES + 1];
	lvp__near_low_shares(binding, shares, ring_ends);
	lvp__clearance_pass pass = {binding, NULL, shares, scratch, roles, keep_floors, binding->contact.near};
	/* The vertices past the rings a pass walks, which its last ring reads, hold 1 in both. */
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v)
		scratch[binding->dynamic.vertices[v]] = shares[binding->dynamic.vertices[v]];
	/* First no share more than the slope above a neighbour's (each pass reaches one ring further;
	 * none rises), then averaged. An even number of passes leaves the result in `shares`. Pass i
	 * changes the rings up to i + 1 only. */
	for (int i = 0; i < LVP__SLOPE_PASSES + LVP__AVERAGE_PASSES; ++i) {
		int32_t count = ring_ends[i + 1];
		lvp__pool *pool = LVP__POOL_FOR(binding, (int64_t)count * LVP__SHARE_WORK);
		lvp__parallel_for(pool, i < LVP__SLOPE_PASSES ? lvp__slope_range : lvp__average_range, &pass, count,
		                  LVP__SHARE_GRAIN);
		float *read = pass.to;
		pass.to = (float *)pass.from;
		pass.from = read;
	}
}
_Static_assert((LVP__SLOPE_PASSES + LVP__AVERAGE_PASSES) % 2 == 0, "the smoothed shares end where they began");

bool lvp__fade_at_clearance(lvp_binding *binding, const float *positions)
{
	int32_t count = binding->dynamic.vertex_count;
	lvp__pool *pool = LVP__POOL_FOR(binding, (int64_t)count * LVP__SHARE_WORK);
	lvp__clearance_pass pass = {binding, positions, NULL, NULL, NULL, false, NULL};
	lvp__parallel_for(pool, lvp__share_range, &pass, count, LVP__SHARE_GRAIN);
	bool any = false;
	for (int32_t v = 0; v < count && !any; ++v)
		any = binding->contact.fade[binding->dynamic.vertices[v]] < 1.0f;
	if (!any)
		return false;
	/* Clearances differ from vertex to vertex with the triangles around them: the averaging raises
	 * the single low ones to their neighbours' (the floors of the dips). */
	lvp__smooth_shares(binding, binding->contact.fade, binding->contact.fade_scratch, NULL, false);
	lvp__parallel_for(pool, lvp__apply_range, &pass, count, LVP__SHARE_GRAIN);
	return true;
}
