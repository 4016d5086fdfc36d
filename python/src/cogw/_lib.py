# SPDX-License-Identifier: MIT
"""libcogw through ctypes: the library found, its functions declared, and
the payload structs of mailbox/proto.h the calls take or answer with.

Everything the package says to the daemon goes through libcogw (mailbox/
cogw.h); the structs below are the public header's layouts, mirrored field
for field (tests/test_layout.py compiles the header and compares every size
and offset). Where the library is looked for: docs/python.md "Installing".
"""
from __future__ import annotations

import ctypes
import ctypes.util
import os
from ctypes import (POINTER, Structure, c_char, c_char_p, c_int, c_size_t,
                    c_uint, c_uint8, c_uint16, c_uint32, c_uint64, c_void_p)

from ._version import SOURCE_TREE

LIBRARY_ENV = "COGW_LIBRARY"
SONAME = "libcogw.so.1"


def _build_tree_candidates() -> list[str]:
    """libcogw.so of the source tree: the one this file lies in (running
    from a checkout), then the one the package was built from."""
    here = os.path.dirname(os.path.abspath(__file__))
    trees = [os.path.normpath(os.path.join(here, "..", "..", ".."))]
    if SOURCE_TREE:
        trees.append(SOURCE_TREE)
    return [os.path.join(t, "build", "rel", "lib", SONAME) for t in trees]


def find_library() -> str:
    """The path (or soname) of the libcogw to load: $COGW_LIBRARY, else the
    build tree's build/rel/lib/libcogw.so.1, else the installed one (the
    system's loader path: make install, the Debian package)."""
    env = os.environ.get(LIBRARY_ENV)
    if env:
        return env
    for path in _build_tree_candidates():
        if os.path.exists(path):
            return path
    return ctypes.util.find_library("cogw") or SONAME


class LibraryNotFound(ImportError):
    pass


def _load() -> ctypes.CDLL:
    where = find_library()
    try:
        return ctypes.CDLL(where)
    except OSError as exc:
        raise LibraryNotFound(
            f"cogw: cannot load libcogw ({where}): {exc}; set {LIBRARY_ENV} to the path of "
            "libcogw.so.1, install it (make install, the Debian package), or build it "
            "(make) in the tree the package came from") from exc


# ---- mailbox/proto.h payloads ---------------------------------------------------------


class Msg(Structure):  # cogw_msg
    _fields_ = [("kind", c_uint8), ("line", c_uint8), ("code", c_uint16), ("status", c_int),
                ("abort", c_uint32), ("corr", c_uint64), ("dropped", c_uint32),
                ("len", c_size_t), ("data", POINTER(c_uint8))]


class Options(Structure):  # cogw_options
    _fields_ = [("instance", c_char_p), ("queue_mode", c_uint), ("resp_depth", c_uint),
                ("event_depth", c_uint), ("msg_size", c_uint), ("timeout_ms", c_uint)]


class SdoOpts(Structure):  # cogw_sdo_opts
    _fields_ = [("mode", c_uint8), ("sdo_timeout_ms", c_uint32)]


class TypeInfo(Structure):  # cogw_type
    _fields_ = [("name", c_char_p), ("cia_name", c_char_p), ("type", c_uint16),
                ("size", c_uint8)]


class ObjReq(Structure):  # mbx_obj_req
    _fields_ = [("index", c_uint16), ("sub", c_uint8), ("flags", c_uint8)]


class SdoReq(Structure):  # mbx_sdo_req
    _fields_ = [("node", c_uint8), ("mode", c_uint8), ("index", c_uint16), ("sub", c_uint8),
                ("pad", c_uint8 * 3), ("timeout_ms", c_uint32), ("size", c_uint32)]


class GwSdoReq(Structure):  # mbx_gw_sdo_req
    _fields_ = [("net", c_uint16), ("pad", c_uint16), ("sdo", SdoReq)]


class NmtReq(Structure):  # mbx_nmt_req
    _fields_ = [("cs", c_uint8), ("node", c_uint8), ("pad", c_uint16)]


class NodeEntry(Structure):  # mbx_node_entry
    _fields_ = [("node", c_uint8), ("nmt_state", c_uint8), ("hb", c_uint8), ("flags", c_uint8),
                ("last_heard_ms", c_uint32), ("bootups", c_uint16), ("last_emcy", c_uint16),
                ("emcy_count", c_uint32)]


class MgrNodeReq(Structure):  # mbx_mgr_node_req
    _fields_ = [("node", c_uint8), ("pad", c_uint8 * 3)]


class MgrBits(Structure):  # mbx_mgr_bits
    _fields_ = [("w", c_uint32 * 4)]


class MgrStatus(Structure):  # mbx_mgr_status
    _fields_ = [("state", c_uint8), ("flags", c_uint8), ("first_error_node", c_uint8),
                ("first_error_status", c_char), ("first_error_code", c_uint32),
                ("nmt_ignored", c_uint32), ("unexpected", c_uint32), ("duplicates", c_uint32),
                ("errctrl_events", c_uint32), ("keep_op_restarts", c_uint32),
                ("network_boots", c_uint32)] + [
                    (n, MgrBits) for n in ("assigned", "present", "booted", "operational",
                                           "stopped", "preop", "mismatch", "errctrl_lost",
                                           "emcy_active")] + [
                    ("node_changes", c_uint32), ("node_changes_refused", c_uint32)]


class MgrEmcy(Structure):  # mbx_mgr_emcy
    _fields_ = [("time_us", c_uint64), ("code", c_uint16), ("reg", c_uint8),
                ("msef", c_uint8 * 5)]


class MgrNodeDiag(Structure):  # mbx_mgr_node_diag
    _fields_ = [("node", c_uint8), ("step", c_uint8), ("status", c_char), ("booted", c_uint8),
                ("booting", c_uint8), ("nmt_state", c_uint8), ("sub", c_uint8),
                ("n_emcy", c_uint8), ("index", c_uint16), ("pad", c_uint16),
                ("assignment", c_uint32), ("abort", c_uint32), ("value", c_uint32),
                ("boot_count", c_uint32), ("fail_count", c_uint32), ("own_id_frames", c_uint32),
                ("boot_time_us", c_uint64), ("emcy", MgrEmcy * 8)]


class MgrProgramReq(Structure):  # mbx_mgr_program_req
    _fields_ = [("node", c_uint8), ("pad", c_uint8 * 3), ("expected", c_uint32),
                ("sdo_timeout_ms", c_uint32)]


class MgrProgramResp(Structure):  # mbx_mgr_program_resp
    _fields_ = [("status", c_char), ("step", c_uint8), ("index", c_uint16), ("sub", c_uint8),
                ("mode", c_uint8), ("pad", c_uint8 * 2), ("abort", c_uint32),
                ("found", c_uint32), ("expected", c_uint32), ("bytes", c_uint32)]


class LineStatus(Structure):  # mbx_line_status
    _fields_ = [("can_state", c_uint8), ("nmt_state", c_uint8), ("node_id", c_uint8),
                ("pad", c_uint8), ("bitrate", c_uint32)] + [
                    (n, c_uint64) for n in ("rx_frames", "tx_frames", "rx_dropped", "tx_failed",
                                            "err_frames", "bus_off_count")] + [
                    ("clients", c_uint32), ("bus_load_permille", c_uint32)]


class DevObjReq(Structure):  # mbx_dev_obj_req
    _fields_ = [("node", c_uint8), ("sub", c_uint8), ("index", c_uint16), ("type", c_uint16),
                ("flags", c_uint16)]


class DevWatchReq(Structure):  # mbx_dev_watch_req
    _fields_ = [("obj", DevObjReq), ("min_interval_ms", c_uint32)]


class DevWatchResp(Structure):  # mbx_dev_watch_resp
    _fields_ = [("type", c_uint16), ("pdo", c_uint16), ("cob_id", c_uint32)]


class DevReadReq(Structure):  # mbx_dev_read_req
    _fields_ = [("obj", DevObjReq), ("max_age_ms", c_uint32)]


class DevValue(Structure):  # mbx_dev_value
    _fields_ = [("node", c_uint8), ("sub", c_uint8), ("index", c_uint16), ("type", c_uint16),
                ("via", c_uint8), ("bits", c_uint8), ("seq", c_uint32), ("age_ms", c_uint32),
                ("time_us", c_uint64), ("len", c_uint32), ("pad", c_uint32)]


class DevWriteResp(Structure):  # mbx_dev_write_resp
    _fields_ = [("via", c_uint8), ("held", c_uint8), ("pdo", c_uint16), ("cob_id", c_uint32)]


class EvNode(Structure):  # mbx_ev_node
    _fields_ = [("node", c_uint8), ("state", c_uint8), ("prev", c_uint8), ("pad", c_uint8)]


class EvEmcy(Structure):  # mbx_ev_emcy
    _fields_ = [("ts_us", c_uint64), ("code", c_uint16), ("node", c_uint8), ("reg", c_uint8),
                ("msef", c_uint8 * 5), ("pad", c_uint8 * 7)]


class EvMgr(Structure):  # mbx_ev_mgr
    _fields_ = [("node", c_uint8), ("state", c_uint8), ("prev", c_uint8), ("flags", c_uint8),
                ("step", c_uint8), ("status", c_char), ("what", c_uint8), ("mandatory", c_uint8),
                ("index", c_uint16), ("sub", c_uint8), ("done", c_uint8), ("abort", c_uint32),
                ("value", c_uint32), ("expected", c_uint32)]


class EvPdo(Structure):  # mbx_ev_pdo
    _fields_ = [("ts_us", c_uint64), ("pdo", c_uint16), ("n", c_uint8), ("pad", c_uint8 * 5)]


class PdoValue(Structure):  # mbx_pdo_value
    _fields_ = [("index", c_uint16), ("sub", c_uint8), ("len", c_uint8), ("data", c_uint8 * 8)]


class EvOverflow(Structure):  # mbx_ev_overflow
    _fields_ = [("dropped_events", c_uint32), ("dropped_responses", c_uint32)]


class Stats(Structure):  # cogw_stats
    _fields_ = [("overflow_flags", c_uint64), ("dropped_reported", c_uint64),
                ("stray_responses", c_uint64), ("async_dropped", c_uint64)]


# ---- constants of mailbox/proto.h -------------------------------------------------------

KIND_RESPONSE = 2
KIND_EVENT = 3

CMD = {
    "SDO_UPLOAD": 0x0201, "SDO_DOWNLOAD": 0x0202, "OD_READ": 0x0101, "OD_WRITE": 0x0102,
    "NMT": 0x0301, "NODE_TABLE": 0x0302, "LINE_STATUS": 0x0801,
    "MGR_STATUS": 0x0A01, "MGR_BOOT": 0x0A02, "MGR_START": 0x0A03, "MGR_NODE_DIAG": 0x0A05,
    "MGR_PROGRAM": 0x0A07, "GW_SDO_UPLOAD": 0x0B02, "GW_SDO_DOWNLOAD": 0x0B03,
    "DEV_WATCH": 0x0C02, "DEV_UNWATCH": 0x0C03, "DEV_READ": 0x0C04, "DEV_WRITE": 0x0C05,
}

EV = {
    "OVERFLOW": 0x0001, "NMT_STATE": 0x0301, "BOOTUP": 0x0302, "HB_STARTED": 0x0303,
    "HB_LOST": 0x0304, "PDO": 0x0401, "EMCY": 0x0501, "MGR_STATE": 0x0A01, "MGR_BOOT": 0x0A02,
    "MGR_NODE": 0x0A03, "DEV_VALUE": 0x0E01,
}

# subscription classes (enum mbx_event_class)
EVC = {
    "nmt": 1 << 0, "hb": 1 << 1, "boot": 1 << 2, "emcy": 1 << 3, "pdo": 1 << 4,
    "sdo": 1 << 5, "can": 1 << 6, "od": 1 << 8, "manager": 1 << 9, "gw": 1 << 10,
    "sync": 1 << 11, "time": 1 << 12, "pdo_fault": 1 << 13, "value": 1 << 14,
}

E_ABORT = -13
E_AGAIN = -104
E_TRUNCATED = -105
E_WOULDBLOCK = -110
MGR_NODE_PROGRAM = 10  # mbx_ev_mgr.what of a program download's progress
DEV_SDO_ONLY = 1


# ---- the functions ---------------------------------------------------------------------

_P = POINTER
_u32p = _P(c_uint32)
_szp = _P(c_size_t)
_h = c_void_p

_SIGNATURES = {
    "cogw_strerror": (c_char_p, [c_int]),
    "sdo_abort_to_string": (c_char_p, [c_uint32]),
    "mbx_event_to_string": (c_char_p, [c_uint]),
    "cogw_open_opts": (c_int, [_P(_h), _P(Options)]),
    "cogw_loop_open": (c_int, [_P(_h), _P(Options)]),
    "cogw_close": (None, [_h]),
    "cogw_od_read": (c_int, [_h, c_uint, c_uint16, c_uint8, c_void_p, c_size_t, _szp, c_uint,
                             _u32p]),
    "cogw_od_write": (c_int, [_h, c_uint, c_uint16, c_uint8, c_void_p, c_size_t, c_uint, _u32p]),
    "cogw_sdo_read_ex": (c_int, [_h, c_uint, c_uint8, c_uint16, c_uint8, _P(SdoOpts), c_void_p,
                                 c_size_t, _szp, c_uint, _u32p]),
    "cogw_sdo_write_ex": (c_int, [_h, c_uint, c_uint8, c_uint16, c_uint8, _P(SdoOpts), c_void_p,
                                  c_size_t, c_uint, _u32p]),
    "cogw_sdo_read_net": (c_int, [_h, c_uint, c_uint16, c_uint8, c_uint16, c_uint8, _P(SdoOpts),
                                  c_void_p, c_size_t, _szp, c_uint, _u32p]),
    "cogw_sdo_write_net": (c_int, [_h, c_uint, c_uint16, c_uint8, c_uint16, c_uint8, _P(SdoOpts),
                                   c_void_p, c_size_t, c_uint, _u32p]),
    "cogw_nmt": (c_int, [_h, c_uint, c_uint8, c_uint8, c_uint]),
    "cogw_node_table": (c_int, [_h, c_uint, _P(NodeEntry), c_size_t, c_uint]),
    "cogw_line_status": (c_int, [_h, c_uint, _P(LineStatus), c_uint]),
    "cogw_mgr_status": (c_int, [_h, c_uint, _P(MgrStatus), c_uint]),
    "cogw_mgr_node_diag": (c_int, [_h, c_uint, c_uint8, _P(MgrNodeDiag), c_uint]),
    "cogw_mgr_boot": (c_int, [_h, c_uint, c_uint8, c_uint]),
    "cogw_mgr_start": (c_int, [_h, c_uint, c_uint]),
    "cogw_dev_watch": (c_int, [_h, c_uint, _P(DevObjReq), c_uint32, _P(DevWatchResp), c_uint,
                               _u32p]),
    "cogw_dev_unwatch": (c_int, [_h, c_uint, _P(DevObjReq), c_uint]),
    "cogw_dev_read": (c_int, [_h, c_uint, _P(DevObjReq), c_uint32, _P(DevValue), c_void_p,
                              c_size_t, _szp, c_uint, _u32p]),
    "cogw_dev_write": (c_int, [_h, c_uint, _P(DevObjReq), c_void_p, c_size_t, _P(DevWriteResp),
                               c_uint, _u32p]),
    "cogw_dev_value_parse": (c_int, [c_void_p, c_size_t, _P(DevValue), _P(_P(c_uint8))]),
    "cogw_type_find": (_P(TypeInfo), [c_char_p]),
    "cogw_type_of": (_P(TypeInfo), [c_uint16]),
    "cogw_type_names": (c_char_p, []),
    "cogw_subscribe": (c_int, [_h, c_uint, c_uint32, c_void_p, c_size_t, c_uint]),
    "cogw_unsubscribe": (c_int, [_h, c_uint, c_uint32, c_uint]),
    "cogw_send_async": (c_int, [_h, c_uint, c_uint16, c_void_p, c_size_t, _P(c_uint64)]),
    "cogw_recv": (c_int, [_h, _P(Msg), c_int]),
    "cogw_msg_release": (None, [_P(Msg)]),
    "cogw_ping": (c_int, [_h, c_uint, c_uint]),
    "cogw_loop_attach": (c_int, [_h, c_uint, c_uint]),
    "cogw_loop_fd": (c_int, [_h]),
    "cogw_loop_send": (c_int, [_h, c_uint, c_uint16, c_void_p, c_size_t, c_uint, _P(c_uint64)]),
    "cogw_loop_cmd_fd": (c_int, [_h, c_uint]),
    "cogw_loop_recv": (c_int, [_h, _P(Msg)]),
    "cogw_loop_timeout_ms": (c_int, [_h]),
    "cogw_loop_tick": (None, [_h]),
    "cogw_get_stats": (None, [_h, _P(Stats)]),
}

lib = _load()
for _name, (_res, _args) in _SIGNATURES.items():
    try:
        _fn = getattr(lib, _name)
    except AttributeError as _exc:
        raise LibraryNotFound(f"cogw: {lib._name} has no {_name}: a libcogw older than this "
                              "package (rebuild it, or point COGW_LIBRARY at a newer one)") from _exc
    _fn.restype = _res
    _fn.argtypes = _args

__all__ = ["lib", "find_library", "LibraryNotFound"]
