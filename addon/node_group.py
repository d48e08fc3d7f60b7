# SPDX-License-Identifier: GPL-3.0-or-later
"""The "Volume Preservation" modifier: its node group, built by code, and its place in the stack.

Python cannot define modifiers, so the add-on uses a Geometry Nodes modifier placed directly after
the Armature modifier. Its node group does three things, in this order:

    Group Input -> Store Named Attribute "lvp_position" = Position   (what the Armature modifier made)
                -> Store Named Attribute "lvp_index"    = Index      (to find these vertices again
                                                                      after a Subdivision Surface)
                -> Set Position, Offset = Sample Index(Object Info(Offsets).Geometry, Position, Index)
                -> Group Output                                      (the correction)

"Offsets" is an Object input of the group, so each modifier names its own object: the offsets
object (offsets.py), whose vertex i sits at the offset of vertex i. The handlers read the two
captured attributes from the evaluated mesh, compute the correction with the C core and write it
into that object's mesh, never into the character's own mesh: a character linked from a library
(whose mesh cannot be written) and objects that share one mesh are corrected too, and on Blender 3.4
the second evaluation does not copy the character's mesh. With no offsets object, or one with fewer
vertices, Sample Index reads zero and the modifier passes the mesh through unchanged.

The node group is never loaded from a file: it is rebuilt when missing or outdated. Its sockets are
found by name and type (_socket), so the same code builds it on Blender 3.4 (one "Value" socket per
data type) and on 4.x and 5.x (a single "Value" socket that changes type); how the group's inputs
are declared and how a modifier holds their values differ too (blender_api.py).
"""

import bpy

from . import blender_api
from . import names


def _socket(sockets, name, socket_type=None):
    """The socket called name (and of socket_type, e.g. 'VECTOR'), preferring an available one."""
    candidates = [socket for socket in sockets
                  if socket.name == name and (socket_type is None or socket.type == socket_type)]
    for socket in candidates:
        if getattr(socket, "enabled", True):
            return socket
    if candidates:
        return candidates[0]
    raise LookupError("node socket %r of type %r not found" % (name, socket_type))


def _new_group_sockets(group):
    blender_api.new_group_socket(group, "Geometry", 'INPUT', 'NodeSocketGeometry')
    offsets = blender_api.new_group_socket(group, names.OFFSETS_SOCKET_NAME, 'INPUT', 'NodeSocketObject')
    blender_api.new_group_socket(group, "Geometry", 'OUTPUT', 'NodeSocketGeometry')
    offsets.description = "The object that holds this object's correction (made and written by Volume Preservation)"
    blender_api.offer_as_modifier(group)


def _new_store_node(nodes, attribute_name, data_type, location):
    node = nodes.new('GeometryNodeStoreNamedAttribute')
    node.data_type = data_type
    node.domain = 'POINT'
    node.location = location
    _socket(node.inputs, "Name").default_value = attribute_name
    return node


def build_node_group():
    """Creates a new node group with the layout described at the top of this file."""
    group = bpy.data.node_groups.new(names.NODE_GROUP_NAME, 'GeometryNodeTree')
    _new_group_sockets(group)
    nodes = group.nodes
    links = group.links

    group_input = nodes.new('NodeGroupInput')
    group_input.location = (-800, 0)
    group_output = nodes.new('NodeGroupOutput')
    group_output.location = (600, 0)

    position = nodes.new('GeometryNodeInputPosition')
    position.location = (-800, -200)
    store_position = _new_store_node(nodes, names.CAPTURED_POSITION_ATTRIBUTE, 'FLOAT_VECTOR', (-550, 0))

    index = nodes.new('GeometryNodeInputIndex')
    index.location = (-550, -250)
    store_index = _new_store_node(nodes, names.CAPTURED_INDEX_ATTRIBUTE, 'INT', (-300, 0))

    # ORIGINAL: the offsets object's vertices as written, whatever its transform.
    offsets_object = nodes.new('GeometryNodeObjectInfo')
    offsets_object.transform_space = 'ORIGINAL'
    offsets_object.location = (-550, -450)
    offset = nodes.new('GeometryNodeInputPosition')  # evaluated on the offsets object's mesh
    offset.location = (-300, -550)
    sample = nodes.new('GeometryNodeSampleIndex')
    sample.data_type = 'FLOAT_VECTOR'
    sample.domain = 'POINT'
    sample.location = (-50, -400)
    set_position = nodes.new('GeometryNodeSetPosition')
    set_position.location = (250, 0)

    links.new(group_input.outputs[0], _socket(store_position.inputs, "Geometry"))
    links.new(_socket(position.outputs, "Position"), _socket(store_position.inputs, "Value", 'VECTOR'))
    links.new(_socket(store_position.outputs, "Geometry"), _socket(store_index.inputs, "Geometry"))
    links.new(_socket(index.outputs, "Index"), _socket(store_index.inputs, "Value", 'INT'))
    links.new(_socket(store_index.outputs, "Geometry"), _socket(set_position.inputs, "Geometry"))
    links.new(_socket(group_input.outputs, names.OFFSETS_SOCKET_NAME), _socket(offsets_object.inputs, "Object"))
    links.new(_socket(offsets_object.outputs, "Geometry"), _socket(sample.inputs, "Geometry"))
    links.new(_socket(offset.outputs, "Position"), _socket(sample.inputs, "Value", 'VECTOR'))
    links.new(_socket(index.outputs, "Index"), _socket(sample.inputs, "Index"))
    links.new(_socket(sample.outputs, "Value", 'VECTOR'), _socket(set_position.inputs, "Offset"))
    links.new(_socket(set_position.outputs, "Geometry"), group_output.inputs[0])

    group[names.NODE_GROUP_TAG] = names.NODE_GROUP_VERSION
    return group


def is_our_node_group(group):
    return group is not None and group.get(names.NODE_GROUP_TAG) is not None


EXPECTED_NODES = sorted((
    'NodeGroupInput', 'NodeGroupOutput', 'GeometryNodeInputPosition', 'GeometryNodeInputIndex',
    'GeometryNodeStoreNamedAttribute', 'GeometryNodeStoreNamedAttribute', 'GeometryNodeObjectInfo',
    'GeometryNodeInputPosition', 'GeometryNodeSampleIndex', 'GeometryNodeSetPosition'))
EXPECTED_LINKS = 11
EXPECTED_NAMES = sorted((names.CAPTURED_POSITION_ATTRIBUTE, names.CAPTURED_INDEX_ATTRIBUTE))


def is_current(group):
    """Whether group is ours, of the current layout, and was not edited by hand."""
    if group is None or group.get(names.NODE_GROUP_TAG) != names.NODE_GROUP_VERSION:
        return False
    if sorted(node.bl_idname for node in group.nodes) != EXPECTED_NODES or len(group.links) != EXPECTED_LINKS:
        return False
    attribute_names = []
    for node in group.nodes:
        if node.bl_idname == 'GeometryNodeStoreNamedAttribute':
            attribute_names.append(_socket(node.inputs, "Name").default_value)
    return sorted(attribute_names) == EXPECTED_NAMES and offsets_socket_identifier(group) is not None


def offsets_socket_identifier(group):
    """The identifier of the modifier's input that holds the offsets object ("Input_1" on 3.x,
    "Socket_1" on 4.x+; blender_api.modifier_input reads it), or None when group has no such input."""
    for socket in blender_api.group_inputs(group):
        if socket.name == names.OFFSETS_SOCKET_NAME and socket.bl_socket_idname == 'NodeSocketObject':
            return socket.identifier
    return None


def ensure_node_group():
    """Our node group with the current layout: an existing one when it is current, else a new one."""
    for group in bpy.data.node_groups:
        if group.library is None and is_current(group):
            return group
    return build_node_group()


def repair_modifiers(objects):
    """Gives every Volume Preservation modifier a current node group (after loading a file made with
    another version of the add-on, or whose group was edited by hand or deleted). Returns how many
    changed."""
    repaired = 0
    for obj in objects:
        if obj.library is not None:
            continue
        for modifier in obj.modifiers:
            if is_our_modifier(modifier) and not is_current(modifier.node_group):
                modifier.node_group = ensure_node_group()
                repaired += 1
    if repaired:
        remove_unused_node_groups()
    return repaired


def is_our_modifier(modifier):
    """A Geometry Nodes modifier with our node group, or with none and our name: its group was deleted
    (Outliner > Blender File > Node Groups > Delete leaves the modifier without one), and it is still
    the object's Volume Preservation, to repair (repair_modifiers) or remove."""
    if modifier.type != 'NODES':
        return False
    if modifier.node_group is None:
        return modifier.name == names.MODIFIER_NAME or modifier.name.startswith(names.MODIFIER_NAME + ".")
    return is_our_node_group(modifier.node_group)


def find_modifier(obj):
    """The object's Volume Preservation modifier, or None."""
    for modifier in obj.modifiers:
        if is_our_modifier(modifier):
            return modifier
    return None


def count_modifiers(obj):
    """How many Volume Preservation modifiers obj has (a copy made with Duplicate Modifier counts)."""
    return sum(1 for modifier in obj.modifiers if is_our_modifier(modifier))


def modifiers_before(obj, armature_modifier, mode):
    """The modifiers enabled in mode ('VIEWPORT' or 'RENDER') that come before armature_modifier."""
    found = []
    for modifier in obj.modifiers:
        if modifier == armature_modifier:
            break
        if modifier_enabled(modifier, mode):
            found.append(modifier)
    return found


def stack_signature(obj):
    """What the modifier stack looks like: changes when a modifier is added, removed, moved or toggled."""
    return tuple((modifier.name, modifier.type, modifier.show_viewport, modifier.show_render)
                 for modifier in obj.modifiers)


def find_armature_modifier(obj):
    """The Armature modifier that Volume Preservation follows: the last one before our modifier, or
    the first one in the stack when our modifier is not there yet. None when there is none."""
    ours = find_modifier(obj)
    found = None
    for modifier in obj.modifiers:
        if modifier == ours:
            break
        if modifier.type == 'ARMATURE':
            if ours is None:
                return modifier
            found = modifier
    return found


def modifier_index(obj, modifier):
    for index, candidate in enumerate(obj.modifiers):
        if candidate == modifier:
            return index
    raise LookupError("modifier %r is not on object %r" % (modifier.name, obj.name))


def move_modifier(context, obj, modifier, index):
    """Moves modifier to position index of obj's stack (ObjectModifiers.move() does not exist on 3.4)."""
    current = modifier_index(obj, modifier)
    if current == index:
        return
    moved = blender_api.move_modifier(context, obj, modifier, current, index)
    if not moved or modifier_index(obj, modifier) != index:
        raise RuntimeError("could not move modifier %r to position %d" % (modifier.name, index))


def add_modifier(context, obj, armature_modifier):
    """Adds the Volume Preservation modifier directly after armature_modifier and returns it."""
    group = ensure_node_group()
    modifier = obj.modifiers.new(names.MODIFIER_NAME, 'NODES')
    try:
        modifier.node_group = group
        modifier.show_expanded = False
        move_modifier(context, obj, modifier, modifier_index(obj, armature_modifier) + 1)
    except Exception:
        obj.modifiers.remove(modifier)
        raise
    return modifier


def remove_modifier(obj):
    """Removes the object's Volume Preservation modifier(s); returns how many were removed."""
    removed = 0
    modifier = find_modifier(obj)
    while modifier is not None:
        obj.modifiers.remove(modifier)
        removed += 1
        modifier = find_modifier(obj)
    return removed


def remove_unused_node_groups():
    """Deletes our node groups that nothing uses any more (no modifier, no other node group)."""
    for group in list(bpy.data.node_groups):
        if is_our_node_group(group) and group.library is None and group.users == 0:
            bpy.data.node_groups.remove(group)


def modifier_enabled(modifier, depsgraph_mode):
    """Whether the modifier runs in a depsgraph of this mode ('VIEWPORT' or 'RENDER')."""
    if depsgraph_mode == 'RENDER':
        return modifier.show_render
    return modifier.show_viewport
