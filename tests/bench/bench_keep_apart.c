/*
 * bench_keep_apart.c - what Keep Skin Apart (lvp.h, CONTACT) costs a frame in the core, and a hash of
 * what it gives: chains of the core's bench bent at one joint or at every joint, the finger of the C
 * tests bent until skinning crosses, and the paper's giraffe, each with the add-on's Restore (the whole
 * mesh), with and without keep_apart (and with smoothing and fold-over, the add-on's other options), on
 * 1 and 2 threads. Frames go through POSES poses on one binding, as an animation plays; the time is the
 * median, the hash (FNV-1a over the corrected positions of every pose) must match across thread
 * counts, and across builds when a change is meant to keep results bit for bit.
 *
 *   cc ... tests/bench/bench_keep_apart.c tests/c/support/\*.c build/liblvp.a -lm -lgmp (as cmd_bench)
 *   (cd tests && bench_keep_apart [TEXT] [--quick])   TEXT: only the cases whose names contain it;
 *   KSA_REPEATS=N times each case N frames (a profile of one)
 */
#include "lvp.h"
#include "support/test_meshes.h"
#include "bench_common.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define MAX_REPEATS 301

typedef struct ksa_case {
	const char *name;
	const test_rig *rig;
	const float *rotations; /* bone_count*4: axis and angle per bone */
	int32_t keep_apart, smoothing, fold_over;
	int repeats;
} ksa_case;

static uint64_t fnv1a(uint64_t hash, const void *data, size_t size)
{
	const unsigned char *bytes = data;
	for (size_t i = 0; i < size; ++i)
		hash = (hash ^ bytes[i]) * 1099511628211ull;
	return hash;
}

/* Median ms of a frame over `repeats` frames, and the hash of each pose's corrected positions (the same
 * whenever a pose comes back: checked). */
static double run(const ksa_case *c, int32_t threads, uint64_t *r_hash, lvp_frame_stats *r_stats)
{
	const test_rig *rig = c->rig;
	int32_t n = rig->vertex_count;
	float *posed[POSES], *skinned[POSES];
	pose_animation(rig, c->rotations, 1.0f, posed, skinned);
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	lvp_bind_options bind_options = lvp_bind_default_options();
	bind_options.thread_count = threads;
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	if (lvp_bind(&binding, rig->positions, n, rig->triangles, rig->triangle_count, &weights, &skeleton, &bind_options,
	             &diag) != lvp_success) {
		fprintf(stderr, "bind failed: %s\n", diag.message);
		exit(1);
	}
	lvp_frame_options options = lvp_frame_default_options();
	options.restore = LVP_RESTORE_WHOLE_MESH;
	options.keep_apart = c->keep_apart;
	options.smoothing_passes = c->smoothing;
	options.fold_over = c->fold_over;
	float *out = malloc(sizeof(float) * 3 * (size_t)n);
	uint64_t hashes[POSES] = {0};
	double times[MAX_REPEATS];
	int repeats = getenv("KSA_REPEATS") ? atoi(getenv("KSA_REPEATS")) : c->repeats;
	repeats = repeats < 1 ? 1 : (repeats < MAX_REPEATS ? repeats : MAX_REPEATS);
	/* One frame first, untimed: the first with keep_apart builds the contact hierarchy. */
	for (int i = -1; i < repeats; ++i) {
		int pose = ((i % POSES) + POSES) % POSES;
		double start = now();
		lvp_result result = lvp_correct(out, NULL, binding, skinned[pose], posed[pose], NULL, &options, r_stats, &diag);
		double elapsed = now() - start;
		if (result != lvp_success) {
			fprintf(stderr, "%s: %s\n", c->name, diag.message);
			exit(1);
		}
		if (i >= 0)
			times[i] = elapsed;
		uint64_t hash = fnv1a(1469598103934665603ull, out, sizeof(float) * 3 * (size_t)n);
		if (hashes[pose] && hashes[pose] != hash) {
			fprintf(stderr, "%s: pose %d gave other positions when it came back\n", c->name, pose);
			exit(1);
		}
		hashes[pose] = hash;
	}
	*r_hash = 1469598103934665603ull;
	for (int pose = 0; pose < POSES; ++pose)
		*r_hash = fnv1a(*r_hash, &hashes[pose], sizeof(hashes[pose]));
	free(out);
	lvp_free(binding);
	for (int pose = 0; pose < POSES; ++pose) {
		free(posed[pose]);
		free(skinned[pose]);
	}
	return 1e3 * median(times, repeats);
}

static const char *only;

static void report(const ksa_case *c)
{
	if (only && !strstr(c->name, only))
		return;
	uint64_t hash1, hash2;
	lvp_frame_stats stats;
	double one = run(c, 1, &hash1, &stats);
	double two = run(c, 2, &hash2, &stats);
	printf("| %s | %.2f | %.2f | %d | %d | %016llx%s |\n", c->name, one, two, (int)stats.shortened_vertices,
	       (int)stats.crossing_triangles, (unsigned long long)hash1, hash1 == hash2 ? "" : " (2 threads differ!)");
	fflush(stdout);
}

/* The case with and without keep_apart, and with the add-on's smoothing, and fold-over. */
static void report_variants(const char *name, const test_rig *rig, const float *rotations, int repeats, int all)
{
	char text[160];
	ksa_case c = {text, rig, rotations, 0, 0, 0, repeats};
	snprintf(text, sizeof(text), "%s", name);
	report(&c);
	snprintf(text, sizeof(text), "%s, kept apart", name);
	c.keep_apart = 1;
	report(&c);
	if (!all)
		return;
	snprintf(text, sizeof(text), "%s, kept apart, smoothed 6", name);
	c.smoothing = 6;
	report(&c);
	snprintf(text, sizeof(text), "%s, kept apart, fold-over", name);
	c.smoothing = 0;
	c.fold_over = 1;
	report(&c);
}

int main(int argc, char **argv)
{
	int quick = 0;
	for (int i = 1; i < argc; ++i) {
		if (!strcmp(argv[i], "--quick"))
			quick = 1;
		else
			only = argv[i];
	}
	printf("| case | frame, 1 thread (ms) | 2 threads (ms) | shortened | crossing | positions (FNV-1a) |\n");
	printf("|---|---:|---:|---:|---:|---|\n");
	test_rig small = test_make_chain(8, 1.0f, 0.3f, 32, 20, 0.5f);
	test_rig large = test_make_chain(32, 1.0f, 0.3f, 64, 50, 0.5f);
	float *small_all = chain_pose(small.bone_count, 1, 40.0), *small_one = chain_pose(small.bone_count, 0, 100.0);
	float *large_one = chain_pose(large.bone_count, 0, 40.0), *large_all = chain_pose(large.bone_count, 1, 40.0);
	report_variants("chain 5k every joint", &small, small_all, 21, 1);
	report_variants("chain 5k one joint 100 degrees", &small, small_one, 21, 1);
	report_variants("chain 100k one joint", &large, large_one, 21, 1);
	test_rig finger = test_make_finger();
	float *finger_pose = calloc((size_t)finger.bone_count * 4, sizeof(float));
	for (int32_t i = 1; i < finger.bone_count && i <= 2; ++i) {
		finger_pose[4 * i] = 1.0f;
		finger_pose[4 * i + 3] = (float)(100.0 * PI / 180.0);
	}
	report_variants("finger 100 degrees", &finger, finger_pose, 21, 1);
	test_rig giraffe;
	if (test_load_giraffe(&giraffe, "data/giraffe") != 0) {
		fprintf(stderr, "cannot load data/giraffe (run from tests/)\n");
		return 1;
	}
	float *giraffe_rotations = giraffe_pose(&giraffe);
	report_variants("giraffe", &giraffe, giraffe_rotations, 21, 1);
	if (!quick)
		report_variants("chain 100k every joint", &large, large_all, 3, 0);
	free(small_all);
	free(small_one);
	free(large_one);
	free(large_all);
	free(finger_pose);
	free(giraffe_rotations);
	test_rig_free(&small);
	test_rig_free(&large);
	test_rig_free(&finger);
	test_rig_free(&giraffe);
	return 0;
}
