# SPDX-License-Identifier: GPL-3.0-or-later
"""Replays a hand dumped by dump_hand.py through the core's Python module, with and without Keep Skin Apart:
ms a correction (median over the rounds, the frames taken in turn on one binding, as an animation plays) and a
hash of the corrected positions of each frame, on 1 and 2 threads. The hashes show a change to the core leaves
its results as they were, bit for bit.

    python3 tests/bench/bench_keep_apart.py HAND.pickle [--module DIR] [--rounds N] [--threads 1,2]

DIR holds _lvp.abi3.so (default: build/, from `bash -c 'source ./build.sh; build_module'`).
"""
import argparse
import hashlib
import os
import pickle
import statistics
import sys
import time
from array import array

HERE = os.path.dirname(os.path.abspath(__file__))


def replay(lvp, dump, threads, keep_apart, rounds):
    binding = lvp.Binding(*dump["bind_args"], threads=threads, **dump["bind_kwargs"])
    frames = sorted(frame for frame in dump["frames"] if frame != 1)
    times = {frame: [] for frame in frames}
    hashes, stats_of = {}, {}
    for round_index in range(rounds + 1):  # the first round builds what the first frame needs, untimed
        for frame in frames:
            data = dump["frames"][frame]
            out = array('f', bytes(len(data["positions"]) * 4))
            start = time.perf_counter()
            stats = binding.correct(data["positions"], data["bone_matrices"], out_positions=out,
                                    rest_positions=data["rest_positions"], keep_apart=keep_apart,
                                    **data["options"])
            elapsed = time.perf_counter() - start
            if round_index > 0:
                times[frame].append(elapsed)
            digest = hashlib.sha256(out.tobytes()).hexdigest()[:16]
            if frame in hashes and hashes[frame] != digest:
                raise SystemExit("frame %d gave different positions on a later round" % frame)
            hashes[frame] = digest
            stats_of[frame] = stats
    return {frame: 1000.0 * statistics.median(times[frame]) for frame in frames}, hashes, stats_of


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("dump")
    parser.add_argument("--module", default=os.path.join(os.path.dirname(os.path.dirname(HERE)), "build"))
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--threads", default="1,2")
    arguments = parser.parse_args()
    sys.path.insert(0, arguments.module)
    import _lvp
    with open(arguments.dump, "rb") as source:
        dump = pickle.load(source)
    print("| threads | Keep Skin Apart | frame | ms | shortened | crossing | positions |")
    print("|---|---|---|---:|---:|---:|---|")
    for threads in [int(t) for t in arguments.threads.split(",")]:
        for keep_apart in (False, True):
            ms, hashes, stats = replay(_lvp, dump, threads, keep_apart, arguments.rounds)
            for frame in sorted(ms):
                print("| %d | %s | %d | %.2f | %d | %d | %s |" % (
                    threads, "on" if keep_apart else "off", frame, ms[frame], stats[frame]["shortened_vertices"],
                    stats[frame]["crossing_triangles"], hashes[frame]))
            sys.stdout.flush()


main()
