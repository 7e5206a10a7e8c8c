"""Tests of stream/export/export.py: ``export_recording``'s CSV files bit for bit against the recorded results,
the events, the refusals before anything is written, and a stop at each stage leaving only whole files.

The recording is written directly (a known uniform stretch on a grid, no tracker), so it takes no numba time;
the maps' colours, the video and the VTK values of a tracked recording are in test_field_export.py.
"""

import csv
import json
import os
import signal

import cv2
import numpy as np
import pytest

from livedic.stream.export.export import export_recording
from livedic.stream.export.field_export import FieldOptions
from livedic.stream.export.stop import ExportStopped
from tests.stream.export.conftest import partial_files

SIZE = (80, 100)                                  # image height, width
FRAMES = 6
EYY = 0.01                                        # per frame: v = i EYY (y - 10)
ROI, STEP = (20, 10, 60, 60), 10


def _grid():
    x, y = np.meshgrid(ROI[0] + STEP * np.arange(7.0), ROI[1] + STEP * np.arange(7.0))
    return x.ravel(), y.ravel()


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """FRAMES frames 0.1 s apart: a uniform stretch e_yy = i EYY on a 7 x 7 grid (P0 = point 0); frame 3's
    point 10 not ok (NaN); two events."""
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder
    path = tmp_path_factory.mktemp("export") / "stretch.mcap"
    x, y = _grid()
    n = x.size
    metadata = {"command": "livedic run", "source_uri": "test:stretch", "subset": 11, "roi": list(ROI), "step": STEP,
                "point_ids": "P0 is point 0", "search": "improved-wso", "subpixel": "icgn"}
    rng = np.random.default_rng(0)
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        recorder.write_event("start", "the test starts, with a\nline break", timestamp_ns=50_000_000)
        for i in range(FRAMES):
            t = 100_000_000 * (i + 1)
            recorder.write_frame(Frame(i, t, rng.integers(0, 255, SIZE, dtype=np.uint8), "Mono8"))
            u, v, ok = np.full(n, 0.1 * i / 3), i * EYY * (y - 10.0), np.ones(n, dtype=bool)
            if i == 3:
                u[10], v[10], ok[10] = np.nan, np.nan, False
            recorder.write_results(i, t, np.arange(n, dtype=np.uint32), x, y, u, v, np.full(n, 0.97), ok,
                                   status=np.where(ok, 0, 1).astype(np.int32), method="improved-wso+icgn",
                                   reference_frame_index=0)
        recorder.write_event("stop", "done", level="warning", timestamp_ns=700_000_000)
    return str(path)


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.fixture(scope="module")
def exported(recording, tmp_path_factory):
    out = tmp_path_factory.mktemp("out") / "csv"
    return export_recording(recording, out), out


def test_the_csv_files_hold_the_recorded_numbers_bit_for_bit(recording, exported):
    from livedic.acquire.recording.reader import read_results
    summary, out = exported
    assert (summary["frames"], summary["points"], summary["p0_id"], summary["p0_rows"]) == (FRAMES, 49, 0, FRAMES)
    assert sorted(os.listdir(out)) == sorted(["p0_trace.csv", "fields.csv", "events.csv", "session.json",
                                              "extensometers.csv", "extensometers.png"])
    rows = _rows(out / "fields.csv")
    assert len(rows) == FRAMES * 49 and list(rows[0])[:9] == ["frame", "timestamp_ns", "point_id", "x", "y", "u", "v",
                                                              "zncc", "ok"]
    for result in read_results(recording):
        part = [row for row in rows if int(row["frame"]) == result.frame_index]
        for name in ("u", "v", "x", "y", "zncc"):
            got = np.array([float(row[name]) for row in part])
            assert np.array_equal(got, getattr(result, name), equal_nan=True), (result.frame_index, name)
        assert [row["ok"] for row in part] == ["1" if ok else "0" for ok in result.ok]
    trace = _rows(out / "p0_trace.csv")
    assert np.allclose([float(row["time_s"]) for row in trace], 0.1 * np.arange(FRAMES), rtol=0, atol=1e-12)
    assert [int(row["timestamp_ns"]) for row in trace] == [100_000_000 * (i + 1) for i in range(FRAMES)]


def test_the_recomputed_strain_is_the_known_uniform_stretch(exported):
    _, out = exported
    rows = [row for row in _rows(out / "fields.csv") if row["frame"] == "5"]
    eyy = np.array([float(row["eyy"]) for row in rows])
    exx = np.array([float(row["exx"]) for row in rows])
    finite = np.isfinite(eyy)
    assert finite.mean() > 0.5
    assert np.allclose(eyy[finite], 5 * EYY, rtol=0, atol=1e-12) and np.allclose(exx[finite], 0.0, atol=1e-12)


def test_events_are_on_the_clock_of_the_first_frame_in_one_line_each(exported):
    _, out = exported
    events = _rows(out / "events.csv")
    assert [(row["kind"], row["level"]) for row in events] == [("start", "info"), ("stop", "warning")]
    assert float(events[0]["time"]) == pytest.approx(-0.05) and float(events[1]["time"]) == pytest.approx(0.6)
    assert events[0]["message"] == "the test starts, with a line break" and events[1]["timestamp_ns"] == "700000000"
    session = json.loads((out / "session.json").read_text())
    assert session["livedic.export"]["frames_with_results"] == FRAMES


def test_existing_files_are_kept_without_overwrite_and_replaced_with_it(recording, exported, tmp_path):
    _, out = exported
    before = (out / "fields.csv").read_bytes()
    with pytest.raises(ValueError) as error:
        export_recording(recording, out)
    assert str(error.value).startswith(f"{out} already holds p0_trace.csv, fields.csv") and \
        str(error.value).endswith("pass --overwrite to replace them, or choose another folder")
    again = tmp_path / "again"
    export_recording(recording, again)
    assert (again / "fields.csv").read_bytes() == before                # the same recording, the same bytes
    (again / "fields.csv").write_text("old")
    export_recording(recording, again, overwrite=True)
    assert (again / "fields.csv").read_bytes() == before


def test_bad_inputs_raise_before_the_folder_is_made(recording, tmp_path):
    from livedic.acquire.recording.errors import RecordingError
    missing = tmp_path / "missing.mcap"
    with pytest.raises((ValueError, RecordingError)):
        export_recording(missing, tmp_path / "out1")
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    with pytest.raises(ValueError, match="is an existing file: give a folder"):
        export_recording(recording, blocker)
    with pytest.raises(ValueError):
        export_recording(recording, tmp_path / "out2", strain={"window": 2})
    assert not (tmp_path / "out1").exists() and not (tmp_path / "out2").exists()


# --------------------------------------------------------------------------- stopping

def _stop_after(calls):
    """A ``stop`` for ``export_recording`` that raises ``ExportStopped`` (as SIGTERM) on its ``calls``-th call."""
    count = [0]

    def stop():
        count[0] += 1
        if count[0] >= calls:
            raise ExportStopped("SIGTERM", signal.SIGTERM)
    return stop


def test_stopped_while_writing_the_csv_files_leaves_nothing(recording, tmp_path):
    out = tmp_path / "out"
    with pytest.raises(ExportStopped) as stopped:
        export_recording(recording, out, fields=FieldOptions(), stop=_stop_after(3))
    assert stopped.value.state == f"while writing the CSV files: nothing was written ({out} removed again)"
    assert not out.exists()


def test_stopped_while_drawing_keeps_the_csv_files_and_whole_pictures(recording, tmp_path):
    """Stopped at the third frame of the maps: the CSV files are complete, two frames' maps and .vtu files are
    there, whole; no video and no .pvd (they would claim frames that are not there), no partial file."""
    out = tmp_path / "out"
    with pytest.raises(ExportStopped) as stopped:
        export_recording(recording, out, fields=FieldOptions(every=1), stop=_stop_after(FRAMES + 3))
    assert stopped.value.state == (f"while drawing the maps, video and VTK (frame 3 of {FRAMES}): {out} holds the "
                                   f"CSV files, plots and session.json, complete, and 10 maps, 2 .vtu files, each "
                                   f"complete; not written: overlay_eyy.mp4, fields.pvd")
    assert len(_rows(out / "p0_trace.csv")) == FRAMES
    assert sorted(os.listdir(out / "vtk")) == ["frame_000000.vtu", "frame_000001.vtu"]
    assert sorted(os.listdir(out / "maps" / "exy")) == ["exy_000000.png", "exy_000001.png"]
    assert all(cv2.imread(str(out / "maps" / q / f"{q}_000001.png")) is not None for q in ("u", "v", "exx", "eyy"))
    assert not (out / "fields.pvd").exists() and not (out / "overlay_eyy.mp4").exists()
    assert partial_files(out) == []


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_a_stereo_recordings_strain_and_extensometers_are_the_recorded_ones_in_space(stereo_recording, tmp_path):
    """extensometers.csv holds each extensometer in space as recorded (L0_mm, L_mm; eng_strain = L / L0 - 1, bit for
    bit), fields.csv the surface strain recorded on /dic/strain, the stress-strain curve the axial one in space;
    the note says so."""
    from livedic.acquire.recording.reader import Recording
    from livedic.stream.stages.stress import StressOptions, RECORDED_FORCE
    out = tmp_path / "out"
    summary = export_recording(stereo_recording, out, stress=StressOptions(RECORDED_FORCE, 0.0, 40.0))
    recording = Recording(stereo_recording)
    samples = list(recording.extensometer_samples())
    rows = _rows(out / "extensometers.csv")
    assert len(rows) == len(samples) == 2 * summary["frames"]
    for row, sample in zip(rows, samples):
        assert (int(row["frame"]), row["name"]) == (sample.frame_index, sample.name)
        assert (float(row["L0_mm"]), float(row["L_mm"])) == (sample.l0_mm, sample.l_mm)
        assert float(row["eng_strain"]) == sample.l_mm / sample.l0_mm - 1.0 == sample.eng_strain
    assert float(rows[-2]["eng_strain"]) == pytest.approx(0.01, abs=1e-4)     # the axial strain, in space
    fields = _rows(out / "fields.csv")
    strain = list(recording.strain_fields())
    last = [row for row in fields if int(row["frame"]) == strain[-1].frame_index]
    for name in ("exx", "eyy", "exy"):
        np.testing.assert_array_equal([float(row[name]) for row in last], getattr(strain[-1], name))
    axial = [row for row in rows if row["name"] == "axial"]
    curve = _rows(out / "stress_strain.csv")
    assert [float(row["eng_strain"]) for row in curve] == [float(row["eng_strain"]) for row in axial]
    assert any("the session's 3D results as recorded" in note for note in summary["notes"])
    session = json.loads((out / "session.json").read_text())
    assert session["livedic.export"]["strain"]["recomputed_from"] is None


def test_strain_options_on_a_stereo_recording_are_one_line_before_the_folder(stereo_recording, tmp_path):
    with pytest.raises(ValueError, match="stereo recording's strain and extensometers") as error:
        export_recording(stereo_recording, tmp_path / "out", strain={"window": 3})
    assert "\n" not in str(error.value) and not (tmp_path / "out").exists()
