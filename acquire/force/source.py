"""What every force source shares: the ``LoadSource`` base class, its error, events and warnings, the
two time bases, force interpolated between samples, and the parsing of a URI's options.

How a URI opens a source, the time bases and each source's behaviour: docs/guide/tensile-test.md.
"""

from __future__ import annotations

import enum
import math
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal, TypeVar
from urllib.parse import parse_qsl, urlsplit

import numpy as np
import numpy.typing as npt

from livedic.acquire.options import parse_number

__all__ = ["LoadError", "LoadEventKind", "LoadEvent", "LoadWarnings", "LoadSource", "interpolate_force",
           "TIME_BASE_SESSION", "TIME_BASE_MONOTONIC"]

TIME_BASE_SESSION = "session"        # seconds since the session's first frame
TIME_BASE_MONOTONIC = "monotonic"    # time.monotonic_ns() / 1e9, the clock that stamps frame arrival

CSV_HEADER = ("time_s", "force_N")
DEFAULT_MAX_GAP_S = 0.5
DEFAULT_RETRY_S = 1.0
DEFAULT_KEEP_S = 600.0
DEFAULT_MAX_SAMPLES = 2_000_000
MAX_LINE_BYTES = 4096                # a "line" longer than this without a newline is garbage
MAX_EVENTS = 10_000                  # an endless outage adds events once per outage, this is a safety cap


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
    def is_trouble(self) -> bool:
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

    def total(self) -> int:
        """How many lines or polls gave no sample (``trimmed`` excluded: those were good samples, dropped when old)."""
        return (self.garbage_lines + self.out_of_order + self.exception_responses + self.timeouts
                + self.bad_values)


def interpolate_force(sample_t: npt.ArrayLike, sample_f: npt.ArrayLike, times_s: npt.ArrayLike,
                      max_gap_s: float) -> npt.NDArray[np.float64]:
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


_Load = TypeVar("_Load", bound="LoadSource")


class LoadSource(ABC):
    """A force signal: ``force_at(times_s)`` on the clock named by ``time_base``.

    Attributes: ``uri``, ``time_base`` (``TIME_BASE_SESSION`` or ``TIME_BASE_MONOTONIC``),
    ``max_gap_s``. A context manager; ``close()`` releases it.
    """

    uri: str = ""
    time_base: str = TIME_BASE_SESSION
    max_gap_s: float = DEFAULT_MAX_GAP_S

    @abstractmethod
    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        """``(time_s, force_N)`` copies of the samples kept, on ``time_base``."""

    def force_at(self, times_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Force (N) at ``times_s`` (see ``interpolate_force``): NaN where it is not known."""
        t, f = self.samples()
        return interpolate_force(t, f, times_s, self.max_gap_s)

    def force_when_known(self, time_s: float, *, wait_s: float | None = None) -> float:
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

    def frame_time_s(self, *, since_first_frame_s: npt.ArrayLike | None = None,
                     arrival_ns: npt.ArrayLike | None = None) -> np.ndarray:
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
    def last_sample_time_s(self) -> float:
        """Time of the newest sample (NaN if none): frames later than this have no force yet."""
        t, _ = self.samples()
        return float(t[-1]) if t.size else math.nan

    def events(self, since: int = 0) -> list[LoadEvent]:
        """``LoadEvent`` list, oldest first (a copy); ``since=n`` skips the n already seen (a poller's count)."""
        return []

    @property
    def warnings(self) -> LoadWarnings:
        """``LoadWarnings`` snapshot."""
        return LoadWarnings()

    @property
    def settings(self) -> dict[str, Any]:
        """What describes this source in session metadata."""
        return {"uri": self.uri, "time_base": self.time_base, "max_gap_s": self.max_gap_s}

    def close(self) -> None:
        pass

    def __enter__(self: _Load) -> _Load:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close()
        return False


def _exception_name(code: int) -> str:
    from pymodbus.constants import ExcCodes
    try:
        return f"{int(code)} ({ExcCodes(code).name.lower().replace('_', ' ')})"
    except ValueError:
        return str(code)


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__


def _option(name: str, value: object, low: float | None = None, low_open: bool = False,
            integer: bool = False) -> float:
    try:
        return parse_number(value, low=low, low_open=low_open, integer=integer)
    except ValueError as error:
        raise LoadError(f"load option {name}={value!r}: {error}") from None


def _address_and_options(uri: str, options: Mapping[str, Any], form: str) -> tuple[str, int, dict[str, Any]]:
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
