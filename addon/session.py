# SPDX-License-Identifier: GPL-3.0-or-later
"""The add-on's state in this Blender session, which no file holds: SESSION, the one Session.

A file keeps only each object's bind record (Object.lvp.bind_id and topology_signature); everything
else is rebuilt from the file when needed, and forgotten when another file is loaded:

- the bindings (bound_object.BoundObject), one per object, keyed by (object name, bind id): renaming or
  duplicating an object gives a new key, which gets its own binding the next time it is needed;
- the status of each object, which the panel shows: (level, message), level 'INFO', 'WARNING' or 'ERROR';
- the changes to bound meshes not yet read, and the add-on's own updates (changes.MeshChanges);
- the objects the viewport left uncorrected because they are hidden (corrected once shown again);
- whether a render from the interface started without Lock Interface (the panel says so);
- whether a bake is running: its frames are corrected with the render settings (Keep Skin Apart);
- while a file is saved, the offsets taken out of the offsets objects (the file holds no correction).

Only the handlers, the operators and the panel run on the main thread or with the interface locked,
so the session needs no lock.
"""

from . import changes


class Session:
    """The state above, changed only through the methods that name what happened."""

    def __init__(self):
        self._bound = {}        # (object name, bind id) -> BoundObject
        self._statuses = {}     # object name -> (level, message)
        self._hidden = set()    # names of the objects the viewport hides
        self._render_without_lock = False
        self._baking = False
        self._offsets_while_saving = {}  # offsets object name -> its offsets, from save_pre to save_post
        self.changes = changes.MeshChanges()

    # ---- a file ---------------------------------------------------------------------------------

    def start_file(self):
        """Another file was loaded: nothing of the last one holds."""
        self.close_bindings()
        self.changes.reset()
        self._hidden.clear()
        self._render_without_lock = False

    def close_bindings(self):
        """Drops every binding and status (a file load, the add-on unregistered)."""
        for bound in self._bound.values():
            bound.close()
        self._bound.clear()
        self._statuses.clear()
        self.changes.drop_own_updates()
        self.changes.forget_all()

    def file_data_changed(self):
        """Undo, redo or saving changed the file's data under the bindings: what was last written to
        and read from every mesh is read again."""
        for bound in self._bound.values():
            bound.forget_file_data()

    # ---- bindings -------------------------------------------------------------------------------

    def bound(self, obj):
        """The object's binding under its current bind record, or None (never binds)."""
        return self._bound.get((obj.name_full, obj.lvp.bind_id))

    def keep(self, obj, bound):
        """bound becomes obj's binding (under bound.bind_id), made of the mesh as it is now; any other
        binding of obj is dropped."""
        key = (obj.name_full, bound.bind_id)
        for other in [other for other in self._bound if other[0] == obj.name_full and self._bound[other] is not bound]:
            self._drop(other)
        self.changes.forget(obj.name_full)
        self._bound[key] = bound

    def drop(self, obj, bound):
        """bound no longer serves obj (closed, whether stored or not)."""
        self._drop((obj.name_full, bound.bind_id))
        bound.close()

    def forget(self, obj):
        """Drops the object's bindings and status."""
        for key in [key for key in self._bound if key[0] == obj.name_full]:
            self._drop(key)
        self._statuses.pop(obj.name_full, None)

    def prune(self, objects):
        """Drops the bindings whose object is gone or has been bound again (after undo, delete...), and
        the statuses of objects without a bind record."""
        live = set()
        for obj in objects:
            settings = getattr(obj, "lvp", None)
            if settings is not None and settings.bind_id:
                live.add((obj.name_full, settings.bind_id))
        for key in [key for key in self._bound if key not in live]:
            self._drop(key)
        names = {key[0] for key in live}
        for name in [name for name in self._statuses if name not in names]:
            del self._statuses[name]

    def _drop(self, key):
        bound = self._bound.pop(key, None)
        if bound is not None:
            bound.close()
        if not any(other[0] == key[0] for other in self._bound):
            self.changes.forget(key[0])

    # ---- who changed the mesh (changes.py) -----------------------------------------------------

    def note_mesh_changed(self, obj, at_once=False):
        """Someone else changed obj's mesh: its binding's inputs are read again (changes.py), once the
        changes paused, or at the next correction when at_once."""
        if self.bound(obj) is not None:
            self.changes.note_changed(obj, at_once)

    # ---- statuses -------------------------------------------------------------------------------

    def set_status(self, obj, level, message):
        self._statuses[obj.name_full] = (level, message)

    def status(self, obj):
        """(level, message) of what obj shows, or None."""
        return self._statuses.get(obj.name_full)

    # ---- hidden objects ---------------------------------------------------------------------------

    def note_hidden(self, obj):
        """The viewport leaves obj uncorrected until it shows it again."""
        self._hidden.add(obj.name_full)
        self.set_status(obj, 'INFO', "Hidden: corrected again when shown (the figures are of the last frame it "
                                     "was shown)")

    def note_shown(self, obj):
        self._hidden.discard(obj.name_full)

    def is_hidden(self, obj):
        return obj.name_full in self._hidden

    def any_hidden(self):
        return bool(self._hidden)

    def take_hidden(self):
        """The names of the hidden objects (and forgets them: those still hidden are noted again)."""
        names = set(self._hidden)
        self._hidden.clear()
        return names

    # ---- renders ----------------------------------------------------------------------------------

    @property
    def render_without_lock(self):
        """Whether a render from the interface started without Lock Interface, so that the handlers could
        not correct it."""
        return self._render_without_lock

    def note_render_started(self, locked):
        """A render started; locked: whether the handlers may write from its thread."""
        self._render_without_lock = not locked

    def note_render_refused(self):
        """A render thread was not corrected: Lock Interface is off."""
        self._render_without_lock = True

    @property
    def baking(self):
        """Whether a bake is running: it evaluates the viewport's depsgraph, but what it writes is final
        output, corrected with the render settings, as Blender's own exporters evaluate by default."""
        return self._baking

    def note_baking(self, baking):
        self._baking = bool(baking)

    # ---- saving ---------------------------------------------------------------------------------------

    def note_saving(self, taken_out):
        """A file is being saved without the correction: taken_out, offsets object name -> the offsets taken
        out of it, to be put back once it is saved."""
        self._offsets_while_saving = dict(taken_out)

    def take_saved_offsets(self):
        """The offsets taken out for saving (and forgets them)."""
        taken_out = self._offsets_while_saving
        self._offsets_while_saving = {}
        return taken_out


SESSION = Session()
