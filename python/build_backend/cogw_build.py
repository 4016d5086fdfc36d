# SPDX-License-Identifier: MIT
"""The in-tree PEP 517 build backend of the cogw Python package (standard
library only: pip needs nothing from an index to build it).

The version is the project's one version: VERSION at the top of the source
tree when pip builds ./python in place, else (building from an sdist) the
PKG-INFO the sdist carries. The wheel gets cogw/_build_info.py with that
version and the source tree it came from (where libcogw's build tree is,
cogw/_lib.py). The wheel is pure Python (py3-none-any): libcogw is loaded
at run time (docs/python.md "Installing")."""
from __future__ import annotations

import base64
import hashlib
import io
import os
import re
import tarfile
import zipfile

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # python/
TOP = os.path.dirname(HERE)
SRC = os.path.join(HERE, "src")
NAME = "cogw"


def _project() -> dict:
    """pyproject.toml's [project] table (tomllib, or its simple keys on Python < 3.11)."""
    path = os.path.join(HERE, "pyproject.toml")
    try:
        import tomllib
        with open(path, "rb") as f:
            return tomllib.load(f)["project"]
    except ImportError:
        with open(path, encoding="utf-8") as f:
            text = f.read().split("[project]", 1)[1]
        return dict(re.findall(r'^(\w[\w-]*)\s*=\s*"([^"]*)"', text, re.M))


def _version() -> str:
    top_version = os.path.join(TOP, "VERSION")
    if os.path.exists(top_version):
        with open(top_version, encoding="ascii") as f:
            return f.read().strip()
    pkg_info = os.path.join(HERE, "PKG-INFO")
    if os.path.exists(pkg_info):
        with open(pkg_info, encoding="utf-8") as f:
            m = re.search(r"^Version: (\S+)$", f.read(), re.M)
        if m:
            return m.group(1)
    raise RuntimeError("cogw_build: no VERSION above python/ (nor a PKG-INFO): build the "
                       "package from the cogw source tree, e.g. pip install ./python")


def _source_tree() -> str | None:
    return TOP if os.path.exists(os.path.join(TOP, "VERSION")) else None


def _metadata(version: str) -> str:
    p = _project()
    text = (f"Metadata-Version: 2.1\nName: {p['name']}\nVersion: {version}\n"
            f"Summary: {p.get('description', '')}\nLicense: {p.get('license', '')}\n"
            f"Requires-Python: {p.get('requires-python', '')}\n")
    readme = os.path.join(HERE, "README.md")
    if os.path.exists(readme):
        with open(readme, encoding="utf-8") as f:
            text += "Description-Content-Type: text/markdown\n\n" + f.read()
    return text


def _package_files() -> list[tuple[str, bytes]]:
    out = []
    base = os.path.join(SRC, NAME)
    for name in sorted(os.listdir(base)):
        if name.endswith(".py") or name == "py.typed":
            if name == "_build_info.py":
                continue
            with open(os.path.join(base, name), "rb") as f:
                out.append((f"{NAME}/{name}", f.read()))
    return out


def _build_info(version: str) -> bytes:
    return (f'"""Written by the build (python/build_backend/cogw_build.py): do not edit."""\n'
            f"VERSION = {version!r}\nSOURCE_TREE = {_source_tree()!r}\n").encode()


def _dist_info(version: str) -> str:
    return f"{NAME}-{version}.dist-info"


def _dist_info_files(version: str) -> list[tuple[str, bytes]]:
    d = _dist_info(version)
    return [(f"{d}/METADATA", _metadata(version).encode()),
            (f"{d}/WHEEL", b"Wheel-Version: 1.0\nGenerator: cogw_build\nRoot-Is-Purelib: true\n"
                           b"Tag: py3-none-any\n"),
            (f"{d}/top_level.txt", f"{NAME}\n".encode())]


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def _write_wheel(directory: str, files: list[tuple[str, bytes]], version: str) -> str:
    name = f"{NAME}-{version}-py3-none-any.whl"
    record = f"{_dist_info(version)}/RECORD"
    lines = [_record_line(n, d) for n, d in files] + [f"{record},,"]
    with zipfile.ZipFile(os.path.join(directory, name), "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in files:
            z.writestr(zipfile.ZipInfo(n, date_time=(1980, 1, 1, 0, 0, 0)), d)
        z.writestr(zipfile.ZipInfo(record, date_time=(1980, 1, 1, 0, 0, 0)),
                   "\n".join(lines) + "\n")
    return name


# ---- PEP 517 -------------------------------------------------------------------------

def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def get_requires_for_build_editable(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    version = _version()
    for n, d in _dist_info_files(version):
        path = os.path.join(metadata_directory, n)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(d)
    return _dist_info(version)


prepare_metadata_for_build_editable = prepare_metadata_for_build_wheel


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    version = _version()
    files = _package_files() + [(f"{NAME}/_build_info.py", _build_info(version))]
    return _write_wheel(wheel_directory, files + _dist_info_files(version), version)


def build_editable(wheel_directory, config_settings=None, metadata_directory=None):
    """PEP 660: a .pth that puts python/src on the path (the version is then read
    from VERSION, cogw/_version.py)."""
    version = _version()
    files = [(f"__editable__.{NAME}.pth", (SRC + "\n").encode())]
    return _write_wheel(wheel_directory, files + _dist_info_files(version), version)


def build_sdist(sdist_directory, config_settings=None):
    version = _version()
    stem = f"{NAME}-{version}"
    name = f"{stem}.tar.gz"
    members = [("pyproject.toml", None), ("README.md", None),
               ("build_backend/cogw_build.py", None)]
    members += [(f"src/{n}", None) for n, _ in _package_files()]
    with tarfile.open(os.path.join(sdist_directory, name), "w:gz", format=tarfile.PAX_FORMAT) as t:
        for rel, _ in members:
            t.add(os.path.join(HERE, rel), f"{stem}/{rel}")
        info = tarfile.TarInfo(f"{stem}/PKG-INFO")
        data = _metadata(version).encode()
        info.size = len(data)
        t.addfile(info, io.BytesIO(data))
    return name
