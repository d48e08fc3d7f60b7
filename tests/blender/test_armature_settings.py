# SPDX-License-Identifier: GPL-3.0-or-later
"""The Armature modifier's settings.

Its Vertex Group: the modifier moves a vertex only by the vertex's weight m in that group (1 - m
when inverted) and leaves it where it is where m is 0. The add-on gives the core one more bone that
never moves, weighted 1 - m (skeleton.py).

The paper's cylinder with a mask that holds its top end (z >= 3.6) still and fades to full effect
at z = 2.6: bent 90 degrees, the masked top stays where it was and the band below it stretches.
Plain skinning: -14.63 %. Before the add-on followed the mask, the core took the top for skin that
follows its bone, measured -30.05 % and left the mesh at +15.41 %; now +0.0001 %.

Its Bind To options: with Vertex Groups off, the weights the add-on follows are not used, so the
mesh is passed through with a message. With Bone Envelopes on, Blender moves the vertices without
weights by the envelopes: the correction measures them where they are and leaves them alone.
"""

import bpy

import lvp_helpers as helpers
from test_live import CylinderTestCase

MASK = "Armature Mask"


def mask_weight(z):
    """The Armature modifier's effect on a vertex at height z: 1 below 2.6, 0 from 3.6 up."""
    return min(max(3.6 - z, 0.0), 1.0)


class MaskTestCase(CylinderTestCase):

    inverted = False

    def prepare_character(self):
        group = self.obj.vertex_groups.new(name=MASK)
        for vertex in self.obj.data.vertices:
            weight = mask_weight(vertex.co.z)
            if self.inverted:
                weight = 1.0 - weight
            if weight > 0.0:
                group.add([vertex.index], weight, 'REPLACE')
        armature_modifier = self.obj.modifiers["Armature"]
        armature_modifier.vertex_group = MASK
        armature_modifier.invert_vertex_group = self.inverted

    def still_vertices(self):
        return [vertex.index for vertex in self.obj.data.vertices if mask_weight(vertex.co.z) == 0.0]

    def check_masked_bend(self):
        self.scene.frame_set(10)
        self.assertIsNotNone(self.bound().skeleton.still_bone)
        # The core's input is plain skinning of its bones, the still one included.
        plain = self.assertSkinningMatchesBlender()
        self.assertCoreMeasuredFrom(plain)
        self.assertCorrected(message="masked cylinder at 90 degrees")
        offsets = helpers.offsets_of(self.obj)
        still = self.still_vertices()
        self.assertGreater(len(still), 16)
        self.assertEqual(max(abs(offsets[3 * index + axis]) for index in still for axis in range(3)), 0.0,
                         "vertices the Armature modifier keeps still were moved")
        self.assertStatusContains(self.obj, "Correcting")


class TestArmatureMask(MaskTestCase):

    def test_masked_vertices_stay_still(self):
        self.check_masked_bend()

    def test_posed_frames_are_blenders(self):
        self.scene.frame_set(10)
        self.assertIsNotNone(self.bound().skeleton.still_bone)
        self.assertPosedFramesAreBlenders()

    def test_mask_changed_after_bind(self):
        self.scene.frame_set(10)
        self.obj.modifiers["Armature"].vertex_group = ""
        self.scene.frame_set(9)
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "bound again by itself: the vertex group of the Armature modifier changed")
        self.assertIsNone(self.bound().skeleton.still_bone)
        self.assertCorrected(message="without the mask, bound again")

    def test_mask_weights_painted_after_bind(self):
        """The mask group is weights too: painted anew, the binding follows them."""
        self.scene.frame_set(10)
        group = self.obj.vertex_groups[MASK]
        group.add([vertex.index for vertex in self.obj.data.vertices], 1.0, 'REPLACE')  # no vertex held still
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "bound again by itself: the weights changed")
        self.assertSkinningMatchesBlender()
        self.assertCorrected(message="mask weights all 1, bound again")


class TestInvertedArmatureMask(MaskTestCase):

    inverted = True

    def test_masked_vertices_stay_still(self):
        self.check_masked_bend()


class TestArmatureBinding(CylinderTestCase):
    """The Armature modifier's Bind To options: Volume Preservation follows vertex group weights."""

    def test_vertex_groups_off_passes_through(self):
        self.scene.frame_set(10)
        self.obj.modifiers["Armature"].use_vertex_groups = False
        self.scene.frame_set(9)
        self.assertStatusContains(self.obj, "Vertex Groups is off")
        self.assertEqual(helpers.max_abs(helpers.offsets_of(self.obj)), 0.0, "offsets while not followed")
        helpers.select_only(self.obj)
        with self.assertRaises(RuntimeError):  # the operator reports the error and cancels
            bpy.ops.object.lvp_bind()
        self.obj.modifiers["Armature"].use_vertex_groups = True
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "Correcting")

    def test_envelopes_move_unweighted_vertices(self):
        # The top ring loses its weights; the Upper bone's envelope reaches it.
        top = [vertex.index for vertex in self.obj.data.vertices if vertex.co.z > 3.9]
        for group in self.obj.vertex_groups:
            group.remove(top)
        self.obj.modifiers["Armature"].use_bone_envelopes = True
        upper = self.rig.data.bones["Upper"]
        upper.envelope_distance, upper.tail_radius = 1.0, 0.5
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "16 vertices without weights move by bone envelopes")
        plain = helpers.uncorrected_positions(self.obj)
        moved = helpers.vertex_distances(plain, helpers.mesh_positions(self.obj.data))
        self.assertGreater(min(moved[index] for index in top), 1.0, "the envelope should carry the top ring along")
        self.assertCoreMeasuredFrom(plain)
        self.assertCorrected(message="with envelopes")
        offsets = helpers.offsets_of(self.obj)
        self.assertEqual(max(abs(offsets[3 * index + axis]) for index in top for axis in range(3)), 0.0,
                         "vertices moved by envelopes were corrected")
