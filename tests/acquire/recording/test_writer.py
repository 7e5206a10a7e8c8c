"""Recorder: round trip, format compatibility, chunk layout, threads, crash safety (SIGKILL), disk full
(RLIMIT_FSIZE)."""

import faulthandler
import inspect
import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.acquire.recording.reader import inspect_recording, read_events, read_results, read_session
from livedic.acquire.recording.recover import recover
from livedic.acquire.recording.source import McapSource
from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.recording.writer import Recorder
from tests.waiting import wait_until

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
T0 = 1_700_000_000_000_000_000


@pytest.fixture(autouse=True)
def _hang_guard():
    """Every test here is bounded: a hang dumps the stacks and ends the run after 60 s."""
    faulthandler.dump_traceback_later(60, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


def _frames(n, dtype, shape=(24, 40), seed=0):
    rng = np.random.default_rng(seed)
    top = 255 if dtype == np.uint8 else 65535
    return [rng.integers(0, top + 1, size=shape, dtype=dtype) for _ in range(n)]


def _results(i, n_points=17, seed=0):
    rng = np.random.default_rng(seed + i)
    u = rng.normal(size=n_points)
    u[3] = np.nan
    return dict(point_ids=np.arange(100, 100 + n_points), x=rng.uniform(0, 40, n_points),
                y=rng.uniform(0, 24, n_points), u=u, v=rng.normal(size=n_points),
                zncc=rng.uniform(-1, 1, n_points), ok=rng.random(n_points) > 0.3)


def _run_child(code, *args, timeout=30):
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code), *map(str, args)], env=env, cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


# ----------------------------------------------------------------------------- round trip

@pytest.mark.parametrize("dtype,pixel_format,compression", [
    (np.uint8, "Mono8", None), (np.uint16, "Mono16", None), (np.uint16, "Mono12", "lz4"), (np.uint8, "Mono8", "lz4"),
    (np.uint16, "Mono10", None)])
def test_round_trip_is_bit_exact(tmp_path, dtype, pixel_format, compression):
    path = tmp_path / "session.mcap"
    images = _frames(7, dtype)
    session = {"source_uri": "synthetic://seed=3", "camera": {"exposure_us": 800.0, "gain_db": 0.0},
               "roi": [0, 0, 40, 24], "points": np.arange(8.0).reshape(4, 2), "method": "improved-wso+icgn1",
               "parameters": {"subset": 21, "radius": 16}}
    with Recorder(path, session, compression=compression, chunk_bytes=4096) as rec:
        for i, image in enumerate(images):
            index = 10 + 2 * i                                   # gaps: frames lost upstream
            metadata = {"truth_u": [0.5 * i, 1.0]} if i % 3 == 0 else {}
            assert rec.write_frame(Frame(index, T0 + i * 40_000_000, image, pixel_format, metadata))
            extra = dict(ux=np.full(17, 0.01 * i), uy=np.zeros(17), vx=np.zeros(17), vy=np.full(17, -0.02),
                         status=np.arange(17, dtype=np.int8) % 3, iterations=np.full(17, 4),
                         method="improved-wso+icgn1", processing_ns=1_234_567, latency_ns=2_000_000,
                         dropped_frames=1) if i % 2 else {}
            assert rec.write_results(index, T0 + i * 40_000_000, **_results(i), **extra)
        assert rec.write_event("drop", "1 frame dropped (queue full)", level="warning")
        rec.write_event("recording_stopped", "operator stopped")
    assert rec.error is None and rec.frames_written == 7 and rec.results_written == 7
    assert rec.frames_durable == 7 and rec.results_durable == 7 and rec.bytes_written == os.path.getsize(path)

    with McapSource(path) as source:
        frames = list(source)
    assert [f.index for f in frames] == [10 + 2 * i for i in range(7)]
    for i, (frame, image) in enumerate(zip(frames, images)):
        assert frame.timestamp_ns == T0 + i * 40_000_000
        assert frame.image.dtype == image.dtype and frame.image.shape == image.shape
        assert frame.image.tobytes() == image.tobytes()
        assert frame.pixel_format == pixel_format
        assert frame.metadata == ({"truth_u": [0.5 * i, 1.0]} if i % 3 == 0 else {})
    assert source.info.indexed and not source.info.truncated and source.info.note == ""

    results = read_results(path)
    assert [r.frame_index for r in results] == [10 + 2 * i for i in range(7)]
    for i, got in enumerate(results):
        want = _results(i)
        assert got.timestamp_ns == T0 + i * 40_000_000
        assert got.point_id.dtype == np.uint32 and np.array_equal(got.point_id, want["point_ids"])
        for name in ("x", "y", "u", "v", "zncc"):
            assert getattr(got, name).tobytes() == want[name].tobytes()      # NaN included, bit for bit
        assert got.ok.dtype == bool and np.array_equal(got.ok, want["ok"])
        if i % 2:
            assert np.array_equal(got.ux, np.full(17, 0.01 * i)) and np.array_equal(got.vy, np.full(17, -0.02))
            assert np.array_equal(got.status, np.arange(17) % 3) and np.array_equal(got.iterations, np.full(17, 4))
            assert (got.method, got.processing_ns, got.latency_ns, got.dropped_frames) == \
                ("improved-wso+icgn1", 1_234_567, 2_000_000, 1)
        else:
            assert got.ux is None and got.status is None and got.method == ""

    events = read_events(path)
    assert [(e.kind, e.level) for e in events] == [("drop", "warning"), ("recording_stopped", "info")]
    assert events[0].timestamp_ns >= T0 + 6 * 40_000_000            # frame clock, after the last frame

    from mcap.reader import NonSeekingReader
    with open(path, "rb") as f:                            # the session is the first message, in the frame clock
        _, channel, first = next(iter(NonSeekingReader(f).iter_messages(log_time_order=False)))
    assert channel.topic == rs.TOPIC_SESSION and first.log_time == T0

    meta = read_session(path)
    assert meta["source_uri"] == "synthetic://seed=3"
    assert meta["camera"] == {"exposure_us": 800.0, "gain_db": 0.0}
    assert meta["points"] == [[0.0, 1.0], [2.0, 3.0], [4.0, 5.0], [6.0, 7.0]]
    assert meta["parameters"] == {"subset": 21, "radius": 16}
    assert meta["software_version"] and meta["start_time"] and isinstance(meta["start_time_ns"], int)
    assert meta[rs.FORMAT_KEY] == rs.FORMAT_VERSION


def test_reused_image_buffer_is_copied_at_write(tmp_path):
    path = tmp_path / "reuse.mcap"
    buffer = np.zeros((8, 8), np.uint8)
    with Recorder(path, {}) as rec:
        for i in range(3):
            buffer[:] = i
            rec.write_frame(Frame(i, T0 + i, buffer, "Mono8"))
    assert [int(f.image[0, 0]) for f in McapSource(path)] == [0, 1, 2]


def test_strided_and_big_endian_images_are_stored_as_seen(tmp_path):
    path = tmp_path / "views.mcap"
    base = _frames(1, np.uint16, (30, 50))[0]
    views = [base[::2, 5:45], base.astype(">u2"), np.asfortranarray(base)]
    with Recorder(path, {}) as rec:
        for i, image in enumerate(views):
            rec.write_frame(Frame(i, T0 + i, image, "Mono16"))
    for got, want in zip(McapSource(path), views):
        assert np.array_equal(got.image, want) and got.image.dtype == np.uint16


def test_live_sized_session_round_trips_and_a_cut_file_keeps_its_whole_chunks(tmp_path):
    """1 MP frames and 1,059- and 2,000-point results, default chunks (4 MiB: a few frames each): read back
    bit for bit by livedic's readers and by mcap's own (every CRC checked); a file cut inside any image
    chunk still gives every frame of the chunks before it."""
    from mcap.reader import make_reader
    from mcap.records import Message
    from mcap.stream_reader import breakup_chunk
    path = tmp_path / "live.mcap"
    images = _frames(10, np.uint8, (1024, 1024))
    sizes = [1059, 2000] * 5
    with Recorder(path, {"source_uri": "synthetic:tensile"}) as rec:
        for i, (image, n) in enumerate(zip(images, sizes)):
            assert rec.write_frame(Frame(i, T0 + i * 20_000_000, image, "Mono8", {"exposure_us": 5000.0}))
            assert rec.write_results(i, T0 + i * 20_000_000, **_results(i, n_points=n), status=np.zeros(n, np.int32),
                                     iterations=np.full(n, 3), method="improved-wso+icgn1")
    assert rec.frames_durable == 10 and rec.results_durable == 10 and rec.bytes_written == os.path.getsize(path)
    assert [np.array_equal(f.image, image) for f, image in zip(McapSource(path), images)] == [True] * 10
    for got, n in zip(read_results(path), sizes):
        want = _results(got.frame_index, n_points=n)
        assert all(getattr(got, name).tobytes() == want[name].tobytes() for name in ("x", "y", "u", "v", "zncc"))
        assert np.array_equal(got.ok, want["ok"]) and np.array_equal(got.iterations, np.full(n, 3))
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        topics = [channel.topic for _, channel, _ in reader.iter_messages(log_time_order=False)]
    assert topics.count(rs.TOPIC_IMAGE) == 10 and topics.count(rs.TOPIC_RESULTS) == 10
    assert recover(path, tmp_path / "recovered.mcap")["frames"] == 10

    image_topics = {cid for cid, channel in summary.channels.items() if channel.topic == rs.TOPIC_IMAGE}
    data = path.read_bytes()
    before = 0                                   # frames in the image chunks before the one cut
    image_chunks = [c for c in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
                    if set(c.message_index_offsets) & image_topics]
    assert len(image_chunks) >= 3
    for chunk in image_chunks:
        cut = tmp_path / "cut.mcap"
        cut.write_bytes(data[:chunk.chunk_start_offset + chunk.chunk_length - 1])
        frames = list(McapSource(cut))
        assert [f.index for f in frames] == list(range(before))
        assert all(np.array_equal(f.image, images[f.index]) for f in frames)
        before += sum(isinstance(record, Message) and record.channel_id in image_topics
                      for record in breakup_chunk(_read_chunk(data, chunk)))


def _read_chunk(data, index):
    """The chunk record an mcap ``ChunkIndex`` points at, parsed by mcap."""
    from mcap.data_stream import ReadDataStream
    from mcap.records import Chunk
    return Chunk.read(ReadDataStream(io.BytesIO(data[index.chunk_start_offset + 9:])))


def test_plain_mcap_with_protobuf_decoder_reads_everything(tmp_path):
    """What docs/guide/recording-format.md promises: no livedic needed to read a recording."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    path = tmp_path / "plain.mcap"
    image = _frames(1, np.uint16)[0]
    with Recorder(path, {"source_uri": "x"}) as rec:
        rec.write_frame(Frame(5, T0, image, "Mono12", {"a": 1}))
        rec.write_results(5, T0, **_results(0), ux=np.zeros(17))
        rec.write_event("note", "hello")
    seen = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().library.startswith("livedic/")
        (meta,) = [m for m in reader.iter_metadata() if m.name == rs.METADATA_NAME]
        assert meta.metadata["source_uri"] == "x"
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            seen[channel.topic] = (schema.name, message, decoded)
    name, message, raw = seen[rs.TOPIC_IMAGE]
    assert name == "foxglove.RawImage" and raw.encoding == "mono16" and raw.step == 80
    assert (raw.width, raw.height, raw.timestamp.seconds, raw.timestamp.nanos) == (40, 24, 1_700_000_000, 0)
    assert np.array_equal(np.frombuffer(raw.data, "<u2").reshape(24, 40), image)
    assert message.sequence == 5 and message.log_time == T0
    name, _, info = seen[rs.TOPIC_FRAME_INFO]
    assert name == "livedic.FrameInfo" and info.pixel_format == "Mono12" and json.loads(info.metadata_json) == {"a": 1}
    name, _, res = seen[rs.TOPIC_RESULTS]
    assert name == "livedic.FrameResults" and res.frame_index == 5 and list(res.point_id) == list(range(100, 117))
    assert np.array_equal(np.array(res.x), _results(0)["x"]) and len(res.ux) == 17
    assert seen[rs.TOPIC_EVENTS][2].message == "hello"
    assert dict(seen[rs.TOPIC_SESSION][2].metadata)["source_uri"] == "x"


def test_a_stereo_frames_3d_arrays_round_trip_and_a_protobuf_decoder_reads_them(tmp_path):
    """X, Y, Z, U, V, W, the 3D status and the right image positions (stereo sessions) come back bit for bit,
    NaN included, through livedic's reader and through plain protobuf decoding; 2D results have none."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    path = tmp_path / "stereo.mcap"
    rng = np.random.default_rng(5)
    stereo = {name: rng.normal(size=17) for name in rs.STEREO_ARRAYS if name != "stereo_status"}
    stereo["w_mm"][3] = np.nan
    stereo["stereo_status"] = np.arange(17) % 4
    with Recorder(path, {"source_uri": "stereo:a,b"}, stereo=True) as rec:
        assert rec.write_results(0, T0, **_results(0), **stereo)
        assert rec.write_results(1, T0 + 1, **_results(1))
    first, second = read_results(path)
    for name in rs.STEREO_ARRAYS:
        assert first.stereo[name].tobytes() == np.asarray(stereo[name], dtype=wire.RESULT_DTYPES.get(
            name, np.float64)).tobytes(), name
    assert second.stereo == {}
    with open(path, "rb") as f:
        decoded = [d for _, channel, _, d in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
                   if channel.topic == rs.TOPIC_RESULTS]
    assert np.array_equal(np.array(decoded[0].z_mm), stereo["z_mm"]) and list(decoded[0].stereo_status)[:4] == [0, 1, 2, 3]


@pytest.mark.skipif(shutil.which("rerun", path=os.path.dirname(sys.executable)) is None, reason="no rerun CLI")
def test_rerun_mcap_convert_accepts_a_recording(tmp_path):
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.dic.strain import strain_field, strain_window

    path, out = tmp_path / "r.mcap", tmp_path / "r.rrd"
    windows = strain_window(np.array([[x, y] for y in range(3) for x in range(3)], float), window=3, step=1.0)
    with Recorder(path, {"source_uri": "x"}) as rec:
        for i, image in enumerate(_frames(2, np.uint8)):
            rec.write_frame(Frame(i, T0 + i * 10**7, image, "Mono8"))
            rec.write_results(i, T0 + i * 10**7, **_results(i))
            rec.write_strain(i, T0 + i * 10**7, strain_field(windows, np.full(9, 0.1), np.zeros(9), np.ones(9, bool)))
            rec.write_extensometers(i, T0 + i * 10**7, ExtensometerReadings(
                ("axial",), np.array([100.0]), np.array([100.0 + i]), np.array([0.01 * i]),
                np.array([np.log1p(0.01 * i)]), np.array([0], np.int32)))
    rerun = shutil.which("rerun", path=os.path.dirname(sys.executable))
    done = subprocess.run([rerun, "mcap", "convert", str(path), "-o", str(out)], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 0, done.stderr
    from rerun.chunk import RrdReader
    summary = str(RrdReader(str(out)).stream().collect().summary())
    assert "Image:buffer" in summary and "livedic.FrameResults:message" in summary
    assert "livedic.StrainField:message" in summary and "livedic.ExtensometerSample:message" in summary


# ----------------------------------------------------------------------------- API contract

def test_existing_file_is_never_replaced_without_overwrite(tmp_path):
    path = tmp_path / "precious.mcap"
    path.write_bytes(b"yesterday's test")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        Recorder(path, {})
    assert path.read_bytes() == b"yesterday's test"
    with Recorder(path, {}, overwrite=True):
        pass
    assert read_session(path)[rs.FORMAT_KEY] == "1"


def test_bad_calls_raise_at_once_and_leave_the_recorder_working(tmp_path):
    path = tmp_path / "calls.mcap"
    with Recorder(path, {}) as rec:
        with pytest.raises(ValueError, match="2-D"):
            rec.write_frame(Frame(0, T0, np.zeros((2, 2, 3), np.uint8), "RGB8"))
        with pytest.raises(ValueError, match="uint8 or uint16"):
            rec.write_frame(Frame(0, T0, np.zeros((2, 2), np.float32), "Mono8"))
        with pytest.raises(ValueError, match="timestamp_ns"):
            rec.write_frame(Frame(0, -1, np.zeros((2, 2), np.uint8), "Mono8"))
        args = _results(0)
        with pytest.raises(ValueError, match="entries"):
            rec.write_results(0, T0, **{**args, "u": args["u"][:-1]})
        with pytest.raises(TypeError, match="strain"):
            rec.write_results(0, T0, **args, strain=1)
        with pytest.raises(ValueError, match="point_ids"):
            rec.write_results(0, T0, **{**args, "point_ids": -args["point_ids"]})
        with pytest.raises(ValueError, match="level"):
            rec.write_event("note", "x", level="loud")
        assert rec.write_frame(Frame(0, T0, np.zeros((2, 2), np.uint8), "Mono8"))
    assert rec.error is None and len(list(McapSource(path))) == 1
    assert not rec.write_frame(Frame(1, T0, np.zeros((2, 2), np.uint8), "Mono8"))   # after close: dropped
    assert rec.frames_dropped == 1


def test_idle_recorder_flushes_in_the_background(tmp_path):
    """With no further writes, an open chunk still reaches the file within flush_interval_s."""
    path, copy = tmp_path / "live.mcap", tmp_path / "copy.mcap"
    rec = Recorder(path, {}, flush_interval_s=0.1)
    try:
        rec.write_frame(Frame(0, T0, np.ones((4, 4), np.uint8), "Mono8"))     # small: stays in an open chunk
        rec.write_results(0, T0, **_results(0))
        def flushed():
            shutil.copyfile(path, copy)
            return len(read_results(copy)) == 1

        wait_until(flushed, 30, "the open chunk reaching the file")
        assert [f.index for f in McapSource(copy)] == [0] and len(read_results(copy)) == 1
        assert inspect_recording(copy).truncated
    finally:
        rec.close()


# ----------------------------------------------------------------------------- chunk layout

def _chunk_kinds(path):
    """Per chunk of an indexed file, in file order: the set of topics it holds."""
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    return [{summary.channels[cid].topic for cid in c.message_index_offsets} for c in chunks]


_IMAGE_TOPICS = {rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO}


def test_chunks_hold_one_kind_are_few_and_follow_the_age_bound(tmp_path):
    """Images and data (results, events, session) never share a chunk, yet frames and results that
    alternate do not cost a chunk each; nothing waits unwritten longer than flush_interval_s.

    A hand-driven clock makes the bound exact: 64 frames a second (dt = 1/64 s, exact in binary),
    flush_interval_s = 0.25 s = 16 frames. After each frame's writes the oldest unwritten message is
    younger than 16 frames, so at most 16 frames and 16 results are not yet durable."""
    path = tmp_path / "layout.mcap"
    dt, flush = 1 / 64, 0.25
    image = _frames(1, np.uint8, (128, 256))[0]                       # 32 KiB
    n = 200
    big = {k: np.resize(v, n) for k, v in _results(0).items()}       # ~9 KB of results a frame
    big["point_ids"] = np.arange(n)
    clock = [0.0]
    frames = 150
    with Recorder(path, {"source_uri": "x"}, chunk_bytes=256 << 10, flush_interval_s=flush) as rec:
        rec._cw.clock = lambda: clock[0]
        lags = []
        for i in range(frames):
            clock[0] += dt
            assert rec.write_frame(Frame(i, T0 + i, image, "Mono8"))
            assert rec.write_results(i, T0 + i, **big)
            if i % 40 == 39:
                assert rec.write_event("note", f"frame {i}")
            lags.append((i + 1 - rec.frames_durable, i + 1 - rec.results_durable))
            assert rec.frames_durable >= rec.results_durable          # a frame is on disk before its results
    chunks = rec.chunks_written
    assert max(f for f, _ in lags) <= round(flush / dt) and max(r for _, r in lags) <= round(flush / dt), lags
    assert max(r for _, r in lags) >= round(flush / dt) - 1           # results do wait (they are not per frame)
    kinds = _chunk_kinds(path)
    assert len(kinds) == chunks
    assert all(k <= _IMAGE_TOPICS or not k & _IMAGE_TOPICS for k in kinds), kinds
    assert kinds[0] == {rs.TOPIC_SESSION}                              # the session message is first, alone
    # 32 KiB images fill a 256 KiB chunk every 8 frames, results (~9 KB) age out every 16 frames: one data
    # chunk and at most two image chunks per 16 frames (the data write closes the open image chunk early).
    assert chunks <= 1 + 3 * math.ceil(frames / 16) + 2, chunks
    assert chunks < 0.25 * frames
    assert [r.frame_index for r in read_results(path)] == list(range(frames))
    assert [f.index for f in McapSource(path)] == list(range(frames))
    assert len(read_events(path)) == frames // 40


def test_writes_from_several_threads(tmp_path):
    """Frames from one thread, results and events from another, flushes from the background thread and a
    third caller: everything is recorded once, in order per channel, and no chunk mixes the kinds (pending
    results fill a 16 KiB chunk every two frames, mostly while an image chunk is open)."""
    path = tmp_path / "threads.mcap"
    n = 300
    images = _frames(4, np.uint8, (64, 64))
    errors = []
    with Recorder(path, {}, chunk_bytes=16 << 10, flush_interval_s=0.01) as rec:
        flush_now = threading.Semaphore(0)

        def frames():
            for i in range(n):
                rec.write_frame(Frame(i, T0 + i * 1000, images[i % 4], "Mono8"))
                if i % 15 == 14:
                    flush_now.release()             # the third caller flushes in the middle of the writes

        def results():
            for i in range(n):
                rec.write_results(i, T0 + i * 1000, **_results(i, n_points=200))    # ~9 KB
                if i % 30 == 0:
                    rec.write_event("note", str(i))

        def flusher():
            for _ in range(n // 15):
                flush_now.acquire()
                errors.append(rec.flush() is not True)

        threads = [threading.Thread(target=f) for f in (frames, results, flusher)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert rec.error is None and not any(errors)
    assert rec.frames_written == rec.frames_durable == n and rec.results_written == rec.results_durable == n
    assert [f.index for f in McapSource(path)] == list(range(n))
    assert [r.frame_index for r in read_results(path)] == list(range(n))
    assert [e.message for e in read_events(path)] == [str(i) for i in range(0, n, 30)]
    kinds = _chunk_kinds(path)
    assert len(kinds) == rec.chunks_written
    assert all(k <= _IMAGE_TOPICS or not k & _IMAGE_TOPICS for k in kinds)


# ----------------------------------------------------------------------------- SIGKILL

_KILL_CHILD = """
    import sys, time
    import numpy as np
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder

    path, marker, pause = sys.argv[1], sys.argv[2], float(sys.argv[3])
    rec = Recorder(path, {"source_uri": "test://sigkill"})
    image = np.zeros((96, 128), np.uint8)
    with open(marker, "w", buffering=1) as out:
        i, idled = 0, False
        while True:
            image[:] = i % 256
            stamp = time.time_ns()
            rec.write_frame(Frame(i, stamp, image, "Mono8"))
            rec.write_results(i, stamp, [i], [1.0], [2.0], [0.5], [-0.5], [0.9], [True])
            # frame i's writes returned; what the recorder counts as handed to the kernel at this moment
            out.write(f"{i} {rec.frames_durable} {rec.results_durable}\\n")
            i += 1
            if not idled and i >= 40 and (rec.frames_durable < i or rec.results_durable < i):
                # an idle spell while frames wait in memory: only the background flush can write them
                idled, quiet_since = True, time.monotonic()
                while rec.frames_durable < i or rec.results_durable < i:
                    time.sleep(0.01)
                out.write(f"idle {i} {time.monotonic() - quiet_since:.3f}\\n")
            time.sleep(pause)
"""


def test_sigkill_loses_nothing_the_recorder_counted_durable(tmp_path):
    """SIGKILL a recording process: every frame, and its results, that the recorder had handed to the
    kernel (``frames_durable``, ``results_durable``) is recoverable, and nothing waits in memory longer
    than ``flush_interval_s`` (0.25 s) of the writer's own pace, whatever the machine's load:

    * while frames come, each write checks the age of what waits, so with at least ``pause`` between
      frames no more than flush_interval_s / pause frames (+1 for rounding) are ever waiting;
    * when the caller goes quiet (the idle spell), the background flush writes the rest by itself.
    """
    path, marker, fixed = tmp_path / "killed.mcap", tmp_path / "marker.txt", tmp_path / "fixed.mcap"
    pause = 0.01
    flush_interval_s = inspect.signature(Recorder).parameters["flush_interval_s"].default     # the child's
    child = _run_child(_KILL_CHILD, path, marker, pause)
    try:
        def past_the_idle_spell():                          # with frames waiting again
            assert child.poll() is None, child.communicate()
            return marker.exists() and len(marker.read_text().splitlines()) > 200

        wait_until(past_the_idle_spell, 60, "the child writing 200 frames")
        child.send_signal(signal.SIGKILL)
    finally:
        child.kill()
        child.communicate()
    counts, idle = [], []
    for line in marker.read_text().splitlines():             # every line was written before the kill
        parts = line.split()
        if len(parts) == 3 and parts[0].isdigit():
            counts.append(tuple(int(part) for part in parts))
        elif len(parts) == 3 and parts[0] == "idle":
            idle.append((int(parts[1]), float(parts[2])))
    assert [frame for frame, _, _ in counts] == list(range(len(counts)))
    assert len(idle) == 1, "the idle spell did not end: the background flush did not write what waited"
    quiet_at = idle[0][0]                                   # frames written when the writer went quiet
    assert min(counts[quiet_at - 1][1:]) < quiet_at <= min(counts[quiet_at][1:])
    most_waiting = int(flush_interval_s / pause) + 1
    for frame, frames_durable, results_durable in counts:
        assert frame + 1 - frames_durable <= most_waiting, (frame, frames_durable)
        assert frame + 1 - results_durable <= most_waiting, (frame, results_durable)
    frames_durable = max(durable for _, durable, _ in counts)
    results_durable = max(durable for _, _, durable in counts)
    assert frames_durable > 60 and results_durable > 60, "the child wrote too little to test anything"

    frames = {f.index: f for f in McapSource(path)}
    assert set(range(frames_durable)) <= set(frames), sorted(set(range(frames_durable)) - set(frames))
    assert all(int(frames[i].image[0, 0]) == i % 256 for i in frames)
    results = {r.frame_index: r for r in read_results(path)}          # each frame's results, written after it
    assert set(range(results_durable)) <= set(results), sorted(set(range(results_durable)) - set(results))
    assert all(r.point_id.tolist() == [i] and r.u.tolist() == [0.5] for i, r in results.items())
    assert set(results) <= set(frames)                                   # results never ahead of their frames
    info = inspect_recording(path)
    assert info.truncated and "truncated" in info.note
    summary = recover(path, fixed)
    assert summary["truncated"] and summary["frames"] == len(frames)
    assert inspect_recording(fixed).indexed
    assert [f.index for f in McapSource(fixed)] == sorted(frames)
    print(f"SIGKILL: {len(counts)} frames written, {frames_durable} counted durable, {len(frames)} frames and "
          f"{len(results)} results recovered; the background flush wrote the idle spell's frames in {idle[0][1]:.2f} s")


# ----------------------------------------------------------------------------- disk full

_FULL_CHILD = """
    import json, resource, signal, sys
    import numpy as np
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder

    path, limit, dt, flush = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)           # get EFBIG instead of being killed
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    calls, raised, results = [], [], []
    def on_error(message):                                  # a callback may close the recorder
        calls.append(message)
        rec.close()
    rec = Recorder(path, {"source_uri": "test://full"}, on_error=on_error, chunk_bytes=64 << 10,
                   flush_interval_s=flush)
    clock = [0.0]
    rec._cw.clock = lambda: clock[0]                        # one frame every dt seconds, whatever the machine
    for i in range(120):
        clock[0] += dt
        image = np.full((128, 256), i % 251, np.uint8)
        try:
            results.append(rec.write_frame(Frame(i, 10**18 + i, image, "Mono8")))
            rec.write_results(i, 10**18 + i, [0], [1.0], [1.0], [0.0], [0.0], [1.0], [True])
            rec.write_event("note", f"frame {i}")
        except Exception as error:
            raised.append(repr(error))
    rec.flush()
    rec.close()
    print(json.dumps({"error": rec.error, "calls": calls, "raised": raised, "accepted": sum(results),
                      "written": rec.frames_written, "durable": rec.frames_durable, "dropped": rec.frames_dropped,
                      "results_written": rec.results_written, "results_durable": rec.results_durable,
                      "results_dropped": rec.results_dropped}))
"""


def test_disk_full_stops_recording_cleanly(tmp_path):
    """The file may grow to 1 MB: ~30 frames of 32 KiB. Frames come every dt = 0.25 s of the recorder's
    clock (driven by the child) and flush_interval_s = 1 s, so data waits at most 4 frames: when the
    disk fills, the results on disk lag the durable frames by at most flush_interval_s / dt + 1 = 5
    frames (the results of the frames written within flush_interval_s before the failure, which were
    still waiting in memory, are lost with the chunk that could not be written)."""
    path, fixed = tmp_path / "full.mcap", tmp_path / "fixed.mcap"
    dt, flush = 0.25, 1.0
    child = _run_child(_FULL_CHILD, path, 1_000_000, dt, flush)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 0, stderr
    report = json.loads(stdout.strip().splitlines()[-1])
    assert report["raised"] == []
    error = report["error"]
    assert error and "\n" not in error and "File too large" in error and str(path) in error
    assert report["calls"] == [error]
    assert 0 < report["durable"] <= report["accepted"] == report["written"] < 120
    assert report["dropped"] == 120 - report["accepted"]                 # every call counted once
    assert report["results_dropped"] == 120 - report["results_written"] > 0
    assert os.path.getsize(path) <= 1_000_000

    frames = list(McapSource(path))       # a chunk whose index records failed is still readable: >=
    assert report["durable"] <= len(frames) <= report["accepted"]
    assert [f.index for f in frames] == list(range(len(frames)))
    assert all(int(f.image[0, 0]) == f.index % 251 for f in frames)
    results = [r.frame_index for r in read_results(path)]
    assert results == list(range(len(results)))
    assert report["results_durable"] <= len(results) <= report["durable"]  # results follow their frames
    lag = round(flush / dt) + 1
    assert report["durable"] - len(results) <= lag, (report, len(results))
    assert read_session(path)["source_uri"] == "test://full"
    assert recover(path, fixed)["frames"] == len(frames)
    print(f"disk full: {report['accepted']} frames accepted, {report['durable']} durable, {len(frames)} read back, "
          f"{len(results)} results read back (bound: >= {report['durable'] - lag}); {error}")
