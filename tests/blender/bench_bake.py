# SPDX-License-Identifier: GPL-3.0-or-later
"""Bake speed: frames per second baking the giraffe and a ~100k-vertex mesh with 1 and 2 jobs.

Run by tests/blender/bench_bake.sh in each Blender:

    blender -b --factory-startup -noaudio --python tests/blender/bench_bake.py -- [--frames N] [--vertices N]

Each scene is saved to a .blend and baked by the command as a user runs it (a second Blender, the
add-on enabled by a --python script first), from a clean output directory. frames/s is the frames
baked divided by the wall time of the whole command: Blender start-up, loading, evaluation, writing,
merging. The bake-loop figure is the rate of the command's last progress line: from its first frame in-process
(--jobs 1), from spawning the jobs with --jobs 2 (their start-up included).
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lvp_helpers as helpers  # noqa: E402
import test_bake  # noqa: E402

AROUND = 256


def parse_arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_bake.py")
    parser.add_argument("--frames", type=int, default=480, help="giraffe frames (the dense mesh bakes a fifth)")
    parser.add_argument("--vertices", type=int, default=100_000)
    return parser.parse_args(argv)


def save(path):
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    return path


def giraffe_blend(directory, frames):
    helpers.reset_scene()
    test_bake.giraffe_scene(frames)
    return save(os.path.join(directory, "giraffe.blend")), "Giraffe", 1673


def dense_blend(directory, frames, vertices):
    helpers.reset_scene()
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, frames
    rig = helpers.two_bone_armature("DenseRig")
    rings = max(16, round(vertices / AROUND))
    obj = helpers.link(bpy.data.objects.new("Dense", helpers.cylinder_mesh("Dense", rings=rings, around=AROUND)))
    helpers.weight_linear_band(obj)
    helpers.add_armature_modifier(obj, rig)
    obj.parent = rig
    helpers.keyframe_bend(rig, {1: 0.0, frames // 2: 90.0, frames: 0.0})
    scene.frame_set(1)
    helpers.add_volume_preservation(obj)
    return save(os.path.join(directory, "dense.blend")), "Dense", len(obj.data.vertices)


def bake(blend, name, frames, jobs, directory):
    output = tempfile.mkdtemp(prefix="out-", dir=directory)
    script = os.path.join(os.path.dirname(helpers.enable_addon().__file__), "bake", "lvp_bake.py")
    command = helpers.blender_command() + ["--python", helpers.enable_script_path(), blend, "--python", script, "--",
                                           "--objects", name, "--frames", "1-%d" % frames, "--output", output,
                                           "--jobs", str(jobs), "--no-alembic"]
    start = time.perf_counter()
    completed = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, universal_newlines=True)
    seconds = time.perf_counter() - start
    if completed.returncode != 0:
        raise RuntimeError("the bake failed:\n%s" % completed.stderr[-3000:])
    rates = re.findall(r"\d+/\d+ frames \(100%\), ([0-9.]+) frames/s", completed.stderr)
    return frames / seconds, float(rates[-1]) if rates else float("nan"), seconds


def main():
    arguments = parse_arguments()
    helpers.enable_addon(check_volumes=False)
    directory = helpers.test_tmp()
    dense_frames = max(8, arguments.frames // 5)
    scenes = [giraffe_blend(directory, arguments.frames) + (arguments.frames,),
              dense_blend(directory, dense_frames, arguments.vertices) + (dense_frames,)]
    lines = ["Blender %s, %d CPUs: baking to PC2 with the command (wall time including Blender start-up)"
             % (bpy.app.version_string, os.cpu_count() or 0),
             "| mesh | vertices | frames | jobs | frames/s (whole command) | frames/s in the bake loop | seconds |",
             "|---|---|---|---|---|---|---|"]
    for blend, name, vertices, frames in scenes:
        for jobs in (1, 2):
            rate, baking, seconds = bake(blend, name, frames, jobs, directory)
            lines.append("| %s | %d | %d | %d | %.1f | %.1f | %.1f |" % (name, vertices, frames, jobs, rate, baking,
                                                                          seconds))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
