"""The simulated stereo rig: two known lenses and the rigid motion between the cameras (the truth of a stereo
calibration).

Conventions are ``dic.calibration.StereoCalibration``'s (OpenCV's): the world frame is the left camera's, in
mm, and a point X there is ``rotation @ X + translation_mm`` in the right camera's frame. ``symmetric`` builds
the usual rig: both cameras at ``distance_mm`` from a point on the left camera's axis, ``angle_deg`` apart,
turned about the y axis towards it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.targets import Pose
from livedic.dic.calibration import CameraCalibration, StereoCalibration


@dataclass(frozen=True)
class StereoRig:
    """Two simulated cameras: ``left`` and ``right`` lenses, ``rotation`` and ``translation_mm`` left -> right."""

    left: Lens
    right: Lens
    rotation: np.ndarray
    translation_mm: np.ndarray

    @classmethod
    def symmetric(cls, left: Lens, right: Lens, *, distance_mm: float, angle_deg: float) -> StereoRig:
        """Cameras ``angle_deg`` apart about y, both aimed at the point ``distance_mm`` down the left's axis."""
        turn = math.radians(angle_deg)
        rotation = cv2.Rodrigues(np.array([0.0, turn, 0.0]))[0]
        target = np.array([0.0, 0.0, distance_mm])
        # the right camera's centre: the left's, swung by angle_deg about the target (about y)
        centre_right = target + np.array([distance_mm * math.sin(turn), 0.0, -distance_mm * math.cos(turn)])
        return cls(left, right, rotation, -rotation @ centre_right)

    def right_pose(self, pose: Pose) -> Pose:
        """A board's pose (board -> left camera) as the right camera sees it (board -> right camera)."""
        R = cv2.Rodrigues(np.asarray(pose.rvec, dtype=np.float64))[0]
        return Pose(cv2.Rodrigues(self.rotation @ R)[0].ravel(),
                    self.rotation @ np.asarray(pose.tvec, dtype=np.float64) + self.translation_mm)

    def calibration(self) -> StereoCalibration:
        """The rig's exact calibration (what ``livedic calibrate`` should find from its target pairs)."""
        def camera(lens: Lens) -> CameraCalibration:
            return CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "truth", 1.0)
        return StereoCalibration(camera(self.left), camera(self.right), np.array(self.rotation, dtype=np.float64),
                                 np.array(self.translation_mm, dtype=np.float64), 0.0)
