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
 * Two subtrees that share an edge and whose cones together fit under 90 degrees are such a patch too: the
 * pairs between them are passed over as well (most pairs of nodes the traversal meets are neighbours on the
 * skin, their boxes overlapping along the edges they share). Which triangles lie across each subtree's
 * edges is found once with the rest.
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

/* The same for two cones together: the cosine of the sum of their axes' angle and half angles above minus this,
 * the cosine of twice the margin above. */
#define LVP__FLAT_TOGETHER_COSINE 0.999998

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

/* What a walk over the edges between triangles records (lvp__walk_edges): the nodes whose two children
 * meet, or per node the triangles across its edges, counted (cursor NULL) or written at cursor. */
typedef struct lvp__edge_sink {
	uint8_t *children_meet;
	int32_t *counts, *cursor;
} lvp__edge_sink;

/* Each edge between two triangles of the hierarchy, at positions p and q: the deepest node holding both
 * is where two children meet, and q lies across the edges of every node from p's leaf up to below that
 * node (p across those from q's). An edge is taken from the lesser of its two corners, or from the other
 * where that one is the pole of a fan of more than LVP__FAN_TRIANGLES triangles (not looked at from:
 * an edge between two poles is not found, which leaves a patch unculled, never a crossing unseen). */
static void lvp__walk_edges(lvp__contact *contact, const lvp__mesh *mesh, int32_t vertex_count, const int32_t *position,
                            const lvp__edge_sink *sink)
{
	const lvp__bvh *bvh = &contact->bvh;
	const int32_t *range = contact->node_range, *offsets = mesh->vertex_corner_offsets;
	for (int32_t k = 0; k < vertex_count; ++k) {
		if (offsets[k + 1] - offsets[k] > LVP__FAN_TRIANGLES)
			continue;
		for (int32_t c = offsets[k]; c < offsets[k + 1]; ++c) {
			int32_t p = position[mesh->vertex_triangles[c]];
			for (int32_t d = c + 1; d < offsets[k + 1] && p >= 0; ++d) {
				int32_t q = position[mesh->vertex_triangles[d]];
				if (q < 0 || !lvp__share_edge(bvh->triangles[p].vertices, bvh->triangles[q].vertices))
					continue;
				/* The edge's other corner: the corner of p other than k that q holds too. */
				int32_t other = -1;
				for (int i = 0; i < 3; ++i) {
					int32_t v = bvh->triangles[p].vertices[i];
					const int32_t *b = bvh->triangles[q].vertices;
					if (v != k && (v == b[0] || v == b[1] || v == b[2]))
						other = v;
				}
				if (other >= 0 && other < k && offsets[other + 1] - offsets[other] <= LVP__FAN_TRIANGLES)
					continue; /* taken from that corner */
				int32_t first = p < q ? p : q, second = p < q ? q : p;
				int32_t common = lvp__common_node(bvh, range, contact->leaf_of[bvh->triangles[first].source], second);
				if (common < 0)
					continue;
				if (sink->children_meet)
					sink->children_meet[common] = 1;
				for (int side = 0; side < 2 && sink->counts; ++side) {
					int32_t from = side ? second : first, to = side ? first : second;
					for (int32_t node = contact->leaf_of[bvh->triangles[from].source]; node >= 0 && node != common;
					     node = bvh->parents[node]) {
						if (sink->cursor)
							contact->across[sink->cursor[node]++] = to;
						else
							sink->counts[node]++;
					}
				}
			}
		}
	}
}

static int lvp__compare_positions(const void *a, const void *b)
{
	int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
	return (x > y) - (x < y);
}

/* contact.across and across_offsets: counted by one walk over the edges, written by another, then each
 * node's list sorted and its repeats dropped (a triangle across two edges of one node). */
static bool lvp__find_across(lvp__contact *contact, const lvp__mesh *mesh, int32_t vertex_count,
                             const int32_t *position)
{
	int32_t nodes = contact->bvh.node_count;
	bool ok = true;
	int32_t *counts = lvp__calloc((size_t)nodes + 1, sizeof(int32_t), &ok);
	contact->across_offsets = lvp__calloc((size_t)nodes + 1, sizeof(int32_t), &ok);
	if (!ok) {
		free(counts);
		return false;
	}
	lvp__edge_sink sink = {NULL, counts, NULL};
	lvp__walk_edges(contact, mesh, vertex_count, position, &sink);
	int64_t total = 0;
	for (int32_t i = 0; i < nodes; ++i) {
		contact->across_offsets[i] = (int32_t)total;
		total += counts[i];
	}
	contact->across_offsets[nodes] = (int32_t)total;
	contact->across = total < INT32_MAX ? lvp__calloc((size_t)total + 1, sizeof(int32_t), &ok) : NULL;
	if (!contact->across) {
		free(counts);
		return false;
	}
	memcpy(counts, contact->across_offsets, sizeof(int32_t) * (size_t)nodes);
	sink.cursor = counts;
	lvp__walk_edges(contact, mesh, vertex_count, position, &sink);
	free(counts);
	int32_t kept = 0;
	for (int32_t i = 0; i < nodes; ++i) {
		int32_t begin = contact->across_offsets[i], end = contact->across_offsets[i + 1];
		qsort(contact->across + begin, (size_t)(end - begin), sizeof(int32_t), lvp__compare_positions);
		contact->across_offsets[i] = kept;
		for (int32_t j = begin; j < end; ++j)
			if (j == begin || contact->across[j] != contact->across[j - 1])
				contact->across[kept++] = contact->across[j];
	}
	contact->across_offsets[nodes] = kept;
	return true;
}

lvp_result lvp__flat_patches_begin(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	lvp__contact *contact = &binding->contact;
	const lvp__bvh *bvh = &contact->bvh;
	int32_t nodes = bvh->node_count;
	bool ok = true;
	contact->connected = lvp__calloc((size_t)nodes, 1, &ok);
	contact->flat = lvp__calloc((size_t)nodes, 1, &ok);
	contact->cones = lvp__calloc((size_t)nodes * LVP__CONE_FLOATS, sizeof(float), &ok);
	contact->node_range = lvp__calloc((size_t)nodes * 2, sizeof(int32_t), &ok);
	int32_t *position = lvp__calloc((size_t)binding->triangle_count, sizeof(int32_t), &ok);
	uint8_t *children_meet = lvp__calloc((size_t)nodes, 1, &ok);
	if (ok) {
		lvp__node_ranges(bvh, contact->node_range);
		for (int32_t t = 0; t < binding->triangle_count; ++t)
			position[t] = -1;
		for (int32_t i = 0; i < bvh->triangle_count; ++i)
			position[bvh->triangles[i].source] = i;
		/* Two children meet where an edge has a triangle on each side of their parent's split. */
		lvp__edge_sink sink = {children_meet, NULL, NULL};
		lvp__walk_edges(contact, &binding->mesh, binding->vertex_count, position, &sink);
		for (int32_t index = nodes - 1; index >= 0; --index) {
			const lvp__bvh_node *node = &bvh->nodes[index];
			if (node->count > 0)
				contact->connected[index] = lvp__leaf_connected(bvh, node);
			else
				contact->connected[index] = children_meet[index] && contact->connected[node->index] &&
				                            contact->connected[node->index + 1];
		}
		ok = lvp__find_across(contact, &binding->mesh, binding->vertex_count, position);
	}
	free(position);
	free(children_meet);
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1,
		                 "could not allocate the contact test's patches of %d triangles.", (int)binding->triangle_count);
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

bool lvp__flat_together(const void *context, int32_t a, int32_t b)
{
	const lvp__contact *contact = context;
	if (!contact->node_dynamic[a] || !contact->node_dynamic[b] || !contact->flat[a] || !contact->flat[b])
		return false;
	/* The two cones fit in one under 90 degrees (less the margin of LVP__FLAT_COSINE) when the angle between
	 * their axes and their two half angles sum to under 180 degrees (less twice the margin). */
	const float *x = contact->cones + LVP__CONE_FLOATS * (int64_t)a, *y = contact->cones + LVP__CONE_FLOATS * (int64_t)b;
	double c = (double)x[0] * y[0] + (double)x[1] * y[1] + (double)x[2] * y[2];
	c = c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c);
	double s = sqrt(1.0 - c * c);
	double c1 = c * x[3] - s * x[4], s1 = s * x[3] + c * x[4]; /* the axes' angle plus a's half angle */
	double c2 = c1 * y[3] - s1 * y[4], s2 = s1 * y[3] + c1 * y[4]; /* plus b's */
	if (!(s1 >= 0.0 && s2 > 0.0 && c2 > -LVP__FLAT_TOGETHER_COSINE))
		return false;
	/* Some triangle across a's edges lies in b: the first at or past b's range's start, below its end. */
	int32_t lo = contact->node_range[2 * b], hi = contact->node_range[2 * b + 1];
	int32_t first = contact->across_offsets[a], last = contact->across_offsets[a + 1];
	while (first < last) {
		int32_t middle = first + (last - first) / 2;
		if (contact->across[middle] < lo)
			first = middle + 1;
		else
			last = middle;
	}
	return first < contact->across_offsets[a + 1] && contact->across[first] < hi;
}
