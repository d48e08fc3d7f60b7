# SPDX-License-Identifier: GPL-3.0-or-later
"""Rigs that come through Blender's own FBX and glTF round trips: exported, imported back, Volume
Preservation added to the imported character, the animation played. Importers rebuild the bones
(FBX adds "_end" leaf bones, both may change the bones' rolls and rest frames) and the parenting;
the correction must follow what the Armature modifier does with them: the shown volume within
0.1 % of the rest at every frame, measured without the fallback for positions that are not the
bound skinning (lvp.h, stats.unskinned_distance), and the panel's "after" the shown volume.
"""

import math
import os
import unittest

import addon_utils
import bpy
from mathutils import Quaternion

import lvp_helpers as helpers
import real_cases

BONES = 11
LENGTH = 4.0
FRAMES = (1, 5, 7, 9, 13, 21, 30, 40)


def chain_character():
    """A coarse tube (10 rings of 6) along a chain of BONES bones, each joint's weights blending
    linearly over one bone length, the mesh parented to the armature; every bone turns, back and
    forth, over 40 frames (rotations only)."""
    armature = bpy.data.armatures.new("Chain")
    rig = helpers.link(bpy.data.objects.new("Chain", armature))
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    step = LENGTH / BONES
    previous = None
    for index in range(BONES):
        bone = armature.edit_bones.new("Bone%02d" % index)
        bone.head, bone.tail = (0.0, 0.0, index * step), (0.0, 0.0, (index + 1) * step)
        if previous is not None:
            bone.parent, bone.use_connect = previous, True
        previous = bone
    bpy.ops.object.mode_set(mode='OBJECT')
    obj = helpers.link(bpy.data.objects.new("Tube", helpers.cylinder_mesh("Tube", rings=10, around=6)))
    # Smooth: glTF stores normals per vertex, and splits the vertices of a flat-shaded mesh at its
    # sharp edges (a mesh of separate pieces, whose seams are not what this test is about).
    obj.data.polygons.foreach_set("use_smooth", [True] * len(obj.data.polygons))
    groups = [obj.vertex_groups.new(name="Bone%02d" % index) for index in range(BONES)]
    for vertex in obj.data.vertices:
        position = vertex.co.z / step - 0.5
        lower = max(0, min(BONES - 2, int(math.floor(position))))
        blend = min(max(position - lower, 0.0), 1.0)
        groups[lower].add([vertex.index], 1.0 - blend, 'REPLACE')
        groups[lower + 1].add([vertex.index], blend, 'REPLACE')
    helpers.add_armature_modifier(obj, rig)
    obj.parent = rig
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 40
    for frame, degrees in ((1, 0.0), (10, 25.0), (20, 40.0), (40, -15.0)):
        for index in range(1, BONES):
            pose_bone = rig.pose.bones["Bone%02d" % index]
            pose_bone.rotation_mode = 'QUATERNION'
            axis = (1.0, 0.0, 0.0) if index % 3 else (0.0, 1.0, 0.0)
            pose_bone.rotation_quaternion = Quaternion(axis, math.radians(degrees * (1.0 if index % 2 else -0.6)))
            pose_bone.keyframe_insert("rotation_quaternion", frame=frame)
    return obj, rig


class RoundTripTestCase(helpers.AddonTestCase):

    def round_trip(self, export, import_, extension):
        chain_character()
        path = os.path.join(helpers.fresh_directory("round-trip"), "chain" + extension)
        bpy.ops.object.select_all(action='SELECT')
        export(path)
        helpers.reset_scene()
        import_(path)
        # (glTF's importer also makes a mesh to display bones with: not a skinned one.)
        meshes = [obj for obj in bpy.data.objects
                  if obj.type == 'MESH' and any(modifier.type == 'ARMATURE' for modifier in obj.modifiers)]
        self.assertEqual(len(meshes), 1, [obj.name for obj in bpy.data.objects])
        return meshes[0]

    def assertCorrectedAtEveryFrame(self, obj, what):
        scene = bpy.context.scene
        scene.frame_set(1)
        helpers.select_only(obj)
        self.assertEqual(bpy.ops.object.lvp_add(), {'FINISHED'})
        triangles = helpers.mesh_triangles(obj.data)
        rest = helpers.volume(helpers.mesh_positions(obj.data), triangles)
        worst_plain = 0.0
        for frame in FRAMES:
            scene.frame_set(frame)
            level, status = self.status_of(obj)
            self.assertTrue(status.startswith("Correcting") and level == 'INFO', "%s, frame %d: %r" % (what, frame, status))
            stats = self.addon.session.SESSION.bound(obj).stats
            self.assertEqual(stats["unskinned_distance"], 0.0, "%s, frame %d: the bound skinning" % (what, frame))
            shown = helpers.volume(helpers.evaluated_positions(obj), triangles)
            self.assertSmallerThan(abs(shown / rest - 1.0), 1e-3, "%s, frame %d: shown volume" % (what, frame))
            self.assertSmallerThan(abs(stats["volume_after"] / shown - 1.0), 1e-5, "%s, frame %d: the panel's "
                                   "after against the shown volume" % (what, frame))
            worst_plain = max(worst_plain, abs(stats["volume_before"] / rest - 1.0))
        self.assertGreater(worst_plain, 0.05, "%s: plain skinning loses volume in this animation" % what)


class TestFBX(RoundTripTestCase):

    def setUp(self):
        super().setUp()
        if addon_utils.enable("io_scene_fbx", default_set=False) is None:
            self.skipTest("this Blender has no FBX add-on")

    def test_fbx_round_trip(self):
        obj = self.round_trip(
            lambda path: bpy.ops.export_scene.fbx(filepath=path, add_leaf_bones=True, bake_anim=True),
            lambda path: bpy.ops.import_scene.fbx(filepath=path), ".fbx")
        rig = obj.parent
        self.assertIsNotNone(rig)
        self.assertIn("Bone%02d_end" % (BONES - 1), rig.data.bones, "FBX's leaf bone")
        self.assertCorrectedAtEveryFrame(obj, "FBX")

    def test_fbx_round_trip_in_centimetres(self):
        obj = self.round_trip(
            lambda path: bpy.ops.export_scene.fbx(filepath=path, add_leaf_bones=True, bake_anim=True,
                                                  global_scale=0.01),
            lambda path: bpy.ops.import_scene.fbx(filepath=path, automatic_bone_orientation=True), ".fbx")
        self.assertAlmostEqual(obj.parent.matrix_world.to_scale().x, 0.01, places=4)
        self.assertCorrectedAtEveryFrame(obj, "FBX at 0.01, bones oriented by the importer")


class TestGLTF(RoundTripTestCase):

    def setUp(self):
        super().setUp()
        if not real_cases.enable_gltf():
            self.skipTest("this Blender cannot import glTF here (real_cases.enable_gltf says why)")

    def test_gltf_round_trip(self):
        obj = self.round_trip(
            lambda path: bpy.ops.export_scene.gltf(filepath=path, export_format='GLB', export_animations=True),
            lambda path: bpy.ops.import_scene.gltf(filepath=path), ".glb")
        self.assertCorrectedAtEveryFrame(obj, "glTF")


if __name__ == "__main__":
    unittest.main()
