#!/usr/bin/env bash
# tests/blender/bench_bake.sh - bake speed (issue 4): frames per second baking the giraffe and a
# ~100k-vertex mesh to PC2 with 1 and 2 jobs, on each Blender of bench_common.sh (3.4, 4.3, 5.2,
# $BLENDER). Called by tests/blender/bench.sh
# (./build.sh bench); tests what is in dist/.
#
#   tests/blender/bench_bake.sh [--frames N] [--vertices N]
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=bench_common.sh
source "$HERE/bench_common.sh"

bench_in_each_blender bake-bench bench_bake.py '/^Blender [0-9].*baking to PC2/' '/^| Dense.*| 2 |/' "$@"
