"""Tests of acquire/calibration.py's stereo side: a rig's CAL.json round trip, a stereo file given where one camera's
is expected (and the reverse) refused in one line, and image lists that cannot pair refused before any work."""

import json
from dataclasses import replace

import cv2
import numpy as np
import pytest

from livedic.acquire.calibration import (FORMAT, VERSION, calibrate_image_pairs, read_calibration,
                                         read_stereo_calibration, write_calibration)
from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.dic.calibration import CalibrationError, CameraCalibration, PairFit


@pytest.fixture
def rig_calibration():
    rig = StereoRig.symmetric(Lens((640, 480), k1=-0.1), Lens((640, 480), k1=-0.05, focal_px=700.0),
                              distance_mm=300.0, angle_deg=25.0)
    exact = rig.calibration()
    return replace(exact, rms_px=0.07, pairs=(PairFit("l0.png", "r0.png", 54, 0.06, 0.08),),
                   skipped=("l1.png | r1.png: no target in the right view",))


def test_a_stereo_calibration_round_trips_through_cal_json(rig_calibration, tmp_path):
    path = tmp_path / "rig.json"
    write_calibration(path, rig_calibration)
    document = json.loads(path.read_text())
    assert (document["format"], document["version"], document["stereo"]) == (FORMAT, VERSION, True)
    back = read_stereo_calibration(path)
    np.testing.assert_array_equal(back.rotation, rig_calibration.rotation)
    np.testing.assert_array_equal(back.translation_mm, rig_calibration.translation_mm)
    for side in ("left", "right"):
        np.testing.assert_array_equal(getattr(back, side).camera_matrix, getattr(rig_calibration, side).camera_matrix)
        np.testing.assert_array_equal(getattr(back, side).dist_coeffs, getattr(rig_calibration, side).dist_coeffs)
    assert back.pairs == rig_calibration.pairs and back.skipped == rig_calibration.skipped
    assert back.baseline_mm == pytest.approx(rig_calibration.baseline_mm)


def test_a_stereo_file_for_one_camera_and_the_reverse_are_one_line(rig_calibration, tmp_path):
    stereo, single = tmp_path / "rig.json", tmp_path / "cal.json"
    write_calibration(stereo, rig_calibration)
    write_calibration(single, CameraCalibration((640, 480), rig_calibration.left.camera_matrix, np.zeros(5), 0.1, (),
                                                "chessboard:9x6", 5.0))
    with pytest.raises(CalibrationError) as caught:
        read_calibration(stereo)
    assert str(caught.value).startswith(f"calibration file {stereo} is a stereo calibration")
    assert "use it with a stereo source" in str(caught.value) and "\n" not in str(caught.value)
    with pytest.raises(CalibrationError, match="is a one-camera calibration: a stereo source needs a stereo one"):
        read_stereo_calibration(single)
    broken = json.loads(stereo.read_text())
    del broken["rotation"]
    stereo.write_text(json.dumps(broken))
    with pytest.raises(CalibrationError, match="'rotation' is missing"):
        read_stereo_calibration(stereo)


def test_image_lists_that_cannot_pair_are_refused(tmp_path):
    for name, size in (("a.png", (64, 48)), ("b.png", (64, 48)), ("c.png", (80, 48))):
        cv2.imwrite(str(tmp_path / name), np.full(size[::-1], 128, np.uint8))
    a, b, c = (str(tmp_path / n) for n in ("a.png", "b.png", "c.png"))
    with pytest.raises(CalibrationError, match="--left gives 2 image.s. but --right 1"):
        calibrate_image_pairs([a, b], [a], "chessboard:9x6", 5.0)
    with pytest.raises(CalibrationError, match="the right camera's calibration images must have the same size"):
        calibrate_image_pairs([a, b], [a, c], "chessboard:9x6", 5.0)
    with pytest.raises(CalibrationError, match="found in both views of 0 of 2"):
        calibrate_image_pairs([a, b], [b, a], "chessboard:9x6", 5.0)
