"""Tests of stream/export/notes.py: the reader's notes as lines, the session metadata or a note, plural words."""

import logging

import pytest

from livedic.stream.export.notes import plural, read_session_or_note, reader_notes, say


def test_reader_notes_are_collected_once_each_without_the_prefix_and_not_printed(caplog):
    logger = logging.getLogger("livedic.acquire.recording.reader")
    with caplog.at_level(logging.INFO), reader_notes() as notes:
        logger.info("note: the file is truncated")
        logger.warning("note: the file is truncated")
        logger.info("another thing")
    assert notes == ["the file is truncated", "another thing"]
    assert caplog.records == []                          # collected, not propagated to the root logger
    logger.info("note: after")
    assert notes == ["the file is truncated", "another thing"] and logger.propagate


def test_plural():
    assert [plural(n, "frame") for n in (0, 1, 2)] == ["0 frames", "1 frame", "2 frames"]


def test_say_is_one_livedic_line_on_stderr(capsys):
    say("exported 3 frames")
    captured = capsys.readouterr()
    assert captured.err == "livedic: exported 3 frames\n" and captured.out == ""


def test_the_session_metadata_or_a_note_of_its_absence(tmp_path):
    import numpy as np
    from livedic.acquire.base import Frame
    from livedic.acquire.recording import schema as rs
    from livedic.acquire.recording import wire
    from livedic.acquire.recording.chunked_writer import ChunkedWriter
    from livedic.acquire.recording.writer import Recorder
    path = tmp_path / "with.mcap"
    with Recorder(str(path), {"command": "test", "subset": 21}, start_time_ns=0) as recorder:
        recorder.write_frame(Frame(0, 0, np.zeros((8, 8), np.uint8), "Mono8"))
    session, note = read_session_or_note(path)
    assert (session["command"], session["subset"], note) == ("test", 21, "")
    bare = tmp_path / "bare.mcap"
    with open(bare, "wb") as handle:
        writer = ChunkedWriter(handle, chunk_bytes=1 << 20, compression=None, library="livedic/test")
        image = writer.register(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA, rs.schema_data(rs.RAW_IMAGE_SCHEMA))
        writer.add("image", image, 5, wire.encode_raw_image(np.zeros((4, 6), np.uint8), 5))
        writer.finish()
    session, note = read_session_or_note(bare)
    assert session == {} and note.endswith("has no session metadata (livedic.session)")


def test_not_a_recording_is_a_recording_error(tmp_path):
    from livedic.acquire.recording.errors import RecordingError
    path = tmp_path / "not.mcap"
    path.write_text("hello")
    with pytest.raises(RecordingError):
        read_session_or_note(path)
