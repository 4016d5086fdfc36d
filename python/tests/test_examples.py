# SPDX-License-Identifier: MIT
"""The examples of docs/python.md (the code blocks that begin with
"# example: NAME") run as they are written, against the test's daemon
(COGW_INSTANCE) and node 5 of line 0."""
from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from conftest import INSTANCE, NODE, TOP

DOC = os.path.join(TOP, "docs", "python.md")


def examples():
    with open(DOC, encoding="utf-8") as f:
        text = f.read()
    return re.findall(r"```python\n# example: (\S+)\n(.*?)```", text, re.S)


def test_the_doc_has_examples():
    assert len(examples()) >= 2


@pytest.mark.parametrize("name,code", examples(), ids=[n for n, _ in examples()])
def test_example_runs(system, name, code, tmp_path):
    path = tmp_path / name
    path.write_text(code)
    env = dict(os.environ, COGW_INSTANCE=INSTANCE, COGW_EDS=system.eds[NODE],
               PYTHONPATH=os.path.join(TOP, "python", "src"))
    r = subprocess.run([sys.executable, str(path)], env=env, capture_output=True, text=True,
                       timeout=120, cwd=str(tmp_path))
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.strip(), "the example printed nothing"
