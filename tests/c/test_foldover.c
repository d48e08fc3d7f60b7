/*
 * test_foldover.c - paper 5.4 on a finger of three phalanges bent until plain skinning makes
 * the skin cross itself on the inside of the knuckles. After fold-over prevention no pair of
 * skin triangles may intersect (counted exactly, in rational arithmetic), and the volume is
 * still restored.
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846
#define FINGER_RADIUS 0.22 /* test_make_finger() */

typedef struct bent_finger {
	test_rig rig;
	float posed[48];
	float *skinned;
} bent_finger;

/* The finger rig bent by `first` degrees at the first knuckle and `second` at the second. */
static bent_finger pose_finger(test_rig rig, double first, double second)
{
	bent_finger f;
	f.rig = rig;
	float rotations[12] = {0, 0, 0, 0, 1, 0, 0, (float)(first * PI / 180), 1, 0, 0, (float)(second * PI / 180)};
	float skin[48];
	test_pose(f.posed, &f.rig, rotations);
	test_skin_matrices(skin, &f.rig, f.posed);
	f.skinned = malloc(sizeof(float) * 3 * (size_t)f.rig.vertex_count);
	lvp_weights weights = test_rig_weights(&f.rig);
	lvp_diagnostic diag;
	CHECK_OK(lvp_skin_linear(f.skinned, f.rig.positions, f.rig.vertex_count, &weights, skin, 3, &diag), diag);
	return f;
}

/* test_make_finger() bent by `first` degrees at the first knuckle and `second` at the second. */
static bent_finger make_finger_pose(double first, double second)
{
	return pose_finger(test_make_finger(), first, second);
}

static bent_finger make_bent_finger(double degrees)
{
	return make_finger_pose(degrees, degrees);
}

/* The largest distance between a and b over the vertices whose rest position is within 0.3 of
 * the knuckle at y = knuckle along the finger and whose rest z is in [z_min, z_max]; *r_count
 * receives how many there are. */
static double largest_difference(const test_rig *rig, const float *a, const float *b, double knuckle, double z_min,
                                 double z_max, int32_t *r_count)
{
	double largest = 0.0;
	*r_count = 0;
	for (int32_t k = 0; k < rig->vertex_count; ++k) {
		const float *rest = rig->positions + 3 * k;
		if (!(fabs(rest[1] - knuckle) < 0.3) || rest[2] < z_min || rest[2] > z_max)
			continue;
		++*r_count;
		double d2 = 0.0;
		for (int c = 0; c < 3; ++c)
			d2 += (double)(a[3 * k + c] - b[3 * k + c]) * (a[3 * k + c] - b[3 * k + c]);
		largest = fmax(largest, sqrt(d2));
	}
	return largest;
}

/* Corrects the finger's pose with and without fold-over prevention (r_volume_only, r_folded:
 * vertex_count * 3 each, allocated here). Returns the vertices fold-over moved. */
static int32_t correct_both_ways(bent_finger *f, float **r_volume_only, float **r_folded)
{
	int32_t n = f->rig.vertex_count;
	lvp_binding *binding = test_bind_rig(&f->rig, NULL);
	lvp_diagnostic diag;
	*r_volume_only = malloc(sizeof(float) * 3 * (size_t)n);
	*r_folded = malloc(sizeof(float) * 3 * (size_t)n);
	lvp_frame_options options = lvp_frame_default_options();
	lvp_frame_stats stats;
	memset(&stats, 0, sizeof(stats));
	CHECK_OK(lvp_correct(*r_volume_only, NULL, binding, f->skinned, f->posed, NULL, &options, NULL, &diag), diag);
	options.fold_over = 1;
	CHECK_OK(lvp_correct(*r_folded, NULL, binding, f->skinned, f->posed, NULL, &options, &stats, &diag), diag);
	lvp_free(binding);
	return stats.folded_vertices;
}

static void free_finger(bent_finger *f)
{
	test_rig_free(&f->rig);
	free(f->skinned);
}

static void test_fold_over_removes_self_intersections(void)
{
	/* Plain skinning crosses itself from about 50 degrees; asserted up to 110 degrees, printed
	 * beyond (past 110 the tip crosses the first phalanx, bones that are not neighbours: a
	 * limitation stated in lvp.h and README). Pressed exactly onto the contact plane, the crease
	 * itself folded past 90 degrees (4 pairs at 110); pressed softly it does not. */
	const double angles[] = {60, 70, 80, 90, 95, 100, 110, 120};
	printf("  finger, both knuckles bent; intersecting triangle pairs and volume error:\n");
	printf("  angle | plain SSD        | volume only      | volume + fold-over (moved vertices)\n");
	for (size_t i = 0; i < sizeof(angles) / sizeof(angles[0]); ++i) {
		bent_finger f = make_bent_finger(angles[i]);
		int32_t n = f.rig.vertex_count;
		lvp_binding *binding = test_bind_rig(&f.rig, NULL);
		lvp_diagnostic diag;
		if (!binding)
			continue;
		float *plain_volume = malloc(sizeof(float) * 3 * (size_t)n), *folded = malloc(sizeof(float) * 3 * (size_t)n);
		lvp_frame_options options = lvp_frame_default_options();
		lvp_frame_stats volume_stats, fold_stats;
		CHECK_OK(lvp_correct(plain_volume, NULL, binding, f.skinned, f.posed, NULL, &options, &volume_stats, &diag),
		         diag);
		options.fold_over = 1;
		CHECK_OK(lvp_correct(folded, NULL, binding, f.skinned, f.posed, NULL, &options, &fold_stats, &diag), diag);
		int64_t before = test_count_intersecting_pairs(f.skinned, f.rig.triangles, f.rig.triangle_count);
		int64_t volume_only = test_count_intersecting_pairs(plain_volume, f.rig.triangles, f.rig.triangle_count);
		int64_t after = test_count_intersecting_pairs(folded, f.rig.triangles, f.rig.triangle_count);
		double rest = fold_stats.volume_rest;
		printf("  %4.0f  | %4lld, %+7.2f%% | %4lld, %+7.3f%% | %4lld, %+7.3f%% (%d)\n", angles[i], (long long)before,
		       100 * (fold_stats.volume_before - rest) / rest, (long long)volume_only,
		       100 * (volume_stats.volume_after - rest) / rest, (long long)after,
		       100 * (fold_stats.volume_after - rest) / rest, (int)fold_stats.folded_vertices);
		if (angles[i] <= 110) {
			CHECK(before > 0); /* the finger does fold through itself */
			CHECK(after == 0);
			CHECK(fold_stats.folded_vertices > 0);
			CHECK(fabs(fold_stats.volume_after - rest) < 0.001 * rest);
		}
		free(plain_volume);
		free(folded);
		lvp_free(binding);
		test_rig_free(&f.rig);
		free(f.skinned);
	}
}

/* Fold-over prevention changes the skin where it folds, the concave side of the bend, and not its
 * flanks: there the flesh is not pressed against anything, and holding it would leave a ridge
 * between held and bulging skin. On the knuckles' flanks (rest |z| <= 0.1: the bend is about x),
 * the result with fold-over prevention stays within a tenth of the finger's radius of the result
 * without. */
static void test_fold_over_keeps_the_flanks(void)
{
	const double angles[] = {75, 90, 100};
	for (size_t i = 0; i < sizeof(angles) / sizeof(angles[0]); ++i) {
		bent_finger f = make_bent_finger(angles[i]);
		float *volume_only, *folded;
		CHECK(correct_both_ways(&f, &volume_only, &folded) > 0);
		int32_t first_count, second_count;
		double first = largest_difference(&f.rig, folded, volume_only, 1.0, -0.1, 0.1, &first_count);
		double second = largest_difference(&f.rig, folded, volume_only, 1.7, -0.1, 0.1, &second_count);
		printf("  %3.0f degrees: fold-over moves the knuckles' flanks by at most %.4f and %.4f (radius %.2f)\n",
		       angles[i], first, second, FINGER_RADIUS);
		CHECK(first_count > 0 && second_count > 0);
		CHECK(first < 0.1 * FINGER_RADIUS && second < 0.1 * FINGER_RADIUS);
		free(volume_only);
		free(folded);
		free_finger(&f);
	}
}

/* A knuckle bent without contact keeps its volume correction as it is when another one folds:
 * the second knuckle bent 40 degrees (plain skinning does not cross itself there below about
 * 50), the first 90. Around the second knuckle, on the concave side where a fade would hold the
 * skin, the result with fold-over prevention stays within a twentieth of the radius of the
 * result without. */
static void test_fold_over_leaves_joints_without_contact(void)
{
	bent_finger f = make_finger_pose(90, 40);
	float *volume_only, *folded;
	CHECK(correct_both_ways(&f, &volume_only, &folded) > 0);
	int32_t count;
	double largest = largest_difference(&f.rig, folded, volume_only, 1.7, 0.0, 1.0, &count);
	printf("  first knuckle 90, second 40 degrees: fold-over moves the second's concave side by at most %.4f\n",
	       largest);
	CHECK(count > 0);
	CHECK(largest < 0.05 * FINGER_RADIUS);
	free(volume_only);
	free(folded);
	free_finger(&f);
}

/* At rest and under a rigid motion, fold-over prevention moves nothing. */
static void test_fold_over_idle_without_bend(void)
{
	bent_finger f = make_bent_finger(0);
	int32_t n = f.rig.vertex_count;
	lvp_binding *binding = test_bind_rig(&f.rig, NULL);
	lvp_diagnostic diag;
	float *offsets = malloc(sizeof(float) * 3 * (size_t)n);
	lvp_frame_options options = lvp_frame_default_options();
	options.fold_over = 1;
	lvp_frame_stats stats;
	CHECK_OK(lvp_correct(NULL, offsets, binding, f.skinned, f.posed, NULL, &options, &stats, &diag), diag);
	CHECK(stats.folded_vertices == 0);
	for (int32_t i = 0; i < 3 * n; ++i)
		CHECK(offsets[i] == 0.0f);
	free(offsets);
	lvp_free(binding);
	test_rig_free(&f.rig);
	free(f.skinned);
}

/* The largest roughness of the offsets result - skinned (per vertex: its offset minus the mean
 * of its edge neighbours' offsets), over the largest offset: a smooth bulge stays far below 1, a
 * step in the skin comes close to it (QUALITY.md). */
static double offset_roughness(const test_rig *rig, const float *skinned, const float *result)
{
	int32_t n = rig->vertex_count;
	double *sum = calloc((size_t)n * 3, sizeof(double));
	int32_t *count = calloc((size_t)n, sizeof(int32_t));
	for (int32_t t = 0; t < rig->triangle_count; ++t)
		for (int e = 0; e < 3; ++e) { /* each edge twice over the closed surface: once each way */
			int32_t a = rig->triangles[3 * t + e], b = rig->triangles[3 * t + (e + 1) % 3];
			for (int c = 0; c < 3; ++c)
				sum[3 * a + c] += result[3 * b + c] - skinned[3 * b + c];
			++count[a];
		}
	double rough = 0.0, largest = 0.0;
	for (int32_t k = 0; k < n; ++k) {
		double d2 = 0.0, o2 = 0.0;
		for (int c = 0; c < 3; ++c) {
			double offset = (double)result[3 * k + c] - skinned[3 * k + c];
			double off_mean = offset - (count[k] ? sum[3 * k + c] / count[k] : 0.0);
			d2 += off_mean * off_mean;
			o2 += offset * offset;
		}
		rough = fmax(rough, sqrt(d2));
		largest = fmax(largest, sqrt(o2));
	}
	free(sum);
	free(count);
	return largest > 0.0 ? rough / largest : 0.0;
}

/* Fold-over's contact plane goes through the crease, where the skins of the two bones meet, not
 * through the bone's head: with the weights blending short of the knuckles (as heat weights put
 * them where a finger meets the palm), bent 45 degrees (plain skinning does not cross itself yet),
 * the result with fold-over prevention is as smooth as without. With the plane through the head
 * the part of a phalanx's skin beyond it at rest was never pressed and the part just short of it
 * was: a step in the skin, roughness 0.60 of the largest offset against 0.39 at 0.1 short. The
 * plane moves at most half the flesh radius (0.11 here, lvp.h): at 0.15 short it stops before the
 * crease, printed, not asserted. */
static void test_fold_over_follows_the_crease(void)
{
	const double shifts[] = {0.0, 0.1, 0.15};
	for (size_t i = 0; i < sizeof(shifts) / sizeof(shifts[0]); ++i) {
		test_rig rig = test_make_finger();
		test_shift_finger_bands(&rig, shifts[i]);
		bent_finger f = pose_finger(rig, 45, 45);
		float *volume_only, *folded;
		int32_t moved = correct_both_ways(&f, &volume_only, &folded);
		double plain_pairs = (double)test_count_intersecting_pairs(f.skinned, f.rig.triangles, f.rig.triangle_count);
		double rough_volume = offset_roughness(&f.rig, f.skinned, volume_only);
		double rough_folded = offset_roughness(&f.rig, f.skinned, folded);
		printf("  bands %.2f short of the knuckles, 45 degrees: plain skinning %0.f crossing pairs; roughness over "
		       "the largest offset %.3f without fold-over, %.3f with (%d vertices moved)\n",
		       shifts[i], plain_pairs, rough_volume, rough_folded, (int)moved);
		CHECK(plain_pairs == 0.0);
		if (shifts[i] <= 0.5 * FINGER_RADIUS)
			CHECK(rough_folded <= 1.05 * rough_volume);
		free(volume_only);
		free(folded);
		free_finger(&f);
	}
}

/* Intersecting pairs of triangles and the volume, a limb of two B-Bones folded 150 degrees, corrected with
 * fold-over as the add-on does (whole mesh, Smoothing 6), its joints passed as one group per B-Bone or as
 * bones alone; the corrected positions into r_corrected when it is not NULL. */
static void fold_limb_into(float *r_corrected, const test_rig *rig, const float *posed, const float *skinned,
                           const int32_t *groups, int64_t *r_pairs, double *r_volume_error)
{
	lvp_bind_options bind_options = lvp_bind_default_options();
	bind_options.bone_groups = groups;
	lvp_binding *binding = test_bind_rig(rig, &bind_options);
	*r_pairs = -1;
	*r_volume_error = INFINITY;
	if (!binding)
		return;
	float *corrected = malloc(sizeof(float) * 3 * (size_t)rig->vertex_count);
	lvp_frame_options options = lvp_frame_default_options();
	options.fold_over = 1;
	options.restore = LVP_RESTORE_WHOLE_MESH;
	options.smoothing_passes = 6;
	lvp_frame_stats stats;
	lvp_diagnostic diag;
	CHECK_OK(lvp_correct(corrected, NULL, binding, skinned, posed, NULL, &options, &stats, &diag), diag);
	*r_pairs = test_count_intersecting_pairs(corrected, rig->triangles, rig->triangle_count);
	*r_volume_error = (stats.volume_after - stats.volume_rest) / stats.volume_rest;
	if (r_corrected)
		memcpy(r_corrected, corrected, sizeof(float) * 3 * (size_t)rig->vertex_count);
	free(corrected);
	lvp_free(binding);
}

static void fold_limb(const test_rig *rig, const float *posed, const float *skinned, const int32_t *groups,
                      int64_t *r_pairs, double *r_volume_error)
{
	fold_limb_into(NULL, rig, posed, skinned, groups, r_pairs, r_volume_error);
}

/* Rigify's limbs are B-Bones, whose joints the add-on passes as bones of one group (lvp.h, GROUPS): here a
 * chain of eight joints, the first four one B-Bone and the last four another, folded 150 degrees where the
 * second begins. The second's skin lies on the first's from the joint to three joints along, skin of regions
 * that border no region of the other side; each side of the joint is its B-Bone's skin, pressed as one
 * (foldover.c, lvp__find_side_entries): at most an eighth of plain skinning's crossing pairs are left (none of
 * 174 since the pressed skin relaxes into skin of no map, lvp__relax_pressed; 18 before, at the edge of the
 * pressed skin), and the volume is within half a percent (-0.005 %; -0.13 %
 * before: the frame keeps its contacts with a little volume missing, lvp.h FOLD-OVER). As bones alone, fold-over
 * presses only the two regions at the joint (143 pairs, 212 before; printed). */
static void test_fold_over_presses_a_b_bone_whole(void)
{
	test_rig rig = test_make_chain(8, 0.25f, 0.2f, 24, 6, 0.5f);
	float rotations[8 * 4] = {0};
	rotations[4 * 4 + 0] = 1.0f;
	rotations[4 * 4 + 3] = (float)(150.0 * PI / 180.0);
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	int32_t groups[8] = {0, 0, 0, 0, 1, 1, 1, 1}, alone[8] = {0, 1, 2, 3, 4, 5, 6, 7};
	int64_t plain = test_count_intersecting_pairs(skinned, rig.triangles, rig.triangle_count), grouped_pairs,
	        alone_pairs;
	double grouped_error, alone_error;
	fold_limb(&rig, posed, skinned, groups, &grouped_pairs, &grouped_error);
	fold_limb(&rig, posed, skinned, alone, &alone_pairs, &alone_error);
	printf("  150 degrees: plain skinning %lld intersecting pairs; fold-over %lld (volume %+.4f%%) with the joints "
	       "as two B-Bones, %lld (%+.4f%%) as bones alone\n",
	       (long long)plain, (long long)grouped_pairs, 100 * grouped_error, (long long)alone_pairs,
	       100 * alone_error);
	CHECK(plain > 100); /* the fold passes skin through skin well past the joint's regions */
	CHECK(grouped_pairs >= 0 && 8 * grouped_pairs <= plain);
	CHECK(fabs(grouped_error) < 5e-3);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

/* The add-on passes a B-Bone as one bone per joint of its segments, all with the bone's head and tail (lvp.h,
 * BONE LINES), and which joint a vertex near the bone's head is skin of is the heat weights' choice: at the back
 * of a Rigify knee, three of the shin's joints border the thigh's skin. Here the chain of
 * test_fold_over_presses_a_b_bone_whole as two such B-Bones, folded 150 degrees at the second's head, where
 * the second's joints all move alike: the inside of the bend near the joint given to its second joint instead
 * of its first skins exactly the same, and must be pressed the same: every joint of a B-Bone that borders the
 * other side makes the same plane, and the side is pressed once, not once per joint. Printed: the largest
 * difference of the two corrections against the largest offset. */
static void test_fold_over_presses_a_b_bone_side_once(void)
{
	test_rig rig = test_make_chain(8, 0.25f, 0.2f, 24, 6, 0.5f);
	for (int b = 0; b < 8; ++b) {
		int first = b < 4 ? 0 : 4;
		for (int i = 0; i < 3; ++i) {
			rig.heads[3 * b + i] = rig.heads[3 * first + i];
			rig.tails[3 * b + i] = rig.tails[3 * (first + 3) + i];
		}
	}
	float rotations[8 * 4] = {0};
	rotations[4 * 4 + 0] = 1.0f;
	rotations[4 * 4 + 3] = (float)(150.0 * PI / 180.0);
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	int32_t groups[8] = {0, 0, 0, 0, 1, 1, 1, 1};
	size_t size = sizeof(float) * 3 * (size_t)rig.vertex_count;
	float *whole = malloc(size), *split = malloc(size);
	int64_t whole_pairs, split_pairs;
	double whole_error, split_error;
	fold_limb_into(whole, &rig, posed, skinned, groups, &whole_pairs, &whole_error);
	/* The second B-Bone bends at its head (z = 1), towards -y: the inside of the bend, short of its second joint's
	 * band, goes to that joint. */
	int32_t moved = 0;
	for (int32_t k = 0; k < rig.vertex_count; ++k) {
		const float *p = rig.positions + 3 * k;
		if (!(p[1] < 0.0f && p[2] < 1.125f))
			continue;
		for (int32_t w = rig.weight_offsets[k]; w < rig.weight_offsets[k + 1]; ++w)
			if (rig.weight_bones[w] == 4) {
				rig.weight_bones[w] = 5;
				++moved;
			}
	}
	fold_limb_into(split, &rig, posed, skinned, groups, &split_pairs, &split_error);
	double largest = test_largest_distance(whole, skinned, rig.vertex_count);
	double differ = test_largest_distance(whole, split, rig.vertex_count);
	printf("  150 degrees, %d weights moved to the second joint: corrections differ by %.3f of the largest offset "
	       "(%.4f); crossing pairs %lld and %lld\n",
	       (int)moved, differ / largest, largest, (long long)whole_pairs, (long long)split_pairs);
	CHECK(moved > 20);
	CHECK(whole_pairs == 0 && split_pairs == 0);
	CHECK(differ <= 0.05 * largest);
	free(whole);
	free(split);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
}

/* What fold_twinned_cylinder measures. */
typedef struct twinned_fold {
	int32_t twins;        /* pairs of a vertex and its twin straight above it */
	double apart;         /* the twins' offsets apart at most, against the largest offset */
	int32_t turned;       /* thin triangles (a side under twice the gap) turned by more than 30 degrees against
	                         plain skinning's */
	int64_t pairs, plain; /* crossing pairs, and plain skinning's */
	double volume_error;
} twinned_fold;

/* The paper's cylinder with a twin ring `gap` of the ring spacing above every odd ring
 * (test_make_cylinder_twinned), bent 150 degrees with fold-over as the add-on does. */
static twinned_fold fold_twinned_cylinder(float gap)
{
	twinned_fold result = {0, 0.0, 0, -1, -1, INFINITY};
	test_rig rig = test_make_cylinder_twinned(16, 16, 0.5f, 4.0f, 2.6f, gap);
	float rotations[8] = {0, 0, 0, 0, 1, 0, 0, (float)(150.0 * PI / 180.0)};
	float *posed = NULL, *skinned = NULL;
	CHECK(test_pose_and_skin(&rig, rotations, &posed, &skinned) == 0);
	int32_t n = rig.vertex_count;
	float *corrected = malloc(sizeof(float) * 3 * (size_t)n);
	result.plain = test_count_intersecting_pairs(skinned, rig.triangles, rig.triangle_count);
	fold_limb_into(corrected, &rig, posed, skinned, NULL, &result.pairs, &result.volume_error);
	double largest = test_largest_distance(corrected, skinned, n), apart = 0.0;
	double spacing = 4.0 / 15.0;
	for (int32_t a = 0; a < n; ++a)
		for (int32_t b = 0; b < n; ++b) {
			const float *p = rig.positions + 3 * a, *q = rig.positions + 3 * b;
			double dz = (double)q[2] - p[2];
			if (!(fabs((double)q[0] - p[0]) < 1e-6 && fabs((double)q[1] - p[1]) < 1e-6 && dz > 0.0 &&
			      dz < 1.5 * gap * spacing))
				continue;
			++result.twins;
			double d2 = 0.0;
			for (int c = 0; c < 3; ++c) {
				double d = ((double)corrected[3 * a + c] - skinned[3 * a + c]) -
				           ((double)corrected[3 * b + c] - skinned[3 * b + c]);
				d2 += d * d;
			}
			apart = fmax(apart, sqrt(d2));
		}
	result.apart = largest > 0.0 ? apart / largest : INFINITY;
	for (int32_t t = 0; t < rig.triangle_count; ++t) {
		const int32_t *v = rig.triangles + 3 * t;
		double shortest = INFINITY;
		for (int i = 0; i < 3; ++i) {
			const float *p = rig.positions + 3 * v[i], *q = rig.positions + 3 * v[(i + 1) % 3];
			shortest = fmin(shortest, sqrt((double)(p[0] - q[0]) * (p[0] - q[0]) + (double)(p[1] - q[1]) * (p[1] - q[1]) +
			                               (double)(p[2] - q[2]) * (p[2] - q[2])));
		}
		if (!(shortest < 2.0 * gap * spacing))
			continue;
		double normal[2][3];
		const float *shapes[2] = {skinned, corrected};
		for (int s = 0; s < 2; ++s) {
			const float *x = shapes[s] + 3 * v[0], *y = shapes[s] + 3 * v[1], *z = shapes[s] + 3 * v[2];
			double e1[3] = {y[0] - x[0], y[1] - x[1], y[2] - x[2]}, e2[3] = {z[0] - x[0], z[1] - x[1], z[2] - x[2]};
			double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
			double length = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
			for (int i = 0; i < 3; ++i)
				normal[s][i] = length > 0.0 ? c[i] / length : 0.0;
		}
		double cosine = normal[0][0] * normal[1][0] + normal[0][1] * normal[1][1] + normal[0][2] * normal[1][2];
		result.turned += acos(fmax(-1.0, fmin(1.0, cosine))) * 180.0 / PI > 30.0;
	}
	printf("  gap %.2f of the spacing, %d twin pairs: offsets at most %.2g of the largest apart, %d thin triangles "
	       "turned by more than 30 degrees against plain skinning's; crossing pairs %lld (plain %lld), volume %+.4f%%\n",
	       gap, result.twins, result.apart, result.turned, (long long)result.pairs, (long long)result.plain,
	       100.0 * result.volume_error);
	free(corrected);
	free(posed);
	free(skinned);
	test_rig_free(&rig);
	return result;
}

/* What both folds of twinned cylinders must show: every twin pair found, at most an eighth of plain skinning's
 * crossing pairs left, the volume restored, the twins' offsets at most `apart_most` of the largest apart, and
 * at most 4 thin triangles turned on edge. */
static void check_twins_kept_together(twinned_fold fold, double apart_most)
{
	CHECK(fold.twins == 16 * 7);
	CHECK(fold.plain > 0 && fold.pairs >= 0 && fold.pairs <= fold.plain / 8);
	CHECK(fabs(fold.volume_error) < 0.005);
	CHECK(fold.apart < apart_most);
	CHECK(fold.turned <= 4);
}

/* A twin ring 2 % of the ring spacing above every odd ring (test_offset_smoothing.c: the twins' short edges
 * tie each pair into one point). The presses and the volume steps after them move each vertex on its own; a
 * twin pair left with offsets that differ by a share of them turns the thin triangles between the twins on
 * edge, a crease each (a metaball body's knees and elbows at 150 degrees: 49 creases where 46 were allowed).
 * After fold-over every tied pair that fold-over does not hold on its contact plane moves as one point (a held
 * pair keeps the places the press gave it): the thin triangles turned by more than 30 degrees against plain
 * skinning's 41 -> 2 (at held pairs), the pairs' offsets at most 0.11 -> 0.016 of the largest apart, the volume
 * restored, and fold-over still removes plain skinning's crossings (3 of its 96 pairs are left). */
static void test_fold_over_moves_tied_vertices_as_one(void)
{
	check_twins_kept_together(fold_twinned_cylinder(0.02f), 0.05);
}

/* The twins 15 % of the ring spacing apart: needles, whose short edges (a fifth of the ring's) the offsets'
 * smoothing does not tie. Fold-over's relaxation does (it decides its ties on weights that grow as an edge
 * shortens: offset_smoothing.c), so the pressed skin relaxes with each pair's ends together: thin triangles
 * turned by more than 30 degrees against plain skinning's 29 -> 0, the pairs' offsets at most 0.21 -> 0.04 of
 * the largest apart. Twins a fifth of the spacing apart and more are not tied by the relaxation either, and keep
 * 21-23 such triangles (25-27 before). */
static void test_relaxation_keeps_short_edges_whole(void)
{
	check_twins_kept_together(fold_twinned_cylinder(0.15f), 0.08);
}

int main(void)
{
	RUN(test_fold_over_removes_self_intersections);
	RUN(test_fold_over_keeps_the_flanks);
	RUN(test_fold_over_leaves_joints_without_contact);
	RUN(test_fold_over_idle_without_bend);
	RUN(test_fold_over_follows_the_crease);
	RUN(test_fold_over_presses_a_b_bone_whole);
	RUN(test_fold_over_presses_a_b_bone_side_once);
	RUN(test_fold_over_moves_tied_vertices_as_one);
	RUN(test_relaxation_keeps_short_edges_whole);
	return check_failures() != 0;
}
