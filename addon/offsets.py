# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the correction lives: one offsets object per corrected object.

The handlers compute per-vertex offsets every frame; the modifier's node group adds them to what
leaves the Armature modifier (node_group.py). They are written into a small object of their own,
never into the character's mesh:

    character object --modifier "Volume Preservation", input "Offsets"--> offsets object
                                                                          mesh: N loose vertices,
                                                                          vertex i at offset i

Why not an attribute of the character's mesh:
- a character linked from a library, as productions bring characters into shots by library
  override, keeps its mesh linked, and Blender ignores what add-ons write into it; the offsets
  object is local to the shot, and the override records which one the modifier uses;
- objects that share one mesh (linked duplicates) each need their own correction;
- on Blender 3.4 a tagged mesh is copied whole into its evaluated copy before the modifiers run
  again, so evaluating the object again costs less after its offsets object changed than after its
  own mesh did (BENCHMARKS.md).

The offsets object is in no collection (nothing to see, select or render) and is kept and saved
because the modifier uses it. Its custom property names.OFFSETS_OWNER_TAG names the object it was
made for: a modifier copied to another object (Copy to Selected, Link Modifiers, Duplicate) names
the same offsets object; the object that is not its owner gets one of its own at its next correction,
or, while it cannot be corrected (not bound yet), names none.
New offsets objects are made on the main thread only (never from a render thread).
"""

import threading
from array import array

import bpy

from . import blender_api
from . import mesh_data
from . import names
from . import node_group
from .session import SESSION


def offsets_object(modifier):
    """The object the modifier's Offsets input names, or None."""
    if modifier is None or modifier.node_group is None:
        return None
    identifier = node_group.offsets_socket_identifier(modifier.node_group)
    if identifier is None:
        return None
    value = blender_api.modifier_input(modifier, identifier)
    return value if isinstance(value, bpy.types.Object) else None


def is_offsets_object(obj):
    return obj is not None and obj.type == 'MESH' and obj.get(names.OFFSETS_OWNER_TAG) is not None


def _writable(obj):
    return not mesh_data.is_linked(obj) and obj.data is not None and not mesh_data.is_linked(obj.data)


def _users_of(holder):
    """Objects whose Volume Preservation modifier names holder (cheap when only one does: the usual case)."""
    if holder.users < 2:
        return None
    return [obj for obj in bpy.data.objects
            if obj.type == 'MESH' and offsets_object(node_group.find_modifier(obj)) == holder]


def _owned_by(holder, obj):
    """Whether obj may write holder: obj's modifier is the only one that names it, or obj is the
    object it was made for (a copy's modifier names its original's until it gets its own)."""
    users = _users_of(holder)
    return users is None or len(users) < 2 or holder.get(names.OFFSETS_OWNER_TAG) == obj.name_full


def _may_write(holder, obj):
    """Whether obj may write holder: an offsets object the add-on made, local, and obj's own (never
    the original's from a copy)."""
    return is_offsets_object(holder) and _writable(holder) and _owned_by(holder, obj)


def usable_offsets_object(obj, modifier, vertex_count):
    """The offsets object obj's modifier names when obj may write it (_may_write) and it has
    vertex_count vertices. None when obj needs a new one."""
    holder = offsets_object(modifier)
    if not _may_write(holder, obj) or len(holder.data.vertices) != vertex_count:
        return None
    return holder


def new_offsets_object(obj, modifier, vertex_count):
    """Makes an offsets object for obj, of vertex_count vertices at zero (no correction), names it in
    the modifier and returns it. The one it replaces is deleted when nothing else uses it."""
    identifier = node_group.offsets_socket_identifier(modifier.node_group)
    if identifier is None:
        raise ValueError("the node group of %r has no %r input" % (modifier.name, names.OFFSETS_SOCKET_NAME))
    name = (names.OFFSETS_OBJECT_PREFIX + obj.name)[:63]
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(vertex_count)  # at (0, 0, 0)
    holder = bpy.data.objects.new(name, mesh)
    holder[names.OFFSETS_OWNER_TAG] = obj.name_full
    previous = offsets_object(modifier)
    # A new dependency of obj: the dependency graph learns of it because bpy.data.objects.new() above
    # has it rebuild its relations at the next evaluation (tested: tests/blender/test_live.py,
    # TestDuplicates, a copy given a new offsets object from a handler is corrected on that frame).
    blender_api.set_modifier_input(modifier, identifier, holder)
    SESSION.changes.expect_own_update(obj)
    obj.update_tag()
    if previous is not None:
        delete_if_unused(previous)
    return holder


def delete_if_unused(holder):
    """Deletes an offsets object made by the add-on, and its mesh, when no modifier uses it any more."""
    if not is_offsets_object(holder) or not _writable(holder) or holder.users > 0:
        return
    mesh = holder.data
    bpy.data.objects.remove(holder)
    if mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def _name_no_offsets_object(obj, modifier):
    """obj's modifier then samples nothing: it passes the mesh through."""
    identifier = node_group.offsets_socket_identifier(modifier.node_group)
    blender_api.set_modifier_input(modifier, identifier, None)
    SESSION.changes.expect_own_update(obj)
    obj.update_tag()


def delete_offsets_object(modifier):
    """Before the modifier is removed: deletes its offsets object when nothing else uses it."""
    holder = offsets_object(modifier)
    if holder is None:
        return
    identifier = node_group.offsets_socket_identifier(modifier.node_group)
    blender_api.set_modifier_input(modifier, identifier, None)
    delete_if_unused(holder)


def write(holder, offsets, bound=None):
    """Writes offsets (3 floats a vertex) into the offsets object when they differ from what it holds,
    and tags its mesh for a new evaluation (which evaluates the corrected object again). Returns
    whether anything was written.

    bound remembers what was last written, which saves reading it back every frame; it forgets it
    whenever something else may have changed it (undo, a new offsets object).
    """
    if bound is not None and bound.wrote(offsets):
        return False
    mesh = holder.data
    if len(mesh.vertices) * 3 != len(offsets):
        return False
    if bound is None or bound.written is None:
        current = mesh_data.vertex_positions(mesh)
        if mesh_data.same_values(current, offsets):
            if bound is not None:
                bound.note_written(current)
            return False
    mesh_data.set_vertex_positions(mesh, offsets)
    mesh.update_tag()
    if bound is not None:
        bound.note_written(offsets)
    return True


def write_zeros(obj, modifier, bound=None):
    """Pass-through: obj's modifier then adds nothing. Writes zeros into an offsets object obj may
    write (_may_write). A modifier that names another object's offsets object (a copy of that
    object's modifier: Copy to Selected, Link Modifiers) would add that object's correction: it is
    made to name none (on the main thread, where data-blocks may change). Returns whether anything
    was written."""
    holder = offsets_object(modifier)
    if holder is None:
        return False
    if not _may_write(holder, obj):
        if is_offsets_object(holder) and not _owned_by(holder, obj) and \
                threading.current_thread() is threading.main_thread():
            _name_no_offsets_object(obj, modifier)
            return True
        return False
    zeros = array('f', bytes(12 * len(holder.data.vertices)))
    if bound is not None and len(zeros) != 3 * bound.vertex_count:
        bound = None
    return write(holder, zeros, bound)


def read(obj):
    """The offsets obj's modifier adds (3 floats a vertex of obj's mesh; zero where its offsets
    object has no vertex), or None when it has no Volume Preservation modifier."""
    modifier = node_group.find_modifier(obj)
    if modifier is None:
        return None
    values = array('f', bytes(12 * len(obj.data.vertices)))
    holder = offsets_object(modifier)
    if holder is not None and holder.type == 'MESH':
        stored = mesh_data.vertex_positions(holder.data)
        count = min(len(stored), len(values))
        values[:count] = stored[:count]
    return values


def swap_untagged(holder, offsets=None):
    """Replaces the offsets object's offsets with offsets (zeros when None) WITHOUT tagging it: what
    Blender shows stays as it is, only what is saved changes. Returns the previous offsets, or None
    when nothing was replaced (another vertex count, or the same values)."""
    mesh = holder.data
    previous = mesh_data.vertex_positions(mesh)
    if offsets is None:
        offsets = array('f', bytes(4 * len(previous)))
    if len(offsets) != len(previous) or mesh_data.same_values(previous, offsets):
        return None
    mesh_data.set_vertex_positions(mesh, offsets)
    return previous


def all_writable_offsets_objects():
    return [obj for obj in bpy.data.objects if is_offsets_object(obj) and _writable(obj)]
