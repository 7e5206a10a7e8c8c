"""``open_load(uri)``: the testing machine's force signal, opened from a URI like a frame source.

Valid forms::

    csv:FILE                         a file exported by the machine's software (header ``time_s,force_N``)
    tcp://HOST:PORT[?clock=arrival|sender]   text lines ``force_N`` or ``time_s,force_N`` over TCP
    modbus://HOST:PORT?register=N[&scale=K&...]   one register of a PLC, polled (Modbus TCP, pymodbus)
    synthetic                        the simulator's force: ``open_load("synthetic", source=SOURCE)``
                                     with SOURCE the session's ``synthetic:tensile`` camera
    synthetic:tensile?...            the same force for a simulated test named by its camera URI
                                     (nothing is rendered: the force needs only the model)

Every error is a ``LoadError`` (a ``ValueError``) of one line, naming the file and line or the
option at fault.

Time bases (``LoadSource.time_base``)
-------------------------------------
Each source gives force at times on one clock, in seconds:

* ``"session"`` (``csv:``, ``synthetic``): seconds since the session's first frame, as the machine's software
  exports them, shifted by ``offset_s`` (the CLI's ``--load-offset S``): a sample written at
  ``time_s`` belongs to frame time ``time_s + offset_s``. The session passes each frame's
  timestamp relative to the first frame: ``(frame.timestamp_ns - first.timestamp_ns) / 1e9``.
  ``synthetic`` has one sample per frame of the simulated camera, frame i at ``i / fps``: its
  ``force_N(i)`` (``acquire.simulator.sources``, module notes, Force), exact at frame times; between two
  frames the force is interpolated linearly (so across the fracture it falls from the last loaded
  frame's force to 0). ``max_gap_s`` is 5 frame periods (0.5 s at least), as a csv's.
* ``"monotonic"`` (``tcp://``, ``modbus://``): ``time.monotonic_ns() / 1e9``, the clock that stamps frame
  arrival (``stream.tracker_loop``'s ``arrival_ns``). Each line is stamped when it arrives, unless
  ``?clock=sender`` says its ``time_s`` is already on that clock (a sender on the same host that
  stamps with ``time.monotonic()``: the exact time of the reading, not of its delivery); each
  Modbus value halfway between its request and the answer. The session passes each frame's
  arrival: ``arrival_ns / 1e9``. ``offset_s`` (``--load-offset``) is added to a stream's sample
  times too (a known delay of the sender, negative), 0 by default.

``LoadSource.frame_time_s(since_first_frame_s=..., arrival_ns=...)`` picks the one its base needs.

Interpolation (``force_at``)
----------------------------
Linear between the two samples around each frame time; NaN before the first sample, after the
last one (never extrapolated), and where the two samples are more than ``max_gap_s`` apart (a
stream that stalled: a stale value is never used), or around a NaN marker (a stream leaves one
where a connection was lost or a Modbus poll got no value, so nothing is interpolated across it).
``max_gap_s`` defaults to 0.5 s for tcp, for modbus to 0.5 s or 5 poll periods, and for csv to
0.5 s or 5 median sample intervals of the file, whichever is longer.

A live frame usually arrives before the stream's next sample: ``force_when_known(time_s)`` waits
for it, bounded (until ``time_s`` plus two recent sample intervals and the delivery lag, at most
``max_gap_s``, on the monotonic clock; not at all when the stream has stalled), and is
``force_at`` for a file or the simulator.

TCP source
----------
A background thread connects (client), reads lines and stamps them; a line that is not one or
two finite numbers is counted (``warnings.garbage_lines``) and skipped, the first of a
connection also a ``bad_data`` event. Lines that arrive in one
read share one arrival instant: with arrival stamping only the last of them is kept (the
freshest reading; the others are counted in ``warnings.superseded``), so a fast DAQ stream is
thinned to the rate of reads: use ``?clock=sender`` for every sample with its true time. With
sender times a sample not later than the previous one is counted (``warnings.out_of_order``) and
skipped, and a bare ``force_N`` line (no time) is garbage. No data for ``max_gap_s`` is a ``stalled`` event (``resumed`` when data comes back); a
refused or lost connection is an event (and, with arrival stamping, a NaN marker) and the thread
reconnects every ``retry_s`` (1 s). ``close()`` stops the thread (joined with a timeout).

Modbus source
-------------
``modbus://HOST:PORT?register=N&scale=K`` polls one value with a pymodbus ``ModbusTcpClient``
from a background thread (``ModbusLoad``). Options in the query (or as keywords of ``open_load``):

==============  ==========================================================  =================
option          meaning                                                     default
==============  ==========================================================  =================
``register``    address of the (first) register, 0-based as sent on the      required
                wire (the register a manual calls 40001 or 30001 is 0)
``scale``       newtons per unit: ``force_N = value x scale`` (non-zero)     1
``kind``        ``holding`` (function 3) or ``input`` (function 4)           holding
``type``        ``int16``, ``uint16``, ``int32``, ``uint32``, ``float32``;     int16
                32-bit types read 2 registers
``word_order``  ``big`` (first register = high word) or ``little``           big
``unit``        the device (slave, unit) id, 0-255                           1
``rate``        polls per second, at most 1000                               100
``max_gap_s``   a longer hole between values is a stall (NaN)                 max(0.5, 5/rate)
``timeout_s``   connect and answer timeout of one poll                        0.25
``retry_s``     reconnect period after a lost or refused connection           1
``keep_s``, ``max_samples``, ``offset_s``: as for tcp
==============  ==========================================================  =================

Values are decoded by pymodbus (``convert_from_registers``). Each answered poll is a sample
stamped halfway between request and answer. A poll answered with a Modbus exception (a wrong
register, kind or unit), not answered within ``timeout_s``, or holding a non-finite float32 is
counted (``warnings.exception_responses``, ``timeouts``, ``bad_values``), leaves a NaN marker
(no force is interpolated across it) and, first of a run of failures, is a ``read_failed``
event; after a timeout the connection is reopened (a late answer must not pass for the next
poll's). Stall, resume, refused and lost connections are events as for tcp, never an exception
in the session; pymodbus's own log records are kept off stderr (a ``NullHandler`` on the
``pymodbus`` logger) since each is said once as an event.

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

__all__ = ["LoadError", "LoadEventKind", "LoadEvent", "LoadWarnings", "LoadSource", "CsvLoad", "StreamingLoad",
           "TcpLoad", "ModbusLoad", "SyntheticLoad",
           "open_load", "interpolate_force", "read_force_csv", "csv_max_gap_s", "parse_line", "decode_registers",
           "modbus_register_count", "TIME_BASE_SESSION", "TIME_BASE_MONOTONIC", "LOAD_USAGE"]

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
              "modbus://HOST:PORT?register=N[&scale=K...], "
              "synthetic (with the synthetic:tensile camera) or synthetic:tensile?...")


class LoadError(ValueError):
    """A load URI, option or file that cannot be used; the one-line message says what and where."""


class LoadEventKind(str, enum.Enum):
    """What happened to a streamed force signal."""
    CONNECTED = "connected"
    CONNECT_FAILED = "connect_failed"    # once per outage, not once per retry
    DISCONNECTED = "disconnected"
    STALLED = "stalled"                  # no data for max_gap_s
    RESUMED = "resumed"                  # data again after a stall
    BAD_DATA = "bad_data"                # a line that is not a force: once per connection (then counted)
    READ_FAILED = "read_failed"          # a poll without a value (exception, timeout): once per run of failures

    @property
    def is_trouble(self):
        """Whether the event is a warning (the force is, or may be, missing) rather than news."""
        return self in _TROUBLE


_TROUBLE = frozenset({LoadEventKind.CONNECT_FAILED, LoadEventKind.DISCONNECTED, LoadEventKind.STALLED,
                      LoadEventKind.BAD_DATA, LoadEventKind.READ_FAILED})


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
    exception_responses: int = 0     # modbus: the server answered a poll with an exception code
    timeouts: int = 0                # modbus: no answer to a poll within timeout_s
    bad_values: int = 0              # modbus: a float32 register holding NaN or infinity

    def total(self):
        """How many lines or polls gave no sample (``trimmed`` excluded: those were good samples, dropped when old)."""
        return (self.garbage_lines + self.out_of_order + self.exception_responses + self.timeouts
                + self.bad_values)


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

    def force_when_known(self, time_s, *, wait_s=None):
        """Force (N) at one frame time, waiting (bounded) for a live stream's next sample.

        A live frame usually arrives before the stream's next sample, and force is never
        extrapolated: asked at once, it would be NaN. A file or the simulator knows every sample
        already: this is ``force_at(time_s)``. A stream (``StreamingLoad``) waits until it has a
        sample at or after ``time_s``, at most until ``time_s + wait_s`` on the monotonic clock
        (default: two of its recent sample intervals plus its delivery lag, at most ``max_gap_s``),
        and not at all when its newest sample is more than ``max_gap_s`` before ``time_s`` (a
        stalled stream: NaN at once). A session is thus never more than ``wait_s`` behind a frame's
        arrival because of its force, and waits never add up.
        """
        return float(np.asarray(self.force_at(np.atleast_1d(np.float64(time_s))), np.float64)[0])

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


class _KnownSamples(LoadSource):
    """A force known in full before the session (a file, the simulator's law), on session time.

    Read in place: the per-frame look-ups (``force_at``, ``last_sample_time_s``) copy nothing, whatever
    the length of the file (a 1 kHz log of a long test holds 10^5-10^6 samples).
    """

    time_base = TIME_BASE_SESSION
    _time = np.zeros(0)
    _force = np.zeros(0)

    def samples(self):
        return self._time.copy(), self._force.copy()

    def force_at(self, times_s):
        return interpolate_force(self._time, self._force, times_s, self.max_gap_s)

    @property
    def last_sample_time_s(self):
        return float(self._time[-1]) if self._time.size else math.nan


class CsvLoad(_KnownSamples):
    """Force from a CSV file; times are seconds since the session's first frame, plus ``offset_s``."""

    def __init__(self, path, *, offset_s=0.0, max_gap_s=None, uri=None):
        self.path = str(path)
        self.uri = uri or f"csv:{self.path}"
        self.offset_s = float(offset_s)
        time_s, self._force = read_force_csv(self.path)
        self._time = time_s + self.offset_s
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(time_s)

    @property
    def settings(self):
        return {**super().settings, "offset_s": self.offset_s}


# --- synthetic ----------------------------------------------------------------------------------

class SyntheticLoad(_KnownSamples):
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

    def __init__(self, source, *, uri="synthetic", offset_s=0.0, max_gap_s=None):
        self.uri = uri
        self.source_uri = getattr(source, "uri", None)
        self.offset_s = float(offset_s)
        self.specimen = dict(getattr(source, "specimen", {}) or {})
        self._time = np.arange(int(source.frames), dtype=np.float64) / float(source.fps) + self.offset_s
        self._force = np.asarray(source.forces_N(), dtype=np.float64)
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(self._time)

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


class StreamingLoad(LoadSource):
    """What a force stream read by a background thread shares (tcp://, modbus://): samples on the
    monotonic clock in a bounded ``_SampleBuffer``, events, warning counts, the thread and ``close()``.

    A subclass sets ``uri``, ``max_gap_s``, ``retry_s`` and ``_counts`` (its warning names) and
    implements ``_run`` (the thread's body, which returns when ``_stop`` is set); it calls
    ``_start_thread()`` at the end of its ``__init__``. ``connected`` says whether a connection is
    open now, ``running`` whether the thread is alive.
    """

    time_base = TIME_BASE_MONOTONIC

    def __init__(self, *, max_gap_s, retry_s, keep_s, max_samples, counts, offset_s=0.0):
        self.offset_s = float(offset_s)
        self.max_gap_s = float(max_gap_s)
        self.retry_s = float(retry_s)
        self._buffer = _SampleBuffer(float(keep_s), int(max_samples))
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)      # notified with every sample stored
        self._last_arrival_s = -math.inf                       # monotonic time the newest sample was stored
        self.nominal_interval_s = None                         # a source that polls knows its period
        self._events = []
        self._counts = dict.fromkeys(counts, 0)
        self._stop = threading.Event()
        self.connected = False
        self._thread = None

    def _start_thread(self):
        self._thread = threading.Thread(target=self._run, name=f"livedic-load {self.uri}", daemon=True)
        self._thread.start()

    # -- what the session reads --

    def samples(self):
        with self._lock:
            t, f = self._buffer.view()
            return t + self.offset_s, f.copy()

    def force_at(self, times_s):
        with self._lock:                       # no copy of the whole buffer per frame
            t, f = self._buffer.view()
            return interpolate_force(t, f, np.asarray(times_s, np.float64) - self.offset_s, self.max_gap_s)

    @property
    def last_sample_time_s(self):
        with self._lock:
            return float(self._buffer.last_time) + self.offset_s if len(self._buffer) else math.nan

    def force_when_known(self, time_s, *, wait_s=None):
        # Why the deadline is time_s + wait and not "now + wait": a session that is behind (its frames
        # queued) does not wait for frames whose samples are long known, so waits never add up; and
        # why the wait is about two sample intervals, not max_gap_s: at the start of a stall every
        # frame waits its full wait, and a lag of max_gap_s (0.5 s) would fill the frame queue.
        t = float(time_s) - self.offset_s                     # on the stored clock (monotonic)
        with self._arrived:
            deadline = t + (self._default_wait_s() if wait_s is None else float(wait_s))
            while not self._stop.is_set():
                last = self._buffer.last_time
                if last >= t or last < t - self.max_gap_s:    # known, or the stream stalled before t
                    break
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._arrived.wait(remaining)
            times, forces = self._buffer.view()
            return float(interpolate_force(times, forces, np.float64(t), self.max_gap_s))

    def _default_wait_s(self):
        """Two sample intervals (the median of the last few, else ``nominal_interval_s``) plus the
        newest sample's delivery lag (arrival minus its time: a sender's delay, a Modbus round
        trip), at most ``max_gap_s``; 0 while the interval is unknown. Called with the lock held."""
        times, _ = self._buffer.view()
        recent = np.diff(times[-9:])
        interval = float(np.median(recent)) if recent.size else self.nominal_interval_s
        if interval is None or not math.isfinite(interval):
            return 0.0
        lag = max(0.0, self._last_arrival_s - float(self._buffer.last_time)) if times.size else 0.0
        return min(self.max_gap_s, 2.0 * interval + lag)

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
        return self._thread is not None and self._thread.is_alive()

    @property
    def settings(self):
        return {**super().settings, "retry_s": self.retry_s, "offset_s": self.offset_s,
                "keep_s": self._buffer.keep_s, "max_samples": self._buffer.max_samples}

    def close(self, timeout_s=2.0):
        """Stop the reader thread (``_wake`` interrupts a blocked read; joined for at most ``timeout_s``)."""
        self._stop.set()
        with self._arrived:
            self._arrived.notify_all()
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def _wake(self):
        """Interrupt a read in progress (the thread checks ``_stop`` after it)."""

    # -- for the reader thread --

    def _run(self):
        """The reader thread: connect, read until the connection ends, reconnect every ``retry_s``, until ``_stop``.

        A failed connection is one event until one succeeds; each loss is an event, and a gap
        marker where the source stamps samples on arrival (never interpolated across an outage).
        """
        failing = False
        while not self._stop.is_set():
            connection, message = self._connect()
            if connection is None:
                if not failing:
                    self._event(LoadEventKind.CONNECT_FAILED, f"{message}; retrying every {self.retry_s:g} s")
                    failing = True
                self._stop.wait(self.retry_s)
                continue
            failing = False
            self.connected = True
            self._event(LoadEventKind.CONNECTED, message)
            try:
                reason = self._read_until_lost(connection)
            finally:
                self.connected = False
                self._hang_up(connection)
            if self._stop.is_set():
                break
            if self._outage_is_a_gap:
                self._append(time.monotonic(), math.nan)   # why: never interpolate across an outage
            self._event(LoadEventKind.DISCONNECTED, f"{reason}; reconnecting every {self.retry_s:g} s")
            self._stop.wait(self.retry_s)

    @abstractmethod
    def _connect(self):
        """(connection, "connected ..." message), or (None, "cannot connect ...") for the event."""

    @abstractmethod
    def _read_until_lost(self, connection):
        """Read samples until the connection is lost or ``close()``; the reason it ended, in words."""

    @abstractmethod
    def _hang_up(self, connection):
        """Close ``connection`` (the reader thread's; after ``_read_until_lost``)."""

    @property
    def _outage_is_a_gap(self):
        """Whether a lost connection adds a NaN gap marker (sources stamping samples on arrival)."""
        return True

    def _event(self, kind, message):
        with self._lock:
            if len(self._events) < MAX_EVENTS:
                self._events.append(LoadEvent(kind, f"{self.uri}: {message}", time.monotonic()))

    def _count(self, name, n=1):
        with self._lock:
            self._counts[name] += n

    def _append(self, time_s, force_n):
        """Add one sample (NaN force: a gap marker) if it is later than the last one; whether it was."""
        with self._lock:
            if time_s > self._buffer.last_time:
                self._buffer.append(time_s, force_n)
                self._stored()
                return True
            return False

    def _stored(self):
        """After samples were stored (lock held): note when, and wake ``force_when_known``."""
        self._last_arrival_s = time.monotonic()
        self._arrived.notify_all()


class TcpLoad(StreamingLoad):
    """Force lines read from a TCP server by a background thread (see the module notes).

    ``connected`` says whether a connection is open now, ``running`` whether the thread is alive.
    """

    def __init__(self, host, port, *, clock="arrival", max_gap_s=DEFAULT_MAX_GAP_S, retry_s=DEFAULT_RETRY_S,
                 keep_s=DEFAULT_KEEP_S, max_samples=DEFAULT_MAX_SAMPLES, connect_timeout_s=0.5, poll_s=0.05,
                 offset_s=0.0, uri=None):
        super().__init__(max_gap_s=max_gap_s, retry_s=retry_s, keep_s=keep_s, max_samples=max_samples,
                         counts=("garbage_lines", "out_of_order", "superseded"), offset_s=offset_s)
        self.host, self.port = host, int(port)
        self.uri = uri or f"tcp://{host}:{port}" + ("?clock=sender" if clock == "sender" else "")
        self.clock = clock
        self.connect_timeout_s = float(connect_timeout_s)
        self.poll_s = float(poll_s)
        self._socket = None
        self._garbage_told = False
        self._start_thread()

    @property
    def settings(self):
        return {**super().settings, "clock": self.clock}

    def _wake(self):
        sock = self._socket
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)    # wakes a blocked recv at once
            except OSError:
                pass

    # -- the reader thread --

    def _connect(self):
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.connect_timeout_s)
        except OSError as error:
            return None, f"cannot connect ({error.strerror or error})"
        self._socket = sock
        self._garbage_told = False
        return sock, "connected"

    def _hang_up(self, sock):
        self._socket = None
        sock.close()

    @property
    def _outage_is_a_gap(self):
        return self.clock == "arrival"      # sender times: the gap shows in the samples' own times

    def _read_until_lost(self, sock):
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
                self._garbage(f"{pending[:30]!r}... (over {MAX_LINE_BYTES} bytes without a newline)")
                pending = b""
            self._take(lines, arrival_ns)
        return "closed"

    def _garbage(self, text, n=1):
        """Count ``n`` garbage lines; the first of a connection is also a ``BAD_DATA`` event."""
        self._count("garbage_lines", n)
        if not self._garbage_told:
            self._garbage_told = True
            self._event(LoadEventKind.BAD_DATA, f"skipped a line that is not force_N or time_s,force_N: {text}; "
                                                f"further ones are counted (warnings.garbage_lines)")

    def _take(self, lines, arrival_ns):
        parsed = []
        garbage = 0
        for raw in lines:
            text = raw.decode("utf-8", "replace").strip()
            if not text:
                continue
            sample = parse_line(text)
            if sample is None:
                if not garbage:
                    first_garbage = text
                garbage += 1
            else:
                parsed.append(sample)
        if garbage:
            self._garbage(repr(first_garbage[:40]), garbage)
        with self._lock:
            if not parsed:
                return
            if self.clock == "arrival":
                self._counts["superseded"] += len(parsed) - 1
                arrival_s = arrival_ns / 1e9
                if arrival_s > self._buffer.last_time:
                    self._buffer.append(arrival_s, parsed[-1][1])
                    self._stored()
                return
            for time_s, force_n in parsed:
                if time_s is None or time_s <= self._buffer.last_time:
                    self._counts["out_of_order" if time_s is not None else "garbage_lines"] += 1
                    continue
                self._buffer.append(time_s, force_n)
            self._stored()


# --- modbus:// -----------------------------------------------------------------------------------

MODBUS_KINDS = ("holding", "input")
MODBUS_TYPES = ("int16", "uint16", "int32", "uint32", "float32")
MODBUS_WORD_ORDERS = ("big", "little")
DEFAULT_MODBUS_RATE_HZ = 100.0
MAX_MODBUS_RATE_HZ = 1000.0
DEFAULT_MODBUS_TIMEOUT_S = 0.25
MODBUS_FORM = ("modbus://HOST:PORT?register=N[&scale=K&kind=holding|input&type=int16|uint16|int32|uint32|float32"
               "&word_order=big|little&unit=ID&rate=HZ]")


def modbus_register_count(value_type):
    """Registers one value of ``value_type`` takes: 1 for 16-bit types, 2 for 32-bit ones."""
    return 2 if value_type in ("int32", "uint32", "float32") else 1


def decode_registers(registers, value_type, word_order="big"):
    """The number held in ``registers`` (16-bit words) as ``value_type``, by pymodbus's own conversion.

    Parameters
    ----------
    registers : sequence of int
        One register (16-bit types) or two (32-bit types), as a read returns them.
    value_type : str
        One of ``MODBUS_TYPES``.
    word_order : str
        ``big`` (the first register holds the high word, the Modbus convention) or ``little``.

    Returns
    -------
    int or float (float32 may be NaN or infinite: the caller decides).
    """
    from pymodbus.client import ModbusTcpClient
    return ModbusTcpClient.convert_from_registers(list(registers), ModbusTcpClient.DATATYPE[value_type.upper()],
                                                  word_order=word_order)


def _quiet_pymodbus():
    """pymodbus logs every refused connection and timeout as an error, with a dump of the last frames;
    livedic says each as one event instead. A NullHandler keeps those records from Python's
    last-resort stderr handler while still passing them to handlers an application configured."""
    import logging
    logger = logging.getLogger("pymodbus")
    if not any(isinstance(handler, logging.NullHandler) for handler in logger.handlers):
        logger.addHandler(logging.NullHandler())


class ModbusLoad(StreamingLoad):
    """Force read from one Modbus TCP register, polled at ``rate_hz`` by a background thread.

    Each answered poll is a sample ``force_N = value x scale`` stamped on the monotonic clock (the
    one that stamps frame arrival) halfway between the request and the answer: the server read
    the register inside that interval, so the stamp is off by at most half the round trip. A poll
    that gets no value (an exception response, no answer within ``timeout_s``, a non-finite
    float32) is counted in ``warnings`` and leaves a NaN marker at its time, so no force is
    interpolated across it; the first of a run of failures is a ``READ_FAILED`` event. After a
    timeout the connection is reopened (a late answer must not be taken for the next poll's).
    No answered poll for ``max_gap_s`` is ``STALLED`` (``RESUMED`` when values come back); a
    refused or lost connection is an event, a NaN marker, and a retry every ``retry_s``.

    Parameters
    ----------
    host, port : str, int
    register : int
        Address of the (first) register as sent in the request, 0-65535 (0-based: the register a
        manual calls 40001 or 30001 is 0).
    scale : float
        Newtons per unit of the register's value (non-zero).
    kind : {"holding", "input"}
        Function 3 (read holding registers) or 4 (read input registers).
    value_type : {"int16", "uint16", "int32", "uint32", "float32"}
        32-bit types read two registers.
    word_order : {"big", "little"}
        Which register of a 32-bit value holds the high word (``big``: the first).
    unit : int
        The device (slave, unit) id, 0-255.
    rate_hz : float
        Polls per second (at most ``MAX_MODBUS_RATE_HZ``); a poll that answers late delays the
        next one rather than bursting to catch up.
    max_gap_s : float, optional
        Default: 5 poll periods, 0.5 s at least.
    timeout_s : float
        Connect and answer timeout of one poll.
    """

    def __init__(self, host, port, *, register, scale=1.0, kind="holding", value_type="int16", word_order="big",
                 unit=1, rate_hz=DEFAULT_MODBUS_RATE_HZ, max_gap_s=None, retry_s=DEFAULT_RETRY_S,
                 timeout_s=DEFAULT_MODBUS_TIMEOUT_S, keep_s=DEFAULT_KEEP_S, max_samples=DEFAULT_MAX_SAMPLES,
                 offset_s=0.0, uri=None):
        rate_hz = float(rate_hz)
        if max_gap_s is None:
            max_gap_s = max(DEFAULT_MAX_GAP_S, 5.0 / rate_hz)
        super().__init__(max_gap_s=max_gap_s, retry_s=retry_s, keep_s=keep_s, max_samples=max_samples,
                         counts=("exception_responses", "timeouts", "bad_values"), offset_s=offset_s)
        self.host, self.port = host, int(port)
        self.register, self.scale, self.kind = int(register), float(scale), kind
        self.value_type, self.word_order, self.unit = value_type, word_order, int(unit)
        self.rate_hz, self.timeout_s = rate_hz, float(timeout_s)
        self.uri = uri or f"modbus://{host}:{port}?register={self.register}&scale={self.scale:g}"
        self._count_registers = modbus_register_count(value_type)
        self.nominal_interval_s = 1.0 / rate_hz
        self._client = None
        _quiet_pymodbus()
        self._start_thread()

    @property
    def settings(self):
        return {**super().settings, "register": self.register, "scale": self.scale, "kind": self.kind,
                "type": self.value_type, "word_order": self.word_order, "unit": self.unit, "rate_hz": self.rate_hz,
                "timeout_s": self.timeout_s}

    def _wake(self):
        client = self._client
        sock = getattr(client, "socket", None)
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)    # an answer being waited for returns at once
            except OSError:
                pass

    # -- the reader thread --

    def _where(self):
        return f"{self.kind} register {self.register} ({self.value_type}) of unit {self.unit}"

    def _connect(self):
        from pymodbus.client import ModbusTcpClient
        client = ModbusTcpClient(self.host, port=self.port, timeout=self.timeout_s, retries=0)
        if not client.connect():
            client.close()
            return None, "cannot connect to the Modbus server"
        self._client = client
        return client, f"connected; polling the {self._where()} at {self.rate_hz:g} Hz"

    def _hang_up(self, client):
        self._client = None
        client.close()

    def _read_until_lost(self, client):
        """Poll until the connection is lost or ``close()``; the reason it ended."""
        from pymodbus.exceptions import ConnectionException, ModbusException
        read = client.read_holding_registers if self.kind == "holding" else client.read_input_registers
        period = 1.0 / self.rate_hz
        due = time.monotonic()
        last_value = due                  # a fresh connection has until max_gap_s to answer
        stalled = failing = False
        while not self._stop.is_set():
            sent_ns = time.monotonic_ns()
            try:
                if not client.connected and not client.connect():
                    return "cannot reconnect after a poll without an answer"
                response = read(self.register, count=self._count_registers, device_id=self.unit)
            except ConnectionException as error:
                if self._stop.is_set():
                    break
                return f"connection lost ({_first_line(error)})"
            except ModbusException as error:          # no answer within timeout_s (or a mismatched one)
                response = error
            except (OSError, ValueError) as error:     # why: whatever the wire does, the thread carries on
                return f"connection lost ({type(error).__name__}: {_first_line(error)})"
            answered_ns = time.monotonic_ns()
            stamp_s = (sent_ns + answered_ns) / 2e9
            problem = self._take(response, stamp_s)
            if problem is None:
                last_value = answered_ns / 1e9
                if stalled:
                    stalled = False
                    self._event(LoadEventKind.RESUMED, "values again")
                failing = False
            else:
                self._append(stamp_s, math.nan)
                if not failing:
                    failing = True
                    self._event(LoadEventKind.READ_FAILED, f"{problem}; force is NaN until a poll answers "
                                                           f"(further failures are counted)")
                if isinstance(response, Exception):
                    client.close()       # why: a late answer would be read as the next poll's
            now = time.monotonic()
            if not stalled and now - last_value > self.max_gap_s:
                stalled = True
                self._event(LoadEventKind.STALLED, f"no value for {self.max_gap_s:g} s: force is NaN until it resumes")
            due = max(due + period, now)
            self._stop.wait(due - now)
        return "closed"

    def _take(self, response, stamp_s):
        """Store the sample a poll's answer holds; None, or what went wrong (counted)."""
        if isinstance(response, Exception):
            self._count("timeouts")
            return f"no answer from the {self._where()} within {self.timeout_s:g} s"
        if response.isError():
            self._count("exception_responses")
            return (f"the server answered a read of the {self._where()} with exception "
                    f"{_exception_name(response.exception_code)}: check register=, kind=, type= and unit=")
        try:
            value = decode_registers(response.registers, self.value_type, self.word_order)
        except Exception as error:       # why: a device answering the wrong register count must not end the thread
            self._count("bad_values")
            return f"the answer from the {self._where()} does not decode ({_first_line(error)})"
        force_n = float(value) * self.scale
        if not math.isfinite(force_n):
            self._count("bad_values")
            return f"the {self._where()} holds {value!r}, not a finite force"
        self._append(stamp_s, force_n)
        return None


def _exception_name(code):
    from pymodbus.constants import ExcCodes
    try:
        return f"{int(code)} ({ExcCodes(code).name.lower().replace('_', ' ')})"
    except ValueError:
        return str(code)


def _first_line(error):
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__


# --- open_load -----------------------------------------------------------------------------------

def _option(name, value, low=None, low_open=False, integer=False):
    try:
        return parse_number(value, low=low, low_open=low_open, integer=integer)
    except ValueError as error:
        raise LoadError(f"load option {name}={value!r}: {error}") from None


def _address_and_options(uri, options, form):
    """(host, port, options of the query updated with ``options``) of a stream URI; LoadError naming ``form``."""
    parts = urlsplit(uri)
    try:
        host, port = parts.hostname, parts.port
    except ValueError:
        host, port = None, None
    if not host or not port or parts.path not in ("", "/"):
        raise LoadError(f"load {uri!r}: expected {form}")
    merged = dict(parse_qsl(parts.query, keep_blank_values=True))
    merged.update(options)
    return host, port, merged


def _open_tcp(uri, options):
    host, port, merged = _address_and_options(uri, options, "tcp://HOST:PORT (port 1-65535)[?clock=arrival|sender]")
    clock = str(merged.pop("clock", "arrival")).strip().lower()
    if clock not in ("arrival", "sender"):
        raise LoadError(f"load {uri!r}: clock={clock!r}; use clock=arrival (stamp lines on arrival) "
                        f"or clock=sender (time_s is on the monotonic clock already)")
    kwargs = {}
    for name, low in (("max_gap_s", 0.0), ("retry_s", 0.0), ("keep_s", 0.0), ("connect_timeout_s", 0.0),
                      ("poll_s", 0.0)):
        if name in merged:
            kwargs[name] = _option(name, merged.pop(name), low=low, low_open=True)
    if "offset_s" in merged:
        kwargs["offset_s"] = _option("offset_s", merged.pop("offset_s"))
    if "max_samples" in merged:
        kwargs["max_samples"] = int(_option("max_samples", merged.pop("max_samples"), low=4))
    if merged:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(merged))}; tcp takes clock, "
                        f"max_gap_s, retry_s, keep_s, max_samples, offset_s")
    return TcpLoad(host, port, clock=clock, uri=uri, **kwargs)


def _open_modbus(uri, options):
    """``modbus://HOST:PORT?register=N&...`` (see ``ModbusLoad`` and the module notes)."""
    host, port, merged = _address_and_options(uri, options, f"{MODBUS_FORM} (port 1-65535)")
    if "register" not in merged:
        raise LoadError(f"load {uri!r}: register= is required (the force register's 0-based address); "
                        f"expected {MODBUS_FORM}")
    kwargs = {"register": int(_option("register", merged.pop("register"), low=0, integer=True))}
    for name, keyword, allowed in (("kind", "kind", MODBUS_KINDS), ("type", "value_type", MODBUS_TYPES),
                                   ("word_order", "word_order", MODBUS_WORD_ORDERS)):
        if name in merged:
            value = str(merged.pop(name)).strip().lower()
            if value not in allowed:
                raise LoadError(f"load {uri!r}: {name}={value!r}; use {name}={'|'.join(allowed)}")
            kwargs[keyword] = value
    last = 65535 - (modbus_register_count(kwargs.get("value_type", "int16")) - 1)
    if kwargs["register"] > last:
        raise LoadError(f"load {uri!r}: register={kwargs['register']}: must be 0-{last} for this type")
    if "scale" in merged:
        kwargs["scale"] = _option("scale", merged.pop("scale"))
        if kwargs["scale"] == 0:
            raise LoadError(f"load {uri!r}: scale=0 would make every force 0 N; give newtons per register unit")
    if "unit" in merged:
        kwargs["unit"] = int(_option("unit", merged.pop("unit"), low=0, integer=True))
        if kwargs["unit"] > 255:
            raise LoadError(f"load {uri!r}: unit={kwargs['unit']}: a Modbus device id is 0-255")
    if "rate" in merged:
        kwargs["rate_hz"] = _option("rate", merged.pop("rate"), low=0.0, low_open=True)
        if kwargs["rate_hz"] > MAX_MODBUS_RATE_HZ:
            raise LoadError(f"load {uri!r}: rate={kwargs['rate_hz']:g}: at most {MAX_MODBUS_RATE_HZ:g} polls per "
                            f"second (one request and answer each)")
    for name in ("max_gap_s", "retry_s", "keep_s", "timeout_s"):
        if name in merged:
            kwargs[name] = _option(name, merged.pop(name), low=0.0, low_open=True)
    if "offset_s" in merged:
        kwargs["offset_s"] = _option("offset_s", merged.pop("offset_s"))
    if "max_samples" in merged:
        kwargs["max_samples"] = int(_option("max_samples", merged.pop("max_samples"), low=4))
    if merged:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(merged))}; modbus takes register, "
                        f"scale, kind, type, word_order, unit, rate, max_gap_s, retry_s, timeout_s, keep_s, "
                        f"max_samples, offset_s")
    return ModbusLoad(host, port, uri=uri, **kwargs)


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
    from livedic.acquire.simulator.sources import SyntheticTensileSource, parse_synthetic_uri
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
        ``csv:FILE``, ``tcp://HOST:PORT[?clock=arrival|sender]``, ``modbus://HOST:PORT?register=N...``,
        ``synthetic`` or ``synthetic:tensile?...`` (see the module notes).
    **options
        csv: ``offset_s`` (``--load-offset``), ``max_gap_s`` (default: see ``csv_max_gap_s``).
        synthetic: ``source`` (the ``synthetic:tensile`` camera; required for plain ``synthetic``),
        ``offset_s``, ``max_gap_s``.
        tcp: ``clock``, ``max_gap_s``, ``retry_s``, ``keep_s``, ``max_samples``, ``connect_timeout_s``,
        ``poll_s``, ``offset_s``. modbus: ``register``, ``scale``, ``kind``, ``type``, ``word_order``,
        ``unit``, ``rate``, ``max_gap_s``, ``retry_s``, ``timeout_s``, ``keep_s``, ``max_samples``,
        ``offset_s``. They override the query string.

    Returns
    -------
    LoadSource
        A tcp or modbus source is returned at once, connected or not: its ``events()`` say which.

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
    if scheme == "synthetic":
        return _open_synthetic(uri, options)
    if not sep or scheme not in ("csv", "tcp", "modbus"):
        raise LoadError(f"unknown load {uri!r}; {LOAD_USAGE}")
    if scheme == "tcp":
        return _open_tcp(uri, options)
    if scheme == "modbus":
        return _open_modbus(uri, options)
    if not rest:
        raise LoadError(f"load {uri!r} names no file; {LOAD_USAGE}")
    offset_s = _option("offset_s", options.pop("offset_s", 0.0))
    max_gap_s = options.pop("max_gap_s", None)
    if max_gap_s is not None:
        max_gap_s = _option("max_gap_s", max_gap_s, low=0.0, low_open=True)
    if options:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(options))}; csv takes offset_s, max_gap_s")
    return CsvLoad(rest, offset_s=offset_s, max_gap_s=max_gap_s, uri=uri)
