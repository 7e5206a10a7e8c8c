"""Tests of acquire/recording/source.py: McapSource replays a recording's frames; FrameReader reads one by its key."""

import time

import numpy as np
import pytest

from livedic.acquire.base import Frame, SourceError
from livedic.acquire.recording.errors import CorruptRecording, RecordingError, RecordingSourceError
from livedic.acquire.recording.source import FrameReader, McapSource
from livedic.acquire.recording.writer import Recorder
from tests.acquire.recording.recordings import T0, one_line_error, record


# ----------------------------------------------------------------------------- McapSource

def test_replay_as_fast_as_possible_gives_every_frame_in_order(recording):
    path, images = recording
    with McapSource(path) as source:
        assert source.settings["recorded_source_uri"] == "synthetic://"
        frames = list(source)
    assert [f.index for f in frames] == list(range(len(images)))
    assert all(np.array_equal(f.image, im) for f, im in zip(frames, images))
    assert all(isinstance(f, Frame) and f.pixel_format == "Mono8" for f in frames)


def test_realtime_replay_follows_the_recorded_pace(tmp_path, monkeypatch):
    import livedic.acquire.recording.source as mcap_source
    waits = []
    real_sleep = time.sleep

    def sleep(seconds):
        waits.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(mcap_source.time, "sleep", sleep)
    path = tmp_path / "paced.mcap"
    record(path, n=6, dt_ns=60_000_000)                   # 5 gaps of 60 ms
    arrivals = []
    start = time.monotonic()
    for frame in McapSource(path, realtime=True):
        arrivals.append((frame.index, time.monotonic() - start))
    assert [i for i, _ in arrivals] == list(range(6))
    assert arrivals[-1][1] >= 0.8 * 0.3                    # loose: never faster than recorded
    assert waits
    waits.clear()
    assert [f.index for f in McapSource(path)] == list(range(6))
    assert waits == []                                     # and the fast mode never waits (counted, not timed)


def test_close_stops_iteration(recording):
    path, _ = recording
    source = McapSource(path)
    seen = []
    for frame in source:
        seen.append(frame.index)
        source.close()
    assert seen == [0]


def test_frame_info_gives_back_index_pixel_format_and_metadata(tmp_path):
    path = tmp_path / "info.mcap"
    image = np.arange(12, dtype=np.uint16).reshape(3, 4)
    with Recorder(path, {"source_uri": "gige://x", "start_time": "today"}) as rec:
        rec.write_frame(Frame(2**32 + 5, T0, image, "Mono12", metadata={"exposure_us": 800.0, "gain": [1, 2]}))
        rec.write_frame(Frame(7, T0 + 10, image, "Mono16"))
    source = McapSource(path)
    first, second = list(source)
    assert (first.index, first.pixel_format, first.metadata) == (2**32 + 5, "Mono12",
                                                                 {"exposure_us": 800.0, "gain": [1, 2]})
    assert (second.index, second.pixel_format, second.metadata) == (7, "Mono16", {})
    assert np.array_equal(first.image, image) and not first.image.flags.writeable
    assert source.session["start_time"] == "today" and source.uri == f"mcap:{path}"
    assert source.settings == {"kind": "mcap_replay", "path": str(path), "realtime": False,
                               "recorded_source_uri": "gige://x", "recorded_start_time": "today"}
    assert not source.live and McapSource(path, realtime=True).live


def test_not_a_recording_is_a_source_error_of_one_line(tmp_path):
    path = tmp_path / "text.mcap"
    path.write_text("hello")
    message = one_line_error(lambda: McapSource(path), RecordingSourceError)
    assert str(path) in message
    assert isinstance(pytest.raises(RecordingSourceError, McapSource, path).value, SourceError)


def test_a_stereo_recording_gives_each_view_its_own_frames_and_a_2d_reader_the_left(tmp_path, recording):
    """Both cameras' frames interleaved in one file come back per view, bit for bit and in order (the right
    view's 16-bit frames with their own pixel format and metadata); a 2D reader sees the left view; asking a 2D
    recording for its right view is one line; a 2D recorder refuses a right frame."""
    path = tmp_path / "stereo.mcap"
    rng = np.random.default_rng(3)
    left = [rng.integers(0, 255, (5, 6), dtype=np.uint8) for _ in range(4)]
    right = [rng.integers(0, 4095, (5, 6), dtype=np.uint16) for _ in range(4)]
    with Recorder(path, {"source_uri": "stereo:a,b"}, stereo=True) as rec:
        for k in range(4):
            assert rec.write_frame(Frame(k, T0 + 10 * k, left[k], "Mono8"))
            assert rec.write_frame(Frame(k, T0 + 10 * k + 1, right[k], "Mono12", metadata={"view": "right"}),
                                   view="right")
        assert (rec.frames_written, rec.right_frames_written) == (4, 4)
    got_left, got_right = list(McapSource(path)), list(McapSource(path, view="right"))
    assert [f.index for f in got_left] == [f.index for f in got_right] == [0, 1, 2, 3]
    assert all(np.array_equal(f.image, im) for f, im in zip(got_left, left))
    assert all(np.array_equal(f.image, im) and f.pixel_format == "Mono12" and f.metadata == {"view": "right"}
               for f, im in zip(got_right, right))
    assert [f.timestamp_ns for f in got_right] == [T0 + 10 * k + 1 for k in range(4)]
    assert McapSource(path, view="right").uri == f"mcap:{path}?view=right"
    message = one_line_error(lambda: McapSource(recording[0], view="right"), RecordingSourceError)
    assert "no right view (/camera/right/image)" in message
    with Recorder(tmp_path / "mono.mcap", {}) as rec, pytest.raises(ValueError, match="stereo=True"):
        rec.write_frame(Frame(0, T0, left[0], "Mono8"), view="right")


# ----------------------------------------------------------------------------- FrameReader

def test_frame_reader_reads_any_frame_as_the_source_gives_it(recording, tmp_path):
    path, _ = recording
    frames = list(McapSource(path))
    reader = FrameReader(path)
    for frame in reversed(frames):
        assert np.array_equal(reader.image(frame.index, frame.timestamp_ns), frame.image)
    with pytest.raises(RecordingError, match="holds no image of frame 99"):
        reader.image(99, frames[-1].timestamp_ns + 1)
    cut = tmp_path / "cut.mcap"
    data = open(path, "rb").read()
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(RecordingError, match="has no index"):
        FrameReader(cut)


def test_frame_reader_reads_a_chunk_once_for_the_frames_it_holds(tmp_path):
    path = tmp_path / "big-chunks.mcap"
    images = record(path, n=5, shape=(8, 8))                           # 1 MiB chunks: every frame in one
    reader = FrameReader(path)
    for i in (3, 0, 4, 1):
        assert np.array_equal(reader.image(i, T0 + i * 20_000_000), images[i])
    assert reader.chunks_read == 1 and reader.path == str(path)


def test_frame_reader_tells_a_damaged_chunk(tmp_path):
    path = tmp_path / "bad.mcap"
    record(path, n=3, shape=(32, 32), chunk_bytes=1024)
    data = bytearray(path.read_bytes())
    second = data.find(b"mono8", data.find(b"mono8") + 1)
    data[second + 100] ^= 0x55                                         # inside frame 1's pixels
    path.write_bytes(bytes(data))
    reader = FrameReader(path)
    assert reader.image(0, T0).shape == (32, 32)
    with pytest.raises(CorruptRecording, match="corrupt"):
        reader.image(1, T0 + 20_000_000)
