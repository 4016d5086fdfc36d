#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""tests/interop/test_network.py - a network that looks after itself, with
python-canopen nodes (PyPI `canopen`, pinned in
tests/interop/requirements.txt) that the daemon was not configured for:

  - unknown nodes (docs/config.md "Unknown nodes"): a python-canopen node
    outside `nodes` that sends a boot-up, a heartbeat (OPERATIONAL, and
    STOPPED: not read), or an EMCY is reported once with the identity it
    answers (1000h, 1018h:1..4) - event, log line, cache - and a node the
    line consumes the heartbeat of (heartbeat_consumers) is not; each
    policy on its own line: "ignore" (line 0), "supervise" (line 1: the
    heartbeat consumer, its loss and return), "boot" (line 2: the manager
    boots a node whose identity an EDS of the directory has, downloads its
    values and starts it; a node of another vendor is "no-match");
  - `cogwctl scan` of 127 node-IDs with 8 python-canopen nodes present (and
    one STOPPED, which does not answer SDO): exactly those, with their
    identities, within the bound it reports; the cache afterwards; a
    second scan while one runs is BUSY; a part of the range one node at a
    time; cogwctl's refusal of bad arguments;
  - an interface deleted and created again under the daemon (the adapter
    unplugged and plugged in): a configured python-canopen node switched
    on again with it is booted again by the manager; an unknown node the
    line supervises is lost during the outage and supervised again after.

Own daemon (instance "netscan") on its own vcan interfaces, which the test
creates (it runs as root in the VM): nothing of it touches the other interop
groups. Prints Unity-style results for tests/run-tests (tests/interop/run-network).
"""
import faulthandler
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback

import canopen
from canopen.objectdictionary import ODRecord, ODVariable, ObjectDictionary, datatypes, export_od

import interop
from interop import RESULTS, check, eq, run_test, selected, step, summary

TOP = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("COGW_BIN", os.path.join(TOP, "build/san/bin"))
INSTANCE = "netscan"
IFACES = ("vcan10", "vcan11", "vcan12")  # created and deleted by the test
IGNORE_LINE, SUPERVISE_LINE, BOOT_LINE = 0, 1, 2
OWN_ID = 127
KNOWN_ID = 3           # in line 0's heartbeat_consumers: not unknown
VENDOR = 0x00C0FFEE
OTHER_VENDOR = 0x00BADBAD
PRODUCT, REVISION = 0x4711, 0x00020003
DEVICE_TYPE = 0x000F0191
SUPERVISE_HB_MS = 1000
SDO_TIMEOUT_MS = 1000   # per frame: python nodes in the emulated VM under load (300 lost answers)
SCAN_PRESENT = tuple(range(60, 68))  # 8 nodes
SCAN_STOPPED = 70
BOOT_VALUE = 0x5A5A1234  # 2000h in the EDS: what the boot downloads
MANAGED_ID = 45          # a configured node of the boot line (its manager's)

WORK = tempfile.mkdtemp(prefix="cogw-network-")
DEVICES = os.path.join(WORK, "devices")
PROCS = {}
NETS = []


def read_log(name, tail=2000):
    try:
        with open(os.path.join(WORK, name + ".log")) as f:
            return f.read()[-tail:] if tail else f.read()
    except OSError:
        return ""


def on_failure():
    print("  cogwd log:\n" + read_log("cogwd", 1500), flush=True)


def ctl(*args, check_rc=True, timeout=60):
    argv = [os.path.join(BIN, "cogwctl"), "--instance", INSTANCE, "--timeout", "30000"] + \
        list(args)
    r = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=TOP)
    if check_rc and r.returncode != 0:
        raise AssertionError(f"cogwctl {' '.join(args)}: exit {r.returncode}: {r.stderr.strip()}")
    return r


def ctl_json(*args):
    return json.loads(ctl("--json", *args).stdout)


class Monitor(interop.Monitor):
    """A subscriber of one line of the daemon, events of a node."""

    def __init__(self, line, classes="manager,hb"):
        super().__init__([os.path.join(BIN, "cogwctl"), "--instance", INSTANCE], classes,
                         line, cwd=TOP)

    def of(self, name, node=None):
        return [e for e in super().of(name) if node is None or e.get("node") == node]

    def wait(self, what, pred, timeout=15.0):
        return super().wait(what, pred, timeout)

    def unknown(self, node, timeout=15.0):
        return self.wait(f"unknown-node event of node {node}",
                         lambda: self.of("unknown-node", node), timeout)[0]


# ---------------------------------------------------------------------------
# python-canopen nodes

def var(name, index, sub, dtype, access="rw", default=None):
    v = ODVariable(name, index, sub)
    v.data_type = dtype
    v.access_type = access
    if default is not None:
        v.default = default
    return v


def node_od(vendor=VENDOR, serial=1, hb_ms=0):
    """A small device: 1000h, 1017h, 1018h:1..4 and one value 2000h."""
    U32 = datatypes.UNSIGNED32
    od = ObjectDictionary()
    od.add_object(var("device type", 0x1000, 0, U32, "ro", DEVICE_TYPE))
    od.add_object(var("producer heartbeat time", 0x1017, 0, datatypes.UNSIGNED16, "rw", hb_ms))
    rec = ODRecord("identity", 0x1018)
    rec.add_member(var("highest sub-index", 0x1018, 0, datatypes.UNSIGNED8, "ro", 4))
    for sub, name, value in ((1, "vendor", vendor), (2, "product", PRODUCT),
                             (3, "revision", REVISION), (4, "serial", serial)):
        rec.add_member(var(name, 0x1018, sub, U32, "ro", value))
    od.add_object(rec)
    od.add_object(var("setting", 0x2000, 0, U32, "rw", 0))
    return od


def local(line, node_id, vendor=VENDOR, hb_ms=0):
    node = canopen.LocalNode(node_id, node_od(vendor, serial=1000 + node_id, hb_ms=hb_ms))
    NETS[line].add_node(node)
    return node


def remove(node):
    node.nmt.stop_heartbeat()
    node.remove_network()


def boot_up(node):
    """Its boot-up, then PRE-OPERATIONAL with the heartbeat of 1017h."""
    node.nmt.send_command(0x81)
    node.nmt.send_command(0x80)


def heartbeat_only(node, state_cmd, period_ms=200):
    """Heartbeats in a state without a boot-up first (a node that was there
    before the daemon)."""
    node.nmt.send_command(state_cmd)  # 0x01 OPERATIONAL, 0x02 STOPPED
    node.nmt.start_heartbeat(period_ms)


# ---------------------------------------------------------------------------
# the daemon

def write_devices():
    os.makedirs(DEVICES, exist_ok=True)
    od = node_od(hb_ms=200)  # the download keeps its heartbeat on
    od[0x2000].default = BOOT_VALUE
    export_od(od, os.path.join(DEVICES, "a-device.eds"), doc_type="eds")
    # another product of the same vendor: not the one a node of PRODUCT gets
    other = node_od(hb_ms=200)
    other[0x1018][2].default = PRODUCT + 1
    export_od(other, os.path.join(DEVICES, "b-other.eds"), doc_type="eds")


CONFIG = {
    "version": 1,
    "state_dir": os.path.join(WORK, "state"),
    "mailbox": {"instance": INSTANCE},
    "lines": [{
        "name": "ignore", "interface": IFACES[0], "bitrate": 1000000, "node_id": OWN_ID,
        "heartbeat_ms": 0, "sdo_clients": 8, "sdo_timeout_ms": 3000,
        "heartbeat_consumers": [{"node_id": KNOWN_ID, "time_ms": 3000}],
        # no manager here: identities are read when asked for
        "unknown_nodes": {"policy": "ignore", "identify": True,
                          "sdo_timeout_ms": SDO_TIMEOUT_MS},
    }, {
        "name": "supervise", "interface": IFACES[1], "bitrate": 1000000, "node_id": OWN_ID,
        "heartbeat_ms": 0, "sdo_timeout_ms": 3000,
        "unknown_nodes": {"policy": "supervise", "heartbeat_ms": SUPERVISE_HB_MS,
                          "identify": True, "sdo_timeout_ms": SDO_TIMEOUT_MS},
    }, {
        "name": "boot", "interface": IFACES[2], "bitrate": 1000000, "node_id": OWN_ID,
        "heartbeat_ms": 0, "sdo_timeout_ms": 3000,
        "manager": {"sdo_timeout_ms": 2000, "retry_ms": 1000},
        "nodes": [{"id": MANAGED_ID, "heartbeat_ms": 3000, "device_type": hex(DEVICE_TYPE)}],
        "unknown_nodes": {"policy": "boot", "heartbeat_ms": 3000,
                          "sdo_timeout_ms": SDO_TIMEOUT_MS, "devices_dir": "devices"},
    }],
}


def ip(*args):
    subprocess.run(["ip", "link"] + list(args), check=True, capture_output=True)


def start_system():
    for name in IFACES:
        subprocess.run(["ip", "link", "del", name], capture_output=True)
        ip("add", name, "type", "vcan")
        ip("set", name, "up")
    write_devices()
    os.makedirs(CONFIG["state_dir"], exist_ok=True)
    cfg = os.path.join(WORK, "cogw.json")
    with open(cfg, "w") as f:
        json.dump(CONFIG, f)
    log = open(os.path.join(WORK, "cogwd.log"), "w")
    PROCS["cogwd"] = subprocess.Popen([os.path.join(BIN, "cogwd"), "--config", cfg],
                                      stdout=log, stderr=subprocess.STDOUT, cwd=TOP)
    deadline = time.monotonic() + 30
    while ctl("status", "0", check_rc=False).returncode != 0:
        check(time.monotonic() < deadline, "cogwd did not come up: " + read_log("cogwd"))
        time.sleep(0.2)
    for name in IFACES:
        net = canopen.Network()
        net.connect(interface="socketcan", channel=name)
        NETS.append(net)


def stop_system():
    for net in NETS:
        net.disconnect()
    for p in PROCS.values():
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    for name in IFACES:
        subprocess.run(["ip", "link", "del", name], capture_output=True)
    shutil.rmtree(WORK, ignore_errors=True)


# ---------------------------------------------------------------------------
# unknown nodes

def assert_identity(ev, node_id, vendor=VENDOR):
    eq(True, ev["identity"], f"node {node_id}: identity read")
    eq(DEVICE_TYPE, ev["device_type"], f"node {node_id}: 1000h")
    eq(vendor, ev["vendor_id"], f"node {node_id}: 1018h:1")
    eq(PRODUCT, ev["product_code"], f"node {node_id}: 1018h:2")
    eq(REVISION, ev["revision"], f"node {node_id}: 1018h:3")
    eq(1000 + node_id, ev["serial"], f"node {node_id}: 1018h:4")


def test_unknown_node_boot_up_heartbeat_emcy_reported_once_with_identity():
    mon = Monitor(IGNORE_LINE)
    nodes = []
    try:
        step("boot-up of node 20: reported once, identity read")
        n20 = local(IGNORE_LINE, 20)
        nodes.append(n20)
        boot_up(n20)
        ev = mon.unknown(20)
        eq("boot-up", ev["source"], "source")
        eq("ignore", ev["policy"], "policy")
        eq("none", ev["action"], "action")
        assert_identity(ev, 20)
        step("a second boot-up of node 20: no second report")
        boot_up(n20)

        step("heartbeat (OPERATIONAL, no boot-up) of node 21")
        n21 = local(IGNORE_LINE, 21)
        nodes.append(n21)
        heartbeat_only(n21, 0x01)
        ev = mon.unknown(21)
        eq("heartbeat", ev["source"], "source")
        assert_identity(ev, 21)

        step("EMCY of node 22 (no heartbeat at all)")
        n22 = local(IGNORE_LINE, 22)
        nodes.append(n22)
        n22.emcy.send(0x5000, 0x01)
        ev = mon.unknown(22)
        eq("emcy", ev["source"], "source")
        assert_identity(ev, 22)

        step("heartbeat in STOPPED of node 23: reported, not read (no SDO there)")
        n23 = local(IGNORE_LINE, 23)
        nodes.append(n23)
        heartbeat_only(n23, 0x02)
        ev = mon.unknown(23)
        eq(False, ev["identity"], "node 23 identity")
        check("not read: stopped" in read_log("cogwd", 0), "log: node 23 not read")

        step("heartbeat of node 3, a configured heartbeat consumer: not unknown")
        n3 = local(IGNORE_LINE, KNOWN_ID)
        nodes.append(n3)
        heartbeat_only(n3, 0x01)
        time.sleep(2.0)
        eq([], mon.of("unknown-node", KNOWN_ID), "events of the configured node 3")
        eq(1, len(mon.of("unknown-node", 20)), "reports of node 20 after two boot-ups")
        eq(1, len(mon.of("unknown-node", 21)), "reports of node 21 after many heartbeats")
        eq([1, 2, 3, 4], sorted(e["reported"] for e in mon.of("unknown-node")),
           "the line's report counter")

        step("the log names each node once, with its identity")
        log = read_log("cogwd", 0)
        eq(1, log.count("node 20 is not configured"), "log lines of node 20")
        check(f"{VENDOR:08X}/{PRODUCT:08X}/{REVISION:08X}" in log, "identity in the log")

        step("the cache has them, with where they were heard")
        cache = ctl_json("scan", str(IGNORE_LINE), "--cache")
        by_node = {n["node"]: n for n in cache["nodes"]}
        eq("boot-up", by_node[20]["source"], "cache source of 20")
        eq(f"0x{VENDOR:08X}", by_node[21]["vendor_id"], "cache vendor of 21")
        eq("emcy", by_node[22]["source"], "cache source of 22")
        eq(True, by_node[23]["stopped_not_read"], "cache: 23 not read")
        check(KNOWN_ID not in by_node, "the configured node 3 is not in the cache")
    finally:
        for n in nodes:
            remove(n)
        mon.stop()


def test_supervise_policy_consumes_the_heartbeat():
    mon = Monitor(SUPERVISE_LINE)
    n30 = local(SUPERVISE_LINE, 30, hb_ms=200)
    try:
        step("boot-up of node 30 (heartbeat 200 ms) on the supervising line")
        boot_up(n30)
        ev = mon.unknown(30)
        eq("supervise", ev["policy"], "policy")
        eq("supervised", ev["action"], "action")
        assert_identity(ev, 30)
        step("its heartbeat is consumed: hb-started")
        mon.wait("hb-started of node 30", lambda: mon.of("hb-started", 30))
        step("it goes silent: hb-lost after the consumer time")
        n30.nmt.stop_heartbeat()
        mon.wait("hb-lost of node 30", lambda: mon.of("hb-lost", 30),
                 timeout=SUPERVISE_HB_MS / 1000 + 10)
        step("it comes back: hb-started again, no second unknown-node report")
        n30.nmt.start_heartbeat(200)
        mon.wait("hb-started of node 30 again", lambda: len(mon.of("hb-started", 30)) >= 2)
        eq(1, len(mon.of("unknown-node", 30)), "reports of node 30")
    finally:
        remove(n30)
        mon.stop()


def test_boot_policy_boots_a_node_matched_by_identity():
    mon = Monitor(BOOT_LINE, "manager,boot")
    n40 = local(BOOT_LINE, 40, hb_ms=200)
    n41 = local(BOOT_LINE, 41, vendor=OTHER_VENDOR, hb_ms=200)
    try:
        step("boot-up of node 40, whose identity a-device.eds has")
        boot_up(n40)
        ev = mon.unknown(40)
        eq("boot", ev["policy"], "policy")
        eq("booting", ev["action"], "action")
        step("the manager boots it: configuration downloaded, started")
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and n40.nmt.state != "OPERATIONAL":
            time.sleep(0.1)
        eq("OPERATIONAL", n40.nmt.state, "node 40 after its boot")
        eq(BOOT_VALUE, n40.sdo[0x2000].raw, "2000h downloaded from the EDS")
        diag = ctl_json("diag", str(BOOT_LINE), "40")
        eq(True, diag["booted"], f"diag of node 40: {diag}")
        eq(5, diag["assignment"] & 5, "1F81h:40: slave, may be booted")
        eq(0, diag["assignment"] & 8, "1F81h:40: not mandatory")
        log = read_log("cogwd", 0)
        check("node 40 is booted as an optional slave with" in log and "a-device.eds" in log,
              "log: the file node 40 was booted with")
        step("boot-up of node 41 of another vendor: no file matches")
        boot_up(n41)
        ev = mon.unknown(41)
        eq("no-match", ev["action"], "action of node 41")
        time.sleep(1.0)
        eq("PRE-OPERATIONAL", n41.nmt.state, "node 41 is left alone")
    finally:
        remove(n40)
        remove(n41)
        mon.stop()


# ---------------------------------------------------------------------------
# an interface that goes away and comes back

def health(line):
    return ctl_json("health", str(line))["lines"][0]["faults"]["link-down"]


def wait_link(line, down, timeout=10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if health(line)["active"] == down:
            return
        time.sleep(0.1)
    raise AssertionError(f"line {line}: link-down still {not down}")


def recreate(line):
    """The adapter of the line unplugged and plugged in again: the
    interface deleted and created, python-canopen's socket opened anew."""
    name = IFACES[line]
    # python-can's receive thread dies with the interface (and says so at
    # the disconnect): the test's side leaves before and comes back after
    NETS[line].disconnect()
    ip("del", name)
    wait_link(line, True)
    time.sleep(1.0)
    ip("add", name, "type", "vcan")
    ip("set", name, "up")
    NETS[line].connect(interface="socketcan", channel=name)
    wait_link(line, False)


def wait_diag(node, pred, what, timeout=30.0):
    deadline = time.monotonic() + timeout
    d = None
    while time.monotonic() < deadline:
        d = ctl_json("diag", str(BOOT_LINE), str(node))
        if pred(d):
            return d
        time.sleep(0.2)
    raise AssertionError(f"node {node}: {what}; diag {d}")


def test_interface_returns_manager_reboots_and_supervision_resumes():
    mon = Monitor(SUPERVISE_LINE)
    managed = local(BOOT_LINE, MANAGED_ID, hb_ms=200)
    supervised = local(SUPERVISE_LINE, 31, hb_ms=200)
    try:
        step("node 45 (configured) booted by the manager, node 31 (unknown) supervised")
        boot_up(managed)
        d = wait_diag(MANAGED_ID, lambda d: d["booted"], "not booted")
        boots = d["boot_count"]
        boot_up(supervised)
        eq("supervised", mon.unknown(31)["action"], "node 31")
        mon.wait("hb-started of node 31", lambda: mon.of("hb-started", 31))

        step("the boot line's interface deleted and created again; node 45 was off")
        managed.nmt.stop_heartbeat()
        recreate(BOOT_LINE)
        boot_up(managed)  # switched on again with the adapter
        step("the manager boots node 45 again: configured, started")
        wait_diag(MANAGED_ID, lambda d: d["booted"] and d["boot_count"] > boots,
                  "not booted again")
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and managed.nmt.state != "OPERATIONAL":
            time.sleep(0.1)
        eq("OPERATIONAL", managed.nmt.state, "node 45 after the return")

        step("the supervising line's interface deleted and created again; node 31 "
             "kept running")
        started = len(mon.of("hb-started", 31))
        supervised.nmt.stop_heartbeat()  # its periodic frame is the old socket's
        recreate(SUPERVISE_LINE)
        supervised.nmt.start_heartbeat(200)  # on the new socket
        mon.wait("hb-lost of node 31 during the outage", lambda: mon.of("hb-lost", 31),
                 timeout=15)
        mon.wait("hb-started of node 31 after the return",
                 lambda: len(mon.of("hb-started", 31)) > started, timeout=15)
        eq(1, len(mon.of("unknown-node", 31)), "reports of node 31")
    finally:
        mon.stop()
        remove(managed)
        remove(supervised)


# ---------------------------------------------------------------------------
# the scan

def test_scan_finds_every_answering_node_within_its_bound():
    nodes = [local(IGNORE_LINE, n) for n in SCAN_PRESENT]
    # python-canopen's SDO server answers in STOPPED too; a device does not
    # (CiA 301 §7.3.2.2): this one is only its heartbeat, STOPPED
    stopped = local(IGNORE_LINE, SCAN_STOPPED)
    stopped.remove_network()
    stopped_hb = NETS[IGNORE_LINE].send_periodic(0x700 + SCAN_STOPPED, [0x04], 0.2)
    try:
        step("two scans of 1..127 asked 2 s apart: one runs, the other is BUSY")
        argv = [os.path.join(BIN, "cogwctl"), "--instance", INSTANCE, "--json", "scan",
                str(IGNORE_LINE)]
        first = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True)
        time.sleep(2.0)  # a scan takes > 10 s here; cogwctl may start slowly
        second = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True)
        runs = [p.communicate(timeout=180) + (p.returncode,) for p in (first, second)]
        busy = [r for r in runs if r[2] != 0]
        done = [r for r in runs if r[2] == 0]
        check(len(busy) == 1 and len(done) == 1 and
              json.loads(busy[0][0])["error"].startswith("busy"),
              f"two scans at once: {runs}")
        res = json.loads(done[0][0])
        found = {n["node"]: n for n in res["nodes"]}
        eq(sorted(SCAN_PRESENT), sorted(found), "nodes found")
        for n in SCAN_PRESENT:
            eq(f"0x{DEVICE_TYPE:08X}", found[n]["device_type"], f"node {n} 1000h")
            eq(f"0x{VENDOR:08X}", found[n]["vendor_id"], f"node {n} vendor")
            eq(f"0x{1000 + n:08X}", found[n]["serial"], f"node {n} serial")
            eq("scan", found[n]["source"], f"node {n} source")
        eq(8, res["parallel"], "nodes asked at once (the line's SDO clients)")
        eq(SDO_TIMEOUT_MS, res["timeout_ms"], "per-frame timeout")
        check(res["duration_ms"] <= res["bound_ms"],
              f"scan took {res['duration_ms']} ms, bound {res['bound_ms']} ms")
        # every node-ID but ours asked for 1000h, the 8 for 1018h:1..4 too
        eq(126 + 8 * 4, res["requests"], "SDO requests of the scan")
        print(f"  scan 1..127, 8 present: {res['duration_ms']} ms "
              f"(bound {res['bound_ms']} ms, {res['requests']} requests)", file=sys.stderr)

        step("the cache answers at once with the same nodes")
        cache = ctl_json("scan", str(IGNORE_LINE), "--cache")
        cached = {n["node"] for n in cache["nodes"]}
        check(set(SCAN_PRESENT) <= cached, f"cache {sorted(cached)}")
        check(SCAN_STOPPED not in cached, "the silent node is not in the cache")
        eq(res["duration_ms"], cache["duration_ms"], "the last scan's figures")

        step("a part of the range, one node at a time")
        part = ctl_json("scan", str(IGNORE_LINE), "--nodes", "60-63", "--parallel", "1")
        eq([60, 61, 62, 63], [n["node"] for n in part["nodes"]], "nodes 60-63")
        eq(1, part["parallel"], "parallel 1")

        step("bad arguments are refused before the daemon is asked")
        for bad in (["--nodes", "0-5"], ["--nodes", "9-3"], ["--timeout-ms", "5001"],
                    ["--parallel", "129"]):
            r = ctl("scan", str(IGNORE_LINE), *bad, check_rc=False)
            eq(2, r.returncode, f"cogwctl scan {' '.join(bad)}")
    finally:
        for n in nodes:
            remove(n)
        stopped_hb.stop()


def main():
    faulthandler.enable()
    try:
        start_system()
        for t in (test_unknown_node_boot_up_heartbeat_emcy_reported_once_with_identity,
                  test_supervise_policy_consumes_the_heartbeat,
                  test_boot_policy_boots_a_node_matched_by_identity,
                  test_scan_finds_every_answering_node_within_its_bound,
                  test_interface_returns_manager_reboots_and_supervision_resumes):
            if selected(t):
                run_test(t, "tests/interop/test_network.py", on_failure)
    except Exception:  # noqa: BLE001 - set-up failure: one failed test
        traceback.print_exc()
        RESULTS.append(False)
        print("cogwd log:\n" + read_log("cogwd"))
    finally:
        stop_system()
    return summary()


if __name__ == "__main__":
    sys.exit(main())
