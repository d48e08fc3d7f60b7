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
    they and the icons exist in this Blender. It also keeps the layout's tree, so that fitting()
    can lay it out at a given width as Blender does: a row shares its width between its items, a
    split gives its first item its factor of the width, a box insets its content, a property in a
    property split layout has its name in the first PROPERTY_SPLIT of the width."""

    def __init__(self, test, record=None, kind="column", factor=None, heading=""):
        self.test = test
        self.record = record if record is not None else {"labels": [], "props": [], "inactive": [], "operators": []}
        self.kind, self.factor, self.heading = kind, factor, heading
        self.children = []
        self.use_property_split = False
        self.use_property_decorate = True
        self.active = True
        self.enabled = True
        self.alert = False
        self.alignment = 'EXPAND'

    def _child(self, kind, factor=None, heading=""):
        child = RecordingLayout(self.test, self.record, kind, factor, heading)
        child.use_property_split = self.use_property_split
        child.active = self.active
        self.children.append(child)
        return child

    def row(self, align=False, heading="", **_keywords):
        return self._child("row", heading=heading)

    def column(self, align=False, heading="", **_keywords):
        return self._child("column", heading=heading)

    def box(self):
        return self._child("box")

    def split(self, factor=0.0, align=False):
        return self._child("split", factor=factor)

    def separator(self, **_keywords):
        pass

    def _leaf(self, kind, text, icon='NONE', **details):
        self.children.append(dict(details, kind=kind, text=text, icon=icon, split=self.use_property_split,
                                  heading=self.heading))

    def _check_icon(self, icon):
        self.test.assertIn(icon, ICONS, "no icon %r in this Blender" % icon)

    def label(self, text="", icon='NONE', **_keywords):
        self._check_icon(icon)
        self.record["labels"].append(text)
        self._leaf("label", text, icon)

    def _check_property(self, data, name):
        self.test.assertIn(name, data.bl_rna.properties.keys(), "%s has no property %r" % (data, name))
        self.record["props"].append(name)
        return data.bl_rna.properties[name]

    def prop(self, data, name, text=None, icon='NONE', **_keywords):
        self._check_icon(icon)
        rna = self._check_property(data, name)
        if not self.active:
            self.record["inactive"].append(name)  # drawn greyed out
        value = ""
        if rna.type == 'ENUM':
            value = next(item.name for item in rna.enum_items if item.identifier == getattr(data, name))
        self._leaf("prop", rna.name if text is None else text, icon, boolean=rna.type == 'BOOLEAN', value=value)

    def prop_search(self, data, name, search_data, search_name, text=None, **_keywords):
        rna = self._check_property(data, name)
        self.test.assertTrue(hasattr(search_data, search_name), search_name)
        self._leaf("prop", rna.name if text is None else text, boolean=False, value="")

    def operator(self, idname, text=None, icon='NONE', **_keywords):
        self._check_icon(icon)
        category, name = idname.split(".")
        self.test.assertIn(name, dir(getattr(bpy.ops, category)), idname)
        self.record["operators"].append(idname)
        label = getattr(bpy.ops, category).__getattr__(name).get_rna_type().name if text is None else text
        self._leaf("operator", label, icon)
        return types.SimpleNamespace()

    def template_list(self, list_type, list_id, data, name, active_data, active_name, **_keywords):
        self.test.assertTrue(hasattr(bpy.types, list_type), list_type)
        self._check_property(data, name)
        self._check_property(active_data, active_name)
        self._leaf("list", "")

    # ---- widths ----

    def fitting(self, width, scale):
        """[(text, needed, available)] for every text of the tree laid out at width pixels."""
        found = []
        self._fit(width, scale, found)
        return found

    def _fit(self, width, scale, found):
        if self.kind == "box":
            width -= self.test.addon.panel_text.BOX_MARGINS * scale
        if not self.children:
            return
        if self.kind == "row":
            widths = [width / len(self.children)] * len(self.children)
        elif self.kind == "split":
            first = width * self.factor
            rest = (width - first) / max(1, len(self.children) - 1)
            widths = [first] + [rest] * (len(self.children) - 1)
        else:
            widths = [width] * len(self.children)
        for child, child_width in zip(self.children, widths):
            if isinstance(child, RecordingLayout):
                child._fit(child_width, scale, found)
            else:
                found.extend(_leaf_fitting(child, child_width, scale, self.test.addon.panel_text))


def _needed(text, scale, pt, icon=False):
    needed = pt.text_width(text, scale) + pt.TEXT_MARGINS * scale
    return needed + (pt.ICON_WIDTH * scale if icon else 0.0)


def _leaf_fitting(leaf, width, scale, pt):
    """[(text, needed, available)] for one label, property or operator given width pixels."""
    text, icon = leaf["text"], leaf["icon"] != 'NONE'
    if leaf["kind"] in ("label", "operator"):
        return [(text, _needed(text, scale, pt, icon), width)] if text or icon else []
    if leaf["kind"] != "prop":
        return []
    if not leaf["split"]:
        if leaf["boolean"]:
            return [(text, _needed(text, scale, pt, True), width)]
        return [(text + ": " + leaf["value"], _needed(text + ": " + leaf["value"], scale, pt), width)]
    names = width * pt.PROPERTY_SPLIT
    values = width - names - pt.ICON_WIDTH * scale  # the decorator (keyframe dot) takes an icon's room
    if leaf["boolean"]:
        # The checkbox and its text in the values' column; the name column shows the heading, if any.
        result = [(text, _needed(text, scale, pt, True), values)]
        if leaf["heading"]:
            result.append((leaf["heading"], _needed(leaf["heading"], scale, pt), names))
        return result
    result = [(text, _needed(text, scale, pt), names)]
    if leaf["value"]:
        result.append((leaf["value"], _needed(leaf["value"], scale, pt, True), values))  # with the menu's arrow
    return result


class TestPanel(helpers.AddonTestCase):

    SUB_PANELS = ("LVP_PT_statistics", "LVP_PT_region_restrictions")

    def context(self, obj):
        """A context as the Properties editor of the factory layout gives the panel (panel_text.py)."""
        text = self.addon.panel_text
        return types.SimpleNamespace(
            object=obj, scene=bpy.context.scene, screen=None,
            region=types.SimpleNamespace(width=text.DEFAULT_REGION_WIDTH),
            preferences=types.SimpleNamespace(system=types.SimpleNamespace(ui_scale=text.DEFAULT_SCALE)))

    def draw(self, obj):
        """What the Volume Preservation panel and its open sub-panels draw for obj:
        {"labels", "props", "inactive", "operators"}. Every text must fit the default layout."""
        context = self.context(obj)
        panel_type = bpy.types.LVP_PT_volume_preservation
        self.assertTrue(panel_type.poll(context))
        record = None
        for name in ("LVP_PT_volume_preservation",) + self.SUB_PANELS:
            panel_type = getattr(bpy.types, name)
            if not panel_type.poll(context):
                continue
            layout = RecordingLayout(self, record)
            record = layout.record
            panel_type.draw(types.SimpleNamespace(layout=layout), context)
            self.assertFits(layout, boxed=name in self.SUB_PANELS)
        return record

    def assertFits(self, layout, boxed):
        """Every text of the layout fits the Properties editor of the factory layout: none is cut."""
        text = self.addon.panel_text
        scale = text.DEFAULT_SCALE
        width = text.DEFAULT_REGION_WIDTH - (text.PANEL_MARGINS + (text.BOX_MARGINS if boxed else 0.0)) * scale
        cut = ["%r needs %.0f px, has %.0f" % (label, needed, available)
               for label, needed, available in layout.fitting(width, scale) if needed > available]
        self.assertEqual(cut, [], "texts cut at the default width of the Properties editor")

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
        for name in ("effect", "alpha", "beta", "iterations", "tolerance", "smoothing", "fold_over", "keep_apart",
                     "keep_apart_paused_only", "keep_apart_render", "painted_vertex_group", "display"):
            self.assertIn(name, record["props"])
        self.assertEqual(record["inactive"], ["alpha", "beta"], "the painted map ignores alpha and beta")
        obj.lvp.effect = 'ORGANIC'
        bpy.context.scene.frame_set(9)
        bpy.context.scene.frame_set(10)
        record = self.draw(obj)
        self.assertEqual(record["inactive"], [])
        labels = record["labels"]
        for label in ("Before", "After", "Volume", "Worst Region", "Lower", "Corrected"):
            self.assertIn(label, labels)
        at = labels.index("Volume")
        before, after = (float(value.rstrip(" %")) for value in labels[at + 1:at + 3])
        self.assertLess(before, -5.0, "plain skinning loses about 11 % at 90 degrees")
        self.assertLess(abs(after), 0.1, "corrected")

    def test_production_names_fit(self):
        """A Rigify arm's bone names, Fold-Over Prevention unfolding vertices, the painted map and the
        F12 warning: every text fits the factory layout's Properties editor (draw() checks it)."""
        obj, rig = helpers.make_cylinder_character()
        for old, new in (("Lower", "DEF-upper_arm.L.001"), ("Upper", "DEF-forearm.L.001")):
            rig.data.bones[old].name = new  # renames the vertex groups too
        helpers.keyframe_bend(rig, {1: 0.0, 10: 120.0}, bone="DEF-forearm.L.001")
        helpers.add_volume_preservation(obj)
        obj.lvp.fold_over = True
        bpy.context.scene.frame_set(10)
        record = self.draw(obj)
        self.assertIn("DEF-upper_arm.L.001", record["labels"], "the worst region is named")
        self.assertTrue(any(label.endswith("vertices") for label in record["labels"]),
                        "at 120 degrees fold-over unfolds vertices: %s" % record["labels"])
        obj.lvp.effect = 'PAINTED'
        bpy.context.scene.render.use_lock_interface = False
        record = self.draw(obj)
        self.assertIn("painted_vertex_group", record["props"])
        self.assertIn("use_lock_interface", record["props"])

    def test_keeping_skin_apart_is_shown(self):
        """Bent to 120 degrees, the inside of the elbow nears itself: Keep Skin Apart holds those offsets back by
        fading them, before any pair would cross (nothing left to shorten), and the statistics count them all the
        same; without it the line is not drawn."""
        obj, rig = helpers.make_cylinder_character()
        helpers.keyframe_bend(rig, {1: 0.0, 10: 120.0})
        helpers.add_volume_preservation(obj)
        for keep_apart in (True, False):
            obj.lvp.keep_apart = keep_apart
            bpy.context.scene.frame_set(9)
            bpy.context.scene.frame_set(10)
            stats = self.addon.session.SESSION.bound(obj).stats
            labels = self.draw(obj)["labels"]
            if not keep_apart:
                self.assertNotIn("Kept Apart", labels)
                self.assertEqual(stats["kept_apart_vertices"], 0)
                continue
            self.assertIn("Kept Apart", labels)
            held_back = int(labels[labels.index("Kept Apart") + 1].split()[0])
            self.assertEqual(held_back, stats["kept_apart_vertices"])
            self.assertGreater(held_back, stats["shortened_vertices"], "the fade held skin back, not only the test")
            self.assertLess(held_back, len(obj.data.vertices) // 2, "only the inside of the bend")

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
