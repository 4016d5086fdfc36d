#!/usr/bin/env bash
# Fetches the source distribution of python-canopen (a pinned release) from
# PyPI with pip and unpacks it into build/deps/, idempotently. Prints the
# unpacked directory on stdout.
#
# Why: tests need device files and a CANopen implementation this project
# did not write - the sample EDS files inside the sdist (examples/eds/,
# test/) for the DCF/EDS import tests, and the package itself for
# interoperability tests. Third-party files are never committed: they are
# fetched at test set-up time (scripts/deps.sh calls this) or on first use
# by a test.
#
# Usage: scripts/fetch-python-canopen.sh            -> prints the directory
#        PYCANOPEN_VERSION=x.y.z scripts/...        -> another release
set -euo pipefail

version=${PYCANOPEN_VERSION:-2.4.1}
top=$(cd "$(dirname "$0")/.." && pwd)
dest="$top/build/deps/python-canopen"
dir="$dest/canopen-$version"

log() { printf 'fetch-python-canopen: %s\n' "$*" >&2; }
die() { printf 'fetch-python-canopen: error: %s\n' "$*" >&2; exit 1; }

if [ -f "$dir/.complete" ]; then
    echo "$dir"
    exit 0
fi

if ! python3 -m pip --version >/dev/null 2>&1; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    log "installing python3-pip"
    $SUDO apt-get update -qq >/dev/null || true
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends python3-pip >/dev/null \
        || die "python3-pip is not installed and could not be installed"
fi

mkdir -p "$dest"
tmp=$(mktemp -d "$dest/dl.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
log "downloading canopen==$version (source distribution)"
python3 -m pip download -q --no-deps --no-binary :all: \
    -d "$tmp" "canopen==$version" >&2 || die "pip download canopen==$version failed"
sdist=$(ls "$tmp"/canopen-"$version".tar.gz 2>/dev/null | head -1)
[ -n "$sdist" ] || die "no canopen-$version.tar.gz in the download"
rm -rf "$dir"
tar -xzf "$sdist" -C "$dest"
[ -d "$dir" ] || die "the sdist did not unpack to canopen-$version/"
cp "$sdist" "$dest/"
touch "$dir/.complete"
echo "$dir"
