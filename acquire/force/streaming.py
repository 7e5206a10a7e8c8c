"""What a force stream read by a background thread shares (``tcp://``, ``modbus://``): samples on the
monotonic clock in a bounded buffer, events, warning counts, the bounded wait for a frame's force, and
reconnection; and ``parse_line``, a stream's text line (``force_N`` or ``time_s,force_N``).
"""

from __future__ import annotations

import math
import threading
import time
from abc import abstractmethod
from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.acquire.force.source import (MAX_EVENTS, TIME_BASE_MONOTONIC, LoadEvent, LoadEventKind, LoadSource,
                                          LoadWarnings, interpolate_force)

__all__ = ["StreamingLoad", "parse_line"]


class _SampleBuffer:
    """Samples in time order in growing numpy arrays, bounded by age (``keep_s``) and count (``max_samples``).

    Not locked: its owner holds a lock around every call.
    """

    def __init__(self, keep_s: float, max_samples: int) -> None:
        self.keep_s = keep_s
        self.max_samples = max_samples
        capacity = min(1024, max_samples)
        self._t = np.empty(capacity)
        self._f = np.empty(capacity)
        self._start = 0
        self._end = 0
        self.trimmed = 0

    def __len__(self) -> int:
        return self._end - self._start

    @property
    def last_time(self) -> float:
        return self._t[self._end - 1] if self._end > self._start else -math.inf

    def append(self, time_s: float, force_n: float) -> None:
        if self._end == self._t.size:
            self._make_room()
        self._t[self._end] = time_s
        self._f[self._end] = force_n
        self._end += 1

    def view(self) -> tuple[np.ndarray, np.ndarray]:
        return self._t[self._start:self._end], self._f[self._start:self._end]

    def _make_room(self) -> None:
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


def parse_line(text: str) -> tuple[float | None, float] | None:
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

    def __init__(self, *, max_gap_s: float, retry_s: float, keep_s: float, max_samples: int, counts: Iterable[str],
                 offset_s: float = 0.0) -> None:
        self.offset_s = float(offset_s)
        self.max_gap_s = float(max_gap_s)
        self.retry_s = float(retry_s)
        self._buffer = _SampleBuffer(float(keep_s), int(max_samples))
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)      # notified with every sample stored
        self._last_arrival_s = -math.inf                       # monotonic time the newest sample was stored
        self.nominal_interval_s: float | None = None           # a source that polls knows its period
        self._events: list[LoadEvent] = []
        self._counts = dict.fromkeys(counts, 0)
        self._stop = threading.Event()
        self.connected = False
        self.connect_attempts = 0            # every try, the failed ones too (an outage is one event, not one per try)
        self._thread: threading.Thread | None = None

    def _start_thread(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"livedic-load {self.uri}", daemon=True)
        self._thread.start()

    # -- what the session reads --

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        with self._lock:
            t, f = self._buffer.view()
            return t + self.offset_s, f.copy()

    def force_at(self, times_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        with self._lock:                       # no copy of the whole buffer per frame
            t, f = self._buffer.view()
            return interpolate_force(t, f, np.asarray(times_s, np.float64) - self.offset_s, self.max_gap_s)

    @property
    def last_sample_time_s(self) -> float:
        with self._lock:
            return float(self._buffer.last_time) + self.offset_s if len(self._buffer) else math.nan

    def force_when_known(self, time_s: float, *, wait_s: float | None = None) -> float:
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

    def _default_wait_s(self) -> float:
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

    def events(self, since: int = 0) -> list[LoadEvent]:
        with self._lock:
            return self._events[since:]

    @property
    def warnings(self) -> LoadWarnings:
        with self._lock:
            return LoadWarnings(trimmed=self._buffer.trimmed, **self._counts)

    @property
    def running(self) -> bool:
        """Whether the reader thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def settings(self) -> dict[str, Any]:
        return {**super().settings, "retry_s": self.retry_s, "offset_s": self.offset_s,
                "keep_s": self._buffer.keep_s, "max_samples": self._buffer.max_samples}

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the reader thread (``_wake`` interrupts a blocked read; joined for at most ``timeout_s``)."""
        self._stop.set()
        with self._arrived:
            self._arrived.notify_all()
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def _wake(self) -> None:
        """Interrupt a read in progress (the thread checks ``_stop`` after it)."""

    # -- for the reader thread --

    def _run(self) -> None:
        """The reader thread: connect, read until the connection ends, reconnect every ``retry_s``, until ``_stop``.

        A failed connection is one event until one succeeds; each loss is an event, and a gap
        marker where the source stamps samples on arrival (never interpolated across an outage).
        """
        failing = False
        while not self._stop.is_set():
            self.connect_attempts += 1
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
    def _connect(self) -> tuple[Any, str]:
        """(connection, "connected ..." message), or (None, "cannot connect ...") for the event."""

    @abstractmethod
    def _read_until_lost(self, connection: Any) -> str:
        """Read samples until the connection is lost or ``close()``; the reason it ended, in words."""

    @abstractmethod
    def _hang_up(self, connection: Any) -> None:
        """Close ``connection`` (the reader thread's; after ``_read_until_lost``)."""

    @property
    def _outage_is_a_gap(self) -> bool:
        """Whether a lost connection adds a NaN gap marker (sources stamping samples on arrival)."""
        return True

    def _event(self, kind: LoadEventKind, message: str) -> None:
        with self._lock:
            if len(self._events) < MAX_EVENTS:
                self._events.append(LoadEvent(kind, f"{self.uri}: {message}", time.monotonic()))

    def _count(self, name: str, n: int = 1) -> None:
        with self._lock:
            self._counts[name] += n

    def _append(self, time_s: float, force_n: float) -> bool:
        """Add one sample (NaN force: a gap marker) if it is later than the last one; whether it was."""
        with self._lock:
            if time_s > self._buffer.last_time:
                self._buffer.append(time_s, force_n)
                self._stored()
                return True
            return False

    def _stored(self) -> None:
        """After samples were stored (lock held): note when, and wake ``force_when_known``."""
        self._last_arrival_s = time.monotonic()
        self._arrived.notify_all()
