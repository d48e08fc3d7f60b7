#!/usr/bin/env bash
# tests/blender/panel_screenshot.sh - screenshots of the whole Blender window with the Volume
# Preservation panel open (set up by tests/blender/panel_screenshot.py), real Blender windows on an
# Xvfb screen of 1920x1080: the default layout that test_panel.py checks the panel's texts against.
#
#   tests/blender/panel_screenshot.sh [OUT_DIR]     default: build/screenshots
#
# One PNG per Blender: panel-3.4.png (Debian's), panel-5.2.png (the chroot of blender_chroot.sh,
# into which Mesa's OpenGL drivers are installed the first time: the headless tests need none).
# Tests what is in dist/ (./build.sh package builds it).
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=../../build.sh
source "$HERE/../../build.sh"
OUT="$(mkdir -p "${1:-$BUILD/screenshots}" && cd "${1:-$BUILD/screenshots}" && pwd)"
ensure_packages xvfb blender debootstrap

run_tmp="$(mktemp -d /tmp/lvp-screenshot.XXXXXX)"
chmod 755 "$run_tmp"
trap 'rm -rf "$run_tmp"' EXIT
export BLENDER_USER_RESOURCES="$run_tmp/user" LVP_TEST_TMP="$run_tmp" LVP_REPO="$ROOT"
export LVP_ADDON_DIR="$DIST/$ADDON_ID" LVP_EXTENSION_ZIP="$HOST_EXTENSION_ZIP"

CHROOT_BLENDER="$HERE/blender_chroot.sh"
"$CHROOT_BLENDER" 5.2 ensure >/dev/null
"$CHROOT_BLENDER" 5.2 exec sh -c 'test -e /usr/lib/x86_64-linux-gnu/dri' 2>/dev/null || {
	log "installing Mesa's OpenGL drivers into the Blender 5.2 chroot"
	chroot_dir="$("$CHROOT_BLENDER" 5.2 ensure)"
	as_root unshare -m sh -c 'mount -t proc proc "$1/proc" && chroot "$1" env DEBIAN_FRONTEND=noninteractive \
		apt-get install -y -q --no-install-recommends libgl1-mesa-dri libglx-mesa0 libegl-mesa0 libgl1' sh "$chroot_dir" >&2
}

# Xvfb's screen, read by ImageMagick's import (Blender's own screenshot reads black from Mesa's
# software OpenGL in the chroot).
ensure_packages imagemagick
display=":$((90 + RANDOM % 100))"
Xvfb "$display" -screen 0 1920x1080x24 -nolisten tcp >"$run_tmp/xvfb.log" 2>&1 &
xvfb_pid=$!
trap 'kill "$xvfb_pid" 2>/dev/null || true; rm -rf "$run_tmp"' EXIT
export DISPLAY="$display"

for version in 3.4 5.2; do
	case "$version" in
	3.4) command=(/usr/bin/blender) ;;
	*) command=("$CHROOT_BLENDER" "$version" run) ;;
	esac
	log "Blender $version"
	ready="$run_tmp/ready-$version" done="$run_tmp/done-$version"
	timeout 300 "${command[@]}" --factory-startup -noaudio --python "$HERE/panel_screenshot.py" -- \
		"$ready" "$done" >"$run_tmp/blender-$version.log" 2>&1 &
	blender_pid=$!
	for _ in $(seq 600); do
		[ -e "$ready" ] || ! kill -0 "$blender_pid" 2>/dev/null && break
		sleep 0.2
	done
	if [ ! -e "$ready" ]; then
		cat "$run_tmp/blender-$version.log" >&2
		die "Blender $version did not show the panel"
	fi
	import -display "$display" -window root "$OUT/panel-$version.png"
	touch "$done"
	wait "$blender_pid" || true
	grep '^PROPERTIES' "$run_tmp/blender-$version.log" || true
	log "$OUT/panel-$version.png"
done
