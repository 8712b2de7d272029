"""gonio - a Python client of goniod, the daemon of the gonio capture rig, for lab scripts.

Speaks goniod's control protocol (docs/protocol.md: JSON-RPC 2.0, one object per line, over
a Unix stream socket) with the standard library only. Every request of the protocol is a
method taking keyword arguments and returning the result as a dict; an error response raises
GonioError with the protocol's code and message; notifications are kept in a bounded queue
and read with next_event() or the events() iterator. Every wait is bounded by a timeout.
docs/python.md documents the API, with a complete example (examples/scripts/capture.py).

    import gonio

    with gonio.Client() as rig:          # $GONIO_SOCKET, else the daemon's default socket
        rig.home()
        rig.goto(turntable=90, light_arm=30)
        rig.dataset_open("gem1", create=True)
        print(rig.capture_at(lamps=["lamp0"]))

A Client is not thread-safe: use one per thread.
"""

import collections
import errno as _errno
import json
import os
import socket
import time

__version__ = "0.1.0"
__all__ = ["Client", "Event", "GonioError", "ProtocolError", "ConnectionClosed", "Timeout",
           "socket_path", "PROTOCOL", "PARSE_ERROR", "INVALID_REQUEST", "METHOD_NOT_FOUND",
           "INVALID_PARAMS", "INTERNAL_ERROR", "E_BUSY", "E_RANGE", "E_DEVICE", "E_TIMEOUT",
           "E_NOT_FOUND", "E_STORAGE", "E_CANCELED", "E_STATE", "E_LINE_TOO_LONG"]

PROTOCOL = 1             # the protocol version this module speaks (hello)
MAX_LINE = 64 * 1024     # bytes in a message line, its '\n' included (PROTO_MAX_LINE)
TIMEOUT = 30.0           # s: connect, hello and quick requests
TIMEOUT_LONG = 120.0     # s: home, move, capture, datasets, sessions, scans
EVENTS_KEPT = 4096       # notifications queued at most; the oldest are dropped beyond
FOLLOW_POLL = 10.0       # s without a session notification before run_session asks for the status
IDLE_POLL = 0.25         # s between status requests of wait_idle while no state notification comes

# Error codes (docs/protocol.md, section 7): GonioError.code of an error response.
PARSE_ERROR = -32700
INVALID_REQUEST = -32600
METHOD_NOT_FOUND = -32601
INVALID_PARAMS = -32602
INTERNAL_ERROR = -32603
E_BUSY = -32001
E_RANGE = -32002
E_DEVICE = -32003
E_TIMEOUT = -32004
E_NOT_FOUND = -32005
E_STORAGE = -32006
E_CANCELED = -32007
E_STATE = -32008
E_LINE_TOO_LONG = -32009

# The errors goniod answers with "id": null, which answer the request outstanding.
_NULL_ID_CODES = (PARSE_ERROR, INVALID_REQUEST, E_LINE_TOO_LONG)


class GonioError(Exception):
    """An error: code is the protocol's error code (the module's E_* and *_ERROR constants)
    for an error response of goniod, None for a failure on this side (the subclasses);
    message says what failed; data is the response's error.data (a dict, empty when absent)."""

    def __init__(self, code, message, data=None):
        super().__init__(message)
        self.code = code
        self.message = message
        self.data = data if isinstance(data, dict) else {}

    @property
    def errno_name(self):
        """The errno name goniod gave (data.errno, e.g. "ERANGE"), or None."""
        return self.data.get("errno")

    def __str__(self):
        return self.message if self.code is None else f"{self.message} (error {self.code})"


class ProtocolError(GonioError):
    """goniod sent something the protocol does not allow (a malformed, over-long or
    unexpected message, another protocol version). The connection is closed."""

    def __init__(self, message):
        super().__init__(None, message)


class ConnectionClosed(ProtocolError):
    """The connection to goniod is closed (by goniod, by an error, or by close())."""


class Timeout(GonioError, TimeoutError):
    """No answer (or no notification) came in time. A request that timed out goes on in
    goniod; its late reply is skipped. The connection stays usable."""

    def __init__(self, message):
        GonioError.__init__(self, None, message)


Event = collections.namedtuple("Event", "method params")
Event.__doc__ = """A notification of goniod: method (e.g. "move.done") and params (a dict)."""


def socket_path():
    """goniod's socket path, as both sides find it: $GONIO_SOCKET, else
    $XDG_RUNTIME_DIR/gonio/goniod.sock, else /run/gonio/goniod.sock."""
    if os.environ.get("GONIO_SOCKET"):
        return os.environ["GONIO_SOCKET"]
    if os.environ.get("XDG_RUNTIME_DIR"):
        return os.path.join(os.environ["XDG_RUNTIME_DIR"], "gonio", "goniod.sock")
    return "/run/gonio/goniod.sock"


def _params(**kw):
    """The params object of a request: the keyword arguments that are not None."""
    return {k: v for k, v in kw.items() if v is not None}


def _no_duplicates(pairs):
    """json object_pairs_hook: an object with a member name twice is malformed."""
    obj = dict(pairs)
    if len(obj) != len(pairs):
        raise ValueError("duplicate member name")
    return obj


def _reject_constant(name):
    raise ValueError(f"{name} is not JSON")


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_id(v):
    return _is_int(v) or isinstance(v, str)


def _answers_outstanding(msg):
    """Whether msg is one of the errors with "id": null that answer the request outstanding:
    goniod could not read its id, or closes the connection (too many clients)."""
    err = msg.get("error") or {}
    return err.get("code") in _NULL_ID_CODES or (
        err.get("code") == E_BUSY and err.get("data", {}).get("errno") == "EUSERS")


def _check_response(msg):
    """Raises ValueError unless msg is a well-formed response."""
    if not (_is_id(msg["id"]) or msg["id"] is None):
        raise ValueError(f"bad id {msg['id']!r}")
    if ("result" in msg) == ("error" in msg):
        raise ValueError("a response needs exactly one of result and error")
    if "result" in msg and not isinstance(msg["result"], dict):
        raise ValueError("result is not an object")
    err = msg.get("error", {"code": 0, "message": ""})
    if not (isinstance(err, dict) and _is_int(err.get("code")) and isinstance(err.get("message"), str)
            and isinstance(err.get("data", {}), dict)):
        raise ValueError("error is not an object with an integer code and a string message")


def _parse(line):
    """The message of one line (a dict). Raises ProtocolError for anything but a
    notification or a response of JSON-RPC 2.0."""
    try:
        msg = json.loads(line, object_pairs_hook=_no_duplicates, parse_constant=_reject_constant)
        if not isinstance(msg, dict) or msg.get("jsonrpc") != "2.0":
            raise ValueError("not a JSON-RPC 2.0 object")
        if "method" in msg:
            if "id" in msg or not isinstance(msg["method"], str):
                raise ValueError("a request from the server, or a method that is not a string")
            if not isinstance(msg.get("params", {}), dict):
                raise ValueError("notification params are not an object")
        elif "id" in msg:
            _check_response(msg)
        else:
            raise ValueError("neither a response nor a notification")
    except ValueError as e:  # json.JSONDecodeError and UnicodeDecodeError are ValueErrors
        shown = line[:120].decode("utf-8", "replace")
        raise ProtocolError(f"bad message from goniod: {e}: {shown!r}") from None
    return msg


def _wanted(ev, methods):
    """Whether Event ev is one of methods: names, or prefixes ending in '.' (None: all)."""
    return methods is None or any(
        ev.method == m or (m.endswith(".") and ev.method.startswith(m)) for m in methods)


def _deadline(timeout):
    return time.monotonic() + timeout


def _left(deadline):
    return max(deadline - time.monotonic(), 0.0)


class Client:
    """A connection to goniod. Connects to the socket path (default: socket_path()) within
    timeout seconds and says hello (the server's answer is in self.server). timeout bounds
    quick requests, timeout_long those that wait for the rig (home, move, capture, datasets,
    sessions, scans); every method also takes timeout= for its own wait. Raises GonioError
    when the socket cannot be reached, ProtocolError when goniod speaks another protocol."""

    def __init__(self, path=None, *, timeout=TIMEOUT, timeout_long=TIMEOUT_LONG, name=None):
        self.path = path or socket_path()
        self.timeout = timeout
        self.timeout_long = timeout_long
        self.events_dropped = 0  # notifications dropped because the queue was full
        self.server = None       # hello's result: server, version, protocol, rig
        self._buf = bytearray()
        self._next_id = 1
        self._pending = {}       # id -> method of the requests sent and not answered
        self._abandoned = set()  # ids whose wait timed out: their late reply is skipped
        self._replies = {}       # id -> response that came while waiting for another
        self._events = collections.deque()
        self._sock = self._connect(timeout)
        try:
            self.hello(client=name or f"gonio.py/{__version__}")
        except BaseException:
            self.close()
            raise

    def _connect(self, timeout):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        try:
            sock.connect(self.path)
        except socket.timeout:
            sock.close()
            raise Timeout(f"cannot connect to goniod at {self.path}: no answer in {timeout:g} s") \
                from None
        except OSError as e:
            sock.close()
            raise GonioError(None, f"cannot connect to goniod at {self.path}: {e.strerror}",
                             {"errno": _errno.errorcode.get(e.errno)}) from None
        return sock

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"<gonio.Client {self.path} {'closed' if self.closed else 'open'}>"

    @property
    def closed(self):
        """Whether the connection is closed."""
        return self._sock is None

    def close(self):
        """Closes the connection (requests still running in goniod go on). Idempotent."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    # ---- the wire ----

    def _fail(self, exc):
        """Closes the connection and returns exc (a ProtocolError) to raise."""
        self.close()
        return exc

    def _read_line(self, deadline):
        """The next non-empty line, without its '\\n' and a trailing '\\r'."""
        while True:
            i = self._buf.find(b"\n")
            if i >= 0 or len(self._buf) >= MAX_LINE:
                if i < 0 or i + 1 > MAX_LINE:
                    raise self._fail(ProtocolError(
                        f"message from goniod longer than {MAX_LINE} bytes"))
                line = bytes(self._buf[:i])
                del self._buf[:i + 1]
                line = line[:-1] if line.endswith(b"\r") else line
                if line:
                    return line
                continue
            self._buf += self._recv(deadline)

    def _recv(self, deadline):
        if self._sock is None:
            raise ConnectionClosed("the connection to goniod is closed")
        self._sock.settimeout(_left(deadline))
        try:
            data = self._sock.recv(MAX_LINE)
        except (socket.timeout, BlockingIOError):  # timeout 0 makes the socket non-blocking
            raise Timeout("no message from goniod in time") from None
        except OSError as e:
            raise self._fail(ConnectionClosed(f"goniod closed the connection ({e.strerror})")) \
                from None
        if not data:
            raise self._fail(ConnectionClosed("goniod closed the connection"))
        return data

    def _receive(self, deadline):
        """Reads one message before deadline: queues a notification (and returns its Event),
        or files a response to an outstanding request (returns None)."""
        try:
            msg = _parse(self._read_line(deadline))
        except ProtocolError as e:
            raise self._fail(e) from None
        if "method" in msg:
            return self._queue(Event(msg["method"], msg.get("params", {})))
        rid = msg["id"]
        if rid is None and self._pending and _answers_outstanding(msg):
            rid = min(self._pending)  # the oldest request outstanding
        if rid in self._abandoned:
            self._abandoned.discard(rid)
        elif rid in self._pending:
            del self._pending[rid]
            self._replies[rid] = msg
        else:
            err = msg.get("error")
            said = f" ({err['code']}: {err['message']})" if err else ""
            raise self._fail(ProtocolError(
                f"bad message from goniod: a reply with id {json.dumps(rid)}{said}, "
                f"which answers no request of this connection"))
        return None

    def _queue(self, ev):
        if len(self._events) >= EVENTS_KEPT:
            self._events.popleft()
            self.events_dropped += 1
        self._events.append(ev)
        return ev

    # ---- requests ----

    def send(self, method, params=None):
        """Sends a request without waiting for its reply; returns its id for wait().
        Requests may overlap: goniod answers each when it is done. Raises ConnectionClosed,
        Timeout (the socket did not take it), GonioError E_LINE_TOO_LONG."""
        if self._sock is None:
            raise ConnectionClosed("the connection to goniod is closed")
        rid = self._next_id
        line = json.dumps({"jsonrpc": "2.0", "id": rid, "method": method, "params": params or {}},
                          separators=(",", ":"), ensure_ascii=False, allow_nan=False) + "\n"
        data = line.encode()
        if len(data) > MAX_LINE:
            raise GonioError(E_LINE_TOO_LONG, f"request '{method}' of {len(data)} bytes is longer "
                             f"than the protocol's {MAX_LINE}")
        self._sock.settimeout(self.timeout)
        try:
            self._sock.sendall(data)
        except socket.timeout:
            raise self._fail(Timeout(f"goniod took no request for {self.timeout:g} s")) from None
        except OSError as e:
            raise self._fail(ConnectionClosed(f"connection to goniod lost: {e.strerror}")) from None
        self._next_id += 1
        self._pending[rid] = method
        return rid

    def wait(self, rid, timeout=None):
        """Waits for the reply to request rid (from send) for timeout seconds (default: the
        client's); returns its result (a dict). Raises GonioError for an error response,
        Timeout (the request goes on in goniod; its reply will be skipped), ProtocolError."""
        timeout = self.timeout if timeout is None else timeout
        deadline = _deadline(timeout)
        method = self._pending.get(rid, "?")
        try:
            while rid not in self._replies:
                if rid not in self._pending:
                    raise ValueError(f"no request {rid} is outstanding")
                self._receive(deadline)
        except Timeout:
            self._abandon([rid])
            raise Timeout(f"no reply to '{method}' from goniod in {timeout:g} s "
                          "(the request goes on in goniod)") from None
        except KeyboardInterrupt:
            self._abandon([rid])
            raise
        msg = self._replies.pop(rid)
        if "error" in msg:
            err = msg["error"]
            raise GonioError(err["code"], err["message"], err.get("data"))
        return msg["result"]

    def _abandon(self, rids):
        """Gives up waiting for the replies to rids: they will be skipped when they come."""
        for rid in rids:
            self._replies.pop(rid, None)
            if self._pending.pop(rid, None) is not None:
                self._abandoned.add(rid)

    def call(self, method, params=None, timeout=None):
        """Sends method with params (a dict) and waits for its result (a dict) for timeout
        seconds (default: the client's). Any method, also one this module does not name."""
        return self.wait(self.send(method, params), timeout)

    def _long(self, timeout):
        return self.timeout_long if timeout is None else timeout

    # ---- notifications ----

    def next_event(self, timeout=None, methods=None):
        """The oldest notification not yet taken (an Event), waiting up to timeout seconds
        (default: the client's) for one. With methods (names or prefixes ending in '.', e.g.
        ("session.", "fault")), only those: others stay queued. Raises Timeout."""
        timeout = self.timeout if timeout is None else timeout
        deadline = _deadline(timeout)
        for ev in self._events:
            if _wanted(ev, methods):
                self._events.remove(ev)
                return ev
        while True:
            try:
                ev = self._receive(deadline)
            except Timeout:
                which = f" ({', '.join(methods)})" if methods else ""
                raise Timeout(f"no notification{which} from goniod in {timeout:g} s") from None
            if ev is not None and _wanted(ev, methods):
                self._events.pop()
                return ev

    def events(self, timeout=None, methods=None):
        """An iterator over the notifications (next_event's arguments); it never ends by
        itself and raises Timeout when none comes for timeout seconds."""
        while True:
            yield self.next_event(timeout, methods)

    def take_events(self, methods=None):
        """Takes the notifications queued so far (those of methods, as in next_event) without
        waiting: returns them as a list, oldest first. take_events() empties the queue."""
        taken = [ev for ev in self._events if _wanted(ev, methods)]
        self._events = collections.deque(ev for ev in self._events if not _wanted(ev, methods))
        return taken

    def _pump(self, deadline):
        """Queues what arrives until deadline; returns the first notification or None."""
        try:
            return self._receive(deadline)
        except Timeout:
            return None

    # ---- the protocol's methods (docs/protocol.md, section 5) ----

    def hello(self, client=None, protocol=PROTOCOL, timeout=None):
        """hello (done on connect): checks that goniod speaks this module's protocol
        (ProtocolError, connection closed, when not); returns {server, version, protocol, rig}."""
        res = self.call("hello", _params(client=client, protocol=protocol), timeout)
        if res.get("protocol") != PROTOCOL:
            raise self._fail(ProtocolError(f"goniod speaks protocol {res.get('protocol')}, "
                                           f"this client {PROTOCOL}"))
        self.server = res
        return res

    def status(self, timeout=None):
        """The whole state of the rig: state, homed, axes, lamps, lasers, cameras, dataset, fault."""
        return self.call("status", None, timeout)

    def describe(self, timeout=None):
        """Every device, its backend and options, and the rig's calibration: {rig, devices,
        calibration}."""
        return self.call("describe", None, timeout)

    def home(self, axes=None, timeout=None):
        """Homes axes (a list of names; None: all); returns {axes: [{name, position}]}."""
        return self.call("home", _params(axes=axes), self._long(timeout))

    def move(self, axis, position, relative=False, wait=True, timeout=None):
        """Moves one axis to position (degrees; an offset when relative). Returns {axis,
        position} when done, or {axis, target} at once with wait=False (then move.done)."""
        params = _params(axis=axis, position=position, relative=relative, wait=wait)
        return self.call("move", params, self._long(timeout))

    def stop(self, timeout=None):
        """Stops all motion at once; returns {stopped: [axis names]}."""
        return self.call("stop", None, timeout)

    def lamp_set(self, lamp, on, timeout=None):
        """Switches a lamp (name, or index in the rig file); returns {lamp, on}."""
        return self.call("lamp.set", _params(lamp=lamp, on=on), self._long(timeout))

    def laser_set(self, on, laser=None, timeout=None):
        """Switches the laser of that name, or every laser; returns {laser, on,
        off_on_disconnect}. With off_on_disconnect (a laser's default in the rig file) goniod
        switches it off when this client's connection closes: it stays on while connected."""
        return self.call("laser.set", _params(on=on, laser=laser), self._long(timeout))

    def device_get(self, device=None, setting=None, timeout=None):
        """Device settings (an axis's speed and accel, a camera's exposure_us and gain) with
        their limits: {devices: [...]}, one device's {device, class, settings}, or one
        setting's {device, setting, value, min, max, unit, limit}."""
        return self.call("device.get", _params(device=device, setting=setting), timeout)

    def device_set(self, device, setting, value, timeout=None):
        """Changes a device setting until goniod restarts (E_RANGE outside the rig file's
        limits, E_BUSY during a session); returns {device, setting, value}."""
        return self.call("device.set", _params(device=device, setting=setting, value=value),
                         timeout)

    def capture(self, camera=None, exposure_us=None, gain=None, bits=None, timeout=None):
        """Captures from camera (None: every camera) into the open dataset; returns
        {captures: [...]}. A partial failure's error has data.stored and data.failed."""
        params = _params(camera=camera, exposure_us=exposure_us, gain=gain, bits=bits)
        return self.call("capture", params, self._long(timeout))

    def dataset_open(self, name, create=False, timeout=None):
        """Opens dataset name (creates it with create=True); returns {path, name, count}."""
        return self.call("dataset.open", _params(name=name, create=create), self._long(timeout))

    def dataset_close(self, timeout=None):
        """Closes the open dataset; returns {}."""
        return self.call("dataset.close", None, self._long(timeout))

    def dataset_list(self, timeout=None):
        """Every dataset: {datasets: [{name, path, count, created, rig}]}."""
        return self.call("dataset.list", None, self._long(timeout))

    def dataset_info(self, name=None, timeout=None):
        """A dataset (None: the open one): {name, path, count, created, rig, cameras, captures}."""
        return self.call("dataset.info", _params(name=name), self._long(timeout))

    def dataset_check(self, name, timeout=None):
        """Checks dataset name; returns {name, path, count, problems: []} when clean, else
        raises GonioError E_STORAGE with data.problems."""
        return self.call("dataset.check", _params(name=name), self._long(timeout))

    def fault_clear(self, timeout=None):
        """Clears a latched fault (axes that lost their position need homing); returns {}."""
        return self.call("fault.clear", None, self._long(timeout))

    def session_plan(self, file, text=None, timeout=None):
        """Plans the session file (its text read from the path file unless given; nothing
        moves): {session, dataset, captures, estimate_s, ...}."""
        return self.call("session.plan", _session_params(file, text), self._long(timeout))

    def session_run(self, file, text=None, timeout=None):
        """Starts the session file (as session_plan); returns its status (session_status).
        Progress follows as notifications: see run_session."""
        return self.call("session.run", _session_params(file, text), self._long(timeout))

    def session_resume(self, dataset=None, timeout=None):
        """Resumes the paused or unfinished session (of dataset); returns its status."""
        return self.call("session.resume", _params(dataset=dataset), self._long(timeout))

    def session_pause(self, timeout=None):
        """Pauses the session at the next capture boundary; returns its status."""
        return self.call("session.pause", None, self._long(timeout))

    def session_abort(self, dataset=None, timeout=None):
        """Aborts the session (or dataset's unfinished one after a restart); returns its status."""
        return self.call("session.abort", _params(dataset=dataset), self._long(timeout))

    def session_status(self, timeout=None):
        """The session's status: {state, name, dataset, planned, captured, eta_s, ...}."""
        return self.call("session.status", None, timeout)

    def scan_continuous(self, dataset, camera=None, from_=None, to=None, step=None,
                        exposure_us=None, gain=None, bits=None, timeout=None):
        """A laser scan in continuous rotation into the open dataset (from_ is the protocol's
        "from"); returns its figures when it has ended: {stored, missed, max_gap_deg, ...}."""
        params = _params(dataset=dataset, camera=camera, to=to, step=step,
                         exposure_us=exposure_us, gain=gain, bits=bits)
        params.update(_params(**{"from": from_}))
        return self.call("scan.continuous", params, self._long(timeout))

    # ---- helpers for lab scripts ----

    def wait_idle(self, timeout=None):
        """Waits until the rig is idle (state "idle", every axis done) for timeout seconds
        (default: timeout_long); returns the status. Raises GonioError E_STATE when a fault
        is latched, Timeout. Notifications stay queued."""
        timeout = self._long(timeout)
        deadline = _deadline(timeout)
        while True:
            st = self.status()
            if st["state"] == "fault":
                fault = st.get("fault") or {}
                raise GonioError(E_STATE, f"the rig has a fault: {fault.get('device', '?')}: "
                                 f"{fault.get('message', '')}", {"status": st})
            if st["state"] == "idle" and all(a.get("done", not a.get("moving"))
                                             for a in st["axes"]):
                return st
            if _left(deadline) <= 0:
                raise Timeout(f"the rig is not idle after {timeout:g} s (state {st['state']})")
            self._wait_note(("state.changed", "move.done", "fault"),
                            _deadline(min(IDLE_POLL, _left(deadline))))

    def _wait_note(self, methods, deadline):
        """Reads (and queues) messages until one of the notifications methods or deadline."""
        while _left(deadline) > 0:
            ev = self._pump(deadline)
            if ev is not None and ev.method in methods:
                return

    def goto(self, positions=None, *, relative=False, timeout=None, **axes):
        """Moves several axes at once and waits until all are done: goto(turntable=90,
        light_arm=30) or goto({"turntable": 90}). Returns {axis: position reached}. When a
        move fails, waits for the others, then raises the first error."""
        targets = dict(positions or {}, **axes)
        ids = {axis: self.send("move", _params(axis=axis, position=pos, relative=relative,
                                               wait=True))
               for axis, pos in targets.items()}
        results = self._gather(ids, self._long(timeout))
        return {axis: res["position"] for axis, res in results.items()}

    def _gather(self, ids, timeout):
        """Waits for the replies to ids ({key: request id}) within timeout seconds; returns
        {key: result}, or raises the first error once every reply is in."""
        deadline = _deadline(timeout)
        results, first = {}, None
        for key, rid in ids.items():
            try:
                results[key] = self.wait(rid, _left(deadline))
            except (Timeout, ProtocolError, KeyboardInterrupt):
                self._abandon(ids.values())
                raise
            except GonioError as e:
                first = first or e
        if first is not None:
            raise first
        return results

    def set_lamps(self, on=(), timeout=None):
        """Switches on exactly the lamps named (or indexed) in on, every other lamp off, all
        at once; returns the names of the lamps now on."""
        lamps = [lamp["name"] for lamp in self.status(timeout)["lamps"]]
        lit = {lamps[x] if isinstance(x, int) else x for x in on}
        unknown = lit - set(lamps)
        if unknown:
            raise GonioError(E_NOT_FOUND, f"no lamp {', '.join(sorted(unknown))} in the rig "
                             f"(lamps: {', '.join(lamps)})")
        ids = {name: self.send("lamp.set", {"lamp": name, "on": name in lit}) for name in lamps}
        self._gather(ids, self._long(timeout))
        return [name for name in lamps if name in lit]

    def capture_at(self, positions=None, *, lamps=None, laser=None, camera=None,
                   exposure_us=None, gain=None, bits=None, timeout=None):
        """Moves to positions ({axis: degrees}, as goto), switches on exactly lamps (unless
        None, as set_lamps) and the laser on or off (unless None), captures (as capture) and
        returns the list of captures stored."""
        if positions:
            self.goto(positions, timeout=timeout)
        if lamps is not None:
            self.set_lamps(lamps, timeout)
        if laser is not None:
            self.laser_set(laser, timeout=timeout)
        return self.capture(camera, exposure_us, gain, bits, timeout)["captures"]

    def run_session(self, file, text=None, *, on_progress=None, timeout=None):
        """Runs the session file (as session_run) and follows it to its end, calling
        on_progress(status) for each session notification; returns the last status when it
        ended done. Raises GonioError with the status in data.status when it ended otherwise
        or paused (code: its cause's, else E_CANCELED); Timeout after timeout seconds (default:
        none; goniod is asked for the status after 10 s without news)."""
        st = self.session_run(file, text)
        self.take_events(("session.",))  # they came before the answer: older than st
        return self.follow_session(st, on_progress=on_progress, timeout=timeout)

    def follow_session(self, status=None, *, on_progress=None, timeout=None):
        """Follows the running session from status (default: session_status()) until it
        ends or pauses, as run_session."""
        st = status or self.session_status()
        deadline = None if timeout is None else _deadline(timeout)
        while st["state"] not in ("none", "paused"):
            wait = FOLLOW_POLL if deadline is None else min(FOLLOW_POLL, _left(deadline))
            try:
                st = self.next_event(wait, methods=("session.",)).params
            except Timeout:
                if deadline is not None and _left(deadline) <= 0:
                    raise Timeout(f"session {st.get('name')} still {st['state']} after "
                                  f"{timeout:g} s") from None
                st = self.session_status()
            if on_progress is not None:
                on_progress(st)
        if st["state"] == "none" and st.get("ended") == "done":
            return st
        how = st.get("ended") or st["state"]
        reason = f": {st['reason']}" if st.get("reason") else ""
        raise GonioError(st.get("code", E_CANCELED), f"session {st.get('name')} {how}{reason}",
                         {"status": st})


def _session_params(file, text):
    """session.plan/run params: the file's name and its text (read from it unless given)."""
    if text is None:
        with open(file, encoding="utf-8") as f:
            text = f.read()
    return {"file": str(file), "text": text}
