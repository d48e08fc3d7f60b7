# SPDX-License-Identifier: GPL-3.0-or-later
"""The correction keeps the surface smooth on the real cases of real_cases.py (the measures of QUALITY.md, from
surface_quality.py), with the add-on's defaults (Smoothing 6) and Keep Skin Apart on, as renders have it: what
issue 24 asks, at every pose tested (README, Limitations, gives the numbers).

- Every pose: the volume within 0.5 % and no crossing pair that does not cross in plain skinning (Keep Skin
  Apart; counted, 240 against 240 on the human bent hard, 196 against 220 at the fist; without it
  243 against 240, 5 against 0 on the hand a little past half closed, 227 against 220 at the fist).
- A Rigify human with a closed body and heat weights, elbows, knees and hips bent hard, and bent half as far: at
  most one crease added per 300 edges and roughness at most a quarter of the largest offset (1 crease of
  13,900 edges and 0.09 bent hard; 4 and 0.14 with 2 passes of Smoothing).
- A hand closing into a fist: half closed, three quarters closed and closed, at most one crease per 300 edges and
  roughness at most a quarter of the largest offset (at the fist 29 creases of 22,400 edges, 74 allowed, and
  0.06; 54 and 0.09 with 2 passes of Smoothing; without Smoothing 123 creases and 0.14: docs/method.md,
  Smoothing the offsets).

Restoring each region on its own (Restore: Each Region, the add-on's default before Whole Mesh) failed several of
these without Smoothing: on the human bent hard roughness 0.30 of the largest offset, on the hand three quarters
closed 271 creases (74 allowed).

With the paper's own norm (the displacement counted per vertex, not over the surface: docs/method.md) every one of
these failed: 143 creases on the human (at most 46 allowed), 368 on the half-closed hand (74), roughness a third of
the largest offset at the fist.
"""

import math
import unittest

import bpy

import lvp_helpers as helpers
import real_cases
import surface_quality as quality


class SurfaceCase(unittest.TestCase):

    def measure(self, obj, label):
        """The measures of the current pose, after checking that the correction ran and restored the volume."""
        status = self.addon.session.SESSION.status(obj)
        self.assertIn("Correcting", status[1] if status else "", "%s: %r" % (label, status))
        measured = quality.measure_pose(self.mesh, helpers.uncorrected_positions(obj),
                                        {"vp": helpers.evaluated_positions(obj)})
        vp = measured["vp"]
        self.plain_crossings = measured["plain"]["crossings"]
        print("\n    %s: volume %+.4f %% (plain %+.3f %%), %d creases of %d edges, roughness %.2f and shard %.2f of "
              "the largest offset, %d crossing pairs (plain %d)"
              % (label, 100 * vp["volume"], 100 * measured["plain"]["volume"], vp["creases"],
                 len(self.mesh.interior_edges()), vp["roughness"] / vp["largest_offset"],
                 vp["shard"] / vp["largest_offset"], vp["crossings"], measured["plain"]["crossings"]))
        self.assertLess(abs(vp["volume"]), 0.005, label)
        self.assertEqual(vp["crack"], 0.0, label)
        self.assertEqual(vp["new contacts"], 0, label)
        self.assertLessEqual(vp["added crossings"], 0, label)
        return vp

    def assertFewCreases(self, vp, label):
        self.assertEqual(quality.surface_faults(vp, len(self.mesh.interior_edges()), roughness=False, shard=False),
                         [], label)

    def assertSmooth(self, vp, label):
        """Roughness and shards (surface_quality.shard: a vertex standing further out of its neighbours' surface
        than plain skinning leaves it) within QUALITY.md's limits."""
        self.assertEqual(quality.surface_faults(vp, len(self.mesh.interior_edges()), creases=False), [], label)

    def assertNoShard(self, vp, label):
        self.assertEqual(quality.surface_faults(vp, len(self.mesh.interior_edges()), roughness=False, creases=False),
                         [], label)


class TestRigifyHuman(SurfaceCase):

    @classmethod
    def setUpClass(cls):
        cls.addon = helpers.enable_addon()
        helpers.reset_scene()
        if not real_cases.enable_rigify():
            raise unittest.SkipTest("this Blender has no Rigify add-on")
        cls.body, cls.rig = real_cases.rigify_human()
        helpers.add_volume_preservation(cls.body)
        cls.body.lvp.keep_apart = True
        cls.mesh = quality.WeldedMesh(helpers.mesh_positions(cls.body.data), helpers.mesh_triangles(cls.body.data))

    def test_bent_hard(self):
        real_cases.pose_rigify_human(self.rig, 1.0)
        bpy.context.view_layer.update()
        vp = self.measure(self.body, "Rigify human bent hard")
        self.assertFewCreases(vp, "bent hard")
        self.assertSmooth(vp, "bent hard")

    def test_bent_half_as_far(self):
        real_cases.pose_rigify_human(self.rig, 0.5)
        bpy.context.view_layer.update()
        vp = self.measure(self.body, "Rigify human bent half as far")
        self.assertFewCreases(vp, "bent half as far")
        self.assertSmooth(vp, "bent half as far")

    def fold_over_at(self, amount, label):
        """Fold-Over Prevention with Keep Skin Apart at pose_rigify_human(amount): the measures, after checking that
        the correction ran, restored the volume and left no more crossing pairs than plain skinning and no shard."""
        real_cases.pose_rigify_human(self.rig, amount)
        self.body.lvp.fold_over = True
        try:
            bpy.context.view_layer.update()
            status = self.addon.session.SESSION.status(self.body)
            self.assertIn("Correcting", status[1] if status else "")
            measured = quality.measure_pose(self.mesh, helpers.uncorrected_positions(self.body),
                                            {"fold": helpers.evaluated_positions(self.body)})
        finally:
            self.body.lvp.fold_over = False
        fold = measured["fold"]
        print("\n    Rigify human %s, Fold-Over: volume %+.4f %%, %d crossing pairs (plain %d), %d creases, "
              "roughness %.2f and shard %.2f of the largest offset"
              % (label, 100 * fold["volume"], fold["crossings"], measured["plain"]["crossings"], fold["creases"],
                 fold["roughness"] / fold["largest_offset"], fold["shard"] / fold["largest_offset"]))
        self.assertLess(abs(fold["volume"]), 0.005)
        self.assertLessEqual(fold["crossings"], measured["plain"]["crossings"], label)
        self.assertNoShard(fold, label)
        return fold, measured["plain"]

    def test_fold_over_bent_hard(self):
        # Fold-Over Prevention too: at most half of plain skinning's crossing pairs (issue 46; none of its 240 on 3.4,
        # 4.3 and 5.2), and no skin pressed where no joint folds. The two thighs raised alike turn about one line
        # through both hips, which left both heads in place: taken for a joint (foldover.c, lvp__joint_child), the inner
        # skin of one thigh was pressed onto a plane across the other, roughness 0.78 of the largest offset there; then
        # 0.50 at the armpit, where the upper arm's skin meets the spine's, the shoulder's and the breast's, each pair
        # pressing onto a plane of its own until they shared the plane of the bone the arm hangs from. Now 0.27
        # (README), at the back of the knees, where the press takes the skin that plain skinning folded back onto the
        # contact plane: the offsets there undo the fold's roughness, and the surface is smoother than plain skinning's
        # (the roughest vertex 0.15 mean edge lengths from its neighbours' mean, 0.64 in plain skinning), so no shard.
        # At most one crease per 300 edges: 36 (46 allowed); 92 while the pressed skin's relaxation stopped at skin its
        # bones carry rigidly (the upper arm's two DEF bones) and the map was faded on the convex side of a joint too
        # (the buttock, across the raised hip's plane; foldover.c).
        fold, plain = self.fold_over_at(1.0, "bent hard")
        self.assertLessEqual(fold["crossings"], plain["crossings"] / 2)
        self.assertFewCreases(fold, "bent hard, Fold-Over")
        self.assertLessEqual(fold["roughness"], 0.45 * fold["largest_offset"])

    def test_fold_over_bent_half_as_far(self):
        # Half as far the knees begin to fold (plain skinning crosses itself in a few pairs there): the press
        # reads as roughness 0.36 of the largest offset, which is small at this pose (0.6 mean edge lengths), at
        # the back of the knee, the surface smoother than plain skinning's.
        fold, _plain = self.fold_over_at(0.5, "bent half as far")
        self.assertFewCreases(fold, "bent half as far, Fold-Over")

    def test_a_wrist_alone(self):
        # A small joint on a big mesh: the wrist bent 40 degrees loses 7 % of the hand's region but 0.007 % of
        # the body, under the body's own tolerance (0.01 %). Restoring the whole mesh, the tolerance is measured
        # against the flesh that bent, so the hand still gets its volume back.
        real_cases.pose_rigify_human(self.rig, 0.0)
        hand = self.rig.pose.bones["hand_tweak.L"]
        hand.rotation_mode = 'XYZ'
        hand.rotation_euler = (math.radians(40.0), 0.0, 0.0)
        bpy.context.view_layer.update()
        helpers.evaluated_positions(self.body)
        stats = self.addon.session.SESSION.bound(self.body).stats
        rest = stats["volume_rest"]
        before, after = (stats["volume_before"] - rest) / rest, (stats["volume_after"] - rest) / rest
        print("\n    wrist bent 40 degrees: volume %+.5f %% -> %+.5f %%, region %s %+.2f %% -> %+.2f %%"
              % (100 * before, 100 * after, stats["worst_region_name"], 100 * stats["worst_region_change_before"],
                 100 * stats["worst_region_change_after"]))
        self.assertLess(before, -5e-5, "the wrist's loss is a small share of the body")
        self.assertLess(abs(after), 0.1 * abs(before))
        self.assertLess(abs(stats["worst_region_change_after"]), 0.75 * abs(stats["worst_region_change_before"]))
        hand.rotation_euler = (0.0, 0.0, 0.0)


class TestHand(SurfaceCase):

    @classmethod
    def setUpClass(cls):
        cls.addon = helpers.enable_addon()
        helpers.reset_scene()
        cls.obj, cls.rig = real_cases.hand()
        helpers.add_volume_preservation(cls.obj)
        cls.obj.lvp.keep_apart = True
        cls.mesh = quality.WeldedMesh(helpers.mesh_positions(cls.obj.data), helpers.mesh_triangles(cls.obj.data))

    def at_fraction(self, fraction):
        first, last = real_cases.HAND_FRAMES
        bpy.context.scene.frame_set(round(first + fraction * (last - first)))

    def test_half_closed(self):
        self.at_fraction(0.5)
        vp = self.measure(self.obj, "hand half closed")
        self.assertFewCreases(vp, "half closed")
        self.assertSmooth(vp, "half closed")

    def test_three_quarters_closed(self):
        self.at_fraction(0.75)
        vp = self.measure(self.obj, "hand three quarters closed")
        self.assertFewCreases(vp, "three quarters closed")
        self.assertSmooth(vp, "three quarters closed")

    def test_fist(self):
        self.at_fraction(1.0)
        vp = self.measure(self.obj, "hand closed into a fist")
        self.assertFewCreases(vp, "fist")
        self.assertSmooth(vp, "fist")


if __name__ == "__main__":
    unittest.main()
