# SPDX-License-Identifier: GPL-3.0-or-later
"""Characters brought into a shot from their own file by library override, as productions do.

The override keeps the character's mesh linked, and Blender ignores what add-ons write into a linked
or overridden mesh (tested here: the offsets read back as zeros), where the correction lives. So the
panel says so and offers Make Mesh Local (object.lvp_make_mesh_local), which gives the object a local
copy of its mesh; from then on it is corrected like a local character, and the override keeps it
after saving and reopening the shot.
"""

import os

import bpy

import lvp_helpers as helpers
from test_panel import draw_panel


class TestLibraryOverride(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        obj, rig = helpers.make_cylinder_character()
        collection = bpy.data.collections.new("Character")
        bpy.context.scene.collection.children.link(collection)
        for item in (obj, rig):
            for owner in list(item.users_collection):
                owner.objects.unlink(item)
            collection.objects.link(item)
        self.assertEqual(helpers.add_volume_preservation(obj), {'FINISHED'})
        self.directory = helpers.fresh_directory("override")
        self.asset = os.path.join(self.directory, "character.blend")
        bpy.ops.wm.save_as_mainfile(filepath=self.asset, copy=True)
        # The shot: a new file that links the character and overrides it.
        scene = helpers.reset_scene()
        with bpy.data.libraries.load(self.asset, link=True) as (source, target):
            target.collections = ["Character"]
        linked = target.collections[0]
        instance = helpers.link(bpy.data.objects.new("CharacterInstance", None))
        instance.instance_type = 'COLLECTION'
        instance.instance_collection = linked
        override = linked.override_hierarchy_create(scene, bpy.context.view_layer, reference=instance)
        self.obj = next(item for item in override.all_objects if item.type == 'MESH')
        self.rig = next(item for item in override.all_objects if item.type == 'ARMATURE')
        self.triangles = helpers.mesh_triangles(self.obj.data)
        self.rest_volume = helpers.volume(helpers.mesh_positions(self.obj.data), self.triangles)

    def errors(self):
        corrected = helpers.evaluated_positions(self.obj)
        plain = helpers.uncorrected_positions(self.obj)
        return (helpers.relative_volume_error(corrected, self.triangles, self.rest_volume),
                helpers.relative_volume_error(plain, self.triangles, self.rest_volume))

    def test_linked_mesh_made_local(self):
        self.assertIsNotNone(self.obj.override_library)
        self.assertTrue(self.addon.live.mesh_from_library(self.obj.data))
        helpers.bend(self.rig, 90.0)
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "Make Mesh Local")
        self.assertIn("object.lvp_make_mesh_local", draw_panel(self, self.obj)["operators"])
        corrected, plain = self.errors()
        self.assertGreater(plain, 0.05)
        self.assertEqual(corrected, plain, "nothing can be written into the linked mesh")

        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_make_mesh_local(), {'FINISHED'})
        self.assertFalse(self.addon.live.mesh_from_library(self.obj.data))
        self.assertNotIn("object.lvp_make_mesh_local", draw_panel(self, self.obj)["operators"])
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "Correcting")
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "corrected volume error with the local mesh (plain %g)" % plain)

        # The override keeps the local mesh in the saved shot.
        shot = os.path.join(self.directory, "shot.blend")
        names = (self.obj.name, self.rig.name)
        bpy.ops.wm.save_as_mainfile(filepath=shot)
        bpy.ops.wm.open_mainfile(filepath=shot)
        self.obj, self.rig = (next(item for item in bpy.data.objects if item.name == name and item.library is None)
                              for name in names)
        self.assertFalse(self.addon.live.mesh_from_library(self.obj.data))
        helpers.bend(self.rig, 90.0)
        bpy.context.view_layer.update()
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after reopening the shot (plain %g)" % plain)

    def test_nothing_to_make_local(self):
        bpy.ops.object.select_all(action='DESELECT')
        with self.assertRaises(RuntimeError):  # the poll fails: no selected object has a linked mesh
            bpy.ops.object.lvp_make_mesh_local()
