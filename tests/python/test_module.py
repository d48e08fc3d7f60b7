"""Tests of the _lvp extension module against the real C core (contract: docs/python_module.md).

Run all:   ./build.sh test   (or: PYTHONPATH=build /usr/bin/python3 -m unittest discover -s tests/python)
Run one:   PYTHONPATH=build /usr/bin/python3 -m unittest -v test_module.TestBinding.test_correct_reduces_volume_error
           (from tests/python)

Meshes are built here with the array module only: the module must work without numpy.
"""

import array
import ctypes
import math
import random
import struct
import subprocess
import sys
import threading
import unittest

import _lvp


# ---- geometry ------------------------------------------------------------------------------------------------------


def identity_matrix():
    return [1.0 if row == column else 0.0 for row in range(4) for column in range(4)]


def translation_matrix(x, y, z):
    matrix = identity_matrix()
    matrix[3], matrix[7], matrix[11] = x, y, z
    return matrix


def rotation_z_matrix(angle):
    """Rotation about the z axis through the origin, row-major, acting on column vectors."""
    cosine, sine = math.cos(angle), math.sin(angle)
    matrix = identity_matrix()
    matrix[0], matrix[1], matrix[4], matrix[5] = cosine, -sine, sine, cosine
    return matrix


def multiply_matrices(left, right):
    return [sum(left[4 * row + k] * right[4 * k + column] for k in range(4)) for row in range(4) for column in range(4)]


def transform_point(matrix, point):
    return [sum(matrix[4 * row + k] * point[k] for k in range(3)) + matrix[4 * row + 3] for row in range(3)]


def unit_cube():
    """The unit cube [0, 1]^3, triangles counter-clockwise seen from outside."""
    positions = array.array('f', [0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1])
    triangles = array.array('i', [
        0, 2, 1, 0, 3, 2,  # bottom, z = 0
        4, 5, 6, 4, 6, 7,  # top, z = 1
        0, 1, 5, 0, 5, 4,  # front, y = 0
        2, 3, 7, 2, 7, 6,  # back, y = 1
        1, 2, 6, 1, 6, 5,  # right, x = 1
        3, 0, 4, 3, 4, 7,  # left, x = 0
    ])
    return positions, triangles


class Tube:
    """A closed tube along x from -length/2 to length/2 (a ring of `around` vertices at each of `rings` stations
    and a centre vertex closing each end) with two bones meeting at x = 0, bone 0 from -length/2 to 0 and bone 1
    from 0 to length/2. Bone 1's weight rises linearly from 0 to 1 over `band` centred on the joint, as in the
    paper's cylinder; outside the band every vertex follows one bone rigidly."""

    def __init__(self, around=16, rings=17, radius=0.5, length=4.0, band=2.6):
        self.around, self.rings, self.radius, self.length, self.band = around, rings, radius, length, band
        points = []
        for ring in range(rings):
            x = -length / 2 + length * ring / (rings - 1)
            for step in range(around):
                angle = 2 * math.pi * step / around
                points.append((x, radius * math.cos(angle), radius * math.sin(angle)))
        self.start_centre = len(points)
        points.append((-length / 2, 0.0, 0.0))
        self.end_centre = len(points)
        points.append((length / 2, 0.0, 0.0))
        self.points = points
        self.positions = array.array('f', [coordinate for point in points for coordinate in point])
        self.vertex_count = len(points)

        def ring_vertex(ring, step):
            return ring * around + step % around

        triangles = []
        for ring in range(rings - 1):
            for step in range(around):
                a, b = ring_vertex(ring, step), ring_vertex(ring, step + 1)
                c, d = ring_vertex(ring + 1, step), ring_vertex(ring + 1, step + 1)
                triangles += [a, b, c, b, d, c]
        for step in range(around):
            triangles += [self.start_centre, ring_vertex(0, step + 1), ring_vertex(0, step)]
            triangles += [self.end_centre, ring_vertex(rings - 1, step), ring_vertex(rings - 1, step + 1)]
        self.triangles = array.array('i', triangles)
        self.triangle_count = len(triangles) // 3

        offsets, bones, values = [0], [], []
        for x, _, _ in points:
            weight_1 = min(max((x + band / 2) / band, 0.0), 1.0)
            for bone, weight in ((0, 1.0 - weight_1), (1, weight_1)):
                if weight > 0.0:
                    bones.append(bone)
                    values.append(weight)
            offsets.append(len(bones))
        self.weight_offsets = array.array('i', offsets)
        self.weight_bones = array.array('i', bones)
        self.weight_values = array.array('f', values)

        self.rest_frames = [translation_matrix(-length / 2, 0, 0), translation_matrix(0, 0, 0)]
        self.rest_matrices = array.array('f', self.rest_frames[0] + self.rest_frames[1])
        self.heads = array.array('f', [-length / 2, 0, 0, 0, 0, 0])
        self.tails = array.array('f', [0, 0, 0, length / 2, 0, 0])

    def prism_volume(self):
        """The exact volume of the tube: its polygonal cross-section times its length."""
        return self.length * self.around / 2 * self.radius ** 2 * math.sin(2 * math.pi / self.around)

    def rigid_vertices(self):
        """Vertices outside the weight band, which follow one bone rigidly."""
        return [index for index, point in enumerate(self.points) if abs(point[0]) > self.band / 2 + 1e-6]

    def bone_matrices(self, angle):
        """Posed bone frames: bone 1 turned by `angle` about z around the joint, bone 0 at rest."""
        posed_1 = multiply_matrices(rotation_z_matrix(angle), self.rest_frames[1])
        return array.array('f', self.rest_frames[0] + posed_1)

    def skin_matrices(self, angle):
        """posed * rest^-1 per bone, what skin_linear takes."""
        return array.array('f', identity_matrix() + rotation_z_matrix(angle))

    def skinned(self, angle):
        positions = array.array('f', bytes(4 * 3 * self.vertex_count))
        _lvp.skin_linear(positions, self.positions, self.weight_offsets, self.weight_bones, self.weight_values,
                         self.skin_matrices(angle))
        return positions

    def binding(self, **options):
        return _lvp.Binding(self.positions, self.triangles, self.weight_offsets, self.weight_bones,
                            self.weight_values, self.rest_matrices, self.heads, self.tails, **options)


def zeros(typecode, count):
    return array.array(typecode, bytes(array.array(typecode).itemsize * count))


def volume(positions, triangles):
    return _lvp.mesh_volume(positions, triangles)


STATS_KEYS = {
    'volume_rest', 'volume_before', 'volume_after', 'worst_region', 'worst_region_change_before',
    'worst_region_change_after', 'iterations', 'active_regions', 'skipped_regions', 'folded_vertices',
    'max_displacement', 'passed_through', 'unskinned_distance', 'given_up_regions', 'given_up_region',
    'given_up_diverged', 'shortened_vertices', 'kept_apart_vertices', 'crossing_triangles', 'bones_scale',
}


# ---- stand-alone functions -----------------------------------------------------------------------------------------


class TestGeometry(unittest.TestCase):

    def test_version(self):
        self.assertEqual(_lvp.version, '0.1.0')

    def test_unit_cube_volume_is_one(self):
        positions, triangles = unit_cube()
        self.assertAlmostEqual(_lvp.mesh_volume(positions, triangles), 1.0, places=12)
        self.assertAlmostEqual(_lvp.mesh_volume(positions=positions, triangles=triangles), 1.0, places=12)

    def test_tube_volume_is_its_prism_volume(self):
        tube = Tube()
        self.assertAlmostEqual(volume(tube.positions, tube.triangles), tube.prism_volume(), places=5)

    def test_volume_gradient_identities(self):
        # On a closed mesh the volume is homogeneous of degree 3 and translation invariant, so
        # sum_k p_k . grad_k V = 3 V and sum_k grad_k V = 0.
        tube = Tube()
        gradient = zeros('f', 3 * tube.vertex_count)
        self.assertIsNone(_lvp.volume_gradient(gradient, tube.positions, tube.triangles))
        euler = sum(gradient[i] * tube.positions[i] for i in range(len(gradient)))
        self.assertAlmostEqual(euler, 3 * volume(tube.positions, tube.triangles), places=4)
        for axis in range(3):
            self.assertAlmostEqual(sum(gradient[axis::3]), 0.0, places=5)

    def test_volume_gradient_matches_finite_difference(self):
        positions, triangles = unit_cube()
        gradient = zeros('f', 24)
        _lvp.volume_gradient(out=gradient, positions=positions, triangles=triangles)
        step = 1e-2  # the volume is a polynomial of degree 1 in each coordinate, so this step is exact
        for index in range(24):
            moved = array.array('f', positions)
            moved[index] += step
            difference = (volume(moved, triangles) - volume(positions, triangles)) / step
            self.assertAlmostEqual(gradient[index], difference, places=4, msg=f'coordinate {index}')

    def test_vertex_normals_are_unit_and_radial_on_the_tube(self):
        tube = Tube()
        normals = zeros('f', 3 * tube.vertex_count)
        self.assertIsNone(_lvp.vertex_normals(normals, tube.positions, tube.triangles))
        for index, (x, y, z) in enumerate(tube.points):
            normal = normals[3 * index:3 * index + 3]
            self.assertAlmostEqual(math.sqrt(sum(value * value for value in normal)), 1.0, places=5)
            if 0 < index // tube.around < tube.rings - 1 and index < tube.start_centre:  # inner rings
                self.assertGreater((normal[1] * y + normal[2] * z) / tube.radius, 0.99)
        self.assertLess(normals[3 * tube.start_centre], -0.99)
        self.assertGreater(normals[3 * tube.end_centre], 0.99)

    def test_skin_linear_with_identity_returns_rest(self):
        tube = Tube()
        out = zeros('f', 3 * tube.vertex_count)
        identities = array.array('f', identity_matrix() * 2)
        self.assertIsNone(_lvp.skin_linear(out, tube.positions, tube.weight_offsets, tube.weight_bones,
                                           tube.weight_values, identities))
        self.assertEqual(out, tube.positions)

    def test_skin_linear_blends_the_bone_matrices(self):
        tube = Tube()
        angle = math.radians(60)
        skinned = tube.skinned(angle)
        rotation = rotation_z_matrix(angle)
        for index, point in enumerate(tube.points):
            begin, end = tube.weight_offsets[index], tube.weight_offsets[index + 1]
            expected = [0.0, 0.0, 0.0]
            for entry in range(begin, end):
                matrix = identity_matrix() if tube.weight_bones[entry] == 0 else rotation
                moved = transform_point(matrix, point)
                expected = [expected[axis] + tube.weight_values[entry] * moved[axis] for axis in range(3)]
            for axis in range(3):
                self.assertAlmostEqual(skinned[3 * index + axis], expected[axis], places=5)

    def test_skin_dual_quaternion(self):
        tube = Tube()
        out = zeros('f', 3 * tube.vertex_count)
        identities = array.array('f', identity_matrix() * 2)
        _lvp.skin_dual_quaternion(out, tube.positions, tube.weight_offsets, tube.weight_bones, tube.weight_values,
                                  identities)
        for index in range(len(out)):
            self.assertAlmostEqual(out[index], tube.positions[index], places=6)
        angle = math.radians(90)
        _lvp.skin_dual_quaternion(out=out, rest_positions=tube.positions, weight_offsets=tube.weight_offsets,
                                  weight_bones=tube.weight_bones, weight_values=tube.weight_values,
                                  skin_matrices=tube.skin_matrices(angle))
        linear = tube.skinned(angle)
        for index in tube.rigid_vertices():  # one bone: both methods apply its matrix exactly
            for axis in range(3):
                self.assertAlmostEqual(out[3 * index + axis], linear[3 * index + axis], places=5)
        # Blending rotations instead of matrices keeps the joint from collapsing.
        rest_volume = volume(tube.positions, tube.triangles)
        self.assertLess(abs(volume(out, tube.triangles) - rest_volume),
                        abs(volume(linear, tube.triangles) - rest_volume))

    def test_auto_weights_rows_are_normalized(self):
        tube = Tube()
        for visibility in ('NORMAL', 'EXACT', 'NONE'):
            with self.subTest(visibility=visibility):
                offsets, bones, values = _lvp.auto_weights(tube.positions, tube.triangles, tube.rest_matrices,
                                                           tube.heads, tube.tails, visibility=visibility)
                self.assertEqual((offsets.typecode, bones.typecode, values.typecode), ('i', 'i', 'f'))
                self.assertEqual(len(offsets), tube.vertex_count + 1)
                self.assertEqual(offsets[0], 0)
                self.assertEqual(len(bones), offsets[-1])
                self.assertEqual(len(values), offsets[-1])
                for vertex in range(tube.vertex_count):
                    row = values[offsets[vertex]:offsets[vertex + 1]]
                    self.assertGreater(len(row), 0, f'vertex {vertex} has no weight')
                    self.assertAlmostEqual(sum(row), 1.0, places=5, msg=f'vertex {vertex}')
                    self.assertEqual(list(row), sorted(row, reverse=True))
                    self.assertTrue(all(bone in (0, 1) for bone in bones[offsets[vertex]:offsets[vertex + 1]]))
                # The far ends are much closer to their own bone.
                start_row = offsets[tube.start_centre]
                self.assertEqual(bones[start_row], 0)
                self.assertEqual(bones[offsets[tube.end_centre]], 1)

    def test_auto_weights_options(self):
        tube = Tube()
        offsets, bones, values = _lvp.auto_weights(tube.positions, tube.triangles, tube.rest_matrices, tube.heads,
                                                   tube.tails, alpha=3.0, visibility='NONE', normal_cos_max=0.5,
                                                   max_influences=1, min_weight=0.0)
        self.assertEqual(list(offsets), list(range(tube.vertex_count + 1)))
        self.assertTrue(all(value == 1.0 for value in values))

    def test_auto_weights_by_length(self):
        # Bone 1 shortened to a quarter: by its length it reaches a quarter as far, so the vertices of the
        # joint's ring lean to bone 0; by distance alone they are shared evenly.
        tube = Tube()
        tails = array.array('f', tube.tails)
        tails[3] = tube.heads[3] + 0.25 * (tube.tails[3] - tube.heads[3])
        arguments = (tube.positions, tube.triangles, tube.rest_matrices, tube.heads, tails)
        joint_ring = [(tube.rings // 2) * tube.around + index for index in range(tube.around)]
        for by_length, least_on_bone_0 in ((True, 0.99), (False, 0.49)):
            offsets, bones, values = _lvp.auto_weights(*arguments, alpha=4.0, visibility='NONE', by_length=by_length,
                                                       min_weight=0.0)
            for vertex in joint_ring:
                row = dict(zip(bones[offsets[vertex]:offsets[vertex + 1]], values[offsets[vertex]:offsets[vertex + 1]]))
                self.assertGreater(row.get(0, 0.0), least_on_bone_0, f'by_length {by_length}, vertex {vertex}')
                if not by_length:
                    self.assertAlmostEqual(row.get(0, 0.0), 0.5, places=4)

    def test_auto_weights_facing(self):
        # Measured along the normal, the other bone lies off to the side of a ring beside the joint (its closest
        # point is the joint, the path oblique to the skin) and counts farther: each ring's own bone gains weight,
        # the joint's ring (the two bones alike) stays shared evenly. The end rings, at the caps' rims, face
        # both ways and are left out.
        tube = Tube()
        arguments = (tube.positions, tube.triangles, tube.rest_matrices, tube.heads, tube.tails)
        rows = {}
        for facing in (False, True):
            offsets, bones, values = _lvp.auto_weights(*arguments, alpha=4.0, visibility='NONE', by_length=False,
                                                       min_weight=0.0, facing=facing)
            rows[facing] = [dict(zip(bones[offsets[vertex]:offsets[vertex + 1]],
                                     values[offsets[vertex]:offsets[vertex + 1]]))
                            for vertex in range(tube.vertex_count)]
        for ring in range(1, tube.rings - 1):
            own = 0 if ring < tube.rings // 2 else 1
            for step in range(tube.around):
                vertex = ring * tube.around + step
                straight, facing = rows[False][vertex], rows[True][vertex]
                self.assertAlmostEqual(sum(facing.values()), 1.0, places=5)
                if ring == tube.rings // 2:
                    self.assertAlmostEqual(facing.get(0, 0.0), 0.5, places=4)
                elif abs(ring - tube.rings // 2) == 1:
                    self.assertGreater(facing.get(own, 0.0), straight.get(own, 0.0) + 0.01, f'vertex {vertex}')
                else:
                    self.assertGreaterEqual(facing.get(own, 0.0), straight.get(own, 0.0) - 1e-6, f'vertex {vertex}')

    def test_auto_weights_smoothing(self):
        tube = Tube()
        arguments = (tube.positions, tube.triangles, tube.rest_matrices, tube.heads, tube.tails)
        sharp = _lvp.auto_weights(*arguments, alpha=16.0)
        smooth = _lvp.auto_weights(*arguments, alpha=16.0, smoothing_iterations=10)
        self.assertNotEqual(list(sharp[2]), list(smooth[2]))
        by_length = _lvp.auto_weights(*arguments, alpha=16.0, smoothing_length=0.5)
        self.assertNotEqual(list(sharp[2]), list(by_length[2]))
        by_thickness = _lvp.auto_weights(*arguments, alpha=16.0, smoothing_thickness=1.0)
        self.assertNotEqual(list(sharp[2]), list(by_thickness[2]))
        heat = _lvp.auto_weights(*arguments, facing=True, heat=True)
        self.assertNotEqual(list(sharp[2]), list(heat[2]))
        self.assertEqual([list(part) for part in heat],
                         [list(part) for part in _lvp.auto_weights(*arguments, facing=True, heat=True, threads=2)])
        for offsets, bones, values in (smooth, by_thickness, heat):
            for vertex in range(tube.vertex_count):
                row = values[offsets[vertex]:offsets[vertex + 1]]
                self.assertAlmostEqual(sum(row), 1.0, places=5, msg=f'vertex {vertex}')
                self.assertEqual(list(row), sorted(row, reverse=True))


# ---- Binding -------------------------------------------------------------------------------------------------------


def float32(value):
    return struct.unpack('f', struct.pack('f', value))[0]


def mathutils_product(left, right):
    """left @ right (row-major lists) as Blender's mathutils computes it: each product in float32, summed in
    double from 0 in order, rounded once to float32."""
    result = []
    for row in range(4):
        for column in range(4):
            dot = 0.0
            for item in range(4):
                dot += float32(left[4 * row + item] * right[4 * item + column])
            result.append(float32(dot))
    return result


def columns_of(rows):
    """A row-major matrix stored column by column, as Blender keeps it."""
    return [rows[4 * row + column] for column in range(4) for row in range(4)]


def random_matrix(generator):
    return [float32(generator.uniform(-2.0, 2.0)) for _ in range(12)] + [0.0, 0.0, 0.0, 1.0]


class TestComposeFrames(unittest.TestCase):
    """compose_frames: posed frames from Blender's matrices, bit for bit as mathutils composes them."""

    def compose(self, premat, bones, joint_counts, joints, corrections=None):
        frame_count = sum(count or 1 for count in joint_counts)
        out = zeros('f', 16 * frame_count)
        columns = (lambda matrices: array.array('f', [value for matrix in matrices for value in columns_of(matrix)]))
        _lvp.compose_frames(out, columns([premat]), columns(bones), array.array('i', joint_counts), columns(joints),
                            None if corrections is None else columns(corrections))
        return out

    def expected(self, premat, bones, joint_counts, joints, corrections=None):
        frames, next_joint = [], 0
        for bone, count in zip(bones, joint_counts):
            posed_bone = mathutils_product(premat, bone)
            if count == 0:
                frames.append(posed_bone)
            for _joint in range(count):
                frames.append(mathutils_product(posed_bone, joints[next_joint]))
                next_joint += 1
        if corrections is not None:
            frames = [mathutils_product(frame, correction) for frame, correction in zip(frames, corrections)]
        return array.array('f', [value for frame in frames for value in frame])

    def test_whole_bones_and_joints_bit_for_bit(self):
        generator = random.Random(47)
        premat = random_matrix(generator)
        joint_counts = [0, 4, 0, 2]
        bones = [random_matrix(generator) for _ in joint_counts]
        joints = [random_matrix(generator) for _ in range(sum(joint_counts))]
        corrections = [random_matrix(generator) for _ in range(8)]
        for given in (None, corrections):
            with self.subTest(corrections=given is not None):
                out = self.compose(premat, bones, joint_counts, joints, given)
                self.assertEqual(out.tobytes(), self.expected(premat, bones, joint_counts, joints, given).tobytes())

    def test_reads_columns_and_writes_rows(self):
        bone = [float(value) for value in range(1, 17)]
        out = self.compose(identity_matrix(), [bone], [0], [])
        self.assertEqual(list(out), bone)

    def test_negative_zero_as_mathutils(self):
        # 0.0 + -0.0 is 0.0: a -0.0 in a bone's matrix comes out as 0.0 through the identity, as in mathutils.
        bone = identity_matrix()
        bone[1] = -0.0
        out = self.compose(identity_matrix(), [bone], [0], [])
        self.assertEqual(math.copysign(1.0, out[1]), 1.0)

    def test_no_bones(self):
        out = zeros('f', 0)
        _lvp.compose_frames(out, array.array('f', identity_matrix()), zeros('f', 0), zeros('i', 0), zeros('f', 0))
        self.assertEqual(len(out), 0)


class TestBinding(unittest.TestCase):

    def test_counts(self):
        tube = Tube()
        binding = tube.binding()
        self.assertEqual(binding.vertex_count, tube.vertex_count)
        self.assertEqual(binding.triangle_count, tube.triangle_count)
        self.assertEqual(binding.bone_count, 2)
        self.assertEqual(binding.region_count, 2)
        self.assertEqual(binding.flipped_edge_count, 0)
        with self.assertRaises(AttributeError):
            binding.vertex_count = 3
        self.assertIn('Binding', repr(binding))

    def test_correct_reduces_volume_error(self):
        tube = Tube()
        binding = tube.binding()
        rest_volume = volume(tube.positions, tube.triangles)
        for degrees in (10, 50, 90):
            with self.subTest(degrees=degrees):
                angle = math.radians(degrees)
                positions = tube.skinned(angle)
                before = volume(positions, tube.triangles)
                out_positions = zeros('f', 3 * tube.vertex_count)
                out_offsets = zeros('f', 3 * tube.vertex_count)
                stats = binding.correct(positions, tube.bone_matrices(angle), out_positions=out_positions,
                                        out_offsets=out_offsets)
                after = volume(out_positions, tube.triangles)
                self.assertLess(abs(after - rest_volume), abs(before - rest_volume))
                self.assertLess(abs(after - rest_volume) / rest_volume, 1e-3)
                for index in range(len(positions)):
                    self.assertAlmostEqual(out_positions[index], positions[index] + out_offsets[index], places=5)
                self.assertEqual(set(stats), STATS_KEYS)
                self.assertAlmostEqual(stats['volume_rest'], rest_volume, places=4)
                self.assertAlmostEqual(stats['volume_before'], before, places=4)
                self.assertAlmostEqual(stats['volume_after'], after, places=4)
                self.assertGreaterEqual(stats['iterations'], 1)
                self.assertIn(stats['worst_region'], (0, 1))
                self.assertGreater(stats['max_displacement'], 0.0)
                for index in tube.rigid_vertices():  # the correction stays at the joint
                    for axis in range(3):
                        self.assertLess(abs(out_offsets[3 * index + axis]), 0.01 * tube.radius)

    def test_correct_options(self):
        tube = Tube()
        binding = tube.binding()
        angle = math.radians(90)
        positions = tube.skinned(angle)
        offsets = zeros('f', 3 * tube.vertex_count)
        matrices = tube.bone_matrices(angle)
        stats = binding.correct(positions, matrices, out_offsets=offsets, rest_positions=tube.positions, iterations=1,
                                tolerance=1e-3)
        self.assertEqual(stats['iterations'], 1)  # the paper's single pass
        stats = binding.correct(positions, matrices, out_offsets=offsets, fold_over=True)
        self.assertGreaterEqual(stats['folded_vertices'], 0)
        # A limit below what the bend needs gives up the regions (lvp.h, DEGRADING): none corrected.
        stats = binding.correct(positions, matrices, out_offsets=offsets, displacement_limit=1e-6)
        self.assertEqual((stats['given_up_regions'], stats['given_up_diverged']), (2, 1))
        self.assertIn(stats['given_up_region'], (0, 1))
        self.assertEqual(stats['max_displacement'], 0.0)
        stats = binding.correct(positions, matrices, out_offsets=offsets, displacement_limit=10.0)
        self.assertEqual((stats['given_up_regions'], stats['given_up_region']), (0, -1))
        self.assertGreater(stats['max_displacement'], 0.0)
        rest_volume = stats['volume_rest']
        self.assertLess(abs(stats['volume_after'] - rest_volume), abs(stats['volume_before'] - rest_volume))
        # Smoothing the offsets: another shape, the volume restored as well (lvp.h, OFFSET SMOOTHING).
        binding.correct(positions, matrices, out_offsets=offsets)
        smoothed = zeros('f', 3 * tube.vertex_count)
        stats = binding.correct(positions, matrices, out_offsets=smoothed, smoothing_passes=2)
        self.assertNotEqual(smoothed, offsets)
        self.assertLess(abs(stats['volume_after'] / rest_volume - 1.0), 1e-4)
        for passes in (-1, 65):
            with self.assertRaises(_lvp.Error) as caught:
                binding.correct(positions, matrices, out_offsets=offsets, smoothing_passes=passes)
            self.assertEqual((caught.exception.code, caught.exception.argument),
                             ('invalid_option', 'smoothing_passes'), str(caught.exception))

    def test_correct_in_place(self):
        tube = Tube()
        binding = tube.binding()
        angle = math.radians(70)
        matrices = tube.bone_matrices(angle)
        positions = tube.skinned(angle)
        expected = zeros('f', 3 * tube.vertex_count)
        binding.correct(positions, matrices, out_positions=expected)
        binding.correct(positions, matrices, out_positions=positions)
        self.assertEqual(positions, expected)

    def test_memoryview_and_bytearray_inputs(self):
        tube = Tube()

        def as_memoryview(values):
            return memoryview(bytearray(values.tobytes())).cast(values.typecode)

        self.assertAlmostEqual(_lvp.mesh_volume(as_memoryview(tube.positions), as_memoryview(tube.triangles)),
                               volume(tube.positions, tube.triangles), places=12)
        binding = _lvp.Binding(*(as_memoryview(values) for values in (
            tube.positions, tube.triangles, tube.weight_offsets, tube.weight_bones, tube.weight_values,
            tube.rest_matrices, tube.heads, tube.tails)))
        angle = math.radians(45)
        out_storage = bytearray(4 * 3 * tube.vertex_count)
        stats = binding.correct(as_memoryview(tube.skinned(angle)), as_memoryview(tube.bone_matrices(angle)),
                                out_positions=memoryview(out_storage).cast('f'))
        corrected = array.array('f', out_storage)
        self.assertAlmostEqual(volume(corrected, tube.triangles), stats['volume_after'], places=5)

    def test_explicit_byte_order_formats(self):
        # ctypes arrays export '<f' and '<i': the same items as 'f' and 'i' on this machine.
        tube = Tube()
        positions = (ctypes.c_float * len(tube.positions))(*tube.positions)
        triangles = (ctypes.c_int32 * len(tube.triangles))(*tube.triangles)
        self.assertAlmostEqual(_lvp.mesh_volume(positions, triangles), volume(tube.positions, tube.triangles),
                               places=12)
        swapped_type = ctypes.c_float.__ctype_be__ if sys.byteorder == 'little' else ctypes.c_float.__ctype_le__
        swapped = (swapped_type * len(tube.positions))(*tube.positions)
        with self.assertRaises(ValueError) as caught:
            _lvp.mesh_volume(swapped, triangles)
        self.assertTrue(str(caught.exception).startswith('positions'), str(caught.exception))

    def test_segmentation(self):
        tube = Tube()
        binding = tube.binding()
        vertex_regions = zeros('i', tube.vertex_count)
        triangle_regions = zeros('i', tube.triangle_count)
        self.assertIsNone(binding.segmentation(vertex_regions, triangle_regions))
        for index, (x, _, _) in enumerate(tube.points):
            if abs(x) > 1e-6:
                self.assertEqual(vertex_regions[index], 0 if x < 0 else 1, f'vertex {index} at x = {x}')
        self.assertEqual(set(triangle_regions), {0, 1})
        only_triangles = zeros('i', tube.triangle_count)
        binding.segmentation(out_triangle_regions=only_triangles)
        self.assertEqual(only_triangles, triangle_regions)
        binding.segmentation()

    def test_correction_map_and_set_map(self):
        tube = Tube()
        binding = tube.binding(map='ORGANIC', alpha=1.0, beta=1.0)
        correction_map = zeros('f', tube.vertex_count)
        self.assertIsNone(binding.correction_map(correction_map))
        self.assertAlmostEqual(max(correction_map), 1.0, places=6)
        self.assertGreaterEqual(min(correction_map), 0.0)
        for index in tube.rigid_vertices():
            self.assertEqual(correction_map[index], 0.0)

        binding.set_map('UNIFORM')
        binding.correction_map(correction_map)
        self.assertTrue(all(value == 1.0 for value in correction_map))

        painted = array.array('f', [2.0 * (index % 3) for index in range(tube.vertex_count)])
        binding.set_map(map='PAINTED', painted=painted)
        binding.correction_map(out=correction_map)
        for index in range(tube.vertex_count):
            self.assertAlmostEqual(correction_map[index], painted[index] / 4.0, places=6)

        # Fig. 11: measure the distance term of each region to the other bone only.
        binding.set_map(map='RUBBER', alpha=2.0, beta=0.5, region_bone_offsets=array.array('i', [0, 1, 2]),
                        region_bones=array.array('i', [1, 0]))
        binding.set_map(map='BOUNDARY_FADE')
        binding.set_map()
        binding.correction_map(correction_map)
        self.assertAlmostEqual(max(correction_map), 1.0, places=6)

    def test_region_volume_changes(self):
        tube = Tube()
        binding = tube.binding()
        changes, references = binding.region_volume_changes(tube.positions, tube.bone_matrices(0.0))
        self.assertEqual((changes.typecode, references.typecode), ('d', 'd'))
        self.assertEqual((len(changes), len(references)), (2, 2))
        for change, reference in zip(changes, references):
            self.assertGreater(reference, 0.0)
            self.assertLess(abs(change), 1e-5 * reference)
        angle = math.radians(90)
        positions = tube.skinned(angle)
        changes, references = binding.region_volume_changes(positions, tube.bone_matrices(angle),
                                                             rest_positions=tube.positions)
        self.assertLess(min(changes), -1e-3 * max(references))  # linear blend skinning loses volume
        corrected = zeros('f', 3 * tube.vertex_count)
        stats = binding.correct(positions, tube.bone_matrices(angle), out_positions=corrected)
        after, _ = binding.region_volume_changes(corrected, tube.bone_matrices(angle))
        for region in range(2):
            self.assertLess(abs(after[region]), abs(changes[region]))
        worst = stats['worst_region']
        self.assertAlmostEqual(changes[worst] / references[worst], stats['worst_region_change_before'], places=5)
        self.assertAlmostEqual(after[worst] / references[worst], stats['worst_region_change_after'], places=5)

    def test_global_mode_without_skeleton(self):
        tube = Tube()
        binding = _lvp.Binding(tube.positions, tube.triangles, None, None, None, None, None, None, mode='GLOBAL',
                               map='UNIFORM')
        self.assertEqual((binding.bone_count, binding.region_count), (0, 1))
        squeezed = array.array('f', [value * (0.9 if axis else 1.0)
                                     for index, value in enumerate(tube.positions) for axis in [index % 3]])
        out = zeros('f', 3 * tube.vertex_count)
        binding.correct(squeezed, None, out_positions=out)
        rest_volume = volume(tube.positions, tube.triangles)
        self.assertLess(abs(volume(out, tube.triangles) - rest_volume) / rest_volume, 1e-3)
        binding.correct(squeezed, array.array('f'), out_positions=out)  # no bones: an empty buffer is no matrices
        with self.assertRaises(ValueError) as caught:
            binding.set_map('ORGANIC')
        self.assertTrue(str(caught.exception).startswith('map'), str(caught.exception))

    def test_threads_give_the_same_result(self):
        tube = Tube()
        angle = math.radians(80)
        positions, matrices = tube.skinned(angle), tube.bone_matrices(angle)
        results = []
        for threads in (1, 2):
            out = zeros('f', 3 * tube.vertex_count)
            tube.binding(threads=threads).correct(positions, matrices, out_positions=out)
            results.append(out)
        self.assertEqual(results[0], results[1])

    def test_bone_groups(self):
        # The tube's two bones as one group: one multiplier for both, so nothing tells the bend's two sides
        # apart, and the volume still comes back.
        tube = Tube()
        angle = math.radians(80)
        positions, matrices = tube.skinned(angle), tube.bone_matrices(angle)
        out = zeros('f', 3 * tube.vertex_count)
        stats = tube.binding(bone_groups=array.array('i', [1, 1])).correct(positions, matrices, out_positions=out)
        rest_volume = volume(tube.positions, tube.triangles)
        self.assertLess(abs(volume(out, tube.triangles) - rest_volume) / rest_volume, 1e-3)
        self.assertEqual(stats['active_regions'], 1)

    def test_tails_do_not_change_the_correction(self):
        # Skinning reads no tail: with the bones' parents given, the tails are not read either (lvp.h, BONE
        # LINES). Tails pointing across the tube, as an importer may guess them, give the same offsets.
        tube = Tube()
        angle = math.radians(80)
        positions, matrices = tube.skinned(angle), tube.bone_matrices(angle)
        across = array.array('f', [-tube.length / 2, 0.3, 0, 0, 0, -0.7])
        parents = array.array('i', [-1, 0])
        offsets = []
        for tails in (tube.tails, across):
            out = zeros('f', 3 * tube.vertex_count)
            binding = _lvp.Binding(tube.positions, tube.triangles, tube.weight_offsets, tube.weight_bones,
                                   tube.weight_values, tube.rest_matrices, tube.heads, tails, parents=parents)
            binding.correct(positions, matrices, out_offsets=out)
            offsets.append(out)
        self.assertGreater(max(abs(value) for value in offsets[0]), 1e-3)
        self.assertEqual(offsets[0], offsets[1])

    def test_bulge_width(self):
        # A wider bulge restores the same volume with a smaller largest offset.
        tube = Tube()
        angle = math.radians(80)
        positions, matrices = tube.skinned(angle), tube.bone_matrices(angle)
        rest_volume = volume(tube.positions, tube.triangles)
        largest = []
        for width in (0.0, 1.0):
            out = zeros('f', 3 * tube.vertex_count)
            offsets = zeros('f', 3 * tube.vertex_count)
            tube.binding(bulge_width=width).correct(positions, matrices, out_positions=out, out_offsets=offsets)
            self.assertLess(abs(volume(out, tube.triangles) - rest_volume) / rest_volume, 1e-3)
            largest.append(max(math.dist(offsets[3 * k:3 * k + 3], (0, 0, 0)) for k in range(tube.vertex_count)))
        self.assertLess(largest[1], largest[0])

    def test_close(self):
        tube = Tube()
        binding = tube.binding()
        binding.close()
        binding.close()  # like a file, closing twice is harmless
        out = zeros('f', 3 * tube.vertex_count)
        calls = {
            'correct': lambda: binding.correct(tube.positions, tube.bone_matrices(0.0), out_positions=out),
            'set_map': lambda: binding.set_map('UNIFORM'),
            'segmentation': lambda: binding.segmentation(),
            'correction_map': lambda: binding.correction_map(zeros('f', tube.vertex_count)),
            'region_volume_changes': lambda: binding.region_volume_changes(tube.positions, tube.bone_matrices(0.0)),
            'vertex_count': lambda: binding.vertex_count,
            'region_count': lambda: binding.region_count,
        }
        for name, call in calls.items():
            with self.subTest(call=name):
                with self.assertRaisesRegex(ValueError, 'closed'):
                    call()
        self.assertIn('closed', repr(binding))


# ---- threads -------------------------------------------------------------------------------------------------------


class TestThreads(unittest.TestCase):
    """The GIL is released while the core computes, and a Binding refuses a second caller."""

    @classmethod
    def setUpClass(cls):
        cls.tube = Tube(around=64, rings=400, length=40.0, band=2.6)  # 25602 vertices
        cls.angles = [math.radians(degrees) for degrees in (30, 60, 90)]
        cls.frames = [(cls.tube.skinned(angle), cls.tube.bone_matrices(angle)) for angle in cls.angles]

    def correct_all(self, binding):
        results = []
        for positions, matrices in self.frames:
            out = zeros('f', 3 * self.tube.vertex_count)
            binding.correct(positions, matrices, out_positions=out)
            results.append(out)
        return results

    def test_two_bindings_in_two_threads(self):
        sequential = self.correct_all(self.tube.binding())
        bindings = [self.tube.binding(), self.tube.binding()]
        results, errors = [None, None], []

        def work(slot):
            try:
                for _ in range(3):
                    results[slot] = self.correct_all(bindings[slot])
            except Exception as error:  # reported below: an exception in a thread would pass silently
                errors.append(error)

        workers = [threading.Thread(target=work, args=(slot,)) for slot in range(2)]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
        self.assertEqual(errors, [])
        self.assertEqual(results[0], sequential)
        self.assertEqual(results[1], sequential)

    def test_one_binding_refuses_a_second_thread(self):
        binding = self.tube.binding()
        expected = self.correct_all(binding)
        refused, wrong, errors = [], [], []

        def work():
            for _ in range(20):
                for (positions, matrices), reference in zip(self.frames, expected):
                    out = zeros('f', 3 * self.tube.vertex_count)
                    try:
                        binding.correct(positions, matrices, out_positions=out)
                    except RuntimeError:
                        refused.append(1)
                        continue
                    except Exception as error:
                        errors.append(error)
                        return
                    if out != reference:
                        wrong.append(1)

        workers = [threading.Thread(target=work) for _ in range(2)]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join()
        self.assertEqual(errors, [])
        self.assertEqual(wrong, [], 'a call that was let in gave a wrong result')
        if not refused:
            self.skipTest('the two threads never overlapped, so the refusal could not be observed')


# ---- errors --------------------------------------------------------------------------------------------------------


class TestErrors(unittest.TestCase):
    """Every bad argument raises _lvp.Error, a ValueError whose message starts with the argument's name and
    whose .argument is that name."""

    def assertValueErrorNames(self, name, call, *args, **kwargs):
        with self.assertRaises(_lvp.Error, msg=f'{name}: no _lvp.Error') as caught:
            call(*args, **kwargs)
        message = str(caught.exception)
        self.assertTrue(message.startswith(name), f'the message does not start with {name!r}: {message}')
        self.assertEqual(caught.exception.argument, name, message)
        self.assertIsInstance(caught.exception.code, str, message)
        # Every view taken before the refusal was released: an array still exported cannot be resized.
        for value in list(args) + list(kwargs.values()):
            if isinstance(value, array.array):
                value.append(value[0] if len(value) else 0)
                value.pop()
        return message

    def bad_variants(self, value, writable):
        """(description, replacement) pairs that are each wrong for the buffer argument `value`."""
        other = 'd' if value.typecode == 'f' else 'f'
        variants = [
            ('a list', list(value)),
            ('a str', 'positions'),
            ('None', None),
            ('a wrong item format', array.array(other, [0] * len(value))),
            ('an 8-byte int format', array.array('q', [0] * len(value))),
            ('raw bytes', bytearray(value.tobytes())),
            ('one item short', value[:-1]),
            ('one item long', value + value[:1]),
            ('a non-contiguous view', memoryview(value + value)[::2]),
        ]
        if writable:
            variants.append(('a read-only buffer', memoryview(value.tobytes()).cast(value.typecode)))
        return variants

    def check_every_buffer(self, call, arguments, outputs=(), optional=()):
        """Replaces each buffer argument of `call` in turn by every bad variant of it."""
        for name, value in arguments.items():
            if not isinstance(value, array.array):
                continue
            for description, replacement in self.bad_variants(value, name in outputs):
                if replacement is None and name in optional:
                    continue
                with self.subTest(argument=name, bad=description):
                    self.assertValueErrorNames(name, call, **dict(arguments, **{name: replacement}))

    def test_mesh_functions(self):
        tube = Tube()
        self.check_every_buffer(_lvp.mesh_volume, {'positions': tube.positions, 'triangles': tube.triangles})
        for function in (_lvp.volume_gradient, _lvp.vertex_normals):
            arguments = {'out': zeros('f', 3 * tube.vertex_count), 'positions': tube.positions,
                         'triangles': tube.triangles}
            self.check_every_buffer(function, arguments, outputs=('out',))
            self.assertValueErrorNames('out', function, tube.positions, tube.positions, tube.triangles)

    def test_skinning_functions(self):
        tube = Tube()
        for function in (_lvp.skin_linear, _lvp.skin_dual_quaternion):
            arguments = {'out': zeros('f', 3 * tube.vertex_count), 'rest_positions': tube.positions,
                         'weight_offsets': tube.weight_offsets, 'weight_bones': tube.weight_bones,
                         'weight_values': tube.weight_values, 'skin_matrices': tube.skin_matrices(0.5)}
            self.check_every_buffer(function, arguments, outputs=('out',))
            self.assertValueErrorNames('out', function, **dict(arguments, out=tube.positions))
            values = array.array('f', tube.weight_values)
            values[5] = -0.5
            self.assertValueErrorNames('weight_values', function, **dict(arguments, weight_values=values))
            values[5] = math.nan
            self.assertValueErrorNames('weight_values', function, **dict(arguments, weight_values=values))
            bones = array.array('i', tube.weight_bones)
            bones[3] = 2
            self.assertValueErrorNames('weight_bones', function, **dict(arguments, weight_bones=bones))
            offsets = array.array('i', tube.weight_offsets)
            offsets[4], offsets[5] = offsets[5], offsets[4]
            self.assertValueErrorNames('weight_offsets', function, **dict(arguments, weight_offsets=offsets))
            positions = array.array('f', tube.positions)
            positions[7] = math.inf
            self.assertValueErrorNames('rest_positions', function, **dict(arguments, rest_positions=positions))
            matrices = tube.skin_matrices(0.5)
            matrices[20] = math.nan
            self.assertValueErrorNames('skin_matrices', function, **dict(arguments, skin_matrices=matrices))

    def test_compose_frames(self):
        identity = array.array('f', identity_matrix())
        arguments = {'out': zeros('f', 16 * 4), 'premat': identity, 'bone_matrices': identity * 2,
                     'joint_counts': array.array('i', [0, 3]), 'joint_matrices': identity * 3,
                     'corrections': identity * 4}
        self.check_every_buffer(_lvp.compose_frames, arguments, outputs=('out',), optional=('corrections',))
        self.assertValueErrorNames('joint_counts', _lvp.compose_frames,
                                   **dict(arguments, joint_counts=array.array('i', [0, -3])))
        self.assertValueErrorNames('joint_matrices', _lvp.compose_frames,
                                   **dict(arguments, joint_counts=array.array('i', [1, 3])))
        self.assertValueErrorNames('out', _lvp.compose_frames, **dict(arguments, out=arguments['corrections']))

    def test_errors_carry_their_code(self):
        """A bad argument says what went wrong for code too, not only for people: .code (the core's result
        without its prefix, or this module's for a buffer it cannot take) and .argument (the Python name at
        fault, or None)."""
        self.assertTrue(issubclass(_lvp.Error, ValueError))
        tube = Tube()
        values = array.array('f', tube.weight_values)
        values[5] = -0.5
        with self.assertRaises(_lvp.Error) as caught:
            _lvp.skin_linear(zeros('f', 3 * tube.vertex_count), tube.positions, tube.weight_offsets,
                             tube.weight_bones, values, tube.skin_matrices(0.5))
        self.assertEqual((caught.exception.code, caught.exception.argument), ('negative_weight', 'weight_values'))
        opened = array.array('i', tube.triangles[3:])  # one triangle less: a hole
        with self.assertRaises(_lvp.Error) as caught:
            _lvp.Binding(tube.positions, opened, None, None, None, None, None, None, mode='GLOBAL', map='UNIFORM')
        self.assertEqual(caught.exception.code, 'mesh_not_closed', str(caught.exception))
        refused_here = [
            ('invalid_size', 'positions', lambda: _lvp.mesh_volume(array.array('f', [0.0] * 4), tube.triangles)),
            ('invalid_buffer', 'triangles', lambda: _lvp.mesh_volume(tube.positions, array.array('f', [0.0] * 3))),
            ('null_argument', 'triangles', lambda: _lvp.mesh_volume(tube.positions, None)),
            ('invalid_option', 'visibility', lambda: _lvp.auto_weights(
                tube.positions, tube.triangles, tube.rest_matrices, tube.heads, tube.tails, visibility='SOME')),
        ]
        for code, argument, call in refused_here:
            with self.subTest(code=code), self.assertRaises(_lvp.Error) as caught:
                call()
            self.assertEqual((caught.exception.code, caught.exception.argument), (code, argument),
                             str(caught.exception))

    def test_auto_weights(self):
        tube = Tube()
        arguments = {'positions': tube.positions, 'triangles': tube.triangles, 'rest_matrices': tube.rest_matrices,
                     'heads': tube.heads, 'tails': tube.tails}
        self.check_every_buffer(_lvp.auto_weights, arguments)
        self.assertValueErrorNames('visibility', _lvp.auto_weights, **arguments, visibility='SOMETIMES')
        self.assertValueErrorNames('alpha', _lvp.auto_weights, **arguments, alpha=-1.0)
        self.assertValueErrorNames('alpha', _lvp.auto_weights, **arguments, alpha='two')
        self.assertValueErrorNames('normal_cos_max', _lvp.auto_weights, **arguments, normal_cos_max=2.0)
        self.assertValueErrorNames('max_influences', _lvp.auto_weights, **arguments, max_influences=-1)
        self.assertValueErrorNames('max_influences', _lvp.auto_weights, **arguments, max_influences=2 ** 40)
        self.assertValueErrorNames('max_influences', _lvp.auto_weights, **arguments, max_influences=1.5)
        self.assertValueErrorNames('smoothing_iterations', _lvp.auto_weights, **arguments, smoothing_iterations=-1)
        self.assertValueErrorNames('smoothing_iterations', _lvp.auto_weights, **arguments,
                                   smoothing_iterations=1001)
        self.assertValueErrorNames('smoothing_length', _lvp.auto_weights, **arguments, smoothing_length=-0.5)
        self.assertValueErrorNames('smoothing_thickness', _lvp.auto_weights, **arguments, smoothing_thickness=-1.0)
        self.assertValueErrorNames('smoothing_thickness', _lvp.auto_weights, **arguments, smoothing_thickness=17.0)
        self.assertValueErrorNames('threads', _lvp.auto_weights, **arguments, heat=True, threads=0)

    def binding_arguments(self, tube):
        return {'rest_positions': tube.positions, 'triangles': tube.triangles, 'weight_offsets': tube.weight_offsets,
                'weight_bones': tube.weight_bones, 'weight_values': tube.weight_values,
                'rest_matrices': tube.rest_matrices, 'heads': tube.heads, 'tails': tube.tails,
                'painted': array.array('f', [1.0] * tube.vertex_count),
                'region_bone_offsets': array.array('i', [0, 1, 2]), 'region_bones': array.array('i', [0, 1]),
                'bone_groups': array.array('i', [0, 1]), 'parents': array.array('i', [-1, 0])}

    def test_binding_buffers(self):
        tube = Tube()
        optional = ('weight_offsets', 'weight_bones', 'weight_values', 'rest_matrices', 'heads', 'tails', 'painted',
                    'region_bone_offsets', 'region_bones', 'bone_groups', 'parents')
        self.check_every_buffer(_lvp.Binding, self.binding_arguments(tube), optional=optional)
        # None for one array of a group that must come together.
        for name in optional:
            if name not in ('painted', 'bone_groups', 'parents'):
                with self.subTest(argument=name, bad='None alone'):
                    self.assertValueErrorNames(name, _lvp.Binding, **dict(self.binding_arguments(tube), **{name: None}))

    def test_binding_values(self):
        tube = Tube()
        arguments = self.binding_arguments(tube)
        triangles = array.array('i', tube.triangles)
        triangles[12] = tube.vertex_count
        message = self.assertValueErrorNames('triangles', _lvp.Binding, **dict(arguments, triangles=triangles))
        self.assertIn(str(tube.vertex_count), message)
        triangles[12] = -1
        self.assertValueErrorNames('triangles', _lvp.Binding, **dict(arguments, triangles=triangles))
        positions = array.array('f', tube.positions)
        positions[10] = math.nan
        self.assertValueErrorNames('rest_positions', _lvp.Binding, **dict(arguments, rest_positions=positions))
        values = array.array('f', tube.weight_values)
        values[0] = -1.0
        self.assertValueErrorNames('weight_values', _lvp.Binding, **dict(arguments, weight_values=values))
        bones = array.array('i', tube.weight_bones)
        bones[0] = 7
        self.assertValueErrorNames('weight_bones', _lvp.Binding, **dict(arguments, weight_bones=bones))
        singular = array.array('f', tube.rest_matrices)
        singular[16:32] = array.array('f', [0.0] * 16)
        self.assertValueErrorNames('rest_matrices', _lvp.Binding, **dict(arguments, rest_matrices=singular))
        heads = array.array('f', tube.heads)
        heads[4] = math.inf
        self.assertValueErrorNames('heads', _lvp.Binding, **dict(arguments, heads=heads))
        self.assertValueErrorNames('mode', _lvp.Binding, **arguments, mode='local')
        self.assertValueErrorNames('map', _lvp.Binding, **arguments, map=3)
        self.assertValueErrorNames('threads', _lvp.Binding, **arguments, threads=0)
        self.assertValueErrorNames('threads', _lvp.Binding, **arguments, threads=1000)
        self.assertValueErrorNames('threads', _lvp.Binding, **arguments, threads='two')
        self.assertValueErrorNames('alpha', _lvp.Binding, **arguments, alpha=-1.0)
        self.assertValueErrorNames('beta', _lvp.Binding, **arguments, beta=-1.0)
        self.assertValueErrorNames('beta', _lvp.Binding, **arguments, beta=1e300)
        painted = array.array('f', [1.0] * tube.vertex_count)
        painted[3] = -1.0
        self.assertValueErrorNames('painted', _lvp.Binding, **dict(arguments, painted=painted), map='PAINTED')
        self.assertValueErrorNames('painted', _lvp.Binding, **dict(arguments, painted=None), map='PAINTED')
        region_bones = array.array('i', [0, 5])
        self.assertValueErrorNames('region_bones', _lvp.Binding, **dict(arguments, region_bones=region_bones))
        # A group is named by a bone index, one per bone.
        self.assertValueErrorNames('bone_groups', _lvp.Binding, **dict(arguments, bone_groups=array.array('i', [0, 2])))
        self.assertValueErrorNames('bone_groups', _lvp.Binding, **dict(arguments, bone_groups=array.array('i', [0])))
        # A parent is another bone, or -1.
        for parents in ([-1, 2], [-2, 0], [0, 1]):
            message = self.assertValueErrorNames('parents', _lvp.Binding,
                                                 **dict(arguments, parents=array.array('i', parents)))
            self.assertIn("-1 for none", message)
        self.assertValueErrorNames('parents', _lvp.Binding, **dict(arguments, parents=array.array('i', [-1])))
        for bad in (-1.0, 9.0, math.nan, 'wide'):
            self.assertValueErrorNames('bulge_width', _lvp.Binding, **arguments, bulge_width=bad)
        # A character needs its weights and bones; only a prop in GLOBAL mode goes without.
        no_weights = dict(arguments, weight_offsets=None, weight_bones=None, weight_values=None)
        self.assertValueErrorNames('weight_offsets', _lvp.Binding, **no_weights)
        no_skeleton = dict(arguments, rest_matrices=None, heads=None, tails=None, region_bone_offsets=None,
                           region_bones=None)
        self.assertValueErrorNames('rest_matrices', _lvp.Binding, **no_skeleton)
        empty_weights = dict(arguments, weight_offsets=array.array('i', [0] * (tube.vertex_count + 1)),
                             weight_bones=array.array('i'), weight_values=array.array('f'))
        self.assertValueErrorNames('weight_offsets', _lvp.Binding, **empty_weights)  # no vertex has a weight

    def test_binding_methods(self):
        tube = Tube()
        binding = tube.binding()
        angle = math.radians(40)
        positions, matrices = tube.skinned(angle), tube.bone_matrices(angle)
        arguments = {'positions': positions, 'bone_matrices': matrices,
                     'out_positions': zeros('f', 3 * tube.vertex_count),
                     'out_offsets': zeros('f', 3 * tube.vertex_count), 'rest_positions': tube.positions,
                     'rigid_space': array.array('f', [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])}
        optional = ('bone_matrices', 'out_positions', 'out_offsets', 'rest_positions', 'rigid_space')
        self.check_every_buffer(binding.correct, arguments, outputs=('out_positions', 'out_offsets'),
                                optional=optional)
        self.assertValueErrorNames('out_positions', binding.correct, positions, matrices)
        self.assertValueErrorNames('out_offsets', binding.correct, positions, matrices, out_offsets=positions)
        self.assertValueErrorNames('out_offsets', binding.correct, positions, matrices,
                                   out_positions=arguments['out_positions'], out_offsets=arguments['out_positions'])
        self.assertValueErrorNames('out_positions', binding.correct, positions, matrices, out_positions=matrices)
        storage = memoryview(positions + positions)  # out_positions overlapping positions by all but one vertex
        self.assertValueErrorNames('out_positions', binding.correct, storage[:len(positions)], matrices,
                                   out_positions=storage[3:3 + len(positions)])
        nan_positions = array.array('f', positions)
        nan_positions[5] = math.nan
        self.assertValueErrorNames('positions', binding.correct, nan_positions, matrices,
                                   out_positions=arguments['out_positions'])
        nan_matrices = array.array('f', matrices)
        nan_matrices[17] = math.nan
        self.assertValueErrorNames('bone_matrices', binding.correct, positions, nan_matrices,
                                   out_positions=arguments['out_positions'])
        self.assertValueErrorNames('bone_matrices', binding.correct, positions, None,
                                   out_positions=arguments['out_positions'])
        singular_space = array.array('f', [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1])
        for name, value in (('iterations', 0), ('iterations', 'many'), ('tolerance', 0.0), ('tolerance', -1.0),
                            ('tolerance', None), ('rigid_space', singular_space), ('rigid_space', singular_space[:9]),
                            ('rigid_space', array.array('d', singular_space)), ('displacement_limit', -1.0),
                            ('displacement_limit', math.nan), ('displacement_limit', 'far')):
            with self.subTest(argument=name, value=value):
                self.assertValueErrorNames(name, binding.correct, positions, matrices,
                                           out_positions=arguments['out_positions'], **{name: value})

        frame = {'positions': positions, 'bone_matrices': matrices, 'rest_positions': tube.positions}
        self.check_every_buffer(binding.region_volume_changes, frame, optional=('bone_matrices', 'rest_positions'))
        self.check_every_buffer(binding.correction_map, {'out': zeros('f', tube.vertex_count)}, outputs=('out',))
        segmentation = {'out_vertex_regions': zeros('i', tube.vertex_count),
                        'out_triangle_regions': zeros('i', tube.triangle_count)}
        self.check_every_buffer(binding.segmentation, segmentation, outputs=tuple(segmentation),
                                optional=tuple(segmentation))
        map_arguments = {'painted': array.array('f', [1.0] * tube.vertex_count),
                         'region_bone_offsets': array.array('i', [0, 1, 2]), 'region_bones': array.array('i', [0, 1])}
        self.check_every_buffer(binding.set_map, map_arguments, optional=tuple(map_arguments))
        self.assertValueErrorNames('map', binding.set_map, 'FANCY')
        self.assertValueErrorNames('alpha', binding.set_map, alpha=-2.0)
        self.assertValueErrorNames('painted', binding.set_map, 'PAINTED')
        # An empty buffer is a buffer of the wrong size, not None.
        self.assertValueErrorNames('out', binding.correction_map, array.array('f'))
        self.assertValueErrorNames('out_vertex_regions', binding.segmentation, array.array('i'))
        self.assertValueErrorNames('out_triangle_regions', binding.segmentation, None, array.array('i'))
        self.assertValueErrorNames('out_offsets', binding.correct, positions, matrices, out_offsets=array.array('f'))
        self.assertValueErrorNames('painted', binding.set_map, 'PAINTED', painted=array.array('f'))
        self.assertValueErrorNames('region_bone_offsets', binding.set_map, region_bone_offsets=array.array('i'),
                                   region_bones=array.array('i'))
        # The binding still works after all these refusals.
        stats = binding.correct(positions, matrices, out_positions=arguments['out_positions'])
        self.assertEqual(set(stats), STATS_KEYS)


# ---- numpy ---------------------------------------------------------------------------------------------------------


class TestNoNumpy(unittest.TestCase):

    def test_module_never_imports_numpy(self):
        # A fresh interpreter records every attempt to import numpy, whether or not numpy is installed.
        script = '\n'.join([
            'import sys',
            'attempts = []',
            'class Recorder:',
            '    def find_spec(self, name, path=None, target=None):',
            '        if name.split(".")[0] == "numpy":',
            '            attempts.append(name)',
            '        return None',
            'sys.meta_path.insert(0, Recorder())',
            'import array, _lvp',
            'positions = array.array("f", [0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1])',
            'triangles = array.array("i", [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3])',
            'volume = _lvp.mesh_volume(positions, triangles)',
            'print(attempts, "numpy" in sys.modules, round(volume * 6, 6))',
        ])
        result = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, check=True)
        self.assertEqual(result.stdout.strip(), '[] False 1.0')


if __name__ == '__main__':
    unittest.main()
