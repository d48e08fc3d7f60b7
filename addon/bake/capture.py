# SPDX-License-Identifier: GPL-3.0-or-later
"""What a bake records for one object and one frame: the mesh as it leaves the Volume Preservation
modifier, in object local space, one point per vertex of the object's mesh, in vertex order.

That is the geometry a Mesh Cache modifier on a copy of the mesh (without Armature) can replay, and
the one with the vertex count of the base mesh that Maya, 3ds Max and Houdini expect:

- when no modifier after Volume Preservation is enabled, it is exactly the evaluated mesh;
- when modifiers follow (Subdivision Surface, Corrective Smooth...), they are NOT baked: the positions
  are the ones Volume Preservation hands to them, i.e. the positions it captured on its input plus the
  offsets the handlers wrote for this frame, read from the evaluated mesh's first N vertices (Blender
  keeps the original vertices first and copies their attributes). Keep those modifiers after the Mesh
  Cache modifier on the target.

Also the checks made before baking, each with a message that says what is wrong and how to fix it.
"""

import operator
from array import array

import bpy

from .. import handlers
from .. import mesh_data
from .. import names
from .. import node_group
from .. import offsets
from ..session import SESSION


class BakeError(Exception):
    """Something the user must fix before the bake can go on; the message says what and how."""


def objects_with_modifier(scene):
    return [obj for obj in scene.objects if obj.type == 'MESH' and node_group.find_modifier(obj) is not None]


def find_objects(scene, object_names):
    """The objects to bake: those named (every one must exist and carry the modifier), or, when no name is
    given, every object of the scene with a Volume Preservation modifier. Raises BakeError listing every
    problem."""
    if not object_names:
        objects = objects_with_modifier(scene)
        if not objects:
            raise BakeError("scene %r has no object with a Volume Preservation modifier: add it to the character "
                            "(object.lvp_add) or name the objects to bake" % scene.name)
        return objects
    problems = []
    objects = []
    for name in object_names:
        obj = bpy.data.objects.get(name)
        if obj is None:
            candidates = ", ".join(sorted(o.name for o in objects_with_modifier(scene))) or "none"
            problems.append("there is no object named %r in this file (objects with Volume Preservation: %s)"
                            % (name, candidates))
            continue
        problem = object_problem(scene, obj)
        if problem:
            problems.append(problem)
        elif obj not in objects:
            objects.append(obj)
    if problems:
        raise BakeError("; ".join(problems))
    return objects


def object_problem(scene, obj):
    """Why obj cannot be baked in scene, or None."""
    if obj.type != 'MESH':
        return "%r is not a mesh (it is %s object): bake the character's mesh objects" % (
            obj.name, "an " + obj.type.lower() if obj.type[0] in "AEIOU" else "a " + obj.type.lower())
    modifier = node_group.find_modifier(obj)
    if modifier is None:
        return ("%r has no Volume Preservation modifier: add it first (select it, then Add Volume Preservation, "
                "or bpy.ops.object.lvp_add())" % obj.name)
    if not modifier.show_viewport:
        return ("the Volume Preservation modifier of %r is disabled in the viewport: enable it (the monitor icon) "
                "to bake it" % obj.name)
    if obj.name not in scene.objects:
        return "%r is not in scene %r: bake it from the scene it is in" % (obj.name, scene.name)
    if obj.hide_viewport:
        return "%r is disabled in viewports (the monitor icon), so it is not evaluated: enable it to bake it" % obj.name
    return None


def check_evaluated(objects, depsgraph):
    """Objects that the depsgraph does not correct (hidden, in an excluded collection that nothing
    instances: handlers.corrected_in) cannot be baked."""
    missing = [obj.name for obj in objects if not handlers.corrected_in(obj, depsgraph)]
    if missing:
        raise BakeError("%s %s not shown in this view layer (hidden, or in an excluded or disabled collection): "
                        "show %s to bake" % (", ".join(repr(name) for name in missing),
                                             "is" if len(missing) == 1 else "are",
                                             "it" if len(missing) == 1 else "them"))


def _modifiers_after(obj):
    modifier = node_group.find_modifier(obj)
    index = node_group.modifier_index(obj, modifier)
    return [candidate for candidate in list(obj.modifiers)[index + 1:] if candidate.show_viewport]


class ObjectReader:
    """Reads one object's baked positions from an evaluated depsgraph into a reused float32 buffer."""

    def __init__(self, obj):
        self.obj = obj
        self.name = obj.name
        self.vertex_count = len(obj.data.vertices)
        self.positions = array('f', bytes(12 * self.vertex_count))
        self._captured = None

    def read(self, depsgraph, frame):
        """Fills self.positions for the frame the depsgraph was evaluated at. Raises BakeError."""
        obj = self.obj
        status = SESSION.status(obj)
        if status is not None and status[0] == 'ERROR':
            raise BakeError("%r at frame %d: %s" % (self.name, frame, status[1]))
        mesh_eval = obj.evaluated_get(depsgraph).data
        count = len(mesh_eval.vertices)
        if not _modifiers_after(obj):
            if count != self.vertex_count:
                raise BakeError("%r at frame %d: the mesh leaving Volume Preservation has %d vertices, the object's "
                                "mesh %d: a modifier before the Armature modifier adds or removes vertices"
                                % (self.name, frame, count, self.vertex_count))
            mesh_data.vertex_positions(mesh_eval, self.positions)
            return self.positions
        captured = mesh_eval.attributes.get(names.CAPTURED_POSITION_ATTRIBUTE)
        if captured is None or captured.domain != 'POINT' or count < self.vertex_count:
            raise BakeError("%r at frame %d: a modifier after Volume Preservation (%s) drops or reorders its vertices; "
                            "disable it in the viewport while baking, or move it above the Armature modifier"
                            % (self.name, frame, ", ".join(m.name for m in _modifiers_after(obj))))
        if self._captured is None or len(self._captured) != 3 * count:
            self._captured = array('f', bytes(12 * count))
        captured.data.foreach_get("vector", self._captured)
        positions = self.positions
        offset_values = offsets.read(obj)
        if offset_values is None:
            positions[:] = self._captured[:3 * self.vertex_count]
            return positions
        # float32 + float32 rounded to float32, as the node group's Set Position does; map() sums without a
        # Python loop over the coordinates, which would take about twice as long.
        positions[:] = array('f', map(operator.add, memoryview(self._captured)[:3 * self.vertex_count], offset_values))
        return positions
