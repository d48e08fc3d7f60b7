# SPDX-License-Identifier: GPL-3.0-or-later
"""The demo: builds the default scenes by code, renders plain skinning next to Volume Preservation,
the segmentation and the correction map as colours, a plot of the volume error over a bend, and
prints the volume-error table. Run by demo/run.sh (`./build.sh demo`):

    blender -b --factory-startup -noaudio --python-exit-code 1 --python demo/demo.py -- [--out DIR] [--quick]

--quick renders at a quarter of the pixels with fewer samples (for a fast check). The add-on is taken
from dist/local_volume_preservation (LVP_ADDON_DIR), built by ./build.sh.
"""

import argparse
import os
import sys
import time

import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(1, os.path.join(REPO, "tests", "blender"))

import lvp_helpers as helpers  # noqa: E402
import demo_plot as plot  # noqa: E402
import demo_render as render  # noqa: E402
import demo_scenes as scenes  # noqa: E402

SWEEP_ANGLES = list(range(0, 121, 5))
# The paper's Table 2 for the cylinder (relative volume error, volume lost): before and after its one pass.
PAPER_TABLE2 = ((10, 0.2, 0.05), (50, 4.0, 1.5), (90, 11.0, 4.9))

COLORS = {
    "plain": (0.85, 0.20, 0.12, 1.0),
    "preserve_volume": (0.15, 0.35, 0.85, 1.0),
    "corrected": (0.10, 0.60, 0.20, 1.0),
}
PAPER_COLOR = (0.45, 0.45, 0.45, 1.0)


def percent(value, digits):
    """A signed percentage with `digits` decimals, without a minus sign on a rounded zero."""
    text = "%+.*f %%" % (digits, 100 * value)
    return text.replace("-", "+") if float(text[:-2]) == 0.0 else text


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="demo.py")
    parser.add_argument("--out", default=os.path.join(HERE, "out"))
    parser.add_argument("--quick", action="store_true", help="small, noisy renders for a fast check")
    return parser.parse_args(argv)


class Demo:
    def __init__(self, out, quick):
        self.out = out
        self.scale = 0.5 if quick else 1.0
        self.samples = 8 if quick else 64
        self.images = []
        self.tables = []  # (title, Markdown lines)
        self.rows = []  # (scene, plain, preserve volume, corrected) signed changes, for the summary table
        os.makedirs(out, exist_ok=True)

    def size(self, pixels):
        return max(32, int(pixels * self.scale))

    def path(self, name):
        return os.path.join(self.out, name)

    def new_scene(self, width, height):
        helpers.reset_scene()
        scene = bpy.context.scene
        render.setup_cycles(scene, self.size(width), self.size(height), self.samples)
        render.add_sun()
        return scene

    def captions(self, camera, lines):
        """Caption objects for one panel: a title line, then smaller lines."""
        return [render.add_caption(camera, line, size_fraction=0.055 if index == 0 else 0.042, line=index)
                for index, line in enumerate(lines)]

    def before_after(self, name, objects, camera, lines):
        """Renders each object alone with the same camera, captioned with its lines, and composites the
        renders left to right into NAME.png: plain skinning first, its outline drawn in red over the others."""
        panels = []
        for number, (obj, obj_lines) in enumerate(zip(objects, lines)):
            if number > 0:
                obj_lines = list(obj_lines) + ["red: outline of Armature only"]
            captions = self.captions(camera, obj_lines)
            others = [other for other in objects if other is not obj]
            panels.append(render.render_still(self.path("%s_%d.png" % (name, number)), [obj] + captions, others))
        self.images.append(render.side_by_side(self.path(name + ".png"), panels, outline_first=True))

    def colours(self, name, obj, camera):
        """Renders the add-on's two colour displays of obj side by side into NAME.png."""
        left_captions = self.captions(camera, ["Segmentation", "one colour per region (bone)"])
        right_captions = self.captions(camera, ["Correction map", "blue: rigid, red: moves most"])
        obj.lvp.display = 'SEGMENTATION'
        render.set_material(obj, render.attribute_material("lvp_segmentation"))
        left = render.render_still(self.path(name + "_0.png"), [obj] + left_captions)
        obj.lvp.display = 'CORRECTION_MAP'
        render.set_material(obj, render.attribute_material("lvp_correction_map"))
        right = render.render_still(self.path(name + "_1.png"), [obj] + right_captions)
        obj.lvp.display = 'NONE'
        render.set_material(obj, render.skin_material())
        self.images.append(render.side_by_side(self.path(name + ".png"), [left, right]))

    # ---- the scenes ---------------------------------------------------------------------------------

    def sweep(self):
        self.new_scene(64, 64)
        changes = scenes.cylinder_sweep(SWEEP_ANGLES)
        self.sweep_changes = changes
        lines = ["| bend | Armature | Armature, Preserve Volume | Armature + Volume Preservation |",
                 "|---:|---:|---:|---:|"]
        for index, degrees in enumerate(SWEEP_ANGLES):
            if degrees % 10 == 0 and degrees > 0:
                lines.append("| %d\u00b0 | %s | %s | %s |" % (
                    degrees, percent(changes["plain"][index], 3), percent(changes["preserve_volume"][index], 3),
                    percent(changes["corrected"][index], 4)))
        self.table("The paper's cylinder (16 x 16 side vertices, radius 0.5, length 4, weights linear over a "
                   "band of 2.6) bent at its joint: volume change, % of the rest volume", lines)
        print("The paper's Table 2 (volume lost, before -> after its one correction pass): "
              + ", ".join("%d deg %.2g %% -> %.2g %%" % row for row in PAPER_TABLE2))
        index = SWEEP_ANGLES.index(90)
        self.rows.append(("cylinder, bent 90\u00b0", changes["plain"][index], changes["preserve_volume"][index],
                          changes["corrected"][index]))

    def table(self, title, lines):
        """Prints a Markdown table and keeps it for demo/out/volume_tables.md (README.md quotes it)."""
        print("\n" + title)
        for line in lines:
            print(line)
        self.tables.append((title, lines))

    def cylinder(self):
        self.new_scene(400, 400)
        plain, corrected = scenes.cylinder_pair(90.0)
        for obj in (plain, corrected):
            render.smooth(obj)
            render.set_material(obj, render.skin_material())
        triangles = scenes.triangles_of(plain)
        rest = scenes.rest_volume(plain)
        changes = [scenes.volume_change(obj, triangles, rest) for obj in (plain, corrected)]
        camera = render.add_camera((8.0, -1.0, 1.35), (0.0, -1.0, 1.35), (0.0, 0.0, 1.0), 4.4)
        self.before_after("cylinder_90", (plain, corrected), camera,
                          (("Armature only", "volume %+.1f %%" % (100 * changes[0])),
                           ("Armature + Volume Preservation", "volume %+.2f %%" % (100 * changes[1]))))
        self.colours("cylinder_maps", corrected, camera)

    def character_trio(self, name, plain, dual, corrected):
        """Skins plain and corrected for rendering, hides dual (Preserve Volume: measured, not rendered), and
        adds the three volume changes to the summary table as `name`; returns them."""
        dual.hide_render = True
        for obj in (plain, corrected):
            render.smooth(obj)
            render.set_material(obj, render.skin_material())
        triangles = scenes.triangles_of(plain)
        rest = scenes.rest_volume(plain)
        changes = [scenes.volume_change(obj, triangles, rest) for obj in (plain, dual, corrected)]
        self.rows.append((name, changes[0], changes[1], changes[2]))
        return changes

    def giraffe(self):
        self.new_scene(440, 440)
        plain, corrected, dual = scenes.giraffe_pair()
        changes = self.character_trio("giraffe, neck bent down, a knee folded", plain, dual, corrected)
        camera = render.add_camera((-6.0, 0.5, 0.06), (0.0, 0.5, 0.06), (0.0, 1.0, 0.0), 1.15)
        self.before_after("giraffe", (plain, corrected), camera,
                          (("Armature only", "volume %+.1f %%" % (100 * changes[0])),
                           ("Armature + Volume Preservation", "volume %+.2f %%" % (100 * changes[2]))))
        self.colours("giraffe_maps", corrected, camera)

    def finger(self):
        self.new_scene(360, 360)
        plain, volume_only, corrected = scenes.finger_trio()
        dual, dual_rig = scenes.finger_character("FingerPreserveVolume")  # measured, not rendered
        dual.modifiers["Armature"].use_deform_preserve_volume = True
        dual.hide_render = True
        scenes.bend_finger(dual_rig)
        bpy.context.view_layer.update()
        objects = (plain, volume_only, corrected)
        for obj in objects:
            render.smooth(obj)
            render.set_material(obj, render.skin_material())
        triangles = scenes.triangles_of(plain)
        rest = scenes.rest_volume(plain)
        changes = [scenes.volume_change(obj, triangles, rest) for obj in objects]
        crossings = [scenes.crossing_face_pairs(obj) for obj in objects]
        self.rows.append(("finger, both knuckles %g\u00b0, Fold-Over on" % scenes.FINGER_BEND, changes[0],
                          scenes.volume_change(dual, triangles, rest), changes[2]))
        self.finger_crossings = crossings
        camera = render.add_camera((6.0, 0.62, 0.6), (0.0, 0.62, 0.6), (0.0, 0.0, 1.0), 2.1)
        titles = ("Armature only", "Volume Preservation", "Volume Preservation + Fold-Over")
        lines = [(title, "volume %+.2f %%, %d crossing face pairs" % (100 * change, count))
                 for title, change, count in zip(titles, changes, crossings)]
        self.before_after("finger_fold", objects, camera, lines)

    def rigify(self):
        """Rigify's human posed hard, close up: the left leg (knee and hip) and the left elbow."""
        self.new_scene(420, 420)
        plain, dual, corrected, rig = scenes.rigify_trio()
        changes = self.character_trio("Rigify human, elbows, knees and hips bent hard", plain, dual, corrected)
        bones = rig.pose.bones
        knee, hip = (rig.matrix_world @ bones[name].head for name in ("DEF-shin.L", "DEF-thigh.L"))
        elbow = rig.matrix_world @ bones["DEF-forearm.L"].head
        lines = (("Armature only", "volume %+.1f %%" % (100 * changes[0])),
                 ("Armature + Volume Preservation", "volume %+.2f %%" % (100 * changes[2])))
        for name, target, view_from, size in (("rigify_leg", (knee + hip) / 2, Vector((1.5, -0.6, 0.3)), 0.75),
                                              ("rigify_elbow", elbow, Vector((0.6, -1.2, 0.5)), 0.45)):
            camera = render.add_camera(tuple(target + view_from), tuple(target), (0.0, 0.0, 1.0), size)
            self.before_after(name, (plain, corrected), camera, lines)

    def auto_weights(self):
        """The hip's weights as weight paint shows them, on Rigify's human at rest from behind: the left
        thigh's (both its B-Bone parts), Blender's heat weights beside the add-on's Auto Weights."""
        self.new_scene(420, 420)
        heat, auto, rig = scenes.auto_weights_pair()
        thigh = ("DEF-thigh.L", "DEF-thigh.L.001")
        material = render.attribute_material("lvp_demo_thigh_weight")
        for obj in (heat, auto):
            scenes.paint_weights(obj, thigh, "lvp_demo_thigh_weight")
            render.set_material(obj, material)
        hip = rig.matrix_world @ rig.data.bones["DEF-thigh.L"].head_local
        target = hip + Vector((0.0, 0.0, -0.12))
        # The body faces -Y: the buttock from behind and to its left, the groin from in front.
        for name, side in (("auto_weights_back", 1.6), ("auto_weights_front", -1.6)):
            camera = render.add_camera(tuple(target + Vector((0.9, side, 0.35))), tuple(target), (0.0, 0.0, 1.0), 0.8)
            panels = []
            for number, (obj, title) in enumerate(((heat, "With Automatic Weights (heat)"), (auto, "Auto Weights"))):
                captions = self.captions(camera, [title, "the left thigh's weight: blue 0, red 1"])
                panels.append(render.render_still(self.path("%s_%d.png" % (name, number)), [obj] + captions,
                                                  [other for other in (heat, auto) if other is not obj]))
            self.images.append(render.side_by_side(self.path(name + ".png"), panels))

    def volume_plot(self):
        helpers.reset_scene()
        changes = self.sweep_changes
        series = [
            ("Armature (plain skinning)", COLORS["plain"], [100 * value for value in changes["plain"]]),
            ("Armature, Preserve Volume (dual quaternion)", COLORS["preserve_volume"],
             [100 * value for value in changes["preserve_volume"]]),
            ("Armature + Volume Preservation", COLORS["corrected"], [100 * value for value in changes["corrected"]]),
        ]
        markers = [("the paper's Table 2, after its one pass", PAPER_COLOR,
                    [(degrees, -after) for degrees, _before, after in PAPER_TABLE2])]
        path = self.path("volume_error_plot.png")
        plot.line_plot(path, "The paper's cylinder bent at its joint: volume change",
                       "bend angle", "volume change (% of rest volume)", SWEEP_ANGLES, series, markers,
                       x_ticks=list(range(0, 121, 15)), pixel_width=self.size(960), samples=self.samples)
        self.images.append(path)

    def summary(self):
        lines = ["| scene | Armature | Armature, Preserve Volume | Armature + Volume Preservation |",
                 "|---|---:|---:|---:|"]
        for name, plain, dual, corrected in self.rows:
            lines.append("| %s | %s | %s | %s |" % (name, percent(plain, 2), percent(dual, 2), percent(corrected, 4)))
        self.table("The demo's scenes: volume change of the whole mesh, % of the rest volume", lines)
        print("Finger: pairs of faces that cross each other: %d with plain skinning, %d with Volume Preservation, "
              "%d with Fold-Over Prevention on" % tuple(self.finger_crossings))
        path = self.path("volume_tables.md")
        with open(path, "w") as file:
            for title, table_lines in self.tables:
                file.write("%s\n\n%s\n\n" % (title, "\n".join(table_lines)))

    def check_images(self):
        """Every image must be a real picture: readable, of the right size, not one flat colour."""
        print("\nImages in %s:" % self.out)
        bad = []
        for path in self.images:
            width, height, levels, foreground = render.image_statistics(path)
            print("  %-24s %4d x %-4d %6.1f kB, %3d grey levels, %4.1f %% not background"
                  % (os.path.basename(path), width, height, os.path.getsize(path) / 1024.0, levels,
                     100 * foreground))
            if levels < 8 or foreground < 0.02:
                bad.append(path)
        if bad:
            raise RuntimeError("empty-looking images: %s" % ", ".join(bad))


def main():
    args = parse_args()
    start = time.monotonic()
    addon = helpers.enable_addon()
    print("Local Volume Preservation demo: Blender %s, add-on from %s"
          % (bpy.app.version_string, os.path.dirname(addon.__file__)))
    demo = Demo(os.path.abspath(args.out), args.quick)
    for step in (demo.sweep, demo.cylinder, demo.giraffe, demo.finger, demo.rigify, demo.auto_weights,
                 demo.volume_plot):
        step_start = time.monotonic()
        step()
        print("[demo] %s: %.1f s" % (step.__name__, time.monotonic() - step_start))
        sys.stdout.flush()
    demo.summary()
    demo.check_images()
    print("\nDemo done in %.0f s: %d images in %s" % (time.monotonic() - start, len(demo.images), demo.out))
    return 0


if __name__ == "__main__":
    try:
        status = main()
    except Exception:
        import traceback
        traceback.print_exc()
        status = 1
    sys.stdout.flush()
    if status:
        sys.exit(status)
