# SPDX-License-Identifier: GPL-3.0-or-later
"""The paper's giraffe (tests/data/giraffe, built by giraffe_import.py): 1673 vertices, 44 weighted
joints of 59. Bending the neck, the knees and the tail loses volume under plain skinning (paper
Table 2: 10 % -> 3 %); Volume Preservation must give it back, and leave alone what is far from every
bent joint."""

import math
import unittest

import bpy
from mathutils import Quaternion, Vector

import giraffe_import
import lvp_helpers as helpers

BENDS = (  # each of these loses volume under plain skinning; together about 10 %, like the paper's
    ("gi_neckC7", (1.0, 0.0, 0.0), 60.0),
    ("gi_L_knee", (0.0, 0.0, 1.0), -60.0),
    ("gi_R_knee", (0.0, 0.0, 1.0), 60.0),
    ("gi_tailA", (1.0, 0.0, 0.0), -60.0),
)


def pose(rig, bone_name, axis, degrees):
    pose_bone = rig.pose.bones[bone_name]
    pose_bone.rotation_mode = 'QUATERNION'
    pose_bone.rotation_quaternion = Quaternion(Vector(axis), math.radians(degrees))


class TestGiraffe(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.obj, self.rig = giraffe_import.build_giraffe()
        self.triangles = helpers.mesh_triangles(self.obj.data)
        self.rest_volume = helpers.volume(helpers.mesh_positions(self.obj.data), self.triangles)
        self.assertGreater(self.rest_volume, 0.0, "the importer should wind the faces outward")
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})

    def test_import(self):
        self.assertEqual(len(self.obj.data.vertices), 1673)
        self.assertEqual(len(self.rig.data.bones), 59)
        self.assertEqual(len(self.obj.vertex_groups), 44)

    def test_offsets_zero_at_rest(self):
        bpy.context.view_layer.update()
        self.assertSmallerThan(helpers.max_abs(helpers.offsets_of(self.obj)), 1e-6, "offsets at rest")

    def test_volume_error_below_plain_skinning(self):
        for bone_name, axis, degrees in BENDS:
            pose(self.rig, bone_name, axis, degrees)
        bpy.context.view_layer.update()
        corrected, plain = helpers.volume_errors(self.obj, self.triangles, self.rest_volume)
        print("\n    giraffe, neck + knees + tail bent: volume error %.3f %% plain, %.4f %% corrected"
              % (100 * plain, 100 * corrected))
        self.assertGreater(plain, 0.05)
        self.assertSmallerThan(corrected, 0.1 * plain, "corrected vs plain volume error")
        status = self.status_of(self.obj)
        self.assertEqual(status[0], 'INFO', status)

    def test_far_parts_do_not_move(self):
        bone_name = "gi_L_knee"
        pose(self.rig, bone_name, (1.0, 0.0, 0.0), 70.0)
        bpy.context.view_layer.update()
        corrected = helpers.evaluated_positions(self.obj)
        plain = helpers.uncorrected_positions(self.obj)
        distances = helpers.vertex_distances(corrected, plain)
        knee = self.rig.data.bones[bone_name].head_local  # armature and mesh share the world frame here
        far = [vertex.index for vertex in self.obj.data.vertices if (vertex.co - knee).length > 0.3]
        self.assertGreater(len(far), 600)
        self.assertSmallerThan(max(distances[index] for index in far), 1e-6,
                               "displacement of vertices far from the bent knee")
        self.assertGreater(max(distances), 1e-3, "the knee should be corrected")

    def test_many_single_joint_poses(self):
        """Every major joint bent by 60 degrees both ways about two axes: the correction never makes the
        volume worse, never trips the add-on's divergence safety net, and stays a small displacement:
        below 0.225, a fifth of the giraffe's 1.13 bounding-box diagonal (a shoulder bent 60 degrees
        loses 6 % of the whole body's volume, which comes back as a bulge of about 0.2 at the shoulder:
        measured over the surface, the correction no longer spreads it over the torso's few large
        triangles, docs/method.md; the safety net is at a quarter of the diagonal)."""
        failures = []
        names = ("gi_neckC7", "gi_neckC4", "gi_head", "gi_L_shoulder", "gi_L_elbow", "gi_R_elbow", "gi_L_hip",
                 "gi_L_knee", "gi_R_knee", "gi_tailA", "gi_tailB")
        for bone_name in names:
            for axis in ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)):
                for degrees in (60.0, -60.0):
                    for pose_bone in self.rig.pose.bones:
                        pose_bone.rotation_mode = 'QUATERNION'
                        pose_bone.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
                    pose(self.rig, bone_name, axis, degrees)
                    bpy.context.view_layer.update()
                    corrected = helpers.evaluated_positions(self.obj)
                    plain = helpers.uncorrected_positions(self.obj)
                    corrected_error = helpers.relative_volume_error(corrected, self.triangles, self.rest_volume)
                    plain_error = helpers.relative_volume_error(plain, self.triangles, self.rest_volume)
                    status = self.status_of(self.obj)
                    moved = helpers.max_distance(corrected, plain)
                    if status[0] != 'INFO' or corrected_error > max(0.5 * plain_error, 1e-3) or moved > 0.225:
                        failures.append("%s %s %+g: volume error %.4f%% plain, %.4f%% corrected, largest offset "
                                        "%.3f, status %r" % (bone_name, axis, degrees, 100 * plain_error,
                                                             100 * corrected_error, moved, status))
        self.assertEqual(failures, [], "\n".join(failures))

    def test_subdivision_and_animation(self):
        subdivision = self.obj.modifiers.new("Subdivision", 'SUBSURF')
        subdivision.levels = 1
        scene = bpy.context.scene
        for frame, degrees in ((1, 0.0), (10, 70.0)):
            pose(self.rig, "gi_L_knee", (1.0, 0.0, 0.0), degrees)
            self.rig.pose.bones["gi_L_knee"].keyframe_insert("rotation_quaternion", frame=frame)
        scene.frame_set(1)
        scene.frame_set(10)
        status = self.status_of(self.obj)
        self.assertEqual(status[0], 'INFO', status)
        self.assertGreater(helpers.max_abs(helpers.offsets_of(self.obj)), 1e-3)


if __name__ == "__main__":
    unittest.main()
