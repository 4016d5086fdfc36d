# SPDX-License-Identifier: MIT
"""tests/interop/interop.py - what an interop script needs around its tests:
the step it is at (printed when a test fails; as it goes with
COGW_INTEROP_VERBOSE=1), the checks, and the Unity-style result lines that
tests/run-tests counts (file:line:name:PASS/FAIL, then the summary)."""
import json
import os
import subprocess
import sys
import threading
import time
import traceback

STEP = [""]
RESULTS = []
T0 = time.monotonic()


def step(text):
    STEP[0] = text
    if os.environ.get("COGW_INTEROP_VERBOSE"):
        print(f"  [{time.monotonic() - T0:7.1f} s] {text}", file=sys.stderr, flush=True)


def check(cond, msg):
    if not cond:
        raise AssertionError(msg)


def eq(want, got, what):
    if want != got:
        raise AssertionError(f"{what}: expected {want!r}, got {got!r}")


def selected(fn):
    """COGW_TEST_ONLY=word,word: only the tests whose names contain one."""
    only = os.environ.get("COGW_TEST_ONLY")
    return not only or any(o in fn.__name__ for o in only.split(","))


def run_test(fn, script, on_failure):
    """Run one test of `script` (its path from the repository root); a
    failure names the line in the script, the step, then on_failure()."""
    line = fn.__code__.co_firstlineno
    step(fn.__name__)
    try:
        fn()
        print(f"{script}:{line}:{fn.__name__}:PASS", flush=True)
        RESULTS.append(True)
    except Exception as exc:  # noqa: BLE001 - report every failure the same way
        tb = traceback.extract_tb(exc.__traceback__)
        name = os.path.basename(script)
        where = next((f.lineno for f in reversed(tb) if f.filename.endswith(name)), line)
        msg = f"{type(exc).__name__}: {exc}".replace("\n", " ")
        print(f"{script}:{where}:{fn.__name__}:FAIL: {msg}", flush=True)
        print("  step: " + STEP[0])
        on_failure()
        RESULTS.append(False)


def summary():
    """The closing lines; the exit status."""
    failed = RESULTS.count(False)
    print("\n-----------------------")
    print(f"{len(RESULTS)} Tests {failed} Failures 0 Ignored")
    print("OK" if failed == 0 else "FAIL")
    return 1 if failed else 0


class Monitor:
    """A mailbox subscriber: `cogwctl [OPTIONS] --json monitor --line LINE
    --class CLASSES` (cogwctl_argv: the program and its global options) in
    the background, its events collected as they come."""

    def __init__(self, cogwctl_argv, classes, line=0, cwd=None):
        argv = list(cogwctl_argv) + ["--json", "monitor", "--line", str(line),
                                     "--class", classes]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, cwd=cwd)
        self.events = []
        # it says on stderr when its subscriptions are in place
        said = self.proc.stderr.readline()
        check("watching" in said, f"cogwctl monitor: {said!r}")
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.events.append(json.loads(line))

    def of(self, *names):
        return [e for e in list(self.events) if e["event"] in names]

    def wait(self, what, pred, timeout=5.0):
        """Until pred() gives something true; that."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            got = pred()
            if got:
                return got
            time.sleep(0.05)
        raise AssertionError(f"subscriber: no {what}; got {self.events[-10:]}")

    def stop(self):
        self.proc.terminate()
        self.proc.wait(10)
