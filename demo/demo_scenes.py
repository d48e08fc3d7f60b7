# SPDX-License-Identifier: GPL-3.0-or-later
"""The demo's characters, built by code: the paper's cylinder, the giraffe of tests/data/giraffe and
a three-phalanx finger. Each is made several times in the same pose: with plain skinning (Armature
modifier only), with Volume Preservation added by the add-on's own operator (object.lvp_add), and for
the measurements with Blender's "Preserve Volume" (dual quaternion skinning).

The cylinder and the giraffe come from the test helpers (tests/blender/lvp_helpers.py,
tests/blender/giraffe_import.py), so the demo shows exactly what the tests measure. The finger is the
one of tests/c/support/test_meshes.c (test_make_finger), rebuilt here in Python.
"""

import math

import bpy
from mathutils import Quaternion, Vector
from mathutils.bvhtree import BVHTree

import giraffe_import
import lvp_helpers as helpers
import real_cases

# The giraffe's pose: neck bent down (forward: it is Y-up and looks along +Z) and the left hind leg
# folded back at the knee.
GIRAFFE_POSE = (
    ("gi_neckC7", (1.0, 0.0, 0.0), 55.0),
    ("gi_neckC4", (1.0, 0.0, 0.0), 30.0),
    ("gi_L_knee", (1.0, 0.0, 0.0), 90.0),
)

# The finger of test_foldover.c: bones along +Y, lengths 1.0, 0.7 and 0.5, radius 0.22, blending over
# bands of 0.2 centred on the knuckles; plain skinning crosses itself from about 50 degrees per knuckle.
FINGER_LENGTHS = (1.0, 0.7, 0.5)
FINGER_RADIUS = 0.22
FINGER_BAND = 0.2
FINGER_AROUND = 16
FINGER_TUBE_RINGS = 40
FINGER_TIP_RINGS = 4
FINGER_BEND = 75.0  # degrees at both knuckles; plain skinning crosses itself from about 50 (test_foldover.c)


def triangles_of(obj):
    return helpers.mesh_triangles(obj.data)


def rest_volume(obj):
    return helpers.volume(helpers.mesh_positions(obj.data), triangles_of(obj))


def volume_change(obj, triangles, rest):
    """Signed relative volume change of the evaluated mesh: (V - V_rest) / V_rest."""
    return (helpers.volume(helpers.evaluated_positions(obj), triangles) - rest) / rest


def set_rotation(rig, bone_name, axis, degrees):
    pose_bone = rig.pose.bones[bone_name]
    pose_bone.rotation_mode = 'QUATERNION'
    pose_bone.rotation_quaternion = Quaternion(Vector(axis), math.radians(degrees))


def add_volume_preservation(obj, fold_over=False):
    """Adds the modifier with the add-on's operator (object.lvp_add), as an animator would."""
    result = helpers.add_volume_preservation(obj)
    if result != {'FINISHED'}:
        raise RuntimeError("object.lvp_add failed on %s: %r" % (obj.name, result))
    obj.lvp.fold_over = fold_over
    # The pictures are renders, which keep skin apart by default; the numbers written on them are measured
    # in this process's viewport depsgraph, so it does the same.
    obj.lvp.keep_apart = obj.lvp.keep_apart_render
    bpy.context.view_layer.update()


def move_rig(rig, location):
    rig.location = location
    bpy.context.view_layer.update()


# ---- the paper's cylinder --------------------------------------------------------------------------


def cylinder_pair(degrees):
    """(plain, corrected): two copies of the paper's cylinder (16 x 16 side vertices, radius 0.5,
    length 4, weights linear over a band of 2.6 around the joint), each bent by `degrees` at the joint
    about the bone's X axis (towards -Y). Both stand at the origin: render one at a time."""
    plain, plain_rig = helpers.make_cylinder_character("CylinderPlain")
    corrected, corrected_rig = helpers.make_cylinder_character("CylinderCorrected")
    add_volume_preservation(corrected)
    for rig in (plain_rig, corrected_rig):
        helpers.bend(rig, degrees)
    bpy.context.view_layer.update()
    return plain, corrected


def cylinder_sweep(angles):
    """Signed relative volume change of the cylinder bent to each angle, for plain skinning, Blender's
    "Preserve Volume" (dual quaternion skinning) and Volume Preservation: {name: [change per angle]}.
    The three stand apart and are removed afterwards."""
    plain, plain_rig = helpers.make_cylinder_character("SweepPlain")
    dual, dual_rig = helpers.make_cylinder_character("SweepPreserveVolume", preserve_volume=True)
    corrected, corrected_rig = helpers.make_cylinder_character("SweepCorrected")
    add_volume_preservation(corrected)
    characters = (("plain", plain, plain_rig), ("preserve_volume", dual, dual_rig),
                  ("corrected", corrected, corrected_rig))
    triangles = triangles_of(plain)
    rest = rest_volume(plain)
    changes = {name: [] for name, _obj, _rig in characters}
    for degrees in angles:
        for _name, _obj, rig in characters:
            helpers.bend(rig, degrees)
        bpy.context.view_layer.update()
        for name, obj, _rig in characters:
            changes[name].append(volume_change(obj, triangles, rest))
    for _name, obj, rig in characters:
        remove_character(obj, rig)
    return changes


def remove_character(obj, rig):
    mesh, armature = obj.data, rig.data
    bpy.data.objects.remove(obj)
    bpy.data.objects.remove(rig)
    bpy.data.meshes.remove(mesh)
    bpy.data.armatures.remove(armature)


# ---- the giraffe ------------------------------------------------------------------------------------


def pose_giraffe(rig, pose=GIRAFFE_POSE):
    for bone_name, axis, degrees in pose:
        set_rotation(rig, bone_name, axis, degrees)


def giraffe_pair():
    """(plain, corrected, dual): the giraffe posed with GIRAFFE_POSE, three times (the third with
    Blender's "Preserve Volume", measured only)."""
    plain, plain_rig = giraffe_import.build_giraffe("GiraffePlain")
    corrected, corrected_rig = giraffe_import.build_giraffe("GiraffeCorrected")
    dual, dual_rig = giraffe_import.build_giraffe("GiraffePreserveVolume")
    dual.modifiers["Armature"].use_deform_preserve_volume = True
    add_volume_preservation(corrected)
    for rig in (plain_rig, corrected_rig, dual_rig):
        pose_giraffe(rig)
    bpy.context.view_layer.update()
    return plain, corrected, dual


# ---- the finger -------------------------------------------------------------------------------------


def finger_mesh(name):
    """A closed tube along +Y with a rounded tip: FINGER_TUBE_RINGS rings from y = 0 to the tip's
    equator, FINGER_TIP_RINGS rings on the tip, a centre vertex closing each end (triangle fans)."""
    tip = sum(FINGER_LENGTHS)
    equator = tip - FINGER_RADIUS
    rings = []
    for ring in range(FINGER_TUBE_RINGS):
        rings.append((equator * ring / (FINGER_TUBE_RINGS - 1), FINGER_RADIUS))
    for ring in range(1, FINGER_TIP_RINGS + 1):
        phi = 0.5 * math.pi * ring / (FINGER_TIP_RINGS + 1)
        rings.append((equator + FINGER_RADIUS * math.sin(phi), FINGER_RADIUS * math.cos(phi)))
    vertices = []
    for y, radius in rings:
        for step in range(FINGER_AROUND):
            angle = 2.0 * math.pi * step / FINGER_AROUND
            # Around +Y, counter-clockwise seen from the tip: (x, z) = (cos, -sin) keeps the winding outward.
            vertices.append((radius * math.cos(angle), y, -radius * math.sin(angle)))
    base = len(vertices)
    vertices.append((0.0, 0.0, 0.0))
    vertices.append((0.0, tip, 0.0))
    faces = []
    for ring in range(len(rings) - 1):
        for step in range(FINGER_AROUND):
            a0 = ring * FINGER_AROUND + step
            a1 = ring * FINGER_AROUND + (step + 1) % FINGER_AROUND
            faces.append((a0, a1, a1 + FINGER_AROUND, a0 + FINGER_AROUND))
    last = (len(rings) - 1) * FINGER_AROUND
    for step in range(FINGER_AROUND):
        a0, a1 = step, (step + 1) % FINGER_AROUND
        faces.append((base, a1, a0))
        faces.append((base + 1, last + a0, last + a1))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    mesh.validate()
    mesh.update()
    return mesh


def finger_character(name):
    """(mesh object, armature object): the finger skinned to three phalanges along +Y."""
    joints = [0.0]
    for length in FINGER_LENGTHS:
        joints.append(joints[-1] + length)
    armature = bpy.data.armatures.new(name + "Rig")
    rig = helpers.link(bpy.data.objects.new(name + "Rig", armature))
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    previous = None
    bone_names = []
    for index in range(3):
        bone = armature.edit_bones.new("phalanx%d" % (index + 1))
        bone.head = (0.0, joints[index], 0.0)
        bone.tail = (0.0, joints[index + 1], 0.0)
        if previous is not None:
            bone.parent = previous
            bone.use_connect = True
        previous = bone
        bone_names.append(bone.name)
    bpy.ops.object.mode_set(mode='OBJECT')

    obj = helpers.link(bpy.data.objects.new(name, finger_mesh(name)))
    groups = [obj.vertex_groups.new(name=bone_name) for bone_name in bone_names]
    for vertex in obj.data.vertices:
        # Weight of bone j rises linearly from 0 to 1 over the band centred on joint j (test__chain_weights).
        bone, weight = 0, 1.0
        for joint in (1, 2):
            start = joints[joint] - 0.5 * FINGER_BAND
            if vertex.co.y < start:
                break
            bone, weight = joint, min((vertex.co.y - start) / FINGER_BAND, 1.0)
        if weight < 1.0:
            groups[bone - 1].add([vertex.index], 1.0 - weight, 'REPLACE')
        if weight > 0.0:
            groups[bone].add([vertex.index], weight, 'REPLACE')
    helpers.add_armature_modifier(obj, rig)
    obj.parent = rig
    bpy.context.view_layer.update()
    return obj, rig


def bend_finger(rig, degrees=FINGER_BEND):
    """Both knuckles bent by `degrees` about X: the tip turns towards +Z."""
    for bone_name in ("phalanx2", "phalanx3"):
        set_rotation(rig, bone_name, (1.0, 0.0, 0.0), degrees)


def finger_trio(degrees=FINGER_BEND):
    """(plain, volume only, with fold-over): the finger folded at both knuckles, with plain skinning,
    with Volume Preservation, and with Volume Preservation and Fold-Over Prevention."""
    plain, plain_rig = finger_character("FingerPlain")
    volume_only, volume_rig = finger_character("FingerVolume")
    corrected, corrected_rig = finger_character("FingerFoldOver")
    add_volume_preservation(volume_only)
    add_volume_preservation(corrected, fold_over=True)
    for rig in (plain_rig, volume_rig, corrected_rig):
        bend_finger(rig, degrees)
    bpy.context.view_layer.update()
    return plain, volume_only, corrected


def crossing_face_pairs(obj):
    """Pairs of faces of the evaluated mesh that intersect without sharing a vertex: skin that went
    through itself (mathutils' BVH overlap test)."""
    mesh = helpers.evaluated_mesh(obj)
    vertices = [vertex.co.copy() for vertex in mesh.vertices]
    faces = [tuple(polygon.vertices) for polygon in mesh.polygons]
    tree = BVHTree.FromPolygons(vertices, faces, all_triangles=False, epsilon=0.0)
    count = 0
    for first, second in tree.overlap(tree):
        if first < second and not set(faces[first]) & set(faces[second]):
            count += 1
    return count


# ---- a Rigify character ----------------------------------------------------------------------------


def rigify_trio():
    """(plain, preserve_volume, corrected, rig): the Rigify human of tests/blender/real_cases.py (Rigify's
    generated rig, a closed body parented With Automatic Weights), three times on one rig posed hard (elbows and
    knees past 110 degrees, hips bent): Armature only, Armature with Preserve Volume, and with Volume
    Preservation. Raises RuntimeError when this Blender has no Rigify."""
    corrected, rig = real_cases.rigify_human()
    copies = []
    for name in ("BodyPlain", "BodyPreserveVolume"):
        copy = corrected.copy()
        copy.data = corrected.data.copy()
        copy.name = name
        bpy.context.scene.collection.objects.link(copy)
        copies.append(copy)
    copies[1].modifiers["Armature"].use_deform_preserve_volume = True
    add_volume_preservation(corrected)
    real_cases.pose_rigify_human(rig, 1.0)
    bpy.context.view_layer.update()
    return copies[0], copies[1], corrected, rig


def auto_weights_pair():
    """(heat, auto, rig): the Rigify human of tests/blender/real_cases.py at rest twice, weighted With Automatic
    Weights (Blender's heat weights) and by the add-on's Auto Weights with its defaults. Raises RuntimeError
    when this Blender has no Rigify or a weighting fails."""
    heat, rig = real_cases.rigify_human()
    heat.name = "BodyHeatWeights"
    auto = heat.copy()
    auto.data = heat.data.copy()
    auto.name = "BodyAutoWeights"
    bpy.context.scene.collection.objects.link(auto)
    helpers.select_only(auto)
    if bpy.ops.object.lvp_auto_weights() != {'FINISHED'}:
        raise RuntimeError("Auto Weights failed on the Rigify human")
    return heat, auto, rig


def weight_colour(weight):
    """Weight paint's colour for a weight in [0, 1]: blue at 0, through cyan, green and yellow, to red at 1."""
    import colorsys
    weight = min(max(weight, 0.0), 1.0)
    return colorsys.hsv_to_rgb((1.0 - weight) * 2.0 / 3.0, 1.0, 1.0) + (1.0,)


def paint_weights(obj, bone_names, attribute_name):
    """A point colour attribute of obj showing, as weight paint does, the weight the Armature modifier gives
    bone_names together: their groups' weights over the sum of every deforming bone's."""
    deforming = {obj.vertex_groups[bone.name].index for bone in obj.parent.data.bones
                 if bone.use_deform and bone.name in obj.vertex_groups}
    shown = {obj.vertex_groups[name].index for name in bone_names}
    colours = []
    for vertex in obj.data.vertices:
        total = sum(element.weight for element in vertex.groups if element.group in deforming)
        part = sum(element.weight for element in vertex.groups if element.group in shown)
        colours.extend(weight_colour(part / total if total > 0.0 else 0.0))
    attribute = obj.data.attributes.get(attribute_name) or obj.data.attributes.new(attribute_name, 'FLOAT_COLOR',
                                                                                     'POINT')
    attribute.data.foreach_set("color", colours)
    obj.data.update()
