#!/usr/bin/env bash
# Creates build/pyenv, a Python virtual environment with the pinned packages
# of tests/interop/requirements.txt (python-canopen and python-can, pytest) from
# PyPI, for the interoperability tests (tests/interop/) and the Python package's
# tests (python/tests, tests/python/run). Idempotent: a second run
# only compares the requirements with what was installed and returns.
# Nothing of it is committed (build/ is ignored). The VM harness sees it,
# since the VM runs this machine's file system read-only.
set -euo pipefail

top=$(cd "$(dirname "$0")/.." && pwd)
venv="$top/build/pyenv"
req="$top/tests/interop/requirements.txt"
py=${PYTHON:-python3}

log() { printf 'pyenv: %s\n' "$*" >&2; }
die() { printf 'pyenv: error: %s\n' "$*" >&2; exit 1; }

if [ -f "$venv/.complete" ] && cmp -s "$req" "$venv/.complete"; then
    exit 0
fi
command -v "$py" >/dev/null || die "no $py (scripts/deps.sh installs python3 and python3-venv)"
rm -rf "$venv"
log "creating $venv"
"$py" -m venv "$venv" || die "$py -m venv failed (Debian: apt-get install python3-venv)"
log "installing $(grep -v '^#' "$req" | tr '\n' ' ')"
"$venv/bin/python" -m pip install -q --disable-pip-version-check --no-input -r "$req" \
    || die "pip install from PyPI failed"
"$venv/bin/python" -c 'import canopen, can, paho.mqtt.client, pytest, socket; socket.AF_CAN' \
    || die "the environment cannot import canopen/can/pytest or has no AF_CAN sockets"
cp "$req" "$venv/.complete"
