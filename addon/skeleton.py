# SPDX-License-Identifier: GPL-3.0-or-later
"""The skeleton the C core binds to, read from an armature: rest frames, weights and posed frames.

Everything is expressed in the MESH OBJECT's local space, exactly as Blender's Armature modifier
sees it. The modifier maps a vertex into armature space with premat^-1, deforms it there with
pose_bone.matrix @ bone.matrix_local^-1 and maps it back with premat, where

    premat = mesh_world^-1 @ armature_world

so in mesh space a bone's rest frame is premat @ bone.matrix_local and its posed frame is
premat @ pose_bone.matrix. Object and armature transforms, scale and parenting cancel out.

The binding keeps the rest frames it was bound with. When an object moves relative to its armature
after the bind, premat changes and so does the skinning transform S = premat @ P @ R^-1 @ premat^-1;
the posed frame handed to the core is then S @ rest_frame_at_bind, which is what the bone frame
became under the deformation that Blender actually applied.

B-Bones. A bone with n > 1 B-Bone segments does not move its vertices with one matrix. The Armature
modifier finds where a vertex lies along the bone (its rest position in armature space, projected on
the bone's axis, or with the Curved mapping of Blender 4.2+ on the rest curve), that is a segment
index i and a blend factor t, and moves it with the matrices of the segment joints i and i + 1,
weighted (1 - t) and t (blenkernel's b_bone_deform). So the core is given one bone per joint,
n + 1 for such a bone, with the vertex's weight on the bone split the same way: plain linear (or
dual quaternion) skinning of those joints is then exactly Blender's deformation, which is what the
core's contract asks for (lvp.h, lvp_correct). Each joint is a region, measured in its own frame,
so a curved B-Bone is measured along its curve. A joint's frame is pose_bone.matrix @
bbone_segment_matrix(i) (rest: bone.matrix_local @ bbone_segment_matrix(i, rest=True)); its
line for the organic map's distances is the whole bone, from head to tail, since the tail shapes
the curve. Every other bone's line the core takes from the joints (its children's heads) and its
skin, never from its tail or roll (lvp.h, BONE LINES): importers guess those.

The split uses the base mesh, as bound. Shape keys or modifiers before the Armature modifier that
slide a vertex along a B-Bone change Blender's split slightly, which the binding does not follow.

The Armature modifier's Vertex Group (a mask). With one, the modifier moves a vertex only by its
mask weight m (1 - m when inverted): co + m * (skinned - co), and not at all where m is 0. That is
skinning with one more bone that never moves, weighted 1 - m, the bones' normalized weights scaled
by m. The core is given that bone (the "still" bone, last, its frame the identity in mesh space),
so that its input is still plain skinning of its bones. It is a point at the origin and takes no
part in the organic map's distances (every region's distance term is restricted to the real bones).
"""

import math
from array import array

from mathutils import Vector

from . import _lvp
from . import blender_api
from . import mesh_data

PLAIN = -1  # the joint of a core bone that is a whole bone (no B-Bone segments)
STILL = -2  # the joint of the still bone (the Armature modifier's vertex group, see above)


def unfollowed_armature_setting(armature_modifier):
    """Why the Armature modifier's settings keep Volume Preservation from following it, or None."""
    if not armature_modifier.use_vertex_groups:
        return ("the Armature modifier %r does not bind to vertex groups (Bind To: Vertex Groups is off), and Volume "
                "Preservation follows their weights: turn it on" % armature_modifier.name)
    return None


def armature_mask(mesh_object, armature_modifier):
    """(vertex group name, inverted) when the Armature modifier limits itself to a vertex group of
    the mesh object, else None (a name that is not a group of the object limits nothing)."""
    name = armature_modifier.vertex_group
    if not name or mesh_object.vertex_groups.get(name) is None:
        return None
    return (name, bool(armature_modifier.invert_vertex_group))


def armature_space_to_mesh_space(mesh_object, armature_object):
    """premat = mesh_world^-1 @ armature_world (see the top of this file)."""
    return mesh_object.matrix_world.inverted_safe() @ armature_object.matrix_world


def deforming_bone_names(mesh_object, armature_object):
    """Names of the armature's deforming bones that have a vertex group on the mesh object, in the
    armature's bone order. These are the bones that are bound."""
    group_names = set(mesh_object.vertex_groups.keys())
    bones = armature_object.data.bones
    deform = array('b', bytes(len(bones)))
    bones.foreach_get("use_deform", deform)
    return [name for name, deforms in zip(bones.keys(), deform) if deforms and name in group_names]


def _rest_state(mesh_object, armature_object):
    """What binding reads of the rest skeleton, read in bulk (a few calls, not a walk over the bones): the
    bones' names, rest matrices, tails, B-Bone segments, mappings and deform flags, and the object's vertex
    group names. Equal states bind alike. Read every frame, since a script can change any of it without an
    update Blender reports (foreach_set); each read walks all the armature's bones, so there are as few as
    binding needs."""
    bones = armature_object.data.bones
    names = tuple(bones.keys())  # also the count: len(bones) would walk the bones once more
    count = len(names)
    matrices = mesh_data.float_array(16 * count)
    tails = mesh_data.float_array(3 * count)
    segments = mesh_data.int_array(count)
    deform = array('b', bytes(count))
    bones.foreach_get("matrix_local", matrices)
    bones.foreach_get("tail_local", tails)
    bones.foreach_get("bbone_segments", segments)
    bones.foreach_get("use_deform", deform)
    return (names, matrices.tobytes(), tails.tobytes(), segments.tobytes(),
            blender_api.bbone_mapping_modes(bones, count), deform.tobytes(), tuple(mesh_object.vertex_groups.keys()))


def rest_skeleton_arrays(mesh_object, armature_object, bone_names):
    """(rest_matrices float32[16B], heads float32[3B], tails float32[3B]) of whole bones, in mesh space."""
    premat = armature_space_to_mesh_space(mesh_object, armature_object)
    bones = armature_object.data.bones
    rest_matrices = mesh_data.float_array(16 * len(bone_names))
    heads = mesh_data.float_array(3 * len(bone_names))
    tails = mesh_data.float_array(3 * len(bone_names))
    for index, name in enumerate(bone_names):
        bone = bones[name]
        mesh_data.flatten_matrix(premat @ bone.matrix_local, rest_matrices, 16 * index)
        heads[3 * index:3 * index + 3] = array('f', premat @ Vector(bone.head_local))
        tails[3 * index:3 * index + 3] = array('f', premat @ Vector(bone.tail_local))
    return rest_matrices, heads, tails


_IDENTITY = array('f', (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0))


def _segments(bone):
    """B-Bone segments the Armature modifier deforms with (1: the bone moves as one)."""
    return max(1, bone.bbone_segments)


def _mapping(bone):
    """'STRAIGHT' or 'CURVED' (Blender 4.2+): how a vertex is placed along a B-Bone."""
    return blender_api.bbone_mapping_mode(bone)


def _segment_matrix(pose_bone, joint, rest):
    """A B-Bone joint's matrix in the bone's space (RuntimeError when the pose's B-Bone segments were
    not evaluated since the segment count changed)."""
    return pose_bone.bbone_segment_matrix(joint, rest=rest)


def straight_segment(head_tail, segments):
    """(index, blend) of a point at head_tail along a B-Bone (0 at the head, 1 at the tail), as
    blenkernel's BKE_pchan_bbone_deform_clamp_segment_index computes it."""
    head_tail = min(max(head_tail, 0.0), 1.0)
    position = head_tail * segments
    index = min(max(int(math.floor(position)), 0), segments - 1)
    blend = min(max(position - index, 0.0), 1.0)
    return index, blend


def _bound_ancestor(bone, bound):
    """The name of bone's nearest ancestor that is in bound (names), or None."""
    parent = bone.parent
    while parent is not None and parent.name not in bound:
        parent = parent.parent
    return None if parent is None else parent.name


class CoreSkeleton:
    """The bones given to the core for one binding, read at bind time.

    bone_names are the bound bones (deforming, with a vertex group). bones has one (name, joint)
    per core bone: joint is PLAIN for a whole bone, 0..n for the joints of a B-Bone of n segments,
    and STILL (name None) for the still bone, last, when the Armature modifier has a mask.
    Raises RuntimeError when a B-Bone's segments have not been evaluated yet.
    """

    def __init__(self, mesh_object, armature_object, bone_names, pose=None, mask=None):
        """pose: the pose to read the B-Bones' rest joints from (the evaluated armature's, when the
        original's has not been evaluated); the armature object's own by default. mask: the Armature
        modifier's (armature_mask())."""
        self.bone_names = list(bone_names)
        self.mask = mask
        self.armature_name = armature_object.name_full
        data_bones = armature_object.data.bones
        # The rest pose as bound (armature space), to tell when it is edited.
        self._rest_bones = {name: (data_bones[name].matrix_local.copy(), data_bones[name].tail_local.copy())
                            for name in bone_names}
        pose_bones = (pose or armature_object.pose).bones
        premat = armature_space_to_mesh_space(mesh_object, armature_object)
        self.segments = {name: _segments(data_bones[name]) for name in bone_names}
        self.mappings = {name: _mapping(data_bones[name]) for name in bone_names}
        self._rest_state = _rest_state(mesh_object, armature_object)
        self.bones = []
        self.first_core_bone = {}
        # Per core bone: the rest frame in armature space (R, or R @ joint rest) and its inverse.
        self._rest_armature = []
        for name in bone_names:
            self.first_core_bone[name] = len(self.bones)
            bone = data_bones[name]
            segments = self.segments[name]
            if segments == 1:
                self.bones.append((name, PLAIN))
                self._rest_armature.append(bone.matrix_local.copy())
                continue
            for joint in range(segments + 1):
                self.bones.append((name, joint))
                self._rest_armature.append(bone.matrix_local @ _segment_matrix(pose_bones[name], joint, True))
        self._rest_armature_inverse = [matrix.inverted_safe() for matrix in self._rest_armature]
        # Per bound bone, the joints read each frame (None for a whole bone), and their counts for
        # _lvp.compose_frames (0 for a whole bone).
        self._joints = [(name, None if self.segments[name] == 1 else range(self.segments[name] + 1))
                        for name in bone_names]
        self._joint_counts = mesh_data.int_array(len(bone_names))
        for index, (_name, joints) in enumerate(self._joints):
            self._joint_counts[index] = 0 if joints is None else len(joints)
        # Rest frames in mesh space at bind (see the top of this file).
        self.rest_frames = [premat @ matrix for matrix in self._rest_armature]
        self.still_bone = None
        if mask is not None:
            self.still_bone = len(self.bones)
            self.bones.append((None, STILL))
        self._bound_premat = premat.copy()
        self._bound_premat_inverse = premat.inverted_safe()
        self._to_bind_premat = None  # see _posed_to_bind_frames
        self._to_bind = None
        self._rigid_space = None     # premat^-1 as float32[16], with _to_bind
        self._head_tail = {}
        for name in bone_names:
            bone = data_bones[name]
            self._head_tail[name] = (premat @ Vector(bone.head_local), premat @ Vector(bone.tail_local))
        self._bound_parent = {name: _bound_ancestor(data_bones[name], self.first_core_bone) for name in bone_names}

    @property
    def core_bone_count(self):
        return len(self.bones)

    @property
    def has_bbones(self):
        return any(segments > 1 for segments in self.segments.values())

    @property
    def real_core_bones(self):
        """Indices of the core bones that are bones (all but the still bone)."""
        return list(range(len(self.bones) if self.still_bone is None else self.still_bone))

    def region_name(self, region):
        """How the panel names a core bone's region."""
        if not 0 <= region < len(self.bones):
            return str(region)
        name, joint = self.bones[region]
        if joint == STILL:
            return "kept still by the Armature modifier's vertex group %r" % self.mask[0]
        # A B-Bone's joints are corrected as one (bone_groups): the core names the bone by its first.
        return name

    def core_bones_of(self, name):
        """Indices of the core bones that stand for the bone called name (empty when not bound)."""
        first = self.first_core_bone.get(name)
        if first is None:
            return []
        count = 1 if self.segments[name] == 1 else self.segments[name] + 1
        return list(range(first, first + count))

    def bone_groups(self):
        """Per core bone, the first core bone of its bone (int32): the joints of a B-Bone are corrected
        together, with one multiplier (lvp.h, GROUPS); None when no bone is a B-Bone."""
        if not self.has_bbones:
            return None
        groups = mesh_data.int_array(len(self.bones))
        for index, (name, _joint) in enumerate(self.bones):
            groups[index] = index if name is None else self.first_core_bone[name]
        return groups

    def bone_index(self, region):
        """Index in bone_names of the bone a core bone belongs to (-1 for the still bone)."""
        name = self.bones[region][0]
        return -1 if name is None else self.bone_names.index(name)

    def rest_arrays(self):
        """(rest_matrices float32[16C], heads float32[3C], tails float32[3C]) of the core bones, in mesh
        space. A B-Bone's joints all have the whole bone as their segment."""
        count = len(self.bones)
        rest_matrices = mesh_data.float_array(16 * count)
        heads = mesh_data.float_array(3 * count)
        tails = mesh_data.float_array(3 * count)
        for index, (name, joint) in enumerate(self.bones):
            if joint == STILL:  # the identity, a point at the origin
                rest_matrices[16 * index:16 * index + 16] = _IDENTITY
                continue
            mesh_data.flatten_matrix(self.rest_frames[index], rest_matrices, 16 * index)
            head, tail = self._head_tail[name]
            heads[3 * index:3 * index + 3] = array('f', head)
            tails[3 * index:3 * index + 3] = array('f', tail)
        return rest_matrices, heads, tails

    def parents(self):
        """Per core bone, the core bone it hangs from, or -1 (int32): the core takes each bone's line from its
        children's heads (lvp.h, BONE LINES). A bone hangs from its nearest bound ancestor, at that bone's last
        joint when it is a B-Bone; a B-Bone's joints hang one from the one before."""
        parents = mesh_data.int_array(len(self.bones))
        for index, (name, joint) in enumerate(self.bones):
            if joint == STILL:
                parents[index] = -1
            elif joint > 0:
                parents[index] = index - 1
            else:
                ancestor = self._bound_parent[name]
                parents[index] = -1 if ancestor is None else self.core_bones_of(ancestor)[-1]
        return parents

    def split_weights(self, pose, positions, offsets, bones, values):
        """Weights over bone_names (compressed rows, see mesh_data.weights_csr) -> weights over the core
        bones: a B-Bone's weight split over the two joints Blender blends for the vertex at positions
        (the bound rest, mesh space). pose: as for __init__."""
        if not self.has_bbones:
            return offsets, bones, values
        pose_bones = pose.bones
        bound_premat_inverse = self._bound_premat_inverse
        # Per bone index: None for a whole bone; else (first core bone, segments, the row of the
        # mesh-to-bone-rest transform that gives the distance along the bone, its length, pose bone
        # when the mapping is curved).
        plans = []
        for name in self.bone_names:
            segments = self.segments[name]
            if segments == 1:
                plans.append((self.first_core_bone[name], None))
                continue
            bone = pose_bones[name].bone
            to_bone = bone.matrix_local.inverted_safe() @ bound_premat_inverse
            curved = pose_bones[name] if self.mappings[name] == 'CURVED' else None
            plans.append((self.first_core_bone[name], (segments, to_bone[1], bone.length, curved)))
        new_offsets = mesh_data.int_array(len(offsets))
        new_bones = array('i')
        new_values = array('f')
        for vertex in range(len(offsets) - 1):
            x, y, z = positions[3 * vertex], positions[3 * vertex + 1], positions[3 * vertex + 2]
            for entry in range(offsets[vertex], offsets[vertex + 1]):
                first, bbone = plans[bones[entry]]
                weight = values[entry]
                if bbone is None:
                    new_bones.append(first)
                    new_values.append(weight)
                    continue
                segments, row, length, curved = bbone
                if curved is not None:
                    point = bound_premat_inverse @ Vector((x, y, z))
                    index, blend = curved.bbone_segment_index(point)
                else:
                    along = row[0] * x + row[1] * y + row[2] * z + row[3]
                    index, blend = straight_segment(along / length if length > 0.0 else 0.0, segments)
                if blend < 1.0:
                    new_bones.append(first + index)
                    new_values.append(weight * (1.0 - blend))
                if blend > 0.0:
                    new_bones.append(first + index + 1)
                    new_values.append(weight * blend)
            new_offsets[vertex + 1] = len(new_bones)
        return new_offsets, new_bones, new_values

    def core_weights(self, mesh_object, pose, positions, offsets, bones, values, mask_values=None):
        """Weights over bone_names (mesh_data.weights_csr) -> the weights the core is given: B-Bone
        weights split over their joints (split_weights), then the Armature modifier's mask applied
        (apply_mask, with the mask group's weights mask_values, read from mesh_object when None)."""
        offsets, bones, values = self.split_weights(pose, positions, offsets, bones, values)
        if self.mask is None:
            return offsets, bones, values
        if mask_values is None:
            mask_values = mesh_data.vertex_group_values(mesh_object, self.mask[0])
        return self.apply_mask(mask_values, offsets, bones, values)

    def apply_mask(self, mask_values, offsets, bones, values):
        """Weights over the core bones -> the same with the Armature modifier's mask: per vertex, the
        weights normalized and scaled by the mask weight m, and 1 - m on the still bone. mask_values:
        the mask group's weight per vertex (0 outside it), not yet inverted."""
        if self.still_bone is None:
            return offsets, bones, values
        inverted = self.mask[1]
        still = self.still_bone
        new_offsets = mesh_data.int_array(len(offsets))
        new_bones = array('i')
        new_values = array('f')
        for vertex in range(len(offsets) - 1):
            mask = mask_values[vertex]
            mask = min(max(1.0 - mask if inverted else mask, 0.0), 1.0)
            begin, end = offsets[vertex], offsets[vertex + 1]
            total = sum(values[begin:end])
            if total > 0.0 and mask > 0.0:
                scale = mask / total
                new_bones.extend(bones[begin:end])
                new_values.extend(value * scale for value in values[begin:end])
            if mask < 1.0 or total <= 0.0:
                # Where nothing moves it (no weight, or m = 0), Blender leaves the vertex as it is.
                new_bones.append(still)
                new_values.append(1.0 - mask if total > 0.0 else 1.0)
            new_offsets[vertex + 1] = len(new_bones)
        return new_offsets, new_bones, new_values

    def changed(self, mesh_object, armature_object, mask):
        """Why mesh_object's Armature modifier, following armature_object with mask (armature_mask()),
        no longer deforms with this skeleton, or None. Cheap enough for every frame: the armature, the
        mask group and the rest state (_rest_state) compared with the bind's, bone by bone only when
        that differs."""
        if armature_object.name_full != self.armature_name:
            return "the Armature modifier follows %s instead of %s" % (armature_object.name, self.armature_name)
        if mask != self.mask:
            return "the vertex group of the Armature modifier changed"
        state = _rest_state(mesh_object, armature_object)
        if state != self._rest_state:
            reason = self._rest_changed(mesh_object, armature_object)
            if reason is not None:
                return reason
            self._rest_state = state  # changes to what is not bound: nothing to bind again
        return None

    def _rest_changed(self, mesh_object, armature_object):
        """changed(), bone by bone: why the bound bones no longer deform as bound, or None."""
        if deforming_bone_names(mesh_object, armature_object) != self.bone_names:
            return "the deforming bones with a vertex group changed"
        data_bones = armature_object.data.bones
        for name in self.bone_names:
            bone = data_bones[name]
            if _segments(bone) != self.segments[name]:
                return "the B-Bone segments of %r changed" % name
            if _mapping(bone) != self.mappings[name]:
                return "the B-Bone vertex mapping of %r changed" % name
            matrix_local, tail_local = self._rest_bones[name]
            if bone.matrix_local != matrix_local or bone.tail_local != tail_local:
                return "the rest pose of %r changed" % name
        return None

    @property
    def rigid_space(self):
        """float32[16]: the map from the mesh's coordinates to the armature's, where a bone that is not
        scaled only turns: the core tells a bone's scale from its bend there (lvp.h, rigid_space). Kept
        for the object matrices of the last posed_matrices()."""
        return self._rigid_space

    def posed_matrices(self, out, mesh_object, armature_object):
        """Writes the posed core bone frames (float32[16C]) into out, and sets rigid_space.

        mesh_object and armature_object should be the EVALUATED objects of the depsgraph being
        corrected (their matrices and pose are those of the frame being evaluated), after changed()
        found nothing. Returns None, or why the frames cannot be given.

        Blender gives a B-Bone's joint matrices one call each (bbone_segment_matrix); everything else is
        read as whole matrices and composed in C (_lvp.compose_frames), with Python's mathutils arithmetic,
        so the frames are the same bits as premat @ pose_bone.matrix @ bbone_segment_matrix(joint) (@ the
        correction of _posed_to_bind_frames).
        """
        premat = armature_space_to_mesh_space(mesh_object, armature_object)
        corrections = self._posed_to_bind_frames(premat)
        pose_bones = armature_object.pose.bones
        bone_matrices = []
        joint_matrices = []
        for name, joints in self._joints:
            try:
                pose_bone = pose_bones[name]
            except KeyError:
                return "the bound bone %r has no pose in %s" % (name, armature_object.name)
            bone_matrices.append(pose_bone.matrix)
            if joints is not None:
                try:
                    joint_matrices.extend(map(pose_bone.bbone_segment_matrix, joints))
                except RuntimeError:
                    return "the B-Bone segments of %r are not evaluated" % name
        real_count = len(self.bones)
        if self.still_bone is not None:
            out[16 * self.still_bone:] = _IDENTITY
            real_count = self.still_bone
        with memoryview(out) as frames:
            _lvp.compose_frames(frames[:16 * real_count], blender_api.matrices_column_major((premat,)),
                                blender_api.matrices_column_major(bone_matrices), self._joint_counts,
                                blender_api.matrices_column_major(joint_matrices), corrections)
        return None

    def _posed_to_bind_frames(self, premat):
        """Per real core bone, F^-1 @ premat^-1 @ rest_frame_at_bind, with F its rest frame in armature
        space: premat @ posed @ this is the posed frame S @ rest_frame_at_bind (the top of this file).
        None while the object has not moved against its armature since the bind (the identity); else
        float32, each matrix column by column (_lvp.compose_frames); cached per premat."""
        if self._to_bind_premat != premat:
            premat_inverse = premat.inverted_safe()
            self._rigid_space = mesh_data.float_array(16)
            mesh_data.flatten_matrix(premat_inverse, self._rigid_space, 0)
            self._to_bind = None if premat == self._bound_premat else blender_api.matrices_column_major(
                [inverse @ premat_inverse @ rest for inverse, rest in zip(self._rest_armature_inverse, self.rest_frames)])
            self._to_bind_premat = premat.copy()
        return self._to_bind
