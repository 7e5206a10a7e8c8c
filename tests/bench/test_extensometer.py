"""``livedic bench extensometer``: known elongations read back within bounds, classified, written for the report.

A small run (L0 400 px, rigid translations and a 1 % stretch, noise-free 8-bit frames): the readings' bias is the
tracker's and the end fits' own error (measured: below 0.002 px on these steps), far inside ISO 9513 class 0.5's
1.5 um (0.015 px at 10 px/mm); the class follows from the readings by dic.strain.iso9513.
"""

import json

import numpy as np
import pytest

from livedic.bench.cli import main
from livedic.dic.strain.iso9513 import classify


def test_small_noise_free_run_reads_the_known_elongations(tmp_path, capsys):
    out = tmp_path / "verification.json"
    assert main(["bench", "extensometer", "--gauge-length", "400", "--steps", "1", "--frames-per-step", "3",
                 "--noise", "0", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "L0 400 px = 40 mm: class" in printed and "target ISO 9513 class 0.5" in printed
    verification = json.loads(out.read_text())
    assert verification["kind"] == "livedic extensometer verification" and verification["lost_points"] == 0
    assert (verification["settings"]["end_fit"], verification["settings"]["seed"]) == ("band", 0)   # run's default
    (entry,) = verification["gauge_lengths"]
    steps = entry["steps"]
    assert [s["strain"] for s in steps] == [0.0, 0.0, 0.0, 0.01]
    for step in steps:
        assert step["readings"] == 3 and step["true_px"] == pytest.approx(400.0 * step["strain"])
        assert abs(step["bias_px"]) <= 0.005 + 0.002 * step["true_px"], step
    assert entry["met_class"] in ("0.2", "0.5"), entry
    # the file holds every reading: the class is the classifier's on them
    rebuilt = classify([s["true_px"] for s in steps], [np.array(s["readings_px"]) for s in steps], 400.0,
                       scale_px_per_mm=verification["settings"]["scale_px_per_mm"])
    assert rebuilt.met_class == entry["met_class"]


@pytest.mark.parametrize("options, says", [(["--frames-per-step", "1"], "--frames-per-step"),
                                           (["--gauge-length", "0"], "--gauge-length"),
                                           (["--scale", "ten"], "--scale"),
                                           (["--noise", "-1"], "--noise")])
def test_bad_options_are_one_line_and_exit_2(options, says, capsys):
    assert main(["bench", "extensometer", *options]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err


def test_the_end_fit_and_seed_are_chosen_and_recorded(tmp_path, capsys):
    out = tmp_path / "verification.json"
    assert main(["bench", "extensometer", "--gauge-length", "400", "--steps", "1", "--frames-per-step", "2",
                 "--noise", "0", "--extensometer-ends", "local", "--seed", "3", "-o", str(out)]) == 0
    assert "local ends; seed 3" in capsys.readouterr().out
    settings = json.loads(out.read_text())["settings"]
    assert (settings["end_fit"], settings["seed"]) == ("local", 3)
