# SPDX-License-Identifier: GPL-3.0-or-later
"""Measures the surface (../shared/QUALITY.md) of Volume Preservation on the real cases of real_cases.py: a
Rigify human posed hard and a hand closing into a fist, each as built and through a glTF round trip (split at
its UV seams). Per case and pose it prints the whole-mesh volume change, crossing pairs, creases added,
roughness, largest offset and crack of plain skinning, Volume Preservation (VP) and VP with Fold-Over Prevention
(VP+fold), and what the add-on's panel says; for the hand, how much VP's offsets jump from frame to frame of its
animation against the skin's motion (popping); with --render DIR, one close-up per case at its hardest pose (plain |
VP | VP+fold) into DIR. Nothing is asserted: these are the numbers issues 24-26 are judged by.

    tests/blender/blender_chroot.sh 5.2 run -b --factory-startup --python tests/blender/measure_quality.py \
        -- [--cases body,hand] [--no-gltf] [--render /tmp/quality_renders] [--bulge-width W] [--smoothing N]
           [--keep-apart] [--auto-weights]
    blender -b --factory-startup --python tests/blender/measure_quality.py -- ...

The add-on comes from dist/ as in the tests (./build.sh package first).
"""

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
sys.path.insert(1, os.path.join(REPO, "demo"))

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402

import lvp_helpers as helpers  # noqa: E402
import real_cases  # noqa: E402
import surface_quality as quality  # noqa: E402

VARIANTS = ("plain", "VP", "VP+fold")


def arguments():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="measure_quality.py")
    parser.add_argument("--cases", default="body,hand", help="comma-separated: body, hand")
    parser.add_argument("--no-gltf", action="store_true", help="leave out the glTF round-tripped versions")
    parser.add_argument("--render", metavar="DIR", help="render a close-up per case at its hardest pose into DIR")
    parser.add_argument("--bulge-width", type=float, help="the objects' Bulge Width (default: the add-on's)")
    parser.add_argument("--smoothing", type=int, help="the objects' Smoothing (default: the add-on's)")
    parser.add_argument("--keep-apart", action="store_true",
                        help="Keep Skin Apart in the viewport too (renders have it on by default)")
    parser.add_argument("--auto-weights", action="store_true",
                        help="weight the human with the add-on's Auto Weights (its defaults) instead of heat weights")
    return parser.parse_args(argv)


def status_text(addon, obj):
    status = addon.session.SESSION.status(obj)
    return "%s: %s" % status if status else "-"


def positions_of_variants(addon, obj):
    """{variant: evaluated positions, "status " + variant: the panel's status} at the current pose."""
    result = {"plain": helpers.uncorrected_positions(obj)}
    for variant, fold_over in (("VP", False), ("VP+fold", True)):
        obj.lvp.fold_over = fold_over
        bpy.context.view_layer.update()
        result[variant] = helpers.evaluated_positions(obj)
        result["status " + variant] = status_text(addon, obj)
    obj.lvp.fold_over = False
    bpy.context.view_layer.update()
    return result


def print_header(title, obj, mesh):
    print("\n%s: %d vertices (%d of them copies at a seam), %d triangles, mean rest edge %.4g m"
          % (title, len(obj.data.vertices), mesh.split_vertex_count, len(mesh.triangles), mesh.mean_rest_edge_length))
    print("  %-22s %-8s %9s %9s %8s %10s %9s %7s  %s" % ("pose", "variant", "volume %", "crossing", "creases",
                                                        "roughness", "largest", "crack", "panel"))


def measure_pose(addon, obj, mesh, label):
    positions = positions_of_variants(addon, obj)
    started = time.perf_counter()
    measured = quality.measure_pose(mesh, positions["plain"], {v: positions[v] for v in VARIANTS[1:]})
    seconds = time.perf_counter() - started
    for variant in VARIANTS:
        row = measured[variant]
        if variant == "plain":
            print("  %-22s %-8s %+9.3f %9d %8s %10s %9s %7s" % (label, variant, 100 * row["volume"], row["crossings"],
                                                               "-", "-", "-", "-"))
        else:
            print("  %-22s %-8s %+9.3f %9d %8d %10.3f %9.3f %7.1e  %s"
                  % ("", variant, 100 * row["volume"], row["crossings"], row["creases"], row["roughness"],
                     row["largest_offset"], row["crack"], positions["status " + variant][:70]))
    print("  %-22s (measured in %.2f s; roughness, largest offset and crack in mean rest edge lengths)"
          % ("", seconds))
    return measured


def measure_animation(addon, obj, mesh, frames):
    """Prints, for VP and VP+fold at each frame of `frames` after the first, the largest change of an offset
    since the frame before over the largest motion of plain skinning's skin (surface_quality.offset_change_ratio):
    a fraction where the correction follows the motion, 1 or more where it pops; and each frame's crossing pairs
    of plain skinning, VP and VP+fold."""
    scene = bpy.context.scene
    before = None
    ratios = {variant: [] for variant in VARIANTS[1:]}
    crossings = {variant: [] for variant in VARIANTS}
    for frame in frames:
        scene.frame_set(frame)
        positions = positions_of_variants(addon, obj)
        offsets = {variant: quality.offsets_between(positions["plain"], positions[variant])
                   for variant in VARIANTS[1:]}
        for variant in VARIANTS:
            crossings[variant].append(quality.count_crossing_pairs(positions[variant], mesh))
        if before is not None:
            for variant in VARIANTS[1:]:
                ratios[variant].append((frame, quality.offset_change_ratio(before[variant], offsets[variant],
                                                                           before["plain"], positions["plain"])))
        before = dict(offsets, plain=positions["plain"])
    for variant in VARIANTS[1:]:
        worst = max(ratios[variant], key=lambda item: item[1])
        print("  animation %-8s frames %d-%d: offset change against skin motion, largest %.2f at frame %d; by frame: %s"
              % (variant, frames[0], frames[-1], worst[1], worst[0],
                 " ".join("%.2f" % ratio for _frame, ratio in ratios[variant])))
    for variant in VARIANTS:
        print("  crossing pairs %-8s by frame: %s" % (variant, " ".join(str(c) for c in crossings[variant])))
    return ratios, crossings


def measure_case(addon, title, obj, poses):
    """poses: [(label, function that sets the pose)]."""
    mesh = quality.WeldedMesh(helpers.mesh_positions(obj.data), helpers.mesh_triangles(obj.data))
    print_header(title, obj, mesh)
    for label, pose in poses:
        pose()
        measure_pose(addon, obj, mesh, label)


# ---- the cases ---------------------------------------------------------------------------------


def body_poses(rig):
    return [("hard x%.2g" % amount, lambda amount=amount: real_cases.pose_rigify_human(rig, amount))
            for amount in (0.5, 1.0)]


def hand_poses():
    scene = bpy.context.scene
    return [("frame %d (%d%% fist)" % (frame, round(100 * (frame - 1) / 20)),
             lambda frame=frame: scene.frame_set(frame)) for frame in (6, 11, 16, 21)]


def build_body(with_gltf, auto_weights=False):
    started = time.perf_counter()
    body, rig = real_cases.rigify_human()
    built = time.perf_counter() - started
    if auto_weights:
        helpers.select_only(body)
        bpy.context.view_layer.objects.active = body
        started = time.perf_counter()
        result = bpy.ops.object.lvp_auto_weights()
        print("\nAuto Weights (the add-on's defaults) instead of heat weights: %s in %.2f s"
              % (result, time.perf_counter() - started))
    objects = [("Rigify human", body)]
    if with_gltf:
        objects.append(("Rigify human, glTF round trip", real_cases.gltf_round_trip(body, rig)))
    angles = real_cases.pose_rigify_human(rig, 1.0)
    print("\nRigify human built in %.1f s; its hard pose measured on the DEF bones: %s"
          % (built, ", ".join("%s %.0f" % (name, value) for name, value in angles.items())))
    real_cases.pose_rigify_human(rig, 0.0)
    return objects, rig


def build_hand(with_gltf):
    started = time.perf_counter()
    obj, rig = real_cases.hand()
    built = time.perf_counter() - started
    objects = [("Hand", obj)]
    if with_gltf:
        objects.append(("Hand, glTF round trip", real_cases.gltf_round_trip(obj, rig)))
    scene = bpy.context.scene
    scene.frame_set(real_cases.HAND_FRAMES[1])
    height, along = real_cases.fingertip_to_palm(rig)
    print("\nHand built in %.1f s; at the fist the middle fingertip's bone ends %.1f mm from the palm's middle "
          "plane, %.0f %% of the way from the wrist to the knuckles" % (built, 1000 * height, 100 * along))
    scene.frame_set(real_cases.HAND_FRAMES[0])
    return objects, rig


# ---- renders -----------------------------------------------------------------------------------


def render_close_up(addon, directory, name, obj, target, view_from, size):
    """plain | VP | VP+fold of obj at the current pose, seen from target + view_from, into DIR/name.png."""
    import demo_render as render
    scene = bpy.context.scene
    render.setup_cycles(scene, 480, 360, 16)
    for other in scene.objects:
        if other.type in {'CAMERA', 'LIGHT', 'FONT'}:
            bpy.data.objects.remove(other)
    render.add_sun(direction=tuple(-Vector(view_from) + Vector((0.0, 0.0, -0.5))), strength=3.0)
    camera = render.add_camera(tuple(Vector(target) + Vector(view_from)), tuple(target), (0.0, 0.0, 1.0), size)
    scene.camera = camera
    render.set_material(obj, render.skin_material())
    others = [other for other in scene.objects if other.type == 'MESH' and other != obj]
    modifier = addon.node_group.find_modifier(obj)
    paths = []
    for variant in VARIANTS:
        modifier.show_render = variant != "plain"
        obj.lvp.fold_over = variant == "VP+fold"
        bpy.context.view_layer.update()
        caption = render.add_caption(camera, "%s: %s" % (name, variant))
        path = os.path.join(directory, "%s_%s.png" % (name, variant.replace("+", "_")))
        paths.append(render.render_still(path, [obj, caption], others))
    modifier.show_render = True
    obj.lvp.fold_over = False
    bpy.context.view_layer.update()
    return render.side_by_side(os.path.join(directory, name + ".png"), paths, outline_first=True, remove_parts=False)


def add_volume_preservation(options, objects):
    helpers.add_volume_preservation(*(obj for _title, obj in objects))
    for _title, obj in objects:
        if options.bulge_width is not None:
            obj.lvp.bulge_width = options.bulge_width
        if options.smoothing is not None:
            obj.lvp.smoothing = options.smoothing
        obj.lvp.keep_apart = options.keep_apart
        print("%s: Bulge Width %g, Smoothing %d, Keep Skin Apart in the viewport %s"
              % (obj.name, obj.lvp.bulge_width, obj.lvp.smoothing, "on" if obj.lvp.keep_apart else "off"))


def main():
    options = arguments()
    addon = helpers.enable_addon()
    cases = options.cases.split(",")
    print("Blender %s, add-on from %s" % (bpy.app.version_string, helpers.addon_dir()))
    if options.render:
        os.makedirs(options.render, exist_ok=True)
    if "body" in cases:
        helpers.reset_scene()
        objects, rig = build_body(not options.no_gltf, options.auto_weights)
        add_volume_preservation(options, objects)
        for title, obj in objects:
            measure_case(addon, title, obj, body_poses(rig))
        if options.render:
            for title, obj in objects:
                knee = rig.matrix_world @ rig.pose.bones["DEF-shin.L"].head
                hip = rig.matrix_world @ rig.pose.bones["DEF-thigh.L"].head
                name = "body_gltf" if "glTF" in title else "body"
                print("render:", render_close_up(addon, options.render, name + "_leg", obj, (knee + hip) / 2,
                                                 (1.5, -0.6, 0.3), 0.75))
                elbow = rig.matrix_world @ rig.pose.bones["DEF-forearm.L"].head
                print("render:", render_close_up(addon, options.render, name + "_elbow", obj, elbow,
                                                 (0.6, -1.2, 0.5), 0.45))
    if "hand" in cases:
        helpers.reset_scene()
        objects, rig = build_hand(not options.no_gltf)
        add_volume_preservation(options, objects)
        for title, obj in objects:
            measure_case(addon, title, obj, hand_poses())
            mesh = quality.WeldedMesh(helpers.mesh_positions(obj.data), helpers.mesh_triangles(obj.data))
            measure_animation(addon, obj, mesh, list(range(real_cases.HAND_FRAMES[0], real_cases.HAND_FRAMES[1] + 1)))
        if options.render:
            for title, obj in objects:
                bpy.context.scene.frame_set(real_cases.HAND_FRAMES[1])
                palm = rig.matrix_world @ rig.pose.bones["palm"].tail
                name = "hand_gltf" if "glTF" in title else "hand"
                print("render:", render_close_up(addon, options.render, name + "_index_side", obj, palm,
                                                 (0.5, 0.1, -0.25), 0.14))
                print("render:", render_close_up(addon, options.render, name + "_little_finger_side", obj, palm,
                                                 (-0.5, 0.25, -0.2), 0.14))


if __name__ == "__main__":
    main()
