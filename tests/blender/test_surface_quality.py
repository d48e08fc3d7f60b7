# SPDX-License-Identifier: GPL-3.0-or-later
"""The instruments of surface_quality.py measured on shapes whose answer is known by construction: two triangles
that cross, touch or share a corner; closed spheres apart and through each other; a flat sheet folded along a line;
a smooth bump and a one-vertex spike; a sphere split along box-projection seams, as glTF's importer splits meshes,
which must measure exactly as its welded self. No add-on involved: these tests hold the rulers, not the work.
"""

import math
import random
import unittest

import real_cases
import surface_quality as quality


def uv_sphere(rings=12, around=16, radius=1.0, centre=(0.0, 0.0, 0.0)):
    """(points, triangles) of a closed sphere wound outward (real_cases.ellipsoid, its quads cut in two)."""
    points, faces = real_cases.ellipsoid(centre, (radius, radius, radius), rings, around)
    triangles = []
    for face in faces:
        triangles += [face] if len(face) == 3 else [(face[0], face[1], face[2]), (face[0], face[2], face[3])]
    return points, triangles


def grid(size=11, spacing=1.0):
    """(points, triangles) of a flat square sheet in the XY plane, size x size vertices, each quad cut along the
    same diagonal; vertex (i, j) is j * size + i."""
    points = [(i * spacing, j * spacing, 0.0) for j in range(size) for i in range(size)]
    triangles = []
    for j in range(size - 1):
        for i in range(size - 1):
            a, b, c, d = j * size + i, j * size + i + 1, (j + 1) * size + i + 1, (j + 1) * size + i
            triangles += [(a, b, c), (a, c, d)]
    return points, triangles


def split_at_box_seams(points, triangles):
    """The mesh split as a box-projected UV map splits it: each triangle goes to the island of its normal's
    dominant axis and sign, and a vertex used by several islands gets one copy per island (copies at the same
    position, the triangles re-pointed). Returns (points, triangles, original vertex of each new one)."""
    copies, new_points, origin, new_triangles = {}, [], [], []
    for triangle in triangles:
        a, b, c = (points[v] for v in triangle)
        normal = quality._cross(quality._sub(b, a), quality._sub(c, a))
        axis = max(range(3), key=lambda k: abs(normal[k]))
        island = (axis, normal[axis] > 0)
        renamed = []
        for v in triangle:
            key = (v, island)
            if key not in copies:
                copies[key] = len(new_points)
                new_points.append(points[v])
                origin.append(v)
            renamed.append(copies[key])
        new_triangles.append(tuple(renamed))
    return new_points, new_triangles, origin


def flat(points):
    return [x for point in points for x in point]


class TestCrossings(unittest.TestCase):
    BASE = ((0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))

    def pairs(self, second, weld=True):
        points = list(self.BASE) + list(second)
        triangles = [(0, 1, 2), (3, 4, 5)]
        if weld:
            return quality.count_crossing_pairs(points, quality.WeldedMesh(points, triangles))
        return int(quality.triangles_cross(self.BASE, second))

    def test_an_edge_through_the_inside_is_one_pair(self):
        crossing = ((0.5, 0.5, -1.0), (0.5, 0.5, 1.0), (1.5, 1.5, 1.0))
        self.assertEqual(self.pairs(crossing), 1)
        self.assertTrue(quality.triangles_cross(self.BASE, crossing))
        self.assertTrue(quality.triangles_cross(crossing, self.BASE), "symmetric")

    def test_a_triangle_through_the_other_without_its_corners_inside(self):
        # Second triangle pierces the first only by the first's edge: a "chain link" crossing.
        link = ((1.0, 0.3, -1.0), (1.0, 0.3, 1.0), (1.0, -3.0, 0.0))
        self.assertEqual(self.pairs(link), 1)

    def test_touching_is_not_crossing(self):
        corner_on_inside = ((0.5, 0.5, 0.0), (0.5, 0.5, 1.0), (1.0, 0.2, 1.0))
        edge_on_edge = ((1.0, 0.0, 0.0), (1.0, -1.0, 1.0), (1.0, -1.0, -1.0))
        edge_in_plane_outside = ((3.0, 0.0, 0.0), (3.0, 1.0, 0.0), (3.0, 0.0, 1.0))
        # An edge of each through the middle of an edge of the other, the rest apart.
        edges_crossing = ((1.0, -1.0, -1.0), (1.0, 1.0, 1.0), (1.0, -1.0, 1.0))
        for second in (corner_on_inside, edge_on_edge, edge_in_plane_outside, edges_crossing):
            self.assertEqual(self.pairs(second), 0, second)
            self.assertEqual(self.pairs(second, weld=False), 0, second)

    def test_apart_and_coplanar_are_not_crossing(self):
        self.assertEqual(self.pairs(((0.0, 0.0, 1.0), (2.0, 0.0, 1.0), (0.0, 2.0, 1.0))), 0)
        self.assertEqual(self.pairs(((0.2, 0.2, 0.0), (1.2, 0.2, 0.0), (0.2, 1.2, 0.0))), 0)

    def test_sharing_a_corner_is_not_counted_even_split(self):
        # Would cross if the shared corner did not count: its edge (0.5, 0.5, +-1) goes through the inside.
        through = ((0.0, 0.0, 0.0), (0.5, 0.5, -1.0), (0.5, 0.5, 1.0))
        self.assertTrue(quality.triangles_cross(self.BASE, through))
        self.assertEqual(self.pairs(through), 0, "a corner at the same position is one vertex once welded")
        moved = ((-0.1, 0.0, 0.0), (0.5, 0.5, -1.0), (0.5, 0.5, 1.0))
        self.assertEqual(self.pairs(moved), 1)

    def test_spheres_apart_and_through_each_other(self):
        points, triangles = uv_sphere()
        self.assertEqual(quality.count_crossing_pairs(points, triangles), 0, "a closed sphere")
        other, other_triangles = uv_sphere(centre=(3.0, 0.0, 0.0))
        both = points + other
        offset = len(points)
        all_triangles = triangles + [(a + offset, b + offset, c + offset) for a, b, c in other_triangles]
        self.assertEqual(quality.count_crossing_pairs(both, all_triangles), 0, "two spheres apart")
        through, _triangles = uv_sphere(centre=(1.3, 0.1, 0.05))
        pairs = quality.crossing_pairs(points + through, all_triangles)
        self.assertGreater(len(pairs), 16, "two spheres through each other cross all around a circle")
        mesh = quality.WeldedMesh(points + through, all_triangles)
        for i, j in pairs:
            self.assertNotEqual(i < len(triangles), j < len(triangles), "only pairs of one triangle from each")
            self.assertFalse(set(mesh.welded_triangles[i]) & set(mesh.welded_triangles[j]))


class TestCreases(unittest.TestCase):

    def folded(self, degrees, size=11):
        """The grid folded up along its middle row j = size // 2 by `degrees`."""
        points, triangles = grid(size)
        hinge = size // 2
        angle = math.radians(degrees)
        moved = [(x, hinge + (y - hinge) * math.cos(angle), (y - hinge) * math.sin(angle)) if y > hinge else (x, y, z)
                 for x, y, z in points]
        return points, triangles, moved

    def test_a_fold_adds_one_crease_per_hinge_edge(self):
        points, triangles, moved = self.folded(60.0)
        mesh = quality.WeldedMesh(points, triangles)
        creases = quality.creases_added(points, moved, mesh)
        self.assertEqual(len(creases), 10, "the hinge's 10 edges, none elsewhere")
        self.assertTrue(all(points[u][1] == points[v][1] == 5.0 for u, v in creases), creases)
        angles = quality.dihedral_angles(moved, mesh)
        self.assertAlmostEqual(angles[creases[0]], 60.0, places=6)

    def test_a_gentle_fold_adds_none_and_plain_is_the_reference(self):
        points, triangles, moved = self.folded(25.0)
        mesh = quality.WeldedMesh(points, triangles)
        self.assertEqual(quality.creases_added(points, moved, mesh), [])
        _points, _triangles, more = self.folded(80.0)
        # Against plain skinning already folded 60 degrees, folding to 80 adds 20: no crease.
        _points, _triangles, plain = self.folded(60.0)
        self.assertEqual(quality.creases_added(plain, more, mesh), [])
        self.assertEqual(len(quality.creases_added(points, more, mesh)), 10)

    def test_a_ridge_adds_creases_on_three_rows(self):
        points, triangles = grid(11)
        ridge = [(x, y, 1.0 if y == 5.0 else z) for x, y, z in points]
        mesh = quality.WeldedMesh(points, triangles)
        # The row lifted (90 degrees) and the rows either side (45): 3 rows of 10 edges.
        self.assertEqual(len(quality.creases_added(points, ridge, mesh)), 30)


class TestRoughness(unittest.TestCase):
    SIZE = 21
    HEIGHT = 2.0

    def setUp(self):
        self.points, self.triangles = grid(self.SIZE)
        self.mesh = quality.WeldedMesh(self.points, self.triangles)
        # A grid of unit squares cut along one diagonal: edges of 1 and sqrt(2).
        self.assertAlmostEqual(self.mesh.mean_rest_edge_length, 1.0 + (math.sqrt(2.0) - 1.0) * 400 / 1240,
                               places=9)

    def test_a_smooth_bump_is_far_below_its_height(self):
        centre, sigma = 10.0, 3.0
        offsets = [(0.0, 0.0, self.HEIGHT * math.exp(-((x - centre) ** 2 + (y - centre) ** 2) / (2 * sigma ** 2)))
                   for x, y, _z in self.points]
        rough, largest, _vertex = quality.roughness(offsets, self.mesh)
        self.assertAlmostEqual(largest, self.HEIGHT / self.mesh.mean_rest_edge_length, places=9)
        self.assertLess(rough, 0.15 * largest)
        self.assertGreater(rough, 0.0)

    def test_a_spike_is_as_rough_as_it_is_tall(self):
        offsets = [(0.0, 0.0, 0.0)] * len(self.points)
        spike = 10 * self.SIZE + 10
        offsets[spike] = (0.0, 0.0, self.HEIGHT)
        rough, largest, vertex = quality.roughness(offsets, self.mesh)
        self.assertEqual(vertex, spike)
        self.assertAlmostEqual(rough, self.HEIGHT / self.mesh.mean_rest_edge_length, places=9)
        self.assertAlmostEqual(rough, largest, places=9)

    def test_a_spike_on_a_bump_is_found(self):
        offsets = [(0.0, 0.0, 0.5 * math.exp(-((x - 10) ** 2 + (y - 10) ** 2) / 18.0)) for x, y, _z in self.points]
        offsets[10 * self.SIZE + 12] = (0.0, 0.0, offsets[10 * self.SIZE + 12][2] + 1.0)
        rough, largest, vertex = quality.roughness(offsets, self.mesh)
        self.assertEqual(vertex, 10 * self.SIZE + 12)
        self.assertGreater(rough, 0.8 / self.mesh.mean_rest_edge_length)


class TestShards(unittest.TestCase):
    """shard: how much further out of its neighbours' surface the correction leaves a vertex than plain skinning."""
    SIZE = 21

    def setUp(self):
        self.points, self.triangles = grid(self.SIZE)
        self.mesh = quality.WeldedMesh(self.points, self.triangles)
        self.unit = self.mesh.mean_rest_edge_length
        self.centre = 10 * self.SIZE + 10

    def lifted(self, points, vertex, height):
        return [(x, y, z + (height if i == vertex else 0.0)) for i, (x, y, z) in enumerate(points)]

    def test_a_vertex_pushed_out_is_a_shard(self):
        value, vertex = quality.shard(self.points, self.lifted(self.points, self.centre, 0.8), self.mesh)
        self.assertEqual(vertex, self.centre)
        self.assertAlmostEqual(value, 0.8 / self.unit, places=6)

    def test_a_smooth_bulge_is_none(self):
        bulge = [(x, y, 2.0 * math.exp(-((x - 10) ** 2 + (y - 10) ** 2) / 18.0)) for x, y, _z in self.points]
        value, _vertex = quality.shard(self.points, bulge, self.mesh)
        self.assertLess(value, 0.15 / self.unit)

    def test_never_more_than_the_roughness(self):
        generator = random.Random(46)
        bumpy = [(x + 0.2 * generator.random(), y + 0.2 * generator.random(), 0.3 * math.sin(x) * math.cos(y))
                 for x, y, _z in self.points]
        moved = [tuple(c + 0.3 * generator.random() for c in point) for point in bumpy]
        value, _vertex = quality.shard(bumpy, moved, self.mesh)
        rough = quality.roughness(quality.offsets_between(bumpy, moved), self.mesh)[0]
        self.assertGreater(value, 0.0)
        self.assertLessEqual(value, rough + 1e-12)

    def test_a_fold_pressed_flat_is_none(self):
        # Plain skinning leaves a vertex folded 0.8 out of the surface; the correction puts it back: its offset is
        # as rough as a spike, its surface smoother than plain skinning's.
        folded = self.lifted(self.points, self.centre, 0.8)
        offsets = quality.offsets_between(folded, self.points)
        self.assertAlmostEqual(quality.roughness(offsets, self.mesh)[0], 0.8 / self.unit, places=6)
        value, _vertex = quality.shard(folded, self.points, self.mesh)
        self.assertLessEqual(value, 0.0)


class TestSurfaceFaults(unittest.TestCase):
    """surface_faults: QUALITY.md's limits on one correction's measures, as the family tests hold them."""
    SIZE = 21

    def setUp(self):
        self.points, self.triangles = grid(self.SIZE)
        self.mesh = quality.WeldedMesh(self.points, self.triangles)
        self.edges = len(self.mesh.interior_edges())
        self.bulge = [(x, y, 2.0 * math.exp(-((x - 10) ** 2 + (y - 10) ** 2) / 18.0)) for x, y, _z in self.points]

    def measured(self, positions):
        """The measures surface_faults reads, as measure_pose gives them (which a sheet, holding no volume, cannot
        take)."""
        rough, largest, _vertex = quality.roughness(quality.offsets_between(self.points, positions), self.mesh)
        return {"roughness": rough, "largest_offset": largest,
                "shard": quality.shard(self.points, positions, self.mesh)[0],
                "creases": len(quality.creases_added(self.points, positions, self.mesh))}

    def test_a_smooth_bulge_holds(self):
        self.assertEqual(quality.surface_faults(self.measured(self.bulge), self.edges), [])

    def test_a_spike_on_the_bulge_is_rough_a_shard_and_creased(self):
        spiked = list(self.bulge)
        x, y, z = spiked[10 * self.SIZE + 12]
        spiked[10 * self.SIZE + 12] = (x, y, z + 1.5)
        measured = self.measured(spiked)
        faults = quality.surface_faults(measured, self.edges)
        self.assertEqual([fault.split()[0] for fault in faults], ["roughness", "shard", str(measured["creases"])],
                         faults)
        self.assertEqual(quality.surface_faults(measured, self.edges, roughness=False, shard=False, creases=False), [])

    def test_creases_past_one_per_300_edges(self):
        # A sheet folded up by 90 degrees along the row x = 10: each edge on it a crease, 20 of them against the
        # 3.9 allowed on the sheet's 1,160 interior edges; as many already added by another setting are not counted.
        folded = [(x, y, 0.0) if x <= 10 else (10.0, y, x - 10.0) for x, y, _z in self.points]
        measured = self.measured(folded)
        self.assertEqual((self.edges, measured["creases"]), (1160, 20))
        self.assertEqual(len(quality.surface_faults(measured, self.edges, roughness=False, shard=False)), 1)
        self.assertEqual(quality.surface_faults(measured, self.edges, roughness=False, shard=False,
                                                creases_before=measured["creases"]), [])


class TestPopping(unittest.TestCase):
    """offset_change_ratio: a bulge that grows with the bend changes by a fraction of the skin's motion; one that
    appears at once (a region starting to be corrected) by more than the skin moved."""

    def setUp(self):
        self.points, _triangles = grid(11)
        # The skin turns a little between the two frames: the far corner moves most, by 0.1 * its distance.
        self.plain_before = list(self.points)
        self.plain = [(x, y, 0.1 * x) for x, y, _z in self.points]
        self.motion = max(0.1 * x for x, _y, _z in self.points)

    def bump(self, height):
        return [(0.0, 0.0, height * math.exp(-((x - 5) ** 2 + (y - 5) ** 2) / 8.0)) for x, y, _z in self.points]

    def test_a_bulge_that_follows_the_motion(self):
        ratio = quality.offset_change_ratio(self.bump(0.20), self.bump(0.25), self.plain_before, self.plain)
        self.assertAlmostEqual(ratio, 0.05 / self.motion, places=9)
        self.assertLess(ratio, 0.25)

    def test_a_bulge_that_pops(self):
        ratio = quality.offset_change_ratio(self.bump(0.0), self.bump(1.5), self.plain_before, self.plain)
        self.assertAlmostEqual(ratio, 1.5 / self.motion, places=9)
        self.assertGreater(ratio, 1.0)

    def test_no_motion_no_ratio(self):
        self.assertEqual(quality.offset_change_ratio(self.bump(0.0), self.bump(1.0), self.points, self.points), 0.0)


class TestVolume(unittest.TestCase):

    def test_sphere_volume_and_its_change(self):
        points, triangles = uv_sphere(rings=48, around=64)
        self.assertAlmostEqual(quality.mesh_volume(points, triangles), 4.0 / 3.0 * math.pi, delta=0.02)
        grown = [(1.1 * x, 1.1 * y, 1.1 * z) for x, y, z in points]
        self.assertAlmostEqual(quality.volume_change(points, grown, triangles), 0.331, places=9)
        self.assertAlmostEqual(quality.volume_change(flat(points), flat(grown), flat(triangles)), 0.331, places=9)


class TestSeams(unittest.TestCase):
    """A mesh split at its seams measures as its welded version does."""

    def setUp(self):
        self.points, self.triangles = uv_sphere(rings=16, around=24)
        self.split_points, self.split_triangles, self.origin = split_at_box_seams(self.points, self.triangles)
        self.assertGreater(len(self.split_points), len(self.points) + 40, "the split mesh has seams")

    def poses(self, points):
        """Plain: squashed along Z, crossing itself near the poles; corrected: plain plus a smooth bulge on +X, a
        spike at one vertex and a ridge along the equator."""
        plain = [(x, y, 0.9 * z - (1.5 * z * abs(z) if abs(z) > 0.9 else 0.0)) for x, y, z in points]
        corrected = []
        for (x, y, z), (px, py, pz) in zip(points, plain):
            bulge = 0.3 * math.exp(-((x - 1.0) ** 2 + y ** 2 + z ** 2) / 0.3)
            ridge = 0.2 if abs(z) < 1e-9 and y > 0 else 0.0
            spike = 0.5 if (x, y, z) == self.points[40] else 0.0
            corrected.append((px * (1 + bulge + ridge + spike), py * (1 + bulge + ridge + spike), pz))
        return plain, corrected

    def test_weld_map(self):
        weld = quality.weld_map(self.split_points)
        for index, representative in enumerate(weld):
            self.assertEqual(self.split_points[index], self.split_points[representative])
            self.assertLessEqual(representative, index)
        self.assertEqual(len(set(weld)), len(self.points))
        mesh = quality.WeldedMesh(self.split_points, self.split_triangles)
        self.assertEqual(mesh.split_vertex_count, len(self.split_points) - len(self.points))
        # Relative to the mesh's size: 1e-3 apart on a sphere of diameter 2 are two points.
        apart = [(0.0, 0.0, 0.0), (1e-3, 0.0, 0.0), (2.0, 0.0, 0.0), (1e-9, 0.0, 0.0)]
        self.assertEqual(quality.weld_map(apart), [0, 1, 2, 0])

    def test_split_and_welded_measure_the_same(self):
        plain, corrected = self.poses(self.points)
        split_plain = [plain[v] for v in self.origin]
        split_corrected = [corrected[v] for v in self.origin]
        whole = quality.WeldedMesh(self.points, self.triangles)
        split = quality.WeldedMesh(self.split_points, self.split_triangles)
        self.assertEqual(len(split.edges), len(whole.edges))
        self.assertEqual(len(split.interior_edges()), len(whole.edges), "no open border once welded")
        measured_whole = quality.measure_pose(whole, plain, {"vp": corrected})
        measured_split = quality.measure_pose(split, split_plain, {"vp": split_corrected})
        self.assertGreater(measured_whole["plain"]["crossings"], 0, "the squashed poles cross")
        self.assertGreater(measured_whole["vp"]["creases"], 0, "the ridge")
        for pose in ("plain", "vp"):
            for name, value in measured_whole[pose].items():
                self.assertAlmostEqual(measured_split[pose][name], value, places=9, msg="%s %s" % (pose, name))
        self.assertEqual(measured_split["vp"]["crack"], 0.0)
        # Unwelded, the seams would be open borders, and the measures would change: this sphere's seams run where
        # its bulge is, so the roughness, which sees fewer neighbours along them, differs.
        unwelded = quality.WeldedMesh(self.split_points, self.split_triangles, weld=False)
        self.assertLess(len(unwelded.interior_edges()), len(whole.edges) - 40)
        offsets = quality.offsets_between(split_plain, split_corrected)
        self.assertNotAlmostEqual(quality.roughness(offsets, unwelded)[0], measured_whole["vp"]["roughness"], places=3)

    def test_a_crack_is_measured(self):
        plain, corrected = self.poses(self.points)
        split = quality.WeldedMesh(self.split_points, self.split_triangles)
        offsets = quality.offsets_between([plain[v] for v in self.origin], [corrected[v] for v in self.origin])
        copy = next(index for index, representative in enumerate(split.weld) if representative != index)
        offsets[copy] = (offsets[copy][0] + 0.1, offsets[copy][1], offsets[copy][2])
        self.assertAlmostEqual(quality.crack(offsets, split), 0.1 / split.mean_rest_edge_length, places=6)


if __name__ == "__main__":
    unittest.main()
