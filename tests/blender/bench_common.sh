# tests/blender/bench_common.sh - what bench.sh and bench_bake.sh share (sourced, not run): one
# benchmark script run headless in each Blender, its table printed.
#
# Blenders: 3.4 (Debian's), 4.3 and 5.2 (the chroots of blender_chroot.sh) unless
# LVP_SKIP_BLENDER43=1 or LVP_SKIP_BLENDER52=1, and $BLENDER when set. The add-on tested is what is in dist/. Blender's user directories point into a
# fresh directory under /tmp, so the user's own Blender set-up is never touched.

BENCH_HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
# shellcheck source=../../build.sh
source "$BENCH_HERE/../../build.sh"

# bench_in_each_blender TAG SCRIPT FROM TO [ARGS...]: runs tests/blender/SCRIPT -- ARGS in each
# Blender and prints its output from the line matching the sed pattern FROM to the one matching TO;
# on a failure prints the whole output. Returns 1 when any Blender failed.
bench_in_each_blender() {
	local tag="$1" script="$2" from="$3" to="$4"
	shift 4
	local run_tmp
	run_tmp="$(mktemp -d "/tmp/lvp-$tag.XXXXXX")"
	chmod 755 "$run_tmp"
	(
		trap 'rm -rf "$run_tmp"' EXIT
		log() { printf '\033[1m[%s]\033[0m %s\n' "$tag" "$*" >&2; }
		export BLENDER_USER_RESOURCES="$run_tmp/user"
		export BLENDER_USER_CONFIG="$run_tmp/user/config"
		export BLENDER_USER_SCRIPTS="$run_tmp/user/scripts"
		export BLENDER_USER_DATAFILES="$run_tmp/user/datafiles"
		export BLENDER_USER_EXTENSIONS="$run_tmp/user/extensions"
		export LVP_REPO="$ROOT"
		export LVP_TEST_TMP="$run_tmp"
		export LVP_ADDON_DIR="${LVP_ADDON_DIR:-$DIST/$ADDON_ID}"
		export LVP_EXTENSION_ZIP="${LVP_EXTENSION_ZIP:-$HOST_EXTENSION_ZIP}"

		local blenders=(3.4) selection status=0
		[ "${LVP_SKIP_BLENDER43:-0}" = 1 ] || blenders+=(4.3)
		[ "${LVP_SKIP_BLENDER52:-0}" = 1 ] || blenders+=(5.2)
		[ -z "${BLENDER:-}" ] || blenders+=("$BLENDER")
		for selection in "${blenders[@]}"; do
			local command
			case "$selection" in
			3.4) ensure_packages blender; command=(/usr/bin/blender) ;;
			4.3 | 5.2) command=("$BENCH_HERE/blender_chroot.sh" "$selection" run) ;;
			*) command=("$selection") ;;
			esac
			log "Blender $selection"
			if ! "${command[@]}" -b --factory-startup -noaudio --python-exit-code 1 --python "$BENCH_HERE/$script" \
				-- "$@" >"$run_tmp/log" 2>&1; then
				cat "$run_tmp/log" >&2
				log "Blender $selection: $script failed"
				status=1
				continue
			fi
			sed -n "${from},${to}p" "$run_tmp/log"
			echo
		done
		exit $status
	)
}
