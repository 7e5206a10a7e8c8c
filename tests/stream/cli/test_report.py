"""Tests of stream/cli/report.py: what ``livedic report`` says (the properties in one line, the notes) and its
refusals (exit 2, one line, nothing written), on the short recording of tests/stream/cli/conftest.py.

The properties against a known law are in tests/stream/stages/test_stress.py and test_session_force.py.
"""

import json
import os

import pytest

from livedic.stream.cli import main
from tests.stream.cli.conftest import livedic_lines
from livedic.stream.export.report import CURVE_SHAPE_KEY, PROPERTY_KEYS, PROPERTY_TITLES, REPORT_FILES, YIELD_KEYS


def _lines(capsys):
    return livedic_lines(capsys.readouterr().err)


def test_the_report_line_says_each_property_as_report_json_has_it(short_run, tmp_path, capsys):
    out = tmp_path / "report"
    capsys.readouterr()
    assert main(["report", short_run, "-o", str(out)]) == 0       # the recorded force and the simulator's A0
    lines = _lines(capsys)
    report = json.loads((out / "report.json").read_text())
    words = []
    continuous = report[CURVE_SHAPE_KEY]["value"] == "continuous"
    for key in PROPERTY_KEYS:
        if continuous and key in YIELD_KEYS:          # no yield phenomenon: report.md says why
            continue
        name, unit = PROPERTY_TITLES[key]
        value = report[key]["value"]
        words.append(f"{name} {'n/a' if value is None else f'{value:.4g} {unit}'}")
    nu = report["poisson_ratio"]["value"]
    words.append(f"Poisson's ratio (elastic) {'n/a' if nu is None else f'{nu:.3f}'}")
    words.append("ISO 9513 class not verified")       # no --verification given
    assert lines[-1] == f"livedic: report: {', '.join(words)}; written to {out}/ ({', '.join(REPORT_FILES)})"
    assert all(line.startswith("livedic: note: ") for line in lines[:-1])
    assert report["source"]["frames_with_force"] == 4 and report["Rm_MPa"]["value"] > 0
    assert sorted(os.listdir(out)) == sorted(REPORT_FILES)


def test_a_given_load_is_said_to_replace_the_recorded_force(short_run, tmp_path, capsys):
    force = tmp_path / "force.csv"
    force.write_text("time_s,force_N\n0,0\n1,1000\n")
    capsys.readouterr()
    assert main(["report", short_run, "-o", str(tmp_path / "report"), "--load", f"csv:{force}", "--area", "10"]) == 0
    lines = _lines(capsys)
    assert f"livedic: note: --load csv:{force} is the force here, not the one recorded on /machine/force " \
           f"(4 frames)" in lines


def test_without_any_force_the_report_is_refused_in_one_line(tmp_path, capsys):
    import numpy as np
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder
    path = tmp_path / "no_force.mcap"
    with Recorder(str(path), {"command": "test"}, start_time_ns=0) as recorder:
        recorder.write_frame(Frame(0, 0, np.zeros((8, 8), np.uint8), "Mono8"))
    out = tmp_path / "report"
    assert main(["report", str(path), "-o", str(out)]) == 2
    assert _lines(capsys) == ["livedic: error: the report needs the machine's force: --load csv:FILE with the "
                              "cross-section (--area MM2, or --width MM --thickness MM), or a recording that holds "
                              "it (/machine/force)"]
    assert not out.exists()


def test_existing_report_files_are_refused_without_overwrite(short_run, tmp_path, capsys):
    out = tmp_path / "report"
    out.mkdir()
    (out / "report.md").write_text("mine")
    assert main(["report", short_run, "-o", str(out)]) == 2
    lines = _lines(capsys)
    assert lines == [f"livedic: error: {out} already holds report.md: pass --overwrite to replace it, or choose "
                     f"another folder"]
    assert (out / "report.md").read_text() == "mine" and os.listdir(out) == ["report.md"]
