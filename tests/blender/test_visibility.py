# SPDX-License-Identifier: GPL-3.0-or-later
"""Which characters are corrected: the ones Blender shows.

A character is corrected wherever the viewport or a render shows it: as an object of the view layer,
or through a collection instance (its collection excluded from the view layer and placed by an Empty,
or linked from its own file that way: crowds, sets, characters placed by layout). Blender evaluates
those without listing them among the view layer's objects, and before the add-on walked the evaluated
data-blocks they showed plain skinning (-11.2 % on the cylinder at 90 degrees). A character the user
hid (its eye, or its collection's) is evaluated by Blender all the same, but not corrected until it is
shown again: hiding characters keeps the correction's time out of playback.
"""

import os
import unittest
from array import array

import bpy

import lvp_helpers as helpers
from test_live import CylinderTestCase


def instance_positions(obj):
    """The positions of obj's evaluated mesh as a collection instance shows it (obj's mesh space)."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    found = None
    # Walked to the end: leaving Blender's instance iterator early leaks its state.
    for instance in depsgraph.object_instances:
        if found is None and instance.is_instance and instance.object.original == obj:
            mesh = instance.object.data
            found = array('f', bytes(12 * len(mesh.vertices)))
            mesh.vertices.foreach_get("co", found)
    if found is None:
        raise AssertionError("%s is not instanced" % obj.name)
    return found


class TestVisibility(CylinderTestCase):

    def move_into_collection(self):
        collection = bpy.data.collections.new("Character")
        self.scene.collection.children.link(collection)
        for item in (self.obj, self.rig):
            self.scene.collection.objects.unlink(item)
            collection.objects.link(item)
        return collection

    def place_instance(self, collection):
        instance = helpers.link(bpy.data.objects.new("Character instance", None))
        instance.instance_type = 'COLLECTION'
        instance.instance_collection = collection
        instance.location = (3.0, 0.0, 0.0)
        return instance

    def assertInstanceCorrected(self, obj, rig, message):
        self.assertIsNotNone(self.addon.session.SESSION.bound(obj),
                             "%s: the character was never corrected" % message)
        rest = helpers.mesh_positions(obj.data)
        triangles = helpers.mesh_triangles(obj.data)
        rest_volume = helpers.volume(rest, triangles)
        plain = helpers.relative_volume_error(helpers.core_skinned_positions(obj, rig), triangles, rest_volume)
        corrected = helpers.relative_volume_error(instance_positions(obj), triangles, rest_volume)
        self.assertGreater(plain, 0.08, "%s: plain skinning at 90 degrees" % message)
        self.assertSmallerThan(corrected, 0.005, "%s: the instance's volume error (plain %g)" % (message, plain))

    def test_instance_of_an_excluded_collection(self):
        collection = self.move_into_collection()
        bpy.context.view_layer.layer_collection.children[collection.name].exclude = True
        self.place_instance(collection)
        self.scene.frame_set(10)
        self.assertNotIn(self.obj.name, [obj.name for obj in bpy.context.evaluated_depsgraph_get().objects])
        self.assertInstanceCorrected(self.obj, self.rig, "collection instance")

    def test_instance_of_a_collection_linked_from_another_file(self):
        """The character's file linked into a shot with Instance Collections (File > Link's default): its
        objects, its rig and its animation stay in the library, placed by an Empty."""
        collection_name = self.move_into_collection().name
        directory = helpers.fresh_directory("visibility")
        library = os.path.join(directory, "character.blend")
        bpy.ops.wm.save_as_mainfile(filepath=library, copy=True)
        helpers.reset_scene()
        with bpy.data.libraries.load(library, link=True) as (_source, target):
            target.collections = [collection_name]
        linked = target.collections[0]
        self.place_instance(linked)
        obj = next(item for item in linked.all_objects if item.type == 'MESH')
        rig = next(item for item in linked.all_objects if item.type == 'ARMATURE')
        self.assertIsNotNone(obj.library)
        bpy.context.scene.frame_set(10)
        self.assertInstanceCorrected(obj, rig, "linked collection instance")
        self.assertStatusContains(obj, "Correcting")

    def check_hidden_then_shown(self, hide, show):
        hide()
        self.scene.frame_set(10)
        self.assertSmallerThan(helpers.max_abs(helpers.offsets_of(self.obj)), 1e-6,
                               "a hidden character is not corrected (the offsets of frame 1)")
        self.assertStatusContains(self.obj, "Hidden: corrected again when shown")
        show()
        bpy.context.view_layer.update()
        self.assertCorrected(plain_at_least=0.08, message="shown again at 90 degrees")

    def test_hidden_character_is_corrected_once_shown(self):
        self.check_hidden_then_shown(lambda: self.obj.hide_set(True), lambda: self.obj.hide_set(False))

    def test_character_of_a_hidden_collection_is_corrected_once_shown(self):
        collection = self.move_into_collection()
        layer_collection = bpy.context.view_layer.layer_collection.children[collection.name]

        def set_hidden(hidden):
            layer_collection.hide_viewport = hidden

        self.check_hidden_then_shown(lambda: set_hidden(True), lambda: set_hidden(False))


if __name__ == "__main__":
    unittest.main()
