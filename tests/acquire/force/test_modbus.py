"""The force over Modbus TCP (``--load modbus://HOST:PORT?register=N&scale=K``), against a real
pymodbus server in this process (``modbus_server.ModbusTestServer``, 127.0.0.1, a free port).

Physics checked: a force ramp written into the server's registers while it is polled is read back
on the monotonic clock and interpolated onto frame times within the ramp's change over 25 ms
(a 5 ms poll period, 2 ms register updates and loopback round trips with three threads sharing
the interpreter) for at least 90 % of the frames, and exactly where the register holds still;
scale and every register type (two-register ones in both word orders) decode exactly, from
register values written by hand, not by the library that decodes them. Faults: the server
stopping, hanging, or answering with an exception code is an event and NaN, never an exception
and never a stale value, and samples resume when it is back. No test waits on a timing threshold:
waits are for conditions, with a generous limit only against a hang.
"""

import contextlib
import math
import threading
import time

import numpy as np
import pytest

from livedic.acquire.force import LoadError, LoadEventKind, ModbusLoad, TIME_BASE_MONOTONIC, decode_registers, open_load
from tests.acquire.force.modbus_server import INPUT_MARK, ModbusTestServer
from tests.waiting import wait_until

pytestmark = pytest.mark.usefixtures("time_limit")


@pytest.fixture
def server():
    """A pymodbus server on 127.0.0.1 and a free port, shut down (listener, connections, loop) after the test."""
    with ModbusTestServer() as running:
        yield running


@contextlib.contextmanager
def polling(uri, **options):
    load = open_load(uri, **options)
    try:
        yield load
    finally:
        load.close()
    assert not load.running


def kinds(load):
    return [event.kind for event in load.events()]


def newest_force(load):
    return load.samples()[1][-1] if load.samples()[1].size else math.nan


# --- decoding and options ----------------------------------------------------------------------

@pytest.mark.parametrize("registers, value_type, word_order, expected", [
    ([0xFB2E], "int16", "big", -1234),
    ([0xFFFF], "uint16", "big", 65535),
    ([0xFFFE, 0x7960], "int32", "big", -100000),
    ([0x7960, 0xFFFE], "int32", "little", -100000),
    ([0xB2D0, 0x5E00], "uint32", "big", 3_000_000_000),
    ([0x449A, 0x5000], "float32", "big", 1234.5),
    ([0x5000, 0x449A], "float32", "little", 1234.5),
])
def test_registers_decode_exactly(registers, value_type, word_order, expected):
    assert decode_registers(registers, value_type, word_order) == expected


@pytest.mark.parametrize("query, where", [
    ("scale=0.1", "register= is required"),
    ("register=-1", "register"),
    ("register=65536", "register=65536"),
    ("register=65535&type=float32", "must be 0-65534"),
    ("register=1.5", "not an integer"),
    ("register=1&scale=abc", "scale"),
    ("register=1&scale=0", "scale=0"),
    ("register=1&kind=coil", "kind=holding|input"),
    ("register=1&type=float64", "type=int16|uint16|int32|uint32|float32"),
    ("register=1&word_order=middle", "word_order=big|little"),
    ("register=1&unit=256", "0-255"),
    ("register=1&rate=0", "rate"),
    ("register=1&rate=5000", "at most 1000"),
    ("register=1&timeout_s=-1", "timeout_s"),
    ("register=1&clock=sender", "unknown option"),
])
def test_bad_modbus_uris_are_one_line(query, where):
    with pytest.raises(LoadError) as error:
        open_load(f"modbus://127.0.0.1:5020?{query}")
    message = str(error.value)
    assert "\n" not in message and where in message, message


@pytest.mark.parametrize("uri", ["modbus://127.0.0.1?register=1", "modbus://127.0.0.1:99999?register=1",
                                 "modbus://:502?register=1", "modbus://host:502/path?register=1"])
def test_a_modbus_uri_without_host_and_port_is_one_line(uri):
    with pytest.raises(LoadError) as error:
        open_load(uri)
    assert "\n" not in str(error.value) and "modbus://HOST:PORT?register=N" in str(error.value), str(error.value)


def test_options_are_in_the_settings_and_the_default_gap_follows_the_rate(server):
    uri = (f"modbus://127.0.0.1:{server.port}?register=7&scale=0.25&kind=input&type=float32&word_order=little"
           f"&unit=1&rate=2")
    with polling(uri) as load:
        assert isinstance(load, ModbusLoad) and load.time_base == TIME_BASE_MONOTONIC
        settings = load.settings
        assert {key: settings[key] for key in ("register", "scale", "kind", "type", "word_order", "unit", "rate_hz")} \
            == {"register": 7, "scale": 0.25, "kind": "input", "type": "float32", "word_order": "little", "unit": 1,
                "rate_hz": 2.0}
        assert load.max_gap_s == 2.5 and settings["uri"] == uri            # 5 poll periods at 2 Hz
    with polling(f"modbus://127.0.0.1:{server.port}?register=7") as load:
        assert load.max_gap_s == 0.5 and load.settings["rate_hz"] == 100.0 and load.settings["type"] == "int16"


# --- values ------------------------------------------------------------------------------------

@pytest.mark.parametrize("registers, query, expected_N", [
    ([0xFB2E], "scale=0.5", -617.0),
    ([0xFFFF], "type=uint16&scale=2", 131070.0),
    ([0xFFFE, 0x7960], "type=int32&scale=0.01", -1000.0),
    ([0x7960, 0xFFFE], "type=int32&word_order=little&scale=0.01", -1000.0),
    ([0xB2D0, 0x5E00], "type=uint32", 3.0e9),
    ([0x449A, 0x5000], "type=float32&scale=2", 2469.0),
])
def test_scale_and_types_are_exact_through_the_server(server, registers, query, expected_N):
    server.write(20, registers)
    with polling(f"modbus://127.0.0.1:{server.port}?register=20&{query}&rate=200") as load:
        wait_until(lambda: load.samples()[0].size >= 3)
        _, forces = load.samples()
        assert np.all(forces == expected_N), forces
        assert load.warnings.total() == 0


def test_input_registers_are_read_with_kind_input(server):
    with polling(f"modbus://127.0.0.1:{server.port}?register=0&kind=input&rate=200") as load:
        wait_until(lambda: load.samples()[0].size >= 2)
        assert np.all(load.samples()[1] == INPUT_MARK)
    with polling(f"modbus://127.0.0.1:{server.port}?register=0&rate=200") as load:     # holding 0: a separate block
        wait_until(lambda: load.samples()[0].size >= 2)
        assert np.all(load.samples()[1] == 0)


def test_a_force_ramp_is_stamped_on_the_monotonic_clock_and_interpolated_onto_frame_times(server):
    """The register follows F(t) = SLOPE x (t - t0) in steps of 2 ms (values in 0.1 N, int16), polled at 200 Hz."""
    slope, step_s, scale = 2000.0, 0.002, 0.1                 # N/s; the register's update period; N per unit
    written = []                                              # (monotonic time of the write, force in N)
    done = threading.Event()

    def ramp():
        t0 = time.monotonic()
        while not done.is_set():
            now = time.monotonic()
            force = round(slope * (now - t0) / scale) * scale
            if force > 3000:
                break
            server.write(30, [int(round(force / scale))])
            written.append((time.monotonic(), force))         # after the write returned: it is in the register
            done.wait(step_s)
        done.set()

    writer = threading.Thread(target=ramp, daemon=True)
    with polling(f"modbus://127.0.0.1:{server.port}?register=30&scale={scale}&rate=200") as load:
        wait_until(lambda: load.samples()[0].size >= 2)
        writer.start()
        wait_until(done.is_set, timeout_s=10)
        writer.join(5)
        samples_t, samples_f = load.samples()
    write_t, write_f = np.array(written).T
    assert samples_t.size > 50 and np.all(np.diff(samples_t) > 0)
    # Read in order: a later poll never sees an earlier value of a rising ramp (whatever the timing).
    during = (samples_t > write_t[0]) & (samples_t < write_t[-1])
    assert np.all(np.diff(samples_f[during]) >= 0)
    # Frames at 50 fps on the same clock, inside the ramp: their force is the ramp's at their time.
    frames = np.arange(write_t[0] + 0.05, write_t[-1] - 0.05, 1 / 50)
    measured = load.force_at(frames)
    true = np.interp(frames, write_t, write_f)
    error = np.abs(measured - true)
    tolerance = slope * 0.025
    assert np.isfinite(measured).all()
    assert np.mean(error <= tolerance) >= 0.9, (np.median(error), error.max(), tolerance)


# --- faults ------------------------------------------------------------------------------------

def test_a_server_that_stops_is_an_event_and_nan_then_samples_resume(server):
    server.write(40, [500])
    with polling(f"modbus://127.0.0.1:{server.port}?register=40&rate=200&retry_s=0.05") as load:
        wait_until(lambda: load.samples()[0].size >= 3)
        server.stop()
        wait_until(lambda: LoadEventKind.DISCONNECTED in kinds(load))
        stopped_at = time.monotonic()
        assert math.isnan(load.force_at(stopped_at))
        wait_until(lambda: LoadEventKind.CONNECT_FAILED in kinds(load))   # retries find nobody: one event
        t_before, f_before = load.samples()
        assert math.isnan(f_before[-1])                                   # the NaN marker where it was lost
        server.write(40, [800])
        server.start()
        wait_until(lambda: newest_force(load) == 800.0)
        t, f = load.samples()
        assert kinds(load) == [LoadEventKind.CONNECTED, LoadEventKind.DISCONNECTED, LoadEventKind.CONNECT_FAILED,
                               LoadEventKind.CONNECTED]
        # Never interpolated across the outage: from the last 500 N sample to the first 800 N one it is NaN.
        last_500 = t[np.flatnonzero(f == 500.0)[-1]]
        first_800 = t[np.flatnonzero(f == 800.0)[0]]
        inside = np.linspace(last_500, first_800, 9)[1:-1]
        assert np.isnan(load.force_at(inside)).all()
        assert load.force_at(first_800) == 800.0
        assert load.running


def test_a_wrong_register_is_a_counted_warning_and_nan_never_a_crash(server):
    with polling(f"modbus://127.0.0.1:{server.port}?register=150&type=float32&rate=200") as fine, \
            polling(f"modbus://127.0.0.1:{server.port}?register=500&rate=200") as wrong:
        wait_until(lambda: wrong.warnings.exception_responses >= 5 and fine.samples()[0].size >= 5)
        assert wrong.running and wrong.connected                     # the connection is fine, the address is not
        assert kinds(wrong) == [LoadEventKind.CONNECTED, LoadEventKind.READ_FAILED, LoadEventKind.STALLED] or \
            kinds(wrong) == [LoadEventKind.CONNECTED, LoadEventKind.READ_FAILED]
        failed = wrong.events()[1]
        assert "exception 2 (illegal address)" in failed.message and "register=" in failed.message
        assert failed.kind.is_trouble
        t, f = wrong.samples()
        assert np.isnan(f).all()                                     # NaN markers only
        assert np.isnan(wrong.force_at(t)).all() and math.isnan(wrong.force_at(time.monotonic()))
        assert np.all(fine.samples()[1] == 0.0)                      # float32 0.0 at 150-151


def test_a_server_that_does_not_answer_is_a_timeout_nan_and_a_stall(server):
    server.write(60, [100])
    with polling(f"modbus://127.0.0.1:{server.port}?register=60&rate=200&timeout_s=0.05&max_gap_s=0.2") as load:
        wait_until(lambda: load.samples()[0].size >= 3)
        server.silent = True
        wait_until(lambda: LoadEventKind.STALLED in kinds(load))
        assert load.warnings.timeouts >= 1
        assert kinds(load)[:3] == [LoadEventKind.CONNECTED, LoadEventKind.READ_FAILED, LoadEventKind.STALLED]
        assert "no answer" in load.events()[1].message
        assert math.isnan(load.force_at(load.samples()[0][-1]))      # a NaN marker at the failed poll
        server.silent = False
        wait_until(lambda: LoadEventKind.RESUMED in kinds(load))
        wait_until(lambda: newest_force(load) == 100.0)
        t, f = load.samples()
        good = np.flatnonzero(np.isfinite(f))
        gaps = np.flatnonzero(np.diff(good) > 1)
        assert gaps.size >= 1                                         # a hole of NaN markers between good runs
        left, right = t[good[gaps[0]]], t[good[gaps[0] + 1]]
        assert np.isnan(load.force_at(np.linspace(left, right, 7)[1:-1])).all()


def test_nothing_listening_is_one_event_and_close_stops_the_thread(server):
    port = server.port
    server.stop()
    with polling(f"modbus://127.0.0.1:{port}?register=1&retry_s=0.02") as load:
        wait_until(lambda: load.connect_attempts >= 4)      # several retries: still one event for the outage
        assert kinds(load) == [LoadEventKind.CONNECT_FAILED]
        assert math.isnan(load.force_when_known(time.monotonic()))


def test_close_wakes_a_poll_waiting_for_an_answer(server):
    load = open_load(f"modbus://127.0.0.1:{server.port}?register=1&timeout_s=3")
    wait_until(lambda: load.connected and load.samples()[0].size >= 1)
    server.silent = True
    wait_until(lambda: server.held >= 1)                    # a poll is now waiting (up to 3 s) for its answer
    load.close(timeout_s=5.0)
    assert not load.running


def test_force_when_known_waits_for_the_next_poll_and_not_for_a_stalled_one(server):
    server.write(70, [250])
    with polling(f"modbus://127.0.0.1:{server.port}?register=70&rate=50") as load:
        wait_until(lambda: load.samples()[0].size >= 2)
        frame_time = time.monotonic()                       # a frame that arrives now: no sample after it yet
        assert load.force_when_known(frame_time, wait_s=5.0) == 250.0   # waited for the next poll
        assert load.last_sample_time_s >= frame_time
        server.silent = True
        wait_until(lambda: LoadEventKind.STALLED in kinds(load))
        assert math.isnan(load.force_when_known(time.monotonic()))
