"""Strain out (``--publish``): UDP JSON datagrams and a Modbus TCP register map, checked against the recording.

Every value a controller receives is compared with what the same session recorded for the
same frame (``/dic/extensometers``, read back): UDP's JSON numbers exactly (a float64's
shortest repr round-trips), Modbus's float32 registers exactly as float32 of the recorded
double. Bad URIs and a port in use are one line, exit 2, no recording.
"""

import dataclasses
import errno
import json
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from livedic.acquire.recording.reader import Recording, read_events
from livedic.dic.strain.extensometer import ExtensometerStatus
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.publish import STATE_ENDED, decode_registers, register_count
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import StrainConfig
from tests.stream.publish.conftest import assert_port_free

SOURCE = "synthetic:tensile?frames=14&size=384x512&pace=0"
SMALL = "synthetic:tensile?size=192x256&frames=3&fps=1000"


def test_preload_imports_the_modbus_server_and_only_for_modbus():
    """What opening a Modbus server imports is imported by ``preload`` (before the session's first frame)."""
    script = ("import sys; from livedic.stream.publish import parse_publish_uris, preload; "
              "preload(parse_publish_uris(sys.argv[1:])); print('pymodbus.server' in sys.modules)")
    def imported(*uris):
        done = subprocess.run([sys.executable, "-c", script, *uris], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr
        return done.stdout.strip() == "True"
    assert not imported("udp://:9870")
    assert imported("udp://:9870", "modbus://:0")


# --------------------------------------------------------------------------- sessions

def _config(record, publish, **more):
    more.setdefault("static_frames", 0)      # the frames counted here are the test's: no noise-floor frames before
    return SessionConfig(source=SOURCE, viewer=ViewerConfig("none"), record=record, warm_up=False,
                         strain=StrainConfig(gauge_length=200), publish=tuple(publish), **more)


def _receiver():
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    return receiver


def _drain(receiver):
    """Every datagram waiting on ``receiver`` (the session has ended: all were sent)."""
    receiver.setblocking(False)
    out = []
    while True:
        try:
            out.append(receiver.recv(65536))
        except BlockingIOError:
            return out


def _recorded(path):
    """{frame: (time_s as export gives it, eng_strain array, ok array)} from the recording."""
    recording = Recording(path)
    frames = [r.frame_index for r in recording.results()]
    first_ns = next(iter(Recording(path).results())).timestamp_ns
    readings = {frame: ((int(ts) - int(first_ns)) / 1e9, r) for frame, ts, r in recording.extensometer_readings()}
    return frames, readings


@pytest.fixture(scope="module")
def udp_session(tmp_path_factory):
    record = str(tmp_path_factory.mktemp("udp") / "session.mcap")
    receiver = _receiver()
    port = receiver.getsockname()[1]
    said = []
    with Session(_config(record, [f"udp://:{port}"]), say=said.append) as session:
        session.execute()
    datagrams = _drain(receiver)
    receiver.close()
    return session, record, datagrams, said


def test_one_datagram_per_tracked_frame_with_the_recorded_strain(udp_session):
    session, record, datagrams, said = udp_session
    frames, readings = _recorded(record)
    assert session.stats.frames == len(frames) == 14 and len(datagrams) == len(frames)
    messages = [json.loads(d.decode("utf-8")) for d in datagrams]
    assert [m["frame"] for m in messages] == frames                     # in order, each once
    for message in messages:
        assert set(message) == {"frame", "time_s", "strain", "ok", "true_strain"}
        time_s, recorded = readings[message["frame"]]
        assert message["time_s"] == time_s                              # as the recording and export give it
        assert list(message["strain"]) == list(recorded.names) == ["axial", "transverse"]
        for name, eng, true in zip(recorded.names, recorded.eng_strain, recorded.true_strain):
            assert message["strain"][name] == float(eng)                # exactly the recorded double
            assert message["true_strain"][name] == float(true)
        assert message["ok"] is bool(recorded.ok.all()) is True
    assert messages[-1]["strain"]["axial"] > 0.05                       # the test went well into plasticity
    assert any(f"publishing strain to udp://127.0.0.1:" in line for line in said)


def test_summary_counts_the_datagrams_and_their_latency(udp_session):
    session, _, _, _ = udp_session
    (entry,) = session.summary()["publish"]
    assert entry["sent"] == session.stats.frames and entry["failed"] == 0
    assert 0 < entry["upstream_p50_ms"] <= entry["latency_p50_ms"] <= entry["latency_p99_ms"]
    assert f"  publish    {entry['uri']}: {entry['sent']} frames sent; result -> sent p50" in session.summary_text()


def _lose_transverse_on_odd_frames(session):
    """The strain stage's readings with the transverse extensometer lost (NaN, END_LOST) on odd frames."""
    stage = session.strain
    compute = stage.compute
    calls = []

    def lossy(u, v, ok):
        strain, readings = compute(u, v, ok)
        calls.append(None)
        if len(calls) % 2 == 0:
            eng, true, status = (readings.eng_strain.copy(), readings.true_strain.copy(), readings.status.copy())
            eng[1] = true[1] = np.nan
            status[1] = int(ExtensometerStatus.END_LOST)
            readings = dataclasses.replace(readings, eng_strain=eng, true_strain=true, status=status)
        return strain, readings
    stage.compute = lossy


def test_a_lost_extensometer_is_null_and_the_frame_not_ok(tmp_path):
    record = str(tmp_path / "lossy.mcap")
    receiver = _receiver()
    with Session(_config(record, [f"udp://127.0.0.1:{receiver.getsockname()[1]}"], frames=6), say=lambda m: None) \
            as session:
        session.prepare()
        _lose_transverse_on_odd_frames(session)
        session.start()
        session.run()
    messages = [json.loads(d) for d in _drain(receiver)]
    receiver.close()
    _, readings = _recorded(record)
    assert len(messages) == 6
    lost = [m for m in messages if m["strain"]["transverse"] is None]
    assert len(lost) == 3
    for message in messages:
        _, recorded = readings[message["frame"]]
        assert message["ok"] is bool(recorded.ok.all())
        if message["strain"]["transverse"] is None:
            assert not recorded.ok[1] and np.isnan(recorded.eng_strain[1]) and message["ok"] is False
            assert message["strain"]["axial"] == float(recorded.eng_strain[0])   # the other one still goes out
        else:
            assert message["ok"] is True and message["strain"]["transverse"] == float(recorded.eng_strain[1])


class _FailingSocket:
    """A UDP socket whose sends fail for frames 3..5 (ENETUNREACH), then work again."""

    def __init__(self, real):
        self.real = real
        self.calls = 0

    def sendto(self, data, address):
        self.calls += 1
        if 4 <= self.calls <= 6:
            raise OSError(errno.ENETUNREACH, "Network is unreachable")
        return self.real.sendto(data, address)

    def close(self):
        self.real.close()


def test_a_failing_send_is_a_warning_and_the_session_and_recording_go_on(tmp_path):
    record = str(tmp_path / "failing.mcap")
    receiver = _receiver()
    said = []
    with Session(_config(record, [f"udp://127.0.0.1:{receiver.getsockname()[1]}"], frames=10), say=said.append) \
            as session:
        session.prepare()
        outlet = session.publishers[0].outlet
        outlet.socket = _FailingSocket(outlet.socket)
        session.start()
        session.run()
    received = _drain(receiver)
    receiver.close()
    frames, _ = _recorded(record)
    assert len(frames) == session.stats.frames == 10                     # every frame recorded
    (entry,) = session.summary()["publish"]
    assert entry["sent"] == len(received) == 7 and entry["failed"] == 3
    assert "3 NOT sent" in session.summary_text()
    events = [e for e in read_events(record) if e.kind == "publish"]
    assert [e.level for e in events] == ["warning", "info"]
    assert "not sent (" in events[0].message and "Network is unreachable" in events[0].message
    assert "sending again from frame" in events[1].message
    assert sum("warning: udp://127.0.0.1:" in line for line in said) == 1     # said once, not per frame
    assert not session.sink_errors


def test_strain_goes_out_before_the_load_stage_waits_for_force(tmp_path):
    """The publisher is the tracking thread's stage right after the strain stage: a force stream's wait never
    delays strain out."""
    receiver = _receiver()
    seen = []
    with Session(_config(None, [f"udp://127.0.0.1:{receiver.getsockname()[1]}"], frames=3, load="synthetic"),
                 say=lambda m: None) as session:
        session.prepare()
        session.start()
        sinks = session.loop.stages
        publisher = session.publishers[0]
        assert sinks == [session.strain, publisher, session.load_stage]

        send = publisher.on_frame

        def watched(result):                      # what the frame holds when the publisher runs
            seen.append((result.extensometers is not None, result.force_N))
            send(result)
        publisher.on_frame = watched
        session.run()
    messages = [json.loads(d) for d in _drain(receiver)]
    receiver.close()
    assert seen == [(True, None)] * 3                 # strain computed, force not yet looked up
    assert len(messages) == 3 and all(m["ok"] for m in messages)
    assert "force_N" not in messages[0]               # the controller has its own load cell
    assert session.summary()["force"]["frames"] == 3  # and the load stage still ran on every frame


# --------------------------------------------------------------------------- Modbus

def _read_map(client, count):
    response = client.read_holding_registers(0, count=count)
    assert not response.isError(), response
    return response.registers


def test_modbus_serves_each_frame_whole_and_the_last_one_after_the_session(tmp_path):
    from pymodbus.client import ModbusTcpClient
    record = str(tmp_path / "modbus.mcap")
    said = []
    reads, stop = [], threading.Event()
    with Session(_config(record, ["modbus://127.0.0.1:0"]), say=said.append) as session:
        session.prepare()
        outlet = session.publishers[0].outlet
        count = register_count(2)
        client = ModbusTcpClient("127.0.0.1", port=outlet.port, timeout=5)
        assert client.connect()
        before = decode_registers(_read_map(client, count))
        assert before["state"] == 0 and before["update_count"] == 0 and before["extensometers"] == 2

        def poll():
            while not stop.is_set():
                reads.append(decode_registers(_read_map(client, count)))
                stop.wait(0.002)
        poller = threading.Thread(target=poll)
        poller.start()
        try:
            session.start()
            session.run()
        finally:
            stop.set()
            poller.join()
        after = decode_registers(_read_map(client, count))
        # pymodbus's own decoding agrees with the map: float32, big-endian word order
        raw = _read_map(client, count)
        axial = client.convert_from_registers(raw[16:18], data_type=client.DATATYPE.FLOAT32, word_order="big")
        frame = client.convert_from_registers(raw[2:4], data_type=client.DATATYPE.UINT32, word_order="big")
        refused = client.write_register(20, 1)
        client.close()
        port = outlet.port
    frames, readings = _recorded(record)
    last = frames[-1]
    time_s, recorded = readings[last]
    assert after["state"] == STATE_ENDED and after["update_count"] == session.stats.frames == len(frames)
    assert after["frame"] == frame == last and after["ok"] is True and after["valid"] == [True, True]
    assert after["time_s"] == np.float32(time_s)
    assert after["eng_strain"] == [np.float32(v) for v in recorded.eng_strain]
    assert after["true_strain"] == [np.float32(v) for v in recorded.true_strain]
    assert axial == np.float32(recorded.eng_strain[0])
    assert refused.isError()                                                    # writes are refused
    # Every read during the session is one frame whole: its time and strains are that frame's.
    during = [r for r in reads if r["update_count"] > 0]
    assert during, "no read landed during the session"
    for read in during:
        t, frame_readings = readings[read["frame"]]
        assert read["time_s"] == np.float32(t)
        assert read["eng_strain"] == [np.float32(v) for v in frame_readings.eng_strain]
    assert [r["update_count"] for r in reads] == sorted(r["update_count"] for r in reads)
    assert any(f"publishing strain on modbus://127.0.0.1:{port}" in line and "axial at 16, transverse at 22" in line
               for line in said)
    assert_port_free(port)                  # closed with the session: the port is free again


def test_modbus_answers_the_ended_state_for_the_linger_then_closes(tmp_path):
    """A controller polling while the session closes reads state 2 with the last frame's values.

    The reads start only once the session's tracking has ended and ``close`` is called: the
    server answers them for ``linger_s`` (the new-user trial: it was shut down right after
    state 2 was written, and a client polling every 5 ms never saw it), then the port is free.
    """
    from pymodbus.client import ModbusTcpClient
    record = str(tmp_path / "linger.mcap")
    count = register_count(2)
    reads, closing = [], threading.Event()

    def poll_from_closing(client):
        closing.wait()
        while True:
            try:
                response = client.read_holding_registers(0, count=count)
            except Exception:  # noqa: BLE001 - pymodbus's "connection closed": the server stopped
                return
            if response.isError():
                return
            reads.append(decode_registers(response.registers))
            time.sleep(0.005)

    with Session(_config(record, ["modbus://127.0.0.1:0?linger_s=0.5"], frames=6), say=lambda m: None) as session:
        session.prepare()
        port = session.publishers[0].outlet.port
        client = ModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
        assert client.connect()
        poller = threading.Thread(target=poll_from_closing, args=(client,))
        poller.start()
        try:
            session.start()
            session.run()
        finally:
            closing.set()              # the session's tracking has ended; the context now closes it
    poller.join(timeout=10)
    client.close()
    assert not poller.is_alive()                                  # the server did stop answering
    frames, readings = _recorded(record)
    time_s, recorded = readings[frames[-1]]
    assert len(reads) >= 2, "no read was answered after the session ended"
    for read in reads:
        assert read["state"] == STATE_ENDED and read["update_count"] == session.stats.frames == len(frames) == 6
        assert read["frame"] == frames[-1] and read["ok"] is True and read["time_s"] == np.float32(time_s)
        assert read["eng_strain"] == [np.float32(v) for v in recorded.eng_strain]
        assert read["true_strain"] == [np.float32(v) for v in recorded.true_strain]
    assert reads[-1]["age_ms"] >= reads[0]["age_ms"]             # the same values, older
    assert_port_free(port)                                        # closed: the port is free again


_WATCH_THE_FIRST_FRAME = """
import sys
import livedic.stream.session.preparation as preparation_module
import livedic.stream.session.session as session_module
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.stages.strain import StrainConfig


class Watched(preparation_module.FirstFrameAhead):
    def __init__(self, source, uri):
        print("pymodbus.server" in sys.modules)          # imported by the time the first frame is read?
        super().__init__(source, uri)


preparation_module.FirstFrameAhead = Watched
config = SessionConfig(source="synthetic:tensile?size=192x256&frames=2&pace=0", viewer=ViewerConfig("none"),
                       record=None, warm_up=False, strain=StrainConfig(gauge_length=100),
                       publish=("modbus://127.0.0.1:0?linger_s=0",))
with session_module.Session(config, say=lambda m: None) as session:
    session.prepare()
"""


def test_the_modbus_server_is_imported_before_the_first_frame():
    """pymodbus is imported before the session reads its first frame, not while the server opens between the
    first frame and the start: a paced source's frames then came late, in a burst (2-10 dropped at 50 fps)."""
    done = subprocess.run([sys.executable, "-c", _WATCH_THE_FIRST_FRAME], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True"]


# --------------------------------------------------------------------------- the command line

def _run(tmp_path, *extra):
    record = tmp_path / "s.mcap"
    argv = ["run", "--viewer", "none", "--record", str(record), "--progress", "off", "--source", SMALL, *extra]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          timeout=120)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    return done, errors, record


@pytest.mark.parametrize("extra, message", [
    (["--gauge-length", "100", "--publish", "udp://127.0.0.1"], "--publish udp://127.0.0.1: a port is needed"),
    (["--gauge-length", "100", "--publish", "mqtt://127.0.0.1:1883"], "unknown scheme 'mqtt'"),
    (["--publish", "udp://127.0.0.1:9870"], "--publish sends extensometer strain: add --gauge-length"),
    (["--gauge-length", "100", "--publish", "udp://no-such-host.invalid:9870"], "cannot resolve host"),
])
def test_bad_publish_input_is_one_line_exit_2_and_no_file(tmp_path, extra, message):
    done, errors, record = _run(tmp_path, *extra)
    assert done.returncode == 2, done.stderr
    assert len(errors) == 1 and message in errors[0], done.stderr
    assert "Traceback" not in done.stderr and not record.exists()


def test_a_modbus_port_in_use_is_one_line_exit_2_and_no_file(tmp_path):
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    port = busy.getsockname()[1]
    try:
        done, errors, record = _run(tmp_path, "--gauge-length", "100", "--publish", "udp://:9870",
                                    "--publish", f"modbus://127.0.0.1:{port}")
    finally:
        busy.close()
    assert done.returncode == 2, done.stderr
    assert len(errors) == 1 and f"cannot listen on 127.0.0.1:{port}" in errors[0], done.stderr
    assert "Address already in use" in errors[0] and not record.exists()
    assert "Traceback" not in done.stderr


def test_run_publishes_from_the_command_line(tmp_path):
    receiver = _receiver()
    # the test's 3 frames only (at 1000 fps): no static frames before them
    done, errors, record = _run(tmp_path, "--gauge-length", "100", "--static-frames", "0", "--publish",
                                f"udp://localhost:{receiver.getsockname()[1]}")
    messages = [json.loads(d) for d in _drain(receiver)]
    receiver.close()
    assert done.returncode == 0 and not errors, done.stderr
    assert len(messages) == 3 and [m["frame"] for m in messages] == _recorded(str(record))[0]
    assert "  publish    udp://localhost:" in done.stdout and "3 frames sent" in done.stdout
