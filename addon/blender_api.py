# SPDX-License-Identifier: GPL-3.0-or-later
"""Where Blender's Python API differs between the versions the add-on supports (3.4 to 5.2).

Every difference the add-on meets lives here, named for what it does, so that the rest of the
add-on reads the same on every version. Each function says which versions take which path; the
checks look for the feature, not the version number, so a build between two known versions takes
whichever path it has.
"""

import operator
import struct
from array import array
from itertools import chain

import bpy
from mathutils import Matrix

# ---- Geometry Nodes modifier inputs ---------------------------------------------------------
# Up to Blender 5.1 a Geometry Nodes modifier keeps the values of its node group's inputs as custom
# properties of the modifier, keyed by the socket's identifier (modifier["Socket_1"]). Blender 5.2
# made them RNA properties (modifier.properties.inputs.Socket_1.value), and the modifier no longer
# holds custom properties at all: modifier.get() raises TypeError.


def _modifier_input_item(modifier, identifier):
    """The RNA item of one input on Blender 5.2+ (None when the node group has no such input), or
    False where inputs are custom properties of the modifier."""
    properties = getattr(modifier, "properties", None)
    inputs = getattr(properties, "inputs", None) if properties is not None else None
    if inputs is None:
        return False
    return getattr(inputs, identifier, None)


def modifier_input(modifier, identifier):
    """The value of the modifier's input identifier (a socket identifier), or None when unset."""
    item = _modifier_input_item(modifier, identifier)
    if item is False:
        return modifier.get(identifier)
    return item.value if item is not None else None


def set_modifier_input(modifier, identifier, value):
    """Sets the modifier's input identifier to value. The caller tags the object for evaluation:
    neither way of writing it does.

    An Object input is a dependency of the modifier's object. On 5.2 the RNA input has no update of
    its own, so the dependency graph would not learn of a new object there (it would stay out of the
    graph, never evaluated, and the modifier would read nothing from it); giving the modifier its
    node group again is the update Blender runs when inputs change, and rebuilds the relations."""
    item = _modifier_input_item(modifier, identifier)
    if item is False:
        modifier[identifier] = value
    elif item is None:
        raise KeyError("modifier %r has no input %r" % (modifier.name, identifier))
    else:
        item.value = value
        modifier.node_group = modifier.node_group


# ---- node groups ---------------------------------------------------------------------------
# Blender 4.0 replaced a node group's inputs and outputs collections with its interface.


def new_group_socket(group, name, in_out, socket_type):
    """Adds an input (in_out 'INPUT') or output ('OUTPUT') of socket_type (e.g. 'NodeSocketObject')
    to the node group and returns it."""
    if hasattr(group, "interface"):  # Blender 4.0+
        return group.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    sockets = group.inputs if in_out == 'INPUT' else group.outputs
    return sockets.new(socket_type, name)


def group_inputs(group):
    """The node group's input sockets (interface items on 4.0+, sockets on 3.x): each has name,
    identifier and bl_socket_idname."""
    if hasattr(group, "interface"):  # Blender 4.0+
        return [item for item in group.interface.items_tree if item.item_type == 'SOCKET' and item.in_out == 'INPUT']
    return list(group.inputs)


def offer_as_modifier(group):
    """Lists the node group among the Geometry Nodes modifier's groups (the flag exists from 4.1 on;
    before, every geometry node group is listed)."""
    if hasattr(group, "is_modifier"):
        group.is_modifier = True


# ---- the modifier stack ----------------------------------------------------------------------


def move_modifier(context, obj, modifier, current, index):
    """Moves modifier from position current to position index of obj's stack. ObjectModifiers.move()
    exists from 4.0 on; 3.4 has only the operator, which needs the object in the context."""
    if hasattr(obj.modifiers, "move"):
        obj.modifiers.move(current, index)
        return True
    with context.temp_override(object=obj, active_object=obj):
        result = bpy.ops.object.modifier_move_to_index(modifier=modifier.name, index=index)
    return 'FINISHED' in result


# ---- meshes --------------------------------------------------------------------------------


def update_loop_triangles(mesh):
    """Makes mesh.loop_triangles current: 3.x computes them on request (calc_loop_triangles), 4.0+
    keeps them current by itself and has no such method."""
    if hasattr(mesh, "calc_loop_triangles"):
        mesh.calc_loop_triangles()


def color_attributes(mesh):
    """The collection that holds the mesh's colour attributes and which one is active: 3.2+ has
    mesh.color_attributes; the attributes themselves before."""
    return getattr(mesh, "color_attributes", mesh.attributes)


def active_color_name(mesh):
    active = getattr(color_attributes(mesh), "active_color", None)
    return active.name if active is not None else ""


def set_active_color(mesh, name):
    """Makes the colour attribute name the one shown in the viewport and rendered (the render colour
    exists from 3.2 on)."""
    attribute = mesh.attributes.get(name) if name else None
    if attribute is None:
        return
    group = color_attributes(mesh)
    group.active_color = attribute
    if hasattr(group, "render_color_index"):
        for index, candidate in enumerate(group):
            if candidate.name == name:
                group.render_color_index = index
                break


# ---- library overrides ---------------------------------------------------------------------


def prepare_override_diff(obj, group_name):
    """Lets the library override of obj record each property of its add-on property group
    group_name that differs from the linked object, before Blender compares the two (saving).

    Blender 5.0+ keeps add-on properties apart from custom properties and gives a linked object its
    group of them only once something reads it. Where the linked object has none (a character whose
    own file never had the add-on), the override records a change of the whole group, which opening
    the file cannot apply: the settings and the bind come back at their defaults. Reading the group
    on the linked object makes it (in memory, the library file is not changed), so the override
    records each setting, as it does on earlier versions, where this read changes nothing."""
    override = obj.override_library
    reference = override.reference if override is not None else None
    if reference is not None and reference.bl_rna is obj.bl_rna:
        getattr(reference, group_name)


# ---- armatures -----------------------------------------------------------------------------


def bbone_mapping_mode(bone):
    """How a B-Bone maps its vertices to its segments: 'STRAIGHT' before 3.5 (the only way there
    was), or the bone's setting ('STRAIGHT' or 'CURVED') from 3.5 on."""
    return getattr(bone, "bbone_mapping_mode", 'STRAIGHT')


_HAS_BBONE_MAPPING = None


def bbone_mapping_modes(bones, count):
    """bytes: the count bones' B-Bone mappings as numbers, read in bulk (empty before 3.5, which has none)."""
    global _HAS_BBONE_MAPPING
    if _HAS_BBONE_MAPPING is None:
        _HAS_BBONE_MAPPING = "bbone_mapping_mode" in bpy.types.Bone.bl_rna.properties
    if not _HAS_BBONE_MAPPING:
        return b""
    modes = array('i', bytes(4 * count))
    bones.foreach_get("bbone_mapping_mode", modes)
    return modes.tobytes()


# ---- matrices in bulk ------------------------------------------------------------------------
# Blender keeps a 4x4 matrix column by column. Blender 5.2's mathutils Matrix exposes that memory through
# the buffer protocol, so joining matrices copies their floats at C speed. 3.4's and 4.3's do not; there
# each matrix is transposed (mathutils, in C) and its rows, the columns, read as tuples. The check looks at
# what this Blender's Matrix does, layout included.


def _matrix_memory_is_columns():
    probe = Matrix(((1.0, 2.0, 3.0, 4.0), (5.0, 6.0, 7.0, 8.0), (9.0, 10.0, 11.0, 12.0), (13.0, 14.0, 15.0, 16.0)))
    try:
        data = b"".join((probe,))
    except TypeError:
        return False
    return len(data) == 64 and array('f', data).tolist() == [float(1 + row * 4 + column)
                                                              for column in range(4) for row in range(4)]


_MATRIX_MEMORY = None
_ROW = operator.itemgetter(slice(None))


def matrices_column_major(matrices):
    """A float32 buffer of the 4x4 matrices' floats, each column by column as Blender stores them, in order."""
    global _MATRIX_MEMORY
    if _MATRIX_MEMORY is None:
        _MATRIX_MEMORY = _matrix_memory_is_columns()
    if _MATRIX_MEMORY:
        return memoryview(b"".join(matrices)).cast('f')
    values = list(chain.from_iterable(map(_ROW, chain.from_iterable(map(Matrix.transposed, matrices)))))
    return memoryview(struct.pack("%df" % len(values), *values)).cast('f')


def bone_selected(armature_object, name):
    """Whether bone `name` is selected: a pose bone's state from 5.0 on, the bone's before."""
    pose_bone = armature_object.pose.bones.get(name) if armature_object.pose else None
    if pose_bone is not None and hasattr(pose_bone, "select"):
        return pose_bone.select
    return armature_object.data.bones[name].select


def bone_collections(armature_object):
    """{name: set of the bone names in it}: the armature's bone collections from 4.0 on (nested ones
    included: collections_all from 4.1, collections in 4.0, where they are flat); before 4.0, where
    there are none, its bone groups by name and its bone layers as "Layer 1" to "Layer 32"."""
    armature = armature_object.data
    collections = getattr(armature, "collections_all", None)
    if collections is None:
        collections = getattr(armature, "collections", None)
    if collections is not None:
        return {collection.name: {bone.name for bone in collection.bones} for collection in collections}
    result = {}
    for index in range(32):
        members = {bone.name for bone in armature.bones if bone.layers[index]}
        if members:
            result["Layer %d" % (index + 1)] = members
    if armature_object.pose is not None:
        for group in armature_object.pose.bone_groups:
            result[group.name] = {bone.name for bone in armature_object.pose.bones if bone.bone_group == group}
    return result


# ---- application handlers -------------------------------------------------------------------


def animation_playing():
    """Whether an animation plays in any window (Screen.is_animation_playing): never without an interface."""
    for window_manager in bpy.data.window_managers:
        for window in window_manager.windows:
            if window.screen is not None and window.screen.is_animation_playing:
                return True
    return False


def app_handlers(name):
    """The list bpy.app.handlers.<name>, or None where this Blender has no such handler
    (save_post_fail exists from 4.1 on; 3.4 has no animation_playback_post)."""
    return getattr(bpy.app.handlers, name, None)


# ---- command line --------------------------------------------------------------------------


def has_cli_commands():
    """Whether add-ons can register `blender --command` commands (4.2+)."""
    return hasattr(bpy.utils, "register_cli_command")
