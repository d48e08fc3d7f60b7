# SPDX-License-Identifier: GPL-3.0-or-later
"""Frame times of Keep Skin Apart in the viewport on characters of a game's size, against the correction alone:
what Add's choice rests on (properties.KEEP_APART_VIEWPORT_VERTICES: Add turns Keep Skin Apart on in the viewport,
while the animation plays too for meshes of at most that many vertices, only on a still frame for denser ones).

Run by tests/blender/bench.sh in each Blender:

    blender -b --factory-startup -noaudio --python tests/blender/bench_characters.py -- [--rounds N]

The characters, each in a scene of its own, added with the add-on's defaults:

    the glTF horse of tests/data/horse (2,146 vertices), playing its first action
    the same horse's level of detail (test_horse's low-poly horse, about 300 vertices)
    the jumps of assimp-testmodels' CMU clip on a body of about 4,000 vertices, and the same decimated to about 600
    (real_cases.mocap_character; Blender 3.4's BVH importer cannot open files on Debian's Python 3.11: skipped there)
    the test hand (real_cases.hand, 7,478 vertices) from three quarters closed to the fist

A time is the wall time of scene.frame_set(frame), as playback pays it: the Armature modifier alone (Volume
Preservation's modifier hidden), the correction with the defaults less Keep Skin Apart, and with it. Medians over
all frames of --rounds passes over the character's frames; the three setups take turns frame by frame. For scale,
the last column is Blender's own test of the skinned triangles against each other (mathutils' BVHTree built and
overlapped with itself, lvp_helpers.self_intersection_test_ms), the median over the same frames: what an exact
crossing test of every triangle costs in Blender (Keep Skin Apart runs one of its own over the moving skin, with
the clearance searches of its fades).
"""

import argparse
import os
import statistics
import sys
import time
import unittest

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lvp_helpers as helpers  # noqa: E402
import real_cases  # noqa: E402
import test_horse  # noqa: E402


def parse_arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_characters.py")
    parser.add_argument("--rounds", type=int, default=3)
    return parser.parse_args(argv)


def added(obj):
    helpers.select_only(obj)
    if bpy.ops.object.lvp_add() != {'FINISHED'}:
        raise RuntimeError("Volume Preservation could not be added to %s" % obj.name)
    return obj


def horse(low_poly):
    obj, rig = test_horse.horse_scene(low_poly)  # added by horse_scene
    first, last = (int(round(frame)) for frame in rig.animation_data.action.frame_range)
    return obj, list(range(first, min(last, first + 29) + 1))


def jumps(decimated):
    obj, _rig, _first, _last = real_cases.mocap_character("jumps", 0.015, decimated)
    return added(obj), list(range(300, 420, 4))


def hand():
    obj, _rig = real_cases.hand()
    return added(obj), list(range(14, 22))


CHARACTERS = (
    ("horse (glTF)", lambda: horse(None)),
    ("horse, low-poly", lambda: horse(0.18)),
    ("jumps, decimated", lambda: jumps(0.15)),
    ("jumps", lambda: jumps(None)),
    ("hand, closing", hand),
)


def frame_times(modifier, obj, frames, rounds):
    """{setup: median ms} over rounds passes of frames, the setups taking turns at each frame."""
    scene = bpy.context.scene
    setups = {"armature": (False, False), "correction": (True, False), "keep_apart": (True, True)}
    times = {name: [] for name in setups}
    for name, (shown, keep_apart) in setups.items():  # warm up
        modifier.show_viewport, obj.lvp.keep_apart = shown, keep_apart
        for frame in frames[:3]:
            scene.frame_set(frame)
    for _round in range(rounds):
        for frame in frames:
            for name, (shown, keep_apart) in setups.items():
                modifier.show_viewport, obj.lvp.keep_apart = shown, keep_apart
                scene.frame_set(frame - 1)
                start = time.perf_counter()
                scene.frame_set(frame)
                times[name].append(time.perf_counter() - start)
    modifier.show_viewport = True
    return {name: 1000.0 * statistics.median(values) for name, values in times.items()}


def self_intersection_ms(modifier, obj, frames):
    """Blender's own crossing test of the skinned triangles (helpers.self_intersection_test_ms), median over
    frames: for scale beside Keep Skin Apart's frame."""
    modifier.show_viewport = False
    times = []
    for frame in frames:
        bpy.context.scene.frame_set(frame)
        times.append(helpers.self_intersection_test_ms(obj))
    modifier.show_viewport = True
    return statistics.median(times)


def main():
    arguments = parse_arguments()
    addon = helpers.enable_addon(check_volumes=False)
    version = bpy.app.version_string
    lines = ["Blender %s: characters of a game's size, ms a frame (medians)" % version, "",
             "| character | vertices | Armature alone | + Volume Preservation | with Keep Skin Apart | ratio | "
             "Add keeps it on in playback | Blender's self-intersection test |",
             "|---|---:|---:|---:|---:|---:|---|---:|"]
    limit = addon.properties.KEEP_APART_VIEWPORT_VERTICES
    for label, make in CHARACTERS:
        helpers.reset_scene()
        try:
            obj, frames = make()
        except unittest.SkipTest as skipped:
            lines.append("| %s | skipped: %s | | | | | | |" % (label, skipped))
            continue
        added_on = obj.lvp.keep_apart  # frame_times turns it off and on
        in_playback = added_on and not obj.lvp.keep_apart_paused_only
        modifier = addon.node_group.find_modifier(obj)
        ms = frame_times(modifier, obj, frames, arguments.rounds)
        vertices = len(obj.data.vertices)
        lines.append("| %s | %d | %.2f | %.2f | %.2f | %.1fx | %s | %.2f |"
                     % (label, vertices, ms["armature"], ms["correction"], ms["keep_apart"],
                        ms["keep_apart"] / ms["correction"], "yes" if in_playback else "no",
                        self_intersection_ms(modifier, obj, frames)))
        if added_on != (vertices <= addon.properties.KEEP_APART_STILL_VERTICES) or in_playback != (vertices <= limit):
            raise RuntimeError("Add left Keep Skin Apart %s in the viewport on %s (%d vertices)"
                               % ("off" if not added_on else ("on in playback" if in_playback else
                                                              "only on still frames"), label, vertices))
    lines.append("")
    lines.append("end of characters")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
