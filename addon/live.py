# SPDX-License-Identifier: GPL-3.0-or-later
"""Correcting one object for one depsgraph: the work the handlers do per frame and per pose change.

    evaluated mesh of the depsgraph --(captured positions, original indices)--> positions[N]
    evaluated armature and objects --(posed bone frames in mesh space)------> bone_matrices[B]
                                     (a B-Bone: one per segment joint, skeleton.py)
    Binding.correct(positions, bone_matrices) -------------------------------> offsets[N]
    offsets --> the object's offsets object (offsets.py), whose mesh is then tagged, so Blender
    evaluates the object once more and the same frame shows the corrected shape.

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
from . import blender_api
from . import display
from . import mesh_data
from . import names
from . import node_group
from . import offsets
from . import skeleton
from .session import SESSION


def _evaluated_positions(mesh_eval, bound, stack):
    """Fills bound.positions from the evaluated mesh. Returns None on success, else the reason.
    stack: the modifier stack's signature (node_group.stack_signature)."""
    attributes = mesh_eval.attributes
    position_attribute = attributes.get(names.CAPTURED_POSITION_ATTRIBUTE)
    if position_attribute is None or position_attribute.domain != 'POINT':
        return "the modifier produced no data (a modifier after it may have removed its attributes)"
    index_attribute = attributes.get(names.CAPTURED_INDEX_ATTRIBUTE)
    if index_attribute is not None and index_attribute.domain != 'POINT':
        index_attribute = None
    vertex_count = bound.vertex_count
    evaluated_count = len(mesh_eval.vertices)
    if evaluated_count < vertex_count:
        return ("the final mesh has %d vertices, fewer than the %d that were bound: a modifier before the "
                "Armature modifier or after Volume Preservation removes vertices" % (evaluated_count, vertex_count))
    if evaluated_count > vertex_count and index_attribute is None:
        return ("a modifier after Volume Preservation changes the topology and drops its attributes: move it "
                "above, or use Subdivision Surface")
    if index_attribute is not None:
        indices = bound.scratch("indices", 'i', evaluated_count)
        index_attribute.data.foreach_get("value", indices)
        expected = bound.identity_indices()
        if not mesh_data.same_values(indices if evaluated_count == vertex_count else indices[:vertex_count], expected):
            return ("the vertices that leave Volume Preservation are not the bound ones in order (a modifier before "
                    "the Armature modifier changes them, or one after Volume Preservation reorders them)")
        if evaluated_count != vertex_count and bound.mapping_checked != (evaluated_count, stack):
            # Once per topology of the final mesh and layout of the stack (a Subdivision Surface moved
            # from after ours to before the Armature modifier keeps the vertex count): every vertex
            # comes from the bound ones.
            if max(indices) >= vertex_count or min(indices) < 0:
                return ("the mesh entering Volume Preservation has more vertices than were bound: a modifier "
                        "before the Armature modifier adds vertices")
            bound.note_mapping_checked(evaluated_count, stack)
    if evaluated_count == vertex_count:
        position_attribute.data.foreach_get("vector", bound.positions)
    else:
        captured = bound.scratch("positions", 'f', 3 * evaluated_count)
        position_attribute.data.foreach_get("vector", captured)
        bound.positions[:] = captured[:3 * vertex_count]
    return None


def evaluated_problem(obj, depsgraph, bound):
    """Why obj's evaluated mesh cannot be corrected with bound (a modifier before the Armature modifier
    that adds vertices, one after ours that changes the topology...), or None when it can."""
    return _evaluated_positions(obj.evaluated_get(depsgraph).data, bound, node_group.stack_signature(obj))


def _shape_key_rest(obj, bound, mesh_changed):
    """This frame's un-skinned positions with shape keys (None when they change nothing), cached
    while the key values stay the same and nobody edited the mesh."""
    mesh = obj.data
    keys = mesh.shape_keys
    state = (obj.show_only_shape_key, keys.use_relative,
             tuple((block.name, block.value, block.mute, block.vertex_group,
                    block.relative_key.name if block.relative_key is not None else "")
                   for block in keys.key_blocks))
    return bound.shape_key_rest(state, mesh_changed, lambda rest: mesh_data.shape_key_rest_positions(
        obj, mesh_data.vertex_positions(mesh), rest))


def _follow_changes(obj, bound, depsgraph, armature_modifier, armature_object):
    """bound, or a new binding of obj when what bound was made of changed since: what a reopened file
    or a render farm would bind, so that the viewport shows what they will. None when obj cannot be
    bound any more (the status says why).

    Checked every frame (cheap): the armature, the Armature modifier's mask group, the bound bones
    and their rest pose and B-Bone settings. Checked when someone else changed the mesh, once the
    changes paused (changes.py): the weights, the rest mesh, the painted map. A changed painted map
    alone only has the map set again (by refresh_map).

    Returns (the BoundObject to use or None, the bindings.BindInputs read, or None).
    """
    reason = bound.skeleton.changed(obj, armature_object, skeleton.armature_mask(obj, armature_modifier))
    inputs = None
    if reason is None and SESSION.changes.take_due(obj):
        inputs = bindings.BindInputs(obj, armature_modifier, armature_object)
        parts = inputs.changed_parts(bound)
        if parts == ["painted map"]:
            bound.painted_map_changed(inputs.digests)  # refresh_map sets the map again, from inputs
        elif parts:
            reason = "the %s changed" % " and the ".join(parts)
    if reason is None:
        return bound, inputs
    return bindings.rebind(obj, bound, depsgraph, reason, inputs), inputs


def is_main_thread():
    return threading.current_thread() is threading.main_thread()


class LeftAlone(Exception):
    """Why obj is left as it is this time (nothing written): its status."""

    def __init__(self, message, level='INFO'):
        super().__init__(message)
        self.message = message
        self.level = level


class PassThrough(Exception):
    """Why obj's mesh is shown as plain skinning this frame. message: the object's status, or None
    when the binding code already set it (bindings.ensure, rebind, refresh_map); reason, where given:
    the cause alone, to go inside another sentence."""

    def __init__(self, message=None, level='ERROR', reason=None):
        super().__init__(message)
        self.message = message
        self.level = level
        self.reason = reason


def correct_object(obj, depsgraph, check_topology=False):
    """Corrects obj as evaluated in depsgraph. Returns whether its offsets object was written.

    Never raises for bad input: every problem becomes the object's status and, once the object is
    corrected at all, a pass-through (zero offsets), so that the panel always says what is shown.
    Preconditions: obj has a modifier, and is not left alone this time (_modifier_to_run). The
    computation, each stage raising PassThrough: the binding (_current_binding), where the offsets go
    (_holder), the rig (_armature), the binding following the object's changes (_following_changes),
    the evaluated positions and bones (_read_pose), the core (_correct). Then the status of what was
    written (_status_of_correction).
    """
    modifier = node_group.find_modifier(obj)
    if modifier is None:
        return False
    try:
        modifier = _modifier_to_run(obj, modifier, depsgraph, check_topology)
    except LeftAlone as why:
        SESSION.set_status(obj, why.level, why.message)
        return False

    bound = None
    try:
        bound = _current_binding(obj, depsgraph, check_topology)
        holder = _holder(obj, modifier, bound)
        armature_modifier, armature_object = _armature(obj, depsgraph)
        bound = _following_changes(obj, bound, depsgraph, armature_modifier, armature_object)
        if bound is None:
            raise PassThrough()  # the status says why (bindings.rebind, refresh_map)
        _read_pose(obj, depsgraph, bound, armature_object)
        stats = _correct(obj, bound, check_topology, _for_final_output(depsgraph))
    except PassThrough as why:
        if why.message is not None:
            SESSION.set_status(obj, why.level, why.message)
        return offsets.write_zeros(obj, modifier, bound)

    SESSION.set_status(obj, *_status_of_correction(obj, depsgraph, bound, stats, armature_modifier))
    return offsets.write(holder, bound.offsets, bound)


def _modifier_to_run(obj, modifier, depsgraph, check_topology):
    """obj's modifier, its node group rebuilt when it is not the add-on's (on the main thread). Raises
    LeftAlone when obj is left as it is this time."""
    if not node_group.is_current(modifier.node_group):
        # Deleted or edited by hand: what it does is no longer the correction the panel reports.
        if not is_main_thread():
            raise LeftAlone("The modifier's node group was deleted or edited: it is rebuilt at the next frame "
                            "shown in the viewport", 'ERROR')
        node_group.repair_modifiers([obj])
        modifier = node_group.find_modifier(obj)
    if check_topology:
        # Noted before anything returns early (Edit Mode, the modifier hidden): checked when corrected.
        SESSION.note_mesh_changed(obj)
    if obj.mode in {'EDIT', 'SCULPT'}:
        # Those modes own the mesh data while they run; writing it from a handler would fight them.
        raise LeftAlone("Paused in %s Mode" % obj.mode.title())
    if not node_group.modifier_enabled(modifier, depsgraph.mode):
        raise LeftAlone("The modifier is disabled in the %s" % _mode_name(depsgraph))
    return modifier


def _following_changes(obj, bound, depsgraph, armature_modifier, armature_object):
    """bound, or the binding that replaced it because the object changed (_follow_changes) or its map
    settings did (bindings.refresh_map), the display's colours following it; None when obj cannot be
    bound any more (the status says why)."""
    previous_map = bound.map_key
    followed, inputs = _follow_changes(obj, bound, depsgraph, armature_modifier, armature_object)
    if followed is not None:
        followed = bindings.refresh_map(obj, followed, depsgraph, inputs)
    if followed is not None:
        _follow_display(obj, followed, bound, previous_map)
    return followed


def _follow_display(obj, bound, previous_bound, previous_map):
    """The display's colours follow the binding, alpha, beta and the effect (on the main thread)."""
    settings = obj.lvp
    if is_main_thread() and (settings.display != 'NONE' and bound is not previous_bound or
                             settings.display == 'CORRECTION_MAP' and bound.map_key != previous_map):
        display.update_display(obj)


def _for_final_output(depsgraph):
    """Whether this correction is seen in a render or written by a bake (the render settings apply) rather
    than in the viewport."""
    return depsgraph.mode == 'RENDER' or SESSION.baking


def _mode_name(depsgraph):
    return "render" if depsgraph.mode == 'RENDER' else "viewport"


def _current_binding(obj, depsgraph, check_topology):
    """obj's binding, when it still maps onto the mesh vertex for vertex."""
    bound = bindings.ensure(obj, depsgraph)
    if bound is None:
        raise PassThrough()
    # The counts are cheap to compare every frame; the whole topology is read when the mesh changed.
    # What was found holds until the mesh changes again (undone, the binding follows again) or the
    # artist binds: a changed topology is never left for a later frame to forget.
    mesh = obj.data
    counts_changed = mesh_data.quick_topology_counts(mesh) != bound.topology.rsplit(" ", 1)[0]
    if counts_changed or check_topology:
        bound.note_topology(counts_changed or mesh_data.topology_signature(mesh) != bound.topology)
    if bound.topology_changed:
        raise PassThrough(bindings.REBIND_NEEDED)
    return bound


def _holder(obj, modifier, bound):
    """The offsets object obj writes (made when it has none of its own, on the main thread)."""
    holder = offsets.usable_offsets_object(obj, modifier, bound.vertex_count)
    if holder is None:
        if not is_main_thread():
            raise PassThrough("Passing the mesh through: %s has no offsets object of its own, which is made on the "
                              "main thread (render once from the viewport, or press Bind)" % obj.name)
        holder = offsets.new_offsets_object(obj, modifier, bound.vertex_count)
        bound.forget_written()
    if node_group.count_modifiers(obj) > 1:
        # A copy (Duplicate Modifier) would capture the corrected shape and add the offsets again.
        raise PassThrough("Passing the mesh through: %s has more than one Volume Preservation modifier; remove "
                          "the copies" % obj.name)
    return holder


def _armature(obj, depsgraph):
    """(Armature modifier, armature object) that pose the mesh entering Volume Preservation."""
    armature_modifier = node_group.find_armature_modifier(obj)
    if armature_modifier is None:
        raise PassThrough("No Armature modifier before Volume Preservation: move Volume Preservation right after "
                          "the Armature modifier, or remove it")
    armature_object = armature_modifier.object
    if armature_object is None or armature_object.type != 'ARMATURE':
        raise PassThrough("The Armature modifier %r has no armature object: set its Object field"
                          % armature_modifier.name)
    if not node_group.modifier_enabled(armature_modifier, depsgraph.mode):
        # The mesh enters Volume Preservation unposed: the bones' pose is not what it shows.
        raise PassThrough("Passing the mesh through: the Armature modifier %r is disabled in the %s, so the mesh is "
                          "not posed" % (armature_modifier.name, _mode_name(depsgraph)), 'INFO')
    unfollowed = skeleton.unfollowed_armature_setting(armature_modifier)
    if unfollowed is not None:
        raise PassThrough("Passing the mesh through: " + unfollowed)
    return armature_modifier, armature_object


def _read_pose(obj, depsgraph, bound, armature_object):
    """The positions entering Volume Preservation and the posed bones, into bound."""
    problem = evaluated_problem(obj, depsgraph, bound)
    if problem is not None:
        raise PassThrough("Passing the mesh through: " + problem)
    problem = bound.skeleton.posed_matrices(bound.bone_matrices, obj.evaluated_get(depsgraph),
                                            armature_object.evaluated_get(depsgraph))
    if problem is not None:
        raise PassThrough("Passing the mesh through: " + problem)


def _correct(obj, bound, check_topology, final_output):
    """The core's correction of bound.positions into bound.offsets, with the render settings when
    final_output (a render, a bake); its statistics. Where Fold-Over Prevention fails at this pose (no
    finite result, or a blown-up one), the frame is corrected without it, and stats["fold_over_failed"]
    says why, rather than the whole mesh falling back to plain skinning."""
    rest_positions = None
    if obj.data.shape_keys is not None:
        rest_positions = _shape_key_rest(obj, bound, check_topology)
    fold_over = obj.lvp.fold_over and bound.mode == 'LOCAL'
    keep_apart = obj.lvp.keep_apart_render if final_output else _keep_apart_in_viewport(obj.lvp)
    stats, failure = _core_correction(obj, bound, rest_positions, fold_over, keep_apart)
    if failure is not None and fold_over:
        stats, without = _core_correction(obj, bound, rest_positions, False, keep_apart)
        if without is None:
            stats["fold_over_failed"] = failure.reason
        failure = without
    bound.note_corrected(stats)
    if failure is not None:
        raise failure
    return stats


def _keep_apart_in_viewport(settings):
    """Whether the viewport's correction keeps skin apart now: its Viewport setting, unless that is only for a still
    frame and an animation is playing (handlers.animation_playback_post corrects the frame it stops on again)."""
    return settings.keep_apart and not (settings.keep_apart_paused_only and blender_api.animation_playing())


def _core_correction(obj, bound, rest_positions, fold_over, keep_apart):
    """(stats, None) for a correction that may be shown, or (stats, PassThrough) saying why not."""
    settings = obj.lvp
    try:
        stats = bound.binding.correct(bound.positions, bound.bone_matrices, out_offsets=bound.offsets,
                                      rest_positions=rest_positions, rigid_space=bound.skeleton.rigid_space,
                                      iterations=settings.iterations, tolerance=settings.tolerance / 100.0,
                                      fold_over=fold_over, displacement_limit=bound.displacement_limit,
                                      restore=settings.restore, keep_apart=keep_apart,
                                      smoothing_passes=settings.smoothing)
    except (ValueError, MemoryError) as error:
        raise PassThrough("Passing the mesh through: %s" % error) from None
    stats["worst_region_name"] = bound.skeleton.region_name(stats["worst_region"])
    stats["given_up_region_name"] = bound.skeleton.region_name(stats["given_up_region"])
    stats["mode"] = bound.mode
    if stats["passed_through"]:
        reason = "no finite correction exists at this pose (a joint folded onto itself?)"
        return stats, PassThrough("Passing the mesh through: " + reason, 'WARNING', reason)
    rest = stats["volume_rest"]
    if stats["unskinned_distance"] > 0.0 and abs(stats["volume_after"] - rest) > abs(stats["volume_before"] - rest):
        # Positions that are not the bound skinning (an evaluation older than the weights) are measured
        # right, but the map and the regions are the binding's: when that made things worse, show none.
        reason = _not_the_bound_skinning(obj, stats)
        return stats, PassThrough("Passing the mesh through: " + reason, 'WARNING', reason)
    displacement = stats["max_displacement"]
    if not displacement <= bound.displacement_limit:  # also catches NaN
        # A safety net, not a feature: never show a blown-up mesh to the animator.
        diverged = ("diverged at this pose (largest offset %.3g, above %.3g, a quarter of the mesh size)"
                    % (displacement, bound.displacement_limit))
        return stats, PassThrough("The correction %s: showing plain skinning for this frame" % diverged, 'WARNING',
                                  "it " + diverged)
    return stats, None


def _deformed_by_parent(obj):
    """Whether Blender deforms obj by its parent armature (Parent Type: Armature), with a modifier of
    its own before the stack's: with an Armature modifier too, the mesh is deformed twice."""
    return obj.parent is not None and obj.parent.type == 'ARMATURE' and obj.parent_type == 'ARMATURE'


def _not_the_bound_skinning(obj, stats):
    """What the core found (stats.unskinned_distance) when the positions are not the bound skinning,
    with its likeliest cause and fix."""
    if _deformed_by_parent(obj):
        return ("its parent armature deforms it too (Object Properties > Relations > Parent Type: Armature), "
                "before the Armature modifier does: set Parent Type to Object")
    return ("the mesh entering Volume Preservation is not the skinning of the bound mesh by these bones (off by up "
            "to %.3g): press Bind if the weights or the rig changed" % stats["unskinned_distance"])


# The shown volume may end this far from the rest (a share of it) before the panel warns: "Correcting" alone
# means the volume is back.
SHORTFALL = 0.005


def _volume_shortfall(stats):
    """What is left when the correction did not bring the volume back at this pose, past SHORTFALL of the rest
    volume (a map that cannot move the skin there, steps that made things worse and were undone), with the region
    furthest from its own, or None. Not in frames where bones scale: their volume is not the rest's."""
    rest = stats["volume_rest"]
    if not rest or stats.get("bones_scale"):
        return None
    before, after = (stats[key] / rest - 1.0 for key in ("volume_before", "volume_after"))
    if abs(after) <= SHORTFALL:
        return None
    return ("the volume comes back only from %+.2f %% to %+.2f %% at this pose (region %s: %+.2f %%): the map "
            "cannot move the skin there, or the correction's steps made it worse"
            % (100.0 * before, 100.0 * after, stats["worst_region_name"], 100.0 * stats["worst_region_change_after"]))


def _given_up(stats):
    """Which regions the core left as plain skinning at this pose, and why (lvp.h, DEGRADING), or None."""
    count = stats["given_up_regions"]
    if not count:
        return None
    others = " and %d more" % (count - 1) if count > 1 else ""
    why = ("its correction moved the skin too far (a joint folded onto itself?)" if stats["given_up_diverged"]
           else "its volume could not be brought back, and its steps held back the others' (a joint folded onto "
                "itself?)")
    rest = "the rest corrected" if stats["active_regions"] > 0 else "and no other region corrected either"
    return ("region %s%s left as plain skinning at this pose, %s: %s"
            % (stats["given_up_region_name"], others, rest, why))


def _status_of_correction(obj, depsgraph, bound, stats, armature_modifier):
    """(level, message) of a frame corrected with stats: "Correcting", and what holds it back."""
    warnings = []
    unseen = node_group.modifiers_before(obj, armature_modifier, depsgraph.mode)
    if unseen:
        warnings.append("the bind does not see %s before the Armature modifier: the volume aimed at is the mesh's "
                        "without it (apply it, or move it after Volume Preservation)"
                        % ", ".join("%r" % modifier.name for modifier in unseen))
    if armature_modifier.use_bone_envelopes and bound.unweighted_vertices:
        # Blender moves vertices without vertex group weight by the bones' envelopes; the core does
        # not correct them (they are in no region), but measures them where Blender put them.
        warnings.append("%d vertices without weights move by bone envelopes, which the correction leaves alone "
                        "(weight them, or turn off Bind To: Bone Envelopes)" % bound.unweighted_vertices)
    if stats["unskinned_distance"] > 0.0 or _deformed_by_parent(obj):
        slow = " (measured the slow way)" if stats["unskinned_distance"] > 0.0 else ""
        warnings.append(_not_the_bound_skinning(obj, stats) + slow)
    if bound.stray_vertex is not None:
        vertex, distance = bound.stray_vertex
        warnings.append("vertex %d lies %.3g away from the armature, a stray? Its region's volume is measured "
                        "wrong; move it back or delete it, then Bind" % (vertex, distance))
    if stats.get("fold_over_failed"):
        warnings.append("Fold-Over Prevention is left out at this pose, where it failed (%s)"
                        % stats["fold_over_failed"])
    given_up = _given_up(stats)
    if given_up is not None:
        warnings.append(given_up)
    shortfall = _volume_shortfall(stats)
    if shortfall is not None and given_up is None:
        warnings.append(shortfall)
    if stats.get("skipped_regions"):
        warnings.append("%d region(s) of a bone scaled to zero left as they are (nothing to restore)"
                        % stats["skipped_regions"])
    flipped = bound.binding.flipped_edge_count
    if flipped:
        warnings.append("%d edges join faces whose normals point opposite ways, where the correction is weak or "
                        "missing (Edit Mode > Mesh > Normals > Recalculate Outside, then Bind)" % flipped)
    if warnings:
        return 'WARNING', "Correcting, but " + "; and ".join(warnings)
    if SESSION.changes.changed_at(obj) is not None:
        return 'INFO', "Correcting (the weights and the rest mesh are read again when the changes pause)"
    if bound.rebound_because is not None:
        return 'INFO', "Correcting (bound again by itself: %s)" % bound.rebound_because
    return 'INFO', "Correcting"
