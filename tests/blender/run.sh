#!/usr/bin/env bash
# tests/blender/run.sh - the headless-Blender unittest suites (tests/blender/test_*.py) on every
# Blender we support. `./build.sh test` calls it.
#
#   tests/blender/run.sh [OPTIONS] [TEST_NAME ...]
#
#   TEST_NAME               test_module, test_module.TestClass or test_module.TestClass.test_method
#   --blender SEL           only this Blender (repeatable): 3.4 = Debian's /usr/bin/blender (installed
#                           with apt when missing), 4.3 = trixie's Blender 4.3.2 and 5.2 = sid's
#                           Blender 5.2.2 LTS, each in its chroot (tests/blender/blender_chroot.sh),
#                           or the path of any blender binary
#   -k PATTERN              only tests whose name contains PATTERN (unittest -k)
#   -f, --failfast          stop each Blender's run at its first failure
#   -q, --quiet             one character per test
#   --list                  list the tests (on each Blender) without running them
#   --no-build              do not run `./build.sh package` first; test what is in dist/
#
# Default Blenders: 3.4, then 4.3 unless LVP_SKIP_BLENDER43=1, then 5.2 unless LVP_SKIP_BLENDER52=1,
# then $BLENDER when set.
# Every failing test is printed with the command that reruns it alone, e.g.
#   tests/blender/run.sh --blender 4.3 test_modifier.TestLive.test_frame_set
# A Blender that dies in a test is reported (its stacks) and started again after that test, so the rest of
# the suite still runs; the test is then run alone, and fails the run only if it fails or dies again there.
#
# Environment: BLENDER, LVP_SKIP_BLENDER43, LVP_SKIP_BLENDER52, LVP_ADDON_DIR / LVP_EXTENSION_ZIP (test another
# build than dist/), LVP_BLENDER_TIMEOUT (seconds per Blender, default 1800), LVP_KEEP_TMP=1
# (keep the per-run directory under /tmp), LVP_CACHE (where the chroots live).
# Blender's user directories (config, scripts, extensions) point into a fresh directory under
# /tmp, so the tests never touch the user's own Blender set-up.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
# build.sh gives ensure_packages (apt, with sudo when not root), ADDON_ID, DIST and VERSION.
# shellcheck source=../../build.sh
source "$REPO/build.sh"
log() { printf '\033[1m[blender-tests +%ss]\033[0m %s\n' "$SECONDS" "$*" >&2; }
die() { printf '\033[31m[blender-tests] error:\033[0m %s\n' "$*" >&2; exit 1; }

usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }

selectors=()
runner_args=()
names=()
build=1
list=0
while [ $# -gt 0 ]; do
	case "$1" in
	--blender) [ $# -ge 2 ] || die "--blender needs a value"; selectors+=("$2"); shift 2 ;;
	--blender=*) selectors+=("${1#--blender=}"); shift ;;
	-k) [ $# -ge 2 ] || die "-k needs a value"; runner_args+=(-k "$2"); shift 2 ;;
	-f | --failfast) runner_args+=(--failfast); shift ;;
	-q | --quiet) runner_args+=(--quiet); shift ;;
	--list) list=1; runner_args+=(--list); shift ;;
	--no-build) build=0; shift ;;
	-h | --help) usage; exit 0 ;;
	--) shift; names+=("$@"); break ;;
	-*) die "unknown option $1 (see --help)" ;;
	*) names+=("$1"); shift ;;
	esac
done
# Names may be given as file paths too: tests/blender/test_x.py -> test_x.
for i in "${!names[@]}"; do
	n="$(basename "${names[$i]}")"
	names[$i]="${n%.py}"
done

if [ ${#selectors[@]} -eq 0 ]; then
	selectors=(3.4)
	[ "${LVP_SKIP_BLENDER43:-0}" = 1 ] || selectors+=(4.3)
	[ "${LVP_SKIP_BLENDER52:-0}" = 1 ] || selectors+=(5.2)
	[ -z "${BLENDER:-}" ] || selectors+=("$BLENDER")
fi

# How to call this script in the printed rerun commands: relative when run from the repo.
if [ "$(pwd -P)" = "$(cd "$REPO" && pwd -P)" ]; then SELF=tests/blender/run.sh; else SELF="$HERE/run.sh"; fi

# ---- set-up -------------------------------------------------------------------------------

# The Blenders that live in a chroot (blender_chroot.sh), by their selector.
is_chroot_blender() { [ "$1" = 4.3 ] || [ "$1" = 5.2 ]; }

for sel in "${selectors[@]}"; do
	case "$sel" in
	3.4) ;;
	*) is_chroot_blender "$sel" || [ -x "$sel" ] || die "--blender $sel: not 3.4, 4.3, 5.2 or an executable file" ;;
	esac
done

CHROOT_BLENDER="$HERE/blender_chroot.sh"
declare -A builder_pids=()
RUN_TMP="$(mktemp -d /tmp/lvp-blender-tests.XXXXXX)"
chmod 755 "$RUN_TMP"
cleanup() {
	local pid
	for pid in "${builder_pids[@]}"; do kill "$pid" 2>/dev/null || true; done
	if [ "${LVP_KEEP_TMP:-0}" = 1 ]; then log "kept $RUN_TMP"; else rm -rf "$RUN_TMP"; fi
}
trap cleanup EXIT

if [ "$list" = 0 ]; then
	for sel in "${selectors[@]}"; do
		is_chroot_blender "$sel" || continue
		ensure_packages debootstrap
		if ! "$CHROOT_BLENDER" "$sel" status >/dev/null 2>&1; then
			# Build the chroot while the rest is built, installed and tested: it has its own dpkg, so
			# the host's apt-get below can run at the same time.
			log "building the Blender $sel chroot in the background (log: $RUN_TMP/blender$sel-build.log)"
			"$CHROOT_BLENDER" "$sel" ensure >"$RUN_TMP/blender$sel-build.log" 2>&1 &
			builder_pids[$sel]=$!
		fi
	done
fi

if [ "$build" = 1 ] && [ "$list" = 0 ]; then
	if [ -f "$REPO/csrc/lvp_python.c" ]; then
		log "building the module and the packages (./build.sh package)"
		"$REPO/build.sh" package || die "./build.sh package failed; fix the build, or rerun with --no-build to test what is in dist/"
	else
		log "csrc/lvp_python.c does not exist yet: nothing to build, testing without the module"
	fi
fi

for sel in "${selectors[@]}"; do
	# python3-numpy: Blender's glTF add-on needs it (the round trips of test_imports and real_cases.py).
	if [ "$sel" = 3.4 ]; then ensure_packages blender python3-numpy; fi
done
# Real skinned, animated files (test_assimp_models), shown inside the chroots at the same path.
if [ "$list" = 0 ]; then ensure_packages assimp-testmodels; fi
export LVP_CHROOT_BINDS="${LVP_CHROOT_BINDS:+$LVP_CHROOT_BINDS:}/usr/share/assimp"

# Blender's user directories: fresh for this run (an extension installed by a test stays here).
export BLENDER_USER_RESOURCES="${BLENDER_USER_RESOURCES:-$RUN_TMP/user}"
export BLENDER_USER_CONFIG="${BLENDER_USER_CONFIG:-$BLENDER_USER_RESOURCES/config}"
export BLENDER_USER_SCRIPTS="${BLENDER_USER_SCRIPTS:-$BLENDER_USER_RESOURCES/scripts}"
export BLENDER_USER_DATAFILES="${BLENDER_USER_DATAFILES:-$BLENDER_USER_RESOURCES/datafiles}"
export BLENDER_USER_EXTENSIONS="${BLENDER_USER_EXTENSIONS:-$BLENDER_USER_RESOURCES/extensions}"
export LVP_RUN_TMP="$RUN_TMP"
export LVP_ADDON_DIR="${LVP_ADDON_DIR:-$DIST/$ADDON_ID}"
export LVP_EXTENSION_ZIP="${LVP_EXTENSION_ZIP:-$HOST_EXTENSION_ZIP}" # this machine's zip (platforms.sh)
[ -f "$LVP_EXTENSION_ZIP" ] || LVP_EXTENSION_ZIP=""

# ---- running ------------------------------------------------------------------------------

total_passed=0 total_failed=0 total_skipped=0
failed_lines=()
blender_failures=0

run_one() {
	local sel="$1" label expect="" cmd
	case "$sel" in
	3.4) label="3.4"; expect=3.4; cmd=(/usr/bin/blender) ;;
	4.3 | 5.2) label="$sel"; expect="$sel"; cmd=("$CHROOT_BLENDER" "$sel" run) ;;
	*) label="$sel"; cmd=("$sel") ;;
	esac
	local rerun
	rerun="$SELF --blender $(printf '%q' "$sel")"

	if is_chroot_blender "$sel" && [ -n "${builder_pids[$sel]:-}" ]; then
		log "waiting for the Blender $sel chroot"
		local builder="${builder_pids[$sel]}"
		unset "builder_pids[$sel]"
		if ! wait "$builder"; then
			cat "$RUN_TMP/blender$sel-build.log" >&2
			log "Blender $sel: the chroot could not be built (LVP_SKIP_BLENDER${sel//./}=1 skips it)"
			failed_lines+=("${SELF%run.sh}blender_chroot.sh $sel ensure    # the Blender $sel chroot could not be built")
			blender_failures=$((blender_failures + 1))
			return 1
		fi
		grep 'ready in' "$RUN_TMP/blender$sel-build.log" >&2 || true
	fi

	local results="$RUN_TMP/results-${label//[^A-Za-z0-9.]/_}"
	local start=$SECONDS passed=0 failed=0 skipped=0 rc after="" resumes=0 crashed=()
	# A Blender that dies in a test is started again after it, up to three times, so that one crash does not
	# take the rest of the suite with it; each test it died in is then run alone once (below).
	while :; do
		blender_tests "$results" ${after:+--after "$after"} ${runner_args[@]+"${runner_args[@]}"} \
			${names[@]+"${names[@]}"}
		[ "$list" = 1 ] && return $rc
		local summary=""
		if [ -f "$results" ]; then summary="$(head -n 1 "$results")"; fi
		case "$summary" in
		done*)
			add_tally "$summary" "$results"
			if [ "$rc" != 0 ] && [ "$(count_of failed "$summary")" = 0 ]; then
				# All tests passed but Blender still failed (e.g. a crash on exit).
				failed=$((failed + 1))
				failed_lines+=("$rerun    # Blender $label exited with status $rc after the tests passed")
			fi
			[ "$rc" = 0 ] || blender_failures=$((blender_failures + 1))
			;;
		running*)
			local current="${summary#running }"
			# What ran before Blender died still counts (runner.py keeps the tally in the results file).
			add_tally "$(sed -n 's/^so far //p' "$results")" "$results"
			if [ "$rc" = 124 ] || [ "$rc" = 137 ]; then
				log "Blender $label timed out after ${LVP_BLENDER_TIMEOUT:-1800}s in $current"
				failed=$((failed + 1))
				failed_lines+=("$rerun $current    # Blender $label timed out in it")
				blender_failures=$((blender_failures + 1))
			else
				log "Blender $label died (status $rc) in $current"
				crash_report "$label" "$results.fault" "$current"
				if [ "$resumes" -lt 3 ]; then
					crashed+=("$current")
					resumes=$((resumes + 1))
					after="$current"
					log "Blender $label: going on after $current in a new Blender"
					continue
				fi
				failed=$((failed + 1))
				failed_lines+=("$rerun $current    # Blender $label died in it (status $rc), the fourth time in this run: the rest was not run")
				blender_failures=$((blender_failures + 1))
			fi
			;;
		*)
			failed=$((failed + 1))
			failed_lines+=("$rerun    # Blender $label did not run the tests (status $rc)")
			blender_failures=$((blender_failures + 1))
			;;
		esac
		break
	done
	# A test Blender died in, alone in a fresh Blender: where it dies again (or fails) it fails the run. Where it
	# passes, the crash did not come from what the test does but from what the long session had built up
	# (Blender 3.4 built against Debian's Python 3.11 has crashed inside Python's interpreter that way): it is
	# reported, with its stacks, and does not fail the run.
	local name
	for name in ${crashed[@]+"${crashed[@]}"}; do
		log "Blender $label: $name alone, after Blender died in it"
		blender_tests "$results" ${runner_args[@]+"${runner_args[@]}"} "$name"
		local summary=""
		if [ -f "$results" ]; then summary="$(head -n 1 "$results")"; fi
		if [ "$rc" = 0 ] && [[ "$summary" == done*failed=0* ]]; then
			add_tally "$summary" "$results"
			crash_notes+=("Blender $label died in $name (the report above) and passed it alone: not counted as a failure")
		else
			failed=$((failed + 1))
			if [[ "$summary" == running* ]]; then
				crash_report "$label" "$results.fault" "$name (alone)"
				failed_lines+=("$rerun $name    # Blender $label died in it (status $rc), and again alone")
			else
				failed_lines+=("$rerun $name    # Blender $label died in it, and it failed alone (status $rc)")
			fi
			blender_failures=$((blender_failures + 1))
		fi
	done
	total_passed=$((total_passed + passed))
	total_failed=$((total_failed + failed))
	total_skipped=$((total_skipped + skipped))
	log "Blender $label: $passed passed, $failed failed, $skipped skipped ($((SECONDS - start)) s)"
}

# count_of KEY TEXT: the number after "KEY=" in TEXT (a line of runner.py's results), 0 when there is none.
count_of() {
	local value
	value="$(sed -n "s/.*$1=\([0-9]*\).*/\1/p" <<<"$2")"
	printf '%s\n' "${value:-0}"
}

# add_tally COUNTS RESULTS: COUNTS (a line "passed=P failed=F skipped=S" of runner.py's results) added to run_one's
# passed, failed and skipped, and the tests RESULTS names as failed to failed_lines.
add_tally() {
	passed=$((passed + $(count_of passed "$1")))
	failed=$((failed + $(count_of failed "$1")))
	skipped=$((skipped + $(count_of skipped "$1")))
	local name
	while IFS= read -r name; do
		failed_lines+=("$rerun $name")
	done < <(sed -n 's/^failed //p' "$2")
}

# blender_tests RESULTS RUNNER_ARGUMENTS...: runner.py in a fresh Blender of run_one's (label, cmd, expect,
# rerun), its results in RESULTS; its exit status into rc.
blender_tests() {
	local results="$1"
	shift
	rm -f "$results" "$results.fault"
	touch "$RUN_TMP/started-$label"
	log "Blender $label: ${cmd[*]}${*:+ ($*)}"
	rc=0
	# Debian's Blender leaves a core file on a crash (where the kernel writes one to the working directory),
	# for crash_report's backtrace; the chroots' would stay inside them.
	(
		if [ "$label" = 3.4 ]; then ulimit -c unlimited 2>/dev/null || true; fi
		exec timeout --kill-after=30 "${LVP_BLENDER_TIMEOUT:-1800}" "${cmd[@]}" -b --factory-startup -noaudio \
			--python-exit-code 1 --python "$HERE/runner.py" -- \
			--expect-version "$expect" --rerun "$rerun" --results "$results" "$@"
	) || rc=$?
}

# crash_report LABEL FAULT_FILE TEST: where a Blender that died was (the crashed thread's native frames, from its
# core file, and every thread's Python stack, from runner.py's faulthandler), kept for the end of the output
# with the failing test, so that a crash seen once on CI can be traced from its log. The crashed thread's
# Python stack comes last: a log cut to its last lines still shows it.
crash_reports=() crash_notes=()
crash_report() {
	local label="$1" fault="$2" report="Blender $label crashed in $3."
	# The native frames, from a core file the kernel left in this directory (the crash file Blender 3.4 writes
	# has none). Only after a crash, so gdb is installed only then.
	local core
	core="$(find . -maxdepth 1 -name 'core*' -type f -newer "$RUN_TMP/started-$label" 2>/dev/null | head -n 1 || true)"
	if [ -n "$core" ] && [ "$label" = 3.4 ] && ensure_packages gdb >/dev/null 2>&1; then
		# The thread whose stack holds the signal handler, from the frame the last handler was called on (the
		# first ones are faulthandler's and Blender's own, raising the signal again).
		report+=$'\n'"The crashed thread's native frames (gdb, $core):"$'\n'
		local frames
		frames="$(gdb -q -batch -ex 'thread apply all bt 40' -ex 'info sharedlibrary' /usr/bin/blender "$core" 2>/dev/null ||
			true)"
		report+="$(awk <<<"$frames" '
			function flush() { if (had && !done) { printf "%s", frames; done = 1 } }
			/^Thread / { flush(); frames = ""; had = 0 }
			/<signal handler called>/ { frames = ""; had = 1; next }
			had && /^#/ { frames = frames substr($0, 1, 200) "\n" }
			END { flush() }' | head -n 8)"
		# Where the add-on's module was loaded (its frames have no names: the packaged module is stripped).
		report+=$'\n'"$(grep '_lvp' <<<"$frames" | cut -c1-200 || true)"
	fi
	[ -z "$core" ] || rm -f "$core"
	if [ -s "$fault" ]; then
		# faulthandler writes a block per thread, the crashed one headed "Current thread", innermost call first.
		report+=$'\n'"The other threads' Python stacks (faulthandler):"$'\n'
		report+="$(awk '/^Current thread/ { skip = 1 } skip && /^$/ { skip = 0; next } !skip && !/^Extension modules/' "$fault" | head -n 16)"
		report+=$'\n'"The crashed thread's Python stack (faulthandler):"$'\n'
		report+="$(awk '/^Current thread/ { on = 1 } on && /^$/ { exit } on' "$fault" | head -n 24)"
	else
		report+=$'\n'"    (faulthandler wrote no Python stack)"
	fi
	crash_reports+=("$report")
}

for sel in "${selectors[@]}"; do
	run_one "$sel" || true
done

[ "$list" = 1 ] && exit 0
# The crash reports (with or without a failure: a crash that did not recur alone is still reported) before the
# failed tests' names, which end the output: a log cut to its last lines keeps the names and as much of the
# reports as fits.
for report in ${crash_reports[@]+"${crash_reports[@]}"}; do
	printf '\n%s\n' "$report" >&2
done
for note in ${crash_notes[@]+"${crash_notes[@]}"}; do
	printf '\n\033[33mWARNING\033[0m %s\n' "$note" >&2
done
if [ ${#failed_lines[@]} -gt 0 ]; then
	printf '\n\033[31mFAILED\033[0m headless-Blender tests; rerun one alone with:\n' >&2
	printf '    %s\n' "${failed_lines[@]}" >&2
fi
echo "blender: $total_passed passed, $total_failed failed, $total_skipped skipped"
[ ${#failed_lines[@]} -eq 0 ] && [ "$blender_failures" = 0 ]
