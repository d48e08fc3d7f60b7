/*
 * bind_rig.h - a test rig bound by the core; a failure is counted by the test that includes it (check.h).
 */
#ifndef LVP_TEST_BIND_RIG_H
#define LVP_TEST_BIND_RIG_H

#include "lvp.h"
#include "support/check.h"
#include "support/test_meshes.h"

/* The rig bound with options (NULL: the defaults); NULL, reported, when that fails. */
static inline lvp_binding *test_bind_rig(const test_rig *rig, const lvp_bind_options *options)
{
	lvp_weights weights = test_rig_weights(rig);
	lvp_skeleton skeleton = test_rig_skeleton(rig);
	lvp_binding *binding = NULL;
	lvp_diagnostic diag;
	CHECK_OK(lvp_bind(&binding, rig->positions, rig->vertex_count, rig->triangles, rig->triangle_count, &weights,
	                  &skeleton, options, &diag),
	         diag);
	return binding;
}

#endif
