/*
 * diffusion.h - rows of bone weights diffused over a mesh's edges (diffusion.c). Shared by the
 * automatic weights (weights.c: SMOOTHING in lvp.h) and the correction's reach (reach.c: BULGE
 * WIDTH in lvp.h). Not part of the public API.
 */
#ifndef LVP_DIFFUSION_H
#define LVP_DIFFUSION_H

#include "lvp_internal.h"
#include "threads.h"

/* Bones per row while diffusing: room for the blends of a few bones around a joint; at most
 * LVP__DIFFUSION_MAX_ROW (rows with more keep their strongest). */
#define LVP__DIFFUSION_ROW 8
#define LVP__DIFFUSION_MAX_ROW 32
/* A step's vertices are cut into at most this many chunks, each with scratch of its own. */
#define LVP__DIFFUSION_CHUNKS 16

/* Rows of `stride` entries, sorted by decreasing weight: counts[k] bones of vertex k at
 * bones + k * stride, their weights at values + k * stride (they sum to 1 after a step). */
typedef struct lvp__diffusion {
	int32_t stride;
	int32_t *counts, *bones;
	float *values;
	int32_t *next_counts, *next_bones;
	float *next_values;
	int32_t *neighbour_offsets, *neighbours; /* the edge neighbours of each vertex, CSR */
	/* Scratch of each chunk of `grain` vertices (at most LVP__DIFFUSION_CHUNKS): bone_count sums,
	 * zero between vertices, and the bones a vertex met. */
	double *accum;
	int32_t *touched;
	int32_t bone_count, grain;
	void *memory;
} lvp__diffusion;

/* Allocates rows of `stride` entries (at most LVP__DIFFUSION_MAX_ROW) for vertex_count vertices
 * over bone_count bones and finds the edge neighbours of the triangles (degenerate corners left
 * out). The rows start empty: the caller fills counts, bones and values. Returns false when
 * memory runs out (free it anyway). */
bool lvp__diffusion_init(lvp__diffusion *diffusion, const int32_t *triangles, int32_t vertex_count,
                         int32_t triangle_count, int32_t bone_count, int32_t stride);
void lvp__diffusion_free(lvp__diffusion *diffusion);
/* The rows and scratch alone, for a graph whose neighbour lists the caller sets: neighbour_offsets
 * (vertex_count + 1, in the block) and neighbours (malloc'ed; lvp__diffusion_free frees it). */
bool lvp__diffusion_alloc(lvp__diffusion *diffusion, int32_t vertex_count, int32_t bone_count, int32_t stride);

/* Sorts each list [offsets[k], offsets[k + 1]) of `list` (k < count), drops repeats and k itself, and
 * packs the lists to the front, offsets shrinking to match. */
void lvp__compact_neighbour_lists(int32_t *offsets, int32_t *list, int32_t count);

/* Adds `share` times row k of `rows` to the sums in accum, listing in touched (touched_count of them so far)
 * each bone met for the first time; returns the new count. A share that adds nothing (a weight that rounded
 * to zero) is skipped: its bone, not yet in accum, would be listed once per such share, past its bone_count
 * entries. */
static inline int32_t lvp__diffusion_add_row(double *accum, int32_t *touched, int32_t touched_count,
                                             const lvp__diffusion *rows, int32_t k, double share)
{
	int64_t at = (int64_t)k * rows->stride;
	for (int32_t j = 0; j < rows->counts[k]; ++j) {
		int32_t bone = rows->bones[at + j];
		double value = share * (double)rows->values[at + j];
		if (!(value > 0.0))
			continue;
		if (accum[bone] == 0.0)
			touched[touched_count++] = bone;
		accum[bone] += value;
	}
	return touched_count;
}

/* A row from the sums of its bones in accum (the bones met listed in touched, accum zero elsewhere): the
 * `stride` strongest, by decreasing weight, renormalized, into r_bones and r_values; clears what it read
 * of accum. Returns the row's length. */
int32_t lvp__diffusion_finish_row(int32_t *r_bones, float *r_values, int32_t stride, double *accum,
                                  const int32_t *touched, int32_t touched_count);

/* One step: every row becomes (1 - rate_k) of itself plus rate_k of the mean of its own and its
 * edge neighbours' rows, kept to the `stride` strongest bones and renormalized. rates NULL: 1
 * for every vertex. A row of one bone among neighbours of that bone alone is copied. Rows are
 * independent within a step: split over the pool's threads (NULL: this thread), the same result. */
void lvp__diffusion_step(lvp__diffusion *diffusion, int32_t vertex_count, const float *rates, lvp__pool *pool);

/* Copies vertex_count rows of `stride` entries (counts, bones, values) from the from_ arrays. */
void lvp__copy_rows(int32_t *counts, int32_t *bones, float *values, const int32_t *from_counts,
                    const int32_t *from_bones, const float *from_values, int32_t vertex_count, int32_t stride);

/* `steps` steps of lvp__diffusion_step. With `wanted` (per vertex, nonzero: wanted), on this thread and only
 * on the wanted vertices and those within `steps` edges of one, which is all that the wanted ones' rows
 * read: theirs come out as the whole mesh's steps give them, bit for bit; the others' rows are left partly
 * stepped. Returns false when memory runs out (wanted only). */
bool lvp__diffusion_steps_near(lvp__diffusion *diffusion, int32_t vertex_count, int64_t steps, const uint8_t *wanted,
                               lvp__pool *pool);

/* Diffuses the rows as `steps` steps at rate 1 would. From LVP__DIFFUSION_COARSE_FROM steps on, in a
 * time that does not grow with them (diffusion_levels.c): the rows are averaged over clusters of the
 * vertices within LVP__DIFFUSION_CLUSTER_RINGS edges of a seed, diffused over the graph of the
 * clusters (adjacent when an edge joins them) as far as the steps would spread them (through clusters
 * of clusters when that is many steps again), given back to
 * the vertices, and smoothed over about one cluster's width by ordinary steps. Like the steps, weight
 * flows only along edges. positions: the vertices', to measure the clusters' spacing. wanted (NULL:
 * every vertex): the ordinary steps are taken only where the wanted vertices' rows need them
 * (lvp__diffusion_steps_near), and only the wanted rows are the blend's. Returns false when memory
 * runs out (the rows are then as they were or diffused in part). */
#define LVP__DIFFUSION_COARSE_FROM 64
#define LVP__DIFFUSION_CLUSTER_RINGS 2
bool lvp__diffusion_blend(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count, int64_t steps,
                          const uint8_t *wanted, lvp__pool *pool);

/* Blends the rows (filled, not yet blended) over a distance that follows the flesh (lvp.h, SMOOTHING BY
 * THICKNESS; diffusion_thickness.c): distances[k] is vertex k's distance from the first bone of its row
 * (what its bone's thickness is measured by), depths[k] how deep the vertex lies under its skin (that
 * distance, at most twice the straight one and the longest bone's length), share how many times a bone's
 * thickness or a vertex's depth its skin blends over. Returns false when memory runs out (the rows are
 * then partly blended). */
bool lvp__diffusion_blend_by_thickness(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count,
                                       const double *distances, const double *depths, double share);

/* Aggregation multigrid over one symmetric system sum_j -c_ij x_j + d_i x_i (screened_multigrid.c): one
 * cycle is bone heat's preconditioner. Level 0 is the caller's system (borrowed; offsets/columns/coupling
 * its rows' off-diagonal entries), each next level the one above summed over aggregates of neighbours. */
#define LVP__MULTIGRID_MAX_LEVELS 16
typedef struct lvp__multigrid_level {
	int32_t n;
	int32_t *offsets, *columns;
	double *coupling, *diagonal, *inverse; /* inverse: 1 / diagonal */
	int32_t *aggregate; /* each vertex's aggregate at the next level; NULL on the coarsest */
	double *x, *b;      /* the level's solution and right-hand side in a cycle from the level above */
	double *r, *y;      /* the residual of that and its correction (the second cycle) */
	double *t;          /* scratch */
} lvp__multigrid_level;
typedef struct lvp__multigrid {
	lvp__multigrid_level levels[LVP__MULTIGRID_MAX_LEVELS];
	int32_t level_count;
	double *factor; /* the coarsest level's dense Cholesky factor, or NULL (then it is swept) */
} lvp__multigrid;
/* Builds the levels over the caller's system (kept, not copied: it must outlive the grid). False when
 * memory runs out (nothing kept). */
bool lvp__multigrid_build(lvp__multigrid *grid, int32_t n, const int32_t *offsets, const int32_t *columns,
                          const double *coupling, const double *diagonal);
/* z = one cycle applied to r (a symmetric positive definite approximation of the system's inverse). */
void lvp__multigrid_apply(lvp__multigrid *grid, const double *r, double *z);
void lvp__multigrid_free(lvp__multigrid *grid);

/* Replaces the rows by bone heat's weights (Baran and Popovic 2007; screened_diffusion.c): each bone's weight
 * solves -(1/4) Laplacian(w) + H w = H p, p its share of each vertex's row as filled (the vertex's nearest
 * bones, evenly), H = screening[k]; depths[k], the vertex's distance to its nearest bone, bounds how far a
 * bone's weight can reach past it. Rows keep the `stride` strongest, renormalized; a vertex no weight reaches
 * (a piece of skin with no source) is left with an empty row. The bones are solved on thread_count threads,
 * the same bits on any count. Returns false when memory runs out (the rows then as filled). */
bool lvp__diffusion_screened(lvp__diffusion *rows, const float *positions, const int32_t *triangles,
                             int32_t vertex_count, int32_t triangle_count, const double *screening,
                             const double *depths, int32_t thread_count);

/* Gives the ends of every edge far shorter than the edges around its two ends (a sliver a metaball or a
 * remesher left; diffusion_slivers.c), and of chains of such edges, the mean of their rows. positions: the
 * vertices'. Returns false when memory runs out (the rows are then as they were). */
bool lvp__diffusion_share_slivers(lvp__diffusion *diffusion, const float *positions, int32_t vertex_count);

/* The mean length of the edges (each counted from both ends); 0 when there is none. */
double lvp__mean_edge_length(const lvp__diffusion *diffusion, const float *positions, int32_t vertex_count);

/* Steps that blend a border over about `length`: explicit diffusion spreads one over about
 * sqrt(2 steps) edges (each step moves weight by about an edge, either way), so
 * (length / edge)^2 / 2, not rounded. */
static inline double lvp__blend_steps(double length, double edge)
{
	double ratio = length / edge;
	return 0.5 * ratio * ratio;
}

/* lvp__blend_steps rounded up, at most `most`; 0 without an edge of any length. */
int32_t lvp__diffusion_steps(double length, double edge, int32_t most);

#endif
