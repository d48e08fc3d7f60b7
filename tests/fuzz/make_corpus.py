#!/usr/bin/env python3
"""Writes the fuzzer's seed corpus (tests/fuzz/corpus/): a dozen small inputs, valid and invalid,
spelled out in the byte format that tests/fuzz/fuzz_decode.h decodes (read that header first;
this script follows its reading order call by call). Run it with the system python3 after a
change to the format: python3 tests/fuzz/make_corpus.py
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))

NAN, INF, NEG_INF, HUGE = 0xE0, 0xE1, 0xE2, 0xE3


def f(value):
    """The one-byte float code of a multiple of 1/32 in [-3.5, 3.47]."""
    code = round(value * 32) + 112
    assert 0 <= code < 0xE0, value
    return code


def angle_byte(degrees):
    """fuzz_decode_generated reads a bend as (byte - 128) * pi / 128."""
    return (round(degrees / 180 * 128) + 128) & 0xFF


def option_default():
    return [0]


def option_small(quarters):
    return [1, quarters]


def option_float(code):
    return [2, code]


def frame(iterations_byte=0, tolerance=None, fold=0):
    """fuzz_decode_frame: iterations (byte % 4 == 0: default), tolerance option, fold-over."""
    return [iterations_byte] + (tolerance or option_default()) + [fold]


def map_options(kind=0, alpha=None, beta=None, flags=0, extra=()):
    """fuzz_decode_map: kind, alpha, beta, flags, then painted values / region lists."""
    return [kind] + (alpha or option_default()) + (beta or option_default()) + [flags] + list(extra)


def bind_and_run(flags=0, threads=0, first_map=None, frames=None, hows=(0, 4, 16, 20), second_map=None,
                 set_map_null=1):
    """fuzz_bind_and_run: flags, threads, map, two frames, two corrections, a new map, a NULL-map
    byte (% 16 == 0 passes NULL), two more corrections."""
    frames = frames or (frame(), frame())
    return ([flags, threads] + (first_map or map_options()) + frames[0] + frames[1] + [hows[0], hows[1]] +
            (second_map or map_options()) + [set_map_null, hows[2], hows[3]])


def common_tail(counts=(0, 0, 0), skin_nulls=(0, 0), auto=None, bind=None):
    """After the geometry: how counts are passed, the two skinnings, automatic weights, binding."""
    auto = auto or [0] + option_default() + [0] + option_default() + [5] + option_default()
    return list(counts) + list(skin_nulls) + auto + (bind or bind_and_run())


def generated(around, rings, bones, bends, edits=()):
    body = [0, around - 3, rings - 2, bones - 1] + [angle_byte(b) for b in bends]
    body.append(len(edits))
    for edit in edits:
        body += list(edit)
    return body


def raw(positions, triangles, influences, bones):
    """bones: (head, tail, rest mode bytes, posed mode bytes) per bone."""
    body = [1, len(positions), len(triangles), len(bones)]
    for p in positions:
        body += [f(x) for x in p]
    for t in triangles:
        body += list(t)
    for row in influences:
        body.append(len(row))
        for bone, weight in row:
            body += [bone, f(weight)]
    if len(positions) > 1:
        body.append(1)  # CSR left intact
    body.append(1)  # offsets[0] left at 0
    for head, tail, rest, posed in bones:
        body += [f(x) for x in head] + [f(x) for x in tail] + list(rest) + list(posed)
    return body


TETRAHEDRON = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRAHEDRON_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def seeds():
    s = {}
    # The paper's case in small: a two-bone tube bent by 90 degrees, organic map, default frames.
    s["tube_two_bones_bent_90"] = generated(8, 6, 2, [0, 90]) + common_tail()
    # Three bones, fold-over prevention on both frames, rubber map, offsets and shape-keyed rest.
    s["tube_three_bones_fold_over"] = generated(8, 6, 3, [0, 60, 60]) + common_tail(
        bind=bind_and_run(first_map=map_options(kind=1), frames=(frame(fold=1), frame(9, option_small(1), 1)),
                          hows=(4, 20, 21, 5)))
    # Global mode (one region) on the closed tube, uniform map, then a painted map.
    s["tube_global_uniform"] = generated(6, 4, 1, [0]) + common_tail(
        bind=bind_and_run(flags=1, first_map=map_options(kind=4),
                          second_map=map_options(kind=3, flags=1, extra=[2] * (6 * 4 + 2))))
    # A NaN in the rest positions: every call must refuse it cleanly.
    s["tube_nan_position"] = generated(4, 3, 2, [0, 45], edits=[(0, 7, NAN)]) + common_tail()
    # A triangle index out of range (INT32_MAX) and one negative.
    s["tube_index_out_of_range"] = generated(4, 3, 2, [0, 45], edits=[(1, 5, 0xFF), (1, 9, 0xF7)]) + common_tail()
    # A negative skinning weight.
    s["tube_negative_weight"] = generated(5, 4, 2, [0, 30], edits=[(2, 3, f(-0.5))]) + common_tail()
    # A zero-length bone: its tail moved onto its head.
    s["tube_zero_length_bone"] = generated(6, 5, 2, [0, 40], edits=[(5, 5, f(1))]) + common_tail()
    # A singular rest frame (its Y column zeroed) and an infinite posed entry.
    s["tube_singular_matrices"] = generated(6, 4, 2, [0, 70],
                                            edits=[(6, 9, f(0)), (7, 16 + 3, INF)]) + common_tail()
    # Boundary-fade map with a per-region bone restriction (Fig. 11), two threads, auto weights bound.
    s["tube_region_restriction_threads"] = generated(8, 6, 3, [10, 50, -50]) + common_tail(
        auto=[16] + option_default() + [1] + option_default() + [5] + option_default(),
        bind=bind_and_run(threads=200, first_map=map_options(kind=2, alpha=option_small(8), flags=4,
                                                             extra=[1, 2, 1, 0, 1, 2, 0])))
    # Zero-area triangles (a corner repeated) and a collapsed vertex on the tube.
    s["tube_zero_area"] = generated(6, 4, 2, [0, 80], edits=[(9, 3), (9, 10), (8, 2, f(0))]) + common_tail()
    # A raw tetrahedron on one bone: valid, closed, tiny.
    s["raw_tetrahedron"] = raw(TETRAHEDRON, TETRAHEDRON_FACES, [[(0, 1.0)]] * 4,
                               [((0, 0, 0), (0, 0, 1), [0], [1, 0, f(0.5)])]) + [0] + common_tail(
        bind=bind_and_run(flags=1, first_map=map_options(kind=4)))
    # Raw garbage: indices outside, a negative and duplicate zero weights, no bones, NaN deformed
    # positions, and a negative vertex count (-1 - 3).
    s["raw_invalid_everything"] = raw([(0, 0, 0), (1, 1, 1), (2, 0, 1)], [(0, 1, 0xFF), (0xF0, 1, 2)],
                                      [[(3, -1.0)], [], [(0, 0.0), (0, 0.0)]], []) + [NAN] * 9 + common_tail(
        counts=(15, 3, 14, 0))
    # Empty mesh: all counts zero.
    s["raw_empty"] = [1, 0, 0, 0, 1, 0] + common_tail()
    # Counts passed wrong: one vertex fewer than the triangles use, and a negative bone count
    # (case 15 of fuzz_count reads one more byte).
    s["tube_counts_wrong"] = generated(5, 3, 2, [0, 20]) + common_tail(counts=(13, 0, 15, 0))
    # Inward winding (negative volume) on a bent tube: automatic weights must notice.
    s["tube_inward_winding"] = generated(8, 5, 2, [0, 60], edits=[(12, 0)]) + common_tail()
    # A ring collapsed to a point and the model scaled down to 1/32: tiny, degenerate geometry.
    s["tube_collapsed_ring_tiny"] = generated(8, 6, 3, [0, 30, 30], edits=[(10, 2), (11, 0, f(1 / 32))]) + \
        common_tail()
    # The calls that take a binding, given NULL (bind flags 0xC0), before a normal run.
    s["tube_null_binding_calls"] = generated(5, 3, 2, [0, 45]) + common_tail(bind=bind_and_run(flags=0xC0))
    return s


def main():
    corpus = os.path.join(HERE, "corpus")
    os.makedirs(corpus, exist_ok=True)
    for name, data in seeds().items():
        with open(os.path.join(corpus, name), "wb") as out:
            out.write(bytes(b & 0xFF for b in data))
    print(f"wrote {len(seeds())} seeds to {corpus}")


if __name__ == "__main__":
    main()
