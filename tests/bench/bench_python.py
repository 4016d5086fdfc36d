#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""tests/bench/bench_python.py - the Python side of bench_vcan_python (the
C benchmark starts it, with PYTHONPATH=python/src and COGW_LIBRARY set):

  read INSTANCE NODE N       N typed reads of 1018h:04 (u32) over one kept
                             connection (the blocking API); prints
                             "python read us: t1 t2 ..." (each read's time);
  watch INSTANCE NODE SECS   watches 6401h:01 of NODE (asyncio API, one loop
                             handle), prints "ready", counts for SECS seconds
                             the values received (not the one the mirror held
                             when the watch began)
                             and prints "python watch: received R lost L"
                             (lost: gaps of the watch's sequence numbers and
                             the daemon's overflow counts).
"""
import asyncio
import sys
import time

import cogw
import cogw.aio


def read(instance, node, n):
    with cogw.connect(instance) as gw:
        sdo = gw.node(node).sdo
        sdo.read(0x1018, 4, "u32")  # registered, warm
        times = []
        clock = time.perf_counter_ns
        for _ in range(n):
            t0 = clock()
            sdo.read(0x1018, 4, "u32")
            times.append((clock() - t0) / 1000)
    print("python read us: " + " ".join(f"{t:.1f}" for t in times), flush=True)


async def watch(instance, node, seconds):
    async with await cogw.aio.connect(instance) as gw:
        stream = await gw.node(node).obj(0x6401, 1, "i16").watch()
        received = lost = 0
        last_seq = None
        print("ready", flush=True)
        try:
            async with asyncio.timeout(seconds):
                async for ev in stream:
                    if ev.held:  # the value the mirror held at the watch: not this run's
                        last_seq = ev.seq
                        continue
                    received += 1
                    lost += ev.dropped
                    if last_seq is not None and ev.seq != last_seq + 1:
                        lost += max(ev.seq - last_seq - 1, 0)
                    last_seq = ev.seq
        except TimeoutError:
            pass
        await stream.aclose()
    print(f"python watch: received {received} lost {lost}", flush=True)


def main():
    what, instance, node, arg = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    if what == "read":
        read(instance, node, int(arg))
    else:
        asyncio.run(watch(instance, node, float(arg)))


if __name__ == "__main__":
    main()
