/*
 * bench_core.c - `./build.sh bench`: bind time and per-frame correction time of the C core for
 * about 5k, 100k and 1M vertices (a long chain of bones skinned as a subdivided tube, and the
 * paper's giraffe subdivided), on one thread and on all cores. Medians of repeated runs, wall
 * clock. The frames are an animation: the bends go through POSES angles (90 to 100 % of the
 * case's), so no frame is the one before it again. Prints a Markdown table for BENCHMARKS.md.
 */
#include "lvp.h"
#include "support/test_meshes.h"
#include "bench_common.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#ifndef ADDON_SMOOTHING_PASSES
#define ADDON_SMOOTHING_PASSES 6 /* the add-on's Smoothing (addon/properties.py) */
#endif

typedef struct bench_case {
	const char *name;
	test_rig rig;
	const char *pose;   /* what is bent */
	float *rotations;   /* bone_count*4 */
	float stretch;      /* every other bone scaled by it about its head (1: none): squash and stretch */
	float bulge_width;  /* lvp_bind_options.bulge_width (0, the core's default: none; the add-on's is 1) */
	int32_t fold_over;  /* lvp_frame_options.fold_over */
	int32_t restore;    /* lvp_frame_options.restore (the core's default: each region; the add-on's: the whole mesh) */
	int32_t keep_apart; /* lvp_frame_options.keep_apart (the core's default: off; the add-on's: off in the
	                       viewport, on in renders) */
	int32_t smoothing;  /* lvp_frame_options.smoothing_passes (the core's default: 0; the add-on's:
	                       ADDON_SMOOTHING_PASSES) */
} bench_case;

/* Median wall time of lvp_correct over `repeats` frames with `threads` threads; frame i shows
 * pose (repeats - 1 - i) % POSES, so the last one, whose statistics are kept, is pose 0 (the
 * case's full bend). */
static double frame_time(const bench_case *c, int32_t threads, float *const skinned[POSES],
                         float *const posed[POSES], lvp_frame_stats *r_stats, double *r_bind)
{
	const test_rig *rig = &c->rig;
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	lvp_bind_options options = lvp_bind_default_options();
	options.thread_count = threads;
	options.bulge_width = c->bulge_width;
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	double start = now();
	if (lvp_bind(&binding, rig->positions, rig->vertex_count, rig->triangles, rig->triangle_count, &weights,
	             &skeleton, &options, &diag) != lvp_success) {
		fprintf(stderr, "bind failed: %s\n", diag.message);
		exit(1);
	}
	*r_bind = now() - start;
	float *offsets = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	lvp_frame_options frame_options = lvp_frame_default_options();
	frame_options.fold_over = c->fold_over;
	frame_options.restore = c->restore;
	frame_options.keep_apart = c->keep_apart;
	frame_options.smoothing_passes = c->smoothing;
	int repeats = rig->vertex_count > 500000 ? 7 : 21;
	double times[21];
	for (int i = 0; i < repeats; ++i) {
		start = now();
		int pose = (repeats - 1 - i) % POSES;
		lvp_correct(NULL, offsets, binding, skinned[pose], posed[pose], NULL, &frame_options, r_stats, NULL);
		times[i] = now() - start;
	}
	free(offsets);
	lvp_free(binding);
	return median(times, repeats);
}

/* The add-on's Auto Weights blends over this many times the flesh's thickness (its Blend Width default). */
#define ADDON_BLEND_WIDTH 0.9

/* How the weights are made: the core's defaults (the paper's weights), or what the add-on's Auto Weights asks
 * with its Visibility Test, Exact, and Method: Distance (falloff 16 by distance alone, not by the bones'
 * lengths, measured along the skin's normal, 4 influences of at least 1 %, smoothed over ADDON_BLEND_WIDTH
 * times the flesh's thickness: lvp.h, SMOOTHING BY THICKNESS) or its default Method: Bone Heat (lvp.h, HEAT). */
typedef enum { PAPER, DISTANCE, HEAT } weights_method;

static double auto_weights_time(const test_rig *rig, lvp_visibility visibility, weights_method method)
{
	double blend = method == DISTANCE ? ADDON_BLEND_WIDTH : 0.0;
	lvp_auto_weights_options options = lvp_auto_weights_default_options();
	options.visibility = visibility;
	options.heat = method == HEAT;
	if (method != PAPER) {
		options.alpha = 16.0f;
		options.by_length = 0;
		options.facing = 1;
		options.max_influences = 4;
		options.min_weight = 0.01f;
		options.smoothing_thickness = (float)blend;
	}
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	int64_t capacity = lvp_auto_weights_bound(rig->vertex_count, rig->bone_count, &options);
	int32_t *offsets = malloc(sizeof(int32_t) * ((size_t)rig->vertex_count + 1));
	int32_t *bones = malloc(sizeof(int32_t) * (size_t)capacity);
	float *values = malloc(sizeof(float) * (size_t)capacity);
	lvp_diagnostic diag;
	double start = now();
	lvp_result result = lvp_auto_weights(offsets, bones, values, capacity, rig->positions, rig->vertex_count,
	                                     rig->triangles, rig->triangle_count, &skeleton, &options, &diag);
	double elapsed = now() - start;
	if (result != lvp_success)
		fprintf(stderr, "auto weights failed: %s\n", diag.message);
	free(offsets);
	free(bones);
	free(values);
	return elapsed;
}

/* `bench_core TEXT` runs only the cases whose mesh or pose names contain TEXT (a profile of one). */
static const char *only_cases;

static void run_case(bench_case *c, int32_t cores)
{
	if (only_cases && !strstr(c->name, only_cases) && !strstr(c->pose, only_cases))
		return;
	test_rig *rig = &c->rig;
	int32_t n = rig->vertex_count, b = rig->bone_count;
	float *posed[POSES], *skinned[POSES];
	pose_animation(rig, c->rotations, c->stretch, posed, skinned);
	lvp_frame_stats stats;
	double bind1, bind_all;
	double one = frame_time(c, 1, skinned, posed, &stats, &bind1);
	double all = frame_time(c, cores, skinned, posed, &stats, &bind_all);
	double normal = auto_weights_time(rig, LVP_VISIBILITY_NORMAL, PAPER);
	double heat = auto_weights_time(rig, LVP_VISIBILITY_EXACT, HEAT); /* the add-on's defaults */
	double smoothed = auto_weights_time(rig, LVP_VISIBILITY_EXACT, DISTANCE);
	double exact = n <= 200000 ? auto_weights_time(rig, LVP_VISIBILITY_EXACT, PAPER) : NAN;
	double before = 100.0 * (stats.volume_before - stats.volume_rest) / stats.volume_rest;
	double after = 100.0 * (stats.volume_after - stats.volume_rest) / stats.volume_rest;
	char exact_text[32] = "-";
	if (!isnan(exact))
		snprintf(exact_text, sizeof(exact_text), "%.0f", 1e3 * exact);
	printf("| %s | %d | %d | %s | %.0f | %.0f | %.0f | %s | %.0f | %.2f | %.2f | %.2f | %.2f%% -> %.4f%% (%d steps) |\n",
	       c->name, (int)n, (int)b, c->pose, 1e3 * normal, 1e3 * heat, 1e3 * smoothed, exact_text, 1e3 * bind1,
	       1e3 * one, 1e3 * all,
	       one / all, before, after, (int)stats.iterations);
	fflush(stdout);
	for (int pose = 0; pose < POSES; ++pose) {
		free(posed[pose]);
		free(skinned[pose]);
	}
}

int main(int argc, char **argv)
{
	only_cases = argc > 1 ? argv[1] : NULL;
	int32_t cores = (int32_t)sysconf(_SC_NPROCESSORS_ONLN);
	cores = cores < 1 ? 1 : (cores > LVP_MAX_THREADS ? LVP_MAX_THREADS : cores);
	printf("Core benchmark: median wall time per frame of an animation through %d poses (default options: organic "
	       "map, up to 8 steps, tolerance 1e-4), %d cores.\n\n",
	       POSES,
	       (int)cores);
	printf("| mesh | vertices | bones | bent | automatic weights, normal test (ms) | the add-on's Auto Weights, "
	       "Bone Heat (ms) | Auto Weights, Distance (falloff 16, blended over 0.9 times the flesh's thickness; ms) "
	       "| automatic weights, exact test (ms) "
	       "| bind (ms) | frame, 1 thread (ms) | frame, %d threads (ms) | speed-up | volume error |\n",
	       (int)cores);
	printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");

	struct {
		const char *name;
		int bones, around, rings;
	} chains[3] = {{"chain 5k", 8, 32, 20}, {"chain 100k", 32, 64, 50}, {"chain 1M", 64, 128, 122}};
	for (int i = 0; i < 3; ++i) {
		for (int all = 1; all >= 0; --all) {
			bench_case c = {0};
			c.name = chains[i].name;
			c.rig = test_make_chain(chains[i].bones, 1.0f, 0.3f, chains[i].around, chains[i].rings, 0.5f);
			c.pose = all ? "every joint" : "one joint";
			c.rotations = chain_pose(c.rig.bone_count, all, 40.0);
			c.stretch = 1.0f;
			c.bulge_width = 0.0f;
			run_case(&c, cores);
			if (i == 1) { /* the add-on's default: one multiplier for the whole mesh (lvp.h, RESTORE) */
				c.pose = all ? "every joint, whole mesh" : "one joint, whole mesh";
				c.restore = LVP_RESTORE_WHOLE_MESH;
				run_case(&c, cores);
				c.pose = all ? "every joint, whole mesh, kept apart" : "one joint, whole mesh, kept apart";
				c.keep_apart = 1; /* lvp.h, CONTACT */
				run_case(&c, cores);
				c.keep_apart = 0;
				c.pose = all ? "every joint, whole mesh, smoothed" : "one joint, whole mesh, smoothed";
				c.smoothing = ADDON_SMOOTHING_PASSES; /* lvp.h, OFFSET SMOOTHING */
				run_case(&c, cores);
				c.smoothing = 0;
				c.restore = LVP_RESTORE_EACH_REGION;
				c.pose = all ? "every joint" : "one joint";
			}
			if (i == 1 && !all) { /* fold-over's contacts at a joint bent until the skin crosses */
				free(c.rotations);
				c.rotations = chain_pose(c.rig.bone_count, 0, 100.0);
				c.pose = "one joint 100 degrees";
				run_case(&c, cores);
				c.pose = "one joint 100 degrees, fold-over";
				c.fold_over = 1;
				run_case(&c, cores);
				c.fold_over = 0;
			}
			if (i == 1 && all) { /* the cost of bones scaled against each other (lvp.h, ALGORITHM 5) */
				c.pose = "every joint, every other bone x1.2";
				c.stretch = 1.2f;
				run_case(&c, cores);
				c.pose = "every joint, bulge width 1"; /* the add-on's default (lvp.h, BULGE WIDTH) */
				c.stretch = 1.0f;
				c.bulge_width = 1.0f;
				run_case(&c, cores);
				c.pose = "every joint, bulge width 1, whole mesh"; /* the add-on's defaults */
				c.restore = LVP_RESTORE_WHOLE_MESH;
				run_case(&c, cores);
				c.pose = "every joint, bulge width 1, whole mesh, kept apart"; /* with Keep Skin Apart */
				c.keep_apart = 1;
				run_case(&c, cores);
				c.keep_apart = 0;
				c.pose = "every joint, bulge width 1, whole mesh, smoothed"; /* the add-on's viewport */
				c.smoothing = ADDON_SMOOTHING_PASSES;
				run_case(&c, cores);
				c.smoothing = 0;
				c.restore = LVP_RESTORE_EACH_REGION;
			}
			free(c.rotations);
			test_rig_free(&c.rig);
		}
	}
	/* A low-polygon tail: many short regions, each bent a little, where the regions' estimates add up
	 * to more than the mesh's true change (lvp.h, ALGORITHM 5); and a long one, whose 500 regions
	 * bend at once (the region system stored by its profile: lvp.h, PERFORMANCE). */
	struct {
		const char *name;
		int bones;
	} tails[2] = {{"tail 4k", 64}, {"tail 32k", 500}};
	for (int i = 0; i < 2; ++i) {
		bench_case tail = {0};
		tail.name = tails[i].name;
		tail.rig = test_make_chain(tails[i].bones, 1.0f, 0.3f, 16, 4, 0.5f);
		tail.pose = "every joint, 5 degrees";
		tail.rotations = chain_pose(tail.rig.bone_count, 1, 5.0);
		tail.stretch = 1.0f;
		tail.bulge_width = 0.0f;
		run_case(&tail, cores);
		free(tail.rotations);
		test_rig_free(&tail.rig);
	}
	test_rig giraffe;
	if (test_load_giraffe(&giraffe, "data/giraffe") != 0) {
		fprintf(stderr, "cannot load data/giraffe (run from tests/)\n");
		return 1;
	}
	const int levels[3] = {0, 3, 5};
	const char *names[3] = {"giraffe", "giraffe x64", "giraffe x1024"};
	for (int i = 0; i < 3; ++i) {
		bench_case c = {0};
		c.name = names[i];
		c.rig = levels[i] ? test_subdivide(&giraffe, levels[i]) : giraffe;
		c.pose = "neck, 2 legs";
		c.rotations = giraffe_pose(&c.rig);
		c.stretch = 1.0f;
		c.bulge_width = 0.0f;
		run_case(&c, cores);
		if (i == 1) {
			c.pose = "neck, 2 legs, bulge width 1";
			c.bulge_width = 1.0f;
			run_case(&c, cores);
		}
		free(c.rotations);
		if (levels[i])
			test_rig_free(&c.rig);
	}
	/* The same giraffe as imported from glTF: split at seams, welded by lvp_bind (lvp.h, SEAMS). */
	bench_case split = {0};
	test_rig subdivided = test_subdivide(&giraffe, 3);
	int32_t *original;
	split.name = "giraffe x64, split at seams";
	split.rig = test_split_at_seams(&subdivided, &original);
	split.pose = "neck, 2 legs";
	split.rotations = giraffe_pose(&split.rig);
	split.stretch = 1.0f;
	split.bulge_width = 0.0f;
	run_case(&split, cores);
	free(split.rotations);
	free(original);
	test_rig_free(&split.rig);
	test_rig_free(&subdivided);
	test_rig_free(&giraffe);
	return 0;
}
