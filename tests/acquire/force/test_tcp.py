"""The force signal of a TCP stream (acquire.force.tcp), interpolated onto frame times.

Physics checked: a stalled stream gives NaN, and a stream delivered 37 ms late but stamped by its sender
lines up with 50 fps frames within the force change of half a frame period. (Interpolation, csv files,
URIs and the simulator's force have their own modules: test_source, test_csv_file, test_open, test_simulated.)
"""

import contextlib
import math
import socketserver
import threading
import time

import numpy as np
import pytest

from livedic.acquire.force import LoadEventKind, open_load
from tests.acquire.force.loads import free_port, loading, write_csv
from tests.waiting import wait_until


# --- helpers -----------------------------------------------------------------------------------

class ScriptedServer:
    """A local TCP server; connection k runs ``scripts[k](sock, stop)``, later ones hold the line open."""

    def __init__(self, *scripts):
        self.stop = threading.Event()
        self.connections = 0
        owner = self

        class Handler(socketserver.BaseRequestHandler):
            def handle(self):
                index, owner.connections = owner.connections, owner.connections + 1
                if index < len(scripts):
                    scripts[index](self.request, owner.stop)
                else:
                    owner.stop.wait(5)

        socketserver.ThreadingTCPServer.allow_reuse_address = True
        self.server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.port = self.server.server_address[1]
        self.thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self.thread.start()

    def close(self):
        self.stop.set()
        self.server.shutdown()
        self.server.server_close()


@contextlib.contextmanager
def serving(*scripts):
    server = ScriptedServer(*scripts)
    try:
        yield server
    finally:
        server.close()


def send_then_hold(payload):
    def script(sock, stop):
        sock.sendall(payload)
        stop.wait(5)
    return script


# --- tcp:// ------------------------------------------------------------------------------------

def test_tcp_lines_are_stamped_on_arrival_with_the_monotonic_clock():
    sent = {}

    def script(sock, stop):
        sent["before"] = time.monotonic()
        sock.sendall(b"12.5\n")
        stop.wait(0.1)
        sent["second"] = time.monotonic()
        sock.sendall(b"999.0,13.5\r\n")     # time_s of the sender ignored: stamped on arrival
        sent["after"] = time.monotonic()
        stop.wait(5)

    with serving(script) as server, loading(f"tcp://127.0.0.1:{server.port}") as load:
        wait_until(lambda: load.samples()[0].size == 2)
        wait_until(lambda: "after" in sent)
        t, f = load.samples()
        np.testing.assert_array_equal(f, [12.5, 13.5])
        assert sent["before"] <= t[0] < sent["second"] <= t[1] <= time.monotonic()
        assert [event.kind for event in load.events()] == [LoadEventKind.CONNECTED]


def test_tcp_sender_clock_keeps_the_senders_times_and_counts_garbage():
    payload = (b"1.0,10\nabc\n1,2,3\nnan\n\n5\n2.0,20\n1.5,15\n3.0,30\n" + b"x" * 5000 + b"\n")
    with serving(send_then_hold(payload)) as server, \
            loading(f"tcp://127.0.0.1:{server.port}?clock=sender", max_gap_s=2.0) as load:
        wait_until(lambda: load.samples()[0].size == 3 and load.warnings.garbage_lines == 5)
        t, f = load.samples()
        np.testing.assert_array_equal(t, [1.0, 2.0, 3.0])
        np.testing.assert_array_equal(f, [10.0, 20.0, 30.0])
        # abc, 1,2,3, nan, a bare force without the sender's time, the 5000-byte line
        assert load.warnings.garbage_lines == 5 and load.warnings.out_of_order == 1
        np.testing.assert_allclose(load.force_at([1.5, 2.5, 3.5]), [15.0, 25.0, np.nan])
        assert load.running


def test_a_stalled_stream_is_an_event_and_nan_never_a_stale_value():
    def script(sock, stop):
        for burst in range(2):
            for _ in range(20):
                sock.sendall(f"{time.monotonic()},{100 + burst}\n".encode())
                stop.wait(0.01)
            if burst == 0:
                stop.wait(0.5)              # the stall: longer than max_gap_s
        stop.wait(5)

    with serving(script) as server, \
            loading(f"tcp://127.0.0.1:{server.port}?clock=sender", max_gap_s=0.15) as load:
        wait_until(lambda: load.samples()[0].size == 40)
        t, _ = load.samples()
        gap = int(np.argmax(np.diff(t)))
        assert t[gap + 1] - t[gap] > 0.4
        inside_gap = np.linspace(t[gap], t[gap + 1], 7)[1:-1]
        assert np.isnan(load.force_at(inside_gap)).all()
        assert np.isfinite(load.force_at(t[gap - 1:gap + 1])).all()
        assert math.isnan(load.force_at(t[-1] + 0.01))       # after the last sample: not held
        kinds = [event.kind for event in load.events()]
        assert kinds[:3] == [LoadEventKind.CONNECTED, LoadEventKind.STALLED, LoadEventKind.RESUMED], kinds


def test_a_disconnect_is_an_event_and_the_source_reconnects():
    def first(sock, stop):
        sock.sendall(b"1,10\n2,20\n")

    with serving(first, send_then_hold(b"3,30\n")) as server, \
            loading(f"tcp://127.0.0.1:{server.port}?clock=sender", retry_s=0.1) as load:
        wait_until(lambda: load.samples()[0].size == 3)
        np.testing.assert_array_equal(load.samples()[1], [10.0, 20.0, 30.0])
        kinds = [event.kind for event in load.events()]
        assert kinds == [LoadEventKind.CONNECTED, LoadEventKind.DISCONNECTED, LoadEventKind.CONNECTED], kinds
        assert all(event.message.startswith(f"tcp://127.0.0.1:{server.port}") for event in load.events())
        assert [event.kind for event in load.events(since=2)] == [LoadEventKind.CONNECTED]


def test_nothing_listening_is_one_event_and_close_stops_the_thread():
    with loading(f"tcp://127.0.0.1:{free_port()}", retry_s=0.05) as load:
        wait_until(lambda: load.connect_attempts >= 4)      # several retries: still one event for the outage
        assert [event.kind for event in load.events()] == [LoadEventKind.CONNECT_FAILED]
        assert math.isnan(load.force_at(time.monotonic()))
        load.close()
        assert not load.running


def test_close_stops_a_reader_blocked_on_a_silent_connection():
    with serving(send_then_hold(b"")) as server:
        load = open_load(f"tcp://127.0.0.1:{server.port}", poll_s=1.0)   # a long recv: close must wake it
        wait_until(lambda: load.connected)
        load.close(timeout_s=3.0)
        assert not load.running
        assert [event.kind for event in load.events()] == [LoadEventKind.CONNECTED]


def test_memory_is_bounded_by_max_samples_and_keep_s():
    many = "".join(f"{k},{k}\n" for k in range(1, 5001)).encode()
    with serving(send_then_hold(many), send_then_hold(many)) as server:
        with loading(f"tcp://127.0.0.1:{server.port}?clock=sender", max_samples=64) as load:
            wait_until(lambda: load.last_sample_time_s == 5000.0)
            t, f = load.samples()
            assert t.size <= 64 and load.warnings.trimmed == 5000 - t.size
            np.testing.assert_array_equal(t, np.arange(5001 - t.size, 5001))
            np.testing.assert_array_equal(f, t)
        with loading(f"tcp://127.0.0.1:{server.port}?clock=sender", keep_s=100) as load:
            wait_until(lambda: load.last_sample_time_s == 5000.0)
            t, _ = load.samples()
            assert t.size <= 1024 and load.warnings.trimmed == 5000 - t.size
            assert np.all(np.diff(t) == 1.0)


def test_garbage_is_one_bad_data_event_per_connection_and_counted():
    with serving(send_then_hold(b"1,10\nabc\n2,20\n#x\n??\n3,30\n")) as server, \
            loading(f"tcp://127.0.0.1:{server.port}?clock=sender", max_gap_s=2.0) as load:
        wait_until(lambda: load.samples()[0].size == 3 and load.warnings.garbage_lines == 3)
        assert [event.kind for event in load.events()] == [LoadEventKind.CONNECTED, LoadEventKind.BAD_DATA]
        bad = load.events()[1]
        assert bad.kind.is_trouble and "'abc'" in bad.message and "counted" in bad.message
        assert load.warnings.total() == 3


def test_the_session_offset_shifts_a_streams_samples():
    """``--load-offset`` reaches every load (the session passes it): a stream shifts its times by it."""
    with serving(send_then_hold(b"1,10\n2,20\n")) as server, \
            loading(f"tcp://127.0.0.1:{server.port}?clock=sender", offset_s=-0.5, max_gap_s=2.0) as load:
        wait_until(lambda: load.samples()[0].size == 2)
        np.testing.assert_array_equal(load.samples()[0], [0.5, 1.5])
        assert load.force_at(1.0) == 15.0 and load.last_sample_time_s == 1.5
        assert load.settings["offset_s"] == -0.5
        assert load.force_when_known(1.0) == 15.0


def test_force_when_known_waits_for_the_sample_after_a_live_frame():
    """A frame arriving between two lines has no force until the next line: asked at once it is NaN.
    (A generous ``wait_s`` here: the default bound, two sample intervals, is checked by the session tests.)"""
    frame_time = {}

    def script(sock, stop):
        for k in range(4):
            sock.sendall(f"{100 * k}\n".encode())
            stop.wait(0.05 if k < 3 else 0.01)
        frame_time["t"] = time.monotonic()              # a frame arrives here, between two lines
        stop.wait(0.04)
        sock.sendall(b"400\n")
        stop.wait(5)

    with serving(script) as server, loading(f"tcp://127.0.0.1:{server.port}") as load:
        wait_until(lambda: "t" in frame_time)
        at_once = load.force_at(frame_time["t"])
        known = load.force_when_known(frame_time["t"], wait_s=5.0)
        t, f = load.samples()
        assert t.size == 5 and t[3] < frame_time["t"] < t[4]
        expected = 300 + 100 * (frame_time["t"] - t[3]) / (t[4] - t[3])
        assert math.isnan(at_once) and known == pytest.approx(expected, abs=1e-9)


def test_force_when_known_does_not_wait_on_a_stalled_stream_or_a_file(tmp_path):
    with serving(send_then_hold(b"5\n")) as server, loading(f"tcp://127.0.0.1:{server.port}", max_gap_s=0.05) as load:
        wait_until(lambda: load.samples()[0].size == 1)
        time.sleep(0.1)                                  # longer than max_gap_s: the stream stalled
        assert math.isnan(load.force_when_known(time.monotonic()))
    path = write_csv(tmp_path / "f.csv", [(0, 0), (1, 100)])
    with loading(f"csv:{path}") as load:
        assert load.force_when_known(0.25) == 25.0 and math.isnan(load.force_when_known(2.0))


def test_an_arrival_stamped_stream_is_nan_across_a_reconnection():
    """retry_s shorter than max_gap_s: the outage still is NaN (a marker where the connection was lost)."""
    with serving(send_then_hold(b"10\n"), send_then_hold(b"30\n")) as server:
        with loading(f"tcp://127.0.0.1:{server.port}", retry_s=0.01, max_gap_s=5.0) as load:
            wait_until(lambda: load.samples()[0].size == 1)
            server.stop.set()                            # the first connection ends, the second sends 30 at once
            wait_until(lambda: np.any(load.samples()[1] == 30.0))
            t, f = load.samples()
            assert np.isnan(f[1]) and list(f[[0, 2]]) == [10.0, 30.0]
            assert np.isnan(load.force_at(np.linspace(t[0], t[2], 7)[1:-1])).all()


# --- the target: a delayed stream aligned with 50 fps frames -----------------------------

FPS = 50.0
DELAY_S = 0.037
AMPLITUDE_N, FREQUENCY_HZ = 1000.0, 2.0


def true_force(t):
    return AMPLITUDE_N * np.sin(2 * np.pi * FREQUENCY_HZ * t)


def delayed_stream(start, duration_s=0.6, rate_hz=500.0):
    """Readings taken at start + k/rate, each sent DELAY_S later (a DAQ's buffering), with its reading time."""
    def script(sock, stop):
        k, n = 0, int(duration_s * rate_hz)
        while k < n and not stop.is_set():
            now = time.monotonic()
            lines = []
            while k < n and start + k / rate_hz + DELAY_S <= now:
                taken = start + k / rate_hz
                lines.append(f"{taken!r},{float(true_force(taken))!r}\n")
                k += 1
            if lines:
                sock.sendall("".join(lines).encode())
            stop.wait(0.002)
        stop.wait(5)
    last_taken = start + (int(duration_s * rate_hz) - 1) / rate_hz
    return script, last_taken


@pytest.mark.parametrize("clock", ["sender", "arrival"])
def test_a_delayed_force_stream_is_aligned_within_half_a_frame_period(clock):
    start = time.monotonic() + 0.1
    script, last_taken = delayed_stream(start)
    with serving(script) as server, loading(f"tcp://127.0.0.1:{server.port}?clock={clock}", max_gap_s=0.2) as load:
        wait_until(lambda: load.last_sample_time_s >= last_taken - 1e-6)
        # Frame arrival times on the same clock, between samples (1.3 ms after one) so interpolation is used.
        frames = start + 0.1013 + np.arange(int(0.4 * FPS)) / FPS
        error = np.abs(load.force_at(frames) - true_force(frames))
    half_frame_change = AMPLITUDE_N * 2 * np.pi * FREQUENCY_HZ * (0.5 / FPS)   # largest slope x half a period
    if clock == "sender":
        assert np.isfinite(error).all()
        assert error.max() <= half_frame_change, (error.max(), half_frame_change)
    else:
        # Stamped on arrival the same stream lags by the 37 ms delay: why clock=sender exists.
        assert np.nanmax(error) > half_frame_change, (np.nanmax(error), half_frame_change)
