"""Tests of dic/calibration/targets.py: target specs parsed, the board's corners in mm, detection and its
typed not-found reason, ChArUco ids."""

import numpy as np
import pytest

from livedic.dic.calibration import Detection, NotFound, NotFoundReason, detect_target, parse_target


def test_target_specs_parse_and_refuse_clearly():
    chess = parse_target("chessboard:9x6")
    assert (chess.kind, chess.inner_corners, chess.text) == ("chessboard", (9, 6), "chessboard:9x6")
    board = parse_target("charuco:11x8")
    assert board.inner_corners == (10, 7)
    assert board.text == "charuco:11x8:DICT_5X5_100:0.75"
    assert parse_target("charuco:5x5:DICT_4X4_50:0.6").marker_fraction == 0.6
    for bad in ("chessboard", "chess:9x6", "chessboard:9by6", "chessboard:1x6", "charuco:11x8:DICT_NOPE",
                "charuco:11x8:DICT_4X4_50:1.5", "charuco:30x30:DICT_4X4_50"):
        with pytest.raises(ValueError) as error:
            parse_target(bad)
        assert "\n" not in str(error.value)


def test_object_points_are_the_inner_corners_in_mm():
    points = parse_target("chessboard:3x2").object_points(5.0)
    np.testing.assert_array_equal(points[:, :2], [[0, 0], [5, 0], [10, 0], [0, 5], [5, 5], [10, 5]])
    charuco = parse_target("charuco:4x3").object_points(2.0)
    assert charuco.shape == (6, 3) and np.ptp(charuco[:, 0]) == 4.0 and np.ptp(charuco[:, 1]) == 2.0


def test_no_target_is_a_typed_reason():
    blank = np.full((200, 200), 128, np.uint8)
    result = detect_target(blank, parse_target("chessboard:9x6"), 10.0)
    assert isinstance(result, NotFound) and result.reason is NotFoundReason.NO_TARGET
    assert isinstance(detect_target(blank, parse_target("charuco:5x5"), 10.0), NotFound)


def test_a_charuco_board_is_found_with_its_corner_ids():
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.targets import calibration_views, render_target
    lens = Lens((384, 384), k1=-0.12)
    spec = parse_target("charuco:7x5:DICT_4X4_50")
    image = render_target(spec, 10.0, lens, calibration_views(spec, 10.0, lens)[1], seed=3)
    found = detect_target(image, spec, 10.0)
    assert isinstance(found, Detection) and len(found.ids) >= 20
    np.testing.assert_array_equal(found.object_points, spec.object_points(10.0)[found.ids])
    # where the lens put each corner (the board's corners projected through it): RMS within 0.3 px, every one
    # within 0.6 px (measured: RMS 0.21 px, 0.48 px at worst on this small, tilted view; a chessboard gets 0.07)
    import cv2
    pose = calibration_views(spec, 10.0, lens)[1]
    expected, _ = cv2.projectPoints(found.object_points, pose.rvec, pose.tvec, lens.camera_matrix, lens.dist_coeffs)
    miss = np.hypot(*(expected.reshape(-1, 2) - found.image_points).T)
    assert np.sqrt(np.mean(miss ** 2)) < 0.3 and np.max(miss) < 0.6
