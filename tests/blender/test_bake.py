# SPDX-License-Identifier: GPL-3.0-or-later
"""Baking to PC2 (docs/baking.md): object.lvp_bake in this Blender, and the headless command
(`-c lvp_bake` on 4.2+, `--python <add-on>/bake/lvp_bake.py --` everywhere) in a second Blender.

- every baked frame equals the live evaluated mesh at that frame (bit for bit: the same floats);
- a Mesh Cache modifier on a copy of the mesh replays the same positions;
- missing object, object without the modifier, empty or reversed range, unwritable directory and a
  disk that fills mid-bake: a clear message, a non-zero exit and no file with the final name;
- a killed bake resumes where it stopped; chunks baked out of order merge; --jobs 2 == --jobs 1.

The disk and the read-only directory are real: a tmpfs mounted in a private mount namespace
(unshare -m, needs root) around the second Blender; without root, RLIMIT_FSIZE and a file in the
way stand in for them.
"""

import os
import shutil
import signal
import subprocess
import tempfile
import time
import unittest

import bpy

import giraffe_import
import lvp_helpers as helpers

GIRAFFE_BENDS = (  # bone, axis, degrees at the last frame
    ("gi_neckC7", (1.0, 0.0, 0.0), 60.0),
    ("gi_L_knee", (0.0, 0.0, 1.0), -60.0),
    ("gi_tailA", (1.0, 0.0, 0.0), -60.0),
)


def read_pc2(path):
    pc2 = helpers.enable_addon().bake.pc2
    return pc2.read_pc2(path)


def keyframe_giraffe(rig, last_frame):
    for bone_name, axis, degrees in GIRAFFE_BENDS:
        for frame, factor in ((1, 0.0), (last_frame, 1.0)):
            pose_bone = rig.pose.bones[bone_name]
            pose_bone.rotation_mode = 'QUATERNION'
            from mathutils import Quaternion, Vector
            import math
            pose_bone.rotation_quaternion = Quaternion(Vector(axis), math.radians(degrees * factor))
            pose_bone.keyframe_insert("rotation_quaternion", frame=frame)


def giraffe_scene(last_frame=24):
    """The paper's giraffe with Volume Preservation, neck, knee and tail bending over the frames."""
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, last_frame
    obj, rig = giraffe_import.build_giraffe()
    keyframe_giraffe(rig, last_frame)
    scene.frame_set(1)
    if helpers.add_volume_preservation(obj) != {'FINISHED'}:
        raise RuntimeError("object.lvp_add failed on the giraffe")
    # A bake corrects as renders do (Keep Skin Apart: Render, on by default); the viewport the same, so
    # that the live mesh the tests compare with is what a render shows.
    obj.lvp.keep_apart = True
    return obj, rig


def cylinder_scene(last_frame=12):
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, last_frame
    obj, rig = helpers.make_cylinder_character()
    helpers.keyframe_bend(rig, {1: 0.0, last_frame // 2: 90.0, last_frame: 30.0})
    scene.frame_set(1)
    if helpers.add_volume_preservation(obj) != {'FINISHED'}:
        raise RuntimeError("object.lvp_add failed on the cylinder")
    return obj, rig


def live_frames(obj, frames):
    scene = bpy.context.scene
    result = {}
    for frame in frames:
        scene.frame_set(frame)
        result[frame] = helpers.evaluated_positions(obj)
    return result


class BakeTestCase(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.out = helpers.fresh_directory("bake")

    def bake(self, obj, first, last, **options):
        helpers.select_only(obj)
        return bpy.ops.object.lvp_bake(filepath=self.out, frame_start=first, frame_end=last, **options)

    def assertFramesEqualLive(self, obj, path, first, last):
        header, samples = read_pc2(path)
        self.assertEqual((header.num_points, header.start_frame, header.sample_rate, header.num_samples),
                         (len(obj.data.vertices), float(first), 1.0, last - first + 1))
        live = live_frames(obj, range(first, last + 1))
        for index, frame in enumerate(range(first, last + 1)):
            # The same floats: what the bake wrote is what the viewport shows.
            self.assertEqual(samples[index].tobytes(), live[frame].tobytes(),
                             "frame %d differs from the live mesh by %g" % (
                                 frame, helpers.max_distance(samples[index], live[frame])))
        return samples


class TestOperator(BakeTestCase):

    def test_every_frame_equals_the_live_mesh_cylinder(self):
        obj, _rig = cylinder_scene(12)
        self.assertEqual(self.bake(obj, 1, 12), {'FINISHED'})
        self.assertEqual(sorted(os.listdir(self.out)), ["Cylinder.pc2", "Cylinder.pc2.json"])
        samples = self.assertFramesEqualLive(obj, os.path.join(self.out, "Cylinder.pc2"), 1, 12)
        # And it is the corrected shape, not plain skinning.
        bpy.context.scene.frame_set(6)
        self.assertGreater(helpers.max_distance(samples[5], helpers.uncorrected_positions(obj)), 1e-3)

    def test_every_frame_equals_the_live_mesh_giraffe(self):
        obj, _rig = giraffe_scene(8)
        self.assertEqual(self.bake(obj, 2, 8), {'FINISHED'})
        self.assertFramesEqualLive(obj, os.path.join(self.out, "Giraffe.pc2"), 2, 8)

    def test_mesh_cache_round_trip(self):
        obj, _rig = cylinder_scene(12)
        self.assertEqual(self.bake(obj, 3, 12), {'FINISHED'})
        path = os.path.join(self.out, "Cylinder.pc2")
        _header, samples = read_pc2(path)
        copy = helpers.link(bpy.data.objects.new("Replay", obj.data.copy()))
        cache = copy.modifiers.new("Mesh Cache", 'MESH_CACHE')
        cache.cache_format = 'PC2'
        cache.filepath = path
        cache.frame_start = 3  # scene frame 3 plays sample 0
        cache.interpolation = 'NONE'
        cache.forward_axis = 'POS_Y'
        cache.up_axis = 'POS_Z'
        scene = bpy.context.scene
        for index, frame in enumerate(range(3, 13)):
            scene.frame_set(frame)
            replayed = helpers.evaluated_positions(copy)
            self.assertEqual(replayed.tobytes(), samples[index].tobytes(), "frame %d" % frame)
            self.assertEqual(replayed.tobytes(), helpers.evaluated_positions(obj).tobytes(), "frame %d" % frame)

    def test_modifiers_after_are_not_baked(self):
        obj, _rig = cylinder_scene(6)
        subdivision = obj.modifiers.new("Subdivision", 'SUBSURF')
        subdivision.levels = 1
        self.assertEqual(self.bake(obj, 1, 6), {'FINISHED'})
        _header, samples = read_pc2(os.path.join(self.out, "Cylinder.pc2"))
        subdivision.show_viewport = False
        live = live_frames(obj, range(1, 7))
        for index, frame in enumerate(range(1, 7)):
            self.assertSmallerThan(helpers.max_distance(samples[index], live[frame]), 1e-6, "frame %d" % frame)

    def test_invoke_in_background_runs_to_the_end(self):
        obj, _rig = cylinder_scene(4)
        helpers.select_only(obj)
        result = bpy.ops.object.lvp_bake('INVOKE_DEFAULT', filepath=os.path.join(self.out, "one.pc2"))
        self.assertEqual(result, {'FINISHED'})
        header, _samples = read_pc2(os.path.join(self.out, "one.pc2"))
        self.assertEqual((header.start_frame, header.num_samples), (1.0, 4))  # the scene's range

    def test_errors(self):
        obj, _rig = cylinder_scene(4)
        with self.assertRaisesRegex(RuntimeError, "reversed"):
            self.bake(obj, 5, 2)
        plain = helpers.link(bpy.data.objects.new("Plain", helpers.cylinder_mesh("Plain")))
        with self.assertRaisesRegex(RuntimeError, "'Plain' has no Volume Preservation modifier"):
            self.bake(plain, 1, 4)
        blocker = os.path.join(self.out, "file")
        open(blocker, "w").close()
        helpers.select_only(obj)
        with self.assertRaisesRegex(RuntimeError, "cannot create the output directory"):
            bpy.ops.object.lvp_bake(filepath=os.path.join(blocker, "cache"), frame_start=1, frame_end=4)
        self.assertEqual(os.listdir(self.out), ["file"])

    def test_hidden_character_is_refused_with_a_reason(self):
        """A character the viewport does not correct (hidden: handlers.corrected_in) would bake as plain
        skinning: the bake refuses it and says how to fix it. One shown through a collection instance
        is corrected, so it bakes."""
        obj, _rig = cylinder_scene(4)
        capture = self.addon.bake.capture
        capture.check_evaluated([obj], bpy.context.evaluated_depsgraph_get())
        collection = bpy.data.collections.new("Character")
        bpy.context.scene.collection.children.link(collection)
        bpy.context.scene.collection.objects.unlink(obj)
        collection.objects.link(obj)
        layer_collection = bpy.context.view_layer.layer_collection.children[collection.name]
        for hide in (lambda: obj.hide_set(True), lambda: setattr(layer_collection, "hide_viewport", True)):
            obj.hide_set(False)
            layer_collection.hide_viewport = False
            hide()
            with self.assertRaisesRegex(capture.BakeError, "'Cylinder' is not shown in this view layer .*show it"):
                capture.check_evaluated([obj], bpy.context.evaluated_depsgraph_get())
        layer_collection.hide_viewport = False
        layer_collection.exclude = True
        instance = helpers.link(bpy.data.objects.new("Instance", None))
        instance.instance_type = 'COLLECTION'
        instance.instance_collection = collection
        capture.check_evaluated([obj], bpy.context.evaluated_depsgraph_get())

    def test_cancel_keeps_frames_and_the_next_bake_resumes(self):
        obj, _rig = cylinder_scene(12)
        path = os.path.join(self.out, "Cylinder.pc2")
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(self.out, "scene.blend"))  # a saved file resumes
        engine = self.addon.bake.engine
        bake = engine.Bake(bpy.context.scene, [obj], range(1, 13), self.out)
        self.assertEqual(len(bake.plan()), 12)
        for _frame in range(5):
            bake.step()
        bake.close()  # what Esc does
        self.assertFalse(os.path.exists(path))
        again = engine.Bake(bpy.context.scene, [obj], range(1, 13), self.out)
        self.assertEqual(again.plan(), list(range(6, 13)))
        self.assertEqual(self.bake(obj, 1, 12), {'FINISHED'})
        self.assertFramesEqualLive(obj, path, 1, 12)
        self.assertFalse(os.path.exists(path + ".parts"))


# ---- the command in a second Blender --------------------------------------------------------


def mount_namespace():
    """The command prefix that runs a command in a private mount namespace where it may mount a tmpfs, or
    None (not root, no unshare). Inside the 4.3 and 5.2 chroots "/" is not a mount point: its namespace is
    already private (blender_chroot.sh), so a copy with unchanged propagation is private too."""
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return None
    attempts = [["unshare", "-m", "--propagation", "private"]]
    with open("/proc/self/mountinfo") as file:
        if "shared:" not in file.read():
            attempts.append(["unshare", "-m", "--propagation", "unchanged"])
    for prefix in attempts:
        probe = subprocess.run(prefix + ["sh", "-c", 'mount -t tmpfs -o size=64k tmpfs "$0"',
                                         tempfile.mkdtemp(dir=helpers.test_tmp())],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if probe.returncode == 0:
            return prefix
    return None


class CommandTestCase(BakeTestCase):
    """Saves a scene and runs the bake command on it in a second Blender."""

    last_frame = 24

    def setUp(self):
        super().setUp()
        self.obj, self.rig = self.make_scene()
        self.blend = os.path.join(helpers.fresh_directory("scene"), "shot.blend")
        bpy.ops.wm.save_as_mainfile(filepath=self.blend, copy=True)

    def make_scene(self):
        return giraffe_scene(self.last_frame)

    def command(self, arguments, blend=None):
        """The bake command line: -c on 4.2+, the script on 3.4 (the add-on is enabled by --python first)."""
        blend = blend or self.blend
        enable = ["--python-exit-code", "1", "--python", helpers.enable_script_path()]
        if bpy.app.version >= (4, 2, 0):
            return helpers.blender_command() + enable + [blend, "-c", "lvp_bake"] + list(arguments)
        script = os.path.join(os.path.dirname(self.addon.__file__), "bake", "lvp_bake.py")
        return helpers.blender_command() + enable + [blend, "--python", script, "--"] + list(arguments)

    def environment(self):
        environment = dict(os.environ)
        environment["LVP_TEST_TMP"] = tempfile.mkdtemp(prefix="child-", dir=helpers.test_tmp())
        return environment

    def run_bake(self, arguments, wrapper=(), preexec_fn=None, blend=None, timeout=600):
        completed = subprocess.run(list(wrapper) + self.command(arguments, blend), stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True, timeout=timeout,
                                   env=self.environment(), preexec_fn=preexec_fn)
        return completed.returncode, completed.stdout

    def assertBakeOk(self, arguments, **options):
        status, output = self.run_bake(arguments, **options)
        self.assertEqual(status, 0, "the bake failed:\n%s" % output[-4000:])
        return output

    def assertBakeFails(self, arguments, message, **options):
        status, output = self.run_bake(arguments, **options)
        self.assertNotEqual(status, 0, "the bake should have failed:\n%s" % output[-4000:])
        self.assertIn(message, output)
        return output

    def assertJobsEqualOneJobAndLive(self, obj, first, last):
        """Bakes obj's frames first-last with `--jobs 1` into out/one and `--jobs 2` into out/two: the two PC2
        files are the same bytes, and their frames the live mesh's. Returns the two bakes' outputs."""
        frames = "%d-%d" % (first, last)
        one, two = os.path.join(self.out, "one"), os.path.join(self.out, "two")
        output_one = self.assertBakeOk(["--objects", obj.name, "--frames", frames, "--output", one])
        output_two = self.assertBakeOk(["--objects", obj.name, "--frames", frames, "--output", two, "--jobs", "2"])
        self.assertIn("job 2: frames ", output_two)
        name = obj.name + ".pc2"
        with open(os.path.join(one, name), "rb") as a, open(os.path.join(two, name), "rb") as b:
            self.assertTrue(a.read() == b.read(), "%s: --jobs 2 and --jobs 1 differ" % obj.name)
        self.assertFramesEqualLive(obj, os.path.join(two, name), first, last)
        return output_one, output_two

    def final_files(self, directory=None):
        directory = directory or self.out
        return sorted(name for name in os.listdir(directory) if name.endswith((".pc2", ".abc")))


class TestCommand(CommandTestCase):

    def test_jobs_2_equals_jobs_1_bit_for_bit_and_the_live_mesh(self):
        output_one, output = self.assertJobsEqualOneJobAndLive(self.obj, 1, 24)
        self.assertRegex(output_one, r"lvp_bake: 24/24 frames \(100%\), [0-9.]+ frames/s")
        two = os.path.join(self.out, "two")
        self.assertIn("job 2: frames 13-24", output)
        self.assertIn("wrote %s" % os.path.join(two, "Giraffe.pc2"), output)
        self.assertFalse(os.path.exists(os.path.join(two, "Giraffe.pc2.parts")))
        if not bpy.app.alembic.supported:
            self.assertIn("Alembic not written", output)

    def test_chunks_baked_out_of_order_then_merged(self):
        common = ["--objects", "Giraffe", "--output", self.out]
        self.assertBakeOk(common + ["--frames", "17-24", "--chunk"])
        output = self.assertBakeFails(common + ["--frames", "1-24", "--merge"], "frames 1-16 of Giraffe.pc2 are not "
                                                                               "baked yet")
        self.assertEqual(self.final_files(), [])
        self.assertBakeOk(common + ["--frames", "1-8", "--chunk"])
        self.assertBakeOk(common + ["--frames", "9-16", "--chunk"])
        self.assertBakeOk(common + ["--frames", "1-24", "--merge"])
        self.assertFramesEqualLive(self.obj, os.path.join(self.out, "Giraffe.pc2"), 1, 24)
        # Done is done: running the whole bake again bakes nothing.
        output = self.assertBakeOk(common + ["--frames", "1-24"])
        self.assertIn("24 already baked, 0 to bake", output)

    def test_errors_give_a_message_a_status_and_no_file(self):
        common = ["--output", self.out]
        self.assertBakeFails(common + ["--objects", "Nobody"], "there is no object named 'Nobody'")
        self.assertBakeFails(common + ["--objects", "GiraffeRig"], "'GiraffeRig' is not a mesh")
        self.assertBakeFails(common + ["--objects", "Giraffe", "--frames", "10-3"], "is reversed")
        self.assertBakeFails(common + ["--objects", "Giraffe", "--frames", ""], "the frame range is empty")
        self.assertEqual(os.listdir(self.out), [])

    def test_object_without_the_modifier(self):
        bpy.data.objects.new("Plain", helpers.cylinder_mesh("Plain"))
        helpers.link(bpy.data.objects["Plain"])
        bpy.ops.wm.save_as_mainfile(filepath=self.blend, copy=True)
        self.assertBakeFails(["--objects", "Giraffe", "Plain", "--output", self.out],
                             "'Plain' has no Volume Preservation modifier")
        self.assertEqual(os.listdir(self.out), [])

    def test_unwritable_directory(self):
        target = os.path.join(self.out, "readonly")
        os.makedirs(target)
        prefix = mount_namespace()
        if prefix:
            wrapper = prefix + ["sh", "-c",
                       'mount -t tmpfs -o ro,size=1m tmpfs "$0" && shift && exec "$@"', target, "--"]
            self.assertBakeFails(["--objects", "Giraffe", "--output", target], "Read-only file system",
                                 wrapper=wrapper)
        else:  # without root: a file where the directory should be
            open(os.path.join(target, "cache"), "w").close()
            self.assertBakeFails(["--objects", "Giraffe", "--output", os.path.join(target, "cache", "x")],
                                 "cannot create the output directory")
        self.assertEqual(self.final_files(target), [])

    def test_disk_full_mid_bake(self):
        target = os.path.join(self.out, "small")
        os.makedirs(target)
        listing = os.path.join(self.out, "listing")
        frame_size = 12 * len(self.obj.data.vertices)
        prefix = mount_namespace()
        if prefix:
            print("\n    a %d KiB tmpfs fills mid-bake" % ((10 * frame_size) // 1024))
            # Room for about 10 of the 24 frames: the disk fills mid-bake.
            size_k = (10 * frame_size) // 1024
            wrapper = prefix + ["sh", "-c",
                       'mount -t tmpfs -o size=%dk tmpfs "$0" && shift && "$@"; status=$?; '
                       'ls -R "$0" > %s; exit $status' % (size_k, listing), target, "--"]
            output = self.assertBakeFails(["--objects", "Giraffe", "--output", target], "the disk is full",
                                          wrapper=wrapper)
            with open(listing) as file:
                files = file.read()
            self.assertIn(".journal", files, "the finished frames should be kept")
            self.assertNotIn("Giraffe.pc2\n", files.replace("Giraffe.pc2.parts", ""))
        else:
            print("\n    no mount namespace here: RLIMIT_FSIZE stands in for a full disk")
            limit = 10 * frame_size

            def limit_file_size():
                signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
                import resource
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

            output = self.assertBakeFails(["--objects", "Giraffe", "--output", target], "file size limit",
                                          preexec_fn=limit_file_size)
            self.assertEqual(self.final_files(target), [])
        self.assertIn("run the same command again", output)

    def test_resume_after_a_killed_bake(self):
        last = 400
        common = ["--objects", "Giraffe", "--frames", "1-%d" % last]
        parts = os.path.join(self.out, "Giraffe.pc2.parts")
        process = subprocess.Popen(self.command(common + ["--output", self.out]), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL, env=self.environment())
        try:
            deadline = time.monotonic() + 300
            journaled = 0
            while journaled < 20 and time.monotonic() < deadline and process.poll() is None:
                time.sleep(0.05)
                journaled = self.journaled_frames(parts)
            self.assertIsNone(process.poll(), "the bake ended before it could be killed")
            process.kill()
        finally:
            process.wait()
        self.assertFalse(os.path.exists(os.path.join(self.out, "Giraffe.pc2")))
        kept = self.journaled_frames(parts)
        self.assertGreaterEqual(kept, 20)
        self.assertLess(kept, last)
        output = self.assertBakeOk(common + ["--output", self.out])
        already = int(output.split(" already baked")[0].rsplit(" ", 1)[-1])
        self.assertGreaterEqual(already, kept)
        self.assertIn("%d to bake" % (last - already), output)
        # Identical to a bake that was never interrupted.
        fresh = os.path.join(self.out, "fresh")
        self.assertBakeOk(common + ["--output", fresh, "--frames", "1-%d" % last])
        with open(os.path.join(self.out, "Giraffe.pc2"), "rb") as a, \
                open(os.path.join(fresh, "Giraffe.pc2"), "rb") as b:
            self.assertTrue(a.read() == b.read(), "the resumed bake differs from an uninterrupted one")

    @staticmethod
    def journaled_frames(parts):
        count = 0
        if os.path.isdir(parts):
            for name in os.listdir(parts):
                if name.endswith(".journal"):
                    with open(os.path.join(parts, name), "rb") as file:
                        count += max(0, file.read().count(b"\n") - 1)
        return count


if __name__ == "__main__":
    unittest.main()


# ---- docs/baking.md, command by command ---------------------------------------------------------

DOC = os.path.join(helpers.REPO, "docs", "baking.md")
DOC_OUTPUT = "/shared/cache/shot"
DOC_SCRIPT_FOLDER = "~/.config/blender/3.4/scripts/addons/local_volume_preservation"


def doc_commands():
    """The shell commands of docs/baking.md's ```sh blocks, in order."""
    commands = []
    inside = False
    with open(DOC) as file:
        for line in file:
            if line.startswith("```"):
                inside = line.strip() == "```sh"
                continue
            if inside and line.strip():
                commands.append(line.strip())
    return commands


SETUP_PREFERENCES = """
import os, sys, shutil, bpy, addon_utils
if bpy.app.version >= (4, 2, 0):
    result = bpy.ops.extensions.package_install_files(filepath=%(zip)r, repo="user_default", enable_on_install=True)
    assert 'FINISHED' in result, result
else:
    target = os.path.join(bpy.utils.user_resource('SCRIPTS', path="addons"), "local_volume_preservation")
    shutil.copytree(%(folder)r, target)
    addon_utils.enable("local_volume_preservation", default_set=True)
bpy.ops.wm.save_userpref()
"""


class TestDocs(CommandTestCase):
    """Runs every command of docs/baking.md as written, in a Blender whose user preferences have the add-on
    enabled (like a user's or a farm worker's), with only the file names replaced by the test's."""

    last_frame = 48

    def setUp(self):
        super().setUp()
        user = helpers.fresh_directory("user")
        self.user_environment = dict(os.environ)
        for name, sub in (("BLENDER_USER_RESOURCES", ""), ("BLENDER_USER_CONFIG", "config"),
                          ("BLENDER_USER_SCRIPTS", "scripts"), ("BLENDER_USER_DATAFILES", "datafiles"),
                          ("BLENDER_USER_EXTENSIONS", "extensions")):
            self.user_environment[name] = os.path.join(user, sub) if sub else user
        script = os.path.join(user, "setup.py")
        with open(script, "w") as file:
            file.write(SETUP_PREFERENCES % {"zip": helpers.extension_zip(), "folder": helpers.addon_dir()})
        completed = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "-noaudio", "--python-exit-code",
                                    "1", "--python", script], env=self.user_environment, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True, timeout=300)
        self.assertEqual(completed.returncode, 0, completed.stdout[-3000:])

    def script_folder(self):
        probe = subprocess.run([bpy.app.binary_path, "-b", "-noaudio", "--python-expr",
                                "import addon_utils, os\n"
                                "for m in addon_utils.modules():\n"
                                "    if m.__name__.endswith('local_volume_preservation'):\n"
                                "        print('FOLDER=' + os.path.dirname(m.__file__))\n"],
                               env=self.user_environment, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               universal_newlines=True, timeout=300)
        folders = [line[len("FOLDER="):] for line in probe.stdout.splitlines() if line.startswith("FOLDER=")]
        self.assertTrue(folders, probe.stdout[-2000:])
        return folders[0]

    def run_doc_command(self, command, output):
        import shlex
        text = command.replace(DOC_SCRIPT_FOLDER, self.script_folder()).replace(DOC_OUTPUT, output)
        arguments = shlex.split(text)
        self.assertEqual(arguments[0], "blender")
        arguments = [bpy.app.binary_path] + [self.blend if word == "shot.blend" else word for word in arguments[1:]]
        completed = subprocess.run(arguments, env=self.user_environment, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, universal_newlines=True, timeout=600)
        self.assertEqual(completed.returncode, 0, "%s\n%s" % (command, completed.stdout[-4000:]))
        return completed.stdout

    def test_every_command(self):
        commands = doc_commands()
        self.assertGreaterEqual(len(commands), 5)
        has_command = bpy.app.version >= (4, 2, 0)
        ran = 0
        output = None
        previous_farm = False
        for command in commands:
            if " -c " in command and not has_command:
                continue  # the -c form needs Blender 4.2+ (Blender 4.3 runs it)
            farm = "--chunk" in command or "--merge" in command
            if not (farm and previous_farm):  # the farm's chunks and merge share one output directory
                output = helpers.fresh_directory("doc")
            previous_farm = farm and "--merge" not in command
            log = self.run_doc_command(command, output)
            ran += 1
            if "--chunk" not in command:
                self.assertIn("wrote %s" % os.path.join(output, "Giraffe.pc2"), log)
                self.assertFramesEqualLive(self.obj, os.path.join(output, "Giraffe.pc2"), 1, 48)
        self.assertEqual(ran, len(commands) if has_command else 1)
        if has_command:
            help_text = self.run_doc_command("blender -b -c lvp_bake --help", "")
            self.assertIn("--jobs N", help_text)
