# SPDX-License-Identifier: GPL-3.0-or-later
"""The binding follows what it was made of, as a reopened file, a render farm or a bake would bind it.

The core's contract (lvp.h, lvp_correct) is that its input is plain skinning of the bound rest mesh
by the bound bones and weights. An artist who paints weights, edits the rest mesh or the rig's rest
pose breaks it until the object is bound again; a file reopened elsewhere binds the new data. So the
add-on binds again by itself (live.py, _follow_changes): the armature's side is checked every
frame, the weights and the rest mesh when someone else changed the mesh: at once in background
Blender (these tests), once the changes pause in the interface and in Weight Paint Mode. Each test
checks the contract against Blender's Armature modifier afterwards (helpers.core_skinned_positions),
and that the result is the one the Bind button gives.
"""

import time

import bpy

import lvp_helpers as helpers
from test_live import CylinderTestCase


class FollowTestCase(CylinderTestCase):

    def assertSameAsBindButton(self, message):
        """The offsets equal those of pressing Bind now."""
        followed = helpers.offsets_of(self.obj)
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        self.scene.frame_set(self.scene.frame_current - 1)
        self.scene.frame_set(self.scene.frame_current + 1)
        self.assertSmallerThan(helpers.max_distance(followed, helpers.offsets_of(self.obj)), 1e-6, message)

    def assertFollowedNewWeights(self, before, message):
        """Bound again by itself (no longer the binding before), nothing left to check, corrected."""
        self.assertIsNot(self.bound(), before)
        self.assertIsNone(self.addon.handlers.after_mesh_changes(), "nothing left to check")
        self.assertStatusContains(self.obj, "Correcting (bound again by itself: the weights changed)")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, %s" % message)
        self.assertCorrected(message=message)

    def repaint_weights(self):
        """Narrower weight bands, centred higher: another skinning, same groups."""
        for name in ("Lower", "Upper"):
            self.obj.vertex_groups.remove(self.obj.vertex_groups[name])
        helpers.weight_linear_band(self.obj, joint=2.3, band=1.4)


class TestFollowChanges(FollowTestCase):

    def test_weights_painted(self):
        self.obj.lvp.display = 'SEGMENTATION'
        self.scene.frame_set(10)
        before = self.bound()
        colors_before = helpers._foreach(self.obj.data.attributes["lvp_segmentation"].data, "color", 4, 'f')
        self.repaint_weights()
        bpy.context.view_layer.update()
        self.assertFollowedNewWeights(before, "new weights")
        colors_after = helpers._foreach(self.obj.data.attributes["lvp_segmentation"].data, "color", 4, 'f')
        self.assertNotEqual(colors_before, colors_after, "the segmentation display follows")
        self.assertSameAsBindButton("followed vs Bind")

    def test_undo_of_painted_weights(self):
        self.scene.frame_set(10)
        first = helpers.offsets_of(self.obj)
        bpy.ops.ed.undo_push(message="before painting")
        self.repaint_weights()
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "bound again by itself: the weights changed")
        self.assertGreater(helpers.max_distance(first, helpers.offsets_of(self.obj)), 1e-3)
        bpy.ops.ed.undo_push(message="painted")
        bpy.ops.ed.undo()
        bpy.context.view_layer.update()
        self.obj = bpy.data.objects["Cylinder"]  # undo replaced the Python objects
        self.rig = bpy.data.objects["CylinderRig"]
        self.assertStatusContains(self.obj, "bound again by itself: the weights changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier after undo")
        self.assertSmallerThan(helpers.max_distance(first, helpers.offsets_of(self.obj)), 1e-6,
                               "the correction of the weights before painting")

    def test_rest_mesh_edited(self):
        self.scene.frame_set(10)
        mesh = self.obj.data
        for vertex in mesh.vertices:  # a thicker limb
            vertex.co.x *= 1.2
            vertex.co.y *= 1.2
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "bound again by itself: the rest mesh changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, new rest mesh")
        self.rest_volume = helpers.volume(helpers.mesh_positions(mesh), self.triangles)
        self.assertCorrected(message="the thicker limb")
        self.assertSameAsBindButton("followed vs Bind")

    def test_rig_rest_pose_edited(self):
        self.scene.frame_set(10)
        bpy.context.view_layer.objects.active = self.rig
        bpy.ops.object.mode_set(mode='EDIT')
        self.rig.data.edit_bones["Upper"].head.z = 2.3  # the joint moves up; Lower's tail with it
        bpy.ops.object.mode_set(mode='OBJECT')
        self.scene.frame_set(9)
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "bound again by itself: the rest pose of 'Lower' changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, new rest pose")
        self.assertSameAsBindButton("followed vs Bind")

    def test_bbone_segments_and_mapping_changed(self):
        """Settings of a bound bone that change how Blender deforms with it, not its rest pose: its B-Bone
        segments, then (Blender 4.2+) how its vertices are placed along them."""
        self.scene.frame_set(10)
        bone = self.rig.data.bones["Lower"]
        bone.bbone_segments = 4
        self.scene.frame_set(9)
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "bound again by itself: the B-Bone segments of 'Lower' changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, B-Bone segments")
        if "bbone_mapping_mode" not in bpy.types.Bone.bl_rna.properties:
            return  # before 4.2, a B-Bone has one mapping
        before = self.bound()
        bone.bbone_mapping_mode = 'CURVED'
        self.scene.frame_set(9)
        self.scene.frame_set(10)
        self.assertIsNot(self.bound(), before)
        self.assertStatusContains(self.obj, "bound again by itself: the B-Bone vertex mapping of 'Lower' changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, Curved mapping")
        self.assertSameAsBindButton("followed vs Bind")

    def test_weights_changed_by_a_script_then_rendered(self):
        """No update between the change and the render (a frame change brings none): the render reads
        the weights again at its start."""
        self.scene.frame_set(10)
        self.repaint_weights()
        self.addon.handlers.render_init(self.scene)  # what bpy.ops.render.render() calls first
        self.scene.frame_set(9)
        self.scene.frame_set(10)
        self.assertStatusContains(self.obj, "bound again by itself: the weights changed")
        self.assertSkinningMatchesBlender("core skinning vs the Armature modifier, weights changed by a script")

    def test_mesh_tagged_without_change_keeps_the_binding(self):
        self.scene.frame_set(10)
        before = self.bound()
        offsets = helpers.offsets_of(self.obj)
        self.obj.data.update()
        bpy.context.view_layer.update()
        self.assertIs(self.bound(), before)
        self.assertEqual(self.status_of(self.obj), ('INFO', "Correcting"))
        self.assertEqual(offsets.tobytes(), helpers.offsets_of(self.obj).tobytes())

    def test_painted_map_repainted(self):
        group = self.obj.vertex_groups.new(name="Painted")
        group.add([vertex.index for vertex in self.obj.data.vertices], 1.0, 'REPLACE')
        self.obj.lvp.painted_vertex_group = "Painted"
        self.obj.lvp.effect = 'PAINTED'
        self.scene.frame_set(10)
        before = self.bound()
        offsets_before = helpers.offsets_of(self.obj)
        # The skin above the joint is not to move: the correction goes below it.
        group.add([vertex.index for vertex in self.obj.data.vertices if vertex.co.z > 2.0], 0.0, 'REPLACE')
        bpy.context.view_layer.update()
        self.assertIs(self.bound(), before, "a new painted map needs no new binding")
        map_values = helpers.array('f', bytes(4 * len(self.obj.data.vertices)))
        before.binding.correction_map(map_values)
        above = [map_values[vertex.index] for vertex in self.obj.data.vertices if vertex.co.z > 2.0]
        self.assertEqual(max(above), 0.0, "the map follows the painted group")
        self.assertNotEqual(offsets_before.tobytes(), helpers.offsets_of(self.obj).tobytes())
        self.assertCorrected(message="the repainted map")


class TestWeightPaintMode(FollowTestCase):

    def tearDown(self):
        after_mesh_changes = self.addon.handlers.after_mesh_changes
        if bpy.app.timers.is_registered(after_mesh_changes):
            bpy.app.timers.unregister(after_mesh_changes)
        if bpy.context.object is not None and bpy.context.object.mode != 'OBJECT':
            bpy.ops.object.mode_set(mode='OBJECT')
        super().tearDown()

    def test_strokes_are_followed_when_painting_pauses(self):
        self.scene.frame_set(10)
        before = self.bound()
        bpy.context.view_layer.objects.active = self.obj
        bpy.ops.object.mode_set(mode='WEIGHT_PAINT')
        self.repaint_weights()  # a stroke
        bpy.context.view_layer.update()
        # While strokes come, the weights are not read again (a Python loop over the vertices).
        self.assertIs(self.bound(), before)
        self.assertStatusContains(self.obj, "read again when the changes pause")
        self.assertTrue(bpy.app.timers.is_registered(self.addon.handlers.after_mesh_changes))
        self.assertGreater(self.addon.handlers.after_mesh_changes(), 0.0, "the timer comes back after the pause")
        time.sleep(self.addon.changes.CHECK_PAUSE)
        self.assertIsNone(self.addon.handlers.after_mesh_changes(), "the timer tagged the object and stops")
        bpy.context.view_layer.update()
        self.assertFollowedNewWeights(before, "after painting")

    def test_own_changes_read_nothing_again(self):
        """A setting, the display, a region restriction and Bind each have Blender report the mesh as
        changed; what the add-on did itself changed neither the weights nor the rest mesh (or was just
        bound), so they are not read again (a Python loop over the vertices once the changes pause). The
        next stroke still is."""
        self.scene.frame_set(10)
        bpy.context.view_layer.objects.active = self.obj
        bpy.ops.object.mode_set(mode='WEIGHT_PAINT')
        bpy.context.view_layer.update()  # Blender reports entering the mode as a change of the mesh
        time.sleep(self.addon.changes.CHECK_PAUSE)
        self.addon.handlers.after_mesh_changes()
        bpy.context.view_layer.update()
        self.assertEqual(self.addon.session.SESSION.changes.unread(), [], "checked once painting paused")
        offsets_before = helpers.offsets_of(self.obj)
        settings = self.obj.lvp

        def set_alpha():
            settings.alpha = 0.5

        def show_segmentation():
            settings.display = 'SEGMENTATION'

        def restrict_a_region():
            self.assertEqual(bpy.ops.object.lvp_region_restriction_add(), {'FINISHED'})
            settings.region_restrictions[0].region = "Upper"
            settings.region_restrictions[0].bones = "Upper"
            settings.active_region_restriction = 0

        def bind():
            helpers.select_only(self.obj)
            self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})

        for change in (set_alpha, show_segmentation, restrict_a_region, bind):
            change()
            bpy.context.view_layer.update()
            self.assertEqual(self.addon.session.SESSION.changes.unread(), [], change.__name__)
            self.assertEqual(self.status_of(self.obj), ('INFO', "Correcting"), change.__name__)
        self.assertNotEqual(offsets_before.tobytes(), helpers.offsets_of(self.obj).tobytes(), "alpha 0.5 corrects")
        self.assertIn("lvp_segmentation", self.obj.data.attributes)
        before = self.bound()
        self.repaint_weights()
        bpy.context.view_layer.update()
        self.assertEqual([name for name, _changed_at in self.addon.session.SESSION.changes.unread()],
                         [self.obj.name], "a stroke after the add-on's own updates is a change")
        time.sleep(self.addon.changes.CHECK_PAUSE)
        self.assertIsNone(self.addon.handlers.after_mesh_changes())
        bpy.context.view_layer.update()
        self.assertFollowedNewWeights(before, "a stroke after the add-on's own updates")
