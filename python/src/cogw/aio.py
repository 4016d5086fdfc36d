# SPDX-License-Identifier: MIT
"""The asyncio API: a libcogw loop handle (cogw_loop_open, mailbox/cogw.h
"For event loops") whose one descriptor the event loop watches with
add_reader: no thread, in the library or here. Requests go out with
cogw_loop_send, which never waits (a full command queue: the writer
callback of the line's queue tells when to retry); their answers and the
events come in through cogw_loop_recv when the descriptor is readable;
cogw_loop_tick runs when cogw_loop_timeout_ms says (leases, restarts,
time-outs). Two set-up calls wait for the daemon's mailbox itself, not
for the bus: registering with a line (cogw_loop_attach, once per line)
and changing the event subscriptions (cogw_subscribe).

    async with await cogw.aio.connect("main") as gw:
        node = gw.node(5, od="device.eds")
        print(await node.sdo[0x1018][1].read())
        async for v in node.obj(0x6000, 1).watch():
            print(v.value)
"""
from __future__ import annotations

import asyncio
import ctypes
from typing import Any, AsyncIterator, Callable, Optional, Union

from . import datatypes, eds, events
from ._events_sync import Response
from ._subs import SubscriptionCount
from ._lib import (CMD, E_AGAIN, E_WOULDBLOCK, EV, EVC, KIND_RESPONSE, MGR_NODE_PROGRAM,
                   DevReadReq, DevWatchReq, DevWatchResp, DevWriteResp, GwSdoReq, LineStatus,
                   MgrNodeDiag, MgrNodeReq, MgrStatus, Msg, NmtReq, NodeEntry, ObjReq, Options,
                   SdoReq, lib)
from .client import (Emcy, Nmt, NodeEvents, ODLike, _event_match, _obj_req, _od, dev_encode,
                     resolve_obj, watch_match)
from .datatypes import TypeLike
from .errors import CogwError, check
from .events import NMT_COMMANDS
from .objects import AsyncSdoVariable, Dictionary
from .status import (LineInfo, ManagerStatus, NodeDiag, NodeInfo, ProgramResult, WriteResult,
                     line_info, manager_status, node_diag, node_info, program_request,
                     program_result)


PROGRAM_BOUND_MS = 24 * 3600 * 1000


def _fixed(cls: type, data: bytes, what: str) -> Any:
    if len(data) < ctypes.sizeof(cls):
        raise CogwError(-107, f"{what}: a short answer")
    return cls.from_buffer_copy(data[:ctypes.sizeof(cls)])


class _Sink:
    def __init__(self, match: Callable[[Any], bool], callback: Optional[Callable] = None):
        self.match, self.callback = match, callback
        self.queue: "asyncio.Queue[Any]" = asyncio.Queue()


class AsyncConnection:
    """A loop handle on a cogwd instance, driven by the running asyncio loop."""

    def __init__(self, instance: str = "main", timeout_ms: int = 0, resp_depth: int = 0,
                 event_depth: int = 0):
        self.instance = instance
        self.timeout_ms = timeout_ms
        self._opts = (resp_depth, event_depth)
        self._h = ctypes.c_void_p()
        self._loop: Optional[asyncio.AbstractEventLoop] = None
        self._fd = -1
        self._timer: Optional[asyncio.TimerHandle] = None
        self._pending: dict[int, asyncio.Future] = {}
        self._sinks: list[_Sink] = []
        self._attached: set[int] = set()
        self._subs = SubscriptionCount()
        self._room: dict[int, asyncio.Future] = {}
        self._msg = Msg()

    async def open(self) -> "AsyncConnection":
        self._loop = asyncio.get_running_loop()
        opts = Options(self.instance.encode(), 0, self._opts[0], self._opts[1], 0,
                       self.timeout_ms)
        check(lib.cogw_loop_open(ctypes.byref(self._h), ctypes.byref(opts)),
              f"connect to cogwd instance {self.instance!r}")
        self._fd = lib.cogw_loop_fd(self._h)
        self._loop.add_reader(self._fd, self._readable)
        self._arm()
        return self

    async def close(self) -> None:
        self.close_now()

    def close_now(self) -> None:
        if not self._h:
            return
        if self._loop is not None and self._fd >= 0:
            self._loop.remove_reader(self._fd)
            for line in list(self._room):
                self._loop.remove_writer(lib.cogw_loop_cmd_fd(self._h, line))
        if self._timer is not None:
            self._timer.cancel()
        for f in self._pending.values():
            if not f.done():
                f.set_exception(CogwError(-106, "connection closed"))
        lib.cogw_close(self._h)
        self._h = ctypes.c_void_p()

    async def __aenter__(self) -> "AsyncConnection":
        return self if self._h else await self.open()

    async def __aexit__(self, *exc: Any) -> None:
        await self.close()

    # -- the loop's side
    def _arm(self) -> None:
        """Wake up when cogw_loop_tick has something to do (a timer armed for
        an earlier time stays: it arms the next one when it runs)."""
        assert self._loop is not None
        due = self._loop.time() + max(lib.cogw_loop_timeout_ms(self._h), 0) / 1000
        if self._timer is not None:
            if self._timer.when() <= due:
                return
            self._timer.cancel()
        self._timer = self._loop.call_at(due, self._due)

    def _due(self) -> None:
        self._timer = None
        if self._h:
            lib.cogw_loop_tick(self._h)
            self._drain()
            self._arm()

    def _readable(self) -> None:
        lib.cogw_loop_tick(self._h)
        self._drain()
        self._arm()

    def _drain(self) -> None:
        m = self._msg
        while self._h:
            rc = lib.cogw_loop_recv(self._h, ctypes.byref(m))
            if rc == E_AGAIN:
                return
            if rc < 0:
                raise CogwError(rc, "cogw_loop_recv")
            try:
                item: Any = Response(m) if m.kind == KIND_RESPONSE else events.decode(m)
            finally:
                lib.cogw_msg_release(ctypes.byref(m))
            self._deliver(item)

    def _deliver(self, item: Any) -> None:
        if isinstance(item, Response):
            f = self._pending.pop(item.corr, None)
            if f is not None and not f.done():
                f.set_result(item)
            return
        for s in list(self._sinks):
            if not s.match(item):
                continue
            if s.callback is None:
                s.queue.put_nowait(item)
                continue
            try:
                s.callback(item)
            except Exception:  # noqa: BLE001 - one callback's failure must not end the others
                assert self._loop is not None
                self._loop.call_exception_handler({"message": "cogw event callback failed",
                                                   "exception": Exception(s.callback)})

    # -- requests
    def _attach(self, line: int) -> None:
        if line not in self._attached:
            check(lib.cogw_loop_attach(self._h, line, self.timeout_ms), f"attach line {line}")
            self._attached.add(line)

    async def _room_on(self, line: int) -> None:
        """Until the line's command queue is writable (or 50 ms: our own answers
        taken in may be what makes room)."""
        assert self._loop is not None
        fd = lib.cogw_loop_cmd_fd(self._h, line)
        fut = self._loop.create_future()
        if fd >= 0:
            self._loop.add_writer(fd, lambda: fut.done() or fut.set_result(None))
            self._room[line] = fut
        try:
            await asyncio.wait_for(asyncio.shield(fut), 0.05)
        except asyncio.TimeoutError:
            pass
        finally:
            if fd >= 0:
                self._loop.remove_writer(fd)
                self._room.pop(line, None)

    async def start(self, line: int, cmd: int, payload: bytes = b"",
                    timeout_ms: Optional[int] = None) -> tuple[int, "asyncio.Future[Response]"]:
        """Send a command (payload as mailbox/proto.h defines it): its correlation
        id (the events that belong to it carry it) and the future of its answer."""
        if not self._h:
            raise CogwError(-106, "connection closed")
        assert self._loop is not None
        self._attach(line)
        corr = ctypes.c_uint64()
        t = self.timeout_ms if timeout_ms is None else timeout_ms
        while True:
            rc = lib.cogw_loop_send(self._h, line, cmd, payload or None, len(payload), t,
                                    ctypes.byref(corr))
            if rc != E_WOULDBLOCK:
                break
            await self._room_on(line)
        check(rc, f"line {line} command 0x{cmd:04X}")
        fut = self._loop.create_future()
        self._pending[corr.value] = fut
        self._arm()  # the request's time-out is a deadline of the handle now
        return corr.value, fut

    async def request(self, line: int, cmd: int, payload: bytes = b"",
                      timeout_ms: Optional[int] = None) -> Response:
        """Send a command and await its answer."""
        return await (await self.start(line, cmd, payload, timeout_ms))[1]

    async def call(self, line: int, cmd: int, payload: bytes, what: str,
                   timeout_ms: Optional[int] = None) -> bytes:
        r = await self.request(line, cmd, payload, timeout_ms)
        check(r.status, what, r.abort)
        return r.data

    # -- events
    def subscribe(self, line: int, mask: int) -> None:
        self._attach(line)
        new = self._subs.add(line, mask)
        if new:
            check(lib.cogw_subscribe(self._h, line, new, None, 0, self.timeout_ms),
                  f"subscribe line {line}")
            self._drain()  # what came in while the set-up call waited

    def unsubscribe(self, line: int, mask: int) -> None:
        gone = self._subs.remove(line, mask)
        if gone and self._h:
            lib.cogw_unsubscribe(self._h, line, gone, self.timeout_ms)
            self._drain()

    # -- what it reaches
    def line(self, number: int) -> "AsyncLine":
        return AsyncLine(self, number)

    def node(self, node_id: int, line: int = 0, od: ODLike = None,
             network: Optional[int] = None) -> "AsyncNode":
        return AsyncNode(self, line, node_id, _od(od), network)


class AsyncEvents:
    """Events as an async iterator (async for ev in stream) or await stream.get(timeout);
    with a callback, callback(event) runs in the loop. close() unsubscribes."""

    def __init__(self, conn: AsyncConnection, line: int, mask: int,
                 match: Callable[[Any], bool], callback: Optional[Callable] = None):
        self._conn, self._line, self._mask = conn, line, mask
        conn.subscribe(line, mask)
        self._sink = _Sink(match, callback)
        conn._sinks.append(self._sink)

    async def get(self, timeout: Optional[float] = None) -> Optional[events.AnyEvent]:
        q = self._sink.queue
        if not q.empty():
            return q.get_nowait()
        try:
            return await asyncio.wait_for(q.get(), timeout)
        except asyncio.TimeoutError:
            return None

    def __aiter__(self) -> AsyncIterator[events.AnyEvent]:
        return self

    async def __anext__(self) -> events.AnyEvent:
        return await self._sink.queue.get()

    async def aclose(self) -> None:
        self.close()

    def close(self) -> None:
        if self._sink in self._conn._sinks:
            self._conn._sinks.remove(self._sink)
            self._conn.unsubscribe(self._line, self._mask)

    async def __aenter__(self) -> "AsyncEvents":
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self.aclose()


class _AOdAccess:
    def __init__(self, conn: AsyncConnection, line: int):
        self.conn, self.line = conn, line
        self.label = f"line {line} OD"

    async def upload(self, index: int, sub: int) -> bytes:
        return await self.conn.call(self.line, CMD["OD_READ"], bytes(ObjReq(index, sub, 0)),
                                    f"{self.label} {index:04X}:{sub:02X}")

    async def download(self, index: int, sub: int, data: bytes) -> None:
        await self.conn.call(self.line, CMD["OD_WRITE"], bytes(ObjReq(index, sub, 0)) + data,
                             f"{self.label} {index:04X}:{sub:02X}")


class AsyncLine:
    def __init__(self, conn: AsyncConnection, number: int):
        self.conn, self.number = conn, number
        self.od = Dictionary(_AOdAccess(conn, number), None, AsyncSdoVariable)
        self.manager = AsyncManager(self)

    def node(self, node_id: int, od: ODLike = None, network: Optional[int] = None) -> "AsyncNode":
        return self.conn.node(node_id, self.number, od, network)

    async def status(self) -> LineInfo:
        d = await self.conn.call(self.number, CMD["LINE_STATUS"], b"", "line status")
        return line_info(_fixed(LineStatus, d, "line status"))

    async def nodes(self) -> list[NodeInfo]:
        d = await self.conn.call(self.number, CMD["NODE_TABLE"], b"", "node table")
        size = ctypes.sizeof(NodeEntry)
        return [node_info(NodeEntry.from_buffer_copy(d[i:i + size]))
                for i in range(0, len(d) - size + 1, size)]

    async def nmt(self, command: Union[int, str], node: int = 0) -> None:
        cs = NMT_COMMANDS[command] if isinstance(command, str) else command
        await self.conn.call(self.number, CMD["NMT"], bytes(NmtReq(cs, node, 0)),
                             f"line {self.number} NMT {command} node {node}")

    def events(self, *classes: str, node: Optional[int] = None) -> AsyncEvents:
        return AsyncEvents(self.conn, self.number, events.classes_mask(classes),
                           _event_match(self.number, None, node))

    def add_callback(self, callback: Callable[[Any], None], *classes: str,
                     node: Optional[int] = None) -> AsyncEvents:
        return AsyncEvents(self.conn, self.number, events.classes_mask(classes),
                           _event_match(self.number, None, node), callback)


class AsyncManager:
    def __init__(self, line: AsyncLine):
        self._c, self._n = line.conn, line.number

    async def status(self) -> ManagerStatus:
        d = await self._c.call(self._n, CMD["MGR_STATUS"], b"", "manager status")
        # an older daemon's answer ends before the counters added since: 0 (as libcogw)
        return manager_status(_fixed(MgrStatus, d.ljust(ctypes.sizeof(MgrStatus), b"\0"),
                                     "manager status"))

    async def boot(self, node: int = 0) -> None:
        await self._c.call(self._n, CMD["MGR_BOOT"], bytes(MgrNodeReq(node)),
                           f"manager boot {node}")

    async def start(self) -> None:
        await self._c.call(self._n, CMD["MGR_START"], b"", "manager start")

    async def node_diag(self, node: int) -> NodeDiag:
        d = await self._c.call(self._n, CMD["MGR_NODE_DIAG"], bytes(MgrNodeReq(node)),
                               f"manager diag {node}")
        return node_diag(_fixed(MgrNodeDiag, d, "manager diag"))


class _ASdoAccess:
    def __init__(self, node: "AsyncNode"):
        self.node = node
        self.mode = 0
        self.sdo_timeout_ms = 0
        net = f" network {node.network}" if node.network is not None else ""
        self.label = f"line {node.line}{net} node {node.id}"

    def _req(self, index: int, sub: int) -> tuple[int, bytes]:
        r = SdoReq(self.node.id, self.mode, index, sub, (ctypes.c_uint8 * 3)(),
                   self.sdo_timeout_ms, 0)
        if self.node.network is None:
            return 0, bytes(r)
        return 1, bytes(GwSdoReq(self.node.network, 0, r))

    async def upload(self, index: int, sub: int) -> bytes:
        routed, p = self._req(index, sub)
        return await self.node.conn.call(self.node.line,
                                         CMD["GW_SDO_UPLOAD" if routed else "SDO_UPLOAD"], p,
                                         f"{self.label} SDO upload {index:04X}:{sub:02X}")

    async def download(self, index: int, sub: int, data: bytes) -> None:
        routed, p = self._req(index, sub)
        await self.node.conn.call(self.node.line,
                                  CMD["GW_SDO_DOWNLOAD" if routed else "SDO_DOWNLOAD"], p + data,
                                  f"{self.label} SDO download {index:04X}:{sub:02X}")


class AsyncSdoClient(Dictionary):
    def __init__(self, node: "AsyncNode"):
        super().__init__(_ASdoAccess(node), node.od, AsyncSdoVariable)

    async def upload(self, index: int, subindex: int) -> bytes:
        return await self.access.upload(index, subindex)

    async def download(self, index: int, subindex: int, data: bytes) -> None:
        await self.access.download(index, subindex, bytes(data))

    async def read(self, index: int, subindex: int, type: TypeLike) -> datatypes.Value:  # noqa: A002
        return datatypes.decode(type, await self.upload(index, subindex))

    async def write(self, index: int, subindex: int, value: datatypes.Value,
                    type: TypeLike) -> None:  # noqa: A002
        await self.download(index, subindex, datatypes.encode(type, value))


class AsyncNmt(NodeEvents):
    """node.nmt for asyncio: commands and the node table's state are coroutines;
    events() / add_callback() as the blocking Nmt's."""
    CLASSES = Nmt.CLASSES

    async def send_command(self, code: int) -> None:
        await self._node.conn.line(self._node.line).nmt(code, self._node.id)

    async def set_state(self, new: str) -> None:
        await self.send_command(NMT_COMMANDS[new])

    async def state(self) -> str:
        for e in await self._node.conn.line(self._node.line).nodes():
            if e.node == self._node.id:
                return e.state_name
        return "UNKNOWN"


class AsyncNode:
    events_cls = AsyncEvents

    def __init__(self, conn: AsyncConnection, line: int, node_id: int,
                 od: Optional[eds.ObjectDictionary], network: Optional[int]):
        self.conn, self.line, self.id, self.od, self.network = conn, line, node_id, od, network
        self.sdo = AsyncSdoClient(self)
        self.nmt = AsyncNmt(self)
        self.emcy = Emcy(self)

    def obj(self, index: Union[int, str], sub: Union[int, str] = 0,
            type: Optional[TypeLike] = None) -> "AsyncDeviceObject":  # noqa: A002
        return AsyncDeviceObject(self, *resolve_obj(self, index, sub, type))

    async def program(self, image: bytes, expected: int = 0, sdo_timeout_ms: int = 0,
                      progress: Optional[Callable[[int, int], None]] = None,
                      timeout: float = 60.0) -> ProgramResult:
        """As the blocking Node.program: progress(bytes_sent, size) as it goes."""
        c = self.conn
        payload = program_request(self.id, expected, sdo_timeout_ms, image)
        box: dict[str, int] = {}

        def mine(item: Any) -> bool:
            return (not isinstance(item, Response) and item.corr == box.get("corr", -1) and
                    item.code == EV["MGR_NODE"] and getattr(item, "what", -1) == MGR_NODE_PROGRAM)
        stream = AsyncEvents(c, self.line, EVC["manager"], mine)
        try:
            # the library's bound is the whole update's; `timeout` counts from the
            # last progress, here
            box["corr"], answer = await c.start(self.line, CMD["MGR_PROGRAM"], payload,
                                                PROGRAM_BOUND_MS)
            while True:
                get = asyncio.ensure_future(stream._sink.queue.get())
                done, _ = await asyncio.wait({answer, get}, timeout=timeout,
                                             return_when=asyncio.FIRST_COMPLETED)
                if get in done:
                    if progress is not None:
                        ev = get.result()
                        progress(ev.value, ev.expected)
                    continue
                get.cancel()
                if answer in done:
                    r = answer.result()
                    return program_result(r.status, r.abort, r.data, self.id)
                raise CogwError(-12, f"program node {self.id}: no progress in {timeout} s")
        finally:
            stream.close()


class AsyncDeviceObject:
    def __init__(self, node: AsyncNode, index: int, sub: int, type_: Optional[TypeLike]):
        self.node, self.index, self.sub, self.type = node, index, sub, type_

    def _what(self, verb: str) -> str:
        return f"line {self.node.line} node {self.node.id} {verb} {self.index:04X}:{self.sub:02X}"

    def _req(self, sdo_only: bool = False):
        return _obj_req(self.node.id, self.index, self.sub, self.type, sdo_only)

    async def read(self, max_age_ms: int = 0, sdo_only: bool = False) -> events.DeviceValue:
        d = await self.node.conn.call(self.node.line, CMD["DEV_READ"],
                                      bytes(DevReadReq(self._req(sdo_only), max_age_ms)),
                                      self._what("read"))
        return events.device_value(d, self.node.line)

    async def write(self, value: datatypes.Value, sdo_only: bool = False) -> WriteResult:
        data = dev_encode(self.type, value, self._what("write"))
        d = await self.node.conn.call(self.node.line, CMD["DEV_WRITE"],
                                      bytes(self._req(sdo_only)) + data, self._what("write"))
        r = _fixed(DevWriteResp, d, self._what("write"))
        return WriteResult(events.VIA.get(r.via, str(r.via)), bool(r.held), r.pdo, r.cob_id)

    async def watch(self, min_interval_ms: int = 0,
                    callback: Optional[Callable[[events.DeviceValue], None]] = None
                    ) -> "AsyncWatch":
        """Each new value: `async for v in await obj.watch()`, or callback(value)."""
        w = AsyncWatch(self, callback)
        try:
            d = await self.node.conn.call(self.node.line, CMD["DEV_WATCH"],
                                          bytes(DevWatchReq(self._req(), min_interval_ms)),
                                          self._what("watch"))
        except BaseException:
            w.close()
            raise
        r = _fixed(DevWatchResp, d, self._what("watch"))
        w.type, w.pdo, w.cob_id = r.type, r.pdo, r.cob_id
        return w


class AsyncWatch(AsyncEvents):
    def __init__(self, obj: AsyncDeviceObject, callback: Optional[Callable]):
        self.obj = obj
        self.type = self.pdo = self.cob_id = 0
        super().__init__(obj.node.conn, obj.node.line, 0, watch_match(obj), callback)

    async def aclose(self) -> None:
        c = self.obj.node.conn
        self.close()
        if c._h:
            await c.call(self.obj.node.line, CMD["DEV_UNWATCH"], bytes(self.obj._req()),
                         self.obj._what("unwatch"))


async def connect(instance: str = "main", timeout_ms: int = 0) -> AsyncConnection:
    """An open AsyncConnection (use `async with`, or await conn.close())."""
    return await AsyncConnection(instance, timeout_ms).open()
