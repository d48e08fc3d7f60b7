# SPDX-License-Identifier: GPL-3.0-or-later
"""The operators (object.lvp_add, lvp_bind, lvp_remove, lvp_auto_weights), their error cases, undo,
and bad input: nothing the add-on does may lose the user's data."""

import unittest

import bmesh
import bpy

import lvp_helpers as helpers


def node_group_count():
    return sum(1 for group in bpy.data.node_groups if group.get("lvp_node_group_version") is not None)


class TestAddErrors(helpers.AddonTestCase):
    """object.lvp_add reports an ERROR that says what and how to fix, and changes nothing."""

    def assertAddFails(self, objects, expected_text, watched):
        before = [helpers.object_snapshot(obj) for obj in watched]
        helpers.select_only(*objects)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_add()
        message = str(raised.exception)
        self.assertIn(expected_text.lower(), message.lower())
        self.assertIn("Nothing was changed", message)
        self.assertEqual([helpers.object_snapshot(obj) for obj in watched], before)
        self.assertEqual(node_group_count(), 0)
        for obj in watched:
            if obj.type == 'MESH':
                self.assertEqual(obj.lvp.bind_id, "")
        return message

    def test_not_a_mesh(self):
        empty = helpers.link(bpy.data.objects.new("Empty", None))
        self.assertAddFails([empty], "Empty is not a mesh (it is an empty object)", [])

    def test_armature_alone(self):
        rig = helpers.two_bone_armature()
        self.assertAddFails([rig], "not a mesh", [])

    def test_no_armature_modifier(self):
        obj = helpers.link(bpy.data.objects.new("Plain", helpers.cylinder_mesh("Plain")))
        message = self.assertAddFails([obj], "no Armature modifier", [obj])
        self.assertIn("Ctrl+P", message)

    def test_armature_modifier_without_object(self):
        obj, rig = helpers.make_cylinder_character()
        obj.modifiers["Armature"].object = None
        self.assertAddFails([obj], "has no armature object", [obj])

    def test_no_vertex_group_matches_a_deforming_bone(self):
        obj, rig = helpers.make_cylinder_character()
        obj.vertex_groups["Lower"].name = "Something"
        obj.vertex_groups["Upper"].name = "Else"
        self.assertAddFails([obj], "No vertex group", [obj])

    def test_bones_not_deforming(self):
        obj, rig = helpers.make_cylinder_character()
        for bone in rig.data.bones:
            bone.use_deform = False
        self.assertAddFails([obj], "No vertex group", [obj])

    def test_already_added(self):
        obj, rig = helpers.make_cylinder_character()
        self.assertEqual(helpers.add_volume_preservation(obj), {'FINISHED'})
        before = helpers.object_snapshot(obj)
        bind_id = obj.lvp.bind_id
        helpers.select_only(obj)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_add()
        self.assertIn("already has", str(raised.exception))
        self.assertEqual(helpers.object_snapshot(obj), before)
        self.assertEqual(obj.lvp.bind_id, bind_id)

    def test_modifier_before_armature_adds_vertices(self):
        # Mirror before the Armature modifier: what reaches Volume Preservation is not the bound mesh.
        obj, rig = helpers.make_cylinder_character()
        mirror = obj.modifiers.new("Mirror", 'MIRROR')
        mirror.use_mirror_merge = False
        helpers.modifier_operator(obj, "modifier_move_to_index", modifier="Mirror", index=0)
        self.assertEqual([modifier.type for modifier in obj.modifiers], ['MIRROR', 'ARMATURE'])
        message = self.assertAddFails([obj], "Cylinder cannot be corrected", [obj])
        self.assertIn("before the Armature modifier adds vertices", message)

    def test_one_bad_object_changes_nothing_on_the_good_one(self):
        good, rig = helpers.make_cylinder_character("Good")
        bad = helpers.link(bpy.data.objects.new("Bad", helpers.cylinder_mesh("Bad")))
        self.assertAddFails([good, bad], "Bad has no Armature modifier", [good, bad])

    def test_no_faces(self):
        obj, rig = helpers.make_cylinder_character()
        mesh = obj.data
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bmesh.ops.delete(bm, geom=list(bm.faces), context='FACES_ONLY')
        bm.to_mesh(mesh)
        bm.free()
        self.assertAddFails([obj], "no faces", [obj])


class TestBindAndRemove(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.obj, self.rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(self.rig, {1: 0.0, 10: 90.0})
        self.triangles = helpers.mesh_triangles(self.obj.data)
        self.rest_volume = helpers.volume(helpers.mesh_positions(self.obj.data), self.triangles)

    def errors(self):
        """(corrected, plain) volume errors of the evaluated cylinder against its rest."""
        return helpers.volume_errors(self.obj, self.triangles, self.rest_volume)

    def test_remove_leaves_the_mesh_exactly_as_it_was(self):
        smooth = self.obj.modifiers.new("Smooth", 'SMOOTH')  # another modifier, after the Armature
        smooth.factor = 0.25
        before = helpers.object_snapshot(self.obj)
        active_colour = self.obj.data.color_attributes.new("Paint", 'BYTE_COLOR', 'CORNER')
        self.obj.data.color_attributes.active_color = active_colour
        before = helpers.object_snapshot(self.obj)
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})
        self.assertEqual([modifier.name for modifier in self.obj.modifiers],
                         ["Armature", "Volume Preservation", "Smooth"])
        for frame in (3, 7, 10):
            bpy.context.scene.frame_set(frame)
        self.obj.lvp.display = 'SEGMENTATION'
        self.obj.lvp.display = 'CORRECTION_MAP'
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_remove(), {'FINISHED'})
        self.assertEqual(helpers.object_snapshot(self.obj), before)
        self.assertEqual(self.obj.data.color_attributes.active_color.name, "Paint")
        self.assertEqual(node_group_count(), 0)
        self.assertEqual(self.obj.lvp.bind_id, "")
        bpy.context.scene.frame_set(9)
        self.assertEqual(helpers.object_snapshot(self.obj), before)

    def test_add_keeps_skin_apart_in_the_viewport(self):
        # Add turns Keep Skin Apart on in the viewport, so that it shows what renders. A game character's few
        # thousand vertices take it for a few milliseconds a frame, even while the animation plays; a denser mesh
        # has it only on a still frame, and past 20,000 vertices not at all, where each update of a pose would
        # take tens of milliseconds (its cost, README). Either way the Render setting stays on.
        characters = []
        for name, rings, around in (("Dense", 64, 64), ("Denser", 160, 128)):
            character = helpers.link(bpy.data.objects.new(name, helpers.cylinder_mesh(name, rings=rings,
                                                                                      around=around)))
            helpers.weight_linear_band(character)
            helpers.add_armature_modifier(character, self.rig, False)
            character.parent = self.rig
            characters.append(character)
        dense, denser = characters
        bpy.context.view_layer.update()
        helpers.select_only(self.obj, dense, denser)
        self.assertEqual(bpy.ops.object.lvp_add(), {'FINISHED'})
        self.assertLessEqual(len(self.obj.data.vertices), 3000)
        self.assertTrue(3000 < len(dense.data.vertices) <= 20000)
        self.assertGreater(len(denser.data.vertices), 20000)
        self.assertEqual([(obj.lvp.keep_apart, obj.lvp.keep_apart_paused_only) for obj in (self.obj, dense, denser)],
                         [(True, False), (True, True), (False, True)])
        self.assertTrue(all(obj.lvp.keep_apart_render for obj in (self.obj, dense, denser)))
        # Bind again leaves the animator's choice as it is.
        self.obj.lvp.keep_apart = False
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        self.assertFalse(self.obj.lvp.keep_apart)

    def test_remove_after_applying_the_modifier(self):
        # Applying Volume Preservation (Ctrl A) bakes this frame's shape and makes the captured
        # attributes real; Remove then takes those away too.
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})
        bpy.context.scene.frame_set(10)
        helpers.modifier_operator(self.obj, "modifier_apply", modifier="Volume Preservation")
        self.assertIsNotNone(self.obj.data.attributes.get("lvp_position"))
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_remove(), {'FINISHED'})
        left = [attribute.name for attribute in self.obj.data.attributes if attribute.name.startswith("lvp_")]
        self.assertEqual(left, [])

    def test_remove_keeps_the_node_group_while_used(self):
        second, _rig = helpers.make_cylinder_character("Second", rig=self.rig, location=(2.0, 0.0, 0.0))
        helpers.select_only(self.obj, second)
        self.assertEqual(bpy.ops.object.lvp_add(), {'FINISHED'})
        self.assertEqual(node_group_count(), 1)
        helpers.select_only(second)
        bpy.ops.object.lvp_remove()
        self.assertEqual(node_group_count(), 1)
        helpers.select_only(self.obj)
        bpy.ops.object.lvp_remove()
        self.assertEqual(node_group_count(), 0)

    def test_remove_and_bind_without_modifier_report_errors(self):
        helpers.select_only(self.obj)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_remove()
        self.assertIn("nothing to remove", str(raised.exception))
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_bind()
        self.assertIn("Add Volume Preservation first", str(raised.exception))

    def test_bind_in_weight_paint_mode(self):
        # Rebinding right after painting weights, without leaving Weight Paint Mode.
        helpers.add_volume_preservation(self.obj)
        bind_id = self.obj.lvp.bind_id
        bpy.context.view_layer.objects.active = self.obj
        bpy.ops.object.mode_set(mode='WEIGHT_PAINT')
        try:
            self.obj.vertex_groups["Upper"].add([0], 0.5, 'REPLACE')
            self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
            self.assertNotEqual(self.obj.lvp.bind_id, bind_id)
        finally:
            bpy.ops.object.mode_set(mode='OBJECT')

    def test_topology_changed_after_bind_passes_through(self):
        helpers.add_volume_preservation(self.obj)
        bpy.context.scene.frame_set(10)
        self.assertSmallerThan(self.errors()[0], 0.01, "before the edit")
        weights_before = helpers.object_snapshot(self.obj)["vertex_groups"]
        mesh = self.obj.data
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bm.edges.ensure_lookup_table()
        bmesh.ops.subdivide_edges(bm, edges=[bm.edges[40]], cuts=1, use_grid_fill=True)
        bm.to_mesh(mesh)
        bm.free()
        mesh.update()
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "rebind needed")
        offsets = helpers.offsets_of(self.obj)
        self.assertSmallerThan(helpers.max_abs(offsets), 1e-9, "pass-through offsets")
        for frame in (9, 10):
            bpy.context.scene.frame_set(frame)
        self.assertStatusContains(self.obj, "rebind needed")
        plain = helpers.uncorrected_positions(self.obj)
        self.assertSmallerThan(helpers.max_distance(helpers.evaluated_positions(self.obj), plain), 1e-9,
                               "the modifier passes the mesh through")
        # Weights and the other data are untouched.
        self.assertEqual(len(helpers.object_snapshot(self.obj)["vertex_groups"]), len(weights_before))
        # Binding again fixes it.
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_bind(), {'FINISHED'})
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        self.assertEqual(self.status_of(self.obj)[0], 'INFO')
        self.triangles = helpers.mesh_triangles(mesh)
        self.rest_volume = helpers.volume(helpers.mesh_positions(mesh), self.triangles)
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after rebinding")

    def test_same_counts_but_reconnected_needs_rebind(self):
        helpers.add_volume_preservation(self.obj)
        bpy.context.scene.frame_set(10)
        mesh = self.obj.data
        counts = (len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops))
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bmesh.ops.triangulate(bm, faces=list(bm.faces)[:1])
        bmesh.ops.rotate_edges(bm, edges=[edge for edge in bm.edges if len(edge.link_faces) == 2
                                          and all(len(face.verts) == 3 for face in edge.link_faces)][:1])
        bmesh.ops.join_triangles(bm, faces=list(bm.faces), angle_face_threshold=3.2, angle_shape_threshold=3.2)
        bm.to_mesh(mesh)
        bm.free()
        mesh.update()
        self.assertEqual((len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops)), counts)
        bpy.context.view_layer.update()
        self.assertStatusContains(self.obj, "rebind needed")

    def test_armature_deleted_after_bind(self):
        helpers.add_volume_preservation(self.obj)
        bpy.context.scene.frame_set(10)
        bpy.data.objects.remove(self.rig)
        bpy.context.scene.frame_set(9)
        self.assertEqual(self.status_of(self.obj)[0], 'ERROR')
        self.assertSmallerThan(helpers.max_abs(helpers.offsets_of(self.obj)), 1e-9, "pass-through")
        self.assertEqual(len(self.obj.vertex_groups), 2)

    def test_bone_renamed_after_bind(self):
        helpers.add_volume_preservation(self.obj)
        bpy.context.scene.frame_set(10)
        self.rig.data.bones["Upper"].name = "Renamed"  # Blender renames the vertex group "Upper" too
        self.assertIn("Renamed", self.obj.vertex_groups)
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        self.assertStatusContains(self.obj, "bound again by itself: the deforming bones with a vertex group changed")
        bound = self.addon.session.SESSION.bound(self.obj)
        self.assertEqual(bound.skeleton.bone_names, ["Lower", "Renamed"])
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after the rename")

    def test_edit_mode_pauses(self):
        helpers.add_volume_preservation(self.obj)
        bpy.context.scene.frame_set(10)
        bpy.context.view_layer.objects.active = self.obj
        bpy.ops.object.mode_set(mode='EDIT')
        bpy.context.scene.frame_set(9)
        self.assertStatusContains(self.obj, "Edit Mode")
        bpy.ops.object.mode_set(mode='OBJECT')
        bpy.context.scene.frame_set(10)
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after Edit Mode")

    def test_undo_and_redo(self):
        before = helpers.object_snapshot(self.obj)
        bpy.ops.ed.undo_push(message="before")
        helpers.add_volume_preservation(self.obj)
        bpy.ops.ed.undo_push(message="added")
        bpy.context.scene.frame_set(10)
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after add")
        bpy.ops.ed.undo()
        obj = bpy.data.objects["Cylinder"]
        self.assertIsNone(self.addon.node_group.find_modifier(obj))
        self.assertEqual(helpers.object_snapshot(obj), before)
        bpy.ops.ed.redo()
        self.obj = bpy.data.objects["Cylinder"]
        self.rig = bpy.data.objects["CylinderRig"]
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after redo")
        # Undo a removal.
        helpers.select_only(self.obj)
        bpy.ops.object.lvp_remove()
        bpy.ops.ed.undo_push(message="removed")
        bpy.ops.ed.undo()
        self.obj = bpy.data.objects["Cylinder"]
        self.assertIsNotNone(self.addon.node_group.find_modifier(self.obj))
        bpy.context.scene.frame_set(8)
        bpy.context.scene.frame_set(10)
        corrected, plain = self.errors()
        self.assertSmallerThan(corrected, 0.1 * plain, "after undoing the removal")


class TestNodeGroup(helpers.AddonTestCase):

    def test_edited_node_group_is_rebuilt_on_load(self):
        import os
        obj, rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(rig, {1: 0.0, 10: 90.0})
        helpers.add_volume_preservation(obj)
        group = self.addon.node_group.find_modifier(obj).node_group
        self.assertTrue(self.addon.node_group.is_current(group))
        group.links.remove(group.links[0])  # someone edited it by hand
        self.assertFalse(self.addon.node_group.is_current(group))
        path = os.path.join(helpers.fresh_directory("group"), "edited.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
        bpy.ops.wm.open_mainfile(filepath=path)
        obj = bpy.data.objects["Cylinder"]
        modifier = self.addon.node_group.find_modifier(obj)
        self.assertTrue(self.addon.node_group.is_current(modifier.node_group))
        self.assertEqual(node_group_count(), 1)
        bpy.context.scene.frame_set(10)
        self.assertGreater(helpers.max_abs(helpers.offsets_of(obj)), 0.01)
        self.assertEqual(self.status_of(obj)[0], 'INFO')


class TestAutoWeights(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.rig = helpers.two_bone_armature()
        self.obj = helpers.link(bpy.data.objects.new("Cylinder", helpers.cylinder_mesh()))
        self.obj.parent = self.rig
        helpers.add_armature_modifier(self.obj, self.rig)
        keep = self.obj.vertex_groups.new(name="Keep")
        keep.add([0, 1, 2], 0.5, 'REPLACE')
        bpy.context.view_layer.update()

    def weights(self, group_name):
        group = self.obj.vertex_groups[group_name]
        result = {}
        for vertex in self.obj.data.vertices:
            for element in vertex.groups:
                if element.group == group.index:
                    result[vertex.index] = element.weight
        return result

    def check_weights(self):
        lower = self.weights("Lower")
        upper = self.weights("Upper")
        for vertex in self.obj.data.vertices:
            total = lower.get(vertex.index, 0.0) + upper.get(vertex.index, 0.0)
            self.assertAlmostEqual(total, 1.0, places=4)
            if vertex.co.z < 0.3:
                self.assertGreater(lower.get(vertex.index, 0.0), 0.8)
            if vertex.co.z > 3.7:
                self.assertGreater(upper.get(vertex.index, 0.0), 0.8)
        self.assertEqual(self.weights("Keep"), {0: 0.5, 1: 0.5, 2: 0.5})

    def test_normal_and_exact_tests(self):
        helpers.select_only(self.obj)
        for visibility in ('NORMAL', 'EXACT'):
            self.assertEqual(bpy.ops.object.lvp_auto_weights(visibility=visibility), {'FINISHED'})
            self.check_weights()
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})
        helpers.keyframe_bend(self.rig, {1: 0.0, 10: 90.0})
        bpy.context.scene.frame_set(10)
        corrected, plain = helpers.volume_errors(self.obj)
        self.assertSmallerThan(corrected, 0.1 * plain, "with automatic weights")

    def select_bones(self, *names):
        """Selects these bones of the rig (a pose bone's state from 5.0 on, the bone's before)."""
        for bone in self.rig.data.bones:
            pose_bone = self.rig.pose.bones[bone.name]
            holder = pose_bone if hasattr(pose_bone, "select") else bone
            holder.select = bone.name in names

    def test_selected_bones_only(self):
        self.obj.vertex_groups.new(name="Upper").add([5, 6], 0.25, 'REPLACE')
        self.select_bones("Lower")
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_auto_weights(bones='SELECTED'), {'FINISHED'})
        lower = self.weights("Lower")
        self.assertEqual(len(lower), len(self.obj.data.vertices), "the selected bone weights every vertex")
        self.assertTrue(all(abs(weight - 1.0) < 1e-6 for weight in lower.values()))
        self.assertEqual(self.weights("Upper"), {5: 0.25, 6: 0.25}, "the bone not selected is left as it was")
        self.assertEqual(self.weights("Keep"), {0: 0.5, 1: 0.5, 2: 0.5})
        self.select_bones()
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_auto_weights(bones='SELECTED')
        self.assertIn("No deforming bone of Rig is selected", str(raised.exception))
        self.assertEqual(self.weights("Upper"), {5: 0.25, 6: 0.25})

    def put_in_collection(self, bone_name, collection_name):
        """A bone collection from 4.0 on, a bone group before (blender_api.bone_collections)."""
        if hasattr(self.rig.data, "collections"):
            self.rig.data.collections.new(collection_name).assign(self.rig.data.bones[bone_name])
        else:
            self.rig.pose.bones[bone_name].bone_group = self.rig.pose.bone_groups.new(name=collection_name)

    def test_bone_collections(self):
        self.obj.vertex_groups.new(name="Upper").add([5, 6], 0.25, 'REPLACE')
        self.put_in_collection("Lower", "Legs")
        self.put_in_collection("Upper", "Arms")
        helpers.select_only(self.obj)
        self.assertEqual(bpy.ops.object.lvp_auto_weights(bones='COLLECTIONS', collections=" Legs "), {'FINISHED'})
        lower = self.weights("Lower")
        self.assertEqual(len(lower), len(self.obj.data.vertices), "the bone in Legs weights every vertex")
        self.assertEqual(self.weights("Upper"), {5: 0.25, 6: 0.25}, "the bone in Arms is left as it was")
        self.assertEqual(bpy.ops.object.lvp_auto_weights(bones='COLLECTIONS', collections="Legs,Arms"), {'FINISHED'})
        self.check_weights()
        for collections, message in (("Tail", "Rig has no bone collection named 'Tail' (it has: Arms, "),
                                     ("", "needs the names of bone collections")):
            with self.assertRaises(RuntimeError) as raised:
                bpy.ops.object.lvp_auto_weights(bones='COLLECTIONS', collections=collections)
            self.assertIn(message, str(raised.exception))
        self.rig.data.bones["Lower"].use_deform = False
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_auto_weights(bones='COLLECTIONS', collections="Legs")
        self.assertIn("No deforming bone of Rig is in 'Legs'", str(raised.exception))

    def test_undo_restores_previous_weights(self):
        bpy.ops.ed.undo_push(message="before")
        helpers.select_only(self.obj)
        bpy.ops.object.lvp_auto_weights()
        bpy.ops.ed.undo_push(message="weights")
        self.assertIn("Lower", self.obj.vertex_groups)
        bpy.ops.ed.undo()
        obj = bpy.data.objects["Cylinder"]
        self.assertEqual([group.name for group in obj.vertex_groups], ["Keep"])

    def test_errors(self):
        plain = helpers.link(bpy.data.objects.new("Plain", helpers.cylinder_mesh("Plain")))
        helpers.select_only(plain)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.object.lvp_auto_weights()
        self.assertIn("no Armature modifier", str(raised.exception))
        self.assertEqual(len(plain.vertex_groups), 0)


if __name__ == "__main__":
    unittest.main()
