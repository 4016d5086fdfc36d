# SPDX-License-Identifier: MIT
"""The package's version: the project's one version (the file VERSION at the
top of the source tree). A built package carries it in _build_info.py,
which the build backend (python/build_backend/cogw_build.py) writes into the
wheel from VERSION; run from a checkout (PYTHONPATH=python/src), it is read
from VERSION itself. SOURCE_TREE: the tree the package came from, where its
libcogw may be (build/rel/lib), or None."""
from __future__ import annotations

import os
from typing import Optional

SOURCE_TREE: Optional[str]
try:
    from ._build_info import SOURCE_TREE, VERSION  # type: ignore[import-not-found]
except ImportError:
    SOURCE_TREE = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                "..", "..", ".."))
    with open(os.path.join(SOURCE_TREE, "VERSION"), encoding="ascii") as _f:
        VERSION = _f.read().strip()

__version__ = VERSION
