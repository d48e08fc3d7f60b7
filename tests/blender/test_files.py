# SPDX-License-Identifier: GPL-3.0-or-later
"""What happens outside this Blender: saving and reopening in a fresh Blender, and renders made by
`blender -b file.blend -a` (and -f), with and without a Subdivision Surface modifier after ours, and
the motion steps of a motion-blurred render.

Each test saves a temporary .blend here and starts a second Blender of the same version with the
add-on enabled the same way (lvp_helpers.run_blender). Renders are compared by their alpha
silhouettes (Cycles, one sample per pixel at the pixel centre, transparent film) against a render of
a static copy of the mesh this process evaluated: equal when the render shows the corrected shape.
"""

import json
import math
import os
import unittest
from array import array

import bpy
from mathutils import Euler

import lvp_helpers as helpers

CHILD_DUMP = """
import bpy, json, sys
from array import array
sys.path.insert(0, {here!r})
import lvp_helpers
addon = lvp_helpers.enable_addon()
out = {out!r}
obj = bpy.data.objects[{name!r}]
result = {{}}
def dump(key):
    positions = lvp_helpers.evaluated_positions(obj)
    result[key] = list(positions)
    status = addon.session.SESSION.status(obj)
    result[key + "_status"] = list(status) if status else None
dump("opened")
for frame in {frames!r}:
    bpy.context.scene.frame_set(frame)
    dump("frame%d" % frame)
result["bound"] = addon.session.SESSION.bound(obj) is not None
with open(out, "w") as file:
    json.dump(result, file)
"""

# A Blender WITHOUT the add-on opens the file: what it shows at each frame.
CHILD_DUMP_WITHOUT_ADDON = """
import bpy, json
from array import array
obj = bpy.data.objects[{name!r}]
modifier = obj.modifiers["Volume Preservation"]  # the correction is in the object its Offsets input names
group = modifier.node_group
if hasattr(group, "interface"):
    key = next(item.identifier for item in group.interface.items_tree if getattr(item, "name", "") == "Offsets")
else:
    key = group.inputs["Offsets"].identifier
inputs = getattr(getattr(modifier, "properties", None), "inputs", None)  # Blender 5.2+: RNA, not custom properties
holder = (getattr(inputs, key).value if inputs is not None else modifier[key]).data
offsets = array('f', bytes(12 * len(holder.vertices)))
holder.vertices.foreach_get("co", offsets)
result = {{"addon_registered": hasattr(bpy.types.Object, "lvp"), "largest_offset": max(map(abs, offsets))}}
for frame in {frames!r}:
    bpy.context.scene.frame_set(frame)
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    positions = array('f', bytes(12 * len(evaluated.vertices)))
    evaluated.vertices.foreach_get("co", positions)
    result["frame%d" % frame] = list(positions)
with open({out!r}, "w") as file:
    json.dump(result, file)
"""


def alpha_of(path):
    image = bpy.data.images.load(path, check_existing=False)
    try:
        pixels = array('f', bytes(4 * len(image.pixels)))
        image.pixels.foreach_get(pixels)
        return pixels[3::4], tuple(image.size)
    finally:
        bpy.data.images.remove(image)


def count_differences(a, b):
    return sum(1 for x, y in zip(a, b) if abs(x - y) > 0.5)


class FileTestCase(helpers.AddonTestCase):

    def setUp(self):
        super().setUp()
        self.directory = helpers.fresh_directory("files")
        self.obj, self.rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(self.rig, {1: 0.0, 10: 90.0})
        bpy.context.scene.frame_set(1)
        self.assertEqual(helpers.add_volume_preservation(self.obj), {'FINISHED'})

    def save(self, name):
        path = os.path.join(self.directory, name)
        bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
        return path

    def run_child(self, arguments, what, with_addon=True):
        completed = helpers.run_blender(arguments, with_addon=with_addon)
        if completed.returncode != 0:
            self.fail("%s: the second Blender failed (exit %d):\n%s" % (what, completed.returncode,
                                                                       completed.stdout[-4000:]))
        return completed

    def dump_in_child(self, path, template, stem, frames, what, with_addon=True):
        """Opens path in a second Blender that runs template (CHILD_DUMP...) for self.obj at frames;
        returns what it dumped."""
        out = os.path.join(self.directory, stem + ".json")
        script = os.path.join(self.directory, "dump_" + stem + ".py")
        with open(script, "w") as file:
            file.write(template.format(here=helpers.HERE, out=out, name=self.obj.name, frames=frames))
        self.run_child([path, "--python", script], what, with_addon=with_addon)
        with open(out) as file:
            return json.load(file)


class TestSaveAndReopen(FileTestCase):

    def test_reopen_in_a_fresh_blender(self):
        scene = bpy.context.scene
        expected = {}
        for frame in (10, 4):
            scene.frame_set(frame)
            expected[frame] = helpers.evaluated_positions(self.obj)
        scene.frame_set(7)
        at_save = helpers.evaluated_positions(self.obj)
        path = self.save("saved.blend")
        result = self.dump_in_child(path, CHILD_DUMP, "reopened", [10, 4], "reopen")
        self.assertTrue(result["bound"], "the binding was not rebuilt after opening the file")
        self.assertSmallerThan(helpers.max_distance(array('f', result["opened"]), at_save), 1e-5,
                               "as saved, right after opening")
        for frame in (10, 4):
            self.assertSmallerThan(helpers.max_distance(array('f', result["frame%d" % frame]), expected[frame]),
                                   1e-5, "frame %d in the fresh Blender" % frame)
            self.assertEqual(result["frame%d_status" % frame][0], 'INFO', result["frame%d_status" % frame])

    def test_file_bound_by_the_old_rule_is_bound_again(self):
        # A file saved by a version whose correction followed the bones' tails (its record has no rule, 0):
        # opened, it is bound by today's rule, shows what a fresh bind shows, and the panel says why.
        scene = bpy.context.scene
        scene.frame_set(10)
        expected = helpers.evaluated_positions(self.obj)
        self.obj.lvp.bind_rule = 0
        path = self.save("old_rule.blend")
        result = self.dump_in_child(path, CHILD_DUMP, "old_rule", [10], "reopen a file of the old rule")
        self.assertTrue(result["bound"], "the binding was not rebuilt after opening the file")
        self.assertSmallerThan(helpers.max_distance(array('f', result["frame10"]), expected), 1e-5,
                               "frame 10 as a fresh bind shows it")
        level, message = result["frame10_status"][:2]
        self.assertEqual(level, 'INFO', message)
        self.assertIn("bound again by itself: this file was bound by an earlier version", message)
        self.assertIn("press Bind", message)

    def test_saved_file_carries_no_correction(self):
        # Opened where the add-on does not run (a farm machine without it), the file must show plain
        # skinning at every frame, not the correction of the frame it was saved at on other poses.
        scene = bpy.context.scene
        plain = {}
        for frame in (4, 10):
            scene.frame_set(frame)
            plain[frame] = helpers.uncorrected_positions(self.obj)
        shown = helpers.evaluated_positions(self.obj)
        offsets = helpers.offsets_of(self.obj)
        self.assertGreater(helpers.max_abs(offsets), 0.01, "frame 10 is bent: it needs a correction")
        path = self.save("without_addon.blend")
        # This session goes on showing and holding its correction.
        self.assertEqual(helpers.offsets_of(self.obj), offsets, "the offsets were not put back after saving")
        self.assertEqual(helpers.evaluated_positions(self.obj), shown, "saving changed what is shown")
        scene.frame_set(9)
        scene.frame_set(10)
        self.assertEqual(helpers.evaluated_positions(self.obj), shown, "the next frames are corrected as before")

        result = self.dump_in_child(path, CHILD_DUMP_WITHOUT_ADDON, "without_addon", [10, 4],
                                    "open without the add-on", with_addon=False)
        self.assertFalse(result["addon_registered"], "the second Blender was meant to run without the add-on")
        self.assertEqual(result["largest_offset"], 0.0, "the saved file holds a correction")
        for frame in (10, 4):
            self.assertSmallerThan(helpers.max_distance(array('f', result["frame%d" % frame]), plain[frame]), 1e-6,
                                   "frame %d without the add-on is plain skinning" % frame)

    def test_topology_changed_before_saving_needs_rebind(self):
        import bmesh
        mesh = self.obj.data
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bm.edges.ensure_lookup_table()
        bmesh.ops.subdivide_edges(bm, edges=[bm.edges[10]], cuts=2)
        bm.to_mesh(mesh)
        bm.free()
        mesh.update()
        bpy.context.scene.frame_set(10)
        plain = helpers.uncorrected_positions(self.obj)
        path = self.save("changed.blend")
        result = self.dump_in_child(path, CHILD_DUMP, "changed", [10], "reopen after a topology change")
        self.assertIn("rebind needed", result["frame10_status"][1].lower())
        self.assertSmallerThan(helpers.max_distance(array('f', result["frame10"]), plain), 1e-6,
                               "passes the mesh through")


class TestFilesOfVersionOne(FileTestCase):
    """Files whose node group reads the offsets from an attribute of the character's own mesh (another
    layout of the group): opening one gives the modifier the current node group and an offsets
    object, with no user action."""

    @staticmethod
    def version_one_node_group():
        """The node group of version 1, as it built it: the offsets from the mesh's "lvp_offset"."""
        group = bpy.data.node_groups.new("Volume Preservation", 'GeometryNodeTree')
        if hasattr(group, "interface"):
            group.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
            group.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
        else:
            group.inputs.new('NodeSocketGeometry', "Geometry")
            group.outputs.new('NodeSocketGeometry', "Geometry")
        nodes, links = group.nodes, group.links
        group_input, group_output = nodes.new('NodeGroupInput'), nodes.new('NodeGroupOutput')
        stores = []
        for name, data_type, field in (("lvp_position", 'FLOAT_VECTOR', 'GeometryNodeInputPosition'),
                                       ("lvp_index", 'INT', 'GeometryNodeInputIndex')):
            store = nodes.new('GeometryNodeStoreNamedAttribute')
            store.data_type = data_type
            store.domain = 'POINT'
            store.inputs["Name"].default_value = name
            value = next(socket for socket in store.inputs if socket.name == "Value" and socket.enabled)
            links.new(nodes.new(field).outputs[0], value)
            stores.append(store)
        offset = nodes.new('GeometryNodeInputNamedAttribute')
        offset.data_type = 'FLOAT_VECTOR'
        offset.inputs["Name"].default_value = "lvp_offset"
        set_position = nodes.new('GeometryNodeSetPosition')
        links.new(group_input.outputs[0], stores[0].inputs[0])
        links.new(stores[0].outputs[0], stores[1].inputs[0])
        links.new(stores[1].outputs[0], set_position.inputs["Geometry"])
        links.new(next(socket for socket in offset.outputs if socket.name == "Attribute" and socket.enabled),
                  set_position.inputs["Offset"])
        links.new(set_position.outputs[0], group_output.inputs[0])
        group["lvp_node_group_version"] = 1
        return group

    def test_opened_and_corrected(self):
        modifier = self.addon.node_group.find_modifier(self.obj)
        holder_name = helpers.offsets_object(self.obj).name
        # The file is made with this add-on's handlers off, which would bring the group up to date at
        # once (bpy.ops.wm.save_as_mainfile updates the view layer first).
        self.addon.handlers.unregister()
        try:
            old_group = self.version_one_node_group()
            modifier.node_group = old_group
            self.obj.data.attributes.new("lvp_offset", 'FLOAT_VECTOR', 'POINT')
            self.addon.offsets.delete_if_unused(bpy.data.objects[holder_name])
            self.assertIsNone(bpy.data.objects.get(holder_name))
            path = self.save("version_one.blend")
            self.assertEqual(modifier.node_group, old_group)
        finally:
            self.addon.handlers.register()
        name = self.obj.name
        bpy.ops.wm.open_mainfile(filepath=path)
        self.obj = bpy.data.objects[name]
        modifier = self.addon.node_group.find_modifier(self.obj)
        self.assertTrue(self.addon.node_group.is_current(modifier.node_group))
        self.assertEqual([group.name for group in bpy.data.node_groups if group.get("lvp_node_group_version") == 1],
                         [], "the version 1 group is replaced")
        bpy.context.scene.frame_set(10)
        self.assertStatusContains(self.obj, "Correcting")
        self.assertIsNotNone(helpers.offsets_object(self.obj))
        corrected, plain = helpers.volume_errors(self.obj)
        self.assertGreater(plain, 0.05)
        self.assertSmallerThan(corrected, 0.1 * plain, "corrected after opening (plain %g)" % plain)


class TestRender(FileTestCase):
    """Renders from a background Blender show the corrected shape."""

    resolution = 120

    def setup_render(self):
        scene = bpy.context.scene
        scene.render.engine = 'CYCLES'
        scene.cycles.samples = 1
        if hasattr(scene.cycles, "use_denoising"):
            scene.cycles.use_denoising = False
        if hasattr(scene.cycles, "use_adaptive_sampling"):
            scene.cycles.use_adaptive_sampling = False
        scene.cycles.pixel_filter_type = 'BOX'
        scene.cycles.filter_width = 0.01
        scene.cycles.device = 'CPU'
        scene.render.film_transparent = True
        scene.render.resolution_x = self.resolution
        scene.render.resolution_y = self.resolution
        scene.render.resolution_percentage = 100
        scene.render.image_settings.file_format = 'PNG'
        scene.render.image_settings.color_mode = 'RGBA'
        scene.render.use_file_extension = True
        scene.render.threads_mode = 'FIXED'
        scene.render.threads = 2
        camera_data = bpy.data.cameras.new("Camera")
        camera_data.type = 'ORTHO'
        camera_data.ortho_scale = 3.0
        camera = helpers.link(bpy.data.objects.new("Camera", camera_data))
        # Looking along -X at the joint (z = 2): the bend about X shows in the silhouette.
        camera.location = (10.0, -0.2, 1.9)
        camera.rotation_euler = Euler((math.pi / 2, 0.0, math.pi / 2))
        scene.camera = camera
        scene.frame_start = 9
        scene.frame_end = 10

    def render(self, path, frame_arguments, name):
        output = os.path.join(self.directory, name + "_")
        self.run_child([path, "-o", output, "-F", "PNG"] + frame_arguments, "render %s" % name)
        return output + "0010.png"

    def static_copy(self):
        """Replaces the character by a static mesh of what this process evaluates at frame 10."""
        bpy.context.scene.frame_set(10)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        obj_eval = self.obj.evaluated_get(depsgraph)
        mesh = bpy.data.meshes.new_from_object(obj_eval)
        static = helpers.link(bpy.data.objects.new("Static", mesh))
        static.matrix_world = self.obj.matrix_world.copy()
        self.obj.hide_render = True
        return static

    def check_renders(self, subdivision):
        self.setup_render()
        if subdivision:
            modifier = self.obj.modifiers.new("Subdivision", 'SUBSURF')
            modifier.levels = 2
            modifier.render_levels = 2
        ours = self.addon.node_group.find_modifier(self.obj)
        # Saved at frame 1, so the offsets stored in the file are those of the rest pose: only the
        # handlers running inside the render can produce frame 10's correction.
        bpy.context.scene.frame_set(1)
        if subdivision:
            self.obj.modifiers["Subdivision"].levels = 0  # the viewport differs from the render
        live = self.save("live.blend")
        ours.show_render = False
        plain = self.save("plain.blend")
        ours.show_render = True
        if subdivision:
            self.obj.modifiers["Subdivision"].levels = 2
        static = self.static_copy()
        reference = self.save("reference.blend")
        bpy.data.objects.remove(static)

        live_alpha, size = alpha_of(self.render(live, ["-a"], "live"))
        self.assertEqual(size, (self.resolution, self.resolution))
        reference_alpha, _size = alpha_of(self.render(reference, ["-a"], "reference"))
        plain_alpha, _size = alpha_of(self.render(plain, ["-a"], "plain"))
        single_alpha, _size = alpha_of(self.render(live, ["-f", "10"], "single"))
        bulge = count_differences(reference_alpha, plain_alpha)
        print("\n    silhouette pixels changed by the correction: %d; -a render vs corrected: %d; -f: %d"
              % (bulge, count_differences(live_alpha, reference_alpha),
                 count_differences(single_alpha, reference_alpha)))
        self.assertGreater(bulge, 20, "the correction should change the silhouette (pixels)")
        self.assertLessEqual(count_differences(live_alpha, reference_alpha), 2,
                             "-a render vs the corrected shape (%d pixels differ from plain)" % bulge)
        self.assertLessEqual(count_differences(single_alpha, reference_alpha), 2,
                             "-f render vs the corrected shape")

    def test_motion_blur_steps_are_corrected(self):
        """Cycles' motion blur evaluates the scene again at the ends of the shutter (a frame and a
        subframe, in the render's depsgraph) and blurs between what it finds: each of those
        evaluations must carry the correction of its own pose, not the frame's."""
        self.setup_render()
        scene = bpy.context.scene
        scene.render.resolution_x = scene.render.resolution_y = 16
        scene.render.use_motion_blur = True
        scene.frame_set(5)
        seen = []

        def record(_scene, depsgraph=None):  # runs after the add-on's frame_change_post
            if depsgraph is not None and depsgraph.mode == 'RENDER':
                evaluated = depsgraph.scene_eval
                seen.append((evaluated.frame_current, evaluated.frame_subframe, helpers.offsets_of(self.obj)))

        bpy.app.handlers.frame_change_post.append(record)
        try:
            bpy.ops.render.render()
        finally:
            bpy.app.handlers.frame_change_post.remove(record)
        times = sorted({frame + subframe for frame, subframe, _offsets in seen})
        self.assertGreaterEqual(len(times), 3, "motion steps evaluated: %s" % times)
        self.assertLess(times[0], 5.0)
        self.assertGreater(times[-1], 5.0)
        centre = next(offsets for frame, subframe, offsets in seen if frame + subframe == 5.0)
        for frame, subframe, offsets in seen:
            scene.frame_set(frame, subframe=subframe)
            expected = helpers.offsets_of(self.obj)
            self.assertGreater(helpers.max_abs(expected), 1e-3, "a bent pose is corrected")
            self.assertLess(helpers.max_distance(offsets, expected), 1e-6,
                            "the render's correction at frame %d + %g is the viewport's" % (frame, subframe))
            if frame + subframe != 5.0:
                self.assertGreater(helpers.max_distance(offsets, centre), 1e-4,
                                   "frame %d + %g is corrected for its own pose, not frame 5's" % (frame, subframe))

    def test_render_animation_shows_corrected_shape(self):
        self.check_renders(subdivision=False)

    def test_render_with_subdivision_after(self):
        self.check_renders(subdivision=True)


if __name__ == "__main__":
    unittest.main()
