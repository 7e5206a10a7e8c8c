"""``livedic calibrate --left ... --right ...``: a stereo rig's CAL.json from rendered target pairs, what it prints,
and bad inputs as one line, exit 2, nothing written."""

import shutil

import cv2
import numpy as np
import pytest

from livedic.acquire.calibration import read_stereo_calibration
from livedic.stream.cli.main import main


@pytest.fixture(scope="module")
def pairs(tmp_path_factory):
    """Seven chessboard:7x5 pairs through a known 30-degree rig, in folder/left and folder/right; and the rig."""
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.stereo_rig import StereoRig
    from livedic.acquire.simulator.targets import render_target_pair, stereo_calibration_views
    from livedic.dic.calibration import parse_target

    folder = tmp_path_factory.mktemp("pairs")
    (folder / "left").mkdir()
    (folder / "right").mkdir()
    rig = StereoRig.symmetric(Lens((480, 360), k1=-0.1), Lens((480, 360), k1=-0.05), distance_mm=250.0,
                              angle_deg=30.0)
    spec = parse_target("chessboard:7x5")
    for i, pose in enumerate(stereo_calibration_views(spec, 10.0, rig)[:7]):
        for side, image in zip(("left", "right"), render_target_pair(spec, 10.0, rig, pose, seed=i)):
            cv2.imwrite(str(folder / side / f"view_{i}.png"), image)
    return folder, rig


def _calibrate(*arguments):
    return main(["calibrate", *arguments, "--target", "chessboard:7x5", "--square", "10"])


def test_calibrate_writes_the_rig_and_prints_each_pair_the_baseline_and_angle(pairs, tmp_path, capsys):
    folder, rig = pairs
    out = tmp_path / "rig.json"
    code = _calibrate("--left", str(folder / "left"), "--right", str(folder / "right" / "*.png"), "-o", str(out))
    printed = capsys.readouterr().out
    assert code == 0
    assert "view_6.png | view_6.png: 35 corners in both, reprojection RMS left" in printed
    assert "baseline" in printed and "angle between the cameras" in printed and "reprojection RMS" in printed
    calibration = read_stereo_calibration(out)
    truth = rig.calibration()
    assert len(calibration.pairs) == 7
    assert calibration.angle_deg == pytest.approx(30.0, abs=0.5)
    assert calibration.baseline_mm == pytest.approx(truth.baseline_mm, rel=0.02)
    assert f"baseline {calibration.baseline_mm:.3f} mm" in printed


@pytest.mark.parametrize("case, says", [
    ("counts differ", "--left gives 7 image(s) but --right 6"),
    ("sizes differ", "must have the same size"),
    ("too few pairs", "found in both views of 2 of 2 pair(s)"),
    ("left alone", "--left is given without --right"),
    ("with a plane", "--plane is for one camera"),
    ("with images", "either as IMAGES (one camera) or as --left and --right"),
    ("bound", "--max-error"),
])
def test_bad_stereo_inputs_are_one_line_and_write_nothing(pairs, tmp_path, capsys, case, says):
    folder, _ = pairs
    left, right = folder / "left", tmp_path / "right"
    shutil.copytree(folder / "right", right)
    arguments = ["--left", str(left), "--right", str(right)]
    if case == "counts differ":
        (right / "view_6.png").unlink()
    elif case == "sizes differ":
        cv2.imwrite(str(right / "view_6.png"), np.zeros((100, 120), np.uint8))
    elif case == "too few pairs":
        arguments = ["--left", str(left / "view_0.png"), str(left / "view_1.png"),
                     "--right", str(right / "view_0.png"), str(right / "view_1.png")]
    elif case == "left alone":
        arguments = ["--left", str(left)]
    elif case == "with a plane":
        arguments += ["--plane", str(left / "view_0.png")]
    elif case == "with images":
        arguments = [str(left / "view_0.png"), *arguments]
    elif case == "bound":
        arguments += ["--max-error", "0"]
    out = tmp_path / "rig.json"
    code = _calibrate(*arguments, "-o", str(out))
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and says in error and error.startswith("livedic: error:"), error
    assert not out.exists()
