# SPDX-License-Identifier: GPL-3.0-or-later
"""Frame times of Volume Preservation against Blender's own modifiers, on a ~100k-vertex mesh.

Run by tests/blender/bench.sh in each Blender:

    blender -b --factory-startup -noaudio --python tests/blender/bench.py -- [--vertices N] [--frames N]
                                                                             [--result FILE]

Three copies of the same skinned tube (the paper's cylinder, made dense: rings x 256 vertices,
radius 0.5, length 4, two bones, weights linear over a band of 2.6) are timed one at a time, the
others hidden, while the joint bends from 0 to 90 degrees and back:

    Armature alone
    Armature + Corrective Smooth (default settings)
    Armature + Volume Preservation (this add-on, default settings as playback runs them: on a mesh this
    dense, Keep Skin Apart only on a still frame)
    Armature + Volume Preservation with Keep Skin Apart (what renders have; issue 46's target: under 0.75x
    Armature + Corrective Smooth)
    Armature + Volume Preservation's node group with the correction off (the add-on's handlers
    unregistered): what one evaluation of the stack costs, before any correction

A frame time is the wall time of scene.frame_set(frame), which is what playback pays: animation,
the modifier stack, and for Volume Preservation its handler and Blender's second evaluation. The
setups take turns every few frames (so that other load on the machine affects them alike) and the
median over all frames is reported. Targets: Volume Preservation at most 2.5x Armature
alone and at most 0.25x Armature + Corrective Smooth.

For scale beside Keep Skin Apart's frame: Blender's own test of the tube's triangles against each other at 90
degrees (mathutils' BVHTree built and overlapped with itself), what an exact crossing test of every triangle costs
in Blender.

Where the time of Volume Preservation goes: the core's correction alone (Binding.correct on one
frame), and the evaluation Blender does again after the offsets are written (the mesh tagged, the
view layer updated, correction off). One evaluation with the node group plus that re-evaluation is
what a correction that took no time at all would still cost: the floor of this architecture.
"""

import argparse
import json
import os
import statistics
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lvp_helpers as helpers  # noqa: E402

AROUND = 256


def parse_arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench.py")
    parser.add_argument("--vertices", type=int, default=100_000)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--result", default="")
    return parser.parse_args(argv)


def dense_character(name, rig, rings):
    obj = helpers.link(bpy.data.objects.new(name, helpers.cylinder_mesh(name, rings=rings, around=AROUND)))
    helpers.weight_linear_band(obj)
    helpers.add_armature_modifier(obj, rig)
    obj.parent = rig
    return obj


def bending_scene(half):
    """The rig of the bench, its joint bending from 0 degrees at frame 1 to 90 at `half` and back at 2 * half, in a
    new scene of those frames."""
    scene = helpers.reset_scene()
    scene.frame_start = 1
    scene.frame_end = 2 * half
    rig = helpers.two_bone_armature("BenchRig")
    helpers.keyframe_bend(rig, {1: 0.0, half: 90.0, 2 * half: 0.0})
    return rig


def set_correction(addon, on):
    """Registers or unregisters the add-on's handlers: with them off, the modifier's node group still
    runs (and adds the offsets last written), but nothing is corrected or written."""
    if on:
        addon.handlers.register()
    else:
        addon.handlers.unregister()


def time_frames(scene, frames):
    times = []
    for frame in frames:
        start = time.perf_counter()
        scene.frame_set(frame)
        times.append(time.perf_counter() - start)
    return times


def main():
    arguments = parse_arguments()
    addon = helpers.enable_addon(check_volumes=False)
    half = max(2, arguments.frames // 2)
    rings = max(16, round(arguments.vertices / AROUND))
    rig = bending_scene(half)
    scene = bpy.context.scene

    setups = {}
    setups["armature"] = dense_character("ArmatureOnly", rig, rings)
    smooth_object = dense_character("CorrectiveSmooth", rig, rings)
    smooth_object.modifiers.new("CorrectiveSmooth", 'CORRECTIVE_SMOOTH')
    setups["corrective_smooth"] = smooth_object
    ours = dense_character("VolumePreservation", rig, rings)
    bpy.context.view_layer.update()
    helpers.select_only(ours)
    start = time.perf_counter()
    bpy.ops.object.lvp_add()
    bind_seconds = time.perf_counter() - start
    # The correction as playback runs it on a mesh this dense: Add sets Keep Skin Apart Only When Paused, and
    # frame_set here is never playing, so it is turned off for this setup and timed with the next.
    ours.lvp.keep_apart = False
    setups["volume_preservation"] = ours
    kept_apart = dense_character("VolumePreservationKeptApart", rig, rings)
    helpers.select_only(kept_apart)
    bpy.ops.object.lvp_add()
    kept_apart.lvp.keep_apart, kept_apart.lvp.keep_apart_paused_only = True, False
    setups["kept_apart"] = kept_apart
    setups["node_group_only"] = ours  # the same object, with the correction off (set_correction)
    vertex_count = len(ours.data.vertices)

    # The setups take turns, a few frames each, so that a change in machine load affects them alike.
    frames = list(range(2, 2 * half + 1))
    chunk = 6
    times = {name: [] for name in setups}
    for name, obj in setups.items():  # warm up
        helpers.show_only_one(setups, obj)
        set_correction(addon, name != "node_group_only")
        scene.frame_set(1)
        time_frames(scene, frames[:4])
    for start in range(0, len(frames), chunk):
        for name, obj in setups.items():
            helpers.show_only_one(setups, obj)
            set_correction(addon, name != "node_group_only")
            scene.frame_set(frames[start] - 1)
            times[name].extend(time_frames(scene, frames[start:start + chunk]))
    results = {name: 1000.0 * statistics.median(values) for name, values in times.items()}
    helpers.show_only_one(setups, ours)

    # Blender's evaluation after the offsets are written, alone: the offsets object's mesh tagged as
    # the handlers do (addon/offsets.py, write), the view layer updated, the correction off.
    set_correction(addon, False)
    scene.frame_set(half)
    holder = helpers.offsets_object(ours)
    reevaluation_times = []
    for _repeat in range(15):
        start = time.perf_counter()
        holder.data.update_tag()
        bpy.context.view_layer.update()
        reevaluation_times.append(time.perf_counter() - start)
    results["reevaluation"] = 1000.0 * statistics.median(reevaluation_times)
    set_correction(addon, True)

    # Where the time goes in Volume Preservation: the C core's correction alone, on one frame.
    scene.frame_set(half)
    bound = addon.session.SESSION.bound(ours)
    status = addon.session.SESSION.status(ours)
    correct_times = []
    for _repeat in range(5):
        start = time.perf_counter()
        bound.binding.correct(bound.positions, bound.bone_matrices, out_offsets=helpers.array(
            'f', bytes(4 * len(bound.offsets))), iterations=ours.lvp.iterations, tolerance=ours.lvp.tolerance / 100.0,
            restore=ours.lvp.restore, keep_apart=ours.lvp.keep_apart,
            smoothing_passes=ours.lvp.smoothing)
        correct_times.append(time.perf_counter() - start)
    results["core_correct"] = 1000.0 * statistics.median(correct_times)
    stats = bound.stats or {}

    # For scale: Blender's own crossing test of the same triangles at 90 degrees, as Armature alone leaves them.
    helpers.show_only_one(setups, setups["armature"])
    scene.frame_set(half)
    results["blender_self_intersection"] = helpers.self_intersection_test_ms(setups["armature"])
    helpers.show_only_one(setups, ours)

    armature = results["armature"]
    smooth = results["corrective_smooth"]
    volume = results["volume_preservation"]
    kept = results["kept_apart"]
    node_group = results["node_group_only"]
    floor = node_group + results["reevaluation"]
    version = bpy.app.version_string
    lines = [
        "Blender %s, %d vertices, %d triangles, %d frames (median), %d threads for the core, bind %.0f ms"
        % (version, vertex_count, bound.binding.triangle_count, len(frames), addon.bindings.thread_count(),
           1000 * bind_seconds),
        "| setup | ms / frame | vs Armature alone | vs Armature + Corrective Smooth |",
        "|---|---|---|---|",
        "| Armature alone | %.1f | 1.00x | %.2fx |" % (armature, armature / smooth),
        "| Armature + Corrective Smooth (defaults) | %.1f | %.2fx | 1.00x |" % (smooth, smooth / armature),
        "| Armature + Volume Preservation | %.1f | %.2fx (target <= 2.5x) | %.2fx (target <= 0.25x) |"
        % (volume, volume / armature, volume / smooth),
        "| Armature + Volume Preservation, Keep Skin Apart | %.1f | %.2fx | %.2fx (target < 0.75x) |"
        % (kept, kept / armature, kept / smooth),
        "| Armature + its node group, correction off | %.1f | %.2fx | %.2fx |"
        % (node_group, node_group / armature, node_group / smooth),
        "core Binding.correct alone: %.1f ms (%s passes at 90 degrees); status: %s"
        % (results["core_correct"], stats.get("iterations", "?"), status[1] if status else "?"),
        "for scale, Blender's own self-intersection test of the triangles at 90 degrees (mathutils BVHTree built "
        "and overlapped with itself): %.1f ms = %.2fx Armature + Corrective Smooth"
        % (results["blender_self_intersection"], results["blender_self_intersection"] / smooth),
        "re-evaluation after the offsets are written: %.1f ms; floor with a correction of no time "
        "(node group + re-evaluation): %.1f ms = %.2fx Armature, %.2fx Armature + Corrective Smooth"
        % (results["reevaluation"], floor, floor / armature, floor / smooth),
    ]
    print("\n".join(lines))
    if arguments.result:
        with open(arguments.result, "w") as file:
            json.dump({"blender": version, "vertices": vertex_count, "ms": results, "table": lines}, file)


if __name__ == "__main__":
    main()
