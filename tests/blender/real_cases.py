# SPDX-License-Identifier: GPL-3.0-or-later
"""Real cases, as users have them (../shared/QUALITY.md), built from what Blender ships, small enough for a test
and the same at every run:

- rigify_human(): Rigify's human metarig generated into a rig, a closed smooth body of our own (spheres along
  the DEF bones, united and smoothed by a voxel remesh: one closed manifold surface), parented With Automatic
  Weights (heat weights over every DEF bone, face bones included); pose_rigify_human() bends it hard through
  the rig's own FK controls: elbows and knees past 110 degrees, a hip to 90, shoulders raised, spine bent;
- hand(): a palm, four fingers side by side and a thumb, phalanges of different lengths and thicknesses, one
  closed surface the same way, an armature of a palm bone and 3 bones per digit, heat weights, and an animation
  from open (frame 1) to a fist (frame 21: finger joints at 90, 100 and 70 degrees, fingertips at the palm);
- mocap_character(): a motion capture clip of Debian's assimp-testmodels imported as a BVH file, a closed body
  grown around its skeleton, heat weights: a character as game and previs pipelines have them;
- modelled_human(): the mannequin of assimp-testmodels' HUMAN.blend, modelled by hand from a box, mirrored and
  subdivided, a rig placed by hand, heat weights; pose_modelled_human() bends its knees, hips and elbows hard;
- gltf_round_trip(): a mesh through Blender's own glTF exporter and importer, which split it at its UV seams
  as files from other packages are split, then skinned to the same armature with the same weights.

The add-on is not involved: measure_quality.py adds Volume Preservation to these.
"""

import collections
import importlib.util
import math
import os
import tempfile
import unittest

import addon_utils
import bpy
from mathutils import Euler, Quaternion, Vector, kdtree

# ---- closed smooth surfaces from spheres --------------------------------------------------------


def ellipsoid(centre, radii, rings=10, around=16):
    """(vertices, quads and triangles) of an axis-aligned ellipsoid, wound outward: two poles and rings x
    around vertices, each quad (ring, step), (ring + 1, step), (ring + 1, step + 1), (ring, step + 1)."""
    cx, cy, cz = centre
    rx, ry, rz = radii
    vertices = [(cx, cy, cz + rz)]
    for ring in range(1, rings):
        polar = math.pi * ring / rings
        for step in range(around):
            azimuth = 2.0 * math.pi * step / around
            vertices.append((cx + rx * math.sin(polar) * math.cos(azimuth),
                             cy + ry * math.sin(polar) * math.sin(azimuth), cz + rz * math.cos(polar)))
    vertices.append((cx, cy, cz - rz))

    def index(ring, step):
        return 1 + (ring - 1) * around + step % around

    faces = [(0, index(1, step), index(1, step + 1)) for step in range(around)]
    faces += [(index(ring, step), index(ring + 1, step), index(ring + 1, step + 1), index(ring, step + 1))
              for ring in range(1, rings - 1) for step in range(around)]
    faces += [(len(vertices) - 1, index(rings - 1, step + 1), index(rings - 1, step)) for step in range(around)]
    return vertices, faces


def _chain(points, radii, spacing=0.3):
    """Spheres along the polyline `points`, their radii interpolated from `radii` (one per point), one every
    spacing x radius, so their union is a smooth tube whose thickness follows the radii."""
    spheres = []
    for index in range(len(points) - 1):
        start, end = Vector(points[index]), Vector(points[index + 1])
        r0, r1 = radii[index], radii[index + 1]
        length = (end - start).length
        steps = max(1, int(math.ceil(length / (spacing * min(r0, r1)))))
        for step in range(steps + (1 if index == len(points) - 2 else 0)):
            t = step / steps
            r = r0 + (r1 - r0) * t
            spheres.append((tuple(start.lerp(end, t)), (r, r, r)))
    return spheres


def closed_surface(name, spheres, voxel_size, smoothing=6):
    """A mesh object: the union of the ellipsoids `spheres` [(centre, radii)], by a voxel remesh (one closed
    manifold surface, vertices about voxel_size apart), smoothed a little so the voxels and the spheres do not
    show. Smooth shaded."""
    vertices, faces = [], []
    for centre, radii in spheres:
        sphere_vertices, sphere_faces = ellipsoid(centre, radii)
        base = len(vertices)
        vertices += sphere_vertices
        faces += [tuple(base + v for v in face) for face in sphere_faces]
    pieces = bpy.data.meshes.new(name + "Pieces")
    pieces.from_pydata(vertices, [], faces)
    pieces.update()
    source = bpy.data.objects.new(name + "Pieces", pieces)
    bpy.context.scene.collection.objects.link(source)
    remesh = source.modifiers.new("Remesh", 'REMESH')
    remesh.mode = 'VOXEL'
    remesh.voxel_size = voxel_size
    remesh.adaptivity = 0.0
    if smoothing:
        smooth = source.modifiers.new("Smooth", 'SMOOTH')
        smooth.factor = 0.5
        smooth.iterations = smoothing
    obj = _as_mesh_object(source, name)
    bpy.data.meshes.remove(pieces)
    return obj


def _as_mesh_object(source, name):
    """A new object `name` in the scene holding source's evaluated mesh (its modifiers, or a metaball's
    polygonization, applied), shaded smooth. source is removed; its data is left to the caller."""
    bpy.context.view_layer.update()
    mesh = bpy.data.meshes.new_from_object(source.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    bpy.data.objects.remove(source)
    mesh.name = name
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def open_edge_count(mesh):
    """Edges with other than two faces (0 on a closed manifold mesh)."""
    faces_of_edge = {}
    for polygon in mesh.polygons:
        for key in polygon.edge_keys:
            faces_of_edge[key] = faces_of_edge.get(key, 0) + 1
    return sum(1 for count in faces_of_edge.values() if count != 2) + len(mesh.edges) - len(faces_of_edge)


def _select_only(*objects):
    # Blender 4.3 and 5.2 list a removed object as None in view_layer.objects until the view layer is updated.
    bpy.context.view_layer.update()
    for other in bpy.context.view_layer.objects:
        if other is not None:
            other.select_set(False)
    for obj in objects:
        obj.select_set(True)


def parent_with_automatic_weights(obj, rig):
    """Ctrl+P > With Automatic Weights (heat weights over the rig's deforming bones); returns the operator's
    result. The mesh gets an Armature modifier and the rig as its parent."""
    _select_only(obj, rig)
    bpy.context.view_layer.objects.active = rig
    with bpy.context.temp_override(active_object=rig, object=rig, selected_editable_objects=[obj, rig],
                                   selected_objects=[obj, rig]):
        result = bpy.ops.object.parent_set(type='ARMATURE_AUTO')
    bpy.context.view_layer.update()
    return result


def empty_vertex_groups(obj):
    """Names of the vertex groups in which no vertex has weight (heat weighting that failed)."""
    used = set()
    for vertex in obj.data.vertices:
        for element in vertex.groups:
            if element.weight > 0.0:
                used.add(element.group)
    return [group.name for group in obj.vertex_groups if group.index not in used]


# ---- a Rigify human ----------------------------------------------------------------------------

BODY_VOXEL = 0.024


def enable_rigify():
    _default, loaded = addon_utils.check("rigify")
    if not loaded:
        addon_utils.enable("rigify", default_set=True)  # its register() reads its preferences
    return hasattr(bpy.ops.pose, "rigify_generate")


# The builds of rigify_human's body, each as ellipsoids along Rigify's DEF bones (radii in metres, the metarig
# 1.98 m tall): the legs' radii from the hip to the ankle, the arms' from the shoulder joint to the wrist, and
# the trunk's (width, depth, height) at the pelvis, the waist, the chest and under the shoulders. "male": narrow
# hips, a gap of 2.6 cm between the thighs at the crotch. "female": hips wider than the shoulders, a narrow
# waist, breasts on Rigify's DEF-breast bones, fuller thighs that meet at the crotch and part below it, slimmer
# arms. "no gap": the male body with thighs so full that they press on each other from the crotch to the
# middle of the thigh, as a heavy body's do.
BODY_BUILDS = {
    "male": {"leg": [0.085, 0.075, 0.058, 0.052, 0.04], "arm": [0.052, 0.048, 0.042, 0.04, 0.03, 0.028],
             "pelvis": (0.15, 0.11, 0.12), "waist": (0.14, 0.10, 0.10), "belly": (0.135, 0.095, 0.10),
             "chest": (0.15, 0.10, 0.11), "upper chest": (0.16, 0.105, 0.11), "breast": None},
    "female": {"leg": [0.094, 0.074, 0.058, 0.05, 0.038], "arm": [0.045, 0.042, 0.037, 0.036, 0.028, 0.026],
               "pelvis": (0.18, 0.125, 0.13), "waist": (0.13, 0.095, 0.10), "belly": (0.115, 0.085, 0.10),
               "chest": (0.13, 0.09, 0.11), "upper chest": (0.14, 0.095, 0.10), "breast": (0.06, 0.055, 0.058)},
    "no gap": {"leg": [0.115, 0.092, 0.064, 0.054, 0.04], "arm": [0.056, 0.052, 0.045, 0.042, 0.031, 0.028],
               "pelvis": (0.17, 0.125, 0.13), "waist": (0.16, 0.12, 0.11), "belly": (0.16, 0.12, 0.11),
               "chest": (0.16, 0.11, 0.11), "upper chest": (0.165, 0.105, 0.11), "breast": None},
}


def _limbs(rig, side, build="male"):
    """{limb: (points, radii)} of one side of a body that fits Rigify's human (BODY_BUILDS): the leg from the
    hip to the ankle, the foot from the ankle to the toe, the arm from the shoulder joint to the hand, the
    shoulder."""
    bones = rig.data.bones
    radii = BODY_BUILDS[build]

    def head(name):
        return tuple(bones[name].head_local)

    def tail(name):
        return tuple(bones[name].tail_local)

    return {
        "leg": ([head("DEF-thigh." + side), tail("DEF-thigh." + side), tail("DEF-thigh.%s.001" % side),
                 tail("DEF-shin." + side), tail("DEF-shin.%s.001" % side)], radii["leg"]),
        "foot": ([tail("DEF-shin.%s.001" % side), tail("DEF-foot." + side), tail("DEF-toe." + side)],
                 [0.04, 0.035, 0.03]),
        "arm": ([head("DEF-upper_arm." + side), tail("DEF-upper_arm." + side),
                 tail("DEF-upper_arm.%s.001" % side), tail("DEF-forearm." + side),
                 tail("DEF-forearm.%s.001" % side), tail("DEF-hand." + side)], radii["arm"]),
        "shoulder": ([head("DEF-shoulder." + side), head("DEF-upper_arm." + side)], [0.055, 0.055]),
    }


def _body_spheres(rig, build="male"):
    """Ellipsoids of a body of that build (BODY_BUILDS) that fits Rigify's human metarig (1.98 m, facing -Y),
    from the rig's DEF bones."""
    radii = BODY_BUILDS[build]
    bones = rig.data.bones

    def head(name):
        return tuple(bones[name].head_local)

    def tail(name):
        return tuple(bones[name].tail_local)

    spheres = []
    for side in ("L", "R"):
        for points, limb_radii in _limbs(rig, side, build).values():
            spheres += _chain(points, limb_radii)
        if radii["breast"]:
            breast = "DEF-breast." + side
            spheres.append((tuple(Vector(head(breast)).lerp(Vector(tail(breast)), 0.55)), radii["breast"]))
    # The trunk: flattened ellipsoids along the spine, from the pelvis to the head.
    trunk = [("DEF-spine", 0.0, radii["pelvis"]), ("DEF-spine", 1.0, radii["waist"]),
             ("DEF-spine.001", 1.0, radii["belly"]), ("DEF-spine.002", 0.5, radii["chest"]),
             ("DEF-spine.003", 0.0, radii["upper chest"]), ("DEF-spine.003", 0.6, (0.15, 0.095, 0.10))]
    for name, t, trunk_radii in trunk:
        spheres.append((tuple(Vector(head(name)).lerp(Vector(tail(name)), t)), trunk_radii))
    spheres += _chain([head("DEF-spine.004"), tail("DEF-spine.005")], [0.05, 0.05])
    centre = Vector(head("DEF-spine.006")).lerp(Vector(tail("DEF-spine.006")), 0.4)
    spheres.append((tuple(centre), (0.085, 0.1, 0.115)))
    return spheres


def metaball_surface(name, spheres, resolution, threshold=0.6):
    """A closed mesh object `name` of the ellipsoids `spheres` ((centre, radii) pairs) as metaballs of that
    resolution, converted to a mesh (Blender's marching cubes: where the surface passes near a corner of its
    grid it leaves edges a few hundredths of the mean long, and needle triangles around them)."""
    balls = bpy.data.metaballs.new(name + "Balls")
    balls.resolution = balls.render_resolution = resolution
    balls.threshold = threshold
    for centre, radii in spheres:
        element = balls.elements.new(type='ELLIPSOID')
        element.co = centre
        element.radius = max(radii)
        element.size_x, element.size_y, element.size_z = (radius / element.radius for radius in radii)
    holder = bpy.data.objects.new(name + "Balls", balls)
    bpy.context.scene.collection.objects.link(holder)
    obj = _as_mesh_object(holder, name)
    bpy.data.metaballs.remove(balls)
    return obj


def _skin_skeleton(rig):
    """(points, radii, edges) of a body along Rigify's DEF bones for the Skin modifier: the spine from the pelvis
    to the head, from its base the legs and feet, from the chest the arms (the radii of _limbs)."""
    bones = rig.data.bones
    points, radii, edges = [], [], []

    def add(point, radius, previous):
        points.append(tuple(point))
        radii.append(radius)
        if previous is not None:
            edges.append((previous, len(points) - 1))
        return len(points) - 1

    spine = [(bones["DEF-spine"].head_local, (0.15, 0.11))] + [
        (bones[name].tail_local, radius) for name, radius in (
            ("DEF-spine", (0.14, 0.10)), ("DEF-spine.001", (0.135, 0.095)), ("DEF-spine.002", (0.15, 0.10)),
            ("DEF-spine.003", (0.15, 0.095)), ("DEF-spine.004", (0.05, 0.05)), ("DEF-spine.005", (0.05, 0.05)),
            ("DEF-spine.006", (0.085, 0.1)))]
    previous, along_spine = None, []
    for point, radius in spine:
        previous = add(point, radius, previous)
        along_spine.append(previous)
    for side in ("L", "R"):
        limbs = _limbs(rig, side)
        leg, foot, arm = limbs["leg"], limbs["foot"], limbs["arm"]
        for previous, (limb_points, limb_radii) in ((along_spine[0], (leg[0] + foot[0][1:], leg[1] + foot[1][1:])),
                                                     (along_spine[3], arm)):
            for point, radius in zip(limb_points, limb_radii):
                previous = add(point, (radius, radius), previous)
    return points, radii, edges


def skin_modifier_surface(name, rig, subdivisions):
    """A closed mesh object `name` grown along the rig's DEF bones by the Skin modifier (its quads, the branch
    junctions at the pelvis and chest) and subdivided `subdivisions` times, converted to a mesh."""
    points, radii, edges = _skin_skeleton(rig)
    mesh = bpy.data.meshes.new(name + "Skeleton")
    mesh.from_pydata(points, edges, [])
    holder = bpy.data.objects.new(name + "Skeleton", mesh)
    bpy.context.scene.collection.objects.link(holder)
    holder.modifiers.new("Skin", 'SKIN')
    for skin_vertex, radius in zip(mesh.skin_vertices[0].data, radii):
        skin_vertex.radius = radius
    mesh.skin_vertices[0].data[0].use_root = True
    holder.modifiers.new("Subdivision", 'SUBSURF').levels = subdivisions
    obj = _as_mesh_object(holder, name)
    bpy.data.meshes.remove(mesh)
    return obj


def rigify_human(voxel_size=BODY_VOXEL, metaball_resolution=None, skin_subdivisions=None, decimated=None,
                 build="male"):
    """(body, rig): Rigify's human generated, a closed body of that build (BODY_BUILDS) around its DEF bones
    parented to it With Automatic Weights: a voxel remesh; with metaball_resolution, the same ellipsoids as
    metaballs; with skin_subdivisions, the Skin modifier's body subdivided that many times (male); decimated to
    that ratio of its faces when given (the irregular triangles of a game mesh). Raises RuntimeError when this
    Blender has no Rigify or heat weighting leaves the body unweighted."""
    if not enable_rigify():
        raise RuntimeError("this Blender has no Rigify add-on")
    bpy.ops.object.armature_human_metarig_add()
    metarig = bpy.context.object
    bpy.ops.pose.rigify_generate()
    rig = next(obj for obj in bpy.data.objects if obj.type == 'ARMATURE' and obj != metarig)
    bpy.data.objects.remove(metarig)
    if metaball_resolution is not None:
        body = metaball_surface("Body", _body_spheres(rig, build), metaball_resolution)
    elif skin_subdivisions is not None:
        body = skin_modifier_surface("Body", rig, skin_subdivisions)
    else:
        body = closed_surface("Body", _body_spheres(rig, build), voxel_size)
    if decimated is not None:
        decimate(body, decimated)
    if parent_with_automatic_weights(body, rig) != {'FINISHED'}:
        raise RuntimeError("With Automatic Weights failed on the body")
    limbs = [name for name in ("DEF-thigh.L", "DEF-shin.L", "DEF-forearm.L", "DEF-spine.002")
             if name in empty_vertex_groups(body)]
    if limbs:
        raise RuntimeError("heat weighting left %s empty" % limbs)
    return body, rig


def _turn_towards(rig, control, axis, degrees, bone, direction):
    """Rotates pose bone `control` about its local `axis` ('X', 'Y' or 'Z') by `degrees`, with the sign that
    moves the tail of `bone` towards world `direction` (so the pose reads anatomically whatever the control's
    roll is in this Rigify version)."""
    pose_bone = rig.pose.bones[control]
    pose_bone.rotation_mode = 'XYZ'
    index = "XYZ".index(axis)
    before = pose_bone.rotation_euler.copy()
    bpy.context.view_layer.update()
    start = rig.matrix_world @ rig.pose.bones[bone].tail
    moves = []
    for sign in (1.0, -1.0):
        rotation = before.copy()
        rotation[index] += sign * math.radians(degrees)
        pose_bone.rotation_euler = rotation
        bpy.context.view_layer.update()
        moves.append(((rig.matrix_world @ rig.pose.bones[bone].tail) - start).dot(Vector(direction)))
    rotation = before.copy()
    rotation[index] += (1.0 if moves[0] >= moves[1] else -1.0) * math.radians(degrees)
    pose_bone.rotation_euler = rotation
    bpy.context.view_layer.update()


def bend_angle(rig, first, second):
    """Degrees between the posed directions of two bones (0: straight on)."""
    a = rig.pose.bones[first]
    b = rig.pose.bones[second]
    return math.degrees((a.tail - a.head).angle(b.tail - b.head))


def pose_rigify_human(rig, amount=1.0):
    """The hard pose, `amount` of the way from rest (1.0: elbows 125 and 115 degrees, knees 120 and 115, left hip
    90, right hip 40, shoulders raised 25, arms raised 50, spine bent forward 35 through the chest and the torso
    FK). Arms and legs are switched to FK and posed through their FK controls: constraints and drivers carry that
    to the DEF B-Bones. Returns {joint: degrees measured between the DEF bones}."""
    pose_bones = rig.pose.bones
    for name in ("upper_arm_parent.L", "upper_arm_parent.R", "thigh_parent.L", "thigh_parent.R"):
        pose_bones[name]["IK_FK"] = 1.0
    for pose_bone in pose_bones:
        pose_bone.rotation_mode = 'XYZ'
        pose_bone.rotation_euler = Euler((0.0, 0.0, 0.0))
    bpy.context.view_layer.update()
    forward, up, back = (0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)
    for side, elbow, knee, hip in (("L", 125.0, 120.0, 90.0), ("R", 115.0, 115.0, 40.0)):
        _turn_towards(rig, "shoulder." + side, 'Z', 25.0 * amount, "DEF-shoulder." + side, up)
        _turn_towards(rig, "upper_arm_fk." + side, 'Z', 50.0 * amount, "DEF-upper_arm.%s.001" % side, up)
        _turn_towards(rig, "forearm_fk." + side, 'X', elbow * amount, "DEF-forearm.%s.001" % side, forward)
        _turn_towards(rig, "thigh_fk." + side, 'X', hip * amount, "DEF-thigh.%s.001" % side, forward)
        _turn_towards(rig, "shin_fk." + side, 'X', knee * amount, "DEF-shin.%s.001" % side, back)
    _turn_towards(rig, "chest", 'X', 35.0 * amount, "DEF-spine.003", forward)
    bpy.context.view_layer.update()
    return {
        "elbow.L": bend_angle(rig, "DEF-upper_arm.L.001", "DEF-forearm.L"),
        "elbow.R": bend_angle(rig, "DEF-upper_arm.R.001", "DEF-forearm.R"),
        **_leg_angles(rig),
        "spine": bend_angle(rig, "DEF-spine.001", "DEF-spine.003"),
    }


def _leg_angles(rig):
    """{joint: degrees} of the knees and hips, measured between the DEF bones."""
    return {
        "knee.L": bend_angle(rig, "DEF-thigh.L.001", "DEF-shin.L"),
        "knee.R": bend_angle(rig, "DEF-thigh.R.001", "DEF-shin.R"),
        # Flexion: 0 when the thigh hangs straight down from the spine.
        "hip.L": 180.0 - bend_angle(rig, "DEF-spine", "DEF-thigh.L"),
        "hip.R": 180.0 - bend_angle(rig, "DEF-spine", "DEF-thigh.R"),
    }


def pose_rigify_human_legs(rig, kind):
    """Two more hard poses of the legs, from rest, arms and spine left straight: 'crouch' (both hips raised 100
    degrees, both knees bent 130: thigh on belly, calf on thigh) or 'spread' (both thighs swung out 50 degrees,
    then raised 60). Returns {joint: degrees measured between the DEF bones}."""
    pose_rigify_human(rig, 0.0)
    forward, back = (0.0, -1.0, 0.0), (0.0, 1.0, 0.0)
    for side, outwards in (("L", (1.0, 0.0, 0.0)), ("R", (-1.0, 0.0, 0.0))):
        thigh, shin = "DEF-thigh.%s.001" % side, "DEF-shin.%s.001" % side
        if kind == "crouch":
            _turn_towards(rig, "thigh_fk." + side, 'X', 100.0, thigh, forward)
            _turn_towards(rig, "shin_fk." + side, 'X', 130.0, shin, back)
        elif kind == "spread":
            _turn_towards(rig, "thigh_fk." + side, 'Z', 50.0, thigh, outwards)
            _turn_towards(rig, "thigh_fk." + side, 'X', 60.0, thigh, forward)
        else:
            raise ValueError("no leg pose %r: 'crouch' or 'spread'" % kind)
    bpy.context.view_layer.update()
    return _leg_angles(rig)


def pose_rigify_human_arms_down(rig, degrees=80.0):
    """Both upper arms lowered from Rigify's rest (62 degrees from hanging straight down) by `degrees` about their
    FK controls' Z axis, the rest of the body at rest: at 60 an upper arm hangs 17 degrees from vertical beside
    the chest, at 80 it is turned past that into the side of the chest, where plain skinning passes the arm's skin
    through the chest's. Returns {"arm.L", "arm.R": degrees of the upper arm from straight down}."""
    pose_rigify_human(rig, 0.0)
    down = (0.0, 0.0, -1.0)
    for side in ("L", "R"):
        _turn_towards(rig, "upper_arm_fk." + side, 'Z', degrees, "DEF-upper_arm.%s.001" % side, down)
    bpy.context.view_layer.update()
    angles = {}
    for side in ("L", "R"):
        bone = rig.pose.bones["DEF-upper_arm.%s.001" % side]
        angles["arm." + side] = math.degrees((bone.tail - bone.head).angle(Vector(down)))
    return angles


def pose_rigify_human_folded(rig, degrees=150.0):
    """Knees and elbows bent to `degrees` measured between the DEF bones (real_cases.bend_angle), from rest, the
    rest of the body straight: Rigify's rest pose already bends them a little, so each FK control is turned until
    the DEF bones read the angle (within 0.5 degrees). Returns {joint: degrees}."""
    pose_rigify_human(rig, 0.0)
    forward, back = (0.0, -1.0, 0.0), (0.0, 1.0, 0.0)
    for side in ("L", "R"):
        for control, bone, direction, first, second in (
                ("forearm_fk." + side, "DEF-forearm.%s.001" % side, forward, "DEF-upper_arm.%s.001" % side,
                 "DEF-forearm." + side),
                ("shin_fk." + side, "DEF-shin.%s.001" % side, back, "DEF-thigh.%s.001" % side, "DEF-shin." + side)):
            turned = degrees
            for _attempt in range(4):
                rig.pose.bones[control].rotation_euler = Euler((0.0, 0.0, 0.0))
                bpy.context.view_layer.update()
                _turn_towards(rig, control, 'X', turned, bone, direction)
                error = degrees - bend_angle(rig, first, second)
                if abs(error) < 0.5:
                    break
                turned += error
    bpy.context.view_layer.update()
    return {
        "elbow.L": bend_angle(rig, "DEF-upper_arm.L.001", "DEF-forearm.L"),
        "elbow.R": bend_angle(rig, "DEF-upper_arm.R.001", "DEF-forearm.R"),
        "knee.L": bend_angle(rig, "DEF-thigh.L.001", "DEF-shin.L"),
        "knee.R": bend_angle(rig, "DEF-thigh.R.001", "DEF-shin.R"),
    }


# ---- a hand ------------------------------------------------------------------------------------

HAND_VOXEL = 0.003
HAND_FRAMES = (1, 21)

# Digits: name, knuckle position (wrist at the origin, fingers along +Y, palm facing -Z), phalanx lengths and
# radii at the knuckle and at each joint (metres).
FINGERS = (
    ("index", (0.0405, 0.092, 0.0), (0.040, 0.024, 0.019), (0.0096, 0.0089, 0.0081, 0.0072)),
    ("middle", (0.0135, 0.097, 0.0), (0.045, 0.028, 0.021), (0.0099, 0.0092, 0.0083, 0.0074)),
    ("ring", (-0.0135, 0.094, 0.0), (0.042, 0.026, 0.020), (0.0093, 0.0087, 0.0079, 0.0070)),
    ("pinky", (-0.0405, 0.086, 0.0), (0.032, 0.019, 0.017), (0.0083, 0.0076, 0.0069, 0.0061)),
)
# The thumb: from the base of the palm, out, forward and down towards the palm side.
THUMB = ("thumb", (0.034, 0.018, -0.006), (0.038, 0.032, 0.026), (0.0135, 0.0115, 0.0100, 0.0088))
THUMB_DIRECTION = Vector((0.75, 0.6, -0.28)).normalized()
# Fist at the last frame: degrees at the knuckle, the middle and the last joint (QUALITY.md's 90, 100, 70).
FIST = (90.0, 100.0, 70.0)
THUMB_FIST = (35.0, 45.0, 50.0)


def _digit_joints(knuckle, lengths, direction):
    points = [Vector(knuckle)]
    for length in lengths:
        points.append(points[-1] + length * direction)
    return points


class HandShape:
    """A hand: its fingers (FINGERS' layout), its thumb (THUMB's) and the direction the thumb leaves the palm,
    the fist's joint angles for the fingers and the thumb."""

    def __init__(self, fingers=FINGERS, thumb=THUMB, thumb_direction=THUMB_DIRECTION, fist=FIST,
                 thumb_fist=THUMB_FIST):
        self.fingers, self.thumb, self.thumb_direction = fingers, thumb, Vector(thumb_direction).normalized()
        self.fist, self.thumb_fist = fist, thumb_fist

    def scaled(self, length=1.0, thickness=1.0):
        """The same hand with phalanges `length` times as long and `thickness` times as thick (knuckles where
        they were)."""
        def digit(name, knuckle, lengths, radii):
            return (name, knuckle, tuple(length * x for x in lengths), tuple(thickness * r for r in radii))
        return HandShape(tuple(digit(*finger) for finger in self.fingers), digit(*self.thumb),
                         self.thumb_direction, self.fist, self.thumb_fist)


HAND = HandShape()


def _hand_spheres(shape=HAND):
    spheres = []
    # The palm: a thick plate made of flattened ellipsoids along the metacarpals and one at the wrist.
    for _name, knuckle, _lengths, _radii in shape.fingers:
        x = knuckle[0]
        for t in (0.25, 0.5, 0.75, 0.92):
            spheres.append(((x * (0.75 + 0.25 * t), knuckle[1] * t, -0.002), (0.016, 0.022, 0.0135)))
    spheres.append(((0.0, 0.012, -0.002), (0.03, 0.02, 0.015)))
    for _name, knuckle, lengths, radii in shape.fingers:
        spheres += _chain(_digit_joints((knuckle[0], knuckle[1] - 0.008, knuckle[2]), (0.008,) + lengths,
                                        Vector((0.0, 1.0, 0.0))), (radii[0],) + radii)
    _name, base, lengths, radii = shape.thumb
    spheres += _chain(_digit_joints(base, lengths, shape.thumb_direction), radii)
    return spheres


def hand_armature(name="HandRig", shape=HAND):
    """The palm bone (wrist to the middle knuckle) and 3 bones per digit, rolled so that each finger bone's local
    X is the axis its joint bends about."""
    armature = bpy.data.armatures.new(name)
    rig = bpy.data.objects.new(name, armature)
    bpy.context.scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    palm = armature.edit_bones.new("palm")
    palm.head, palm.tail = (0.0, 0.0, 0.0), (0.0, 0.09, 0.0)
    digits = [(n, k, lengths, Vector((0.0, 1.0, 0.0))) for n, k, lengths, _radii in shape.fingers]
    digits.append((shape.thumb[0], shape.thumb[1], shape.thumb[2], shape.thumb_direction))
    for digit, knuckle, lengths, direction in digits:
        points = _digit_joints(knuckle, lengths, direction)
        parent = palm
        for index in range(3):
            bone = armature.edit_bones.new("%s.%02d" % (digit, index + 1))
            bone.head, bone.tail = points[index], points[index + 1]
            # Local Z towards the back of the hand (+Z), so local X is the bending axis.
            bone.align_roll(Vector((0.0, 0.0, 1.0)))
            bone.parent = parent
            bone.use_connect = index > 0
            parent = bone
    bpy.ops.object.mode_set(mode='OBJECT')
    return rig


def hand_joint_rotations(amount, shape=HAND):
    """{bone: degrees about its local X} of the hand `amount` of the way to the fist; positive curls towards the
    palm (-Z)."""
    rotations = {}
    for digit, _knuckle, _lengths, _radii in shape.fingers:
        for index, degrees in enumerate(shape.fist):
            rotations["%s.%02d" % (digit, index + 1)] = degrees * amount
    for index, degrees in enumerate(shape.thumb_fist):
        rotations["%s.%02d" % (shape.thumb[0], index + 1)] = degrees * amount
    return rotations


def pose_hand(rig, amount, shape=HAND):
    """Poses the hand `amount` of the way from open (0) to the fist (1), without keys."""
    for name, degrees in hand_joint_rotations(amount, shape).items():
        pose_bone = rig.pose.bones[name]
        pose_bone.rotation_mode = 'XYZ'
        # A right-handed rotation about local X takes +Y (along the bone) to +Z (the back of the hand): curling
        # towards the palm is negative.
        pose_bone.rotation_euler = Euler((-math.radians(degrees), 0.0, 0.0))
    bpy.context.view_layer.update()


def _apply_modifier(obj, kind, **settings):
    """Replaces the mesh of obj (which has no other modifier) by its own with a new modifier of `kind` applied."""
    modifier = obj.modifiers.new(kind.title(), kind)
    for name, value in settings.items():
        setattr(modifier, name, value)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    mesh = bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph))
    obj.modifiers.remove(modifier)
    old, obj.data = obj.data, mesh
    bpy.data.meshes.remove(old)


def decimate(obj, ratio):
    """Collapses the mesh of obj (which has no other modifier) to `ratio` of its faces with Blender's Decimate
    modifier: irregular triangles, long and thin beside small ones."""
    _apply_modifier(obj, 'DECIMATE', ratio=ratio)


def triangulate(obj):
    """Splits every face of obj's mesh (which has no other modifier) into triangles with Blender's Triangulate
    modifier (its Beauty split), as game exporters leave a mesh."""
    _apply_modifier(obj, 'TRIANGULATE', quad_method='BEAUTY', ngon_method='BEAUTY')


def subdivide(obj):
    """One level of Catmull-Clark subdivision of obj's mesh (which has no other modifier; the Subdivision Surface
    modifier): each quad split in four and the surface rounded, as a modeller's cage is."""
    _apply_modifier(obj, 'SUBSURF', levels=1)


# Hands the suite's own was not tuned on (issue 46): {name: HandCase}. Stubby and long phalanges, three fingers and
# a thumb, a thumb that closes over the fingers and one that closes under them, 1,000 to 17,000 vertices from the
# voxel remesh; decimated to irregular triangles as most game and scanned meshes have, split into triangles as game
# exporters leave a mesh, and a coarse one subdivided once, as a modeller's cage is.
# decimated: the ratio of faces Blender's Decimate keeps, or None; finish: what is done to the mesh after that
# (triangulate, subdivide), or None.
HandCase = collections.namedtuple("HandCase", "voxel_size shape decimated finish", defaults=(None, None))
THUMB_OVER = HandShape(thumb_direction=(0.8, 0.55, 0.0), thumb_fist=(60.0, 40.0, 40.0))
THUMB_UNDER = HandShape(thumb_direction=(0.6, 0.6, -0.6), thumb_fist=(45.0, 55.0, 60.0))
HAND_FAMILY = {
    "very coarse": HandCase(0.008, HAND),
    "coarse": HandCase(0.006, HAND),
    "fine": HandCase(0.002, HAND),
    "stubby": HandCase(0.004, HAND.scaled(length=0.75, thickness=1.25)),
    "long and slender": HandCase(0.004, HAND.scaled(length=1.25, thickness=0.85)),
    "three fingers": HandCase(0.004, HandShape(fingers=FINGERS[:1] + FINGERS[2:])),
    "thumb over the fingers": HandCase(0.004, THUMB_OVER),
    "thumb under the fingers": HandCase(0.004, THUMB_UNDER),
    "decimated": HandCase(0.003, HAND, decimated=0.3),
    "decimated, thumb over": HandCase(0.003, THUMB_OVER, decimated=0.3),
    "decimated to half": HandCase(0.004, HAND, decimated=0.5),
    "triangulated": HandCase(0.004, HAND, finish=triangulate),
    "subdivided once": HandCase(0.008, HAND, finish=subdivide),
}


def hand(voxel_size=HAND_VOXEL, shape=HAND, name="Hand", decimated=None, finish=None):
    """(hand, rig): the closed hand (decimated to that ratio of its faces when given, then given to `finish`:
    triangulate, subdivide) parented With Automatic Weights to its armature, animated from open at frame
    HAND_FRAMES[0] to the fist at HAND_FRAMES[1] (two keys, Blender's default ease in and out), the scene's frame
    range set to it."""
    rig = hand_armature(name + "Rig", shape)
    obj = closed_surface(name, _hand_spheres(shape), voxel_size)
    if decimated is not None:
        decimate(obj, decimated)
    if finish is not None:
        finish(obj)
    if parent_with_automatic_weights(obj, rig) != {'FINISHED'}:
        raise RuntimeError("With Automatic Weights failed on the hand")
    empty = empty_vertex_groups(obj)
    if empty:
        raise RuntimeError("heat weighting left %s empty" % empty)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = HAND_FRAMES
    for frame, amount in zip(HAND_FRAMES, (0.0, 1.0)):
        pose_hand(rig, amount, shape)
        for bone_name in hand_joint_rotations(amount, shape):
            rig.pose.bones[bone_name].keyframe_insert("rotation_euler", frame=frame)
    scene.frame_set(HAND_FRAMES[0])
    return obj, rig


def fingertip_to_palm(rig, digit="middle"):
    """(distance from the digit's tip to the plane of the palm bone and its roll, i.e. the middle of the palm's
    thickness; how far along the palm the tip is, 0 at the wrist, 1 at the knuckles) at the current pose."""
    tip = rig.pose.bones["%s.03" % digit].tail
    palm = rig.pose.bones["palm"]
    normal = palm.matrix.to_3x3().col[2].normalized()
    axis = palm.tail - palm.head
    return abs((tip - palm.head).dot(normal)), (tip - palm.head).dot(axis) / axis.length_squared


# ---- the seams of a glTF round trip ------------------------------------------------------------


def box_uv_map(mesh, name="UVMap"):
    """A UV map by box projection: each face on the plane of its normal's dominant axis, so the islands split the
    surface along seams all over it, as a real UV map does."""
    layer = mesh.uv_layers.new(name=name)
    for polygon in mesh.polygons:
        normal = polygon.normal
        axis = max(range(3), key=lambda k: abs(normal[k]))
        u_axis, v_axis = [k for k in range(3) if k != axis]
        shift = 0.0 if normal[axis] > 0 else 10.0  # opposite faces in different places of the map
        for loop in polygon.loop_indices:
            co = mesh.vertices[mesh.loops[loop].vertex_index].co
            layer.data[loop].uv = (co[u_axis] + shift + 3.0 * axis, co[v_axis])
    return layer


def enable_gltf():
    """Enables Blender's glTF add-on; False when this Blender cannot import glTF here: no numpy, or Blender 4.3
    with numpy 2 (Debian trixie's), which crashes in a long session: a segmentation fault in the view layer
    update of the importer, after Rigify and heat weighting ran in the same Blender (test_real_cases, then
    test_seams). The same happens with the code of 775f1e7, which passed there before; Blender 4.3 was built
    and tested with numpy 1. Blender 3.4's importer names numpy.bool, gone from numpy 1.24 (Debian bookworm's
    python3-numpy): it is given back."""
    if importlib.util.find_spec("numpy") is None:
        return False
    import numpy
    if bpy.app.version[:2] == (4, 3) and int(numpy.__version__.split(".")[0]) >= 2:
        return False
    if "bool" not in vars(numpy):  # (hasattr would warn: numpy 1.24 keeps a FutureWarning under that name)
        numpy.bool = numpy.bool_
    return addon_utils.enable("io_scene_gltf2", default_set=False) is not None


def gltf_round_trip(obj, rig, directory=None):
    """A copy of obj's rest mesh exported by Blender's glTF exporter (with a box-projected UV map) and imported
    back, which splits it at the UV seams; its vertices get the weights of obj's vertices at their positions, an
    Armature modifier on `rig` and `rig` as parent. Returns the imported object (obj stays); the file it wrote
    is gltf_round_trip_file(obj, directory)."""
    if not enable_gltf():
        raise RuntimeError("this Blender cannot import glTF (Blender's importer needs numpy)")
    path = gltf_round_trip_file(obj, directory or tempfile.mkdtemp(prefix="lvp-gltf-"))
    mesh = obj.data.copy()
    mesh.name = obj.name + "Export"
    if not mesh.uv_layers:
        box_uv_map(mesh)
    exported = bpy.data.objects.new(obj.name + "Export", mesh)
    bpy.context.scene.collection.objects.link(exported)
    exported.matrix_world = obj.matrix_world.copy()
    _select_only(exported)
    bpy.context.view_layer.objects.active = exported
    bpy.ops.export_scene.gltf(filepath=path, export_format='GLB', use_selection=True, export_animations=False,
                              export_skins=False)
    # Unlinked, not removed: freeing the exported object and its mesh right before the importer's view layer
    # update crashed Blender 4.3 once (a segmentation fault in the update); an orphan is never evaluated, and
    # it is gone with the next file read.
    bpy.context.scene.collection.objects.unlink(exported)
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=path)
    imported = [new for new in bpy.data.objects if new not in before and new.type == 'MESH']
    if len(imported) != 1:
        raise RuntimeError("the glTF round trip gave %d meshes" % len(imported))
    result = imported[0]
    result.name = obj.name + "GLTF"
    world = result.matrix_world.copy()
    result.parent = None
    result.matrix_world = world
    bpy.context.view_layer.update()
    _copy_weights_by_position(obj, result)
    modifier = result.modifiers.new("Armature", 'ARMATURE')
    modifier.object = rig
    result.parent = rig
    result.matrix_parent_inverse = rig.matrix_world.inverted()
    result.matrix_world = world
    result.data.polygons.foreach_set("use_smooth", [True] * len(result.data.polygons))
    bpy.context.view_layer.update()
    return result


def gltf_round_trip_file(obj, directory):
    """The .glb file gltf_round_trip(obj, rig, directory) writes."""
    return os.path.join(directory, obj.name + ".glb")


def glb_triangle_count(path):
    """Triangles a .glb file holds: its meshes' triangle primitives' indices (or vertices, unindexed) over 3, read
    from the file's JSON chunk, so that a round trip that loses triangles says whether the exporter or the importer
    lost them."""
    import json
    import struct
    with open(path, "rb") as glb:
        magic, _version, _length = struct.unpack("<4sII", glb.read(12))
        chunk_length, chunk_type = struct.unpack("<II", glb.read(8))
        if magic != b"glTF" or chunk_type != 0x4E4F534A:
            raise RuntimeError("%s is not a binary glTF file with its JSON first" % path)
        document = json.loads(glb.read(chunk_length))
    accessors = document.get("accessors", [])
    triangles = 0
    for mesh in document.get("meshes", []):
        for primitive in mesh["primitives"]:
            if primitive.get("mode", 4) != 4:
                raise RuntimeError("%s holds a primitive of mode %d, not triangles" % (path, primitive["mode"]))
            counted = primitive["indices"] if "indices" in primitive else primitive["attributes"]["POSITION"]
            triangles += accessors[counted]["count"] // 3
    return triangles


def world_positions(obj, evaluated=False):
    """obj's vertices in world space (mathutils Vectors): its mesh's, or with evaluated its evaluated mesh's."""
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data if evaluated else obj.data
    return [obj.matrix_world @ vertex.co for vertex in mesh.vertices]


def nearest_vertices(source, target):
    """Per vertex of target, the index of the vertex of source nearest to it in world space (their meshes as
    they are, not evaluated). Raises RuntimeError when one is more than 1e-4 away: target is not a copy."""
    tree = kdtree.KDTree(len(source.data.vertices))
    for index, position in enumerate(world_positions(source)):
        tree.insert(position, index)
    tree.balance()
    nearest, worst = [], 0.0
    for position in world_positions(target):
        _co, index, distance = tree.find(position)
        nearest.append(index)
        worst = max(worst, distance)
    if worst > 1e-4:
        raise RuntimeError("%s is no copy of %s: a vertex is %g from the nearest" % (target.name, source.name, worst))
    return nearest


def _copy_weights_by_position(source, target):
    """Every vertex of target gets the vertex groups of the source vertex nearest to it (in world space)."""
    groups = {group.index: target.vertex_groups.new(name=group.name) for group in source.vertex_groups}
    for vertex, index in zip(target.data.vertices, nearest_vertices(source, target)):
        for element in source.data.vertices[index].groups:
            groups[element.group].add([vertex.index], element.weight, 'REPLACE')


def split_vertex_count(obj, relative_tolerance=1e-6):
    """How many vertices of obj's mesh are copies of another one at the same position."""
    import surface_quality
    positions = [tuple(vertex.co) for vertex in obj.data.vertices]
    return len(positions) - len(set(surface_quality.weld_map(positions, relative_tolerance)))



# ---- motion capture on a body grown around its skeleton ---------------------------------------------------

BVH_MODELS = os.environ.get("LVP_ASSIMP_MODELS", "/usr/share/assimp/models")

# Per bone, the flesh's radius at its head and at its tail, in shares of the skeleton's height. BVH files name a
# bone after the joint at its head, and skeletons differ in which joints they have and what they call them:
# the CMU database's conversion (a bone from the hip joint to the knee is LeftUpLeg, a clavicle LeftShoulder)
# and the older one of Boxing_Toes.bvh (that thigh is LeftHip, the upper arm LeftShoulder). Bones left out
# (the importer's stubs at the hips, the chest and the wrists, a tenth of a unit long) get no flesh of their own.
_CMU_FLESH = {
    "LHipJoint": (0.075, 0.055), "LeftUpLeg": (0.055, 0.036), "LeftLeg": (0.036, 0.024), "LeftFoot": (0.024, 0.02),
    "LeftToeBase": (0.02, 0.014), "LowerBack": (0.075, 0.07), "Spine": (0.07, 0.075), "Neck": (0.075, 0.03),
    "Neck1": (0.03, 0.038), "Head": (0.045, 0.035), "LeftShoulder": (0.055, 0.034), "LeftArm": (0.034, 0.026),
    "LeftForeArm": (0.026, 0.018), "LeftFingerBase": (0.018, 0.014), "LFingers": (0.014, 0.01),
    "LThumb": (0.011, 0.008),
}
_BOXING_FLESH = {
    "Hips": (0.075, 0.075), "Ab": (0.072, 0.07), "Chest": (0.07, 0.072), "Neck": (0.04, 0.03),
    "Head": (0.045, 0.035), "LeftCollar": (0.055, 0.034), "LeftShoulder": (0.034, 0.026),
    "LeftElbow": (0.026, 0.018), "LeftWrist": (0.018, 0.012), "LeftHip": (0.055, 0.036), "LeftKnee": (0.036, 0.024),
    "LeftAnkle": (0.024, 0.02), "LeftToes": (0.02, 0.014),
}


def _both_sides(flesh):
    """flesh with each Left / L bone's radii given to its Right / R twin too."""
    both = dict(flesh)
    for name, radii in flesh.items():
        for left, right in (("Left", "Right"), ("LHip", "RHip"), ("LFingers", "RFingers"), ("LThumb", "RThumb")):
            if name.startswith(left):
                both[right + name[len(left):]] = radii
    return both


# name: (file under BVH_MODELS, the flesh of its skeleton, what it does)
MOCAP_CLIPS = {
    "jumps": ("BVH/01_01.bvh", _both_sides(_CMU_FLESH), "CMU subject 1: forward jumps, turning round"),
    "climbing": ("BVH/01_03.bvh", _both_sides(_CMU_FLESH), "CMU subject 1: climbing, hanging, stepping down"),
    "boxing": ("BVH/Boxing_Toes.bvh", _both_sides(_BOXING_FLESH), "a boxer's punches and footwork"),
}


def _skeleton_spheres(rig, flesh):
    """Spheres along each bone of `flesh` from its head's radius to its tail's (shares of the rest skeleton's
    height), and where a bone starts away from its parent's ends (Boxing_Toes.bvh's hips sit 12 cm either side of
    its root) from the nearer end to its head."""
    bones = rig.data.bones
    heights = [point.z for bone in bones for point in (bone.head_local, bone.tail_local)]
    height = max(heights) - min(heights)
    spheres = []
    for bone in bones:
        if bone.name not in flesh:
            continue
        head_radius, tail_radius = (height * share for share in flesh[bone.name])
        spheres += _chain([bone.head_local, bone.tail_local], [head_radius, tail_radius])
        parent = bone.parent
        if parent is None or parent.name not in flesh:
            continue
        ends = ((parent.head_local, flesh[parent.name][0]), (parent.tail_local, flesh[parent.name][1]))
        end, share = min(ends, key=lambda end_share: (end_share[0] - bone.head_local).length)
        if (end - bone.head_local).length > 1e-3 * height:
            spheres += _chain([end, bone.head_local], [height * share, head_radius])
    return spheres, height


def mocap_character(clip="jumps", voxel_share=0.015, decimated=None):
    """(body, rig, first, last): the clip of MOCAP_CLIPS imported as a user does (File > Import > Motion Capture,
    its defaults: an armature in the file's units with the whole clip as its action), a closed body grown around
    the rest skeleton (spheres along its bones, a voxel remesh of voxel_share of its height, decimated to that
    ratio of its faces when given), parented With Automatic Weights; the scene's frame range set to the clip's.
    Raises unittest.SkipTest where the file is missing or this Blender cannot import BVH files, RuntimeError when
    the body is not closed or heat weighting leaves it unweighted."""
    relative, flesh, _what = MOCAP_CLIPS[clip]
    path = os.path.join(BVH_MODELS, relative)
    if not os.path.isfile(path):
        raise unittest.SkipTest("%s is missing: apt-get install assimp-testmodels" % path)
    try:
        bpy.ops.import_anim.bvh(filepath=path)
    except RuntimeError as error:
        if "invalid mode: 'rU'" in str(error):  # Blender 3.4's importer on Python 3.11, as Debian builds it
            raise unittest.SkipTest("this Blender's BVH importer opens files in mode 'rU', which its Python "
                                    "removed") from None
        raise
    rig = next(obj for obj in bpy.data.objects if obj.type == 'ARMATURE')
    first, last = (int(round(frame)) for frame in rig.animation_data.action.frame_range)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = first, last
    scene.frame_set(first)
    rig.data.pose_position = 'REST'  # the body is grown around the rest skeleton and weighted there
    spheres, height = _skeleton_spheres(rig, flesh)
    body = closed_surface("Body", spheres, voxel_share * height)
    if decimated is not None:
        decimate(body, decimated)
    if open_edge_count(body.data):
        raise RuntimeError("the body around %s is not closed" % relative)
    if parent_with_automatic_weights(body, rig) != {'FINISHED'}:
        raise RuntimeError("With Automatic Weights failed on the body around %s" % relative)
    rig.data.pose_position = 'POSE'
    bpy.context.view_layer.update()
    limbs = [name for name in empty_vertex_groups(body) if rig.data.bones[name].length > 0.1 * height]
    if limbs:
        raise RuntimeError("heat weighting left %s empty" % limbs)
    return body, rig, first, last


# ---- a body modelled by hand ------------------------------------------------------------------------------------

MODELLED_HUMAN = "BLEND/HUMAN.blend"  # in assimp-testmodels: (c) 2010 Tobias Rittig, reuse allowed for any purpose

# The rig a user places by hand in the modelled human (its mesh's units: 10.7 tall, feet at z -5.2, arms hanging
# 20 degrees out): per bone, its head, its tail and its parent, the left side (+x) mirrored to the right. The
# joints lie on the limbs' centre lines, measured from the subdivided mesh.
_MODELLED_HUMAN_BONES = {
    "pelvis": ((0.0, 0.2, 0.2), (0.0, 0.2, -0.6), None),
    "spine": ((0.0, 0.2, 0.2), (0.0, 0.2, 1.6), "pelvis"),
    "chest": ((0.0, 0.2, 1.6), (0.0, 0.2, 3.4), "spine"),
    "neck": ((0.0, 0.2, 3.4), (0.0, 0.15, 4.0), "chest"),
    "head": ((0.0, 0.15, 4.0), (0.0, 0.0, 5.5), "neck"),
    "thigh.L": ((0.75, 0.25, -0.5), (0.8, 0.2, -2.8), "pelvis"),
    "shin.L": ((0.8, 0.2, -2.8), (0.84, 0.35, -5.15), "thigh.L"),
    "shoulder.L": ((0.3, 0.2, 3.3), (1.1, 0.2, 3.35), "chest"),
    "upper_arm.L": ((1.15, 0.25, 3.3), (1.68, 0.3, 1.9), "shoulder.L"),
    "forearm.L": ((1.68, 0.3, 1.9), (2.15, 0.0, 0.45), "upper_arm.L"),
    "hand.L": ((2.15, 0.0, 0.45), (2.3, -0.13, -0.05), "forearm.L"),
}


def _modelled_human_armature(name):
    """The armature of _MODELLED_HUMAN_BONES, both sides, each child connected where its head is its parent's
    tail."""
    data = bpy.data.armatures.new(name)
    rig = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(rig)
    _select_only(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    for bone_name, (head, tail, parent) in _MODELLED_HUMAN_BONES.items():
        sides = ((bone_name, 1.0, parent),)
        if bone_name.endswith(".L"):
            sides += ((bone_name[:-2] + ".R", -1.0, parent[:-2] + ".R" if parent.endswith(".L") else parent),)
        for side_name, sign, side_parent in sides:
            bone = data.edit_bones.new(side_name)
            bone.head = (sign * head[0], head[1], head[2])
            bone.tail = (sign * tail[0], tail[1], tail[2])
            if side_parent:
                bone.parent = data.edit_bones[side_parent]
                bone.use_connect = (bone.parent.tail - bone.head).length < 1e-6
    bpy.ops.object.mode_set(mode='OBJECT')
    return rig


def modelled_human(subdivisions=2):
    """(body, rig): the human of assimp-testmodels' HUMAN.blend, a mannequin modelled by hand from a box (151
    vertices of quads, a Mirror and a Subdivision Surface modifier), appended as File > Append does, its modifiers
    applied with the subdivision at `subdivisions` levels (1: 1,072 vertices, 2: 4,282, all quads, long along the
    limbs and short around them), parented With Automatic Weights to a rig of 17 bones placed by hand. Raises
    unittest.SkipTest where the file is missing."""
    path = os.path.join(BVH_MODELS, MODELLED_HUMAN)
    if not os.path.isfile(path):
        raise unittest.SkipTest("%s is missing: apt-get install assimp-testmodels" % path)
    with bpy.data.libraries.load(path) as (source, target):
        target.objects = ["Cube"]
    appended = target.objects[0]
    bpy.context.scene.collection.objects.link(appended)
    appended.modifiers["Subsurf"].levels = subdivisions
    modelled = appended.data
    body = _as_mesh_object(appended, "ModelledHuman")
    bpy.data.meshes.remove(modelled)
    rig = _modelled_human_armature("ModelledHumanRig")
    if parent_with_automatic_weights(body, rig) != {'FINISHED'}:
        raise RuntimeError("With Automatic Weights failed on the modelled human")
    empty = empty_vertex_groups(body)
    if empty:
        raise RuntimeError("heat weighting left %s empty" % empty)
    return body, rig


def _turn_about(rig, bone_name, axis, degrees):
    """Pose bone `bone_name` turned by `degrees` about `axis`, given in the armature's rest space (the turn is
    applied in the bone's own rest frame, so the axis moves with the bones above it)."""
    pose_bone = rig.pose.bones[bone_name]
    pose_bone.rotation_mode = 'QUATERNION'
    local_axis = pose_bone.bone.matrix_local.to_3x3().inverted() @ Vector(axis)
    pose_bone.rotation_quaternion = Quaternion(local_axis.normalized(), math.radians(degrees))


def _elbow_hinge(sign):
    """The axis an elbow bends about, for the left (sign 1) or right (-1) arm: across the upper arm and the body's
    facing (-y), so that a positive turn brings the forearm forward."""
    head, tail, _parent = _MODELLED_HUMAN_BONES["upper_arm.L"]
    upper_arm = Vector((sign * (tail[0] - head[0]), tail[1] - head[1], tail[2] - head[2]))
    return tuple(upper_arm.cross(Vector((0.0, -1.0, 0.0))))


_ACROSS = (1.0, 0.0, 0.0)  # a knee's and a hip's hinge: positive turns a shin back, negative a thigh forward
_FRONT_TO_BACK = (0.0, 1.0, 0.0)  # turns a hanging arm in towards the body (left arm negative, right positive)

# name: the turns that pose_modelled_human makes, (bone, axis in rest space, degrees)
MODELLED_HUMAN_POSES = {
    "knees at 150 degrees": (("shin.L", _ACROSS, 150.0), ("shin.R", _ACROSS, 150.0)),
    "crouching": (("thigh.L", _ACROSS, -100.0), ("thigh.R", _ACROSS, -100.0), ("shin.L", _ACROSS, 140.0),
                  ("shin.R", _ACROSS, 140.0)),
    "hips at 110 degrees": (("thigh.L", _ACROSS, -110.0), ("thigh.R", _ACROSS, -110.0)),
    "elbows at 140 degrees": (("forearm.L", _elbow_hinge(1.0), 140.0), ("forearm.R", _elbow_hinge(-1.0), 140.0)),
    "arms against the chest": (("upper_arm.L", _FRONT_TO_BACK, -28.0), ("upper_arm.R", _FRONT_TO_BACK, 28.0)),
    "arms down, elbows at 120 degrees": (("upper_arm.L", _FRONT_TO_BACK, -25.0), ("upper_arm.R", _FRONT_TO_BACK, 25.0),
                                         ("forearm.L", _elbow_hinge(1.0), 120.0),
                                         ("forearm.R", _elbow_hinge(-1.0), 120.0)),
}


def pose_modelled_human(rig, pose):
    """The rig at MODELLED_HUMAN_POSES[pose], every other bone at rest."""
    for pose_bone in rig.pose.bones:
        pose_bone.rotation_mode = 'QUATERNION'
        pose_bone.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
    for bone_name, axis, degrees in MODELLED_HUMAN_POSES[pose]:
        _turn_about(rig, bone_name, axis, degrees)
    bpy.context.view_layer.update()
