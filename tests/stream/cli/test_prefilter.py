"""``--prefilter`` end to end: ``livedic run`` records it in the session metadata, ``livedic replay`` tracks with
the recorded value (or the one given), and ``livedic report`` shows it in the analysis table."""

import json

import pytest

from livedic.acquire.recording.reader import read_session
from livedic.stream.cli import main
from livedic.stream.replay.replay import replay
from tests.stream.cli.conftest import SHORT_SOURCE, livedic_lines

PREFILTER = "gaussian:0.6"


@pytest.fixture(scope="module")
def filtered_run(tmp_path_factory):
    """``short_run`` of conftest.py with ``--prefilter gaussian:0.60`` (not yet in its canonical text)."""
    path = tmp_path_factory.mktemp("filtered_run") / "filtered.mcap"
    code = main(["run", "--source", SHORT_SOURCE, "--load", "synthetic", "--record", str(path), "--viewer", "none",
                 "--progress", "off", "--gauge-length", "100", "--static-frames", "0",
                 "--prefilter", "gaussian:0.60"])
    assert code == 0 and path.exists()
    return str(path)


def test_run_records_the_prefilter_in_its_canonical_text(filtered_run, short_run):
    assert read_session(filtered_run)["prefilter"] == PREFILTER
    assert read_session(short_run)["prefilter"] == "none"


def test_replay_tracks_with_the_recorded_prefilter_and_repeats_the_live_results(filtered_run):
    report = replay(filtered_run)
    assert report.params["prefilter"] == report.recorded_params["prefilter"] == PREFILTER and not report.changed
    assert report.compared_frames > 1 and report.mismatched_frames == 0 and report.max_du == report.max_dv == 0.0


def test_replay_with_another_prefilter_says_so_and_measures_otherwise(filtered_run):
    report = replay(filtered_run, {"prefilter": "none"})
    assert report.changed == [("prefilter", PREFILTER, "none")]
    assert report.max_du > 0.0 or report.max_dv > 0.0         # the recorded results were filtered; these are not


def test_the_report_analysis_table_shows_the_prefilter(filtered_run, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", filtered_run, "-o", str(out)]) == 0
    livedic_lines(capsys.readouterr().err)                    # no traceback
    assert json.loads((out / "report.json").read_text())["analysis"]["prefilter"] == PREFILTER
    row = next(line for line in (out / "report.md").read_text().splitlines() if "image pre-filter" in line)
    assert "Gaussian low-pass, sigma 0.6 px (5 x 5 kernel)" in row and PREFILTER in row


@pytest.mark.parametrize("value", ["gaussian:2.5", "box:3"])
def test_replay_refuses_a_bad_prefilter_in_one_line(filtered_run, tmp_path, capsys, value):
    out = tmp_path / "rows.csv"
    capsys.readouterr()
    assert main(["replay", filtered_run, "-o", str(out), "--progress", "off", "--prefilter", value]) == 2
    lines = livedic_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "pre-filter" in lines[0] and not out.exists()
