"""Strain out: each tracked frame's extensometer strain sent to a machine controller (``--publish URI``).

A video extensometer feeds the testing machine's controller, which strain-controlled
tests need. ``livedic run --publish URI`` (repeatable) hands every tracked frame's
extensometer readings out as soon as the frame's result exists:

``udp://HOST:PORT``
    One UDP datagram per tracked frame to HOST:PORT (127.0.0.1 when no host is given; a
    name goes to its first IPv4 address, else IPv6), a UTF-8 JSON object::

        {"frame": 41, "time_s": 0.82, "strain": {"axial": 0.00123, "transverse": -0.00037},
         "ok": true, "true_strain": {"axial": 0.00122925, "transverse": -0.00037007}}

    ``strain`` holds every extensometer of the session by name (engineering strain,
    (L - L0) / L0), ``null`` where the extensometer has no valid reading in this frame
    (an end lost: NaN is never written); ``ok`` is true only when every extensometer has a
    valid reading; ``time_s`` is seconds since the session's first frame (as the recording
    and ``livedic export`` give it). ``true_strain`` (ln(L / L0)) comes along. The socket
    never blocks the tracker: a datagram the system cannot take at once is not sent,
    and counted.

``modbus://HOST:PORT``
    A Modbus TCP server (pymodbus) listening on HOST:PORT (127.0.0.1 when no host is
    given; ``0.0.0.0`` for every interface; port 0 picks a free one, said at the start)
    serving the same values as holding registers (``REGISTER_MAP``; function 3, function 4
    reads the same). Writes are refused. A read of one block is one frame's values, never
    half of one frame and half of the next: the tracker thread replaces one immutable
    snapshot, and a read copies it whole into the registers in the server's thread.
    When the session ends the last frame's values stay, with state 2 (ended), and the
    server keeps answering for ``linger_s`` seconds (``?linger_s=SECONDS``, default
    ``DEFAULT_LINGER_S``, 0..60) before it closes, so a polling controller reads the end;
    the session's exit waits for what is left of it (the summary is said meanwhile).

``PublishStage`` is a session sink placed right after the strain stage, before the load
stage, the recording and the view, so the values leave as early as they exist. No force
goes out: the controller has its own load cell, and the load stage may wait (bounded) for
a live force stream's next sample, which strain out must not. A send that fails
(network unreachable, no route) is a warning event once, counted, and publishing goes on;
it never costs the session or its recording. pymodbus is imported by ``preload`` before the
session reads its first frame (~0.1-0.2 s on 2 busy cores): imported when the server opens,
between the first frame and the start, it held back a paced source, whose frames then
came in a burst and 2-4 were dropped by the queue. The stage keeps, per frame, the time from
the tracker's result to the send returning (``latency_ms``): the strain-out latency
``livedic bench live`` prints.
"""

import errno
import json
import math
import socket
import struct
import threading
import time
from array import array
from dataclasses import dataclass
from urllib.parse import urlsplit

import numpy as np

SCHEMES = ("udp", "modbus")
DEFAULT_HOST = "127.0.0.1"
DEFAULT_LINGER_S = 1.0       # a controller polling every 5-100 ms reads the ended state several times
MAX_LINGER_S = 60.0

# ----------------------------------------------------------------------------- the register map

# Holding registers (0-based addresses, as a request gives them; a PLC's "4xxxx" numbering is address + 40001).
# 32-bit values take two registers, high word first (big-endian words of big-endian bytes: "ABCD").
HEADER_REGISTERS = 16
EXTENSOMETER_REGISTERS = 6       # per extensometer, from HEADER_REGISTERS + k * EXTENSOMETER_REGISTERS
MAX_AGE_MS = 65535
STATE_WAITING, STATE_RUNNING, STATE_ENDED = 0, 1, 2

REGISTER_MAP = (
    # (address, registers, type, name, meaning)
    (0, 2, "uint32", "update_count", "frames published so far: +1 per tracked frame (0 before the first)"),
    (2, 2, "uint32", "frame", "the frame's index"),
    (4, 2, "float32", "time_s", "seconds since the session's first frame"),
    (6, 1, "uint16", "ok", "1 when every extensometer has a valid reading in this frame, else 0"),
    (7, 1, "uint16", "state", "0 waiting for the first frame, 1 running, 2 session ended (values final)"),
    (8, 1, "uint16", "age_ms", "milliseconds since these values were written, when read (65535 at most)"),
    (9, 1, "uint16", "extensometers", "N, the number of extensometer blocks that follow"),
    (10, 6, "-", "reserved", "0"),
)
EXTENSOMETER_MAP = (
    # (offset in the block, registers, type, name, meaning)
    (0, 2, "float32", "eng_strain", "engineering strain (L - L0) / L0; NaN when not valid"),
    (2, 2, "float32", "true_strain", "true strain ln(L / L0); NaN when not valid"),
    (4, 1, "uint16", "valid", "1 when this extensometer has a valid reading in this frame"),
    (5, 1, "-", "reserved", "0"),
)
_AGE_ADDRESS = 8


def register_count(n_extensometers):
    """Holding registers the map takes for ``n_extensometers``."""
    return HEADER_REGISTERS + EXTENSOMETER_REGISTERS * n_extensometers


def _words(fmt, value):
    """``value`` packed big-endian as ``fmt`` ("I" or "f"), as 16-bit registers, high word first."""
    raw = struct.pack(">" + fmt, value)
    return [int.from_bytes(raw[i:i + 2], "big") for i in range(0, len(raw), 2)]


def _float32(value):
    """``value`` as float32 registers; NaN stays NaN (a legitimate float32 a PLC can test)."""
    value = float(value) if value is not None else math.nan
    return _words("f", value if math.isfinite(value) else math.nan)


def encode_registers(values, *, update_count, state=STATE_RUNNING):
    """One frame's ``FrameValues`` as the holding registers of ``REGISTER_MAP`` (``age_ms`` 0).

    Parameters
    ----------
    values : FrameValues
    update_count : int
        Frames published so far, this one included.
    state : int
        ``STATE_RUNNING`` or ``STATE_ENDED``.

    Returns
    -------
    list of int
        ``register_count(len(values.names))`` values, 0..65535 each.
    """
    registers = (_words("I", update_count & 0xFFFFFFFF) + _words("I", values.frame & 0xFFFFFFFF)
                 + _float32(values.time_s) + [int(values.ok), state, 0, len(values.names)] + [0] * 6)
    for eng, true, valid in zip(values.eng_strain, values.true_strain, values.valid):
        registers += _float32(eng if valid else math.nan) + _float32(true if valid else math.nan) + [int(valid), 0]
    return registers


def decode_registers(registers):
    """The values a client reads back from ``registers`` (a whole map, address 0 first), as a dict.

    The inverse of ``encode_registers`` as the register map of docs/guide/strain-out.md states it: what a controller
    does with the registers (the tests check the map through it and through pymodbus's own
    decoding).
    """
    def u32(at):
        return (registers[at] << 16) | registers[at + 1]

    def f32(at):
        return struct.unpack(">f", struct.pack(">HH", registers[at], registers[at + 1]))[0]

    n = registers[9]
    blocks = [HEADER_REGISTERS + EXTENSOMETER_REGISTERS * k for k in range(n)]
    return {"update_count": u32(0), "frame": u32(2), "time_s": f32(4), "ok": bool(registers[6]),
            "state": registers[7], "age_ms": registers[_AGE_ADDRESS], "extensometers": n,
            "eng_strain": [f32(at) for at in blocks], "true_strain": [f32(at + 2) for at in blocks],
            "valid": [bool(registers[at + 4]) for at in blocks]}


# ----------------------------------------------------------------------------- targets

@dataclass(frozen=True)
class PublishTarget:
    """Where strain goes out: ``scheme`` udp or modbus, ``host`` and ``port`` (see the module notes).

    ``linger_s``: how long a Modbus server keeps answering after the session ended.
    """
    uri: str
    scheme: str
    host: str
    port: int
    linger_s: float = DEFAULT_LINGER_S

    def describe(self):
        """``udp://127.0.0.1:9870`` (the host as used; an IPv6 one in brackets)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.scheme}://{host}:{self.port}"


def parse_publish_uri(text):
    """``--publish`` ``udp://HOST:PORT`` or ``modbus://HOST:PORT`` -> ``PublishTarget``.

    No host (``udp://:9870``) means 127.0.0.1. A modbus port may be 0 (any free port); a modbus
    URI may end in ``?linger_s=SECONDS`` (0..60, default ``DEFAULT_LINGER_S``).

    Raises
    ------
    ValueError
        Anything else (one line naming the option).
    """
    raw = str(text).strip()
    example = "e.g. udp://127.0.0.1:9870 or modbus://127.0.0.1:5020"
    if "://" not in raw:
        raise ValueError(f"--publish {raw!r}: expected udp://HOST:PORT or modbus://HOST:PORT, {example}")
    try:
        parts = urlsplit(raw)
        port = parts.port
    except ValueError as error:
        raise ValueError(f"--publish {raw}: {error} ({example})") from None
    scheme = parts.scheme.lower()
    if scheme not in SCHEMES:
        raise ValueError(f"--publish {raw}: unknown scheme {parts.scheme!r}: use udp://HOST:PORT or "
                         f"modbus://HOST:PORT")
    linger_s = _linger_option(raw, scheme, parts.query)
    if parts.path not in ("", "/") or parts.fragment or parts.username or parts.password or linger_s is None:
        also = ", and ?linger_s=SECONDS" if scheme == "modbus" else ""
        raise ValueError(f"--publish {raw}: only HOST:PORT may follow {scheme}://{also} ({example})")
    if port is None:
        raise ValueError(f"--publish {raw}: a port is needed, {example}")
    lowest = 0 if scheme == "modbus" else 1
    if not lowest <= port <= 65535:
        raise ValueError(f"--publish {raw}: port must be {lowest}..65535, got {port}")
    return PublishTarget(uri=raw, scheme=scheme, host=parts.hostname or DEFAULT_HOST, port=port, linger_s=linger_s)


def _linger_option(raw, scheme, query):
    """A URI's ``linger_s`` (the default without a query); None for a query that is not one modbus ``linger_s``.

    Raises
    ------
    ValueError
        ``linger_s`` not a number in 0..60 (one line).
    """
    if not query:
        return DEFAULT_LINGER_S
    key, _, text = query.partition("=")
    if scheme != "modbus" or key != "linger_s" or "&" in text:
        return None
    try:
        linger_s = float(text)
    except ValueError:
        linger_s = math.nan
    if not 0.0 <= linger_s <= MAX_LINGER_S:
        raise ValueError(f"--publish {raw}: linger_s must be seconds in 0..{MAX_LINGER_S:g}, got {text!r}")
    return linger_s


def parse_publish_uris(texts):
    """Every ``--publish`` given, parsed (``parse_publish_uri``); ValueError for one given twice."""
    targets = tuple(parse_publish_uri(text) for text in texts)
    seen = set()
    for target in targets:
        key = (target.scheme, target.host, target.port)
        if key in seen and target.port != 0:
            raise ValueError(f"--publish {target.describe()} is given twice")
        seen.add(key)
    return targets


# ----------------------------------------------------------------------------- one frame's values

@dataclass(frozen=True)
class FrameValues:
    """What goes out for one frame (see the module notes); arrays in the order of the extensometers."""
    frame: int
    time_s: float
    names: tuple
    eng_strain: tuple
    true_strain: tuple
    valid: tuple

    @property
    def ok(self):
        """True when every extensometer has a valid reading (False with none at all)."""
        return bool(self.valid) and all(self.valid)

    def as_json(self):
        """The UDP datagram: compact UTF-8 JSON, ``null`` for every missing number (never NaN)."""
        def number(value, valid=True):
            return float(value) if valid and value is not None and math.isfinite(value) else None

        message = {"frame": int(self.frame), "time_s": float(self.time_s),
                   "strain": {n: number(e, v) for n, e, v in zip(self.names, self.eng_strain, self.valid)},
                   "ok": self.ok,
                   "true_strain": {n: number(t, v) for n, t, v in zip(self.names, self.true_strain, self.valid)}}
        return json.dumps(message, allow_nan=False, separators=(",", ":")).encode("utf-8")


def frame_values(result, names, time_s):
    """The ``FrameValues`` of a ``stream.pipeline.frame_result.FrameResult`` for the extensometers ``names``.

    A reading is valid when its extensometer is ok and its strain finite; an extensometer the
    frame has no reading of (the strain stage failed) is not valid.
    """
    readings = result.extensometers
    eng, true, valid = [math.nan] * len(names), [math.nan] * len(names), [False] * len(names)
    if readings is not None:
        index = {name: i for i, name in enumerate(readings.names)}
        for k, name in enumerate(names):
            i = index.get(name)
            if i is None:
                continue
            eng[k], true[k] = float(readings.eng_strain[i]), float(readings.true_strain[i])
            valid[k] = bool(readings.ok[i]) and math.isfinite(eng[k])
    return FrameValues(frame=int(result.frame.index), time_s=time_s, names=tuple(names), eng_strain=tuple(eng),
                       true_strain=tuple(true), valid=tuple(valid))


# ----------------------------------------------------------------------------- outlets

class UdpOutlet:
    """Sends each frame's JSON datagram to ``target`` (non-blocking socket, never connected).

    Raises
    ------
    ValueError
        The host does not resolve (one line), when opened.
    """

    def __init__(self, target):
        self.target = target
        try:
            infos = socket.getaddrinfo(target.host, target.port, type=socket.SOCK_DGRAM)
        except socket.gaierror as error:
            raise ValueError(f"--publish {target.uri}: cannot resolve host {target.host!r} ({error.strerror})") \
                from None
        # A name goes to its first IPv4 address when it has one: "localhost" is ::1 first on many systems,
        # and a controller on this machine most often listens on 127.0.0.1 or 0.0.0.0.
        infos.sort(key=lambda info: info[0] != socket.AF_INET)
        family, kind, proto, _, self.address = infos[0]
        self.socket = socket.socket(family, kind, proto)
        # Never wait in the tracker thread: a datagram the system cannot take now is counted as not sent.
        self.socket.setblocking(False)
        self.where = target.describe()

    def note(self):
        """What the session says at the start."""
        return f"publishing strain to {self.where} (one UDP JSON datagram per tracked frame)"

    def send(self, values, update_count):
        """Send one frame; OSError when the system refuses it."""
        self.socket.sendto(values.as_json(), self.address)

    def finish(self):
        """The session ended: nothing to say over UDP (the datagrams stop)."""

    def close(self):
        self.socket.close()


class ModbusOutlet:
    """A Modbus TCP server (pymodbus) in a background thread serving ``REGISTER_MAP``.

    Attributes
    ----------
    port : int
        The port it listens on (the one asked for, or the one the system chose for port 0).
    where : str
        ``modbus://HOST:PORT`` as it listens.

    Raises
    ------
    ValueError
        The address cannot be listened on (in use, not allowed, not this machine's), when opened.
    """

    def __init__(self, target, names):
        self.target = target
        self.names = tuple(names)
        self.count = register_count(len(self.names))
        empty = FrameValues(frame=0, time_s=0.0, names=self.names, eng_strain=(math.nan,) * len(self.names),
                            true_strain=(math.nan,) * len(self.names), valid=(False,) * len(self.names))
        # (registers, monotonic ns written): replaced whole by the tracker thread, read once per request.
        self._snapshot = (tuple(encode_registers(empty, update_count=0, state=STATE_WAITING)), time.monotonic_ns())
        self._last = None
        self._ended_ns = None              # monotonic ns when the session ended (finish)
        self._loop = None
        self._server = None
        self._error = None
        self._ready = threading.Event()
        _check_listen(target)
        self._thread = threading.Thread(target=self._serve_thread, name=f"livedic publish {target.describe()}",
                                        daemon=True)
        self._thread.start()
        self._ready.wait(timeout=10.0)
        if self._error is not None or self._server is None:
            self.close()
            raise ValueError(f"--publish {target.uri}: cannot serve Modbus on {target.describe()}: "
                             f"{self._error or 'the server did not start within 10 s'}")
        self.where = f"modbus://{_bracketed(target.host)}:{self.port}"

    def note(self):
        """What the session says at the start: where it listens, where each extensometer's block is."""
        blocks = ", ".join(f"{name} at {HEADER_REGISTERS + EXTENSOMETER_REGISTERS * k}"
                           for k, name in enumerate(self.names))
        return (f"publishing strain on {self.where} (Modbus TCP, holding registers 0..{self.count - 1}: header at 0, "
                f"extensometers {blocks})")

    def send(self, values, update_count):
        """Make ``values`` the registers' content (the next read gets all of them)."""
        self._last = (values, update_count)
        self._snapshot = (tuple(encode_registers(values, update_count=update_count)), time.monotonic_ns())

    def finish(self):
        """The session ended: the last frame's values stay, with state 2 (ended), ``linger_s`` more seconds."""
        self._ended_ns = time.monotonic_ns()
        if self._last is None:
            registers = list(self._snapshot[0])
            registers[7] = STATE_ENDED
            self._snapshot = (tuple(registers), self._snapshot[1])
            return
        values, update_count = self._last
        self._snapshot = (tuple(encode_registers(values, update_count=update_count, state=STATE_ENDED)),
                          self._snapshot[1])

    async def _fill(self, function_code, start_address, address, count, current_registers, set_values):
        """pymodbus's action before every request: the registers become the latest snapshot, whole."""
        registers, written_ns = self._snapshot
        offset = -start_address
        current_registers[offset:offset + len(registers)] = registers
        age = (time.monotonic_ns() - written_ns) // 1_000_000
        current_registers[offset + _AGE_ADDRESS] = min(MAX_AGE_MS, max(0, age))
        return None

    def _serve_thread(self):
        import asyncio
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        finally:
            loop.close()

    async def _serve(self):
        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice
        try:
            device = SimDevice(id=0, simdata=[SimData(address=0, count=self.count, values=0,
                                                      datatype=DataType.REGISTERS, readonly=True)],
                               action=self._fill)
            server = ModbusTcpServer(device, address=(self.target.host, self.target.port))
            if not await server.listen():
                raise OSError(f"cannot listen on {self.target.describe()}")
            self.port = server.transport.sockets[0].getsockname()[1]
        except Exception as error:  # noqa: BLE001 - handed to the opening thread as its one line
            self._error = f"{type(error).__name__}: {error}" if not isinstance(error, OSError) else str(error)
            self._ready.set()
            return
        self._server = server
        self._ready.set()
        await server.serving

    def linger_left_s(self):
        """Seconds the server still answers before ``close`` stops it: what is left of ``linger_s``
        since ``finish`` (0 when the session did not end: ``close`` after a failure stops at once)."""
        if self._ended_ns is None:
            return 0.0
        return max(0.0, self.target.linger_s - (time.monotonic_ns() - self._ended_ns) / 1e9)

    def close(self):
        """Stop the server (its port is free afterwards) and its thread, after what is left of the linger."""
        try:
            if self._server is not None:
                time.sleep(self.linger_left_s())
        finally:
            self._shutdown()

    def _shutdown(self):
        server, loop = self._server, self._loop
        self._server = None
        if server is not None and loop is not None and loop.is_running():
            import asyncio
            future = asyncio.run_coroutine_threadsafe(server.shutdown(), loop)
            try:
                future.result(timeout=5.0)
            except Exception:  # noqa: BLE001 - closing: the thread is a daemon and goes with the process
                pass
        self._thread.join(timeout=5.0)


def _bracketed(host):
    return f"[{host}]" if ":" in host else host


def _check_listen(target):
    """ValueError (one line) when ``target``'s address cannot be listened on: in use, not allowed, not here.

    A probe bound as pymodbus binds (SO_REUSEADDR) and released: the server's own failure
    is only logged, this says why.
    """
    try:
        infos = socket.getaddrinfo(target.host, target.port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as error:
        raise ValueError(f"--publish {target.uri}: cannot resolve host {target.host!r} ({error.strerror})") from None
    family, kind, proto, _, address = infos[0]
    probe = socket.socket(family, kind, proto)
    try:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(address)
        probe.listen(1)
    except OSError as error:
        why = error.strerror or str(error)
        hint = "; choose another port" if error.errno == errno.EADDRINUSE else ""
        raise ValueError(f"--publish {target.uri}: cannot listen on {_bracketed(target.host)}:{target.port}: "
                         f"{why}{hint}") from None
    finally:
        probe.close()


def preload(targets):
    """Import now what opening ``targets`` needs (pymodbus and asyncio for a Modbus server).

    The session calls it before it reads its first frame: the imports take ~0.1-0.2 s, and
    between the first frame and the start a paced source's frames pile up and come late, in a
    burst the queue drops from. ``open_outlet`` afterwards takes a few ms.
    """
    if any(target.scheme == "modbus" for target in targets):
        import asyncio  # noqa: F401
        from pymodbus.server import ModbusTcpServer  # noqa: F401
        from pymodbus.simulator import DataType, SimData, SimDevice  # noqa: F401


def open_outlet(target, names):
    """The outlet for ``target``: ``UdpOutlet`` or ``ModbusOutlet`` (ValueError, one line, when it cannot open)."""
    if target.scheme == "udp":
        return UdpOutlet(target)
    return ModbusOutlet(target, names)


# ----------------------------------------------------------------------------- the session stage

class PublishStage:
    """Sends every tracked frame's extensometer strain to one outlet (a session sink; see the module notes).

    Parameters
    ----------
    outlet : UdpOutlet or ModbusOutlet
    names : sequence of str
        The session's extensometers, in order (the JSON keys, the register blocks).
    report : callable
        ``report(kind, message, level)``: the session's event.

    Attributes
    ----------
    sent, failed : int
        Frames sent, and frames not sent (the system refused the datagram).
    latencies_ns : array of int
        Per frame sent: the send returning - the tracker's result (``FrameResult.done_ns``),
        monotonic clock; the strain stage before this one is inside it.
    upstream_ns : array of int
        Per frame sent: this stage's start - the tracker's result (the part of the latency spent
        before it: the loop's bookkeeping, on the simulator its error against the truth, the
        strain stage).
    """
    required = False
    stage = "publish"                  # its row in the session's stage times

    def __init__(self, outlet, names, report):
        self.outlet = outlet
        self.names = tuple(names)
        self.report = report
        self.name = f"publish {outlet.where}"
        self.first_ns = None
        self.sent = 0
        self.failed = 0
        self.latencies_ns = array("q")
        self.upstream_ns = array("q")
        self._failing = None               # (first frame not sent, failures since) while sends fail

    def __call__(self, result, stats):
        entered = time.monotonic_ns()
        frame = result.frame
        if self.first_ns is None:
            self.first_ns = frame.timestamp_ns
        values = frame_values(result, self.names, (frame.timestamp_ns - self.first_ns) / 1e9)
        try:
            self.outlet.send(values, self.sent + 1)
        except OSError as error:
            self.failed += 1
            if self._failing is None:
                self._failing = frame.index
                self.report("publish", f"{self.outlet.where}: frame {frame.index} not sent ({error}); "
                                       f"trying every frame, failures counted in the summary", "warning")
            return
        self.latencies_ns.append(time.monotonic_ns() - result.done_ns)
        self.upstream_ns.append(entered - result.done_ns)
        self.sent += 1
        if self._failing is not None:
            self.report("publish", f"{self.outlet.where}: sending again from frame {frame.index} "
                                   f"(not sent since frame {self._failing})", "info")
            self._failing = None

    def latency_ms(self, percentile, *, part="all"):
        """The strain-out latency's ``percentile`` (ms), NaN before any frame was sent.

        ``part``: ``"all"`` (result -> sent), ``"upstream"`` (result -> this stage's start) or
        ``"stage"`` (this stage's start -> sent: the message built and sent).
        """
        if not self.latencies_ns:
            return math.nan
        values = {"all": lambda: np.array(self.latencies_ns, np.int64),
                  "upstream": lambda: np.array(self.upstream_ns, np.int64),
                  "stage": lambda: np.array(self.latencies_ns, np.int64) - np.array(self.upstream_ns, np.int64)}
        return float(np.percentile(values[part](), percentile)) / 1e6

    def finish(self):
        """The session ended (a Modbus map says so; the last values stay)."""
        self.outlet.finish()

    def close(self):
        self.outlet.close()

    def summary(self):
        """This outlet's numbers for the session summary."""
        return {"uri": self.outlet.where, "sent": self.sent, "failed": self.failed,
                "latency_p50_ms": self.latency_ms(50), "latency_p99_ms": self.latency_ms(99),
                "latency_max_ms": self.latency_ms(100),
                "upstream_p50_ms": self.latency_ms(50, part="upstream"),
                "upstream_p99_ms": self.latency_ms(99, part="upstream"),
                "stage_p50_ms": self.latency_ms(50, part="stage"), "stage_p99_ms": self.latency_ms(99, part="stage")}


def open_publishers(targets, names, report):
    """A ``PublishStage`` per target, opened (sockets, servers listening); closes them all if one fails.

    Raises
    ------
    ValueError
        A target cannot open (one line); nothing stays open.
    """
    stages = []
    try:
        for target in targets:
            stages.append(PublishStage(open_outlet(target, names), names, report))
    except BaseException:
        for stage in stages:
            stage.close()
        raise
    return stages


def format_publish_summary(publish):
    """The summary's lines for the outlets (none without ``--publish``)."""
    def num(value):
        return "n/a" if value is None or not math.isfinite(value) else f"{value:.2f}"
    return [f"  publish    {entry['uri']}: {entry['sent']} frames sent"
            + (f", {entry['failed']} NOT sent" if entry["failed"] else "")
            + f"; result -> sent p50 {num(entry['latency_p50_ms'])} ms, p99 {num(entry['latency_p99_ms'])} ms"
            for entry in publish or ()]
