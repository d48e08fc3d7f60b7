# SPDX-License-Identifier: GPL-3.0-or-later
"""README.md's install and bake commands, run as README writes them (every command in README is
exercised). The commands are read from README.md itself (tests/python/readme_commands.py), with
its placeholders replaced: `blender` by this Blender, `shot.blend` by a saved animated cylinder whose
mesh is named Character, `/path/to/cache` by a fresh directory, and `~` by a fresh home directory
(Blender's user directories are not redirected for these children, so README's paths are used).

- Blender < 4.2: the add-on folder copied with README's `cp` command is found and enabled by a fresh
  Blender; the bake through `--python dist/.../bake/lvp_bake.py` writes Character.pc2.
- Blender 4.2+: README's `blender --command extension install-file` installs and enables the zip, and
  with it installed, `-c lvp_bake` bakes with 2 jobs, and as farm chunks plus a merge; the
  `--python` form works too (in a home without the extension).
"""

import os
import shlex
import struct
import subprocess
import tempfile
import sys
import unittest

import bpy

import lvp_helpers as helpers

sys.path.insert(0, os.path.join(helpers.REPO, "tests", "python"))
import readme_commands  # noqa: E402

FRAMES = 250
PC2_HEADER = struct.Struct("<12siiffi")


def child_environment(home):
    environment = {name: value for name, value in os.environ.items() if not name.startswith("BLENDER_USER_")}
    environment["HOME"] = home
    environment.pop("XDG_CONFIG_HOME", None)
    return environment


def concrete(command, blend, cache):
    """README's command with its placeholders replaced (README writes `~` only as the home directory)."""
    words = command.split(" ")
    if words[0] == "blender":
        words[0] = shlex.quote(bpy.app.binary_path)
    replaced = []
    for word in words:
        if word == "shot.blend":
            word = shlex.quote(blend)
        elif word == "/path/to/cache":
            word = shlex.quote(cache)
        replaced.append(word)
    return " ".join(replaced)


class TestReadmeCommands(helpers.AddonTestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.version = tuple(bpy.app.version[:2])
        cls.commands = readme_commands.commands_run_in_blender(readme_commands.read_readme(), cls.version)

    def setUp(self):
        super().setUp()
        self.directory = helpers.fresh_directory("readme")
        self.blend = self.save_shot()

    def save_shot(self):
        """shot.blend: the paper's cylinder, its mesh named Character, bending over FRAMES frames."""
        obj, rig = helpers.make_cylinder_character("Character")
        helpers.keyframe_bend(rig, {1: 0.0, FRAMES: 90.0})
        self.assertEqual(helpers.add_volume_preservation(obj), {'FINISHED'})
        scene = bpy.context.scene
        scene.frame_start, scene.frame_end = 1, FRAMES
        self.vertex_count = len(obj.data.vertices)
        path = os.path.join(self.directory, "shot.blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
        return path

    def fresh(self, name):
        return tempfile.mkdtemp(prefix=name + "-", dir=self.directory)

    def commands_like(self, *words):
        found = [command for command in self.commands if all(word in command for word in words)]
        if not found:
            self.skipTest("README has no command with %s for Blender %d.%d" % (" ".join(words), *self.version))
        return found

    def run_readme(self, command, home, cache=None, timeout=600):
        line = concrete(command, self.blend, cache or self.fresh("cache"))
        result = subprocess.run(["bash", "-c", line], cwd=helpers.REPO, env=child_environment(home),
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, universal_newlines=True,
                                timeout=timeout)
        self.assertEqual(result.returncode, 0, "README's command failed (status %d):\n  %s\nrun as\n  %s\n%s"
                         % (result.returncode, command, line, result.stdout[-4000:]))
        return result.stdout

    def run_blender_check(self, home, expression):
        """A fresh Blender with the user set-up of `home` (no --factory-startup): expression must hold."""
        script = ("import sys, bpy, addon_utils\n"
                  "ok = bool(%s)\n"
                  "print('README CHECK', ok)\n"
                  "sys.stdout.flush()\n" % expression)
        result = subprocess.run([bpy.app.binary_path, "-b", "-noaudio", "--python-expr", script],
                                cwd=helpers.REPO, env=child_environment(home), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, universal_newlines=True, timeout=300)
        self.assertIn("README CHECK True", result.stdout, result.stdout[-4000:])

    def assertPointCache(self, directory, frames=FRAMES):
        path = os.path.join(directory, "Character.pc2")
        self.assertTrue(os.path.isfile(path), "no Character.pc2 in %s: %s" % (directory, os.listdir(directory)))
        with open(path, "rb") as file:
            signature, version, points, start, rate, samples = PC2_HEADER.unpack(file.read(PC2_HEADER.size))
        self.assertEqual(signature, b"POINTCACHE2\0")
        self.assertEqual((version, points, start, rate, samples), (1, self.vertex_count, 1.0, 1.0, frames))
        self.assertEqual(os.path.getsize(path), PC2_HEADER.size + 12 * points * frames)

    # ---- installing ------------------------------------------------------------------------------------

    def test_install_folder(self):
        if self.version >= (4, 2):
            self.skipTest("the add-on folder is how Blender < 4.2 installs it")
        commands = self.commands_like("~/.config/blender/")
        self.assertEqual(len(commands), 2, commands)  # mkdir -p, cp -r
        home = self.fresh("home")
        for command in commands:
            self.run_readme(command, home)
        self.assertTrue(os.path.isfile(os.path.join(home, ".config", "blender", "%d.%d" % self.version, "scripts",
                                                    "addons", "local_volume_preservation", "_lvp.abi3.so")))
        # Edit > Preferences > Add-ons, tick the box: what the tick does.
        self.run_blender_check(home, "addon_utils.enable('local_volume_preservation', default_set=True) is not None "
                                     "and hasattr(bpy.types.Object, 'lvp') and hasattr(bpy.ops.object, 'lvp_add')")

    def test_install_extension_then_bake(self):
        if self.version < (4, 2):
            self.skipTest("extensions need Blender 4.2+")
        install, = self.commands_like("extension install-file")
        home = self.fresh("home")
        self.run_readme(install, home)
        self.run_blender_check(home, "hasattr(bpy.types.Object, 'lvp')")
        # With it installed: the bake with 2 jobs, then the farm's chunks and merge.
        bake, = self.commands_like("-c lvp_bake", "--jobs 2")
        cache = self.fresh("cache-jobs")
        self.run_readme(bake, home, cache)
        self.assertPointCache(cache)
        farm = self.commands_like("-c lvp_bake", "--chunk") + self.commands_like("-c lvp_bake", "--merge")
        self.assertEqual(len(farm), 3)
        cache = self.fresh("cache-farm")
        for command in farm:
            output = self.run_readme(command, home, cache)
        self.assertIn("wrote", output)
        self.assertPointCache(cache)

    # ---- baking ----------------------------------------------------------------------------------------

    def test_bake_with_the_script(self):
        command, = self.commands_like("--python dist/local_volume_preservation/bake/lvp_bake.py")
        cache = self.fresh("cache-script")
        output = self.run_readme(command, self.fresh("home"), cache)
        self.assertIn("250/250 frames", output)
        self.assertPointCache(cache)


if __name__ == "__main__":
    unittest.main()
