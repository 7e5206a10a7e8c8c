"""Tests of stream/cli/export.py: what ``livedic export`` says and returns (its lines, exit codes 0, 2 and
128 + a stop signal), on the short recording of tests/stream/cli/conftest.py."""

import os
import signal

import pytest

from livedic.stream.cli import main
from tests.stream.cli.conftest import livedic_lines


def _lines(capsys):
    return livedic_lines(capsys.readouterr().err)


def test_the_csv_files_only_and_what_was_written(short_run, tmp_path, capsys):
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["export", short_run, "-o", str(out), "--maps", "none", "--video", "none", "--no-vtk",
                 "--progress", "off"]) == 0
    lines = _lines(capsys)
    summary = next(line for line in lines if line.startswith("livedic: exported "))
    assert summary.startswith("livedic: exported 4 frames x 1081 points, P0 = point 0 (4 rows), ")
    assert summary.endswith(f"to {out}/ (p0_trace.csv, fields.csv, events.csv, session.json, extensometers.csv, "
                            f"extensometers.png, stress_strain.csv, stress_strain.png)")
    assert any("extensometers axial L0 100.0 px" in line for line in lines)
    assert not any(line.startswith("livedic: and ") for line in lines)          # no pictures asked for
    assert sorted(os.listdir(out)) == sorted(["p0_trace.csv", "fields.csv", "events.csv", "session.json",
                                              "extensometers.csv", "extensometers.png", "stress_strain.csv",
                                              "stress_strain.png"])


def test_the_pictures_are_said_in_one_more_line(short_run, tmp_path, capsys):
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["export", short_run, "-o", str(out), "--maps", "u", "--every", "2", "--video", "none",
                 "--progress", "off"]) == 0
    lines = _lines(capsys)
    assert "livedic: and 3 maps, 4 .vtu files and fields.pvd" in lines      # frames 0, 2 and the last, 3


@pytest.mark.parametrize("options, words", [
    (["--strain-window", "2"], "--strain-window"),
    (["--every", "0"], "--every 0"),
    (["--load", "tcp://localhost:1", "--area", "3"], "--load 'tcp://localhost:1'"),
])
def test_bad_options_are_one_line_exit_2_before_anything_is_written(options, words, short_run, tmp_path, capsys):
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["export", short_run, "-o", str(out), *options]) == 2
    lines = _lines(capsys)
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and words in lines[0], lines
    assert not out.exists()


def test_a_missing_recording_is_one_line_exit_2(tmp_path, capsys):
    assert main(["export", str(tmp_path / "missing.mcap"), "-o", str(tmp_path / "out")]) == 2
    lines = _lines(capsys)
    assert len(lines) == 1 and "missing.mcap" in lines[0] and not (tmp_path / "out").exists()


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_stop_is_one_line_saying_what_was_left_and_exit_128_plus_the_signal(signum, code, short_run, tmp_path,
                                                                             capsys, monkeypatch):
    import livedic.stream.cli.export as command
    from livedic.stream.export.stop import ExportStopped

    def stopped(*_args, **_kwargs):
        error = ExportStopped(signal.Signals(signum).name, signum)
        error.state = "while writing the CSV files: nothing was written"
        raise error
    monkeypatch.setattr(command, "export_recording", stopped)
    capsys.readouterr()
    before = signal.getsignal(signal.SIGTERM)
    assert main(["export", short_run, "-o", str(tmp_path / "out"), "--progress", "off"]) == code
    assert _lines(capsys) == [f"livedic: export stopped on {signal.Signals(signum).name} while writing the CSV "
                              f"files: nothing was written"]
    assert signal.getsignal(signal.SIGTERM) is before        # StopSignals put the previous handler back
