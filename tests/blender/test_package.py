# SPDX-License-Identifier: GPL-3.0-or-later
"""How the add-on is installed: on Blender 4.2+ the packaged zip, installed as an extension; on 3.4
the add-on folder with bl_info. Both register the same operators, properties, panel and handlers,
and unregister cleanly."""

import os
import unittest
import zipfile

import addon_utils
import bpy

import lvp_helpers as helpers

OPERATORS = ("lvp_add", "lvp_bind", "lvp_remove", "lvp_auto_weights")
HANDLER_NAMES = ("frame_change_post", "depsgraph_update_post", "load_post", "undo_post", "redo_post",
                 "render_init")


def our_handlers():
    found = []
    for name in HANDLER_NAMES:
        for function in getattr(bpy.app.handlers, name):
            if "local_volume_preservation" in getattr(function, "__module__", ""):
                found.append(name)
    return sorted(found)


class TestPackage(helpers.AddonTestCase):

    def test_installed_the_supported_way(self):
        module = self.addon
        module_file = os.path.realpath(module.__file__)
        self.assertTrue(os.path.isfile(os.path.join(os.path.dirname(module_file), "_lvp.abi3.so")))
        self.assertEqual(module._lvp.version, "0.1.0")
        if helpers.uses_extensions():
            self.assertEqual(module.__name__, "bl_ext.%s.local_volume_preservation" % helpers.EXTENSION_REPO)
            self.assertFalse(module_file.startswith(os.path.realpath(helpers.addon_dir())),
                             "on 4.2+ the add-on must come from the installed zip, not the folder")
            # This machine's zip of the five (build.sh names them as `extension build --split-platforms`
            # does): the Linux x86-64 module alone, and a manifest that declares that platform alone.
            self.assertTrue(helpers.extension_zip().endswith("-linux_x64.zip"), helpers.extension_zip())
            with zipfile.ZipFile(helpers.extension_zip()) as archive:
                names = archive.namelist()
            for required in ("blender_manifest.toml", "__init__.py", "_lvp.abi3.so"):
                self.assertIn(required, names)
            self.assertEqual([name for name in names if name.startswith("_lvp.")], ["_lvp.abi3.so"])
            installed_manifest = os.path.join(os.path.dirname(module_file), "blender_manifest.toml")
            self.assertTrue(os.path.isfile(installed_manifest))
            with open(installed_manifest, encoding="utf-8") as file:
                self.assertIn('platforms = ["linux-x64"]\n', file.read())
        else:
            self.assertEqual(module.__name__, "local_volume_preservation")
            self.assertEqual(os.path.dirname(module_file), os.path.realpath(helpers.addon_dir()))
            self.assertEqual(tuple(module.bl_info["blender"][:2]), (3, 4))
        self.assertIn(module.__name__, {addon.module for addon in bpy.context.preferences.addons})

    def test_registered(self):
        for name in OPERATORS:
            self.assertTrue(hasattr(bpy.types, "OBJECT_OT_" + name), name)
            self.assertIn(name, dir(bpy.ops.object))
        self.assertTrue(hasattr(bpy.types.Object, "lvp"))
        self.assertTrue(hasattr(bpy.types, "LVP_PT_volume_preservation"))
        self.assertEqual(bpy.types.LVP_PT_volume_preservation.bl_context, "modifier")
        self.assertEqual(our_handlers(), sorted(HANDLER_NAMES))
        settings = bpy.data.objects.new("Probe", bpy.data.meshes.new("Probe")).lvp
        self.assertEqual(settings.effect, 'ORGANIC')
        for effect in ('ORGANIC', 'RUBBER', 'PAINTED', 'GLOBAL'):
            settings.effect = effect
        for name in ("alpha", "beta", "iterations", "tolerance", "smoothing", "fold_over", "keep_apart",
                     "keep_apart_paused_only", "keep_apart_render", "painted_vertex_group", "region_restrictions"):
            self.assertTrue(hasattr(settings, name), name)

    def test_disable_and_enable_again(self):
        name = self.addon.__name__
        addon_utils.disable(name, default_set=True)
        try:
            self.assertFalse(hasattr(bpy.types.Object, "lvp"))
            self.assertEqual(our_handlers(), [])
            self.assertFalse(hasattr(bpy.types, "OBJECT_OT_lvp_add"))
        finally:
            addon_utils.enable(name, default_set=True)
        self.assertTrue(hasattr(bpy.types.Object, "lvp"))
        self.assertEqual(our_handlers(), sorted(HANDLER_NAMES))
        # And it still works.
        obj, rig = helpers.make_cylinder_character()
        helpers.bend(rig, 90.0)
        self.assertEqual(helpers.add_volume_preservation(obj), {'FINISHED'})
        bpy.context.view_layer.update()
        self.assertGreater(helpers.max_abs(helpers.offsets_of(obj)), 0.01)


if __name__ == "__main__":
    unittest.main()
