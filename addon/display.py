# SPDX-License-Identifier: GPL-3.0-or-later
"""Viewport display of the segmentation (paper Fig. 1b) and of the correction map (paper Fig. 8).

Both are colour attributes on the original mesh (point domain, float colour), made the active colour
attribute, and shown by Solid shading with Color: Attribute. Turning the display off removes them
and makes the previously active colour attribute active again, so the mesh is left as it was.
"""

import colorsys

import bpy

from . import bindings
from . import blender_api
from . import mesh_data
from . import names
from . import skeleton
from .session import SESSION

NO_REGION_COLOR = (0.5, 0.5, 0.5, 1.0)


def region_color(region, core_skeleton):
    """A distinct, stable colour per bone (golden-ratio hues). The joints of a B-Bone, one region
    each, share their bone's colour, every other one darker, so that its segments show as bands."""
    if region < 0:
        return NO_REGION_COLOR
    bone = core_skeleton.bone_index(region)
    if bone < 0:  # the still bone: what the Armature modifier does not move
        return NO_REGION_COLOR
    joint = core_skeleton.bones[region][1]
    value = 0.6 if joint != skeleton.PLAIN and joint % 2 == 1 else 0.95
    hue = (bone * 0.618033988749895) % 1.0
    saturation = 0.55 + 0.35 * ((bone * 7) % 3) / 2.0
    red, green, blue = colorsys.hsv_to_rgb(hue, saturation, value)
    return (red, green, blue, 1.0)


def heat_color(value):
    """Blue (0, rigid) -> cyan -> green -> yellow -> red (1, moves most), like the paper's Fig. 8."""
    value = min(max(value, 0.0), 1.0)
    stops = ((0.0, (0.05, 0.1, 0.8)), (0.25, (0.0, 0.7, 0.9)), (0.5, (0.1, 0.8, 0.2)),
             (0.75, (0.95, 0.85, 0.1)), (1.0, (0.9, 0.1, 0.05)))
    for (start, low), (end, high) in zip(stops, stops[1:]):
        if value <= end:
            t = (value - start) / (end - start)
            return tuple(low[i] + t * (high[i] - low[i]) for i in range(3)) + (1.0,)
    return stops[-1][1] + (1.0,)


def remove_display_attributes(obj):
    """Removes the display attributes and restores the previously active colour attribute."""
    mesh = obj.data
    if mesh_data.is_linked(mesh):
        return
    removed = False
    for name in (names.SEGMENTATION_ATTRIBUTE, names.CORRECTION_MAP_ATTRIBUTE):
        attribute = mesh.attributes.get(name)
        if attribute is not None:
            mesh.attributes.remove(attribute)
            removed = True
    previous = obj.lvp.previous_color_attribute
    if removed and previous:
        blender_api.set_active_color(mesh, previous)
    obj.lvp.previous_color_attribute = ""
    return removed


def _write_colors(mesh, name, colors):
    attribute = mesh.attributes.get(name)
    if attribute is not None and (attribute.domain != 'POINT' or attribute.data_type != 'FLOAT_COLOR'):
        mesh.attributes.remove(attribute)
        attribute = None
    if attribute is None:
        attribute = mesh.attributes.new(name, 'FLOAT_COLOR', 'POINT')
    attribute.data.foreach_set("color", colors)
    return attribute


def _show_attribute_colors(context):
    """Solid shading with Color: Attribute in the 3D views of the current screen."""
    screen = getattr(context, "screen", None) if context is not None else None
    if screen is None:
        return
    for area in screen.areas:
        if area.type == 'VIEW_3D':
            for space in area.spaces:
                if space.type == 'VIEW_3D' and space.shading.type == 'SOLID':
                    space.shading.color_type = 'VERTEX'
            area.tag_redraw()


def update_display(obj, context=None):
    """Makes the mesh's display attributes match obj.lvp.display. Returns an error message or None."""
    settings = obj.lvp
    mesh = obj.data
    if settings.display == 'NONE' or obj.type != 'MESH':
        remove_display_attributes(obj)
        SESSION.changes.expect_own_update(obj)
        mesh.update_tag()
        return None
    if mesh_data.is_linked(mesh):
        return ("The mesh %r comes from a library, and the display's colours are written into the mesh, which "
                "Blender does not let add-ons change here (the correction itself works): show them in the "
                "library's file" % mesh.name)
    bound = bindings.ensure(obj)
    if bound is None:
        return "Bind first: the display shows the binding's segmentation and correction map"
    vertex_count = bound.vertex_count
    if len(mesh.vertices) != vertex_count:
        return "Rebind needed: the mesh topology changed since the bind"
    colors = mesh_data.float_array(4 * vertex_count)
    if settings.display == 'SEGMENTATION':
        regions = mesh_data.int_array(vertex_count)
        bound.binding.segmentation(out_vertex_regions=regions)
        palette = {}
        for vertex, region in enumerate(regions):
            color = palette.get(region)
            if color is None:
                color = palette[region] = region_color(region, bound.skeleton)
            colors[4 * vertex:4 * vertex + 4] = mesh_data.array('f', color)
        shown, hidden = names.SEGMENTATION_ATTRIBUTE, names.CORRECTION_MAP_ATTRIBUTE
    else:
        values = mesh_data.float_array(vertex_count)
        bound.binding.correction_map(values)
        for vertex, value in enumerate(values):
            colors[4 * vertex:4 * vertex + 4] = mesh_data.array('f', heat_color(value))
        shown, hidden = names.CORRECTION_MAP_ATTRIBUTE, names.SEGMENTATION_ATTRIBUTE
    if not settings.previous_color_attribute:
        active = blender_api.active_color_name(mesh)
        if active not in (names.SEGMENTATION_ATTRIBUTE, names.CORRECTION_MAP_ATTRIBUTE):
            settings.previous_color_attribute = active
    other = mesh.attributes.get(hidden)
    if other is not None:
        mesh.attributes.remove(other)
    _write_colors(mesh, shown, colors)
    blender_api.set_active_color(mesh, shown)
    SESSION.changes.expect_own_update(obj)  # colours, not weights or positions
    mesh.update_tag()
    _show_attribute_colors(context if context is not None else bpy.context)
    return None
