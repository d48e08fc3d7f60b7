#!/usr/bin/env bash
# build.sh - the one entry point: build, test, bench, fuzz, demo, package.
#
#   ./build.sh            build the core, the Python module for every platform and the packages (dist/):
#                         the add-on folder (this machine's module) and one extension zip per platform
#   ./build.sh test       C tests (ASan+UBSan), module tests, the other platforms' tests (wine, qemu),
#                         headless-Blender tests
#   ./build.sh test-platforms [PART...]  only the other platforms' tests (tests/platforms/run.sh)
#   ./build.sh bench      benchmarks (core, then Blender)
#   ./build.sh fuzz [s]   libFuzzer over bind and the per-frame call for s seconds (default 60)
#   ./build.sh demo       renders the demo scenes into demo/out/
#   ./build.sh package    only the packages
#
# Each command installs what it needs when it is missing (Debian packages, with sudo when not
# root). BLENDER=/path/to/blender adds a Blender to test against; LVP_SKIP_BLENDER43=1 and
# LVP_SKIP_BLENDER52=1 skip the chroots of Blender 4.3 and 5.2.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
BUILD="$ROOT/build"
DIST="$ROOT/dist"
ADDON_ID="local_volume_preservation"
VERSION="$(sed -n 's/^version = "\(.*\)"/\1/p' "$ROOT/blender_manifest.toml" 2>/dev/null || true)"
VERSION="${VERSION:-0.1.0}"
CACHE="${LVP_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/lvp}"
PYTHON_INCLUDE="/usr/include/python3.11"
CLANG_PACKAGES=(clang libclang-rt-14-dev) # the fuzzer and the replay of its findings

CC="${CC:-gcc}"
CFLAGS_COMMON=(-std=c11 -D_GNU_SOURCE -Wall -Wextra -Wpedantic -Wshadow -Wno-unused-function)
CFLAGS_RELEASE=(-O3 -fPIC -fno-math-errno -fvisibility=hidden)
CFLAGS_SANITIZE=(-O1 -g -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)

# The modules and zips of every platform, and their tests: HOST_EXTENSION_ZIP, build_platform_modules,
# build_platform_packages, run_platform_tests.
source "$ROOT/platforms.sh"
source "$ROOT/tests/platforms/run.sh"

log() { printf '\033[1m[build]\033[0m %s\n' "$*" >&2; }
die() { printf '\033[31m[build] error:\033[0m %s\n' "$*" >&2; exit 1; }

as_root() {
	if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}

APT_UPDATED=0
# ensure_packages pkg...: installs the Debian packages that are not installed yet.
ensure_packages() {
	local missing=()
	for pkg in "$@"; do
		dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
	done
	[ ${#missing[@]} -eq 0 ] && return 0
	log "installing ${missing[*]}"
	if [ "$APT_UPDATED" = 0 ]; then
		as_root env DEBIAN_FRONTEND=noninteractive apt-get update -q >&2
		APT_UPDATED=1
	fi
	# Once more after a fresh update when the archive fails to deliver (a mirror changing under the lists,
	# a dropped connection): a fresh CI machine installs everything, and one such failure fails a stage.
	as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}" >&2 ||
		{
			log "installing ${missing[*]} failed; updating the package lists and trying once more"
			sleep 10
			as_root env DEBIAN_FRONTEND=noninteractive apt-get update -q >&2
			as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
		}
}

core_sources() {
	find "$ROOT/csrc" -maxdepth 1 -name '*.c' ! -name 'lvp_python.c' | sort
}

support_sources() {
	find "$ROOT/tests/c/support" -maxdepth 1 -name '*.c' 2>/dev/null | sort
}

# ---- build --------------------------------------------------------------------------------

build_module() {
	ensure_packages gcc libc6-dev python3-dev
	mkdir -p "$BUILD"
	local out="$BUILD/_lvp.abi3.so"
	log "compiling the core and the Python module ($out)"
	# shellcheck disable=SC2046
	"$CC" "${CFLAGS_COMMON[@]}" "${CFLAGS_RELEASE[@]}" -Werror -shared -pthread \
		-DPy_LIMITED_API=0x030B0000 -I"$PYTHON_INCLUDE" -I"$ROOT/csrc" \
		$(core_sources) "$ROOT/csrc/lvp_python.c" -o "$out" -lm
}

build_core_library() {
	ensure_packages gcc libc6-dev
	mkdir -p "$BUILD/obj"
	local objects=()
	for src in $(core_sources); do
		local obj="$BUILD/obj/$(basename "${src%.c}").o"
		"$CC" "${CFLAGS_COMMON[@]}" "${CFLAGS_RELEASE[@]}" -Werror -pthread -c "$src" -o "$obj"
		objects+=("$obj")
	done
	rm -f "$BUILD/liblvp.a"
	ar rcs "$BUILD/liblvp.a" "${objects[@]}"
}

# dist/: the add-on folder with this machine's module, and one extension zip per platform, each with
# its own module (platforms.sh). The module build/_lvp.abi3.so of build_module, Debian's gcc, is for
# the tests here only: it needs glibc 2.34.
build_packages() {
	build_platform_modules
	build_platform_packages
}

cmd_build() {
	build_module
	build_core_library
	build_packages
}

# ---- tests --------------------------------------------------------------------------------

sanitized_archive_path() { printf '%s\n' "$BUILD/tests/liblvp-$(basename "$1").a"; }

# sanitized_archive COMPILER: the core and the tests' support code compiled once with the C tests' flags
# (sanitized, warnings as errors), the files side by side on every core, into
# $BUILD/tests/liblvp-NAME.a (NAME the compiler's file name); compiled again only when a source, a header
# or this file changed.
sanitized_archive() {
	local compiler="$1"
	local archive object_dir
	archive="$(sanitized_archive_path "$compiler")"
	object_dir="$BUILD/tests/objects-$(basename "$compiler")"
	if [ -f "$archive" ] &&
		[ -z "$(find "$ROOT/csrc" "$ROOT/tests/c/support" "$ROOT/build.sh" -newer "$archive" -print -quit)" ]; then
		return 0
	fi
	rm -rf "$object_dir" "$archive"
	mkdir -p "$object_dir"
	local src kind pid pids=() failed=0 jobs
	jobs="$(nproc)"
	for src in $(core_sources) $(support_sources); do
		case "$src" in "$ROOT/csrc/"*) kind=core ;; *) kind=support ;; esac
		"$compiler" "${CFLAGS_COMMON[@]}" "${CFLAGS_SANITIZE[@]}" -Werror -pthread -I"$ROOT/csrc" -I"$ROOT/tests/c" \
			-c "$src" -o "$object_dir/$kind-$(basename "${src%.c}").o" &
		pids+=($!)
		if [ ${#pids[@]} -ge "$jobs" ]; then
			wait "${pids[0]}" || failed=1
			pids=("${pids[@]:1}")
		fi
	done
	for pid in "${pids[@]}"; do wait "$pid" || failed=1; done
	[ "$failed" = 0 ] && ar rcs "$archive" "$object_dir"/*.o
}

# build_c_test COMPILER NAME OUT: tests/c/NAME.c with the core, sanitized, warnings as errors,
# into $BUILD/tests/OUT. Its callers test its status: they run inside `||`, where set -e does not
# stop at a failed compile, and the binary of the last build would run instead.
build_c_test() {
	local compiler="$1" name="$2" out="$3"
	mkdir -p "$BUILD/tests"
	rm -f "$BUILD/tests/$out"
	sanitized_archive "$compiler" || return 1
	"$compiler" "${CFLAGS_COMMON[@]}" "${CFLAGS_SANITIZE[@]}" -Werror -pthread -I"$ROOT/csrc" -I"$ROOT/tests/c" \
		"$ROOT/tests/c/$name.c" "$(sanitized_archive_path "$compiler")" -o "$BUILD/tests/$out" -lm -lgmp
}

# C_TESTS_FAILED: the names of the C tests that failed in the last run_c_tests.
C_TESTS_FAILED=()
run_c_tests() {
	ensure_packages gcc libc6-dev libgmp-dev
	local failed=0
	C_TESTS_FAILED=()
	for test_src in "$ROOT"/tests/c/test_*.c; do
		local name
		name="$(basename "${test_src%.c}")"
		log "C test $name"
		if ! build_c_test "$CC" "$name" "$name" || ! (cd "$ROOT/tests" && "$BUILD/tests/$name"); then
			printf '\033[31mFAILED\033[0m %s; rerun alone: ./build.sh test-c %s\n' "$name" "$name" >&2
			C_TESTS_FAILED+=("$name")
			failed=1
		fi
	done
	run_fuzz_regressions_clang || { C_TESTS_FAILED+=("test_fuzz_regressions (clang)"); failed=1; }
	run_threads_tsan || { C_TESTS_FAILED+=("test_threads (ThreadSanitizer)"); failed=1; }
	return $failed
}

# The worker threads once more under ThreadSanitizer, which reports an access to a loop's fields that the
# pool's lock and counters do not order even when this run's timing did not make it go wrong.
run_threads_tsan() {
	ensure_packages gcc libc6-dev
	log "C test test_threads (ThreadSanitizer)"
	mkdir -p "$BUILD/tests"
	if ! "$CC" "${CFLAGS_COMMON[@]}" -O1 -g -fsanitize=thread -Werror -pthread -I"$ROOT/csrc" -I"$ROOT/tests/c" \
		"$ROOT/tests/c/test_threads.c" "$ROOT/csrc/threads.c" -o "$BUILD/tests/test_threads_tsan" ||
		! (cd "$ROOT/tests" && "$BUILD/tests/test_threads_tsan"); then
		printf '\033[31mFAILED\033[0m test_threads under ThreadSanitizer; rerun alone: %s\n' \
			"bash -c 'source ./build.sh; run_threads_tsan'" >&2
		return 1
	fi
}

# The fuzzer's findings replayed once more, built by clang as the fuzzer is: its UBSan checks
# more than gcc's (a zero offset applied to a null pointer, for one).
run_fuzz_regressions_clang() {
	ensure_packages "${CLANG_PACKAGES[@]}" libc6-dev libgmp-dev
	log "C test test_fuzz_regressions (clang)"
	if ! build_c_test clang test_fuzz_regressions test_fuzz_regressions_clang ||
		! (cd "$ROOT/tests" && "$BUILD/tests/test_fuzz_regressions_clang"); then
		printf '\033[31mFAILED\033[0m test_fuzz_regressions under clang; rerun alone: %s\n' \
			"bash -c 'source ./build.sh; run_fuzz_regressions_clang'" >&2
		return 1
	fi
}

run_c_test_alone() {
	local name="$1"
	ensure_packages gcc libc6-dev libgmp-dev
	build_c_test "$CC" "$name" "$name"
	(cd "$ROOT/tests" && "$BUILD/tests/$name")
}

run_module_tests() {
	[ -f "$ROOT/csrc/lvp_python.c" ] || return 0
	build_module
	ensure_packages python3
	log "Python module tests (/usr/bin/python3)"
	# CI runs the demo first; without its output the tests of the tables README quotes from it skip.
	[ -f "$ROOT/demo/out/volume_tables.md" ] ||
		log "demo/out/ is missing: README's quoted demo tables are not checked (./build.sh demo first, as CI does)"
	PYTHONPATH="$BUILD" /usr/bin/python3 -m unittest discover -s "$ROOT/tests/python" -t "$ROOT/tests/python" -v
}

# The failed stages are named again at the end: a CI log often keeps only its tail, after the Blender
# tests, and the C or platform tests' own failure lines are far above it.
cmd_test() {
	local failed=()
	run_c_tests || failed+=("C tests: ${C_TESTS_FAILED[*]}")
	run_module_tests || failed+=("Python module tests (rerun: bash -c 'source ./build.sh; run_module_tests')")
	run_platform_tests || failed+=("platform tests: ${PLATFORM_PARTS_FAILED[*]} (rerun: ./build.sh test-platforms PART)")
	if [ -x "$ROOT/tests/blender/run.sh" ]; then
		"$ROOT/tests/blender/run.sh" || failed+=("Blender tests (see the FAILED lines above)")
	fi
	if [ ${#failed[@]} -gt 0 ]; then
		printf '    %s\n' "${failed[@]}" >&2
		die "some tests failed: ${#failed[@]} stage(s), listed above"
	fi
	log "all tests passed"
}

# ---- fuzz, bench --------------------------------------------------------------------------

cmd_fuzz() {
	local seconds="${1:-60}"
	ensure_packages "${CLANG_PACKAGES[@]}"
	mkdir -p "$BUILD/fuzz" "$BUILD/fuzz/corpus"
	log "building the fuzzer (clang, libFuzzer, ASan, UBSan)"
	# shellcheck disable=SC2046
	clang -std=c11 -D_GNU_SOURCE -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
		-pthread -I"$ROOT/csrc" $(core_sources) "$ROOT/tests/fuzz/fuzz_lvp.c" -o "$BUILD/fuzz/fuzz_lvp" -lm
	log "fuzzing for $seconds s (seeds: tests/fuzz/corpus and tests/fuzz/regressions)"
	"$BUILD/fuzz/fuzz_lvp" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=4096 \
		-artifact_prefix="$BUILD/fuzz/" "$BUILD/fuzz/corpus" "$ROOT/tests/fuzz/corpus" "$ROOT/tests/fuzz/regressions"
}

cmd_bench() {
	build_core_library
	ensure_packages gcc libc6-dev
	mkdir -p "$BUILD/bench"
	"$CC" "${CFLAGS_COMMON[@]}" -O3 -march=x86-64-v2 -pthread -I"$ROOT/csrc" -I"$ROOT/tests/c" \
		"$ROOT/tests/bench/bench_core.c" $(support_sources) "$BUILD/liblvp.a" -o "$BUILD/bench/bench_core" -lm -lgmp
	(cd "$ROOT/tests" && "$BUILD/bench/bench_core")
	# Keep Skin Apart's cost, and hashes of what it gives (the same bits across thread counts)
	"$CC" "${CFLAGS_COMMON[@]}" -O3 -march=x86-64-v2 -pthread -I"$ROOT/csrc" -I"$ROOT/tests/c" \
		"$ROOT/tests/bench/bench_keep_apart.c" $(support_sources) "$BUILD/liblvp.a" -o "$BUILD/bench/bench_keep_apart" \
		-lm -lgmp
	(cd "$ROOT/tests" && "$BUILD/bench/bench_keep_apart" --quick)
	if [ -x "$ROOT/tests/blender/bench.sh" ]; then
		cmd_build
		"$ROOT/tests/blender/bench.sh"
	fi
}

main() {
	local command="${1:-build}"
	shift || true
	case "$command" in
	build) cmd_build ;;
	package) build_packages ;;
	test) cmd_test ;;
	test-c) run_c_test_alone "$@" ;;
	test-platforms) run_platform_tests "$@" ;;
	fuzz) cmd_fuzz "$@" ;;
	bench) cmd_bench ;;
	demo)
		[ -x "$ROOT/demo/run.sh" ] || die "the demo is not written yet"
		cmd_build
		"$ROOT/demo/run.sh"
		;;
	*) die "unknown command '$command' (build, test, test-c NAME, test-platforms [PART...], bench, fuzz [seconds], demo, package)" ;;
	esac
}

# Run only when executed: tests/blender/*.sh source this file for log, as_root, ensure_packages, CACHE.
if [ "${BASH_SOURCE[0]}" = "$0" ]; then main "$@"; fi
