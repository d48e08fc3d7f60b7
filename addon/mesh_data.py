# SPDX-License-Identifier: GPL-3.0-or-later
"""Reading a mesh's data into the flat arrays the C core takes (see docs/python_module.md): positions,
triangles, topology, weights, shape keys, in the mesh object's local space. The skeleton is read by
skeleton.py.

No numpy (Debian's Blender 3.4 has none): array.array buffers with foreach_get / foreach_set.
"""

import zlib
from array import array

from . import blender_api


def flatten_matrix(matrix, out, offset):
    """Writes a 4x4 mathutils Matrix row by row into out[offset:offset + 16]."""
    for row in range(4):
        for column in range(4):
            out[offset + 4 * row + column] = matrix[row][column]


def float_array(count):
    return array('f', bytes(4 * count))


def int_array(count):
    return array('i', bytes(4 * count))


def same_values(first, second):
    """Bitwise equality of two arrays, at memcmp speed (array.__eq__ compares item by item in Python
    objects, which costs milliseconds per frame on large meshes)."""
    return len(first) == len(second) and first.tobytes() == second.tobytes()


# ---- mesh ----------------------------------------------------------------------------------


def is_linked(data):
    """Whether a data-block (a mesh, an object) comes from a library (linked, or kept linked by a
    library override): Blender ignores what add-ons write into such a mesh (its weights, its
    attributes)."""
    return data.library is not None or data.override_library is not None


def coordinates(mesh):
    """(collection, property) through which foreach_get / foreach_set move a mesh's vertex coordinates
    fastest: the "position" attribute on Blender 3.5+ (where vertices' "co" is many times slower to
    move), the vertices on 3.4, which has no such attribute and moves "co" at attribute speed."""
    attribute = mesh.attributes.get("position")
    if attribute is not None and attribute.domain == 'POINT' and attribute.data_type == 'FLOAT_VECTOR':
        return attribute.data, "vector"
    return mesh.vertices, "co"


def vertex_positions(mesh, out=None):
    """The mesh's vertex coordinates (its base shape, without shape keys), float32[3N], into out when
    given."""
    positions = float_array(3 * len(mesh.vertices)) if out is None else out
    collection, key = coordinates(mesh)
    collection.foreach_get(key, positions)
    return positions


def set_vertex_positions(mesh, positions):
    """Moves the mesh's vertices to float32[3N] positions (without tagging the mesh)."""
    collection, key = coordinates(mesh)
    collection.foreach_set(key, positions)


def bounding_box_diagonal(positions):
    """Length of the diagonal of the axis-aligned box around float[3N] positions (0 when empty)."""
    if len(positions) < 3:
        return 0.0
    extent = [max(positions[axis::3]) - min(positions[axis::3]) for axis in range(3)]
    return sum(value * value for value in extent) ** 0.5


def blender_loop_triangles(mesh):
    """Blender's own split of the mesh's faces into triangles (its loop triangles, brought up to date), int32[3T],
    as it hands them."""
    blender_api.update_loop_triangles(mesh)
    triangles = int_array(3 * len(mesh.loop_triangles))
    mesh.loop_triangles.foreach_get("vertices", triangles)
    return triangles


def loop_triangles(mesh):
    """The mesh's faces split into triangles, int32[3T], wound like the faces: Blender's own split (its loop
    triangles), or the same split made here when Blender's cached one does not fit the mesh."""
    triangles = blender_loop_triangles(mesh)
    if not fits_faces(mesh, triangles):
        # Blender 3.4 once handed a bind, in a full test run, a triangle with a corner past the mesh's vertices
        # (not reproduced alone): split here rather than refuse a sound mesh.
        triangles = triangles_of_faces(mesh)
    return triangles


def fits_faces(mesh, triangles):
    """Whether int32[3T] triangles can be a split of the mesh's faces: as many as its faces make (a face of n
    corners makes n - 2) and every corner one of its vertices."""
    if len(triangles) != 3 * (len(mesh.loops) - 2 * len(mesh.polygons)):
        return False
    return len(triangles) == 0 or (min(triangles) >= 0 and max(triangles) < len(mesh.vertices))


def triangles_of_faces(mesh):
    """The mesh's faces split into triangles, int32[3T], wound like the faces, as Blender splits them: a
    triangle as it is, a quad along the diagonal from its first corner, a larger face by filling its outline
    (mathutils.geometry.tessellate_polygon, each triangle turned to the face's winding)."""
    from mathutils import Vector, geometry

    corner_vertices = int_array(len(mesh.loops))
    mesh.loops.foreach_get("vertex_index", corner_vertices)
    starts = int_array(len(mesh.polygons))
    mesh.polygons.foreach_get("loop_start", starts)
    sizes = int_array(len(mesh.polygons))
    mesh.polygons.foreach_get("loop_total", sizes)
    triangles = array('i')
    for face, (start, size) in enumerate(zip(starts, sizes)):
        corners = corner_vertices[start:start + size]
        if size == 3:
            triangles.extend(corners)
        elif size == 4:
            triangles.extend((corners[0], corners[1], corners[2], corners[0], corners[2], corners[3]))
        elif size > 4:
            points = [Vector(mesh.vertices[v].co) for v in corners]
            normal = mesh.polygons[face].normal
            for a, b, c in geometry.tessellate_polygon([points]):
                if (points[b] - points[a]).cross(points[c] - points[a]).dot(normal) < 0.0:
                    b, c = c, b
                triangles.extend((corners[a], corners[b], corners[c]))
    return triangles


def topology_signature(mesh):
    """A short string that changes when vertices, edges or faces are added, removed or reconnected.

    Positions, weights and attributes do not enter it: it tells whether a binding made on an
    earlier version of this mesh can still be applied to it vertex for vertex.
    """
    corner_vertices = int_array(len(mesh.loops))
    mesh.loops.foreach_get("vertex_index", corner_vertices)
    face_sizes = int_array(len(mesh.polygons))
    mesh.polygons.foreach_get("loop_total", face_sizes)
    checksum = zlib.crc32(corner_vertices.tobytes())
    checksum = zlib.crc32(face_sizes.tobytes(), checksum)
    return "v%d e%d f%d l%d c%08x" % (len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops),
                                      checksum)


def quick_topology_counts(mesh):
    """The element counts of topology_signature(), cheap enough to compare every frame."""
    return "v%d e%d f%d l%d" % (len(mesh.vertices), len(mesh.edges), len(mesh.polygons), len(mesh.loops))


# ---- weights -------------------------------------------------------------------------------


def weights_csr(mesh_object, bone_names):
    """Skinning weights of the deforming bones as compressed rows.

    Returns (offsets int32[N+1], bones int32[nnz], values float32[nnz]): the influences of vertex k
    are bones[offsets[k]:offsets[k+1]], indices into bone_names. Zero weights are left out; other
    vertex groups are ignored. The core normalizes by the weight sum, as the Armature modifier does.
    """
    bone_of_group = {}
    for group in mesh_object.vertex_groups:
        if group.name in bone_names:
            bone_of_group[group.index] = bone_names.index(group.name)
    mesh = mesh_object.data
    offsets = int_array(len(mesh.vertices) + 1)
    bones = array('i')
    values = array('f')
    count = 0
    for vertex in mesh.vertices:
        for element in vertex.groups:
            bone = bone_of_group.get(element.group)
            if bone is not None and element.weight > 0.0:
                bones.append(bone)
                values.append(element.weight)
                count += 1
        offsets[vertex.index + 1] = count
    return offsets, bones, values


def vertex_group_values(mesh_object, group_name):
    """Per-vertex weights of one vertex group (0 where a vertex is not in it), float32[N]; None when
    the object has no such group."""
    group = mesh_object.vertex_groups.get(group_name)
    if group is None:
        return None
    group_index = group.index
    mesh = mesh_object.data
    values = float_array(len(mesh.vertices))
    for vertex in mesh.vertices:
        for element in vertex.groups:
            if element.group == group_index:
                values[vertex.index] = element.weight
                break
    return values


def replace_vertex_group_weights(mesh_object, bone_names, offsets, bones, values):
    """Writes compressed-row weights into the vertex groups named bone_names (created when missing),
    replacing what those groups held. Other vertex groups are left alone. Object Mode only."""
    vertex_count = len(offsets) - 1
    # Blender adds one weight to a list of vertices per call: the vertices a bone holds wholly go in one call,
    # every other weight in its own (nearly all differ; grouping them by value costs more than it saves).
    whole = [[] for _ in bone_names]
    partial = [[] for _ in bone_names]
    for vertex in range(vertex_count):
        for entry in range(offsets[vertex], offsets[vertex + 1]):
            weight = values[entry]
            if weight == 1.0:
                whole[bones[entry]].append(vertex)
            else:
                partial[bones[entry]].append((vertex, weight))
    groups = [mesh_object.vertex_groups.get(name) for name in bone_names]
    # What the groups that exist hold, found in one pass over the mesh (asking each group about each vertex costs
    # vertices x bones calls: seconds for 100k vertices on a rig of 160 bones); none when all are new.
    members = {group.index: [] for group in groups if group is not None}
    if members:
        for vertex in mesh_object.data.vertices:
            for element in vertex.groups:
                held = members.get(element.group)
                if held is not None:
                    held.append(vertex.index)
    for bone_index, name in enumerate(bone_names):
        if groups[bone_index] is None:
            groups[bone_index] = mesh_object.vertex_groups.new(name=name)
    for bone_index, group in enumerate(groups):
        held = members.get(group.index)
        if held:
            # Only the vertices that get no weight now leave the group; the others' weights are replaced in place.
            weighted = set(whole[bone_index])
            weighted.update(vertex for vertex, _weight in partial[bone_index])
            stale = [vertex for vertex in held if vertex not in weighted]
            if stale:
                group.remove(stale)
        if whole[bone_index]:
            group.add(whole[bone_index], 1.0, 'REPLACE')
        add = group.add
        for vertex, weight in partial[bone_index]:
            add((vertex,), weight, 'REPLACE')


# ---- shape keys ----------------------------------------------------------------------------


def shape_key_rest_positions(mesh_object, base_positions, out):
    """This frame's un-skinned positions when relative shape keys are active: the mix Blender
    feeds the Armature modifier. Writes float32[3N] into out and returns True; returns False when
    no shape key changes the base shape (then the binding's rest is the right reference).

    Handles relative keys with value, slider range, mute, relative key and vertex group; absolute
    (evaluation-time) keys and keys in Edit Mode are not mixed (returns False).
    """
    mesh = mesh_object.data
    keys = mesh.shape_keys
    if keys is None or not keys.use_relative or len(keys.key_blocks) < 2:
        return False
    if mesh_object.show_only_shape_key:
        return False
    vertex_count = len(mesh.vertices)
    active = [block for block in keys.key_blocks[1:] if not block.mute and block.value != 0.0]
    if not active:
        return False
    if len(out) != 3 * vertex_count:
        return False
    out[:] = base_positions
    key_positions = float_array(3 * vertex_count)
    relative_positions = float_array(3 * vertex_count)
    for block in active:
        block.data.foreach_get("co", key_positions)
        relative = block.relative_key if block.relative_key is not None else keys.key_blocks[0]
        relative.data.foreach_get("co", relative_positions)
        value = block.value
        mask = None
        if block.vertex_group:
            mask = vertex_group_values(mesh_object, block.vertex_group)
        if mask is None:
            for index in range(3 * vertex_count):
                out[index] += value * (key_positions[index] - relative_positions[index])
        else:
            for index in range(3 * vertex_count):
                out[index] += value * mask[index // 3] * (key_positions[index] - relative_positions[index])
    return True
