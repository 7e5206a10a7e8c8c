"""``livedic bench replay --quick``: every mode replays the same recording to the same results.

Timings are printed, never asserted: the check is that each parallel mode agrees with the recording
(exactly or within floating-point rounding, never "differs"), that every frame came back once, and that
the outputs timed are the ones named (the CSV formatted as before and as now the same bytes, the Parquet
file smaller than the CSV).
"""

import json

from livedic.bench.cli import main


def test_quick_replay_benchmark_agrees_in_every_mode(tmp_path, capsys):
    assert main(["bench", "replay", "--quick", "-o", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "replay.json").read_text())["rows"]
    assert [row["mode"] for row in rows][:3] == ["sequential", "--workers 1", "--workers 2"]
    assert {row["agreement"] for row in rows} <= {"EXACT", "WITHIN_ROUNDING"}
    assert len({row["frames"] for row in rows}) == 1 and rows[0]["frames"] == 30
    assert rows[0]["ratio_vs_sequential"] == 1.0 and all(row["frames_per_s"] > 0 for row in rows)
    out = capsys.readouterr().out
    assert "frames/s" in out and "writing ms/f" in out and "warning" not in out
    writers = json.loads((tmp_path / "replay.json").read_text())["writers"]
    assert [row["output"] for row in writers] == ["no output", "CSV, per-cell (before)", "CSV", "Parquet"]
    assert all(row["frames"] == 30 and row["agreement"] == rows[0]["agreement"] for row in writers)
    assert writers[0]["writing_ms_per_frame"] == 0 and all(row["writing_ms_per_frame"] > 0 for row in writers[1:])
    assert writers[1]["same_text_as_before"] and writers[1]["file_mb"] == writers[2]["file_mb"] > writers[3]["file_mb"]


def test_sequential_only_with_no_workers():
    from livedic.bench.replay import parse_workers
    assert parse_workers("0") == () and parse_workers("1,2") == (1, 2)


def test_bad_worker_list_is_one_line_exit_2(capsys, tmp_path):
    assert main(["bench", "replay", "--workers", "two", "-o", str(tmp_path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
