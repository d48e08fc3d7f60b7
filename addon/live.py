# SPDX-License-Identifier: GPL-3.0-or-later
"""Correcting one object for one depsgraph: the work the handlers do per frame and per pose change.

    evaluated mesh of the depsgraph --(captured positions, original indices)--> positions[N]
    evaluated armature and objects --(posed bone frames in mesh space)------> bone_matrices[B]
    Binding.correct(positions, bone_matrices) -------------------------------> offsets[N]
    offsets --> the "lvp_offset" attribute of the ORIGINAL mesh, then the mesh is tagged, so
    Blender evaluates the object once more and the same frame shows the corrected shape.

Reading the positions back. Without a topology-changing modifier after ours, the evaluated mesh
has the original N vertices in their order. With a Subdivision Surface modifier after ours, the
evaluated mesh is the subdivided one: Blender puts the original (corner) vertices first, in order,
and copies their attributes, so "lvp_index" reads 0..N-1 on the first N vertices and the captured
positions there are exactly the ones that entered our modifier; every other vertex interpolates
indices that stay within [0, N). That is checked on every frame: when it does not hold (a Remesh or
Decimate after ours), nothing is guessed, the offsets are zeroed (pass-through) and the panel says
why. With GPU subdivision in the viewport, the CPU mesh is not subdivided at all.
"""

import threading

from . import bindings
from . import mesh_data
from . import names
from . import node_group


def _read_vector_attribute(attribute, out):
    attribute.data.foreach_get("vector", out)


def _evaluated_positions(mesh_eval, bound):
    """Fills bound.positions from the evaluated mesh. Returns None on success, else the reason."""
    position_attribute = mesh_eval.attributes.get(names.CAPTURED_POSITION_ATTRIBUTE)
    if position_attribute is None or position_attribute.domain != 'POINT':
        return "the modifier produced no data (a modifier after it may have removed its attributes)"
    vertex_count = bound.vertex_count
    evaluated_count = len(mesh_eval.vertices)
    if evaluated_count == vertex_count:
        index_attribute = mesh_eval.attributes.get(names.CAPTURED_INDEX_ATTRIBUTE)
        if index_attribute is not None:
            if bound.expected_indices is None:
                bound.expected_indices = mesh_data.int_array(vertex_count)
                for index in range(vertex_count):
                    bound.expected_indices[index] = index
            indices = mesh_data.int_array(vertex_count)
            index_attribute.data.foreach_get("value", indices)
            if indices != bound.expected_indices:
                return ("the modifiers before Volume Preservation reorder or change the vertices (it must "
                        "come right after the Armature modifier, with only deforming modifiers before that)")
        _read_vector_attribute(position_attribute, bound.positions)
        return None
    if evaluated_count < vertex_count:
        return ("the final mesh has %d vertices, fewer than the %d that were bound: a modifier before the "
                "Armature modifier or after Volume Preservation removes vertices" % (evaluated_count, vertex_count))
    index_attribute = mesh_eval.attributes.get(names.CAPTURED_INDEX_ATTRIBUTE)
    if index_attribute is None or index_attribute.domain != 'POINT':
        return ("a modifier after Volume Preservation changes the topology and drops its attributes: move it "
                "above, or use Subdivision Surface")
    indices = mesh_data.int_array(evaluated_count)
    index_attribute.data.foreach_get("value", indices)
    if bound.expected_indices is None:
        bound.expected_indices = mesh_data.int_array(vertex_count)
        for index in range(vertex_count):
            bound.expected_indices[index] = index
    if indices[:vertex_count] != bound.expected_indices or max(indices) >= vertex_count or min(indices) < 0:
        return ("a modifier changes the topology in a way that loses the original vertices (Subdivision Surface "
                "after Volume Preservation works; Remesh, Decimate and the like do not)")
    captured = mesh_data.float_array(3 * evaluated_count)
    _read_vector_attribute(position_attribute, captured)
    bound.positions[:] = captured[:3 * vertex_count]
    return None


def _offset_attribute(mesh, create):
    attribute = mesh.attributes.get(names.OFFSET_ATTRIBUTE)
    if attribute is not None and (attribute.domain != 'POINT' or attribute.data_type != 'FLOAT_VECTOR'):
        if not create:
            return None
        mesh.attributes.remove(attribute)
        attribute = None
    if attribute is None and create:
        attribute = mesh.attributes.new(names.OFFSET_ATTRIBUTE, 'FLOAT_VECTOR', 'POINT')
    return attribute


def write_offsets(mesh, offsets):
    """Writes offsets into the original mesh's offset attribute when they differ from what it holds,
    and tags the mesh for a new evaluation. Returns whether anything was written."""
    attribute = _offset_attribute(mesh, create=True)
    current = mesh_data.float_array(3 * len(mesh.vertices))
    attribute.data.foreach_get("vector", current)
    if current == offsets:
        return False
    attribute.data.foreach_set("vector", offsets)
    mesh.update_tag()
    return True


def write_zero_offsets(mesh):
    """Pass-through: the modifier then adds nothing. Returns whether anything was written."""
    attribute = _offset_attribute(mesh, create=False)
    if attribute is None:
        return False
    zeros = mesh_data.float_array(3 * len(mesh.vertices))
    return write_offsets(mesh, zeros)


def is_main_thread():
    return threading.current_thread() is threading.main_thread()


def correct_object(obj, depsgraph, check_topology=False):
    """Corrects obj as evaluated in depsgraph. Returns whether the original mesh was written.

    Never raises for bad input: every problem becomes the object's status and a pass-through.
    """
    modifier = node_group.find_modifier(obj)
    if modifier is None:
        return False
    mesh = obj.data
    if mesh.library is not None or getattr(mesh, "override_library", None) is not None:
        bindings.set_status(obj, 'WARNING', "The mesh is linked from a library: its volume cannot be corrected "
                                            "here (make it local)")
        return False
    if obj.mode == 'EDIT':
        bindings.set_status(obj, 'INFO', "Paused in Edit Mode")
        return False
    if not node_group.modifier_enabled(modifier, depsgraph.mode):
        bindings.set_status(obj, 'INFO', "The modifier is disabled in the %s" %
                            ("render" if depsgraph.mode == 'RENDER' else "viewport"))
        return False

    bound = bindings.ensure(obj)
    if bound is None:
        return write_zero_offsets(mesh)
    if mesh_data.quick_topology_counts(mesh) != bound.topology.rsplit(" ", 1)[0] or (
            check_topology and mesh_data.topology_signature(mesh) != bound.topology):
        bindings.set_status(obj, 'ERROR', "Rebind needed: the mesh topology changed since the bind (press Bind)")
        return write_zero_offsets(mesh)
    bound = bindings.refresh_map(obj, bound)
    if bound is None:
        return write_zero_offsets(mesh)

    armature_modifier = node_group.find_armature_modifier(obj)
    armature_object = armature_modifier.object if armature_modifier is not None else None
    if armature_object is None or armature_object.type != 'ARMATURE':
        bindings.set_status(obj, 'ERROR', "No Armature modifier with an armature before Volume Preservation: "
                                          "move it right after the Armature modifier, or remove it")
        return write_zero_offsets(mesh)

    obj_eval = obj.evaluated_get(depsgraph)
    armature_eval = armature_object.evaluated_get(depsgraph)
    mesh_eval = obj_eval.data
    problem = _evaluated_positions(mesh_eval, bound)
    if problem is not None:
        bindings.set_status(obj, 'ERROR', "Passing the mesh through: " + problem)
        return write_zero_offsets(mesh)
    if not mesh_data.posed_bone_matrices(bound.bone_matrices, obj_eval, armature_eval, bound.bone_names,
                                         bound.rest_frames):
        bindings.set_status(obj, 'ERROR', "Rebind needed: a bound bone is missing from %s" % armature_object.name)
        return write_zero_offsets(mesh)

    rest_positions = None
    if mesh.shape_keys is not None:
        if bound.rest_positions is None:
            bound.rest_positions = mesh_data.float_array(3 * bound.vertex_count)
        base = mesh_data.vertex_positions(mesh)
        if mesh_data.shape_key_rest_positions(obj, base, bound.rest_positions):
            rest_positions = bound.rest_positions

    settings = obj.lvp
    try:
        stats = bound.binding.correct(bound.positions, bound.bone_matrices, out_offsets=bound.offsets,
                                      rest_positions=rest_positions, iterations=settings.iterations,
                                      fold_over=settings.fold_over and bound.mode == 'LOCAL')
    except (ValueError, MemoryError) as error:
        bindings.set_status(obj, 'ERROR', "Passing the mesh through: %s" % error)
        return write_zero_offsets(mesh)
    stats["bone_names"] = bound.bone_names
    stats["mode"] = bound.mode
    bound.stats = stats
    displacement = stats["max_displacement"]
    if not displacement <= bound.displacement_limit:  # also catches NaN
        # A safety net, not a feature: never show a blown-up mesh to the animator.
        bindings.set_status(obj, 'WARNING', "The correction diverged at this pose (largest offset %.3g, above %.3g, "
                                            "a quarter of the mesh size): showing plain skinning for this frame"
                            % (displacement, bound.displacement_limit))
        return write_zero_offsets(mesh)
    bindings.set_status(obj, 'INFO', "Correcting")
    return write_offsets(mesh, bound.offsets)
