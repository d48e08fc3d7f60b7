# SPDX-License-Identifier: GPL-3.0-or-later
"""The panel, drawn headless into a recording layout: it must draw in every state (no modifier,
bound and correcting, rebind needed) with existing properties and operators only, and show the live
statistics. Background Blender has no real UI layout, so the layout records what is asked of it."""

import types
import unittest

import bmesh
import bpy

import lvp_helpers as helpers


ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())


class RecordingLayout:
    """Stands in for bpy.types.UILayout: records labels, properties and operators, and checks that
    they and the icons exist in this Blender."""

    def __init__(self, test, record=None):
        self.test = test
        self.record = record if record is not None else {"labels": [], "props": [], "inactive": [], "operators": []}
        self.use_property_split = False
        self.active = True
        self.enabled = True
        self.alert = False

    def _child(self, *_arguments, **_keywords):
        return RecordingLayout(self.test, self.record)

    row = column = box = split = column_flow = _child

    def _check_icon(self, icon):
        self.test.assertIn(icon, ICONS, "no icon %r in this Blender" % icon)

    def label(self, text="", icon='NONE', **_keywords):
        self._check_icon(icon)
        self.record["labels"].append(text)

    def _check_property(self, data, name):
        self.test.assertIn(name, data.bl_rna.properties.keys(), "%s has no property %r" % (data, name))
        self.record["props"].append(name)

    def prop(self, data, name, icon='NONE', **_keywords):
        self._check_icon(icon)
        self._check_property(data, name)
        if not self.active:
            self.record["inactive"].append(name)  # drawn greyed out

    def prop_search(self, data, name, search_data, search_name, **_keywords):
        self._check_property(data, name)
        self.test.assertTrue(hasattr(search_data, search_name), search_name)

    def operator(self, idname, icon='NONE', **_keywords):
        self._check_icon(icon)
        category, name = idname.split(".")
        self.test.assertIn(name, dir(getattr(bpy.ops, category)), idname)
        self.record["operators"].append(idname)
        return types.SimpleNamespace()

    def template_list(self, list_type, list_id, data, name, active_data, active_name, **_keywords):
        self.test.assertTrue(hasattr(bpy.types, list_type), list_type)
        self._check_property(data, name)
        self._check_property(active_data, active_name)


class TestPanel(helpers.AddonTestCase):

    def draw(self, obj):
        """What the Volume Preservation panel draws for obj: {"labels", "props", "inactive", "operators"}."""
        panel_type = bpy.types.LVP_PT_volume_preservation
        context = types.SimpleNamespace(object=obj, scene=bpy.context.scene, screen=None)
        self.assertTrue(panel_type.poll(context))
        layout = RecordingLayout(self)
        panel = types.SimpleNamespace(layout=layout, draw_statistics=None)
        panel.draw_statistics = lambda *arguments: panel_type.draw_statistics(panel, *arguments)
        panel_type.draw(panel, context)
        return layout.record

    def test_without_modifier(self):
        obj, rig = helpers.make_cylinder_character()
        record = self.draw(obj)
        self.assertIn("object.lvp_add", record["operators"])

    def test_correcting_shows_statistics(self):
        obj, rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(rig, {1: 0.0, 10: 90.0})
        helpers.add_volume_preservation(obj)
        bpy.context.scene.frame_set(10)
        obj.lvp.effect = 'PAINTED'
        obj.lvp.region_restrictions.add()
        record = self.draw(obj)
        for idname in ("object.lvp_bind", "object.lvp_remove", "object.lvp_region_restriction_add", "object.lvp_bake"):
            self.assertIn(idname, record["operators"])
        for name in ("effect", "alpha", "beta", "iterations", "tolerance", "fold_over", "painted_vertex_group",
                     "display"):
            self.assertIn(name, record["props"])
        self.assertEqual(record["inactive"], ["alpha", "beta"], "the painted map ignores alpha and beta")
        obj.lvp.effect = 'ORGANIC'
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        record = self.draw(obj)
        self.assertEqual(record["inactive"], [])
        labels = "\n".join(record["labels"])
        self.assertIn("Volume change:", labels)
        self.assertIn("Worst region", labels)
        self.assertIn("before", labels)

    def test_rebind_needed_is_shown(self):
        obj, rig = helpers.make_cylinder_character()
        helpers.add_volume_preservation(obj)
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bm.verts.ensure_lookup_table()
        bmesh.ops.delete(bm, geom=[bm.verts[0]], context='VERTS')
        bm.to_mesh(obj.data)
        bm.free()
        obj.data.update()
        bpy.context.view_layer.update()
        labels = "\n".join(self.draw(obj)["labels"])
        self.assertIn("Rebind needed", labels)

    def test_lock_interface_warning(self):
        obj, rig = helpers.make_cylinder_character()
        helpers.add_volume_preservation(obj)
        bpy.context.scene.render.use_lock_interface = False
        record = self.draw(obj)
        self.assertIn("use_lock_interface", record["props"])
        bpy.context.scene.render.use_lock_interface = True
        record = self.draw(obj)
        self.assertNotIn("use_lock_interface", record["props"])


if __name__ == "__main__":
    unittest.main()
