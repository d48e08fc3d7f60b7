"""Sets up the Blender window that tests/blender/panel_screenshot.sh takes a screenshot of, with the
Volume Preservation panel open, as an artist sees it: the factory layout, the paper's cylinder bent
90 degrees and corrected, the Properties editor on its Modifiers tab. Run in a real Blender window
(under Xvfb), never headless:

    blender --factory-startup -noaudio --python tests/blender/panel_screenshot.py -- READY DONE

Writes the file READY once the window shows the panel, then waits for the file DONE (the
screenshot is taken from outside: X's own copy of the screen, which Blender's screenshot operator
cannot read on every OpenGL driver) and quits. It prints the Properties editor's width, which
test_panel.py's check of the texts' widths takes as the default layout's.
"""

import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import lvp_helpers as helpers  # noqa: E402

ARGUMENTS = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
READY, DONE = ARGUMENTS[0], ARGUMENTS[1]


def set_up_scene():
    """The cylinder with a Rigify arm's bone names, bent 120 degrees, Fold-Over Prevention on: the
    longest texts the statistics show."""
    helpers.enable_addon()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    obj, rig = helpers.make_cylinder_character()
    for old, new in (("Lower", "DEF-upper_arm.L.001"), ("Upper", "DEF-forearm.L.001")):
        rig.data.bones[old].name = new
    helpers.keyframe_bend(rig, {1: 0.0, 10: 120.0}, bone="DEF-forearm.L.001")
    bpy.context.scene.frame_set(1)
    helpers.select_only(obj)
    bpy.context.view_layer.objects.active = obj
    result = helpers.add_volume_preservation(obj)
    if result != {'FINISHED'}:
        raise RuntimeError("Add Volume Preservation: %r" % (result,))
    obj.lvp.fold_over = True
    obj.lvp.region_restrictions.add().region = "DEF-forearm.L.001"


def show_modifiers_tab(window):
    for area in window.screen.areas:
        if area.type == 'PROPERTIES':
            area.spaces.active.context = 'MODIFIER'
            for region in area.regions:
                if region.type == 'WINDOW':
                    print("PROPERTIES EDITOR: area %d px wide, its window region %d px, UI scale %.3f"
                          % (area.width, region.width, bpy.context.preferences.system.ui_scale))
            area.tag_redraw()


def step(state={"n": 0}):
    window = bpy.context.window_manager.windows[0]
    state["n"] += 1
    if state["n"] == 1:
        with bpy.context.temp_override(window=window):
            set_up_scene()
            # Opening a file closes the splash screen, which would cover the window.
            path = os.path.join(helpers.test_tmp(), "panel_screenshot.blend")
            bpy.ops.wm.save_as_mainfile(filepath=path)
            bpy.ops.wm.open_mainfile(filepath=path)
        return 1.0
    if state["n"] == 2:
        window = bpy.context.window_manager.windows[0]
        with bpy.context.temp_override(window=window):
            bpy.context.scene.frame_set(10)
            show_modifiers_tab(window)
        return 1.0
    if state["n"] == 3:
        with open(READY, "w") as ready:
            ready.write("ready\n")
        return 0.5
    if not os.path.exists(DONE):
        return 0.5
    bpy.ops.wm.quit_blender()
    return None


bpy.app.timers.register(step, first_interval=1.0, persistent=True)  # survives the file load
