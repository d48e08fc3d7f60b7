# SPDX-License-Identifier: GPL-3.0-or-later
"""The demo's pictures are checked, not only written.

- The paper's cylinder bent to 90 degrees, rendered before (Armature only) and after (with Volume
  Preservation) by Cycles at low resolution with a transparent film: the two silhouettes must differ
  around the joint, where the volume is put back, and match pixel for pixel far from it, where the skin
  follows one bone rigidly. The scene and the renderer are the demo's own (demo/demo_scenes.py,
  demo/demo_render.py).
- The PNGs that README.md shows (docs/images/) and, when `./build.sh demo` has run, the ones in
  demo/out/, must be valid PNG files (signature, chunk CRCs, image data of the size the header says)
  and real pictures, not empty frames.
"""

import os
import struct
import sys
import unittest
import zlib
from array import array

import bpy
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

import lvp_helpers as helpers

DEMO = os.path.join(helpers.REPO, "demo")
if DEMO not in sys.path:
    sys.path.insert(0, DEMO)

import demo_render  # noqa: E402
import demo_scenes  # noqa: E402

DEMO_IMAGES = ("cylinder_90.png", "cylinder_maps.png", "giraffe.png", "giraffe_maps.png", "finger_fold.png",
               "rigify_leg.png", "rigify_elbow.png", "auto_weights_back.png", "auto_weights_front.png",
               "volume_error_plot.png")
README_IMAGES = os.path.join(helpers.REPO, "docs", "images")
WIDTH, HEIGHT = 200, 150


def alpha_mask(path):
    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    pixels = array('f', bytes(16 * width * height))
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return width, height, bytearray(1 if pixels[4 * index + 3] > 0.5 else 0 for index in range(width * height))


def pixel_box(scene, camera, corners, margin=0):
    """(x0, y0, x1, y1) pixel box (row 0 at the bottom, as Blender stores images) around world points."""
    xs, ys = [], []
    for corner in corners:
        projected = world_to_camera_view(scene, camera, Vector(corner))
        xs.append(projected.x * scene.render.resolution_x)
        ys.append(projected.y * scene.render.resolution_y)
    return (int(min(xs)) - margin, int(min(ys)) - margin, int(max(xs)) + 1 + margin, int(max(ys)) + 1 + margin)


def box_corners(y_range, z_range, x_range=(-0.6, 0.6)):
    return [(x, y, z) for x in x_range for y in y_range for z in z_range]


def count_in_box(mask, width, box, height):
    x0, y0, x1, y1 = box
    return sum(mask[y * width + x]
               for y in range(max(0, y0), min(height, y1)) for x in range(max(0, x0), min(width, x1)))


class TestCylinderSilhouettes(helpers.AddonTestCase):
    """Before and after on the paper's cylinder bent to 90 degrees (towards -Y, seen from +X)."""

    def test_silhouettes_differ_at_the_joint_and_match_far_from_it(self):
        scene = bpy.context.scene
        demo_render.setup_cycles(scene, WIDTH, HEIGHT, samples=1)
        scene.cycles.max_bounces = 0
        if hasattr(scene.cycles, "use_adaptive_sampling"):
            scene.cycles.use_adaptive_sampling = False
        plain, corrected = demo_scenes.cylinder_pair(90.0)
        camera = demo_render.add_camera((8.0, -1.0, 1.35), (0.0, -1.0, 1.35), (0.0, 0.0, 1.0), 4.4)
        directory = helpers.fresh_directory("silhouettes")
        before = demo_render.render_still(os.path.join(directory, "before.png"), [plain], [corrected])
        after = demo_render.render_still(os.path.join(directory, "after.png"), [corrected], [plain])
        width, height, plain_mask = alpha_mask(before)
        _width, _height, corrected_mask = alpha_mask(after)
        self.assertEqual((width, height), (WIDTH, HEIGHT))
        difference = bytearray(a ^ b for a, b in zip(plain_mask, corrected_mask))
        gained = bytearray(b & (1 - a) for a, b in zip(plain_mask, corrected_mask))

        # The cylinder covers a good part of the frame in both renders.
        for name, mask in (("before", plain_mask), ("after", corrected_mask)):
            self.assertGreater(sum(mask), 0.1 * width * height, "the cylinder is missing from the %s render" % name)

        # Around the joint (the weight band is 2.6 long, centred on the joint at z = 2, and the bulge tapers
        # over one more flesh thickness past it, to the rings at z = 0.53 and 3.47, whose faces reach z = 0.27
        # and, bent, y = -1.73): the silhouettes differ, and the corrected one is larger (the lost volume is
        # put back as a bulge).
        joint = pixel_box(scene, camera, box_corners((-1.75, 0.9), (0.2, 2.9)))
        changed = count_in_box(difference, width, joint, height)
        print("\n    cylinder at 90 degrees, %d x %d: %d pixels differ around the joint (%d gained), %d elsewhere"
              % (width, height, changed, count_in_box(gained, width, joint, height), sum(difference) - changed))
        self.assertGreater(changed, 15, "before and after silhouettes should differ around the joint")
        self.assertGreater(count_in_box(gained, width, joint, height), 0.6 * changed,
                           "the corrected silhouette should mostly grow at the joint")

        # Far from the joint both ends follow one bone rigidly: identical pixels. The weights' band ends at
        # z = 0.7 (and 3.3) at rest, and the Bulge Width of 1 lets the bulge taper over one more flesh
        # thickness, the radius of 0.5 (with 6 passes of smoothing the ring at z = 0.53 moves 0.012, the ring
        # at 0.27 nothing): below z = 0.2, and past y = -1.8 after the 90 degree bend, nothing moves.
        for name, y_range, z_range in (("lower end", (-0.7, 0.7), (-0.2, 0.2)),
                                       ("upper end", (-2.2, -1.8), (1.3, 2.7))):
            box = pixel_box(scene, camera, box_corners(y_range, z_range))
            self.assertGreater(count_in_box(plain_mask, width, box, height), 50, "the %s is not in view" % name)
            self.assertEqual(count_in_box(difference, width, box, height), 0,
                             "the %s moved: it follows one bone rigidly and must not" % name)

        # Nothing differs outside the joint's box at all.
        outside = sum(difference) - changed
        self.assertEqual(outside, 0, "%d pixels differ away from the joint" % outside)


# ---- PNG files -------------------------------------------------------------------------------------


def read_png(path):
    """(width, height, channels): checks a PNG file in pure Python: the signature, every chunk's CRC, an
    IHDR and an IEND, and that the image data inflates to exactly the size the header announces."""
    with open(path, "rb") as file:
        data = file.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("%s: not a PNG (bad signature)" % path)
    position = 8
    header = None
    compressed = []
    ended = False
    while position + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[position:position + 8])
        body = data[position + 8:position + 8 + length]
        crc, = struct.unpack(">I", data[position + 8 + length:position + 12 + length])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError("%s: chunk %r has a bad CRC" % (path, kind))
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            compressed.append(body)
        elif kind == b"IEND":
            ended = True
            break
        position += 12 + length
    if header is None or not ended:
        raise ValueError("%s: no IHDR or no IEND chunk (truncated?)" % path)
    width, height, depth, color_type, _compression, _filter, interlace = header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(color_type)
    if depth != 8 or channels is None or interlace != 0:
        raise ValueError("%s: expected an 8-bit, non-interlaced grey/RGB/RGBA PNG, got %r" % (path, header))
    expected = height * (width * channels + 1)
    raw = zlib.decompress(b"".join(compressed))
    if len(raw) != expected:
        raise ValueError("%s: image data is %d bytes, the header says %d" % (path, len(raw), expected))
    return width, height, channels


def picture_statistics(path):
    """(width, height, distinct grey levels over a sample, fraction of the sample that differs from the
    top-left pixel's colour), read by Blender."""
    image = bpy.data.images.load(path, check_existing=False)
    try:
        width, height = image.size
        pixels = array('f', bytes(16 * width * height))
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    corner = pixels[0:3]
    levels = set()
    differing = samples = 0
    for index in range(0, width * height, max(1, (width * height) // 20000)):
        pixel = pixels[4 * index:4 * index + 3]
        levels.add(int(255 * sum(pixel) / 3) // 4)
        if sum(abs(a - b) for a, b in zip(pixel, corner)) > 0.06:
            differing += 1
        samples += 1
    return width, height, len(levels), differing / samples


class TestDemoImages(unittest.TestCase):
    """Valid PNGs that show something: the README's images, and demo/out/ after ./build.sh demo."""

    def assertPicture(self, path, min_width=300):
        self.assertTrue(os.path.isfile(path), "%s is missing" % path)
        width, height, _channels = read_png(path)
        self.assertGreaterEqual(width, min_width, "%s is too small" % path)
        self.assertGreaterEqual(height, 150, "%s is too small" % path)
        read_width, read_height, levels, foreground = picture_statistics(path)
        self.assertEqual((read_width, read_height), (width, height), "Blender reads %s with another size" % path)
        self.assertGreater(levels, 10, "%s has %d grey levels: an empty frame?" % (path, levels))
        self.assertGreater(foreground, 0.03, "%s is %.1f %% background: an empty frame?"
                           % (path, 100 * (1 - foreground)))

    def test_readme_images(self):
        names = sorted(name for name in os.listdir(README_IMAGES) if name.endswith(".png"))
        self.assertTrue(names, "docs/images/ has no PNG")
        for name in names:
            with self.subTest(image=name):
                self.assertPicture(os.path.join(README_IMAGES, name))

    def test_demo_output(self):
        out = os.path.join(DEMO, "out")
        if not os.path.isdir(out):
            self.skipTest("demo/out/ does not exist: run ./build.sh demo first")
        for name in DEMO_IMAGES:
            with self.subTest(image=name):
                self.assertPicture(os.path.join(out, name))

    def test_png_reader_rejects_broken_files(self):
        directory = helpers.fresh_directory("png")
        source = os.path.join(README_IMAGES, "cylinder_90.png")
        with open(source, "rb") as file:
            data = file.read()
        for name, broken in (("truncated", data[:len(data) // 2]), ("signature", b"GIF89a" + data[6:]),
                             ("crc", data[:40] + bytes([data[40] ^ 0xFF]) + data[41:])):
            path = os.path.join(directory, name + ".png")
            with open(path, "wb") as file:
                file.write(broken)
            with self.subTest(broken=name):
                with self.assertRaises((ValueError, struct.error, zlib.error)):
                    read_png(path)


if __name__ == "__main__":
    unittest.main()
