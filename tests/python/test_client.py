"""test_client.py - the Python client (python/gonio.py) against goniod on the simulated rig,
and against a server that breaks the protocol (suite python).

    PYTHONPATH=SOURCE_ROOT/python python3 test_client.py CASE GONIOD GONIO_SIM SOURCE_ROOT

Cases: hello (hello, describe, status, errors of requests), move (moves and their errors,
notifications, parallel moves, stop, lamps), session (capture_at, a session run to its end
with its progress), fault (a device fault, a session paused by another client and resumed), closed (goniod killed under a pending request), broken (malformed
replies, silence, a late reply: a fake server), example (examples/scripts/capture.py)."""

import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

import gonio
from harness import Rig, check, main

SESSION = """\
name: s1
dataset: ds1
sweep:
  turntable: { from: 0, to: 270, step: 90 }
cameras: [cam0]
lamps: [lamp0, lamp1]
skip_occluded: false
skip_glare: false
"""


def rig_of(argv, time_scale=10):
    """The Rig of the test's arguments."""
    return Rig(argv[0], argv[1], time_scale)


def expect_error(code, fn, *args, **kw):
    """Calls fn and checks that it raises GonioError with code; returns the error."""
    try:
        fn(*args, **kw)
    except gonio.GonioError as e:
        check(e.code == code, f"error code {e.code}, expected {code}", str(e))
        return e
    check(False, f"{fn.__name__} did not fail")


def case_hello(argv):
    with rig_of(argv) as rig:
        os.environ["GONIO_SOCKET"] = rig.sock
        check(gonio.socket_path() == rig.sock, "socket_path ignores $GONIO_SOCKET")
        with gonio.Client() as c:
            check(c.server["server"] == "goniod" and c.server["protocol"] == gonio.PROTOCOL
                  and c.server["rig"] == "py", "hello", c.server)
            devices = c.describe()["devices"]
            check([d["class"] for d in devices] == ["axis"] * 3 + ["lamp"] * 2 + ["laser"]
                  + ["camera"] * 2, "describe", devices)
            st = c.status()
            check([lamp["name"] for lamp in st["lamps"]] == ["lamp0", "lamp1"], "status", st)
            expect_error(gonio.METHOD_NOT_FOUND, c.call, "no.such.method")
            e = expect_error(gonio.INVALID_PARAMS, c.call, "move", {"axis": "turntable",
                                                                    "position": 1, "sped": 2})
            check(e.errno_name == "EINVAL", "errno of invalid params", e.data)
            expect_error(gonio.E_NOT_FOUND, c.lamp_set, "lamp9", True)
            check(c.dataset_list()["datasets"] == [], "datasets")
        check(c.closed, "the context manager closed the connection")
        check(isinstance(expect_error(None, c.status), gonio.ConnectionClosed), "closed")
        e = expect_error(None, gonio.Client, os.path.join(rig.dir, "nothing.sock"))
        check(e.errno_name == "ENOENT", "connect to nothing", e.data)


def case_move(argv):
    with rig_of(argv) as rig:
        c = gonio.Client(rig.sock)
        check({a["name"] for a in c.home()["axes"]} == {"turntable", "light_arm", "camera_arm"},
              "home")
        check(abs(c.move("camera_arm", 45)["position"] - 45) < 0.01, "move")
        e = expect_error(gonio.E_RANGE, c.move, "camera_arm", 200)
        check("soft limits" in e.message and e.errno_name == "ERANGE", "past a soft limit", e)
        expect_error(gonio.E_NOT_FOUND, c.move, axis="elevator", position=1)
        check(c.device_set("camera_arm", "speed", 20)["value"] == 20, "device_set")
        got = c.device_get("camera_arm", "speed")
        check(got["value"] == 20 and got["limit"] == "max_speed", "device_get", got)
        e = expect_error(gonio.E_RANGE, c.device_set, "camera_arm", "speed", 1e6)
        check("max_speed" in e.message, "a speed past max_speed", e)
        c.take_events()
        check(c.move("turntable", 30, wait=False)["target"] == 30, "move without waiting")
        done = c.next_event(5, methods=("move.done",))
        check(done.params["axis"] == "turntable" and abs(done.params["position"] - 30) < 0.01,
              "move.done", done)
        check(c.wait_idle(5)["state"] == "idle", "wait_idle")
        seen = [ev.method for ev in c.take_events()]
        check("axis.moved" in seen and "state.changed" in seen, "notifications kept", seen)
        reached = c.goto(turntable=90, light_arm=30, camera_arm=-20)
        want = {"turntable": 90, "light_arm": 30, "camera_arm": -20}
        check(reached.keys() == want.keys()
              and all(abs(reached[k] - want[k]) < 0.01 for k in want), "goto", reached)
        expect_error(gonio.E_RANGE, c.goto, {"camera_arm": -180, "light_arm": 210})
        arm = c.status()["axes"][1]
        check(abs(arm["position"] - 210) < 0.01 and not arm["moving"], "goto waits", arm)
        check(c.set_lamps(["lamp1"]) == ["lamp1"], "set_lamps")
        check([lamp["on"] for lamp in c.status()["lamps"]] == [False, True], "lamps")
        c.take_events()  # the next axis.moved is the turntable's, moving
        rid = c.send("move", {"axis": "turntable", "position": 3000, "relative": True})
        c.next_event(5, methods=("axis.moved",))
        check(c.stop()["stopped"] == ["turntable"], "stop")
        expect_error(gonio.E_CANCELED, c.wait, rid)
        c.close()


def case_session(argv):
    with rig_of(argv) as rig:
        c = gonio.Client(rig.sock)
        c.home()
        c.dataset_open("manual", create=True)
        caps = c.capture_at({"turntable": 45, "light_arm": 10}, lamps=[0], laser=False)
        check([(x["camera"], x["turntable"], x["lamps"]) for x in caps]
              == [("cam0", 45, "lamp0"), ("cam1", 45, "lamp0")], "capture_at", caps)
        e = expect_error(gonio.INVALID_PARAMS, c.session_plan, "bad.yaml", "name: x\nsweep: 3\n")
        check(e.message.startswith("bad.yaml:"), "session file error names the file", e)
        path = os.path.join(rig.dir, "s1.yaml")
        with open(path, "w") as f:
            f.write(SESSION)
        planned = c.session_plan(path)["captures"]
        seen = []
        final = c.run_session(path, on_progress=seen.append, timeout=20)
        check(final["ended"] == "done" and final["captured"] == planned == 8, "session", final)
        captured = [st["captured"] for st in seen if st["state"] == "running"]
        check(captured and captured == sorted(captured), "progress", seen)
        stored = c.take_events(("capture.stored",))
        check(len(stored) == planned + len(caps), "capture.stored kept", len(stored))
        check(c.dataset_check("ds1")["problems"] == [], "dataset check")
        expect_error(gonio.E_NOT_FOUND, c.session_resume, "ds1")
        c.close()


def case_fault(argv):
    with rig_of(argv) as rig:
        c, other = gonio.Client(rig.sock), gonio.Client(rig.sock)
        c.home()
        rig.sim_request({"cmd": "inject", "bus": "drives", "unit": 1, "fault": "stall"})
        expect_error(gonio.E_DEVICE, c.move, "turntable", 170)
        e = expect_error(gonio.E_STATE, c.wait_idle, 10)
        check(e.data["status"]["fault"]["device"] == "turntable", "fault", e.data)
        fault = c.next_event(5, ("fault",)).params
        check(fault["device"] == "turntable" and fault["code"] == gonio.E_DEVICE, "note", fault)
        rig.sim_request({"cmd": "inject", "bus": "drives", "unit": 1, "fault": "none"})
        c.fault_clear()
        c.home(["turntable"])
        path = os.path.join(rig.dir, "s1.yaml")
        with open(path, "w") as f:
            f.write(SESSION)
        paused = []

        def pause_once(st):  # another client pauses the session after its first capture
            if st.get("captured") and not paused:
                paused.append(other.session_pause())
        e = expect_error(gonio.E_CANCELED, c.run_session, path, timeout=20, on_progress=pause_once)
        check(e.data["status"]["state"] == "paused", "paused", e.data)
        final = c.follow_session(c.session_resume(), timeout=20)
        check(final["ended"] == "done" and final["captured"] == 8, "resumed", final)
        c.close()
        other.close()


def case_closed(argv):
    with rig_of(argv) as rig:
        c = gonio.Client(rig.sock)
        c.home()
        c.take_events()  # the next axis.moved is the turntable's, moving
        rid = c.send("move", {"axis": "turntable", "position": 3000, "relative": True})
        c.next_event(5, methods=("axis.moved",))
        rig.kill_daemon()
        t0 = time.monotonic()
        e = expect_error(None, c.wait, rid, 10)
        check(isinstance(e, gonio.ConnectionClosed) and "closed" in e.message, "killed", e)
        check(time.monotonic() - t0 < 2, "noticed at once")
        check(c.closed and isinstance(expect_error(None, c.status), gonio.ConnectionClosed),
              "closed after")
        expect_error(None, gonio.Client, rig.sock)


def hello_v1(req, conn):
    send(conn, {"id": req["id"], "result": {"server": "fake", "protocol": 1}})


class FakeServer:
    """A Unix socket server for one connection: answers hello with the function hello, then
    each request with script, functions of (request, connection) that send what they like;
    the connection is closed when script returns False."""

    def __init__(self, path, script, hello=hello_v1):
        self.script, self.hello = script, hello
        self.lsock = socket.socket(socket.AF_UNIX)
        self.lsock.bind(path)
        self.lsock.listen()
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        with self.lsock:
            conn, _ = self.lsock.accept()
        with conn, conn.makefile("rb") as f:
            try:
                for line in f:
                    req = json.loads(line)
                    answer = self.hello if req["method"] == "hello" else self.script
                    if answer(req, conn) is False:
                        return
            except OSError:  # the client closed the connection: it is done
                pass


def send(conn, msg):
    conn.sendall(json.dumps(dict(jsonrpc="2.0", **msg)).encode() + b"\n")


def case_broken(argv):
    tmp = tempfile.mkdtemp(prefix="gonio-py-")

    def client(name, script, timeout=0.5, hello=hello_v1):
        FakeServer(os.path.join(tmp, name), script, hello)
        return gonio.Client(os.path.join(tmp, name), timeout=timeout)
    try:
        bad_replies(client)
        odd_replies(client)
        late_reply(client)
    finally:
        shutil.rmtree(tmp)


def bad_replies(client):
    """Malformed replies, a closed connection, silence: a clear exception in time each."""
    def broken(name, script, cls, words):
        c = client(name, script)
        t0 = time.monotonic()
        e = expect_error(None, c.status)
        check(isinstance(e, cls) and words in e.message, name, type(e), e.message)
        check(time.monotonic() - t0 < 2, name + ": no hang")
        check(cls is gonio.Timeout or c.closed, name + ": connection closed")
        c.close()

    broken("garbage", lambda req, conn: conn.sendall(b"not json\n"), gonio.ProtocolError,
           "bad message")
    broken("dup", lambda req, conn: conn.sendall(
        b'{"jsonrpc":"2.0","id":%d,"result":{},"result":{}}\n' % req["id"]),
        gonio.ProtocolError, "duplicate")
    broken("noresult", lambda req, conn: send(conn, {"id": req["id"]}), gonio.ProtocolError,
           "exactly one of result and error")
    broken("otherid", lambda req, conn: send(conn, {"id": 99, "result": {}}), gonio.ProtocolError,
           "answers no request")
    broken("long", lambda req, conn: conn.sendall(b"x" * 70000), gonio.ProtocolError, "longer")
    broken("close", lambda req, conn: False, gonio.ConnectionClosed, "closed the connection")
    broken("silent", lambda req, conn: None, gonio.Timeout, "no reply to 'status'")


def odd_replies(client):
    """Another protocol version, an error with "id": null, and the params the methods send."""
    def hello_v2(req, conn):
        send(conn, {"id": req["id"], "result": {"server": "fake", "protocol": 2}})
    e = expect_error(None, client, "v2", None, hello=hello_v2)
    check(isinstance(e, gonio.ProtocolError) and "protocol 2" in e.message, "version", e)

    c = client("null", lambda req, conn: send(conn, {
        "id": None, "error": {"code": -32700, "message": "parse error"}}))
    e = expect_error(gonio.PARSE_ERROR, c.status)
    check(e.message == "parse error", "id-null error answers the request", e)
    c.close()

    c = client("echo", lambda req, conn: send(conn, {"id": req["id"], "result": req["params"]}))
    check(c.scan_continuous("d1", from_=10, to=20) == {"dataset": "d1", "from": 10, "to": 20}
          and c.move("turntable", 5) == {"axis": "turntable", "position": 5, "relative": False,
                                         "wait": True}
          and c.session_plan(__file__)["text"].startswith('"""test_client.py'), "params")
    c.close()


def late_reply(client):
    """A reply that comes after its wait timed out is skipped; notifications stay queued."""
    def late(req, conn):  # answers a status late, the one after at once, with notifications
        if req["id"] == 2:
            time.sleep(0.5)
        send(conn, {"method": "state.changed", "params": {"state": "moving"}})
        send(conn, {"id": req["id"], "result": {"n": req["id"]}})
    c = client("late", late, timeout=0.2)
    expect_error(None, c.status)
    check(c.status(timeout=2) == {"n": 3}, "the late reply is skipped")
    evs = []
    try:
        for ev in c.events(timeout=0.2):
            evs.append(ev)
    except gonio.Timeout:
        pass
    check(evs == [gonio.Event("state.changed", {"state": "moving"})] * 2, "events", evs)
    c.close()


def case_example(argv):
    with rig_of(argv, 20) as rig:
        script = os.path.join(argv[2], "examples", "scripts", "capture.py")
        env = dict(rig.env, PYTHONPATH=os.path.join(argv[2], "python"))
        out = subprocess.run([sys.executable, script, "ex1"], env=env, capture_output=True,
                             text=True, timeout=30)
        print(out.stdout, out.stderr)
        check(out.returncode == 0, "capture.py failed", out.stderr)
        lines = out.stdout.splitlines()
        check(lines[0] == "connected to goniod 0.1.0, rig py", "hello", lines[0])
        check(any(x.startswith("refused: ") and "soft limits" in x for x in lines), "refused")
        check("20 captures, 0 problems" in lines, "captures", lines[-2:])
        check(lines[-1] == "dataset: " + os.path.join(rig.data, "ex1"), "path", lines[-1])
    with open(script) as f, open(os.path.join(argv[2], "docs", "python.md")) as doc:
        check("```python\n" + f.read() + "```\n" in doc.read(), "docs/python.md has the script")


if __name__ == "__main__":
    main({"hello": case_hello, "move": case_move, "session": case_session, "fault": case_fault,
          "closed": case_closed, "broken": case_broken, "example": case_example})
