# SPDX-License-Identifier: GPL-3.0-or-later
"""Whether fields of each limb's rest skin could stand in for Keep Skin Apart's clearance search (BENCHMARKS.md,
"each limb's rest skin carried rigidly as the clearance's field"). For a hand dumped by dump_hand.py, at each frame
given: every moving vertex's clearance (the least |x|^2 / <x, d> over the skin in front of it, its own triangles
left out; clearance.c) against the skinned skin, and against each limb's rest skin carried by that bone's skin
matrix (what a field fitted to the limb at bind would give), the skin sampled at 10 points a triangle. The offsets
are those the first clearance search sees: the correction without Keep Skin Apart. Prints how many vertices each
finds under 4 times their offset (where the fade takes a share), and how far the shares kept differ.

    python3 tests/bench/field_clearance.py HAND.pickle [--frames 12,16,21] [--other-limbs] [--module DIR]

--other-limbs: only skin of limbs other than the vertex's own (its largest weight's), for both measures. Needs numpy
and scipy (Debian's python3-numpy, python3-scipy).
"""
import argparse
import os
import pickle
import sys
from array import array

import numpy as np
from scipy.spatial import cKDTree

HERE = os.path.dirname(os.path.abspath(__file__))
# Where each triangle is sampled: its corners, edge midpoints, centroid and three points between.
BARYCENTRIC = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [.5, .5, 0], [0, .5, .5], [.5, 0, .5], [1 / 3, 1 / 3, 1 / 3],
                        [2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
WANTED = 4.0  # clearance.c, LVP__CLEARANCE_WANTED
REACH = 5.0  # clearance.c, LVP__CLEARANCE_REACH


def least_diameter(p, d, points, triangles, own):
    """min |x - p|^2 / <x - p, d> over the points in front of p whose triangle is not one of p's own."""
    x = points - p
    ahead = x @ d
    keep = (ahead > 0.0) & ~np.isin(triangles, own)
    return float(np.min((x[keep] ** 2).sum(1) / ahead[keep])) if keep.any() else np.inf


def share_kept(m, c):
    """clearance.c, lvp__share_kept."""
    h = 0.5 * c
    with np.errstate(invalid="ignore"):
        return np.where(m <= 0.5 * h, 1.0, (h - h * h / (4.0 * m)) / m)


class Hand:
    def __init__(self, dump, lvp):
        self.dump, self.args = dump, dump["bind_args"]
        self.rest = np.array(self.args[0], dtype=np.float64).reshape(-1, 3)
        self.triangles = np.array(self.args[1], dtype=np.int64).reshape(-1, 3)
        offsets, bones, values = (np.array(a) for a in self.args[2:5])
        self.bone_count = len(self.args[5]) // 16
        weights = np.zeros((len(self.rest), self.bone_count))
        for k in range(len(self.rest)):
            np.add.at(weights[k], bones[offsets[k]:offsets[k + 1]], values[offsets[k]:offsets[k + 1]])
        weights /= weights.sum(1, keepdims=True)  # normalized by their sum, as the core reads them
        self.limb_of_vertex = np.argmax(weights, axis=1)
        self.limb_of_triangle = np.argmax(weights[self.triangles].sum(1), axis=1)
        self.sample_triangle = np.repeat(np.arange(len(self.triangles)), len(BARYCENTRIC))
        self.incident = [[] for _ in self.rest]
        for t, triangle in enumerate(self.triangles):
            for v in triangle:
                self.incident[v].append(t)
        self.binding = lvp.Binding(*self.args, threads=1, **dump["bind_kwargs"])
        self.rest_matrices = np.array(self.args[5], dtype=np.float64).reshape(-1, 4, 4)

    def samples(self, positions):
        return np.einsum("sc,tcx->tsx", BARYCENTRIC, positions[self.triangles]).reshape(-1, 3)

    def frame(self, number):
        """The skinned positions, the offsets the first clearance search sees, and each bone's skin matrix."""
        data = self.dump["frames"][number]
        out = array('f', bytes(len(data["positions"]) * 4))
        self.binding.correct(data["positions"], data["bone_matrices"], out_positions=out,
                             rest_positions=data["rest_positions"], keep_apart=False, **data["options"])
        skinned = np.array(data["positions"], dtype=np.float64).reshape(-1, 3)
        posed = np.array(data["bone_matrices"], dtype=np.float64).reshape(-1, 4, 4)
        skin = posed @ np.linalg.inv(self.rest_matrices)
        return skinned, np.array(out, dtype=np.float64).reshape(-1, 3) - skinned, skin


def measure(hand, number, other_limbs_only):
    skinned, offsets, skin = hand.frame(number)
    lengths = np.linalg.norm(offsets, axis=1)
    samples = hand.samples(skinned)
    sample_limb = hand.limb_of_triangle[hand.sample_triangle]
    tree = cKDTree(samples)
    rest_samples = hand.samples(hand.rest)
    limbs = {}
    for limb in range(hand.bone_count):
        chosen = np.nonzero(sample_limb == limb)[0]
        if len(chosen):
            limbs[limb] = (rest_samples[chosen], hand.sample_triangle[chosen], cKDTree(rest_samples[chosen]))
    inverse = np.linalg.inv(skin)
    rows = []
    for k in np.nonzero(lengths > 1e-9 * np.abs(skinned).max())[0]:
        d, reach, own = offsets[k] / lengths[k], REACH * lengths[k], hand.incident[k]
        near = np.array(tree.query_ball_point(skinned[k], reach), dtype=np.int64)
        if other_limbs_only:
            near = near[sample_limb[near] != hand.limb_of_vertex[k]]
        exact = least_diameter(skinned[k], d, samples[near], hand.sample_triangle[near], own) if len(near) else np.inf
        field = np.inf
        for limb, (points, triangles, limb_tree) in limbs.items():
            if other_limbs_only and limb == hand.limb_of_vertex[k]:
                continue
            p = (inverse[limb] @ np.append(skinned[k], 1.0))[:3]
            near = limb_tree.query_ball_point(p, reach)
            if near:
                direction = inverse[limb][:3, :3] @ d
                field = min(field, least_diameter(p, direction / np.linalg.norm(direction), points[near],
                                                  triangles[near], own))
        rows.append((lengths[k], exact, field))
    m, exact, field = np.array(rows).T
    wanted, field_wanted = exact < WANTED * m, field < WANTED * m
    difference = np.abs(share_kept(m, exact) - share_kept(m, field))
    print("frame %d: %d moving vertices; clearance under %g times the offset: exact %d, rigid limbs %d, both %d, "
          "missed %d, extra %d; shares kept differing by more than 0.1 at %d, 0.3 at %d"
          % (number, len(rows), WANTED, wanted.sum(), field_wanted.sum(), (wanted & field_wanted).sum(),
             (wanted & ~field_wanted).sum(), (field_wanted & ~wanted).sum(), (difference > 0.1).sum(),
             (difference > 0.3).sum()))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("dump")
    parser.add_argument("--frames", default="12,16,21")
    parser.add_argument("--other-limbs", action="store_true")
    parser.add_argument("--module", default=os.path.join(HERE, "..", "..", "build"))
    arguments = parser.parse_args()
    sys.path.insert(0, os.path.abspath(arguments.module))
    import _lvp
    with open(arguments.dump, "rb") as dump_file:
        hand = Hand(pickle.load(dump_file), _lvp)
    for number in (int(frame) for frame in arguments.frames.split(",")):
        measure(hand, number, arguments.other_limbs)


if __name__ == "__main__":
    main()
