# SPDX-License-Identifier: GPL-3.0-or-later
"""BoundObject: one object's binding and the buffers a frame's correction reuses (runtime only).

Its fields change only through its methods, each named for what happened: the binding was recorded
or had its map set (bindings.py), a frame was read and corrected (live.py), offsets were written
(offsets.py), the file's data changed under it (undo, saving).
"""

from array import array

from . import mesh_data


class BoundObject:
    """An object's binding and everything needed to correct a frame with it."""

    def __init__(self, binding, core_skeleton, vertex_count, topology, bind_id, map_key, shape, *, digests,
                 displacement_limit, unweighted_vertices, stray_vertex):
        # What the binding is made of (bindings.py).
        self.binding = binding
        self.skeleton = core_skeleton       # skeleton.CoreSkeleton: the bones given to the core
        self.vertex_count = vertex_count
        self.topology = topology
        self.bind_id = bind_id
        self.map_key = map_key
        self.shape = shape                  # bindings.shape_of: what only a new bind changes
        self.mode = shape[0]
        self.digests = digests              # BindInputs.digests of what this binding was made of
        self.displacement_limit = displacement_limit  # see bindings.DISPLACEMENT_LIMIT
        self.unweighted_vertices = unweighted_vertices  # vertices without weight on a bound bone
        self.stray_vertex = stray_vertex    # (index, distance) of a vertex far from the armature, or None
        self.rebound_because = None         # why this binding replaced an earlier one of the same record
        # A frame's inputs and outputs, reused from frame to frame (live.py).
        self.positions = mesh_data.float_array(3 * vertex_count)
        self.offsets = mesh_data.float_array(3 * vertex_count)
        self.bone_matrices = mesh_data.float_array(16 * core_skeleton.core_bone_count)
        self.stats = None                   # the last frame's statistics (dict from Binding.correct)
        self.topology_changed = False       # the mesh's topology is no longer the bound one
        self.rest_positions = None          # allocated when shape keys are used
        self.rest_in_use = False            # whether rest_positions differs from the bind rest
        self.rest_state = None              # the shape key values rest_positions was mixed for
        self.mapping_checked = None         # (final vertex count, stack signature) whose index range was checked
        self._identity_indices = None       # array('i', range(vertex_count))
        self._scratch = {}                  # name -> a buffer sized for the final mesh
        # What was last written to the offsets object (offsets.py), when known.
        self.written = None

    def close(self):
        if self.binding is not None:
            self.binding.close()
            self.binding = None

    # ---- the binding ----------------------------------------------------------------------------

    def recorded_as(self, bind_id, rebound_because=None):
        """Stored under the bind record bind_id; rebound_because: why it replaced an earlier binding."""
        self.bind_id = bind_id
        self.rebound_because = rebound_because

    def map_set(self, map_key):
        """The binding's map now follows the settings whose map_key this is."""
        self.map_key = map_key

    def painted_map_changed(self, digests):
        """The painted map alone changed (digests: of the data as it is now): the map is set again."""
        self.map_key = None
        self.digests = digests

    # ---- a frame --------------------------------------------------------------------------------

    def identity_indices(self):
        """array('i', range(vertex_count)): the "lvp_index" values of the bound vertices in order."""
        if self._identity_indices is None:
            self._identity_indices = array('i', range(self.vertex_count))
        return self._identity_indices

    def scratch(self, name, kind, count):
        """A buffer of count items, reused from frame to frame while the count stays."""
        buffer = self._scratch.get(name)
        if buffer is None or len(buffer) != count:
            buffer = self._scratch[name] = array(kind, bytes(4 * count))
        return buffer

    def note_mapping_checked(self, evaluated_count, stack):
        self.mapping_checked = (evaluated_count, stack)

    def note_topology(self, changed):
        self.topology_changed = changed

    def shape_key_rest(self, state, mesh_changed, mix):
        """The un-skinned positions with shape keys (None when they change nothing), mixed again by
        mix(buffer) -> whether they differ from the bind rest, unless state (the key values) is the
        one they were mixed for and the mesh did not change."""
        if mesh_changed or self.rest_state != state:
            if self.rest_positions is None:
                self.rest_positions = array('f', bytes(12 * self.vertex_count))
            self.rest_in_use = mix(self.rest_positions)
            self.rest_state = state
        return self.rest_positions if self.rest_in_use else None

    def note_corrected(self, stats):
        self.stats = stats

    # ---- what the offsets object holds ------------------------------------------------------------

    def wrote(self, offsets):
        """Whether offsets are known to be what the offsets object holds."""
        return self.written is not None and mesh_data.same_values(self.written, offsets)

    def note_written(self, offsets):
        if self.written is None:
            self.written = array('f', offsets)
        else:
            self.written[:] = offsets  # in place: no new buffer per frame (it resizes when it must)

    def forget_written(self):
        """Something else may have changed the offsets object (a new one was made)."""
        self.written = None

    def forget_file_data(self):
        """The file's data changed (undo, redo, saving): what was written and read is read again."""
        self.written = None
        self.rest_state = None
