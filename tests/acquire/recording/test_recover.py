"""Tests of acquire/recording/recover.py: a cut or damaged recording rewritten complete and indexed, or refused."""

import os
import struct

import pytest
from mcap.reader import make_reader

from livedic.acquire.atomic_file import OutputError
from livedic.acquire.recording import schema as rs
from livedic.acquire.recording.errors import NotMcap, RecordingError, RecordingSourceError
from livedic.acquire.recording.reader import inspect_recording, read_events, read_results, read_session
from livedic.acquire.recording.recover import recover
from livedic.acquire.recording.source import McapSource
from tests.acquire.recording.recordings import one_line_error, record


def _metadata(path, name):
    with open(path, "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}.get(name)


def test_recover_rewrites_a_complete_indexed_file(tmp_path, recording):
    path, images = recording
    cut, fixed = tmp_path / "cut.mcap", tmp_path / "fixed.mcap"
    data = path.read_bytes()
    # 80 % into the data section (the footer's summary_start ends it), wherever the summary's size puts it
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 4 - 8 - 8)[0]
    cut.write_bytes(data[:int(summary_start * 0.8)])
    expected = [f.index for f in McapSource(cut)]
    summary = recover(cut, fixed)
    assert summary["truncated"] and summary["frames"] == len(expected) and summary["dst"] == str(fixed)
    assert "truncated" in summary["note"]
    info = inspect_recording(fixed)
    assert info.indexed and not info.truncated and info.note == ""
    assert [f.index for f in McapSource(fixed)] == expected
    assert read_session(fixed) == read_session(path)
    assert len(read_results(fixed)) == summary["results"]

    before = fixed.read_bytes()
    assert "already exists" in one_line_error(lambda: recover(cut, fixed))
    assert fixed.read_bytes() == before
    assert "source itself" in one_line_error(lambda: recover(cut, cut))
    assert recover(cut, fixed, overwrite=True)["frames"] == len(expected)
    assert sorted(os.listdir(tmp_path)) == ["cut.mcap", "fixed.mcap"]          # no temporary file left


def test_recover_skips_a_corrupt_chunk_that_strict_readers_reject(tmp_path):
    """1 KiB chunks: each 32x32 frame closes its own image chunk, the results share one data chunk.
    Corrupting frame 1 loses frame 1 only."""
    path, fixed = tmp_path / "bad.mcap", tmp_path / "fixed.mcap"
    record(path, n=5, shape=(32, 32), chunk_bytes=1024)
    data = bytearray(path.read_bytes())
    summary_start = struct.unpack_from("<Q", data, len(data) - 8 - 20)[0]     # the footer's first field
    data = data[:summary_start]                          # drop the summary: force the recovery scan
    second_image = data.find(b"mono8", data.find(b"mono8") + 1)
    data[second_image + 100] ^= 0x55                     # inside frame 1's pixels
    path.write_bytes(bytes(data))
    message = one_line_error(lambda: list(McapSource(path)), RecordingSourceError)
    assert "corrupt" in message and "recover" in message
    summary = recover(path, fixed)
    assert summary["corrupt_chunks"] == 1
    assert [f.index for f in McapSource(fixed)] == [0, 2, 3, 4]
    assert [r.frame_index for r in read_results(fixed)] == [0, 1, 2, 3, 4]


def test_a_complete_recording_is_copied_whole_with_a_recovery_record(tmp_path, recording):
    path, images = recording
    fixed = tmp_path / "copy.mcap"
    summary = recover(path, fixed, compression="lz4")
    assert not summary["truncated"] and summary["note"] == "" and summary["corrupt_chunks"] == 0
    assert summary["frames"] == len(images) and summary["results"] == len(images) and summary["events"] == 1
    assert summary["messages"] == sum(summary["message_counts"].values()) and summary["skipped_messages"] == 0
    assert summary["valid_bytes"] <= summary["src_bytes"] == os.path.getsize(path)
    assert [f.image.tolist() for f in McapSource(fixed)] == [image.tolist() for image in images]
    assert [e.message for e in read_events(fixed)] == [e.message for e in read_events(path)]
    recovery = _metadata(fixed, rs.RECOVERY_METADATA_NAME)
    assert recovery["source"] == os.path.abspath(path) and recovery["truncated"] == "false"
    assert recovery["messages"] == str(summary["messages"]) and recovery["recovered_at"]
    assert _metadata(fixed, rs.METADATA_NAME) == _metadata(path, rs.METADATA_NAME)


def test_recover_of_a_recovered_file_keeps_every_message(tmp_path, recording):
    path, _ = recording
    once, twice = tmp_path / "once.mcap", tmp_path / "twice.mcap"
    first, second = recover(path, once), recover(once, twice)
    assert second["message_counts"] == first["message_counts"]
    assert [r.frame_index for r in read_results(twice)] == [r.frame_index for r in read_results(path)]


def test_bad_sources_and_destinations_are_refused_and_nothing_is_written(tmp_path, recording):
    path, _ = recording
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap at all")
    assert "junk.mcap" in one_line_error(lambda: recover(junk, tmp_path / "out.mcap"), NotMcap)
    one_line_error(lambda: recover(tmp_path / "missing.mcap", tmp_path / "out.mcap"))
    with pytest.raises(OutputError):
        recover(path, tmp_path / "no-such-folder" / "out.mcap")
    with pytest.raises((OutputError, RecordingError)):
        recover(path, tmp_path)                                      # a folder
    assert sorted(p.name for p in tmp_path.iterdir()) == ["junk.mcap"]
