"""The calibrated stereo rig: ``StereoCalibration`` (two ``CameraCalibration`` and the pose between them).

Conventions (OpenCV's ``cv2.stereoCalibrate``): the world frame is the left camera's, in mm; a point X
(mm) in the left camera's frame is ``R @ X + T`` in the right camera's. Each camera keeps its own
intrinsics and lens distortion. Image positions go through ``undistort_points`` to ideal pixels first;
``projection_matrices`` and ``fundamental_matrix`` act on ideal pixels. A calibration is plain data:
``to_dict`` / ``from_dict`` give the JSON body of a stereo CAL.json (``livedic.acquire.calibration``
writes and reads the file). The guide: docs/guide/calibration.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from livedic.dic.calibration.camera import CalibrationError, CameraCalibration, _matrix


@dataclass(frozen=True)
class PairFit:
    """One calibration image pair: both names and the pair's reprojection RMS (px) in each view."""

    left: str
    right: str
    corners: int
    rms_left_px: float
    rms_right_px: float


@dataclass(frozen=True)
class StereoCalibration:
    """Two calibrated cameras and the rigid motion from the left camera's frame to the right's.

    Attributes
    ----------
    left, right : CameraCalibration
        Each camera's intrinsics and distortion (their ``plane`` is None: a stereo rig measures the
        specimen's surface in 3D instead).
    rotation : ndarray, shape (3, 3)
        R: ``X_right = R @ X_left + T``.
    translation_mm : ndarray, shape (3,)
        T (mm).
    rms_px : float
        The stereo fit's reprojection RMS over every corner of every pair, both views (px).
    pairs : tuple of PairFit
        Each image pair used.
    skipped : tuple of str
        Pairs left out (a target not found in one view), as "LEFT | RIGHT: reason".
    """

    left: CameraCalibration
    right: CameraCalibration
    rotation: np.ndarray
    translation_mm: np.ndarray
    rms_px: float
    pairs: tuple[PairFit, ...] = field(default=())
    skipped: tuple[str, ...] = field(default=())

    @property
    def baseline_mm(self) -> float:
        """Distance between the two cameras' centres (mm)."""
        return float(np.linalg.norm(self.translation_mm))

    @property
    def angle_deg(self) -> float:
        """Angle of the rotation between the two cameras (degrees)."""
        cos = (np.trace(self.rotation) - 1.0) / 2.0
        return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))

    def projection_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """P_left = K_l [I | 0] and P_right = K_r [R | T]: world (mm, left camera frame) -> ideal pixels."""
        left = self.left.camera_matrix @ np.hstack([np.eye(3), np.zeros((3, 1))])
        right = self.right.camera_matrix @ np.hstack([self.rotation, self.translation_mm.reshape(3, 1)])
        return left, right

    def fundamental_matrix(self) -> np.ndarray:
        """F with ``x_r^T F x_l = 0`` for ideal pixels (homogeneous) of one world point in both views."""
        t = self.translation_mm
        skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
        essential = skew @ self.rotation
        F = np.linalg.inv(self.right.camera_matrix).T @ essential @ np.linalg.inv(self.left.camera_matrix)
        return F / np.linalg.norm(F)

    def to_dict(self) -> dict[str, Any]:
        """The JSON body of a stereo CAL.json (without its format header)."""
        return {"stereo": True, "left": self.left.to_dict(), "right": self.right.to_dict(),
                "rotation": self.rotation.tolist(), "translation_mm": np.asarray(self.translation_mm).tolist(),
                "rms_px": self.rms_px, "baseline_mm": self.baseline_mm, "angle_deg": self.angle_deg,
                "pairs": [{"left": p.left, "right": p.right, "corners": p.corners, "rms_left_px": p.rms_left_px,
                           "rms_right_px": p.rms_right_px} for p in self.pairs],
                "skipped": list(self.skipped)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StereoCalibration:
        """The stereo calibration in ``data`` (as ``to_dict`` wrote it); CalibrationError names a bad field."""
        try:
            rotation = _matrix(data["rotation"], (3, 3), "rotation")
            if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6) or np.linalg.det(rotation) < 0:
                raise CalibrationError("rotation must be a proper rotation matrix")
            translation = np.asarray(data["translation_mm"], dtype=np.float64).ravel()
            if translation.shape != (3,) or not np.all(np.isfinite(translation)) or not np.any(translation):
                raise CalibrationError("translation_mm must be three finite numbers, not all zero")
            pairs = tuple(PairFit(str(p["left"]), str(p["right"]), int(p["corners"]), float(p["rms_left_px"]),
                                  float(p["rms_right_px"])) for p in data.get("pairs", ()))
            return cls(CameraCalibration.from_dict(data["left"]), CameraCalibration.from_dict(data["right"]),
                       rotation, translation, float(data["rms_px"]), pairs,
                       tuple(str(s) for s in data.get("skipped", ())))
        except KeyError as missing:
            raise CalibrationError(f"field {missing.args[0]!r} is missing") from None
        except (TypeError, ValueError) as error:
            if isinstance(error, CalibrationError):
                raise
            raise CalibrationError(f"a field has the wrong form ({error})") from None
