"""A live session to fracture: reference updates and the fracture are events, recorded, exported, replayed.

The simulated test to fracture (30 % uniform / 100 % neck strain, fading paint, the coupon breaks at
90 % of the frames) on a small image, tracked by ``livedic run`` with the default ``--reference-update
auto``. Accuracy against the truth is ``livedic bench fracture``'s (1 MP); here: what a user gets.
"""

import csv

import numpy as np
import pytest

from livedic.acquire.recording.reader import read_results
from livedic.dic.status import Status
from livedic.stream.cli import main
from livedic.stream.session.config import DEFAULT_STATIC_FRAMES

SOURCE = "synthetic:tensile?strain=0.30&neck=1.0&fade=0.2&fracture=1&size=384x512&frames=60&pace=0"
FRACTURE_FRAME = 54 + DEFAULT_STATIC_FRAMES     # the test's frames - round(0.1 frames), after the static ones


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fracture")
    record = folder / "test.mcap"
    summary = folder / "summary.json"
    code = main(["run", "--source", SOURCE, "--record", str(record), "--viewer", "none", "--progress", "off",
                 "--gauge-length", "200", "--summary-json", str(summary)])
    assert code == 0
    return record, summary, folder


def test_the_fracture_and_the_updates_are_in_the_summary(session):
    import json
    _, summary, _ = session
    numbers = json.loads(summary.read_text())
    assert numbers["reference_update"] == "auto" and numbers["reference_updates"] >= 5
    assert numbers["reference_update_lost"] == 0
    assert [f["frame"] for f in numbers["fractures"]] == [FRACTURE_FRAME]
    assert numbers["fractures"][0]["separated"] > 0


def test_results_say_which_reference_and_which_points_separated(session):
    record, _, _ = session
    results = read_results(record)
    references = [int(r.reference_frame_index) for r in results]
    assert references[0] == 0 and len(set(references)) >= 5
    assert references == sorted(references)                      # the reference only moves forward
    before = results[FRACTURE_FRAME - 1]
    after = results[-1]
    separated = after.status == Status.SEPARATED
    assert separated.any() and not (before.status == Status.SEPARATED).any()
    assert np.all(np.isnan(after.u[separated])) and not after.ok[separated].any()
    assert after.ok[~separated].mean() > 0.9                      # the rest is tracked on


def test_export_lists_the_updates_and_the_fracture(session):
    record, _, folder = session
    out = folder / "export"
    assert main(["export", str(record), "-o", str(out)]) == 0
    with open(out / "events.csv", newline="") as handle:
        kinds = [row["kind"] for row in csv.DictReader(handle)]
    assert kinds.count("fracture") == 1 and kinds.count("reference_update") >= 5


def test_replay_repeats_the_updates_and_the_fracture_exactly(session, capsys):
    record, _, folder = session
    capsys.readouterr()
    assert main(["replay", str(record), "-o", str(folder / "replay.csv"), "--progress", "off"]) == 0
    assert "replay matches the recording exactly" in capsys.readouterr().err
