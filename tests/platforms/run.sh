# tests/platforms/run.sh - tests of what platforms.sh builds for the platforms this machine is not;
# sourced by build.sh (`./build.sh test` runs them all, `./build.sh test-platforms [PART]` one part).
#
#   c-windows      the C tests built by MinGW-w64 (-static), run under wine
#   c-arm64        the C tests built by gcc-aarch64-linux-gnu (-static), run under qemu-aarch64
#   module-arm64   the shipped linux_arm64 module: tests/python/test_module.py under qemu, by Debian's
#                  arm64 Python 3.11
#   module-linux   the shipped linux_x64 module: tests/python/test_module.py by /usr/bin/python3
#   module-windows the shipped _lvp.pyd loaded under wine and initialised (PyInit__lvp, then its exec
#                  slot) against a stub python3.dll (python3_stub.c, load_module.c)
#   binaries       each module: its format and architecture (ELF, PE, Mach-O bundle), its one export,
#                  its Python symbols all in the stable ABI, the glibc it needs (Linux: 2.28 at most),
#                  the macOS it is marked for; each zip: its manifest's one platform and its module
#
# The C tests here are not sanitized (MinGW has no sanitizers, and they do not run under qemu):
# the sanitized builds are the Linux ones of build.sh. The GMP that tests/c/support/test_intersect.c
# uses is Debian's arm64 libgmp.a for arm64, and for Windows, which Debian has no GMP for, mini-gmp,
# compiled from Debian's gmp source (platforms.sh, ensure_debian_sources): exact too, but 5 times
# slower (test_foldover under qemu: 56 s with it, 10 s with GMP).

PLATFORM_TEST_PARTS=(binaries module-linux module-windows module-arm64 c-windows c-arm64)
WINE=/usr/lib/wine/wine64
CROSS_TEST_PACKAGES=(wine64 qemu-user)

platform_tests_setup() {
	ensure_packages "${CROSS_TEST_PACKAGES[@]}" binutils python3
	ensure_cross_toolchains
	# Wine's prefix (its C: drive and registry) is made once, ~15 s, and kept with the other downloads.
	export WINEPREFIX="$CACHE/wine-prefix" WINEDEBUG=-all WINEDLLOVERRIDES="mscoree,mshtml="
}

# ---- the C tests ----------------------------------------------------------------------------------

# build_cross_c_tests PLATFORM COMPILER EXE_SUFFIX: every tests/c/test_*.c, with the core and the
# support files compiled once, into $(platform_dir PLATFORM)/tests/, linked -static (no runtime DLLs
# to find under wine, no arm64 libc to point qemu at).
build_cross_c_tests() {
	local platform="$1" compiler="$2" suffix="$3"
	local dir gmp_flags=() objects=() libraries=()
	dir="$(platform_dir "$platform")/tests"
	mkdir -p "$dir/obj"
	if [ "$platform" = linux_arm64 ]; then
		gmp_flags=(-I"$ARM64_ROOT/usr/include/aarch64-linux-gnu")
		libraries=("$ARM64_ROOT/usr/lib/aarch64-linux-gnu/libgmp.a")
	else
		gmp_flags=(-DLVP_TEST_MINI_GMP -I"$MINI_GMP")
		# GMP's code, not ours: its own warnings are not this project's to fix. GMP 6.2.1's mini-mpq.c
		# uses GMP_LIMB_MAX, which only mini-gmp.c defines: the same definition here.
		for src in "$MINI_GMP/mini-gmp.c" "$MINI_GMP/mini-mpq.c"; do
			local obj
			obj="$dir/obj/$(basename "${src%.c}").o"
			"$compiler" -O2 -w -I"$MINI_GMP" -DGMP_LIMB_MAX='((mp_limb_t) ~(mp_limb_t) 0)' -c "$src" -o "$obj" ||
				return 1
			objects+=("$obj")
		done
	fi
	for src in $(core_sources) $(support_sources); do
		local obj
		obj="$dir/obj/$(basename "${src%.c}").o"
		"$compiler" "${CFLAGS_COMMON[@]}" -O2 -Werror -pthread "${gmp_flags[@]}" -I"$ROOT/csrc" -I"$ROOT/tests/c" \
			-c "$src" -o "$obj" || return 1
		objects+=("$obj")
	done
	for test_src in "$ROOT"/tests/c/test_*.c; do
		local name
		name="$(basename "${test_src%.c}")"
		"$compiler" "${CFLAGS_COMMON[@]}" -O2 -Werror -pthread "${gmp_flags[@]}" -I"$ROOT/csrc" -I"$ROOT/tests/c" \
			"$test_src" "${objects[@]}" -static -o "$dir/$name$suffix" "${libraries[@]}" -lm || return 1
	done
}

# run_cross_c_tests PLATFORM EXE_SUFFIX RUNNER...: runs each test from tests/, as build.sh does.
run_cross_c_tests() {
	local platform="$1" suffix="$2"
	shift 2
	local failed=0 dir
	dir="$(platform_dir "$platform")/tests"
	for test_src in "$ROOT"/tests/c/test_*.c; do
		local name started
		name="$(basename "${test_src%.c}")"
		started=$SECONDS
		if (cd "$ROOT/tests" && "$@" "$dir/$name$suffix" >"$dir/$name.log" 2>&1); then
			log "  $platform $name: passed ($((SECONDS - started)) s)"
		else
			cat "$dir/$name.log" >&2
			printf '\033[31mFAILED\033[0m %s on %s (output above); rerun: ./build.sh test-platforms c-%s\n' \
				"$name" "$platform" "${platform#*_}" >&2
			[ "$platform" = linux_arm64 ] && printf '  or alone: (cd tests && %s %s)\n' "$*" "$dir/$name$suffix" >&2
			[ "$platform" = windows_x64 ] && printf '  or alone: (cd tests && WINEPREFIX=%s %s %s)\n' \
				"$WINEPREFIX" "$*" "$dir/$name$suffix" >&2
			failed=1
		fi
	done
	return $failed
}

test_part_c_windows() {
	log "C tests for windows_x64 (MinGW-w64, under wine)"
	build_cross_c_tests windows_x64 x86_64-w64-mingw32-gcc-posix .exe || return 1
	run_cross_c_tests windows_x64 .exe "$WINE"
}

# -O2: at -O3 Debian 12's cross gcc 12.2 stops with an internal compiler error in the loop vectorizer
# on bind.c and mesh.c (the module itself is built by Zig's clang).
test_part_c_arm64() {
	log "C tests for linux_arm64 (gcc-aarch64-linux-gnu, under qemu-aarch64)"
	build_cross_c_tests linux_arm64 aarch64-linux-gnu-gcc "" || return 1
	run_cross_c_tests linux_arm64 "" qemu-aarch64
}

# ---- the modules ----------------------------------------------------------------------------------

# The Python module's tests, on a module directory, by a Python command.
run_module_test_file() {
	local module_dir="$1"
	shift
	(cd "$ROOT/tests/python" && PYTHONPATH="$module_dir" "$@")
}

test_part_module_linux() {
	log "module tests on the shipped linux_x64 module (Zig, glibc 2.28), /usr/bin/python3"
	run_module_test_file "$(platform_dir linux_x64)" /usr/bin/python3 -m unittest test_module || {
		printf '\033[31mFAILED\033[0m the linux_x64 module; rerun: ./build.sh test-platforms module-linux\n' >&2
		return 1
	}
}

# Debian's arm64 python3.11 under qemu. A child interpreter started by a test (sys.executable) must
# go through qemu too (this machine has no binfmt_misc to do that by itself): sys.executable is a
# script that starts it so.
test_part_module_arm64() {
	log "module tests on the shipped linux_arm64 module, Debian's arm64 Python 3.11 under qemu-aarch64"
	local python
	python="$(platform_dir linux_arm64)/python3.11-qemu"
	printf '#!/bin/sh\nexec qemu-aarch64 -L "%s" "%s/usr/bin/python3.11" "$@"\n' "$ARM64_ROOT" "$ARM64_ROOT" >"$python"
	chmod +x "$python"
	run_module_test_file "$(platform_dir linux_arm64)" "$python" -c \
		"import platform, sys, unittest; sys.executable = '$python'; print('python', platform.machine(), sys.version.split()[0]); unittest.main(module=None, argv=['unittest', 'test_module'])" || {
		printf '\033[31mFAILED\033[0m the linux_arm64 module under qemu; rerun: ./build.sh test-platforms module-arm64\n' >&2
		return 1
	}
}

# windows_python_imports PYD: the names it imports from python3.dll (objdump's import table, one
# block per DLL, ended by a blank line).
windows_python_imports() {
	x86_64-w64-mingw32-objdump -p "$1" |
		awk '/DLL Name: python3.dll/ { inside = 1; getline; next } inside && NF == 0 { inside = 0 } inside { print $NF }'
}

# python3_stub.c's python3.dll: the functions initialisation calls, plus a trap for every other name _lvp.pyd imports
# from python3.dll (the stable ABI's data symbols among them as plain data).
build_python3_stub() {
	local dir="$1" pyd="$2" config="$3"
	x86_64-w64-mingw32-gcc-posix "${CFLAGS_COMMON[@]}" -O1 -Werror -DPy_NO_ENABLE_SHARED -DMS_WIN64 \
		-DPy_LIMITED_API=0x030B0000 -I"$PYTHON_SOURCE/Include" -I"$config" \
		-c "$ROOT/tests/platforms/python3_stub.c" -o "$dir/python3_stub.o" || return 1
	local implemented imports
	implemented="$(x86_64-w64-mingw32-nm --defined-only -g "$dir/python3_stub.o" | awk '{ print $3 }')"
	imports="$(windows_python_imports "$pyd")"
	[ -n "$imports" ] || { log "no imports from python3.dll in $pyd"; return 1; }
	{
		printf '/* Generated by tests/platforms/run.sh: what _lvp.pyd imports and python3_stub.c lacks. */\n'
		printf 'void lvp_stub_trap(const char *name);\n'
		for name in $imports; do
			grep -qx "$name" <<<"$implemented" && continue
			if grep -qx "$name DATA" "$(platform_dir windows_x64)/python3.def"; then
				printf 'char %s[256];\n' "$name"
			else
				printf 'void %s(void) { lvp_stub_trap("%s"); }\n' "$name" "$name"
			fi
		done
	} >"$dir/python3_traps.c"
	x86_64-w64-mingw32-gcc-posix -O1 -shared -static "$dir/python3_stub.o" "$dir/python3_traps.c" \
		-o "$dir/python3.dll" -Wl,--export-all-symbols -Wl,--out-implib,"$dir/libpython3_stub.a"
}

test_part_module_windows() {
	log "the shipped windows_x64 module under wine: loaded, PyInit__lvp and its exec slot run (stub python3.dll)"
	local dir pyd config functions
	dir="$(platform_dir windows_x64)/load"
	pyd="$(platform_module windows_x64)"
	config="$(platform_dir windows_x64)/pyconfig"
	rm -rf "$dir"
	mkdir -p "$dir"
	if ! build_python3_stub "$dir" "$pyd" "$config" ||
		! x86_64-w64-mingw32-gcc-posix "${CFLAGS_COMMON[@]}" -O1 -Werror -DPy_NO_ENABLE_SHARED -DMS_WIN64 \
			-DPy_LIMITED_API=0x030B0000 -I"$PYTHON_SOURCE/Include" -I"$config" \
			"$ROOT/tests/platforms/load_module.c" -o "$dir/load_module.exe" -L"$dir" -lpython3_stub; then
		printf '\033[31mFAILED\033[0m building the Windows module loader; rerun: ./build.sh test-platforms module-windows\n' >&2
		return 1
	fi
	cp "$pyd" "$dir/"
	# The functions the Linux module has: the Windows one must have the same.
	functions="$(PYTHONPATH="$(platform_dir linux_x64)" /usr/bin/python3 -c \
		'import types, _lvp; print(" ".join(n for n in dir(_lvp) if isinstance(getattr(_lvp, n), types.BuiltinFunctionType)))')"
	# shellcheck disable=SC2086
	(cd "$dir" && "$WINE" load_module.exe _lvp.pyd "$VERSION" $functions) || {
		printf '\033[31mFAILED\033[0m _lvp.pyd under wine; rerun: ./build.sh test-platforms module-windows\n' >&2
		return 1
	}
}

# ---- the binaries and the zips --------------------------------------------------------------------

# check FAILURE-MESSAGE COMMAND...: runs the check; prints the message when it does not hold.
check_binary() {
	local message="$1"
	shift
	if "$@"; then return 0; fi
	printf '\033[31mFAILED\033[0m %s; rerun: ./build.sh test-platforms binaries\n' "$message" >&2
	return 1
}

# The Python symbols a platform's module asks for, all in python3.dll's export list (the stable ABI
# of 3.11: what every Python 3.11+ has, on every platform).
python_symbols_in_stable_abi() {
	local platform="$1" module symbols abi
	module="$(platform_module "$platform")"
	abi="$(sed -n 's/ DATA$//; 3,$p' "$(platform_dir windows_x64)/python3.def")"
	case "$platform" in
	windows_*) symbols="$(windows_python_imports "$module")" ;;
	macos_*) symbols="$(llvm-nm -u "$module" | awk '{ print $NF }' | sed 's/^_//' | grep -E '^_*Py')" ;; # C names take a _ there
	*) symbols="$(llvm-nm -D -u "$module" | awk '{ print $NF }' | sed 's/@.*//' | grep -E '^_*Py')" ;; # stripped: dynamic symbols
	esac
	local outside
	outside="$(comm -23 <(sort -u <<<"$symbols") <(sort -u <<<"$abi"))"
	[ -n "$symbols" ] && [ -z "$outside" ] || { log "$module: outside the stable ABI: ${outside:-no Python symbols at all}"; return 1; }
}

glibc_at_most_2_28() {
	local newest
	newest="$(objdump -T "$1" | grep -o 'GLIBC_[0-9.]*' | sed 's/GLIBC_//' | sort -V | tail -n 1)"
	log "  $1: needs glibc $newest"
	[ "$(printf '%s\n2.28\n' "$newest" | sort -V | tail -n 1)" = 2.28 ]
}

elf_is() {
	local description
	description="$(file -b "$1")"
	[[ "$description" == "ELF 64-bit LSB shared object, $2"* ]] || { log "$1: $description"; return 1; }
}

pe_is_x64_dll_exporting_init() {
	local headers
	headers="$(x86_64-w64-mingw32-objdump -p "$1")"
	grep -q 'file format pei-x86-64' <<<"$headers" && grep -q '(DLL)' <<<"$(file -b "$1")" &&
		[ "$(awk '/\[Ordinal\/Name Pointer\] Table/ { inside = 1; next } inside && NF == 0 { inside = 0 } inside { print $NF }' <<<"$headers")" = PyInit__lvp ] &&
		[ "$(grep 'DLL Name:' <<<"$headers" | awk '{ print $3 }' | sort | tr '\n' ' ')" = "KERNEL32.dll msvcrt.dll python3.dll " ]
}

# macho_is MODULE ARCH MINIMUM: a bundle for that architecture, marked for that macOS, exporting
# _PyInit__lvp alone, loading no library but libSystem. The minimum is LC_BUILD_VERSION's minos, or
# before macOS 10.14 LC_VERSION_MIN_MACOSX's version (the command that such macOS versions read).
macho_is() {
	local module="$1" arch="$2" minimum="$3" headers marked
	headers="$(llvm-objdump --macho --private-headers "$module")"
	marked="$(awk '/cmd LC_BUILD_VERSION/ { build = 1 } build && $1 == "minos" { print $2; exit }
		/cmd LC_VERSION_MIN_MACOSX/ { old = 1 } old && $1 == "version" { print $2; exit }' <<<"$headers")"
	log "  $module: $(file -b "$module"), for macOS $marked and later"
	awk '/^ *MH_MAGIC_64/ { print $2, $5 }' <<<"$headers" | grep -qx "$arch BUNDLE" &&
		[ "$marked" = "$minimum" ] &&
		[ "$(llvm-nm -g --defined-only "$module" | awk '{ print $3 }')" = _PyInit__lvp ] &&
		[ "$(awk '/cmd LC_LOAD_DYLIB/ { getline; getline; print $2 }' <<<"$headers")" = /usr/lib/libSystem.B.dylib ]
}

# The zip of each platform: its manifest declares that platform alone, and it holds that platform's
# module, byte for byte, and no other.
zip_declares_its_platform() {
	local platform="$1" zip manifest modules
	zip="$(platform_zip "$platform")"
	[ -f "$zip" ] || { log "$zip is missing"; return 1; }
	manifest="$(unzip -p "$zip" blender_manifest.toml)"
	modules="$(unzip -Z1 "$zip" | grep -E '^_lvp\.' | tr '\n' ' ')"
	grep -qx "platforms = \[\"$(platform_manifest_name "$platform")\"\]" <<<"$manifest" &&
		[ "$modules" = "$(platform_module_name "$platform") " ] &&
		unzip -p "$zip" "$(platform_module_name "$platform")" | cmp -s - "$(platform_module "$platform")"
}

test_part_binaries() {
	log "the modules' binaries and the zips"
	ensure_packages file unzip
	local failed=0
	check_binary "linux_x64: not an x86-64 ELF" elf_is "$(platform_module linux_x64)" "x86-64" || failed=1
	check_binary "linux_arm64: not an AArch64 ELF" elf_is "$(platform_module linux_arm64)" "ARM aarch64" || failed=1
	for platform in linux_x64 linux_arm64; do
		check_binary "$platform needs a glibc newer than 2.28" glibc_at_most_2_28 "$(platform_module "$platform")" || failed=1
	done
	check_binary "dist/$ADDON_ID/ does not carry the linux_x64 module" \
		cmp -s "$DIST/$ADDON_ID/_lvp.abi3.so" "$(platform_module linux_x64)" || failed=1
	check_binary "windows_x64: not a PE32+ x86-64 DLL exporting PyInit__lvp alone, importing python3.dll, \
KERNEL32.dll and msvcrt.dll only" pe_is_x64_dll_exporting_init "$(platform_module windows_x64)" || failed=1
	check_binary "macos_arm64: not an arm64 bundle for macOS $MACOS_MIN_ARM64 exporting _PyInit__lvp alone" \
		macho_is "$(platform_module macos_arm64)" ARM64 "$MACOS_MIN_ARM64" || failed=1
	check_binary "macos_x64: not an x86-64 bundle for macOS $MACOS_MIN_X64 exporting _PyInit__lvp alone" \
		macho_is "$(platform_module macos_x64)" X86_64 "$MACOS_MIN_X64" || failed=1
	for platform in "${PLATFORMS[@]}"; do
		check_binary "$platform: Python symbols outside the stable ABI" \
			python_symbols_in_stable_abi "$platform" || failed=1
		check_binary "$(platform_zip "$platform"): not its platform's manifest and module" \
			zip_declares_its_platform "$platform" || failed=1
	done
	return $failed
}

# ---- all of them ----------------------------------------------------------------------------------

# PLATFORM_PARTS_FAILED: the parts that failed in the last run_platform_tests.
PLATFORM_PARTS_FAILED=()
# run_platform_tests [PART...]: builds the modules and packages (platforms.sh), then runs the parts
# (all by default), each timed.
run_platform_tests() {
	local parts=("$@") failed=0
	PLATFORM_PARTS_FAILED=()
	[ ${#parts[@]} -gt 0 ] || parts=("${PLATFORM_TEST_PARTS[@]}")
	platform_tests_setup
	build_platform_modules && build_platform_packages || { PLATFORM_PARTS_FAILED+=("building"); return 1; }
	for part in "${parts[@]}"; do
		local started=$SECONDS
		case "$part" in
		binaries) test_part_binaries ;;
		module-linux) test_part_module_linux ;;
		module-windows) test_part_module_windows ;;
		module-arm64) test_part_module_arm64 ;;
		c-windows) test_part_c_windows ;;
		c-arm64) test_part_c_arm64 ;;
		*) die "unknown part '$part' (${PLATFORM_TEST_PARTS[*]})" ;;
		esac || { failed=1; PLATFORM_PARTS_FAILED+=("$part"); }
		log "platforms: $part took $((SECONDS - started)) s"
	done
	return $failed
}
