# SPDX-License-Identifier: GPL-3.0-or-later
"""Keep Skin Apart on a family of hands the suite was not tuned on (issue 46), as renders and bakes have it:
real_cases.HAND_FAMILY, stubby and long phalanges, three fingers, a thumb closing over the fingers and one closing
under them, 998 to 17,078 vertices, three decimated to irregular triangles (to 0.3 and to half of their faces), one
split into triangles as game exporters leave a mesh, and a coarse one subdivided once. Each is built as the
suite's own hand is (a voxel remesh of its spheres, heat weights, an animation from open to a fist) and measured
three quarters closed and at the fist (the measures of QUALITY.md, from surface_quality.py):

- the volume within 0.5 % of the rest, no more crossing pairs than plain skinning, and no new contact (a pair
  crossing where plain skinning keeps skin apart, surface_quality.new_contact_pairs);
- roughness at most a quarter of the largest offset;
- at most one crease added per 300 edges.

Measured on 3.4: no new contact on any, and 0-37 fewer crossing pairs than plain skinning (the correction without
Keep Skin Apart has up to 153 pairs that plain skinning has not at the fist), roughness 0.03-0.12 of the largest
offset, at most 4 creases but on the fine hand at the fist, 19 (171 allowed; 57 without Keep Skin Apart). The
decimated hands are the ones that need the smoothing weighted by the mesh (offset_smoothing.c): smoothed with
equal weights over the rings, the offsets tilt their long thin triangles beside small ones into creases.
"""

import unittest

import bpy

import lvp_helpers as helpers
import real_cases
import surface_quality as quality

FRAMES = {"three quarters closed": 16, "at the fist": 21}
# (hand, pose) whose roughness with Fold-Over is not held to a quarter yet (test_fold_over_halves_the_crossings): the
# very coarse hand and the one decimated to half, where the two sides of a crease, one edge apart, are pressed in
# opposite directions, the crossing undone; and the coarse hand three quarters closed, whose roughest vertex (259, a
# pressed vertex standing 0.29 mean edges off the mean of neighbours that move its way) reads 0.249 of the largest
# offset where the offsets' passes weigh the neighbours by the mesh only and 0.251 with every third pass weighing
# them equally (offset_smoothing.c): the vertex is the same to a ten-thousandth, the largest offset elsewhere 1.168
# -> 1.159 mean edges.
FOLD_OVER_ROUGH = ({(hand, pose) for hand in ("very coarse", "decimated to half") for pose in FRAMES}
                   | {("coarse", "three quarters closed")})


class TestHandFamily(unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        cls.addon = helpers.enable_addon()

    def corrected_hand(self, case):
        """(hand, its WeldedMesh): a hand of the family (a real_cases.HandCase) in a fresh scene, Volume
        Preservation added."""
        helpers.reset_scene()
        obj, _rig = real_cases.hand(case.voxel_size, case.shape, decimated=case.decimated, finish=case.finish)
        mesh = quality.WeldedMesh(helpers.mesh_positions(obj.data), helpers.mesh_triangles(obj.data))
        helpers.select_only(obj)
        self.assertEqual(bpy.ops.object.lvp_add(), {'FINISHED'})
        return obj, mesh

    @staticmethod
    def straddling_joints(obj, mesh):
        """The welded triangles whose corners follow different bones (each corner's bone: the vertex group that
        weighs it most; a corner in no group follows none), those that span a joint."""
        group_names = {group.index: group.name for group in obj.vertex_groups}
        bone_of = {vertex.index: group_names[max(vertex.groups, key=lambda g: g.weight).group]
                   for vertex in obj.data.vertices if vertex.groups}
        return {t for t, corners in enumerate(mesh.welded_triangles)
                if len({bone_of[corner] for corner in corners if corner in bone_of}) > 1}

    def measure(self, obj, mesh, frame):
        """{"plain", "kept apart", "viewport"} measures at `frame`: plain skinning, Keep Skin Apart on and off."""
        corrected = {}
        for label, keep_apart in (("viewport", False), ("kept apart", True)):
            obj.lvp.keep_apart = keep_apart
            bpy.context.scene.frame_set(frame)
            status = self.addon.session.SESSION.status(obj)
            self.assertIn("Correcting", status[1] if status else "", "%s: %r" % (label, status))
            corrected[label] = helpers.evaluated_positions(obj)
        return quality.measure_pose(mesh, helpers.uncorrected_positions(obj), corrected)

    def test_kept_apart_and_smooth(self):
        for name, case in real_cases.HAND_FAMILY.items():
            with self.subTest(hand=name):
                obj, mesh = self.corrected_hand(case)
                edges = len(mesh.interior_edges())
                for pose, frame in FRAMES.items():
                    measured = self.measure(obj, mesh, frame)
                    kept, viewport = measured["kept apart"], measured["viewport"]
                    label = "%s, %s" % (name, pose)
                    print("\n    %-24s %-21s %5d vertices: volume %+.4f %%, crossing pairs %d (plain %d, new %d; "
                          "without Keep Skin Apart %d new), creases %d (%d without; %.0f allowed), roughness %.2f, "
                          "shard %.2f"
                          % (name, pose, len(obj.data.vertices), 100 * kept["volume"], kept["crossings"],
                             measured["plain"]["crossings"], kept["new crossings"], viewport["new crossings"],
                             kept["creases"], viewport["creases"], edges / quality.EDGES_PER_CREASE,
                             kept["roughness"] / kept["largest_offset"], kept["shard"] / kept["largest_offset"]))
                    self.assertLess(abs(kept["volume"]), 0.005, label)
                    self.assertEqual(kept["new contacts"], 0, label)
                    self.assertLessEqual(kept["added crossings"], 0, label)
                    self.assertEqual(quality.surface_faults(kept, edges), [], label)

    def test_fold_over_halves_the_crossings(self):
        """Fold-Over Prevention with Keep Skin Apart (what renders with Fold-Over get): the volume kept, at most half of
        plain skinning's crossing pairs, three quarters closed and at the fist (issue 46), Keep Skin Apart adding at
        most one crease per 300 edges to Fold-Over's own, roughness at most a quarter of the largest offset but on
        FOLD_OVER_ROUGH, and on every hand no shard (surface_quality.shard, a quarter of the largest offset).

        Keep Skin Apart shortens only what it can part. Skin that fold-over holds on a contact plane keeps its place
        where its press parted a crossing of the skinning (contact.c, lvp__pin_held), and where the skin around it
        is shortened because it met a third skin (the thumb's web under the index's fingertip, which the skinning
        already pushed into it), it comes down with that skin as far as the crossing it parted stays parted
        (lvp__raise_pinned_crossing): held in place alone, it stood out of the skin around it.

        Every pair left must have a triangle that spans a joint (its corners following different bones). On the
        decimated hands those are triangles from a finger's first phalanx to its last with no corner on the middle
        one: their straight edges cut through the bent finger wherever corners that follow the skin go. That is why
        the decimated hands three quarters closed are not held to half (one keeps 23 of plain skinning's 30 pairs
        on 3.4). The very coarse hand (998 vertices; README asks Smoothing 10 of meshes this coarse) and the hand
        decimated to half (2,056 vertices) are not held to the roughness bound: the worst vertex is the bottom of a
        crease pressed one way while its neighbour an edge away on the other side is pressed the other, undoing the
        skinning's crossing (0.32-0.33; on the hand decimated to half 0.29 / 0.26, the palm's skin under the ring
        finger's knuckle and the finger's an edge beside it); their surface is held by the shard bound like every
        other hand's."""
        for name, case in real_cases.HAND_FAMILY.items():
            with self.subTest(hand=name):
                obj, mesh = self.corrected_hand(case)
                edges = len(mesh.interior_edges())
                straddling = self.straddling_joints(obj, mesh)
                obj.lvp.fold_over = True
                for pose, frame in FRAMES.items():
                    label = "%s, %s" % (name, pose)
                    corrected = {}
                    for variant, keep_apart in (("fold-over alone", False), ("fold-over", True)):
                        obj.lvp.keep_apart = keep_apart
                        bpy.context.scene.frame_set(frame)
                        self.assertEqual(self.addon.session.SESSION.status(obj), ('INFO', "Correcting"), label)
                        corrected[variant] = helpers.evaluated_positions(obj)
                    measured = quality.measure_pose(mesh, helpers.uncorrected_positions(obj), corrected)
                    folded, plain = measured["fold-over"], measured["plain"]["crossings"]
                    alone = measured["fold-over alone"]
                    print("\n    %-24s %-21s Fold-Over: crossing pairs %d (plain %d), creases %d (%d without Keep Skin "
                          "Apart), roughness %.2f, shard %.2f"
                          % (name, pose, folded["crossings"], plain, folded["creases"], alone["creases"],
                             folded["roughness"] / folded["largest_offset"], folded["shard"] / folded["largest_offset"]))
                    self.assertLess(abs(folded["volume"]), 0.005, label)
                    if case.decimated is None or pose == "at the fist":
                        self.assertLessEqual(folded["crossings"], plain / 2, label)
                    # What it leaves is skin a joint's plane cannot part: a triangle that spans a joint.
                    left = quality.crossing_pairs(corrected["fold-over"], mesh)
                    self.assertFalse([pair for pair in left if not set(pair) & straddling], label)
                    rough_held = (name, pose) not in FOLD_OVER_ROUGH
                    self.assertEqual(quality.surface_faults(folded, edges, roughness=rough_held,
                                                            creases_before=alone["creases"]), [], label)


if __name__ == "__main__":
    unittest.main()
