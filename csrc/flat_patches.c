/*
 * flat_patches.c - which subtrees of the contact hierarchy need no test of their triangles against each other
 * (lvp.h, CONTACT; contact.c). The crossing test looks for pairs of triangles that cross after the
 * correction; most pairs whose boxes overlap are neighbours on one smooth stretch of skin, and the traversal
 * of the hierarchy against itself spends most of its time on them. A connected patch of triangles whose
 * normals all lie within less than 90 degrees of one axis is a height field over the plane across that axis
 * (no triangle turns its back to it): two of its triangles cannot cross, so a subtree whose triangles form
 * such a patch is skipped as a whole (self-collision culling by normal cones, Volino and Magnenat-Thalmann,
 * 1994). Which subtrees are connected (through shared edges) depends on the mesh alone and is found once;
 * their normals' cones are fitted before each search, to the positions it sees, for the subtrees the
 * correction moves (the only ones searched).
 *
 * The cones bound: a leaf's axis is the mean of its triangles' unit normals and its half angle the widest
 * of them from it; an inner node's axis is the mean of its children's and its half angle the widest of
 * (angle between the axes + the child's half angle). Patches are the hierarchy's subtrees, compact on the
 * skin, so a patch that is a height field locally does not wind over itself.
 */
#include "binding.h"

#include <stdlib.h>

/* A cone counts as flat when its half angle is below 90 degrees by more than float rounding of the normals
 * can move it: its cosine above this. */
#define LVP__FLAT_COSINE 1e-3f

/* Triangles around a vertex, at most, whose pairs are looked at for shared edges. */
#define LVP__FAN_TRIANGLES 32

/* Per node, 5 floats: the cone's unit axis, and the cosine and sine of its half angle. */
enum { LVP__CONE_FLOATS = 5 };

/* The triangles' positions in leaf order of each node, [range[2 i], range[2 i + 1]). Children come after
 * their parent, so from the last node to the first both children are seen before the node. */
static void lvp__node_ranges(const lvp__bvh *bvh, int32_t *range)
{
	for (int32_t index = bvh->node_count - 1; index >= 0; --index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count > 0) {
			range[2 * index] = node->index;
			range[2 * index + 1] = node->index + node->count;
		} else {
			range[2 * index] = range[2 * node->index];
			range[2 * index + 1] = range[2 * (node->index + 1) + 1];
		}
	}
}

/* Whether two triangles share an edge (two corners). */
static bool lvp__share_edge(const int32_t *a, const int32_t *b)
{
	int shared = 0;
	for (int c = 0; c < 3; ++c)
		shared += a[c] == b[0] || a[c] == b[1] || a[c] == b[2];
	return shared >= 2;
}

/* Whether a leaf's triangles are one patch, joined through shared edges. */
static bool lvp__leaf_connected(const lvp__bvh *bvh, const lvp__bvh_node *leaf)
{
	int32_t group[64];
	if (leaf->count > 64)
		return false; /* leaves hold a handful of triangles; a larger one is simply not culled */
	int32_t count = leaf->count;
	for (int32_t i = 0; i < count; ++i)
		group[i] = i;
	/* Each triangle takes the least group of those it shares an edge with, until nothing changes. */
	for (bool changed = true; changed;) {
		changed = false;
		for (int32_t i = 0; i < count; ++i) {
			const int32_t *a = bvh->triangles[leaf->index + i].vertices;
			for (int32_t j = 0; j < count; ++j) {
				if (group[j] >= group[i])
					continue;
				if (lvp__share_edge(a, bvh->triangles[leaf->index + j].vertices)) {
					group[i] = group[j];
					changed = true;
				}
			}
		}
	}
	for (int32_t i = 0; i < count; ++i)
		if (group[i] != 0)
			return false;
	return true;
}

/* The deepest node whose range holds leaf-order positions p < q, from the leaf holding p. */
static int32_t lvp__common_node(const lvp__bvh *bvh, const int32_t *range, int32_t leaf, int32_t q)
{
	int32_t node = leaf;
	while (node >= 0 && !(range[2 * node] <= q && q < range[2 * node + 1]))
		node = bvh->parents[node];
	return node;
}

lvp_result lvp__flat_patches_begin(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	lvp__contact *contact = &binding->contact;
	const lvp__bvh *bvh = &contact->bvh;
	const lvp__mesh *mesh = &binding->mesh;
	int32_t nodes = bvh->node_count;
	bool ok = true;
	contact->connected = lvp__calloc((size_t)nodes, 1, &ok);
	contact->flat = lvp__calloc((size_t)nodes, 1, &ok);
	contact->cones = lvp__calloc((size_t)nodes * LVP__CONE_FLOATS, sizeof(float), &ok);
	int32_t *range = lvp__calloc((size_t)nodes * 2, sizeof(int32_t), &ok);
	int32_t *position = lvp__calloc((size_t)binding->triangle_count, sizeof(int32_t), &ok);
	uint8_t *children_meet = lvp__calloc((size_t)nodes, 1, &ok);
	if (!ok) {
		free(range);
		free(position);
		free(children_meet);
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "could not allocate the contact test's patches of %d triangles.", (int)binding->triangle_count);
	}
	lvp__node_ranges(bvh, range);
	for (int32_t t = 0; t < binding->triangle_count; ++t)
		position[t] = -1;
	for (int32_t i = 0; i < bvh->triangle_count; ++i)
		position[bvh->triangles[i].source] = i;
	/* Two children meet where an edge has a triangle on each side of their parent's split: the deepest
	 * node holding both triangles of each edge (found from each of its two corners). A corner of more than
	 * LVP__FAN_TRIANGLES triangles (the pole of a fan) is not looked at from: its edges are found from their
	 * other corners, or not at all, which leaves a patch unculled, never a crossing unseen. */
	for (int32_t k = 0; k < binding->vertex_count; ++k) {
		if (mesh->vertex_corner_offsets[k + 1] - mesh->vertex_corner_offsets[k] > LVP__FAN_TRIANGLES)
			continue;
		for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c) {
			int32_t p = position[mesh->vertex_triangles[c]];
			for (int32_t d = c + 1; d < mesh->vertex_corner_offsets[k + 1] && p >= 0; ++d) {
				int32_t q = position[mesh->vertex_triangles[d]];
				if (q < 0 || !lvp__share_edge(bvh->triangles[p].vertices, bvh->triangles[q].vertices))
					continue;
				int32_t first = p < q ? p : q, second = p < q ? q : p;
				int32_t node = lvp__common_node(bvh, range, contact->leaf_of[bvh->triangles[first].source], second);
				if (node >= 0)
					children_meet[node] = 1;
			}
		}
	}
	for (int32_t index = nodes - 1; index >= 0; --index) {
		const lvp__bvh_node *node = &bvh->nodes[index];
		if (node->count > 0)
			contact->connected[index] = lvp__leaf_connected(bvh, node);
		else
			contact->connected[index] = children_meet[index] && contact->connected[node->index] &&
			                            contact->connected[node->index + 1];
	}
	free(range);
	free(position);
	free(children_meet);
	return lvp_success;
}

/* The cone of a leaf's triangles (at the hierarchy's corners). */
static void lvp__leaf_cone(const lvp__bvh *bvh, const lvp__bvh_node *leaf, float *cone)
{
	lvp__vec3 normals[64], sum = lvp__v(0.0, 0.0, 0.0);
	int32_t count = leaf->count < 64 ? leaf->count : 64;
	for (int32_t i = 0; i < count; ++i) {
		const lvp__bvh_triangle *t = &bvh->triangles[leaf->index + i];
		lvp__vec3 a = lvp__load(t->corners[0]);
		lvp__vec3 n = lvp__cross(lvp__sub(lvp__load(t->corners[1]), a), lvp__sub(lvp__load(t->corners[2]), a));
		double length = lvp__length(n);
		normals[i] = length > 0.0 ? lvp__scale(n, 1.0 / length) : lvp__v(0.0, 0.0, 0.0);
		sum = lvp__add(sum, normals[i]);
	}
	double length = lvp__length(sum);
	double least = -1.0;
	if (length > 0.0) {
		sum = lvp__scale(sum, 1.0 / length);
		least = 1.0;
		for (int32_t i = 0; i < count; ++i) {
			double c = lvp__dot(sum, normals[i]);
			least = c < least ? c : least;
		}
	}
	cone[0] = (float)sum.x, cone[1] = (float)sum.y, cone[2] = (float)sum.z;
	cone[3] = (float)least;
	cone[4] = (float)sqrt(fmax(0.0, 1.0 - least * least));
}

/* The cone of an inner node from its children's: around the mean of their axes, wide enough for each. */
static void lvp__inner_cone(const float *left, const float *right, float *cone)
{
	lvp__vec3 axis = lvp__add(lvp__load(left), lvp__load(right));
	double length = lvp__length(axis);
	double cos_half = -1.0, sin_half = 0.0;
	if (length > 0.0) {
		axis = lvp__scale(axis, 1.0 / length);
		cos_half = 1.0;
		for (int side = 0; side < 2; ++side) {
			const float *child = side ? right : left;
			double cos_apart = lvp__dot(axis, lvp__load(child)), sin_apart = sqrt(fmax(0.0, 1.0 - cos_apart * cos_apart));
			/* The angle between the axes plus the child's half angle; past 180 degrees, all of the sphere. */
			double c = cos_apart * child[3] - sin_apart * child[4], s = sin_apart * child[3] + cos_apart * child[4];
			if (s < 0.0)
				c = -1.0, s = 0.0;
			if (c < cos_half)
				cos_half = c, sin_half = s;
		}
	}
	cone[0] = (float)axis.x, cone[1] = (float)axis.y, cone[2] = (float)axis.z;
	cone[3] = (float)cos_half;
	cone[4] = (float)sin_half;
}

static void lvp__fit_cone(lvp__contact *contact, int32_t index)
{
	const lvp__bvh *bvh = &contact->bvh;
	const lvp__bvh_node *node = &bvh->nodes[index];
	float *cone = contact->cones + LVP__CONE_FLOATS * (int64_t)index;
	if (node->count > 0) {
		lvp__leaf_cone(bvh, node, cone);
	} else if (contact->node_dynamic[node->index] && contact->node_dynamic[node->index + 1]) {
		lvp__inner_cone(contact->cones + LVP__CONE_FLOATS * (int64_t)node->index,
		                contact->cones + LVP__CONE_FLOATS * (int64_t)(node->index + 1), cone);
	} else {
		cone[3] = -1.0f; /* a child not fitted: any direction */
		cone[4] = 0.0f;
	}
	contact->flat[index] = contact->connected[index] && cone[3] > LVP__FLAT_COSINE;
}

/* The listed leaves in [begin, end) (each writes only its own cone). */
static void lvp__fit_leaves(void *context, int32_t begin, int32_t end)
{
	lvp__contact *contact = context;
	for (int32_t i = begin; i < end; ++i)
		if (contact->bvh.nodes[contact->dynamic_nodes[i]].count > 0)
			lvp__fit_cone(contact, contact->dynamic_nodes[i]);
}

/* Listed nodes a task of the leaves' fit takes at a time. */
#define LVP__FIT_GRAIN 512

void lvp__fit_flat_patches(lvp__contact *contact, lvp__pool *pool)
{
	lvp__parallel_for(pool, lvp__fit_leaves, contact, contact->dynamic_node_count, LVP__FIT_GRAIN);
	/* Then the inner nodes, each after its children (listed before it). */
	for (int32_t i = 0; i < contact->dynamic_node_count; ++i)
		if (contact->bvh.nodes[contact->dynamic_nodes[i]].count == 0)
			lvp__fit_cone(contact, contact->dynamic_nodes[i]);
}
