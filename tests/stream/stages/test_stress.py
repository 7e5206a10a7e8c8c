"""The offline stress-strain curve: ``livedic export --load`` (stress_strain.csv/.png) and ``livedic report``.

A short simulated tensile test is recorded with a 200 px ``axial`` extensometer; the force file is
written from a known law of the simulator's *exact* axial strain at each frame (bilinear:
elastic, then linear hardening up to the neck, then a falling force while the neck grows), so the
stress is exact and what the properties test is the strain the extensometer reads.

The law's yield strain is 2 % (E = 20 GPa, 400 MPa): the simulator's strain rises by about
0.0019 per frame in its plastic phase, and a steel-like 0.2 % yield strain would leave one or two
frames in ISO's 10-40 % of Rp0.2 fitting range; with 2 % about seven frames lie in it.
"""

import csv
import json
import os

import numpy as np
import pytest

from livedic.stream.session.config import DEFAULT_STATIC_FRAMES
from livedic.acquire.recording.reader import read_results, read_session
from livedic.stream.cli import main

TENSILE = "synthetic:tensile?frames=60&size=384x512&pace=0"
HEADER = ["frame", "time_s", "force_N", "eng_strain", "eng_stress_MPa", "true_strain", "true_stress_MPa"]
E_MPA = 20_000.0          # the law's modulus
YIELD_STRAIN = 0.02
HARDENING_MPA = 2_000.0
NECK_DROP = 0.4           # the force falls by this share of its maximum over the necking frames
WIDTH_MM, THICKNESS_MM = 10.0, 2.0
AREA_MM2 = WIDTH_MM * THICKNESS_MM
KEYS = ("E_GPa", "Rp02_MPa", "Rm_MPa", "Ag_percent", "A_percent")


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def _law_MPa(strain):
    strain = np.asarray(strain, dtype=np.float64)
    return np.where(strain <= YIELD_STRAIN, E_MPA * strain,
                    E_MPA * YIELD_STRAIN + HARDENING_MPA * (strain - YIELD_STRAIN))


def _law_rp02_MPa():
    """Where the offset line E (e - 0.002) meets the hardening line."""
    strain = (E_MPA * YIELD_STRAIN - HARDENING_MPA * YIELD_STRAIN + 0.002 * E_MPA) / (E_MPA - HARDENING_MPA)
    return float(_law_MPa(strain))


@pytest.fixture(scope="module")
def test_run(tmp_path_factory):
    """(recording, force CSV, frames, time_s, exact axial strain, force per frame, frame of maximum force)."""
    from livedic.acquire.simulator.sources import SyntheticTensileSource

    folder = tmp_path_factory.mktemp("stress")
    path = folder / "tensile.mcap"
    code = main(["run", "--source", TENSILE, "--record", str(path), "--viewer", "none", "--progress", "off",
                 "--gauge-length", "200"])
    assert code == 0 and path.exists()
    results = read_results(str(path))
    frames = np.array([r.frame_index for r in results])
    time_s = np.array([(r.timestamp_ns - results[0].timestamp_ns) / 1e9 for r in results])
    x1, y1, x2, y2 = next(tuple(e) for name, *e in read_session(str(path))["extensometers"] if name == "axial")
    source = SyntheticTensileSource(TENSILE, static=DEFAULT_STATIC_FRAMES)     # as run rendered it
    exact = []
    for frame in frames:
        u, v = source.truth(int(frame), np.array([x1, x2]), np.array([y1, y2]))
        exact.append(np.hypot(x2 + u[1] - x1 - u[0], y2 + v[1] - y1 - v[0]) / np.hypot(x2 - x1, y2 - y1) - 1.0)
    exact = np.array(exact)
    loading = np.array([source.model.state(source.rendered_index(int(f)))["phase"] in ("elastic", "plastic")
                        for f in frames])
    peak = int(np.flatnonzero(loading)[-1])
    stress = _law_MPa(exact)
    after = np.arange(len(frames)) > peak
    share = (np.arange(len(frames)) - peak) / (len(frames) - 1 - peak)
    stress[after] = stress[peak] * (1.0 - NECK_DROP * share[after] ** 2)
    force = stress * AREA_MM2
    force_csv = folder / "force.csv"
    _write_force(force_csv, time_s, force)
    return {"recording": str(path), "force_csv": str(force_csv), "frames": frames, "time_s": time_s,
            "exact": exact, "force": force, "peak": peak, "folder": folder}


def _write_force(path, time_s, force):
    """Samples at every frame time and half-way between (the mean of the two), as a machine logs faster."""
    mid_t = 0.5 * (time_s[1:] + time_s[:-1])
    mid_f = 0.5 * (force[1:] + force[:-1])
    order = np.argsort(np.concatenate([time_s, mid_t]))
    t, f = np.concatenate([time_s, mid_t])[order], np.concatenate([force, mid_f])[order]
    with open(path, "w", newline="") as handle:
        handle.write("time_s,force_N\n")
        for a, b in zip(t, f):
            handle.write(f"{float(a)!r},{float(b)!r}\n")


def _rows(path):
    with open(path, newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


def _col(rows, name):
    return np.array([float(row[name]) for row in rows])


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and "Traceback" not in err, err
    return lines[0]


def _strict_json(path):
    def refuse(name):
        raise ValueError(f"not strict JSON: {name}")
    with open(path) as handle:
        return json.loads(handle.read(), parse_constant=refuse)


def test_export_writes_the_stress_strain_table(test_run, tmp_path, capsys):
    out = tmp_path / "export"
    assert main(["export", test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
                 "--width", str(WIDTH_MM), "--thickness", str(THICKNESS_MM)]) == 0
    assert "stress_strain.csv, stress_strain.png" in capsys.readouterr().err
    header, rows = _rows(out / "stress_strain.csv")
    assert header == HEADER
    assert np.array_equal(_col(rows, "frame"), test_run["frames"])
    assert np.array_equal(_col(rows, "time_s"), test_run["time_s"])
    force, strain, stress = _col(rows, "force_N"), _col(rows, "eng_strain"), _col(rows, "eng_stress_MPa")
    # a frame time equals a sample's: the sample itself; stress F / A0 at every frame
    assert np.allclose(force, test_run["force"], rtol=1e-12, atol=0)
    assert np.all(np.abs(stress - force / AREA_MM2) <= 1e-9 * np.abs(stress))
    # the strain is the axial extensometer of extensometers.csv, bit for bit
    _, ext = _rows(out / "extensometers.csv")
    assert np.array_equal(strain, _col([r for r in ext if r["name"] == "axial"], "eng_strain"))
    # true values up to the frame of maximum force (the last loading frame), NaN after it
    peak = test_run["peak"]
    assert int(np.argmax(force)) == peak
    true_strain, true_stress = _col(rows, "true_strain"), _col(rows, "true_stress_MPa")
    assert np.allclose(true_strain[:peak + 1], np.log1p(strain[:peak + 1]), rtol=1e-12, atol=1e-15)
    assert np.allclose(true_stress[:peak + 1], stress[:peak + 1] * (1 + strain[:peak + 1]), rtol=1e-12, atol=0)
    assert np.isnan(true_strain[peak + 1:]).all() and np.isnan(true_stress[peak + 1:]).all()
    assert peak + 1 < len(rows)
    with open(out / "stress_strain.png", "rb") as handle:
        assert handle.read(8) == b"\x89PNG\r\n\x1a\n"
    session = _strict_json(out / "session.json")
    assert session["livedic.export"]["stress"]["area_mm2"] == AREA_MM2


def test_force_is_nan_where_the_file_has_none(test_run, tmp_path):
    """A file that stops at frame 20's time: force NaN after it (never extrapolated), stress NaN too."""
    short = tmp_path / "short.csv"
    _write_force(short, test_run["time_s"][:21], test_run["force"][:21])
    out = tmp_path / "export"
    assert main(["export", test_run["recording"], "-o", str(out), "--load", f"csv:{short}",
                 "--area", str(AREA_MM2)]) == 0
    _, rows = _rows(out / "stress_strain.csv")
    force = _col(rows, "force_N")
    assert np.allclose(force[:21], test_run["force"][:21], rtol=1e-12, atol=0)
    assert np.isnan(force[21:]).all() and np.isnan(_col(rows, "eng_stress_MPa")[21:]).all()
    # the maximum of the force known: frame 20; no true value after it
    assert np.isfinite(_col(rows, "true_stress_MPa")[:21]).all()
    assert np.isnan(_col(rows, "true_stress_MPa")[21:]).all()


def test_export_without_load_writes_no_stress_files(test_run, tmp_path):
    out = tmp_path / "export"
    assert main(["export", test_run["recording"], "-o", str(out), "--maps", "none", "--video", "none",
                 "--no-vtk"]) == 0                      # the CSV files only: what export wrote before its maps
    assert sorted(os.listdir(out)) == sorted(["p0_trace.csv", "fields.csv", "events.csv", "session.json",
                                              "extensometers.csv", "extensometers.png"])
    assert "stress" not in _strict_json(out / "session.json")["livedic.export"]


def test_report_recovers_the_laws_properties(test_run, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
                 "--area", str(AREA_MM2)]) == 0
    assert "report: E " in capsys.readouterr().err
    assert sorted(os.listdir(out)) == ["report.html", "report.json", "report.md", "stress_strain.png"]
    report = _strict_json(out / "report.json")
    for key in KEYS:
        assert set(report[key]) == {"value", "method", "reason"} and report[key]["method"], key
    assert "specimen" in report and "source" in report
    # the iDICs guide's tables, from the recording's session metadata
    assert report["analysis"]["subset_px"] == 21 and report["analysis"]["subpixel"] == "icgn"
    assert report["analysis"]["shape_function"].startswith("first order")
    assert report["hardware"]["camera"].startswith("livedic simulator")
    html = (out / "report.html").read_text()
    assert "<table>" in html and "data:image/png;base64," in html and 'src="stress_strain.png"' not in html
    assert report["specimen"]["area_mm2"] == AREA_MM2 and report["specimen"]["gauge_length_px"] == 200.0
    peak = test_run["peak"]
    rm_law = float(test_run["force"][peak] / AREA_MM2)
    # E: the axial extensometer reads the exact strain within 50 microstrain + 0.5 % (export/test_recomputed_strain.py);
    # over the fitted range (about 0.002 to 0.008) that is within 2 % of the slope.
    assert abs(report["E_GPa"]["value"] / (E_MPA / 1000.0) - 1.0) <= 0.02, report["E_GPa"]
    assert abs(report["Rm_MPa"]["value"] / rm_law - 1.0) <= 0.01, report["Rm_MPa"]
    # Rp0.2 moves by the hardening slope times the strain error (2 GPa x 1e-4 = 0.2 MPa): within 1 %.
    assert abs(report["Rp02_MPa"]["value"] / _law_rp02_MPa() - 1.0) <= 0.01, report["Rp02_MPa"]
    # Ag = strain at Rm - Rm / E (%): the strain there is read within 50e-6 + 0.5 % x 0.053 = 3.2e-4, and
    # Rm / E moves by 2 % of 0.023: 0.1 percentage point in all.
    ag_law = 100.0 * (test_run["exact"][peak] - rm_law / E_MPA)
    assert abs(report["Ag_percent"]["value"] - ag_law) <= 0.1, report["Ag_percent"]
    # the force never drops below 10 % of Rm: no fracture, A is null with the reason
    assert report["A_percent"]["value"] is None and report["A_percent"]["reason"]
    text = (out / "report.md").read_text()
    assert "![stress-strain curve](stress_strain.png)" in text and "| Rp0.2 |" in text and "200.0 px" in text
    # Poisson's ratio: labelled with its frames and range, in the table; the plastic ratio in report.json only.
    # (This force law is not the simulator's own: its E range reaches past the images' elastic 0.4 %, so only
    # the form is checked here; tests/stream/session/test_session_numbers.py checks the value on the simulator's law.)
    nu = report["poisson_ratio"]
    assert set(nu) >= {"value", "stderr", "label", "frames", "axial_strain_range", "basis", "method", "reason"}
    assert nu["label"].startswith("Poisson's ratio (elastic") and f"| {nu['label']} |" in text
    assert report["plastic_contraction_ratio"]["label"].startswith("plastic contraction ratio")
    assert "plastic contraction" not in text


@pytest.mark.parametrize("options, says", [
    (["--area", "0"], "--area"),
    (["--area", "-3"], "--area"),
    (["--width", "10"], "--thickness is missing"),
    (["--area", "20", "--width", "10", "--thickness", "2"], "not both"),
    ([], "cross-section"),
])
def test_bad_cross_section_is_one_line_and_writes_nothing(test_run, tmp_path, capsys, options, says):
    for command in ("export", "report"):
        out = tmp_path / command
        code = main([command, test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
                     *options])
        line = _one_error_line(capsys.readouterr().err)
        assert code == 2 and says in line and not out.exists(), (command, line)


@pytest.mark.parametrize("load, says", [
    ("tcp://127.0.0.1:5000", "csv:FILE"),
    ("csv:/nonexistent/force.csv", "cannot be read"),
])
def test_bad_load_is_one_line_and_writes_nothing(test_run, tmp_path, capsys, load, says):
    for command in ("export", "report"):
        out = tmp_path / command
        code = main([command, test_run["recording"], "-o", str(out), "--load", load, "--area", "20"])
        line = _one_error_line(capsys.readouterr().err)
        assert code == 2 and says in line and not out.exists(), (command, line)


def test_area_without_load_and_no_axial_extensometer(test_run, tmp_path, capsys):
    out = tmp_path / "export"
    code = main(["export", test_run["recording"], "-o", str(out), "--area", "20"])
    assert code == 2 and "without --load" in _one_error_line(capsys.readouterr().err) and not out.exists()
    for command in ("export", "report"):
        out = tmp_path / command
        code = main([command, test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
                     "--area", "20", "--extensometer", "upper=180,150,180,350"])
        line = _one_error_line(capsys.readouterr().err)
        assert code == 2 and "'axial' extensometer" in line and not out.exists(), (command, line)


def test_load_offset_shifts_the_file_onto_the_frames(test_run, tmp_path):
    """A file whose clock starts 0.25 s late, with --load-offset 0.25: the same force at every frame."""
    late = tmp_path / "late.csv"
    _write_force(late, test_run["time_s"] - 0.25, test_run["force"])
    out = tmp_path / "export"
    assert main(["export", test_run["recording"], "-o", str(out), "--load", f"csv:{late}", "--load-offset", "0.25",
                 "--area", str(AREA_MM2)]) == 0
    _, rows = _rows(out / "stress_strain.csv")
    assert np.allclose(_col(rows, "force_N"), test_run["force"], rtol=1e-9, atol=1e-9)


def test_report_without_any_force_says_why_each_value_is_missing(test_run, tmp_path):
    """Force samples that end before the first frame (offset -100 s): every property null, with its reason."""
    out = tmp_path / "report"
    assert main(["report", test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
                 "--load-offset", "-100", "--area", str(AREA_MM2)]) == 0
    report = _strict_json(out / "report.json")
    assert report["source"]["frames_with_force"] == 0 and report["source"]["uniform_frame"] is None
    for key in KEYS:
        assert report[key]["value"] is None and report[key]["reason"], key
    assert "n/a" in (out / "report.md").read_text()
    # Poisson's ratio needs no force: the linear part of transverse vs axial
    assert report["poisson_ratio"]["basis"] == "linear_part"
    assert report["poisson_ratio"]["method"].startswith("elastic range: ")
    assert "transverse against axial strain" in report["poisson_ratio"]["method"]


def test_existing_report_files_are_kept_without_overwrite(test_run, tmp_path, capsys):
    out = tmp_path / "report"
    out.mkdir()
    (out / "report.json").write_text("keep")
    options = ["report", test_run["recording"], "-o", str(out), "--load", f"csv:{test_run['force_csv']}",
               "--area", str(AREA_MM2)]
    assert main(options) == 2 and "--overwrite" in _one_error_line(capsys.readouterr().err)
    assert (out / "report.json").read_text() == "keep" and sorted(os.listdir(out)) == ["report.json"]
    assert main(options + ["--overwrite"]) == 0 and _strict_json(out / "report.json")["Rm_MPa"]["value"] > 0


def test_table_true_values_stop_at_the_first_maximum_and_need_a_force():
    from livedic.stream.stages.stress import stress_strain_table
    strain = np.array([0.0, 0.01, 0.02, 0.03, 0.04])
    table = stress_strain_table([0, 1, 2, 3, 4], [0, 1, 2, 3, 4], [0.0, 50.0, 80.0, 80.0, 60.0], strain, 4.0)
    assert table.uniform_frame == 2                               # a tie: the first frame with the maximum
    assert np.array_equal(table.eng_stress_MPa, [0.0, 12.5, 20.0, 20.0, 15.0])
    assert np.allclose(table.true_stress_MPa[:3], [0.0, 12.625, 20.4], rtol=1e-15, atol=0)
    assert np.isnan(table.true_strain[3:]).all() and np.isnan(table.true_stress_MPa[3:]).all()
    none = stress_strain_table([0, 1], [0, 1], [np.nan, np.nan], [0.0, 0.01], 4.0)
    assert none.uniform_frame == -1 and np.isnan(none.true_strain).all() and np.isnan(none.eng_stress_MPa).all()


# ----------------------------------------------------------------------------- the recorded force (/machine/force)

LOST_ROW = 10      # the load had no value for this frame: NaN recorded, NaN exported


def _with_force(test_run, name, *, area_in_metadata):
    """The test run's session and results written again with the Recorder, plus the law's force per frame on
    /machine/force (as the live session records it), NaN at ``LOST_ROW``."""
    from livedic.acquire.recording.writer import Recorder

    source = test_run["recording"]
    metadata = {key: value for key, value in read_session(source).items() if not key.startswith("livedic.")}
    if area_in_metadata:
        metadata["area_mm2"] = AREA_MM2
    path = test_run["folder"] / name
    force = test_run["force"].copy()
    force[LOST_ROW] = np.nan
    with Recorder(path, metadata) as rec:
        for result, f in zip(read_results(source), force):
            assert rec.write_results(result.frame_index, result.timestamp_ns, result.point_id, result.x, result.y,
                                     result.u, result.v, result.zncc, result.ok)
            assert rec.write_force(result.frame_index, result.timestamp_ns, f, f / AREA_MM2,
                                   source="synthetic:tensile")
    assert rec.error is None and rec.force_written == len(force)
    return str(path), force


@pytest.fixture(scope="module")
def force_recordings(test_run):
    with_area, force = _with_force(test_run, "force-area.mcap", area_in_metadata=True)
    without_area, _ = _with_force(test_run, "force-no-area.mcap", area_in_metadata=False)
    return {"with_area": with_area, "without_area": without_area, "force": force}


def test_export_without_load_uses_the_recorded_force(test_run, force_recordings, tmp_path, capsys):
    """Force per frame as recorded (NaN where it was), A0 from the session's area_mm2, strain as always."""
    out = tmp_path / "export"
    assert main(["export", force_recordings["with_area"], "-o", str(out)]) == 0
    assert "stress_strain.csv, stress_strain.png" in capsys.readouterr().err
    header, rows = _rows(out / "stress_strain.csv")
    assert header == HEADER and np.array_equal(_col(rows, "frame"), test_run["frames"])
    force, stress = _col(rows, "force_N"), _col(rows, "eng_stress_MPa")
    want = force_recordings["force"]
    lost = np.arange(len(want)) == LOST_ROW
    assert np.array_equal(force[~lost], want[~lost]) and np.isnan(force[lost]).all()     # bit for bit
    assert np.isnan(stress[lost]).all()
    assert np.all(np.abs(stress[~lost] - want[~lost] / AREA_MM2) <= 1e-12 * np.abs(stress[~lost]))
    _, ext = _rows(out / "extensometers.csv")
    assert np.array_equal(_col(rows, "eng_strain"), _col([r for r in ext if r["name"] == "axial"], "eng_strain"))
    stress_entry = _strict_json(out / "session.json")["livedic.export"]["stress"]
    assert stress_entry["load"] == "recorded:/machine/force" and stress_entry["area_mm2"] == AREA_MM2
    assert stress_entry["recorded_source"] == "synthetic:tensile"
    assert stress_entry["frames_with_force"] == len(want) - 1


def test_recorded_force_takes_the_cross_section_from_the_options_or_asks_for_it(force_recordings, tmp_path,
                                                                                  capsys):
    out = tmp_path / "export"
    code = main(["export", force_recordings["without_area"], "-o", str(out)])
    line = _one_error_line(capsys.readouterr().err)
    assert code == 2 and "--area" in line and "/machine/force" in line and not out.exists(), line
    assert main(["export", force_recordings["without_area"], "-o", str(out), "--width", "5",
                 "--thickness", "2"]) == 0
    _, rows = _rows(out / "stress_strain.csv")
    force, stress = _col(rows, "force_N"), _col(rows, "eng_stress_MPa")
    ok = np.isfinite(force)
    assert np.all(np.abs(stress[ok] - force[ok] / 10.0) <= 1e-12 * np.abs(stress[ok]))


def test_a_given_load_replaces_the_recorded_force_with_a_note(test_run, force_recordings, tmp_path, capsys):
    half = tmp_path / "half.csv"
    _write_force(half, test_run["time_s"], 0.5 * test_run["force"])
    out = tmp_path / "export"
    assert main(["export", force_recordings["with_area"], "-o", str(out), "--load", f"csv:{half}",
                 "--area", str(AREA_MM2)]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "/machine/force" in line]
    assert len(notes) == 1 and notes[0].startswith("livedic: note: --load csv:"), notes
    _, rows = _rows(out / "stress_strain.csv")
    assert np.allclose(_col(rows, "force_N"), 0.5 * test_run["force"], rtol=1e-12, atol=0)


def test_report_reads_the_recorded_force(test_run, force_recordings, tmp_path):
    from livedic.stream.export.report import report_recording
    from livedic.stream.stages.stress import RECORDED_FORCE, StressOptions

    out = tmp_path / "report"
    report = report_recording(force_recordings["with_area"], out,
                              stress=StressOptions(RECORDED_FORCE, 0.0, AREA_MM2))
    assert sorted(os.listdir(out)) == ["report.html", "report.json", "report.md", "stress_strain.png"]
    assert report["source"]["frames_with_force"] == len(test_run["frames"]) - 1
    assert report["source"]["recorded_source"] == "synthetic:tensile"
    # the same law as test_report_recovers_the_laws_properties, one elastic frame without force: same tolerances
    rm_law = float(test_run["force"][test_run["peak"]] / AREA_MM2)
    assert abs(report["E_GPa"]["value"] / (E_MPA / 1000.0) - 1.0) <= 0.02, report["E_GPa"]
    assert abs(report["Rm_MPa"]["value"] / rm_law - 1.0) <= 0.01, report["Rm_MPa"]
    assert abs(report["Rp02_MPa"]["value"] / _law_rp02_MPa() - 1.0) <= 0.01, report["Rp02_MPa"]


def test_export_of_a_recording_without_force_is_unchanged(test_run, tmp_path, capsys):
    """No --load, no /machine/force: no stress files and no note, as before the channel existed."""
    out = tmp_path / "export"
    assert main(["export", test_run["recording"], "-o", str(out)]) == 0
    assert "/machine/force" not in capsys.readouterr().err and not (out / "stress_strain.csv").exists()


def _report_args(recording, out):
    """``livedic report`` arguments without --load (the parser asks for it today: the recorded force needs none)."""
    from livedic.stream.cli import build_parser
    args = build_parser().parse_args(["report", recording, "-o", str(out), "--load", "csv:unused.csv"])
    args.load = None
    return args


def test_report_command_without_load_reads_the_recorded_force_or_says_what_is_missing(test_run, force_recordings,
                                                                                       tmp_path, capsys):
    from livedic.stream.cli.report import report_command

    out = tmp_path / "report"
    assert report_command(_report_args(force_recordings["with_area"], out)) == 0
    assert "report: E " in capsys.readouterr().err
    report = _strict_json(out / "report.json")
    assert report["specimen"]["area_mm2"] == AREA_MM2 and report["source"]["load"] == "recorded:/machine/force"
    assert "as recorded on `/machine/force` (from `synthetic:tensile`)" in (out / "report.md").read_text()
    none = tmp_path / "none"
    with pytest.raises(ValueError, match="the report needs the machine's force"):
        report_command(_report_args(test_run["recording"], none))
    assert not none.exists()


def test_force_coverage_notes_say_what_is_missing():
    from livedic.stream.stages.stress import force_coverage_notes
    frames = np.arange(10)
    times = frames * 0.02
    strain = np.full(10, 0.01)
    assert force_coverage_notes(frames, times, np.ones(10), strain) == []
    none, = force_coverage_notes(frames, times, np.full(10, np.nan), strain)
    assert "no frame has a force" in none and "0-0.18 s" in none and "--load-offset" in none
    force = np.ones(10)
    force[[2, 3, 7]] = np.nan
    gaps, = force_coverage_notes(frames, times, force, strain)
    assert "no force at 3 of 10 frames with a strain (frames 2-3, 7)" in gaps
    strain[7] = np.nan                      # no strain there either: nothing is missing for the curve
    assert "(frames 2-3)" in force_coverage_notes(frames, times, force, strain)[0]


def test_a_force_file_takes_the_recorded_cross_section_when_none_is_given(test_run, force_recordings, tmp_path,
                                                                          capsys):
    """--load csv:FILE without --area on a recording whose session holds A0: that A0 (the stress is F / A0);
    without one in the recording the cross-section is asked for, one line."""
    out = tmp_path / "with"
    assert main(["export", force_recordings["with_area"], "-o", str(out), "--load",
                 f"csv:{test_run['force_csv']}"]) == 0
    _, rows = _rows(out / "stress_strain.csv")
    force, stress = _col(rows, "force_N"), _col(rows, "eng_stress_MPa")
    finite = np.isfinite(force)
    assert finite.any()
    np.testing.assert_allclose(stress[finite], force[finite] / AREA_MM2, rtol=1e-12)
    capsys.readouterr()
    missing = tmp_path / "without"
    assert main(["export", force_recordings["without_area"], "-o", str(missing), "--load",
                 f"csv:{test_run['force_csv']}"]) == 2
    assert "cross-section" in _one_error_line(capsys.readouterr().err) and not missing.exists()


def test_report_states_the_extensometer_class_verified_or_not(test_run, tmp_path, capsys):
    from livedic.dic.strain.iso9513 import classify
    from livedic.stream.export.report_verification import VERIFICATION_KIND
    entry = classify([0.0, 2.0], [[0.001, -0.001], [2.002, 2.004]], 200.0, scale_px_per_mm=10.0).as_dict()
    verification = tmp_path / "verification.json"
    verification.write_text(json.dumps({"kind": VERIFICATION_KIND, "date": "2026-12-02", "gauge_lengths": [entry],
                                        "settings": {"subset": 21, "scale_px_per_mm": 10.0}}))
    load = ["--load", f"csv:{test_run['force_csv']}", "--area", str(AREA_MM2)]
    assert main(["report", test_run["recording"], "-o", str(tmp_path / "verified"), *load,
                 "--verification", str(verification)]) == 0
    assert "ISO 9513 class 0.2 (verified)" in capsys.readouterr().err
    report = _strict_json(tmp_path / "verified" / "report.json")
    assert report["extensometer_verification"]["class"] == "0.2"
    assert "class met: **0.2** at L0 200 px" in (tmp_path / "verified" / "report.md").read_text()
    assert main(["report", test_run["recording"], "-o", str(tmp_path / "plain"), *load]) == 0
    assert "ISO 9513 class not verified" in capsys.readouterr().err
    assert not _strict_json(tmp_path / "plain" / "report.json")["extensometer_verification"]["verified"]
    verification.write_text("[]")
    assert main(["report", test_run["recording"], "-o", str(tmp_path / "bad"), *load,
                 "--verification", str(verification)]) == 2
    assert "not an extensometer verification" in _one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "bad").exists()
