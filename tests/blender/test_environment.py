"""Smoke test of the test environment itself, on every Blender that run.sh starts.

It checks what the other suites take for granted: the Blender version is the one asked for,
bpy works headless (scene evaluation, text with the built-in font, a small Cycles CPU render
with denoising off), the repository and /tmp are visible at the same paths (also inside the
Blender 4.3 and 5.2 chroots), and the compiled module `_lvp` from the built add-on folder imports in
this Blender's Python and reports its version.
"""

import array
import contextlib
import importlib.util
import os
import sys
import unittest

import bpy

REPO = os.environ.get("LVP_REPO") or os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ADDON_DIR = os.environ.get("LVP_ADDON_DIR") or os.path.join(REPO, "dist", "local_volume_preservation")
EXPECTED = os.environ.get("LVP_EXPECT_BLENDER_VERSION", "")

# The Python that each supported Blender embeds (Debian's builds link the system Python).
EXPECTED_PYTHON = {"3.4": (3, 11), "4.3": (3, 13), "5.2": (3, 14)}


def load_lvp():
    """Imports _lvp from the add-on folder by file name (not from wherever sys.path points)."""
    path = os.path.join(ADDON_DIR, "_lvp.abi3.so")
    if not os.path.isfile(path):
        raise unittest.SkipTest(
            "no compiled module at %s: run ./build.sh package (tests/blender/run.sh does it "
            "unless --no-build; the core may not compile yet)" % path)
    if "_lvp" in sys.modules and os.path.abspath(getattr(sys.modules["_lvp"], "__file__", "")) == path:
        return sys.modules["_lvp"]
    spec = importlib.util.spec_from_file_location("_lvp", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@contextlib.contextmanager
def quiet_stdout():
    """Sends what C code prints to stdout to /dev/null (Python's sys.stdout is left alone)."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


class TestBlender(unittest.TestCase):
    def test_version(self):
        print("\n    Blender %s at %s, Python %s" % (bpy.app.version_string, bpy.app.binary_path,
                                                   sys.version.split()[0]), end=" ")
        self.assertGreaterEqual(tuple(bpy.app.version), (3, 4, 0))
        self.assertTrue(bpy.app.background, "Blender is not running in background mode (-b)")
        if EXPECTED:
            self.assertEqual("%d.%d" % tuple(bpy.app.version[:2]), EXPECTED,
                             "run.sh asked for Blender %s but started %s (%s)"
                             % (EXPECTED, bpy.app.version_string, bpy.app.binary_path))

    def test_python(self):
        # _lvp is built against the stable ABI of Python 3.11 (Py_LIMITED_API 0x030B0000).
        self.assertGreaterEqual(sys.version_info[:2], (3, 11),
                                "_lvp.abi3.so needs Python 3.11 or newer, this Blender has %s" % sys.version)
        if EXPECTED in EXPECTED_PYTHON:
            self.assertEqual(sys.version_info[:2], EXPECTED_PYTHON[EXPECTED])

    def test_same_paths(self):
        # Tests pass absolute paths unchanged, also into the chroots of Blender 4.3 and 5.2.
        self.assertTrue(os.path.isfile(os.path.join(REPO, "build.sh")), REPO)
        self.assertTrue(os.path.isfile(os.path.abspath(__file__)))
        tmp = os.environ.get("LVP_TEST_TMP")
        self.assertTrue(tmp and tmp.startswith("/tmp/") and os.path.isdir(tmp), tmp)
        probe = os.path.join(tmp, "probe")
        with open(probe, "w") as f:
            f.write("ok")
        os.remove(probe)


class TestBpy(unittest.TestCase):
    def setUp(self):
        bpy.ops.wm.read_factory_settings(use_empty=True)

    def test_evaluated_mesh(self):
        mesh = bpy.data.meshes.new("lvp_env_cube")
        verts = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
        mesh.from_pydata(verts, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6),
                                     (0, 2, 6, 4), (1, 5, 7, 3)])
        obj = bpy.data.objects.new("lvp_env_cube", mesh)
        bpy.context.scene.collection.objects.link(obj)
        obj.modifiers.new("subdiv", "SUBSURF").levels = 1
        bpy.context.scene.frame_set(2)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = obj.evaluated_get(depsgraph)
        mesh_eval = evaluated.to_mesh()
        try:
            self.assertEqual(len(mesh_eval.vertices), 26)
            # The add-on moves data through flat buffers without numpy.
            coords = array.array("f", [0.0]) * (3 * len(mesh_eval.vertices))
            mesh_eval.vertices.foreach_get("co", coords)
            self.assertLess(max(abs(c) for c in coords), 1.0 + 1e-6)
        finally:
            evaluated.to_mesh_clear()

    def test_text_with_builtin_font(self):
        curve = bpy.data.curves.new("lvp_env_text", "FONT")
        curve.body = "LVP"
        obj = bpy.data.objects.new("lvp_env_text", curve)
        bpy.context.scene.collection.objects.link(obj)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = obj.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        try:
            self.assertGreater(len(mesh.vertices), 0, "the text produced no geometry (fonts?)")
        finally:
            evaluated.to_mesh_clear()

    def test_cycles_cpu_render(self):
        scene = bpy.context.scene
        bpy.ops.mesh.primitive_uv_sphere_add(radius=1.0)
        camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
        camera.location = (0.0, -6.0, 0.0)
        camera.rotation_euler = (1.5708, 0.0, 0.0)
        scene.collection.objects.link(camera)
        scene.camera = camera
        light = bpy.data.objects.new("light", bpy.data.lights.new("light", "SUN"))
        light.rotation_euler = (0.8, 0.2, 0.0)
        scene.collection.objects.link(light)
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = 2
        scene.cycles.use_denoising = False
        scene.render.resolution_x, scene.render.resolution_y = 32, 24
        scene.render.resolution_percentage = 100
        scene.render.image_settings.file_format = "PNG"
        path = os.path.join(os.environ.get("LVP_TEST_TMP", "/tmp"), "lvp_env_render.png")
        scene.render.filepath = path
        with quiet_stdout():  # Cycles prints a progress line per step
            bpy.ops.render.render(write_still=True)
        self.assertTrue(os.path.isfile(path) and os.path.getsize(path) > 0, path)
        image = bpy.data.images.load(path)
        try:
            pixels = list(image.pixels)
        finally:
            bpy.data.images.remove(image)
        reds = pixels[0::4]
        self.assertGreater(max(reds) - min(reds), 0.05, "the render is a flat image")


class TestModule(unittest.TestCase):
    def test_lvp_imports(self):
        lvp = load_lvp()
        self.assertEqual(os.path.dirname(os.path.abspath(lvp.__file__)), os.path.abspath(ADDON_DIR))
        version = getattr(lvp, "version", None)
        self.assertIsInstance(version, str, "_lvp.version should be a string")
        self.assertTrue(version)
        print("\n    _lvp %s from %s" % (version, lvp.__file__), end=" ")

    def test_lvp_computes(self):
        lvp = load_lvp()
        if not hasattr(lvp, "mesh_volume"):
            self.skipTest("_lvp has no mesh_volume yet")
        # The unit cube, triangles wound counter-clockwise seen from outside.
        positions = array.array("f", [c for x in (0, 1) for y in (0, 1) for z in (0, 1) for c in (x, y, z)])
        quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        triangles = array.array("i", [i for a, b, c, d in quads for i in (a, b, c, a, c, d)])
        volume = lvp.mesh_volume(positions, triangles)
        self.assertAlmostEqual(abs(volume), 1.0, places=5)


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0]])
