# SPDX-License-Identifier: GPL-3.0-or-later
"""Rendering for the demo: Cycles on the CPU, small and quick, denoising off (Debian's Blender has no
OpenImageDenoise); one orthographic camera per scene, captions that follow the camera, materials that
show the add-on's colour attributes, and side-by-side composites made with Blender's own image API
(no PIL, no numpy in Blender 3.4)."""

import os
from array import array

import bpy
from mathutils import Matrix, Vector

SKIN_COLOR = (0.80, 0.52, 0.40, 1.0)
BACKGROUND = (0.92, 0.92, 0.90)
CAPTION_COLOR = (0.0, 0.0, 0.0, 1.0)  # pure black: _mask() leaves it out of silhouettes
OUTLINE_COLOR = (0.85, 0.05, 0.05)
GUTTER = 6  # pixels between two panels of a composite
CAPTION_TAG = "lvp_demo_caption"


def setup_cycles(scene, width, height, samples):
    scene.render.engine = 'CYCLES'
    cycles = scene.cycles
    cycles.device = 'CPU'
    cycles.samples = samples
    cycles.use_denoising = False
    if hasattr(cycles, "use_preview_denoising"):
        cycles.use_preview_denoising = False
    if hasattr(cycles, "use_adaptive_sampling"):
        cycles.use_adaptive_sampling = True
    cycles.max_bounces = 4
    cycles.diffuse_bounces = 2
    cycles.glossy_bounces = 1
    cycles.transmission_bounces = 0
    cycles.transparent_max_bounces = 2
    render = scene.render
    render.resolution_x = width
    render.resolution_y = height
    render.resolution_percentage = 100
    render.film_transparent = True
    render.use_persistent_data = False
    render.image_settings.file_format = 'PNG'
    render.image_settings.color_mode = 'RGBA'
    render.image_settings.color_depth = '8'
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    world = scene.world or bpy.data.worlds.new("DemoWorld")
    scene.world = world
    world.use_nodes = True
    background = world.node_tree.nodes.get("Background")
    background.inputs["Color"].default_value = BACKGROUND + (1.0,)
    background.inputs["Strength"].default_value = 0.65


def add_sun(direction=(-0.4, 0.3, -1.0), strength=3.0):
    light = bpy.data.lights.new("DemoSun", 'SUN')
    light.energy = strength
    light.angle = 0.2
    sun = bpy.data.objects.new("DemoSun", light)
    bpy.context.scene.collection.objects.link(sun)
    sun.rotation_euler = Vector(direction).to_track_quat('-Z', 'Y').to_euler()
    return sun


def add_camera(location, target, up, ortho_scale):
    """An orthographic camera at `location` looking at `target`, with `up` (approximately) up."""
    data = bpy.data.cameras.new("DemoCamera")
    data.type = 'ORTHO'
    data.ortho_scale = ortho_scale
    data.clip_start = 0.01
    data.clip_end = 100.0
    camera = bpy.data.objects.new("DemoCamera", data)
    bpy.context.scene.collection.objects.link(camera)
    forward = (Vector(target) - Vector(location)).normalized()
    right = forward.cross(Vector(up)).normalized()
    true_up = right.cross(forward)
    # The camera looks down its local -Z with local +Y up: its rotation's columns are right, up, -forward.
    rotation = Matrix((right, true_up, -forward)).transposed()
    camera.rotation_euler = rotation.to_euler()
    camera.location = location
    bpy.context.scene.camera = camera
    return camera


def _emission_material(name, color):
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    nodes = material.node_tree.nodes
    nodes.clear()
    emission = nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = color
    output = nodes.new("ShaderNodeOutputMaterial")
    material.node_tree.links.new(emission.outputs["Emission"], output.inputs["Surface"])
    return material


def skin_material(color=SKIN_COLOR):
    material = bpy.data.materials.get("DemoSkin")
    if material is None:
        material = bpy.data.materials.new("DemoSkin")
        material.use_nodes = True
        principled = material.node_tree.nodes.get("Principled BSDF")
        principled.inputs["Base Color"].default_value = color
        principled.inputs["Roughness"].default_value = 0.6
    return material


def attribute_material(attribute_name):
    """Diffuse colour read from a point colour attribute of the mesh (the add-on's display attributes
    lvp_segmentation and lvp_correction_map), so renders show what the viewport's Color: Attribute shows."""
    name = "DemoAttribute_" + attribute_name
    material = bpy.data.materials.get(name)
    if material is not None:
        return material
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    tree = material.node_tree
    principled = tree.nodes.get("Principled BSDF")
    principled.inputs["Roughness"].default_value = 0.8
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_type = 'GEOMETRY'
    attribute.attribute_name = attribute_name
    tree.links.new(attribute.outputs["Color"], principled.inputs["Base Color"])
    return material


def set_material(obj, material):
    obj.data.materials.clear()
    obj.data.materials.append(material)


def smooth(obj):
    for polygon in obj.data.polygons:
        polygon.use_smooth = True


def add_caption(camera, text, size_fraction=0.055, corner=(0.03, 0.04), line=0):
    """A text that follows the camera, in the view's top-left corner (fractions of the view's width
    from the left and from the top). Returns the text object; hide it with hide_render."""
    scene = bpy.context.scene
    width = camera.data.ortho_scale
    aspect = scene.render.resolution_y / scene.render.resolution_x
    height = width * aspect if aspect <= 1.0 else width
    width = width if aspect <= 1.0 else width / aspect
    curve = bpy.data.curves.new("DemoCaption", 'FONT')
    curve.body = text
    curve.size = size_fraction * width
    curve.align_x = 'LEFT'
    caption = bpy.data.objects.new("DemoCaption", curve)
    scene.collection.objects.link(caption)
    caption.parent = camera
    caption.location = (-0.5 * width + corner[0] * width,
                        0.5 * height - corner[1] * width - (line + 1) * 1.25 * curve.size, -0.05)
    caption.visible_shadow = False
    caption[CAPTION_TAG] = True
    set_material(caption, _emission_material("DemoCaptionInk", CAPTION_COLOR))
    return caption


def render_still(path, show, hide=()):
    """Renders the scene's camera into `path` (RGBA, transparent background) with the objects of `show`
    visible and those of `hide` hidden (hide_render); captions not in `show` are hidden too."""
    for obj in bpy.context.scene.objects:
        if obj.get(CAPTION_TAG):
            obj.hide_render = True
    for obj in hide:
        obj.hide_render = True
    for obj in show:
        obj.hide_render = False
    scene = bpy.context.scene
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    if not os.path.isfile(path):
        raise RuntimeError("the render did not write %s" % path)
    return path


def _load_pixels(path):
    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    pixels = array('f', bytes(4 * 4 * width * height))
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return width, height, pixels


def save_pixels(path, width, height, pixels):
    """Writes float RGBA pixels (bottom row first, as Blender stores them) as an 8-bit RGB PNG."""
    image = bpy.data.images.new("DemoComposite", width, height, alpha=False, float_buffer=False)
    image.pixels.foreach_set(pixels)
    image.filepath_raw = path
    image.file_format = 'PNG'
    image.save()
    bpy.data.images.remove(image)
    return path


def _mask(pixels, width, height):
    """The silhouette of the rendered objects: opaque pixels, except the captions' near-black ink."""
    return bytearray(1 if pixels[4 * index + 3] > 0.5 and max(pixels[4 * index:4 * index + 3]) > 0.2 else 0
                     for index in range(width * height))


def _outline(mask, width, height):
    """Indices of the pixels on the border of a mask, two pixels thick."""
    edge = set()
    for y in range(1, height - 1):
        row = y * width
        for x in range(1, width - 1):
            index = row + x
            inside = mask[index - 1] and mask[index + 1] and mask[index - width] and mask[index + width]
            if mask[index] and not inside:
                edge.update((index, index + 1, index + width))
    return edge


def _over_background(pixels, background=BACKGROUND):
    """Straight-alpha RGBA over an opaque background colour (in place)."""
    for index in range(0, len(pixels), 4):
        alpha = pixels[index + 3]
        if alpha < 1.0:
            for channel in range(3):
                pixels[index + channel] = pixels[index + channel] * alpha + background[channel] * (1.0 - alpha)
            pixels[index + 3] = 1.0


def side_by_side(path, panel_paths, outline_first=False, remove_parts=True):
    """Composites renders of the same size into one PNG, left to right with a gutter between them, over
    the background colour. With outline_first, the outline of the first render's silhouette is drawn over
    the others (OUTLINE_COLOR), so that the difference shows at a glance."""
    panels = [_load_pixels(panel_path) for panel_path in panel_paths]
    width, height = panels[0][0], panels[0][1]
    for panel_path, (panel_width, panel_height, _pixels) in zip(panel_paths, panels):
        if (panel_width, panel_height) != (width, height):
            raise ValueError("%s is %d x %d, not %d x %d" % (panel_path, panel_width, panel_height, width, height))
    outline = _outline(_mask(panels[0][2], width, height), width, height) if outline_first else ()
    for number, (_width, _height, pixels) in enumerate(panels):
        _over_background(pixels)
        if number > 0:
            for index in outline:
                pixels[4 * index:4 * index + 3] = array('f', OUTLINE_COLOR)
    total = len(panels) * width + (len(panels) - 1) * GUTTER
    composite = array('f', [1.0]) * (4 * total * height)
    row = 4 * width
    for number, (_width, _height, pixels) in enumerate(panels):
        left = 4 * number * (width + GUTTER)
        for y in range(height):
            start = 4 * total * y + left
            composite[start:start + row] = pixels[row * y:row * (y + 1)]
    save_pixels(path, total, height, composite)
    if remove_parts:
        for panel_path in panel_paths:
            os.remove(panel_path)
    return path


def image_statistics(path):
    """(width, height, distinct grey levels over a coarse sample, fraction of pixels that are not the
    background colour): enough to tell a real picture from an empty frame."""
    width, height, pixels = _load_pixels(path)
    levels = set()
    foreground = 0
    corner = tuple(round(value, 2) for value in pixels[0:3])
    step = max(1, (width * height) // 20000)
    samples = 0
    for index in range(0, width * height, step):
        red, green, blue = pixels[4 * index:4 * index + 3]
        levels.add(int(255 * (red + green + blue) / 3.0) // 4)
        if abs(red - corner[0]) + abs(green - corner[1]) + abs(blue - corner[2]) > 0.06:
            foreground += 1
        samples += 1
    return width, height, len(levels), foreground / samples
