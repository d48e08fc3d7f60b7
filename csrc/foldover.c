/*
 * foldover.c - paper 5.4: fold-over prevention. Where two bones bend about a joint, the skin on
 * the concave side of the bend is pressed together: a vertex of one side that the posed skeleton
 * carries across the joint's contact plane (through the joint, halfway through the bend) has
 * crossed into the other side's flesh, and is moved back onto the plane. The paper finds the
 * crossing with its 5.1 weight formula (distances to the bone segments) and walks back towards
 * the vertex's bone in constant steps; both assume each bone runs through the middle of its
 * flesh. A hand's palm is one bone down its middle and its fingers hang off it sideways: the
 * segments' bisector there runs through the palm, far from any crease, and the walk towards the
 * palm bone pulled sheets of skin out of it. The plane through the joint holds for both.
 */
#include "binding.h"

#include <stdlib.h>

/* The pressing of skin onto a contact plane, as shares of the child's flesh radius (joint->reach):
 * - LVP__CREASE_WINDOW: the skin at the bottom of the crease, on either side of the plane within
 *   this at rest, may cross the plane by as much as it lay in front of this depth at rest; the
 *   window closes as the joint bends to a right angle (times the cosine of the bend), where the
 *   two sides of the crease do press on each other. The skin's sheet passes through the plane
 *   there, and as the joint bends, skinning shifts where it passes: its vertices cross the plane
 *   by a fraction of an edge long before any skin meets. One vertex pressed back and its
 *   neighbours not (one just on the other side at rest, one a little deeper) was a spike as tall
 *   as the offsets. Past a right angle the cosine turns negative and the window opens the other
 *   way: the skin at the bottom of the fold is held short of the plane by as much as it lay in
 *   front of the window's depth at rest, so the fold stays open there, as flesh does at the
 *   bottom of a deep fold (lvp__fold_opening). Pressed onto the plane from both sides, the sheet
 *   turned back on itself within an edge or two of a coarse mesh, a crease at each, and crossed
 *   itself there.
 * - LVP__OTHER_SIDE_FADE: the skin of a region on the other side of the plane at rest (heat
 *   weights give a finger's region palm skin behind its knuckle) may cross it further the deeper
 *   it lay there, without limit from this depth on, or from the vertex's longest edge where that
 *   is longer. It was never pressed, and its neighbours a hair on the region's own side were
 *   pressed fully: a step of twice an edge at the fist. Where an edge is longer than the fade
 *   (coarse and irregular meshes), it went from pressed fully to not at all: a step all the same.
 * - LVP__SOFT_CONTACT: skin on the concave side of the bend is pressed from this far (times the
 *   sine of half the bend, so not at all before the joint bends) in front of the plane, gently at
 *   first, fully at this far past it: projected exactly, the pressed skin met the free skin beside
 *   it at an angle (a crease). Fading towards the flanks, where nothing presses the skin. */
#define LVP__CREASE_WINDOW 0.25
#define LVP__OTHER_SIDE_FADE 0.5
#define LVP__SOFT_CONTACT 0.4

/* binding->fold.held, per vertex: */
enum {
	LVP__HELD_BEFORE = 1,     /* held by an earlier round of this frame: not pressed again */
	LVP__HELD_THIS_ROUND = 2, /* held by this round (lvp__fold_over) */
	LVP__HELD_STILL = 3       /* too far from any pressed skin to move while it relaxes (lvp__relax_pressed) */
};

/* binding->fold.contact, per neighbour entry (s, j) of this frame: */
enum {
	LVP__CONTACT_NONE = 0, /* no skin crossed between s and j */
	LVP__CONTACT_FOUND,    /* skin crossed (of s into j, or of j into s); the map not faded yet */
	LVP__CONTACT_FADED,    /* and the map was faded there (lvp__fade_map_at_contact) */
};

static inline double lvp__smoothstep(double x)
{
	x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
	return x * x * (3.0 - 2.0 * x);
}

static inline lvp__vec3 lvp__unit(lvp__vec3 a)
{
	double length = lvp__length(a);
	return length > 0.0 ? lvp__scale(a, 1.0 / length) : lvp__v(0.0, 0.0, 0.0);
}

/* How far apart the two bones' skinning carries rest point p this frame. */
static double lvp__motion_apart(const lvp_binding *binding, int32_t s, int32_t j, lvp__vec3 p)
{
	return lvp__length(lvp__sub(lvp__transform_point(&binding->rig.skin[s], p),
	                            lvp__transform_point(&binding->rig.skin[j], p)));
}

/* How far the parent's bone passes from the child's head, at rest. */
static double lvp__parent_distance(const lvp_binding *binding, int32_t child, int32_t parent)
{
	return lvp__bone_distance(binding, parent, binding->rig.heads[child]);
}

/* The joint of bones s and j: the head of one of them (the child's, where a bone turns about its
 * parent) that their relative motion leaves in place, while it moves the bones' other ends apart.
 * Found from the motion, so the rig's hierarchy is not needed, and a pair that meets without a
 * joint (a thumb folded onto the index) is told apart at any angle: its motion fixes no head. */
static bool lvp__joint_child(const lvp_binding *binding, int32_t s, int32_t j, int32_t *r_child)
{
	const lvp__rig *rig = &binding->rig;
	double at_j = lvp__motion_apart(binding, s, j, rig->heads[j]);
	double at_s = lvp__motion_apart(binding, s, j, rig->heads[s]);
	double moved = fmax(fmax(at_j, at_s), fmax(lvp__motion_apart(binding, s, j, binding->lines.end[s]),
	                                           lvp__motion_apart(binding, s, j, binding->lines.end[j])));
	if (!(moved > 0.0) || !(fmin(at_j, at_s) <= 0.1 * moved))
		return false;
	int32_t child = at_j <= at_s ? j : s, parent = child == s ? j : s;
	/* Both heads in place: the bones turn about one line through both (two thighs raised alike
	 * turn about the line through the hips). A joint only when the child's head lies in the
	 * parent's flesh; two thighs' skins meet at the crotch, but nothing there folds. */
	if (fmax(at_j, at_s) <= 0.1 * moved && !(lvp__parent_distance(binding, child, parent) <= binding->fold.radius[parent]))
		return false;
	*r_child = child;
	return true;
}

/* The contact plane of a joint this frame: through the joint, its normal halfway between where
 * the child would point had it moved with the parent (straight on, `unbent`) and where it points
 * (`bent`), towards the child's side: at rest, the plane across the child at its head; bent, the
 * bisector plane of the bend. Only the child's direction and the two bones' motion enter, never
 * the parent's direction: a palm bone down the middle of the hand, a pelvis bone pointing at the
 * hip bone's crest, say nothing of where the flesh of their children turns. Also the bend's axis
 * and its concave side (where the child bent to). False when the child does not turn (nothing
 * folds) or turns back onto the parent (no plane between them). r_inside: the concave direction
 * square to the unbent child, where the parent carries the skin at the bottom of the crease. */
static bool lvp__contact_plane(lvp__joint *r_joint, lvp__vec3 *r_inside, lvp__vec3 unbent, lvp__vec3 bent)
{
	unbent = lvp__unit(unbent);
	bent = lvp__unit(bent);
	lvp__vec3 normal = lvp__add(unbent, bent), axis = lvp__cross(unbent, bent), concave = lvp__sub(bent, unbent);
	if (!(lvp__length(normal) > 1e-3) || !(lvp__length(axis) > 1e-3))
		return false;
	r_joint->normal = lvp__unit(normal);
	r_joint->axis = lvp__unit(axis);
	r_joint->concave = lvp__unit(concave);
	*r_inside = lvp__unit(lvp__sub(concave, lvp__scale(unbent, lvp__dot(concave, unbent))));
	return true;
}

/* Whether two bones move differently this frame (only then can skin fold between them). */
static bool lvp__bends(const lvp_binding *binding, int32_t s, int32_t j)
{
	const double *a = binding->rig.skin[s].m, *b = binding->rig.skin[j].m;
	double scale = 1.0;
	for (int i = 0; i < 12; ++i)
		scale = fmax(scale, fabs(a[i]));
	for (int i = 0; i < 12; ++i)
		if (fabs(a[i] - b[i]) > 1e-6 * scale)
			return true;
	return false;
}

/* How much of a vertex at p the joint's plane holds, by its distance from the joint along the
 * bend's axis: all of it within the child's flesh radius, none past twice that (the palm under the
 * next finger's knuckle is not pressed by this one). */
static double lvp__across_joint(const lvp__joint *joint, lvp__vec3 p)
{
	double side = fabs(lvp__dot(lvp__sub(p, joint->point), joint->axis));
	return 1.0 - lvp__smoothstep((side - joint->reach) / joint->reach);
}

/* How much of a joint's window bent past a right angle holds vertex k short of the plane
 * (LVP__CREASE_WINDOW): the skin at the bottom of the crease, on the inside of the bend at rest (its rest
 * place from the joint along the bend's direction, as the parent carries it): all of it where it lay
 * the child's flesh radius inside, none on the flanks or outside, where nothing folds over. */
static double lvp__fold_opening(const float *rest, int32_t k, const lvp__joint *joint)
{
	double inside = lvp__dot(lvp__sub(lvp__load(rest + 3 * k), joint->rest_point), joint->rest_inside);
	return lvp__smoothstep(inside / joint->reach);
}

/* How far a vertex may lie across the joint's plane (along its normal) given how far across the
 * rest plane it lay at rest (negative: on its own side), its longest edge, and the joint's crease
 * window there (negative past a right angle: lvp__press_region); INFINITY where it is never pressed
 * (LVP__CREASE_WINDOW, LVP__OTHER_SIDE_FADE). Continuous in the rest side: the skin's sheet is. */
static double lvp__allowed_across(const lvp__joint *joint, double rest_side, double longest_edge, double window)
{
	/* Comparisons rather than fmax, which compilers call out of line (nothing here is NaN): the presses
	 * ask this of every vertex of a joint's side, many times a frame. */
	double fade = LVP__OTHER_SIDE_FADE * joint->reach;
	fade = longest_edge > fade ? longest_edge : fade;
	if (rest_side <= 0.0) {
		if (window < 0.0) /* bent past a right angle: held short of the plane, the fold's bottom open */
			return rest_side - window > 0.0 ? window - rest_side : 0.0;
		return rest_side + window > 0.0 ? rest_side + window : 0.0;
	}
	if (rest_side >= fade)
		return INFINITY;
	return (rest_side + window) / (1.0 - rest_side / fade);
}

/* How far to press a vertex `excess` across what it may (negative: short of it) back along the
 * plane's normal, with the contact softened over `soft` (LVP__SOFT_CONTACT): nothing from `soft`
 * short of the limit, then quadratically, all of the excess from `soft` past it on; its slope
 * is continuous, so the pressed skin runs into the free skin without a kink. */
static double lvp__press(double excess, double soft)
{
	if (!(soft > 0.0))
		return fmax(0.0, excess);
	double x = excess + soft;
	if (x <= 0.0)
		return 0.0;
	return x >= 2.0 * soft ? x - soft : x * x / (4.0 * soft);
}

/* The entry of region s's neighbours for bone j, or -1. */
static int32_t lvp__neighbour_entry(const lvp_binding *binding, int32_t s, int32_t j)
{
	for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n)
		if (binding->mesh.neighbour_bones[n] == j)
			return n;
	return -1;
}

/* Where the border vertices of a joint's two sides lie, weighted (lvp__place_at_border). */
typedef struct lvp__border_mean {
	double weight, across, at_rest;
} lvp__border_mean;

/* Adds the border vertices of neighbour entry m to `mean`: each weighted by how far it lies on the concave
 * side, within the joint's reach along its axis, and within that reach of the joint's rest plane. */
static void lvp__weigh_border(const lvp_binding *binding, const float *rest, int32_t m, const lvp__joint *joint,
                              lvp__border_mean *mean)
{
	const float *work = binding->step.positions;
	for (int32_t i = binding->fold.border_offsets[m]; i < binding->fold.border_offsets[m + 1]; ++i) {
		int32_t k = binding->fold.border_vertices[i];
		lvp__vec3 p = lvp__load(work + 3 * k), from_joint = lvp__sub(p, joint->point);
		double rest_side = lvp__dot(lvp__sub(lvp__load(rest + 3 * k), joint->rest_point), joint->rest_normal);
		double w = lvp__across_joint(joint, p) * lvp__smoothstep(lvp__dot(from_joint, joint->concave) / joint->reach) *
		           (1.0 - lvp__smoothstep(fabs(rest_side) / joint->reach));
		mean->weight += w;
		mean->across += w * lvp__dot(from_joint, joint->normal);
		mean->at_rest += w * rest_side;
	}
}

/* Moves the joint's plane, along its normal, to where the skins of s and j meet on the concave
 * side of the bend, at rest and posed: the weighted mean of their border vertices there, within
 * the joint's reach along its axis and within the child's flesh radius of the joint at rest (a
 * border further away is where the weights blend along a bone, not a crease), the move at most
 * half that radius. Heat weights rarely put the border between a finger and the palm at the
 * finger bone's head; with the plane through the head, the part of the region beyond it at rest
 * (never pressed) and the part just short of it (pressed onto the plane as soon as the joint
 * bends) made a step in the skin, at poses where nothing touches yet. The borders are those of
 * every region of s's group with every region of j's: a B-Bone's joints share its head and line,
 * and which of them borders the crease is the weights' choice (a Rigify shin's first joint may
 * have no skin at all). */
static void lvp__place_at_border(const lvp_binding *binding, const float *rest, int32_t s, int32_t n,
                                 lvp__joint *joint)
{
	const lvp__region_system *system = &binding->system;
	int32_t leaders[2] = {system->group_leader[s], system->group_leader[binding->mesh.neighbour_bones[n]]};
	lvp__border_mean mean = {0.0, 0.0, 0.0};
	for (int side = 0; side < 2; ++side) {
		int32_t leader = leaders[side], other = leaders[1 - side];
		for (int32_t g = system->group_offsets[leader]; g < system->group_offsets[leader + 1]; ++g) {
			int32_t r = system->group_regions[g];
			for (int32_t m = binding->mesh.neighbour_offsets[r]; m < binding->mesh.neighbour_offsets[r + 1]; ++m)
				if (system->group_leader[binding->mesh.neighbour_bones[m]] == other)
					lvp__weigh_border(binding, rest, m, joint, &mean);
		}
	}
	if (!(mean.weight > 0.0))
		return;
	double most = 0.5 * joint->reach, across = mean.across / mean.weight, at_rest = mean.at_rest / mean.weight;
	joint->point = lvp__add(joint->point, lvp__scale(joint->normal, fmax(-most, fmin(most, across))));
	joint->rest_point = lvp__add(joint->rest_point, lvp__scale(joint->rest_normal, fmax(-most, fmin(most, at_rest))));
}

/* A bone whose skin meets the skin of several bones it turns against (the upper arm's meets the
 * spine's, the shoulder's and the breast's) folds at one crease: all its joints as the child take
 * the plane of the one whose parent's bone passes nearest its head, the bone it hangs from. Each
 * pair's own plane bisected a different bend, and skin of the neighbouring regions was pressed
 * onto different planes a hand's width apart (the Rigify human's armpit, roughness 0.50 of the
 * largest offset; 0.36 now). */
static void lvp__share_child_planes(lvp_binding *binding)
{
	int32_t entries = binding->mesh.neighbour_offsets[binding->region_count];
	int32_t *plane_entry = binding->fold.plane_entry;
	lvp__joint *joints = binding->fold.joints;
	for (int32_t r = 0; r < binding->region_count; ++r)
		plane_entry[r] = -1;
	for (int32_t n = 0; n < entries; ++n) {
		if (!joints[n].bends)
			continue;
		int32_t *best = &plane_entry[joints[n].child];
		if (*best < 0 || lvp__parent_distance(binding, joints[n].child, joints[n].parent) <
		                     lvp__parent_distance(binding, joints[*best].child, joints[*best].parent))
			*best = n;
	}
	for (int32_t n = 0; n < entries; ++n) {
		lvp__joint *joint = &joints[n];
		int32_t m = joint->bends ? plane_entry[joint->child] : -1;
		if (m < 0 || joints[m].parent == joint->parent)
			continue;
		lvp__joint shared = joints[m];
		if (shared.child_side != joint->child_side) { /* the normals point from the entry's side */
			shared.normal = lvp__scale(shared.normal, -1.0);
			shared.rest_normal = lvp__scale(shared.rest_normal, -1.0);
			shared.child_side = joint->child_side;
		}
		shared.parent = joint->parent;
		*joint = shared;
	}
}

/* The entry that presses each side of a joint (fold.side_entry): one side is the skin of a group (a B-Bone's
 * joints, or a bone alone) on one side of the joint of two groups, and its first bending entry presses all of
 * it. Around a B-Bone's end its joints bend alike (the knee of a Rigify leg: the thigh's last B-Bone and the
 * shin's first each curve into the bend), and the calf pressed into the back of the thigh at 150 degrees
 * is skin of joints that border no joint of the other bone: pressed region by region, only the pairs at
 * the border were, and the skinning's crossings further along stayed (94 pairs a knee, 91 after). The child
 * is the B-Bone, not one of its joints: a B-Bone's joints share its head and line, and where several of them
 * border the parent's skin (the shin's second, third and fourth at the back of a Rigify knee, its first
 * having no skin), each as the child would make the same plane again and press the whole side once more: the
 * soft contact, applied that many times a pass, held the calf's skin at the bottom of the crease apart from
 * the thigh's further than the relaxation leaves it, a step in the offsets there. */
static void lvp__find_side_entries(lvp_binding *binding)
{
	const lvp__mesh *mesh = &binding->mesh;
	const lvp__region_system *system = &binding->system;
	const lvp__joint *joints = binding->fold.joints;
	for (int32_t s = 0; s < binding->region_count; ++s)
		for (int32_t n = mesh->neighbour_offsets[s]; n < mesh->neighbour_offsets[s + 1]; ++n) {
			binding->fold.side_entry[n] = -1;
			if (!joints[n].bends)
				continue;
			int32_t leader = system->group_leader[s];
			/* The first entry of a region of the group (in region order) with the same child and side. */
			for (int32_t g = system->group_offsets[leader];
			     g < system->group_offsets[leader + 1] && binding->fold.side_entry[n] < 0; ++g) {
				int32_t t = system->group_regions[g];
				for (int32_t m = mesh->neighbour_offsets[t]; m < mesh->neighbour_offsets[t + 1]; ++m)
					if (joints[m].bends &&
					    system->group_leader[joints[m].child] == system->group_leader[joints[n].child] &&
					    joints[m].child_side == joints[n].child_side) {
						binding->fold.side_entry[n] = m;
						break;
					}
			}
		}
}

void lvp__begin_fold_over(lvp_binding *binding, const float *rest_positions)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	const lvp__rig *rig = &binding->rig;
	const lvp__bone_lines *lines = &binding->lines;
	memset(binding->fold.contact, 0, (size_t)binding->mesh.neighbour_offsets[binding->region_count]);
	binding->fold.deepest = 0.0;
	for (int32_t s = 0; s < binding->region_count; ++s)
		for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n) {
			lvp__joint *joint = &binding->fold.joints[n];
			int32_t j = binding->mesh.neighbour_bones[n], child;
			joint->bends = false;
			if (rig->region_skipped[s] || rig->region_skipped[j] || !(lines->length[s] > 0.0) ||
			    !(lines->length[j] > 0.0) || !lvp__bends(binding, s, j))
				continue;
			/* The joints of one B-Bone (one group) bend all along it, not at its head. */
			if (binding->system.group_leader[s] == binding->system.group_leader[j])
				continue;
			if (!lvp__joint_child(binding, s, j, &child))
				continue;
			int32_t parent = child == s ? j : s;
			joint->child = child;
			joint->parent = parent;
			joint->child_side = child == s;
			lvp__vec3 direction = lvp__sub(lines->end[child], rig->heads[child]); /* at rest */
			joint->rest_point = rig->heads[child];
			joint->point = rig->posed_heads[child];
			joint->rest_normal = lvp__unit(direction);
			lvp__vec3 unbent = lvp__transform_vector(&rig->skin[parent], direction), inside;
			if (!lvp__contact_plane(joint, &inside, unbent, lvp__transform_vector(&rig->skin[child], direction)))
				continue;
			/* Where the parent's skinning takes rest direction d, d . rest_inside = (skin d) . inside. */
			joint->rest_inside = lvp__transform_vector_transposed(&rig->skin[parent], inside);
			/* The sine of half the bend: the normal lies halfway between unbent and bent. */
			double sine = lvp__length(lvp__cross(lvp__unit(unbent), joint->normal));
			if (child == s) { /* the normals point from s's side to j's */
				joint->normal = lvp__scale(joint->normal, -1.0);
				joint->rest_normal = lvp__scale(joint->rest_normal, -1.0);
			}
			joint->reach = binding->fold.radius[child];
			joint->soft = LVP__SOFT_CONTACT * joint->reach * sine;
			/* cos(bend) = 1 - 2 sin(bend / 2)^2 */
			joint->window = LVP__CREASE_WINDOW * joint->reach * (1.0 - 2.0 * sine * sine);
			joint->bends = joint->reach > 0.0;
			if (joint->bends)
				lvp__place_at_border(binding, rest, s, n, joint);
		}
	lvp__share_child_planes(binding);
	lvp__find_side_entries(binding);
}

/* Marks the contact of entry n of region s's neighbours, bone j, for both sides: the flesh of s
 * and of j is pressed together, whichever crossed (each side by the entry that presses it). */
static void lvp__mark_contact(lvp_binding *binding, int32_t s, int32_t n, int32_t j)
{
	int32_t m = lvp__neighbour_entry(binding, j, s); /* a region's neighbours are listed once each */
	int32_t sides[2] = {binding->fold.side_entry[n], m >= 0 ? binding->fold.side_entry[m] : -1};
	for (int side = 0; side < 2; ++side)
		if (sides[side] >= 0 && binding->fold.contact[sides[side]] == LVP__CONTACT_NONE)
			binding->fold.contact[sides[side]] = LVP__CONTACT_FOUND;
}

/* Presses the vertices of region r across the joint's plane of entry n (region s, bone j) back onto it, and
 * marks the joint's contact when it pressed any; returns how many were not held before. */
static int32_t lvp__press_region(lvp_binding *binding, const float *rest, int32_t r, int32_t s, int32_t n)
{
	const lvp__joint *joint = &binding->fold.joints[n];
	float *work = binding->step.positions;
	int32_t j = binding->mesh.neighbour_bones[n], moved = 0;
	bool pressed = false;
	/* The skin of the two sides does not quite touch. */
	double gap = 1e-4 * (binding->lines.length[s] + binding->lines.length[j]);
	double softest = joint->soft > 0.0 ? joint->soft : 0.0;
	/* Past a right angle the window holds the fold's bottom open (lvp__fold_opening), scaled down where
	 * the region's edges are shorter than the child's flesh radius: the room is for a sheet of skin to
	 * turn back over a few edges, which a fine mesh has within the press itself. */
	double opening = joint->window < 0.0 ? joint->window * fmin(1.0, binding->fold.mean_edge[r] / joint->reach) : 0.0;
	for (int32_t i = binding->mesh.region_vertex_offsets[r]; i < binding->mesh.region_vertex_offsets[r + 1]; ++i) {
		int32_t k = binding->mesh.region_vertices[i];
		/* Pressed once: pressing again would soften its contact twice. Held still while pressed skin
		 * relaxes: it has not moved. */
		if (binding->fold.held[k] == LVP__HELD_BEFORE || binding->fold.held[k] == LVP__HELD_STILL)
			continue;
		double rest_side = lvp__dot(lvp__sub(lvp__load(rest + 3 * k), joint->rest_point), joint->rest_normal);
		double window = joint->window < 0.0 ? opening * lvp__fold_opening(rest, k, joint) : joint->window;
		double allowed = lvp__allowed_across(joint, rest_side, binding->fold.longest_edge[k], window);
		if (allowed == INFINITY)
			continue;
		lvp__vec3 p = lvp__load(work + 3 * k), from_joint = lvp__sub(p, joint->point);
		double excess = lvp__dot(from_joint, joint->normal) - allowed + gap;
		/* Short of its limit by more than the joint's widest soft band, a vertex is not pressed (lvp__press
		 * gives nothing there): most of a side's skin lies that far back, passed over before its own band
		 * is weighed. */
		if (!(excess + softest > 0.0))
			continue;
		double soft = joint->soft * lvp__smoothstep(lvp__dot(from_joint, joint->concave) / joint->reach);
		double push = lvp__press(excess, soft);
		if (!(push > 0.0))
			continue;
		double held = lvp__across_joint(joint, p);
		if (!(held > 0.0))
			continue;
		binding->fold.deepest = fmax(binding->fold.deepest, held * push / binding->fold.longest_edge[k]);
		lvp__vec3 q = lvp__sub(p, lvp__scale(joint->normal, held * push));
		work[3 * k] = (float)q.x;
		work[3 * k + 1] = (float)q.y;
		work[3 * k + 2] = (float)q.z;
		pressed = true;
		moved += !binding->fold.held[k];
		binding->fold.held[k] = LVP__HELD_THIS_ROUND;
		lvp__make_dynamic(binding, k); /* off its bone's path now: the next pass visits it */
	}
	if (pressed)
		lvp__mark_contact(binding, s, n, j);
	return moved;
}

/* The contact test of lvp__fold_over, at the joints where skin crossed already when at_contacts: each side
 * of each joint, every region of its group (lvp__find_side_entries). */
static int32_t lvp__press_across(lvp_binding *binding, const float *rest_positions, bool at_contacts)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	const lvp__region_system *system = &binding->system;
	int32_t moved = 0;
	for (int32_t s = 0; s < binding->region_count; ++s)
		for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n) {
			if (!binding->fold.joints[n].bends || binding->fold.side_entry[n] != n ||
			    (at_contacts && binding->fold.contact[n] == LVP__CONTACT_NONE))
				continue;
			int32_t leader = system->group_leader[s];
			for (int32_t g = system->group_offsets[leader]; g < system->group_offsets[leader + 1]; ++g)
				moved += lvp__press_region(binding, rest, system->group_regions[g], s, n);
		}
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		if (binding->fold.held[k] == LVP__HELD_THIS_ROUND)
			binding->fold.held[k] = LVP__HELD_BEFORE;
	return moved;
}

int32_t lvp__fold_over(lvp_binding *binding, const float *rest_positions)
{
	return lvp__press_across(binding, rest_positions, false);
}

/* The dynamic set listing every vertex a press made dynamic (lvp__make_dynamic, which only ever adds):
 * a smoothing pass reads the offsets of the vertices flagged dynamic, taken only for those listed. */
static void lvp__list_pressed_dynamic(lvp_binding *binding, const float *rest_positions,
                                      const lvp__region_sums *totals)
{
	int32_t flagged = 0;
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		flagged += binding->frame_map.vertex_dynamic[k] != 0;
	if (flagged != binding->dynamic.vertex_count)
		lvp__find_dynamic_set(binding, rest_positions, totals, false);
}

/* Pressed onto its plane, the skin that crossed it meets the free skin beside it at the angle at which
 * the skinning carried it through the plane, and each vertex is pressed by as much as it crossed: a
 * crease along the contact line, and pressed vertices standing out of their neighbours' surface
 * where the next crossed less. Relaxing it is smoothing under the contact's constraint: the offsets
 * of the pressed skin and of the skin within `passes` rings of it averaged with their neighbours'
 * (both ways), then whatever that carried across a plane pressed back onto it. A few passes leave
 * the pressed patch on its plane and the free skin around it curving into it, as flesh does around
 * a contact; the skin further away keeps its offsets. Averaging settles as a membrane would, into a
 * cone where the plane holds one vertex much further than its neighbours (a coarse mesh's press), so
 * the free skin is then settled as a plate (plate.c). */
bool lvp__relax_pressed(lvp_binding *binding, const float *positions, const float *rest_positions,
                        const lvp__region_sums *totals, int32_t passes, int32_t smoothing_passes)
{
	int32_t n = binding->vertex_count;
	uint8_t *held = binding->fold.held, *before = binding->fold.held_before;
	int32_t *zone = binding->fold.zone;
	if (passes <= 0 || !memchr(held, LVP__HELD_BEFORE, (size_t)n))
		return false;
	memcpy(before, held, (size_t)n);
	/* The skin that may move (the zone): the pressed vertices and the rings around them, found ring
	 * by ring; the rest is held still (lvp__can_move) while the passes run. */
	int32_t count = 0;
	for (int32_t k = 0; k < n; ++k) {
		held[k] = before[k] ? 0 : LVP__HELD_STILL;
		if (before[k])
			zone[count++] = k;
	}
	const int32_t *offsets = binding->smoothing.offsets, *neighbours = binding->smoothing.neighbours;
	for (int32_t ring = 0, first = 0; ring < passes; ++ring) {
		int32_t last = count;
		for (int32_t z = first; z < last; ++z)
			for (int32_t i = offsets[zone[z]]; i < offsets[zone[z] + 1]; ++i)
				if (held[neighbours[i]] == LVP__HELD_STILL) {
					held[neighbours[i]] = 0;
					zone[count++] = neighbours[i];
				}
		first = last;
	}
	/* The zone relaxes whatever its map: skin that its bones carry rigidly beside pressed skin (the upper
	 * arm's upper bone beside the lower one's pressed skin) follows it, or the pressed patch would end in a
	 * step at the map's border. */
	for (int32_t z = 0; z < count; ++z)
		if (!binding->frame_map.vertex_dynamic[zone[z]])
			lvp__make_dynamic(binding, zone[z]);
	for (int32_t pass = 0; pass < passes; ++pass) {
		for (int32_t z = 0; z < count; ++z)
			held[zone[z]] = 0;
		lvp__list_pressed_dynamic(binding, rest_positions, totals);
		lvp__smooth_offsets(binding, positions, 1, LVP__SMOOTH_RELAXATION);
		/* Pressed back at the joints it was pressed at: a plane where no skin crossed yet is the
		 * next contact test's (the rounds', and the one after the last volume step). Pressed softly
		 * again each pass, skin that stays within the soft band goes a little deeper each time,
		 * towards its inner edge: the band's slope is what rounds the contact line (pressed onto
		 * the limit itself, the hands of the tests kept twice the creases). */
		lvp__press_across(binding, rest_positions, true);
	}
	/* The skin the last pass pressed is held (LVP__HELD_BEFORE; the rest of the zone 0, as each pass left it),
	 * and what the plate carries across is pressed back. */
	lvp__settle_as_plate(binding, positions, zone, count, smoothing_passes);
	lvp__press_across(binding, rest_positions, true);
	for (int32_t k = 0; k < n; ++k)
		held[k] = before[k] || held[k] == LVP__HELD_BEFORE ? LVP__HELD_BEFORE : 0;
	return true;
}

/* A pressed patch of depth D relaxed over R rings of edges e slopes into the free skin around it by about
 * D / (R e): at LVP__RELAXATION_RINGS_PER_EDGE rings per edge of the deepest press, by at most a half (27
 * degrees), below the 30 degrees a crease reads. Presses several edges deep come from fine meshes (a thigh's
 * skin pressed under its calf, where the smoothing's rings alone left the rim creased); on coarser meshes the
 * same press is an edge or two deep and the smoothing's rings already take it. */
#define LVP__RELAXATION_RINGS_PER_EDGE 2.0
/* The relaxation reaches at most this many times the smoothing's rings: its passes cost as many smoothing
 * passes over a zone that grows with them. */
#define LVP__RELAXATION_RINGS_MOST 4

int32_t lvp__relaxation_rings(const lvp_binding *binding, int32_t smoothing_passes)
{
	if (smoothing_passes <= 0) /* no smoothing asked for: no relaxation either */
		return smoothing_passes;
	double wanted = ceil(LVP__RELAXATION_RINGS_PER_EDGE * binding->fold.deepest);
	double most = (double)LVP__RELAXATION_RINGS_MOST * smoothing_passes;
	return wanted > smoothing_passes ? (int32_t)fmin(wanted, most) : smoothing_passes;
}

/* The map of region r faded at the joint's contact (lvp__fade_map_at_contact). */
static void lvp__fade_region_at_contact(lvp_binding *binding, int32_t r, const lvp__joint *joint)
{
	const float *work = binding->step.positions;
	for (int32_t i = binding->mesh.region_vertex_offsets[r]; i < binding->mesh.region_vertex_offsets[r + 1]; ++i) {
		int32_t k = binding->mesh.region_vertices[i];
		if (!(binding->frame_map.gamma[k] > 0.0f))
			continue;
		double width = 0.5 * binding->map.distance[k];
		if (!(width > 0.0))
			continue; /* on the bone itself (where the map is zero anyway) */
		lvp__vec3 p = lvp__load(work + 3 * k), from_joint = lvp__sub(p, joint->point);
		double across = lvp__dot(from_joint, joint->normal);
		double fade = lvp__smoothstep(-across / width);
		double concave = lvp__dot(from_joint, joint->concave) / width;
		double pressed = lvp__smoothstep(concave);
		/* Skin of the side already across the plane is pressed too: heat weights give a finger's region
		 * some palm skin behind its knuckle, which otherwise bulged into the crease. Not on the convex
		 * side, which nothing presses: a hip bent 90 degrees puts the buttock, skin of the pelvis's region,
		 * across the hip's plane, and its map faded to nothing beside the thigh's bulge left creases. */
		pressed = fmax(pressed, lvp__smoothstep(across / width) * lvp__smoothstep(concave + 1.0));
		pressed *= lvp__across_joint(joint, p);
		binding->frame_map.gamma[k] *= (float)(1.0 - (1.0 - fade) * pressed);
	}
}

/* Where skin crossed at a joint, the flesh pressed against its contact plane does not bulge into
 * it. The map is faded to zero there, over half the vertex's rest distance to its bone, so the
 * extra volume goes into the bulge beside the contact (paper Fig. 10d) instead of pushing skin
 * back across. Only on the concave side of the bend, faded in over the same width from the joint,
 * and only within the joint's reach along its axis: the plane also runs through the convex side,
 * the flanks of the joint and the flesh beside it, where nothing presses the skin, and holding it
 * there left a ridge between held and bulging skin. Only for pairs where skin crossed (a joint
 * bent without contact keeps its bulge), each once a frame. */
bool lvp__fade_map_at_contact(lvp_binding *binding)
{
	const lvp__region_system *system = &binding->system;
	bool faded = false;
	for (int32_t s = 0; s < binding->region_count; ++s)
		for (int32_t n = binding->mesh.neighbour_offsets[s]; n < binding->mesh.neighbour_offsets[s + 1]; ++n) {
			if (binding->fold.contact[n] != LVP__CONTACT_FOUND)
				continue;
			binding->fold.contact[n] = LVP__CONTACT_FADED;
			/* Contacts are marked on the entries that press a side (lvp__mark_contact): its group's regions. */
			faded = true;
			int32_t leader = system->group_leader[s];
			for (int32_t g = system->group_offsets[leader]; g < system->group_offsets[leader + 1]; ++g)
				lvp__fade_region_at_contact(binding, system->group_regions[g], &binding->fold.joints[n]);
		}
	return faded;
}

/* The flesh radius of each region: its vertices' mean rest distance to its bone. */
static void lvp__flesh_radii(lvp_binding *binding)
{
	for (int32_t s = 0; s < binding->region_count; ++s) {
		int32_t first = binding->mesh.region_vertex_offsets[s], end = binding->mesh.region_vertex_offsets[s + 1];
		double sum = 0.0;
		for (int32_t i = first; i < end; ++i)
			sum += lvp__bone_distance(binding, s,
			                          lvp__load(binding->rest_positions + 3 * binding->mesh.region_vertices[i]));
		binding->fold.radius[s] = end > first ? sum / (end - first) : 0.0;
	}
}

/* Counts (fill false) or lists the border vertices of each neighbour entry. */
static void lvp__list_borders(lvp_binding *binding, int32_t *last_vertex, bool fill)
{
	const lvp__mesh *mesh = &binding->mesh;
	int32_t *count = binding->fold.border_offsets;
	for (int32_t s = 0; s < binding->region_count; ++s)
		for (int32_t i = mesh->region_vertex_offsets[s]; i < mesh->region_vertex_offsets[s + 1]; ++i) {
			int32_t k = mesh->region_vertices[i];
			for (int32_t c = mesh->vertex_corner_offsets[k]; c < mesh->vertex_corner_offsets[k + 1]; ++c)
				for (int corner = 0; corner < 3; ++corner) {
					int32_t region = mesh->vertex_region[mesh->triangles[3 * mesh->vertex_triangles[c] + corner]];
					int32_t n = region >= 0 && region != s ? lvp__neighbour_entry(binding, s, region) : -1;
					if (n < 0 || last_vertex[n] == k)
						continue;
					last_vertex[n] = k;
					if (fill)
						binding->fold.border_vertices[count[n]++] = k;
					else
						++count[n + 1];
				}
		}
}

/* The border vertices of each neighbour entry (fold.border_offsets, fold.border_vertices). */
static bool lvp__find_borders(lvp_binding *binding)
{
	bool ok = true;
	size_t entries = (size_t)binding->mesh.neighbour_offsets[binding->region_count];
	int32_t *last_vertex = lvp__calloc(entries + 1, sizeof(int32_t), &ok);
	binding->fold.border_offsets = lvp__calloc(entries + 1, sizeof(int32_t), &ok);
	if (!ok) {
		free(last_vertex);
		return false;
	}
	for (size_t n = 0; n < entries; ++n)
		last_vertex[n] = -1;
	lvp__list_borders(binding, last_vertex, false);
	for (size_t n = 0; n < entries; ++n)
		binding->fold.border_offsets[n + 1] += binding->fold.border_offsets[n];
	binding->fold.border_vertices = lvp__calloc((size_t)binding->fold.border_offsets[entries] + 1, sizeof(int32_t), &ok);
	if (ok) {
		for (size_t n = 0; n < entries; ++n)
			last_vertex[n] = -1;
		lvp__list_borders(binding, last_vertex, true);
		/* Filling advanced each entry's offset to the next one's: shift them back. */
		for (size_t n = entries; n > 0; --n)
			binding->fold.border_offsets[n] = binding->fold.border_offsets[n - 1];
		binding->fold.border_offsets[0] = 0;
	}
	free(last_vertex);
	return ok;
}

/* fold.longest_edge: each vertex's longest edge at the bind's rest. */
static void lvp__longest_edges(lvp_binding *binding)
{
	float *longest = binding->fold.longest_edge;
	for (int32_t t = 0; t < binding->triangle_count; ++t) {
		const int32_t *corners = binding->mesh.triangles + 3 * (int64_t)t;
		for (int i = 0; i < 3; ++i) {
			int32_t a = corners[i], b = corners[(i + 1) % 3];
			float length = (float)lvp__length(lvp__sub(lvp__load(binding->rest_positions + 3 * (int64_t)a),
			                                           lvp__load(binding->rest_positions + 3 * (int64_t)b)));
			longest[a] = fmaxf(longest[a], length);
			longest[b] = fmaxf(longest[b], length);
		}
	}
}

/* fold.mean_edge: each region's vertices' longest edges (fold.longest_edge), averaged. */
static void lvp__mean_edges(lvp_binding *binding)
{
	for (int32_t r = 0; r < binding->region_count; ++r) {
		int32_t first = binding->mesh.region_vertex_offsets[r], end = binding->mesh.region_vertex_offsets[r + 1];
		double sum = 0.0;
		for (int32_t i = first; i < end; ++i)
			sum += binding->fold.longest_edge[binding->mesh.region_vertices[i]];
		binding->fold.mean_edge[r] = end > first ? sum / (end - first) : 0.0;
	}
}

bool lvp__fold_alloc(lvp_binding *binding)
{
	bool ok = true;
	size_t entries = (size_t)binding->mesh.neighbour_offsets[binding->region_count];
	binding->fold.contact = lvp__calloc(entries, 1, &ok);
	binding->fold.joints = lvp__calloc(entries, sizeof(lvp__joint), &ok);
	binding->fold.radius = lvp__calloc((size_t)binding->region_count + 1, sizeof(double), &ok);
	binding->fold.mean_edge = lvp__calloc((size_t)binding->region_count + 1, sizeof(double), &ok);
	binding->fold.plane_entry = lvp__calloc((size_t)binding->region_count + 1, sizeof(int32_t), &ok);
	binding->fold.side_entry = lvp__calloc(entries + 1, sizeof(int32_t), &ok);
	binding->fold.held = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	binding->fold.held_before = lvp__calloc((size_t)binding->vertex_count, 1, &ok);
	binding->fold.zone = lvp__calloc((size_t)binding->vertex_count, sizeof(int32_t), &ok);
	binding->fold.saved = lvp__calloc((size_t)binding->vertex_count * 3, sizeof(float), &ok);
	binding->fold.longest_edge = lvp__calloc((size_t)binding->vertex_count, sizeof(float), &ok);
	if (ok && binding->mode == LVP_MODE_LOCAL) {
		lvp__flesh_radii(binding);
		lvp__longest_edges(binding);
		lvp__mean_edges(binding);
		ok = lvp__find_borders(binding);
	}
	return ok;
}

void lvp__fold_free(lvp__fold *fold)
{
	free(fold->contact);
	free(fold->joints);
	free(fold->radius);
	free(fold->mean_edge);
	free(fold->plane_entry);
	free(fold->side_entry);
	free(fold->held);
	free(fold->held_before);
	free(fold->zone);
	free(fold->saved);
	free(fold->longest_edge);
	free(fold->border_offsets);
	free(fold->border_vertices);
	lvp__plate_free(&fold->plate);
}
