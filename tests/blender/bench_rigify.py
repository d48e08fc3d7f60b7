# SPDX-License-Identifier: GPL-3.0-or-later
"""Frame times on a production rig: a generated Rigify human, Volume Preservation against Corrective Smooth.

Run by tests/blender/bench.sh in each Blender:

    blender -b --factory-startup -noaudio --python tests/blender/bench_rigify.py -- [--voxel SIZE] [--updates N]
                                                                                    [--result FILE]

The character is real_cases.rigify_human(): Rigify's human metarig generated (its DEF bones B-Bones of several
segments), a closed body grown around them (--voxel 0.0105: about 25k vertices; 0.0052: about 100k), parented
With Automatic Weights. Copies of it, each with its own mesh, are timed one at a time, the others hidden:

    Armature alone
    Armature + Corrective Smooth (default settings)
    Armature + Volume Preservation (the add-on's defaults)
    Armature + Volume Preservation with Keep Skin Apart

The rig takes two hard poses in turn (real_cases.pose_rigify_human, fully and 90 % of the way), as an animator
posing in the viewport does: the pose bones' rotations set, the view layer updated. A time is the wall time of
that update: the rig's own evaluation (constraints, drivers, B-Bones), the stack, and for Volume Preservation its
handler and Blender's second evaluation of the mesh. Medians over all updates; the setups take turns.

Where Volume Preservation's time goes, from the same updates: the C core's correction (Binding.correct), the
add-on's own Python in the handler around it, and the rest (Blender's evaluations). Then Blender's evaluation
of the mesh again once the offsets are written, timed alone, beside the same of the Armature-only copy (Blender
running the Armature modifier again, which a result written from Python costs whatever computes it), and what
the update costs besides the core and the Python: Corrective Smooth's time less that is what the two may take
to match it. Targets (issue 47, on Blender 5.2 at 25k vertices): Armature + Volume Preservation no slower than
Armature + Corrective Smooth, the core at most 3 ms, the add-on's Python at most 1 ms.
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
import real_cases  # noqa: E402


def parse_arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_rigify.py")
    parser.add_argument("--voxel", type=float, default=0.0105)
    parser.add_argument("--updates", type=int, default=24)
    parser.add_argument("--result", default="")
    return parser.parse_args(argv)


def pose_rotations(rig):
    return {bone.name: tuple(bone.rotation_euler) for bone in rig.pose.bones}


def set_pose(rig, rotations):
    for bone in rig.pose.bones:
        bone.rotation_euler = rotations[bone.name]


def copy_character(body, rig, name):
    obj = body.copy()
    obj.data = body.data.copy()
    obj.name = name
    bpy.context.scene.collection.objects.link(obj)
    obj.parent = rig
    return obj


class Timed:
    """Wall time spent in a function while installed (its calls summed), the function left as it was after."""

    def __init__(self, owner, name):
        self.owner, self.name = owner, name
        self.original = getattr(owner, name)
        self.seconds = 0.0

    def __enter__(self):
        original = self.original

        def timed(*arguments, **keywords):
            start = time.perf_counter()
            try:
                return original(*arguments, **keywords)
            finally:
                self.seconds += time.perf_counter() - start
        setattr(self.owner, self.name, timed)
        return self

    def __exit__(self, *_exception):
        setattr(self.owner, self.name, self.original)


def evaluation_again_ms(setups, obj, tagged_mesh, repeats=15):
    """Median ms of the view layer's update after tagged_mesh changed, obj alone shown, the pose as it is."""
    helpers.show_only_one(setups, obj)
    times = []
    for _repeat in range(repeats):
        start = time.perf_counter()
        tagged_mesh.update_tag()
        bpy.context.view_layer.update()
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def main():
    arguments = parse_arguments()
    addon = helpers.enable_addon(check_volumes=False)
    helpers.reset_scene()
    start = time.perf_counter()
    body, rig = real_cases.rigify_human(voxel_size=arguments.voxel)
    build_seconds = time.perf_counter() - start
    real_cases.pose_rigify_human(rig, 1.0)
    hard = pose_rotations(rig)
    real_cases.pose_rigify_human(rig, 0.9)
    less = pose_rotations(rig)
    for pose_bone in rig.pose.bones:
        pose_bone.rotation_euler = (0.0, 0.0, 0.0)
    bpy.context.view_layer.update()

    setups = {"armature": body}
    smooth = copy_character(body, rig, "CorrectiveSmooth")
    smooth.modifiers.new("CorrectiveSmooth", 'CORRECTIVE_SMOOTH')
    setups["corrective_smooth"] = smooth
    bind_ms = {}
    for name, keep_apart in (("volume_preservation", False), ("keep_apart", True)):
        ours = copy_character(body, rig, name)
        bpy.context.view_layer.update()
        helpers.select_only(ours)
        start = time.perf_counter()
        bpy.ops.object.lvp_add()
        bind_ms[name] = 1000.0 * (time.perf_counter() - start)
        ours.lvp.keep_apart = keep_apart
        setups[name] = ours

    updates = max(4, arguments.updates)
    times = {name: [] for name in setups}
    core = {name: [] for name in setups}
    handler = {name: [] for name in setups}
    chunk = 4
    poses = [hard, less]
    for name, obj in setups.items():  # warm up: binds, first evaluations
        helpers.show_only_one(setups, obj)
        for pose in poses:
            set_pose(rig, pose)
            bpy.context.view_layer.update()
    for first in range(0, updates, chunk):
        for name, obj in setups.items():
            helpers.show_only_one(setups, obj)
            for update in range(first, min(first + chunk, updates)):
                set_pose(rig, poses[update % 2])
                with Timed(addon.handlers, "_correct") as in_handler, \
                        Timed(addon.live, "_core_correction") as in_core:
                    start = time.perf_counter()
                    bpy.context.view_layer.update()
                    times[name].append(time.perf_counter() - start)
                core[name].append(in_core.seconds)
                handler[name].append(in_handler.seconds)
    ms = {name: 1000.0 * statistics.median(values) for name, values in times.items()}
    core_ms = {name: 1000.0 * statistics.median(values) for name, values in core.items()}
    handler_ms = {name: 1000.0 * statistics.median(values) for name, values in handler.items()}

    # Blender's evaluation after the offsets are written, alone (bench.py): the offsets object's mesh
    # tagged as the handlers do, the view layer updated, the correction off. Beside it the same
    # evaluation of the copy with the Armature modifier alone (its mesh tagged): the part of it that
    # is Blender running the Armature modifier again, which any result written from Python costs.
    ours = setups["volume_preservation"]
    addon.handlers.unregister()
    holder = helpers.offsets_object(ours)
    reevaluation_ms = evaluation_again_ms(setups, ours, holder.data)
    armature_again_ms = evaluation_again_ms(setups, body, body.data)
    addon.handlers.register()
    bound = addon.session.SESSION.bound(ours)
    stats = bound.stats or {}
    status = addon.session.SESSION.status(ours)
    armature, smooth_ms = ms["armature"], ms["corrective_smooth"]
    version = bpy.app.version_string
    lines = [
        "Blender %s, Rigify human: %d vertices, %d bones (%d deforming, %d core bones with B-Bone joints), "
        "%d threads for the core, body built in %.0f s, bind %.0f ms, %d pose updates (median)"
        % (version, len(body.data.vertices), len(rig.data.bones), len(bound.skeleton.bone_names),
           bound.skeleton.core_bone_count, addon.bindings.thread_count(), build_seconds,
           bind_ms["volume_preservation"], updates),
        "| setup | ms / update | added to Armature alone | vs Armature + Corrective Smooth | core | add-on Python |",
        "|---|---|---|---|---|---|",
    ]
    labels = (("armature", "Armature alone"), ("corrective_smooth", "Armature + Corrective Smooth (defaults)"),
              ("volume_preservation", "Armature + Volume Preservation (defaults)"),
              ("keep_apart", "Armature + Volume Preservation, Keep Skin Apart"))
    for name, label in labels:
        ours_part = name in ("volume_preservation", "keep_apart")
        lines.append("| %s | %.1f | %.1f | %.2fx | %s | %s |" % (
            label, ms[name], ms[name] - armature, ms[name] / smooth_ms,
            "%.1f" % core_ms[name] if ours_part else "-",
            "%.1f" % (handler_ms[name] - core_ms[name]) if ours_part else "-"))
    lines.append("Blender's evaluation of the mesh again once the offsets are written: %.1f ms (of an Armature-only "
                 "copy: %.1f ms)" % (reevaluation_ms, armature_again_ms))
    # What Armature + Volume Preservation costs besides the core and the add-on's Python (Blender's two
    # evaluations, the node group's in each), and what that leaves them to match Corrective Smooth.
    blender_part = ms["volume_preservation"] - handler_ms["volume_preservation"]
    lines.append("Armature + Volume Preservation without the core and the add-on's Python: %.1f ms, which leaves "
                 "%.1f ms for both to match Armature + Corrective Smooth" % (blender_part, smooth_ms - blender_part))
    lines.append("status: %s; %s regions corrected, %s steps"
                 % (status[1] if status else "?", stats.get("active_regions", "?"), stats.get("iterations", "?")))
    print("\n".join(lines))
    if arguments.result:
        with open(arguments.result, "w") as file:
            json.dump({"blender": version, "vertices": len(body.data.vertices), "ms": ms, "core_ms": core_ms,
                       "handler_ms": handler_ms,
                       "reevaluation_ms": reevaluation_ms, "armature_again_ms": armature_again_ms,
                       "table": lines}, file)


if __name__ == "__main__":
    main()
