# SPDX-License-Identifier: GPL-3.0-or-later
"""Hostile and careless use: the odd actions and bad inputs that once left the modifier silently
wrong (the shape wrong while the panel said "Correcting"). Grouped by what the user did; every
defect found gets its case here.

The rule over all of them (assertNeverSilentlyWrong): after any action, either the shown mesh is
corrected, or the offsets are zero and the status says why the mesh is passed through. "Correcting"
never shows over zero offsets where plain skinning lost volume.
"""

import os
import subprocess
import sys
import unittest

import bmesh
import bpy

import lvp_helpers as helpers


class HostileTestCase(helpers.AddonTestCase):
    """The paper's cylinder, corrected, bending from 0 (frame 1) to 90 degrees (frame 10)."""

    def setUp(self):
        super().setUp()
        self.obj, self.rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(self.rig, {1: 0.0, 10: 90.0})
        self.scene = bpy.context.scene
        self.scene.frame_set(1)
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})
        self.scene.frame_set(10)

    def show_frame(self, frame):
        self.scene.frame_set(frame - 1 if frame > 1 else frame + 1)
        self.scene.frame_set(frame)

    def assertNeverSilentlyWrong(self, obj=None, message=""):
        """Corrected (the volume error a tenth of plain skinning's), or passed through (zero offsets)
        with a status that is not "Correcting" and says why."""
        obj = obj or self.obj
        level, status = self.status_of(obj)
        corrected, plain = helpers.volume_errors(obj)
        largest = helpers.max_abs(helpers.offsets_of(obj))
        if status.startswith("Correcting"):
            self.assertGreater(largest, 0.0, "%s: %r over zero offsets" % (message, status))
            if plain > 0.01:
                self.assertSmallerThan(corrected, 0.1 * plain, "%s: %r, volume error (plain %g)"
                                       % (message, status, plain))
        else:
            self.assertSmallerThan(largest, 1e-9, "%s: %r, yet offsets are applied" % (message, status))
            self.assertGreater(len(status), 12, "%s: the pass-through says why (%r)" % (message, status))
        return level, status


class TestTopologyEdits(HostileTestCase):
    """1. A topology edit that keeps the counts (Flip Normals, Rotate Edge, Sort Elements), then a
    weight change."""

    def edit_topology(self, operator):
        bpy.context.view_layer.objects.active = self.obj
        helpers.select_only(self.obj)
        bpy.ops.object.mode_set(mode='EDIT')
        bpy.ops.mesh.select_all(action='SELECT')
        operator()
        bpy.ops.object.mode_set(mode='OBJECT')

    def repaint_weights(self):
        for name in ("Lower", "Upper"):
            self.obj.vertex_groups.remove(self.obj.vertex_groups[name])
        helpers.weight_linear_band(self.obj, joint=2.3, band=1.4)

    def check_edit_then_weights(self, operator, name):
        counts = helpers.topology_counts(self.obj.data)
        self.edit_topology(operator)
        self.assertEqual(helpers.topology_counts(self.obj.data), counts, "%s keeps the counts" % name)
        self.show_frame(10)
        self.assertNeverSilentlyWrong(message="%s" % name)
        self.repaint_weights()
        bpy.context.view_layer.update()
        for frame in (10, 9, 10):
            self.scene.frame_set(frame)
            level, status = self.assertNeverSilentlyWrong(message="%s, then new weights, frame %d" % (name, frame))
            self.assertIn("rebind needed", status.lower(), "%s, frame %d" % (name, frame))
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        self.show_frame(10)
        level, status = self.assertNeverSilentlyWrong(message="%s, bound again" % name)
        self.assertTrue(status.startswith("Correcting"), status)

    def test_flip_normals(self):
        self.check_edit_then_weights(lambda: bpy.ops.mesh.flip_normals(), "Flip Normals")

    def test_sort_elements(self):
        self.check_edit_then_weights(lambda: bpy.ops.mesh.sort_elements(type='RANDOMIZE', elements={'VERT'}),
                                     "Sort Elements")

    def test_rotate_edge(self):
        def rotate():
            bpy.ops.mesh.select_all(action='DESELECT')
            bm = bmesh.from_edit_mesh(self.obj.data)
            edge = next(edge for edge in bm.edges if len(edge.link_faces) == 2
                        and all(len(face.verts) == 4 for face in edge.link_faces))
            edge.select = True
            bmesh.update_edit_mesh(self.obj.data)
            bpy.ops.mesh.edge_rotate(use_ccw=False)
        self.check_edit_then_weights(rotate, "Rotate Edge")


class TestCopiedModifier(HostileTestCase):
    """2. The modifier copied onto another character (Copy to Selected, Copy Modifiers): the copy
    names the source's offsets object until it is bound."""

    def setUp(self):
        super().setUp()
        # Another character with its own rig, at rest.
        self.other, self.other_rig = helpers.make_cylinder_character("Other", location=(3.0, 0.0, 0.0))
        bpy.context.view_layer.update()

    def assertOtherPassesThrough(self, how):
        self.show_frame(10)
        level, status = self.assertNeverSilentlyWrong(self.other, "%s, not bound" % how)
        self.assertIn("not bound", status.lower())
        shown = helpers.evaluated_positions(self.other)
        plain = helpers.uncorrected_positions(self.other)
        self.assertSmallerThan(helpers.max_distance(shown, plain), 1e-6, "%s: the copy shows its own plain "
                                                                        "skinning, not the source's bulge" % how)
        self.assertNeverSilentlyWrong(self.obj, "%s: the source" % how)
        helpers.select_only(self.other)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        helpers.bend(self.other_rig, 90.0)
        bpy.context.view_layer.update()
        level, status = self.assertNeverSilentlyWrong(self.other, "%s, bound" % how)
        self.assertTrue(status.startswith("Correcting"), status)
        self.assertIsNot(helpers.offsets_object(self.other), helpers.offsets_object(self.obj))

    def test_copy_to_selected(self):
        with bpy.context.temp_override(object=self.obj, active_object=self.obj,
                                       selected_objects=[self.obj, self.other]):
            self.assertEqual(bpy.ops.object.modifier_copy_to_selected(modifier="Volume Preservation"),
                             {'FINISHED'})
        self.assertIsNotNone(self.addon.node_group.find_modifier(self.other))
        self.assertOtherPassesThrough("Copy to Selected")

    def test_link_modifiers(self):
        helpers.select_only(self.obj, self.other)
        bpy.context.view_layer.objects.active = self.obj
        self.assertEqual(bpy.ops.object.make_links_data(type='MODIFIERS'), {'FINISHED'})
        self.assertIsNotNone(self.addon.node_group.find_modifier(self.other))
        self.assertOtherPassesThrough("Link Modifiers")


if __name__ == "__main__":
    unittest.main()
