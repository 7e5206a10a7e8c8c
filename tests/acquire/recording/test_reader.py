"""Reading recordings: replay, truncated files, bad input, fuzzing (recover() is tests/.../test_recover.py's)."""

import faulthandler
import os
import signal
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.base import Frame, SourceError
from livedic.acquire.recording.chunked_writer import ChunkedWriter
from livedic.acquire.recording.errors import (CorruptRecording, NoSessionMetadata, NotLivedic, NotMcap, RecordingError,
                                              RecordingSourceError)
from livedic.acquire.recording.reader import (Recording, inspect_recording, iter_results, read_events,
                                              read_extensometer_samples, read_results, read_session, read_strain_fields)
from livedic.acquire.recording.recover import recover
from livedic.acquire.recording.source import McapSource
from livedic.dic.result import Measurement
from livedic.acquire.recording.writer import Recorder
from tests.acquire.recording.recordings import T0, one_line_error, record



@pytest.fixture(autouse=True)
def _hang_guard():
    """Every test here is bounded: a hang dumps the stacks and ends the run after 60 s."""
    faulthandler.dump_traceback_later(60, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


def _plain_mcap(path):
    from mcap.writer import Writer
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="some-robot")
        schema = writer.register_schema("pose", "jsonschema", b"{}")
        channel = writer.register_channel("/robot/pose", "json", schema)
        for i in range(3):
            writer.add_message(channel, log_time=i, data=b'{"x": 1}', publish_time=i)
        writer.finish()


# ----------------------------------------------------------------------------- reading

def test_results_events_and_session(recording):
    path, _ = recording
    results = read_results(path)
    assert [r.frame_index for r in results] == list(range(6))
    assert np.array_equal(results[3].u, [0.30000000000000004, 0.0]) and results[3].ok.tolist() == [True, False]
    assert [r.frame_index for r in iter_results(path)] == list(range(6))
    assert [(e.kind, e.message) for e in read_events(path)] == [("recording_stopped", "end of test")]
    assert read_session(path)["points"] == [[1, 2]]


def test_read_results_uses_the_index_and_skips_image_chunks(tmp_path):
    """Corrupt an image chunk of an indexed file: results still read (never touched), replay reports it."""
    path = tmp_path / "r.mcap"
    record(path, n=4, shape=(64, 64))
    data = bytearray(path.read_bytes())
    third = -1
    for _ in range(3):                                    # the third RawImage's encoding string ...
        third = data.find(b"mono8", third + 1)
    data[third + 100] ^= 0xFF                             # ... is followed by its pixels
    path.write_bytes(bytes(data))
    assert len(read_results(path)) == 4
    message = one_line_error(lambda: list(McapSource(path)), RecordingSourceError)
    assert str(path) in message and "corrupt" in message and "CRC" in message


# ----------------------------------------------------------------------------- truncated / recover

@pytest.mark.parametrize("keep", [0.7, 0.5, 0.25])
def test_truncated_file_reads_with_a_note(tmp_path, recording, caplog, keep):
    path, images = recording
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[:int(len(data) * keep)])
    frames = list(McapSource(cut))
    assert [f.index for f in frames] == list(range(len(frames)))
    assert all(np.array_equal(f.image, images[f.index]) for f in frames)
    assert f"{cut} is truncated (the recording did not finish" in caplog.text
    info = inspect_recording(cut)
    assert info.truncated and not info.indexed and info.frames == len(frames)
    assert read_session(cut)["source_uri"] == "synthetic://"
    results = read_results(cut)
    assert [r.frame_index for r in results] == list(range(len(results)))
    assert len(results) <= len(frames)                     # results are written after their frames
    if keep >= 0.5:
        assert len(frames) >= 3 and len(results) >= 3


def test_lost_index_only_is_a_note_and_loses_nothing(tmp_path, recording, caplog):
    path, images = recording
    cut = tmp_path / "noindex.mcap"
    cut.write_bytes(path.read_bytes()[:-50])              # footer and the end of the summary gone
    assert len(list(McapSource(cut))) == len(images)
    assert "no index" in caplog.text and "record by record" in caplog.text
    info = inspect_recording(cut)
    assert not info.truncated and not info.indexed and "no index" in info.note


def test_truncation_is_a_field_of_the_reader(tmp_path, recording):
    """Callers learn that a recording was cut short from ``RecordingInfo.truncated``, not from a note's text."""
    path, _ = recording
    cut = tmp_path / "cut.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[:int(len(data) * 0.7)])
    for name, truncated in ((path, False), (cut, True)):
        reader = Recording(name)
        results = list(reader.results())
        assert results and reader.info.truncated is truncated and reader.info.indexed is not truncated
        source = McapSource(name)
        assert list(source) and source.info.truncated is truncated


def test_zero_filled_tail_ends_the_scan_where_the_data_ends(tmp_path, recording):
    """Blocks never written before a crash read as zeros: the scan stops at the first one, at once."""
    path, _ = recording
    cut, zeros = tmp_path / "cut.mcap", tmp_path / "zeros.mcap"
    data = path.read_bytes()
    cut.write_bytes(data[:int(len(data) * 0.7)])
    want = inspect_recording(cut)
    zeros.write_bytes(data[:want.valid_bytes] + bytes(4 << 20))           # zeros from the first cut record on
    got = inspect_recording(zeros)
    assert got.truncated and got.frames == want.frames and got.valid_bytes == want.valid_bytes
    assert [f.index for f in McapSource(zeros)] == [f.index for f in McapSource(cut)]


def test_recorded_results_carry_the_measurement(recording):
    path, _ = recording
    result = read_results(path)[2]
    assert isinstance(result.measurement, Measurement) and result.measurement.evaluations is None
    for name in ("x", "y", "u", "v", "zncc", "ok", "status", "ux", "iterations"):
        assert getattr(result, name) is getattr(result.measurement, name)
    assert result.u.tolist() == [0.2, 0.0] and result.ok.tolist() == [True, False] and result.status is None


def _chunks(path):
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)


@pytest.mark.parametrize("compression", [None, "lz4", "zstd"])
def test_a_chunk_is_never_decompressed_beyond_what_it_claims(tmp_path, compression):
    """A chunk's uncompressed size is the most the reader allocates for it: over 1 GiB is refused unread,
    and a chunk that holds more than it claims is corrupt (its CRC is zeroed so only the size can tell)."""
    if compression == "zstd":
        pytest.importorskip("zstandard")
    path = tmp_path / "ok.mcap"
    images = [np.full((32, 32), i, np.uint8) for i in range(3)]
    with Recorder(path, {}, compression=compression, chunk_bytes=512) as rec:
        for i, image in enumerate(images):
            rec.write_frame(Frame(i, T0 + i, image, "Mono8"))
    assert [int(f.image[0, 0]) for f in McapSource(path)] == [0, 1, 2]
    second_image_chunk = _chunks(path)[2].chunk_start_offset     # the session chunk, then one per frame
    size_at = second_image_chunk + 9 + 16                        # opcode, length, start and end times
    for claim, expected in ((5 << 30, "claims 5368709120 uncompressed bytes"), (None, "")):
        data = bytearray(path.read_bytes())
        usize = struct.unpack_from("<Q", data, size_at)[0]
        struct.pack_into("<QI", data, size_at, usize - 8 if claim is None else claim, 0)
        bad = tmp_path / f"bad-{claim}.mcap"
        bad.write_bytes(bytes(data))
        message = one_line_error(lambda: list(McapSource(bad)), RecordingSourceError)
        assert "corrupt" in message and expected in message
        assert isinstance(pytest.raises(RecordingSourceError, lambda: list(McapSource(bad))).value.__cause__,
                          CorruptRecording)


def _without_session(path):
    """A file with livedic's image channel and one frame but no session metadata."""
    with open(path, "wb") as f:
        writer = ChunkedWriter(f, chunk_bytes=1 << 20, compression=None, library="livedic/test")
        channel = writer.register(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA, rs.schema_data(rs.RAW_IMAGE_SCHEMA))
        writer.add("image", channel, T0, wire.encode_raw_image(np.zeros((4, 6), np.uint8), T0))
        writer.finish()


def test_each_problem_has_its_exception_type(tmp_path, recording):
    """What a caller acts on is the type (all RecordingError, one line); McapSource keeps it as the cause."""
    (tmp_path / "empty.mcap").write_bytes(b"")
    (tmp_path / "text.mcap").write_bytes(b"frame,u,v\n")
    _plain_mcap(tmp_path / "robot.mcap")
    _without_session(tmp_path / "nosession.mcap")
    data = recording[0].read_bytes()
    bad = bytearray(data[:_chunks(recording[0])[1].chunk_start_offset + 200])  # cut inside the first image chunk
    bad[-150] ^= 0xFF
    (tmp_path / "corrupt.mcap").write_bytes(bytes(data[:len(bad) - 200]) + bytes(bad[-200:]) + data[len(bad):])
    cases = {"empty.mcap": NotMcap, "text.mcap": NotMcap, "robot.mcap": NotLivedic,
             "nosession.mcap": NoSessionMetadata}
    for name, error_type in cases.items():
        one_line_error(lambda: read_session(tmp_path / name), error_type)
    assert one_line_error(lambda: read_session(tmp_path / "nosession.mcap")).endswith(
        "has no session metadata (livedic.session)")
    assert [f.image.shape for f in McapSource(tmp_path / "nosession.mcap")] == [(4, 6)]
    one_line_error(lambda: list(McapSource(tmp_path / "corrupt.mcap")), RecordingSourceError)
    for name, error_type in {"robot.mcap": NotLivedic, "empty.mcap": NotMcap}.items():
        caught = pytest.raises(RecordingSourceError, McapSource, tmp_path / name).value
        assert isinstance(caught, SourceError) and isinstance(caught.__cause__, error_type)
    assert isinstance(pytest.raises(RecordingSourceError, lambda: list(McapSource(tmp_path / "corrupt.mcap")))
                      .value.__cause__, CorruptRecording)


# ----------------------------------------------------------------------------- bad input

def test_bad_inputs_give_one_clean_line(tmp_path, recording):
    good = recording[0].read_bytes()
    cases = {
        "missing.mcap": None,
        "empty.mcap": b"",
        "random.mcap": np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes(),
        "magic_only.mcap": good[:8],
        "header_cut.mcap": good[:20],
        "text.mcap": b"hello, I am a CSV file\n1,2,3\n",
    }
    expected = {"missing.mcap": "does not exist", "empty.mcap": "empty", "random.mcap": "not an MCAP file",
                "magic_only.mcap": "truncated inside the MCAP header", "header_cut.mcap": "truncated inside",
                "text.mcap": "not an MCAP file"}
    for name, content in cases.items():
        path = tmp_path / name
        if content is not None:
            path.write_bytes(content)
        for reader in (read_session, read_results, read_events, inspect_recording,
                       lambda p: recover(p, tmp_path / "out.mcap")):
            message = one_line_error(lambda: reader(path))
            assert str(path) in message and expected[name] in message, message
        message = one_line_error(lambda: McapSource(path), RecordingSourceError)
        assert expected[name] in message
    assert "directory" in one_line_error(lambda: read_session(tmp_path))


def test_mcap_from_another_program_is_named_as_such(tmp_path):
    path = tmp_path / "x.mcap"
    _plain_mcap(path)
    message = one_line_error(lambda: McapSource(path), SourceError)
    assert message == f"{path} was not written by livedic (no /camera/image RawImage channel)"
    for reader in (read_session, read_results, read_events):
        assert one_line_error(lambda: reader(path)) == message
    assert isinstance(pytest.raises(ValueError, McapSource, path).value, SourceError)
    assert inspect_recording(path).message_counts == {"/robot/pose": 3}   # still inspectable


# ----------------------------------------------------------------------------- fuzz

def test_huge_lengths_at_every_record_start_fail_cleanly(tmp_path):
    """The length fields hypothesis rarely hits: every 8- and 4-byte field in the first 64 bytes of every
    record (chunk headers and the records inside uncompressed chunks among them) set to its maximum."""
    from mcap.opcode import Opcode

    from livedic.acquire.recording.container import RecordScan
    path = tmp_path / "small.mcap"
    record(path, n=2, shape=(4, 4), chunk_bytes=64)
    data = path.read_bytes()
    with open(path, "rb") as f:
        starts = [offset for offset, opcode, _ in RecordScan(f, 8, len(data))
                  if opcode != Opcode.MESSAGE_INDEX]                   # the readers never read those
    fuzzed = tmp_path / "huge.mcap"
    for start in starts:
        for at in range(start + 1, min(start + 64, len(data) - 8)):
            for width, value in ((8, 2**64 - 1), (4, 2**32 - 1)):
                raw = bytearray(data)
                raw[at:at + width] = value.to_bytes(width, "little")
                fuzzed.write_bytes(bytes(raw))
                for call in (read_session, inspect_recording,           # every record path, strict ...
                             lambda p: list(Recording(p).records(strict=False))):        # ... and as recover
                    try:
                        call(fuzzed)
                    except RecordingError:
                        pass



class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang("reader took more than 5 s")


def _exercise(path, tmp_dir):
    """Every public reader on ``path``; only RecordingError may come out."""
    for call in (lambda: list(McapSource(path)), lambda: read_results(path), lambda: read_events(path),
                 lambda: read_session(path), lambda: inspect_recording(path), lambda: read_strain_fields(path),
                 lambda: read_extensometer_samples(path),
                 lambda: recover(path, tmp_dir / "fuzz_out.mcap", overwrite=True)):
        try:
            call()
        except RecordingError:
            pass


@pytest.fixture(scope="module")
def fuzz_bases(tmp_path_factory):
    base = tmp_path_factory.mktemp("fuzz")
    variants = []
    for compression in (None, "lz4"):
        complete = base / f"complete-{compression}.mcap"
        record(complete, n=3, shape=(6, 8), chunk_bytes=256, compression=compression, with_strain=True)
        data = complete.read_bytes()
        variants += [data, data[:int(len(data) * 0.7)]]      # indexed and truncated variants
    return base, variants


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.integers(0, 3), data=st.data())
def test_fuzzed_recordings_fail_cleanly(fuzz_bases, which, data):
    base, variants = fuzz_bases
    raw = bytearray(variants[which])
    for _ in range(data.draw(st.integers(1, 4), label="mutations")):
        kind = data.draw(st.sampled_from(["flip", "byte", "cut", "insert", "delete", "length", "length32"]),
                         label="kind")
        at = data.draw(st.integers(0, max(len(raw) - 1, 0)), label="at")
        if kind == "flip" and raw:
            raw[at] ^= 1 << data.draw(st.integers(0, 7))
        elif kind == "byte" and raw:
            raw[at] = data.draw(st.integers(0, 255))
        elif kind == "cut":
            del raw[at:]
        elif kind == "insert":
            raw[at:at] = data.draw(st.binary(min_size=1, max_size=16))
        elif kind == "delete":
            del raw[at:at + data.draw(st.integers(1, 64))]
        elif kind == "length" and len(raw) >= at + 8:       # a huge or odd record length field
            raw[at:at + 8] = struct.pack("<Q", data.draw(st.sampled_from([0, 1, 2**31, 2**33, 2**63, 2**64 - 1])))
        elif kind == "length32" and len(raw) >= at + 4:     # a string, map or array length field
            raw[at:at + 4] = struct.pack("<I", data.draw(st.sampled_from([0, 1, 2**31, 2**32 - 1])))
    path = base / "fuzzed.mcap"
    path.write_bytes(bytes(raw))
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, 5.0)
    try:
        _exercise(path, base)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
