# SPDX-License-Identifier: GPL-3.0-or-later
"""The Volume Preservation panel, in Properties > Modifiers, below the modifier stack: where an
artist looks for a modifier's settings."""

import bpy

from . import bindings
from . import handlers
from . import node_group

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


class LVP_PT_volume_preservation(bpy.types.Panel):
    """Local Volume Preservation: settings, bind and remove, live statistics and colour display"""

    bl_label = "Volume Preservation"
    bl_idname = "LVP_PT_volume_preservation"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "modifier"

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
            layout.label(text="Keeps the volume of a skinned mesh at bending joints")
            layout.operator("object.lvp_add", icon='MOD_ARMATURE')
            layout.operator("object.lvp_auto_weights", icon='GROUP_VERTEX')
            return

        row = layout.row(align=True)
        row.operator("object.lvp_bind", icon='FILE_REFRESH')
        row.operator("object.lvp_remove", text="Remove", icon='X')

        column = layout.column()
        column.use_property_split = True
        column.prop(settings, "effect")
        if settings.effect == 'PAINTED':
            column.prop_search(settings, "painted_vertex_group", obj, "vertex_groups")
        # The painted map is taken as painted: alpha and beta stay visible, greyed, as Blender shows
        # settings that the current choice ignores.
        shaping = column.column()
        shaping.active = settings.effect != 'PAINTED'
        shaping.prop(settings, "alpha")
        if settings.effect != 'RUBBER':
            shaping.prop(settings, "beta")
        column.prop(settings, "iterations")
        column.prop(settings, "tolerance")
        sub = column.row()
        sub.active = settings.effect != 'GLOBAL'
        sub.prop(settings, "fold_over")
        column.prop(settings, "display")

        box = layout.box()
        box.label(text="Region Restrictions (distance measured from chosen bones)")
        row = box.row()
        row.template_list("LVP_UL_region_restrictions", "", settings, "region_restrictions", settings,
                          "active_region_restriction", rows=2)
        buttons = row.column(align=True)
        buttons.operator("object.lvp_region_restriction_add", icon='ADD', text="")
        buttons.operator("object.lvp_region_restriction_remove", icon='REMOVE', text="")

        self.draw_statistics(layout, context, obj)
        # The scene's frame range into //lvp_cache/<object>.pc2, with a progress bar (Esc keeps what is baked).
        layout.operator("object.lvp_bake", text="Bake to PC2", icon='FILE_CACHE')

        render = context.scene.render
        if not render.use_lock_interface or handlers.render_without_lock:
            box = layout.box()
            box.label(text="F12 renders need Render > Lock Interface", icon='ERROR')
            box.prop(render, "use_lock_interface")
        layout.operator("object.lvp_auto_weights", icon='GROUP_VERTEX')

    def draw_statistics(self, layout, context, obj):
        box = layout.box()
        status = bindings.status(obj)
        if status is not None:
            level, message = status
            box.label(text=message, icon=STATUS_ICONS.get(level, 'INFO'))
        bound = bindings.entry(obj)
        stats = bound.stats if bound is not None else None
        if not stats or (status is not None and status[0] == 'ERROR'):
            return
        rest = stats["volume_rest"]
        if rest != 0.0:
            column = box.column(align=True)
            column.label(text="Volume change: %s before, %s after correction"
                              % (_percent((stats["volume_before"] - rest) / rest),
                                 _percent((stats["volume_after"] - rest) / rest)))
        worst = stats["worst_region"]
        if worst >= 0:
            name = "whole mesh" if stats.get("mode") == 'GLOBAL' else stats.get("worst_region_name", str(worst))
            box.label(text="Worst region %s: %s before, %s after"
                           % (name, _percent(stats["worst_region_change_before"]),
                              _percent(stats["worst_region_change_after"])))
        details = "%d regions corrected, %d passes" % (stats["active_regions"], stats["iterations"])
        if stats.get("folded_vertices"):
            details += ", %d vertices unfolded" % stats["folded_vertices"]
        box.label(text=details)


classes = (
    LVP_UL_region_restrictions,
    LVP_PT_volume_preservation,
)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
