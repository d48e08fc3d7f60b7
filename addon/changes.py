# SPDX-License-Identifier: GPL-3.0-or-later
"""Who changed the mesh: when a correction reads an object's weights and rest mesh again.

A binding is made of the mesh's weights, rest positions and painted map (bindings.BindInputs), which
a reopened file would bind again. Blender reports any of them changing only as an update of the
mesh (depsgraph_update_post), as it reports a selection, a shape key's value or a modifier shown or
hidden, and reading them takes a Python loop over the vertices. So the add-on notes that the mesh
changed, and reads them when the changes pause.

Each bound object is in one of two states (MeshChanges keeps the second, by object name):

    read       its binding is made of the mesh as the add-on last saw it
    changed    someone else changed the mesh at time t (an edit, a weight stroke, a script, undo)

    read    --note_changed(t)----------------------------------------------> changed at t
              (handlers: an update of its mesh the add-on did not make; live: a mesh reported changed
              while the object is not corrected; render_init and bakes: at once, t = -inf)
    changed --note_changed(t')---------------------------------------------> changed at t'
    changed --take_due(obj): the changes paused for CHECK_PAUSE, or they do
              not come one at a time (changes_come_one_at_a_time) ---------> read
              (live._follow_changes reads the inputs, and binds again when they differ)
    either  --forget: the binding is dropped or replaced (Session) ---------> (no state: a new binding
              is made of the mesh as it is)

The add-on's own updates are not changes (a setting, a bind, the display's colours, a new offsets
object): expect_own_update marks the mesh; the next depsgraph_update_post takes the marks
(take_own_updates) and leaves those meshes out. Marks made while the handlers correct are dropped
with them (Blender's pass that follows runs no handlers), and so are the marks of an undo step.

In the interface no correction may come after the last change (no frame change, no pose change): a
timer (handlers.after_mesh_changes) tags each changed object once its changes paused, once per change
(tag_paused), which has the handlers correct it and so read its inputs.
"""

import time

import bpy

# Reading the weights is a Python loop over the vertices, and Weight Paint Mode changes the mesh at
# every stroke: in the interface they are read only once the changes paused for this long (seconds);
# in background Blender, where scripts expect each update to be complete, at once.
CHECK_PAUSE = 0.4


def changes_come_one_at_a_time(obj):
    """Whether obj is changed by a person in the interface (or painted in Weight Paint Mode), one change
    per update: then reading its weights and rest mesh waits for the changes to pause, and the add-on's
    own updates are told apart. Scripts in background Blender may make several changes before one
    update, and expect each update to be followed completely."""
    return obj.mode == 'WEIGHT_PAINT' or not bpy.app.background


class MeshChanges:
    """The changes to bound meshes not yet read, and the add-on's own updates (see the module)."""

    def __init__(self):
        self._changed_at = {}   # object name -> time.monotonic() of a change not yet read
        self._own_updates = set()  # names of the meshes whose next update the add-on made
        self._tagged = {}       # object name -> the change after which tag_paused tagged it

    def reset(self):
        self._changed_at.clear()
        self._own_updates.clear()
        self._tagged.clear()

    # ---- the add-on's own updates ------------------------------------------------------------------

    def expect_own_update(self, obj):
        """The add-on is about to tag obj, or has set a property of obj.lvp (which has Blender tag the
        whole object): the next update reports obj's mesh as changed, but neither its weights nor its rest
        mesh changed, or what changed was just bound. Only where changes come one at a time: a script in
        background Blender may paint weights and change a setting before one update."""
        if obj.type == 'MESH' and obj.data is not None and changes_come_one_at_a_time(obj):
            self._own_updates.add(obj.data.name_full)

    def take_own_updates(self):
        """The meshes marked by expect_own_update since the last call (and forgets them)."""
        marked = set(self._own_updates)
        self._own_updates.clear()
        return marked

    def drop_own_updates(self):
        self._own_updates.clear()

    # ---- changes by someone else ---------------------------------------------------------------------

    def note_changed(self, obj, at_once=False):
        """Someone else changed obj's mesh: read at once, or once the changes paused."""
        self._changed_at[obj.name_full] = float("-inf") if at_once else time.monotonic()

    def changed_at(self, obj):
        """time.monotonic() of a change to obj's mesh not yet read, or None."""
        return self._changed_at.get(obj.name_full)

    def unread(self):
        """(object name, time.monotonic() of the change) of the changes not yet read."""
        return list(self._changed_at.items())

    def take_due(self, obj):
        """Whether obj's inputs are to be read now (and then counts them as read)."""
        changed_at = self._changed_at.get(obj.name_full)
        if changed_at is None:
            return False
        if changes_come_one_at_a_time(obj) and time.monotonic() - changed_at < CHECK_PAUSE:
            return False
        del self._changed_at[obj.name_full]
        return True

    def forget(self, name):
        self._changed_at.pop(name, None)

    def forget_all(self):
        self._changed_at.clear()

    # ---- the timer ------------------------------------------------------------------------------------

    def waiting(self):
        """(object, seconds left until its changes count as paused) of the changes not yet read."""
        now = time.monotonic()
        found = []
        for name, changed_at in self._changed_at.items():
            obj = bpy.data.objects.get(name)
            if obj is not None:
                found.append((obj, CHECK_PAUSE - (now - changed_at)))
        return found

    def any_waiting(self):
        return any(left > 0.0 for _obj, left in self.waiting())

    def tag_paused(self):
        """Tags each object whose changes paused, once per change: an object whose correction does not run
        (in Edit Mode, its modifier hidden) is not tagged again and again. The tag is the transform's,
        which brings the handlers without evaluating the modifiers again. Returns the seconds until the
        next pause ends, or None when none is left."""
        waits = []
        for obj, left in self.waiting():
            if left > 0.0:
                waits.append(left)
                continue
            changed_at = self._changed_at[obj.name_full]
            if self._tagged.get(obj.name_full) != changed_at:
                self._tagged[obj.name_full] = changed_at
                obj.update_tag(refresh={'OBJECT'})
        return max(min(waits), 0.05) if waits else None
