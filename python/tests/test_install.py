# SPDX-License-Identifier: MIT
"""`pip install ./python` into a fresh virtual environment, offline (the
build backend needs nothing from an index), then the installed package
finds libcogw by itself (the build tree it came from) and reads a node."""
from __future__ import annotations

import os
import subprocess
import sys

from conftest import INSTANCE, NODE, TOP


def test_pip_install_into_a_fresh_venv_offline(system, tmp_path):
    venv = tmp_path / "venv"
    base = getattr(sys, "_base_executable", sys.executable)
    # a venv without pip of its own (ensurepip takes minutes in the emulated VM):
    # the test environment's pip installs into it (pip --python)
    subprocess.run([base, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = str(venv / "bin" / "python")
    env = {k: v for k, v in os.environ.items() if k not in ("COGW_LIBRARY", "PYTHONPATH")}
    env.update(PIP_NO_CACHE_DIR="1", PIP_DISABLE_PIP_VERSION_CHECK="1")
    r = subprocess.run([sys.executable, "-m", "pip", "--python", py, "install", "--no-index",
                        os.path.join(TOP, "python")],
                       env=env, capture_output=True, text=True, cwd=str(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    script = ("import cogw, cogw._lib as l\n"
              f"with cogw.connect({INSTANCE!r}) as gw:\n"
              f"    print(cogw.__version__, hex(gw.node({NODE}).sdo[0x1018][1].raw), "
              "l.find_library())\n")
    r = subprocess.run([py, "-c", script], env=env, capture_output=True, text=True,
                       cwd=str(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    with open(os.path.join(TOP, "VERSION")) as f:
        version = f.read().strip()
    got = r.stdout.split()
    assert got[:2] == [version, "0x42"]
    assert got[2] == os.path.join(TOP, "build", "rel", "lib", "libcogw.so.1")
