# SPDX-License-Identifier: MIT
"""Events for the blocking API: one reader of the handle's events at a
time (cogw_recv), handing each message to the sinks that want it: queues
for iterators and waits, callbacks run by one dispatcher thread (started
with the first callback, as python-canopen's notifier runs its callbacks)."""
from __future__ import annotations

import ctypes
import logging
import queue
import threading
import time
from typing import Any, Callable, Optional

from . import events
from ._lib import E_AGAIN, KIND_RESPONSE, Msg, lib
from .errors import CogwError

log = logging.getLogger("cogw")

Match = Callable[[Any], bool]


class Sink:
    """Where matching messages go: a queue, or a callback."""

    def __init__(self, match: Match, callback: Optional[Callable[[Any], None]] = None):
        self.match = match
        self.callback = callback
        self.queue: "queue.Queue[Any]" = queue.Queue()


class Response:
    """The answer to a request started with cogw_send_async."""

    def __init__(self, m: Msg):
        self.line = m.line
        self.code = m.code
        self.status = m.status
        self.abort = m.abort
        self.corr = m.corr
        self.data = events.payload_of(m)


class Pump:
    def __init__(self, handle: ctypes.c_void_p):
        self._h = handle
        self._lock = threading.Lock()
        self._sinks: list[Sink] = []
        self._sinks_lock = threading.Lock()
        self._thread: Optional[threading.Thread] = None
        self._stop = threading.Event()

    def add(self, sink: Sink) -> Sink:
        with self._sinks_lock:
            self._sinks.append(sink)
        if sink.callback is not None:
            self._start()
        return sink

    def remove(self, sink: Sink) -> None:
        with self._sinks_lock:
            if sink in self._sinks:
                self._sinks.remove(sink)

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="cogw-events", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._thread = None

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                self.pump_once(100)

    def pump_once(self, timeout_ms: int) -> bool:
        """Take one message (waiting up to timeout_ms) and hand it on. The
        caller holds self._lock."""
        m = Msg()
        rc = lib.cogw_recv(self._h, ctypes.byref(m), timeout_ms)
        if rc == E_AGAIN:
            return False
        if rc < 0:
            raise CogwError(rc, "cogw_recv")
        try:
            item: Any = Response(m) if m.kind == KIND_RESPONSE else events.decode(m)
        finally:
            lib.cogw_msg_release(ctypes.byref(m))
        self._deliver(item)
        return True

    def _deliver(self, item: Any) -> None:
        with self._sinks_lock:
            sinks = [s for s in self._sinks if s.match(item)]
        if not sinks and isinstance(item, Response):
            log.debug("cogw: an answer nobody waits for (corr %d)", item.corr)
        for s in sinks:
            if s.callback is None:
                s.queue.put(item)
                continue
            try:
                s.callback(item)
            except Exception:  # noqa: BLE001 - a callback's failure must not end the others
                log.exception("cogw: event callback %r failed", s.callback)

    def get(self, sink: Sink, timeout: Optional[float]) -> Any:
        """The next message of a queue sink; None when timeout (s) passed."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            try:
                return sink.queue.get_nowait()
            except queue.Empty:
                pass
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                return None
            wait_ms = 100 if left is None else max(1, min(100, int(left * 1000)))
            if self._thread is not None:
                try:
                    return sink.queue.get(timeout=wait_ms / 1000)
                except queue.Empty:
                    continue
            if self._lock.acquire(timeout=wait_ms / 1000):
                try:
                    if sink.queue.empty():
                        self.pump_once(wait_ms)
                finally:
                    self._lock.release()
