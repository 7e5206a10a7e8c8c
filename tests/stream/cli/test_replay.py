"""Tests of stream/cli/replay.py: what ``livedic replay`` writes (rows on stdout or -o) and says (the replayed
frames, the verdict), its refusals, and the parallel line, on the short recording of tests/stream/cli/conftest.py.

How a replay compares with the recording is tested in tests/stream/replay/.
"""

import csv
import io
from types import SimpleNamespace

import pytest

from livedic.stream.cli import main
from livedic.stream.cli.replay import describe_parallel
from tests.stream.cli.conftest import livedic_lines


def test_rows_on_stdout_and_the_verdict_on_stderr(short_run, capsys):
    capsys.readouterr()
    assert main(["replay", short_run, "--progress", "off"]) == 0
    captured = capsys.readouterr()
    rows = list(csv.DictReader(io.StringIO(captured.out)))
    assert len(rows) == 4 * 1081 and {row["frame"] for row in rows} == {"0", "1", "2", "3"}
    lines = livedic_lines(captured.err)
    assert any(line.startswith("livedic: replayed 4 frames x 1081 points (the recorded frame set; "
                               "improved-wso+icgn) in ") for line in lines), lines
    assert "livedic: replay matches the recording exactly: 4 frames x 1081 points" in lines
    assert not any("; wrote " in line for line in lines)


def test_rows_to_a_file_are_the_rows_of_stdout(short_run, tmp_path, capsys):
    out = tmp_path / "rows.csv"
    capsys.readouterr()
    assert main(["replay", short_run, "--progress", "off"]) == 0
    stdout = capsys.readouterr().out
    assert main(["replay", short_run, "-o", str(out), "--progress", "off"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "" and out.read_text() == stdout
    assert any(line.endswith(f"; wrote {out}") for line in livedic_lines(captured.err))


@pytest.mark.parametrize("options, words", [
    (["--subset", "20"], "subset"),
    (["--threads", "0"], "thread"),
    (["--load", "tcp://localhost:1", "--area", "2"], "--load 'tcp://localhost:1'"),
])
def test_bad_options_are_one_line_exit_2_and_no_output(options, words, short_run, tmp_path, capsys):
    out = tmp_path / "rows.csv"
    capsys.readouterr()
    assert main(["replay", short_run, "-o", str(out), "--progress", "off", *options]) == 2
    captured = capsys.readouterr()
    lines = livedic_lines(captured.err)
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and words in lines[0], lines
    assert captured.out == "" and not out.exists()


def test_an_output_that_is_a_folder_is_refused_before_the_replay(short_run, tmp_path, capsys):
    assert main(["replay", short_run, "-o", str(tmp_path), "--progress", "off"]) == 2
    lines = livedic_lines(capsys.readouterr().err)
    assert len(lines) == 1 and str(tmp_path) in lines[0] and "folder" in lines[0]


def test_the_parallel_line_says_where_and_what_travelled():
    stats = SimpleNamespace(frames=10, where="a local Dask cluster", workers=4, compute_seconds=2.345,
                            image_bytes=5_000_000, seed_bytes=20_000, shared_path=None, segments=1, resubmitted=0)
    assert describe_parallel(stats) == ("parallel: 10 frames measured on a local Dask cluster (4 worker thread(s)): "
                                        "2.3 s of tracking in the tasks; 0.50 MB of image (as recorded) and 2.0 kB "
                                        "of seed per frame sent")
    shared = SimpleNamespace(**dict(vars(stats), shared_path="/mnt/rec.mcap", segments=3, resubmitted=4))
    assert describe_parallel(shared).endswith("the images read by the workers from /mnt/rec.mcap and 2.0 kB of seed "
                                              "per frame sent; 2 reference move(s) or fracture(s): 4 frame(s) "
                                              "measured ahead against the earlier reference were measured again")
    none = SimpleNamespace(**dict(vars(stats), frames=0))
    assert "0.00 MB of image" in describe_parallel(none) and "20.0 kB of seed" in describe_parallel(none)
