# SPDX-License-Identifier: GPL-3.0-or-later
"""Dumps the project's hand (tests/blender/real_cases.hand) as the add-on binds and corrects it: the
arguments of _lvp.Binding and, at frames 12, 16 and 21, those of Binding.correct (the positions entering
Volume Preservation, the bones' matrices and the settings), for bench_keep_apart.py to replay outside
Blender. With --tube, the 100,096-vertex tube of tests/blender/bench.py instead, bending from 0 to 90
degrees over frames 1 to 20 as the bench plays it, at frames 10, 15 and 20 (45, 67 and 90 degrees). Run by
Blender 3.4 with the add-on built (./build.sh package):

    LVP_REPO=$PWD LVP_ADDON_DIR=$PWD/dist/local_volume_preservation \
        blender -b --factory-startup -noaudio --python tests/bench/dump_hand.py -- OUT.pickle [--tube]
"""
import os
import pickle
import sys
from array import array

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "blender"))
import bench  # noqa: E402
import lvp_helpers as helpers  # noqa: E402
import real_cases  # noqa: E402

FRAMES = (12, 16, 21)
TUBE_FRAMES = (10, 15, 20)
TUBE_VERTICES = 100_000


def tube():
    """(mesh, rig): the tube of tests/blender/bench.py, bending as the bench bends it."""
    rig = bench.bending_scene(20)
    return bench.dense_character("Tube", rig, round(TUBE_VERTICES / bench.AROUND)), rig


def main(out_path, use_tube):
    addon = helpers.enable_addon(check_volumes=False)
    real_lvp = addon.bindings._lvp
    bind_calls = []

    class RecordingModule:
        def __getattr__(self, name):
            return getattr(real_lvp, name)

        @staticmethod
        def Binding(*args, **kwargs):
            bind_calls.append((args, kwargs))
            return real_lvp.Binding(*args, **kwargs)

    addon.bindings._lvp = RecordingModule()
    frames = {}
    original = addon.live._core_correction

    def recording(obj, bound, rest_positions, fold_over, keep_apart):
        settings = obj.lvp
        frames[bpy.context.scene.frame_current] = {
            "positions": array('f', bound.positions), "bone_matrices": array('f', bound.bone_matrices),
            "rest_positions": None if rest_positions is None else array('f', rest_positions),
            "options": {"rigid_space": bound.skeleton.rigid_space, "iterations": settings.iterations,
                        "tolerance": settings.tolerance / 100.0, "fold_over": fold_over,
                        "displacement_limit": bound.displacement_limit, "restore": settings.restore,
                        "smoothing_passes": settings.smoothing}}
        return original(obj, bound, rest_positions, fold_over, keep_apart)

    addon.live._core_correction = recording
    obj, _rig = tube() if use_tube else real_cases.hand()
    bpy.context.view_layer.update()
    helpers.select_only(obj)
    bpy.ops.object.lvp_add()
    for frame in TUBE_FRAMES if use_tube else FRAMES:
        bpy.context.scene.frame_set(frame)
        bpy.context.view_layer.update()
        helpers.evaluated_positions(obj)
    addon.bindings._lvp = real_lvp
    args, kwargs = bind_calls[-1]
    kwargs = dict(kwargs)
    kwargs.pop("threads", None)
    with open(out_path, "wb") as out:
        pickle.dump({"bind_args": args, "bind_kwargs": kwargs, "frames": frames}, out, protocol=4)
    print("dumped %d vertices, frames %s to %s" % (len(args[0]) // 3, sorted(frames), out_path))


ARGUMENTS = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
main(next((a for a in ARGUMENTS if not a.startswith("--")), "hand.pickle"), "--tube" in ARGUMENTS)
