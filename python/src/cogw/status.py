# SPDX-License-Identifier: MIT
"""What the daemon answers about lines, nodes, the manager and program
updates, as dataclasses (the fields of mailbox/proto.h's structs; their
meaning: docs/mailbox.md)."""
from __future__ import annotations

import ctypes
from dataclasses import dataclass, field

from ._lib import (LineStatus, MgrBits, MgrNodeDiag, MgrProgramReq, MgrProgramResp, MgrStatus,
                   NodeEntry)
from .errors import CogwError, abort_name, check
from .events import MANAGER_STATES, NMT_STATES

HB_STATES = {0: "not monitored", 1: "active", 2: "lost", 3: "waiting"}


@dataclass
class NodeInfo:
    """A row of the line's node table."""
    node: int
    nmt_state: int
    hb: int
    bootup_seen: bool
    emcy_active: bool
    duplicate: bool
    last_heard_ms: int  # None when never heard
    bootups: int
    last_emcy: int
    emcy_count: int

    @property
    def state_name(self) -> str:
        return NMT_STATES.get(self.nmt_state, str(self.nmt_state))

    @property
    def hb_name(self) -> str:
        return HB_STATES.get(self.hb, str(self.hb))


def node_info(e: NodeEntry) -> NodeInfo:
    return NodeInfo(e.node, e.nmt_state, e.hb, bool(e.flags & 1), bool(e.flags & 2),
                    bool(e.flags & 4), None if e.last_heard_ms == 0xFFFFFFFF else e.last_heard_ms,
                    e.bootups, e.last_emcy, e.emcy_count)


@dataclass
class LineInfo:
    can_state: int
    nmt_state: int
    node_id: int
    bitrate: int
    rx_frames: int
    tx_frames: int
    rx_dropped: int
    tx_failed: int
    err_frames: int
    bus_off_count: int
    clients: int
    bus_load_permille: int


def line_info(s: LineStatus) -> LineInfo:
    return LineInfo(s.can_state, s.nmt_state, s.node_id, s.bitrate, s.rx_frames, s.tx_frames,
                    s.rx_dropped, s.tx_failed, s.err_frames, s.bus_off_count, s.clients,
                    s.bus_load_permille)


def _letter(c: bytes) -> str:
    """A char field: a boot status letter, "" for none."""
    return c.decode("latin-1").strip("\0")


def _nodes(bits: MgrBits) -> set[int]:
    return {n for n in range(128) if bits.w[n // 32] >> (n % 32) & 1}


@dataclass
class ManagerStatus:
    """The line's CiA 302-2 manager: state, flags, node sets, first error, counters."""
    state: int
    flags: int
    first_error_node: int
    first_error_status: str
    first_error_code: int
    counters: dict[str, int] = field(default_factory=dict)
    nodes: dict[str, set[int]] = field(default_factory=dict)

    @property
    def state_name(self) -> str:
        return MANAGER_STATES.get(self.state, str(self.state))


_MGR_COUNTERS = ("nmt_ignored", "unexpected", "duplicates", "errctrl_events", "keep_op_restarts",
                 "network_boots", "node_changes", "node_changes_refused")
_MGR_SETS = ("assigned", "present", "booted", "operational", "stopped", "preop", "mismatch",
             "errctrl_lost", "emcy_active")


def manager_status(s: MgrStatus) -> ManagerStatus:
    return ManagerStatus(s.state, s.flags, s.first_error_node,
                         _letter(s.first_error_status),
                         s.first_error_code, {k: getattr(s, k) for k in _MGR_COUNTERS},
                         {k: _nodes(getattr(s, k)) for k in _MGR_SETS})


@dataclass
class NodeDiag:
    node: int
    booted: bool
    booting: bool
    status: str  # CiA 302-2 boot status letter of the last failure, "" = none
    step: int
    index: int
    sub: int
    abort: int
    value: int
    boot_count: int
    fail_count: int
    boot_time_us: int
    nmt_state: int
    emcys: list[tuple[int, int, int, bytes]]  # time_us, code, register, data


def node_diag(d: MgrNodeDiag) -> NodeDiag:
    return NodeDiag(d.node, bool(d.booted), bool(d.booting),
                    _letter(d.status), d.step, d.index, d.sub,
                    d.abort, d.value, d.boot_count, d.fail_count, d.boot_time_us, d.nmt_state,
                    [(e.time_us, e.code, e.reg, bytes(e.msef)) for e in d.emcy[:d.n_emcy]])


@dataclass
class WriteResult:
    """How a device object was written: via "pdo" (the device's RPDO; held: not
    sent until every object of that RPDO has a value) or "sdo"."""
    via: str
    held: bool
    pdo: int
    cob_id: int


@dataclass
class ProgramResult:
    """A program update that ran to its end, verified."""
    node: int
    bytes: int
    mode: int  # the SDO mode the image went by (3 block, 2 segmented)
    found: int  # 1F56h:1 read after the start
    expected: int


class ProgramError(CogwError):
    """The update failed (boot status I): at which step and object, and why."""

    def __init__(self, node: int, r: MgrProgramResp):
        self.node, self.step, self.index, self.sub = node, r.step, r.index, r.sub
        self.abort, self.found, self.expected = r.abort, r.found, r.expected
        why = (f"SDO abort 0x{r.abort:08X} ({abort_name(r.abort)})" if r.abort else
               f"1F56h:1 is 0x{r.found:08X}, expected 0x{r.expected:08X}")
        super().__init__(-13 if r.abort else -14,
                         f"program node {node}: step {r.step} at {r.index:04X}:{r.sub:02X}: "
                         f"{why}")


def program_request(node: int, expected: int, sdo_timeout_ms: int, image: bytes) -> bytes:
    return bytes(MgrProgramReq(node, (ctypes.c_uint8 * 3)(), expected, sdo_timeout_ms)) + \
        bytes(image)


def program_result(status: int, abort: int, data: bytes, node: int) -> ProgramResult:
    check(status, f"program node {node}", abort)
    if len(data) < ctypes.sizeof(MgrProgramResp):
        raise CogwError(-107, f"program node {node}: a short answer")
    r = MgrProgramResp.from_buffer_copy(data[:ctypes.sizeof(MgrProgramResp)])
    if r.status != b"\0":
        raise ProgramError(node, r)
    return ProgramResult(node, r.bytes, r.mode, r.found, r.expected)
