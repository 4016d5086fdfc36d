# SPDX-License-Identifier: MIT
"""The package's tests against a real cogwd on vcan (tests/python/run, in
the VM of `make test`) with python-canopen devices:

  line 0 (vcan0): python-canopen LocalNode 5, known by the EDS this file
      writes (names, types, a Factor), for SDO, NMT, EMCY and events;
  line 1 (vcan1): a CiA 302-2 manager, and python-canopen LocalNode 12 with
      the program download objects (1F50h, 1F51h, 1F56h);
  line 2 (vcan2, network 3): device objects (pdo "auto") of LocalNode 20,
      whose EDS gives a TPDO and an RPDO; reached from line 0 by routing too.

Results print Unity-style (file:line:name:PASS/FAIL, then "N Tests M
Failures K Ignored") so that tests/run-tests counts them."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import can
import canopen
import pytest

TOP = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(TOP, "python", "src"))

import cogw  # noqa: E402

BIN = os.environ.get("COGW_BIN", os.path.join(TOP, "build", "san", "bin"))
INSTANCE = "pytest"
NODE = 5          # python-canopen LocalNode on line 0
PROGRAM_NODE = 12  # on line 1, with the program download objects
DEV = 20          # on line 2, device objects
SDO_TIMEOUT_MS = 5000

# ---- Unity-style results ---------------------------------------------------------------

_COUNTS = {"tests": 0, "failures": 0, "ignored": 0}


def pytest_runtest_logreport(report):
    if report.when == "call" or (report.when == "setup" and not report.passed):
        status = "PASS" if report.passed else "IGNORE" if report.skipped else "FAIL"
        _COUNTS["tests"] += 1
        _COUNTS["failures"] += status == "FAIL"
        _COUNTS["ignored"] += status == "IGNORE"
        path, line, name = report.location
        tr = _CONFIG[0].pluginmanager.get_plugin("terminalreporter") if _CONFIG else None
        why = ""
        if status == "FAIL":
            why = ": " + str(report.longrepr.reprcrash.message if hasattr(
                report.longrepr, "reprcrash") else report.longrepr).splitlines()[0]
        if tr is not None:
            tr.write_line(f"python/tests/{os.path.basename(path)}:{(line or 0) + 1}:"
                          f"{name}:{status}{why}")


_CONFIG: list = []


def pytest_report_teststatus(report, config):
    """No progress letters: the Unity lines say it."""
    if report.when == "call":
        return report.outcome, "", report.outcome.upper()
    return None


def pytest_configure(config):
    _CONFIG.append(config)


def pytest_unconfigure(config):
    print("\n-----------------------")
    print(f"{_COUNTS['tests']} Tests {_COUNTS['failures']} Failures {_COUNTS['ignored']} Ignored")
    print("OK" if _COUNTS["failures"] == 0 else "FAIL", flush=True)


# ---- the devices' files ------------------------------------------------------------------

def _var(index, name, dtype, access, default=None, sub=None, extra=""):
    sect = f"{index:04X}" if sub is None else f"{index:04X}sub{sub}"
    text = (f"[{sect}]\nParameterName={name}\nObjectType=0x7\nDataType=0x{dtype:04X}\n"
            f"AccessType={access}\nPDOMapping=1\n")
    if default is not None:
        text += f"DefaultValue={default}\n"
    return text + extra


def _record(index, name, subs):
    text = f"[{index:04X}]\nParameterName={name}\nObjectType=0x9\nSubNumber={len(subs)}\n"
    for sub, (sname, dtype, access, default) in enumerate(subs):
        text += _var(index, sname, dtype, access, default, sub)
    return text


def _pdo(comm, mapping, cob, tt, entries, tpdo):
    subs = [("Highest sub-index supported", 0x5, "ro", 6 if tpdo else 5),
            ("COB-ID", 0x7, "rw", hex(cob)), ("Transmission type", 0x5, "rw", tt),
            ("Inhibit time", 0x6, "rw", 0), ("Reserved", 0x5, "rw", 0),
            ("Event timer", 0x6, "rw", 0)]
    if tpdo:
        subs.append(("SYNC start value", 0x5, "rw", 0))
    maps = [("Number of entries", 0x5, "rw", len(entries))]
    maps += [(f"Entry {i}", 0x7, "rw", f"0x{idx:04X}00{bits:02X}")
             for i, (idx, bits) in enumerate(entries, 1)]
    return _record(comm, "PDO communication", subs) + _record(mapping, "PDO mapping", maps)


def _eds(node_id, body):
    return (f"[FileInfo]\nFileName=dev{node_id}.eds\nFileVersion=1\nEDSVersion=4.0\n"
            f"[DeviceInfo]\nVendorName=cogw tests\nVendorNumber=0x42\nProductNumber={node_id}\n"
            + _var(0x1000, "Device type", 0x7, "ro", "0x191")
            + _var(0x1017, "Producer heartbeat time", 0x6, "rw", 0)
            + _record(0x1018, "Identity object", [("Highest sub-index supported", 0x5, "ro", 4),
                                                  ("Vendor-ID", 0x7, "ro", "0x42"),
                                                  ("Product code", 0x7, "ro", node_id),
                                                  ("Revision number", 0x7, "ro", 3),
                                                  ("Serial number", 0x7, "ro", 4711)])
            + body)


def node5_eds():
    return _eds(NODE,
                _var(0x2000, "Speed", 0x3, "rw", 0, extra="Factor=0.1\nUnit=km/h\n")
                + _var(0x2001, "Name", 0x9, "rw", "motor")
                + _var(0x2002, "Blob", 0xF, "rw")
                + _var(0x2003, "Ratio", 0x8, "rw", 0)
                + _record(0x2004, "Limits", [("Highest sub-index supported", 0x5, "ro", 2),
                                             ("Low", 0x4, "rw", -100), ("High", 0x4, "rw", 100)]))


def node20_eds():
    return _eds(DEV,
                _pdo(0x1800, 0x1A00, 0x180 + DEV, 254, [(0x2101, 16), (0x2102, 16)], True)
                + _pdo(0x1400, 0x1600, 0x200 + DEV, 254, [(0x2200, 8)], False)
                + _var(0x2101, "Position", 0x6, "ro", 0)
                + _var(0x2102, "Current", 0x3, "ro", 0, extra="Factor=0.01\nUnit=A\n")
                + _var(0x2200, "Output", 0x5, "rww", 0)
                + _var(0x2300, "Setting", 0x7, "rw", 17))


def config(work):
    return {
        "version": 1,
        "state_dir": os.path.join(work, "state"),
        "mailbox": {"instance": INSTANCE},
        "lines": [{
            "name": "line0", "interface": "vcan0", "bitrate": 1000000, "node_id": 127,
            "heartbeat_ms": 0, "sdo_timeout_ms": SDO_TIMEOUT_MS,
            "heartbeat_consumers": [{"node_id": NODE, "time_ms": 3000}],
            "objects": [
                {"index": "0x2001", "name": "setting", "type": "UNSIGNED32", "access": "rw",
                 "default": 7},
                {"index": "0x2002", "name": "label", "type": "DOMAIN", "access": "rw",
                 "max_size": 4096},
            ],
        }, {
            "name": "line1", "interface": "vcan1", "bitrate": 1000000, "node_id": 1,
            "heartbeat_ms": 0, "sdo_timeout_ms": SDO_TIMEOUT_MS,
            "manager": {"sdo_timeout_ms": 2000},
            "nodes": [],
        }, {
            "name": "line2", "interface": "vcan2", "bitrate": 1000000, "node_id": 1,
            "heartbeat_ms": 0, "sdo_timeout_ms": SDO_TIMEOUT_MS,
            "rpdos": 4, "tpdos": 4, "pdo": "auto",
            "device_objects": {"read_max_age_ms": 600000, "write_update_ms": 20},
            "nodes": [{"id": DEV, "eds": os.path.join(work, "dev20.eds")}],
        }],
    }


# ---- the system under test -------------------------------------------------------------

class System:
    def __init__(self):
        self.work = tempfile.mkdtemp(prefix="cogw-pytest-")
        self.procs = {}
        self.nets = {}
        self.locals = {}
        self.eds = {NODE: os.path.join(self.work, "dev5.eds"),
                    DEV: os.path.join(self.work, "dev20.eds")}

    def start(self):
        with open(self.eds[NODE], "w") as f:
            f.write(node5_eds())
        with open(self.eds[DEV], "w") as f:
            f.write(node20_eds())
        os.makedirs(os.path.join(self.work, "state"))
        cfg = os.path.join(self.work, "cogw.json")
        with open(cfg, "w") as f:
            json.dump(config(self.work), f)
        for iface in ("vcan0", "vcan1", "vcan2"):
            net = canopen.Network()
            net.connect(interface="socketcan", channel=iface)
            self.nets[iface] = net
        self.locals[NODE] = self._local("vcan0", NODE, canopen.import_od(self.eds[NODE], NODE))
        self.locals[PROGRAM_NODE] = self._local("vcan1", PROGRAM_NODE, program_od())
        dev = self._local("vcan2", DEV, canopen.import_od(self.eds[DEV], DEV))
        dev.tpdo.read(from_od=True)
        dev.rpdo.read(from_od=True)
        self.locals[DEV] = dev
        log = open(os.path.join(self.work, "cogwd.log"), "w")
        self.procs["cogwd"] = subprocess.Popen([os.path.join(BIN, "cogwd"), "--config", cfg],
                                               stdout=log, stderr=subprocess.STDOUT, cwd=TOP)
        self._wait_up()
        # the daemon's node of line 2 takes the mirrored TPDOs only when
        # OPERATIONAL (CiA 301 §7.3.2.2): start every node there
        self.nets["vcan2"].send_message(0x000, bytes([0x01, 0x00]))

    def _local(self, iface, node_id, od):
        node = canopen.LocalNode(node_id, od)
        self.nets[iface].add_node(node)
        return node

    def _wait_up(self):
        deadline = time.monotonic() + 30
        with cogw.connect(INSTANCE) as gw:
            while True:
                try:
                    for line in range(3):
                        gw.line(line).status()
                    return
                except cogw.CogwError:
                    if time.monotonic() > deadline or self.procs["cogwd"].poll() is not None:
                        raise RuntimeError("cogwd did not come up: " + self.log())
                    time.sleep(0.2)

    def log(self):
        try:
            with open(os.path.join(self.work, "cogwd.log")) as f:
                return f.read()[-3000:]
        except OSError:
            return ""

    def stop(self):
        for net in self.nets.values():
            net.disconnect()
        for p in self.procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(15)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        shutil.rmtree(self.work, ignore_errors=True)


def program_od():
    from canopen.objectdictionary import ODRecord, ODVariable, ObjectDictionary, datatypes
    od = ObjectDictionary()
    for index, name, dtype, default in ((0x1F50, "Program data", datatypes.DOMAIN, None),
                                        (0x1F51, "Program control", datatypes.UNSIGNED8, 0),
                                        (0x1F56, "Program software identification",
                                         datatypes.UNSIGNED32, 0x3C2A91F0)):
        rec = ODRecord(name, index)
        n = ODVariable("Highest sub-index supported", index, 0)
        n.data_type, n.access_type, n.default = datatypes.UNSIGNED8, "ro", 1
        rec.add_member(n)
        v = ODVariable(name, index, 1)
        v.data_type = dtype
        v.access_type = "ro" if index == 0x1F56 else "rw"
        if default is not None:
            v.default = default
        rec.add_member(v)
        od.add_object(rec)
    return od


@pytest.fixture(scope="session")
def system():
    s = System()
    try:
        s.start()
    except BaseException:
        print(s.log())
        s.stop()
        raise
    yield s
    if os.environ.get("COGW_PYTEST_LOG"):
        print(s.log())
    s.stop()


@pytest.fixture()
def gw(system):
    with cogw.connect(INSTANCE, timeout_ms=20000) as c:
        yield c


@pytest.fixture()
def bus():
    """Frames seen on a vcan line during a test (a plain python-can reader)."""
    buses = []

    def open_bus(iface):
        b = can.Bus(interface="socketcan", channel=iface)
        buses.append(b)
        return b
    yield open_bus
    for b in buses:
        b.shutdown()
