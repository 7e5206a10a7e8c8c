"""Tests of acquire/calibration.py: CAL.json written and read back, bad files refused in one line, images
found and calibrated from disk."""

import json

import cv2
import numpy as np
import pytest

from livedic.acquire.calibration import (FORMAT, calibrate_images, calibration_document, expand_images,
                                         read_calibration, write_calibration)
from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.targets import calibration_views, plane_view, render_target
from livedic.dic.calibration import CalibrationError, parse_target

SIZE = (384, 384)


@pytest.fixture(scope="module")
def views(tmp_path_factory):
    """Chessboard views through a k1 = -0.1 lens written as PNG files, and a plane image at 3 px/mm."""
    folder = tmp_path_factory.mktemp("views")
    lens, spec = Lens(SIZE, k1=-0.1), parse_target("chessboard:9x6")
    for i, pose in enumerate(calibration_views(spec, 4.0, lens)):
        cv2.imwrite(str(folder / f"view_{i:02d}.png"), render_target(spec, 4.0, lens, pose, seed=i))
    cv2.imwrite(str(folder / "plane.png"), render_target(spec, 4.0, lens, plane_view(spec, 4.0, lens, 3.0), seed=50))
    return folder, lens


def test_a_calibration_from_files_round_trips_through_cal_json(views, tmp_path):
    folder, lens = views
    images = expand_images([str(folder / "view_*.png")])
    assert len(images) >= 3 and images == sorted(images)
    seen = []
    calibration = calibrate_images(images, "chessboard:9x6", 4.0, plane=str(folder / "plane.png"),
                                   on_image=seen.append)
    assert [outcome.name for outcome in seen] == images
    assert calibration.camera_matrix[0, 0] == pytest.approx(lens.camera_matrix[0, 0], rel=0.01)
    assert calibration.px_per_mm == pytest.approx(3.0, rel=0.005)
    path = tmp_path / "CAL.json"
    write_calibration(path, calibration)
    document = json.loads(path.read_text())
    assert document["format"] == FORMAT and document == json.loads(json.dumps(calibration_document(calibration)))
    back = read_calibration(path)
    np.testing.assert_array_equal(back.camera_matrix, calibration.camera_matrix)
    np.testing.assert_array_equal(np.ravel(back.dist_coeffs), np.ravel(calibration.dist_coeffs))
    assert back.px_per_mm == calibration.px_per_mm and back.image_size == calibration.image_size


@pytest.mark.parametrize("content, words", [
    ("{not json", "does not parse as JSON"),
    ('{"format": "something else"}', "calibration"),
    ('{"format": "livedic-calibration", "version": 1}', "calibration"),
])
def test_a_file_that_is_no_calibration_is_one_line(tmp_path, content, words):
    path = tmp_path / "CAL.json"
    path.write_text(content)
    with pytest.raises(CalibrationError) as caught:
        read_calibration(path)
    message = str(caught.value)
    assert words in message and str(path) in message and "\n" not in message


def test_missing_files_and_bad_inputs_are_refused_before_any_work(views, tmp_path):
    folder, _ = views
    with pytest.raises(CalibrationError, match="does not exist"):
        read_calibration(tmp_path / "none.json")
    with pytest.raises(CalibrationError, match="no such image"):
        expand_images([str(tmp_path / "nothing_*.png")])
    with pytest.raises(CalibrationError, match="--square"):
        calibrate_images(expand_images([str(folder / "view_*.png")]), "chessboard:9x6", 0.0)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((100, 120), np.uint8))
    with pytest.raises(CalibrationError, match="resolution"):
        calibrate_images([str(folder / "view_00.png"), str(small)], "chessboard:9x6", 4.0)
