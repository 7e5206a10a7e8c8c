"""``--interpolation`` end to end: ``livedic run`` records it in the session metadata, ``livedic replay`` tracks
with the recorded value (or the one given), and ``livedic report`` names the interpolant in the analysis table."""

import json

import pytest

from livedic.acquire.recording.reader import read_session
from livedic.stream.cli import main
from livedic.stream.replay.replay import replay
from tests.stream.cli.conftest import SHORT_SOURCE, livedic_lines


@pytest.fixture(scope="module")
def quintic_run(tmp_path_factory):
    """``short_run`` of conftest.py with ``--interpolation BSPLINE5`` (not yet in its canonical text)."""
    path = tmp_path_factory.mktemp("quintic_run") / "quintic.mcap"
    code = main(["run", "--source", SHORT_SOURCE, "--load", "synthetic", "--record", str(path), "--viewer", "none",
                 "--progress", "off", "--gauge-length", "100", "--static-frames", "0",
                 "--interpolation", "BSPLINE5"])
    assert code == 0 and path.exists()
    return str(path)


def test_run_records_the_interpolation_in_its_canonical_text(quintic_run, short_run):
    assert read_session(quintic_run)["interpolation"] == "bspline5"
    assert read_session(short_run)["interpolation"] == "bspline3"


def test_replay_tracks_with_the_recorded_interpolation_and_repeats_the_live_results(quintic_run):
    report = replay(quintic_run)
    assert report.params["interpolation"] == report.recorded_params["interpolation"] == "bspline5"
    assert not report.changed
    assert report.compared_frames > 1 and report.mismatched_frames == 0 and report.max_du == report.max_dv == 0.0


def test_replay_with_the_cubic_says_so_and_measures_otherwise(quintic_run):
    report = replay(quintic_run, {"interpolation": "bspline3"})
    assert report.changed == [("interpolation", "bspline5", "bspline3")]
    assert report.max_du > 0.0 or report.max_dv > 0.0


def test_the_report_analysis_table_names_the_quintic(quintic_run, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", quintic_run, "-o", str(out)]) == 0
    livedic_lines(capsys.readouterr().err)
    assert "biquintic B-spline" in json.loads((out / "report.json").read_text())["analysis"]["interpolant"]
    row = next(line for line in (out / "report.md").read_text().splitlines() if "grey-level interpolant" in line)
    assert "biquintic B-spline" in row


def test_replay_refuses_a_bad_interpolation_in_one_line(quintic_run, tmp_path, capsys):
    out = tmp_path / "rows.csv"
    capsys.readouterr()
    assert main(["replay", quintic_run, "-o", str(out), "--progress", "off", "--interpolation", "linear"]) == 2
    lines = livedic_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "unknown interpolation 'linear'" in lines[0] and not out.exists()
