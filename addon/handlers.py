# SPDX-License-Identifier: GPL-3.0-or-later
"""The application handlers that keep Volume Preservation live.

- frame_change_post: after Blender evaluated a new frame (playback, scene.frame_set, each frame of
  `blender -b file.blend -a`, F12), correct every object of the handler's depsgraph. Blender then
  evaluates the tagged meshes once more WITHOUT calling handlers again, so the same frame shows
  the corrected shape. Renders have their own depsgraph, which is why the depsgraph argument is
  used and never the context's. The objects are those the depsgraph shows, collection instances
  included; in the viewport, not those the user hid, which are corrected once shown again (Blender
  reports that as an update of the scene: depsgraph_update_post).
- depsgraph_update_post: after an interactive change (posing a bone, moving an object, changing
  a setting, undo), correct the objects whose geometry was re-evaluated. Writing the offsets tags
  the offsets object's mesh; Blender's second pass evaluates it without handlers, and the next call sees unchanged
  offsets and writes nothing, so there is no loop. A mesh reported as changed has its weights and
  rest mesh read again, unless the add-on made that update itself (changes.py).
- load_post, undo_post, redo_post: forget bindings that no longer match the file; they are rebuilt
  lazily by the next correction, with no user action. load_post also replaces node groups of
  another layout (or edited by hand) with the add-on's: the group is the add-on's code.
- save_pre, save_post (and save_post_fail on 4.1+): files are saved without the correction, so a
  file opened where the add-on does not run (a farm machine, a colleague's Blender) shows plain
  skinning at every frame, rather than the correction of the frame it was saved at applied to other
  poses. The offsets objects (offsets.py) are zeroed just before writing and put back right after,
  without tagging anything, so the session never shows the difference. Opened again with the
  add-on, load_post corrects the frame the file opens on, with no user action.
- a timer for changes to meshes: the correction reads the weights and the rest mesh again (binding
  the object again when they changed) once the changes paused (changes.py); the timer then has those
  objects corrected again.
- animation_playback_post (where Blender has it: not 3.4): the frame playback stops on is corrected again, with
  Keep Skin Apart where the viewport has it only on a still frame (live._keep_apart_in_viewport). Blender 3.4
  evaluates that frame again when playback stops, and the handlers above correct it.
- render_init: renders started from the interface run in a thread; handlers that write data then
  need Render > Lock Interface (Blender's rule). With it off, the render thread does not touch the
  data (the frame on screen keeps the viewport's correction; other frames would not be corrected)
  and the panel tells the user; object.lvp_add and file loading turn it on.

Every handler is guarded against re-entrancy and never lets an exception escape into Blender.
"""

import traceback

import bpy
from bpy.app.handlers import persistent

from . import blender_api
from . import changes
from . import live
from . import node_group
from . import offsets
from .session import SESSION

# Whether the handlers are correcting: the updates their own writes cause are not theirs to follow.
_busy = False


def _objects_with_modifier(depsgraph):
    """Original objects that carry a Volume Preservation modifier and that the depsgraph shows
    (_shown_noting_hidden): the visible objects of its view layer, and objects it evaluates because
    something instances them (a collection instance of an excluded or linked collection: a crowd, a
    set, a character placed by layout). depsgraph.objects lists only the first, so the evaluated data-blocks
    are walked (which also costs less than depsgraph.objects)."""
    object_type = bpy.types.Object
    found = []
    seen = set()
    for id_eval in depsgraph.ids:
        if type(id_eval) is not object_type or id_eval.type != 'MESH':
            continue
        obj = id_eval.original
        if obj.name_full in seen:
            continue
        seen.add(obj.name_full)
        if node_group.find_modifier(obj) is not None:
            found.append(obj)
    return _shown_noting_hidden(found, depsgraph)


def _shows(depsgraph, obj):
    """Whether the depsgraph shows obj, which it evaluates: a render shows all it evaluates; the
    viewport does not show the objects the user hid (_shown_in_viewport)."""
    return depsgraph.mode != 'VIEWPORT' or _shown_in_viewport(obj, depsgraph.view_layer)


def _shown_noting_hidden(objects, depsgraph):
    """The objects the depsgraph shows (_shows). Not only a question: those the viewport leaves out
    are noted as hidden by the session (and their status says so) until it shows them again."""
    shown = []
    for obj in objects:
        if _shows(depsgraph, obj):
            shown.append(obj)
            if depsgraph.mode == 'VIEWPORT':
                SESSION.note_shown(obj)
        else:
            SESSION.note_hidden(obj)
    return shown


def corrected_in(obj, depsgraph):
    """Whether the handlers correct obj when the depsgraph is evaluated (what a bake needs): it evaluates
    obj and shows it (_shows)."""
    return obj.evaluated_get(depsgraph).is_evaluated and _shows(depsgraph, obj)


def _shown_again(depsgraph):
    """The objects left uncorrected while hidden that the viewport shows now. Blender reports showing
    an object as an update of the scene alone (its base), not of the object."""
    names = SESSION.take_hidden()
    objects = [obj for obj in bpy.data.objects if obj.name_full in names and node_group.find_modifier(obj)]
    return _shown_noting_hidden(objects, depsgraph)


def _shown_in_viewport(obj, view_layer):
    """Whether an object the viewport's depsgraph evaluates is seen: visible in the view layer, or
    evaluated only because something instances it (its collection excluded from the view layer, or not
    in it at all: Blender evaluates such objects only when they are needed). Objects the user hid (their
    eye, or their collection's) are evaluated by Blender all the same, but not corrected until shown
    again (showing one is an update that corrects it)."""
    if obj.visible_get(view_layer=view_layer):
        return True
    try:
        if obj.hide_get(view_layer=view_layer):  # raises when obj has no base in the view layer
            return False
    except RuntimeError:
        return True
    return not _in_hidden_collection(obj, view_layer.layer_collection)


def _in_hidden_collection(obj, layer_collection):
    """Whether obj is in a collection that the view layer includes but the user hid (its eye)."""
    for child in layer_collection.children:
        if child.exclude:
            continue
        if child.hide_viewport and obj.name_full in {member.name_full for member in child.collection.all_objects}:
            return True
        if _in_hidden_collection(obj, child):
            return True
    return False


def may_write(scene, background=None):
    """Whether this thread may write Blender data now (see the render_init note above): always on the
    main thread and in background Blender; from a render thread only with Lock Interface on."""
    if background is None:
        background = bpy.app.background
    if live.is_main_thread() or background:
        return True
    return bool(scene.render.use_lock_interface)


def _correct(objects, depsgraph, check_topology=()):
    global _busy
    if _busy:
        return
    _busy = True
    try:
        for obj in objects:
            try:
                live.correct_object(obj, depsgraph, check_topology=obj.data.name_full in check_topology)
            except Exception:
                traceback.print_exc()
                SESSION.set_status(obj, 'ERROR', "Internal error (see the system console); the mesh is passed "
                                                 "through")
    finally:
        _busy = False
        # Marks made while correcting are not kept: in a handler, Blender's pass that follows runs no
        # handlers, and after loading a file one more reading of the weights costs nothing but time.
        SESSION.changes.drop_own_updates()
    if live.is_main_thread() and SESSION.changes.any_waiting() and \
            not bpy.app.timers.is_registered(after_mesh_changes):
        bpy.app.timers.register(after_mesh_changes, first_interval=changes.CHECK_PAUSE)


def after_mesh_changes():
    """Timer: once the changes to a mesh paused, its object is corrected again, which reads the weights
    and the rest mesh and binds again when they changed (changes.MeshChanges.tag_paused). Returns when
    to come back, or None."""
    try:
        return SESSION.changes.tag_paused()
    except Exception:
        traceback.print_exc()
        return None


@persistent
def frame_change_post(scene, depsgraph=None):
    if _busy:
        return
    if depsgraph is None:
        if not live.is_main_thread():
            return
        depsgraph = bpy.context.evaluated_depsgraph_get()
    if not may_write(scene):
        SESSION.note_render_refused()
        return
    _correct(_objects_with_modifier(depsgraph), depsgraph)


@persistent
def depsgraph_update_post(scene, depsgraph=None):
    if _busy or depsgraph is None:
        return
    own_updates = SESSION.changes.take_own_updates()
    if not may_write(scene):
        return
    objects = []
    changed_meshes = set()
    seen = set()
    scene_changed = False
    for update in depsgraph.updates:
        data = update.id.original if update.id is not None else None
        if isinstance(data, bpy.types.Scene):
            scene_changed = True
        elif isinstance(data, bpy.types.Mesh):
            if update.is_updated_geometry and data.name_full not in own_updates:
                changed_meshes.add(data.name_full)
        elif isinstance(data, bpy.types.Object) and data.type == 'MESH':
            if data.name_full not in seen and node_group.find_modifier(data) is not None:
                seen.add(data.name_full)
                objects.append(data)
    shown = _shown_noting_hidden(objects, depsgraph)
    for obj in objects:
        if SESSION.is_hidden(obj) and obj.data.name_full in changed_meshes:
            SESSION.note_mesh_changed(obj)  # read again once shown and corrected
    if scene_changed and SESSION.any_hidden():
        shown.extend(obj for obj in _shown_again(depsgraph) if obj.name_full not in seen)
    if shown:
        _correct(shown, depsgraph, check_topology=changed_meshes)


@persistent
def animation_playback_post(scene, depsgraph=None):
    """Playback stopped: the frame it stopped on was corrected as playback has it, without Keep Skin Apart where
    that is only for a still frame (keep_apart_paused_only); it is corrected again with it."""
    if _busy or not live.is_main_thread():
        return
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    if not may_write(scene):
        return
    paused_only = [obj for obj in _objects_with_modifier(depsgraph)
                   if obj.lvp.keep_apart and obj.lvp.keep_apart_paused_only]
    if paused_only:
        _correct(paused_only, depsgraph)


@persistent
def load_post(*_arguments):
    SESSION.start_file()
    node_group.repair_modifiers(bpy.data.objects)
    if not any(obj.type == 'MESH' and node_group.find_modifier(obj) is not None for obj in bpy.data.objects):
        return
    # The file holds no correction (save_pre): correct the frame it opens on, with no user action. Without
    # an interface, now (a script that reads the file's meshes comes next); with one, once the window
    # manager runs again, with a window to evaluate for.
    if bpy.app.background:
        try:
            _correct_view_layer(bpy.context)
        except Exception:
            traceback.print_exc()
        return
    bpy.app.timers.register(_correct_windows_after_load, first_interval=0.0, persistent=True)
    # F12 renders from the interface need Lock Interface for the correction to reach them.
    for scene in bpy.data.scenes:
        if not scene.render.use_lock_interface and any(
                obj.type == 'MESH' and node_group.find_modifier(obj) is not None for obj in scene.objects):
            scene.render.use_lock_interface = True
            print("Local Volume Preservation: turned on Render > Lock Interface in scene %r so that renders "
                  "show the volume correction" % scene.name)


def _correct_view_layer(context):
    if context.scene is None or context.view_layer is None:
        return
    depsgraph = context.evaluated_depsgraph_get()
    _correct(_objects_with_modifier(depsgraph), depsgraph)


def _correct_windows_after_load():
    try:
        for window in bpy.context.window_manager.windows:
            with bpy.context.temp_override(window=window):
                _correct_view_layer(bpy.context)
    except Exception:
        traceback.print_exc()
    return None  # once


@persistent
def undo_post(*_arguments):
    SESSION.changes.drop_own_updates()  # the update that follows brings back what the undo step holds
    SESSION.prune(bpy.data.objects)
    SESSION.file_data_changed()


@persistent
def save_pre(*_arguments):
    for obj in bpy.data.objects:
        if obj.override_library is not None and obj.type == 'MESH':
            blender_api.prepare_override_diff(obj, "lvp")
    taken_out = {}
    for holder in offsets.all_writable_offsets_objects():
        previous = offsets.swap_untagged(holder)
        if previous is not None:
            taken_out[holder.name_full] = previous
    SESSION.note_saving(taken_out)
    # Should save_post never come (a failed save on Blender < 4.1), the next correction reads the
    # meshes again instead of trusting what it wrote last.
    SESSION.file_data_changed()


@persistent
def save_post(*_arguments):
    for name, previous in SESSION.take_saved_offsets().items():
        holder = bpy.data.objects.get(name)
        if holder is not None and offsets.is_offsets_object(holder):
            offsets.swap_untagged(holder, previous)


@persistent
def render_init(scene, *_arguments):
    SESSION.note_render_started(locked=bpy.app.background or scene.render.use_lock_interface)
    # A script may have changed weights or the rest mesh without any update since (the interface
    # always makes one): the first frame rendered reads them again (once, not per frame).
    for obj in scene.objects:
        if obj.type == 'MESH':
            SESSION.note_mesh_changed(obj, at_once=True)


HANDLERS = (
    ("frame_change_post", frame_change_post),
    ("depsgraph_update_post", depsgraph_update_post),
    ("load_post", load_post),
    ("undo_post", undo_post),
    ("redo_post", undo_post),
    ("render_init", render_init),
    ("animation_playback_post", animation_playback_post),
    ("save_pre", save_pre),
    ("save_post", save_post),
    ("save_post_fail", save_post),
)


def register():
    for name, function in HANDLERS:
        handler_list = blender_api.app_handlers(name)
        if handler_list is None:
            continue
        # Reloading the add-on must not leave two copies behind.
        for existing in [item for item in handler_list if getattr(item, "__name__", "") == function.__name__
                         and getattr(item, "__module__", "") == function.__module__]:
            handler_list.remove(existing)
        handler_list.append(function)


def unregister():
    if bpy.app.timers.is_registered(after_mesh_changes):
        bpy.app.timers.unregister(after_mesh_changes)
    for name, function in HANDLERS:
        handler_list = blender_api.app_handlers(name)
        if handler_list is not None and function in handler_list:
            handler_list.remove(function)
