"""Tests of acquire/force/streaming.py: a stream's line parsing, bounded sample buffer, bounded wait, reconnection."""

import math
import threading
import time

import numpy as np
import pytest

from livedic.acquire.force.source import MAX_EVENTS, TIME_BASE_MONOTONIC, LoadEventKind
from livedic.acquire.force.streaming import StreamingLoad, _SampleBuffer, parse_line
from tests.waiting import wait_until


class _Scripted(StreamingLoad):
    """A stream without a network: connection k (k < len(sessions)) delivers ``sessions[k]`` (times, forces)
    then is lost; ``None`` in ``sessions`` is a failed connection; after the script, connections fail."""

    def __init__(self, sessions=(), start=True, **options):
        super().__init__(**{"max_gap_s": 0.5, "retry_s": 0.001, "keep_s": 600.0, "max_samples": 10_000,
                            "counts": ("garbage_lines",), **options})
        self.uri = "scripted://"
        self.sessions = list(sessions)
        self.hung_up = 0
        if start:
            self._start_thread()

    def _connect(self):
        if self.connect_attempts > len(self.sessions) or self.sessions[self.connect_attempts - 1] is None:
            return None, "cannot connect: refused"
        return self.sessions[self.connect_attempts - 1], "connected to the script"

    def _read_until_lost(self, connection):
        for t, f in zip(*connection):
            self._append(t, f)
        return "the script ended"

    def _hang_up(self, connection):
        self.hung_up += 1


# ----------------------------------------------------------------------------- parse_line

@pytest.mark.parametrize("text, parsed", [
    ("12.5", (None, 12.5)), (" -3e2 \r", (None, -300.0)), ("1.5,20", (1.5, 20.0)), ("0, -0.25", (0.0, -0.25)),
    ("", None), ("abc", None), ("1,2,3", None), ("nan", None), ("1,inf", None), ("1;2", None), (",", None),
])
def test_a_line_is_a_force_or_a_time_and_force_or_garbage(text, parsed):
    assert parse_line(text) == parsed


# ----------------------------------------------------------------------------- the sample buffer

def test_the_buffer_keeps_the_newest_samples_in_order_within_its_cap():
    buffer = _SampleBuffer(keep_s=1e9, max_samples=2000)
    for i in range(10_000):
        buffer.append(float(i), 2.0 * i)
    t, f = buffer.view()
    assert len(buffer) == t.size <= 2000 and t[-1] == 9999.0 and np.all(np.diff(t) == 1.0)
    np.testing.assert_array_equal(f, 2.0 * t)
    assert buffer.trimmed == 10_000 - t.size and buffer.last_time == 9999.0


def test_the_buffer_drops_samples_older_than_keep_s():
    buffer = _SampleBuffer(keep_s=100.0, max_samples=1_000_000)
    for i in range(5000):
        buffer.append(float(i), 0.0)
    t, _ = buffer.view()
    assert t[-1] == 4999.0 and t[0] >= 4999.0 - 100.0 - 1024     # trimmed when it makes room (every ~1024)
    assert t.size < 5000 and buffer.trimmed == 5000 - t.size
    empty = _SampleBuffer(keep_s=1.0, max_samples=10)
    assert len(empty) == 0 and empty.last_time == -math.inf


# ----------------------------------------------------------------------------- StreamingLoad

def test_samples_are_on_the_monotonic_clock_shifted_by_the_offset_and_only_later_ones_kept():
    load = _Scripted(start=False, offset_s=10.0, max_gap_s=5.0)
    assert load.time_base == TIME_BASE_MONOTONIC and math.isnan(load.last_sample_time_s)
    assert [load._append(t, f) for t, f in ((1.0, 5.0), (1.0, 6.0), (0.5, 7.0), (2.0, 9.0))] == [True, False, False,
                                                                                               True]
    t, f = load.samples()
    assert t.tolist() == [11.0, 12.0] and f.tolist() == [5.0, 9.0] and load.last_sample_time_s == 12.0
    assert load.force_at(11.5) == pytest.approx(7.0) and math.isnan(load.force_at(1.5))
    assert load.settings["offset_s"] == 10.0 and load.settings["max_samples"] == 10_000


def test_force_when_known_waits_for_the_next_sample_and_wakes_on_it():
    load = _Scripted(start=False)
    now = time.monotonic()
    for i in range(5):
        load._append(now - 0.05 + i * 0.01, 100.0 + i)               # 100 Hz, newest at now - 0.01
    got = {}

    def ask():
        got["force"] = load.force_when_known(now - 0.005, wait_s=30.0)

    asker = threading.Thread(target=ask)
    asker.start()
    load._append(now, 105.0)                                         # the sample after the frame wakes it
    asker.join(30.0)
    assert got["force"] == pytest.approx(104.5)


def test_force_when_known_does_not_wait_for_a_stalled_stream():
    load = _Scripted(start=False, max_gap_s=0.5)
    now = time.monotonic()
    load._append(now - 10.0, 1.0)
    assert math.isnan(load.force_when_known(now, wait_s=30.0))       # at once: 30 s would fail the test's limit
    assert load._default_wait_s() == 0.0                             # one sample: no interval known yet


def test_the_default_wait_is_two_intervals_plus_the_lag_at_most_max_gap():
    load = _Scripted(start=False, max_gap_s=0.5)
    now = time.monotonic()
    for i in range(10):
        load._append(now - 0.2 + i * 0.02, 0.0)                      # 50 Hz, the newest 0.02 s before it arrived
    late = time.monotonic() - now                                    # how much later than "now" it arrived, at most
    assert 2 * 0.02 + 0.02 - 1e-9 <= load._default_wait_s() <= 2 * 0.02 + 0.02 + late + 1e-9
    slow = _Scripted(start=False, max_gap_s=0.5)
    slow.nominal_interval_s = 1.0
    assert slow._default_wait_s() == 0.5                             # capped at max_gap_s


def test_a_lost_connection_is_an_event_a_nan_gap_and_a_reconnection():
    load = _Scripted([([1.0, 2.0], [10.0, 20.0]), None, None, ([5.0, 6.0], [50.0, 60.0])])
    try:
        wait_until(lambda: LoadEventKind.CONNECT_FAILED in [e.kind for e in load.events()]
                   and len(load.events()) >= 5, what="the script played and the next connection failed")
        kinds = [e.kind for e in load.events()]
        assert kinds[:5] == [LoadEventKind.CONNECTED, LoadEventKind.DISCONNECTED, LoadEventKind.CONNECT_FAILED,
                             LoadEventKind.CONNECTED, LoadEventKind.DISCONNECTED]
        assert all(e.message.startswith("scripted://: ") for e in load.events())
        assert load.hung_up == 2 and load.events(since=4)[0].kind is LoadEventKind.DISCONNECTED
        t, f = load.samples()
        assert f[:2].tolist() == [10.0, 20.0] and np.isnan(f[2])     # the outage's gap marker, after the samples
    finally:
        load.close()
    assert not load.running and not load.connected


def test_an_endless_outage_is_one_event_and_close_stops_the_thread():
    load = _Scripted([])
    wait_until(lambda: load.connect_attempts >= 20, what="twenty failed connections")
    load.close()
    assert [e.kind for e in load.events()] == [LoadEventKind.CONNECT_FAILED] and not load.running


def test_counts_become_warnings_and_events_are_capped():
    load = _Scripted(start=False)
    load._count("garbage_lines", 3)
    for _ in range(MAX_EVENTS + 5):
        load._event(LoadEventKind.BAD_DATA, "x")
    assert load.warnings.garbage_lines == 3 and load.warnings.total() == 3
    assert len(load.events()) == MAX_EVENTS
