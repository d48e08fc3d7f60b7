# SPDX-License-Identifier: GPL-3.0-or-later
"""A line plot drawn in Blender: curves for the lines and text objects for the labels, seen by an
orthographic camera from above and rendered by Cycles with emission-only materials on a white
background (Standard view transform, so the colours come out as given)."""

import math

import bpy

import demo_render as render

BLACK = (0.0, 0.0, 0.0, 1.0)
GRID = (0.82, 0.82, 0.82, 1.0)

# Plot area in scene units: x from 0 to WIDTH, y from 0 to HEIGHT; margins around it for labels.
WIDTH, HEIGHT = 10.0, 6.0
LEFT, RIGHT, BOTTOM, TOP = 1.9, 0.5, 1.35, 0.95


def _material(color):
    name = "Plot_%02x%02x%02x" % tuple(int(255 * channel) for channel in color[:3])
    material = bpy.data.materials.get(name)
    if material is None:
        material = render._emission_material(name, color)
    return material


def _link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def polyline(points, color, width, z=0.0, name="PlotLine"):
    curve = bpy.data.curves.new(name, 'CURVE')
    curve.dimensions = '3D'
    curve.bevel_depth = 0.5 * width
    curve.bevel_resolution = 2
    spline = curve.splines.new('POLY')
    spline.points.add(len(points) - 1)
    for point, (x, y) in zip(spline.points, points):
        point.co = (x, y, z, 1.0)
    obj = _link(bpy.data.objects.new(name, curve))
    obj.data.materials.append(_material(color))
    return obj


def marker(x, y, color, size, z=0.2, name="PlotMarker"):
    """A filled square marker."""
    half = 0.5 * size
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x - half, y - half, z), (x + half, y - half, z), (x + half, y + half, z),
                      (x - half, y + half, z)], [], [(0, 1, 2, 3)])
    obj = _link(bpy.data.objects.new(name, mesh))
    obj.data.materials.append(_material(color))
    return obj


def text(body, x, y, size, align_x='CENTER', align_y='CENTER', color=BLACK, rotation=0.0, z=0.3):
    curve = bpy.data.curves.new("PlotText", 'FONT')
    curve.body = body
    curve.size = size
    curve.align_x = align_x
    curve.align_y = align_y
    obj = _link(bpy.data.objects.new("PlotText", curve))
    obj.location = (x, y, z)
    obj.rotation_euler = (0.0, 0.0, rotation)
    obj.data.materials.append(_material(color))
    return obj


def nice_step(span, target_ticks=6):
    raw = span / target_ticks
    magnitude = 10 ** math.floor(math.log10(raw))
    for factor in (1, 2, 2.5, 5, 10):
        if raw <= factor * magnitude:
            return factor * magnitude
    return 10 * magnitude


def line_plot(path, title, x_label, y_label, x_values, series, markers=(), x_ticks=None,
              pixel_width=960, samples=16):
    """Renders a plot into `path` (PNG). series: [(label, colour, [y per x])]; markers: [(label, colour,
    [(x, y), ...])], drawn as squares. The current scene is used: call on an empty scene."""
    x_min, x_max = min(x_values), max(x_values)
    all_y = [value for _label, _color, values in series for value in values]
    all_y += [y for _label, _color, points in markers for _x, y in points]
    y_min, y_max = min(all_y + [0.0]), max(all_y + [0.0])
    step = nice_step(y_max - y_min)
    y_min = step * math.floor(y_min / step - 1e-9)
    y_max = step * math.ceil(y_max / step + 1e-9)

    def to_x(value):
        return WIDTH * (value - x_min) / (x_max - x_min)

    def to_y(value):
        return HEIGHT * (value - y_min) / (y_max - y_min)

    total_width = LEFT + WIDTH + RIGHT
    total_height = BOTTOM + HEIGHT + TOP
    pixel_height = int(round(pixel_width * total_height / total_width))
    scene = bpy.context.scene
    render.setup_cycles(scene, pixel_width, pixel_height, samples)
    background = scene.world.node_tree.nodes.get("Background")
    background.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.cycles.max_bounces = 0
    scene.render.film_transparent = False
    scene.render.image_settings.color_mode = 'RGB'
    center = (-LEFT + 0.5 * total_width, -BOTTOM + 0.5 * total_height)
    render.add_camera((center[0], center[1], 10.0), (center[0], center[1], 0.0), (0.0, 1.0, 0.0), total_width)

    # Grid, ticks and tick labels.
    tick_size = 0.3
    value = y_min
    while value <= y_max + 1e-9:
        y = to_y(value)
        polyline([(0.0, y), (WIDTH, y)], BLACK if abs(value) < 1e-9 else GRID, 0.03 if abs(value) < 1e-9 else 0.015,
                 z=-0.1)
        text(("%g" % round(value, 6)).replace("-", "\u2212"), -0.15, y, tick_size, align_x='RIGHT')
        value += step
    for value in (x_ticks or x_values):
        x = to_x(value)
        polyline([(x, 0.0), (x, HEIGHT)], GRID, 0.015, z=-0.1)
        text("%g\u00b0" % value, x, -0.35, tick_size, align_y='CENTER')
    polyline([(0.0, 0.0), (WIDTH, 0.0), (WIDTH, HEIGHT), (0.0, HEIGHT), (0.0, 0.0)], BLACK, 0.025)

    # Axis labels and title.
    text(x_label, 0.5 * WIDTH, -0.95, 0.34)
    text(y_label, -1.45, 0.5 * HEIGHT, 0.34, rotation=0.5 * math.pi)
    text(title, 0.5 * WIDTH, HEIGHT + 0.5, 0.4)

    # Data.
    for label, color, values in series:
        polyline([(to_x(x), to_y(y)) for x, y in zip(x_values, values)], color, 0.06, z=0.1)
    for label, color, points in markers:
        for x, y in points:
            marker(to_x(x), to_y(y), color, 0.16)

    # Legend, bottom left inside the plot (the curves fall to the right).
    entries = [(label, color, False) for label, color, _values in series]
    entries += [(label, color, True) for label, color, _points in markers]
    line_height = 0.42
    top = 0.3 + line_height * len(entries)
    polyline([(0.15, 0.12), (5.6, 0.12), (5.6, top + 0.05), (0.15, top + 0.05), (0.15, 0.12)], GRID, 0.015, z=0.15)
    legend_background = bpy.data.meshes.new("PlotLegend")
    legend_background.from_pydata([(0.15, 0.12, 0.12), (5.6, 0.12, 0.12), (5.6, top + 0.05, 0.12),
                                   (0.15, top + 0.05, 0.12)], [], [(0, 1, 2, 3)])
    legend = _link(bpy.data.objects.new("PlotLegend", legend_background))
    legend.data.materials.append(_material((1.0, 1.0, 1.0, 1.0)))
    for index, (label, color, is_marker) in enumerate(entries):
        y = top - line_height * (index + 0.5) - 0.05
        if is_marker:
            marker(0.65, y, color, 0.16, z=0.25)
        else:
            polyline([(0.3, y), (1.0, y)], color, 0.06, z=0.2)
        text(label, 1.2, y, 0.28, align_x='LEFT')

    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return path
