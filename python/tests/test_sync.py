# SPDX-License-Identifier: MIT
"""The blocking API against cogwd and python-canopen devices (conftest.py)."""
from __future__ import annotations

import struct
import time

import pytest

import cogw
from conftest import DEV, INSTANCE, NODE, PROGRAM_NODE


def wait_until(cond, what, timeout=10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return
        time.sleep(0.05)
    raise AssertionError(f"{what}: not within {timeout} s")


def test_sdo_by_index_and_name(gw, system):
    node = gw.node(NODE, line=0, od=system.eds[NODE])
    local = system.locals[NODE]
    assert node.sdo[0x1000].raw == 0x191
    assert node.sdo[0x1018][1].raw == 0x42
    assert node.sdo["Identity object"]["Serial number"].raw == 4711
    node.sdo["Speed"].raw = -123
    assert local.sdo["Speed"].raw == -123
    assert node.sdo[0x2000].raw == -123
    node.sdo["Limits"]["Low"].raw = -5000
    assert local.sdo[0x2004][1].raw == -5000
    assert node.sdo["Limits"]["Low"].raw == -5000
    node.sdo["Ratio"].raw = 2.5
    assert node.sdo["Ratio"].raw == 2.5
    node.sdo["Name"].raw = "pump 7"
    assert node.sdo["Name"].raw == "pump 7"
    assert local.sdo["Name"].raw == "pump 7"


def test_phys_uses_the_eds_factor(gw, system):
    node = gw.node(NODE, od=system.eds[NODE])
    node.sdo["Speed"].phys = 12.3  # km/h, Factor 0.1
    assert system.locals[NODE].sdo["Speed"].raw == 123
    assert node.sdo["Speed"].phys == pytest.approx(12.3)


def test_typed_read_and_write_without_an_eds(gw, system):
    node = gw.node(NODE)
    node.sdo.write(0x2000, 0, 777, "i16")
    assert node.sdo.read(0x2000, 0, "INTEGER16") == 777
    assert node.sdo[0x2000][0].read("u16") == 777
    assert node.sdo[0x1018][2].raw == NODE  # no type known: an unsigned integer
    assert node.sdo.upload(0x1000, 0) == struct.pack("<L", 0x191)
    with pytest.raises(TypeError):
        node.sdo[0x2000].raw = 5  # nothing says how many bytes


def test_large_domain_both_ways(gw, system):
    node = gw.node(NODE, od=system.eds[NODE])
    blob = bytes((i * 7) & 0xFF for i in range(1200))  # segmented: 172 segments
    node.sdo["Blob"].raw = blob
    assert bytes(system.locals[NODE].sdo["Blob"].raw) == blob
    assert node.sdo["Blob"].raw == blob
    node.sdo.mode = 2  # segmented by request
    assert node.sdo.upload(0x2002, 0) == blob


def test_abort_is_an_exception_with_its_cia_name(gw):
    node = gw.node(NODE)
    with pytest.raises(cogw.SdoAbortedError) as e:
        node.sdo[0x2999][0].data
    assert e.value.code == 0x06020000
    assert e.value.abort_name == cogw.abort_name(0x06020000) == "object does not exist"
    assert e.value.status == -13 and e.value.status_name == cogw.status_name(-13)
    assert "0x06020000" in str(e.value) and "object does not exist" in str(e.value)
    with pytest.raises(cogw.SdoAbortedError) as e:
        node.sdo[0x1000].write(5, "u32")  # a read-only object
    assert e.value.code == 0x06010002


def test_mailbox_refusal_is_an_exception_with_the_status(gw):
    with pytest.raises(cogw.CogwError) as e:
        gw.node(NODE, line=9).sdo[0x1000].raw
    assert e.value.status < 0 and e.value.status_name
    with pytest.raises(cogw.CogwError) as e:
        gw.line(0).manager.status()  # line 0 has no manager
    assert e.value.status == -15  # unsupported


def test_routed_sdo_by_network(gw, system):
    routed = gw.node(DEV, line=0, network=3, od=system.eds[DEV])
    assert routed.sdo["Device type"].raw == 0x191
    routed.sdo["Setting"].raw = 0xCAFE
    assert system.locals[DEV].sdo["Setting"].raw == 0xCAFE
    with pytest.raises(cogw.SdoAbortedError) as e:
        gw.node(5, line=0, network=99).sdo[0x1000].raw
    assert e.value.code == 0x0A000001


def test_daemon_own_objects(gw):
    od = gw.line(0).od
    od[0x2001].write(99, "u32")
    assert od[0x2001].read("UNSIGNED32") == 99
    od[0x2002].data = b"hello gateway"
    assert od[0x2002].data == b"hello gateway"
    assert od[0x1000].read("u32") is not None


def test_nmt_and_node_table(gw, system):
    line = gw.line(0)
    node = gw.node(NODE)
    local = system.locals[NODE]
    node.nmt.state = "OPERATIONAL"
    wait_until(lambda: local.nmt.state == "OPERATIONAL", "node 5 operational")
    local.nmt.start_heartbeat(100)
    try:
        wait_until(lambda: node.nmt.state == "OPERATIONAL", "the table's state of node 5")
        line.nmt("PRE-OPERATIONAL", NODE)
        wait_until(lambda: local.nmt.state == "PRE-OPERATIONAL", "node 5 pre-operational")
        wait_until(lambda: node.nmt.state == "PRE-OPERATIONAL", "the table's state")
        rows = {r.node: r for r in line.nodes()}
        assert rows[NODE].hb_name == "active" and rows[NODE].last_heard_ms is not None
    finally:
        local.nmt.stop_heartbeat()


def test_events_iterator_and_callbacks(gw, system):
    local = system.locals[NODE]
    node = gw.node(NODE)
    got = []
    with node.emcy.add_callback(got.append), gw.line(0).events("emcy", "boot") as stream:
        local.emcy.send(0x4210, 0x08, b"\x01\x02")
        ev = stream.get(10)
        assert isinstance(ev, cogw.EmcyEvent)
        assert (ev.node, ev.code_emcy, ev.register) == (NODE, 0x4210, 0x08)
        assert ev.data[:2] == b"\x01\x02" and ev.name
        wait_until(lambda: got, "the EMCY callback")
        assert got[0].code_emcy == 0x4210
        local.nmt.send_command(0x81)  # a reset: its boot-up
        ev = stream.get(10)
        while ev is not None and ev.code != 0x0302:
            ev = stream.get(10)
        assert isinstance(ev, cogw.NodeEvent) and ev.node == NODE


def test_wait_for_bootup(gw, system):
    import threading
    local = system.locals[NODE]
    t = threading.Timer(0.5, lambda: local.nmt.send_command(0x81))
    t.start()
    gw.node(NODE).nmt.wait_for_bootup(10)
    t.join()


def test_device_objects_read_write_watch(gw, system):
    dev = system.locals[DEV]
    node = gw.node(DEV, line=2, od=system.eds[DEV])
    pos = node.obj("Position")
    values = []
    with pos.watch() as w, node.obj(0x2102, 0).add_callback(values.append):
        assert w.pdo == 1 and w.cob_id == 0x180 + DEV
        held = w.get(2)  # the value the mirror holds, if any, comes first
        assert held is None or held.held
        for v in (100, 200, 300):
            dev.tpdo[1][0x2101].raw = v
            dev.tpdo[1][0x2102].raw = -v
            dev.tpdo[1].transmit()
            ev = w.get(10)
            assert isinstance(ev, cogw.DeviceValue) and ev.value == v and ev.via == "pdo"
            assert not ev.held and ev.seq == (held.seq if held else 0) + v // 100
        wait_until(lambda: [x.value for x in values if not x.held] == [-100, -200, -300],
                   "3 callbacks of 2102h")
    r = pos.read()
    assert (r.value, r.via) == (300, "pdo")
    r = node.obj(0x2300, 0).read()  # mapped in no PDO: by SDO
    assert (r.value, r.via) == (dev.sdo["Setting"].raw, "sdo")
    out = node.obj("Output")
    res = out.write(0x5A)
    assert (res.via, res.pdo) == ("pdo", 1)
    wait_until(lambda: dev.rpdo[1].is_received and dev.rpdo[1][0x2200].raw == 0x5A,
               "the device's RPDO 1 with 5Ah")
    res = node.obj("Setting").write(4242)
    assert res.via == "sdo"
    assert dev.sdo["Setting"].raw == 4242
    with pytest.raises(cogw.CogwError):
        node.obj(0x2999, 0, "u8").watch()


def test_manager_status_and_boot(gw, system):
    m = gw.line(1).manager
    st = m.status()
    assert st.state_name in cogw.events.MANAGER_STATES.values()
    with gw.line(1).events("manager") as stream:
        m.boot(0)
        ev = stream.get(20)
        assert isinstance(ev, cogw.ManagerEvent)


def test_program_download_with_progress(gw, system):
    image = bytes((i * 13 + 5) & 0xFF for i in range(1500))
    seen = []
    node = gw.node(PROGRAM_NODE, line=1)
    r = node.program(image, expected=0x3C2A91F0, sdo_timeout_ms=SDO_TIMEOUT,
                     progress=lambda sent, size: seen.append((sent, size)))
    assert r.bytes == len(image) and r.found == 0x3C2A91F0
    assert bytes(system.locals[PROGRAM_NODE].get_data(0x1F50, 1)) == image
    assert seen and all(size == len(image) for _, size in seen)
    assert seen == sorted(seen)
    with pytest.raises(cogw.ProgramError) as e:
        node.program(image, expected=0x1234, sdo_timeout_ms=SDO_TIMEOUT)
    assert e.value.found == 0x3C2A91F0


SDO_TIMEOUT = 5000


def test_network_ports_a_python_canopen_script(system):
    network = cogw.Network(INSTANCE)
    network.connect(channel="can0", interface="socketcan")  # bus arguments: the daemon's
    try:
        node = network.add_node(NODE, system.eds[NODE])
        node.sdo["Producer heartbeat time"].raw = 0
        assert node.sdo["Identity object"]["Vendor-ID"].raw == 0x42
        assert NODE in network
    finally:
        network.disconnect()
