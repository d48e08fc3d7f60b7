# SPDX-License-Identifier: GPL-3.0-or-later
"""Binding objects: one _lvp.Binding per object, made from its mesh, weights, armature and settings.

A Binding holds the rest-pose work of the C core (segmentation, maps, rest constants). It cannot
be saved in a .blend file, so the file keeps only a bind record on the object (Object.lvp.bind_id
and Object.lvp.topology_signature), and the Binding is rebuilt from the mesh, its weights and the
armature the first time the handlers need it after a file load or an undo: no user action.

The binding follows what it was made of, as a reopened file or a render farm would bind it: when the
weights, the rest mesh, the Armature modifier's mask, the bound bones or their rest pose change, the
object is bound again under the same record (live.py, _follow_changes; in the interface once the
changes pause). When the mesh's topology no longer matches the record (vertices added or removed
after the bind, or reconnected), nothing is rebuilt: the modifier passes the mesh through and the
panel says "rebind needed". The Bind operator makes a new record.

The bindings are kept by the session (session.py), one per object and bind record.
"""

import hashlib
import os
import uuid

import bpy

from . import _lvp
from . import mesh_data
from . import node_group
from . import skeleton
from .bound_object import BoundObject
from .session import SESSION


# A frame whose largest offset exceeds this fraction of the rest mesh's bounding box diagonal is
# shown uncorrected: legitimate corrections are a few percent of the size of a character.
DISPLACEMENT_LIMIT = 0.25


REBIND_NEEDED = "Rebind needed: the mesh topology changed since the bind (press Bind)"


class BindError(Exception):
    """A user-facing reason why an object cannot be bound: what is wrong and how to fix it."""


def thread_count():
    return max(1, min(8, os.cpu_count() or 1))


# ---- what is bound, and how ----------------------------------------------------------------


def armature_of(obj):
    """(armature_modifier, armature_object) that Volume Preservation follows, or raises BindError."""
    if obj.type != 'MESH':
        raise BindError("%s is not a mesh (it is a %s object): select the character's mesh objects"
                        % (obj.name, obj.type.lower().replace("_", " ")))
    armature_modifier = node_group.find_armature_modifier(obj)
    if armature_modifier is None:
        raise BindError("%s has no Armature modifier: parent it to the armature with Ctrl+P > With Empty "
                        "Groups (or add an Armature modifier) first" % obj.name)
    armature_object = armature_modifier.object
    if armature_object is None or armature_object.type != 'ARMATURE':
        raise BindError("The Armature modifier %r of %s has no armature object: set its Object field"
                        % (armature_modifier.name, obj.name))
    return armature_modifier, armature_object


def _digest(*parts):
    hasher = hashlib.blake2b(digest_size=16)
    for part in parts:
        hasher.update(part if isinstance(part, bytes) else part.tobytes())
    return hasher.digest()


class BindInputs:
    """What a binding is made of, read from the object as it is now: the rest mesh, the bound bones
    (deforming, with a vertex group) and their weights, the Armature modifier's mask weights, the
    painted map. The weights are read by a Python loop over the vertices, too slow for every
    frame, so this is read when binding and when someone else changed the mesh (changes.py).

    digests: a hash per part ("rest mesh", "weights", "painted map"), to tell whether a binding is
    still made of the object's data (changed_parts)."""

    def __init__(self, obj, armature_modifier, armature_object):
        mesh = obj.data
        self.bone_names = skeleton.deforming_bone_names(obj, armature_object)
        self.positions = mesh_data.vertex_positions(mesh)
        self.weights = mesh_data.weights_csr(obj, self.bone_names)
        self.mask = skeleton.armature_mask(obj, armature_modifier)
        self.mask_values = mesh_data.vertex_group_values(obj, self.mask[0]) if self.mask is not None else None
        settings = obj.lvp
        self.painted_values = None
        if settings.effect == 'PAINTED':
            self.painted_values = mesh_data.vertex_group_values(obj, settings.painted_vertex_group)
        self.digests = {
            "rest mesh": _digest(self.positions),
            "weights": _digest("\n".join(self.bone_names).encode(), *self.weights,
                               self.mask_values if self.mask_values is not None else b""),
            "painted map": _digest(self.painted_values if self.painted_values is not None else b""),
        }

    def changed_parts(self, bound):
        """The parts whose digest differs from the ones bound was made of, in a fixed order."""
        return [part for part in ("weights", "rest mesh", "painted map")
                if bound.digests.get(part) != self.digests[part]]


def map_key(settings):
    """Everything in the settings that the binding's map depends on."""
    restrictions = tuple((item.region, item.bones) for item in settings.region_restrictions)
    return (settings.effect, round(settings.alpha, 6), round(settings.beta, 6), settings.painted_vertex_group,
            restrictions)


def mode_of(settings):
    return 'GLOBAL' if settings.effect == 'GLOBAL' else 'LOCAL'


def bulge_width_of(settings):
    """The core's bulge width: none in the global mode, where the one region is the whole mesh."""
    return 0.0 if mode_of(settings) == 'GLOBAL' else round(float(settings.bulge_width), 6)


def shape_of(settings):
    """The settings that the binding is built with and that only a new bind changes."""
    return (mode_of(settings), bulge_width_of(settings))


def map_arguments(obj, settings, core_skeleton, inputs=None):
    """Keyword arguments of Binding() / Binding.set_map() for the object's settings. inputs: a
    BindInputs just read (its painted map is used), else the painted map is read from obj.

    Raises BindError when the settings cannot be used (a missing painted vertex group).
    """
    arguments = {"alpha": float(settings.alpha), "beta": float(settings.beta)}
    if settings.effect == 'PAINTED':
        if inputs is not None:
            values = inputs.painted_values
        else:
            values = mesh_data.vertex_group_values(obj, settings.painted_vertex_group)
        if values is None:
            raise BindError("The Painted effect needs a vertex group: pick one in Painted Map (object %s has "
                            "no vertex group %r)" % (obj.name, settings.painted_vertex_group))
        arguments["map"] = 'PAINTED'
        arguments["painted"] = values
    elif settings.effect == 'RUBBER':
        arguments["map"] = 'RUBBER'
    else:  # ORGANIC, and GLOBAL, which uses the organic map over one region
        arguments["map"] = 'ORGANIC'
    restrictions = [item for item in settings.region_restrictions if item.region.strip()]
    if (restrictions or core_skeleton.still_bone is not None) and core_skeleton.bone_names:
        # Restrictions name bones; a B-Bone is several core bones (its joints), all restricted alike.
        per_region = [[] for _ in range(core_skeleton.core_bone_count)]
        for item in restrictions:
            regions = core_skeleton.core_bones_of(item.region.strip())
            if not regions:
                raise BindError("Region restriction: %r is not a deforming bone with a vertex group on %s"
                                % (item.region, obj.name))
            for name in item.bones.split(","):
                name = name.strip()
                if not name:
                    continue
                allowed = core_skeleton.core_bones_of(name)
                if not allowed:
                    raise BindError("Region restriction of %r: %r is not a deforming bone with a vertex group "
                                    "on %s" % (item.region, name, obj.name))
                for region in regions:
                    per_region[region].extend(bone for bone in allowed if bone not in per_region[region])
        if core_skeleton.still_bone is not None:
            # The still bone is no bone: distances go to the real ones only (skeleton.py).
            for region_bones in per_region:
                if not region_bones:
                    region_bones.extend(core_skeleton.real_core_bones)
        offsets = mesh_data.int_array(len(per_region) + 1)
        bones = mesh_data.int_array(0)
        for region, region_bones in enumerate(per_region):
            bones.extend(region_bones)
            offsets[region + 1] = len(bones)
        arguments["region_bone_offsets"] = offsets
        arguments["region_bones"] = bones
    return arguments


def _core_skeleton(obj, armature_object, depsgraph, inputs):
    """(CoreSkeleton of obj's bound bones, weights over its core bones: B-Bone weights split over
    their joints, the Armature modifier's mask applied). B-Bone joints are read from the armature's
    pose, which Blender fills when it evaluates the armature: from the evaluated armature of depsgraph
    when given (a render's depsgraph), else from the original, which the viewport's evaluation fills."""
    poses = []
    if depsgraph is not None:
        poses.append(armature_object.evaluated_get(depsgraph).pose)
    poses.append(armature_object.pose)
    for pose in poses:
        try:
            core_skeleton = skeleton.CoreSkeleton(obj, armature_object, inputs.bone_names, pose, inputs.mask)
            return core_skeleton, core_skeleton.core_weights(obj, pose, inputs.positions, *inputs.weights,
                                                             mask_values=inputs.mask_values)
        except RuntimeError:
            continue
    raise BindError("The B-Bone segments of %s have not been evaluated yet: change frame or pose a bone, then "
                    "Bind again" % armature_object.name)


def bind(obj, depsgraph=None, inputs=None):
    """Builds a BoundObject from the object's current mesh, weights, armature rest pose and settings.

    Changes no Blender data. Raises BindError (with what to fix) when the object cannot be bound.
    depsgraph: the one being evaluated, when binding from a handler. inputs: a BindInputs of obj
    just read (else it is read here).
    """
    settings = obj.lvp
    armature_modifier, armature_object = armature_of(obj)
    unfollowed = skeleton.unfollowed_armature_setting(armature_modifier)
    if unfollowed is not None:
        raise BindError("Cannot bind %s: %s" % (obj.name, unfollowed))
    if inputs is None:
        inputs = BindInputs(obj, armature_modifier, armature_object)
    bone_names = inputs.bone_names
    if not bone_names:
        raise BindError("No vertex group of %s matches a deforming bone of %s: weight the mesh (Ctrl+P > With "
                        "Automatic Weights, or Local Volume Preservation's Auto Weights) first"
                        % (obj.name, armature_object.name))
    mesh = obj.data
    if len(mesh.vertices) == 0 or len(mesh.polygons) == 0:
        raise BindError("%s has no faces: Volume Preservation needs a surface mesh" % obj.name)
    positions = inputs.positions
    triangles = mesh_data.loop_triangles(mesh)
    offsets, bones, values = inputs.weights
    if len(values) == 0:
        raise BindError("The vertex groups of %s that match deforming bones of %s are empty: weight the mesh "
                        "first" % (obj.name, armature_object.name))
    unweighted = sum(1 for vertex in range(len(offsets) - 1) if offsets[vertex] == offsets[vertex + 1])
    core_skeleton, (offsets, bones, values) = _core_skeleton(obj, armature_object, depsgraph, inputs)
    rest_matrices, heads, tails = core_skeleton.rest_arrays()
    shape = shape_of(settings)
    # The skin the Armature modifier's vertex group keeps still is a bone of its own to the core (the
    # still bone): a bulge spread over the surface would reach it and move it. The panel greys the
    # setting out there.
    bulge_width = shape[1] if core_skeleton.still_bone is None else 0.0
    try:
        binding = _lvp.Binding(positions, triangles, offsets, bones, values, rest_matrices, heads, tails,
                               mode=shape[0], threads=thread_count(), bone_groups=core_skeleton.bone_groups(),
                               parents=core_skeleton.parents(),
                               bulge_width=bulge_width, **map_arguments(obj, settings, core_skeleton, inputs))
    except _lvp.Error as error:
        message = str(error)
        if error.code == "mesh_not_closed":
            message = ("The Global effect needs a closed mesh and %s has holes: use Organic (per region), or "
                       "close the mesh. (%s)" % (obj.name, message))
        raise BindError("Cannot bind %s: %s" % (obj.name, message)) from None
    except MemoryError:
        raise BindError("Not enough memory to bind %s" % obj.name) from None
    return BoundObject(binding, core_skeleton, len(mesh.vertices), mesh_data.topology_signature(mesh),
                       settings.bind_id, map_key(settings), shape, digests=inputs.digests,
                       displacement_limit=DISPLACEMENT_LIMIT * mesh_data.bounding_box_diagonal(positions),
                       unweighted_vertices=unweighted, stray_vertex=stray_vertex(positions, heads, tails))


# A vertex farther than this many times the armature's size from its bones' box is taken for a stray.
STRAY_DISTANCE = 10.0


def stray_vertex(positions, heads, tails):
    """(index, distance) of the vertex farthest outside the box of the bones' heads and tails, when it
    is more than STRAY_DISTANCE times the box's diagonal outside it, else None. Such a vertex (one
    moved far away by mistake, or Inf typed into a field) makes its region's volume mostly its own,
    so its region is measured wrong. Cheap when there is none: six max/min over the coordinates."""
    ends = list(heads) + list(tails)
    low = [min(ends[axis::3]) for axis in range(3)]
    high = [max(ends[axis::3]) for axis in range(3)]
    margin = STRAY_DISTANCE * max(sum((high[axis] - low[axis]) ** 2 for axis in range(3)) ** 0.5, 1e-6)
    if all(min(positions[axis::3]) >= low[axis] - margin and max(positions[axis::3]) <= high[axis] + margin
           for axis in range(3)):
        return None
    farthest, index = 0.0, -1
    for vertex in range(len(positions) // 3):
        outside = sum(max(low[axis] - positions[3 * vertex + axis], positions[3 * vertex + axis] - high[axis], 0.0)
                      ** 2 for axis in range(3)) ** 0.5
        if outside > farthest:
            farthest, index = outside, vertex
    return index, farthest


# The rule a binding is made by, recorded with each bind: a record of an earlier rule is bound by this one
# when the file is opened, and the panel says so (RULE_CHANGED) until the next Bind. 1: each bone's line
# comes from the joints and its skin, not from its tail (lvp.h, BONE LINES); 0: files bound before.
BIND_RULE = 1
RULE_CHANGED = ("this file was bound by an earlier version, whose correction followed the bones' tails; "
                "it now follows the joints (press Bind to record it)")


def _rule_changed(obj):
    """RULE_CHANGED when obj's bind record was made by an earlier rule, else None."""
    return RULE_CHANGED if obj.lvp.bind_rule < BIND_RULE else None


def new_bind_record(obj, bound):
    """Stores a fresh bind record on the object for bound and caches it (operators only)."""
    SESSION.forget(obj)
    SESSION.changes.expect_own_update(obj)  # bound was made of the mesh as it is now
    obj.lvp.bind_id = uuid.uuid4().hex
    obj.lvp.topology_signature = bound.topology
    obj.lvp.bind_rule = BIND_RULE
    bound.recorded_as(obj.lvp.bind_id)
    SESSION.keep(obj, bound)


def ensure(obj, depsgraph=None):
    """The object's BoundObject, rebuilt lazily when missing (after a file load, undo, rename).
    depsgraph: the one being evaluated, when called from a handler.

    Returns None and sets the status when that is not possible: no bind record, the topology
    changed since the bind ("rebind needed"), or the object can no longer be bound.
    """
    settings = obj.lvp
    if not settings.bind_id:
        SESSION.set_status(obj, 'ERROR', "Not bound: press Bind")
        return None
    bound = SESSION.bound(obj)
    if bound is not None:
        if bound.topology != settings.topology_signature:
            SESSION.set_status(obj, 'ERROR', REBIND_NEEDED)
            return None
        return bound
    # Lazy rebuild: only for the topology that was bound.
    signature = mesh_data.topology_signature(obj.data)
    if signature != settings.topology_signature:
        SESSION.set_status(obj, 'ERROR', REBIND_NEEDED)
        return None
    try:
        bound = bind(obj, depsgraph)
    except BindError as error:
        SESSION.set_status(obj, 'ERROR', str(error))
        return None
    bound.recorded_as(settings.bind_id, _rule_changed(obj))
    SESSION.keep(obj, bound)
    # Lazy binds are rare (file load, undo, rename): a good moment to drop the bindings of objects
    # that were renamed or deleted.
    SESSION.prune(bpy.data.objects)
    return bound


def refresh_map(obj, bound, depsgraph=None, inputs=None):
    """Applies changed map settings to the binding. Returns the BoundObject to use (a new one when the
    effect switched between local and global or the bulge width changed), or None with the status set
    when it cannot be done. inputs: a BindInputs of obj just read (its painted map is used), or None."""
    settings = obj.lvp
    key = map_key(settings)
    if shape_of(settings) != bound.shape:
        return rebind(obj, bound, depsgraph, inputs=inputs)
    if key == bound.map_key:
        return bound
    try:
        bound.binding.set_map(**map_arguments(obj, settings, bound.skeleton, inputs))
    except (BindError, ValueError) as error:
        SESSION.set_status(obj, 'ERROR', str(error))
        return None
    bound.map_set(key)
    return bound


def rebind(obj, bound, depsgraph=None, reason=None, inputs=None):
    """Replaces bound by a new binding of obj's current data under the same bind record: what a
    reopened file would bind. reason: why (kept as rebound_because, which the panel shows); inputs:
    a BindInputs of obj just read. Returns the new BoundObject, or None with the status set when
    obj cannot be bound any more (the old binding is dropped either way)."""
    SESSION.drop(obj, bound)
    if mesh_data.topology_signature(obj.data) != obj.lvp.topology_signature:
        # The bind record is of another topology: what was bound no longer maps onto the mesh vertex for
        # vertex, and a reopened file would not bind either. Only the artist's Bind makes a new record.
        SESSION.set_status(obj, 'ERROR', REBIND_NEEDED)
        return None
    try:
        rebound = bind(obj, depsgraph, inputs)
    except BindError as error:
        SESSION.set_status(obj, 'ERROR', str(error))
        return None
    rebound.recorded_as(bound.bind_id, reason or _rule_changed(obj))
    SESSION.keep(obj, rebound)
    return rebound
