"""Tests of dic/calibration/camera.py: the undistortion round trip, the calibration's dict and frame-size
check, points on a tilted plane."""

import numpy as np
import pytest

from livedic.dic.calibration import (CalibrationError, CameraCalibration, distort_points, parse_target,
                                     undistort_points)


def test_undistort_inverts_distort_to_rounding(chessboard_views):
    _, _, lens, _, _ = chessboard_views
    calibration = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "none", 1.0)
    points = np.random.default_rng(0).uniform(-10.0, 520.0, (500, 2))
    np.testing.assert_allclose(undistort_points(calibration, distort_points(calibration, points)), points, atol=1e-9)
    assert np.isnan(undistort_points(calibration, [[np.nan, 3.0]])).all()
    # the centre stays put; a corner moves inward through a barrel lens (k1 < 0) by about k1 r^3 / f^2
    centre = np.array([[255.5, 255.5]])
    np.testing.assert_allclose(distort_points(calibration, centre), centre, atol=1e-12)
    corner = distort_points(calibration, [[0.0, 0.0]])[0]
    assert 10.0 < corner[0] < 20.0 and 10.0 < corner[1] < 20.0


def test_a_calibration_round_trips_through_its_dict_and_checks_the_frame_size(chessboard_views):
    _, _, lens, _, _ = chessboard_views
    calibration = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.1, (), "chessboard:9x6", 10.0)
    again = CameraCalibration.from_dict(calibration.to_dict())
    np.testing.assert_array_equal(again.camera_matrix, calibration.camera_matrix)
    assert again.image_size == (512, 512) and again.px_per_mm is None
    with pytest.raises(CalibrationError, match="1024x768"):
        again.check_size(1024, 768)
    broken = calibration.to_dict()
    del broken["camera_matrix"]
    with pytest.raises(CalibrationError, match="camera_matrix"):
        CameraCalibration.from_dict(broken)


def test_plane_points_are_mm_on_a_tilted_plane_times_px_per_mm():
    """Through a tilted, rolled plane's homography, distances between plane points are board mm x px/mm, the
    axes are the image's at its centre, NaN stays NaN, and ``image_points`` is the inverse (no rendering)."""
    import cv2

    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.targets import pose_looking_at, pose_homography
    from livedic.dic.calibration import image_points, plane_from_homography, plane_points
    lens = Lens((640, 480), k1=-0.1, p1=3e-4)
    spec = parse_target("chessboard:9x6")
    pose = pose_looking_at(spec, 4.0, lens, (9.0, -6.0, 20.0), (0.5, 0.5), 8.0)
    H = pose_homography(lens, pose)
    plane = plane_from_homography("tilted", H, spec.object_points(4.0).mean(axis=0)[:2], lens.camera_matrix)
    calibration = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "lens", 4.0,
                                    plane=plane)
    board = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 18.0], [5.0, 12.0]])
    seen = lens.distort(cv2.perspectiveTransform(board.reshape(-1, 1, 2), H).reshape(-1, 2))
    q = plane_points(calibration, seen)
    distances = lambda p: np.linalg.norm(p[:, None] - p[None, :], axis=-1)  # noqa: E731
    np.testing.assert_allclose(distances(q), distances(board) * plane.px_per_mm, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(image_points(calibration, q), seen, atol=1e-8)
    # the board's x is rolled 20 deg in the image: so are the plane px, whose x is the image's at its centre
    direction = q[1] - q[0]
    assert abs(np.degrees(np.arctan2(direction[1], direction[0])) - 20.0) < 2.0
    centre = np.array([[319.5, 239.5]])
    np.testing.assert_allclose(plane_points(calibration, lens.distort(centre)), centre, atol=1e-9)
    assert np.isnan(plane_points(calibration, np.array([[np.nan, 1.0]]))).all()
