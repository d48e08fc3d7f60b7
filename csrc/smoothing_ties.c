/*
 * smoothing_ties.c - vertices the smoothing's weights tie into one point are averaged as one (lvp.h,
 * OFFSET SMOOTHING; docs/method.md, Smoothing the offsets).
 *
 * A very short edge (metaball and marching-cubes meshes leave edges a few hundredths of the mean edge
 * long) has cotangents in the tens across it, which hold its ends together, as they should: offsets
 * differing between them would tilt its thin triangles steeply. But a pass moves each vertex halfway to
 * the weighted mean of its neighbours, and for two vertices tied that strongly the mean is mostly the
 * other: the pair moves toward the ring around it only by the ring's small share of its weight, and
 * after the passes it still stands out from the surface around it.
 *
 * So, at bind, a cluster (at first each vertex alone) that gives more than half of its weight to one
 * neighbouring cluster is joined with it, round after round until none does; then every member of a
 * cluster averages over the cluster's neighbours outside it, each weighted by the shares of all the
 * members summed. The cluster follows its ring at the pace of any vertex, and its members keep one
 * offset between them. Where no vertex gives one neighbour more than half of its weight (fair
 * triangles, however irregular), nothing changes.
 *
 * Fold-over moves vertices one by one (each pressed onto its contact plane as far as it crossed it,
 * the volume steps after it through each vertex's own map and normal): the ends of a short edge
 * then part by a good share of the offsets, and its thin triangles turn on edge, a crease each. After
 * fold-over each cluster's members take their mean offset (lvp__move_ties_as_one): one point again
 * (correction.c restores the volume that takes, and takes the mean once more). A cluster with a member
 * that fold-over holds on a contact plane keeps the places fold-over gave its members: each is where
 * the press let it be, and a mean pulled one off its plane into the skin across (a decimated hand at
 * the fist: one vertex moved a fifth of an edge, five crossing pairs of plain skinning's back).
 *
 * Fold-over's relaxation has clusters of its own (offset_smoothing.c, binding.relaxation), decided on
 * mean value weights, which tie the ends of any edge much shorter than those around it, a needle's too.
 */
#include "binding.h"

#include <stdlib.h>

/* Members a cluster takes at most. The clusters found on real meshes have 2 to 5; the bound keeps a
 * degenerate mesh (a long strip of needles each tied to the next) from joining into one cluster whose
 * lists would cost the bind quadratic time, and a cluster that large would not be one point. */
#define LVP__CLUSTER_MOST 16

typedef struct lvp__clusters {
	int32_t count;    /* vertices */
	int32_t *parent;  /* union-find: the vertex's cluster is lvp__union_root(parent, vertex) */
	int32_t *first;   /* per cluster (its root): where its members start in `members`; count+1 */
	int32_t *members; /* the vertices by cluster, in vertex order */
	int32_t *joins;   /* per cluster: the cluster it is tied to this round, or -1 */
	int32_t *sizes;   /* per cluster (its root): its members, as joined so far */
	int32_t *keys;    /* scratch: what one cluster neighbours outside it (vertices or clusters) */
	double *sums;     /* scratch: and the shares of its members summed per key */
	int64_t capacity; /* of keys and sums */
} lvp__clusters;

static int32_t lvp__size_of(const lvp__clusters *clusters, int32_t root)
{
	return clusters->first[root + 1] - clusters->first[root];
}

/* The members of every cluster, and scratch enough for the largest cluster's neighbours. */
static bool lvp__list_members(lvp__clusters *clusters, const lvp__smoothing *smoothing)
{
	int32_t n = clusters->count, *first = clusters->first;
	for (int32_t k = 0; k <= n; ++k)
		first[k] = 0;
	for (int32_t k = 0; k < n; ++k)
		++first[lvp__union_root(clusters->parent, k) + 1];
	for (int32_t k = 0; k < n; ++k)
		first[k + 1] += first[k];
	/* first[root] walks along its members as they are placed, then everything shifts back by one */
	for (int32_t k = 0; k < n; ++k)
		clusters->members[first[lvp__union_root(clusters->parent, k)]++] = k;
	for (int32_t k = n; k > 0; --k)
		first[k] = first[k - 1];
	first[0] = 0;
	int64_t need = 1;
	for (int32_t root = 0; root < n; ++root) {
		int64_t entries = 0;
		for (int32_t m = first[root]; m < first[root + 1]; ++m)
			entries += smoothing->offsets[clusters->members[m] + 1] - smoothing->offsets[clusters->members[m]];
		need = entries > need ? entries : need;
	}
	if (need <= clusters->capacity)
		return true;
	int32_t *keys = realloc(clusters->keys, (size_t)need * sizeof(int32_t));
	if (keys)
		clusters->keys = keys;
	double *sums = realloc(clusters->sums, (size_t)need * sizeof(double));
	if (sums)
		clusters->sums = sums;
	if (!keys || !sums)
		return false;
	clusters->capacity = need;
	return true;
}

/* The shares (per entry of smoothing's lists) of the members of cluster `root` to what is outside it,
 * summed per neighbouring vertex, or per neighbouring cluster when by_cluster, into clusters->keys and
 * clusters->sums, in the order the members' lists name them; returns how many. */
static int32_t lvp__sum_outside(lvp__clusters *clusters, const lvp__smoothing *smoothing, const float *shares,
                                int32_t root, bool by_cluster)
{
	int32_t count = 0;
	for (int32_t m = clusters->first[root]; m < clusters->first[root + 1]; ++m) {
		int32_t k = clusters->members[m];
		for (int32_t e = smoothing->offsets[k]; e < smoothing->offsets[k + 1]; ++e) {
			int32_t j = smoothing->neighbours[e], cluster = lvp__union_root(clusters->parent, j);
			if (cluster == root)
				continue;
			int32_t key = by_cluster ? cluster : j, i = 0;
			while (i < count && clusters->keys[i] != key)
				++i;
			if (i == count) {
				clusters->keys[count] = key;
				clusters->sums[count++] = 0.0;
			}
			clusters->sums[i] += shares[e];
		}
	}
	return count;
}

/* One round, decided on the clusters as the round found them: each that gives more than half of its
 * shares (tie_shares) to one neighbouring cluster (and has another neighbour) is joined with it, the
 * lower root staying, unless together they would have more than LVP__CLUSTER_MOST members. Returns how
 * many clusters were joined to another. */
static int32_t lvp__tie_round(lvp__clusters *clusters, const lvp__smoothing *smoothing, const float *tie_shares)
{
	int32_t n = clusters->count;
	for (int32_t root = 0; root < n; ++root) {
		clusters->joins[root] = -1;
		if (lvp__size_of(clusters, root) == 0)
			continue;
		int32_t count = lvp__sum_outside(clusters, smoothing, tie_shares, root, true), heaviest = 0;
		const int32_t *keys = clusters->keys;
		const double *sums = clusters->sums;
		double total = 0.0;
		for (int32_t i = 0; i < count; ++i) {
			total += sums[i];
			if (sums[i] > sums[heaviest] || (sums[i] == sums[heaviest] && keys[i] < keys[heaviest]))
				heaviest = i;
		}
		if (count >= 2 && sums[heaviest] > total - sums[heaviest])
			clusters->joins[root] = keys[heaviest];
	}
	int32_t joined = 0;
	for (int32_t root = 0; root < n; ++root) {
		if (clusters->joins[root] < 0)
			continue;
		int32_t a = lvp__union_root(clusters->parent, root), b = lvp__union_root(clusters->parent, clusters->joins[root]);
		if (a != b && clusters->sizes[a] + clusters->sizes[b] <= LVP__CLUSTER_MOST) {
			int32_t kept = a < b ? a : b;
			clusters->parent[a > b ? a : b] = kept;
			clusters->sizes[kept] = clusters->sizes[a] + clusters->sizes[b];
			++joined;
		}
	}
	return joined;
}

/* The length of vertex k's new neighbour list, or with `neighbours`, the list written there. */
static int32_t lvp__list_of(lvp__clusters *clusters, const lvp__smoothing *smoothing, int32_t k, int32_t *neighbours,
                            float *shares)
{
	int32_t root = lvp__union_root(clusters->parent, k);
	if (lvp__size_of(clusters, root) == 1) {
		int32_t count = smoothing->offsets[k + 1] - smoothing->offsets[k];
		for (int32_t i = 0; neighbours && i < count; ++i) {
			neighbours[i] = smoothing->neighbours[smoothing->offsets[k] + i];
			shares[i] = smoothing->shares[smoothing->offsets[k] + i];
		}
		return count;
	}
	int32_t count = lvp__sum_outside(clusters, smoothing, smoothing->shares, root, false);
	for (int32_t i = 0; neighbours && i < count; ++i) {
		neighbours[i] = clusters->keys[i];
		shares[i] = (float)clusters->sums[i];
	}
	return count;
}

/* binding.smoothing's lists again, each member of a cluster given the cluster's. */
static bool lvp__relist(lvp__smoothing *smoothing, lvp__clusters *clusters)
{
	int32_t n = clusters->count;
	int64_t total = 0;
	for (int32_t k = 0; k < n; ++k)
		total += lvp__list_of(clusters, smoothing, k, NULL, NULL);
	bool ok = true;
	int32_t *offsets = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok);
	int32_t *neighbours = lvp__calloc((size_t)total + 1, sizeof(int32_t), &ok);
	float *shares = lvp__calloc((size_t)total + 1, sizeof(float), &ok);
	if (ok) {
		for (int32_t k = 0; k < n; ++k)
			offsets[k + 1] = offsets[k] + lvp__list_of(clusters, smoothing, k, neighbours + offsets[k], shares + offsets[k]);
		lvp__smoothing_free(smoothing);
		*smoothing = (lvp__smoothing){.offsets = offsets, .neighbours = neighbours, .shares = shares};
		return true;
	}
	free(offsets);
	free(neighbours);
	free(shares);
	return false;
}

/* smoothing.tie_offsets and tie_members: the clusters of two or more, each's members in vertex order. */
static bool lvp__list_ties(lvp__smoothing *smoothing, const lvp__clusters *clusters)
{
	int32_t count = 0, members = 0;
	for (int32_t root = 0; root < clusters->count; ++root)
		if (lvp__size_of(clusters, root) > 1) {
			++count;
			members += lvp__size_of(clusters, root);
		}
	bool ok = true;
	smoothing->tie_offsets = lvp__calloc((size_t)count + 1, sizeof(int32_t), &ok);
	smoothing->tie_members = lvp__calloc((size_t)members + 1, sizeof(int32_t), &ok);
	if (!ok)
		return false;
	int32_t tie = 0, written = 0;
	for (int32_t root = 0; root < clusters->count; ++root)
		if (lvp__size_of(clusters, root) > 1) {
			for (int32_t i = clusters->first[root]; i < clusters->first[root + 1]; ++i)
				smoothing->tie_members[written++] = clusters->members[i];
			smoothing->tie_offsets[++tie] = written;
		}
	smoothing->tie_count = count;
	return true;
}

lvp_result lvp__tie_smoothing(lvp_binding *binding, lvp__smoothing *smoothing, const float *tie_shares,
                              lvp_diagnostic *r_diag)
{
	int32_t n = binding->vertex_count;
	bool ok = true;
	lvp__clusters clusters = {.count = n,
	                          .parent = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok),
	                          .first = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok),
	                          .members = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok),
	                          .joins = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok),
	                          .sizes = lvp__calloc((size_t)n + 1, sizeof(int32_t), &ok)};
	for (int32_t k = 0; ok && k < n; ++k) {
		clusters.parent[k] = k;
		clusters.sizes[k] = 1;
	}
	int32_t joined = 0, round_joined = 1;
	while (ok && round_joined > 0) {
		ok = lvp__list_members(&clusters, smoothing);
		round_joined = ok ? lvp__tie_round(&clusters, smoothing, tie_shares ? tie_shares : smoothing->shares) : 0;
		joined += round_joined;
	}
	if (ok && joined > 0)
		ok = lvp__list_members(&clusters, smoothing) && lvp__relist(smoothing, &clusters) &&
		     lvp__list_ties(smoothing, &clusters);
	free(clusters.parent);
	free(clusters.first);
	free(clusters.members);
	free(clusters.joins);
	free(clusters.sizes);
	free(clusters.keys);
	free(clusters.sums);
	if (!ok)
		return lvp__fail(r_diag, lvp_error_out_of_memory, "binding", -1, "out of memory while binding.");
	return lvp_success;
}

void lvp__move_ties_as_one(lvp_binding *binding, const float *positions)
{
	const lvp__smoothing *smoothing = &binding->smoothing;
	float *work = binding->step.positions;
	for (int32_t tie = 0; tie < smoothing->tie_count; ++tie) {
		int32_t first = smoothing->tie_offsets[tie], last = smoothing->tie_offsets[tie + 1];
		bool held = false;
		for (int32_t i = first; i < last && !held; ++i)
			held = binding->fold.held[smoothing->tie_members[i]] != 0;
		if (held)
			continue;
		double mean[3] = {0.0, 0.0, 0.0};
		for (int32_t i = first; i < last; ++i) {
			int32_t k = smoothing->tie_members[i];
			for (int c = 0; c < 3; ++c)
				mean[c] += (double)work[3 * k + c] - positions[3 * k + c];
		}
		bool moves = false;
		for (int c = 0; c < 3; ++c) {
			mean[c] /= (double)(last - first);
			moves |= mean[c] != 0.0;
		}
		for (int32_t i = first; i < last; ++i) {
			int32_t k = smoothing->tie_members[i];
			if (moves && !binding->frame_map.vertex_dynamic[k])
				lvp__make_dynamic(binding, k);
			for (int c = 0; c < 3; ++c)
				work[3 * k + c] = (float)(positions[3 * k + c] + mean[c]);
		}
	}
}
