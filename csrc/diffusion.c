/*
 * diffusion.c - rows of bone weights diffused over a mesh's edges (diffusion.h): explicit steps of
 * the mean of a row and its edge neighbours' rows, kept to the strongest few bones. Weight flows
 * only along edges: separate pieces, and parts that touch or cross without sharing vertices, never
 * share weight. Most of a skin is one bone's alone, and so are its neighbours: those rows are
 * copied, so a step costs what the blends cost.
 */
#include "diffusion.h"
#include "threads.h"

#include <stdlib.h>
#include <string.h>

static int lvp__compare_int32(const void *a, const void *b)
{
	int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
	return (x > y) - (x < y);
}

void lvp__compact_neighbour_lists(int32_t *offsets, int32_t *list, int32_t count)
{
	int32_t written = 0;
	for (int32_t k = 0; k < count; ++k) {
		int32_t begin = offsets[k], end = offsets[k + 1]; /* offsets[k + 1] is not rewritten yet */
		qsort(list + begin, (size_t)(end - begin), sizeof(int32_t), lvp__compare_int32);
		offsets[k] = written;
		for (int32_t j = begin; j < end; ++j)
			if (list[j] != k && (written == offsets[k] || list[written - 1] != list[j]))
				list[written++] = list[j];
	}
	offsets[count] = written;
}

/* The edge neighbours of every vertex, each listed once (degenerate triangles' repeated corners left out). */
static bool lvp__build_neighbours(lvp__diffusion *diffusion, const int32_t *triangles, int32_t vertex_count,
                                  int32_t triangle_count)
{
	int32_t *offsets = diffusion->neighbour_offsets;
	memset(offsets, 0, sizeof(int32_t) * ((size_t)vertex_count + 1));
	for (int64_t t = 0; t < triangle_count; ++t)
		for (int c = 0; c < 3; ++c)
			offsets[triangles[3 * t + c] + 1] += 2;
	for (int32_t k = 0; k < vertex_count; ++k)
		offsets[k + 1] += offsets[k];
	int32_t *list = malloc(sizeof(int32_t) * ((size_t)offsets[vertex_count] + 1));
	if (!list)
		return false;
	int32_t *cursor = diffusion->next_counts; /* free until the first step */
	memcpy(cursor, offsets, sizeof(int32_t) * (size_t)vertex_count);
	for (int64_t t = 0; t < triangle_count; ++t) {
		const int32_t *corner = triangles + 3 * t;
		for (int c = 0; c < 3; ++c) {
			int32_t a = corner[c], b = corner[(c + 1) % 3], o = corner[(c + 2) % 3];
			list[cursor[a]++] = b;
			list[cursor[a]++] = o;
		}
	}
	lvp__compact_neighbour_lists(offsets, list, vertex_count);
	diffusion->neighbours = list;
	return true;
}

bool lvp__diffusion_alloc(lvp__diffusion *diffusion, int32_t vertex_count, int32_t bone_count, int32_t stride)
{
	memset(diffusion, 0, sizeof(*diffusion));
	int64_t chunks = LVP__DIFFUSION_CHUNKS;
	diffusion->grain = (int32_t)(((int64_t)vertex_count + chunks - 1) / chunks);
	diffusion->grain = diffusion->grain > 4096 ? diffusion->grain : 4096;
	diffusion->bone_count = bone_count;
	size_t n = (size_t)vertex_count, cells = n * (size_t)stride, scratch = (size_t)chunks * (size_t)bone_count;
	size_t bytes = sizeof(double) * scratch + sizeof(int32_t) * (scratch + 3 * n + 1) +
	               2 * (sizeof(int32_t) + sizeof(float)) * cells;
	unsigned char *memory = calloc(1, bytes);
	if (!memory)
		return false;
	diffusion->memory = memory;
	diffusion->stride = stride;
	diffusion->accum = (double *)memory;
	diffusion->touched = (int32_t *)(diffusion->accum + scratch);
	diffusion->counts = diffusion->touched + scratch;
	diffusion->next_counts = diffusion->counts + n;
	diffusion->neighbour_offsets = diffusion->next_counts + n;
	diffusion->bones = diffusion->neighbour_offsets + n + 1;
	diffusion->next_bones = diffusion->bones + cells;
	diffusion->values = (float *)(diffusion->next_bones + cells);
	diffusion->next_values = diffusion->values + cells;
	return true;
}

bool lvp__diffusion_init(lvp__diffusion *diffusion, const int32_t *triangles, int32_t vertex_count,
                         int32_t triangle_count, int32_t bone_count, int32_t stride)
{
	return lvp__diffusion_alloc(diffusion, vertex_count, bone_count, stride) &&
	       lvp__build_neighbours(diffusion, triangles, vertex_count, triangle_count);
}

void lvp__diffusion_free(lvp__diffusion *diffusion)
{
	free(diffusion->memory);
	free(diffusion->neighbours);
	diffusion->memory = NULL;
	diffusion->neighbours = NULL;
}

/* Inserts (bone, w) into the row of at most `room` entries sorted by decreasing weight, ties to the lower
 * bone; returns the new length. */
static int32_t lvp__insert_sorted(int32_t *bones, double *weights, int32_t length, int32_t room, int32_t bone,
                                  double w)
{
	if (length == room &&
	    !(w > weights[length - 1] || (w == weights[length - 1] && bone < bones[length - 1])))
		return length;
	int32_t at = length < room ? length++ : length - 1;
	while (at > 0 && (weights[at - 1] < w || (weights[at - 1] == w && bones[at - 1] > bone))) {
		bones[at] = bones[at - 1];
		weights[at] = weights[at - 1];
		--at;
	}
	bones[at] = bone;
	weights[at] = w;
	return length;
}

int32_t lvp__diffusion_finish_row(int32_t *r_bones, float *r_values, int32_t stride, double *accum,
                                  const int32_t *touched, int32_t touched_count)
{
	double row_weights[LVP__DIFFUSION_MAX_ROW], sum = 0.0;
	int32_t length = 0;
	for (int32_t i = 0; i < touched_count; ++i) {
		int32_t bone = touched[i];
		if (accum[bone] > 0.0)
			length = lvp__insert_sorted(r_bones, row_weights, length, stride, bone, accum[bone]);
		accum[bone] = 0.0;
	}
	for (int32_t j = 0; j < length; ++j)
		sum += row_weights[j];
	for (int32_t j = 0; j < length; ++j)
		r_values[j] = (float)(row_weights[j] / sum);
	return length;
}

/* Whether vertex k's row is one bone, and so is every neighbour's, the same one. */
static bool lvp__alone(const lvp__diffusion *diffusion, int32_t k)
{
	int32_t stride = diffusion->stride, bone = diffusion->bones[(int64_t)k * stride];
	if (diffusion->counts[k] != 1)
		return false;
	for (int32_t e = diffusion->neighbour_offsets[k]; e < diffusion->neighbour_offsets[k + 1]; ++e) {
		int32_t u = diffusion->neighbours[e];
		if (diffusion->counts[u] != 1 || diffusion->bones[(int64_t)u * stride] != bone)
			return false;
	}
	return true;
}

/* The next row of vertex k (diffusion.h, lvp__diffusion_step), summed in `accum` (bone_count, zero
 * before and after) with the bones met listed in `touched`, in the order first met. */
static void lvp__diffuse_vertex(lvp__diffusion *diffusion, int32_t k, double rate, double *accum, int32_t *touched)
{
	int32_t stride = diffusion->stride;
	int64_t at = (int64_t)k * stride;
	int32_t own_count = diffusion->counts[k], touched_count = 0;
	if (!(rate > 0.0) || lvp__alone(diffusion, k)) {
		memcpy(diffusion->next_bones + at, diffusion->bones + at, sizeof(int32_t) * (size_t)own_count);
		memcpy(diffusion->next_values + at, diffusion->values + at, sizeof(float) * (size_t)own_count);
		diffusion->next_counts[k] = own_count;
		return;
	}
	int32_t begin = diffusion->neighbour_offsets[k], end = diffusion->neighbour_offsets[k + 1];
	double share = rate / (double)(end - begin + 1), self = 1.0 - rate + share;
	touched_count = lvp__diffusion_add_row(accum, touched, touched_count, diffusion, k, self);
	for (int32_t e = begin; e < end; ++e)
		touched_count = lvp__diffusion_add_row(accum, touched, touched_count, diffusion, diffusion->neighbours[e], share);
	diffusion->next_counts[k] =
	    lvp__diffusion_finish_row(diffusion->next_bones + at, diffusion->next_values + at, stride, accum, touched,
	                              touched_count);
}

void lvp__copy_rows(int32_t *counts, int32_t *bones, float *values, const int32_t *from_counts,
                    const int32_t *from_bones, const float *from_values, int32_t vertex_count, int32_t stride)
{
	size_t n = (size_t)vertex_count, entries = n * (size_t)stride;
	memcpy(counts, from_counts, sizeof(int32_t) * n);
	memcpy(bones, from_bones, sizeof(int32_t) * entries);
	memcpy(values, from_values, sizeof(float) * entries);
}

/* The next rows become the rows. */
static void lvp__swap_rows(lvp__diffusion *diffusion)
{
	int32_t *swap_ints = diffusion->counts;
	diffusion->counts = diffusion->next_counts, diffusion->next_counts = swap_ints;
	swap_ints = diffusion->bones;
	diffusion->bones = diffusion->next_bones, diffusion->next_bones = swap_ints;
	float *swap_floats = diffusion->values;
	diffusion->values = diffusion->next_values, diffusion->next_values = swap_floats;
}

typedef struct lvp__diffusion_loop {
	lvp__diffusion *diffusion;
	const float *rates;
} lvp__diffusion_loop;

/* A chunk of vertices, with the chunk's own scratch: chunks run on any thread, each on its own. */
static void lvp__diffusion_task(void *context, int32_t begin, int32_t end)
{
	const lvp__diffusion_loop *loop = context;
	lvp__diffusion *diffusion = loop->diffusion;
	int64_t chunk = begin / diffusion->grain;
	double *accum = diffusion->accum + chunk * diffusion->bone_count;
	int32_t *touched = diffusion->touched + chunk * diffusion->bone_count;
	for (int32_t k = begin; k < end; ++k)
		lvp__diffuse_vertex(diffusion, k, loop->rates ? (double)loop->rates[k] : 1.0, accum, touched);
}

void lvp__diffusion_step(lvp__diffusion *diffusion, int32_t vertex_count, const float *rates, lvp__pool *pool)
{
	lvp__diffusion_loop loop = {diffusion, rates};
	lvp__parallel_for(pool, lvp__diffusion_task, &loop, vertex_count, diffusion->grain);
	lvp__swap_rows(diffusion);
}

/* Lists in r_list the vertices marked in `wanted` and every vertex within `reach` edges of one (breadth
 * first; r_ring is scratch); returns how many. */
static int32_t lvp__list_near(int32_t *r_list, int32_t *r_ring, const lvp__diffusion *diffusion, const uint8_t *wanted,
                              int32_t vertex_count, int64_t reach)
{
	int32_t count = 0;
	for (int32_t k = 0; k < vertex_count; ++k) {
		r_ring[k] = wanted[k] ? 0 : -1;
		if (wanted[k])
			r_list[count++] = k;
	}
	for (int32_t i = 0; i < count; ++i) {
		int32_t k = r_list[i];
		if (r_ring[k] >= reach)
			continue;
		for (int32_t e = diffusion->neighbour_offsets[k]; e < diffusion->neighbour_offsets[k + 1]; ++e) {
			int32_t u = diffusion->neighbours[e];
			if (r_ring[u] < 0) {
				r_ring[u] = r_ring[k] + 1;
				r_list[count++] = u;
			}
		}
	}
	return count;
}

bool lvp__diffusion_steps_near(lvp__diffusion *diffusion, int32_t vertex_count, int64_t steps, const uint8_t *wanted,
                               lvp__pool *pool)
{
	if (!wanted) {
		for (int64_t step = 0; step < steps; ++step)
			lvp__diffusion_step(diffusion, vertex_count, NULL, pool);
		return true;
	}
	int32_t *list = malloc(sizeof(int32_t) * ((size_t)vertex_count + 1));
	int32_t *ring = malloc(sizeof(int32_t) * ((size_t)vertex_count + 1));
	if (!list || !ring) {
		free(list);
		free(ring);
		return false;
	}
	int32_t count = lvp__list_near(list, ring, diffusion, wanted, vertex_count, steps);
	/* The vertices left out keep their rows: both buffers hold them, whichever a step reads. */
	lvp__copy_rows(diffusion->next_counts, diffusion->next_bones, diffusion->next_values, diffusion->counts,
	               diffusion->bones, diffusion->values, vertex_count, diffusion->stride);
	for (int64_t step = 0; step < steps; ++step) {
		for (int32_t i = 0; i < count; ++i)
			lvp__diffuse_vertex(diffusion, list[i], 1.0, diffusion->accum, diffusion->touched);
		lvp__swap_rows(diffusion);
	}
	free(list);
	free(ring);
	return true;
}

double lvp__mean_edge_length(const lvp__diffusion *diffusion, const float *positions, int32_t vertex_count)
{
	double sum = 0.0;
	int64_t count = 0;
	for (int32_t k = 0; k < vertex_count; ++k) {
		lvp__vec3 p = lvp__load(positions + 3 * (int64_t)k);
		for (int32_t e = diffusion->neighbour_offsets[k]; e < diffusion->neighbour_offsets[k + 1]; ++e) {
			lvp__vec3 d = lvp__sub(lvp__load(positions + 3 * (int64_t)diffusion->neighbours[e]), p);
			sum += sqrt(lvp__dot(d, d));
			++count;
		}
	}
	return count > 0 ? sum / (double)count : 0.0;
}

int32_t lvp__diffusion_steps(double length, double edge, int32_t most)
{
	if (!(edge > 0.0) || !(length > 0.0))
		return 0; /* no edge of any length: nothing to diffuse over */
	double steps = ceil(lvp__blend_steps(length, edge));
	return steps < (double)most ? (int32_t)steps : most;
}
