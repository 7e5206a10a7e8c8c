"""``livedic export``: strain columns in fields.csv, extensometers.csv and extensometers.png, recomputed from
the recorded displacements with the recorded settings (or the options given)."""

import csv
import json
import os

import numpy as np
import pytest

from livedic.acquire.recording.reader import read_results, read_session
from livedic.stream.cli import main

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SAMPLE = os.path.join(REPO, "recordings", "sample-tensile.mcap")
TENSILE = "synthetic:tensile?frames=12&size=384x384&pace=0"
HEADER = ["frame", "time_s", "name", "L0_px", "L_px", "eng_strain", "true_strain", "ok"]


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


@pytest.fixture(scope="module")
def tensile(tmp_path_factory):
    """A short simulated tensile test recorded by ``livedic run`` with a 200 px gauge length."""
    path = tmp_path_factory.mktemp("tensile") / "tensile.mcap"
    code = main(["run", "--source", TENSILE, "--record", str(path), "--viewer", "none", "--progress", "off",
                 "--gauge-length", "200", "--static-frames", "0"])     # frames as the source built below numbers them
    assert code == 0 and path.exists()
    return str(path)


def _rows(path):
    with open(path, newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


def _floats(rows, name):
    return np.array([float(row[name]) for row in rows])


def _exact_eng_strain(source, frame, ends):
    """The simulator's exact engineering strain between two reference points."""
    x1, y1, x2, y2 = ends
    u, v = source.truth(frame, np.array([x1, x2]), np.array([y1, y2]))
    return np.hypot(x2 + u[1] - x1 - u[0], y2 + v[1] - y1 - v[0]) / np.hypot(x2 - x1, y2 - y1) - 1.0


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and "Traceback" not in err, err
    return lines[0]


def test_extensometers_csv_follows_the_simulators_exact_strain(tensile, tmp_path, capsys):
    from livedic.acquire.simulator.sources import SyntheticTensileSource

    out = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", tensile, "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "extensometers axial L0 200.0 px" in err and "extensometers.csv, extensometers.png" in err
    header, rows = _rows(out / "extensometers.csv")
    assert header == HEADER
    results = read_results(tensile)
    session = read_session(tensile)
    ends = {name: tuple(e) for name, *e in session["extensometers"]}
    assert list(ends) == ["axial", "transverse"] and ends["axial"][3] - ends["axial"][1] == 200.0
    # one row per frame and extensometer, in order, on the clock of p0_trace.csv
    assert [(int(r["frame"]), r["name"]) for r in rows] == [(r.frame_index, n) for r in results for n in ends]
    _, trace = _rows(out / "p0_trace.csv")
    assert np.array_equal(_floats(rows, "time_s")[::2], _floats(trace, "time_s"))
    assert all(r["ok"] == "1" for r in rows)
    source = SyntheticTensileSource(TENSILE)
    for row in rows:
        exact = _exact_eng_strain(source, int(row["frame"]), ends[row["name"]])
        got, l0, length = float(row["eng_strain"]), float(row["L0_px"]), float(row["L_px"])
        assert abs(length / l0 - 1.0 - got) < 1e-12 and abs(np.log(length / l0) - float(row["true_strain"])) < 1e-12
        # Axial (200 px): 50 microstrain + 0.5 % of the reading (ISO 9513 class 0.5; measured max 122 microstrain).
        # Transverse (48 px, 0.02 px noise at each end): 500 microstrain + 0.5 % (measured max 269).
        bound = (50e-6 if row["name"] == "axial" else 500e-6) + 0.005 * abs(exact)
        assert abs(got - exact) <= bound, (row, exact)
    assert float(rows[-2]["eng_strain"]) > 0.08 and float(rows[-1]["eng_strain"]) < -0.05     # pulled, narrowed


def test_fields_strain_columns_are_dic_strain_on_the_recorded_displacements(tensile, tmp_path, capsys):
    from livedic.acquire.simulator.sources import SyntheticTensileSource
    from livedic.dic.strain import strain_field, strain_window

    out = tmp_path / "export"
    assert main(["export", tensile, "-o", str(out)]) == 0
    header, rows = _rows(out / "fields.csv")
    assert header[:9] == ["frame", "timestamp_ns", "point_id", "x", "y", "u", "v", "zncc", "ok"]
    assert header[-3:] == ["exx", "eyy", "exy"] and header[9:-3] == ["status", "ux", "uy", "vx", "vy", "iterations"]
    session = read_session(tensile)
    frames = sorted({int(r["frame"]) for r in rows})
    first = [r for r in rows if int(r["frame"]) == 0]
    points = np.column_stack([_floats(first, "x"), _floats(first, "y")])
    windows = strain_window(points, window=session["strain_window"], step=None, subset=session["subset"])
    assert windows.vsg_px == session["vsg_px"] == 41.0
    source = SyntheticTensileSource(TENSILE)
    for frame in frames:
        part = [r for r in rows if int(r["frame"]) == frame]
        ok = np.array([r["ok"] == "1" for r in part])
        want = strain_field(windows, _floats(part, "u"), _floats(part, "v"), ok, measure=session["strain_measure"])
        for name in ("exx", "eyy", "exy"):
            got = _floats(part, name)
            assert np.array_equal(np.isnan(got), np.isnan(getattr(want, name))), (frame, name)
            assert np.allclose(got, getattr(want, name), rtol=0, atol=1e-15, equal_nan=True), (frame, name)
    # Frame 5 (uniform plastic stretch): e_yy against the exact dV/dY at the points; RMS 5.5e-4 measured
    # (0.02 px displacement noise over a 41 px VSG), bound 1.5e-3.
    part = [r for r in rows if int(r["frame"]) == 5]
    eyy = _floats(part, "eyy")
    exact = source.model.strain_yy(5, _floats(part, "y"))
    assert np.isfinite(eyy).all()
    assert np.sqrt(np.mean((eyy - exact) ** 2)) <= 1.5e-3 and abs(np.mean(exact) - 0.0374) < 1e-3


def test_options_override_the_recorded_settings(tensile, tmp_path, capsys):
    out = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", tensile, "-o", str(out), "--strain-window", "7", "--strain-measure", "green",
                 "--scale", "10", "--gauge-length", "15,4", "--extensometer", "upper=200,120,200,180"]) == 0
    err = capsys.readouterr().err
    assert "green, window 7 points x step 5 px + subset 21 = VSG 51 px" in err
    _, rows = _rows(out / "extensometers.csv")
    last = {r["name"]: r for r in rows if int(r["frame"]) == 11}
    assert list(last) == ["axial", "transverse", "upper"]
    assert [float(last[n]["L0_px"]) for n in last] == [150.0, 40.0, 60.0]        # 15 mm, 4 mm at 10 px/mm
    settings = json.loads((out / "session.json").read_text())["livedic.export"]["strain"]
    assert settings["measure"] == "green" and settings["window"] == 7 and settings["vsg_px"] == 51.0
    assert settings["overridden"] == ["extensometers", "gauge_length", "gauge_width", "measure", "scale", "window"]
    # Green-Lagrange from the 7-point plane fits: E_yy = vy + (uy^2 + vy^2) / 2, E_xy = (uy + vx + ux uy + vx vy) / 2
    from livedic.dic.strain import displacement_gradients, strain_window
    _, fields = _rows(out / "fields.csv")
    part = [r for r in fields if int(r["frame"]) == 11]
    windows = strain_window(np.column_stack([_floats(part, "x"), _floats(part, "y")]), window=7, subset=21)
    ux, uy, vx, vy, _ = displacement_gradients(windows, _floats(part, "u"), _floats(part, "v"),
                                               np.array([r["ok"] == "1" for r in part]))
    assert np.allclose(_floats(part, "eyy"), vy + 0.5 * (uy ** 2 + vy ** 2), rtol=0, atol=1e-14, equal_nan=True)
    assert np.allclose(_floats(part, "exy"), 0.5 * (uy + vx + ux * uy + vx * vy), rtol=0, atol=1e-14,
                       equal_nan=True)
    assert np.nanmedian(_floats(part, "eyy") - vy) > 1e-3          # at ~5-9 % stretch the measures differ


@pytest.mark.parametrize("argv,words", [
    (["--strain-window", "4"], "--strain-window must be an odd number of points >= 3"),
    (["--gauge-length", "long"], "--gauge-length 'long': give L or L,W"),
    (["--extensometer", "nameless"], "--extensometer 'nameless': give NAME=x1,y1,x2,y2"),
    (["--extensometer", "far=5,5,9,380"], "far"),
    (["--scale", "-2"], "--scale must be a positive number"),
    (["--strain-measure", "cauchy"], "invalid choice"),
])
def test_bad_strain_options_are_one_line_exit_2_and_write_nothing(tensile, tmp_path, capsys, argv, words):
    out = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", tensile, "-o", str(out)] + argv) == 2
    assert words in _one_error_line(capsys.readouterr().err)
    assert not out.exists() and os.listdir(tmp_path) == []


def test_an_existing_plot_is_not_replaced_without_overwrite(tensile, tmp_path, capsys):
    out = tmp_path / "export"
    out.mkdir()
    (out / "extensometers.png").write_bytes(b"last week's plot")
    capsys.readouterr()
    assert main(["export", tensile, "-o", str(out)]) == 2
    assert "extensometers.png: pass --overwrite" in _one_error_line(capsys.readouterr().err)
    assert os.listdir(out) == ["extensometers.png"] and (out / "extensometers.png").read_bytes() == b"last week's plot"
    assert main(["export", tensile, "-o", str(out), "--overwrite"]) == 0
    assert (out / "extensometers.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_recording_without_extensometers_gives_the_header_and_says_so(tmp_path, capsys):
    out = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", SAMPLE, "-o", str(out)]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "no extensometers" in line]
    assert len(notes) == 1 and notes[0].startswith("livedic: note: the recording has no extensometers")
    assert (out / "extensometers.csv").read_text() == ",".join(HEADER) + "\n"
    header, rows = _rows(out / "fields.csv")
    assert header[-3:] == ["exx", "eyy", "exy"]
    last = [r for r in rows if int(r["frame"]) == max(int(r["frame"]) for r in rows)]
    assert 0.03 < np.nanmedian(_floats(last, "eyy")) < 0.15         # the sample's specimen is stretched
    assert (out / "extensometers.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_lost_end_is_a_gap_with_nan_and_ok_0(tmp_path, capsys):
    """A recording whose top rows are lost in frames 3 and 4: the axial extensometer has no reading there."""
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder

    xs, ys = np.meshgrid(np.arange(60.0, 341.0, 10.0), np.arange(40.0, 361.0, 10.0))
    points = np.vstack([[[200.0, 200.0]], np.column_stack([xs.ravel(), ys.ravel()])])
    metadata = {"roi": [60, 40, 280, 320], "step": 10, "subset": 21, "point_ids": "P0 is point 0",
                "strain_window": 5, "strain_measure": "engineering", "gauge_length": 240.0,
                "extensometers": [["axial", 200.0, 80.0, 200.0, 320.0]]}
    path = tmp_path / "lost.mcap"
    with Recorder(path, metadata, start_time_ns=0) as rec:
        for i in range(6):
            u = -0.3e-2 * i * (points[:, 0] - 200.0)
            v = 1e-2 * i * (points[:, 1] - 200.0)
            ok = np.ones(len(points), bool)
            if i in (3, 4):
                ok[points[:, 1] < 120] = False
                u[~ok] = v[~ok] = np.nan
            rec.write_frame(Frame(i, i * 50_000_000, np.zeros((8, 8), np.uint8), "Mono8"))
            rec.write_results(i, i * 50_000_000, np.arange(len(points)), points[:, 0], points[:, 1], u, v,
                              np.ones(len(points)), ok)
    out = tmp_path / "export"
    assert main(["export", str(path), "-o", str(out)]) == 0
    header, rows = _rows(out / "extensometers.csv")
    assert header == HEADER and [r["ok"] for r in rows] == ["1", "1", "1", "0", "0", "1"]
    assert [r["L_px"] for r in rows[3:5]] == ["nan", "nan"] and [r["eng_strain"] for r in rows[3:5]] == ["nan", "nan"]
    assert np.allclose(_floats(rows, "eng_strain")[[0, 1, 2, 5]], [0.0, 0.01, 0.02, 0.05], rtol=0, atol=1e-12)
    assert _floats(rows, "time_s").tolist() == [0.0, 0.05, 0.1, 0.15, 0.2, 0.25]
    _, fields = _rows(out / "fields.csv")
    frame2 = [r for r in fields if r["frame"] == "2"]
    assert np.allclose(_floats(frame2, "exx"), -0.6e-2, rtol=0, atol=1e-12)      # uniform: exact everywhere
    assert np.allclose(_floats(frame2, "eyy"), 2e-2, rtol=0, atol=1e-12)
    assert np.allclose(_floats(frame2, "exy"), 0.0, rtol=0, atol=1e-12)
    frame3 = [r for r in fields if r["frame"] == "3"]
    lost = np.array([r["ok"] == "0" for r in frame3])
    assert np.isnan(_floats(frame3, "eyy")[lost]).all() and np.isfinite(_floats(frame3, "eyy")[~lost]).any()


def test_recorded_channels_equal_what_export_computes(tensile, tmp_path):
    """The live session records /dic/strain and /dic/extensometers; export recomputes the same numbers
    from the recorded displacements (one computation everywhere: the same stage on the same data)."""
    from livedic.acquire.recording.reader import read_extensometer_samples, read_strain_fields
    out = tmp_path / "out"
    assert main(["export", tensile, "-o", str(out)]) == 0
    samples = read_extensometer_samples(tensile)
    _, rows = _rows(out / "extensometers.csv")
    assert len(samples) == len(rows) > 0
    for sample, row in zip(samples, rows):
        assert (int(row["frame"]), row["name"]) == (sample.frame_index, sample.name)
        assert float(row["L_px"]) == sample.l_px and float(row["eng_strain"]) == sample.eng_strain
        assert int(row["ok"]) == int(sample.ok)
    fields = read_strain_fields(tensile)
    _, field_rows = _rows(out / "fields.csv")
    assert len(fields) == len(read_results(tensile))
    by_frame = {}
    for row in field_rows:
        by_frame.setdefault(int(row["frame"]), []).append(float(row["eyy"]))
    for field in fields:
        np.testing.assert_array_equal(np.array(by_frame[field.frame_index]), field.eyy)
    assert fields[0].window == 5


def test_a_recording_with_extensometers_but_no_results_exports_its_headers(tmp_path, capsys):
    """A recording cut before its first results (a crash at the start): the files with headers only, one note,
    exit 0 (it was an IndexError on the extensometers' plot: no results, so no L0 to label them with)."""
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder

    metadata = {"roi": [60, 40, 280, 320], "step": 10, "subset": 21, "point_ids": "P0 is point 0",
                "strain_window": 5, "strain_measure": "engineering", "gauge_length": 240.0,
                "extensometers": [["axial", 200.0, 80.0, 200.0, 320.0]]}
    path = tmp_path / "no-results.mcap"
    with Recorder(path, metadata, start_time_ns=0) as rec:
        for i in range(3):
            rec.write_frame(Frame(i, i * 50_000_000, np.zeros((8, 8), np.uint8), "Mono8"))
    out = tmp_path / "export"
    assert main(["export", str(path), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "holds no tracking results" in err and "Traceback" not in err
    assert (out / "extensometers.csv").read_text() == ",".join(HEADER) + "\n"
    assert (out / "extensometers.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
