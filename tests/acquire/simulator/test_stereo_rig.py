"""Tests of acquire/simulator/stereo_rig.py: the symmetric rig's geometry and a board pose seen from the right."""

import cv2
import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.targets import Pose


def test_a_symmetric_rig_aims_both_cameras_at_one_point_and_maps_poses_consistently():
    lens = Lens((1024, 768), k1=-0.05, focal_px=8000.0)
    rig = StereoRig.symmetric(lens, lens, distance_mm=300.0, angle_deg=25.0)
    assert lens.camera_matrix[0, 0] == 8000.0
    calibration = rig.calibration()
    assert calibration.angle_deg == pytest.approx(25.0)
    # the target 300 mm down the left axis is on the right camera's axis at 300 mm too
    np.testing.assert_allclose(rig.rotation @ [0.0, 0.0, 300.0] + rig.translation_mm, [0.0, 0.0, 300.0], atol=1e-9)
    assert calibration.baseline_mm == pytest.approx(2 * 300.0 * np.sin(np.radians(12.5)))
    # a board point seen through the right pose is the left camera's point moved by R, T
    pose = Pose(np.array([0.1, -0.2, 0.05]), np.array([5.0, -3.0, 310.0]))
    board = np.array([12.0, 7.0, 0.0])
    left = cv2.Rodrigues(pose.rvec)[0] @ board + pose.tvec
    right_pose = rig.right_pose(pose)
    right = cv2.Rodrigues(right_pose.rvec)[0] @ board + right_pose.tvec
    np.testing.assert_allclose(right, rig.rotation @ left + rig.translation_mm, atol=1e-9)
