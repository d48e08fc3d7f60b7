/*
 * bvh.h - a bounding volume hierarchy over the triangles of a mesh (internal, not part of the API), for the
 * exact visibility test of the automatic weights (paper 5.1: does a straight segment cross the surface?)
 * and for keeping skin apart (contact.c: which triangles may touch which, refitted to each pose;
 * clearance.c: what skin lies in front of a vertex).
 *
 * ALGORITHM: top-down binned SAH (16 bins on each axis) over axis-aligned boxes, leaves of at most 8
 * triangles; below depth 40, or when the centroids coincide, splits at the object median instead, which
 * bounds the depth (and the fixed traversal stack) whatever the input. Node boxes are padded slightly so
 * that the float box test never culls what the double triangle test would hit.
 * MEMORY: about 2F nodes of 36 bytes (with the parent links) and F triangles of 72 bytes (a copy of the
 * corners in leaf order, for locality), plus 40F bytes during the build.
 * PERFORMANCE: build O(F log F); a segment query visits O(log F) nodes on ordinary meshes; a refit O(F);
 * the tree against itself about O(F) pairs of nodes where the surface does not fold onto itself.
 */
#ifndef LVP_BVH_H
#define LVP_BVH_H

#include "lvp_internal.h"
#include "threads.h"

#include <stdint.h>

typedef struct lvp__bvh_node {
	float lo[3], hi[3];
	int32_t index; /* leaf: first entry in lvp__bvh.triangles; inner: left child (the right one follows it) */
	int32_t count; /* leaf: its number of triangles (> 0); inner: 0 */
} lvp__bvh_node;

typedef struct lvp__bvh_triangle {
	float corners[3][3];
	float lo[3], hi[3]; /* the corners' box */
	int32_t vertices[3]; /* the mesh's vertex indices, to skip the triangles around a query's start */
	int32_t source;      /* the triangle's index in the mesh */
} lvp__bvh_triangle;

typedef struct lvp__bvh {
	lvp__bvh_node *nodes;
	int32_t *parents; /* per node, -1 for the root */
	lvp__bvh_triangle *triangles;
	int32_t node_count;
	int32_t triangle_count; /* triangles with a non-zero area; the others can never be hit */
} lvp__bvh;

/* Builds the hierarchy over a validated mesh (indices in range, finite positions). On failure (only
 * lvp_error_out_of_memory) *r_bvh is zeroed and nothing needs freeing. */
lvp_result lvp__bvh_build(lvp__bvh *r_bvh, const float *positions, const int32_t *triangles, int32_t triangle_count,
                          lvp_diagnostic *r_diag);

void lvp__bvh_free(lvp__bvh *bvh);

/* Epsilon on the barycentric coordinates: a segment through an edge or a vertex hits every triangle
 * around it, so no path slips between two triangles. */
#define LVP__BVH_EDGE_EPSILON 1e-9

/* Whether the segment from + t (to - from), t in [t_min, t_max], crosses a triangle that does not have
 * skip_vertex as a corner (pass -1 to skip none). Triangles parallel to the segment are never hit.
 * io_hint (may be NULL): a subtree searched first (a node index, or -1), and where the subtree around the
 * blocking triangle is stored on a hit, for the next, nearby query; the answer does not depend on it,
 * only the time does. */
bool lvp__bvh_segment_hits(const lvp__bvh *bvh, lvp__vec3 from, lvp__vec3 to, double t_min, double t_max,
                           int32_t skip_vertex, int32_t *io_hint);

/* Moves the triangles to `positions` (indexed like the mesh the hierarchy was built over) and
 * recomputes every node's box from its children's, keeping the tree: after a deformation that keeps
 * neighbours near each other (skinning), the boxes grow where the skin bends but stay valid, and
 * queries stay exact; O(F), the leaves on the pool's threads (NULL: this one). */
void lvp__bvh_refit(lvp__bvh *bvh, const float *positions, lvp__pool *pool);

/* The refit of the listed nodes alone (`nodes`: indices from the last to the first, each listed
 * node's parent listed too): their leaves' triangles moved to `positions`, then their boxes, the
 * leaves on the pool's threads (NULL: this one). Gives what lvp__bvh_refit gives when no triangle
 * outside the listed leaves has a corner that moved since the tree was last fitted; O(count). */
void lvp__bvh_refit_nodes(lvp__bvh *bvh, const float *positions, const int32_t *nodes, int32_t count, lvp__pool *pool);

/* Calls visit(context, triangle) for every triangle whose box may overlap [lo, hi] (a superset:
 * padded boxes), until visit returns true. The box is read at every node: a visit may narrow it
 * (lo and hi pointing into its context), and the rest of the search looks only there. */
typedef bool (*lvp__bvh_visit)(void *context, const lvp__bvh_triangle *triangle);
void lvp__bvh_overlapping(const lvp__bvh *bvh, const float lo[3], const float hi[3], lvp__bvh_visit visit,
                          void *context);

/* Calls visit(context, triangle) for every triangle under the nodes whose (padded) boxes may_hold
 * accepts, until visit returns true: a search by any shape the caller can test a box against (a ball,
 * which a visit may shrink), going down only where it may find something. */
typedef bool (*lvp__bvh_box_test)(void *context, const float lo[3], const float hi[3]);
void lvp__bvh_search(const lvp__bvh *bvh, lvp__bvh_box_test may_hold, lvp__bvh_visit visit, void *context);

/* Calls visit(context, a, b) once for every pair of different triangles whose boxes overlap, one of
 * them under a marked node when `marked` is not NULL, and not both under one node marked in `skipped`
 * (when not NULL: subtrees whose triangles the caller knows cannot meet each other), by a traversal of
 * the tree against itself, on the pool's threads (NULL: this one) in phases whose concurrent calls never
 * share a triangle: a visit may write what belongs to either of its two triangles, nothing else. */
typedef void (*lvp__bvh_visit_pair)(void *context, const lvp__bvh_triangle *a, const lvp__bvh_triangle *b);
void lvp__bvh_self_overlaps(const lvp__bvh *bvh, const uint8_t *marked, const uint8_t *skipped, lvp__pool *pool,
                            lvp__bvh_visit_pair visit, void *context);

/* The segment-triangle test the queries use (Moller-Trumbore in double), exposed for the tests' brute
 * force. Returns true and the parameter in *r_t when it crosses inside [t_min, t_max]. */
static inline bool lvp__segment_triangle(double *r_t, lvp__vec3 from, lvp__vec3 direction, const float corners[3][3],
                                         double t_min, double t_max)
{
	lvp__vec3 p0 = lvp__load(corners[0]);
	lvp__vec3 e1 = lvp__sub(lvp__load(corners[1]), p0), e2 = lvp__sub(lvp__load(corners[2]), p0);
	lvp__vec3 pv = lvp__cross(direction, e2);
	double det = lvp__dot(e1, pv);
	if (det == 0.0 || !isfinite(det))
		return false;
	double inv = 1.0 / det;
	lvp__vec3 tv = lvp__sub(from, p0);
	double u = lvp__dot(tv, pv) * inv;
	if (u < -LVP__BVH_EDGE_EPSILON || u > 1.0 + LVP__BVH_EDGE_EPSILON)
		return false;
	lvp__vec3 qv = lvp__cross(tv, e1);
	double v = lvp__dot(direction, qv) * inv;
	if (v < -LVP__BVH_EDGE_EPSILON || u + v > 1.0 + LVP__BVH_EDGE_EPSILON)
		return false;
	double t = lvp__dot(e2, qv) * inv;
	if (!(t >= t_min && t <= t_max))
		return false;
	*r_t = t;
	return true;
}

#endif /* LVP_BVH_H */
