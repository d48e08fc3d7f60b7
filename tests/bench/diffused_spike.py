# SPDX-License-Identifier: GPL-3.0-or-later
"""Why Bulge Width diffuses every vertex's weights over at least 3 steps (reach.c, LVP__REACH_LEAST_STEPS): on a
regular triangle mesh (six neighbours a vertex), a weight that one vertex alone carried, and one that one row of
vertices carried (a ring round a limb), after each step of the bind's diffusion at rate 1 (the mean of a vertex's
row and its neighbours' rows, diffusion.c), measured as QUALITY.md measures roughness: the largest distance of a
value from its neighbours' mean, over the largest value. Three steps are the fewest that read under a quarter.

    python3 tests/bench/diffused_spike.py [STEPS]
"""
import sys

SIZE = 41
# A triangular lattice in axial coordinates: each vertex's six neighbours.
AROUND = ((1, 0), (0, 1), (-1, 1), (-1, 0), (0, -1), (1, -1))


def around(values, i, j):
    """The sum of vertex (i, j)'s six neighbours' values (the lattice wraps)."""
    return sum(values[(i + di) % SIZE][(j + dj) % SIZE] for di, dj in AROUND)


def step(values):
    """One step at rate 1: each vertex takes the mean of itself and its six neighbours."""
    return [[(values[i][j] + around(values, i, j)) / 7.0 for j in range(SIZE)] for i in range(SIZE)]


def roughness(values):
    """The largest |value - mean of its six neighbours'| over the largest value."""
    worst = max(abs(values[i][j] - around(values, i, j) / 6.0) for i in range(SIZE) for j in range(SIZE))
    return worst / max(max(row) for row in values)


def main():
    steps = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    spike = [[1.0 if (i, j) == (SIZE // 2, SIZE // 2) else 0.0 for j in range(SIZE)] for i in range(SIZE)]
    ring = [[1.0 if i == SIZE // 2 else 0.0 for j in range(SIZE)] for i in range(SIZE)]
    print("| steps | one vertex's weight | one row of vertices |")
    print("|---:|---:|---:|")
    for count in range(steps + 1):
        print("| %d | %.2f | %.2f |" % (count, roughness(spike), roughness(ring)))
        spike, ring = step(spike), step(ring)


if __name__ == "__main__":
    main()
