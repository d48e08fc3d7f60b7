# SPDX-License-Identifier: GPL-3.0-or-later
"""Helpers for the headless-Blender tests: enabling the add-on, building the paper's cylinder and
other test scenes, reading evaluated meshes, measuring volumes, running a second Blender.

Used by tests/blender/test_*.py (run by tests/blender/runner.py) and by bench.py. No numpy.
"""

import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
import unittest
from array import array

import bpy
from mathutils import Matrix, Quaternion, Vector

ADDON_ID = "local_volume_preservation"
HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.environ.get("LVP_REPO") or os.path.dirname(os.path.dirname(HERE))
EXTENSION_REPO = "lvp_test"

_addon_module = None


# ---- the add-on ----------------------------------------------------------------------------


def addon_dir():
    return os.environ.get("LVP_ADDON_DIR") or os.path.join(REPO, "dist", ADDON_ID)


def extension_zip():
    path = os.environ.get("LVP_EXTENSION_ZIP")
    if path:
        return path
    # This machine's zip (Linux x86-64: the one whose module loads here), the newest.
    folder = os.path.join(REPO, "dist")
    zips = [os.path.join(folder, name) for name in os.listdir(folder)
            if name.startswith(ADDON_ID + "-") and name.endswith("-linux_x64.zip")] if os.path.isdir(folder) else []
    return max(zips, key=os.path.getmtime) if zips else ""


def uses_extensions():
    return bpy.app.version >= (4, 2, 0)


def test_tmp():
    path = os.environ.get("LVP_TEST_TMP")
    if not path:
        path = tempfile.mkdtemp(prefix="lvp-test-")
        os.environ["LVP_TEST_TMP"] = path
    os.makedirs(path, exist_ok=True)
    return path


def _install_extension(zip_path):
    """Installs the zip into a fresh local extension repository under the test directory (never the
    user's own repositories) and enables it. Returns the module name."""
    import addon_utils
    directory = os.path.join(test_tmp(), "extensions")
    os.makedirs(directory, exist_ok=True)
    repos = bpy.context.preferences.extensions.repos
    repo = None
    for candidate in repos:
        if candidate.module == EXTENSION_REPO:
            repo = candidate
    if repo is None:
        repo = repos.new(name="LVP Test", module=EXTENSION_REPO, custom_directory=directory, source='USER')
    module_name = "bl_ext.%s.%s" % (EXTENSION_REPO, ADDON_ID)
    if not os.path.isfile(os.path.join(directory, ADDON_ID, "blender_manifest.toml")):
        result = bpy.ops.extensions.package_install_files(filepath=zip_path, repo=EXTENSION_REPO,
                                                          enable_on_install=True)
        if 'FINISHED' not in result:
            raise RuntimeError("installing %s as an extension failed: %r" % (zip_path, result))
    if module_name not in {addon.module for addon in bpy.context.preferences.addons}:
        addon_utils.enable(module_name, default_set=True)
    return module_name


def enable_addon(check_volumes=True):
    """Enables the add-on once per Blender process and returns its package module.

    Blender 4.2+: the packaged zip installed as an extension. Blender 3.4: the add-on folder (the
    runner puts its parent on sys.path). check_volumes: every correction checked against volumes
    measured on their own (_check_every_correction), for the rest of the process; benchmarks, which
    time what users run, leave it off.
    """
    global _addon_module
    if _addon_module is not None and is_registered():
        return _addon_module
    # First call, or something disabled the add-on since (wm.read_factory_settings in another test
    # module resets the preferences and with them the enabled add-ons and extension repositories).
    import addon_utils
    import importlib
    if uses_extensions():
        zip_path = extension_zip()
        if not zip_path or not os.path.isfile(zip_path):
            raise unittest_skip("no extension zip (run ./build.sh first)")
        module_name = _install_extension(zip_path)
    else:
        folder = addon_dir()
        if not os.path.isdir(folder):
            raise unittest_skip("no add-on folder %s (run ./build.sh first)" % folder)
        parent = os.path.dirname(folder)
        if parent not in sys.path:
            sys.path.insert(0, parent)
        module_name = ADDON_ID
        addon_utils.enable(module_name, default_set=True)
    _addon_module = importlib.import_module(module_name)
    if not hasattr(bpy.types.Object, "lvp"):
        raise RuntimeError("the add-on %s did not register (Object.lvp is missing)" % module_name)
    if check_volumes:
        _check_every_correction(_addon_module)
    return _addon_module


# ---- what the core says against what it was given and what it gave -----------------------------

# Every frame any test corrects: the core's volume before is the volume of the positions it was given, and its
# volume after the volume of those positions moved by the offsets it wrote, each measured on its own (the module's
# mesh_volume over the mesh's triangles), to this share. A shortcut of the core's (a region taken as moving
# rigidly, a cached sum) that disagrees with the positions shows here. Only for closed meshes: the core caps an
# open mesh's holes. runner.py fails a test that passed otherwise when one did not hold.
VOLUME_AGREEMENT = 1e-6
VOLUME_DISAGREEMENTS = []


def _check_volumes(obj, bound, rest_positions, stats):
    mesh = obj.data
    if len(bound.positions) != 3 * len(mesh.vertices) or not stats["volume_rest"]:
        return
    triangles = mesh_triangles(mesh)
    measure = lvp().mesh_volume
    rest = rest_positions if rest_positions is not None else mesh_positions(mesh)
    if abs(measure(rest, triangles) / stats["volume_rest"] - 1.0) > VOLUME_AGREEMENT:
        return  # open (holes capped by the core), or the rest edited since the bind (bound again soon)
    import operator
    given = measure(bound.positions, triangles)
    shown = measure(array('f', map(operator.add, bound.positions, bound.offsets)), triangles)
    for name, measured in (("volume_before", given), ("volume_after", shown)):
        if abs(stats[name] / measured - 1.0) > VOLUME_AGREEMENT:
            VOLUME_DISAGREEMENTS.append("%s, frame %g: the core's %s %.9g, measured %.9g" % (
                obj.name, bpy.context.scene.frame_current, name, stats[name], measured))


def _check_every_correction(addon):
    """Wraps the add-on's one call of the core's correction (live._core_correction) with _check_volumes."""
    live = addon.live
    original = live._core_correction
    if getattr(original, "volumes_checked", False):
        return

    def checked(obj, bound, rest_positions, fold_over, keep_apart):
        stats, failure = original(obj, bound, rest_positions, fold_over, keep_apart)
        if failure is None:
            _check_volumes(obj, bound, rest_positions, stats)
        return stats, failure

    checked.volumes_checked = True
    live._core_correction = checked


def is_registered():
    return hasattr(bpy.types.Object, "lvp") and hasattr(bpy.types, "OBJECT_OT_lvp_add")


def unittest_skip(message):
    return unittest.SkipTest(message)


def lvp():
    """The compiled _lvp module inside the enabled add-on."""
    return enable_addon()._lvp


# ---- scenes --------------------------------------------------------------------------------


def reset_scene():
    """An empty scene (keeps the add-on and its handlers)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start = 1
    scene.frame_end = 10
    scene.frame_set(1)
    return scene


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def select_only(*objects):
    for obj in bpy.context.view_layer.objects:
        obj.select_set(False)
    for obj in objects:
        obj.select_set(True)
    if objects:
        bpy.context.view_layer.objects.active = objects[0]


def show_only_one(setups, shown):
    """Of the objects of setups (a dict), only shown is shown in the viewport: the benchmarks time one setup
    at a time, the others not evaluated."""
    for obj in set(setups.values()):
        obj.hide_viewport = obj is not shown


def self_intersection_test_ms(obj, repeats=3):
    """Blender's own test of obj's evaluated triangles against each other, median ms over repeats: mathutils'
    BVHTree built from the evaluated mesh (BVHTree.FromObject), then overlapped with itself (triangles sharing an
    edge passed over). The benchmarks print it beside Keep Skin Apart's frame for scale: an exact crossing test of
    every triangle as Blender itself runs one."""
    from mathutils.bvhtree import BVHTree
    depsgraph = bpy.context.evaluated_depsgraph_get()
    times = []
    for _repeat in range(repeats):
        start = time.perf_counter()
        tree = BVHTree.FromObject(obj, depsgraph)
        tree.overlap(tree)
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def render_tiny_still(scene):
    """An F12 render of scene in this process (bpy.ops.render.render): Cycles, one sample, 4 x 4 pixels, a
    camera added when the scene has none; only the handlers it runs matter. The scene's settings come back."""
    render = scene.render
    kept = (render.engine, render.resolution_x, render.resolution_y, scene.camera)
    camera = None
    if scene.camera is None:
        camera = link(bpy.data.objects.new("TinyRenderCamera", bpy.data.cameras.new("TinyRenderCamera")))
        scene.camera = camera
    render.engine = 'CYCLES'
    samples, denoising = scene.cycles.samples, scene.cycles.use_denoising
    scene.cycles.samples, scene.cycles.use_denoising = 1, False  # Debian's Blender has no OpenImageDenoise
    render.resolution_x = render.resolution_y = 4
    try:
        bpy.ops.render.render()
    finally:
        scene.cycles.samples, scene.cycles.use_denoising = samples, denoising
        render.engine, render.resolution_x, render.resolution_y, scene.camera = kept
        if camera is not None:
            bpy.data.objects.remove(camera)


def cylinder_mesh(name="Cylinder", rings=16, around=16, radius=0.5, length=4.0, caps=True):
    """The paper's cylinder: rings x around side vertices along +Z from 0 to length, closed by two
    n-gon caps (no extra vertices), faces wound outward."""
    vertices = []
    for ring in range(rings):
        z = length * ring / (rings - 1)
        for step in range(around):
            angle = 2.0 * math.pi * step / around
            vertices.append((radius * math.cos(angle), radius * math.sin(angle), z))
    faces = []
    for ring in range(rings - 1):
        for step in range(around):
            a = ring * around + step
            b = ring * around + (step + 1) % around
            faces.append((a, b, b + around, a + around))
    if caps:
        faces.append(tuple(reversed(range(around))))
        faces.append(tuple((rings - 1) * around + step for step in range(around)))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    mesh.validate()
    mesh.update()
    return mesh


def two_bone_armature(name="Rig", length=4.0):
    """Two bones along +Z: "Lower" from 0 to length/2, "Upper" from length/2 to length (child)."""
    armature = bpy.data.armatures.new(name)
    rig = link(bpy.data.objects.new(name, armature))
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    lower = armature.edit_bones.new("Lower")
    lower.head = (0.0, 0.0, 0.0)
    lower.tail = (0.0, 0.0, length / 2)
    upper = armature.edit_bones.new("Upper")
    upper.head = (0.0, 0.0, length / 2)
    upper.tail = (0.0, 0.0, length)
    upper.parent = lower
    upper.use_connect = True
    bpy.ops.object.mode_set(mode='OBJECT')
    return rig


def weight_linear_band(obj, joint=2.0, band=2.6, lower="Lower", upper="Upper"):
    """The paper's weights: linear across a band of width `band` centred on the joint (along Z)."""
    lower_group = obj.vertex_groups.new(name=lower)
    upper_group = obj.vertex_groups.new(name=upper)
    for vertex in obj.data.vertices:
        t = (vertex.co.z - (joint - band / 2)) / band
        t = min(max(t, 0.0), 1.0)
        if t < 1.0:
            lower_group.add([vertex.index], 1.0 - t, 'REPLACE')
        if t > 0.0:
            upper_group.add([vertex.index], t, 'REPLACE')


def add_armature_modifier(obj, rig, preserve_volume=False):
    modifier = obj.modifiers.new("Armature", 'ARMATURE')
    modifier.object = rig
    modifier.use_deform_preserve_volume = preserve_volume
    return modifier


def make_cylinder_character(name="Cylinder", rig=None, location=(0.0, 0.0, 0.0), parent=True,
                            preserve_volume=False):
    """(mesh object, armature object): the paper's cylinder skinned to two bones, not corrected yet."""
    if rig is None:
        rig = two_bone_armature(name + "Rig")
    obj = link(bpy.data.objects.new(name, cylinder_mesh(name)))
    obj.location = location
    weight_linear_band(obj)
    add_armature_modifier(obj, rig, preserve_volume)
    if parent:
        obj.parent = rig
    bpy.context.view_layer.update()
    return obj, rig


def bend(rig, degrees, bone="Upper", axis=(1.0, 0.0, 0.0)):
    """Rotates a pose bone about a local axis (the cylinder's joint bend)."""
    pose_bone = rig.pose.bones[bone]
    pose_bone.rotation_mode = 'QUATERNION'
    pose_bone.rotation_quaternion = Quaternion(Vector(axis), math.radians(degrees))


def keyframe_bend(rig, frame_degrees, bone="Upper", axis=(1.0, 0.0, 0.0)):
    """Keys the bone's rotation: {frame: degrees}."""
    for frame, degrees in sorted(frame_degrees.items()):
        bend(rig, degrees, bone, axis)
        rig.pose.bones[bone].keyframe_insert("rotation_quaternion", frame=frame)


def modifier_operator(obj, name, **arguments):
    """Runs bpy.ops.object.<name> (modifier_move_to_index, modifier_copy, modifier_apply...) on obj."""
    with bpy.context.temp_override(object=obj, active_object=obj):
        return getattr(bpy.ops.object, name)(**arguments)


def add_volume_preservation(*objects):
    """Runs object.lvp_add on the objects; returns the operator's result."""
    select_only(*objects)
    result = bpy.ops.object.lvp_add()
    bpy.context.view_layer.update()
    return result


# ---- reading evaluated geometry ------------------------------------------------------------


def evaluated_mesh(obj, depsgraph=None):
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    return obj.evaluated_get(depsgraph).data


def evaluated_positions(obj, depsgraph=None, first=None):
    """Positions of the evaluated mesh (the first `first` vertices when given), float32[3n]."""
    mesh = evaluated_mesh(obj, depsgraph)
    count = len(mesh.vertices)
    positions = array('f', bytes(12 * count))
    mesh.vertices.foreach_get("co", positions)
    if first is not None:
        positions = positions[:3 * first]
    return positions


def captured_positions(obj, depsgraph=None):
    """What entered the Volume Preservation modifier (its "lvp_position" attribute) on the original
    vertices, the first of the evaluated mesh, float32[3N]."""
    mesh = evaluated_mesh(obj, depsgraph)
    positions = array('f', bytes(12 * len(mesh.vertices)))
    mesh.attributes["lvp_position"].data.foreach_get("vector", positions)
    return positions[:3 * len(obj.data.vertices)]


def mesh_positions(mesh):
    positions = array('f', bytes(12 * len(mesh.vertices)))
    mesh.vertices.foreach_get("co", positions)
    return positions


def blender_triangles(mesh):
    """Blender's own loop triangles of the mesh, int32[3T], as it hands them (mesh_data.blender_loop_triangles)."""
    return enable_addon().mesh_data.blender_loop_triangles(mesh)


def mesh_triangles(mesh):
    """The mesh's triangles, int32[3T], read as the add-on's bind reads them (mesh_data.loop_triangles: Blender's
    own split, made again when its cached one does not fit the mesh), so that a measure never reads a corner
    past the mesh's vertices."""
    return enable_addon().mesh_data.loop_triangles(mesh)


def offsets_of(obj):
    """The offsets obj's Volume Preservation modifier adds, float32[3N], read from its offsets object
    (None when obj has no such modifier)."""
    return enable_addon().offsets.read(obj)


def offsets_object(obj):
    """The offsets object that obj's Volume Preservation modifier reads (addon/offsets.py)."""
    addon = enable_addon()
    return addon.offsets.offsets_object(addon.node_group.find_modifier(obj))


def volume(positions, triangles):
    return lvp().mesh_volume(positions, triangles)


def max_abs(values):
    return max((abs(value) for value in values), default=0.0)


def max_distance(a, b):
    """Largest per-vertex distance between two float[3n] arrays."""
    assert len(a) == len(b), (len(a), len(b))
    worst = 0.0
    for index in range(0, len(a), 3):
        dx = a[index] - b[index]
        dy = a[index + 1] - b[index + 1]
        dz = a[index + 2] - b[index + 2]
        worst = max(worst, dx * dx + dy * dy + dz * dz)
    return math.sqrt(worst)


def vertex_distances(a, b):
    return [math.sqrt((a[i] - b[i]) ** 2 + (a[i + 1] - b[i + 1]) ** 2 + (a[i + 2] - b[i + 2]) ** 2)
            for i in range(0, len(a), 3)]


def core_skinned_positions(obj, rig, dual_quaternion=False):
    """The object's rest mesh skinned by the core (lvp_skin_linear or _dual_quaternion) with what the
    add-on gave it at the last frame it corrected: its bones (B-Bone joints, the still bone of the
    Armature modifier's mask) and their weights. lvp_correct() requires this to be what the Armature
    modifier made (lvp.h), float32[3N]."""
    addon = enable_addon()
    bound = addon.session.SESSION.bound(obj)
    core_skeleton = bound.skeleton
    mesh_data = addon.mesh_data
    rest = mesh_data.vertex_positions(obj.data)
    weights = core_skeleton.core_weights(obj, rig.pose, rest, *mesh_data.weights_csr(obj, core_skeleton.bone_names))
    rest_matrices, _heads, _tails = core_skeleton.rest_arrays()
    skin_matrices = array('f', bytes(64 * core_skeleton.core_bone_count))
    for index in range(core_skeleton.core_bone_count):
        posed = Matrix([bound.bone_matrices[16 * index + 4 * row:16 * index + 4 * row + 4] for row in range(4)])
        resting = Matrix([rest_matrices[16 * index + 4 * row:16 * index + 4 * row + 4] for row in range(4)])
        mesh_data.flatten_matrix(posed @ resting.inverted(), skin_matrices, 16 * index)
    skinned = array('f', bytes(4 * len(rest)))
    skinning = lvp().skin_dual_quaternion if dual_quaternion else lvp().skin_linear
    skinning(skinned, rest, *weights, skin_matrices)
    return skinned


def uncorrected_positions(obj, depsgraph=None):
    """The object's evaluated positions with Volume Preservation switched off (switched back on)."""
    from_module = enable_addon()
    modifier = from_module.node_group.find_modifier(obj)
    modifier.show_viewport = False
    bpy.context.view_layer.update()
    positions = evaluated_positions(obj, depsgraph)
    modifier.show_viewport = True
    bpy.context.view_layer.update()
    return positions


def relative_volume_error(positions, triangles, rest_volume):
    return abs(volume(positions, triangles) - rest_volume) / abs(rest_volume)


def volume_errors(obj, triangles=None, rest_volume=None):
    """(corrected, plain) relative volume errors of obj's evaluated mesh, against rest_volume (by
    default its mesh's volume, with its triangles)."""
    if triangles is None:
        triangles = mesh_triangles(obj.data)
    if rest_volume is None:
        rest_volume = volume(mesh_positions(obj.data), triangles)
    corrected = evaluated_positions(obj)
    plain = uncorrected_positions(obj)
    return (relative_volume_error(corrected, triangles, rest_volume),
            relative_volume_error(plain, triangles, rest_volume))


def topology_counts(mesh):
    return (len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops))


def mesh_snapshot(mesh):
    """Everything a user could lose on a mesh, as comparable Python values."""
    snapshot = {
        "positions": mesh_positions(mesh).tobytes(),
        "edges": _foreach(mesh.edges, "vertices", 2, 'i'),
        "loops": _foreach(mesh.loops, "vertex_index", 1, 'i'),
        "polygons": _foreach(mesh.polygons, "loop_total", 1, 'i'),
        "attributes": sorted((attribute.name, attribute.domain, attribute.data_type)
                             for attribute in mesh.attributes),
        "shape_keys": None,
    }
    if mesh.shape_keys is not None:
        snapshot["shape_keys"] = [(block.name, block.value, _foreach(block.data, "co", 3, 'f'))
                                  for block in mesh.shape_keys.key_blocks]
    return snapshot


def object_snapshot(obj):
    snapshot = mesh_snapshot(obj.data)
    snapshot["vertex_groups"] = [(group.name, [(vertex.index, round(element.weight, 6))
                                               for vertex in obj.data.vertices for element in vertex.groups
                                               if element.group == group.index])
                                 for group in obj.vertex_groups]
    snapshot["modifiers"] = [(modifier.name, modifier.type, modifier.show_viewport, modifier.show_render)
                             for modifier in obj.modifiers]
    snapshot["matrix_world"] = [tuple(row) for row in obj.matrix_world]
    return snapshot


def _foreach(collection, attribute, width, kind):
    values = array(kind, bytes(4 * width * len(collection)))
    collection.foreach_get(attribute, values)
    return values.tobytes()


# ---- a second Blender ----------------------------------------------------------------------


def blender_command():
    """The command that starts this same Blender (inside a chroot, binary_path works as is)."""
    return [bpy.app.binary_path, "-b", "--factory-startup", "-noaudio"]


def enable_script_path():
    """A script that enables the add-on in a fresh Blender the same way enable_addon() does here."""
    path = os.path.join(test_tmp(), "enable_addon.py")
    with open(path, "w") as file:
        file.write(
            "import os, sys\n"
            "sys.path.insert(0, %r)\n"
            "import lvp_helpers\n"
            "lvp_helpers.enable_addon()\n" % HERE)
    return path


def run_blender(arguments, timeout=300, with_addon=True):
    """Runs a fresh background Blender with the add-on enabled (unless with_addon is false) before
    ARGUMENTS are processed.

    Returns the CompletedProcess (stdout and stderr as text). Its environment tells the child where
    the add-on is, and gives it its own extension directory."""
    environment = dict(os.environ)
    environment["LVP_TEST_TMP"] = tempfile.mkdtemp(prefix="child-", dir=test_tmp())
    command = blender_command() + ["--python-exit-code", "1"]
    if with_addon:
        command += ["--python", enable_script_path()]
    command += list(arguments)
    return subprocess.run(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
                          timeout=timeout, env=environment)


def fresh_directory(prefix):
    return tempfile.mkdtemp(prefix=prefix + "-", dir=test_tmp())


# ---- test base -----------------------------------------------------------------------------


class AddonTestCase(unittest.TestCase):
    """Enables the add-on once and starts every test from an empty scene."""

    @classmethod
    def setUpClass(cls):
        cls.addon = enable_addon()

    def setUp(self):
        type(self).addon = enable_addon()
        reset_scene()

    def assertSmallerThan(self, value, limit, message=""):
        self.assertLess(value, limit, "%s: %g is not below %g" % (message, value, limit))

    def status_of(self, obj):
        return self.addon.session.SESSION.status(obj)

    def assertEachFrameAsOpenedAlone(self, obj, frames):
        """Plays `frames` in order, then evaluates each again, last first, bound anew as a file opened at that
        frame is: the same offsets, bit for bit, whatever was evaluated before. Returns {frame: offsets}."""
        scene = bpy.context.scene
        played = {}
        for frame in frames:
            scene.frame_set(frame)
            played[frame] = offsets_of(obj)
        for frame in reversed(frames):
            self.addon.session.SESSION.forget(obj)
            scene.frame_set(frame)
            self.assertEqual(self.status_of(obj)[0], 'INFO', "frame %d: %s" % (frame, self.status_of(obj)))
            alone = offsets_of(obj)
            if alone != played[frame]:
                self.fail("%s: frame %d opened alone differs from the frame played to by %g"
                          % (obj.name, frame, max_distance(alone, played[frame])))
        return played

    def assertStatusContains(self, obj, text):
        status = self.status_of(obj)
        self.assertIsNotNone(status, "no status for %s" % obj.name)
        self.assertIn(text.lower(), status[1].lower(), "status of %s is %r" % (obj.name, status))
