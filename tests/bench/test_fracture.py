"""``livedic bench fracture --quick``: the verdicts it prints rest on numbers within the issue's bounds.

Quick mode: 512 x 512, 120 frames (larger steps per frame than the 1 MP target configuration).
Accuracy bounds only (measured in the quick run: visible ok 100 %, extensometer 0.73 of its tolerance,
fracture detected at the simulated frame); timings are printed, never asserted.
"""

import os

from livedic.bench.fracture import run


def test_quick_fracture_benchmark(tmp_path):
    lines = []
    summaries, dogbone = run(quick=True, output=str(tmp_path), say=lines.append)
    auto = next(s for s in summaries if s["case"] == "auto icgn")
    never = next(s for s in summaries if s["case"] == "never icgn")
    assert auto["worst_visible_ok"] >= 0.99
    assert never["worst_visible_ok"] < auto["worst_visible_ok"]       # frame 0 alone loses the neck
    assert auto["extensometer_ratio"] <= 1.0 and auto["axial_lost"] == 0
    assert auto["detected"] is not None and auto["updates"] > 0
    assert dogbone is None
    assert any(line.startswith("MET  fracture detected at the simulated frame") for line in lines)
    assert os.path.getsize(tmp_path / "fracture.png") > 10_000
    with open(tmp_path / "fracture.csv") as handle:
        header = handle.readline().strip().split(",")
    assert header[:4] == ["case", "frame", "visible", "visible_ok"]
