"""``livedic bench replay --quick``: every mode replays the same recording to the same results.

Timings are printed, never asserted: the check is that each parallel mode agrees with the recording
(exactly or within floating-point rounding, never "differs") and that every frame came back once.
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
    assert "frames/s" in capsys.readouterr().out


def test_bad_worker_list_is_one_line_exit_2(capsys, tmp_path):
    assert main(["bench", "replay", "--workers", "two", "-o", str(tmp_path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
