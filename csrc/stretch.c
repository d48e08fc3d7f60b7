/*
 * stretch.c - what each region is corrected to when bones scale against the bones they blend
 * with (squash and stretch, a stretchy chain, an inflated limb). The paper's bones are rigid;
 * lvp.h (ALGORITHM, 3) documents this extension.
 *
 * A region's local volume is measured in its bone's frame, scale included, so skin that
 * follows a scaled bone keeps the volume the scale gives it. Across the weight band between two
 * bones of different scale, though, linear blending interpolates the two sizes, and in either
 * bone's frame the band is larger or smaller than at rest even where the joint is straight:
 * correcting that to zero would dent one side of the joint and swell the other. What the band
 * should keep is the volume it has with the joint unbent, so each region is corrected to the
 * change of a reference pose instead of to zero. For region r and a bone b weighting a corner
 * of r's triangles, the skin of b seen from r's rest frame, F_rb = skin_r^-1 skin_b, has the
 * linear part Q_rb U_rb (polar decomposition: Q_rb a rotation, U_rb the stretch; taken in a
 * frame where a bone that is not scaled only turns: the caller's rigid space, the armature's,
 * or the first bone's rest frame). The reference keeps the stretch about the pair's centre c_rb and
 * drops the rotation and the translation:
 *     y_k = x_k + sum_b omega_kb (U_rb - I) (x_k - c_rb)        (x_k: rest)
 * and region r's target is its local volume change with y in place of the posed positions (the
 * prisms and side quads of local_volume.c; y and x are both at rest, so they are taken in the
 * mesh's coordinates about r's rest origin, in rest-world units). A straight joint whose
 * bones scale about the centre is its own reference, so nothing is corrected there; a bend is
 * corrected to the volume the scales give.
 * c_rb: Blender scales a bone about its head, and a child's head sits on (or near) its parent;
 * of the two heads, the one nearer the other bone's segment (the joint of connected bones).
 * The reference drops translations so that it goes to the identity with the stretch: a target
 * never jumps when a scale animates through 1.
 * Cost: a test per bone in frames where every bone's skin is a rotation times one common scale
 * (nothing stretched against anything: most animation); otherwise a polar decomposition per
 * bone and a pass over the corners, dynamic triangles and border edges of the stretched regions,
 * in groups of regions split over the worker threads.
 */
#include "binding.h"

#include <stdlib.h>

/* Relative size of a stretch that is float noise of the bone matrices, not a scale. */
#define LVP__STRETCH_EPSILON 1e-5

static lvp_result lvp__stretch_out_of_memory(lvp_diagnostic *r_diag)
{
	return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
}

/* Where the relative stretch of bones r and b is taken about (see the top of the file). */
static lvp__vec3 lvp__pair_centre(const lvp_binding *binding, int32_t r, int32_t b)
{
	double head_b_to_r = lvp__bone_distance(binding, r, binding->rig.heads[b]);
	double head_r_to_b = lvp__bone_distance(binding, b, binding->rig.heads[r]);
	return head_b_to_r <= head_r_to_b ? binding->rig.heads[b] : binding->rig.heads[r];
}

lvp_result lvp__build_stretch_pairs(lvp_binding *binding, lvp_diagnostic *r_diag)
{
	int32_t s = binding->region_count, bones = binding->bone_count;
	bool local = binding->mode == LVP_MODE_LOCAL && binding->rig.weight_offsets;
	binding->stretch.offsets = calloc((size_t)s + 1, sizeof(int32_t));
	binding->stretch.bone_entry = malloc(sizeof(int32_t) * LVP__STRETCH_GROUPS * (size_t)(bones > 0 ? bones : 1));
	binding->stretch.change = calloc((size_t)(s > 0 ? s : 1), sizeof(double));
	size_t slots = (size_t)(local && binding->mesh.slot_count > 0 ? binding->mesh.slot_count : 1);
	binding->stretch.corner_offset = malloc(sizeof(float) * 3 * slots);
	binding->stretch.regions = malloc(sizeof(int32_t) * (size_t)(s > 0 ? s : 1));
	binding->stretch.bone_stretch = malloc(sizeof(lvp__mat4) * 2 * (size_t)(bones > 0 ? bones : 1));
	binding->stretch.bone_stretch_invertible = calloc((size_t)(bones > 0 ? bones : 1), 1);
	if (!binding->stretch.offsets || !binding->stretch.bone_entry || !binding->stretch.change ||
	    !binding->stretch.corner_offset || !binding->stretch.regions || !binding->stretch.bone_stretch ||
	    !binding->stretch.bone_stretch_invertible)
		return lvp__stretch_out_of_memory(r_diag);
	for (int32_t i = 0; i < LVP__STRETCH_GROUPS * bones; ++i)
		binding->stretch.bone_entry[i] = -1;
	/* Per region, the distinct bones other than its own weighting the corners of its triangles
	 * (bone_entry marks them with the region while it is walked): counted, then listed. */
	for (int pass = 0; pass < 2; ++pass) {
		int64_t count = 0;
		for (int32_t r = 0; r < s; ++r) {
			binding->stretch.offsets[r] = (int32_t)count;
			if (!local)
				continue;
			for (int32_t i = binding->mesh.region_corner_offsets[r]; i < binding->mesh.region_corner_offsets[r + 1];
			     ++i) {
				int32_t k = binding->mesh.region_corners[i];
				for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
					int32_t bone = binding->rig.weight_bones[e];
					if (bone == r || !(binding->rig.weight_values[e] > 0.0f) || binding->stretch.bone_entry[bone] == r)
						continue;
					binding->stretch.bone_entry[bone] = r;
					if (pass) {
						binding->stretch.bones[count] = bone;
						binding->stretch.centre[count] = lvp__pair_centre(binding, r, bone);
					}
					++count;
				}
			}
			if (count > INT32_MAX)
				return lvp__stretch_out_of_memory(r_diag);
		}
		binding->stretch.offsets[s] = (int32_t)count;
		for (int32_t i = 0; i < bones; ++i)
			binding->stretch.bone_entry[i] = -1;
		if (!pass) {
			size_t entries = (size_t)(count > 0 ? count : 1);
			binding->stretch.bones = malloc(sizeof(int32_t) * entries);
			binding->stretch.centre = malloc(sizeof(lvp__vec3) * entries);
			binding->stretch.linear = calloc(entries, sizeof(lvp__mat4));
			if (!binding->stretch.bones || !binding->stretch.centre || !binding->stretch.linear)
				return lvp__stretch_out_of_memory(r_diag);
		}
	}
	return lvp_success;
}

/* Bone i's skin in the rigid frame: to_rigid skin_i from_rigid (only its linear part is used). */
static lvp__mat4 lvp__rigid_skin(const lvp_binding *binding, int32_t i, const lvp__mat4 *to_rigid,
                                 const lvp__mat4 *from_rigid)
{
	lvp__mat4 half = lvp__mat4_mul(&binding->rig.skin[i], from_rigid);
	return lvp__mat4_mul(to_rigid, &half);
}

/* Whether the bones' skins, in the rigid frame, may stretch some bone against another: false when
 * each is a rotation times one common scale (A^T A = c I for all of them, the same c). A bone
 * scaled to zero counts (c = 0): its region is skipped, but it stretches its neighbours. */
static bool lvp__some_stretch(const lvp_binding *binding, const lvp__mat4 *to_rigid, const lvp__mat4 *from_rigid)
{
	double common = -1.0;
	for (int32_t i = 0; i < binding->bone_count; ++i) {
		lvp__mat4 skin = lvp__rigid_skin(binding, i, to_rigid, from_rigid);
		const double *m = skin.m;
		lvp__vec3 c0 = lvp__v(m[0], m[4], m[8]), c1 = lvp__v(m[1], m[5], m[9]), c2 = lvp__v(m[2], m[6], m[10]);
		double g00 = lvp__dot(c0, c0), g11 = lvp__dot(c1, c1), g22 = lvp__dot(c2, c2);
		double scale2 = (g00 + g11 + g22) / 3.0, tolerance = LVP__STRETCH_EPSILON * scale2;
		if (fabs(g00 - scale2) > tolerance || fabs(g11 - scale2) > tolerance || fabs(g22 - scale2) > tolerance ||
		    fabs(lvp__dot(c0, c1)) > tolerance || fabs(lvp__dot(c0, c2)) > tolerance ||
		    fabs(lvp__dot(c1, c2)) > tolerance)
			return true;
		if (common < 0.0)
			common = scale2;
		else if (fabs(scale2 - common) > LVP__STRETCH_EPSILON * common)
			return true;
	}
	return false;
}

/* Bone i's stretch U_i and its inverse (bone_stretch[2i], [2i+1]): the polar decomposition A = Q U
 * of its skin in the rigid frame (lvp__split_rotation, the one dual quaternion skinning uses).
 * Blender applies a bone's scale before its rotation (and a child's inherited scale with it), so
 * U_i is the bone's scale and Q_i its turn. U_i is always set, also for a bone scaled to zero
 * (U_i = 0); returns whether U_i^-1 is (false for a singular skin). */
static bool lvp__bone_stretch(lvp_binding *binding, int32_t i, const lvp__mat4 *to_rigid,
                              const lvp__mat4 *from_rigid)
{
	lvp__mat4 skin = lvp__rigid_skin(binding, i, to_rigid, from_rigid);
	double a[9], u[9];
	for (int row = 0; row < 3; ++row)
		for (int col = 0; col < 3; ++col)
			a[3 * row + col] = skin.m[4 * row + col];
	lvp__split_rotation(u, a);
	lvp__mat4 *stretch = &binding->stretch.bone_stretch[2 * (size_t)i];
	memset(stretch, 0, sizeof(*stretch));
	stretch->m[15] = 1.0;
	for (int row = 0; row < 3; ++row) /* made exactly symmetric */
		for (int col = 0; col < 3; ++col)
			stretch->m[4 * row + col] = 0.5 * (u[3 * row + col] + u[3 * col + row]);
	return lvp__mat4_invert_affine(stretch + 1, stretch);
}

typedef struct lvp__stretch_context {
	lvp_binding *binding;
	const lvp__mat4 *to_rigid, *from_rigid;
} lvp__stretch_context;

/* Bones [begin, end): each writes only its own stretch. */
static void lvp__bone_stretch_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__stretch_context *c = context;
	for (int32_t i = begin; i < end; ++i)
		c->binding->stretch.bone_stretch_invertible[i] = lvp__bone_stretch(c->binding, i, c->to_rigid, c->from_rigid);
}

/* The stretch of bone b against region r's bone in the mesh's coordinates, U_r^-1 U_b - I taken
 * back from the rigid frame (r_u_minus_i: its linear part; the translation is not used): what
 * F_rb = skin_r^-1 skin_b is once the turns are taken out (F_rb = U_r^-1 Q_r^-1 Q_b U_b).
 * Returns false, with zeros written, when it is the identity to float noise. */
static bool lvp__relative_stretch(lvp__mat4 *r_u_minus_i, const lvp_binding *binding, int32_t r, int32_t b,
                                  const lvp__mat4 *to_rigid, const lvp__mat4 *from_rigid)
{
	const lvp__mat4 *stretch = binding->stretch.bone_stretch;
	lvp__mat4 relative = lvp__mat4_mul(&stretch[2 * (size_t)r + 1], &stretch[2 * (size_t)b]);
	double largest = 0.0;
	for (int row = 0; row < 3; ++row) {
		relative.m[5 * row] -= 1.0; /* the diagonal */
		for (int col = 0; col < 3; ++col)
			largest = fmax(largest, fabs(relative.m[4 * row + col]));
	}
	if (!(largest > LVP__STRETCH_EPSILON)) {
		memset(r_u_minus_i, 0, sizeof(*r_u_minus_i));
		return false;
	}
	lvp__mat4 half = lvp__mat4_mul(&relative, to_rigid);
	*r_u_minus_i = lvp__mat4_mul(from_rigid, &half); /* linear parts multiply alone */
	return true;
}

/* Region r's change in the reference pose (rest-world units, taken in the mesh's coordinates
 * about r's rest origin). bone_entry: the region's entry of each bone (-1 for bones that are
 * not among its pairs, or not stretched against it). The offsets y - x are kept per slot of the
 * region's corners (binding.h), so that regions sharing a vertex can be walked at once. A corner
 * that this frame's skin carries rigidly with r's bone (binding.h, the dynamic set) has only
 * bones that move as r's, so none stretched against it: its offset is zero, and the triangles
 * whose corners are all such (static) add nothing. So the corners' weights are walked only
 * where some bone moves otherwise, and only the dynamic triangles. */
static double lvp__reference_change(lvp_binding *binding, int32_t r, const float *rest, const int32_t *bone_entry)
{
	float *offset = binding->stretch.corner_offset;
	int32_t bone_class = binding->frame_map.skin_class[r];
	for (int32_t i = binding->mesh.region_corner_offsets[r]; i < binding->mesh.region_corner_offsets[r + 1]; ++i) {
		int32_t k = binding->mesh.region_corners[i], slot = lvp__find_slot(binding, k, r);
		if (slot < 0) /* cannot happen: every corner of r's triangles has a slot for r */
			continue;
		if (lvp__carried_rigidly(binding, k, bone_class)) {
			offset[3 * slot] = offset[3 * slot + 1] = offset[3 * slot + 2] = 0.0f;
			continue;
		}
		lvp__vec3 x = lvp__load(rest + 3 * k), d = lvp__v(0.0, 0.0, 0.0);
		for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
			int32_t entry = bone_entry[binding->rig.weight_bones[e]];
			if (entry < 0)
				continue;
			lvp__vec3 v = lvp__sub(x, binding->stretch.centre[entry]);
			d = lvp__add(d, lvp__scale(lvp__transform_vector(&binding->stretch.linear[entry], v),
			                           binding->rig.weight_values[e]));
		}
		offset[3 * slot] = (float)d.x;
		offset[3 * slot + 1] = (float)d.y;
		offset[3 * slot + 2] = (float)d.z;
	}
	/* Only where a corner moved does a prism or side quad have volume. About the bone's rest
	 * origin, as local_volume.c measures. */
	const double *m = binding->rig.rest_matrices[r].m;
	lvp__vec3 o = lvp__v(m[3], m[7], m[11]);
	double volume6 = 0.0;
	for (int32_t i = binding->dynamic.region_offsets[r]; i < binding->dynamic.region_offsets[r + 1]; ++i) {
		int32_t t = binding->dynamic.triangles[i];
		const int32_t *corners = binding->mesh.triangles + 3 * t, *slots = binding->mesh.corner_slot + 3 * t;
		const float *d0 = offset + 3 * slots[0], *d1 = offset + 3 * slots[1], *d2 = offset + 3 * slots[2];
		if (!d0[0] && !d0[1] && !d0[2] && !d1[0] && !d1[1] && !d1[2] && !d2[0] && !d2[1] && !d2[2])
			continue;
		lvp__vec3 x0 = lvp__sub(lvp__load(rest + 3 * corners[0]), o);
		lvp__vec3 x1 = lvp__sub(lvp__load(rest + 3 * corners[1]), o);
		lvp__vec3 x2 = lvp__sub(lvp__load(rest + 3 * corners[2]), o);
		volume6 += lvp__vol6(lvp__add(x0, lvp__load(d0)), lvp__add(x1, lvp__load(d1)), lvp__add(x2, lvp__load(d2))) -
		           lvp__vol6(x0, x1, x2);
	}
	for (int32_t i = binding->borders.offsets[r]; i < binding->borders.offsets[r + 1]; ++i) {
		int32_t a = binding->borders.edges[2 * i], b = binding->borders.edges[2 * i + 1];
		int32_t slot_a = binding->borders.slots[2 * i], slot_b = binding->borders.slots[2 * i + 1];
		if (slot_a < 0 || slot_b < 0) /* as above */
			continue;
		lvp__vec3 da = lvp__load(offset + 3 * slot_a), db = lvp__load(offset + 3 * slot_b);
		if (!da.x && !da.y && !da.z && !db.x && !db.y && !db.z)
			continue;
		lvp__vec3 xa = lvp__sub(lvp__load(rest + 3 * a), o), xb = lvp__sub(lvp__load(rest + 3 * b), o);
		lvp__vec3 unused_a, unused_b;
		volume6 += lvp__side_quad6(&unused_a, &unused_b, lvp__add(xa, da), lvp__add(xb, db), lvp__add(xa, xb),
		                           lvp__cross(xa, xb));
	}
	return volume6 / 6.0;
}

/* What the reference pass of region r costs, in corners, dynamic triangles and border edges. */
static int64_t lvp__reference_work(const lvp_binding *binding, int32_t r)
{
	return (int64_t)(binding->mesh.region_corner_offsets[r + 1] - binding->mesh.region_corner_offsets[r]) +
	       (binding->dynamic.region_offsets[r + 1] - binding->dynamic.region_offsets[r]) +
	       (binding->borders.offsets[r + 1] - binding->borders.offsets[r]);
}

/* Cuts stretch_regions[0..count) into groups of consecutive regions of about equal work; returns
 * the total work. */
static int64_t lvp__cut_reference_groups(lvp_binding *binding, int32_t count)
{
	int64_t total = 0;
	for (int32_t i = 0; i < count; ++i)
		total += lvp__reference_work(binding, binding->stretch.regions[i]);
	int64_t share = total / LVP__STRETCH_GROUPS + 1, done = 0;
	int32_t groups = 0;
	binding->stretch.group_first[0] = 0;
	for (int32_t i = 0; i < count; ++i) {
		done += lvp__reference_work(binding, binding->stretch.regions[i]);
		if (done >= (groups + 1) * share && groups + 1 < LVP__STRETCH_GROUPS && i + 1 < count)
			binding->stretch.group_first[++groups] = i + 1;
	}
	binding->stretch.group_count = count > 0 ? groups + 1 : 0;
	binding->stretch.group_first[binding->stretch.group_count] = count;
	return total;
}

/* Whether a pair's U_r^-1 U_b - I (stretch_linear) is not the zero lvp__stretch_targets leaves
 * for a pair without stretch. */
static bool lvp__pair_stretched(const lvp__mat4 *u_minus_i)
{
	for (int row = 0; row < 3; ++row)
		for (int col = 0; col < 3; ++col)
			if (u_minus_i->m[4 * row + col] != 0.0)
				return true;
	return false;
}

/* Groups [begin, end) of stretched regions, each with its own bone_entry scratch: each region
 * writes only its own slots and its stretch.change, so the groups can run at once. Only the
 * region's stretched pairs get an entry: the others would add zero at every corner. */
static void lvp__reference_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__loop_context *c = context; /* positions: the rest */
	lvp_binding *binding = c->binding;
	for (int32_t group = begin; group < end; ++group) {
		int32_t *bone_entry = binding->stretch.bone_entry + (size_t)group * (size_t)binding->bone_count;
		for (int32_t i = binding->stretch.group_first[group]; i < binding->stretch.group_first[group + 1]; ++i) {
			int32_t r = binding->stretch.regions[i];
			for (int32_t e = binding->stretch.offsets[r]; e < binding->stretch.offsets[r + 1]; ++e)
				if (lvp__pair_stretched(&binding->stretch.linear[e]))
					bone_entry[binding->stretch.bones[e]] = e;
			binding->stretch.change[r] = lvp__reference_change(binding, r, c->positions, bone_entry);
			for (int32_t e = binding->stretch.offsets[r]; e < binding->stretch.offsets[r + 1]; ++e)
				bone_entry[binding->stretch.bones[e]] = -1;
		}
	}
}

bool lvp__stretch_targets(lvp_binding *binding, const float *rest_positions, const float *rigid_space,
                          double tolerance)
{
	int32_t s = binding->region_count;
	bool had_stretch = binding->stretch.any;
	binding->stretch.any = false;
	/* The rigid frame: the caller's, or the first bone's rest frame (the armature's, turned). */
	lvp__mat4 to_rigid, from_rigid;
	if (rigid_space) {
		to_rigid = lvp__mat4_load(rigid_space);
		lvp__mat4_invert_affine(&from_rigid, &to_rigid); /* checked with the options */
	} else if (binding->bone_count > 0) {
		to_rigid = binding->rig.rest_inverse[0];
		from_rigid = binding->rig.rest_matrices[0];
	}
	if (binding->mode != LVP_MODE_LOCAL || binding->stretch.offsets[s] == 0 ||
	    !lvp__some_stretch(binding, &to_rigid, &from_rigid)) {
		if (had_stretch)
			memset(binding->stretch.change, 0, sizeof(double) * (size_t)s);
		return false;
	}
	lvp__stretch_context bones = {binding, &to_rigid, &from_rigid};
	/* an eigen decomposition a bone, as much as some 32 vertices of a mesh pass */
	lvp__parallel_for(LVP__POOL_FOR(binding, 32 * (int64_t)binding->bone_count), lvp__bone_stretch_loop, &bones,
	                  binding->bone_count, 64);
	/* Each pair's relative stretch (zero for the pairs that have none), and the regions with some.
	 * A region is seen from its own bone, which must be invertible (a region whose bone is scaled
	 * to zero is skipped: correction.c); the bones it blends with need not be. A bone scaled to
	 * zero stretches its neighbours' reference by U_b = 0, the limit of a small scale: the band
	 * that collapses with it is what the animator asked for, not a loss for the neighbour to
	 * make up (which would balloon it by the collapsed part's whole volume). */
	int32_t stretched = 0;
	for (int32_t r = 0; r < s; ++r) {
		binding->stretch.change[r] = 0.0;
		if (binding->rig.region_skipped[r] || !binding->stretch.bone_stretch_invertible[r])
			continue;
		bool any = false;
		for (int32_t e = binding->stretch.offsets[r]; e < binding->stretch.offsets[r + 1]; ++e) {
			int32_t bone = binding->stretch.bones[e];
			any = lvp__relative_stretch(&binding->stretch.linear[e], binding, r, bone, &to_rigid, &from_rigid) || any;
		}
		if (any)
			binding->stretch.regions[stretched++] = r;
	}
	if (stretched == 0)
		return false;
	int64_t work = lvp__cut_reference_groups(binding, stretched);
	lvp__loop_context context = {binding, rest_positions ? rest_positions : binding->rest_positions};
	lvp__parallel_for(LVP__POOL_FOR(binding, work), lvp__reference_loop, &context, binding->stretch.group_count, 1);
	/* A stretch that changes no region's volume by more than the tolerance is no squash and stretch
	 * the correction could tell from the volume it restores: the scale keys of exported animations
	 * carry such noise (a glTF horse's bones scaled by 1e-5 against each other in every frame), and
	 * taking it for a stretch gave up restoring the whole mesh (lvp.h, RESTORE). */
	bool matters = false;
	for (int32_t i = 0; i < stretched && !matters; ++i) {
		int32_t r = binding->stretch.regions[i];
		matters = fabs(binding->stretch.change[r]) > tolerance * binding->measure.reference_volume[r];
	}
	if (!matters) {
		for (int32_t i = 0; i < stretched; ++i)
			binding->stretch.change[binding->stretch.regions[i]] = 0.0;
		return false;
	}
	binding->stretch.any = true;
	return true;
}

void lvp__stretch_free(lvp__stretch *stretch)
{
	void *arrays[] = {stretch->offsets, stretch->bones, stretch->centre, stretch->linear, stretch->bone_stretch,
	                  stretch->bone_stretch_invertible, stretch->bone_entry, stretch->corner_offset,
	                  stretch->regions, stretch->change};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
