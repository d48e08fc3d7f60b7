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
 * ALGORITHM (per frame, local mode; docs/method.md derives each step)
 *
 *   1. Measure: every triangle belongs to one region, a bone's (SEGMENTATION); the volume change
 *      of each region is the volume between its rest and its posed triangles in its bone's frame
 *      (paper 5.2), exact, holes capped.
 *   2. Correct: vertex k moves along its normal n_k by rho_k = gamma_k (g_k / A_k) sum_s phi_ks mu_s
 *      (paper eq. 5 for coupled regions): gamma the correction map (CORRECTION MAPS), g_k =
 *      <n_k, grad_k V>, A_k the vertex's rest area (a third of its triangles'), phi_ks the share
 *      of region s's correction at k, and one multiplier mu_s per region (GROUPS), from a linear
 *      system over the regions whose volume changed. Dividing by A_k makes this the smallest
 *      displacement measured over the surface (the paper's sum of rho_k^2 counts vertices, so its
 *      bulge follows the tessellation: each quad's diagonal ends pushed further than its others).
 *   3. Repeat 1-2 until every region is within `tolerance` of its target, or `max_iterations`
 *      steps are taken. A region's target is zero change plus its share of restoring the whole
 *      mesh's volume (each separate part's, see SEGMENTATION). In a frame where bones scale
 *      (squash and stretch; the paper's bones are rigid) the target is instead the change the
 *      bones' scales alone give the region, and the whole mesh keeps the scaled volume; a
 *      stretch that changes no region's volume by more than the tolerance is none (exporters
 *      round scale keys).
 *   4. Smoothing the offsets, when enabled: see OFFSET SMOOTHING.
 *   5. Fold-over prevention (paper 5.4), when enabled: see FOLD-OVER.
 *   6. Keeping skin apart, when enabled: see CONTACT.
 *
 * RESTORE (lvp_frame_options.restore, local mode)
 *
 *   LVP_RESTORE_EACH_REGION (default) is 1-3 above: each region's multiplier from the coupled
 *   system, each region back to its own volume. LVP_RESTORE_WHOLE_MESH gives every region one
 *   and the same multiplier (per separate part), found as in the paper's global correction
 *   (3.2-3.3) with the local maps: the lost volume goes back where joints bend, in proportion to
 *   the map there (deformation weighting makes it zero where nothing bends), and the whole mesh
 *   (each part) ends at its rest volume, within `tolerance` of the reference volumes of the
 *   groups whose estimate changed by more than it (the flesh that bent: a wrist on a whole body
 *   is held to the hand's volume, not the body's); each region does not. The region estimates
 *   of step 1 serve only that and the report. Why it exists: where joints bend hard (past about 90 degrees) the
 *   estimates are off by a large share of the loss (what each region border sees from two bone
 *   frames: on a Rigify human with hips and knees bent hard, the regions' changes sum to 1.4 to
 *   1.6 times the whole body's), and restoring each region to them gives neighbouring regions
 *   multipliers of opposite signs: bulges beside dents, creases, skin pushed into skin, and
 *   jumps when a region's step fails. One multiplier cannot do that; docs/method.md measures both.
 *   In frames where bones scale (squash and stretch) there is no rest volume for the whole mesh
 *   and each region is restored, as with LVP_RESTORE_EACH_REGION; so is a frame that gives a group
 *   up (DEGRADING: only for moving skin beyond the limit, one multiplier never holds another back),
 *   without it and without the whole mesh's volume.
 *
 * SEAMS (one point of the skin, many vertices)
 *
 *   Meshes from glTF, FBX or caches arrive split along their UV seams and hard edges: several
 *   vertices at one position. lvp_bind() finds them with no option to set: vertices at the same
 *   rest position (bit for bit, -0 as +0) that share a split edge (each has a neighbour at the
 *   same position as one of the other's) are one point, and every quantity of the method
 *   (normals, gradients, regions and their borders, parts, the maps, fold-over) is computed on
 *   the points: a split mesh is corrected as its welded version is, to float rounding. A point
 *   takes the weights, the painted map value and each frame's position of its first vertex (the
 *   lowest index); its offset goes to every vertex of the point, so no crack opens. Shells that
 *   only touch at a vertex stay apart. The API still speaks of the caller's vertices:
 *   lvp_vertex_count(), the per-vertex outputs and the arrays the calls take.
 *
 * BONE LINES (where each bone runs through its flesh at rest)
 *
 *   The method measures distances to the bones (the organic map's d, the bulge's reach, the
 *   flesh radius, an open region's reference volume) and bends skin about them (fold-over).
 *   Skinning moves the skin by the heads, the weights and the bones' transforms alone, never by
 *   a tail or a roll, which importers guess; so the core takes each bone's line from the joints
 *   and the skin, and the same skinning gives the same correction however the tails and rolls
 *   point. Each bone's line is a segment from its head: to its child's head (lvp_skeleton.parents;
 *   children that carry no weight or sit at the head do not count), to the mean of its
 *   children's heads when it has several (a palm down the middle of the hand), and for a bone
 *   without children through the area-weighted centroid of the skin it dominates to as far
 *   beyond (a fingertip to the tip); a bone that dominates no skin is a point at its head.
 *   Without parents every bone is taken as one without children. The joints of a B-Bone (bones
 *   grouped by lvp_bind_options.bone_groups) keep the caller's head and tail, whose curve does
 *   move the skin, and a bone whose tail is its head is a point.
 *
 * CORRECTION MAPS (gamma: where the volume goes; paper 4 and 5.3)
 *
 *   With w_k = max_i omega_ki (the vertex's largest normalized weight) and d_k the rest
 *   distance from vertex k to the nearest bone line (BONE LINES; optionally among chosen bones
 *   only, per region: paper Fig. 11):
 *     LVP_MAP_ORGANIC (default)  gamma_k = (1 - w_k)^alpha * d_k^beta            (eq. 7)
 *     LVP_MAP_RUBBER             gamma_k = (1 - w_k)^alpha                        (4.2)
 *     LVP_MAP_BOUNDARY_FADE      gamma_sk = max(2 w_k - 1, 0)^alpha * d_k^beta    (eq. 8 literal)
 *     LVP_MAP_PAINTED            gamma_k = the caller's per-vertex values (>= 0)
 *     LVP_MAP_UNIFORM            gamma_k = 1                                       (eq. 4)
 *   phi_ks = omega_ks, the normalized skinning weight of vertex k on bone s, for every map but
 *   BOUNDARY_FADE (phi_ks = 1 on region s only): the displacement is blended like the bones
 *   and is continuous across region borders. Vertices that follow one bone rigidly (w_k = 1)
 *   never move. With deformation weighting (default in local mode) the map is multiplied each
 *   frame by how far the vertex's bones disagree about where it goes: zero where they move
 *   together, so nothing moves where the skin moved rigidly. A vertex whose a_k is zero while most
 *   of its neighbours move (a hole or a bay in the moving skin: painted weights that name one bone
 *   inside a blend, a bending bone that is the ninth of its row and the eighth of its neighbours',
 *   the joints of a B-Bone that carry it alike to float noise) takes the mean of its neighbours'
 *   map instead, so no vertex is held back from the skin that moves around it; at bind, likewise, a
 *   vertex whose ORGANIC map is zero though its row blends bones (a bone's line through it) while more
 *   than half of the corners around it are not takes their mean. Every map is as smooth over the
 *   surface as the weights are.
 *
 * GROUPS (one multiplier for several bones)
 *
 *   lvp_bind_options.bone_groups joins bones that are one bone to the animator: the joints of a
 *   B-Bone, which share its weights between them (a vertex between joints i and i + 1 moves with
 *   both). Each joint keeps its region and is measured in its own frame, but the regions of a
 *   group are corrected as one: one multiplier, aiming at the sum of their changes. Corrected
 *   apart, neighbouring joints of one bone are nearly indistinguishable to the correction, and
 *   their multipliers pull against each other (a ridge where one bone should bulge smoothly).
 *   A group's regions stay apart in separate parts (SEGMENTATION). Fold-over takes a group as
 *   one side of a joint, one plane and one press a pass (FOLD-OVER). Stats and warnings speak of
 *   the group by its first bone.
 *
 * BULGE WIDTH (how far a region's correction spreads)
 *
 *   phi_ks above is the skinning weight, so a region's correction stays in the band where its
 *   weights blend: a band narrower than the limb is thick (automatic weights often are) brings
 *   the whole lost volume back in a ring a few edges wide, a ridge. lvp_bind_options.bulge_width
 *   > 0 (local mode) takes phi from the weights diffused over the surface instead, for the
 *   correction alone (the skinning is the caller's): each vertex's rows blend over about
 *   bulge_width times the flesh's thickness there (its rest distance to the nearest of its bones),
 *   by explicit steps along the edges, ceil((bulge_width thickness / its mean edge)^2 / 2) at the
 *   vertex that needs the most, the others diffusing slower in proportion, at most 32 steps
 *   (about 8 edges: a dense mesh of thick flesh is spread less than asked), and at least 3 steps
 *   (the fewest after which a weight one vertex alone carried reads, diffused, at most a quarter of
 *   its height above its neighbours' mean: flesh an edge or two thick, as on a low-poly character,
 *   would blend a vertex's row with its neighbours' only partly). Rows keep their 8 strongest
 *   bones. w_k of the maps and the deformation weighting a_k are taken from the diffused rows
 *   too, so a bulge can reach skin that one bone carries rigidly, near a joint that bends.
 *   Entries under 1 % of their row's largest are dropped. The volume comes back as exactly as
 *   without it, in a lower, wider, smoother bulge; weight flows only along edges, so it never
 *   reaches a separate part. 1 fits a limb (README measures it); a wider bulge also moves more
 *   skin each frame (PERFORMANCE).
 *
 * SEGMENTATION (paper 5.2)
 *
 *   Region s is the set of vertices whose largest normalized weight is on bone s (ties go to
 *   the lower bone index). A triangle belongs to the region of the bone with the largest sum of
 *   weights over its three corners (ties: lower bone index). Vertices without any weight belong
 *   to no region (-1) and never move; so does a triangle whose three corners have none.
 *   Separate parts that bend (a body and its clothes in one mesh: connected sets of triangles
 *   with vertices weighted to two bones or more) each get their own region of each bone they
 *   use, and each part is restored to its own rest volume. The API still speaks of one region
 *   per bone: lvp_get_segmentation() gives a vertex its bone, lvp_region_volume_changes() sums
 *   a bone's parts, and worst_region names the bone of the worst part. Past LVP_MAX_BONES
 *   regions in all, the remaining parts stay in their bones' regions.
 *   In LVP_MODE_GLOBAL there is one region, the whole mesh, which must be closed.
 *
 * FOLD-OVER (paper 5.4)
 *
 *   Where a region's bone s and a neighbouring bone j bend about a joint (the head of one, the
 *   child, that their relative motion leaves in place: found from the motion, no hierarchy
 *   needed; when it leaves both heads in place, only if the child's head lies within the
 *   parent's flesh radius of the parent's bone; a child of several such bones takes the plane
 *   of the one whose bone passes nearest its head), the contact surface is the plane halfway
 *   between where the child would point had it moved with the parent and where it points,
 *   through the crease: where the two groups' skins meet on the concave side of the bend, when
 *   that is within the child's flesh radius of the joint (moved from the joint by at most half
 *   that radius; the joints of a B-Bone share its head and line, and whichever of them border
 *   the crease make one plane: GROUPS). A vertex of s's group, pressed once whichever of its
 *   joints border the other side (a B-Bone's joints press together: the calf's skin away from
 *   the knee lies in regions of the shin's later joints, which border none of the thigh's), on
 *   its own side of that plane at rest and across it now goes back onto it (within the child's
 *   flesh radius of the joint along the bend's axis, tapering off at twice that) and is held
 *   there while further volume steps run with the map faded near the contact (on the concave side
 *   of the bend: nothing presses the convex side), so the squeezed
 *   volume becomes a bulge beside it (paper Fig. 10d). It is pressed softly, so that it runs
 *   into the free skin without a kink; the skin at the bottom of the crease, which the plane
 *   cuts at rest, may cross it by as much as it lay near it at rest until the joint bends to a
 *   right angle, and past it is held short of it, so that the bottom of the fold stays open; a
 *   vertex of s on j's side at rest crosses further the deeper it lay there
 *   (docs/method.md, foldover.c). After each contact test the pressed skin is relaxed under the
 *   contact (options.smoothing_passes passes, none at 0): it and the skin within that many rings
 *   of it take one smoothing pass (whatever their map: skin its bones carry rigidly beside pressed
 *   skin follows it, instead of a step at the map's border; the ends of any edge much shorter than
 *   those around it, a needle's, tied into one point, as mean value weights decide), and whatever
 *   that carries across a plane is pressed back, so
 *   the pressed patch meets the free skin around it without a crease. That averaging settles as a
 *   membrane, a cone's tip where the plane holds one vertex of a coarse mesh; the free skin of the
 *   relaxed rings is then settled as a thin plate tied to the averaged offsets beyond about half the
 *   smoothing's rings (docs/method.md, plate.c), the held skin and a tied cluster's members moving as
 *   the passes move them, and what that carries across pressed back. Contact test and volume
 *   step alternate up to 4 more rounds; a round that would move a vertex more than twice as far
 *   as the correction before it is undone and ends them (the frame keeps its contacts, a little
 *   volume missing); the volume the relaxation took is restored after them, through the map and
 *   then along the offsets smoothed once more (so that it does not rise where the map peaks beside
 *   a contact; by the mesh's weights on every pass, as OFFSET SMOOTHING's equal passes left creases
 *   along the contact line there and skin crossing again), what that carries across pressed back and
 *   relaxed in turn, and what that takes restored through the map once more, that step smoothed and
 *   the volume this takes restored along it (what it carries across pressed back). Last, vertices the
 *   smoothing ties into one point (OFFSET SMOOTHING), which the steps moved one by one, take their
 *   mean offset, the volume that takes is restored through the map, and they take their mean again;
 *   a cluster with a member held on a contact plane keeps the places the press gave it. The ends of a
 *   metaball body's short edges parted by a share of the offsets and turned their thin triangles on
 *   edge (knees and elbows at 150 degrees: creases added 49 -> 37 of 13,740 edges; meshes without
 *   such edges are unchanged). Limits: bones
 *   without a joint between them (a fingertip on the palm, a thumb on the index), two parts of
 *   one bone's flesh and the joints of one B-Bone are not separated; at the edge of the skin
 *   pressed onto the plane the skin beside it may cross it; where two bones lie on top of each
 *   other (a joint folded to 180 degrees) there is no plane.
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
 *     most a quarter of the mesh's size, a step through the map that makes the regions' volumes
 *     worse is tried again at half its multipliers (up to 4 times: a step far past what the linear
 *     response can follow, as where fold-over pressed much skin and left the map few places), then
 *     undone, which ends the iteration, and if anything still went non-finite the frame is passed
 *     through unchanged with stats.passed_through set. With options.displacement_limit the frame
 *     degrades locally first (DEGRADING).
 *   - Positions that are not the skinning of the rest by the bound weights and the given bones
 *     (bone frames other than those that moved the mesh, weights changed since the bind): a
 *     sample of the vertices one bone class carries is checked every frame, and where one is off
 *     by more than float rounding the frame is measured from the positions alone (slower: every
 *     triangle is measured) and stats.unskinned_distance says by how much.
 *
 * OFFSET SMOOTHING (lvp_frame_options.smoothing_passes, local mode)
 *
 *   Each vertex moves along its own normal; where the skin folds (the inside of a finger closing,
 *   the palm under bent fingers) neighbouring normals differ by tens of degrees, and offsets of the
 *   same size along them open creases; on a coarse mesh the map itself changes much from one vertex
 *   to the next. With smoothing_passes > 0, after steps 1-3 each pass gives every vertex that can
 *   move half its offset (a vector) and half the weighted mean of its neighbours' (one that cannot
 *   move counts with none): each triangle a neighbour shares with the vertex weighs it 1 + the
 *   cotangent of its angle opposite their edge (0 past a right angle), so that the corners of a long
 *   thin triangle (decimated and game meshes) stay near the line between them instead of tilting
 *   it into a crease; every third pass, counted back from the last, weighs them equally, which
 *   carries a bulge along quads much longer than wide (a limb of a body modelled as a box and
 *   subdivided), where the cotangents tie each vertex to its ring. Vertices so tied that they move
 *   as one point (the ends of the very short edges that metaballs and marching cubes leave: a
 *   cluster giving more than half of its weight to one neighbouring cluster is joined with it, at
 *   bind) are averaged as one, over the cluster's neighbours outside it, so they follow their ring
 *   at the pace of any vertex. The volume the passes took is then restored along the smoothed
 *   offsets themselves, each part's growing by one factor (what they cannot restore goes through the map),
 *   so the shape the passes gave is kept: more passes, smoother offsets. The passes move only what
 *   the map moves, so where the moving skin ends (the weight of a bone that moves runs out) the
 *   offsets would rise from nothing to their neighbours' within one edge; after the passes, the
 *   vertices on that rim that their bind map lets move, but not this frame's map, take the offsets
 *   that leave the least roughness (an offset against the plain mean of its neighbours') summed in
 *   squares over the rim and the skin on both sides of it, the still skin beyond at none (found by
 *   a few sweeps over the rim; fold-over's held vertices aside; the rim is found before anything
 *   fades the map), so the offsets fall off over one edge more: on a line, half the offset beside
 *   them, the least a one-ring ramp can leave. Restoring each region
 *   (LVP_RESTORE_EACH_REGION, or a frame whose bones scale), steps 1-3 restore it. On a hand
 *   closing into a fist, 6 passes (the add-on's default) with equal weights: creases added
 *   111 -> 29, offsets' roughness 0.15 -> 0.06 of the largest, crossing pairs 253 -> 227; on a
 *   1,709-point game horse, every frame of 14 actions, roughness at most 0.72 -> 0.24; weighted, the
 *   same hand decimated to 2,200 vertices 50 -> 36 creases at the fist (docs/method.md, Smoothing
 *   the offsets). Cost: O(dynamic vertices x valence) a pass, and a volume step or two more. Restoring
 *   the whole mesh, the correction before the smoothing takes one step only: the smoothing moves
 *   the skin by more than a second step would.
 *
 * CONTACT (lvp_frame_options.keep_apart, local mode)
 *
 *   Where skinning brings two sheets of skin close (the inside of a bent finger, a thumb's web, a
 *   fingertip on the palm, a thigh on the buttock), the offsets, each along its own side's normal,
 *   point the sheets at each other, and a fraction of a millimetre can push one through the other: more
 *   crossing triangles than plain skinning. With keep_apart, the correction first fades as skin
 *   approaches skin (without fold_over: with it, skin near other skin is where fold-over's contacts
 *   moved it out of the skinning's own crossings, and fading it would bring them back): after the
 *   volume steps (and the smoothing), each moving vertex's clearance is measured in `positions`, the
 *   diameter of the largest ball tangent at it to its offset (the direction the frame's first fade
 *   finds) that no other skin enters (skin straight ahead counts at its distance, skin at angle phi
 *   to the side at its distance over cos phi, skin beside or behind not at all: it changes
 *   continuously with the pose). An offset up to a quarter of its clearance is kept; a longer one m
 *   is cut to h - h^2 / 4m, h half the clearance (the skin opposite may come as far), which joins it
 *   smoothly and never reaches h. The shares kept are smoothed over the rings around (none more than
 *   0.2 above a neighbour's, then averaged), the map faded by them, the faded offsets smoothed as the
 *   frame's are (smoothing_passes: the shares' slope stood out as a rim of the faded skin), and the
 *   volume they no longer carry restored along them, up to 3 rounds; the restores grow the moving
 *   skin's offsets and not the rim's (OFFSET SMOOTHING), so after them the rim is feathered again and
 *   the volume that adds taken back along the offsets. Then every pair of triangles
 *   (sharing no corner) that still crosses after the correction but not in `positions` is found (a
 *   bounding volume hierarchy over the triangles, built at the first such frame, fitted to
 *   `positions` once a frame and after that only where skin moves), and the
 *   offsets of its corners are shortened to the square of the share of them at which the pair stops
 *   crossing (bisection), over a few rounds, the last of which takes the offsets of a pair still
 *   crossing away; those shares are smoothed the same way but
 *   without raising any (a vertex held back would rise back into the crossing) and tested again (each
 *   test smoothing the shares its pairs asked for, not the smoothed ones once more), and
 *   the volume is restored along the offsets again (with fold-over through the map, which its contacts
 *   faded), checked in turn (unless that restore moved no vertex), at most 8 times; after a restore
 *   through the map a check shortens toward where the check before left the skin (when its rounds
 *   ended apart), not toward `positions`, and judges its pairs against those positions: the map moves
 *   skin off the line its offset lay along, and shortened toward `positions`, skin the check before
 *   found apart came down past that, its volume sent on into the next contact. Where plain skinning
 *   already passes skin through skin (a fist's creases), offsets of a hundredth of an edge move that
 *   intersection by a fraction of a triangle and change which pairs it passes through: in each contact a
 *   check finds (its triangles joined by shared corners: a knee's crease, a fingertip on the palm) where
 *   every pair crossing anew lies along the skinning's own crossing (some triangle around one of the two
 *   crosses, in `positions`, some triangle around the other), those pairs are not shortened when, over all
 *   such contacts, the moved skin crosses no more pairs than the skinning does (counted over the pairs with
 *   a moved triangle that the check visits, which holds every pair crossing after the correction); a new
 *   contact elsewhere does not change that. Vertices fold-over put on a contact surface
 *   keep their place in each patch of them where a skinned triangle crosses skin and no longer does after
 *   the correction (fold-over undid that crossing; moving them back would bring it back), and so do the
 *   gaps of such a patch (free vertices joined by edges, each beside the patch, none beside other free
 *   skin: shortened alone, down into the skinning's crossing); the other patches are shortened as any (a
 *   press that left the skinning's crossing as it was too), and a pair with
 *   such a corner that no shortening of its other corners parts keeps its offsets (taking them would part
 *   nothing and leave a step beside the held skin); where the skin around such a
 *   patch is shortened, the patch comes down with it as the shares are smoothed, and goes back up where
 *   one of its triangles then crosses skin (the crossing fold-over undid), as far as parts it, the skin
 *   beside it brought down with it once more (contact.c). It never
 *   gives up: a pose that folds the skin everywhere costs more (the 100k chain of the bench bent at
 *   every joint: seconds, not milliseconds), and stats.crossing_triangles says how many triangles the
 *   crossing test found after the fade (0 when it left pairs along the skinning's own crossing). Result:
 *   no more pairs cross than in plain skinning, and none that plain skinning keeps apart (to the
 *   bisection's precision; a pair that plain skinning leaves touching can still flip), the volume is
 *   restored as before (within the tolerance on every case measured: the giraffe's 28 single-joint
 *   poses, a hand closing into a fist, a Rigify human bent hard, every frame of a game horse's 14
 *   actions), and smooth (roughness at most 0.22 of the largest offset on those cases);
 *   stats.shortened_vertices counts the vertices the crossing test shortened. Limits: only what the
 *   correction adds is undone, never skinning's own crossings (that is fold-over's); skin that plain
 *   skinning leaves touching has room ahead of every corner, so the crossing test, not the fade, keeps
 *   it apart. Cost: one pass over every triangle a frame (the hierarchy fitted to `positions`), a ball
 *   query per moving vertex reaching five times its offset (the fade needs clearances below four
 *   times; a vertex whose offset a restore grows past that is searched again before the next fade;
 *   vertices near each other gather the skin near any of them by one descent of the hierarchy, and
 *   each sets aside what lies outside its ball in one pass over the gathered boxes; balls wider than
 *   their group's skin gather and test the hierarchy's leaves by the slab each node's skin lies in,
 *   which meets a ball resting on nearly flat skin only near its vertex; a group whose box holds too
 *   much gathers again by its balls, and past that each vertex descends only into boxes that meet its
 *   ball; each passes over what lies
 *   outside the ball of the nearest skin found so far, and searches a triangle's edges and inside
 *   only where their distance could bring it nearer), a traversal of the hierarchy against
 *   itself per check (passing over each subtree whose triangles form one connected patch with every
 *   normal within 90 degrees of one axis: such a height field cannot cross itself), and the volume
 *   restored again after each fade and check; refits in between visit the triangles around moving
 *   vertices only (PERFORMANCE, BENCHMARKS.md).
 *
 * DEGRADING (lvp_frame_options.displacement_limit > 0, local mode)
 *
 *   Where the correction cannot do well at a pose, the regions it cannot correct keep the
 *   skinning and the rest of the mesh is corrected, instead of the whole frame failing. After a
 *   correction, if some vertex moved farther than the limit (or to no finite place), the group
 *   whose multipliers moved it most (phi times the |mu| its steps applied) is given up; else, if
 *   the correction moved nothing at all while some group is more than 0.1 % of its reference
 *   volume off (a joint folded onto itself: its steps make things worse and are undone, and with
 *   them every other group's), the group furthest off is given up. The frame is then corrected
 *   again from the input without the groups given up: they are left out of the solve (skin they
 *   share with other groups still moves with those), and the whole mesh's volume is not
 *   restored, so that their loss is not pushed into the others. At most LVP_MAX_GIVEN_UP groups
 *   a frame, each costing one more correction; stats.given_up_regions counts them and
 *   stats.given_up_region names the first, stats.given_up_diverged says why. Frames that need
 *   none cost what they did. With fold-over on nothing is given up (its contacts, not the
 *   groups, move the skin there): a frame beyond the limit is the caller's to correct again
 *   without fold-over, as the add-on does.
 *
 * THREADS AND MEMORY
 *
 *   No global state. A binding owns all of its memory (sized at bind, O(N + F + E + W + B), W
 *   the weights, and the region system's at most 65,536 cells, see PERFORMANCE) and
 *   is used by one thread at a time; two bindings can be used from two threads at once.
 *   lvp_correct() never allocates, except at the first frame with keep_apart (CONTACT: its
 *   hierarchy and the sheets its searches cull by, about 260 bytes a triangle, and 78 bytes a
 *   vertex) and at the first with fold_over (FOLD-OVER: its relaxation's neighbour lists and plate,
 *   about 320 bytes a vertex);
 *   lvp_error_out_of_memory when that fails. With options.thread_count > 1 a binding keeps that many
 *   worker threads, created by lvp_bind() and joined by lvp_free(); results are identical
 *   for every thread count (reductions use a fixed partition). Between the loops of a frame the
 *   workers watch for the next one for about a tenth of a millisecond before they sleep.
 *
 * PERFORMANCE
 *
 *   Bind: O(N B) for the maps, O(E log E) for the parts (E weight entries), plus O(N) per step
 *   of the bulge width's diffusion (at most 32); lvp_auto_weights(): O(N B) with the normal
 *   test, O(N B log F) with the exact test, plus O(N) per smoothing step (about O(N) in all past 64
 *   steps, SMOOTHING).
 *   Per frame, only the skin around the joints that bend is visited (with a bulge width, the skin
 *   its diffused rows reach): a triangle that its
 *   region's bone carries rigidly enters the measurement in closed form (which relies on
 *   `positions` being the skinning of the rest, as lvp_correct() says, and is checked each frame
 *   on a sample). Per step, a few passes over those triangles and vertices, and a solve of the
 *   active regions' system within its profile (a chain of m regions O(m), regions coupled all
 *   with all m^3 / 3), in at most 65,536 cells; the regions past what fits take the
 *   single-region step of eq. 5.
 *   Restoring the whole mesh (RESTORE), a step reads only the volume: no region's border is
 *   visited until the regions' changes are read, so many small regions (the joints of B-Bones)
 *   cost about what a few large ones do. Measured times: BENCHMARKS.md.
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
#define LVP_MAX_SMOOTHING_ITERATIONS 1000
/* The largest options.smoothing_thickness (lvp_auto_weights). */
#define LVP_MAX_SMOOTHING_THICKNESS 16.0f
#define LVP_MAX_BULGE_WIDTH 8.0f
#define LVP_MAX_GIVEN_UP 4
#define LVP_MAX_SMOOTHING_PASSES 64

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
	const float *heads;         /* bone_count*3: rest position of the bone's head (its joint) */
	const float *tails;         /* bone_count*3: rest position of its end (may equal the head); read
	                               by lvp_auto_weights, and by lvp_bind for the joints of a B-Bone
	                               only (BONE LINES) */
	const int32_t *parents;     /* bone_count, or NULL: each bone's parent among these bones (the
	                               nearest ancestor that is one of them), -1 for none; lvp_bind
	                               takes the bones' lines from it (BONE LINES) */
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
	float alpha;            /* omega_ki = (l_i / d_ki)^alpha (by_length) or (1 / d_ki)^alpha; > 0,
	                           default 2 */
	int32_t by_length;      /* nonzero (default): the paper's l_i, a bone reaching as far as it is
	                           long, so that where a long bone meets short ones (a thigh the pelvis,
	                           an upper arm the shoulder) the border between them lies l_long / l_short
	                           times farther from the long bone; 0: each vertex's strongest bone is its
	                           nearest, borders halfway, as with heat weights */
	int32_t facing;         /* nonzero: d_ki is the distance over (1.001 + cos) / 2, cos that of the angle
	                           between vertex k's outward normal and the path to k from its closest point
	                           on bone i, as Blender's heat weights measure it: a bone straight beneath
	                           the skin counts at its distance, one off to the side at twice it, so the
	                           skin that faces away from a bone is its flesh (the front of a hip is the
	                           thigh's, where the pelvis's bone runs close under the skin above it);
	                           the thickness of SMOOTHING BY THICKNESS is measured so too. The normal
	                           counts only as far as it tells which way the skin faces: the share is
	                           1 - t (1 - (1.001 + cos) / 2), t the least cosine (at least 0) between
	                           the vertex normal and its triangles' normals, 0 at a vertex on an edge
	                           that is not two triangles' (a fin, an open border, whose skin faces no
	                           side). With LVP_VISIBILITY_EXACT t = 1 everywhere, as heat weights count it:
	                           that test sees the paths from such skin to a bone it does not cover leave
	                           the body. Default 0 (the paper's distance) */
	lvp_visibility visibility;
	float normal_cos_max;   /* NORMAL test: bone i is hidden from vertex k when the unit path
	                           from k to its closest point on bone i has cos(path, outward
	                           normal) > normal_cos_max; in [-1, 1], default 0 (path must go
	                           inward) */
	int32_t max_influences; /* keep the strongest ones, renormalized; 0 = all, default 4 */
	float min_weight;       /* drop normalized weights below this, renormalize; default 0.01 */
	int32_t smoothing_iterations; /* steps of diffusion over the surface (SMOOTHING below); 0 = none,
	                                 up to LVP_MAX_SMOOTHING_ITERATIONS, default 0 */
	float smoothing_length; /* > 0: instead, as many steps as blend over about this distance (SMOOTHING);
	                           mesh units, finite, default 0 */
	float smoothing_thickness; /* > 0: instead, each vertex blends over this many times the thickness of
	                              the flesh around its bones (SMOOTHING BY THICKNESS); at most
	                              LVP_MAX_SMOOTHING_THICKNESS, default 0 */
	int32_t heat;             /* 1: bone heat, as Blender's heat weights (HEAT below; the smoothing options
	                             unused); default 0 */
	int32_t thread_count;     /* HEAT: threads solving the bones, the same bits on any count;
	                             1..LVP_MAX_THREADS, default 1 */
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
 * Rows are sorted by decreasing weight.
 *
 * SMOOTHING (options.smoothing_iterations > 0): the rows above, kept to their 8 strongest bones
 * (max_influences and min_weight not applied yet), are diffused over the mesh's edges: each
 * iteration replaces every vertex's row by the mean of its row and its edge neighbours' rows,
 * keeps the 8 strongest bones and renormalizes; then max_influences and min_weight prune as above
 * (so with max_influences 0 a row has at most 8 bones). Visibility is judged before, not during,
 * the diffusion. Weight flows only along edges: separate pieces, and parts that touch or cross
 * without sharing vertices, never share weight; vertices at one position but not joined by an
 * edge (split seams) are smoothed separately. A border between bones spreads over about
 * sqrt(2 steps) edges, so a fixed number of steps blends over a distance that shrinks as the mesh
 * gets denser; options.smoothing_length > 0 takes ceil((smoothing_length / mean edge length)^2 / 2)
 * steps' worth instead, about the same blend at any resolution. From 64 steps on, the rows are
 * blended through clusters of nearby vertices instead of step by step (each cluster the vertices
 * within 2 edges of its seed; the clusters' rows diffused over the graph of adjacent clusters, as far
 * as the steps would spread them, through clusters of clusters when that is many steps again; then
 * given back to the vertices and smoothed over a cluster's width): about the same blend (on a body
 * of 101,336 vertices, a vertex's weights differ from the steps' by 0.03 in all in the median, 0.16
 * at the 99th percentile), at the cost of a few steps however many are asked. Steps count edges, not
 * lengths: the two ends of a sliver (an edge shorter than an eighth of the mean length of the edges
 * around its ends, which metaballs and remeshers leave) would blend as two vertices an edge apart, and
 * a small difference of their rows folds the skin across a millimetre where the bones move apart; the
 * ends of such edges (and of chains of them) take the mean of their rows after the blend.
 *
 * SMOOTHING BY THICKNESS (options.smoothing_thickness = s > 0): a blend that fits a finger is too
 * narrow for a hip, and one that fits a hip takes a finger's whole length, so the distance blended
 * over follows the flesh. Bone i's thickness T_i is the median distance from it of the vertices
 * whose strongest bone (before smoothing) it is; a vertex blends over s times the thickness of its
 * bones, sum_i w_ki T_i over the bones with a thickness (w_k its row blended over s times the
 * largest thickness, which varies smoothly over the surface), or s times its own depth under the
 * skin, its distance from its strongest bone before smoothing, when that is more (at most twice the
 * straight distance and the longest bone's length): skin deeper than its bones' flesh is thick (a
 * palm's edge beside the little finger, a buttock) blends as widely as it is deep. The rows are
 * blended over lengths e sqrt(2)^j (e the mean edge) from s times the least thickness to s times the
 * largest (or the deepest skin's depth), the steps adding only what the mesh's sampling does not
 * blend already (a border spreads over about an edge by itself; widths add in quadrature; at least
 * one step), and each vertex takes the mix of the two lengths around its own (by their ratio's
 * logarithm), kept to its 8 strongest bones and renormalized; then pruned as above. Like heat weights, whose diffusion is screened by the
 * distance to the nearest bone: the blend between finger bones is a few millimetres, at the hip a
 * hand's width, and neither depends on the mesh's size (a tail or a weapon in the mesh changes
 * little) nor much on its resolution. Costs one blend per length (a few dozen steps' worth each).
 * With a high alpha (nearest bone first, e.g. 16) and by_length 0 this gives weights close to
 * Blender's heat weights on a closed body (README).
 *
 * HEAT (options.heat = 1): Baran and Popovic's bone heat, the weights of Blender's With Automatic Weights,
 * solved on any mesh. Each vertex's sources are the bones at its least distance (measured as options.facing
 * says, over the facing share of its triangles' summed unit normals, as heat weights measure it) that the
 * visibility test lets it see, shared evenly; its screening H = their number / d^2. Each bone's weight w
 * solves -(1/4) Laplacian(w) + H w = H p over the surface (the cotangent Laplacian over mixed areas, as
 * Blender scales it; p the bone's share of the sources), so a bone's weight spreads into its neighbours' skin
 * over about half the skin's depth: millimetres on a finger, a hand's width at a hip, whatever the mesh's
 * resolution. Where the skin lies closer to its bone than its edges are long, the screening is held to the
 * vertex's couplings to its neighbours, so that no blend is narrower than an edge. Each bone is solved (by
 * conjugate gradients under a multigrid preconditioner) on the skin within reach of its sources, grown
 * while its weight at the rim is above 2.5e-3: a bone costs what its skin does. Weights below 0.025 are
 * dropped and those up to 0.05 ramp from 0 (heat weights' own cut), then max_influences and min_weight
 * prune as above. Weight flows only along
 * edges: a piece, or a part of the skin, where no vertex sees its nearest bone gets no heat, and its
 * vertices take their rows by 5.1 unsmoothed (alpha and by_length count there alone; the rigid fallback
 * where they see no bone). The smoothing options are not used. */
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
	/* Optional, local mode: bones whose regions are corrected together, with one multiplier
	 * (GROUPS). bone_count values in [0, bone_count): bones with the same value form one group.
	 * NULL (default): every bone alone. */
	const int32_t *bone_groups;
	/* Local mode: how far each region's correction spreads, in multiples of the flesh's thickness
	 * (BULGE WIDTH). 0 (default): over the band where the weights blend (the paper); up to
	 * LVP_MAX_BULGE_WIDTH. */
	float bulge_width;
} lvp_bind_options;

lvp_bind_options lvp_bind_default_options(void);

typedef struct lvp_binding lvp_binding; /* opaque */

/* Binds a mesh to its skeleton and weights at rest: validates everything, segments the mesh,
 * builds the correction map, the region borders and every rest-side constant, and allocates
 * all per-frame work memory (but keep_apart's and fold_over's, THREADS AND MEMORY). In
 * LVP_MODE_GLOBAL, weights and skeleton may be NULL (bone_count 0) unless the map needs them
 * (ORGANIC, RUBBER, BOUNDARY_FADE need them; UNIFORM and PAINTED do not). The inputs are
 * copied: the caller may free them after the call. On success *r_binding receives a binding to
 * release with lvp_free(). */
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

/* What a frame's correction brings back (RESTORE). */
typedef enum lvp_restore {
	LVP_RESTORE_EACH_REGION = 0, /* every region to its own rest volume (paper 5.3), and the whole mesh */
	LVP_RESTORE_WHOLE_MESH = 1,  /* the whole mesh (each separate part), through every region's map */
} lvp_restore;

typedef struct lvp_frame_options {
	int32_t max_iterations; /* correction steps per volume correction, 1..1000, default 8; 1 is
	                           the paper's single pass. Smoothing runs one more volume correction
	                           and fold-over up to 4 more, each with this budget. */
	float tolerance;        /* stop when every region is within tolerance * its reference volume
	                           of its target (ALGORITHM, 3); > 0, default 1e-4 (0.01 %) */
	int32_t fold_over;      /* nonzero: fold-over prevention (local mode only), default 0 */
	const float *rigid_space; /* NULL (default), or 16 floats (row-major, like the bone matrices): the
	                           map from the mesh's coordinates to a space where a bone that is not
	                           scaled only turns (the armature's), used to tell a bone's scale from
	                           its bend (ALGORITHM, 3). NULL: the first bone's rest frame (the
	                           armature's, turned), which is right unless the mesh has been scaled
	                           unevenly against the armature since the bind. Its 3x3 part must be
	                           invertible. */
	float displacement_limit; /* 0 (default) or infinity: none. > 0: a correction that would move
	                           some vertex farther than this (or to no finite place) gives up, for
	                           this frame, the group whose multipliers moved it most, and corrects
	                           again without it, up to LVP_MAX_GIVEN_UP groups (DEGRADING below);
	                           in the mesh's units */
	int32_t restore;        /* lvp_restore: what each frame brings back (RESTORE below); default
	                           LVP_RESTORE_EACH_REGION */
	int32_t keep_apart;     /* nonzero: the offsets fade as skin approaches skin, and none makes two
	                           triangles cross that do not cross in `positions` (CONTACT below), local
	                           mode only; default 0 */
	int32_t smoothing_passes; /* passes smoothing the offsets over the surface before fold-over
	                           (OFFSET SMOOTHING below), 0..LVP_MAX_SMOOTHING_PASSES, local mode only;
	                           default 0, the paper's offsets */
} lvp_frame_options;

lvp_frame_options lvp_frame_default_options(void);

typedef struct lvp_frame_stats {
	double volume_rest;       /* signed mesh volume at rest (divergence formula) */
	double volume_before;     /* of the input positions */
	double volume_after;      /* of the corrected positions */
	int32_t worst_region;     /* region with the largest relative change before correction, -1 if none
	                             (of separate parts, the part's bone: SEGMENTATION; of a group, its
	                             first bone, and the group's change: GROUPS) */
	double worst_region_change_before; /* its (V - V_rest) / V_ref, signed; where bones are scaled
	                                      against each other, less the change their scales give it
	                                      (ALGORITHM, 3) */
	double worst_region_change_after;
	int32_t iterations;       /* correction steps done, fold-over rounds and the corrections again
	                             after giving groups up (DEGRADING) included */
	int32_t active_regions;   /* regions whose volume had changed (corrected), first pass; a bone's
	                             region in each separate part counts once, a group once */
	int32_t skipped_regions;  /* regions left as they were: their posed bone is singular (scaled to zero) */
	int32_t folded_vertices;  /* vertices moved back to a contact surface */
	double max_displacement;  /* largest |offset| written */
	int32_t passed_through;   /* 1 when no finite correction was found (a pose folded onto itself):
	                             the input was written back unchanged */
	int32_t given_up_regions; /* groups given up this frame (options.displacement_limit), 0 if none */
	int32_t given_up_region;  /* the first of them, by its first bone, or -1 */
	int32_t given_up_diverged; /* 1: the first was given up for moving skin beyond the limit; 0: for
	                              stalling the correction (DEGRADING) */
	double unskinned_distance; /* 0, or how far the positions put a vertex that one bone carries from
	                              where that bone puts it, when that is more than float rounding:
	                              the positions are not the skinning of the rest by these bones and
	                              the bound weights (see lvp_correct), and the frame was measured
	                              from the positions alone, without the closed form for rigid parts */
	int32_t shortened_vertices; /* options.keep_apart: vertices whose offset the crossing test
	                             shortened to keep skin from crossing skin (CONTACT), 0 without it */
	int32_t kept_apart_vertices; /* options.keep_apart: vertices whose offset it held back, faded where
	                                it neared other skin in front of it or shortened by the crossing test
	                                (shortened_vertices among them), 0 without it */
	int32_t crossing_triangles; /* options.keep_apart: the triangles the correction made cross skin
	                             at the frame's first check, after the fade, each kept apart since
	                             (CONTACT), 0 without it */
	int32_t bones_scale;      /* 1: bones scale this frame beyond the tolerance (squash and stretch,
	                             ALGORITHM 3): each region keeps the volume its bones' scales give
	                             it, and volume_after is not meant to be volume_rest */
} lvp_frame_stats;

/* Corrects one frame. positions: vertex_count*3, the skinned (deformed) positions, e.g. what
 * leaves Blender's Armature modifier: the rest (or rest_positions) skinned by the bound
 * weights and these bones, linear or dual quaternion (see PERFORMANCE). bone_matrices:
 * bone_count*16, the posed bone frames T_i in the same space as the rest matrices (may be NULL
 * in LVP_MODE_GLOBAL). rest_positions: NULL to use the bind rest, or vertex_count*3 of this
 * frame's un-skinned positions (shape keys), against which volumes are then compared.
 * Outputs (vertex_count*3 each, at least one non-NULL): r_positions, the corrected positions
 * (may be the same buffer as positions), and r_offsets, corrected minus input.
 * r_stats may be NULL. No allocation but at the first frame with keep_apart or with fold_over
 * (THREADS AND MEMORY); O(1) stack. */
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
