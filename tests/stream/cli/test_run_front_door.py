"""``livedic run`` at the front door (issue 8): what can be checked is checked before anything is opened,
bad input leaves no file, a stop signal is clean at any moment, P0 sits on the specimen, the summary is
strict JSON and is printed even when the viewer fails."""

import json
import os
import signal
import socket
import subprocess
import sys

import cv2
import numpy as np
import pytest

from livedic.stream.cli import main
from tests.stream.conftest import HOLE_CENTRE, HOLE_RADIUS, holed_image

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SMALL = "synthetic:tensile?size=96x160&frames=3&fps=1000"


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def _one_error_line(err):
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and "Traceback" not in err, err
    return lines[0]


def _outputs(tmp_path):
    return ["--record", str(tmp_path / "out" / "session.mcap"), "--viewer", "save", str(tmp_path / "out" / "s.rrd"),
            "--summary-json", str(tmp_path / "summary.json")]


def _left_behind(tmp_path, keep=()):
    return sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file() and p.name not in keep)


# --------------------------------------------------------------------------- bad points: nothing left behind

@pytest.mark.parametrize("extra, words", [
    (["--roi", "50,50,200,200"], "ROI 50,50,200,200 extends beyond the 96x160 image"),
    (["--p0", "500,20", "--roi", "0,0,96,160"], "P0 (500, 20) is outside the 96x160 image"),
    (["--step", "1", "--roi", "0,0,96,160", "--max-points", "1000"],
     "--step 1 gives 10,640 points, more than livedic run tracks live (--max-points 1,000; about 74 MB of memory"),
])
def test_bad_points_are_refused_before_any_output_is_opened(extra, words, tmp_path, capsys):
    capsys.readouterr()
    assert main(["run", "--source", SMALL, "--progress", "off", *_outputs(tmp_path), *extra]) == 2
    line = _one_error_line("\n".join(l for l in capsys.readouterr().err.splitlines() if "simulator:" not in l))
    assert words in line, line
    assert _left_behind(tmp_path) == []          # no 1 MB recording with one frame, no .rrd, no summary


def test_more_points_run_when_the_limit_is_raised(tmp_path, capsys):
    summary = tmp_path / "summary.json"
    argv = ["run", "--source", "synthetic:tensile?size=96x128&frames=3&pace=0", "--progress", "off", "--no-record",
            "--viewer", "none", "--step", "2", "--roi", "0,0,96,128", "--summary-json", str(summary)]
    capsys.readouterr()
    assert main(argv + ["--max-points", "2000"]) == 2
    err = "\n".join(line for line in capsys.readouterr().err.splitlines() if "simulator:" not in line)
    assert "--step 2 gives 2,052 points, more than livedic run tracks live (--max-points 2,000" in _one_error_line(err)
    assert main(argv + ["--max-points", "3000"]) == 0
    assert json.loads(summary.read_text())["points"] == 2052


def test_max_points_must_be_positive(capsys):
    assert main(["run", "--source", SMALL, "--no-record", "--viewer", "none", "--max-points", "0"]) == 2
    assert "--max-points must be >= 1" in _one_error_line(capsys.readouterr().err)


# --------------------------------------------------------------------------- outputs checked first

@pytest.mark.parametrize("variant", ["read-only", "denied", "under-a-file"])
@pytest.mark.parametrize("option", ["--record", "--viewer save", "--summary-json"])
def test_an_unwritable_output_is_refused_before_the_session(option, variant, tmp_path, capsys, monkeypatch,
                                                           unwritable_folder):
    folder = unwritable_folder(variant)
    target = {"--record": "s.mcap", "--viewer save": "s.rrd", "--summary-json": "s.json"}[option]
    outputs = {"--record": ["--no-record"], "--viewer save": ["--viewer", "none"], "--summary-json": []}
    argv = ["run", "--source", SMALL, "--progress", "off"]
    for name, default in outputs.items():
        argv += option.split() + [str(folder / target)] if name == option else default
    capsys.readouterr()
    try:
        code = main(argv)
    finally:
        if folder.is_dir():
            folder.chmod(0o755)
    captured = capsys.readouterr()
    assert code == 2
    line = _one_error_line(captured.err)          # only this line: not even the simulator rendered
    assert f"cannot write {option} {folder / target}" in line and "internal" not in line
    assert "not writable" in line or "not a folder" in line
    assert captured.out == ""                     # no session, no summary


def test_a_summary_json_naming_a_folder_is_one_clear_line(tmp_path, capsys):
    assert main(["run", "--source", SMALL, "--no-record", "--viewer", "none", "--summary-json", str(tmp_path)]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"--summary-json {tmp_path} is a folder: give a file name" in line and ".livedic-" not in line


# --------------------------------------------------------------------------- the viewer

def _closed_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]        # free once closed: nothing listens there


def test_connect_to_no_viewer_fails_first_with_one_line(tmp_path, capsys):
    port = _closed_port()
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    capsys.readouterr()
    assert main(["run", "--source", SMALL, "--progress", "off", "--record", str(tmp_path / "s.mcap"),
                 "--viewer", "connect", url]) == 2
    captured = capsys.readouterr()
    line = _one_error_line(captured.err)
    assert f"no Rerun viewer is listening at 127.0.0.1:{port}" in line and "--viewer save" in line
    assert captured.out == "" and _left_behind(tmp_path) == []


def test_connect_to_a_listening_viewer_goes_ahead(monkeypatch):
    from livedic.stream.session.session import check_viewer_reachable
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        check_viewer_reachable(f"rerun+http://127.0.0.1:{server.getsockname()[1]}/proxy")   # no error


def test_the_summary_is_printed_even_when_the_viewer_fails_to_close(tmp_path, capsys, monkeypatch):
    from livedic.stream.view.process import ViewProcess

    close = ViewProcess.close

    def broken_close(self):
        close(self)                           # the view's process ends all the same
        raise RuntimeError("Flush timed out")

    monkeypatch.setattr(ViewProcess, "close", broken_close)
    summary = tmp_path / "summary.json"
    assert main(["run", "--source", "synthetic:tensile?size=96x160&frames=4&pace=0", "--progress", "off",
                 "--no-record", "--viewer", "save", str(tmp_path / "s.rrd"), "--n-points", "20", "--roi", "0,0,96,160",
                 "--summary-json", str(summary)]) == 0
    captured = capsys.readouterr()
    assert "livedic run: synthetic:tensile" in captured.out and "frames     14 tracked" in captured.out   # 4 after 10 static
    assert "warning: closing the Rerun stream failed: RuntimeError: Flush timed out" in captured.err
    assert json.loads(summary.read_text())["frames"] == 14


# --------------------------------------------------------------------------- summary JSON

def test_the_summary_json_is_strict_json_with_null_for_missing_numbers(tmp_path):
    """One frame: no latency percentiles (NaN in Python) -> null, not NaN (which is not JSON)."""
    summary = tmp_path / "summary.json"
    assert main(["run", "--source", "synthetic:tensile?size=96x160&pace=0", "--frames", "1", "--static-frames", "0",
                 "--progress", "off",
                 "--no-record", "--viewer", "none", "--n-points", "20", "--roi", "0,0,96,160",
                 "--summary-json", str(summary)]) == 0
    text = summary.read_text()
    data = json.loads(text, parse_constant=lambda name: pytest.fail(f"summary JSON holds {name}"))
    assert data["frames"] == 1 and data["latency_p50_ms"] is None
    from livedic.stream.output.files import current_umask
    assert summary.stat().st_mode & 0o777 == 0o666 & ~current_umask()


# --------------------------------------------------------------------------- stop signals

def _livedic(tmp_path, *argv):
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("LIVEDIC_DEBUG", None)
    return subprocess.Popen([sys.executable, "-m", "livedic.stream.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=str(tmp_path), env=env)


def test_sigterm_while_the_simulator_renders_ends_cleanly_with_exit_0(tmp_path, signal_when):
    """SIGTERM as soon as the progress bar says the test is being rendered (300 frames of 1 MP: many
    seconds): exit 0, one line saying so, and no recording (none was opened yet)."""
    process = _livedic(tmp_path, "run", "--frames", "300", "--record", "session.mcap", "--viewer", "save",
                       "session.rrd", "--progress", "on", "--summary-json", "summary.json")
    text, out = signal_when(process, lambda err: b"rendering the simulated test" in err, signal.SIGTERM)
    assert process.returncode == 0, text
    assert ("stopped on SIGTERM while rendering the simulated test, before the session started: nothing was "
            "recorded") in text
    assert "Traceback" not in text and out == b""
    assert _left_behind(tmp_path) == []


# --------------------------------------------------------------------------- P0 on the specimen

def test_a_run_on_a_holed_specimen_traces_p0_on_the_speckle_and_says_why(tmp_path, capsys):
    from livedic.acquire.recording.reader import read_events, read_results
    frames = tmp_path / "frames"
    frames.mkdir()
    for i in range(4):
        assert cv2.imwrite(str(frames / f"f{i}.png"), holed_image((0.4 * i, -0.3 * i)))
    record = tmp_path / "holed.mcap"
    summary = tmp_path / "summary.json"
    capsys.readouterr()
    assert main(["run", "--source", f"images:{frames}", "--progress", "off", "--viewer", "none", "--record",
                 str(record), "--step", "20", "--summary-json", str(summary)]) == 0
    data = json.loads(summary.read_text())
    x, y = data["p0"]
    assert data["p0_choice"] == "MOVED_OFF_WEAK_CENTRE" and data["p0_weak"] is False
    assert np.hypot(max(abs(x - HOLE_CENTRE[0]) - 10, 0), max(abs(y - HOLE_CENTRE[1]) - 10, 0)) > HOLE_RADIUS
    results = read_results(str(record))
    last = results[-1]
    assert (last.x[0], last.y[0]) == (x, y) and last.ok[0] and last.zncc[0] > 0.95
    assert abs(last.u[0] - 1.2) < 0.05 and abs(last.v[0] + 0.9) < 0.05
    notes = [e.message for e in read_events(str(record)) if e.kind == "note"]
    # the specimen found in the image: its middle is in the hole (the centroid of a region with a hole in it)
    assert any("is not on specimen texture" in n and f"({x:g}, {y:g})" in n and "speckled specimen" in n
               for n in notes)
    assert "warning" not in capsys.readouterr().err

    # A P0 given in the hole: the run goes on, with a warning on stderr and in the recording.
    record2 = tmp_path / "given.mcap"
    assert main(["run", "--source", f"images:{frames}", "--progress", "off", "--viewer", "none", "--record",
                 str(record2), "--step", "20", "--p0", "120,100"]) == 0
    err = capsys.readouterr().err
    assert "warning: P0 (120, 100) given with --p0 is on weak texture" in err
    # ... and that it is not even ok in the reference frame (a flat subset is not measured at all)
    assert "warning: P0 (120, 100) is not ok in the reference frame (subset has too little texture" in err, err
    assert "P0 was lost" not in err
    assert any(e.kind == "p0_weak" for e in read_events(str(record2)))


def test_a_truncated_recording_replayed_says_so_in_a_livedic_line(tmp_path):
    """The reader's note on a recording cut short is said like every other message: ``livedic: note: ...``."""
    sample = os.path.join(REPO, "recordings", "sample-tensile.mcap")
    cut = tmp_path / "cut.mcap"
    with open(sample, "rb") as whole:
        cut.write_bytes(whole.read()[:os.path.getsize(sample) * 6 // 10])
    argv = ["run", "--viewer", "none", "--no-record", "--progress", "off", "--source", f"mcap:{cut}"]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    assert all(line.startswith("livedic: ") for line in lines), done.stderr
    assert any(line.startswith(f"livedic: note: {cut} is truncated (the recording did not finish") for line in lines)
