# SPDX-License-Identifier: MIT
"""The blocking API: a connection to a cogwd instance (a libcogw handle),
its lines, the nodes on them. Every call is one libcogw call (mailbox/
cogw.h); ctypes lets other Python threads run while it waits.

    with cogw.connect("main") as gw:
        node = gw.node(5, line=0, od="device.eds")
        node.sdo["Producer heartbeat time"].raw = 1000
        print(node.sdo[0x1018][1].raw)
"""
from __future__ import annotations

import ctypes
import threading
import time
from typing import Any, Callable, Iterator, Optional, Union

from . import datatypes, eds, events
from ._events_sync import Pump, Response, Sink
from ._subs import SubscriptionCount
from ._lib import (CMD, DEV_SDO_ONLY, E_TRUNCATED, EV, EVC, MGR_NODE_PROGRAM, DevObjReq,
                   DevValue, DevWatchResp, DevWriteResp, LineStatus, MgrNodeDiag, MgrStatus,
                   NodeEntry, Options, SdoOpts, lib)
from .datatypes import TypeLike
from .errors import CogwError, check
from .events import NMT_COMMANDS, NMT_STATES
from .objects import Dictionary, SdoVariable
from .status import (LineInfo, ManagerStatus, NodeDiag, NodeInfo, ProgramResult, WriteResult,
                     line_info, manager_status, node_diag, node_info, program_request,
                     program_result)

ODLike = Union[None, str, eds.ObjectDictionary]
READ_CAP = 1 << 20  # the daemon's default transfer limit (mailbox.max_transfer)


def _od(od: ODLike) -> Optional[eds.ObjectDictionary]:
    return eds.load(od) if isinstance(od, str) else od


def _sdo_opts(mode: int, sdo_timeout_ms: int) -> Optional[SdoOpts]:
    return SdoOpts(mode, sdo_timeout_ms) if (mode or sdo_timeout_ms) else None


def _obj_req(node: int, index: int, sub: int, type_: Optional[TypeLike], sdo_only: bool):
    t = datatypes.resolve(type_).type if type_ is not None else 0
    return DevObjReq(node, sub, index, t, DEV_SDO_ONLY if sdo_only else 0)


class Connection:
    """One libcogw handle on a daemon instance. Thread-safe: several threads may
    call at once. Close it (or use `with`): its queues go with it. A read takes
    up to max_transfer bytes (the daemon's default mailbox.max_transfer; each
    thread that reads has a buffer of that size)."""

    def __init__(self, instance: str = "main", timeout_ms: int = 0, resp_depth: int = 0,
                 event_depth: int = 0, max_transfer: int = READ_CAP):
        self.instance = instance
        self.timeout_ms = timeout_ms
        self.max_transfer = max_transfer  # the largest value a read takes (bytes)
        self._h = ctypes.c_void_p()
        opts = Options(instance.encode(), 0, resp_depth, event_depth, 0, timeout_ms)
        check(lib.cogw_open_opts(ctypes.byref(self._h), ctypes.byref(opts)),
              f"connect to cogwd instance {instance!r}")
        self._pump = Pump(self._h)
        self._tls = threading.local()
        self._subs = SubscriptionCount()
        self._subs_lock = threading.Lock()

    # -- life
    def close(self) -> None:
        if self._h:
            self._pump.stop()
            lib.cogw_close(self._h)
            self._h = ctypes.c_void_p()

    def __enter__(self) -> "Connection":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    # -- what it reaches
    def line(self, number: int) -> "Line":
        return Line(self, number)

    def node(self, node_id: int, line: int = 0, od: ODLike = None,
             network: Optional[int] = None) -> "Node":
        """Node node_id on `line`, or (network given) on CiA 302-7 network
        `network`, reached through `line`'s routing table (docs/gateway.md)."""
        return Node(self, line, node_id, _od(od), network)

    # -- plumbing
    def _buf(self) -> ctypes.Array:
        b = getattr(self._tls, "buf", None)
        if b is None:
            b = self._tls.buf = ctypes.create_string_buffer(self.max_transfer)
        return b

    def _read(self, what: str, call: Callable[..., int], *args: Any) -> bytes:
        """A call that fills a buffer (…, buf, cap, &len, timeout, &abort)."""
        buf, n, ab = self._buf(), ctypes.c_size_t(), ctypes.c_uint32()
        rc = call(self._h, *args, buf, len(buf), ctypes.byref(n), self.timeout_ms,
                  ctypes.byref(ab))
        if rc == E_TRUNCATED:
            raise CogwError(rc, f"{what}: {n.value} bytes, more than {len(buf)}")
        check(rc, what, ab.value)
        return ctypes.string_at(buf, n.value)

    def _write(self, what: str, call: Callable[..., int], *args: Any, data: bytes) -> None:
        ab = ctypes.c_uint32()
        check(call(self._h, *args, data, len(data), self.timeout_ms, ctypes.byref(ab)), what,
              ab.value)

    def subscribe(self, line: int, mask: int) -> None:
        """Count a user of each class of mask; subscribe what was not yet."""
        with self._subs_lock:
            new = self._subs.add(line, mask)
            if new:
                check(lib.cogw_subscribe(self._h, line, new, None, 0, self.timeout_ms),
                      f"subscribe line {line}")

    def unsubscribe(self, line: int, mask: int) -> None:
        with self._subs_lock:
            gone = self._subs.remove(line, mask)
            if gone and self._h:
                lib.cogw_unsubscribe(self._h, line, gone, self.timeout_ms)


class Events:
    """Events of a line as an iterator (for ev in stream) or one by one
    (stream.get(timeout)); close() (or `with`) unsubscribes."""

    def __init__(self, conn: Connection, line: int, mask: int, match: Callable[[Any], bool],
                 callback: Optional[Callable[[Any], None]] = None):
        self._conn, self._line, self._mask = conn, line, mask
        conn.subscribe(line, mask)
        self._sink = conn._pump.add(Sink(match, callback))

    def get(self, timeout: Optional[float] = None) -> Optional[events.AnyEvent]:
        """The next event, or None after timeout seconds (None: wait for ever)."""
        return self._conn._pump.get(self._sink, timeout)

    def __iter__(self) -> Iterator[events.AnyEvent]:
        while True:
            ev = self.get(None)
            if ev is not None:
                yield ev

    def close(self) -> None:
        self._conn._pump.remove(self._sink)
        self._conn.unsubscribe(self._line, self._mask)

    def __enter__(self) -> "Events":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _event_match(line: int, codes: Optional[set[int]], node: Optional[int]):
    def match(ev: Any) -> bool:
        return (not isinstance(ev, Response) and ev.line == line and
                (codes is None or ev.code in codes) and
                (node is None or getattr(ev, "node", None) == node))
    return match


class _OdAccess:
    """The daemon's own object dictionary of a line."""

    def __init__(self, conn: Connection, line: int):
        self.conn, self.line = conn, line
        self.label = f"line {line} OD"

    def upload(self, index: int, sub: int) -> bytes:
        return self.conn._read(f"{self.label} {index:04X}:{sub:02X}", lib.cogw_od_read,
                               self.line, index, sub)

    def download(self, index: int, sub: int, data: bytes) -> None:
        self.conn._write(f"{self.label} {index:04X}:{sub:02X}", lib.cogw_od_write, self.line,
                         index, sub, data=data)


class Line:
    """A CAN line of the daemon (0-based, as in its configuration)."""

    def __init__(self, conn: Connection, number: int):
        self.conn = conn
        self.number = number
        self.od = Dictionary(_OdAccess(conn, number), None, SdoVariable)
        self.manager = Manager(self)

    def node(self, node_id: int, od: ODLike = None, network: Optional[int] = None) -> "Node":
        return self.conn.node(node_id, self.number, od, network)

    def status(self) -> LineInfo:
        st = LineStatus()
        check(lib.cogw_line_status(self.conn._h, self.number, ctypes.byref(st),
                                   self.conn.timeout_ms), f"line {self.number} status")
        return line_info(st)

    def nodes(self) -> list[NodeInfo]:
        """The line's node table (every node heard of or supervised)."""
        tab = (NodeEntry * 127)()
        n = check(lib.cogw_node_table(self.conn._h, self.number, tab, 127,
                                      self.conn.timeout_ms), f"line {self.number} node table")
        return [node_info(tab[i]) for i in range(min(n, 127))]

    def nmt(self, command: Union[int, str], node: int = 0) -> None:
        """An NMT command (a name of python-canopen's or the CiA 301 cs) to
        node, 0 = all nodes."""
        cs = NMT_COMMANDS[command] if isinstance(command, str) else command
        check(lib.cogw_nmt(self.conn._h, self.number, cs, node, self.conn.timeout_ms),
              f"line {self.number} NMT {command} node {node}")

    def events(self, *classes: str, node: Optional[int] = None) -> Events:
        """The events of these classes (nmt, hb, boot, emcy, pdo, manager, ...)."""
        mask = events.classes_mask(classes)
        return Events(self.conn, self.number, mask, _event_match(self.number, None, node))

    def add_callback(self, callback: Callable[[Any], None], *classes: str,
                     node: Optional[int] = None) -> Events:
        """callback(event) for each event of these classes, from the connection's
        event thread; close() the result to stop."""
        mask = events.classes_mask(classes)
        return Events(self.conn, self.number, mask, _event_match(self.number, None, node),
                      callback)


class Manager:
    """The line's CiA 302-2 manager (the line needs a manager section)."""

    def __init__(self, line: Line):
        self._line = line

    def status(self) -> ManagerStatus:
        st = MgrStatus()
        check(lib.cogw_mgr_status(self._line.conn._h, self._line.number, ctypes.byref(st),
                                  self._line.conn.timeout_ms), "manager status")
        return manager_status(st)

    def boot(self, node: int = 0) -> None:
        """Boot node again (CiA 302-2 boot slave process), or the whole network (0)."""
        check(lib.cogw_mgr_boot(self._line.conn._h, self._line.number, node,
                                self._line.conn.timeout_ms), f"manager boot {node}")

    def start(self) -> None:
        check(lib.cogw_mgr_start(self._line.conn._h, self._line.number,
                                 self._line.conn.timeout_ms), "manager start")

    def node_diag(self, node: int) -> NodeDiag:
        d = MgrNodeDiag()
        check(lib.cogw_mgr_node_diag(self._line.conn._h, self._line.number, node,
                                     ctypes.byref(d), self._line.conn.timeout_ms),
              f"manager diag {node}")
        return node_diag(d)


class _SdoAccess:
    def __init__(self, node: "Node"):
        self.node = node
        self.mode = 0
        self.sdo_timeout_ms = 0
        net = f" network {node.network}" if node.network is not None else ""
        self.label = f"line {node.line}{net} node {node.id}"

    def upload(self, index: int, sub: int) -> bytes:
        n, o = self.node, _sdo_opts(self.mode, self.sdo_timeout_ms)
        what = f"{self.label} SDO upload {index:04X}:{sub:02X}"
        if n.network is None:
            return n.conn._read(what, lib.cogw_sdo_read_ex, n.line, n.id, index, sub, o)
        return n.conn._read(what, lib.cogw_sdo_read_net, n.line, n.network, n.id, index, sub, o)

    def download(self, index: int, sub: int, data: bytes) -> None:
        n, o = self.node, _sdo_opts(self.mode, self.sdo_timeout_ms)
        what = f"{self.label} SDO download {index:04X}:{sub:02X}"
        if n.network is None:
            n.conn._write(what, lib.cogw_sdo_write_ex, n.line, n.id, index, sub, o, data=data)
        else:
            n.conn._write(what, lib.cogw_sdo_write_net, n.line, n.network, n.id, index, sub, o,
                          data=data)


class SdoClient(Dictionary):
    """node.sdo: objects by index or name; upload/download as python-canopen's."""

    def __init__(self, node: "Node"):
        super().__init__(_SdoAccess(node), node.od, SdoVariable)

    @property
    def mode(self) -> int:
        """0 auto, 1 expedited, 2 segmented, 3 block."""
        return self.access.mode

    @mode.setter
    def mode(self, value: int) -> None:
        self.access.mode = value

    def upload(self, index: int, subindex: int) -> bytes:
        return self.access.upload(index, subindex)

    def download(self, index: int, subindex: int, data: bytes) -> None:
        self.access.download(index, subindex, bytes(data))

    def read(self, index: int, subindex: int, type: TypeLike) -> datatypes.Value:  # noqa: A002
        """A value of CiA type `type` ("u32", "UNSIGNED32", 7)."""
        return datatypes.decode(type, self.upload(index, subindex))

    def write(self, index: int, subindex: int, value: datatypes.Value,
              type: TypeLike) -> None:  # noqa: A002
        self.download(index, subindex, datatypes.encode(type, value))


class NodeEvents:
    """A node's events of some classes (codes: all of them when None), as a
    stream or callbacks; the node's connection says which kind of stream
    (Events, or aio.AsyncEvents)."""
    CLASSES: tuple[str, ...] = ()
    CODES: Optional[set[int]] = None

    def __init__(self, node: Any):
        self._node = node

    def _stream(self, callback: Optional[Callable[[Any], None]]) -> Any:
        n = self._node
        return n.events_cls(n.conn, n.line, events.classes_mask(self.CLASSES),
                            _event_match(n.line, self.CODES, n.id), callback)

    def events(self) -> Any:
        return self._stream(None)

    def add_callback(self, callback: Callable[[Any], None]) -> Any:
        """callback(event) for each of the node's events (close() the result to stop)."""
        return self._stream(callback)


class Emcy(NodeEvents):
    """node.emcy: the node's EMCYs (EmcyEvent) as callbacks or a stream."""
    CLASSES = ("emcy",)
    CODES = {EV["EMCY"]}


class Nmt(NodeEvents):
    """node.nmt: python-canopen's state property, commands, heartbeat waits; its
    events (NodeEvent: NMT state changes, boot-up, heartbeat started/lost)."""
    CLASSES = ("nmt", "boot", "hb")

    def send_command(self, code: int) -> None:
        Line(self._node.conn, self._node.line).nmt(code, self._node.id)

    @property
    def state(self) -> str:
        """The node's NMT state as the line last heard it (node table)."""
        for e in Line(self._node.conn, self._node.line).nodes():
            if e.node == self._node.id:
                return e.state_name
        return "UNKNOWN"

    @state.setter
    def state(self, new: str) -> None:
        self.send_command(NMT_COMMANDS[new])

    def _wait(self, codes: set[int], klass: str, timeout: float) -> Optional[events.NodeEvent]:
        n = self._node
        with Events(n.conn, n.line, EVC[klass], _event_match(n.line, codes, n.id)) as ev:
            return ev.get(timeout)  # type: ignore[return-value]

    def wait_for_bootup(self, timeout: float = 10) -> None:
        if self._wait({EV["BOOTUP"]}, "boot", timeout) is None:
            raise CogwError(-12, f"no boot-up of node {self._node.id} in {timeout} s")

    def wait_for_state(self, timeout: float = 10) -> str:
        """The next NMT state change of the node (its name)."""
        ev = self._wait({EV["NMT_STATE"]}, "nmt", timeout)
        if ev is None:
            raise CogwError(-12, f"no NMT state of node {self._node.id} in {timeout} s")
        return NMT_STATES.get(ev.state, str(ev.state))


def resolve_obj(node: Any, index: Union[int, str], sub: Union[int, str],
                type_: Optional[TypeLike]) -> tuple[int, int, Optional[TypeLike]]:
    """index:sub of a device object given by number or by the EDS's names; its type
    from the EDS unless given."""
    if isinstance(index, str) or isinstance(sub, str):
        var = node.sdo[index][sub]
        return var.index, var.subindex, type_ if type_ is not None else var.data_type
    return index, sub, type_  # type: ignore[return-value]


def dev_encode(type_: Optional[TypeLike], value: datatypes.Value, what: str) -> bytes:
    if type_ is not None:
        return datatypes.encode(type_, value)
    if isinstance(value, (bytes, bytearray)):
        return bytes(value)
    raise TypeError(f"{what}: give the object's type (node.obj(..., type='u16')) or bytes")


class Node:
    """A node of a line (or of a network behind it)."""
    events_cls = Events

    def __init__(self, conn: Connection, line: int, node_id: int,
                 od: Optional[eds.ObjectDictionary], network: Optional[int] = None):
        self.conn = conn
        self.line = line
        self.id = node_id
        self.od = od
        self.network = network
        self.sdo = SdoClient(self)
        self.nmt = Nmt(self)
        self.emcy = Emcy(self)

    @property
    def object_dictionary(self) -> Optional[eds.ObjectDictionary]:
        return self.od

    def obj(self, index: Union[int, str], sub: Union[int, str] = 0,
            type: Optional[TypeLike] = None) -> "DeviceObject":  # noqa: A002
        """A device object (docs/devices.md): read, written and watched through the
        daemon's mirror of the node's PDOs, or by SDO, as the daemon decides."""
        if self.network is not None:
            raise CogwError(-15, "device objects are the line's own nodes")
        return DeviceObject(self, *resolve_obj(self, index, sub, type))

    def program(self, image: bytes, expected: int = 0, sdo_timeout_ms: int = 0,
                progress: Optional[Callable[[int, int], None]] = None,
                timeout: float = 60.0) -> ProgramResult:
        """Update the node's program (CiA 302-3 by the line's manager, 1F50h..1F56h):
        progress(bytes_sent, image_size) as it goes. timeout (s) counts from the
        last progress. A failed update raises ProgramError."""
        c, line = self.conn, self.line
        payload = program_request(self.id, expected, sdo_timeout_ms, image)
        c.subscribe(line, EVC["manager"])
        corr = ctypes.c_uint64()
        box: dict[str, int] = {}

        def mine(item: Any) -> bool:
            return item.corr == box.get("corr", -1) and (
                isinstance(item, Response) or
                (item.code == EV["MGR_NODE"] and getattr(item, "what", -1) == MGR_NODE_PROGRAM))
        sink = c._pump.add(Sink(mine))
        try:
            check(lib.cogw_send_async(c._h, line, CMD["MGR_PROGRAM"], payload, len(payload),
                                      ctypes.byref(corr)), f"program node {self.id}")
            box["corr"] = corr.value
            while True:
                item = c._pump.get(sink, timeout)
                if item is None:
                    raise CogwError(-12, f"program node {self.id}: no progress in {timeout} s")
                if isinstance(item, Response):
                    return program_result(item.status, item.abort, item.data, self.id)
                if progress is not None:
                    progress(item.value, item.expected)
        finally:
            c._pump.remove(sink)
            c.unsubscribe(line, EVC["manager"])


class DeviceObject:
    """A device object: node, index:sub, and the CiA type to read it as (None:
    the one the daemon knows from the node's EDS/DCF)."""

    def __init__(self, node: Node, index: int, sub: int, type_: Optional[TypeLike]):
        self.node, self.index, self.sub, self.type = node, index, sub, type_

    def _req(self, sdo_only: bool = False) -> DevObjReq:
        return _obj_req(self.node.id, self.index, self.sub, self.type, sdo_only)

    def _what(self, verb: str) -> str:
        return f"line {self.node.line} node {self.node.id} {verb} {self.index:04X}:{self.sub:02X}"

    def read(self, max_age_ms: int = 0, sdo_only: bool = False) -> events.DeviceValue:
        """From the mirror when its value is at most max_age_ms old (0: the line's
        default), else by SDO; .value typed, .via says which."""
        c = self.node.conn
        v, buf, n, ab = DevValue(), c._buf(), ctypes.c_size_t(), ctypes.c_uint32()
        check(lib.cogw_dev_read(c._h, self.node.line, ctypes.byref(self._req(sdo_only)),
                                max_age_ms, ctypes.byref(v), buf, len(buf), ctypes.byref(n),
                                c.timeout_ms, ctypes.byref(ab)), self._what("read"), ab.value)
        return events.device_value(bytes(v) + ctypes.string_at(buf, n.value), self.node.line)

    @property
    def value(self) -> datatypes.Value:
        return self.read().value

    def write(self, value: datatypes.Value, sdo_only: bool = False) -> WriteResult:
        """By the device's RPDO when the mirror produces it, else by SDO."""
        c = self.node.conn
        data = dev_encode(self.type, value, self._what("write"))
        resp, ab = DevWriteResp(), ctypes.c_uint32()
        check(lib.cogw_dev_write(c._h, self.node.line, ctypes.byref(self._req(sdo_only)), data,
                                 len(data), ctypes.byref(resp), c.timeout_ms, ctypes.byref(ab)),
              self._what("write"), ab.value)
        return WriteResult(events.VIA.get(resp.via, str(resp.via)), bool(resp.held), resp.pdo,
                           resp.cob_id)

    def watch(self, min_interval_ms: int = 0,
              callback: Optional[Callable[[events.DeviceValue], None]] = None) -> "Watch":
        """Each new value (at most one per min_interval_ms): iterate the result,
        or give callback(value). close() the result to stop watching."""
        return Watch(self, min_interval_ms, callback)

    def add_callback(self, callback: Callable[[events.DeviceValue], None],
                     min_interval_ms: int = 0) -> "Watch":
        return Watch(self, min_interval_ms, callback)


def watch_match(obj: Any) -> Callable[[Any], bool]:
    """The values of one watched object; the one the mirror held when the watch
    began (received before it: the same CLOCK_MONOTONIC) marked held."""
    started_us = time.monotonic_ns() // 1000
    line, node = obj.node.line, obj.node.id

    def match(ev: Any) -> bool:
        if not (isinstance(ev, events.DeviceValue) and ev.line == line and ev.node == node and
                ev.index == obj.index and ev.sub == obj.sub):
            return False
        ev.held = ev.time_us < started_us
        return True
    return match


class Watch(Events):
    """A watched device object's values."""

    def __init__(self, obj: DeviceObject, min_interval_ms: int,
                 callback: Optional[Callable[[events.DeviceValue], None]]):
        node, c = obj.node, obj.node.conn
        self.obj = obj
        super().__init__(c, node.line, 0, watch_match(obj), callback)
        resp, ab = DevWatchResp(), ctypes.c_uint32()
        try:
            check(lib.cogw_dev_watch(c._h, node.line, ctypes.byref(obj._req()), min_interval_ms,
                                     ctypes.byref(resp), c.timeout_ms, ctypes.byref(ab)),
                  obj._what("watch"), ab.value)
        except BaseException:
            super().close()
            raise
        self.type, self.pdo, self.cob_id = resp.type, resp.pdo, resp.cob_id

    def close(self) -> None:
        c = self.obj.node.conn
        if c._h:
            lib.cogw_dev_unwatch(c._h, self.obj.node.line, ctypes.byref(self.obj._req()),
                                 c.timeout_ms)
        super().close()


def connect(instance: str = "main", timeout_ms: int = 0) -> Connection:
    """A connection to the cogwd instance (docs/mailbox.md: its queues are
    /cogw.<instance>.line<N>.cmd)."""
    return Connection(instance, timeout_ms)
