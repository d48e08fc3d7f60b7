/*
 * test_degrading.c - degrading locally (lvp.h, DEGRADING): a chain of four bones with one joint
 * folded onto itself (180 degrees) and another bent 60 degrees. The folded joint cannot be
 * corrected: without a displacement limit its correction blows the skin out and the whole frame
 * would have to be thrown away; with one, its regions keep the skinning, the other joint is
 * corrected as if alone, and the stats say which region was given up and why.
 */
#include "lvp.h"
#include "support/bind_rig.h"
#include "support/check.h"
#include "support/test_meshes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PI 3.14159265358979323846

/* The chain bent by `folded` degrees at its second bone's head and by 60 at its fourth's. */
static test_posed_rig make_chain(double folded, double other)
{
	test_posed_rig c;
	float rotations[16] = {0};
	rotations[4] = 1.0f;
	rotations[7] = (float)(folded * PI / 180.0);
	rotations[12] = 1.0f;
	rotations[15] = (float)(other * PI / 180.0);
	CHECK(test_pose_rig(test_make_chain(4, 1.0f, 0.3f, 24, 12, 0.3f), rotations, &c) == 0);
	return c;
}

/* Corrects the chain with the given limit; r_relative: each region's change / reference after. */
static lvp_frame_stats correct(const test_posed_rig *c, lvp_binding *binding, float limit, float *r_out,
                               double r_relative[4])
{
	lvp_frame_options options = lvp_frame_default_options();
	options.displacement_limit = limit;
	lvp_frame_stats stats;
	lvp_diagnostic diag;
	CHECK_OK(lvp_correct(r_out, NULL, binding, c->skinned, c->posed, NULL, &options, &stats, &diag), diag);
	double changes[4], references[4];
	CHECK_OK(lvp_region_volume_changes(changes, references, binding, r_out, c->posed, NULL, &diag), diag);
	for (int i = 0; i < 4; ++i)
		r_relative[i] = changes[i] / references[i];
	return stats;
}

static void test_a_folded_joint_keeps_the_skinning_and_the_rest_is_corrected(void)
{
	test_posed_rig folded = make_chain(180.0, 60.0), alone = make_chain(0.0, 60.0);
	int32_t n = folded.rig.vertex_count;
	lvp_binding *binding = test_bind_rig(&folded.rig, NULL);
	float *out = malloc(sizeof(float) * 3 * (size_t)n);
	const float limit = 1.0f; /* a quarter of the chain's length, as the add-on sets it */
	double plain[4], without[4], with[4], only[4];
	lvp_diagnostic diag;
	double changes[4], references[4];
	CHECK_OK(lvp_region_volume_changes(changes, references, binding, folded.skinned, folded.posed, NULL, &diag), diag);
	for (int i = 0; i < 4; ++i)
		plain[i] = changes[i] / references[i];
	lvp_frame_stats blown = correct(&folded, binding, 0.0f, out, without);
	lvp_frame_stats local = correct(&folded, binding, limit, out, with);
	lvp_frame_stats reference = correct(&alone, binding, limit, out, only);
	printf("  region change (%%)          |  0 (folded) |  1 (folded) |  2 (60 deg) |  3 (60 deg) | largest offset\n");
	printf("  plain skinning             | %+11.3f | %+11.3f | %+11.3f | %+11.3f |\n", 100 * plain[0], 100 * plain[1],
	       100 * plain[2], 100 * plain[3]);
	printf("  no limit                   | %+11.3f | %+11.3f | %+11.3f | %+11.3f | %.3f\n", 100 * without[0],
	       100 * without[1], 100 * without[2], 100 * without[3], blown.max_displacement);
	printf("  limit %.1f                  | %+11.3f | %+11.3f | %+11.3f | %+11.3f | %.3f (%d given up, first %d)\n",
	       (double)limit, 100 * with[0], 100 * with[1], 100 * with[2], 100 * with[3], local.max_displacement,
	       (int)local.given_up_regions, (int)local.given_up_region);
	printf("  the 60 degree joint alone  |             |             | %+11.3f | %+11.3f | %.3f\n", 100 * only[2],
	       100 * only[3], reference.max_displacement);
	/* Without the limit, the folded joint blows the skin out beyond it. */
	CHECK(blown.max_displacement > limit);
	CHECK(blown.given_up_regions == 0 && blown.given_up_region == -1);
	/* With it: the folded joint's groups are given up, first for moving skin too far. */
	CHECK(local.given_up_regions >= 1 && local.given_up_regions <= LVP_MAX_GIVEN_UP);
	CHECK(local.given_up_region == 0 || local.given_up_region == 1);
	CHECK(local.given_up_diverged == 1);
	CHECK(local.passed_through == 0);
	CHECK(local.max_displacement <= limit);
	/* The other joint is corrected, its regions within 0.05 % of their volume. */
	CHECK(fabs(with[2]) < 5e-4 && fabs(with[3]) < 5e-4);
	/* The folded joint keeps the skinning's loss, not made worse. */
	for (int i = 0; i < 2; ++i)
		CHECK(fabs(with[i]) <= fabs(plain[i]) + 1e-3);
	/* A pose that needs no giving up is corrected as without the limit. */
	CHECK(reference.given_up_regions == 0);
	float *unlimited = malloc(sizeof(float) * 3 * (size_t)n);
	double ignored[4];
	correct(&alone, binding, 0.0f, unlimited, ignored);
	CHECK(memcmp(out, unlimited, sizeof(float) * 3 * (size_t)n) == 0);
	free(unlimited);
	free(out);
	lvp_free(binding);
	test_posed_rig_free(&folded);
	test_posed_rig_free(&alone);
}

static void test_the_limit_is_checked(void)
{
	test_posed_rig c = make_chain(30.0, 30.0);
	lvp_binding *binding = test_bind_rig(&c.rig, NULL);
	float *out = malloc(sizeof(float) * 3 * (size_t)c.rig.vertex_count);
	const float bad[2] = {-1.0f, NAN};
	for (int i = 0; i < 2; ++i) {
		lvp_frame_options options = lvp_frame_default_options();
		options.displacement_limit = bad[i];
		lvp_diagnostic diag;
		CHECK(lvp_correct(out, NULL, binding, c.skinned, c.posed, NULL, &options, NULL, &diag) ==
		      lvp_error_invalid_option);
		CHECK(strcmp(diag.argument, "options.displacement_limit") == 0);
	}
	free(out);
	lvp_free(binding);
	test_posed_rig_free(&c);
}

int main(void)
{
	RUN(test_a_folded_joint_keeps_the_skinning_and_the_rest_is_corrected);
	RUN(test_the_limit_is_checked);
	return check_failures() != 0;
}
