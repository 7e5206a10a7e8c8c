"""Tests of dic/calibration/stereo.py: the rig's dict round trip, its checks, and the epipolar geometry and
projection matrices against points projected through a known rig."""

import cv2
import numpy as np
import pytest

from livedic.dic.calibration import CalibrationError, CameraCalibration, PairFit, StereoCalibration


def _rig(angle_deg: float = 20.0, baseline_mm: float = 120.0) -> StereoCalibration:
    K = np.array([[2400.0, 0.0, 511.5], [0.0, 2400.0, 383.5], [0.0, 0.0, 1.0]])
    left = CameraCalibration((1024, 768), K, np.zeros(5), 0.05, (), "chessboard:9x6", 5.0)
    right = CameraCalibration((1024, 768), K * [[1.01], [1.01], [1.0]], np.zeros(5), 0.05, (), "chessboard:9x6", 5.0)
    # the right camera sits baseline_mm to the left camera's right, turned towards the specimen about y
    rotation, _ = cv2.Rodrigues(np.array([0.0, np.radians(angle_deg), 0.0]))
    centre_right = np.array([baseline_mm, 0.0, 0.0])
    return StereoCalibration(left, right, rotation, -rotation @ centre_right, 0.07,
                             (PairFit("l0.png", "r0.png", 54, 0.05, 0.06),))


def test_a_rig_round_trips_through_its_dict_and_names_a_bad_field():
    rig = _rig()
    again = StereoCalibration.from_dict(rig.to_dict())
    np.testing.assert_array_equal(again.rotation, rig.rotation)
    np.testing.assert_array_equal(again.translation_mm, rig.translation_mm)
    assert again.pairs == rig.pairs and again.rms_px == rig.rms_px
    assert again.baseline_mm == pytest.approx(120.0) and again.angle_deg == pytest.approx(20.0)
    for field, value, message in (("rotation", np.diag([1.0, 1.0, -1.0]).tolist(), "proper rotation"),
                                  ("translation_mm", [0.0, 0.0, 0.0], "translation_mm"),
                                  ("right", None, "wrong form")):
        broken = rig.to_dict()
        broken[field] = value
        with pytest.raises(CalibrationError, match=message):
            StereoCalibration.from_dict(broken)
    broken = rig.to_dict()
    del broken["left"]
    with pytest.raises(CalibrationError, match="'left' is missing"):
        StereoCalibration.from_dict(broken)


def test_projections_and_the_fundamental_matrix_agree_with_the_rig():
    """World points (left camera frame, mm) seen through both projection matrices satisfy x_r^T F x_l = 0 to
    rounding, and cv2.triangulatePoints recovers them from the two ideal-pixel views."""
    rig = _rig()
    rng = np.random.default_rng(1)
    world = np.column_stack([rng.uniform(-20, 40, 50), rng.uniform(-15, 15, 50), rng.uniform(280, 320, 50)])
    P_left, P_right = rig.projection_matrices()
    homogeneous = np.column_stack([world, np.ones(len(world))])
    x_left = (P_left @ homogeneous.T).T
    x_right = (P_right @ homogeneous.T).T
    x_left /= x_left[:, 2:]
    x_right /= x_right[:, 2:]
    F = rig.fundamental_matrix()
    residual = np.einsum("ni,ij,nj->n", x_right, F, x_left)
    # the distance of each right point to its epipolar line, in px
    lines = (F @ x_left.T).T
    distance = np.abs(residual) / np.hypot(lines[:, 0], lines[:, 1])
    assert distance.max() < 1e-9
    points = cv2.triangulatePoints(P_left, P_right, x_left[:, :2].T, x_right[:, :2].T)
    np.testing.assert_allclose((points[:3] / points[3]).T, world, atol=1e-6)
    # the right camera's centre, -R^T T, is the baseline along the left camera's x
    np.testing.assert_allclose(-rig.rotation.T @ rig.translation_mm, [120.0, 0.0, 0.0], atol=1e-12)
