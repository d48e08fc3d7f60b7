/*
 * contact.c - the correction never pushes skin through skin (lvp.h, CONTACT; docs/method.md, Keeping
 * skin apart). Where plain skinning brings two sheets of skin close (the inside of a bent finger, the
 * thumb's web, a fingertip on the palm), the offsets, along each side's own normal, point the sheets
 * at each other, and a fraction of a millimetre can push one through the other: more crossing
 * triangles than skinning alone. Here every pair of triangles that crosses after the correction but
 * not in the skinning is found (a hierarchy over the triangles, refitted to each round's positions),
 * and the offsets of its corners are shortened to what keeps the pair apart (a bisected share of
 * them); a few rounds, then the shortening smoothed around and the smoothed patch tested again.
 *
 * Where the skinning itself passes skin through skin (a fist's creases), offsets of a hundredth of an
 * edge move that intersection by a fraction of a triangle, and which pairs it passes through changes:
 * a pair crossing anew there is no new contact. In each contact of a first round (the triangles that
 * took part in it, joined by shared corners) whose pairs crossing anew are all such pairs (some
 * triangle around one of the two crosses some triangle around the other in the skinning), those pairs
 * are left when over all such contacts the moved skin crosses no more pairs than the skinning does:
 * chasing them one by one shortened a fifth of a hand at the fist and still ended with more pairs than
 * the skinning (BENCHMARKS.md). A new contact elsewhere (the other knee) does not change that.
 */
#include "binding.h"

#include <stdlib.h>

/* Rounds of shortening at most, the last of which takes the offsets of pairs still crossing away. */
#define LVP__CONTACT_ROUNDS 8
/* Times a smoothed shortening is tested again (each test's shortening smoothed before the next). */
#define LVP__CONTACT_RETESTS 3
/* Steps of the bisection for how far a pinned patch goes back up (lvp__raise_pinned_crossing). */
#define LVP__RAISE_STEPS 6
/* Steps of the bisection for the share of the offsets that keeps a pair apart. */
#define LVP__CONTACT_BISECTIONS 10

static inline float lvp__min3(float a, float b, float c)
{
	float m = a < b ? a : b;
	return m < c ? m : c;
}

static inline float lvp__max3(float a, float b, float c)
{
	float m = a > b ? a : b;
	return m > c ? m : c;
}

/* The crossing tests decide by signs of orientation determinants in double, each with Shewchuk's
 * static error bound: a sign too close to call is UNSURE, and so is a crossing that hangs on one.
 * The surface measures decide exactly; a pair touching within rounding must not pass for apart
 * after the correction, nor for crossing (skinning's own, left alone) before it. */
enum { LVP__APART = 0, LVP__CROSS = 1, LVP__UNSURE = 2 };
#define LVP__SURE_SIGN 2 /* lvp__orientation's answer when the sign is too close to call */

/* The sign of the orientation of d against the plane of a, b, c: -1, 1, or LVP__SURE_SIGN when the
 * determinant is within its rounding bound (zero included). */
static inline int lvp__orientation(lvp__vec3 a, lvp__vec3 b, lvp__vec3 c, lvp__vec3 d)
{
	double ax = a.x - d.x, ay = a.y - d.y, az = a.z - d.z, bx = b.x - d.x, by = b.y - d.y, bz = b.z - d.z;
	double cx = c.x - d.x, cy = c.y - d.y, cz = c.z - d.z;
	double bc = by * cz - bz * cy, ca = cy * az - cz * ay, ab = ay * bz - az * by;
	double det = ax * bc + bx * ca + cx * ab;
	double permanent = (fabs(by * cz) + fabs(bz * cy)) * fabs(ax) + (fabs(cy * az) + fabs(cz * ay)) * fabs(bx) +
	                   (fabs(ay * bz) + fabs(az * by)) * fabs(cx);
	if (fabs(det) <= 7.771561172376103e-16 * permanent)
		return LVP__SURE_SIGN;
	return det > 0.0 ? 1 : -1;
}

/* Whether segment pq passes through the open triangle abc, from one open side of its plane to the
 * other (the test surface_quality.py counts crossings by). */
static int lvp__pierces(lvp__vec3 p, lvp__vec3 q, lvp__vec3 a, lvp__vec3 b, lvp__vec3 c)
{
	int sp = lvp__orientation(a, b, c, p), sq = lvp__orientation(a, b, c, q);
	if (sp != LVP__SURE_SIGN && sp == sq)
		return LVP__APART;
	int s[3] = {lvp__orientation(p, q, a, b), lvp__orientation(p, q, b, c), lvp__orientation(p, q, c, a)};
	int known = 0;
	bool unsure = sp == LVP__SURE_SIGN || sq == LVP__SURE_SIGN;
	for (int i = 0; i < 3; ++i) {
		if (s[i] == LVP__SURE_SIGN) {
			unsure = true;
		} else if (known == 0) {
			known = s[i];
		} else if (s[i] != known) {
			return LVP__APART; /* the line passes beside the triangle, whatever the others */
		}
	}
	return unsure ? LVP__UNSURE : LVP__CROSS;
}

/* Whether the three corners lie surely on one side of the plane of y (then x cannot cross y). */
static bool lvp__one_side(const lvp__vec3 *x, const lvp__vec3 *y)
{
	int a = lvp__orientation(y[0], y[1], y[2], x[0]);
	return a != LVP__SURE_SIGN && a == lvp__orientation(y[0], y[1], y[2], x[1]) &&
	       a == lvp__orientation(y[0], y[1], y[2], x[2]);
}

/* Whether two triangles (corners) cross, an edge of one through the inside of the other:
 * LVP__APART, LVP__CROSS or LVP__UNSURE. */
static int lvp__triangles_cross(const lvp__vec3 *x, const lvp__vec3 *y)
{
	if (lvp__one_side(x, y) || lvp__one_side(y, x))
		return LVP__APART;
	int result = LVP__APART;
	for (int e = 0; e < 3; ++e) {
		int one = lvp__pierces(x[e], x[(e + 1) % 3], y[0], y[1], y[2]);
		int other = lvp__pierces(y[e], y[(e + 1) % 3], x[0], x[1], x[2]);
		if (one == LVP__CROSS || other == LVP__CROSS)
			return LVP__CROSS;
		if (one == LVP__UNSURE || other == LVP__UNSURE)
			result = LVP__UNSURE;
	}
	return result;
}

typedef struct lvp__contact_pass {
	lvp_binding *binding;
	const float *positions; /* the frame's input points (the skinning) */
	/* A later round: per vertex, moved since its triangles were last tested (lvp__visit_later_pair). */
	const uint8_t *changed;
} lvp__contact_pass;

/* One triangle's search: its corners, corrected and skinned, its box, and the least share of the
 * offsets at which it and a triangle it meets still keep apart (1: it crosses none it did not cross
 * skinned). */
typedef struct lvp__triangle_search {
	const lvp__contact_pass *pass;
	const int32_t *corners;
	lvp__vec3 moved[3], skinned[3];
	float lo[3], hi[3];
	float limit;
	/* A first round's: the share for the pairs along the skinning's own crossing (limit: the others'),
	 * and whether the pair visited crosses after the correction, and in the skinning (to count them). */
	bool first_round, crossing, crossed_skinned;
	float shifted_limit;
} lvp__triangle_search;

/* The share lambda of the offsets (the corners at skinned + lambda (moved - skinned)) below which two
 * triangles that cross moved, and not skinned, keep apart, to 1/1024 (bisection). It varies
 * continuously with the pose where the crossing begins (1 there), so the shortening it asks for
 * starts at nothing rather than all at once. */
static float lvp__share_apart(const lvp__vec3 x_moved[3], const lvp__vec3 x_skinned[3], const lvp__vec3 y_moved[3],
                              const lvp__vec3 y_skinned[3])
{
	double apart = 0.0, crossing = 1.0;
	for (int step = 0; step < LVP__CONTACT_BISECTIONS; ++step) {
		double share = 0.5 * (apart + crossing);
		lvp__vec3 x[3], y[3];
		for (int i = 0; i < 3; ++i) {
			x[i] = lvp__add(x_skinned[i], lvp__scale(lvp__sub(x_moved[i], x_skinned[i]), share));
			y[i] = lvp__add(y_skinned[i], lvp__scale(lvp__sub(y_moved[i], y_skinned[i]), share));
		}
		if (lvp__triangles_cross(x, y) != LVP__APART)
			crossing = share;
		else
			apart = share;
	}
	return (float)apart;
}

/* Whether a corner of the triangle (its vertices) is marked in `marks`. */
static inline bool lvp__any_marked(const uint8_t *marks, const int32_t vertices[3])
{
	return marks[vertices[0]] || marks[vertices[1]] || marks[vertices[2]];
}

/* The search of the triangle with these corners, `moved` where the correction put them (the tree's
 * refitted copy, or step.positions): those, where the skinning put them, and the box of the first. */
static lvp__triangle_search lvp__search_of(const lvp__contact_pass *pass, const int32_t corners[3],
                                           const float *const moved[3])
{
	lvp__triangle_search search;
	search.pass = pass;
	search.corners = corners;
	search.limit = search.shifted_limit = 1.0f;
	search.first_round = search.crossing = search.crossed_skinned = false;
	for (int i = 0; i < 3; ++i) {
		search.moved[i] = lvp__load(moved[i]);
		search.skinned[i] = lvp__load(pass->positions + 3 * (int64_t)corners[i]);
	}
	for (int axis = 0; axis < 3; ++axis) {
		search.lo[axis] = lvp__min3(moved[0][axis], moved[1][axis], moved[2][axis]);
		search.hi[axis] = lvp__max3(moved[0][axis], moved[1][axis], moved[2][axis]);
	}
	return search;
}

/* Whether two triangles (their vertices) share a corner. */
static inline bool lvp__share_corner(const int32_t *a, const int32_t *b)
{
	for (int i = 0; i < 3; ++i)
		if (b[i] == a[0] || b[i] == a[1] || b[i] == a[2])
			return true;
	return false;
}

/* Whether the searched triangle and `other` may cross: they share no corner (neighbours meet at
 * their shared corners, which is no crossing) and their boxes overlap (a leaf's box holds several
 * triangles). */
static bool lvp__may_cross(const lvp__triangle_search *search, const lvp__bvh_triangle *other)
{
	if (lvp__share_corner(search->corners, other->vertices))
		return false;
	for (int axis = 0; axis < 3; ++axis)
		if (other->lo[axis] > search->hi[axis] || other->hi[axis] < search->lo[axis])
			return false;
	return true;
}

/* The corners of triangle t, where the skinning put them. */
static void lvp__skinned_corners(const lvp__contact_pass *pass, int32_t t, lvp__vec3 r_x[3])
{
	const int32_t *corners = pass->binding->mesh.triangles + 3 * (int64_t)t;
	for (int i = 0; i < 3; ++i)
		r_x[i] = lvp__load(pass->positions + 3 * (int64_t)corners[i]);
}

/* Whether a triangle around corner i of `corners` has one of its corners before i too: the triangles
 * around a triangle's corners are each taken once, around the first of its corners they hold. */
static inline bool lvp__has_earlier_corner(const int32_t triangle[3], const int32_t corners[3], int i)
{
	for (int e = 0; e < i; ++e)
		if (triangle[0] == corners[e] || triangle[1] == corners[e] || triangle[2] == corners[e])
			return true;
	return false;
}

/* Whether two triangles (their corners) cross along the skinning's own crossing: some triangle sharing
 * a corner with the first crosses, in the skinning, some triangle sharing a corner with the second.
 * Then the correction moved an intersection the skinning has by less than a triangle. */
static bool lvp__along_skinned_crossing(const lvp__contact_pass *pass, const int32_t a[3], const int32_t b[3])
{
	const lvp__mesh *mesh = &pass->binding->mesh;
	for (int i = 0; i < 3; ++i)
		for (int32_t c = mesh->vertex_corner_offsets[a[i]]; c < mesh->vertex_corner_offsets[a[i] + 1]; ++c) {
			int32_t x = mesh->vertex_triangles[c];
			const int32_t *x_corners = mesh->triangles + 3 * (int64_t)x;
			if (lvp__has_earlier_corner(x_corners, a, i))
				continue; /* seen around that corner */
			lvp__vec3 xs[3];
			lvp__skinned_corners(pass, x, xs);
			for (int j = 0; j < 3; ++j)
				for (int32_t d = mesh->vertex_corner_offsets[b[j]]; d < mesh->vertex_corner_offsets[b[j] + 1]; ++d) {
					int32_t y = mesh->vertex_triangles[d];
					const int32_t *y_corners = mesh->triangles + 3 * (int64_t)y;
					if (lvp__has_earlier_corner(y_corners, b, j) || lvp__share_corner(x_corners, y_corners))
						continue;
					lvp__vec3 ys[3];
					lvp__skinned_corners(pass, y, ys);
					if (lvp__triangles_cross(xs, ys) == LVP__CROSS)
						return true;
				}
		}
	return false;
}

static bool lvp__visit_candidate(void *context, const lvp__bvh_triangle *other)
{
	lvp__triangle_search *search = context;
	if (!lvp__may_cross(search, other))
		return false;
	lvp__vec3 moved[3], skinned[3];
	for (int i = 0; i < 3; ++i) {
		moved[i] = lvp__load(other->corners[i]);
		skinned[i] = lvp__load(search->pass->positions + 3 * (int64_t)other->vertices[i]);
	}
	/* Unsure counts as crossing after the correction and as apart before it: a pair that skinning
	 * leaves touching is kept as it is. Unsure both before and after is skinning's own: two triangles
	 * in one plane (a flat face, a flat strip bent in its plane), where the signs cannot tell and the
	 * surface measures see no crossing. */
	/* A first round counts the pairs crossing skinned too (lvp__leave_skinned_crossings). */
	int after = lvp__triangles_cross(search->moved, moved);
	if (after == LVP__APART) {
		search->crossed_skinned = search->first_round && lvp__triangles_cross(search->skinned, skinned) == LVP__CROSS;
		return false;
	}
	search->crossing = true;
	int before = lvp__triangles_cross(search->skinned, skinned);
	search->crossed_skinned = before == LVP__CROSS;
	if (before == LVP__CROSS || (before == LVP__UNSURE && after == LVP__UNSURE))
		return false;
	/* A corner fold-over pinned keeps its place (lvp__pin_held): the shares move the other corners
	 * only. A pair they cannot part, crossing with every other corner where the skinning put it, is
	 * left as it is: shortening takes offsets there and parts nothing (the skin pressed into a
	 * thumb's web beside a fingertip that the skinning already pushed into it). */
	const uint8_t *pinned = search->pass->binding->contact.pinned;
	lvp__vec3 x_floor[3], y_floor[3];
	bool any_pinned = false;
	for (int i = 0; i < 3; ++i) {
		bool x_pinned = pinned[search->corners[i]], y_pinned = pinned[other->vertices[i]];
		x_floor[i] = x_pinned ? search->moved[i] : search->skinned[i];
		y_floor[i] = y_pinned ? moved[i] : skinned[i];
		any_pinned = any_pinned || x_pinned || y_pinned;
	}
	if (any_pinned && lvp__triangles_cross(x_floor, y_floor) != LVP__APART)
		return false;
	float share = lvp__share_apart(search->moved, x_floor, moved, y_floor);
	if (search->first_round && lvp__along_skinned_crossing(search->pass, search->corners, other->vertices))
		search->shifted_limit = fminf(search->shifted_limit, share);
	else
		search->limit = fminf(search->limit, share);
	return false;
}

/* The first round: every pair of triangles, one of them moved, whose boxes overlap (the traversal
 * calls only those). */
static void lvp__visit_pair(void *context, const lvp__bvh_triangle *a, const lvp__bvh_triangle *b)
{
	const lvp__contact_pass *pass = context;
	lvp__contact *contact = &pass->binding->contact;
	const uint8_t *moved = contact->moved;
	if (!lvp__any_marked(moved, a->vertices) && !lvp__any_marked(moved, b->vertices))
		return;
	if (lvp__share_corner(a->vertices, b->vertices))
		return; /* neighbours, passed over before the search is set up (lvp__may_cross) */
	const float *const corners[3] = {a->corners[0], a->corners[1], a->corners[2]};
	lvp__triangle_search search = lvp__search_of(pass, a->vertices, corners);
	search.first_round = true;
	lvp__visit_candidate(&search, b);
	contact->limit[a->source] = fminf(contact->limit[a->source], search.limit);
	contact->limit[b->source] = fminf(contact->limit[b->source], search.limit);
	contact->shifted_limit[a->source] = fminf(contact->shifted_limit[a->source], search.shifted_limit);
	contact->shifted_limit[b->source] = fminf(contact->shifted_limit[b->source], search.shifted_limit);
	contact->pair_count[a->source] += search.crossing;
	contact->skinned_pair_count[a->source] += search.crossed_skinned;
}

/* A later round: a pair of triangles whose boxes overlap, when one of them has a corner moved since it was
 * last tested (pass->changed; the traversal calls only pairs under a node holding such a triangle) and one has
 * a corner whose triangles this round tests (contact.moved): each of those takes the pair's share. A pair
 * neither of whose triangles moved since was tested where it is now, and kept apart: a round tests the corners
 * the round before shortened, and the rounds end with one that shortens nothing. The share is the pair's,
 * whichever triangle comes first (the crossing tests and the bisection take the two alike), so each limit is
 * what a search from its own triangle finds. */
static void lvp__visit_later_pair(void *context, const lvp__bvh_triangle *a, const lvp__bvh_triangle *b)
{
	const lvp__contact_pass *pass = context;
	lvp__contact *contact = &pass->binding->contact;
	/* A corner that changed is one this round tests (the changed corners are among contact.moved). */
	if (!(lvp__any_marked(pass->changed, a->vertices) || lvp__any_marked(pass->changed, b->vertices)) ||
	    lvp__share_corner(a->vertices, b->vertices))
		return;
	const float *const corners[3] = {a->corners[0], a->corners[1], a->corners[2]};
	lvp__triangle_search search = lvp__search_of(pass, a->vertices, corners);
	lvp__visit_candidate(&search, b);
	if (lvp__any_marked(contact->moved, a->vertices))
		contact->limit[a->source] = fminf(contact->limit[a->source], search.limit);
	if (lvp__any_marked(contact->moved, b->vertices))
		contact->limit[b->source] = fminf(contact->limit[b->source], search.limit);
}

/* A later round's triangles that the hierarchy leaves out (no area at rest) with a corner to test, each
 * against the tree (each writes its own limit only). */
static void lvp__search_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__contact_pass *pass = context;
	lvp_binding *binding = pass->binding;
	lvp__contact *contact = &binding->contact;
	for (int32_t t = begin; t < end; ++t) {
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		if (contact->leaf_of[t] >= 0 || !lvp__any_marked(contact->moved, corners))
			continue;
		const float *const moved[3] = {binding->step.positions + 3 * (int64_t)corners[0],
		                               binding->step.positions + 3 * (int64_t)corners[1],
		                               binding->step.positions + 3 * (int64_t)corners[2]};
		lvp__triangle_search search = lvp__search_of(pass, corners, moved);
		lvp__bvh_overlapping(&contact->bvh, search.lo, search.hi, lvp__visit_candidate, &search);
		contact->limit[t] = search.limit;
	}
}

/* contact.leaf_of: the leaf that holds each triangle (-1 for those of no area, left out). */
static void lvp__find_leaves(lvp__contact *contact, int32_t triangle_count)
{
	const lvp__bvh *bvh = &contact->bvh;
	for (int32_t t = 0; t < triangle_count; ++t)
		contact->leaf_of[t] = -1;
	for (int32_t index = 0; index < bvh->node_count; ++index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		for (int32_t i = node->index; node->count > 0 && i < node->index + node->count; ++i)
			contact->leaf_of[bvh->triangles[i].source] = index;
	}
}

/* contact.dynamic_nodes: the leaves holding a triangle with a dynamic corner and every node above
 * them, the last first. Only dynamic vertices move between the skinning and the correction (every
 * other vertex is its input), so refitting these nodes alone refits the whole tree. */
static void lvp__list_dynamic_nodes(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const lvp__mesh *mesh = &binding->mesh;
	const lvp__bvh *bvh = &contact->bvh;
	uint8_t *marks = contact->node_dynamic;
	memset(marks, 0, (size_t)bvh->node_count);
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
			for (int32_t node = contact->leaf_of[mesh->vertex_triangles[c]]; node >= 0 && !marks[node];
			     node = bvh->parents[node])
				marks[node] = 1;
	}
	int32_t count = 0;
	for (int32_t index = bvh->node_count - 1; index >= 0; --index)
		if (marks[index])
			contact->dynamic_nodes[count++] = index;
	contact->dynamic_node_count = count;
}

/* The work of refitting a node against a vertex's step (LVP__POOL_FOR): up to eight triangles' corners. */
#define LVP__REFIT_WORK 8

void lvp__contact_fit_skinning(lvp_binding *binding, const float *positions)
{
	lvp__bvh *bvh = &binding->contact.bvh;
	lvp__bvh_refit(bvh, positions, LVP__POOL_FOR(binding, (int64_t)bvh->node_count * LVP__REFIT_WORK));
	lvp__list_dynamic_nodes(binding);
}

/* contact.moved_nodes: per node of the hierarchy, whether a triangle under it has a corner marked in `marks`
 * (lvp__bvh_self_overlaps passes over pairs of nodes neither of which is marked). Walked up from the marked
 * corners' triangles, each node once: a later round marks the few corners the round before shortened, of a
 * body's hundreds of thousands of triangles. */
static void lvp__mark_nodes(lvp_binding *binding, const uint8_t *marks)
{
	lvp__contact *contact = &binding->contact;
	const lvp__mesh *mesh = &binding->mesh;
	uint8_t *marked = contact->moved_nodes;
	memset(marked, 0, (size_t)contact->bvh.node_count);
	for (int32_t k = 0; k < binding->vertex_count; ++k) {
		if (!marks[k])
			continue;
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
			for (int32_t node = contact->leaf_of[mesh->vertex_triangles[c]]; node >= 0 && !marked[node];
			     node = contact->bvh.parents[node])
				marked[node] = 1;
	}
}

/* The hierarchy fitted to `to` (the skinning, or the correction), from either. */
static void lvp__refit_dynamic(lvp_binding *binding, const float *to)
{
	lvp__contact *contact = &binding->contact;
	int32_t count = contact->dynamic_node_count;
	lvp__bvh_refit_nodes(&contact->bvh, to, contact->dynamic_nodes, count,
	                     LVP__POOL_FOR(binding, (int64_t)count * LVP__REFIT_WORK));
}

/* The hierarchy fitted to `to` where only the corners marked in contact.moved moved since it was last
 * fitted (a later round: the corners the round before shortened): the nodes above them (moved_nodes). */
static void lvp__refit_moved(lvp_binding *binding, const float *to)
{
	lvp__contact *contact = &binding->contact;
	lvp__mark_nodes(binding, contact->moved);
	int32_t count = 0;
	for (int32_t i = 0; i < contact->dynamic_node_count; ++i)
		if (contact->moved_nodes[contact->dynamic_nodes[i]])
			contact->refit_nodes[count++] = contact->dynamic_nodes[i];
	lvp__bvh_refit_nodes(&contact->bvh, to, contact->refit_nodes, count,
	                     LVP__POOL_FOR(binding, (int64_t)count * LVP__REFIT_WORK));
}

lvp_result lvp__contact_begin(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	lvp__contact *contact = &binding->contact;
	if (contact->bvh.nodes)
		return lvp_success;
	lvp_result result = lvp__bvh_build(&contact->bvh, binding->rest_positions, binding->mesh.triangles,
	                                   binding->triangle_count, r_diag);
	if (result)
		return result;
	bool ok = true;
	contact->moved_nodes = lvp__calloc((size_t)contact->bvh.node_count, 1, &ok);
	contact->node_dynamic = lvp__calloc((size_t)contact->bvh.node_count, 1, &ok);
	contact->dynamic_nodes = lvp__calloc((size_t)contact->bvh.node_count, sizeof(int32_t), &ok);
	contact->refit_nodes = lvp__calloc((size_t)contact->bvh.node_count, sizeof(int32_t), &ok);
	contact->leaf_of = lvp__calloc((size_t)binding->triangle_count, sizeof(int32_t), &ok);
	contact->limit = lvp__calloc((size_t)binding->triangle_count, sizeof(float), &ok);
	contact->shifted_limit = lvp__calloc((size_t)binding->triangle_count, sizeof(float), &ok);
	contact->pair_count = lvp__calloc((size_t)binding->triangle_count, sizeof(int32_t), &ok);
	contact->skinned_pair_count = lvp__calloc((size_t)binding->triangle_count, sizeof(int32_t), &ok);
	contact->moved = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->changed = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->settled = lvp__calloc((size_t)binding->vertex_count * 3, sizeof(float), &ok);
	contact->tested_scale = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->asked = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->asked_smoothed = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->shortened = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->pinned = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->scale = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->next_scale = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->clearance = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->clearance_reach = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->clearance_direction = lvp__calloc((size_t)binding->vertex_count * 3, sizeof(float), &ok);
	contact->fade = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->fade_scratch = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->faded = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->raise_patch = lvp__calloc((size_t)binding->vertex_count, sizeof(int32_t), &ok);
	contact->raise_below = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->raise_above = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->raise_middle = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	contact->raise_tested = lvp__calloc((size_t)binding->triangle_count, 1, &ok);
	contact->raise_patch_crossing = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	contact->share_roles = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	if (ok) {
		lvp__find_leaves(contact, binding->triangle_count);
		if ((result = lvp__flat_patches_begin(binding, r_diag)) == lvp_success &&
		    (result = lvp__clearance_begin(binding, r_diag)) == lvp_success)
			return lvp_success;
		lvp__contact_free(contact);
		return result;
	}
	lvp__contact_free(contact);
	return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "could not allocate the contact test of %d triangles.",
	                 (int)binding->triangle_count);
}

/* step.positions: each dynamic vertex at its share (contact.scale) of its offset in `corrected`. */
static void lvp__place_shortened(lvp_binding *binding, const float *positions, const float *corrected)
{
	const float *scale = binding->contact.scale;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		float *p = binding->step.positions + 3 * k;
		const float *skinned = positions + 3 * k, *full = corrected + 3 * k;
		for (int c = 0; c < 3; ++c)
			p[c] = skinned[c] + scale[k] * (full[c] - skinned[c]);
	}
}

/* Whether triangle t took part in the first round: it crosses after the correction, or crossed in the
 * skinning a triangle it was tested against. */
static inline bool lvp__in_first_round_contact(const lvp__contact *contact, int32_t t)
{
	return contact->limit[t] < 1.0f || contact->shifted_limit[t] < 1.0f || contact->pair_count[t] > 0 ||
	       contact->skinned_pair_count[t] > 0;
}

/* After a first round: the pairs crossing anew that are the skinning's own crossing moved
 * (shifted_limit) are left in every contact that has no other (a contact: the triangles that took part
 * in the round, joined by shared corners; a knee's crease, a fingertip on the palm), when over those
 * contacts the moved skin crosses no more pairs than the skinning does. The skinning's count is over
 * the pairs visited: every pair crossing after with a moved triangle is visited, not every pair
 * crossing in the skinning (its boxes after the correction may part), so it is at most its own. The
 * count is summed over the contacts, not held by each: moving an intersection changes which pairs it
 * passes through, one or two more at one crease and fewer at the next. A new contact at one knee no
 * longer has this check shorten the other knee's crease, where fold-over parted it. */
static void lvp__leave_skinned_crossings(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const lvp__mesh *mesh = &binding->mesh;
	/* Per vertex, the kind of contact it is a corner of, and a contact's corners (scratch of the
	 * smoothing of shares, which does not run during a round). */
	enum { LVP__NO_CONTACT, LVP__NEW_CONTACT, LVP__SKINNED_CONTACT };
	uint8_t *contact_of = contact->near_seen;
	int32_t *queue = contact->near;
	bool any_shifted = false;
	for (int32_t t = 0; t < binding->triangle_count && !any_shifted; ++t)
		any_shifted = contact->shifted_limit[t] < 1.0f;
	if (!any_shifted)
		return;
	memset(contact_of, LVP__NO_CONTACT, (size_t)binding->vertex_count);
	int64_t after = 0, skinned = 0;
	for (int32_t first = 0; first < binding->triangle_count; ++first) {
		int32_t seed = mesh->triangles[3 * (int64_t)first];
		if (contact_of[seed] != LVP__NO_CONTACT || !lvp__in_first_round_contact(contact, first))
			continue;
		/* The contact's corners, and its triangles' pairs, each triangle's counted at its first corner. */
		bool any_new = false;
		int64_t contact_after = 0, contact_skinned = 0;
		int32_t head = 0, tail = 0;
		contact_of[seed] = LVP__SKINNED_CONTACT;
		queue[tail++] = seed;
		while (head < tail) {
			int32_t k = queue[head++];
			for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
				int32_t t = mesh->vertex_triangles[c];
				if (!lvp__in_first_round_contact(contact, t))
					continue;
				const int32_t *corners = mesh->triangles + 3 * (int64_t)t;
				if (corners[0] == k) {
					any_new = any_new || contact->limit[t] < 1.0f;
					contact_after += contact->pair_count[t];
					contact_skinned += contact->skinned_pair_count[t];
				}
				for (int i = 0; i < 3; ++i)
					if (contact_of[corners[i]] == LVP__NO_CONTACT) {
						contact_of[corners[i]] = LVP__SKINNED_CONTACT;
						queue[tail++] = corners[i];
					}
			}
		}
		if (any_new) {
			for (int32_t q = 0; q < tail; ++q)
				contact_of[queue[q]] = LVP__NEW_CONTACT;
			continue;
		}
		after += contact_after;
		skinned += contact_skinned;
	}
	/* Where those contacts have no such pair, their shifted shares are 1 already. */
	if (after > skinned)
		return;
	for (int32_t t = 0; t < binding->triangle_count; ++t)
		if (contact_of[mesh->triangles[3 * (int64_t)t]] == LVP__SKINNED_CONTACT)
			contact->shifted_limit[t] = 1.0f;
}

/* Rounds of shortening (contact.scale, step.positions placed by it): the first tests every pair of
 * triangles one of which moved (`every_pair`), or the pairs with a corner in contact.changed, the
 * triangles around contact.moved taking their limits; each later one the pairs around the corners
 * the round before shortened. Returns whether it shortened any offset. */
static bool lvp__shorten_rounds(lvp_binding *binding, const lvp__contact_pass *pass, const float *corrected,
                                bool every_pair)
{
	lvp__contact *contact = &binding->contact;
	int32_t n = binding->vertex_count, f = binding->triangle_count;
	const uint8_t *pinned = contact->pinned;
	float *scale = contact->scale, *next = contact->next_scale;
	bool shortened = false;
	for (int round = 0; round < LVP__CONTACT_ROUNDS; ++round) {
		/* A first round follows the restore, which moved every dynamic vertex; a later one follows a
		 * shortening, which moved only the corners it marked (a share only falls: smoothing lowers
		 * shares, and a vertex placed again at an unchanged share lands where it was). */
		if (round == 0 && every_pair)
			lvp__refit_dynamic(binding, binding->step.positions);
		else
			lvp__refit_moved(binding, binding->step.positions);
		if (round == 0 && every_pair) {
			for (int32_t t = 0; t < f; ++t) {
				contact->limit[t] = contact->shifted_limit[t] = 1.0f;
				contact->pair_count[t] = contact->skinned_pair_count[t] = 0;
			}
			lvp__mark_nodes(binding, contact->moved);
			/* Which of the subtrees the correction moves (the only ones searched) are flat patches. */
			lvp__fit_flat_patches(contact,
			                      LVP__POOL_FOR(binding, (int64_t)contact->dynamic_node_count * LVP__REFIT_WORK));
			lvp__bvh_self_overlaps(&contact->bvh, contact->moved_nodes, contact->flat, LVP__POOL_FOR(binding, f),
			                       lvp__visit_pair, (void *)pass);
			/* Pairs along the skinning's own crossing are left where they are all a contact has and its
			 * count holds (the top of this file); else they are kept apart as any. */
			lvp__leave_skinned_crossings(binding);
			for (int32_t t = 0; t < f; ++t)
				contact->limit[t] = fminf(contact->limit[t], contact->shifted_limit[t]);
		} else {
			/* The round after a shortening tests the pairs of the corners it moved; a first round of
			 * tests again (after the shares were smoothed), those the caller marked changed. */
			lvp__contact_pass later = *pass;
			later.changed = round == 0 ? contact->changed : contact->moved;
			for (int32_t t = 0; t < f; ++t)
				contact->limit[t] = 1.0f;
			lvp__mark_nodes(binding, later.changed);
			lvp__bvh_self_overlaps(&contact->bvh, contact->moved_nodes, NULL, LVP__POOL_FOR(binding, f),
			                       lvp__visit_later_pair, &later);
			lvp__parallel_for(LVP__POOL_FOR(binding, f), lvp__search_loop, &later, f, LVP__GRAIN);
		}
		/* Each corner of a crossing keeps the square of the share the pair allows: a pair that barely
		 * crosses is barely shortened (the result follows the pose without a jump), a deeper one a
		 * little more than it needs, so that rounding does not bring it back. The last round keeps
		 * nothing: a pair still crossing then is skinning's own, or meets a vertex fold-over pinned on
		 * its contact surface (lvp__pin_held), which keeps its place. */
		bool any = false, last = round + 1 == LVP__CONTACT_ROUNDS;
		if (round == 0 && every_pair) {
			int32_t crossing = 0;
			for (int32_t t = 0; t < f; ++t)
				crossing += contact->limit[t] < 1.0f;
			contact->crossed = crossing;
		}
		memset(contact->moved, 0, (size_t)n);
		for (int32_t t = 0; t < f; ++t) {
			if (!(contact->limit[t] < 1.0f))
				continue;
			float keep = last ? 0.0f : contact->limit[t] * contact->limit[t];
			for (int i = 0; i < 3; ++i) {
				int32_t k = binding->mesh.triangles[3 * (int64_t)t + i];
				if (pinned[k])
					continue;
				next[k] = fminf(next[k], keep * scale[k]);
				contact->asked[k] = fminf(contact->asked[k], next[k]);
				contact->moved[k] = 1;
				any = true;
			}
		}
		if (!any)
			break;
		memcpy(scale, next, sizeof(float) * (size_t)n);
		lvp__place_shortened(binding, pass->positions, corrected);
		shortened = true;
	}
	return shortened;
}

/* With the tree fitted to the pass's positions (the skinning, or the correction as it stands): stops at
 * the first triangle the searched one crosses there (limit 0), touching within rounding included. */
static bool lvp__visit_crossing_at(void *context, const lvp__bvh_triangle *other)
{
	lvp__triangle_search *search = context;
	if (!lvp__may_cross(search, other))
		return false;
	lvp__vec3 corners[3];
	for (int i = 0; i < 3; ++i)
		corners[i] = lvp__load(other->corners[i]);
	if (lvp__triangles_cross(search->skinned, corners) == LVP__APART)
		return false;
	search->limit = 0.0f;
	return true;
}

/* Whether the triangle with these corners crosses skin (touching within rounding included) where the
 * pass's positions put every triangle, the tree fitted there. */
static bool lvp__crosses_at(const lvp__contact_pass *pass, const int32_t corners[3])
{
	const float *at = pass->positions;
	const float *const corner_at[3] = {at + 3 * (int64_t)corners[0], at + 3 * (int64_t)corners[1],
	                                   at + 3 * (int64_t)corners[2]};
	lvp__triangle_search search = lvp__search_of(pass, corners, corner_at);
	lvp__bvh_overlapping(&pass->binding->contact.bvh, search.lo, search.hi, lvp__visit_crossing_at, &search);
	return search.limit < 1.0f;
}

/* Whether vertex k has an edge neighbour marked in `marks`. */
static bool lvp__beside_marked(const lvp_binding *binding, const uint8_t *marks, int32_t k)
{
	const lvp__mesh *mesh = &binding->mesh;
	for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
		if (lvp__any_marked(marks, mesh->triangles + 3 * (int64_t)mesh->vertex_triangles[c]))
			return true;
	return false;
}

/* Marks (1) every dynamic vertex of `patch` that shares a triangle with a marked one, and so on out to the
 * whole patch (its vertices joined by edges), a ring or more a pass (patches are a few rings across). */
static void lvp__grow_marked_patches(const lvp_binding *binding, const uint8_t *patch, uint8_t *marks)
{
	for (bool grew = true; grew;) {
		grew = false;
		for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
			int32_t k = binding->dynamic.vertices[v];
			if (patch[k] && !marks[k] && lvp__beside_marked(binding, marks, k)) {
				marks[k] = 1;
				grew = true;
			}
		}
	}
}

/* Pins the gaps of the pinned patches: the sets of unpinned vertices joined by edges each of which has a
 * pinned neighbour (no vertex of the gap lies a ring away from the patch) and none of which is beside an
 * unpinned vertex out of the gap. Fold-over did not press such a vertex onto its plane (its relaxation moved
 * it), so it is not held, yet it lies among skin kept on its contact surface: shortened
 * alone, it went down to where the skinning put it, inside the other skin (along the crease behind a
 * voxel body's knee bent to 150 degrees, a gap of 11 vertices: 28 more crossing pairs, 11 more creases). */
static void lvp__pin_gaps(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const lvp__mesh *mesh = &binding->mesh;
	uint8_t *pinned = contact->pinned, *seen = contact->near_seen;
	int32_t *gap = contact->near;
	memset(seen, 0, (size_t)binding->vertex_count);
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t seed = binding->dynamic.vertices[v];
		if (pinned[seed] || seen[seed] || !lvp__beside_marked(binding, pinned, seed))
			continue;
		/* The rim of unpinned vertices beside the patches that the seed's joins; it is a gap while no
		 * member has a neighbour off the rim (unpinned, no pinned neighbour) or is static. */
		bool closed = true;
		int32_t head = 0, tail = 0;
		seen[seed] = 1;
		gap[tail++] = seed;
		while (head < tail) {
			int32_t k = gap[head++];
			closed = closed && binding->frame_map.vertex_dynamic[k];
			for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
				for (int i = 0; i < 3; ++i) {
					int32_t corner = mesh->triangles[3 * (int64_t)mesh->vertex_triangles[c] + i];
					if (pinned[corner] || seen[corner])
						continue;
					if (!lvp__beside_marked(binding, pinned, corner)) {
						closed = false;
						continue;
					}
					seen[corner] = 1;
					gap[tail++] = corner;
				}
		}
		for (int32_t i = 0; closed && i < tail; ++i)
			pinned[gap[i]] = 1;
	}
}

/* contact.pinned: the patches of vertices fold-over holds on a contact surface (fold.held; a patch:
 * held vertices joined by edges) where fold-over parted a crossing of the skinning: some triangle
 * crosses skin in the skinning (touching within rounding counts) and no longer does where the
 * correction put it. Shortening the offsets of such a patch would bring that crossing back, so it keeps
 * its place. The other patches are shortened as any: where the skinning crosses nothing yet (a finger
 * half closed), skin put on the contact plane can meet skin coming from the other side, and only moving
 * it back keeps the two apart; where the press left the skinning's crossing as it was, keeping the
 * patch in place kept the crossings it added around it (the game horse falling, two pressed sheets: 16
 * pairs where the skinning has 4). The gaps of a pinned patch are pinned with it (lvp__pin_gaps). */
static void lvp__pin_held(lvp_binding *binding, const float *positions)
{
	lvp__contact *contact = &binding->contact;
	const uint8_t *held = binding->fold.held;
	int32_t n = binding->vertex_count, f = binding->triangle_count;
	memset(contact->pinned, 0, (size_t)n);
	bool any = false;
	for (int32_t v = 0; v < binding->dynamic.vertex_count && !any; ++v)
		any = held[binding->dynamic.vertices[v]];
	if (!any)
		return;
	/* The held triangles crossing in the skinning, marked in contact.raise_tested (scratch until a raise
	 * sets it), then those of them that the correction parted. */
	uint8_t *crossed_skinned = contact->raise_tested;
	lvp__refit_dynamic(binding, positions);
	lvp__contact_pass at_skinning = {binding, positions, NULL};
	for (int32_t t = 0; t < f; ++t) {
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		crossed_skinned[t] = lvp__any_marked(held, corners) && lvp__crosses_at(&at_skinning, corners);
	}
	lvp__refit_dynamic(binding, binding->step.positions);
	lvp__contact_pass at_correction = {binding, binding->step.positions, NULL};
	for (int32_t t = 0; t < f; ++t) {
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		if (!crossed_skinned[t] || lvp__crosses_at(&at_correction, corners))
			continue;
		for (int i = 0; i < 3; ++i)
			contact->pinned[corners[i]] = held[corners[i]];
	}
	lvp__grow_marked_patches(binding, held, contact->pinned);
	lvp__pin_gaps(binding);
}

/* Numbers the patches of the vertices marked in contact.moved (raise_patch: joined by edges), from 0;
 * returns how many there are. */
static int32_t lvp__number_raised_patches(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const lvp__mesh *mesh = &binding->mesh;
	const uint8_t *raised = contact->moved;
	int32_t *patch = contact->raise_patch, *queue = contact->near, count = 0;
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		patch[k] = -1;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t seed = binding->dynamic.vertices[v];
		if (!raised[seed] || patch[seed] >= 0)
			continue;
		int32_t head = 0, tail = 0;
		patch[seed] = count;
		queue[tail++] = seed;
		while (head < tail) {
			int32_t k = queue[head++];
			for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
				for (int i = 0; i < 3; ++i) {
					int32_t corner = mesh->triangles[3 * (int64_t)mesh->vertex_triangles[c] + i];
					if (raised[corner] && patch[corner] < 0) {
						patch[corner] = count;
						queue[tail++] = corner;
					}
				}
		}
		++count;
	}
	return count;
}

/* contact.raise_tested, per triangle, in a raise of pinned patches (lvp__raise_pinned_crossing): */
enum {
	LVP__RAISE_UNTESTED = 0, /* no corner raised, or not crossing with its patch lowered */
	LVP__RAISE_PARTED,       /* crossing with its patch lowered, not raised whole: the bisection's test */
	LVP__RAISE_CROSSING,     /* crossing with its patch raised whole: no height of the patch parts it */
};

/* The shares (contact.scale) of the raised patches (contact.moved) at each one's height: `up` (per patch) of
 * the way from the lowered shares back to 1. */
static void lvp__set_raised_shares(lvp_binding *binding, const float *lowered, const float *up)
{
	lvp__contact *contact = &binding->contact;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		if (contact->moved[k])
			contact->scale[k] = lowered[k] + up[contact->raise_patch[k]] * (1.0f - lowered[k]);
	}
}

/* The raised patches placed at each one's height (lvp__set_raised_shares), the tree fitted there. */
static void lvp__place_raised(lvp_binding *binding, const lvp__contact_pass *pass, const float *lowered,
                              const float *up)
{
	lvp__set_raised_shares(binding, lowered, up);
	lvp__place_shortened(binding, pass->positions, binding->fold.saved);
	lvp__refit_moved(binding, binding->step.positions);
}

/* Marks in contact.raise_patch_crossing the raised patches (contact.moved) one of whose triangles crosses
 * skin where the correction puts it now, of those marked `which` in contact.raise_tested, or (`which` < 0)
 * of all but those marked LVP__RAISE_CROSSING. Patches at `height` 1 (when given) are not tested. */
static void lvp__find_raised_crossing(lvp_binding *binding, const lvp__contact_pass *at_correction, int which,
                                      const float *height, int32_t patch_count)
{
	lvp__contact *contact = &binding->contact;
	uint8_t *crossing = contact->raise_patch_crossing;
	for (int32_t p = 0; p < patch_count; ++p)
		crossing[p] = height && height[p] == 1.0f; /* known: the test below skips them */
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		int tested = contact->raise_tested[t];
		if (which >= 0 ? tested != which : tested == LVP__RAISE_CROSSING)
			continue;
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		bool open = false; /* a raised corner whose patch is not yet known to cross */
		for (int i = 0; i < 3; ++i)
			open = open || (contact->moved[corners[i]] && !crossing[contact->raise_patch[corners[i]]]);
		if (!open || !lvp__crosses_at(at_correction, corners))
			continue;
		for (int i = 0; i < 3; ++i)
			if (contact->moved[corners[i]])
				crossing[contact->raise_patch[corners[i]]] = 1;
	}
}

/* A pinned patch comes down with the skin around it when the shares are smoothed: where the crossing
 * test shortened that skin (it would meet a third skin), a patch left in place stood out of it, a shard
 * as tall as the offsets. Brought down, it may bring back the crossing fold-over undid: every patch one of
 * whose lowered triangles then crosses skin goes back up, no further than parts those triangles (its
 * shares the least way back up to 1, bisected), unless another of its triangles then crosses, when it
 * goes up whole as before. A triangle that crosses with its patch raised whole (between a raised vertex
 * and a neighbour the rounds shortened to nothing) is parted at no height: raising the patch whole for it
 * stood the patch up above its neighbours, a spike. Marks the vertices raised in contact.moved (which the
 * caller sets afterwards) and returns whether it raised any; the positions are left where its last test
 * placed them (the caller places them again by the shares). */
static bool lvp__raise_pinned_crossing(lvp_binding *binding, const lvp__contact_pass *pass)
{
	lvp__contact *contact = &binding->contact;
	const uint8_t *pinned = contact->pinned;
	uint8_t *raised = contact->moved, *tested = contact->raise_tested, *crossing = contact->raise_patch_crossing;
	float *scale = contact->scale, *lowered = contact->next_scale; /* the smoothed shares, as the caller left them */
	const float *work = binding->step.positions;
	const int32_t *dynamic = binding->dynamic.vertices, dynamic_count = binding->dynamic.vertex_count;
	bool down = false;
	for (int32_t v = 0; v < dynamic_count && !down; ++v)
		down = pinned[dynamic[v]] && scale[dynamic[v]] < 1.0f;
	if (!down)
		return false;
	memset(raised, 0, (size_t)binding->vertex_count);
	lvp__refit_dynamic(binding, work);
	/* Searched where the correction put it, against the tree fitted there. */
	lvp__contact_pass at_correction = *pass;
	at_correction.positions = work;
	bool any = false;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		bool lowered_here = false;
		for (int i = 0; i < 3; ++i)
			lowered_here = lowered_here || (pinned[corners[i]] && scale[corners[i]] < 1.0f);
		tested[t] = lowered_here && lvp__crosses_at(&at_correction, corners) ? LVP__RAISE_PARTED : LVP__RAISE_UNTESTED;
		if (!tested[t])
			continue;
		for (int i = 0; i < 3; ++i)
			if (pinned[corners[i]]) {
				raised[corners[i]] = 1;
				any = true;
			}
	}
	if (!any)
		return false;
	lvp__grow_marked_patches(binding, pinned, raised);
	int32_t patch_count = lvp__number_raised_patches(binding);
	float *below = contact->raise_below, *above = contact->raise_above;
	for (int32_t p = 0; p < patch_count; ++p) {
		below[p] = 0.0f;
		above[p] = 1.0f;
	}
	/* Raised whole: those of the triangles found crossing that cross even so. */
	lvp__place_raised(binding, pass, lowered, above);
	for (int32_t t = 0; t < binding->triangle_count; ++t)
		if (tested[t] && lvp__crosses_at(&at_correction, binding->mesh.triangles + 3 * (int64_t)t))
			tested[t] = LVP__RAISE_CROSSING;
	/* The least height that parts the triangles found crossing lowered (below crosses, above parts). */
	for (int step = 0; step < LVP__RAISE_STEPS; ++step) {
		for (int32_t p = 0; p < patch_count; ++p)
			contact->raise_middle[p] = 0.5f * (below[p] + above[p]);
		lvp__place_raised(binding, pass, lowered, contact->raise_middle);
		lvp__find_raised_crossing(binding, &at_correction, LVP__RAISE_PARTED, NULL, patch_count);
		for (int32_t p = 0; p < patch_count; ++p) {
			if (crossing[p])
				below[p] = contact->raise_middle[p];
			else
				above[p] = contact->raise_middle[p];
		}
	}
	/* There, a patch whose other triangles cross goes up whole (those already up are not tested). */
	lvp__place_raised(binding, pass, lowered, above);
	lvp__find_raised_crossing(binding, &at_correction, -1, above, patch_count);
	for (int32_t p = 0; p < patch_count; ++p)
		if (crossing[p])
			above[p] = 1.0f;
	lvp__set_raised_shares(binding, lowered, above);
	for (int32_t v = 0; v < dynamic_count; ++v)
		lowered[dynamic[v]] = scale[dynamic[v]]; /* next_scale as scale, as the caller left them */
	return true;
}

/* After a raise that left a patch part of the way down: the skin beside the pinned patches comes down
 * with them (their shares read, and kept). A smoothing of shares does not read a pinned patch's (its
 * patch takes the slope from the skin around it, and was to go back up whole), so the skin on its other
 * side kept its offsets beside it: a step at the patch's rim (the game horse's walk between the hind
 * legs, a vertex 1.0 mean edges out among pinned neighbours at 0.25-0.36). */
static void lvp__lower_beside_pinned(lvp_binding *binding)
{
	lvp__contact *contact = &binding->contact;
	const int32_t *dynamic = binding->dynamic.vertices, dynamic_count = binding->dynamic.vertex_count;
	bool part_way = false;
	for (int32_t v = 0; v < dynamic_count && !part_way; ++v)
		part_way = contact->moved[dynamic[v]] && contact->scale[dynamic[v]] < 1.0f;
	if (!part_way)
		return;
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		contact->share_roles[k] = contact->pinned[k] ? LVP__SHARE_FIXED : LVP__SHARE_SMOOTHED;
	lvp__smooth_shares(binding, contact->scale, contact->next_scale, contact->share_roles, true);
	memcpy(contact->next_scale, contact->scale, sizeof(float) * (size_t)binding->vertex_count);
}

int32_t lvp__keep_skin_apart(lvp_binding *binding, const float *positions, bool first, bool toward_last_check)
{
	lvp__contact *contact = &binding->contact;
	int32_t n = binding->vertex_count;
	const int32_t *dynamic = binding->dynamic.vertices, dynamic_count = binding->dynamic.vertex_count;
	const uint8_t *pinned = contact->pinned;
	float *corrected = binding->fold.saved, *scale = contact->scale, *next = contact->next_scale;
	memcpy(corrected, binding->step.positions, sizeof(float) * 3 * (size_t)n);
	memset(contact->moved, 0, (size_t)n);
	if (first) {
		memset(contact->shortened, 0, (size_t)n);
		lvp__pin_held(binding, positions);
	}
	contact->crossed = 0;
	/* Shortened toward where the check before left the skin (when it left it apart), not toward the
	 * skinning, after a restore through the map (fold-over's): that restore moves skin off the line from
	 * the skinning through where the check before left it, and growing it into contact there, it had the
	 * skin shortened back past where that check found it apart, sideways, the volume going on to the next
	 * skin out to be shortened in turn at the check after (a decimated body's knees at 150 degrees). A
	 * restore along the offsets keeps each vertex on that line, where the two differ only in how far
	 * along it each share reaches. */
	const float *base = toward_last_check && contact->settled_apart ? contact->settled : positions;
	/* Every vertex, not only the dynamic ones: a crossing's corners and the rim's neighbours may be
	 * static, and what an earlier frame left of them shortened this one (a frame played to differed
	 * from the same frame opened at). */
	for (int32_t k = 0; k < n; ++k)
		scale[k] = next[k] = contact->asked[k] = 1.0f;
	for (int32_t v = 0; v < dynamic_count; ++v) {
		int32_t k = dynamic[v];
		contact->moved[k] = memcmp(corrected + 3 * k, base + 3 * k, sizeof(float) * 3) != 0;
	}
	lvp__contact_pass pass = {binding, base, NULL};
	/* The shares smoothed over the same rings whatever the number of rounds, none rising above what
	 * its pairs allowed (a floor raised crosses again, and would be shortened again vertex by vertex):
	 * a patch shortened as a dip whose neighbours keep at most the slope more, not single vertices
	 * held back from their neighbours' surface. Shortening one side of a pair more than the other can
	 * make it cross, so the smoothed patch is tested again, and what that shortens smoothed in turn.
	 * Each test smooths the shares its pairs asked for (contact.asked), not the smoothed ones again:
	 * smoothing a dip's rim once more widens it by the rings a smoothing reaches, so that the skin
	 * shortened grew with every test. */
	bool shortening = lvp__shorten_rounds(binding, &pass, corrected, true);
	for (int retest = 0; shortening && retest < LVP__CONTACT_RETESTS; ++retest) {
		/* The corners the rounds moved and did not test (their last round shortened), and the shares
		 * the others were tested at. */
		memcpy(contact->changed, contact->moved, (size_t)n);
		memcpy(contact->tested_scale, scale, sizeof(float) * (size_t)n);
		float *smoothed = contact->asked_smoothed;
		memcpy(smoothed, contact->asked, sizeof(float) * (size_t)n);
		lvp__smooth_shares(binding, smoothed, next, pinned, true); /* pinned: LVP__SHARE_KEPT (1) or not (0) */
		for (int32_t k = 0; k < n; ++k)
			scale[k] = fminf(scale[k], smoothed[k]);
		memcpy(next, scale, sizeof(float) * (size_t)n);
		lvp__place_shortened(binding, base, corrected);
		bool raised = lvp__raise_pinned_crossing(binding, &pass);
		if (raised) {
			lvp__lower_beside_pinned(binding);
			lvp__place_shortened(binding, base, corrected);
		}
		/* What the next round tests: the corners shortened, and those raised back (contact.moved); the
		 * pairs it tests, those with a corner the smoothing or the raising moved (contact.changed). */
		for (int32_t v = 0; v < dynamic_count; ++v) {
			int32_t k = dynamic[v];
			bool raised_here = raised && contact->moved[k];
			contact->changed[k] = contact->changed[k] || raised_here || scale[k] != contact->tested_scale[k];
			contact->moved[k] = scale[k] < 1.0f || raised_here;
		}
		shortening = lvp__shorten_rounds(binding, &pass, corrected, false);
	}
	/* The rounds ended with one that shortened nothing: no pair it tested is one to shorten where the
	 * vertices now are, nor any it did not test (no corner of it moved since a round found it so), and a
	 * check of these positions would shorten nothing. */
	contact->settled_apart = !shortening;
	if (contact->settled_apart)
		memcpy(contact->settled, binding->step.positions, sizeof(float) * 3 * (size_t)n);
	int32_t shortened = 0;
	for (int32_t v = 0; v < dynamic_count; ++v) {
		int32_t k = dynamic[v];
		if (scale[k] < 1.0f) {
			contact->shortened[k] = 1;
			++shortened;
		}
	}
	return shortened;
}

void lvp__fade_map_where_shortened(lvp_binding *binding)
{
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		binding->frame_map.gamma[k] *= binding->contact.scale[k];
	}
}

void lvp__kept_apart_counts(const lvp_binding *binding, bool faded, int32_t *r_shortened, int32_t *r_kept_apart)
{
	const lvp__contact *contact = &binding->contact;
	int32_t shortened = 0, kept_apart = 0;
	for (int32_t v = 0; v < binding->dynamic.vertex_count; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		shortened += contact->shortened[k];
		kept_apart += contact->shortened[k] || (faded && contact->faded[k]);
	}
	*r_shortened = shortened;
	*r_kept_apart = kept_apart;
}

bool lvp__still_where_kept_apart(const lvp_binding *binding)
{
	const lvp__contact *contact = &binding->contact;
	return contact->settled_apart &&
	       memcmp(contact->settled, binding->step.positions, sizeof(float) * 3 * (size_t)binding->vertex_count) == 0;
}

void lvp__contact_free(lvp__contact *contact)
{
	lvp__bvh_free(&contact->bvh);
	free(contact->limit);
	free(contact->shifted_limit);
	free(contact->pair_count);
	free(contact->skinned_pair_count);
	free(contact->moved_nodes);
	free(contact->node_dynamic);
	free(contact->dynamic_nodes);
	free(contact->refit_nodes);
	free(contact->leaf_of);
	free(contact->moved);
	free(contact->changed);
	free(contact->settled);
	free(contact->tested_scale);
	free(contact->asked);
	free(contact->asked_smoothed);
	free(contact->shortened);
	free(contact->pinned);
	free(contact->raise_patch);
	free(contact->raise_below);
	free(contact->raise_above);
	free(contact->raise_middle);
	free(contact->raise_tested);
	free(contact->raise_patch_crossing);
	free(contact->share_roles);
	free(contact->scale);
	free(contact->next_scale);
	free(contact->clearance);
	free(contact->clearance_reach);
	free(contact->clearance_direction);
	free(contact->sheets);
	free(contact->fade);
	free(contact->fade_scratch);
	free(contact->faded);
	free(contact->reader_offsets);
	free(contact->readers);
	free(contact->near);
	free(contact->near_seen);
	free(contact->connected);
	free(contact->cones);
	free(contact->flat);
	free(contact->group_offsets);
	free(contact->group_vertices);
	memset(contact, 0, sizeof(*contact));
}
