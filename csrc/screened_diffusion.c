/*
 * screened_diffusion.c - bone weights as heat weights are made (diffusion.h, lvp__diffusion_screened;
 * lvp.h, HEAT): Baran and Popovic's bone heat (2007), which Blender's With Automatic Weights computes.
 * Each bone's weight w solves, over the surface,
 *
 *     -(1/4) Laplacian(w) + H w = H p,
 *
 * p being 1 at the vertices whose nearest bone (seen from the skin) it is, shared where several are
 * equally near, and H = 1 / d^2 there, d the vertex's distance to that bone: the weight diffuses from the
 * bone's skin into its neighbours' screened by the depth of the skin, so deep skin (a hip, a buttock,
 * the palm's edge) blends over a hand's width and skin close to its bone (a finger) over millimetres,
 * however dense the mesh and whatever else is in it. Since the sources of all bones sum to one, so do
 * the weights, wherever the skin sees a bone.
 *
 * The Laplacian is the cotangent one over Meyer's mixed areas, scaled as Blender scales it (each edge's
 * cotangents over the number of triangles on it; the factor 1/4 above), so the blend is as wide as heat
 * weights'. Multiplied by each vertex's area the system is symmetric and positive definite (the stiffness
 * of linear elements plus the screening), which conjugate gradients solve, preconditioned by aggregation
 * multigrid (screened_multigrid.c). The obtuse angles' negative cotangents count as they are: taken as
 * zero, the voxel-remeshed hands (right angles across every quad's diagonal) blended wider than heat
 * weights and folded through themselves at the fist a quarter more.
 *
 * Where the skin lies closer to its bone than its edges are long (a coarse hand's palm, a finger of a few
 * rings), heat weights screen each vertex so hard that it keeps its own bone's weight whatever its
 * neighbours have, and the weight jumps from one bone to the next across a single edge. The screening is
 * held to at most the vertex's couplings to its neighbours: its own bone then counts at most as much as its
 * neighbours together, and no blend is narrower than the edges can show; on skin many edges deep, where
 * the screening is far below that, nothing changes.
 *
 * A bone's weight falls by e over about half the skin's depth: it is solved only on the skin within
 * reach of its sources (each edge costing its length over half the depth at the shallower of its ends, up
 * to LVP__SCREENED_REACH), with no weight beyond; where the weight at the rim of that patch comes out above
 * LVP__SCREENED_RIM, the patch grows and is solved again. So a bone costs what its skin and its blends
 * cost, not the whole mesh. Each bone is solved on one thread, the same wherever it runs, and the rows are
 * gathered bone after bone: the same bits on any thread count.
 */
#include "diffusion.h"
#include "threads.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* How far a bone's patch reaches from its sources at first: where its weight has fallen by about e^-6
 * (2.5e-3), ten times below heat weights' cut (weights.c). */
#define LVP__SCREENED_REACH 6.0
/* A weight above this at the rim of a bone's patch (where the solve takes it as zero beyond) grows the patch
 * by LVP__SCREENED_GROWTH more of the reach and solves again: the solve on a patch differs from the whole
 * mesh's by about its largest weight on the rim, so the weights kept (LVP__SCREENED_KEPT and up) are the
 * whole mesh's to within about this. */
#define LVP__SCREENED_RIM 2.5e-3
#define LVP__SCREENED_GROWTH 3.0
#define LVP__SCREENED_GROWTHS 8 /* at most, past which the weights beyond the rim are left at zero */
#define LVP__SCREENED_KEPT 1e-4
/* Conjugate gradients stop when no vertex's residual over its diagonal (the change of its weight that would
 * answer it alone) is above this (the weights then within a few 1e-4 of the exact solve's), or after this many
 * iterations (a bound that ordinary meshes never reach). Residuals are compared vertex by vertex, not by their
 * sum of squares: a vertex on its bone has a screening millions of times its neighbours', and would hide their
 * residuals in any norm. */
#define LVP__SCREENED_TOLERANCE 1e-5
#define LVP__SCREENED_MAX_ITERATIONS 4000

/* The symmetric system, rows multiplied by the vertex's area: sum_j c_kj (w_k - w_j) + D_k w_k = D_k p_k. */
typedef struct lvp__screened {
	int32_t n;
	const int32_t *offsets, *neighbours; /* the rows' edge neighbours (CSR) */
	double *coupling;                     /* c_kj per neighbour entry */
	double *diagonal;                     /* sum_j c_kj + D_k */
	double *screen;                       /* D_k */
	double *rate;                         /* per vertex, how fast weight falls off there: 2 / depth */
	double *reach_cost;                   /* per neighbour entry, the reach its edge spends (lvp__grow_patch) */
} lvp__screened;

typedef struct lvp__queued {
	double cost;
	int32_t vertex;
} lvp__queued;

static inline bool lvp__before(lvp__queued a, lvp__queued b)
{
	return a.cost < b.cost || (a.cost == b.cost && a.vertex < b.vertex);
}

/* One bone's solve: its patch (global vertex indices), each vertex's place in it (-1 outside), and the
 * vectors of conjugate gradients over it. */
typedef struct lvp__patch {
	int32_t *vertices, count;
	int32_t *slot;
	double *cost; /* per vertex, the least reach spent to get there (Dijkstra), INFINITY when not reached */
	lvp__queued *heap; /* Dijkstra's queue: a vertex is queued again when a shorter way to it is found */
	int32_t heap_count;
	double *x, *r, *z, *p, *q, *b;
	/* The system over the patch alone, rebuilt when it grows: each vertex's neighbours in it (their places)
	 * and couplings, and its diagonal. */
	int32_t *local_offsets, *local_columns;
	double *local_coupling, *local_diagonal;
} lvp__patch;

/* Where neighbour j sits in vertex k's sorted list, or -1. */
static int32_t lvp__entry_of(const lvp__screened *system, int32_t k, int32_t j)
{
	int32_t lo = system->offsets[k], hi = system->offsets[k + 1] - 1;
	while (lo <= hi) {
		int32_t mid = lo + (hi - lo) / 2, value = system->neighbours[mid];
		if (value == j)
			return mid;
		if (value < j)
			lo = mid + 1;
		else
			hi = mid - 1;
	}
	return -1;
}

/* The couplings (cotangents over the triangles on each edge) and each vertex's mixed area, as Blender's
 * Laplacian takes them (twice Meyer's), into `area`. edge_count: scratch, one per neighbour entry. */
static void lvp__assemble(lvp__screened *system, const float *positions, const int32_t *triangles,
                          int32_t triangle_count, double *area, int32_t *edge_count)
{
	int32_t entries = system->offsets[system->n];
	memset(edge_count, 0, sizeof(int32_t) * (size_t)entries);
	for (int32_t e = 0; e < entries; ++e)
		system->coupling[e] = 0.0;
	for (int32_t k = 0; k < system->n; ++k)
		area[k] = 0.0;
	for (int64_t t = 0; t < triangle_count; ++t) {
		const int32_t *v = triangles + 3 * t;
		if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0])
			continue;
		lvp__vec3 p[3] = {lvp__load(positions + 3 * (int64_t)v[0]), lvp__load(positions + 3 * (int64_t)v[1]),
		                  lvp__load(positions + 3 * (int64_t)v[2])};
		double cotangent[3], length2[3]; /* per corner: its angle's cotangent, the opposite edge's length^2 */
		bool obtuse[3];
		double area2 = lvp__length(lvp__cross(lvp__sub(p[1], p[0]), lvp__sub(p[2], p[0])));
		for (int i = 0; i < 3; ++i) {
			lvp__vec3 a = lvp__sub(p[(i + 1) % 3], p[i]), b = lvp__sub(p[(i + 2) % 3], p[i]);
			double cosine = lvp__dot(a, b);
			obtuse[i] = cosine < 0.0;
			cotangent[i] = area2 > 0.0 ? fmin(fmax(cosine / area2, -1e6), 1e6) : 0.0;
			lvp__vec3 opposite = lvp__sub(p[(i + 2) % 3], p[(i + 1) % 3]);
			length2[i] = lvp__dot(opposite, opposite);
		}
		for (int i = 0; i < 3; ++i) {
			int32_t a = v[(i + 1) % 3], b = v[(i + 2) % 3]; /* the edge opposite corner i */
			int32_t ab = lvp__entry_of(system, a, b), ba = lvp__entry_of(system, b, a);
			system->coupling[ab] += cotangent[i];
			system->coupling[ba] += cotangent[i];
			++edge_count[ab];
			++edge_count[ba];
		}
		bool any_obtuse = obtuse[0] || obtuse[1] || obtuse[2];
		for (int i = 0; i < 3; ++i) {
			if (any_obtuse) {
				area[v[i]] += obtuse[i] ? 0.5 * area2 : 0.25 * area2;
			} else {
				int j = (i + 1) % 3, l = (i + 2) % 3; /* corner j's opposite edge joins i and l, and so on */
				area[v[i]] += 0.25 * (cotangent[j] * length2[j] + cotangent[l] * length2[l]);
			}
		}
	}
	for (int32_t e = 0; e < entries; ++e)
		if (edge_count[e] > 0)
			system->coupling[e] /= (double)edge_count[e];
}

/* The screening of every vertex (D_k = 2 area_k H_k, at most its couplings' sum) and the diagonal. A vertex
 * that no coupling and no area ties to the rest keeps its sources as they are (any positive screening gives
 * that). */
static void lvp__finish_diagonal(lvp__screened *system, const double *area, const double *screening)
{
	for (int32_t k = 0; k < system->n; ++k) {
		double sum = 0.0;
		for (int32_t e = system->offsets[k]; e < system->offsets[k + 1]; ++e)
			sum += system->coupling[e];
		double screen = 2.0 * area[k] * screening[k];
		screen = screen < sum ? screen : sum; /* a blend no narrower than the edges around (the top of this file) */
		if (!(screen > 0.0) && screening[k] > 0.0 && !(sum > 0.0))
			screen = 1.0;
		system->screen[k] = screen;
		system->diagonal[k] = sum + screen;
	}
}

static void lvp__heap_push(lvp__patch *patch, int32_t vertex, double cost)
{
	lvp__queued entry = {cost, vertex};
	int32_t at = patch->heap_count++;
	while (at > 0 && lvp__before(entry, patch->heap[(at - 1) / 2])) {
		patch->heap[at] = patch->heap[(at - 1) / 2];
		at = (at - 1) / 2;
	}
	patch->heap[at] = entry;
}

static lvp__queued lvp__heap_pop(lvp__patch *patch)
{
	lvp__queued top = patch->heap[0], last = patch->heap[--patch->heap_count];
	int32_t at = 0;
	for (;;) {
		int32_t child = 2 * at + 1;
		if (child >= patch->heap_count)
			break;
		if (child + 1 < patch->heap_count && lvp__before(patch->heap[child + 1], patch->heap[child]))
			++child;
		if (!lvp__before(patch->heap[child], last))
			break;
		patch->heap[at] = patch->heap[child];
		at = child;
	}
	patch->heap[at] = last;
	return top;
}

/* Each edge's cost to the reach: its length times the lower rate of its two ends (a vertex on its bone,
 * screened without end, holds its own weight but not its neighbours'). */
static void lvp__reach_costs(lvp__screened *system, const float *positions)
{
	for (int32_t k = 0; k < system->n; ++k) {
		lvp__vec3 at = lvp__load(positions + 3 * (int64_t)k);
		for (int32_t e = system->offsets[k]; e < system->offsets[k + 1]; ++e) {
			int32_t j = system->neighbours[e];
			double rate = system->rate[j] < system->rate[k] ? system->rate[j] : system->rate[k];
			system->reach_cost[e] = lvp__length(lvp__sub(lvp__load(positions + 3 * (int64_t)j), at)) * rate;
		}
	}
}

/* Grows the patch to every vertex within `reach` of the bone's sources (queued at cost 0): Dijkstra over
 * the edges at their reach costs. Vertices new to the patch start with no weight; those in it keep
 * theirs. */
static void lvp__grow_patch(const lvp__screened *system, lvp__patch *patch, double reach)
{
	while (patch->heap_count > 0) {
		lvp__queued top = lvp__heap_pop(patch);
		int32_t k = top.vertex;
		if (top.cost > patch->cost[k])
			continue; /* a longer way queued before the shorter one was found */
		if (patch->slot[k] < 0) {
			patch->slot[k] = patch->count;
			patch->x[patch->count] = 0.0;
			patch->vertices[patch->count++] = k;
		}
		for (int32_t e = system->offsets[k]; e < system->offsets[k + 1]; ++e) {
			int32_t j = system->neighbours[e];
			double cost = top.cost + system->reach_cost[e];
			if (cost <= reach && cost < patch->cost[j]) {
				patch->cost[j] = cost;
				lvp__heap_push(patch, j, cost);
			}
		}
	}
}

/* The patch's own system (lvp__patch), from the whole mesh's. */
static void lvp__localize(const lvp__screened *system, lvp__patch *patch)
{
	int32_t written = 0;
	for (int32_t i = 0; i < patch->count; ++i) {
		int32_t k = patch->vertices[i];
		patch->local_offsets[i] = written;
		patch->local_diagonal[i] = system->diagonal[k];
		for (int32_t e = system->offsets[k]; e < system->offsets[k + 1]; ++e) {
			int32_t s = patch->slot[system->neighbours[e]];
			if (s >= 0) {
				patch->local_columns[written] = s;
				patch->local_coupling[written++] = system->coupling[e];
			}
		}
	}
	patch->local_offsets[patch->count] = written;
}

/* q = A v over the patch (zero outside it). */
static void lvp__apply(const lvp__patch *patch, const double *v, double *q)
{
	for (int32_t i = 0; i < patch->count; ++i) {
		double sum = patch->local_diagonal[i] * v[i];
		for (int32_t e = patch->local_offsets[i]; e < patch->local_offsets[i + 1]; ++e)
			sum -= patch->local_coupling[e] * v[patch->local_columns[e]];
		q[i] = sum;
	}
}

static double lvp__dot_n(const double *a, const double *b, int32_t count)
{
	double sum = 0.0;
	for (int32_t i = 0; i < count; ++i)
		sum += a[i] * b[i];
	return sum;
}

/* The largest residual over its diagonal: the change of weight that would answer a vertex's residual alone. */
static double lvp__largest_change(const lvp__patch *patch, const double *r)
{
	double largest = 0.0;
	for (int32_t i = 0; i < patch->count; ++i) {
		double change = fabs(r[i] / patch->local_diagonal[i]);
		largest = change > largest ? change : largest;
	}
	return largest;
}

/* Conjugate gradients from the patch's x against its b, preconditioned by a cycle of multigrid over the
 * patch (screened_multigrid.c). False when memory runs out. */
static bool lvp__solve_patch(lvp__patch *patch)
{
	int32_t count = patch->count;
	double *x = patch->x, *r = patch->r, *z = patch->z, *p = patch->p, *q = patch->q, *b = patch->b;
	lvp__multigrid grid;
	if (!lvp__multigrid_build(&grid, count, patch->local_offsets, patch->local_columns, patch->local_coupling,
	                          patch->local_diagonal))
		return false;
	lvp__apply(patch, x, q);
	for (int32_t i = 0; i < count; ++i)
		r[i] = b[i] - q[i];
	lvp__multigrid_apply(&grid, r, z);
	memcpy(p, z, sizeof(double) * (size_t)count);
	double rz = lvp__dot_n(r, z, count);
	for (int iteration = 0; iteration < LVP__SCREENED_MAX_ITERATIONS; ++iteration) {
		if (!(lvp__largest_change(patch, r) > LVP__SCREENED_TOLERANCE))
			break;
		lvp__apply(patch, p, q);
		double pq = lvp__dot_n(p, q, count);
		if (!(pq > 0.0))
			break;
		double alpha = rz / pq;
		for (int32_t i = 0; i < count; ++i) {
			x[i] += alpha * p[i];
			r[i] -= alpha * q[i];
		}
		lvp__multigrid_apply(&grid, r, z);
		double next = lvp__dot_n(r, z, count), beta = next / rz;
		rz = next;
		for (int32_t i = 0; i < count; ++i)
			p[i] = z[i] + beta * p[i];
	}
	lvp__multigrid_free(&grid);
	return true;
}

/* Whether a vertex on the patch's rim (a neighbour outside it) has a weight above LVP__SCREENED_RIM: the
 * zero the solve assumed beyond it was too early. */
static bool lvp__rim_too_high(const lvp__screened *system, const lvp__patch *patch)
{
	for (int32_t i = 0; i < patch->count; ++i) {
		int32_t k = patch->vertices[i];
		if (!(patch->x[i] > LVP__SCREENED_RIM))
			continue;
		for (int32_t e = system->offsets[k]; e < system->offsets[k + 1]; ++e)
			if (patch->slot[system->neighbours[e]] < 0)
				return true;
	}
	return false;
}

/* Leaves the patch empty for the next bone. */
static void lvp__clear_patch(lvp__patch *patch)
{
	for (int32_t i = 0; i < patch->count; ++i) {
		patch->slot[patch->vertices[i]] = -1;
		patch->cost[patch->vertices[i]] = INFINITY;
	}
	patch->count = 0;
}

/* The weights of one bone, its sources `sources` (count of them): into `out` as (vertex, weight) pairs
 * above LVP__SCREENED_KEPT, returning how many (the patch's size at most), or -1 when memory runs out. */
static int32_t lvp__solve_bone(const lvp__screened *system, lvp__patch *patch,
                               const int32_t *sources, const float *shares, int32_t count, int32_t *out_vertices,
                               float *out_values)
{
	patch->count = 0;
	for (int growth = 0;; ++growth) {
		double reach = LVP__SCREENED_REACH + LVP__SCREENED_GROWTH * growth;
		for (int32_t i = 0; i < patch->count; ++i)
			patch->cost[patch->vertices[i]] = INFINITY;
		patch->heap_count = 0;
		for (int32_t s = 0; s < count; ++s) {
			patch->cost[sources[s]] = 0.0;
			lvp__heap_push(patch, sources[s], 0.0);
		}
		lvp__grow_patch(system, patch, reach);
		for (int32_t i = 0; i < patch->count; ++i)
			patch->b[i] = 0.0;
		for (int32_t s = 0; s < count; ++s) {
			int32_t at = patch->slot[sources[s]];
			patch->b[at] = system->screen[sources[s]] * (double)shares[s];
			/* Conjugate gradients start from the sources' shares: away from the borders between bones that is
			 * the answer already, and what is left to solve lies along those borders. */
			if (growth == 0)
				patch->x[at] = (double)shares[s];
		}
		lvp__localize(system, patch);
		if (!lvp__solve_patch(patch)) {
			lvp__clear_patch(patch);
			return -1;
		}
		if (growth == LVP__SCREENED_GROWTHS || patch->count == system->n || !lvp__rim_too_high(system, patch))
			break;
	}
	int32_t kept = 0;
	for (int32_t i = 0; i < patch->count; ++i) {
		if (patch->x[i] > LVP__SCREENED_KEPT) {
			out_vertices[kept] = patch->vertices[i];
			out_values[kept++] = (float)patch->x[i];
		}
	}
	lvp__clear_patch(patch);
	return kept;
}

/* A worker's scratch (one bone's patch at a time) and what its bones gave, in the order it solved them. */
typedef struct lvp__screened_worker {
	lvp__patch patch;
	int32_t *solved_vertices; /* each bone's weights: (vertex, weight) pairs, bone after bone */
	float *solved_values;
	int64_t solved, capacity;
	void *memory;
} lvp__screened_worker;

/* Where bone i's weights lie: in worker `worker`'s pairs from `first`, `count` of them. */
typedef struct lvp__bone_weights {
	int32_t worker, count;
	int64_t first;
} lvp__bone_weights;

typedef struct lvp__screened_work {
	const lvp__screened *system;
	const int32_t *source_offsets, *source_vertices; /* each bone's sources, and their shares */
	const float *source_shares;
	int32_t bone_count;
	atomic_int next_bone, next_worker;
	atomic_bool failed;
	lvp__bone_weights *weights; /* per bone */
	lvp__screened_worker workers[LVP_MAX_THREADS];
} lvp__screened_work;

static bool lvp__worker_alloc(lvp__screened_worker *worker, int32_t n, int32_t entries)
{
	size_t doubles = 8 * (size_t)n + (size_t)entries, queued = (size_t)entries + (size_t)n + 1;
	size_t ints = 3 * (size_t)n + 1 + (size_t)entries;
	unsigned char *memory =
	    malloc(sizeof(double) * doubles + sizeof(lvp__queued) * queued + sizeof(int32_t) * ints);
	if (!memory)
		return false;
	lvp__patch *patch = &worker->patch;
	worker->memory = memory;
	double *d = (double *)memory;
	patch->cost = d, patch->x = d + n, patch->r = d + 2 * (size_t)n, patch->z = d + 3 * (size_t)n;
	patch->p = d + 4 * (size_t)n, patch->q = d + 5 * (size_t)n, patch->b = d + 6 * (size_t)n;
	patch->local_diagonal = d + 7 * (size_t)n;
	patch->local_coupling = d + 8 * (size_t)n;
	patch->heap = (lvp__queued *)(d + doubles);
	int32_t *i = (int32_t *)(patch->heap + queued);
	patch->vertices = i, patch->slot = i + n, patch->local_offsets = i + 2 * (size_t)n;
	patch->local_columns = i + 3 * (size_t)n + 1;
	for (int32_t k = 0; k < n; ++k) {
		patch->slot[k] = -1;
		patch->cost[k] = INFINITY;
	}
	patch->count = 0;
	return true;
}

static void lvp__worker_free(lvp__screened_worker *worker)
{
	free(worker->memory);
	free(worker->solved_vertices);
	free(worker->solved_values);
	memset(worker, 0, sizeof(*worker));
}

/* Room in the worker's pairs for `more`; false when memory runs out. */
static bool lvp__reserve(lvp__screened_worker *worker, int64_t more)
{
	if (worker->solved + more <= worker->capacity)
		return true;
	int64_t capacity = 2 * worker->capacity > worker->solved + more ? 2 * worker->capacity : worker->solved + more;
	int32_t *vertices = realloc(worker->solved_vertices, sizeof(int32_t) * (size_t)capacity);
	if (vertices)
		worker->solved_vertices = vertices;
	float *values = realloc(worker->solved_values, sizeof(float) * (size_t)capacity);
	if (values)
		worker->solved_values = values;
	if (!vertices || !values)
		return false;
	worker->capacity = capacity;
	return true;
}

/* One worker: its scratch, then bones taken one at a time until none is left (any thread may solve any
 * bone: each bone's solve is the same wherever it runs). */
static void lvp__screened_task(void *context, int32_t begin, int32_t end)
{
	lvp__screened_work *work = context;
	const lvp__screened *system = work->system;
	for (int32_t item = begin; item < end; ++item) {
		int32_t index = atomic_fetch_add(&work->next_worker, 1);
		lvp__screened_worker *worker = &work->workers[index];
		if (!lvp__worker_alloc(worker, system->n, system->offsets[system->n])) {
			atomic_store(&work->failed, true);
			continue;
		}
		for (;;) {
			int32_t bone = atomic_fetch_add(&work->next_bone, 1);
			if (bone >= work->bone_count || atomic_load(&work->failed))
				break;
			int32_t first = work->source_offsets[bone], count = work->source_offsets[bone + 1] - first;
			if (count == 0)
				continue;
			if (!lvp__reserve(worker, system->n)) {
				atomic_store(&work->failed, true);
				break;
			}
			int32_t kept = lvp__solve_bone(system, &worker->patch, work->source_vertices + first,
			                               work->source_shares + first, count,
			                               worker->solved_vertices + worker->solved,
			                               worker->solved_values + worker->solved);
			if (kept < 0) {
				atomic_store(&work->failed, true);
				break;
			}
			work->weights[bone] = (lvp__bone_weights){index, kept, worker->solved};
			worker->solved += kept;
		}
		free(worker->memory); /* the scratch; the pairs stay until the rows are made */
		worker->memory = NULL;
		memset(&worker->patch, 0, sizeof(worker->patch));
	}
}

/* Inserts bone's weight w at vertex k into its row, kept sorted by decreasing weight (ties: the lower bone,
 * inserted first) and `stride` long. */
static void lvp__insert_weight(lvp__diffusion *rows, int32_t k, int32_t bone, float w)
{
	int32_t stride = rows->stride, length = rows->counts[k];
	int64_t at = (int64_t)k * stride;
	if (length == stride && !(w > rows->values[at + length - 1]))
		return;
	int32_t place = length < stride ? length++ : length - 1;
	while (place > 0 && rows->values[at + place - 1] < w) {
		rows->values[at + place] = rows->values[at + place - 1];
		rows->bones[at + place] = rows->bones[at + place - 1];
		--place;
	}
	rows->values[at + place] = w;
	rows->bones[at + place] = bone;
	rows->counts[k] = length;
}

bool lvp__diffusion_screened(lvp__diffusion *rows, const float *positions, const int32_t *triangles,
                             int32_t vertex_count, int32_t triangle_count, const double *screening,
                             const double *depths, int32_t thread_count)
{
	int32_t n = vertex_count, bones = rows->bone_count, stride = rows->stride;
	int32_t entries = rows->neighbour_offsets[n];
	size_t sources = (size_t)n * (size_t)stride + 1; /* a row's bones are its vertex's sources */
	double *doubles = malloc(sizeof(double) * (2 * (size_t)entries + 4 * (size_t)n + 1));
	int32_t *ints = malloc(sizeof(int32_t) * ((size_t)entries + 2 * (size_t)bones + 2 + sources));
	float *source_shares = malloc(sizeof(float) * sources);
	lvp__screened_work *work = calloc(1, sizeof(lvp__screened_work));
	lvp__bone_weights *weights = calloc((size_t)bones + 1, sizeof(lvp__bone_weights));
	lvp__pool *pool = NULL;
	bool ok = doubles && ints && source_shares && work && weights &&
	          lvp__pool_create(&pool, thread_count) == lvp_success;
	if (!ok) {
		free(doubles);
		free(ints);
		free(source_shares);
		free(work);
		free(weights);
		return false;
	}
	lvp__screened system = {.n = n, .offsets = rows->neighbour_offsets, .neighbours = rows->neighbours};
	system.coupling = doubles;
	system.diagonal = doubles + entries;
	system.screen = system.diagonal + n;
	system.rate = system.screen + n;
	double *area = system.rate + n;
	system.reach_cost = area + n;
	int32_t *edge_count = ints; /* entries */
	int32_t *source_offsets = edge_count + entries; /* bones + 1 */
	int32_t *cursor = source_offsets + bones + 1;
	int32_t *source_vertices = cursor + bones;

	lvp__assemble(&system, positions, triangles, triangle_count, area, edge_count);
	lvp__finish_diagonal(&system, area, screening);
	for (int32_t k = 0; k < n; ++k)
		system.rate[k] = depths[k] > 0.0 ? 2.0 / depths[k] : INFINITY;
	lvp__reach_costs(&system, positions);
	/* Each bone's sources: the vertices whose rows name it, with their shares. */
	memset(source_offsets, 0, sizeof(int32_t) * ((size_t)bones + 1));
	for (int32_t k = 0; k < n; ++k)
		for (int32_t j = 0; j < rows->counts[k]; ++j)
			++source_offsets[rows->bones[(int64_t)k * stride + j] + 1];
	for (int32_t i = 0; i < bones; ++i)
		source_offsets[i + 1] += source_offsets[i];
	memcpy(cursor, source_offsets, sizeof(int32_t) * (size_t)bones);
	for (int32_t k = 0; k < n; ++k)
		for (int32_t j = 0; j < rows->counts[k]; ++j) {
			int32_t bone = rows->bones[(int64_t)k * stride + j], at = cursor[bone]++;
			source_vertices[at] = k;
			source_shares[at] = rows->values[(int64_t)k * stride + j];
		}
	/* The solves, on the pool's threads, each bone wherever; then the rows, bone after bone (the rows are free:
	 * the sources were copied out). */
	work->system = &system;
	work->source_offsets = source_offsets;
	work->source_vertices = source_vertices;
	work->source_shares = source_shares;
	work->bone_count = bones;
	work->weights = weights;
	atomic_init(&work->next_bone, 0);
	atomic_init(&work->next_worker, 0);
	atomic_init(&work->failed, false);
	int32_t workers = thread_count < 1 ? 1 : thread_count;
	lvp__parallel_for(pool, lvp__screened_task, work, workers, 1);
	ok = !atomic_load(&work->failed);
	for (int32_t k = 0; ok && k < n; ++k)
		rows->counts[k] = 0;
	for (int32_t bone = 0; ok && bone < bones; ++bone) {
		const lvp__screened_worker *worker = &work->workers[weights[bone].worker];
		for (int32_t i = 0; i < weights[bone].count; ++i)
			lvp__insert_weight(rows, worker->solved_vertices[weights[bone].first + i], bone,
			                   worker->solved_values[weights[bone].first + i]);
	}
	for (int32_t k = 0; ok && k < n; ++k) {
		int64_t at = (int64_t)k * stride;
		double sum = 0.0;
		for (int32_t j = 0; j < rows->counts[k]; ++j)
			sum += rows->values[at + j];
		for (int32_t j = 0; j < rows->counts[k]; ++j)
			rows->values[at + j] = (float)(rows->values[at + j] / sum);
	}
	for (int32_t w = 0; w < workers; ++w)
		lvp__worker_free(&work->workers[w]);
	lvp__pool_destroy(pool);
	free(doubles);
	free(ints);
	free(source_shares);
	free(work);
	free(weights);
	return ok;
}
