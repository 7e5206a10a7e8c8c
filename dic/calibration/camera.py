"""The calibrated camera: ``CameraCalibration`` (intrinsics, lens distortion, the fit's errors, the
specimen plane's scale) and the maps between image pixels and ideal pixels.

Ideal pixels are those of a distortion-free pinhole camera with the same camera matrix K: a point's
ideal position is ``undistort_points`` of where the lens put it. With the specimen plane measured
(``PlaneScale``), ``plane_points`` go one step further: through the plane's homography to plane
pixels, millimetres on the plane times px/mm, in a frame matching the image's at its centre
(``PlaneFrame``), so a tilted plane's foreshortening and perspective are removed too. Distortion is OpenCV's model
(k1, k2, p1, p2[, k3 ...]). A calibration is plain data: ``to_dict`` / ``from_dict`` give the JSON
body of CAL.json (``livedic.acquire.calibration`` writes and reads the file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

# cv2.undistortPoints' default (5 iterations) leaves up to 3e-4 px at the corners of a k1 = -0.12 lens;
# these iterate to 1e-12 px (measured: 1.1e-12 px at the corners, 1.1 s per million points).
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-12)


class CalibrationError(ValueError):
    """A calibration that cannot be made or used; the message is one line for the user."""


@dataclass(frozen=True)
class ImageFit:
    """One calibration image: its name, the corners used and their reprojection RMS (px)."""

    name: str
    corners: int
    rms_px: float


@dataclass(frozen=True)
class PlaneScale:
    """The specimen plane, measured from a target lying on it.

    Attributes
    ----------
    image : str
        The image of the target on the plane.
    px_per_mm : float
        Ideal pixels per mm on the plane at the target's centre (geometric mean of the two axes).
    px_per_mm_xy : tuple of float
        Ideal pixels per mm along the image's x and y at the target's centre (they differ when tilted).
    tilt_deg : float
        Angle between the plane's normal and the camera's axis.
    homography : ndarray, shape (3, 3)
        Board (mm) -> ideal pixels.
    rms_px : float
        RMS of the homography's fit to the target's undistorted corners (ideal px).
    """

    image: str
    px_per_mm: float
    px_per_mm_xy: tuple[float, float]
    tilt_deg: float
    homography: np.ndarray
    rms_px: float

    def to_dict(self) -> dict[str, Any]:
        return {"image": self.image, "px_per_mm": self.px_per_mm, "px_per_mm_xy": list(self.px_per_mm_xy),
                "tilt_deg": self.tilt_deg, "homography": np.asarray(self.homography).tolist(), "rms_px": self.rms_px}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PlaneScale:
        homography = _matrix(data["homography"], (3, 3), "plane.homography")
        return cls(str(data["image"]), _positive(data["px_per_mm"], "plane.px_per_mm"),
                   tuple(float(v) for v in data["px_per_mm_xy"]),  # type: ignore[arg-type]
                   float(data["tilt_deg"]), homography, float(data["rms_px"]))


@dataclass(frozen=True)
class CameraCalibration:
    """A camera calibrated from target images (OpenCV's pinhole model with lens distortion).

    Attributes
    ----------
    image_size : tuple of int
        (width, height) of the images it was made from: it holds for frames of that size only.
    camera_matrix : ndarray, shape (3, 3)
        K: focal lengths and principal point (px).
    dist_coeffs : ndarray, shape (n,)
        OpenCV's distortion coefficients (k1, k2, p1, p2, k3[, ...]).
    rms_px : float
        Reprojection RMS over every corner of every image (px).
    images : tuple of ImageFit
        Each image used, with its reprojection RMS.
    target : str
        The target's spec (``TargetSpec.text``).
    square_mm : float
        The target's square side (mm).
    flags : int
        The ``cv2.calibrateCamera`` flags used.
    plane : PlaneScale or None
        The specimen plane's scale, when a target image on it was given.
    skipped : tuple of str
        Images in which no target was found.
    std_devs : dict of str to float
        Each fitted parameter's standard deviation from its own views (fx, fy, cx, cy in px; k1, k2, p1, p2
        unitless), as ``cv2.calibrateCameraExtended`` estimates it; empty for a calibration not fitted here.
    fixed : tuple of str
        The parameters held fixed (not fitted): k3 always; the principal point, k2, p1, p2 too when the views
        could not determine them (``fixed_reason``; ``dic.calibration.determinacy``).
    fixed_reason : str
        Why more than k3 is fixed ("" when nothing else is).
    """

    image_size: tuple[int, int]
    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    rms_px: float
    images: tuple[ImageFit, ...]
    target: str
    square_mm: float
    flags: int = 0
    plane: PlaneScale | None = None
    skipped: tuple[str, ...] = field(default=())
    std_devs: dict[str, float] = field(default_factory=dict)
    fixed: tuple[str, ...] = field(default=())
    fixed_reason: str = ""

    @property
    def px_per_mm(self) -> float | None:
        """Ideal pixels per mm on the specimen plane, or None without a plane image."""
        return None if self.plane is None else self.plane.px_per_mm

    def to_dict(self) -> dict[str, Any]:
        """The JSON body of CAL.json (without its format header)."""
        return {"image_size": list(self.image_size), "camera_matrix": self.camera_matrix.tolist(),
                "dist_coeffs": np.asarray(self.dist_coeffs).ravel().tolist(), "rms_px": self.rms_px,
                "images": [{"name": f.name, "corners": f.corners, "rms_px": f.rms_px} for f in self.images],
                "skipped": list(self.skipped), "target": self.target, "square_mm": self.square_mm,
                "flags": self.flags, "plane": None if self.plane is None else self.plane.to_dict(),
                "px_per_mm": self.px_per_mm, "std_devs": dict(self.std_devs), "fixed_parameters": list(self.fixed),
                "fixed_reason": self.fixed_reason}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CameraCalibration:
        """The calibration in ``data`` (as ``to_dict`` wrote it); CalibrationError names a missing or bad field."""
        try:
            width, height = (int(v) for v in data["image_size"])
            if width <= 0 or height <= 0:
                raise CalibrationError("image_size must be two positive integers")
            dist = np.asarray(data["dist_coeffs"], dtype=np.float64).ravel()
            if dist.size not in (4, 5, 8, 12, 14) or not np.all(np.isfinite(dist)):
                raise CalibrationError("dist_coeffs must be 4, 5, 8, 12 or 14 finite numbers")
            images = tuple(ImageFit(str(f["name"]), int(f["corners"]), float(f["rms_px"])) for f in data["images"])
            plane = None if data.get("plane") is None else PlaneScale.from_dict(data["plane"])
            return cls((width, height), _matrix(data["camera_matrix"], (3, 3), "camera_matrix"), dist,
                       float(data["rms_px"]), images, str(data["target"]), _positive(data["square_mm"], "square_mm"),
                       int(data.get("flags", 0)), plane, tuple(str(s) for s in data.get("skipped", ())),
                       {str(k): float(v) for k, v in data.get("std_devs", {}).items()},
                       tuple(str(s) for s in data.get("fixed_parameters", ())), str(data.get("fixed_reason", "")))
        except KeyError as missing:
            raise CalibrationError(f"field {missing.args[0]!r} is missing") from None
        except (TypeError, ValueError) as error:
            if isinstance(error, CalibrationError):
                raise
            raise CalibrationError(f"a field has the wrong form ({error})") from None

    def check_size(self, width: int, height: int, what: str = "the frames") -> None:
        """CalibrationError unless ``what`` has this calibration's image size."""
        if (int(width), int(height)) != tuple(self.image_size):
            w, h = self.image_size
            raise CalibrationError(f"the calibration was made for {w}x{h} images but {what} are {width}x{height}: "
                                   "calibrate at the resolution (and binning, ROI) of the measurement")


def undistort_points(calibration: CameraCalibration, xy: npt.ArrayLike) -> np.ndarray:
    """Ideal pixel positions of image points ``xy`` (shape (..., 2)): the lens's distortion removed.

    ``cv2.undistortPoints`` with ``P = K``, iterated to convergence, so the result stays in pixels
    of an ideal pinhole camera with the calibration's camera matrix. NaN points stay NaN.
    """
    return undistort_pixels(calibration.camera_matrix, calibration.dist_coeffs, xy)


def distort_points(calibration: CameraCalibration, xy: npt.ArrayLike) -> np.ndarray:
    """Image positions (where the lens puts them) of ideal pixel positions ``xy`` (shape (..., 2))."""
    return distort_pixels(calibration.camera_matrix, calibration.dist_coeffs, xy)


def undistort_pixels(camera_matrix: npt.ArrayLike, dist_coeffs: npt.ArrayLike, xy: npt.ArrayLike) -> np.ndarray:
    """Image pixels -> ideal pixels for camera matrix K and OpenCV distortion coefficients (NaN stays NaN)."""
    points = np.asarray(xy, dtype=np.float64)
    flat = points.reshape(-1, 2)
    out = np.full(flat.shape, np.nan)
    finite = np.all(np.isfinite(flat), axis=1)
    if np.any(finite):
        K = np.asarray(camera_matrix, dtype=np.float64)
        out[finite] = cv2.undistortPoints(flat[finite].reshape(-1, 1, 2), K, np.asarray(dist_coeffs, dtype=np.float64),
                                          R=np.eye(3), P=K, criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    return out.reshape(points.shape)


def distort_pixels(camera_matrix: npt.ArrayLike, dist_coeffs: npt.ArrayLike, xy: npt.ArrayLike) -> np.ndarray:
    """Ideal pixels -> image pixels through the lens (``cv2.projectPoints`` of the rays they stand for)."""
    points = np.asarray(xy, dtype=np.float64)
    flat = points.reshape(-1, 2)
    K = np.asarray(camera_matrix, dtype=np.float64)
    rays = np.empty((flat.shape[0], 3))
    rays[:, 0] = (flat[:, 0] - K[0, 2]) / K[0, 0]
    rays[:, 1] = (flat[:, 1] - K[1, 2]) / K[1, 1]
    rays[:, 2] = 1.0
    if rays.shape[0] == 0:
        return points.copy()
    image, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, np.asarray(dist_coeffs, dtype=np.float64))
    return image.reshape(points.shape)


@dataclass(frozen=True)
class PlaneFrame:
    """Plane pixels: positions on the specimen plane (mm on the target's board) scaled by px/mm and turned to
    match ideal pixels at the image's centre, so lengths on the plane / px_per_mm are mm and the axes are the
    image's (the nearest rotation to the homography's Jacobian there; x along the image's x).

    ``q = px_per_mm * rotation @ (p - origin_mm) + origin_px`` for a board point p (mm); ``origin_px`` is the
    image's centre (ideal px) and ``origin_mm`` the board point seen there.
    """

    homography: np.ndarray        # board mm -> ideal px
    px_per_mm: float
    origin_mm: np.ndarray
    origin_px: np.ndarray
    rotation: np.ndarray          # 2 x 2, orthogonal

    @classmethod
    def of(cls, plane: PlaneScale, image_size: tuple[int, int]) -> PlaneFrame:
        """The frame of ``plane`` for images of ``image_size`` (width, height)."""
        H = np.asarray(plane.homography, dtype=np.float64)
        origin_px = np.array([(image_size[0] - 1) / 2.0, (image_size[1] - 1) / 2.0])
        origin_mm = _apply_homography(np.linalg.inv(H), origin_px)
        w, _, vt = np.linalg.svd(homography_jacobian(H, origin_mm))
        return cls(H, plane.px_per_mm, origin_mm, origin_px, w @ vt)

    def to_plane(self, ideal: npt.ArrayLike) -> np.ndarray:
        """Ideal pixels (..., 2) -> plane pixels (NaN stays NaN)."""
        board = _apply_homography(np.linalg.inv(self.homography), ideal)
        return self.px_per_mm * (board - self.origin_mm) @ self.rotation.T + self.origin_px

    def to_ideal(self, plane_px: npt.ArrayLike) -> np.ndarray:
        """Plane pixels (..., 2) -> ideal pixels (``to_plane``'s inverse)."""
        board = (np.asarray(plane_px, dtype=np.float64) - self.origin_px) @ self.rotation / self.px_per_mm
        return _apply_homography(self.homography, board + self.origin_mm)


def plane_points(calibration: CameraCalibration, xy: npt.ArrayLike) -> np.ndarray:
    """Image points (..., 2) where strain is measured: undistorted, and with a plane (``--plane``) mapped to
    plane pixels (``PlaneFrame``); ideal pixels without one. NaN stays NaN."""
    ideal = undistort_points(calibration, xy)
    if calibration.plane is None:
        return ideal
    return PlaneFrame.of(calibration.plane, calibration.image_size).to_plane(ideal)


def image_points(calibration: CameraCalibration, xy: npt.ArrayLike) -> np.ndarray:
    """``plane_points``' inverse: where the camera sees those positions (image px)."""
    ideal = np.asarray(xy, dtype=np.float64)
    if calibration.plane is not None:
        ideal = PlaneFrame.of(calibration.plane, calibration.image_size).to_ideal(ideal)
    return distort_points(calibration, ideal)


def homography_jacobian(H: np.ndarray, point: np.ndarray) -> np.ndarray:
    """d(ideal px) / d(board mm) of the homography at ``point``."""
    x, y = float(point[0]), float(point[1])
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    u = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w
    v = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w
    return np.array([[(H[0, 0] - u * H[2, 0]) / w, (H[0, 1] - u * H[2, 1]) / w],
                     [(H[1, 0] - v * H[2, 0]) / w, (H[1, 1] - v * H[2, 1]) / w]])


def _apply_homography(H: np.ndarray, xy: npt.ArrayLike) -> np.ndarray:
    """``H`` applied to points (..., 2) (in numpy, not cv2.perspectiveTransform: NaN points stay NaN)."""
    points = np.asarray(xy, dtype=np.float64)
    mapped = points @ H[:2, :2].T + H[:2, 2]
    w = points @ H[2, :2] + H[2, 2]
    return mapped / w[..., None]


def _matrix(value: Any, shape: tuple[int, int], name: str) -> np.ndarray:
    matrix = np.asarray(value, dtype=np.float64)
    if matrix.shape != shape or not np.all(np.isfinite(matrix)):
        raise CalibrationError(f"{name} must be a {shape[0]}x{shape[1]} matrix of finite numbers")
    return matrix


def _positive(value: Any, name: str) -> float:
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        raise CalibrationError(f"{name} must be a finite number > 0, got {value!r}")
    return number
