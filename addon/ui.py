# SPDX-License-Identifier: GPL-3.0-or-later
"""The Volume Preservation panel, in Properties > Modifiers, with the modifier stack: where an artist
looks for a modifier's settings. The settings are in the panel itself; what the correction did at
the current frame and the region restrictions are in sub-panels of it, so that the panel reads in
full at the default width of the Properties editor (panel_text.py)."""

import bpy

from . import node_group
from . import panel_text
from .session import SESSION

STATUS_ICONS = {'INFO': 'CHECKMARK', 'WARNING': 'ERROR', 'ERROR': 'CANCEL'}


def _percent(value):
    return "%+.2f %%" % (100.0 * value)


class LVP_UL_region_restrictions(bpy.types.UIList):
    """Region restrictions: a region and the bones its flesh is measured from."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0):
        armature = None
        modifier = node_group.find_armature_modifier(data.id_data)
        if modifier is not None and modifier.object is not None and modifier.object.type == 'ARMATURE':
            armature = modifier.object.data
        row = layout.row(align=True)
        if armature is not None:
            row.prop_search(item, "region", armature, "bones", text="")
        else:
            row.prop(item, "region", text="")
        row.prop(item, "bones", text="")


class _InModifierTab:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "modifier"


class LVP_PT_volume_preservation(_InModifierTab, bpy.types.Panel):
    """Local Volume Preservation: settings, bind and remove, baking"""

    bl_label = "Volume Preservation"
    bl_idname = "LVP_PT_volume_preservation"

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == 'MESH'

    def draw(self, context):
        layout = self.layout
        obj = context.object
        settings = obj.lvp
        modifier = node_group.find_modifier(obj)
        if modifier is None:
            panel_text.wrapped_label(layout, context, "Keeps the volume of a skinned mesh at bending joints")
            layout.operator("object.lvp_add", icon='MOD_ARMATURE')
            layout.operator("object.lvp_auto_weights", text="Auto Weights", icon='GROUP_VERTEX')
            return

        row = layout.row(align=True)
        row.operator("object.lvp_bind", icon='FILE_REFRESH')
        row.operator("object.lvp_remove", text="Remove", icon='X')

        column = layout.column()
        column.use_property_split = True
        column.prop(settings, "effect")
        if settings.effect == 'PAINTED':
            column.prop_search(settings, "painted_vertex_group", obj, "vertex_groups", text="Map")
        # The painted map is taken as painted: alpha and beta stay visible, greyed, as Blender shows
        # settings that the current choice ignores.
        shaping = column.column()
        shaping.active = settings.effect != 'PAINTED'
        shaping.prop(settings, "alpha")
        if settings.effect != 'RUBBER':
            shaping.prop(settings, "beta")
        # Not used where the Armature modifier's vertex group keeps skin still (bindings.bind).
        armature = node_group.find_armature_modifier(obj)
        bulge = column.column()
        bulge.active = settings.effect != 'GLOBAL' and not (armature is not None and armature.vertex_group)
        bulge.prop(settings, "bulge_width")
        smoothing = column.column()
        smoothing.active = settings.effect != 'GLOBAL'
        smoothing.prop(settings, "smoothing")
        restore = column.column()
        restore.active = settings.effect != 'GLOBAL'
        restore.prop(settings, "restore")
        column.prop(settings, "iterations")
        column.prop(settings, "tolerance")
        # A heading names the checkbox in the names' column, as Blender's own panels do.
        fold_over = column.column(heading="Fold-Over")
        fold_over.active = settings.effect != 'GLOBAL'
        fold_over.prop(settings, "fold_over", text="Prevent")
        # Viewport and Render, as Blender's own modifiers split what costs time (Subdivision's levels); the
        # viewport's only on a still frame where its cost would slow playback.
        keep_apart = column.column(heading="Keep Skin Apart")
        keep_apart.active = settings.effect != 'GLOBAL'
        keep_apart.prop(settings, "keep_apart", text="Viewport")
        paused_only = keep_apart.column()  # qualifies Viewport
        paused_only.active = keep_apart.active and settings.keep_apart
        paused_only.prop(settings, "keep_apart_paused_only", text="Only When Paused")
        keep_apart.prop(settings, "keep_apart_render", text="Render")
        column.prop(settings, "display")

        render = context.scene.render
        if not render.use_lock_interface or SESSION.render_without_lock:
            box = layout.box()
            panel_text.wrapped_label(box, context, "F12 renders show the correction only with Render > Lock "
                                                   "Interface", icon='ERROR', boxed=True)
            box.prop(render, "use_lock_interface")
        row = layout.row(align=True)
        # The scene's frame range into //lvp_cache/<object>.pc2, with a progress bar (Esc keeps what is baked).
        row.operator("object.lvp_bake", text="Bake to PC2", icon='FILE_CACHE')
        row.operator("object.lvp_auto_weights", text="Auto Weights", icon='GROUP_VERTEX')


class _SubPanel(_InModifierTab):
    """A sub-panel of the Volume Preservation panel, shown once the object has the modifier."""

    bl_parent_id = "LVP_PT_volume_preservation"

    @classmethod
    def poll(cls, context):
        obj = context.object
        return obj is not None and obj.type == 'MESH' and node_group.find_modifier(obj) is not None


class LVP_PT_statistics(_SubPanel, bpy.types.Panel):
    """What the correction did at the current frame"""

    bl_label = "Statistics"
    bl_idname = "LVP_PT_statistics"

    def draw(self, context):
        layout = self.layout
        obj = context.object
        status = SESSION.status(obj)
        if status is not None:
            level, message = status
            panel_text.wrapped_label(layout, context, message, icon=STATUS_ICONS.get(level, 'INFO'), boxed=True)
        bound = SESSION.bound(obj)
        stats = bound.stats if bound is not None else None
        if not stats or (status is not None and status[0] == 'ERROR'):
            return
        column = layout.column(align=True)
        _figures(column, "", "Before", "After")
        rest = stats["volume_rest"]
        if rest != 0.0:
            _figures(column, "Volume", _percent((stats["volume_before"] - rest) / rest),
                     _percent((stats["volume_after"] - rest) / rest))
        worst = stats["worst_region"]
        if worst >= 0:
            name = "Whole Mesh" if stats.get("mode") == 'GLOBAL' else stats.get("worst_region_name", str(worst))
            _figures(column, "Worst Region", name)
            _figures(column, "", _percent(stats["worst_region_change_before"]),
                     _percent(stats["worst_region_change_after"]))
        column.separator()
        _figures(column, "Corrected", "%d regions, %d passes" % (stats["active_regions"], stats["iterations"]))
        if stats.get("folded_vertices"):
            _figures(column, "Unfolded", "%d vertices" % stats["folded_vertices"])
        if stats.get("kept_apart_vertices"):
            # Keep Skin Apart held these offsets back where they neared other skin (faded, or shortened
            # where they would have pushed skin through skin).
            _figures(column, "Kept Apart", "%d vertices" % stats["kept_apart_vertices"])


def _figures(layout, name, *values):
    """One line of the statistics: a name in the names' column (right-aligned, as property names are),
    then the values side by side in the values' column."""
    split = layout.split(factor=panel_text.PROPERTY_SPLIT)
    names = split.row()
    names.alignment = 'RIGHT'
    names.label(text=name)
    row = split.row()
    for value in values:
        row.label(text=value)


class LVP_PT_region_restrictions(_SubPanel, bpy.types.Panel):
    """Regions whose flesh is measured from chosen bones only (paper Fig. 11: the belly from the spine)"""

    bl_label = "Region Restrictions"
    bl_idname = "LVP_PT_region_restrictions"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        settings = context.object.lvp
        panel_text.wrapped_label(layout, context, "Each region listed measures its flesh from the bones named "
                                                  "beside it (comma-separated)", boxed=True)
        row = layout.row()
        row.template_list("LVP_UL_region_restrictions", "", settings, "region_restrictions", settings,
                          "active_region_restriction", rows=2)
        buttons = row.column(align=True)
        buttons.operator("object.lvp_region_restriction_add", icon='ADD', text="")
        buttons.operator("object.lvp_region_restriction_remove", icon='REMOVE', text="")


classes = (
    LVP_UL_region_restrictions,
    LVP_PT_volume_preservation,
    LVP_PT_statistics,
    LVP_PT_region_restrictions,
)


register, unregister = bpy.utils.register_classes_factory(classes)
