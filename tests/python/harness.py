"""harness.py - runs gonio-sim and goniod on the simulated rig for the Python client's tests
(tests/python), as tests/e2e/harness.c does for the C ones, and the checks of those tests.

A test is `python3 test_client.py CASE GONIOD GONIO_SIM SOURCE_ROOT` with the module on
PYTHONPATH; it exits 0 when it passes, 1 when a check fails."""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
START_TIMEOUT = 30.0  # s for gonio-sim to say "ready" and goniod to listen


class CheckFailed(Exception):
    """A check of a test failed."""


def check(cond, what, *values):
    """Fails the test with what (and the values) unless cond."""
    if not cond:
        raise CheckFailed(what + "".join(f"\n  {v!r}" for v in values))


class Rig:
    """gonio-sim and goniod on tests/python/rig.yaml in a temp dir, started by start() (or
    `with`), stopped and removed by stop(); self.sock is goniod's socket."""

    def __init__(self, goniod, gonio_sim, time_scale=10, rig=None):
        self.goniod, self.gonio_sim, self.time_scale = goniod, gonio_sim, time_scale
        self.dir = tempfile.mkdtemp(prefix="gonio-py-")
        self.rig = os.path.join(self.dir, "rig.yaml")
        self.sock = os.path.join(self.dir, "goniod.sock")
        self.data = os.path.join(self.dir, "data")
        shutil.copyfile(rig or os.path.join(HERE, "rig.yaml"), self.rig)
        self.env = dict(os.environ, GONIO_SIM_DIR=os.path.join(self.dir, "sim"),
                        GONIO_SOCKET=self.sock)
        self.sim = self.daemon = None
        self.killed = False  # goniod was killed (its exit status is not checked)

    def __enter__(self):
        return self.start()

    def __exit__(self, exc_type, *exc):
        statuses = self.stop()
        if exc_type is None:  # under ASan a leak makes the status non-zero
            check(statuses["gonio-sim"] == 0 and (self.killed or statuses["goniod"] == 0),
                  "exit statuses", statuses, self.logs)

    def start(self):
        """Starts gonio-sim and goniod; returns self."""
        with open(os.path.join(self.dir, "gonio-sim.log"), "ab") as log:
            self.sim = subprocess.Popen(
                [self.gonio_sim, "--rig", self.rig, "--dir", self.env["GONIO_SIM_DIR"],
                 "--time-scale", str(self.time_scale)],
                env=self.env, stdout=subprocess.PIPE, stderr=log)
        self._wait_ready()
        self.start_daemon()
        return self

    def _wait_ready(self):
        end = time.monotonic() + START_TIMEOUT
        os.set_blocking(self.sim.stdout.fileno(), False)
        seen = b""
        while b"ready" not in seen:
            check(time.monotonic() < end and self.sim.poll() is None, "gonio-sim did not start")
            seen += self.sim.stdout.read() or b""
            time.sleep(0.02)

    def start_daemon(self):
        """Starts goniod (again) and waits until its socket answers."""
        with open(os.path.join(self.dir, "goniod.log"), "ab") as log:
            self.daemon = subprocess.Popen(
                [self.goniod, "--rig", self.rig, "--socket", self.sock, "--data", self.data],
                env=self.env, stdout=subprocess.DEVNULL, stderr=log)
        end = time.monotonic() + START_TIMEOUT
        while True:
            check(time.monotonic() < end and self.daemon.poll() is None, "goniod did not start",
                  self.log("goniod"))
            with socket.socket(socket.AF_UNIX) as s:
                if s.connect_ex(self.sock) == 0:
                    return
            time.sleep(0.02)

    def sim_request(self, request):
        """Sends request (a dict, e.g. a fault injection: docs/sim.md) to gonio-sim's control
        socket and checks that it answers ok."""
        with socket.socket(socket.AF_UNIX) as s:
            s.settimeout(START_TIMEOUT)
            s.connect(os.path.join(self.env["GONIO_SIM_DIR"], "control.sock"))
            s.sendall(json.dumps(request).encode() + b"\n")
            reply = s.makefile("rb").readline()
        check(json.loads(reply).get("ok") is True, "gonio-sim refused", request, reply)

    def kill_daemon(self):
        """SIGKILLs goniod, as a crash would."""
        self.daemon.kill()
        self.daemon.wait()
        self.killed = True

    def log(self, prog):
        """What prog ("goniod", "gonio-sim") wrote on stderr ("" before it started)."""
        try:
            with open(os.path.join(self.dir, prog + ".log"), errors="replace") as f:
                return f.read()
        except FileNotFoundError:
            return ""

    def stop(self):
        """SIGTERMs both programs, keeps their logs in self.logs, removes the temp dir and
        returns their exit statuses by name (negative: the signal that ended one; None: it
        never started)."""
        statuses = {}
        for name, p in (("goniod", self.daemon), ("gonio-sim", self.sim)):
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGTERM)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            statuses[name] = None if p is None else p.returncode
        if self.sim is not None:
            self.sim.stdout.close()
        self.logs = self.log("goniod") + self.log("gonio-sim")
        shutil.rmtree(self.dir, ignore_errors=True)
        return statuses


def main(cases):
    """Runs the case named by argv[1] (a function of cases taking argv) and exits 0 or 1."""
    if len(sys.argv) < 2 or sys.argv[1] not in cases:
        print(f"usage: {sys.argv[0]} {'|'.join(cases)} ARGS...", file=sys.stderr)
        sys.exit(2)
    t0 = time.monotonic()
    try:
        cases[sys.argv[1]](sys.argv[2:])
    except CheckFailed as e:
        print(f"FAIL {sys.argv[1]}: {e}", file=sys.stderr)
        sys.exit(1)
    print(f"ok {sys.argv[1]} ({time.monotonic() - t0:.2f} s, python {sys.version.split()[0]})")
