#!/usr/bin/env bash
# tests/blender/bench.sh - Blender frame times on a ~100k-vertex mesh (called by ./build.sh bench):
# Armature alone, Armature + Corrective Smooth (default settings), Armature + Volume Preservation,
# side by side in one run, on each Blender: 3.4 (Debian's), 4.3 (the chroot of blender43.sh)
# unless LVP_SKIP_BLENDER43=1, and $BLENDER when set. Prints one table per Blender and a summary.
#
#   tests/blender/bench.sh [--vertices N] [--frames N]
#
# Tests what is in dist/ (./build.sh builds it first). Blender's user directories point into a
# fresh directory under /tmp, so the user's own Blender set-up is never touched.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
# shellcheck source=../../build.sh
source "$REPO/build.sh"
log() { printf '\033[1m[blender-bench]\033[0m %s\n' "$*" >&2; }

bench_args=("$@")
RUN_TMP="$(mktemp -d /tmp/lvp-blender-bench.XXXXXX)"
chmod 755 "$RUN_TMP"
trap 'rm -rf "$RUN_TMP"' EXIT
export BLENDER_USER_RESOURCES="$RUN_TMP/user"
export BLENDER_USER_CONFIG="$RUN_TMP/user/config"
export BLENDER_USER_SCRIPTS="$RUN_TMP/user/scripts"
export BLENDER_USER_DATAFILES="$RUN_TMP/user/datafiles"
export BLENDER_USER_EXTENSIONS="$RUN_TMP/user/extensions"
export LVP_REPO="$REPO"
export LVP_TEST_TMP="$RUN_TMP"
export LVP_ADDON_DIR="${LVP_ADDON_DIR:-$DIST/$ADDON_ID}"
export LVP_EXTENSION_ZIP="${LVP_EXTENSION_ZIP:-$DIST/$ADDON_ID-$VERSION.zip}"

blenders=(3.4)
[ "${LVP_SKIP_BLENDER43:-0}" = 1 ] || blenders+=(4.3)
[ -z "${BLENDER:-}" ] || blenders+=("$BLENDER")

status=0
for selection in "${blenders[@]}"; do
	case "$selection" in
	3.4) ensure_packages blender; command=(/usr/bin/blender) ;;
	4.3) command=("$HERE/blender43.sh" run) ;;
	*) command=("$selection") ;;
	esac
	log "Blender $selection"
	result="$RUN_TMP/result-${selection//[^A-Za-z0-9.]/_}.json"
	if ! "${command[@]}" -b --factory-startup -noaudio --python-exit-code 1 --python "$HERE/bench.py" -- \
		--result "$result" ${bench_args[@]+"${bench_args[@]}"} >"$RUN_TMP/log" 2>&1; then
		cat "$RUN_TMP/log" >&2
		log "Blender $selection: the benchmark failed"
		status=1
		continue
	fi
	sed -n '/^Blender [0-9].*vertices/,/^core /p' "$RUN_TMP/log"
	echo
done
"$HERE/bench_bake.sh" || status=1  # bake speed to PC2 with 1 and 2 jobs (issue 4)
exit $status
