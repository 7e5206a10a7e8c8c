"""Tests of stream/export/report.py: report.json (strict, null with a reason) and report.md from known properties.

The whole ``livedic report`` of a simulated test (the properties against a known law, the files, the
force recorded or from a file) is in tests/stream/stages/test_stress.py; here the report's own objects.
"""

import json

import numpy as np
import pytest

from livedic.dic.tensile.poisson import contraction_ratios
from livedic.dic.tensile.properties import tensile_properties
from livedic.stream.export.report import (CONTRACTION_KEYS, POISSON_KEY, PROPERTY_KEYS, report_json,
                                          report_markdown)
from livedic.stream.output.files import json_text

STRAIN = np.linspace(0.0, 0.1, 2001)
STRESS = np.where(STRAIN <= 0.002, 200_000.0 * STRAIN, 400.0 + 2_000.0 * (STRAIN - 0.002))   # MPa, no fracture
STRESS[-1] -= 1.0              # past the maximum force at the last frame (a test ended while it rose has no Rm)
SPECIMEN = {"area_mm2": 20.0, "gauge_length_px": 200.0, "gauge_length_mm": 10.0, "scale_px_per_mm": 20.0}
SOURCE = {"recording": "/data/test|1.mcap", "truncated": True, "load": "csv:force.csv", "load_offset_s": 0.5,
          "frames": 2001, "frames_with_force": 2000, "strain": "strain window 5", "generated_at": "today"}


@pytest.fixture(scope="module")
def report():
    properties = tensile_properties(STRAIN, STRESS)
    pair = contraction_ratios(STRAIN, -0.3 * STRAIN, force=STRESS * 20.0, frames=np.arange(STRAIN.size))
    return report_json(properties, SPECIMEN, SOURCE, pair)


def test_values_are_numbers_or_null_with_a_reason(report):
    assert report["E_GPa"]["value"] == pytest.approx(200.0, rel=1e-3)
    assert report["Rm_MPa"]["value"] == pytest.approx(596.0, abs=0.2)
    assert report["A_percent"]["value"] is None and report["A_percent"]["reason"]       # no fracture in the curve
    for key in PROPERTY_KEYS:
        item = report[key]
        assert set(item) == {"value", "method", "reason"} and item["method"]
        assert (item["value"] is None) == (item["reason"] is not None), key
    assert report[POISSON_KEY]["value"] == pytest.approx(0.3, abs=1e-9)
    assert report["specimen"] == SPECIMEN and report["source"] == SOURCE


def test_the_json_is_strict(report):
    def refuse(name):
        raise ValueError(name)
    back = json.loads(json_text(report), parse_constant=refuse)
    assert back["A_percent"]["value"] is None
    assert back[POISSON_KEY]["axial_strain_range"] == pytest.approx([0.0, 0.002])       # the elastic range
    bare = report_json(tensile_properties(STRAIN, STRESS), SPECIMEN, SOURCE)       # NaN ratios, NaN in lists
    assert bare[POISSON_KEY]["stderr"] is None and bare[POISSON_KEY]["axial_strain_range"] == [None, None]
    assert json.loads(json_text(bare), parse_constant=refuse)[POISSON_KEY]["value"] is None


def test_without_a_transverse_extensometer_both_ratios_are_null_with_a_reason(report):
    properties = tensile_properties(STRAIN, STRESS)
    bare = report_json(properties, SPECIMEN, SOURCE)
    for key in CONTRACTION_KEYS:
        assert bare[key]["value"] is None and bare[key]["reason"], key
    assert bare["E_GPa"] == report["E_GPa"]


def test_the_markdown_lists_each_property_and_escapes_table_cells(report):
    text = report_markdown(report, "stress_strain.png", "test.mcap")
    lines = text.splitlines()
    assert lines[0] == "# Tensile test: test.mcap"
    assert "- cross-section A0: 20 mm^2" in lines
    assert "- gauge length L0 (virtual extensometer `axial`): 200.0 px = 10.000 mm (20 px/mm)" in lines
    rows = {line.split("|")[1].strip(): line for line in lines if line.startswith("| ") and "---" not in line}
    assert rows["Rm"].startswith("| Rm | 595.9 | MPa | ")
    assert rows["A"].startswith("| A | n/a | % | ") and report["A_percent"]["reason"] in rows["A"]
    assert report[POISSON_KEY]["label"] in rows and "0.300 +- 0.000" in rows[report[POISSON_KEY]["label"]]
    assert "![stress-strain curve](stress_strain.png)" in lines
    assert "- recording: `/data/test|1.mcap` (truncated: what could be recovered)" in lines
    assert "- force: `csv:force.csv`, offset 0.5 s; force at 2000 of 2001 frames" in lines
    assert all(line.count("|") == 6 for line in lines if line.startswith("| "))    # a | in a cell is escaped


def test_the_markdown_of_a_recorded_force_and_a_gauge_in_pixels_only(report):
    source = dict(SOURCE, truncated=False, recorded_source="synthetic:tensile")
    specimen = dict(SPECIMEN, gauge_length_mm=None, scale_px_per_mm=None)
    text = report_markdown(dict(report, source=source, specimen=specimen), "plot.png", "t")
    assert "- gauge length L0 (virtual extensometer `axial`): 200.0 px" in text.splitlines()
    assert "- force: as recorded on `/machine/force` (from `synthetic:tensile`); force at 2000 of 2001 frames" in text
    assert "truncated" not in text


def test_a_stereo_recording_is_reported_from_its_extensometer_in_space(stereo_recording, tmp_path, capsys):
    """A stereo test with the simulator's force (E 200 GPa, Rp0.2 820 MPa), moving 0.5 mm away from the cameras and
    turning 1 degree: the report reads the strain of the axial extensometer in space, L / L0 - 1, so E and Rp0.2
    come out of the law within 2 % and 1 % (bench tensile's bounds); one camera would read the motion away as
    -0.5 / 300 = -1.7e-3 of strain over a test of 1e-2. It says it is a stereo measurement, L0 in mm in space."""
    from livedic.acquire.recording.reader import Recording
    from livedic.stream.cli.main import main
    out = tmp_path / "report"
    assert main(["report", stereo_recording, "-o", str(out)]) == 0, capsys.readouterr().err
    report = json.loads((out / "report.json").read_text())
    assert report["E_GPa"]["value"] == pytest.approx(200.0, rel=0.02)
    assert report["Rp02_MPa"]["value"] == pytest.approx(820.0, rel=0.01)
    samples = [s for s in Recording(stereo_recording).extensometer_samples() if s.name == "axial"]
    l0_mm = samples[0].l0_mm
    assert report["specimen"]["gauge_length_in_space"] and report["specimen"]["gauge_length_mm"] == l0_mm
    assert l0_mm == pytest.approx(10.0, rel=0.05) and report["specimen"]["area_mm2"] == 40.0
    stereo = report["stereo"]
    assert stereo["baseline_mm"] == pytest.approx(2 * 300 * np.sin(np.radians(12.5)), rel=1e-6)
    assert stereo["angle_deg"] == pytest.approx(25.0) and "simulator's exact rig" in stereo["calibration_from"]
    strain = [s.l_mm / s.l0_mm - 1.0 for s in samples]
    assert strain[-1] == pytest.approx(0.01, abs=1e-4)                  # the uniform strain, out-of-plane removed
    text = (out / "report.md").read_text()
    assert "## Stereo measurement" in text and f"{l0_mm:.3f} mm measured in space" in text
    assert "two cameras (stereo)" in text and "stereo rig: baseline 129.9 mm" in text
    html = (out / "report.html").read_text()
    assert "Stereo measurement" in html and "measured in space" in html
    # livedic verify checks a one-camera extensometer: no ISO 9513 class is claimed for one in space
    assert report["extensometer_verification"]["verified"] is False and report["extensometer_verification"]["in_space"]
    assert "an extensometer in space (stereo) has no verification" in text
    assert "in space (stereo) has no ISO 9513 verification" in report["extensometer_verification"]["statement"]


def test_a_stereo_recordings_strain_takes_no_strain_option(stereo_recording, tmp_path, capsys):
    from livedic.stream.cli.main import main
    assert main(["report", stereo_recording, "-o", str(tmp_path / "r"), "--strain-window", "3"]) == 2
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("livedic: error")]
    assert len(errors) == 1 and "stereo recording" in errors[0] and "livedic replay" in errors[0], errors
    assert not (tmp_path / "r").exists()
