"""``open_load(uri)``: the testing machine's force signal, opened from a URI like a frame source.

Valid forms::

    csv:FILE                         a file exported by the machine's software (header ``time_s,force_N``)
    tcp://HOST:PORT[?clock=arrival|sender]   text lines ``force_N`` or ``time_s,force_N`` over TCP
    synthetic                        the simulator's force: ``open_load("synthetic", source=SOURCE)``
                                     with SOURCE the session's ``synthetic:tensile`` camera
    synthetic:tensile?...            the same force for a simulated test named by its camera URI
                                     (nothing is rendered: the force needs only the model)

``modbus://HOST:PORT?...`` is named by issue 13 but not built yet: ``open_load`` refuses it with
one ``LoadError`` line. Every error is a ``LoadError`` (a ``ValueError``) of one
line, naming the file and line or the option at fault.

Time bases (``LoadSource.time_base``)
-------------------------------------
Each source gives force at times on one clock, in seconds:

* ``"session"`` (``csv:``, ``synthetic``): seconds since the session's first frame, as the machine's software
  exports them, shifted by ``offset_s`` (the CLI's ``--load-offset S``): a sample written at
  ``time_s`` belongs to frame time ``time_s + offset_s``. The session passes each frame's
  timestamp relative to the first frame: ``(frame.timestamp_ns - first.timestamp_ns) / 1e9``.
  ``synthetic`` has one sample per frame of the simulated camera, frame i at ``i / fps``: its
  ``force_N(i)`` (``acquire.synthetic``, module notes, Force), exact at frame times; between two
  frames the force is interpolated linearly (so across the fracture it falls from the last loaded
  frame's force to 0). ``max_gap_s`` is 5 frame periods (0.5 s at least), as a csv's.
* ``"monotonic"`` (``tcp://``): ``time.monotonic_ns() / 1e9``, the clock that stamps frame
  arrival (``stream.tracker_loop``'s ``arrival_ns``). Each line is stamped when it arrives, unless
  ``?clock=sender`` says its ``time_s`` is already on that clock (a sender on the same host that
  stamps with ``time.monotonic()``: the exact time of the reading, not of its delivery). The
  session passes each frame's arrival: ``arrival_ns / 1e9``.

``LoadSource.frame_time_s(since_first_frame_s=..., arrival_ns=...)`` picks the one its base needs.

Interpolation (``force_at``)
----------------------------
Linear between the two samples around each frame time; NaN before the first sample, after the
last one (never extrapolated: a live session asks again once a later sample exists, see
``last_sample_time_s``), and where the two samples are more than ``max_gap_s`` apart (a stream
that stalled: a stale value is never used). ``max_gap_s`` defaults to 0.5 s for tcp, and for csv to
0.5 s or 5 median sample intervals of the file, whichever is longer.

TCP source
----------
A background thread connects (client), reads lines and stamps them; a line that is not one or
two finite numbers is counted (``warnings.garbage_lines``) and skipped. Lines that arrive in one
read share one arrival instant: with arrival stamping only the last of them is kept (the
freshest reading; the others are counted in ``warnings.superseded``), so a fast DAQ stream is
thinned to the rate of reads: use ``?clock=sender`` for every sample with its true time. With
sender times a sample not later than the previous one is counted (``warnings.out_of_order``) and
skipped, and a bare ``force_N`` line (no time) is garbage. No data for ``max_gap_s`` is a ``stalled`` event (``resumed`` when data comes back); a
refused or lost connection is an event and the thread reconnects every ``retry_s`` (1 s).
``close()`` stops the thread (joined with a timeout).

Memory is bounded: the last ``keep_s`` seconds (600) are kept, and at most ``max_samples``
(2,000,000 samples, 32 MB: 600 s at 3.3 kHz); older samples are dropped (counted in
``warnings.trimmed``, not an error). A 20,000-frame session at 50 fps lasts 400 s.
"""

import csv
import enum
import math
import socket
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from urllib.parse import parse_qsl, urlsplit

import numpy as np

from livedic.acquire.options import parse_number

__all__ = ["LoadError", "LoadEventKind", "LoadEvent", "LoadWarnings", "LoadSource", "CsvLoad", "TcpLoad",
           "SyntheticLoad",
           "open_load", "interpolate_force", "read_force_csv", "csv_max_gap_s", "parse_line",
           "TIME_BASE_SESSION", "TIME_BASE_MONOTONIC", "LOAD_USAGE"]

TIME_BASE_SESSION = "session"        # seconds since the session's first frame
TIME_BASE_MONOTONIC = "monotonic"    # time.monotonic_ns() / 1e9, the clock that stamps frame arrival

CSV_HEADER = ("time_s", "force_N")
DEFAULT_MAX_GAP_S = 0.5
DEFAULT_RETRY_S = 1.0
DEFAULT_KEEP_S = 600.0
DEFAULT_MAX_SAMPLES = 2_000_000
MAX_LINE_BYTES = 4096                # a "line" longer than this without a newline is garbage
MAX_EVENTS = 10_000                  # an endless outage adds events once per outage, this is a safety cap

LOAD_USAGE = ("valid loads: csv:FILE (header time_s,force_N), tcp://HOST:PORT[?clock=arrival|sender], "
              "synthetic (with the synthetic:tensile camera) or synthetic:tensile?...")
NOT_BUILT = ("modbus",)


class LoadError(ValueError):
    """A load URI, option or file that cannot be used; the one-line message says what and where."""


class LoadEventKind(str, enum.Enum):
    """What happened to a streamed force signal."""
    CONNECTED = "connected"
    CONNECT_FAILED = "connect_failed"    # once per outage, not once per retry
    DISCONNECTED = "disconnected"
    STALLED = "stalled"                  # no data for max_gap_s
    RESUMED = "resumed"                  # data again after a stall


@dataclass(frozen=True)
class LoadEvent:
    """One event: ``kind``, a human ``message``, and when (``time.monotonic()`` seconds)."""
    kind: LoadEventKind
    message: str
    monotonic_s: float


@dataclass(frozen=True)
class LoadWarnings:
    """Counts of lines or samples not used (a snapshot)."""
    garbage_lines: int = 0       # not one or two finite numbers, or too long
    out_of_order: int = 0        # sender time not later than the previous sample
    superseded: int = 0          # arrival stamping: earlier lines of one read (same instant)
    trimmed: int = 0             # dropped to bound memory (older than keep_s, or over max_samples)


def interpolate_force(sample_t, sample_f, times_s, max_gap_s):
    """Force at ``times_s`` by linear interpolation between samples.

    Parameters
    ----------
    sample_t, sample_f : array_like
        Sample times (strictly increasing) and forces (N).
    times_s : array_like or float
        Where to evaluate, on the samples' clock.
    max_gap_s : float
        Two neighbouring samples further apart than this do not bracket a value (stalled stream).

    Returns
    -------
    ndarray of float64, the shape of ``times_s``: NaN before the first sample, after the last one
    and inside gaps wider than ``max_gap_s``; a time equal to a sample's gives that sample.
    """
    t = np.asarray(sample_t, np.float64)
    f = np.asarray(sample_f, np.float64)
    times = np.asarray(times_s, np.float64)
    out = np.full(times.shape, np.nan)
    if t.size == 0:
        return out
    flat_times, flat_out = times.reshape(-1), out.reshape(-1)
    exact = np.searchsorted(t, flat_times, side="left")
    exact = np.minimum(exact, t.size - 1)
    is_sample = t[exact] == flat_times
    flat_out[is_sample] = f[exact[is_sample]]
    if t.size < 2:
        return out
    right = np.searchsorted(t, flat_times, side="right")       # first sample after the time
    inside = (right > 0) & (right < t.size) & ~is_sample
    right = right[inside]
    left = right - 1
    gap = t[right] - t[left]
    weight = (flat_times[inside] - t[left]) / gap
    values = f[left] + weight * (f[right] - f[left])
    values[gap > max_gap_s] = np.nan
    flat_out[inside] = values
    return out


class LoadSource(ABC):
    """A force signal: ``force_at(times_s)`` on the clock named by ``time_base``.

    Attributes: ``uri``, ``time_base`` (``TIME_BASE_SESSION`` or ``TIME_BASE_MONOTONIC``),
    ``max_gap_s``. A context manager; ``close()`` releases it.
    """

    uri: str = ""
    time_base: str = TIME_BASE_SESSION
    max_gap_s: float = DEFAULT_MAX_GAP_S

    @abstractmethod
    def samples(self):
        """``(time_s, force_N)`` copies of the samples kept, on ``time_base``."""

    def force_at(self, times_s):
        """Force (N) at ``times_s`` (see ``interpolate_force``): NaN where it is not known."""
        t, f = self.samples()
        return interpolate_force(t, f, times_s, self.max_gap_s)

    def frame_time_s(self, *, since_first_frame_s=None, arrival_ns=None):
        """A frame's time on ``time_base``: its time since the first frame (session) or its arrival (monotonic).

        Both may be given (the session need not know the base); the one the base needs must be.
        """
        if self.time_base == TIME_BASE_SESSION:
            if since_first_frame_s is None:
                raise LoadError(f"{self.uri}: frame times are seconds since the first frame; pass since_first_frame_s")
            return np.asarray(since_first_frame_s, np.float64)
        if arrival_ns is None:
            raise LoadError(f"{self.uri}: frame times are arrival on the monotonic clock; pass arrival_ns")
        return np.asarray(arrival_ns, np.float64) / 1e9

    @property
    def last_sample_time_s(self):
        """Time of the newest sample (NaN if none): frames later than this have no force yet."""
        t, _ = self.samples()
        return float(t[-1]) if t.size else math.nan

    def events(self, since=0):
        """``LoadEvent`` list, oldest first (a copy); ``since=n`` skips the n already seen (a poller's count)."""
        return []

    @property
    def warnings(self):
        """``LoadWarnings`` snapshot."""
        return LoadWarnings()

    @property
    def settings(self):
        """What describes this source in session metadata."""
        return {"uri": self.uri, "time_base": self.time_base, "max_gap_s": self.max_gap_s}

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


# --- csv: ----------------------------------------------------------------------------------------

def read_force_csv(path):
    """``(time_s, force_N)`` arrays from a CSV with header ``time_s,force_N`` (more columns allowed after).

    Raises
    ------
    LoadError
        Missing or unreadable file, wrong header, a value that is not a finite number, time not
        strictly increasing, or no samples: one line naming the file and line.
    """
    try:
        handle = open(path, newline="", encoding="utf-8-sig")
    except OSError as error:
        raise LoadError(f"load file {path}: cannot be read ({error.strerror or error}); "
                        f"expected a CSV with header time_s,force_N") from None
    times, forces = [], []
    with handle:
        try:
            rows = csv.reader(handle)
            header = next(rows, None)
            if header is None or tuple(cell.strip() for cell in header[:2]) != CSV_HEADER:
                raise LoadError(f"load file {path} line 1: header must start with time_s,force_N, "
                                f"found {','.join(header or [])[:60]!r}")
            for row in rows:
                line = rows.line_num
                if not any(cell.strip() for cell in row):
                    continue                      # blank line (a trailing newline, a spreadsheet's empty row)
                if len(row) < 2:
                    raise LoadError(f"load file {path} line {line}: expected time_s,force_N, found {','.join(row)[:60]!r}")
                time_s, force_n = (_finite(path, line, name, cell) for name, cell in zip(CSV_HEADER, row[:2]))
                if times and time_s <= times[-1]:
                    raise LoadError(f"load file {path} line {line}: time_s {time_s:g} is not after "
                                    f"the previous {times[-1]:g} (must increase strictly)")
                times.append(time_s)
                forces.append(force_n)
        except UnicodeDecodeError:
            raise LoadError(f"load file {path}: not a text CSV (expected UTF-8 with header time_s,force_N)") from None
        except csv.Error as error:
            raise LoadError(f"load file {path} line {rows.line_num}: {error}") from None
    if not times:
        raise LoadError(f"load file {path}: no samples after the header time_s,force_N")
    return np.asarray(times, np.float64), np.asarray(forces, np.float64)


def _finite(path, line, name, cell):
    try:
        value = float(cell)
    except ValueError:
        value = None
    if value is None or not math.isfinite(value):
        raise LoadError(f"load file {path} line {line}: {name} {cell.strip()[:30]!r} is not a finite number")
    return value


def csv_max_gap_s(time_s):
    """Default gap that is a stall in a file: ``DEFAULT_MAX_GAP_S`` or 5 median sample intervals if longer.

    Why: a slow export (1 Hz) is not a stall at every sample, yet a hole of several intervals is.
    """
    if time_s.size < 2:
        return DEFAULT_MAX_GAP_S
    return max(DEFAULT_MAX_GAP_S, 5.0 * float(np.median(np.diff(time_s))))


class CsvLoad(LoadSource):
    """Force from a CSV file; times are seconds since the session's first frame, plus ``offset_s``."""

    time_base = TIME_BASE_SESSION

    def __init__(self, path, *, offset_s=0.0, max_gap_s=None, uri=None):
        self.path = str(path)
        self.uri = uri or f"csv:{self.path}"
        self.offset_s = float(offset_s)
        time_s, self._force = read_force_csv(self.path)
        self._time = time_s + self.offset_s
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(time_s)

    def samples(self):
        return self._time.copy(), self._force.copy()

    @property
    def settings(self):
        return {**super().settings, "offset_s": self.offset_s}


# --- synthetic ----------------------------------------------------------------------------------

class SyntheticLoad(LoadSource):
    """The simulated tensile test's force: one sample per frame, frame i at ``i / fps`` s (session time).

    Parameters
    ----------
    source : SyntheticTensileSource
        The simulated camera (or any object with ``frames``, ``fps`` and ``forces_N()``).
    uri : str, optional
        How the session names it (default ``synthetic``).
    offset_s : float, optional
        Added to every sample's time, as a csv's (``--load-offset``); 0 for the simulator's own frames.
    max_gap_s : float, optional
        Default: ``csv_max_gap_s`` of the frame times (5 frame periods, 0.5 s at least).

    Attributes
    ----------
    specimen : dict
        The source's ``specimen`` (A0, E, yield, Rp0.2, Rm): what the stress-strain curve needs.
    """

    time_base = TIME_BASE_SESSION

    def __init__(self, source, *, uri="synthetic", offset_s=0.0, max_gap_s=None):
        self.uri = uri
        self.source_uri = getattr(source, "uri", None)
        self.offset_s = float(offset_s)
        self.specimen = dict(getattr(source, "specimen", {}) or {})
        self._time = np.arange(int(source.frames), dtype=np.float64) / float(source.fps) + self.offset_s
        self._force = np.asarray(source.forces_N(), dtype=np.float64)
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(self._time)

    def samples(self):
        return self._time.copy(), self._force.copy()

    def force_at(self, times_s):
        return interpolate_force(self._time, self._force, times_s, self.max_gap_s)

    @property
    def settings(self):
        return {**super().settings, "source": self.source_uri, "offset_s": self.offset_s, "specimen": self.specimen}


# --- tcp:// --------------------------------------------------------------------------------------

class _SampleBuffer:
    """Samples in time order in growing numpy arrays, bounded by age (``keep_s``) and count (``max_samples``).

    Not locked: its owner holds a lock around every call.
    """

    def __init__(self, keep_s, max_samples):
        self.keep_s = keep_s
        self.max_samples = max_samples
        capacity = min(1024, max_samples)
        self._t = np.empty(capacity)
        self._f = np.empty(capacity)
        self._start = 0
        self._end = 0
        self.trimmed = 0

    def __len__(self):
        return self._end - self._start

    @property
    def last_time(self):
        return self._t[self._end - 1] if self._end > self._start else -math.inf

    def append(self, time_s, force_n):
        if self._end == self._t.size:
            self._make_room()
        self._t[self._end] = time_s
        self._f[self._end] = force_n
        self._end += 1

    def view(self):
        return self._t[self._start:self._end], self._f[self._start:self._end]

    def _make_room(self):
        # Why amortised: drop what is too old, then grow (doubling, up to max_samples) or drop the
        # oldest quarter at the cap, and move what is left to the front in one copy.
        t, f = self.view()
        drop = int(np.searchsorted(t, t[-1] - self.keep_s, side="left"))
        capacity = self._t.size
        remaining = t.size - drop
        if remaining > capacity // 2 and capacity < self.max_samples:
            capacity = min(2 * capacity, self.max_samples)
        elif remaining > (3 * capacity) // 4:
            drop = t.size - (3 * capacity) // 4
        kept_t, kept_f = t[drop:].copy(), f[drop:].copy()
        self.trimmed += drop
        if capacity != self._t.size:
            self._t, self._f = np.empty(capacity), np.empty(capacity)
        self._t[:kept_t.size] = kept_t
        self._f[:kept_f.size] = kept_f
        self._start, self._end = 0, kept_t.size


def parse_line(text):
    """``(time_s or None, force_N)`` from ``force_N`` or ``time_s,force_N``; None if it is garbage."""
    fields = text.split(",")
    if len(fields) > 2:
        return None
    try:
        numbers = [float(field) for field in fields]
    except ValueError:
        return None
    if not all(math.isfinite(number) for number in numbers):
        return None
    return (None, numbers[0]) if len(numbers) == 1 else (numbers[0], numbers[1])


class TcpLoad(LoadSource):
    """Force lines read from a TCP server by a background thread (see the module notes).

    ``connected`` says whether a connection is open now, ``running`` whether the thread is alive.
    """

    time_base = TIME_BASE_MONOTONIC

    def __init__(self, host, port, *, clock="arrival", max_gap_s=DEFAULT_MAX_GAP_S, retry_s=DEFAULT_RETRY_S,
                 keep_s=DEFAULT_KEEP_S, max_samples=DEFAULT_MAX_SAMPLES, connect_timeout_s=0.5, poll_s=0.05,
                 uri=None):
        self.host, self.port = host, int(port)
        self.uri = uri or f"tcp://{host}:{port}" + ("?clock=sender" if clock == "sender" else "")
        self.clock = clock
        self.max_gap_s = float(max_gap_s)
        self.retry_s = float(retry_s)
        self.connect_timeout_s = float(connect_timeout_s)
        self.poll_s = float(poll_s)
        self._buffer = _SampleBuffer(float(keep_s), int(max_samples))
        self._lock = threading.Lock()
        self._events = []
        self._counts = {"garbage_lines": 0, "out_of_order": 0, "superseded": 0}
        self._stop = threading.Event()
        self._socket = None
        self.connected = False
        self._thread = threading.Thread(target=self._run, name=f"livedic-load {self.uri}", daemon=True)
        self._thread.start()

    # -- what the session reads --

    def samples(self):
        with self._lock:
            t, f = self._buffer.view()
            return t.copy(), f.copy()

    def force_at(self, times_s):
        with self._lock:                       # no copy of the whole buffer per frame
            t, f = self._buffer.view()
            return interpolate_force(t, f, times_s, self.max_gap_s)

    @property
    def last_sample_time_s(self):
        with self._lock:
            return float(self._buffer.last_time) if len(self._buffer) else math.nan

    def events(self, since=0):
        with self._lock:
            return self._events[since:]

    @property
    def warnings(self):
        with self._lock:
            return LoadWarnings(trimmed=self._buffer.trimmed, **self._counts)

    @property
    def running(self):
        """Whether the reader thread is alive."""
        return self._thread.is_alive()

    @property
    def settings(self):
        return {**super().settings, "clock": self.clock, "retry_s": self.retry_s,
                "keep_s": self._buffer.keep_s, "max_samples": self._buffer.max_samples}

    def close(self, timeout_s=2.0):
        """Stop the reader thread (it notices within ``poll_s``; joined for at most ``timeout_s``)."""
        self._stop.set()
        sock = self._socket
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)    # wakes a blocked recv at once
            except OSError:
                pass
        self._thread.join(timeout_s)

    # -- the reader thread --

    def _event(self, kind, message):
        with self._lock:
            if len(self._events) < MAX_EVENTS:
                self._events.append(LoadEvent(kind, f"{self.uri}: {message}", time.monotonic()))

    def _run(self):
        failing = False
        while not self._stop.is_set():
            try:
                sock = socket.create_connection((self.host, self.port), timeout=self.connect_timeout_s)
            except OSError as error:
                if not failing:
                    self._event(LoadEventKind.CONNECT_FAILED,
                                f"cannot connect ({error.strerror or error}); retrying every {self.retry_s:g} s")
                    failing = True
                self._stop.wait(self.retry_s)
                continue
            failing = False
            self._socket = sock
            self.connected = True
            self._event(LoadEventKind.CONNECTED, "connected")
            try:
                reason = self._read(sock)
            finally:
                self.connected = False
                self._socket = None
                sock.close()
            if self._stop.is_set():
                break
            self._event(LoadEventKind.DISCONNECTED, f"{reason}; reconnecting every {self.retry_s:g} s")
            self._stop.wait(self.retry_s)

    def _read(self, sock):
        """Read until the stream ends, fails or ``close()``; the reason it ended."""
        sock.settimeout(self.poll_s)
        pending = b""
        last_data = time.monotonic()
        stalled = False
        while not self._stop.is_set():
            try:
                chunk = sock.recv(65536)
            except socket.timeout:
                if not stalled and time.monotonic() - last_data > self.max_gap_s:
                    stalled = True
                    self._event(LoadEventKind.STALLED, f"no data for {self.max_gap_s:g} s: force is NaN until it resumes")
                continue
            except OSError as error:
                return f"connection lost ({error.strerror or error})"
            arrival_ns = time.monotonic_ns()
            if not chunk:
                return "the sender closed the connection"
            last_data = arrival_ns / 1e9
            if stalled:
                stalled = False
                self._event(LoadEventKind.RESUMED, "data again")
            lines = (pending + chunk).split(b"\n")
            pending = lines.pop()
            if len(pending) > MAX_LINE_BYTES:
                pending = b""
                self._count("garbage_lines")
            self._take(lines, arrival_ns)
        return "closed"

    def _count(self, name, n=1):
        with self._lock:
            self._counts[name] += n

    def _take(self, lines, arrival_ns):
        parsed = []
        garbage = 0
        for raw in lines:
            text = raw.decode("utf-8", "replace").strip()
            if not text:
                continue
            sample = parse_line(text)
            if sample is None:
                garbage += 1
            else:
                parsed.append(sample)
        with self._lock:
            self._counts["garbage_lines"] += garbage
            if not parsed:
                return
            if self.clock == "arrival":
                self._counts["superseded"] += len(parsed) - 1
                arrival_s = arrival_ns / 1e9
                if arrival_s > self._buffer.last_time:
                    self._buffer.append(arrival_s, parsed[-1][1])
                return
            for time_s, force_n in parsed:
                if time_s is None or time_s <= self._buffer.last_time:
                    self._counts["out_of_order" if time_s is not None else "garbage_lines"] += 1
                    continue
                self._buffer.append(time_s, force_n)


# --- open_load -----------------------------------------------------------------------------------

def _option(name, value, low=None, low_open=False):
    try:
        return parse_number(value, low=low, low_open=low_open)
    except ValueError as error:
        raise LoadError(f"load option {name}={value!r}: {error}") from None


def _open_tcp(uri, options):
    parts = urlsplit(uri)
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or not port or parts.path not in ("", "/"):
        raise LoadError(f"load {uri!r}: expected tcp://HOST:PORT (port 1-65535)[?clock=arrival|sender]")
    merged = dict(parse_qsl(parts.query, keep_blank_values=True))
    merged.update(options)
    clock = str(merged.pop("clock", "arrival")).strip().lower()
    if clock not in ("arrival", "sender"):
        raise LoadError(f"load {uri!r}: clock={clock!r}; use clock=arrival (stamp lines on arrival) "
                        f"or clock=sender (time_s is on the monotonic clock already)")
    kwargs = {}
    for name, low in (("max_gap_s", 0.0), ("retry_s", 0.0), ("keep_s", 0.0), ("connect_timeout_s", 0.0),
                      ("poll_s", 0.0)):
        if name in merged:
            kwargs[name] = _option(name, merged.pop(name), low=low, low_open=True)
    if "max_samples" in merged:
        kwargs["max_samples"] = int(_option("max_samples", merged.pop("max_samples"), low=4))
    if merged:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(merged))}; tcp takes clock, "
                        f"max_gap_s, retry_s, keep_s, max_samples")
    return TcpLoad(host, port, clock=clock, uri=uri, **kwargs)


def _open_synthetic(uri, options):
    """``synthetic`` with ``source=`` (the session's simulated camera) or ``synthetic:tensile?...``."""
    source = options.pop("source", None)
    offset_s = _option("offset_s", options.pop("offset_s", 0.0))
    max_gap_s = options.pop("max_gap_s", None)
    if max_gap_s is not None:
        max_gap_s = _option("max_gap_s", max_gap_s, low=0.0, low_open=True)
    if options:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(options))}; synthetic takes source, "
                        f"offset_s, max_gap_s")
    if uri.lower() == "synthetic":
        if source is None:
            raise LoadError(f"load {uri!r}: the simulator's force needs the simulated camera: pass source= "
                            f"(a synthetic:tensile source), or name the test: synthetic:tensile?...")
        if not callable(getattr(source, "forces_N", None)):
            raise LoadError(f"load {uri!r}: the camera {getattr(source, 'uri', type(source).__name__)!r} is not a "
                            f"simulated tensile test; --load synthetic needs --source synthetic:tensile?...")
        return SyntheticLoad(source, uri=uri, offset_s=offset_s, max_gap_s=max_gap_s)
    if source is not None:
        raise LoadError(f"load {uri!r}: give either source= with load synthetic, or the test's URI, not both")
    from livedic.acquire.base import SourceError
    from livedic.acquire.synthetic import SyntheticTensileSource, parse_synthetic_uri
    try:
        model, _ = parse_synthetic_uri(uri)
        if model != "tensile":
            raise SourceError(f"synthetic:{model} has no force; use synthetic:tensile?...")
        source = SyntheticTensileSource(uri)
    except SourceError as error:
        raise LoadError(f"load {uri!r}: {error}") from None
    return SyntheticLoad(source, uri=uri, offset_s=offset_s, max_gap_s=max_gap_s)


def open_load(uri, **options):
    """Open the force signal named by ``uri``.

    Parameters
    ----------
    uri : str
        ``csv:FILE``, ``tcp://HOST:PORT[?clock=arrival|sender]``, ``synthetic`` or
        ``synthetic:tensile?...`` (see the module notes).
    **options
        csv: ``offset_s`` (``--load-offset``), ``max_gap_s`` (default: see ``csv_max_gap_s``).
        synthetic: ``source`` (the ``synthetic:tensile`` camera; required for plain ``synthetic``),
        ``offset_s``, ``max_gap_s``.
        tcp: ``clock``, ``max_gap_s``, ``retry_s``, ``keep_s``, ``max_samples``, ``connect_timeout_s``,
        ``poll_s``. They override the query string.

    Returns
    -------
    LoadSource
        A tcp source is returned at once, connected or not: its ``events()`` say which.

    Raises
    ------
    LoadError
        (a ``ValueError``) one line: malformed or unknown URI, a scheme not built yet, a bad option or file.
    """
    if not isinstance(uri, str) or not uri.strip():
        raise LoadError(f"empty load URI; {LOAD_USAGE}")
    uri = uri.strip()
    scheme, sep, rest = uri.partition(":")
    scheme = scheme.lower()
    if scheme in NOT_BUILT:
        raise LoadError(f"load {uri!r}: {scheme} is not built yet; {LOAD_USAGE}")
    if scheme == "synthetic":
        return _open_synthetic(uri, options)
    if not sep or scheme not in ("csv", "tcp"):
        raise LoadError(f"unknown load {uri!r}; {LOAD_USAGE}")
    if scheme == "tcp":
        return _open_tcp(uri, options)
    if not rest:
        raise LoadError(f"load {uri!r} names no file; {LOAD_USAGE}")
    offset_s = _option("offset_s", options.pop("offset_s", 0.0))
    max_gap_s = options.pop("max_gap_s", None)
    if max_gap_s is not None:
        max_gap_s = _option("max_gap_s", max_gap_s, low=0.0, low_open=True)
    if options:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(options))}; csv takes offset_s, max_gap_s")
    return CsvLoad(rest, offset_s=offset_s, max_gap_s=max_gap_s, uri=uri)
