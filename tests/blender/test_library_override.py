# SPDX-License-Identifier: GPL-3.0-or-later
"""Characters brought into a shot from their own file by library override, as productions do.

The override keeps the character's mesh linked, and Blender ignores what add-ons write into a
linked or overridden mesh. The correction lives in an offsets object of the shot's own
(addon/offsets.py), so the character is corrected with its mesh still linked: it keeps following the
character file (new weights, a changed rest mesh), and the override records which offsets object its
modifier uses when the shot is saved.
"""

import os

import bpy

import lvp_helpers as helpers


class TestLibraryOverride(helpers.AddonTestCase):

    def make_shot(self, with_modifier):
        """Saves the cylinder character (corrected or not) in its own file, then makes a new shot that
        links and overrides it, as Blender's Library Override > Make does."""
        obj, rig = helpers.make_cylinder_character()
        collection = bpy.data.collections.new("Character")
        bpy.context.scene.collection.children.link(collection)
        for item in (obj, rig):
            for owner in list(item.users_collection):
                owner.objects.unlink(item)
            collection.objects.link(item)
        if with_modifier:
            self.assertEqual(helpers.add_volume_preservation(obj), {'FINISHED'})
        self.directory = helpers.fresh_directory("override")
        self.asset = os.path.join(self.directory, "character.blend")
        self.shot = os.path.join(self.directory, "shot.blend")
        bpy.ops.wm.save_as_mainfile(filepath=self.asset, copy=True)
        scene = helpers.reset_scene()
        with bpy.data.libraries.load(self.asset, link=True) as (_source, target):
            target.collections = ["Character"]
        linked = target.collections[0]
        instance = helpers.link(bpy.data.objects.new("CharacterInstance", None))
        instance.instance_type = 'COLLECTION'
        instance.instance_collection = linked
        override = linked.override_hierarchy_create(scene, bpy.context.view_layer, reference=instance)
        self.obj = next(item for item in override.all_objects if item.type == 'MESH')
        self.rig = next(item for item in override.all_objects if item.type == 'ARMATURE')
        self.assertIsNotNone(self.obj.override_library)
        self.assertTrue(self.addon.mesh_data.is_linked(self.obj.data))
        self.names = (self.obj.name, self.rig.name)

    def reopen_shot(self):
        bpy.ops.wm.open_mainfile(filepath=self.shot)
        self.obj, self.rig = (next(item for item in bpy.data.objects if item.name == name and item.library is None)
                              for name in self.names)
        self.assertIsNotNone(self.obj.override_library)
        self.assertTrue(self.addon.mesh_data.is_linked(self.obj.data), "the mesh stays linked to the library")

    def assertCorrectedAt90(self, message):
        helpers.bend(self.rig, 90.0)
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "Correcting")
        corrected, plain = helpers.volume_errors(self.obj)
        self.assertGreater(plain, 0.05, message)
        self.assertSmallerThan(corrected, 0.1 * plain, "%s: corrected volume error (plain %g)" % (message, plain))
        holder = helpers.offsets_object(self.obj)
        self.assertIsNone(holder.library, "the offsets object belongs to the shot")

    def test_corrected_with_the_mesh_linked(self):
        self.make_shot(with_modifier=True)
        self.assertCorrectedAt90("in the shot, with no user action")
        self.obj.lvp.alpha = 1.5  # settings changed in the shot
        restriction = self.obj.lvp.region_restrictions.add()
        restriction.region, restriction.bones = "Upper", "Lower"
        bpy.ops.wm.save_as_mainfile(filepath=self.shot)
        self.reopen_shot()
        self.assertEqual(self.obj.lvp.alpha, 1.5, "the shot keeps its own settings")
        self.assertEqual([(item.region, item.bones) for item in self.obj.lvp.region_restrictions],
                         [("Upper", "Lower")], "the shot keeps its region restrictions")
        self.assertCorrectedAt90("after reopening the shot")

        # The character file changes (its rest mesh made 20 % thicker): the shot follows it, corrected.
        bpy.ops.wm.open_mainfile(filepath=self.asset)
        mesh = next(obj for obj in bpy.data.objects if obj.type == 'MESH').data
        for vertex in mesh.vertices:
            vertex.co.x *= 1.2
            vertex.co.y *= 1.2
        bpy.ops.wm.save_mainfile()
        self.reopen_shot()
        widest = max(abs(vertex.co.x) for vertex in self.obj.data.vertices)
        self.assertAlmostEqual(widest, 0.6, places=4, msg="the shot's mesh is the character file's")
        self.assertCorrectedAt90("after the character file changed")

    def test_added_in_the_shot(self):
        self.make_shot(with_modifier=False)
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_add(), {'FINISHED'})
        self.assertCorrectedAt90("added to the override")
        bpy.ops.wm.save_as_mainfile(filepath=self.shot)
        self.reopen_shot()
        self.assertCorrectedAt90("added to the override, after reopening the shot")
        # Saved again as opened: the bind and the settings are still the override's own.
        self.obj.lvp.alpha = 1.5
        bpy.ops.wm.save_mainfile()
        self.reopen_shot()
        self.assertEqual(self.obj.lvp.alpha, 1.5, "the shot keeps its own settings")
        self.assertCorrectedAt90("added to the override, after saving and reopening the shot twice")

    def test_weights_are_the_library_files(self):
        self.make_shot(with_modifier=True)
        helpers.select_only(self.obj)
        before = helpers.mesh_snapshot(self.obj.data)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_auto_weights()
        self.assertIn("linked from a library", str(raised.exception))
        self.assertEqual(helpers.mesh_snapshot(self.obj.data), before)
