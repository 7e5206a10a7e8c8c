"""``livedic replay --load csv:FILE --area MM2``: the machine's force and stress on every row of the replay CSV.

The shipped sample recording replayed with a force ramp of 5,000 N/s (a file, as a machine's software
exports it): each frame's force is the ramp at the frame's time since the reference frame (linear
interpolation of a linear ramp: exact), the stress that over A0, and NaN past the file's last sample
(never extrapolated). Bad force options are one line, exit 2, and no file.
"""

import csv
import os
import subprocess
import sys

import numpy as np
import pytest

from livedic.stream.cli import main
from livedic.stream.replay.rows import FORCE_COLUMNS

SAMPLE = os.path.join(os.path.dirname(__file__), "..", "..", "..", "recordings", "sample-tensile.mcap")
RAMP_N_PER_S = 5000.0
LAST_SAMPLE_S = 0.4
AREA = 10.0


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("replay_force")
    ramp = folder / "force.csv"
    ramp.write_text("time_s,force_N\n" + "".join(f"{t:.2f},{RAMP_N_PER_S * t:.1f}\n"
                                                 for t in np.arange(0.0, LAST_SAMPLE_S + 1e-9, 0.05)))
    out = folder / "replay.csv"
    assert main(["replay", SAMPLE, "-o", str(out), "--load", f"csv:{ramp}", "--area", str(AREA),
                 "--progress", "off"]) == 0
    with open(out, newline="") as handle:
        return list(csv.DictReader(handle))


def test_each_row_carries_its_frames_force_and_stress(replayed):
    assert list(replayed[0])[-2:] == list(FORCE_COLUMNS) == ["force_N", "eng_stress_MPa"]
    t0 = int(replayed[0]["timestamp_ns"])
    frames = {}
    for row in replayed:
        frames.setdefault(int(row["frame"]), set()).add((row["timestamp_ns"], row["force_N"], row["eng_stress_MPa"]))
    assert all(len(values) == 1 for values in frames.values())          # one value per frame, on all its rows
    covered = 0
    for values in frames.values():
        (stamp, force, stress), = values
        t = (int(stamp) - t0) / 1e9
        if t <= LAST_SAMPLE_S:
            covered += 1
            assert float(force) == pytest.approx(RAMP_N_PER_S * t, abs=1e-6)
            assert float(stress) == pytest.approx(RAMP_N_PER_S * t / AREA, abs=1e-7)
        else:
            assert force == stress == "nan"                               # never extrapolated
    assert 2 <= covered < len(frames)


@pytest.mark.parametrize("extra, says", [
    (["--area", "10"], "without --load"),
    (["--load", "tcp://127.0.0.1:9", "--area", "10"], "csv:FILE"),
    (["--load", "csv:/nonexistent.csv", "--area", "10"], "/nonexistent.csv"),
])
def test_bad_force_options_are_one_line_exit_2_and_no_file(tmp_path, extra, says):
    out = tmp_path / "replay.csv"
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", "replay", SAMPLE, "-o", str(out),
                           "--progress", "off", *extra], capture_output=True, text=True, timeout=300)
    assert done.returncode == 2, done.stderr
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert len(errors) == 1 and says in errors[0], done.stderr
    assert not out.exists()
