/*
 * binding.h - the inside of an lvp_binding: everything computed once at rest (segmentation,
 * correction map, region borders, rest constants) and the per-frame work memory, so that
 * lvp_correct() never allocates. Shared by bind.c, parts.c, segmentation.c, local_volume.c,
 * frame_map.c, correction.c, region_system.c, stretch.c and foldover.c; not part of the public API.
 */
#ifndef LVP_BINDING_H
#define LVP_BINDING_H

#include "bvh.h"
#include "lvp_internal.h"
#include "threads.h"

/* Items per chunk of a parallel loop: small enough that two threads share a loop evenly. */
#define LVP__GRAIN 4096

/* The pool for a loop that does about `work` items of work (vertices, triangles): none when
 * that fits in one chunk (a small mesh, or a pose bent at one joint); a hand's few thousand moving
 * vertices are two chunks already, and between the loops of a frame the workers are still awake. */
#define LVP__POOL_FOR(binding, work) ((work) > LVP__GRAIN ? (binding)->pool : NULL)

/* The most cells a region system (region_system.c) is stored in: a step whose active regions'
 * profile would take more solves the coupled system for as many of them as fit (in the solve
 * order) and gives the others the per-region step of eq. 5; the next iteration re-measures. A
 * chain of bones takes 3 cells a region, a bone coupled with all the others 2 more each: a
 * region count far past any rig; only regions coupled all with all (no skeleton does that) reach
 * it, at 256 of them. The normal equations of least squares have the same limit. */
#define LVP__SYSTEM_CELLS (1 << 16)

/* The region system is summed over the dynamic vertices in at most LVP__ASSEMBLY_CHUNKS chunks
 * of at least LVP__GRAIN vertices, cut where the dynamic vertex count alone says (not the
 * thread count), each into its own block of binding->system.assembly: the sums, then one gain per
 * column of the system and a spare one, a cache line apart from the next block. The blocks are
 * added in chunk order. The sums of a system of up to LVP__ROWS_ASSEMBLY regions are (count +
 * 1)^2, row by row with a spare row and column, which the assembly indexes with one load per
 * entry; a larger system's are the cells of its profile and a spare one (lvp__system_cell). */
#define LVP__ASSEMBLY_CHUNKS 16
#define LVP__ROWS_ASSEMBLY 64
#define LVP__ASSEMBLY_ROWS(regions) ((size_t)((regions) < LVP__ROWS_ASSEMBLY ? (regions) : LVP__ROWS_ASSEMBLY) + 1)
#define LVP__ASSEMBLY_BLOCK(cells, regions)                                                                       \
	(((size_t)(cells) + 1 > LVP__ASSEMBLY_ROWS(regions) * LVP__ASSEMBLY_ROWS(regions)                                \
	      ? (size_t)(cells) + 1                                                                                    \
	      : LVP__ASSEMBLY_ROWS(regions) * LVP__ASSEMBLY_ROWS(regions)) +                                           \
	 (size_t)(regions) + 1 + 7) / 8 * 8 + 8

/* The reference pass of stretch.c runs over the stretched regions in at most
 * LVP__STRETCH_GROUPS groups of consecutive regions of about equal work (cut by the regions'
 * sizes, not the thread count), each group with its own bone_entry scratch. */
#define LVP__STRETCH_GROUPS 16

/* What a parallel loop over a binding's vertices, triangles or regions reads besides the binding:
 * one array of positions (this frame's, or the rest). */
typedef struct lvp__loop_context {
	lvp_binding *binding;
	const float *positions;
} lvp__loop_context;

typedef struct lvp__region_sums {
	double volume6;    /* sum over the region's triangles of (p_i - o) . cr, o = the region origin */
	double area6[3];   /* sum of cr = (p_j - p_i) x (p_k - p_i): twice the area vector */
} lvp__region_sums;

/* A square matrix stored by its profile (region_system.c): entry (i, j) with first[i] <= j <= i at
 * cell lower[i] + j, entry (j, i) with first[i] <= j < i at cell upper[i] + j; every other entry
 * is zero. Rows and columns [0, count), in `cells` cells. */
typedef struct lvp__profile {
	int32_t *first, *lower, *upper;
	int32_t count, cells;
} lvp__profile;

/* Where region r's row and column are in a step's system (region_system.c, lvp__system_layout):
 * index its row and column (the profile's count when it is not in the system), first, lower and
 * upper the profile's (first INT32_MAX when it is not in the system). Kept per region, together,
 * so the assembly finds a cell with one load per region. */
typedef struct lvp__system_place {
	int32_t index, first, lower, upper;
} lvp__system_place;

/* ---- the stages' data ------------------------------------------------------------------------
 * Each stage of the method keeps its data in a struct of its own, allocated and freed by the
 * file that implements it (lvp__<stage>_alloc at bind, lvp__<stage>_free): bind-time constants,
 * then what it works out each frame. Arrays "per region" have region_count entries, "per bone"
 * bone_count (the internal bones, see lvp_binding), "per vertex" vertex_count. A stage reads
 * the others' data; it writes only its own, and a cache that depends on another stage's data is
 * marked stale through the owner's function (lvp__frame_map_stale, lvp__dynamic_set_stale). */

/* The points of the skin (weld.c): vertices at the same rest position are one point, and every
 * other stage works on the points (vertex_count counts them). */
typedef struct lvp__weld {
	int32_t caller_vertex_count;
	int32_t point_count;       /* caller_vertex_count when no two vertices coincide */
	int32_t *vertex_point;     /* caller vertex -> point; NULL when no two vertices coincide (then
	                              every array below is NULL too, and a point is its vertex) */
	int32_t *point_first;      /* point -> its first caller vertex */
	int32_t *copy_offsets;     /* point_count+1 into copies */
	int32_t *copies;           /* the caller vertices of each point, in order */
	/* This frame: */
	float *positions, *rest;   /* point_count*3: the frame's positions and rest, gathered */
} lvp__weld;

/* The rig (rig.c): the weights and the bones as bound, and this frame's bones. */
typedef struct lvp__rig {
	/* Weights normalized by their sum, as Blender's Armature modifier normalizes them. */
	int32_t *weight_offsets;  /* vertex_count+1, or NULL without weights */
	int32_t *weight_bones;    /* internal bones */
	float *weight_values;
	int32_t *bone_source;     /* per bone: its caller's bone; NULL when none is a copy */
	lvp__mat4 *rest_matrices, *rest_inverse;
	double *rest_det;         /* det of the rest matrices' 3x3 part */
	lvp__vec3 *heads;
	lvp__vec3 *tails;         /* the caller's: only a B-Bone's joints use them (bone_lines.c) */
	double reach;             /* the farthest rest head from the mesh's origin */
	/* This frame (lvp__prepare_frame): */
	lvp__mat4 *posed, *posed_inverse;
	lvp__mat4 *skin;          /* posed * rest^-1 */
	lvp__vec3 *posed_heads;
	double *kappa;            /* per region: det(rest) / det(posed) of its bone */
	uint8_t *region_skipped;  /* per region: its bone is scaled to zero (lvp.h, the documented fallback) */
} lvp__rig;

/* Where each bone runs through its flesh at rest (bone_lines.c): a segment per bone, taken from
 * the joints and the skin, never from the caller's tails. */
typedef struct lvp__bone_lines {
	lvp__vec3 *end;           /* per bone: where its line ends; it starts at the bone's head (rig.heads) */
	double *length;           /* per bone: |end - head|; 0 for a bone that is a point */
} lvp__bone_lines;

/* The bound mesh as the method walks it (segmentation.c): regions, triangles sorted by region,
 * and the adjacency every stage uses. */
typedef struct lvp__mesh {
	int32_t *triangles;       /* triangle_count*3, SORTED BY REGION (region -1 last) */
	int32_t *triangle_original; /* sorted position -> caller's triangle index */
	int32_t *triangle_region;   /* per sorted triangle */
	int32_t *region_triangle_offsets; /* region_count+1 into the sorted triangles; the triangles
	                                     after offsets[region_count] have no region */
	int32_t *vertex_region;   /* per vertex, -1 = none */
	float *max_weight;        /* per vertex: w_k = max_i omega_ki (0 without weight) */
	/* Slots: the distinct regions of the triangles around each vertex. */
	int32_t *slot_offsets;    /* vertex_count+1 */
	int32_t *slot_region;     /* slot -> region (-1 for triangles without region) */
	int32_t *corner_slot;     /* sorted triangle corner -> slot */
	int32_t slot_count;
	int32_t *vertex_corner_offsets; /* vertex_count+1: the sorted-triangle corners around each vertex */
	int32_t *vertex_triangles;      /* per such corner: its triangle */
	int32_t *vertex_corner_slot;    /* per such corner: the vertex's slot for that triangle */
	/* The distinct corner vertices of each region's triangles (a region is static in a frame
	 * when all of them are: lvp__find_dynamic_set then skips its triangles unread). */
	int32_t *region_corner_offsets; /* region_count+1 */
	int32_t *region_corners;
	int32_t *region_vertex_offsets; /* region_count+1: each region's vertices */
	int32_t *region_vertices;
	int32_t *neighbour_offsets; /* region_count+1: the bones sharing influence with each region */
	int32_t *neighbour_bones;
} lvp__mesh;

/* The bind map (map.c): gamma of lvp.h, and how region multipliers reach vertices. */
typedef struct lvp__map {
	lvp_map_options options;  /* map kind, alpha, beta (pointers cleared after copy) */
	float *gamma;             /* per vertex, normalized to max 1 */
	float *distance;          /* per vertex: rest distance to the nearest (allowed) bone */
	double *log_gamma;        /* per vertex: the map before normalization, as a logarithm */
	float *area_weight;       /* per vertex: the mean rest vertex area over its own (0 without area) */
	int32_t *region_bone_offsets; /* copy of the Fig. 11 restriction, or NULL */
	int32_t *region_bones;
	/* What reaches a vertex: rho_k = gamma_k g_k sum_t phi_kt mu_t over its support
	 * (correction.c, lvp__vertex_support): with a soft map the bones of its weights, phi = the
	 * weight; with the boundary fade, or in global mode, its one region, phi = 1. */
	bool soft_support;
} lvp__map;

/* The reach (reach.c): phi_ks, how region s's multiplier reaches vertex k, by rows like the
 * weights'. Without a bulge width the rows are the skinning weights themselves (the arrays point
 * into rig and mesh, own is false); with one, the weights diffused over the surface. */
typedef struct lvp__reach {
	int32_t *offsets;         /* vertex_count+1 */
	int32_t *regions;         /* internal bones */
	float *phi;
	float *largest;           /* per vertex: its largest phi (w_k of the maps) */
	bool own;                 /* the arrays are the reach's own (else the rig's and mesh's) */
} lvp__reach;

/* This frame's map and the vertices' classes (frame_map.c). */
typedef struct lvp__frame_map {
	float *gamma;             /* per vertex: the bind map times map.area_weight and the deformation weighting */
	int32_t *skin_class;      /* per bone: bones with equal skin matrices this frame share a class */
	bool classes_alone;       /* every bone is alone in its class this frame */
	float *skin_displacement; /* bone_count*12: skin - identity, rows of 3x4, float (lvp__spread) */
	int32_t *vertex_class;    /* per vertex: the skin class all its bones share this frame, or -1 */
	uint8_t *vertex_dynamic;  /* per vertex: not rigid, movable by the map (by the classes alone:
	                             frame_map.c), or moved by fold-over */
	uint8_t *chunk_changed;   /* per LVP__GRAIN vertices: the frame map changed their class or flag */
	int32_t *fill;            /* scratch: the holes in the moving skin this frame (frame_map.c) */
	float *fill_gamma;        /* scratch: per vertex walked, the map it takes when still in moving
	                             skin, else -1 (lvp__fill_holes) */
	int32_t *rim;             /* the moving skin's rim this frame, rim_count vertices: dynamic, the
	                             bind map lets them move and this frame's does not, beside vertices
	                             it moves (lvp__feather_rim) */
	int32_t rim_count;
	/* vertex_class and vertex_dynamic are the frame map's for the current skin classes and map;
	 * lvp__frame_map_stale clears it when something else changes one of them. */
	bool current;
	/* This frame, the vertices one bone class carries were found elsewhere than that class puts
	 * them (lvp__rigid_vertices_hold): every vertex is taken as dynamic, measured from the
	 * positions given, and none is carried in closed form. */
	bool rigid_shortcut_off;
} lvp__frame_map;

/* Region borders and the mesh's own holes (borders.c). */
typedef struct lvp__borders {
	/* Half-edges whose side quad does not cancel: */
	int32_t *offsets;         /* region_count+1 */
	int32_t *edges;           /* 2 per border half-edge: a, b in the triangle's orientation */
	int32_t *slots;           /* 2 per border half-edge: the slots of a and b for the region */
	float *gradient;          /* 6 per border half-edge: this frame's border terms of the region's
	                             volume gradient at a and at b (world, lvp__vertex_gradients) */
	lvp__vec3 *rest;          /* 2 per border half-edge: with A, B its ends at rest in the region's rest
	                             frame, A + B and A x B (all its side quad needs of the rest,
	                             lvp__side_quad6; lvp__frame_rest) */
	bool rest_is_bind;        /* rest holds the bind rest, not a frame's own */
	/* The holes (surplus half-edges over the whole mesh): */
	int32_t *cap_edges;       /* 2 per half-edge, sorted by the part of their hole */
	int32_t cap_edge_count;
	int32_t *cap_part_offsets; /* part count+1 into cap_edges */
	int32_t flipped_edge_count; /* edges of two triangles wound against each other */
} lvp__borders;

/* The dynamic set (dynamic_set.c): what a mesh pass visits. A triangle whose three corners
 * follow its region's bone rigidly is static: its terms are its rest terms moved by the bone. */
typedef struct lvp__dynamic_set {
	int32_t *triangles;       /* triangle_count: the dynamic ones, in sorted order */
	int32_t *region_offsets;  /* region_count+2 into triangles (the last range: no region) */
	uint8_t *region_state;    /* region_count+1: all dynamic, all static or mixed */
	uint8_t *triangle_static; /* per triangle of a mixed region */
	int32_t *vertices;        /* the dynamic vertices */
	int32_t vertex_count;
	lvp__region_sums *static_rest; /* per region: rest sums of the static triangles */
	int32_t *static_count;    /* per region: how many static triangles */
	/* The set is the bind rest's for the current vertex_dynamic, vertex_class, skin_class and
	 * region_skipped (kept from frame to frame while they stay; lvp__dynamic_set_stale). */
	bool current;
} lvp__dynamic_set;

/* Measuring (local_volume.c): the mesh pass, the region sums and changes, the vertex terms. */
typedef struct lvp__measure {
	lvp__region_sums *rest_totals;  /* per region: the sums of the bind rest, about each bone's rest origin */
	lvp__region_sums *frame_totals; /* per region: the same of the frame's own rest, when given */
	double *reference_volume;  /* per region: V_ref,s for the tolerance (0 = empty region) */
	lvp__vec3 global_origin;   /* global mode: rest centroid, to keep the sums well conditioned */
	/* This frame: */
	lvp__vec3 *origin;         /* per region: its bone frame's origin, rounded to float */
	float *origin_float;       /* (region_count + 1)*3: the same in float, last = 0 (no region) */
	lvp__region_sums *sums;    /* region_count + 1 (the last: triangles without region, origin 0) */
	/* Pieces of the dynamic triangles for the pass (lvp__piece_loop); capacity
	 * triangle_count / LVP__GRAIN + region_count + 2. */
	int32_t *piece_first;      /* piece_count + 1 into the dynamic triangles */
	int32_t *piece_region;     /* region of each piece (region_count: triangles without region) */
	lvp__region_sums *piece_sums; /* each piece's sums (area6: the sum of cr / 6) */
	int32_t piece_count;
	float *triangle_gradient;  /* triangle_count*3: cr / 6 of the last pass */
	float *triangle_volume6;   /* triangle_count: (p0 - o) . cr of the last pass (a float product) */
	float *normals;            /* vertex_count*3 */
	float *vertex_g;           /* per vertex: g_k = <n_k, grad_k V> */
	float *slot_gradient;      /* slot_count*3 */
	float *slot_g;             /* per slot: <n_k, part of grad_k V from the slot's region> */
	bool vertex_terms_current; /* normals, g and slot gradients gathered for the last mesh pass */
	bool normals_current;      /* normals and g alone gathered for it (lvp__vertex_normals) */
	/* The update pass's lists, the flags kept zero between uses: */
	uint8_t *triangle_dirty;
	int32_t *dirty_triangles;
	uint8_t *vertex_dirty;
	int32_t *dirty_vertices;
} lvp__measure;

/* The region system of a correction step (region_system.c): the regions coupled with each (both
 * ways), the order it is solved in, and its profile over the step's active regions (the step's
 * active[i] is row and column i). */
typedef struct lvp__region_system {
	/* The groups of regions corrected with one multiplier (lvp.h, GROUPS); a region alone is a
	 * group of one. The system's unknowns are the groups, each named by its leader (its first
	 * region): its rows and columns sum those of its regions. */
	int32_t *group_leader;     /* per region */
	int32_t *group_offsets;    /* region_count+1: a leader's regions, leader first; empty for the others */
	int32_t *group_regions;
	int32_t *coupling_offsets; /* region_count+1, between leaders */
	int32_t *coupling;
	int32_t *solve_order;      /* per region: the regions in the order the system is solved in */
	int32_t capacity;          /* cells of matrix and factor (at most LVP__SYSTEM_CELLS) */
	int32_t normal_capacity;   /* cells of normal */
	lvp__profile profile;      /* this step's; its arrays region_count */
	lvp__profile normal_profile; /* of the least-squares normal equations; region_count */
	lvp__system_place *place;  /* per region: this step's (lvp__system_cell) */
	double *matrix;            /* capacity: the summed system */
	double *factor;            /* capacity: its LU */
	double *normal;            /* normal_capacity: the normal equations, when the LU fails */
	double *assembly;          /* LVP__ASSEMBLY_CHUNKS blocks of assembly_block doubles */
	size_t assembly_block;     /* LVP__ASSEMBLY_BLOCK(capacity, region_count) */
	int32_t assembly_chunks;   /* the blocks of the last assembly */
	double *column_gain;       /* region_count: the summed gains of the last assembly, by column */
	double *row_sums;          /* region_count: the sums of the summed system's rows */
	double *rhs;               /* region_count: the right-hand side */
	double *solution;          /* region_count */
	double *row_values;        /* region_count: scratch (one row of the system) */
	int32_t *row_last;         /* region_count: scratch (each row's last nonzero column) */
	uint8_t *still;            /* region_count: scratch (the rows taken out of the system) */
} lvp__region_system;

/* Bones stretched against the bones they blend with (stretch.c). */
typedef struct lvp__stretch {
	int32_t *offsets;          /* region_count+1 (local mode) */
	int32_t *bones;            /* per entry: a bone other than the region's weighting a corner of its triangles */
	lvp__vec3 *centre;         /* per entry: where the pair's relative stretch is taken about (rest) */
	/* This frame: */
	lvp__mat4 *linear;         /* per entry: U_r^-1 U_b - I in the mesh's coordinates (its 3x3) */
	lvp__mat4 *bone_stretch;   /* bone_count*2: each bone's stretch U and U^-1 in the rigid frame */
	uint8_t *bone_stretch_invertible; /* per bone: U^-1 is set (U is, always) */
	int32_t *bone_entry;       /* LVP__STRETCH_GROUPS*bone_count: scratch per group, -1 between uses (the
	                            * entry of each bone for the region at hand) */
	float *corner_offset;      /* slot_count*3: scratch, y - x at each corner of each stretched region */
	int32_t *regions;          /* the stretched regions, in order */
	int32_t group_first[LVP__STRETCH_GROUPS + 1]; /* groups of regions */
	int32_t group_count;
	double *change;            /* per region: the reference change (zero without stretch) */
	bool any;                  /* some pair is stretched */
} lvp__stretch;

/* A joint between a region and a neighbour, this frame (lvp__begin_fold_over). */
typedef struct lvp__joint {
	bool bends;                /* the two bend about a joint: the rest is set */
	lvp__vec3 point, normal;   /* posed contact plane; normal from the region's side to the neighbour's */
	lvp__vec3 rest_point, rest_normal;
	lvp__vec3 axis;            /* posed bend axis, unit */
	lvp__vec3 concave;         /* posed, unit: from the joint into the bend */
	lvp__vec3 rest_inside;     /* at rest: a rest offset's dot product with it is that of the offset as the
	                              parent carries it with the posed concave direction square to the unbent
	                              child (towards the crease's bottom): the parent's skinning, transposed */
	double reach;              /* along the axis: the child bone's flesh radius */
	double soft;               /* how softly skin is pressed onto the plane (foldover.c) */
	double window;             /* how far the crease's skin may cross the plane; negative: held short of it
	                              (foldover.c) */
	int32_t child, parent;     /* the two bones: the child turns about its head */
	bool child_side;           /* the region of this entry is the child's */
} lvp__joint;

/* Scratch of the relaxation's plate (plate.c), vertex_count long, allocated with the relaxation's lists
 * (lvp__relaxation_begin) and kept between frames only as memory. */
typedef struct lvp__plate {
	uint8_t *role;             /* per vertex: LVP__PLATE_* during a settling, zero between */
	int32_t *free, *rows, *read; /* the vertices it moves, those in its bending sum (by local number once
	                              listed), those the rows read */
	int32_t free_count, row_count, read_count;
	int32_t *number;           /* per vertex the rows read: its local number, the free vertices first */
	int32_t *row_starts;       /* row_count+1: each row's neighbours in columns and weights */
	int32_t *columns;          /* per relaxation entry of a row: the neighbour's local number */
	float *weights;            /* and what the row's Laplacian multiplies its offset by */
	double *offsets;           /* *3, by local number: the offsets the rows read; the free ones are the unknowns */
	double *direction, *product, *residual; /* *3, by local number: conjugate gradients' */
} lvp__plate;

/* Fold-over prevention (foldover.c). */
typedef struct lvp__fold {
	uint8_t *contact;          /* per neighbour entry (lvp__mesh), this frame: LVP__CONTACT_* */
	lvp__joint *joints;        /* per neighbour entry, this frame */
	double *radius;            /* per region: its vertices' mean rest distance to its bone */
	double *mean_edge;         /* per region: its vertices' longest rest edges, averaged */
	int32_t *border_offsets;   /* per neighbour entry (s, j) + 1 into border_vertices */
	int32_t *border_vertices;  /* the vertices of s with an edge to a vertex of j */
	float *saved;              /* vertex_count*3: the positions before a round (lvp__correct_attempt) */
	float *longest_edge;       /* per vertex: its longest edge at the bind's rest (lvp__allowed_across) */
	double deepest;            /* this frame: how far the deepest press moved a vertex, in its longest rest
	                              edges (lvp__relaxation_rings) */
	int32_t *plane_entry;      /* per bone, this frame: the entry whose plane all its joints as the
	                              child share (lvp__share_child_planes), or -1 */
	uint8_t *held;             /* per vertex: moved back to a contact surface and held there (nonzero:
	                              the round that did, foldover.c), kept zero between frames */
	uint8_t *held_before;      /* per vertex: fold.held before a relaxation (lvp__relax_pressed) */
	int32_t *zone;             /* vertex_count: the vertices a relaxation may move, pressed ones first */
	int32_t *side_entry;       /* per neighbour entry (s, j), this frame: the entry that presses the skin of s's
	                              group on its side of the joint (foldover.c, lvp__find_side_entries), or -1 */
	lvp__plate plate;          /* the relaxation's plate (plate.c) */
} lvp__fold;

/* Skin kept from passing through skin (contact.c), allocated at the first frame that asks. */
typedef struct lvp__contact {
	lvp__bvh bvh;              /* over the triangles (mesh.triangles), refitted to each round */
	float *limit;              /* per triangle, this round: the share of the offsets that keeps it apart
	                              from every triangle it crosses and did not cross skinned (1: none) */
	uint8_t *moved;            /* per vertex: its triangles are tested this round */
	uint8_t *changed;          /* per vertex, a test after the shares were smoothed: moved since its
	                              triangles were last tested (the pairs tested have a triangle with such a
	                              corner; contact.c) */
	float *tested_scale;       /* per vertex: its scale when its triangles were last tested */
	float *asked;              /* per vertex, this check: the least share its pairs asked for, never
	                              smoothed (1: none) */
	float *asked_smoothed;     /* per vertex, a test after the rounds: `asked` smoothed (lvp__smooth_shares) */
	uint8_t *moved_nodes;      /* per node of the hierarchy: some triangle under it is tested, or (a later
	                              round) has a corner that moved since it was (contact.c, lvp__mark_nodes) */
	int32_t *leaf_of;          /* per triangle: the leaf of the hierarchy that holds it (-1: none, no area) */
	int32_t *dynamic_nodes;    /* this attempt: the nodes with a triangle around a dynamic vertex, the
	                              last first (what a refit between the skinning and the correction visits) */
	int32_t dynamic_node_count;
	uint8_t *node_dynamic;     /* per node: listed in dynamic_nodes */
	int32_t *refit_nodes;      /* a later round's refit: the dynamic nodes above a moved triangle, the
	                              last first (node_count) */
	float *scale, *next_scale; /* per vertex: what is kept of its offset (1: all of it) */
	uint8_t *shortened;        /* per vertex: some offset of it was shortened this frame */
	uint8_t *pinned;           /* per vertex, this frame: held by fold-over where skinned skin crosses
	                              (lvp__pin_held); its offset is never shortened */
	int32_t *raise_patch;      /* per vertex, a raise of pinned patches (lvp__raise_pinned_crossing): the
	                              number of its patch */
	float *raise_below, *raise_above, *raise_middle; /* per patch of a raise: its height's bisection */
	uint8_t *raise_tested;     /* per triangle, a raise: what its crossing says of its patch (contact.c) */
	uint8_t *raise_patch_crossing; /* per patch, a raise: some triangle of it crosses at its height */
	uint8_t *share_roles;      /* per vertex, after a raise: what its share does in a smoothing (LVP__SHARE_*) */
	float *shifted_limit;      /* per triangle, a first round: limit's share for the pairs that cross along
	                              the skinning's own crossing, moved by less than a triangle (contact.c) */
	int32_t *pair_count;       /* per triangle, a first round: pairs crossing after the correction counted
	                              at it (each pair once) */
	int32_t *skinned_pair_count; /* and of the pairs it visited, those crossing in the skinning */
	int32_t crossed;           /* the last lvp__keep_skin_apart: triangles its first round found crossing
	                              anew (each kept apart since) */
	float *settled;            /* vertex_count*3: where the last lvp__keep_skin_apart left step.positions,
	                              when its last round shortened nothing (settled_apart) */
	bool settled_apart;
	float *clearance;          /* per vertex, this frame: the room in front of its offset in the
	                              skinning (clearance.c; INFINITY: none near) */
	float *clearance_reach;    /* per vertex, this frame: how far that was searched (0: not yet) */
	double *sheets;            /* per node of bvh, this frame (clearance.c, lvp__fit_sheets): the slab of the
	                              skinning's triangles under it, which a clearance search tests wide balls on */
	float *clearance_direction; /* vertex_count*3, this frame: the unit direction it is searched along, its
	                              offset's at the frame's first search (clearance.c, lvp__start_search) */
	float *fade, *fade_scratch; /* per vertex: the share of its offset its clearance lets it keep */
	uint8_t *faded;            /* per vertex, this frame: its clearance held its offset back (before the shares
	                              were smoothed around), at some fade (lvp__kept_apart_counts) */
	int32_t *reader_offsets;   /* vertex_count + 1 into readers: */
	int32_t *readers;          /* the vertices whose smoothing neighbours hold each vertex (clearance.c) */
	int32_t *near;             /* scratch, vertex_count: the vertices a smoothing of shares walks, a raise's
	                              walk over its patches, or a first round's over its contacts */
	uint8_t *near_seen;        /* scratch, vertex_count: listed in near this smoothing (or the kind of
	                              contact a vertex is a corner of, contact.c) */
	uint8_t *connected;        /* per node of the hierarchy: its triangles are one patch (flat_patches.c) */
	float *cones;              /* per node: the cone of its triangles' normals at the last fit */
	uint8_t *flat;             /* per node: connected, and its cone under 90 degrees: none of its
	                              triangles can cross another of them */
	int32_t *group_offsets;    /* clearance.c: vertices near each other, searched together (CSR over */
	int32_t *group_vertices;   /* group_count groups; a vertex in no triangle of the hierarchy in none) */
	int32_t group_count;
} lvp__contact;

/* Separate parts of the mesh (parts.c): the whole-mesh step of lvp.h (ALGORITHM, 3) restores each
 * part's volume (correction.c). Part 0: all that is on the caller's bones (the first part that
 * bends, parts one bone carries, triangles without region); then each split part. */
typedef struct lvp__part_volumes {
	int32_t count;             /* 1 when nothing is split */
	int32_t *region_part;      /* per region: its part, or NULL (all part 0) */
	int32_t *vertex_part;      /* per vertex, or NULL */
	double *bind_volume;       /* per part: its volume, holes capped, at the bind rest */
	/* This frame: */
	double *rest_volume;       /* the same at this frame's rest */
	double *scale;             /* what its change is measured against */
	double *change;            /* its change at the last measurement (lvp__part_changes) */
	double *uniform;           /* the uniform multiplier of the last step (0 when not spreading) */
} lvp__part_volumes;

/* The correction steps of a frame (correction.c). */
typedef struct lvp__step {
	float *positions;          /* vertex_count*3: the frame's positions as the steps move them */
	int32_t *moved;            /* per vertex: vertices moved by the last step */
	float *backup;             /* vertex_count*3: their positions before it, in the same order */
	float *smoothing_offsets;  /* vertex_count*3: the offsets a smoothing pass reads, and after the passes
	                              the smoothed offsets (offset_smoothing.c) */
	float *smoothing_scratch;  /* vertex_count*3: the offsets every other smoothing pass writes */
	int32_t moved_count;
	int32_t *chunk_moved;      /* per LVP__GRAIN dynamic vertices: how many a step moved, -1 if none ran */
	double *change;            /* per region: V_s - V_s,rest in rest-world units */
	bool change_stale;         /* change is of positions before the last steps (lvp__global_steps) */
	double *target;            /* per region: the change a region is corrected to (lvp__correct_volumes):
	                              the stretch's change, plus its part of the whole mesh's fix */
	double *uniform_gain;      /* per active region: what equal multipliers of all active regions do
	                              to its volume (its row of the system) */
	double *total_gain;        /* per active region: what its multiplier does to the whole mesh's
	                              volume (sum_k g_k gamma_k g_k phi_kt) */
	double *diagonal;          /* per active region: its diagonal of the system (the per-region step) */
	uint8_t *region_movable;   /* per region: some vertex of its support can move this frame */
	int32_t movable_entries;   /* support entries of vertices that can move */
	uint8_t *region_touched;   /* per region: corrected at least once this frame */
	int32_t *active;           /* the active regions */
	int32_t *active_index;     /* per region: its index in active, or -1 */
	double *mu;                /* per region: its multiplier of the last step */
	double *applied_mu;        /* per region: mu of the regions a step applies, else 0 (kept zero) */
	double *moved_by;          /* per region: the sum of |mu| its steps applied this attempt */
	uint8_t *given_up;         /* per region: its group is left out of this frame (lvp_correct) */
	bool any_given_up;
	bool spread_total;         /* steps also restore each part's volume (lvp__correct_volumes) */
	double *part_total, *part_gain; /* per part: scratch of the uniform multipliers and whole-mesh steps */
	double *part_response;     /* per part: measured / predicted change of the last whole-mesh steps */
	double *part_mu;           /* per part: its multiplier of the smoothed offsets (along_offsets) */
	float *touched_phi;        /* per dynamic vertex (by its place in the set): the sum of its phi over the
	                              groups touched this frame (lvp__global_steps, one part) */
	double *chunk_gain;        /* per LVP__GRAIN dynamic vertices: their part of the whole mesh's gain */
	bool uniform_step;         /* the step applies one multiplier through touched_phi (lvp__apply_loop) */
	double uniform_mu;         /* that multiplier */
	bool along_offsets;        /* the step moves each vertex by part_mu of its part times its smoothed
	                              offset (lvp__apply_loop) */
} lvp__step;

/* The edge neighbours of each vertex, each with how many triangles of the vertex it is a corner of
 * (2 inside the surface, 1 on a border): what a smoothing pass averages over (offset_smoothing.c). */
typedef struct lvp__smoothing {
	int32_t *offsets;         /* vertex_count+1 */
	int32_t *neighbours;
	float *shares;            /* per neighbour: the weight its triangles around the vertex give it
	                             (offset_smoothing.c: 1 + the cotangent opposite, per triangle) */
	float *halves;            /* per neighbour: half its share of the vertex's shares, what a pass
	                             multiplies its offset by (the other half is the vertex's own) */
	int32_t *movable;         /* scratch, vertex_count: the dynamic vertices that can move, which the
	                             passes walk (lvp__smooth_offsets) */
	int32_t tie_count;        /* clusters of two or more vertices tied into one point (smoothing_ties.c) */
	int32_t *tie_offsets;     /* tie_count+1: each cluster's members in tie_members */
	int32_t *tie_members;
} lvp__smoothing;

struct lvp_binding {
	lvp_mode mode;
	lvp__pool *pool; /* worker threads, NULL for one thread */
	/* vertex_count counts the points (weld.c), the caller's vertices with the coincident ones
	 * taken once; the public API answers per caller vertex. bone_count counts the internal bones (parts.c): the caller's, then, when several separate
	 * parts of the mesh bend, a copy of each bone for every part after the first that uses it.
	 * Every array indexed by bone or region is over the internal bones; the public API answers in
	 * the caller's bones (bind.c, correction.c). */
	int32_t vertex_count, triangle_count, bone_count, region_count;
	int32_t caller_bone_count;
	float *rest_positions;  /* vertex_count*3: the bind rest (copied) */
	double rest_volume;     /* its signed volume, holes capped */
	double size;            /* the diagonal of its bounding box */

	lvp__weld weld;
	lvp__rig rig;
	lvp__bone_lines lines;
	lvp__mesh mesh;
	lvp__reach reach;
	lvp__map map;
	lvp__frame_map frame_map;
	lvp__borders borders;
	lvp__dynamic_set dynamic;
	lvp__measure measure;
	lvp__region_system system;
	lvp__stretch stretch;
	lvp__fold fold;
	lvp__contact contact;
	lvp__part_volumes parts;
	lvp__smoothing smoothing;  /* the offsets' smoothing passes */
	lvp__smoothing relaxation; /* fold-over's relaxation of pressed skin (lvp__relax_pressed): the same
	                              weights, tied by mean value weights; built at the first frame with
	                              fold-over (lvp__relaxation_begin) */
	lvp__step step;
};

/* parts.c */
/* The internal bones of a mesh whose separate parts bend (binding.h). Arrays are malloc'ed; the
 * NULL ones mean "nothing split". */
typedef struct lvp__parts {
	int32_t *weight_bones; /* weights->offsets[vertex_count]: the weights' bones, as internal bones */
	int32_t *bone_source;  /* bone_count: internal bone -> caller's bone, or NULL */
	int32_t *bone_part;    /* bone_count: internal bone -> part, or NULL */
	int32_t *vertex_part;  /* vertex_count: vertex -> part, or NULL */
	int32_t bone_count;    /* internal bones */
	int32_t part_count;    /* 1 when nothing is split */
} lvp__parts;
/* Finds the parts; without `split` (the global mode, one region) only copies the bones.
 * Inputs are validated. On failure *r_parts is all NULL. */
lvp_result lvp__split_parts(lvp__parts *r_parts, const lvp_weights *weights, int32_t vertex_count,
                            const int32_t *triangles, int32_t triangle_count, int32_t bone_count, bool split,
                            lvp_diagnostic *r_diag);

/* Frees the arrays of parts (when they were not handed to a binding) and clears it. */
void lvp__parts_free(lvp__parts *parts);

/* The caller's bone (or region, in local mode) of internal bone i. */
static inline int32_t lvp__caller_bone(const lvp_binding *binding, int32_t i)
{
	return binding->rig.bone_source && i >= 0 ? binding->rig.bone_source[i] : i;
}

/* Whether vertex k can move in a step: the frame's map lets it, and fold-over does not hold it. */
static inline bool lvp__can_move(const lvp_binding *binding, int32_t k)
{
	return binding->frame_map.gamma[k] > 0.0f && !binding->fold.held[k];
}

/* Whether vertex k follows the bone of skin class bone_class rigidly this frame (it does not move
 * in this frame's correction, and rest and posed agree in that bone's frame). */
static inline bool lvp__carried_rigidly(const lvp_binding *binding, int32_t k, int32_t bone_class)
{
	return !binding->frame_map.vertex_dynamic[k] && binding->frame_map.vertex_class[k] == bone_class;
}

/* The slot of vertex k for region r (it exists when k is on one of r's triangles), or -1. */
static inline int32_t lvp__find_slot(const lvp_binding *binding, int32_t k, int32_t r)
{
	for (int32_t slot = binding->mesh.slot_offsets[k]; slot < binding->mesh.slot_offsets[k + 1]; ++slot)
		if (binding->mesh.slot_region[slot] == r)
			return slot;
	return -1;
}

/* The part of region r (-1: the triangles without region, which count in part 0). */
static inline int32_t lvp__region_part(const lvp_binding *binding, int32_t r)
{
	return binding->parts.region_part && r >= 0 ? binding->parts.region_part[r] : 0;
}

/* The regions of the group that region `leader` leads (lvp__region_system): [*r_first, *r_last) of
 * system.group_regions, the leader first; empty when it leads none. */
static inline void lvp__group_range(const lvp_binding *binding, int32_t leader, int32_t *r_first, int32_t *r_last)
{
	*r_first = binding->system.group_offsets[leader];
	*r_last = binding->system.group_offsets[leader + 1];
}

/* Each stage's memory: _alloc (at bind, after the stages it is sized by; false when out of
 * memory, the binding then freed by lvp_bind) and _free (of every array the stage holds, also
 * those its build step allocated). */
bool lvp__rig_alloc(lvp_binding *binding, const lvp_weights *weights); /* weights NULL: no skeleton */
bool lvp__mesh_alloc(lvp_binding *binding);
bool lvp__map_alloc(lvp_binding *binding);
bool lvp__frame_map_alloc(lvp_binding *binding);
bool lvp__borders_alloc(lvp_binding *binding);        /* after the parts are known */
bool lvp__dynamic_set_alloc(lvp_binding *binding);
bool lvp__measure_alloc(lvp_binding *binding);        /* after lvp__segment (the slots) */
bool lvp__fold_alloc(lvp_binding *binding);           /* after lvp__segment (the neighbours) */
bool lvp__part_volumes_alloc(lvp_binding *binding);
bool lvp__step_alloc(lvp_binding *binding);
void lvp__rig_free(lvp__rig *rig);
void lvp__mesh_free(lvp__mesh *mesh);
void lvp__map_free(lvp__map *map);
void lvp__frame_map_free(lvp__frame_map *frame_map);
void lvp__borders_free(lvp__borders *borders);
void lvp__dynamic_set_free(lvp__dynamic_set *dynamic);
void lvp__measure_free(lvp__measure *measure);
void lvp__region_system_free(lvp__region_system *system);
void lvp__stretch_free(lvp__stretch *stretch);
void lvp__fold_free(lvp__fold *fold);
void lvp__part_volumes_free(lvp__part_volumes *parts);
void lvp__step_free(lvp__step *step);

/* weld.c */
/* The welded mesh lvp_bind works on when some vertices coincide (its arrays malloc'ed). */
typedef struct lvp__welded_mesh {
	int32_t vertex_count;
	float *positions;
	int32_t *triangles;
	int32_t *weight_offsets, *weight_bones;
	float *weight_values;
	lvp_weights weights;       /* over the three arrays above, when weights were given */
} lvp__welded_mesh;
/* Finds the points of the caller's mesh (inputs validated). When no two vertices coincide,
 * weld->vertex_point stays NULL and *r_mesh empty; else *r_mesh is the welded mesh. */
lvp_result lvp__find_points(lvp__weld *weld, lvp__welded_mesh *r_mesh, const float *positions, int32_t vertex_count,
                            const int32_t *triangles, int32_t triangle_count, const lvp_weights *weights,
                            lvp_diagnostic *r_diag);
void lvp__welded_mesh_free(lvp__welded_mesh *mesh);
void lvp__weld_free(lvp__weld *weld);
/* r_points[3p..3p+2] = vertex_values of point p's first vertex. */
void lvp__gather(float *r_points, const lvp__weld *weld, const float *vertex_values);
/* Checks a frame's positions (and its rest, when given) against the caller's vertex count and,
 * on a welded mesh, points *positions and *rest_positions to the points' (gathered). */
lvp_result lvp__frame_points(lvp_binding *binding, const float **positions, const float **rest_positions,
                             lvp_diagnostic *r_diag);
/* The caller's vertex whose values point p takes (itself when nothing is welded). */
static inline int32_t lvp__point_vertex(const lvp_binding *binding, int32_t p)
{
	return binding->weld.point_first ? binding->weld.point_first[p] : p;
}
/* The point of caller vertex k. */
static inline int32_t lvp__vertex_point(const lvp_binding *binding, int32_t k)
{
	return binding->weld.vertex_point ? binding->weld.vertex_point[k] : k;
}

/* bone_lines.c */
/* The bones' lines (lvp__bone_lines), after lvp__rig_copy; bone_groups as lvp_bind_options'.
 * False when out of memory. */
bool lvp__build_bone_lines(lvp_binding *binding, const lvp_skeleton *skeleton, const int32_t *bone_groups);
/* Rest distance from p to the bone's line. */
double lvp__bone_distance(const lvp_binding *binding, int32_t bone, lvp__vec3 p);
void lvp__bone_lines_free(lvp__bone_lines *lines);

/* rig.c */
/* Copies the weights, normalized by their sum (their bones are already in weight_bones,
 * lvp__split_parts), and the bones' rest frames (each internal bone its caller's). */
void lvp__rig_copy(lvp_binding *binding, const lvp_weights *weights, const lvp_skeleton *skeleton);
/* Checks the bone matrices and poses the bones: posed, skin, kappa, region_skipped (after
 * lvp__frame_points). */
lvp_result lvp__prepare_frame(lvp_binding *binding, const float *bone_matrices, lvp_diagnostic *r_diag);

/* segmentation.c */
/* Largest normalized weight of vertex k (into *r_max) and its bone, the one that dominates it (ties:
 * lower bone index); -1 if none. Needs the rig's weights only. */
int32_t lvp__main_bone(const lvp_binding *binding, int32_t k, float *r_max);
lvp_result lvp__segment(lvp_binding *binding, lvp_diagnostic *r_diag);
/* Each region's distinct corner vertices (lvp__mesh); after lvp__segment. */
lvp_result lvp__build_region_corners(lvp_binding *binding, lvp_diagnostic *r_diag);

/* map.c */
lvp_result lvp__build_map(lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag);

/* reach.c */
/* The reach for a bulge width (lvp.h, BULGE WIDTH; 0: the weights), after the segmentation. */
lvp_result lvp__build_reach(lvp_binding *binding, float bulge_width, lvp_diagnostic *r_diag);
void lvp__reach_free(lvp__reach *reach);
lvp_result lvp__check_map_options(const lvp_binding *binding, const lvp_map_options *map, lvp_diagnostic *r_diag);

/* borders.c */
lvp_result lvp__build_borders(lvp_binding *binding, lvp_diagnostic *r_diag);
/* The rest side of the borders' side quads at rest_positions, or at the bind rest for NULL (kept
 * while the frames use the bind rest). */
void lvp__borders_rest(lvp_binding *binding, const float *rest_positions);
/* 6 x the volume of the cones that cap the mesh's holes (0 when closed); the same over the cap
 * edges [begin, end) only, from the mean of their first vertices. */
double lvp__cap_volume6(const lvp_binding *binding, const float *positions);
double lvp__cap_range_volume6(const lvp_binding *binding, const float *positions, int32_t begin, int32_t end);
/* Signed volume of the mesh at positions, holes capped (double precision). */
double lvp__volume_of(const lvp_binding *binding, const float *positions);
/* The same per part (lvp__part_volumes): r_volumes has parts.count entries. Each part's holes are
 * capped from their own apex; the triangles without region count in part 0. */
void lvp__volumes_of_parts(const lvp_binding *binding, const float *positions, double *r_volumes);

/* dynamic_set.c */
/* Which triangles and vertices a pass visits (lvp__dynamic_set), from vertex_class and
 * vertex_dynamic; with all_dynamic, everything. rest_totals: rest_totals or frame_totals. */
void lvp__find_dynamic_set(lvp_binding *binding, const float *rest_positions, const lvp__region_sums *rest_totals,
                           bool all_dynamic);
/* Something the dynamic set is made of changed: it is found anew at the next lvp__find_dynamic_set. */
void lvp__dynamic_set_stale(lvp_binding *binding);
/* A region all of whose triangles are dynamic, static (carried by its bone), or some of each. */
enum { LVP__REGION_DYNAMIC, LVP__REGION_STATIC, LVP__REGION_MIXED };

/* local_volume.c */
/* One pass over the dynamic triangles at `positions`: their terms and the region sums. */
void lvp__mesh_pass(lvp_binding *binding, const float *positions);
/* The same after only the vertices moved[0..moved_count) moved: visits their triangles only
 * (and keeps the vertex terms current when they were). */
void lvp__update_pass(lvp_binding *binding, const float *positions, const int32_t *moved, int32_t moved_count);
/* What a correction step needs of the last measurement (of step.positions): normals, g and slot_g
 * of the dynamic vertices, the regions' border terms included. Measuring alone does not need them,
 * so the measurement that ends the iteration skips them. */
void lvp__vertex_gradients(lvp_binding *binding);
/* Only the normals and g of the dynamic vertices: what a step of the whole mesh's one multiplier
 * needs (lvp__global_steps), which reads no region's gradient. */
void lvp__vertex_normals(lvp_binding *binding);
/* Rest side: the region sums of the rest positions (NULL = bind rest) about the rest origins. */
void lvp__rest_constants(lvp_binding *binding, const float *rest_positions, lvp__region_sums *r_totals);
/* The rest side of a frame whose rest is rest_positions (NULL = bind rest): borders.rest, and the
 * region sums to measure against (rest_totals, or frame_totals filled from rest_positions). */
const lvp__region_sums *lvp__frame_rest(lvp_binding *binding, const float *rest_positions);
/* reference_volume[] from the bind rest (see lvp.h, lvp_frame_options.tolerance). */
void lvp__reference_volumes(lvp_binding *binding);
/* Region changes (rest-world units) from the last mesh pass at `positions`; needs posed/posed_inverse. */
void lvp__region_changes(lvp_binding *binding, const float *positions, const lvp__region_sums *rest_totals,
                         double *r_change);
/* Side quad (a, A, B, b) of the prism over the border half-edge a -> b (A, B: a and b at rest),
 * split in four at its centroid m, points in one frame (the bone's). Returns 6 times its signed
 * volume, and in r_grad_a, r_grad_b its gradient with respect to the deformed corners a and b (m
 * moves with them). Only rest_sum = A + B and rest_cross = A x B are needed: expanding the four
 * triangles' sum of x . (y x m), the terms with a repeated point vanish and the rest pair up
 * into ((a + b) . (A x B) + a . ((A + B) x b)) / 2. */
static inline double lvp__side_quad6(lvp__vec3 *r_grad_a, lvp__vec3 *r_grad_b, lvp__vec3 a, lvp__vec3 b,
                                     lvp__vec3 rest_sum, lvp__vec3 rest_cross)
{
	lvp__vec3 sum_b = lvp__cross(rest_sum, b);
	*r_grad_a = lvp__scale(lvp__add(rest_cross, sum_b), 0.5);
	*r_grad_b = lvp__scale(lvp__add(rest_cross, lvp__cross(a, rest_sum)), 0.5);
	return 0.5 * (lvp__dot(lvp__add(a, b), rest_cross) + lvp__dot(a, sum_b));
}

/* Signed mesh volume, holes capped, from the last mesh pass over `positions`; and per part. */
double lvp__pass_volume(const lvp_binding *binding, const float *positions);
void lvp__pass_part_volumes(const lvp_binding *binding, const float *positions, double *r_volumes);

/* Volume term (p0 - o) . cr and cr = (p1 - p0) x (p2 - p0) of a triangle. In float: each term
 * is exact to float precision and the sums are taken in double. */
static inline double lvp__triangle_cross(float r_cross[3], const float *positions, const int32_t *corners,
                                         const float *o)
{
	const float *p0 = positions + 3 * corners[0];
	const float *p1 = positions + 3 * corners[1];
	const float *p2 = positions + 3 * corners[2];
	float e1x = p1[0] - p0[0], e1y = p1[1] - p0[1], e1z = p1[2] - p0[2];
	float e2x = p2[0] - p0[0], e2y = p2[1] - p0[1], e2z = p2[2] - p0[2];
	float cx = e1y * e2z - e1z * e2y, cy = e1z * e2x - e1x * e2z, cz = e1x * e2y - e1y * e2x;
	r_cross[0] = cx;
	r_cross[1] = cy;
	r_cross[2] = cz;
	return (double)((p0[0] - o[0]) * cx + (p0[1] - o[1]) * cy + (p0[2] - o[2]) * cz);
}

/* The origin of region r's bone frame at rest (global mode: the rest centroid). */
static inline lvp__vec3 lvp__rest_origin(const lvp_binding *binding, int32_t region)
{
	if (binding->mode == LVP_MODE_GLOBAL)
		return binding->measure.global_origin;
	const double *m = binding->rig.rest_matrices[region].m;
	return lvp__v(m[3], m[7], m[11]);
}

/* frame_map.c */
/* This frame's map (the bind map times the deformation weighting), the bones' skin classes and
 * the vertices' classes and dynamic flags (needs lvp__prepare_frame). rest_positions: this
 * frame's rest, or NULL for the bind rest. */
void lvp__build_frame_map(lvp_binding *binding, const float *rest_positions);
/* The bind map changed: the next lvp__build_frame_map walks every vertex. */
void lvp__frame_map_stale(lvp_binding *binding);
/* Vertex k, or every vertex, is dynamic until the frame map is built again. */
void lvp__make_dynamic(lvp_binding *binding, int32_t k);
void lvp__make_all_dynamic(lvp_binding *binding);
/* Whether this frame may carry rigid vertices in closed form (lvp__frame_map, rigid_shortcut_off). */
void lvp__use_rigid_shortcut(lvp_binding *binding, bool usable);
/* Whether positions put the vertices that the frame map found carried rigidly where their
 * bone class carries them (checked on a sample, at most LVP__RIGID_SAMPLES a region); r_off:
 * the largest distance found. The closed-form shortcuts of the measurement rest on it. */
bool lvp__rigid_vertices_hold(const lvp_binding *binding, const float *positions, const float *rest_positions,
                              double *r_off);

/* region_system.c */
/* The groups of the regions (bone_groups: lvp.h, GROUPS; NULL, each region alone), their
 * coupling, their solve order and the system's storage (binding.h); after
 * lvp__build_region_corners. */
lvp_result lvp__build_region_system(lvp_binding *binding, const int32_t *bone_groups, lvp_diagnostic *r_diag);
/* Lays out the system of a step over active[0..m) (in solve order, active_index set) in
 * system.profile and system.place; returns how many of them it holds (the first ones), up to
 * system_capacity. */
int32_t lvp__system_layout(lvp_binding *binding, int32_t m);
/* The cell of the step's system that region `row`'s row and region `column`'s column meet in
 * (their places, binding.h), or `spare` when either is not in the system or the entry is outside
 * the profile. Branch free: the assembly calls it for every pair of a vertex's regions. */
static inline int32_t lvp__system_cell(lvp__system_place row, lvp__system_place column, int32_t spare)
{
	int32_t below = column.index >= row.first ? row.lower + column.index : spare;
	int32_t above = row.index >= column.first ? column.upper + row.index : spare;
	return column.index <= row.index ? below : above;
}
/* Whether this step's system is assembled row by row (binding.h, LVP__ROWS_ASSEMBLY). */
static inline bool lvp__assembled_by_rows(const lvp_binding *binding)
{
	return binding->system.profile.count <= LVP__ROWS_ASSEMBLY;
}
/* Where the gains start in an assembly block of this step (binding.h, LVP__ASSEMBLY_CHUNKS): after
 * the (count + 1)^2 sums row by row, or the profile's cells and a spare one. */
static inline size_t lvp__assembly_gains_at(const lvp_binding *binding)
{
	size_t stride = (size_t)binding->system.profile.count + 1;
	return lvp__assembled_by_rows(binding) ? stride * stride : (size_t)binding->system.profile.cells + 1;
}
/* matrix and column_gain: the sums of the chunks' blocks of the last assembly, added in chunk order. */
void lvp__sum_system(lvp_binding *binding);
/* row_sums: the sum of each row of the summed system. */
void lvp__system_row_sums(lvp_binding *binding);
/* Solves the summed system for rhs into solution: regions with a diagonal under 1e-12 of
 * largest_diagonal taken out (multiplier 0), LU, and damped least squares when the LU cannot be
 * trusted. Returns false when neither solves it. */
bool lvp__solve_system(lvp_binding *binding, double largest_diagonal);


/* stretch.c */
/* The bones weighting each region's triangles, and the centre of each pair (lvp.h, ALGORITHM 3). */
lvp_result lvp__build_stretch_pairs(lvp_binding *binding, lvp_diagnostic *r_diag);
/* This frame's stretch.change, zero for every region when no bone is stretched, or when no
 * region's volume changes by more than `tolerance` of its reference by the stretch (needs
 * lvp__prepare_frame and this frame's dynamic set, lvp__find_dynamic_set); sets and returns
 * stretch.any.
 * rest_positions: this frame's rest, or NULL for the bind rest; rigid_space: see lvp.h
 * (lvp_frame_options), checked. */
bool lvp__stretch_targets(lvp_binding *binding, const float *rest_positions, const float *rigid_space,
                          double tolerance);

/* foldover.c */
/* Moves the vertices that crossed into a neighbouring bone's flesh back to the contact surface
 * and holds them (fold.held); marks the neighbour pairs where that happened. Returns how many
 * vertices it held that were not held yet. */
int32_t lvp__fold_over(lvp_binding *binding, const float *rest_positions);
/* The rings (and passes) of the relaxation of this frame's presses (lvp__relax_pressed): the offsets'
 * smoothing passes, or where the presses went deeper than those rings can take, more (foldover.c). */
int32_t lvp__relaxation_rings(const lvp_binding *binding, int32_t smoothing_passes);
/* Relaxes the skin fold-over pressed with the skin around it (within `passes` rings), `passes` times:
 * every held vertex let go, the offsets smoothed one pass (lvp__smooth_offsets), the skin pressed
 * again at the joints where skin crossed; then the skin its last pass left free settled as a plate
 * (lvp__settle_as_plate, reaching about half smoothing_passes rings) and pressed again. The vertices
 * held before stay held. The volume it takes is not restored here. rest_positions, totals: as for
 * the dynamic set (lvp__find_dynamic_set), which it keeps listing the vertices presses made dynamic.
 * Returns whether any vertex was held (else it does nothing). */
bool lvp__relax_pressed(lvp_binding *binding, const float *positions, const float *rest_positions,
                        const lvp__region_sums *totals, int32_t passes, int32_t smoothing_passes);
/* Fades frame_map.gamma near the contact surfaces of the pairs marked since the last call; returns
 * whether there was any. */
bool lvp__fade_map_at_contact(lvp_binding *binding);
/* Finds this frame's joints and their planes, through the creases of step.positions and of the
 * rest (rest_positions: the frame's, NULL for the bind's), and forgets its contacts (before the
 * first lvp__fold_over of a frame). */
void lvp__begin_fold_over(lvp_binding *binding, const float *rest_positions);

/* plate.c */
/* Settles the free vertices of the relaxation's zone (zone[count], those fold.held does not hold) as a thin
 * plate tied to their offsets from `positions` beyond about half smoothing_passes rings; the held vertices
 * and the skin outside the zone stay. Moves step.positions. */
void lvp__settle_as_plate(lvp_binding *binding, const float *positions, const int32_t *zone, int32_t count,
                          int32_t smoothing_passes);
bool lvp__plate_alloc(lvp__plate *plate, int32_t vertex_count, int32_t entry_count);
void lvp__plate_free(lvp__plate *plate);

/* offset_smoothing.c */
/* The neighbour lists of the smoothing passes (binding.smoothing), from the sorted triangles. */
lvp_result lvp__build_smoothing(lvp_binding *binding, lvp_diagnostic *r_diag);
/* Those of fold-over's relaxation (binding.relaxation), and its plate's scratch (plate.c), built at the first
 * frame that asks for fold-over: a binding that never does has no use for them. */
lvp_result lvp__relaxation_begin(lvp_binding *binding, lvp_diagnostic *r_diag);
void lvp__smoothing_free(lvp__smoothing *smoothing);
/* smoothing_ties.c */
/* Gives the vertices that one neighbour dominates in `smoothing` the neighbours of the cluster they
 * form with it, so that a pass averages them as one point, and lists those clusters
 * (smoothing.tie_offsets, tie_members). Which neighbour dominates is decided on tie_shares (per entry
 * of smoothing's lists), or on smoothing.shares when NULL; the cluster's neighbours weigh by
 * smoothing.shares. */
lvp_result lvp__tie_smoothing(lvp_binding *binding, lvp__smoothing *smoothing, const float *tie_shares,
                              lvp_diagnostic *r_diag);
/* The offsets (step.positions against `positions`, the input points) of each cluster's members
 * replaced by their mean, but for the clusters with a member fold-over holds (fold.held): what moved
 * them one by one (the volume steps through the map) moves them as one point again. A member the map
 * left static is made dynamic when the mean moves it. */
void lvp__move_ties_as_one(lvp_binding *binding, const float *positions);
/* What lvp__smooth_offsets averages by, and which vertices move. */
typedef enum lvp__smoothing_kind {
	/* A frame's offsets: the mesh's weights, every third pass equal (offset_smoothing.c); the
	 * vertices that can move, the moving skin's rim feathered after the passes. */
	LVP__SMOOTH_FRAME,
	/* As LVP__SMOOTH_FRAME but the mesh's weights on every pass: beside fold-over's contacts, where
	 * equal passes left creases along the contact line and skin crossing again. */
	LVP__SMOOTH_BY_THE_MESH,
	/* Fold-over's relaxation (lvp__relax_pressed): binding.relaxation's weights and lists, every
	 * dynamic vertex that fold-over does not hold moving, its map zero or not; no feathering. */
	LVP__SMOOTH_RELAXATION,
} lvp__smoothing_kind;
/* `passes` passes of smoothing over the offsets of the vertices that can move (step.positions
 * against `positions`, the input points): each takes half its own offset and half the mean of its
 * neighbours', weighed as `kind` says. The volume is not restored here; step.smoothing_offsets is left
 * holding the smoothed offsets. */
void lvp__smooth_offsets(lvp_binding *binding, const float *positions, int32_t passes, lvp__smoothing_kind kind);
/* step.smoothing_offsets of the dynamic vertices: their offsets as they are (step.positions less
 * positions), for steps along them (lvp__restore_smoothed) without smoothing. */
void lvp__take_offsets(lvp_binding *binding, const float *positions);
/* The moving skin's rim (frame_map.rim) feathered again against the offsets as they are (step.positions against
 * `positions`), as lvp__smooth_offsets feathers it after its passes: after restores that grew the moving skin's
 * offsets but not the rim's. Leaves step.smoothing_offsets holding every dynamic vertex's offset; the volume is
 * not restored here. */
void lvp__feather_rim_again(lvp_binding *binding, const float *positions);

/* contact.c */
/* Allocates the contact test at the first call (lvp_error_out_of_memory when it cannot). */
lvp_result lvp__contact_begin(lvp_binding *binding, lvp_diagnostic *r_diag);
/* The hierarchy fitted to `positions` (the frame's input points), every triangle, and the nodes
 * that later fits visit listed (contact.dynamic_nodes): first of each attempt that keeps skin apart,
 * after the dynamic set is found. */
void lvp__contact_fit_skinning(lvp_binding *binding, const float *positions);
/* Shortens the offsets (step.positions against `positions`, the input points) of the corners of
 * every pair of triangles that crosses after the correction but not in the input, to what keeps the
 * pair apart, over a few rounds (the last takes them away), smoothed around them; the patches of
 * vertices fold-over holds where the input crosses itself keep theirs (contact.pinned). first: the
 * frame's first call (forgets contact.shortened, finds contact.pinned). toward_last_check: a later
 * call after a restore through the map, whose offsets are shortened toward where the call before
 * left the skin when its rounds ended apart (contact.settled), and its pairs judged against those
 * positions rather than the input's. Returns how many dynamic vertices it shortened, and sets
 * contact.crossed. Uses fold.saved as scratch. */
int32_t lvp__keep_skin_apart(lvp_binding *binding, const float *positions, bool first, bool toward_last_check);
/* Fades frame_map.gamma by what the last lvp__keep_skin_apart left of each offset (contact.scale):
 * where skin met skin, the next volume step moves it as much less. */
void lvp__fade_map_where_shortened(lvp_binding *binding);
/* The dynamic vertices this frame's Keep Skin Apart shortened (any lvp__keep_skin_apart: r_shortened) and
 * those it held back (r_kept_apart): shortened, or, when `faded` (the clearance was measured this frame),
 * faded where they neared other skin (contact.faded). */
void lvp__kept_apart_counts(const lvp_binding *binding, bool faded, int32_t *r_shortened, int32_t *r_kept_apart);
/* Whether step.positions are where the last lvp__keep_skin_apart left them, its last round shortening
 * nothing there: another check would shorten nothing (a restore after a fade that moved no vertex). */
bool lvp__still_where_kept_apart(const lvp_binding *binding);
void lvp__contact_free(lvp__contact *contact);

/* flat_patches.c */
/* contact.connected, and room for the cones (after the hierarchy and contact.leaf_of are built). */
lvp_result lvp__flat_patches_begin(lvp_binding *binding, lvp_diagnostic *r_diag);
/* contact.cones and contact.flat of the nodes of contact.dynamic_nodes, from the hierarchy's corners as
 * last fitted (a node with a child not listed is not flat: only listed nodes are searched for crossings,
 * and the others' cones are not fitted). */
void lvp__fit_flat_patches(lvp__contact *contact, lvp__pool *pool);

/* clearance.c */
/* contact.group_offsets and group_vertices (after the hierarchy and contact.leaf_of are built). */
lvp_result lvp__clearance_begin(lvp_binding *binding, lvp_diagnostic *r_diag);
/* contact.clearance of the dynamic vertices, ahead of their offsets (step.positions less
 * `positions`) in the skinning at `positions` (contact.bvh fitted to it: lvp__contact_fit_skinning),
 * as far as their offsets want (LVP__CLEARANCE_WANTED times them, clearance.c); `again` after the
 * offsets changed (the same frame): only those whose offsets grew past what was searched are, along the
 * direction of their first search this frame. */
void lvp__measure_clearance(lvp_binding *binding, const float *positions, bool again);
/* Scales the offsets (step.positions and step.smoothing_offsets) and frame_map.gamma of the dynamic
 * vertices by the share their clearance lets them keep, smoothed over a few rings; returns false,
 * changing nothing, when every offset is within its clearance. */
bool lvp__fade_at_clearance(lvp_binding *binding, const float *positions);
/* Shares of the dynamic vertices' offsets (per vertex, at most 1) smoothed over the rings around:
 * none left more than LVP__SHARE_SLOPE (clearance.c) above a neighbour's, then averaged; with
 * keep_floors the averaging only lowers (it rounds the rims of the dips and keeps their floors).
 * `roles` (per vertex, or NULL: all LVP__SHARE_SMOOTHED) says what each vertex's share does. `scratch`:
 * per vertex. */
void lvp__smooth_shares(lvp_binding *binding, float *shares, float *scratch, const uint8_t *roles, bool keep_floors);
/* What a vertex's share does in lvp__smooth_shares: */
enum {
	LVP__SHARE_SMOOTHED = 0, /* read by its neighbours, and smoothed */
	LVP__SHARE_KEPT = 1,     /* not read by the others; takes only the slope from the skin around it (kept or
	                            not), never averaged */
	LVP__SHARE_FIXED = 2,    /* read by its neighbours, never changed */
};

#endif /* LVP_BINDING_H */
