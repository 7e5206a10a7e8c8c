"""``livedic replay`` and ``livedic export``: exact replay, other methods, dropped frames, truncated files,
the CSV files, bad input, and the sample shipped in recordings/."""

import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest

from livedic.stream.session.config import DEFAULT_STATIC_FRAMES
from livedic.acquire.recording.reader import read_results, read_session
from livedic.stream.cli import main

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SAMPLE = os.path.join(REPO, "recordings", "sample-tensile.mcap")
LEADING = ["frame", "timestamp_ns", "point_id", "x", "y", "u", "v", "zncc", "ok"]


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A small session recorded by ``livedic run`` in-process (unpaced: every frame tracked)."""
    path = tmp_path_factory.mktemp("session") / "session.mcap"
    code = main(["run", "--source", "synthetic:tensile?size=128x256&frames=12&noise=0.5&pace=0",
                 "--record", str(path), "--viewer", "none", "--n-points", "60", "--progress", "off"])
    assert code == 0 and path.exists()
    return str(path)


@pytest.fixture(scope="module")
def killed(tmp_path_factory):
    """A recording by ``livedic run`` cut short as a kill during a write leaves it.

    The run is paced (10 static frames and 30 of the test at 25 fps, 1.6 s), so the recorder writes its chunks
    as a live session does: images when a chunk fills or ages, results together every ``flush_interval_s``
    (0.25 s), not with every frame. The file is then cut in the middle of its last image chunk: every chunk before
    the cut (several data chunks among them) is whole, the results written after it are lost."""
    from mcap.reader import make_reader

    folder = tmp_path_factory.mktemp("killed")
    path = folder / "paced.mcap"
    code = main(["run", "--source", "synthetic:tensile?size=128x256&frames=30&fps=25&noise=0.5",
                 "--record", str(path), "--viewer", "none", "--n-points", "60", "--progress", "off"])
    assert code == 0
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    image_ids = {cid for cid, ch in summary.channels.items() if ch.topic == "/camera/image"}
    last = max((c for c in summary.chunk_indexes if set(c.message_index_offsets) & image_ids),
               key=lambda c: c.chunk_start_offset)
    cut = folder / "killed.mcap"
    cut.write_bytes(path.read_bytes()[:last.chunk_start_offset + last.chunk_length // 2])
    return str(path), str(cut)


@pytest.fixture(scope="module")
def dropped(tmp_path_factory):
    """A recording whose live run 'dropped' frames 3, 6 and 7: all images, results only for the others."""
    from livedic.dic.speckle import SpecklePattern, render
    from livedic.dic.tracking import Tracker
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder
    from livedic.stream.session.points import build_points

    path = tmp_path_factory.mktemp("dropped") / "dropped.mcap"
    pattern = SpecklePattern((128, 160), n_speckles=400, seed=3)
    images = [render(pattern, (0.3 * i, -0.2 * i), noise_sigma=0.5, noise_seed=i) for i in range(10)]
    params = {"subset": 21, "search": "improved-wso", "subpixel": "icgn", "seed_radius": 2,
              "refind_radius": 16, "refind_zncc": 0.8, "seed": 0}
    metadata = dict(params, command="livedic run", source_uri="test:dropped", roi="full image", step=24,
                    n_points_wanted=30, points_file=None, p0="ROI centre", point_ids="P0 is point 0")
    points, _, _ = build_points(images[0].shape, roi=None, step=24, n_points=30, subset=21)
    tracker = Tracker(images[0], points, **params)
    tracked = [0, 1, 2, 4, 5, 8, 9]
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        for i, image in enumerate(images):
            recorder.write_frame(Frame(i, i * 20_000_000, image, "Mono8"))
            if i in tracked:
                m = tracker.track(image)
                recorder.write_results(i, i * 20_000_000, np.arange(m.u.size, dtype=np.uint32), m.x, m.y, m.u,
                                       m.v, m.zncc, m.ok, ux=m.ux, uy=m.uy, vx=m.vx, vy=m.vy,
                                       status=m.status.astype(np.int32), iterations=m.iterations,
                                       method="improved-wso+icgn", reference_frame_index=0,
                                       dropped_frames={4: 1, 8: 2}.get(i, 0))
    return str(path), tracked


def _rows(path):
    with open(path, newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


def _column(rows, name):
    return np.array([float(row[name]) for row in rows])


def _bits_equal(a, b):
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return bool(np.all((a.view(np.uint64) == b.view(np.uint64)) | (np.isnan(a) & np.isnan(b))))


def _assert_equals_recorded(rows, results):
    """The CSV rows hold exactly the recorded results, frame by frame, bit for bit."""
    frames = [int(row["frame"]) for row in rows]
    assert sorted(set(frames)) == [r.frame_index for r in results]
    for result in results:
        part = [row for row in rows if int(row["frame"]) == result.frame_index]
        assert [int(row["point_id"]) for row in part] == result.point_id.tolist()
        assert {int(row["timestamp_ns"]) for row in part} == {result.timestamp_ns}
        for name in ("x", "y", "u", "v", "zncc"):
            assert _bits_equal(_column(part, name), getattr(result, name)), (result.frame_index, name)
        assert np.array_equal(_column(part, "ok").astype(bool), result.ok)


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and "Traceback" not in err, err
    return lines[0]


# --------------------------------------------------------------------------- replay

def test_replay_with_the_recorded_parameters_equals_the_recording_bit_for_bit(recording, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "replay.csv"
    assert main(["replay", recording, "-o", str(out), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    results = read_results(recording)
    n = results[0].u.size
    assert f"replay matches the recording exactly: {len(results)} frames x {n} points" in err
    header, rows = _rows(out)
    assert header[:9] == LEADING and header[9:] == ["status", "ux", "uy", "vx", "vy", "iterations", "exx", "eyy", "exy"]
    assert len(rows) == len(results) * n
    _assert_equals_recorded(rows, results)
    # The strain recomputed on the replayed displacements is the recorded strain, bit for bit.
    from livedic.acquire.recording.reader import read_strain_fields
    recorded_eyy = np.concatenate([field.eyy for field in read_strain_fields(recording)])
    np.testing.assert_array_equal(np.array([float(row["eyy"]) for row in rows]), recorded_eyy)
    assert not [name for name in os.listdir(tmp_path) if name.startswith(".livedic-")]


def test_replay_with_another_subpixel_method_runs_and_differs(recording, capsys):
    capsys.readouterr()
    assert main(["replay", recording, "--subpixel", "gradient", "--progress", "off"]) == 0   # CSV on stdout
    captured = capsys.readouterr()
    assert "subpixel icgn -> gradient" in captured.err and "differs from the recording" in captured.err
    lines = captured.out.splitlines()
    assert lines[0].split(",")[:9] == LEADING
    rows = [dict(zip(lines[0].split(","), line.split(","))) for line in lines[1:]]
    results = read_results(recording)
    last = results[-1]
    part = [row for row in rows if int(row["frame"]) == last.frame_index]
    u, v = _column(part, "u"), _column(part, "v")
    assert len(part) == last.u.size and not _bits_equal(u, last.u)
    ok = np.isfinite(u) & np.isfinite(last.u)
    assert ok.mean() > 0.9
    assert np.median(np.abs(u[ok] - last.u[ok])) < 0.5 and np.median(np.abs(v[ok] - last.v[ok])) < 0.5


def test_replay_tracks_the_recorded_frame_set_or_every_frame(dropped, tmp_path, capsys):
    path, tracked = dropped
    capsys.readouterr()
    out = tmp_path / "replay.csv"
    assert main(["replay", path, "-o", str(out), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    assert f"replay matches the recording exactly: {len(tracked)} frames x" in err
    _, rows = _rows(out)
    _assert_equals_recorded(rows, read_results(path))
    everything = tmp_path / "all.csv"
    assert main(["replay", path, "--all-frames", "-o", str(everything), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    assert "replayed 10 frames" in err
    _, rows = _rows(everything)
    assert sorted({int(row["frame"]) for row in rows}) == list(range(10))
    assert np.mean([row["ok"] == "1" for row in rows]) > 0.95


def test_replay_of_a_truncated_recording_uses_the_recovered_frames(killed, tmp_path, capsys):
    full, half = killed
    recovered = read_results(half)
    assert 0 < len(recovered) < len(read_results(full))
    assert [r.frame_index for r in recovered] == [r.frame_index for r in read_results(full)][:len(recovered)]
    capsys.readouterr()
    out = tmp_path / "half.csv"
    assert main(["replay", half, "-o", str(out), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    assert "truncated" in err and f"replay matches the recording exactly: {len(recovered)} frames" in err
    _, rows = _rows(out)
    _assert_equals_recorded(rows, recovered)


# --------------------------------------------------------------------------- export

EXPORTED = ["events.csv", "extensometers.csv", "extensometers.png", "fields.csv", "p0_trace.csv", "session.json"]
PICTURES = ["fields.pvd", "maps", "overlay_eyy.mp4", "vtk"]     # the fields as pictures: tests/stream/export/test_field_export.py


def _file_bytes(folder):
    """Relative path -> contents of every file under ``folder``."""
    paths = [os.path.join(top, name) for top, _, names in os.walk(folder) for name in names]
    return {os.path.relpath(path, folder): Path(path).read_bytes() for path in paths}


def test_export_writes_the_six_files_and_refuses_to_overwrite(recording, tmp_path, capsys):
    target = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", recording, "-o", str(target)]) == 0
    assert sorted(os.listdir(target)) == sorted(EXPORTED + PICTURES)
    results = read_results(recording)
    n = results[0].u.size
    header, trace = _rows(target / "p0_trace.csv")
    assert header == ["frame", "timestamp_ns", "time_s", "x", "y", "u", "v", "zncc", "ok"]
    assert [int(row["frame"]) for row in trace] == [r.frame_index for r in results]
    for name in ("x", "y", "u", "v", "zncc"):       # P0 is point 0 (session metadata "P0 is point 0")
        assert _bits_equal(_column(trace, name), [getattr(r, name)[r.point_id == 0][0] for r in results])
    assert _column(trace, "time_s")[0] == 0.0
    assert np.allclose(_column(trace, "time_s"), [(r.timestamp_ns - results[0].timestamp_ns) / 1e9 for r in results])
    header, fields = _rows(target / "fields.csv")
    assert header[:9] == LEADING and len(fields) == len(results) * n
    _assert_equals_recorded(fields, results)
    header, events = _rows(target / "events.csv")
    assert header[:4] == ["time", "kind", "level", "message"] and any("P0" in row["message"] for row in events)
    session = json.loads((target / "session.json").read_text())
    recorded = read_session(recording)
    assert session["subpixel"] == recorded["subpixel"] == "icgn" and session["roi"] == recorded["roi"]
    assert session["livedic.export"]["truncated"] is False and session["livedic.export"]["p0_id"] == 0

    before = _file_bytes(target)
    capsys.readouterr()
    assert main(["export", recording, "-o", str(target)]) == 2
    assert "--overwrite" in _one_error_line(capsys.readouterr().err)
    assert _file_bytes(target) == before
    assert main(["export", recording, "-o", str(target), "--overwrite"]) == 0
    assert sorted(os.listdir(target)) == sorted(EXPORTED + PICTURES)


def test_export_of_a_truncated_recording_says_so(killed, tmp_path, capsys):
    full, half = killed
    capsys.readouterr()
    assert main(["export", half, "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "note:" in err and "truncated" in err
    session = json.loads((tmp_path / "out" / "session.json").read_text())
    assert session["livedic.export"]["truncated"] is True
    _, trace = _rows(tmp_path / "out" / "p0_trace.csv")
    recovered = read_results(half)
    assert 0 < len(trace) == len(recovered) < len(read_results(full))
    assert [int(row["frame"]) for row in trace] == [r.frame_index for r in recovered]


def test_session_json_gives_the_frames_delivered_in_the_end_not_at_the_start(tmp_path, capsys):
    """A camera's ``frames_delivered`` in the session metadata is its count when recording began (1); the
    export gives the final count, from the frames recorded, and says so; a cut recording: at least those."""
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder

    path = tmp_path / "camera.mcap"
    metadata = {"command": "livedic run", "source_uri": "aravis:Fake", "source_settings": {"frames_delivered": 1}}
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        for i in range(7):
            recorder.write_frame(Frame(i, i * 20_000_000, np.full((16, 24), i, np.uint8), "Mono8"))
    assert main(["export", str(path), "-o", str(tmp_path / "out")]) == 0
    session = json.loads((tmp_path / "out" / "session.json").read_text())
    export = session["livedic.export"]
    assert export["frames_delivered"] == 7 and export["frames_with_results"] == 0
    assert export["frames_delivered_from"].startswith("the frames in the recording (/camera/image)")
    assert session["source_settings"] == {"frames_delivered": 7, "frames_delivered_at_start": 1}


def test_session_json_of_a_cut_recording_counts_the_frames_it_kept(killed, tmp_path, capsys):
    from livedic.acquire.recording.source import McapSource
    full, half = killed
    assert main(["export", half, "-o", str(tmp_path / "out")]) == 0
    export = json.loads((tmp_path / "out" / "session.json").read_text())["livedic.export"]
    kept = sum(1 for _ in McapSource(half))
    # the test's 30 frames after the simulator's static ones
    assert 0 < export["frames_delivered"] == kept < sum(1 for _ in McapSource(full)) == 30 + DEFAULT_STATIC_FRAMES
    assert export["frames_delivered_from"].endswith("the recording was cut short: at least this many")


def test_export_of_a_recording_without_session_metadata_says_so(tmp_path, capsys):
    """No ``livedic.session`` metadata is a note (the reader's ``NoSessionMetadata``), not an error."""
    import numpy as np
    from livedic.acquire.recording import schema as rs
    from livedic.acquire.recording import wire
    from livedic.acquire.recording.chunked_writer import ChunkedWriter

    path = tmp_path / "bare.mcap"
    with open(path, "wb") as handle:
        writer = ChunkedWriter(handle, chunk_bytes=1 << 20, compression=None, library="livedic/test")
        image = writer.register(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA, rs.schema_data(rs.RAW_IMAGE_SCHEMA))
        writer.add("image", image, 5, wire.encode_raw_image(np.zeros((4, 6), np.uint8), 5))
        writer.finish()
    capsys.readouterr()
    assert main(["export", str(path), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert f"note: {path} has no session metadata (livedic.session)" in err
    exported = json.loads((tmp_path / "out" / "session.json").read_text())["livedic.export"]
    assert exported["truncated"] is False and exported["p0_id"] == 0 and exported["frames_with_results"] == 0


# --------------------------------------------------------------------------- bad input

def _foreign_mcap(path):
    from mcap.writer import Writer
    with open(path, "wb") as handle:
        writer = Writer(handle)
        writer.start(profile="", library="another-program")
        schema = writer.register_schema("Temperature", "jsonschema", b"{}")
        channel = writer.register_channel("/temperature", "json", schema)
        writer.add_message(channel, log_time=1, data=b'{"c": 21.5}', publish_time=1)
        writer.finish()


@pytest.mark.parametrize("case", ["missing", "text", "foreign", "export-onto-a-file", "replay-onto-the-recording",
                                  "bad-method", "missing-points-file"])
def test_bad_input_is_one_line_and_exit_2(case, recording, tmp_path, capsys):
    text = tmp_path / "notes.mcap"
    text.write_text("frame,u,v\n1,2,3\n")
    foreign = tmp_path / "foreign.mcap"
    _foreign_mcap(foreign)
    existing = tmp_path / "existing.csv"
    existing.write_text("keep me\n")
    out = tmp_path / "out.csv"
    argvs = {
        "missing": [["replay", str(tmp_path / "nope.mcap")], ["export", str(tmp_path / "nope.mcap"), "-o",
                                                              str(tmp_path / "d")]],
        "text": [["replay", str(text), "-o", str(out)], ["export", str(text), "-o", str(tmp_path / "d")]],
        "foreign": [["replay", str(foreign)], ["export", str(foreign), "-o", str(tmp_path / "d")]],
        "export-onto-a-file": [["export", recording, "-o", str(existing)]],
        "replay-onto-the-recording": [["replay", recording, "-o", recording]],
        "bad-method": [["replay", recording, "--subpixel", "magic", "-o", str(out)],
                       ["replay", recording, "--subset", "20"]],
        "missing-points-file": [["replay", recording, "--points", str(tmp_path / "nope.csv"), "-o", str(out)]],
    }[case]
    words = {"missing": "does not exist", "text": "not an MCAP file", "foreign": "not written by livedic",
             "export-onto-a-file": "existing file", "replay-onto-the-recording": ".mcap",
             "bad-method": "", "missing-points-file": "does not exist"}[case]
    size = os.path.getsize(recording)
    for argv in argvs:
        capsys.readouterr()
        assert main(argv + (["--progress", "off"] if argv[0] == "replay" else [])) == 2, argv
        assert words in _one_error_line(capsys.readouterr().err)
    assert existing.read_text() == "keep me\n" and os.path.getsize(recording) == size
    assert not out.exists() and not (tmp_path / "d").exists()
    assert not [name for name in os.listdir(tmp_path) if name.startswith(".livedic-")]


# --------------------------------------------------------------------------- the shipped sample

def test_the_shipped_sample_replays_exactly_or_within_rounding_and_exports(tmp_path, capsys):
    """The sample was recorded on another machine: bit for bit is not promised here, agreement within
    floating-point rounding (ROUNDING_TOLERANCE_PX = 1e-4 px, the same points ok) is."""
    from livedic.stream.replay.agreement import ROUNDING_TOLERANCE_PX, Agreement
    from livedic.stream.replay.replay import replay
    assert ROUNDING_TOLERANCE_PX == 1e-4
    assert os.path.getsize(SAMPLE) < 5_000_000
    readme = open(os.path.join(REPO, "recordings", "README.md")).read()
    assert "livedic run --source" in readme and "sample-tensile.mcap" in readme
    session = read_session(SAMPLE)
    assert session["command"] == "livedic run" and "tensile" in session["source_uri"]
    results = read_results(SAMPLE)
    report = replay(SAMPLE)
    assert report.agreement in (Agreement.EXACT, Agreement.WITHIN_ROUNDING), report.verdict()
    assert report.compared_frames == len(results) and report.ok_differs == 0 and report.nan_differs == 0
    assert report.max_difference_px <= ROUNDING_TOLERANCE_PX
    capsys.readouterr()
    assert main(["replay", SAMPLE, "-o", str(tmp_path / "replay.csv"), "--progress", "off"]) == 0
    size = f"{len(results)} frames x {results[0].u.size} points"
    expected = {Agreement.EXACT: f"replay matches the recording exactly: {size}",
                Agreement.WITHIN_ROUNDING: "replay agrees with the recording within floating-point rounding (max "}
    err = capsys.readouterr().err
    assert expected[report.agreement] in err
    if report.agreement is Agreement.WITHIN_ROUNDING:
        assert f"px <= 1e-4 px tolerance): {size}" in err
    assert main(["export", SAMPLE, "-o", str(tmp_path / "export")]) == 0
    _, trace = _rows(tmp_path / "export" / "p0_trace.csv")
    assert len(trace) == len(results) and all(row["ok"] == "1" for row in trace)
    assert float(trace[-1]["v"]) < -0.5      # the top grip pulls upward: P0 moves up by the end of the test


# --------------------------------------------------------------------------- replay verdicts

def _recording_with_offsets(path, change):
    """A 6-frame recording whose recorded results are the tracker's, changed by ``change(i, m) -> (u, v, zncc, ok)``
    (as a replay on another CPU, or by another program, would see them)."""
    from livedic.acquire.base import Frame
    from livedic.dic.speckle import SpecklePattern, render
    from livedic.dic.tracking import Tracker
    from livedic.acquire.recording.writer import Recorder
    from livedic.stream.session.points import build_points

    pattern = SpecklePattern((128, 160), n_speckles=400, seed=5)
    images = [render(pattern, (0.25 * i, -0.15 * i), noise_sigma=0.5, noise_seed=i) for i in range(6)]
    params = {"subset": 21, "search": "improved-wso", "subpixel": "icgn", "seed_radius": 2,
              "refind_radius": 16, "refind_zncc": 0.8, "seed": 0}
    metadata = dict(params, command="livedic run", source_uri="test:offsets", roi="full image", step=24,
                    n_points_wanted=30, points_file=None, p0="ROI centre", point_ids="P0 is point 0")
    points, _, _ = build_points(images[0].shape, roi=None, step=24, n_points=30, subset=21)
    tracker = Tracker(images[0], points, **params)
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        for i, image in enumerate(images):
            recorder.write_frame(Frame(i, i * 20_000_000, image, "Mono8"))
            m = tracker.track(image)
            u, v, zncc, ok = change(i, m)
            recorder.write_results(i, i * 20_000_000, np.arange(m.u.size, dtype=np.uint32), m.x, m.y, u, v, zncc,
                                   ok, status=m.status.astype(np.int32), method="improved-wso+icgn",
                                   reference_frame_index=0)
    return str(path)


def _shifted(du, dzncc=0.0):
    return lambda i, m: (m.u + du * (i > 0), m.v - du * (i > 0), m.zncc - dzncc * (i > 0), m.ok)


def _ok_flipped(i, m):
    ok = m.ok.copy()
    if i == 3:
        ok[2] = not ok[2]
    return m.u, m.v, m.zncc, ok


@pytest.mark.parametrize("case, agreement, words", [
    ("same", "EXACT", "replay matches the recording exactly: 6 frames x"),
    ("rounding", "WITHIN_ROUNDING", "agrees with the recording within floating-point rounding (max 1.8e-06 px <= "
                                    "1e-4 px tolerance): 6 frames x"),
    ("beyond", "DIFFERS", "replay differs from the recording on 5 of 6 frames x"),
    ("zncc-rounding", "WITHIN_ROUNDING", "agrees with the recording within floating-point rounding (max 0 px <= "),
    ("zncc", "DIFFERS", "replay differs from the recording on 5 of 6 frames x"),
    ("ok-flip", "DIFFERS", "ok differs at 1 and NaN at 0 point-frames"),
])
def test_replay_says_exact_within_rounding_or_differs(case, agreement, words, tmp_path, capsys):
    """Bit for bit, within floating-point rounding (1e-4 px, ZNCC ``ROUNDING_TOLERANCE_ZNCC``, the same points ok),
    or different: the verdict is the report's ``agreement`` (data), and the line says the same."""
    from livedic.stream.replay.agreement import ROUNDING_TOLERANCE_ZNCC, Agreement
    from livedic.stream.replay.replay import replay
    change = {"same": _shifted(0.0), "rounding": _shifted(1.8e-6), "beyond": _shifted(2e-4),
              "zncc-rounding": _shifted(0.0, dzncc=0.5 * ROUNDING_TOLERANCE_ZNCC),
              "zncc": _shifted(0.0, dzncc=2 * ROUNDING_TOLERANCE_ZNCC), "ok-flip": _ok_flipped}[case]
    path = _recording_with_offsets(tmp_path / f"{case}.mcap", change)
    report = replay(path)
    assert report.agreement is Agreement[agreement]
    capsys.readouterr()
    assert main(["replay", path, "--progress", "off", "-o", str(tmp_path / "out.csv")]) == 0
    assert words in capsys.readouterr().err


# --------------------------------------------------------------------------- outputs that cannot be written

@pytest.mark.parametrize("variant", ["read-only", "denied", "under-a-file"])
def test_replay_and_export_to_an_unwritable_place_fail_first_with_one_line(variant, recording, tmp_path, capsys,
                                                                            monkeypatch, unwritable_folder):
    folder = unwritable_folder(variant)
    try:
        for argv in (["replay", recording, "-o", str(folder / "replay.csv"), "--progress", "off"],
                     ["export", recording, "-o", str(folder / "export")]):
            capsys.readouterr()
            assert main(argv) == 2, argv
            line = _one_error_line(capsys.readouterr().err)
            assert "cannot write -o" in line and ("not writable" in line or "not a folder" in line), line
            assert "replayed" not in line
    finally:
        if folder.is_dir():
            folder.chmod(0o755)
    assert not [name for name in os.listdir(tmp_path) if name.startswith(".livedic-")]
    if folder.is_dir():
        assert os.listdir(folder) == []


def test_replay_to_a_folder_names_the_folder_not_a_temporary_file(recording, tmp_path, capsys):
    capsys.readouterr()
    assert main(["replay", recording, "-o", str(tmp_path), "--progress", "off"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"-o {tmp_path} is a folder: give a file name" in line and ".livedic-" not in line


def test_replay_and_export_files_get_the_usual_permissions_and_strict_json(recording, tmp_path, capsys):
    from livedic.stream.output.files import current_umask
    expected = 0o666 & ~current_umask()
    assert main(["replay", recording, "-o", str(tmp_path / "replay.csv"), "--progress", "off"]) == 0
    assert main(["export", recording, "-o", str(tmp_path / "export")]) == 0
    assert (tmp_path / "replay.csv").stat().st_mode & 0o777 == expected
    written = _file_bytes(tmp_path / "export")          # every file, the maps, video and VTK files too
    assert len(written) > len(EXPORTED)
    for name in written:
        assert (tmp_path / "export" / name).stat().st_mode & 0o777 == expected, name
    text = (tmp_path / "export" / "session.json").read_text()
    json.loads(text, parse_constant=lambda name: pytest.fail(f"session.json holds {name}: not JSON"))
