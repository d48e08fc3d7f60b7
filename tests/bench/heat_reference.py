# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's heat weights (With Automatic Weights, meshlaplacian's heat_bone_weighting) recomputed outside
Blender in double precision, to tell what Auto Weights' Bone Heat differs from heat weights by and what heat
weights' own rounding does to the measures of tests/blender/test_auto_weights.py (issue 43; BENCHMARKS.md,
"Auto Weights joint by joint against nine heat weightings"). Three steps:

    # 1. In Blender 3.4 with the add-on built: a body of real_cases.rigify_human, its heat weights and
    #    Auto Weights' rows, its mesh and its deforming bones with their rest B-Bone segments, into DUMP.
    LVP_REPO=$PWD LVP_ADDON_DIR=$PWD/dist/local_volume_preservation blender -b --factory-startup -noaudio \\
        --python tests/bench/heat_reference.py -- dump DUMP.json [--voxel-scale 0.9] [--build female] [--decimated 0.3]
    # 2. Outside Blender (numpy and scipy: Debian's python3-numpy, python3-scipy): the rows recomputed,
    #    compared with Blender's and Auto Weights' (half the sum of a row's differences, over the vertices).
    python3 tests/bench/heat_reference.py solve DUMP.json ROWS.json [--one-source-per-bone]
    # 3. In Blender again: the body rebuilt, posed as test_auto_weights poses it, with heat weights and with
    #    each ROWS file's weights: crossing pairs, in all and by joint (on heat weights' skin).
    LVP_REPO=$PWD LVP_ADDON_DIR=... blender -b ... --python tests/bench/heat_reference.py -- cross DUMP.json ROWS.json...

The recomputation follows heat_bone_weighting step by step: each B-Bone segment (from its rest curve) a source;
a vertex's distance to a source over (cos + 1.001) / 2, cos between its normal (the sum of its triangles' unit
normals) and the path from the source's closest point; the sources within 1e-4 of the nearest that a ray to them
leaves unblocked (a hit only on a triangle the ray enters from its front) share the vertex evenly, H = their
number / d^2; the Laplacian with meshlaplacian's areas and each edge's triangles counted; one solve per source,
a B-Bone's positive parts summed; the weight cut (0.025 to 0.05). --one-source-per-bone takes each bone whole,
as Auto Weights' Bone Heat does.
"""
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def arguments():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


def option(args, name, default=None, kind=str):
    return kind(args[args.index(name) + 1]) if name in args else default


# ---- in Blender ------------------------------------------------------------------------------------------------

def body_arguments(args):
    import real_cases
    body = {}
    if "--voxel-scale" in args:
        body["voxel_size"] = real_cases.BODY_VOXEL * option(args, "--voxel-scale", kind=float)
    if "--build" in args:
        body["build"] = option(args, "--build")
    if "--decimated" in args:
        body["decimated"] = option(args, "--decimated", kind=float)
    return body


def build_body(body):
    import bpy
    import lvp_helpers as helpers
    import real_cases
    bpy.ops.wm.read_homefile(use_empty=True)
    if not real_cases.enable_rigify():
        raise SystemExit("this Blender has no Rigify add-on")
    helpers.enable_addon()
    return real_cases.rigify_human(**body)


def group_rows(obj, names):
    """Each vertex's raw weights over names, {name: weight}."""
    index = {obj.vertex_groups[name].index: name for name in names if name in obj.vertex_groups}
    return [{index[e.group]: e.weight for e in vertex.groups if e.group in index and e.weight > 0.0}
            for vertex in obj.data.vertices]


def dump(args):
    sys.path.insert(0, os.path.join(os.path.dirname(HERE), "blender"))
    import test_auto_weights
    body_args = body_arguments(args)
    body, rig = build_body(body_args)
    names = [bone.name for bone in rig.data.bones if bone.use_deform]
    body.data.calc_loop_triangles()
    heat = group_rows(body, names)
    bones = []
    for name in names:
        bone, pose_bone = rig.data.bones[name], rig.pose.bones[name]
        points = []
        if bone.bbone_segments > 1:
            points = [list((bone.matrix_local @ pose_bone.bbone_segment_matrix(i, rest=True)).translation)
                      for i in range(bone.bbone_segments)] + [list(bone.tail_local)]
        bones.append({"name": name, "head": list(bone.head_local), "tail": list(bone.tail_local), "points": points})
    if test_auto_weights.auto_weights(body) != {'FINISHED'}:
        raise SystemExit("Auto Weights failed")
    with open(args[1], "w") as f:
        json.dump({"body": body_args, "positions": [list(v.co) for v in body.data.vertices],
                   "triangles": [list(t.vertices) for t in body.data.loop_triangles], "bones": bones,
                   "heat": heat, "auto": group_rows(body, names)}, f)
    print("dumped %d vertices, %d bones into %s" % (len(body.data.vertices), len(names), args[1]))


def cross(args):
    sys.path.insert(0, os.path.join(os.path.dirname(HERE), "blender"))
    import lvp_helpers as helpers
    import real_cases
    import surface_quality as quality
    import test_auto_weights
    with open(args[1]) as f:
        dumped = json.load(f)
    body, rig = build_body(dumped["body"])
    names = [bone.name for bone in rig.data.bones if bone.use_deform]
    mesh = quality.WeldedMesh(helpers.mesh_positions(body.data), helpers.mesh_triangles(body.data))
    heat_rows = test_auto_weights.normalized_rows(body, names)

    def measure(label):
        for pose in ("hard", "crouch", "spread"):
            test_auto_weights.pose(rig, pose)
            pairs = quality.crossing_pairs(helpers.evaluated_positions(body), mesh)
            joints = test_auto_weights.crossings_by_joint(pairs, mesh, heat_rows)
            print("%s, %s: %d pairs; %s" % (label, pose, len(pairs), ", ".join(
                "%s-%s %d" % (a[4:], b[4:], count) for (a, b), count in sorted(joints.items()) if count >= 3)))
        real_cases.pose_rigify_human(rig, 0.0)

    measure("heat weights")
    for path in args[2:]:
        with open(path) as f:
            rows = json.load(f)
        for name in names:
            if name in body.vertex_groups:
                body.vertex_groups.remove(body.vertex_groups[name])
        groups = {name: body.vertex_groups.new(name=name) for name in names}
        for k, row in enumerate(rows):
            for name, weight in row.items():
                groups[name].add([k], weight, 'REPLACE')
        body.data.update()
        measure(os.path.basename(path))


# ---- outside Blender --------------------------------------------------------------------------------------------

def solve(args):
    import numpy as np
    import scipy.sparse
    import scipy.sparse.linalg
    with open(args[1]) as f:
        dumped = json.load(f)
    whole = "--one-source-per-bone" in args
    V = np.array(dumped["positions"], dtype=np.float64)
    T = np.array(dumped["triangles"], dtype=np.int64)
    n, bones = len(V), dumped["bones"]
    names = [bone["name"] for bone in bones]
    roots, tips, owner = [], [], []
    for index, bone in enumerate(bones):
        points = bone["points"] if bone["points"] and not whole else [bone["head"], bone["tail"]]
        for i in range(len(points) - 1):
            roots.append(points[i])
            tips.append(points[i + 1])
            owner.append(index)
    R, P, owner = np.array(roots), np.array(tips), np.array(owner)
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    face_normals = np.cross(b - a, c - a)
    lengths = np.linalg.norm(face_normals, axis=1)
    unit_normals = face_normals / np.where(lengths > 0, lengths, 1.0)[:, None]
    normals = np.zeros_like(V)
    for corner in range(3):
        np.add.at(normals, T[:, corner], unit_normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-30)[:, None]

    # Distances to every source, and the closest points the rays aim at.
    distance = np.zeros((n, len(R)))
    closest = np.zeros((n, len(R), 3))
    for s in range(len(R)):
        axis = P[s] - R[s]
        t = np.clip((V - R[s]) @ axis / max(axis @ axis, 1e-30), 0.0, 1.0)
        closest[:, s] = R[s] + t[:, None] * axis
        path = V - closest[:, s]
        length = np.linalg.norm(path, axis=1)
        cosine = np.einsum("ij,ij->i", path / np.maximum(length, 1e-30)[:, None], normals)
        distance[:, s] = length / (0.5 * (cosine + 1.001))
    nearest = distance.min(axis=1)

    def visible(k, s):
        start, vector = V[k], closest[k, s] - V[k]
        start = start + vector * 1e-5
        vector = vector * (1.0 - 2e-5)
        length = np.linalg.norm(vector)
        if length == 0.0:
            return True
        d = vector / length
        e1, e2 = b - a, c - a
        h = np.cross(d[None, :], e2)
        det = np.einsum("ij,ij->i", e1, h)
        usable = np.abs(det) > 1e-12
        inverse = np.where(usable, 1.0 / np.where(usable, det, 1.0), 0.0)
        offset = start - a
        u = np.einsum("ij,ij->i", offset, h) * inverse
        q = np.cross(offset, e1)
        v = q @ d * inverse
        t = np.einsum("ij,ij->i", e2, q) * inverse
        hit = usable & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t < length) & (unit_normals @ d < -1e-5)
        return not hit.any()

    H, share = np.zeros(n), np.zeros(n)
    sources = []
    for k in range(n):
        seen = [s for s in np.nonzero(distance[k] <= nearest[k] * (1 + 1e-4))[0] if visible(k, s)]
        sources.append(set(seen))
        if seen:
            H[k] = len(seen) / max(nearest[k], 1e-4) ** 2
            share[k] = 1.0 / len(seen)

    # meshlaplacian's system: rows scaled by 0.5 / (twice Meyer's mixed area), cotangents over the edge's triangles.
    def cotangent(p, q, r):  # at p
        u, w = q - p, r - p
        cross = np.linalg.norm(np.cross(u, w))
        return u @ w / cross if cross != 0 else 0.0

    def angle(p, q, r):  # at q
        u, w = p - q, r - q
        return np.arccos(np.clip(u @ w / (np.linalg.norm(u) * np.linalg.norm(w)), -1.0, 1.0))

    edge_triangles = {}
    for tri in T:
        for i, j in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            key = (min(i, j), max(i, j))
            edge_triangles[key] = edge_triangles.get(key, 0) + 1
    area = np.zeros(n)
    for i1, i2, i3 in T:
        v1, v2, v3 = V[i1], V[i2], V[i3]
        obtuse = 1 if angle(v2, v1, v3) > np.pi / 2 else 2 if angle(v1, v2, v3) > np.pi / 2 else \
            3 if angle(v1, v3, v2) > np.pi / 2 else 0
        if obtuse:
            whole_area = 0.5 * np.linalg.norm(np.cross(v2 - v1, v3 - v1))
            for corner, vertex in enumerate((i1, i2, i3), 1):
                area[vertex] += whole_area if obtuse == corner else 0.5 * whole_area
        else:
            t1 = cotangent(v1, v2, v3) * np.sum((v2 - v3) ** 2)
            t2 = cotangent(v2, v3, v1) * np.sum((v1 - v3) ** 2)
            t3 = cotangent(v3, v1, v2) * np.sum((v1 - v2) ** 2)
            area[i1] += 0.25 * (t2 + t3)
            area[i2] += 0.25 * (t1 + t3)
            area[i3] += 0.25 * (t1 + t2)
    scale = np.where(area != 0, 0.5 / np.where(area != 0, area, 1.0), 0.0)
    rows, cols, values = list(range(n)), list(range(n)), list(H)
    for i1, i2, i3 in T:
        v1, v2, v3 = V[i1], V[i2], V[i3]
        t1 = cotangent(v1, v2, v3) / edge_triangles[(min(i2, i3), max(i2, i3))]
        t2 = cotangent(v2, v3, v1) / edge_triangles[(min(i3, i1), max(i3, i1))]
        t3 = cotangent(v3, v1, v2) / edge_triangles[(min(i1, i2), max(i1, i2))]
        for row, col, value in ((i1, i1, t2 + t3), (i2, i2, t1 + t3), (i3, i3, t1 + t2), (i1, i2, -t3),
                                (i2, i1, -t3), (i2, i3, -t1), (i3, i2, -t1), (i3, i1, -t2), (i1, i3, -t2)):
            rows.append(row)
            cols.append(col)
            values.append(value * scale[row])
    system = scipy.sparse.csc_matrix((values, (rows, cols)), shape=(n, n))
    factor = scipy.sparse.linalg.splu(system)
    weights = np.zeros((n, len(bones)))
    for s in range(len(R)):
        rhs = np.array([H[k] * share[k] if s in sources[k] else 0.0 for k in range(n)])
        if not rhs.any():
            continue
        solution = factor.solve(rhs)
        bone = owner[s]
        if bones[bone]["points"] and not whole:
            weights[:, bone] += np.maximum(solution, 0.0)
        else:
            weights[:, bone] = solution
    weights = np.where(weights < 0.025, 0.0, np.where(weights < 0.05, (weights - 0.025) / 0.025 * 0.05, weights))

    def normalized(matrix):
        total = matrix.sum(axis=1, keepdims=True)
        return np.where(total > 0, matrix / np.where(total > 0, total, 1.0), 0.0)

    def from_rows(rows_of):
        matrix = np.zeros((n, len(bones)))
        index = {name: i for i, name in enumerate(names)}
        for k, row in enumerate(rows_of):
            for name, weight in row.items():
                matrix[k, index[name]] = weight
        return normalized(matrix)

    ours = normalized(weights)
    for label, other in (("Blender's heat weights", from_rows(dumped["heat"])),
                         ("Auto Weights", from_rows(dumped["auto"]))):
        difference = np.sort(0.5 * np.abs(ours - other).sum(axis=1))
        print("recomputed against %s: median %.4f, 99th percentile %.4f, largest %.4f"
              % (label, difference[n // 2], difference[int(0.99 * (n - 1))], difference[-1]))
    with open(args[2], "w") as f:
        json.dump([{names[j]: float(ours[k, j]) for j in np.nonzero(ours[k] > 0)[0]} for k in range(n)], f)


def main():
    args = arguments()
    if not args or args[0] not in ("dump", "solve", "cross") or len(args) < 2:
        raise SystemExit(__doc__)
    {"dump": dump, "solve": solve, "cross": cross}[args[0]](args)


if __name__ == "__main__":
    main()
