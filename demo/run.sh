#!/usr/bin/env bash
# demo/run.sh - the demo: headless Blender 3.4 (Debian's /usr/bin/blender) builds the default scenes by
# code and renders them with Cycles on the CPU into demo/out/, then prints the volume-error table.
# `./build.sh demo` builds the add-on and runs this; run it alone to render again with what is in dist/.
#
#   demo/run.sh [--quick] [--out DIR]
#
# --quick renders a quarter of the pixels with fewer samples. BLENDER=/path/to/blender uses another
# Blender (3.4 or later; on 4.2+ the add-on is installed from the extension zip into a temporary
# directory). Blender's user directories point into a temporary directory, so the user's own set-up
# is never touched.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/.." && pwd)"
# build.sh gives ensure_packages (apt, with sudo when not root), log, die, DIST, ADDON_ID and VERSION.
# shellcheck source=../build.sh
source "$REPO/build.sh"
log() { printf '\033[1m[demo +%ss]\033[0m %s\n' "$SECONDS" "$*" >&2; }

[ -d "$DIST/$ADDON_ID" ] || die "no add-on in $DIST/$ADDON_ID: run ./build.sh demo (it builds first)"
if [ -z "${BLENDER:-}" ]; then
	ensure_packages blender
	BLENDER=/usr/bin/blender
fi

TMP="$(mktemp -d /tmp/lvp-demo.XXXXXX)"
trap 'rm -rf "$TMP"' EXIT
export BLENDER_USER_RESOURCES="$TMP/user"
export BLENDER_USER_CONFIG="$TMP/user/config"
export BLENDER_USER_SCRIPTS="$TMP/user/scripts"
export BLENDER_USER_DATAFILES="$TMP/user/datafiles"
export BLENDER_USER_EXTENSIONS="$TMP/user/extensions"
export LVP_TEST_TMP="$TMP"
export LVP_REPO="$REPO"
export LVP_ADDON_DIR="$DIST/$ADDON_ID"
export LVP_EXTENSION_ZIP="$HOST_EXTENSION_ZIP"

log "rendering with $BLENDER (Cycles on the CPU)"
# Blender's per-frame render lines are left out; everything the demo prints is kept.
set +e
"$BLENDER" -b --factory-startup -noaudio --python-exit-code 1 --python "$HERE/demo.py" -- "$@" 2>&1 |
	grep --line-buffered -v -E '^(Fra:|Saved:| Time:|Info: Volume Preservation added)|^$'
status=${PIPESTATUS[0]}
set -e
[ "$status" = 0 ] || die "the demo failed (Blender exited with status $status)"
log "done in ${SECONDS} s"
