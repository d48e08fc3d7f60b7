# SPDX-License-Identifier: GPL-3.0-or-later
"""Builds the giraffe of tests/data/giraffe (formats in its README.md) as a Blender character: a mesh
object with one vertex group per weighted joint, an armature, and an Armature modifier.

Mesh: the OBJ's `v` lines in order (vertex k is the k-th `v`) and its faces (quads, triangles and
n-gons), each face reversed because the file winds them inward: the mesh then has outward normals
and a positive volume, like tests/c/support/giraffe_loader.c makes it.

Skeleton: joint j's world frame is its parent's frame times (translation, then rotation x y z w).
Blender bone j runs from joint j's head to the head of one child, chosen like the C loader does:
the only child, or with several children the one whose head lies farthest along joint j's own +X
axis (Maya aims X down the bone), or without children the parent's bone continued by half its
length. Blender drops zero-length bones, so a joint that coincides with its child (the gi_T_*
helpers, gi_root; none carries weight) gets a short bone along its own +X axis. Weighted joints
are deforming bones; the others are not.
"""

import os

import bpy
from mathutils import Matrix, Quaternion, Vector

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(os.path.dirname(HERE), "data", "giraffe")


def _numbers(line):
    return [float(value) for value in line.split()]


def read_giraffe(directory=DATA):
    """Plain Python data: vertices, faces, joint names, parents, local frames, per-vertex weights."""
    vertices = []
    faces = []
    with open(os.path.join(directory, "mesh.obj")) as file:
        for line in file:
            if line.startswith("v "):
                vertices.append(tuple(float(value) for value in line.split()[1:4]))
            elif line.startswith("f "):
                faces.append(tuple(int(corner.split("/")[0]) - 1 for corner in line.split()[1:]))

    def lines(name):
        with open(os.path.join(directory, name)) as file:
            return [line.strip() for line in file.read().splitlines()]

    names = [line for line in lines("skeleton_joint_name") if line]
    parents = [int(value) for value in " ".join(lines("skeleton_connectivity_parent")).split()]
    translations = [_numbers(line) for line in lines("skeleton_rest_pose_translation") if line]
    rotations = [_numbers(line) for line in lines("skeleton_rest_pose_rotation") if line]
    joints_per_vertex = [[int(value) for value in line.split()] for line in lines("rig_joint")[:len(vertices)]]
    weights_per_vertex = [_numbers(line) for line in lines("rig_weights")[:len(vertices)]]
    assert len(names) == len(parents) == len(translations) == len(rotations), "inconsistent skeleton files"
    assert len(joints_per_vertex) == len(vertices) == len(weights_per_vertex), "inconsistent weight files"
    return {
        "vertices": vertices, "faces": faces, "names": names, "parents": parents,
        "translations": translations, "rotations": rotations,
        "joints": joints_per_vertex, "weights": weights_per_vertex,
    }


def joint_world_frames(data):
    frames = []
    for joint, parent in enumerate(data["parents"]):
        x, y, z, w = data["rotations"][joint]
        local = Matrix.Translation(Vector(data["translations"][joint])) @ Quaternion((w, x, y, z)).to_matrix().to_4x4()
        frames.append(local if parent < 0 else frames[parent] @ local)
    return frames


def bone_segments(data, frames):
    """(head, tail) per joint, as described at the top of this file."""
    count = len(data["names"])
    children = [[] for _ in range(count)]
    for joint, parent in enumerate(data["parents"]):
        if parent >= 0:
            children[parent].append(joint)
    heads = [frame.to_translation() for frame in frames]
    segments = []
    for joint in range(count):
        head = heads[joint]
        axis = frames[joint].to_3x3() @ Vector((1.0, 0.0, 0.0))
        if len(children[joint]) == 1:
            tail = heads[children[joint][0]]
        elif children[joint]:
            tail = heads[max(children[joint], key=lambda child: (heads[child] - head).dot(axis))]
        else:
            parent = data["parents"][joint]
            tail = head + (head - heads[parent]) / 2 if parent >= 0 else head + axis * 0.05
        segments.append((head, tail))
    # Zero-length bones (a helper joint on top of its child): a short bone along the joint's +X.
    lengths = [(tail - head).length for head, tail in segments]
    typical = sorted(length for length in lengths if length > 1e-6)[len(lengths) // 2] if any(lengths) else 0.05
    for joint, (head, tail) in enumerate(segments):
        if (tail - head).length < 1e-4:
            axis = frames[joint].to_3x3() @ Vector((1.0, 0.0, 0.0))
            segments[joint] = (head, head + axis.normalized() * 0.25 * typical)
    return segments


def build_giraffe(name="Giraffe", directory=DATA):
    """(mesh object, armature object), linked to the scene, the mesh parented to the armature."""
    data = read_giraffe(directory)
    frames = joint_world_frames(data)
    segments = bone_segments(data, frames)
    weighted = set()
    for joints in data["joints"]:
        weighted.update(joints)

    armature = bpy.data.armatures.new(name + "Rig")
    rig = bpy.data.objects.new(name + "Rig", armature)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    edit_bones = []
    for joint, joint_name in enumerate(data["names"]):
        bone = armature.edit_bones.new(joint_name)
        bone.head, bone.tail = segments[joint]
        bone.use_deform = joint in weighted
        edit_bones.append(bone)
    for joint, parent in enumerate(data["parents"]):
        if parent >= 0:
            edit_bones[joint].parent = edit_bones[parent]
    bpy.ops.object.mode_set(mode='OBJECT')

    mesh = bpy.data.meshes.new(name)
    faces = [tuple(reversed(face)) for face in data["faces"]]
    mesh.from_pydata(data["vertices"], [], faces)
    mesh.validate()
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    groups = {}
    for vertex, (joints, weights) in enumerate(zip(data["joints"], data["weights"])):
        for joint, weight in zip(joints, weights):
            if weight <= 0.0:
                continue
            group = groups.get(joint)
            if group is None:
                group = groups[joint] = obj.vertex_groups.new(name=data["names"][joint])
            group.add([vertex], weight, 'REPLACE')
    modifier = obj.modifiers.new("Armature", 'ARMATURE')
    modifier.object = rig
    obj.parent = rig
    bpy.context.view_layer.update()
    return obj, rig
