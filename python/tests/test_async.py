# SPDX-License-Identifier: MIT
"""The asyncio API (a loop handle watched with add_reader) against cogwd."""
from __future__ import annotations

import asyncio
import os

import pytest

import cogw
import cogw.aio
from conftest import DEV, INSTANCE, NODE, PROGRAM_NODE


def run(coro):
    return asyncio.run(asyncio.wait_for(coro, 60))


def test_no_thread_and_sdo(system):
    async def main():
        before = len(os.listdir("/proc/self/task"))  # OS threads, libcogw's too
        async with await cogw.aio.connect(INSTANCE, timeout_ms=20000) as gw:
            node = gw.node(NODE, od=system.eds[NODE])
            assert await node.sdo["Identity object"]["Vendor-ID"].read() == 0x42
            await node.sdo["Speed"].write(-42)
            assert await node.sdo[0x2000].read() == -42
            await node.sdo["Speed"].write_phys(4.2)
            assert await node.sdo["Speed"].read_phys() == pytest.approx(4.2)
            blob = bytes(range(256)) * 8
            await node.sdo.download(0x2002, 0, blob)
            assert await node.sdo.upload(0x2002, 0) == blob
            # many requests at once on one handle, answered by correlation id
            got = await asyncio.gather(*(node.sdo.read(0x1018, s, "u32") for s in (1, 2, 3, 4)))
            assert got == [0x42, NODE, 3, 4711]
            assert len(os.listdir("/proc/self/task")) == before
    run(main())


def test_errors_routing_and_own_od(system):
    async def main():
        async with await cogw.aio.connect(INSTANCE, timeout_ms=20000) as gw:
            with pytest.raises(cogw.SdoAbortedError) as e:
                await gw.node(NODE).sdo.upload(0x2999, 0)
            assert e.value.abort_name == "object does not exist"
            routed = gw.node(DEV, line=0, network=3)
            assert await routed.sdo.read(0x1000, 0, "u32") == 0x191
            od = gw.line(0).od
            await od[0x2001].write(1234, "u32")
            assert await od[0x2001].read("u32") == 1234
            with pytest.raises(cogw.CogwError) as e:
                await gw.line(0).manager.status()
            assert e.value.status == -15
    run(main())


def test_nmt_node_table_and_events(system):
    local = system.locals[NODE]

    async def main():
        async with await cogw.aio.connect(INSTANCE, timeout_ms=20000) as gw:
            node = gw.node(NODE)
            emcys = []
            cb = node.emcy.add_callback(emcys.append)
            async with node.nmt.events() as stream:
                await node.nmt.set_state("OPERATIONAL")
                local.nmt.send_command(0x81)  # boot-up, back in PRE-OPERATIONAL
                while True:
                    ev = await stream.get(10)
                    assert ev is not None, "no boot-up event"
                    if ev.code == 0x0302:
                        break
            local.emcy.send(0x8110, 0x11)
            for _ in range(200):
                if emcys:
                    break
                await asyncio.sleep(0.05)
            assert emcys and emcys[0].code_emcy == 0x8110
            cb.close()
            rows = await gw.line(0).nodes()
            assert NODE in {r.node for r in rows}
            st = await gw.line(0).status()
            assert st.node_id == 127
    run(main())


def test_device_object_watch_as_async_iterator(system):
    dev = system.locals[DEV]

    async def main():
        async with await cogw.aio.connect(INSTANCE, timeout_ms=20000) as gw:
            node = gw.node(DEV, line=2, od=system.eds[DEV])
            watch = await node.obj("Current").watch()
            async with watch:
                for v in (5, 6, 7):
                    dev.tpdo[1][0x2102].raw = v
                    dev.tpdo[1].transmit()
                got = []
                async for ev in watch:
                    if ev.held:  # the value the mirror held when the watch began
                        continue
                    got.append(ev.value)
                    if len(got) == 3:
                        break
                assert got == [5, 6, 7]
            r = await node.obj("Current").read()
            assert (r.value, r.via) == (7, "pdo")
            w = await node.obj("Output").write(9)
            assert w.via == "pdo"
            w = await node.obj("Setting").write(5, sdo_only=True)
            assert w.via == "sdo"
    run(main())


def test_manager_and_program(system):
    image = bytes(range(200)) * 5

    async def main():
        async with await cogw.aio.connect(INSTANCE, timeout_ms=20000) as gw:
            st = await gw.line(1).manager.status()
            assert st.state_name
            seen = []
            r = await gw.node(PROGRAM_NODE, line=1).program(
                image, expected=0x3C2A91F0, sdo_timeout_ms=5000,
                progress=lambda sent, size: seen.append(sent))
            assert r.bytes == len(image) and seen and seen[-1] <= len(image)
    run(main())
    assert bytes(system.locals[PROGRAM_NODE].get_data(0x1F50, 1)) == image
