/*
 * lvp.h - Local Volume Preservation for skinned meshes: the C core and its manual.
 *
 * Implements D. Rohmer, S. Hahmann, M.-P. Cani, "Local volume preservation for skinned
 * characters", Computer Graphics Forum 27(7), 2008: after skinning, each frame is
 * corrected geometrically so that every region of the skin keeps the volume it had at
 * rest, with the displacement concentrated near bending joints (bulges where flesh is
 * squeezed) and without simulation. Pure C11; no global state; no allocation per frame.
 *
 * OVERVIEW
 *
 *   Once, at rest:   lvp_bind()     mesh + weights + skeleton  -> opaque lvp_binding
 *   Every frame:     lvp_correct()  skinned positions + posed bone matrices
 *                                   -> corrected positions and/or offsets
 *   Once, at the end: lvp_free()
 *
 *   Stand-alone helpers over flat arrays (no binding needed): lvp_mesh_volume(),
 *   lvp_volume_gradient(), lvp_vertex_normals(), lvp_skin_linear(), lvp_skin_dual_quaternion(),
 *   lvp_auto_weights().
 *
 * CONVENTIONS
 *
 *   - Output buffers come first in argument lists and are named r_*. Every buffer is owned
 *     by the caller; the size contract is written beside each parameter.
 *   - Positions are float[3] per vertex (x, y, z), packed. Triangles are int32[3], packed,
 *     counter-clockwise seen from outside (either consistent winding works for the volume
 *     correction; automatic weights detect an inward winding from the sign of the volume).
 *   - Matrices are float[16], ROW-MAJOR, acting on column vectors: p' = M p, with the
 *     translation in elements 3, 7, 11 (Blender's Matrix layout, flattened row by row).
 *   - Skinning weights are sparse, in compressed rows (CSR): the influences of vertex k are
 *     bones[offsets[k] .. offsets[k+1]-1] with weights values[...]. Any number per vertex.
 *     Weights need not sum to one: they are normalized by their sum, as Blender's Armature
 *     modifier does.
 *   - Every call that can fail returns an lvp_result and, when r_diag is not NULL, fills it
 *     with the name of the offending argument, the element index and a sentence that says
 *     what is wrong and how to fix it. On failure, outputs are left untouched.
 *
 * ALGORITHM (per frame, local mode)
 *
 *   1. Mesh pass: for every triangle, its area vector; per vertex, the volume gradient
 *      grad_k V = 1/6 sum (p_j - p_k) x (p_l - p_k) and the unit normal n_k = grad_k V / |.|.
 *   2. Local volumes (paper 5.2): every triangle belongs to one region (see SEGMENTATION).
 *      The change of region s is the signed volume of the prisms spanned by its rest and
 *      deformed triangles in the local frame of bone s, each side quad split in four at its
 *      centroid. Sides shared by two triangles of the region cancel exactly, so only the
 *      region's border edges are visited; the rest is two per-region sums (volume and area
 *      vector) that are moved into the bone frame in closed form.
 *   3. Correction (paper eq. 5, generalized to coupled regions): displacements along the
 *      normals, rho_k = gamma_k g_k sum_s phi_ks mu_s, with g_k = <n_k, grad_k V>. The region
 *      multipliers mu solve the small system  sum_t M_st mu_t = dV_s  (M_st = sum_k g_sk gamma_k
 *      g_k phi_kt, g_sk the part of g_k from region s's triangles) over the regions whose
 *      volume changed; unchanged regions cost nothing. With one region this is exactly eq. 5.
 *      M_st can be nonzero only where a corner of s's triangles has a weight of bone t, so
 *      M is stored by its profile, the regions ordered at bind to keep coupled ones close
 *      (reverse Cuthill-McKee: a chain of bones is a band, a bone blending with many comes
 *      after most of them), and solved by LU without pivoting inside that profile.
 *      Where the maps overlap so much that no multipliers tell some regions apart (a tail of
 *      short bones whose every vertex is shared half and half with the next bone: rows
 *      [1 2 1], singular), or a pivot comes out negligible, mu is the damped least-squares
 *      solution (M^T M + 1e-9 diag) mu = M^T dV: the smallest multipliers that come closest,
 *      in one step where the per-region steps of eq. 5 overshoot each other and crawl.
 *   4. The true volumes are measured again and steps 1-3 repeat until every region is within
 *      `tolerance` of its target (step 5) or `max_iterations` is reached: the linearization error
 *      of the paper's single pass is removed, not reported. The gradient of each region's
 *      volume is exact, side quads included, so this converges like Newton's method.
 *   5. The local volumes are estimates (paper 5.2): summed over the mesh they differ from its
 *      true change by what each region border sees from two bone frames (second order in the
 *      bend; 0.4 % of the paper's cylinder at 90 degrees, more for narrow weight bands), and
 *      regions the map cannot move change too. So each step of 3 also adds one multiplier to
 *      every corrected region's, chosen so that the whole mesh's volume, holes capped and
 *      measured with its true gradient, is restored to first order; each region's target
 *      (zero at first) moves by what that multiplier does to it. When every region is at its
 *      target the whole mesh is at its rest volume: no pass is spent on a separate global
 *      step, and each region is left off its rest volume by its part of the difference.
 *      A mesh made of separate parts that bend (see SEGMENTATION) gets one such multiplier per
 *      part: each part is restored to its own rest volume, as it would be alone.
 *      Where such a step makes things worse (many overlapping regions, most of the whole
 *      mesh's change missed by them, as at a shoulder) it is undone, and the frame goes on in
 *      two phases: the regions to their targets, then one multiplier for the whole mesh. A step
 *      that removes less than a tenth of the error is kept and goes on the same way: a Newton
 *      step that achieves so little will not be followed by better ones (degenerate input).
 *      Bones that scale (squash and stretch, a stretchy chain, an inflated limb; not in the
 *      paper, whose bones are rigid): in a frame where some bone's posed frame changes volume
 *      against its rest frame (|det ratio - 1| > 1e-4), or some bone is stretched against a
 *      bone it blends with, the whole mesh has no rest volume to go back to, so this multiplier
 *      is left out. Each region is then corrected to the change it has in a reference pose
 *      where the joints keep their scales and do not bend (stretch.c): each bone's skin is
 *      split into a turn and a stretch (polar decomposition, in lvp_frame_options.rigid_space),
 *      and the stretch of every bone against the region's bone is applied to the rest about
 *      the joint, with the turns left out. A straight joint between a scaled and an unscaled
 *      bone is thus left exactly as skinning makes it (linear blending interpolates the two
 *      sizes across the weight band), and a bend is corrected to the volume the scales give
 *      (the cylinder with its upper bone at x1.2, or stretched 1.5 along it with 0.8 across,
 *      bent by 90 degrees: within 0.4 % of the same cylinder scaled and straight; plain
 *      skinning loses 11 %). Frames where every bone's skin is a rotation times one common
 *      scale skip this with a test per bone.
 *   6. Fold-over prevention (5.4), when enabled: see FOLD-OVER.
 *
 * CORRECTION MAPS (gamma, where the volume goes; paper sections 4 and 5.3)
 *
 *   With w_k = max_i omega_ki (the vertex's largest normalized weight) and d_k the rest
 *   distance from vertex k to the nearest bone segment (optionally among chosen bones only,
 *   per region: paper Fig. 11):
 *     LVP_MAP_ORGANIC (default)  gamma_k = (1 - w_k)^alpha * d_k^beta            (eq. 7)
 *     LVP_MAP_RUBBER             gamma_k = (1 - w_k)^alpha                        (4.2)
 *     LVP_MAP_BOUNDARY_FADE      gamma_sk = max(2 w_k - 1, 0)^alpha * d_k^beta    (eq. 8 literal)
 *     LVP_MAP_PAINTED            gamma_k = the caller's per-vertex values (>= 0)
 *     LVP_MAP_UNIFORM            gamma_k = 1                                       (eq. 4)
 *   How a region's correction is spread (phi_ks), and why:
 *     For every map except BOUNDARY_FADE, region s's multiplier reaches vertex k in proportion
 *     to k's normalized skinning weight on bone s: phi_ks = omega_ks. The region corrections
 *     are therefore blended exactly like the bones themselves, so the total displacement is
 *     continuous across region borders whatever the multipliers of two neighbours are, and
 *     the map can stay largest at the joint, where the volume is lost. Vertices that follow
 *     one bone rigidly (w_k = 1) have gamma_k = 0 and never move.
 *     BOUNDARY_FADE is the paper's eq. 8 read literally: phi_ks = 1 on region s only, and the
 *     map itself fades to zero at region borders. It is continuous too, but it is largest in
 *     the middle of each region, far from the joint, so it inflates limbs rather than joints
 *     (paper Fig. 2b); it is kept for comparison and measured in the tests.
 *   Where the skin moved rigidly, nothing moves (deformation weighting, on by default in local
 *   mode): each frame the map is multiplied by a_k = sum_i omega_ki |S_i pbar_k - sum_j omega_kj
 *   S_j pbar_k| (S_i = T_i Tbar_i^-1), how far the vertex's bones disagree about where it goes.
 *   It is zero where all of a vertex's bones move together and largest at bending joints, so a
 *   region's fix stays near the joint that bent even when artist weights scatter the region
 *   over the body (the giraffe's root bone has weight from the tail to the shoulders); like
 *   the weights, it is continuous over the surface.
 *   Smoothness: every map is a continuous function of the skinning weights and of distances
 *   to bone segments, evaluated per vertex, so it is as smooth as the weights are. alpha >= 1
 *   keeps the onset of the correction C1 where a weight band begins.
 *
 * SEGMENTATION (paper 5.2)
 *
 *   Region s is the set of vertices whose largest normalized weight is on bone s (ties go to
 *   the lower bone index). A triangle belongs to the region of the bone that has the largest
 *   sum of weights over its three corners (ties: lower bone index). This rule is symmetric in
 *   the corners, gives every triangle exactly one region, and agrees with the vertex regions
 *   whenever two corners agree. Vertices without any weight belong to no region (-1): they
 *   never move; a triangle whose three corners have no weight belongs to no region.
 *   Separate parts (a body and its clothes, two limbs modelled apart, in one mesh): a connected
 *   part of the triangles bends when its vertices have weight on two bones or more. When two
 *   parts or more bend, each bone's region is split by part: the first part that bends (by
 *   vertex order) keeps the bones' own regions, and every other one gets its own region for
 *   each bone it uses, so that one part cannot keep a region's volume at the expense of
 *   another (measured together, of two limbs side by side bent 90 degrees, the one further from
 *   the bones took more of the organic map: +7 % and -7 %). Parts one bone carries rigidly (an
 *   eye, a tooth) stay in their bone's region: they keep no volume change to correct. The
 *   public API still speaks of one region per bone: lvp_get_segmentation() gives a vertex its
 *   bone, lvp_region_volume_changes() sums a bone's parts, and worst_region names the bone of
 *   the worst part. Past LVP_MAX_BONES regions in all (thousands of bent hair cards), the
 *   remaining parts stay in their bones' regions. Bind: O(E log E) for E weight entries.
 *   In LVP_MODE_GLOBAL there is one region: the whole mesh, measured with the plain
 *   divergence formula (paper eq. 1/4), which needs a closed mesh.
 *
 * FOLD-OVER (paper 5.4)
 *
 *   For the vertices of regions whose bone bends against a neighbouring bone (a bone that
 *   shares influence with the region), the bone of main influence is recomputed on the posed
 *   skeleton: vertex k of region s has crossed into neighbour j when it is closer to j's posed
 *   segment than to s's (d_kj < d_ks), while at rest it was on its own side. This is 5.1's
 *   weight comparison with the length factor left out: with it, the contact surface would curl
 *   around the shorter bone; without it, near a joint it is the bisector plane of the bend.
 *   A crossed vertex goes back the shortest way, along -grad(d_ks - d_kj) (orthogonal to the
 *   bisector plane, which keeps the crossed skin untangled), to the contact surface, found by
 *   bisection to float precision, plus a gap of 1e-4 of the two bone lengths. The step adapts
 *   to the flesh: there is no fixed step to tune and no flesh width it must stay below. Then
 *   the extra volume step runs with the moved vertices held and the map faded to zero within
 *   half the flesh depth of the contact surface, on the concave side of the bend of each pair
 *   of bones where skin crossed (the contact surface also runs through the convex side and the
 *   flanks of the joint, where nothing presses the skin: holding it there would leave a ridge
 *   between held and bulging skin), so the extra volume becomes a bulge beside the contact
 *   (paper Fig. 10d) rather than pushing skin back across; contact test and volume step
 *   alternate up to 4 more rounds, the map faded at each new contact. Limits: two parts of one
 *   bone's flesh, and bones that are not neighbours (a fingertip folded onto the palm), are not
 *   separated, and moving skin back towards its own bone there can add crossings; a crease
 *   pressed flatter than the bisector plane can hold (a finger folded past about 100 degrees
 *   with a 0.2-wide weight band) may still fold after projection. Where two bones lie on top
 *   of each other (a joint folded to 180 degrees) there is no contact surface, and a vertex
 *   whose contact surface is further than a quarter of the rest mesh's size (bones posed far
 *   from their skin) is not moved: such vertices are left where they are.
 *
 * FALLBACKS (defined outcomes for awkward input; everything else is an error)
 *
 *   - Zero-area triangles and triangles that repeat a vertex contribute nothing.
 *   - Isolated vertices (in no triangle) have no normal and are never moved.
 *   - Open and non-manifold meshes work in local mode: an edge whose exact opposite half-edge
 *     is not found once in the same region is treated as a region border and gets its side
 *     quad. LVP_MODE_GLOBAL refuses them (lvp_error_mesh_not_closed).
 *   - Zero-length bones are treated as points: distances go to the head; they never receive
 *     automatic weights and take no part in fold-over detection.
 *   - A posed bone matrix that is singular (a bone scaled to zero) leaves its region
 *     uncorrected for that frame, and the frame's stats count it. The regions it blends with
 *     are corrected as at a vanishing scale (its stretch against them is U = 0): the band that
 *     collapses with it is not made up for.
 *   - Regions whose map is zero everywhere (fully rigid) cannot move and are left as they are.
 *   - Poses folded onto themselves (a joint bent near 180 degrees): a step moves a vertex by at
 *     most a quarter of the mesh's size, a step that makes the regions' volumes worse is undone and ends
 *     the iteration, and if anything still went non-finite the frame is passed through
 *     unchanged with stats.passed_through set.
 *   - Positions that are not the skinning of the rest by the bound weights and the given bones
 *     (bone frames other than those that moved the mesh, weights changed since the bind): a
 *     sample of the vertices one bone class carries is checked every frame, and where one is off
 *     by more than float rounding the frame is measured from the positions alone (slower: every
 *     triangle is measured) and stats.unskinned_distance says by how much.
 *
 * THREADS AND MEMORY
 *
 *   No global state. A binding owns all of its memory (sized at bind, O(N + F + E + W + B), W
 *   the weights, and the region system's at most 65,536 cells, see PERFORMANCE) and
 *   is used by one thread at a time; two bindings can be used from two threads at once.
 *   lvp_correct() never allocates. With options.thread_count > 1 a binding keeps that many
 *   worker threads, created by lvp_bind() and joined by lvp_free(); results are identical
 *   for every thread count (reductions use a fixed partition).
 *
 * PERFORMANCE
 *
 *   Per frame, bones whose skin matrices agree (to 1e-6) form one class. A triangle whose
 *   three corners are moved by one class only, the class of its region's bone, and that the
 *   map does not let move, is static: in its bone's frame it is its rest triangle, so it
 *   enters the region sums through its rest sums moved by the bone in closed form, and no
 *   pass visits it. The passes visit the dynamic rest: in a pose bent at a few joints, the
 *   skin around those joints. (This is where `positions` being the skinning of the rest, as
 *   lvp_correct() says, is relied on: a vertex weighted to one bone is where that bone puts
 *   it.) Which triangles are static is kept from one frame to the next while the same bones
 *   move (the classes of the bones and of every vertex unchanged, no frame rest given, no
 *   fold-over contact): in an animation it is found again only when other joints start or stop
 *   bending, and until then the other vertices are only copied from input to output. Per
 *   iteration: one pass over the dynamic triangles, region by region (or over the
 *   triangles around the moved vertices, when they are few) and, when a step follows, two
 *   over the dynamic vertices (their gradients, then the active regions' system) and one to
 *   move them, plus a solve of the active regions' system within its profile (a chain of m
 *   regions costs O(m), regions coupled all with all m^3/3). The profile is stored in at most
 *   65,536 cells (3 a region in a chain: some 21,000 regions; 256 coupled all with all); the
 *   regions past what fits take the per-region step of eq. 5 and the next iteration goes on
 *   from there. Bind: O(N B) for maps and, in lvp_auto_weights(), O(N B) for the normal test
 *   or O(N B log F) for the exact test.
 */
#ifndef LVP_H
#define LVP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LVP_VERSION_MAJOR 0
#define LVP_VERSION_MINOR 1
#define LVP_VERSION_PATCH 0

/* Hard limits, far above any real rig, that keep every size computation in range. */
#define LVP_MAX_VERTICES (1 << 26)
#define LVP_MAX_TRIANGLES (1 << 27)
#define LVP_MAX_BONES (1 << 16)
#define LVP_MAX_THREADS 64

typedef enum lvp_result {
	lvp_success = 0,
	lvp_error_null_argument,      /* a required pointer is NULL */
	lvp_error_invalid_size,       /* a count is zero, negative, above a limit, or inconsistent */
	lvp_error_index_out_of_range, /* a vertex or bone index is outside [0, count) */
	lvp_error_not_finite,         /* a NaN or an infinity in a float input */
	lvp_error_negative_weight,    /* a skinning weight or painted map value is below zero */
	lvp_error_invalid_option,     /* an option is outside its documented range */
	lvp_error_singular_matrix,    /* a rest bone matrix cannot be inverted */
	lvp_error_mesh_not_closed,    /* LVP_MODE_GLOBAL on a mesh with border or non-manifold edges */
	lvp_error_no_weights,         /* local mode, but no vertex has any weight */
	lvp_error_out_of_memory,
	lvp_error_thread,             /* worker threads could not be started */
	lvp_result_count
} lvp_result;

/* A short constant name for a result ("lvp_error_not_finite"). Never NULL. */
const char *lvp_result_name(lvp_result result);

/* Where and why a call failed. All fields are filled on failure; untouched on success. */
typedef struct lvp_diagnostic {
	const char *argument; /* the parameter or field at fault, e.g. "triangles" (static string) */
	int64_t index;        /* the element at fault, or -1 */
	char message[256];    /* a full sentence: what is wrong and how to fix it */
} lvp_diagnostic;

/* ---------------------------------------------------------------------------------------
 * Mesh geometry (paper 3.1). Stand-alone; validate their input like everything else.
 * ------------------------------------------------------------------------------------- */

/* Signed volume 1/6 sum p_i . (p_j x p_k) of a triangle mesh, in double precision.
 * Positive when triangles wind counter-clockwise seen from outside. Meaningful for closed
 * meshes; for open ones it depends on the origin. */
lvp_result lvp_mesh_volume(double *r_volume, const float *positions, int32_t vertex_count,
                           const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag);

/* Per-vertex volume gradient: r_gradient (vertex_count*3 floats) receives
 * 1/6 sum over the triangles (k, j, l) around k of (p_j - p_k) x (p_l - p_k), which equals the
 * exact dV/dp_k on closed manifold meshes and stays translation-invariant on open ones. */
lvp_result lvp_volume_gradient(float *r_gradient, const float *positions, int32_t vertex_count,
                               const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag);

/* Unit area-weighted vertex normals (vertex_count*3 floats); zero for isolated vertices and
 * for vertices whose triangles all have zero area. */
lvp_result lvp_vertex_normals(float *r_normals, const float *positions, int32_t vertex_count,
                              const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag);

/* ---------------------------------------------------------------------------------------
 * Skinning (paper eq. 6, and dual quaternion skinning)
 * ------------------------------------------------------------------------------------- */

typedef struct lvp_weights {
	const int32_t *offsets; /* vertex_count + 1 entries, offsets[0] = 0, non-decreasing */
	const int32_t *bones;   /* offsets[vertex_count] bone indices in [0, bone_count) */
	const float *values;    /* offsets[vertex_count] weights >= 0 */
} lvp_weights;

/* Linear blend skinning: r_positions[k] = sum_i w_ki (posed_i * rest_i^-1) rest_positions[k],
 * with the weights normalized by their sum. skin_matrices are the products posed_i * rest_i^-1,
 * bone_count*16 floats (bone_count >= 1; the last row of each matrix is ignored). Vertices
 * without weight keep their rest position. r_positions (vertex_count*3) must not overlap the
 * inputs: an overlap is refused with lvp_error_invalid_option. */
lvp_result lvp_skin_linear(float *r_positions, const float *rest_positions, int32_t vertex_count,
                           const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                           lvp_diagnostic *r_diag);

/* Dual quaternion skinning (Kavan et al.), as Blender's "Preserve Volume": the rigid part of
 * each skin matrix is blended as a dual quaternion (shortest path to the vertex's strongest
 * bone), the remaining scale/shear part linearly, applied first. Same contract as above. */
lvp_result lvp_skin_dual_quaternion(float *r_positions, const float *rest_positions, int32_t vertex_count,
                                    const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                                    lvp_diagnostic *r_diag);

/* ---------------------------------------------------------------------------------------
 * Skeleton
 * ------------------------------------------------------------------------------------- */

typedef struct lvp_skeleton {
	int32_t bone_count;
	const float *rest_matrices; /* bone_count*16: the bone frames at rest (T-bar_i), invertible */
	const float *heads;         /* bone_count*3: rest position of the bone segment's start */
	const float *tails;         /* bone_count*3: rest position of its end (may equal the head) */
} lvp_skeleton;

/* ---------------------------------------------------------------------------------------
 * Automatic skinning weights (paper 5.1)
 * ------------------------------------------------------------------------------------- */

typedef enum lvp_visibility {
	LVP_VISIBILITY_NORMAL = 0, /* the paper's cheap test: angle between path and normal */
	LVP_VISIBILITY_EXACT,      /* the path is tested against the mesh (bounding volume hierarchy) */
	LVP_VISIBILITY_NONE        /* every bone sees every vertex */
} lvp_visibility;

typedef struct lvp_auto_weights_options {
	float alpha;            /* omega_ki = (l_i / d_ki)^alpha; > 0, default 2 */
	lvp_visibility visibility;
	float normal_cos_max;   /* NORMAL test: bone i is hidden from vertex k when the unit path
	                           from k to its closest point on bone i has cos(path, outward
	                           normal) > normal_cos_max; in [-1, 1], default 0 (path must go
	                           inward) */
	int32_t max_influences; /* keep the strongest ones, renormalized; 0 = all, default 4 */
	float min_weight;       /* drop normalized weights below this, renormalize; default 0.01 */
} lvp_auto_weights_options;

lvp_auto_weights_options lvp_auto_weights_default_options(void);

/* Upper bound on the number of influences lvp_auto_weights() can write (for sizing). */
int64_t lvp_auto_weights_bound(int32_t vertex_count, int32_t bone_count, const lvp_auto_weights_options *options);

/* Computes weights by 5.1: distance to the bone segment (not to the joint), a visibility test
 * per (vertex, bone), the rigid fallback (a vertex that sees no bone gets weight 1 on its
 * closest bone with a length; a zero-length one only when the skeleton has no other), then
 * normalization. Zero-length bones get no weight. Distances below 1e-6 of a bone's length
 * count as that (a vertex on a bone is all its; on a joint, split evenly). When min_weight
 * would drop every bone of a vertex, its strongest one is kept. options may be NULL (defaults).
 * r_offsets: vertex_count+1; r_bones and r_values: capacity entries (use
 * lvp_auto_weights_bound(); a smaller capacity works through a temporary buffer of up to
 * `capacity` entries and fails, outputs untouched, with the needed size if it is too small).
 * Rows are sorted by decreasing weight. */
lvp_result lvp_auto_weights(int32_t *r_offsets, int32_t *r_bones, float *r_values, int64_t capacity,
                            const float *positions, int32_t vertex_count, const int32_t *triangles,
                            int32_t triangle_count, const lvp_skeleton *skeleton,
                            const lvp_auto_weights_options *options, lvp_diagnostic *r_diag);

/* ---------------------------------------------------------------------------------------
 * Binding and per-frame correction
 * ------------------------------------------------------------------------------------- */

typedef enum lvp_mode {
	LVP_MODE_LOCAL = 0, /* one region per bone (paper 5.2-5.3): characters */
	LVP_MODE_GLOBAL     /* one region, the whole closed mesh (paper 3.2-3.3): props */
} lvp_mode;

typedef enum lvp_map {
	LVP_MAP_ORGANIC = 0,
	LVP_MAP_RUBBER,
	LVP_MAP_BOUNDARY_FADE,
	LVP_MAP_PAINTED,
	LVP_MAP_UNIFORM
} lvp_map;

typedef struct lvp_map_options {
	lvp_map map;
	float alpha;                    /* >= 0, default 1 */
	float beta;                     /* >= 0, default 1 */
	const float *painted;           /* LVP_MAP_PAINTED: vertex_count values >= 0; else ignored */
	/* Optional restriction of the distance term per region (paper Fig. 11): for region s,
	 * d_k is measured to the bones region_bones[region_bone_offsets[s] ..
	 * region_bone_offsets[s+1]-1] only. Both NULL = all bones for every region; an empty
	 * list for a region also means all bones. region_bone_offsets has bone_count+1 entries. */
	const int32_t *region_bone_offsets;
	const int32_t *region_bones;
	int32_t deformation_weighted; /* nonzero (default): multiply by a_k each frame, local mode */
} lvp_map_options;

typedef struct lvp_bind_options {
	lvp_mode mode;
	lvp_map_options map;
	int32_t thread_count; /* worker threads for lvp_correct(); 1..LVP_MAX_THREADS, default 1 */
} lvp_bind_options;

lvp_bind_options lvp_bind_default_options(void);

typedef struct lvp_binding lvp_binding; /* opaque */

/* Binds a mesh to its skeleton and weights at rest: validates everything, segments the mesh,
 * builds the correction map, the region borders and every rest-side constant, and allocates
 * all per-frame work memory. In LVP_MODE_GLOBAL, weights and skeleton may be NULL (bone_count
 * 0) unless the map needs them (ORGANIC, RUBBER, BOUNDARY_FADE need them; UNIFORM and PAINTED
 * do not). The inputs are copied: the caller may free them after the call.
 * On success *r_binding receives a binding to release with lvp_free(). */
lvp_result lvp_bind(lvp_binding **r_binding, const float *rest_positions, int32_t vertex_count,
                    const int32_t *triangles, int32_t triangle_count, const lvp_weights *weights,
                    const lvp_skeleton *skeleton, const lvp_bind_options *options, lvp_diagnostic *r_diag);

void lvp_free(lvp_binding *binding); /* NULL is allowed */

/* Replaces the correction map without rebinding (an artist changing alpha, beta or the
 * painted map). Same validation as lvp_bind(). */
lvp_result lvp_set_map(lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag);

int32_t lvp_vertex_count(const lvp_binding *binding);
int32_t lvp_triangle_count(const lvp_binding *binding);
int32_t lvp_bone_count(const lvp_binding *binding);
int32_t lvp_region_count(const lvp_binding *binding); /* bone_count in local mode, 1 in global */
/* Edges shared by two triangles wound the same way: their faces' normals point opposite ways, and
 * local volumes across them are wrong (the correction there is weak or missing). 0 for a
 * consistently oriented mesh; recalculate the normals (outside) when it is not. */
int32_t lvp_flipped_edge_count(const lvp_binding *binding);

/* The segmentation: r_vertex_regions (vertex_count) and/or r_triangle_regions (triangle_count)
 * receive region indices, -1 for "no region". Either may be NULL. */
void lvp_get_segmentation(const lvp_binding *binding, int32_t *r_vertex_regions, int32_t *r_triangle_regions);

/* The correction map gamma_k per vertex (vertex_count floats), normalized so its maximum is 1
 * (all zeros when the map is zero everywhere): what the viewport shows as a colour. */
void lvp_get_correction_map(const lvp_binding *binding, float *r_map);

typedef struct lvp_frame_options {
	int32_t max_iterations; /* correction steps per volume correction, 1..1000, default 8; 1 is
	                           the paper's single pass. Fold-over runs up to 4 more volume
	                           corrections, each with this budget. */
	float tolerance;        /* stop when every region is within tolerance * its reference volume
	                           of its target (ALGORITHM, 5); > 0, default 1e-4 (0.01 %) */
	int32_t fold_over;      /* nonzero: fold-over prevention (local mode only), default 0 */
	const float *rigid_space; /* NULL (default), or 16 floats (row-major, like the bone matrices): the
	                           map from the mesh's coordinates to a space where a bone that is not
	                           scaled only turns (the armature's), used to tell a bone's scale from
	                           its bend (ALGORITHM, 5). NULL: the first bone's rest frame (the
	                           armature's, turned), which is right unless the mesh has been scaled
	                           unevenly against the armature since the bind. Its 3x3 part must be
	                           invertible. */
} lvp_frame_options;

lvp_frame_options lvp_frame_default_options(void);

typedef struct lvp_frame_stats {
	double volume_rest;       /* signed mesh volume at rest (divergence formula) */
	double volume_before;     /* of the input positions */
	double volume_after;      /* of the corrected positions */
	int32_t worst_region;     /* region with the largest relative change before correction, -1 if none
	                             (of separate parts, the part's bone: SEGMENTATION) */
	double worst_region_change_before; /* its (V - V_rest) / V_ref, signed; where bones are scaled
	                                      against each other, less the change their scales give it
	                                      (ALGORITHM, 5) */
	double worst_region_change_after;
	int32_t iterations;       /* correction steps done, fold-over rounds included */
	int32_t active_regions;   /* regions whose volume had changed (corrected), first pass; a bone's
	                             region in each separate part counts once */
	int32_t skipped_regions;  /* regions left as they were: their posed bone is singular (scaled to zero) */
	int32_t folded_vertices;  /* vertices moved back to a contact surface */
	double max_displacement;  /* largest |offset| written */
	int32_t passed_through;   /* 1 when no finite correction was found (a pose folded onto itself):
	                             the input was written back unchanged */
	double unskinned_distance; /* 0, or how far the positions put a vertex that one bone carries from
	                              where that bone puts it, when that is more than float rounding:
	                              the positions are not the skinning of the rest by these bones and
	                              the bound weights (see lvp_correct), and the frame was measured
	                              from the positions alone, without the closed form for rigid parts */
} lvp_frame_stats;

/* Corrects one frame. positions: vertex_count*3, the skinned (deformed) positions, e.g. what
 * leaves Blender's Armature modifier: the rest (or rest_positions) skinned by the bound
 * weights and these bones, linear or dual quaternion (see PERFORMANCE). bone_matrices:
 * bone_count*16, the posed bone frames T_i in the same space as the rest matrices (may be NULL
 * in LVP_MODE_GLOBAL). rest_positions: NULL to use the bind rest, or vertex_count*3 of this
 * frame's un-skinned positions (shape keys), against which volumes are then compared.
 * Outputs (vertex_count*3 each, at least one non-NULL): r_positions, the corrected positions
 * (may be the same buffer as positions), and r_offsets, corrected minus input.
 * r_stats may be NULL. No allocation; O(1) stack. */
lvp_result lvp_correct(float *r_positions, float *r_offsets, lvp_binding *binding, const float *positions,
                       const float *bone_matrices, const float *rest_positions, const lvp_frame_options *options,
                       lvp_frame_stats *r_stats, lvp_diagnostic *r_diag);

/* Local volume changes of every region for given positions, without correcting anything:
 * r_changes (region_count doubles) receives V_s - V_s,rest by the prism sum of 5.2 (in the
 * global mode: V - V_rest; a bone's region in separate parts: the sum over the parts).
 * r_references (region_count, may be NULL) receives the reference volumes used by the
 * tolerance (summed the same way). Same inputs as lvp_correct(). */
lvp_result lvp_region_volume_changes(double *r_changes, double *r_references, lvp_binding *binding,
                                     const float *positions, const float *bone_matrices,
                                     const float *rest_positions, lvp_diagnostic *r_diag);

#ifdef __cplusplus
}
#endif

#endif /* LVP_H */
