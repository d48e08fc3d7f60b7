#!/usr/bin/env bash
# tests/blender/bench.sh - Blender frame times on a ~100k-vertex mesh, on a Rigify human and on characters of a
# game's size (called by ./build.sh bench): Armature alone, Armature + Corrective Smooth (default settings),
# Armature + Volume Preservation (with and without Keep Skin Apart), side by side in one run, on each Blender:
# 3.4 (Debian's), 4.3 and 5.2 (the chroots of blender_chroot.sh) unless LVP_SKIP_BLENDER43=1 /
# LVP_SKIP_BLENDER52=1, and $BLENDER when set. One table per Blender and a summary.
#
#   tests/blender/bench.sh [--vertices N] [--frames N]
#
# Tests what is in dist/ (./build.sh builds it first). Blender's user directories point into a
# fresh directory under /tmp, so the user's own Blender set-up is never touched.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=bench_common.sh
source "$HERE/bench_common.sh"

status=0
bench_in_each_blender blender-bench bench.py '/^Blender [0-9].*vertices/' '/^re-evaluation /' "$@" || status=1
# a generated Rigify human, about 25k and about 100k vertices
bench_in_each_blender blender-bench-rigify bench_rigify.py '/^Blender [0-9].*Rigify/' '/^status: /' || status=1
bench_in_each_blender blender-bench-rigify bench_rigify.py '/^Blender [0-9].*Rigify/' '/^status: /' \
	--voxel 0.0052 --updates 12 || status=1
# Keep Skin Apart in the viewport on characters of a game's size (what Add's choice rests on); its real animated
# files are shown inside the chroots at the same path, as run.sh does
ensure_packages assimp-testmodels
export LVP_CHROOT_BINDS="${LVP_CHROOT_BINDS:+$LVP_CHROOT_BINDS:}/usr/share/assimp"
bench_in_each_blender blender-bench-characters bench_characters.py '/^Blender [0-9].*characters/' \
	'/^end of characters/' || status=1
"$HERE/bench_bake.sh" || status=1  # bake speed to PC2 with 1 and 2 jobs (issue 4)
exit $status
