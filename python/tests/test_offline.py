# SPDX-License-Identifier: MIT
"""What needs no daemon: types, EDS names, error names, the library's layouts."""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess

import pytest

import cogw
from cogw import _lib, datatypes, eds
from conftest import TOP, node5_eds


@pytest.mark.parametrize("t,value,raw", [
    ("u8", 200, b"\xc8"), ("i16", -2, b"\xfe\xff"), ("UNSIGNED24", 0xABCDEF, b"\xef\xcd\xab"),
    ("i40", -2, b"\xfe\xff\xff\xff\xff"), ("r32", 1.5, b"\x00\x00\xc0\x3f"),
    ("bool", True, b"\x01"), ("string", "ok", b"ok"), ("domain", b"\x00\x01", b"\x00\x01"),
    (0x07, 0xDEADBEEF, b"\xef\xbe\xad\xde"),
    ("time", datatypes.TimeOfDay(days=14000, ms=3600000), b"\x80\xee\x36\x00\xb0\x36"),
])
def test_types_round_trip(t, value, raw):
    assert datatypes.encode(t, value) == raw
    assert datatypes.decode(t, raw) == value


def test_type_refusals():
    with pytest.raises(ValueError):
        datatypes.encode("u8", 256)
    with pytest.raises(ValueError):
        datatypes.decode("u16", b"\x01")
    with pytest.raises(ValueError):
        datatypes.resolve("u17")


def test_eds_names_types_factor(tmp_path):
    p = tmp_path / "dev.eds"
    p.write_text(node5_eds())
    od = eds.load(str(p))
    assert od["Identity object"].sub_by_name("Vendor-ID").data_type == 0x7
    assert od[0x2000].subs[0].factor == 0.1 and od[0x2000].subs[0].unit == "km/h"
    assert od["Limits"].subs[2].name == "High"
    assert eds.parse_int("$NODEID+0x180", 5) == 0x185


def test_error_names_come_from_libcogw():
    assert cogw.abort_name(0x05040000) == "SDO protocol timed out"
    assert cogw.abort_name(0x0A000001) == "network unknown"
    e = cogw.SdoAbortedError(0x06090011, "x")
    assert e.abort_name == "sub-index does not exist" and e.code == 0x06090011
    assert cogw.status_name(-104)  # COGW_E_AGAIN has a name


def test_version_is_the_projects():
    with open(os.path.join(TOP, "VERSION")) as f:
        assert cogw.__version__ == f.read().strip()


# every struct mirrored in _lib, compared with the header by the C compiler
_STRUCTS = {"Msg": "cogw_msg", "Options": "cogw_options", "SdoOpts": "cogw_sdo_opts",
            "TypeInfo": "cogw_type", "ObjReq": "mbx_obj_req", "SdoReq": "mbx_sdo_req",
            "GwSdoReq": "mbx_gw_sdo_req", "NmtReq": "mbx_nmt_req", "NodeEntry": "mbx_node_entry",
            "MgrNodeReq": "mbx_mgr_node_req", "MgrStatus": "mbx_mgr_status",
            "MgrEmcy": "mbx_mgr_emcy", "MgrNodeDiag": "mbx_mgr_node_diag",
            "MgrProgramReq": "mbx_mgr_program_req", "MgrProgramResp": "mbx_mgr_program_resp",
            "LineStatus": "mbx_line_status", "DevObjReq": "mbx_dev_obj_req",
            "DevWatchReq": "mbx_dev_watch_req", "DevWatchResp": "mbx_dev_watch_resp",
            "DevReadReq": "mbx_dev_read_req", "DevValue": "mbx_dev_value",
            "DevWriteResp": "mbx_dev_write_resp", "EvNode": "mbx_ev_node",
            "EvEmcy": "mbx_ev_emcy", "EvMgr": "mbx_ev_mgr", "EvPdo": "mbx_ev_pdo",
            "PdoValue": "mbx_pdo_value", "EvOverflow": "mbx_ev_overflow", "Stats": "cogw_stats"}


@pytest.mark.skipif(not shutil.which("cc"), reason="no C compiler")
def test_struct_layouts_match_the_header(tmp_path):
    lines = ['#include <stdio.h>', '#include <stddef.h>', '#include "mailbox/cogw.h"',
             "int main(void) {"]
    for c_name in _STRUCTS.values():
        lines.append(f'printf("{c_name} %zu\\n", sizeof({c_name}));')
    for py, c_name in _STRUCTS.items():
        for f, *_ in getattr(_lib, py)._fields_:
            lines.append(f'printf("{c_name}.{f} %zu\\n", offsetof({c_name}, {f}));')
    lines.append("return 0; }")
    src, exe = tmp_path / "layout.c", tmp_path / "layout"
    src.write_text("\n".join(lines))
    subprocess.run(["cc", "-std=gnu11", "-I", TOP, "-o", str(exe), str(src)], check=True)
    want = dict(line.rsplit(" ", 1) for line in
                subprocess.run([str(exe)], capture_output=True, text=True, check=True)
                .stdout.splitlines())
    got = {}
    for py, c_name in _STRUCTS.items():
        cls = getattr(_lib, py)
        got[c_name] = str(ctypes.sizeof(cls))
        for f, *_ in cls._fields_:
            got[f"{c_name}.{f}"] = str(getattr(cls, f).offset)
    assert got == want


def test_subscriptions_are_counted_per_line_and_class():
    from cogw._subs import SubscriptionCount
    s = SubscriptionCount()
    assert s.add(0, 0b11) == 0b11      # both new: subscribe them
    assert s.add(0, 0b01) == 0         # a second user of class 1
    assert s.add(1, 0b01) == 0b01      # another line
    assert s.remove(0, 0b11) == 0b10   # class 1 still has a user
    assert s.remove(0, 0b01) == 0b01
    assert s.remove(0, 0b01) == 0      # nobody left to remove
