"""The force signal (acquire.force): csv files and TCP streams, interpolated onto frame times.

Physics checked: linear force is interpolated exactly (1e-9 N), nothing is extrapolated past the
last sample, a stalled stream gives NaN, and a stream delivered 37 ms late but stamped by its sender
lines up with 50 fps frames within the force change of half a frame period.
"""

import contextlib
import math
import socket
import socketserver
import threading
import time

import numpy as np
import pytest

from livedic.acquire.force import (LoadError, LoadEventKind, TIME_BASE_MONOTONIC, TIME_BASE_SESSION, interpolate_force,
                                   open_load)
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource
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


@contextlib.contextmanager
def loading(uri, **options):
    source = open_load(uri, **options)
    try:
        yield source
    finally:
        source.close()


def send_then_hold(payload):
    def script(sock, stop):
        sock.sendall(payload)
        stop.wait(5)
    return script


def free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def write_csv(path, rows, header="time_s,force_N"):
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path


# --- interpolation -----------------------------------------------------------------------------

def test_interpolation_is_exact_on_linear_force_and_never_extrapolates():
    t = np.array([0.0, 0.1, 0.25, 0.4])
    f = 3.0 + 250.0 * t
    times = np.array([-0.01, 0.0, 0.05, 0.1, 0.17, 0.33, 0.4, 0.4000001, 1.0])
    got = interpolate_force(t, f, times, max_gap_s=1.0)
    inside = (times >= 0.0) & (times <= 0.4)
    np.testing.assert_allclose(got[inside], 3.0 + 250.0 * times[inside], rtol=0, atol=1e-9)
    assert np.isnan(got[~inside]).all()


def test_interpolation_gives_nan_across_a_gap_wider_than_max_gap():
    t = np.array([0.0, 0.1, 0.9, 1.0])
    f = np.array([0.0, 1.0, 9.0, 10.0])
    got = interpolate_force(t, f, [0.05, 0.5, 0.95], max_gap_s=0.5)
    np.testing.assert_allclose(got[[0, 2]], [0.5, 9.5], atol=1e-12)
    assert math.isnan(got[1])


def test_interpolation_of_one_or_no_sample():
    assert np.isnan(interpolate_force([], [], [0.0, 1.0], 1.0)).all()
    np.testing.assert_array_equal(interpolate_force([2.0], [7.0], [1.0, 2.0, 3.0], 1.0), [np.nan, 7.0, np.nan])


# --- csv: --------------------------------------------------------------------------------------

def test_csv_round_trip_interpolates_linear_force_exactly(tmp_path):
    t = np.arange(0, 41) * 0.025                       # 40 Hz machine export
    path = write_csv(tmp_path / "force.csv", zip(t, 12.0 + 800.0 * t))
    frames = np.arange(0, 51) * 0.02                   # 50 fps, the last frame (1.0 s) exactly on the last sample
    with loading(f"csv:{path}") as load:
        assert load.time_base == TIME_BASE_SESSION
        got = load.force_at(frames)
        np.testing.assert_allclose(got, 12.0 + 800.0 * frames, rtol=0, atol=1e-9)
        assert math.isnan(load.force_at(1.0 + 1e-9))    # past the last sample: never extrapolated
        assert math.isnan(load.force_at(-0.001))
        assert load.last_sample_time_s == pytest.approx(1.0)
        assert load.events() == [] and load.warnings.garbage_lines == 0


def test_csv_offset_shifts_the_samples_onto_frame_time(tmp_path):
    path = write_csv(tmp_path / "force.csv", [(0.0, 0.0), (1.0, 100.0), (2.0, 200.0)])
    with loading(f"csv:{path}", offset_s=0.25) as load:
        np.testing.assert_allclose(load.force_at([0.25, 0.75, 2.25]), [0.0, 50.0, 200.0], atol=1e-9)
        assert math.isnan(load.force_at(0.2)) and math.isnan(load.force_at(2.3))
        assert load.settings["offset_s"] == 0.25


def test_csv_extra_columns_and_blank_lines_are_allowed(tmp_path):
    path = tmp_path / "force.csv"
    path.write_text("time_s,force_N,crosshead_mm\n0,1,0.0\n\n1,3,0.1\n")
    with loading(f"csv:{path}") as load:
        np.testing.assert_allclose(load.force_at(0.5), 2.0)


@pytest.mark.parametrize("content, where", [
    (None, "cannot be read"),
    ("", "line 1"),
    ("time,force\n0,1\n", "line 1"),
    ("force_N,time_s\n0,1\n", "line 1"),
    ("time_s,force_N\n", "no samples"),
    ("time_s,force_N\n0,1\n0.1,abc\n", "line 3"),
    ("time_s,force_N\n0,1\n0.1,nan\n", "line 3"),
    ("time_s,force_N\n0,1\n0.1\n", "line 3"),
    ("time_s,force_N\n0,1\n0.2,2\n0.2,3\n", "line 4"),
    ("time_s,force_N\n0,1\n0.2,2\n0.1,3\n", "line 4"),
])
def test_a_bad_csv_is_one_line_naming_file_and_line(tmp_path, content, where):
    path = tmp_path / "bad.csv"
    if content is not None:
        path.write_text(content)
    with pytest.raises(LoadError) as error:
        open_load(f"csv:{path}")
    message = str(error.value)
    assert "\n" not in message and str(path) in message and where in message, message
    assert isinstance(error.value, ValueError)


@pytest.mark.parametrize("uri, where", [
    ("modbus://127.0.0.1:502?scale=0.1", "register= is required"),
    ("synthetic", "pass source="),
    ("synthetic:translate", "has no force"),
    ("synthetic:tensile?frames=1", "frames"),
    ("synthetic:tensile?hardening=-1", "hardening"),
    ("udp://host:1", "unknown load"),
    ("", "empty"),
    ("csv:", "names no file"),
    ("tcp://localhost", "tcp://HOST:PORT"),
    ("tcp://localhost:99999", "tcp://HOST:PORT"),
    ("tcp://localhost:5000?clock=camera", "clock="),
    ("tcp://localhost:5000?rate=3", "unknown option"),
    ("tcp://localhost:5000?max_gap_s=-1", "max_gap_s"),
])
def test_bad_load_uris_are_one_line(uri, where):
    with pytest.raises(LoadError) as error:
        open_load(uri)
    assert "\n" not in str(error.value) and where in str(error.value), str(error.value)


def test_frame_time_convention(tmp_path):
    path = write_csv(tmp_path / "force.csv", [(0.0, 0.0), (1.0, 1.0)])
    with loading(f"csv:{path}") as load:
        assert load.frame_time_s(since_first_frame_s=0.5, arrival_ns=123) == 0.5
        with pytest.raises(LoadError):
            load.frame_time_s(arrival_ns=123)
    with loading(f"tcp://127.0.0.1:{free_port()}") as load:
        assert load.time_base == TIME_BASE_MONOTONIC
        assert load.frame_time_s(since_first_frame_s=0.5, arrival_ns=2_500_000_000) == 2.5
        with pytest.raises(LoadError):
            load.frame_time_s(since_first_frame_s=0.5)


# --- synthetic ---------------------------------------------------------------------------------

def test_synthetic_load_gives_the_simulators_force_at_frame_times():
    source = SyntheticTensileSource("synthetic:tensile?frames=40&fps=25&size=128x128&pace=0&fracture=1")
    with loading("synthetic", source=source) as load:
        assert load.time_base == TIME_BASE_SESSION and load.specimen == source.specimen
        frame_times = np.arange(40) / 25.0                         # frame i at i / fps since the first frame
        forces = np.array([source.force_N(i) for i in range(40)])
        np.testing.assert_allclose(load.force_at(frame_times), forces, rtol=1e-12, atol=0)
        # Between two frames: linear interpolation (the first elastic frames are a straight line).
        np.testing.assert_allclose(load.force_at([0.01, 0.06]), [0.25 * forces[1], 0.5 * (forces[1] + forces[2])],
                                   rtol=1e-12)
        broken = source.fracture_frame
        assert np.all(load.force_at(frame_times[broken:]) == 0.0) and forces[broken - 1] > 0.0
        assert math.isnan(load.force_at(39 / 25.0 + 1e-6)) and math.isnan(load.force_at(-1e-6))
        assert load.last_sample_time_s == pytest.approx(39 / 25.0)
        assert load.settings["specimen"]["E_GPa"] == 200.0 and load.settings["source"] == source.uri


def test_synthetic_load_from_the_tests_uri_matches_the_cameras_force():
    uri = "synthetic:tensile?frames=30&size=128x128&modulus=70&hardening=0.4"
    with loading(uri) as load:
        camera = SyntheticTensileSource(uri)
        np.testing.assert_array_equal(load.samples()[1], camera.forces_N())
        np.testing.assert_allclose(load.samples()[0], np.arange(30) / 50.0, rtol=1e-15)
        assert load.specimen["Rm_MPa"] == pytest.approx(70e3 * 0.004 * 1.4, rel=1e-12)


def test_synthetic_load_offset_shifts_the_frames_as_a_csvs():
    # export and report pass offset_s (--load-offset) to every load: the same meaning as for csv.
    source = SyntheticTensileSource("synthetic:tensile?frames=10&size=64x64")
    with loading("synthetic", source=source, offset_s=0.5) as load:
        np.testing.assert_allclose(load.force_at(0.5 + np.arange(10) / 50.0), source.forces_N(), rtol=1e-12)
        assert math.isnan(load.force_at(0.49)) and load.settings["offset_s"] == 0.5


def test_synthetic_load_needs_a_simulated_tensile_camera():
    with pytest.raises(LoadError) as error:
        open_load("synthetic", source=SyntheticTranslateSource("synthetic:translate?frames=3&size=64x64"))
    assert "\n" not in str(error.value) and "synthetic:tensile" in str(error.value)
    source = SyntheticTensileSource("synthetic:tensile?frames=3&size=64x64")
    with pytest.raises(LoadError, match="not both"):
        open_load("synthetic:tensile", source=source)
    with pytest.raises(LoadError, match="unknown option"):
        open_load("synthetic", source=source, clock="sender")


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
