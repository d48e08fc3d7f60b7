/*
 * frame_map.c - this frame's correction map: the bind map gamma_k times the deformation
 * weighting a_k of lvp.h (how far apart the vertex's bones would carry it), and which vertices
 * are dynamic (binding.h): those whose bones do not all move alike, or that the map lets move.
 * Bones that move alike this frame share a skin class; a vertex whose bones are all in one class
 * moves rigidly, and with the deformation weighting its map is zero (without it, the bind map
 * still lets it move, and it is dynamic). In an animation the classes rarely change, and then
 * only the dynamic vertices' map is recomputed.
 */
#include "binding.h"

#include <stdlib.h>
#include <string.h>

/* Bones whose skin matrices agree (to 1e-6 of their size) this frame share a class: the
 * vertices they alone move, move rigidly. Quadratic in the bones, so only for rigs of up to
 * LVP__CLASS_BONES bones; beyond, every bone is its own class (correct, only slower). */
#define LVP__CLASS_BONES 512
static void lvp__skin_classes(lvp_binding *binding)
{
	int32_t b = binding->caller_bone_count;
	for (int32_t i = 0; i < b; ++i) {
		int32_t skin_class = i;
		const double *m = binding->rig.skin[i].m;
		double scale = 1.0;
		for (int c = 0; c < 12; ++c)
			scale = fmax(scale, fabs(m[c]));
		for (int32_t j = 0; j < i && b <= LVP__CLASS_BONES; ++j) {
			if (binding->frame_map.skin_class[j] != j)
				continue;
			const double *other = binding->rig.skin[j].m;
			bool same = true;
			for (int c = 0; c < 12 && same; ++c)
				same = fabs(m[c] - other[c]) <= 1e-6 * scale;
			if (same) {
				skin_class = j;
				break;
			}
		}
		if (binding->frame_map.skin_class[i] != skin_class) {
			binding->frame_map.current = false;
			lvp__dynamic_set_stale(binding);
		}
		binding->frame_map.skin_class[i] = skin_class;
	}
	/* A copy of a caller's bone for a separate part (binding.h) is in its bone's class. */
	for (int32_t i = b; i < binding->bone_count; ++i)
		binding->frame_map.skin_class[i] = binding->frame_map.skin_class[lvp__caller_bone(binding, i)];
	bool alone = true;
	for (int32_t i = 0; i < binding->bone_count && alone; ++i)
		alone = binding->frame_map.skin_class[i] == i;
	binding->frame_map.classes_alone = alone;
}

/* The skin class that all bones of vertex k (with weight) share, or -1. */
static int32_t lvp__vertex_class(const lvp_binding *binding, int32_t k)
{
	int32_t shared = -1;
	for (int32_t e = binding->rig.weight_offsets[k]; e < binding->rig.weight_offsets[k + 1]; ++e) {
		if (!(binding->rig.weight_values[e] > 0.0f))
			continue;
		int32_t c = binding->frame_map.skin_class[binding->rig.weight_bones[e]];
		if (shared >= 0 && c != shared)
			return -1;
		shared = c;
	}
	return shared;
}

/* Displacement (S_b - I) p of rest point p by bone b's skin matrix, in float (skin_displacement):
 * small where bones nearly agree, so rounding does not swamp their difference. */
static inline void lvp__displacement(float r_d[3], const lvp_binding *binding, int32_t bone, const float *p)
{
	const float *m = binding->frame_map.skin_displacement + 12 * bone;
	r_d[0] = m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3];
	r_d[1] = m[4] * p[0] + m[5] * p[1] + m[6] * p[2] + m[7];
	r_d[2] = m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11];
}

/* Vertex k's bind map as the frame map starts from it: gamma_k times its area weight (map.c,
 * lvp__area_weights). Zero where no frame can move the vertex. */
static inline float lvp__bind_gamma(const lvp_binding *binding, int32_t k)
{
	return binding->map.gamma[k] * binding->map.area_weight[k];
}

/* a_k of lvp.h for rest point p moved by `count` bones with the given weights: how far apart
 * they would carry it (the weighted mean distance of each bone's image from their blend). */
#define LVP__SPREAD_KEPT 16
static float lvp__spread(const lvp_binding *binding, const float *p, const int32_t *bones, const float *weights,
                         int32_t count)
{
	float kept[LVP__SPREAD_KEPT][3]; /* the first bones' displacements, for the second loop */
	float blend[3] = {0.0f, 0.0f, 0.0f};
	for (int32_t e = 0; e < count; ++e) {
		if (!(weights[e] > 0.0f))
			continue; /* a bone of no weight moves the point by nothing here */
		float d[3];
		lvp__displacement(d, binding, bones[e], p);
		if (e < LVP__SPREAD_KEPT)
			memcpy(kept[e], d, sizeof(d));
		for (int c = 0; c < 3; ++c)
			blend[c] += weights[e] * d[c];
	}
	float spread = 0.0f;
	for (int32_t e = 0; e < count; ++e) {
		if (!(weights[e] > 0.0f))
			continue;
		float d[3];
		if (e < LVP__SPREAD_KEPT)
			memcpy(d, kept[e], sizeof(d));
		else
			lvp__displacement(d, binding, bones[e], p);
		float dx = d[0] - blend[0], dy = d[1] - blend[1], dz = d[2] - blend[2];
		spread += weights[e] * sqrtf(dx * dx + dy * dy + dz * dz);
	}
	/* Bones that agree up to float rounding of their matrices move the vertex rigidly. The rounding
	 * is relative to the point and to the skin's translations (of the order of the bones' distance
	 * from the origin); not to the whole mesh's size, which one stray vertex far away would make
	 * so large that every vertex looked rigid and nothing was corrected. */
	float noise = (float)(1e-6 * binding->rig.reach) + 1e-6f * sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
	return spread < noise ? 0.0f : spread;
}

/* The skin classes of the bones that reach vertex k (reach.c: its weights' bones without a bulge
 * width), each with the sum of their phi:
 * bones of one class move it alike, so a_k needs one displacement per class. Returns the
 * number of classes, or -1 when there are more than LVP__SPREAD_KEPT (then taken bone by
 * bone). */
static int32_t lvp__vertex_classes(const lvp_binding *binding, int32_t k, int32_t r_class[LVP__SPREAD_KEPT],
                                   float r_weight[LVP__SPREAD_KEPT])
{
	int32_t count = 0;
	for (int32_t e = binding->reach.offsets[k]; e < binding->reach.offsets[k + 1]; ++e) {
		float w = binding->reach.phi[e];
		if (!(w > 0.0f))
			continue;
		int32_t c = binding->frame_map.skin_class[binding->reach.regions[e]], i = 0;
		while (i < count && r_class[i] != c)
			++i;
		if (i == count) {
			if (count == LVP__SPREAD_KEPT)
				return -1;
			r_class[count] = c;
			r_weight[count++] = 0.0f;
		}
		r_weight[i] += w;
	}
	return count;
}

/* a_k of vertex k: one displacement per class of the bones that reach it (bone by bone when every
 * bone is a class of its own, as on rigs past LVP__CLASS_BONES). */
static float lvp__vertex_spread(const lvp_binding *binding, const float *p, int32_t k)
{
	int32_t classes[LVP__SPREAD_KEPT];
	float class_weight[LVP__SPREAD_KEPT];
	int32_t class_count = binding->frame_map.classes_alone ? -1 : lvp__vertex_classes(binding, k, classes, class_weight);
	if (class_count >= 0)
		return lvp__spread(binding, p, classes, class_weight, class_count);
	int32_t first = binding->reach.offsets[k];
	return lvp__spread(binding, p, binding->reach.regions + first, binding->reach.phi + first,
	                   binding->reach.offsets[k + 1] - first);
}

/* This frame's map at vertex k of the given class (lvp__vertex_class). */
static inline float lvp__frame_gamma(const lvp_binding *binding, const float *rest, int32_t k, int32_t vertex_class)
{
	float gamma = lvp__bind_gamma(binding, k);
	if (!binding->map.options.deformation_weighted)
		return gamma;
	if (!(gamma > 0.0f) || (vertex_class >= 0 && !binding->reach.own))
		return 0.0f; /* all its bones in one class: it moves rigidly */
	/* With a bulge width the regions that reach a vertex are more than its bones: a vertex that
	 * moves rigidly is still moved by a joint that bends near it. */
	return gamma * lvp__vertex_spread(binding, rest + 3 * k, k);
}

/* Whether the map may move vertex k of the given class this frame: decided by the skin classes
 * alone, never by the value of its map, so that a frame whose classes are last frame's has last
 * frame's dynamic vertices (lvp__build_frame_map reuses them). With a bulge width, a vertex that
 * moves rigidly may still be moved by the joints of the regions that reach it, when those fall
 * into more than one class; its map is then zero only while they carry it alike to float noise,
 * and was taken for rigid at that frame: a frame played to differed from the same frame opened
 * at, by the joints that began to bend since. */
static bool lvp__map_may_move(const lvp_binding *binding, int32_t k, int32_t vertex_class)
{
	if (!(lvp__bind_gamma(binding, k) > 0.0f))
		return false;
	if (!binding->map.options.deformation_weighted || vertex_class < 0)
		return true;
	if (!binding->reach.own)
		return false;
	int32_t classes[LVP__SPREAD_KEPT];
	float class_weight[LVP__SPREAD_KEPT];
	return lvp__vertex_classes(binding, k, classes, class_weight) != 1;
}

/* Per vertex, independent of every other: split over the worker threads. A class is the index
 * of its first bone (lvp__skin_classes), so it names that bone's displacement. */
static void lvp__frame_map_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__loop_context *c = context; /* positions: the rest */
	lvp_binding *binding = c->binding;
	bool changed = false;
	for (int32_t k = begin; k < end; ++k) {
		int32_t vertex_class = binding->frame_map.rigid_shortcut_off ? -1 : lvp__vertex_class(binding, k);
		changed = changed || binding->frame_map.vertex_class[k] != vertex_class;
		binding->frame_map.vertex_class[k] = vertex_class;
		binding->frame_map.gamma[k] = lvp__frame_gamma(binding, c->positions, k, vertex_class);
		uint8_t dynamic = vertex_class < 0 || lvp__map_may_move(binding, k, vertex_class);
		changed = changed || binding->frame_map.vertex_dynamic[k] != dynamic;
		binding->frame_map.vertex_dynamic[k] = dynamic;
	}
	binding->frame_map.chunk_changed[begin / LVP__GRAIN] = changed;
}

/* The same over the dynamic vertices only, when their classes and flags are known. */
static void lvp__frame_map_dynamic_loop(void *context, int32_t begin, int32_t end)
{
	const lvp__loop_context *c = context; /* positions: the rest */
	lvp_binding *binding = c->binding;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = binding->dynamic.vertices[v];
		binding->frame_map.gamma[k] = lvp__frame_gamma(binding, c->positions, k, binding->frame_map.vertex_class[k]);
	}
}

/* Vertices checked per region by lvp__rigid_vertices_hold, spread over its vertices. */
#define LVP__RIGID_SAMPLES 8

bool lvp__rigid_vertices_hold(const lvp_binding *binding, const float *positions, const float *rest_positions,
                              double *r_off)
{
	const float *rest = rest_positions ? rest_positions : binding->rest_positions;
	double largest = 0.0;
	bool hold = true;
	if (binding->mode != LVP_MODE_LOCAL) {
		*r_off = 0.0;
		return true;
	}
	for (int32_t r = 0; r < binding->region_count; ++r) {
		int32_t first = binding->mesh.region_vertex_offsets[r],
		        count = binding->mesh.region_vertex_offsets[r + 1] - first;
		int32_t step = count > LVP__RIGID_SAMPLES ? count / LVP__RIGID_SAMPLES : 1;
		for (int32_t i = 0; i < count; i += step) {
			int32_t k = binding->mesh.region_vertices[first + i], c = binding->frame_map.vertex_class[k];
			if (binding->frame_map.vertex_dynamic[k] || c < 0)
				continue;
			lvp__vec3 x = lvp__load(rest + 3 * k), expected = lvp__transform_point(&binding->rig.skin[c], x);
			double off = lvp__length(lvp__sub(lvp__load(positions + 3 * k), expected));
			/* Float rounding of Blender's skinning is of 1e-7 of the point's and the bones' size;
			 * a frame that is not this skinning is off by far more. */
			double allowed = 1e-4 * (binding->rig.reach + lvp__length(x) + lvp__length(expected));
			largest = fmax(largest, off);
			if (!(off <= allowed))
				hold = false;
		}
	}
	*r_off = hold ? 0.0 : largest;
	return hold;
}

/* Whether vertex k borders the moving skin: the map lets it move (its bind map is not zero) and the
 * classes of the bones that reach it do not, while a neighbour is dynamic. It may lie in a hole or a
 * bay of the moving skin: rows keep their strongest bones (reach.c), so where many bones overlap (a
 * torso between four legs) the bone that bends can be the ninth of one vertex and the eighth of its
 * neighbours; left still while they move, the vertex would stay where skinning put it, a dimple in
 * the bulge, and the smoothing would pull the skin around it further out (lvp__fill_holes). Or on
 * the moving skin's rim, where the weight of a bone that moves runs out, which the smoothing feathers
 * (offset_smoothing.c, lvp__feather_rim). Decided by the classes alone, as the dynamic flags are,
 * from the flags before any is made dynamic. */
static bool lvp__borders_moving_skin(const lvp_binding *binding, int32_t k)
{
	const lvp__smoothing *smoothing = &binding->smoothing;
	if (binding->frame_map.vertex_dynamic[k] || !(lvp__bind_gamma(binding, k) > 0.0f))
		return false;
	for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
		if (binding->frame_map.vertex_dynamic[smoothing->neighbours[e]])
			return true;
	return false;
}

/* Finds the vertices that border the moving skin (lvp__borders_moving_skin), all decided before any
 * is made dynamic, and makes them dynamic. Returns whether there are any: the classes' loop compared
 * each vertex's flag by its classes alone, so one made dynamic is a change it did not see (and one
 * that bordered it the frame before, and still does, one it did). */
static bool lvp__find_holes(lvp_binding *binding)
{
	lvp__frame_map *frame_map = &binding->frame_map;
	int32_t count = 0;
	for (int32_t k = 0; k < binding->vertex_count; ++k)
		if (lvp__borders_moving_skin(binding, k))
			frame_map->fill[count++] = k;
	for (int32_t i = 0; i < count; ++i)
		frame_map->vertex_dynamic[frame_map->fill[i]] = 1;
	return count > 0;
}

/* Whether the bones that reach vertex k move alike, to float rounding of their matrices, though
 * they fall into several classes (the joints of a B-Bone that turns as one): their skin matrices
 * agree everywhere, not only at the vertex (as two bones do on the axis of the joint they bend
 * about, which is left still). */
static bool lvp__bones_alike(const lvp_binding *binding, int32_t k)
{
	int32_t first = binding->reach.offsets[k], last = binding->reach.offsets[k + 1];
	if (last - first < 2)
		return true;
	const float *a = binding->frame_map.skin_displacement + 12 * binding->reach.regions[first];
	double tolerance = 1e-5, reach = binding->rig.reach;
	for (int32_t e = first + 1; e < last; ++e) {
		const float *b = binding->frame_map.skin_displacement + 12 * binding->reach.regions[e];
		for (int c = 0; c < 12; ++c) /* rows of 3x4: the translations, c % 4 == 3, in lengths */
			if (fabs((double)a[c] - b[c]) > (c % 4 == 3 ? tolerance * reach : tolerance))
				return false;
	}
	return true;
}

/* Whether dynamic vertex k is still by this frame's map while most of its neighbours move: a hole
 * or a bay (lvp__borders_moving_skin), or a vertex whose bones fall into several classes that carry
 * it alike to float noise (lvp__bones_alike), so its a_k is zero. Read before any of a pass of
 * lvp__fill_holes is filled. */
static bool lvp__still_in_moving_skin(const lvp_binding *binding, int32_t k)
{
	const lvp__smoothing *smoothing = &binding->smoothing;
	const float *gamma = binding->frame_map.gamma;
	if (!binding->frame_map.vertex_dynamic[k] || gamma[k] > 0.0f || !(lvp__bind_gamma(binding, k) > 0.0f))
		return false;
	int32_t moving = 0, count = smoothing->offsets[k + 1] - smoothing->offsets[k];
	for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
		moving += gamma[smoothing->neighbours[e]] > 0.0f;
	return 2 * moving > count && lvp__bones_alike(binding, k); /* the costlier test last */
}

/* The vertices lvp__fill_holes walks: the dynamic ones, or with vertices NULL, all. */
typedef struct lvp__hole_walk {
	lvp_binding *binding;
	const int32_t *vertices;
} lvp__hole_walk;

/* fill_gamma of the vertices [begin, end) of the walk: the map a vertex still in moving skin takes,
 * the mean of its neighbours' maps (one that is still counting with none), or -1 for any other.
 * Reads the maps only, so the walk can be split over threads. */

static void lvp__hole_map_loop(void *context, int32_t begin, int32_t end)
{
	lvp_binding *binding = ((lvp__hole_walk *)context)->binding;
	const int32_t *vertices = ((lvp__hole_walk *)context)->vertices;
	const lvp__smoothing *smoothing = &binding->smoothing;
	lvp__frame_map *frame_map = &binding->frame_map;
	for (int32_t v = begin; v < end; ++v) {
		int32_t k = vertices ? vertices[v] : v;
		frame_map->fill_gamma[v] = -1.0f;
		if (!lvp__still_in_moving_skin(binding, k))
			continue;
		double sum = 0.0;
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
			sum += frame_map->gamma[smoothing->neighbours[e]];
		frame_map->fill_gamma[v] = (float)(sum / (double)(smoothing->offsets[k + 1] - smoothing->offsets[k]));
	}
}

/* The map of each vertex still in moving skin (lvp__still_in_moving_skin) among `vertices` (NULL:
 * all `count` vertices): the mean of its neighbours' maps, so that it moves with the skin around it
 * and its map tapers where the moving skin ends. Pass by pass, each pass's maps all read before any
 * is written, until a pass fills none: two or three such vertices side by side (a crotch vertex
 * the two parts of one thigh carry alike, beside others of the same thigh) each have too few moving
 * neighbours until the first is filled, and one left still keeps no offset among neighbours that
 * take theirs, a pit the smoothing cannot reach (it moves only vertices the map moves). A filled
 * vertex is never a candidate again, so each pass but the last fills one at least. Only dynamic
 * vertices can be such: when the dynamic set is current, it is all that is walked. */
static void lvp__fill_holes(lvp_binding *binding, const int32_t *vertices, int32_t vertex_count)
{
	lvp__frame_map *frame_map = &binding->frame_map;
	lvp__hole_walk walk = {binding, vertices};
	for (bool filled = true; filled;) {
		lvp__parallel_for(LVP__POOL_FOR(binding, vertex_count), lvp__hole_map_loop, &walk, vertex_count, LVP__GRAIN);
		filled = false;
		for (int32_t v = 0; v < vertex_count; ++v)
			if (frame_map->fill_gamma[v] > 0.0f) {
				frame_map->gamma[vertices ? vertices[v] : v] = frame_map->fill_gamma[v];
				filled = true;
			}
	}
}

/* frame_map.rim: among `vertices` (NULL: all `count` vertices), those still by this frame's map though
 * their bind map lets them move, beside a vertex the map moves. Listed before anything fades the map
 * (fold-over's contacts, Keep Skin Apart): only where the moving skin ends. */
static void lvp__list_rim(lvp_binding *binding, const int32_t *vertices, int32_t count)
{
	const lvp__smoothing *smoothing = &binding->smoothing;
	lvp__frame_map *frame_map = &binding->frame_map;
	frame_map->rim_count = 0;
	for (int32_t v = 0; v < count; ++v) {
		int32_t k = vertices ? vertices[v] : v;
		if (!frame_map->vertex_dynamic[k] || frame_map->gamma[k] > 0.0f || !(lvp__bind_gamma(binding, k) > 0.0f))
			continue;
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e)
			if (frame_map->gamma[smoothing->neighbours[e]] > 0.0f) {
				frame_map->rim[frame_map->rim_count++] = k;
				break;
			}
	}
}

/* This frame's map (the bind map times the deformation weighting a_k of lvp.h), and which
 * vertices are dynamic (binding.h). */
void lvp__build_frame_map(lvp_binding *binding, const float *rest_positions)
{
	int32_t n = binding->vertex_count;
	if (binding->mode != LVP_MODE_LOCAL) {
		for (int32_t k = 0; k < n; ++k)
			binding->frame_map.gamma[k] = lvp__bind_gamma(binding, k);
		memset(binding->frame_map.vertex_dynamic, 1, (size_t)n);
		return;
	}
	lvp__skin_classes(binding);
	for (int32_t i = 0; i < binding->bone_count; ++i) {
		const double *m = binding->rig.skin[i].m;
		float *d = binding->frame_map.skin_displacement + 12 * i;
		for (int c = 0; c < 12; ++c)
			d[c] = (float)(m[c] - (c % 5 == 0 ? 1.0 : 0.0)); /* S - I: the diagonal is 0, 5, 10 */
	}
	lvp__loop_context context = {binding, rest_positions ? rest_positions : binding->rest_positions};
	if (binding->frame_map.current && binding->dynamic.current) {
		/* The bones fall into the same classes as in the frame before and nothing else changed a
		 * vertex's class or flag (binding.h): only the dynamic vertices' map follows the pose;
		 * every other vertex is rigid, its map still zero. In an animation this is most frames,
		 * and the walk over all vertices is skipped. */
		lvp__parallel_for(LVP__POOL_FOR(binding, binding->dynamic.vertex_count), lvp__frame_map_dynamic_loop,
		                  &context, binding->dynamic.vertex_count, LVP__GRAIN);
		lvp__fill_holes(binding, binding->dynamic.vertices, binding->dynamic.vertex_count);
		lvp__list_rim(binding, binding->dynamic.vertices, binding->dynamic.vertex_count);
		return;
	}
	int32_t chunks = (n + LVP__GRAIN - 1) / LVP__GRAIN;
	memset(binding->frame_map.chunk_changed, 0, (size_t)chunks);
	lvp__parallel_for(LVP__POOL_FOR(binding, n), lvp__frame_map_loop, &context, n, LVP__GRAIN);
	bool any_hole = lvp__find_holes(binding);
	for (int32_t i = 0; i < chunks; ++i)
		if (binding->frame_map.chunk_changed[i] || any_hole)
			lvp__dynamic_set_stale(binding);
	lvp__fill_holes(binding, NULL, n);
	lvp__list_rim(binding, NULL, n);
	binding->frame_map.current = true;
}

void lvp__frame_map_stale(lvp_binding *binding)
{
	binding->frame_map.current = false;
}

void lvp__make_dynamic(lvp_binding *binding, int32_t k)
{
	binding->frame_map.vertex_dynamic[k] = 1;
	binding->frame_map.current = false;
	lvp__dynamic_set_stale(binding);
}

void lvp__make_all_dynamic(lvp_binding *binding)
{
	memset(binding->frame_map.vertex_dynamic, 1, (size_t)binding->vertex_count);
	binding->frame_map.current = false;
}

void lvp__use_rigid_shortcut(lvp_binding *binding, bool usable)
{
	if (binding->frame_map.rigid_shortcut_off == !usable)
		return;
	binding->frame_map.rigid_shortcut_off = !usable;
	binding->frame_map.current = false;
	lvp__dynamic_set_stale(binding);
}

bool lvp__frame_map_alloc(lvp_binding *binding)
{
	size_t n = (size_t)binding->vertex_count, b = (size_t)binding->bone_count;
	lvp__frame_map *frame_map = &binding->frame_map;
	bool ok = true;
	frame_map->gamma = lvp__calloc(n, sizeof(float), &ok);
	frame_map->skin_class = lvp__calloc(b, sizeof(int32_t), &ok);
	frame_map->skin_displacement = lvp__calloc(b * 12, sizeof(float), &ok);
	frame_map->vertex_class = lvp__calloc(n, sizeof(int32_t), &ok);
	frame_map->vertex_dynamic = lvp__calloc(n, sizeof(uint8_t), &ok);
	frame_map->chunk_changed = lvp__calloc(n / LVP__GRAIN + 1, sizeof(uint8_t), &ok);
	frame_map->fill = lvp__calloc(n + 1, sizeof(int32_t), &ok);
	frame_map->fill_gamma = lvp__calloc(n + 1, sizeof(float), &ok);
	frame_map->rim = lvp__calloc(n + 1, sizeof(int32_t), &ok);
	return ok;
}

void lvp__frame_map_free(lvp__frame_map *frame_map)
{
	free(frame_map->gamma);
	free(frame_map->skin_class);
	free(frame_map->skin_displacement);
	free(frame_map->vertex_class);
	free(frame_map->vertex_dynamic);
	free(frame_map->chunk_changed);
	free(frame_map->fill);
	free(frame_map->fill_gamma);
	free(frame_map->rim);
}
