# SPDX-License-Identifier: MIT
"""Events the daemon sends (docs/mailbox.md "Events") as Python objects, and
the device values of watched objects. Payloads are decoded with the structs
of mailbox/proto.h (_lib); DEV_VALUE through libcogw's cogw_dev_value_parse."""
from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass, field
from typing import Union

from . import datatypes
from ._lib import (EV, EVC, DevValue, EvEmcy, EvMgr, EvNode, EvOverflow, EvPdo, Msg, PdoValue,
                   lib)

# CiA 301 §7.2.8.3.2 / python-canopen's names of the NMT states a heartbeat reports
NMT_STATES = {0: "INITIALISING", 4: "STOPPED", 5: "OPERATIONAL", 127: "PRE-OPERATIONAL",
              0xFF: "UNKNOWN"}
# NMT commands (CiA 301 §7.2.8.3.1) by the names python-canopen's node.nmt.state takes
NMT_COMMANDS = {"OPERATIONAL": 0x01, "STOPPED": 0x02, "PRE-OPERATIONAL": 0x80,
                "INITIALISING": 0x81, "RESET": 0x81, "RESET COMMUNICATION": 0x82}
# mbx_ev_mgr.state / mbx_mgr_status.state (docs/mailbox.md "Events", manager)
MANAGER_STATES = {0: "slave", 1: "resetting", 2: "booting", 3: "wait-mandatory", 4: "booted",
                  5: "operational", 6: "stopped", 7: "pre-operational", 8: "fatal"}
VIA = {1: "pdo", 2: "sdo"}


@functools.lru_cache(maxsize=None)
def event_name(code: int) -> str:
    return lib.mbx_event_to_string(code).decode()


def classes_mask(classes: tuple[str, ...]) -> int:
    mask = 0
    for c in classes:
        if c not in EVC:
            raise ValueError(f"unknown event class {c!r} (known: {', '.join(EVC)})")
        mask |= EVC[c]
    return mask


@dataclass
class Event:
    """An event of a line: code and name (mbx_event_to_string), the
    correlation id of the request it belongs to (0 = none), events lost
    before it (the daemon's overflow count)."""
    line: int
    code: int
    name: str
    corr: int = 0
    dropped: int = 0
    payload: bytes = b""


@dataclass
class NodeEvent(Event):
    """NMT_STATE, BOOTUP, HB_STARTED, HB_LOST: node and NMT state (and the previous one)."""
    node: int = 0
    state: int = 0
    prev: int = 0

    @property
    def state_name(self) -> str:
        return NMT_STATES.get(self.state, str(self.state))


@dataclass
class EmcyEvent(Event):
    """An EMCY received (CiA 301 §7.2.7): python-canopen's EmcyError fields too."""
    node: int = 0
    code_emcy: int = 0
    register: int = 0
    data: bytes = b""
    ts_us: int = 0


@dataclass
class ManagerEvent(Event):
    """MGR_STATE, MGR_BOOT, MGR_NODE (docs/mailbox.md: the fields of mbx_ev_mgr)."""
    node: int = 0
    state: int = 0
    prev: int = 0
    flags: int = 0
    step: int = 0
    status: str = ""
    what: int = 0
    mandatory: bool = False
    index: int = 0
    sub: int = 0
    done: bool = False
    abort: int = 0
    value: int = 0
    expected: int = 0

    @property
    def state_name(self) -> str:
        return MANAGER_STATES.get(self.state, str(self.state))


@dataclass
class PdoEvent(Event):
    """An RPDO of the line's own node received, with its mapped values."""
    pdo: int = 0
    ts_us: int = 0
    values: list[tuple[int, int, bytes]] = field(default_factory=list)


@dataclass
class DeviceValue(Event):
    """A device object's value (docs/devices.md): from a watch's event or a
    read. via "pdo" (the mirror of the device's TPDO) or "sdo"; seq: per
    watch +1 per event (a gap: values lost); age_ms: of a mirrored value read;
    held: a watch's first value, the one the mirror held when the watch began (its
    frame came before the watch request), not a new one."""
    node: int = 0
    index: int = 0
    sub: int = 0
    type: int = 0
    value: datatypes.Value = 0
    data: bytes = b""
    via: str = ""
    bits: int = 0
    seq: int = 0
    age_ms: int = 0
    time_us: int = 0
    held: bool = False


AnyEvent = Union[Event, NodeEvent, EmcyEvent, ManagerEvent, PdoEvent, DeviceValue]


def _fixed(cls: type, data: bytes):  # the payload's fixed part as a struct
    if len(data) < ctypes.sizeof(cls):
        return None
    return cls.from_buffer_copy(data[:ctypes.sizeof(cls)])


def device_value(payload: Union[bytes, Msg], line: int, code: int = 0, corr: int = 0,
                 dropped: int = 0) -> DeviceValue:
    """A DEV_VALUE event's or a DEV_READ answer's payload (bytes, or the message
    itself: parsed where it lies), parsed by libcogw (cogw_dev_value_parse)."""
    v = DevValue()
    p = ctypes.POINTER(ctypes.c_uint8)()
    if isinstance(payload, Msg):
        where, size, payload = payload.data, payload.len, b""
    else:
        where, size = payload, len(payload)
    if lib.cogw_dev_value_parse(where, size, ctypes.byref(v), ctypes.byref(p)) < 0:
        raise ValueError("malformed device value")
    data = ctypes.string_at(p, v.len) if v.len else b""
    try:
        value = datatypes.decode(v.type, data)
    except ValueError:
        value = data
    return DeviceValue(line, code, event_name(code) if code else "dev-value", corr, dropped,
                       payload, v.node, v.index, v.sub, v.type, value, data,
                       VIA.get(v.via, str(v.via)), v.bits, v.seq, v.age_ms, v.time_us)


def decode(m: Msg) -> AnyEvent:
    """The event in a received message (its payload's size checked by libcogw)."""
    code = m.code
    if code == EV["DEV_VALUE"]:  # the hot path of watches: no copy of the payload
        return device_value(m, m.line, code, m.corr, m.dropped)
    data = ctypes.string_at(m.data, m.len) if m.len else b""
    base = (m.line, code, event_name(code), m.corr, m.dropped, data)
    if code in (EV["NMT_STATE"], EV["BOOTUP"], EV["HB_STARTED"], EV["HB_LOST"]):
        n = _fixed(EvNode, data)
        if n is not None:
            return NodeEvent(*base, n.node, n.state, n.prev)
    elif code == EV["EMCY"]:
        e = _fixed(EvEmcy, data)
        if e is not None:
            return EmcyEvent(*base, e.node, e.code, e.reg, bytes(e.msef), e.ts_us)
    elif code in (EV["MGR_STATE"], EV["MGR_BOOT"], EV["MGR_NODE"]):
        g = _fixed(EvMgr, data)
        if g is not None:
            return ManagerEvent(*base, g.node, g.state, g.prev, g.flags, g.step,
                                g.status.decode("latin-1") if g.status != b"\0" else "", g.what,
                                bool(g.mandatory), g.index, g.sub, bool(g.done), g.abort,
                                g.value, g.expected)
    elif code == EV["PDO"]:
        return _pdo_event(base, data)
    elif code == EV["OVERFLOW"]:
        o = _fixed(EvOverflow, data)
        ev = Event(*base)
        if o is not None:
            ev.dropped = max(ev.dropped, o.dropped_events)
        return ev
    return Event(*base)


def _pdo_event(base: tuple, data: bytes) -> AnyEvent:
    p = _fixed(EvPdo, data)
    if p is None:
        return Event(*base)
    values = []
    off, size = ctypes.sizeof(EvPdo), ctypes.sizeof(PdoValue)
    for _ in range(p.n):
        if off + size > len(data):
            break
        v = PdoValue.from_buffer_copy(data[off:off + size])
        values.append((v.index, v.sub, bytes(v.data[:v.len])))
        off += size
    return PdoEvent(*base, p.pdo, p.ts_us, values)


def payload_of(m: Msg) -> bytes:
    return ctypes.string_at(m.data, m.len) if m.len else b""


