#!/usr/bin/env bash
# tests/blender/blender_chroot.sh - a Blender of a newer Debian release in a debootstrap chroot
# cached outside the repository: 4.3 is Blender 4.3.2 (Debian trixie's `blender`), 5.2 is Blender
# 5.2.2 LTS (Debian sid's).
#
#   tests/blender/blender_chroot.sh VERSION [ensure]    create the chroot when missing or half-built; print its path
#   tests/blender/blender_chroot.sh VERSION run ARGS... run that blender with ARGS inside the chroot
#   tests/blender/blender_chroot.sh VERSION exec CMD... run any command inside the chroot the same way (debugging)
#   tests/blender/blender_chroot.sh VERSION status      say whether the chroot is complete, its size and build time
#   tests/blender/blender_chroot.sh VERSION rebuild     delete it and build it again
#   tests/blender/blender_chroot.sh VERSION remove      delete it
#
# `run` and `exec` see the repository and /tmp at the SAME absolute paths as outside (bind mounts
# in a private mount namespace made with `unshare -m`, so they vanish with the process even when
# it is killed), plus /proc and a private /dev/shm. Extra host directories can be shown the same
# way with LVP_CHROOT_BINDS=/a:/b. The command runs as the calling user (uid:gid), in the calling
# directory when that is visible inside, with the caller's environment less LD_*, XDG_*, Wayland,
# locale variables (LANG=C.UTF-8) and with PATH and HOME of the chroot. DISPLAY is kept: a local X
# server's socket (Xvfb's, for screenshots) is in /tmp, which the chroot sees; drawing a window also
# needs Mesa inside (tests/blender/panel_screenshot.sh installs it).
#
# Environment:
#   LVP_CACHE             cache directory (default ${XDG_CACHE_HOME:-$HOME/.cache}/lvp)
#   LVP_BLENDER43_CHROOT  the 4.3 chroot directory (default $LVP_CACHE/trixie-blender)
#   LVP_BLENDER52_CHROOT  the 5.2 chroot directory (default $LVP_CACHE/sid-blender)
#   LVP_DEBIAN_MIRROR     Debian mirror (default http://deb.debian.org/debian)
#
# Building needs root (sudo is used when not root), debootstrap (installed when missing) and about
# 1.5 GB of disk per chroot; it takes a few minutes. Debian sid moves every day: its Release file
# may be past its Valid-Until date on a mirror (not checked here), and a library renamed mid-
# transition can leave blender unpacked but unconfigured (`apt-get -f install` mends it).
# A lock file next to the chroot keeps two runs from building it at once; the chroot is built in
# DIR.partial, gets a marker file (.lvp-complete, which also records the recipe) and only then is renamed to DIR, so a run that
# was killed half-way leaves nothing that looks complete and the next run starts over.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
# build.sh gives log, die, as_root, ensure_packages and CACHE (one implementation of each).
# shellcheck source=../../build.sh
source "$REPO/build.sh"
log() { printf '\033[1m[blender%s +%ss]\033[0m %s\n' "$BLENDER_VERSION" "$SECONDS" "$*" >&2; }
die() { printf '\033[31m[blender%s] error:\033[0m %s\n' "$BLENDER_VERSION" "$*" >&2; exit 1; }

BLENDER_VERSION="${1:-}"
case "$BLENDER_VERSION" in
4.3)
	SUITE=trixie
	CHROOT="${LVP_BLENDER43_CHROOT:-$CACHE/trixie-blender}"
	# numpy: Blender's FBX and glTF add-ons import it (Blender's own builds bundle it).
	PACKAGES=(blender python3-numpy)
	;;
5.2)
	SUITE=sid
	CHROOT="${LVP_BLENDER52_CHROOT:-$CACHE/sid-blender}"
	# Blender 5.2's extension manager (bl_pkg, which `blender --command extension` needs) imports
	# cattrs and requests, its FBX and glTF add-ons numpy; Blender's own builds bundle them, Debian's
	# package does not depend on them.
	PACKAGES=(blender python3-numpy python3-cattr python3-requests)
	;;
-h | --help | help)
	sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'
	exit 0
	;;
*) die "the first argument is the Blender version: 4.3 or 5.2 (see --help)" ;;
esac
shift
CHROOT="${CHROOT%/}"
MIRROR="${LVP_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
MARKER=.lvp-complete
# Bump when the way the chroot is made changes: a chroot with another recipe is rebuilt.
RECIPE="4 $SUITE minbase ${PACKAGES[*]} no-recommends nodoc mtab"
CHROOT_PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin

is_complete() {
	[ -f "$CHROOT/$MARKER" ] && [ -x "$CHROOT/usr/bin/blender" ] &&
		[ "$(sed -n 's/^recipe=//p' "$CHROOT/$MARKER")" = "$RECIPE" ]
}

# unmount_below DIR: unmounts whatever a killed run may have left mounted under DIR (only
# possible without unshare), deepest first, so that deleting DIR cannot reach into the host.
unmount_below() {
	local dir="$1" mp
	[ -d "$dir" ] || return 0
	dir="$(cd "$dir" && pwd -P)"
	awk -v d="$dir" '$5 == d || index($5, d "/") == 1 { print $5 }' /proc/self/mountinfo | sort -r |
		while IFS= read -r mp; do
			log "unmounting leftover $mp"
			as_root umount -l "$mp" || true
		done
}

remove_dir() {
	local dir="$1"
	[ -e "$dir" ] || return 0
	unmount_below "$dir"
	if awk -v d="$(cd "$dir" && pwd -P)" 'index($5, d "/") == 1 { found = 1 } END { exit !found }' /proc/self/mountinfo; then
		die "something is still mounted under $dir; not deleting it"
	fi
	as_root rm -rf --one-file-system "$dir"
}

# ---- running inside the chroot -------------------------------------------------------------

# private_namespace ARRAY_NAME: sets the array to the command prefix that runs a command in a
# private mount namespace (unshare -m), or to nothing where that is not possible (no unshare, or
# "/" is not a mount point, as inside another chroot): then the mounts are made in the host's
# namespace and the trap in INNER (or debootstrap's own) unmounts them.
PRIVATE_NS=""
private_namespace() {
	if [ -z "$PRIVATE_NS" ]; then
		if [ "${LVP_NO_UNSHARE:-0}" != 1 ] && as_root unshare -m --propagation private -- true 2>/dev/null; then
			PRIVATE_NS=yes
		else
			PRIVATE_NS=no
			log "no private mount namespace (unshare -m): mounting in the host's, unmounted on exit"
		fi
	fi
	if [ "$PRIVATE_NS" = yes ]; then
		eval "$1=(unshare -m --propagation private --)"
	else
		eval "$1=()"
	fi
}

# The script run as root by `unshare -m` (or, without unshare, by plain sh with a trap): mounts,
# then runs the command in the chroot, then unmounts (the trap is what cleans up when mounts
# are not private). Arguments: DIR USERSPEC CWD NBINDS BIND... -- CMD...
# shellcheck disable=SC2016
INNER='
set -eu
dir=$1 userspec=$2 cwd=$3 n=$4
shift 4
mounted=""
cleanup() {
	for m in $mounted; do umount -l "$m" 2>/dev/null || true; done
}
child=""
forward() { [ -n "$child" ] && kill -"$1" "$child" 2>/dev/null || true; }
trap cleanup EXIT
trap "forward TERM" TERM
trap "forward HUP" HUP
trap "forward INT" INT
domount() { # domount TARGET mount-args...
	t=$1; shift
	mount "$@" "$t"
	mounted="$t $mounted"
}
domount "$dir/proc" -t proc proc
domount "$dir/dev/shm" -t tmpfs -o mode=1777,nosuid,nodev shm
while [ "$n" -gt 0 ]; do
	b=$1; shift; n=$((n - 1))
	[ -d "$b" ] || continue
	mkdir -p "$dir$b"
	domount "$dir$b" --rbind "$b"
	mount --make-rslave "$dir$b" 2>/dev/null || true
done
[ "$1" = "--" ] && shift
set -- chroot $userspec "$dir" /bin/sh -c "cd \"\$0\" 2>/dev/null || cd /; exec \"\$@\"" "$cwd" "$@"
exec 3<&0
set +e
"$@" 0<&3 &
child=$!
while :; do
	wait "$child"; rc=$?
	# wait returns >128 when a trapped signal interrupted it; the child may still be running.
	kill -0 "$child" 2>/dev/null || break
done
exit "$rc"
'

# in_chroot AS_CALLER BINDS... -- CMD...: runs CMD inside the chroot (root for building).
in_chroot() {
	local as_caller="$1"
	shift
	local binds=()
	while [ "$1" != "--" ]; do
		binds+=("$1")
		shift
	done
	shift
	local userspec="" home=/root
	if [ "$as_caller" = 1 ] && [ "$(id -u)" != 0 ]; then
		userspec="--userspec=$(id -u):$(id -g)"
		home="/tmp/lvp-blender-chroot-home-$(id -u)"
		mkdir -p "$home"
	fi
	local cwd
	cwd="$(pwd -P)"
	# The caller's environment, less what points into the host system.
	local envs=() kv name
	while IFS= read -r -d '' kv; do
		name="${kv%%=*}"
		case "$name" in
		LD_* | XDG_* | LC_* | LANG | LANGUAGE | WAYLAND_DISPLAY | PATH | HOME | TMPDIR | \
			PWD | OLDPWD | SHLVL | _ | SUDO_* | BASH_FUNC_* | *%%*) ;;
		*) envs+=("$kv") ;;
		esac
	done < <(env -0)
	envs+=("PATH=$CHROOT_PATH" "HOME=$home" "LANG=C.UTF-8")
	local launcher=()
	private_namespace launcher
	local cmd=(env -i "${envs[@]}" "${launcher[@]}" /bin/sh -c "$INNER" blender-chroot
		"$CHROOT" "$userspec" "$cwd" "${#binds[@]}" "${binds[@]}" -- "$@")
	[ "$(id -u)" = 0 ] || cmd=(sudo "${cmd[@]}")
	if [ "${IN_CHROOT_EXEC:-0}" = 1 ]; then
		# No shell left in between: signals (timeout, Ctrl-C) reach the command.
		exec "${cmd[@]}"
	fi
	"${cmd[@]}"
}

# run_in_chroot CMD...: the command as the caller, with the repository, /tmp and
# LVP_CHROOT_BINDS visible at the same paths.
run_in_chroot() {
	ensure_chroot >/dev/null
	local binds=(/tmp) extra
	case "$REPO/" in /tmp/*) ;; *) binds+=("$REPO") ;; esac
	if [ -n "${LVP_CHROOT_BINDS:-}" ]; then
		IFS=: read -r -a extra <<<"$LVP_CHROOT_BINDS"
		binds+=("${extra[@]}")
	fi
	IN_CHROOT_EXEC=1 in_chroot 1 "${binds[@]}" -- "$@"
}

# ---- building ------------------------------------------------------------------------------

build_chroot() {
	local partial="$CHROOT.partial" logfile="$CHROOT.log"
	ensure_packages debootstrap
	local avail_mb
	avail_mb="$(df -Pm "$(dirname "$CHROOT")" | awk 'NR == 2 { print $4 }')"
	[ "${avail_mb:-0}" -ge 2500 ] || die "need about 2.5 GB free in $(dirname "$CHROOT") for the chroot (have ${avail_mb} MB); set LVP_CACHE"
	remove_dir "$partial"
	remove_dir "$CHROOT"
	local start=$SECONDS
	log "creating the Debian $SUITE chroot with blender $BLENDER_VERSION in $CHROOT (log: $logfile)"
	: >"$logfile"
	log "debootstrap --variant=minbase $SUITE ($MIRROR)"
	local launcher=()
	private_namespace launcher
	if ! as_root "${launcher[@]}" debootstrap --variant=minbase "$SUITE" "$partial" "$MIRROR" >>"$logfile" 2>&1; then
		tail -n 30 "$logfile" >&2
		return 1
	fi
	# No documentation, manual pages or translations (about 100 MB less); no daemons started.
	as_root sh -c 'cat >"$1/etc/dpkg/dpkg.cfg.d/01-lvp-nodoc" <<EOF
path-exclude=/usr/share/doc/*
path-exclude=/usr/share/man/*
path-exclude=/usr/share/info/*
path-exclude=/usr/share/locale/*
path-exclude=/usr/share/lintian/*
EOF
printf "#!/bin/sh\nexit 101\n" >"$1/usr/sbin/policy-rc.d"
chmod 755 "$1/usr/sbin/policy-rc.d"
# dpkg without fsync: 2-3 times faster to unpack, and a killed build is thrown away anyway.
echo force-unsafe-io >"$1/etc/dpkg/dpkg.cfg.d/02-lvp-unsafe-io"
printf "Acquire::Retries \"5\";\nAcquire::Check-Valid-Until \"false\";\n" >"$1/etc/apt/apt.conf.d/80-lvp-retries"
# Blender lists mounted file systems through /etc/mtab.
ln -sf ../proc/self/mounts "$1/etc/mtab"
cp -L /etc/resolv.conf "$1/etc/resolv.conf" 2>/dev/null || true' sh "$partial"
	log "apt-get install --no-install-recommends ${PACKAGES[*]}"
	local saved="$CHROOT"
	CHROOT="$partial"
	if ! in_chroot 0 -- env DEBIAN_FRONTEND=noninteractive sh -c \
		'apt-get update -q && { apt-get install -y -q --no-install-recommends "$@" || apt-get -f install -y -q; } && apt-get -f install -y -q && apt-get clean' \
		sh "${PACKAGES[@]}" >>"$logfile" 2>&1; then
		CHROOT="$saved"
		tail -n 30 "$logfile" >&2
		return 1
	fi
	local version
	version="$(in_chroot 0 -- blender -b --factory-startup -noaudio --version 2>/dev/null | sed -n 's/^Blender \([0-9.]*\).*/\1/p' | head -n 1)"
	CHROOT="$saved"
	[ -n "$version" ] || {
		tail -n 30 "$logfile" >&2
		die "blender does not start inside $partial"
	}
	local seconds=$((SECONDS - start)) size
	size="$(as_root du -sxh "$partial" | cut -f1)"
	as_root sh -c 'printf "%s\n" "$2" >"$1"' sh "$partial/$MARKER" \
		"recipe=$RECIPE
blender=$version
built=$(date -u +%Y-%m-%dT%H:%M:%SZ)
seconds=$seconds
size=$size
mirror=$MIRROR"
	as_root mv -T "$partial" "$CHROOT"
	log "Blender $version ready in $CHROOT: built in ${seconds}s, $size"
}

# lock / unlock: one run at a time may build or delete the chroot (flock on DIR.lock).
lock() {
	mkdir -p "$(dirname "$CHROOT")" 2>/dev/null || as_root mkdir -p "$(dirname "$CHROOT")"
	local lockfile="$CHROOT.lock"
	exec 9>>"$lockfile" || die "cannot open the lock file $lockfile"
	if ! flock -n 9; then
		log "another run is building $CHROOT; waiting for it"
		flock 9
	fi
}
unlock() {
	flock -u 9
	exec 9>&-
}

ensure_chroot() {
	if is_complete; then
		printf '%s\n' "$CHROOT"
		return 0
	fi
	lock
	if ! is_complete; then
		if [ -e "$CHROOT" ]; then
			log "$CHROOT is incomplete or from an older recipe: rebuilding it"
		fi
		# In a subshell outside any condition, so that set -e applies inside build_chroot.
		local rc
		set +e
		(set -e; build_chroot)
		rc=$?
		if [ "$rc" != 0 ]; then
			log "building the chroot failed; retrying once"
			(set -e; build_chroot)
			rc=$?
		fi
		set -e
		[ "$rc" = 0 ] || die "could not build the Blender $BLENDER_VERSION chroot (see $CHROOT.log)"
	fi
	unlock
	printf '%s\n' "$CHROOT"
}

status() {
	if is_complete; then
		echo "complete: $CHROOT"
		cat "$CHROOT/$MARKER"
	elif [ -e "$CHROOT" ] || [ -e "$CHROOT.partial" ]; then
		echo "incomplete: $CHROOT (the next run rebuilds it)"
		return 1
	else
		echo "missing: $CHROOT"
		return 1
	fi
}

blender_chroot_main() {
	local command="${1:-ensure}"
	shift || true
	case "$command" in
	ensure) ensure_chroot ;;
	run) run_in_chroot blender "$@" ;;
	exec)
		[ $# -gt 0 ] || die "usage: $0 exec COMMAND [ARGS...]"
		run_in_chroot "$@"
		;;
	status) status ;;
	rebuild)
		lock
		remove_dir "$CHROOT"
		unlock
		ensure_chroot
		;;
	remove)
		lock
		remove_dir "$CHROOT.partial"
		remove_dir "$CHROOT"
		unlock
		;;
	*) die "unknown command '$command' (ensure, run, exec, status, rebuild, remove)" ;;
	esac
}

if [ "${BASH_SOURCE[0]}" = "$0" ]; then blender_chroot_main "$@"; fi
