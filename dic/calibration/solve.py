"""Solving a calibration from target detections (Zhang's method, ``cv2.calibrateCameraExtended``) and the
specimen plane's scale from one target lying on it.

``calibrate`` refuses (``CalibrationRefused``) with fewer than ``MIN_VIEWS`` images, when the
overall or any image's reprojection RMS exceeds the bound (default ``DEFAULT_MAX_ERROR_PX``): a
calibration that does not fit its own images would mis-correct every measurement made with it; or when
a parameter its views leave poorly determined exceeds ``UncertaintyBounds`` (after the narrow-field choice of
``dic.calibration.determinacy``), or when the views' boards are (nearly) parallel: one that fits its images by
luck would too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import cv2
import numpy as np

from livedic.dic.calibration.camera import (CalibrationError, CameraCalibration, ImageFit, PlaneScale,
                                            homography_jacobian, undistort_points)
from livedic.dic.calibration.determinacy import (DEFAULT_UNCERTAINTY_BOUNDS, MIN_VIEW_SPREAD_DEG, NARROW_FIELD_FLAGS,
                                                 PARAMETERS, UncertaintyBounds, corner_effects,
                                                 describe_parallel_views, describe_undetermined, free_parameters,
                                                 narrow_field_reason, std_devs, undetermined, view_spread_deg)
from livedic.dic.calibration.targets import Detection

# Zhang's method needs views of the target in at least 3 different orientations.
MIN_VIEWS = 3
# A good corner detector reaches 0.1-0.2 px; above 0.5 px a corner or a view is wrong (blur, a mis-detected
# board, a board that moved or is not flat).
DEFAULT_MAX_ERROR_PX = 0.5
# k3 is left out by default: with a handful of views of an ordinary machine-vision lens it only fits noise
# (it trades against k1, k2); the principal point and both focal lengths are free.
DEFAULT_FLAGS = cv2.CALIB_FIX_K3
# A specimen plane tilted more than this from the camera axis is warned of: the homography takes lengths and strain
# onto the plane, but a target not quite on the specimen, or out-of-plane motion, errs more the more it is tilted.
TILT_WARNING_DEG = 3.0


class CalibrationRefused(CalibrationError):
    """The calibration's fit is not good enough to be used; the message names the worst images."""


def calibrate(detections: Sequence[tuple[str, Detection]], image_size: tuple[int, int], *, target: str,
              square_mm: float, max_error_px: float = DEFAULT_MAX_ERROR_PX, flags: int = DEFAULT_FLAGS,
              skipped: Sequence[str] = (), bounds: UncertaintyBounds = DEFAULT_UNCERTAINTY_BOUNDS,
              narrow_field: str | None = None) -> CameraCalibration:
    """Intrinsics and distortion from targets seen in several images (``cv2.calibrateCameraExtended``).

    The model is chosen from the data (``dic.calibration.determinacy``): when the views cannot locate the
    principal point (a narrow field), it is fixed at the image's centre and k2, p1, p2 at 0, and the fit redone;
    the result's ``fixed`` and ``fixed_reason`` say so.

    Parameters
    ----------
    detections : sequence of (name, Detection)
        The images in which the target was found.
    image_size : (width, height)
    target, square_mm
        The target's spec text and square side, recorded in the result.
    max_error_px : float
        Refuse when the overall RMS or any image's RMS exceeds it.
    flags : int
        ``cv2.calibrateCamera`` flags (default ``CALIB_FIX_K3``).
    skipped : sequence of str
        Images in which no target was found (recorded in the result).
    bounds : UncertaintyBounds
        Refuse when a fitted parameter's standard deviation exceeds them.
    narrow_field : str or None
        A reason to fix the narrow field's parameters (``NARROW_FIELD_FIXED``) whatever these views say (the
        other camera of a rig could not determine them); None: decide from these views.

    Raises
    ------
    CalibrationRefused
        Fewer than ``MIN_VIEWS`` views, an RMS above ``max_error_px``, or a parameter determined worse than
        ``bounds``.
    """
    if len(detections) < MIN_VIEWS:
        raise CalibrationRefused(f"the target was found in {len(detections)} image(s); a calibration needs at least "
                                 f"{MIN_VIEWS} views of it at different tilts (more, 10-20, is better)")
    width, height = (int(image_size[0]), int(image_size[1]))
    fit, spread_deg = _fit(detections, (width, height), flags)
    if spread_deg < MIN_VIEW_SPREAD_DEG:
        raise CalibrationRefused(describe_parallel_views(spread_deg))
    reason = narrow_field if narrow_field is not None else narrow_field_reason(fit.std_devs, (width, height))
    if reason is not None and flags | NARROW_FIELD_FLAGS != flags:
        flags |= NARROW_FIELD_FLAGS
        guess = fit.camera_matrix.copy()
        guess[:2, 2] = (width - 1) / 2.0, (height - 1) / 2.0
        fit, _ = _fit(detections, (width, height), flags, guess)
    _refuse_above(fit, max_error_px)
    poor = undetermined(corner_effects(fit.camera_matrix, fit.dist_coeffs, (width, height), fit.std_devs), bounds)
    if poor:
        raise CalibrationRefused(describe_undetermined(*poor[0]))
    return replace(fit, target=target, square_mm=float(square_mm), skipped=tuple(skipped),
                   fixed=tuple(name for name in PARAMETERS if name not in free_parameters(flags)),
                   fixed_reason=reason or "")


def _refuse_above(fit: CameraCalibration, max_error_px: float) -> None:
    """CalibrationRefused naming the worst images when the overall RMS or an image's exceeds the bound."""
    worst = sorted(fit.images, key=lambda f: f.rms_px, reverse=True)
    bad = [f for f in worst if f.rms_px > max_error_px]
    if fit.rms_px <= max_error_px and not bad:
        return
    names = ", ".join(f"{f.name} ({f.rms_px:.2f} px)" for f in (bad or worst)[:3])
    raise CalibrationRefused(f"reprojection error {fit.rms_px:.3f} px overall, above the bound {max_error_px:g} px in "
                             f"{len(bad)} of {len(fit.images)} image(s); worst: {names}: remove blurred views and "
                             "views where the board moved, bent or was mis-detected, or raise --max-error")


def _fit(detections: Sequence[tuple[str, Detection]], size: tuple[int, int], flags: int,
         guess: np.ndarray | None = None) -> tuple[CameraCalibration, float]:
    """One ``cv2.calibrateCameraExtended`` solution with its per-image errors and standard deviations (``guess``:
    the starting camera matrix, its principal point kept under ``CALIB_FIX_PRINCIPAL_POINT``), and the largest angle
    between its views' boards (degrees)."""
    objects = [d.object_points.astype(np.float32) for _, d in detections]
    images = [d.image_points.astype(np.float32).reshape(-1, 1, 2) for _, d in detections]
    if guess is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    rms, K, dist, rvecs, tvecs, deviations, _, _ = cv2.calibrateCameraExtended(
        objects, images, size, np.eye(3) if guess is None else guess.copy(), np.zeros(5), flags=flags)
    fits = []
    for (name, detection), rvec, tvec in zip(detections, rvecs, tvecs):
        projected, _ = cv2.projectPoints(detection.object_points, rvec, tvec, K, dist)
        residual = projected.reshape(-1, 2) - detection.image_points
        fits.append(ImageFit(name, int(residual.shape[0]), float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))))
    return (CameraCalibration(size, np.asarray(K, dtype=np.float64), np.asarray(dist, dtype=np.float64).ravel(),
                              float(rms), tuple(fits), "", 1.0, int(flags & ~cv2.CALIB_USE_INTRINSIC_GUESS),
                              std_devs=std_devs(deviations, flags)), view_spread_deg(rvecs))


def plane_scale(calibration: CameraCalibration, name: str, detection: Detection) -> PlaneScale:
    """The specimen plane's scale from a target lying on it (its corners undistorted first).

    Fits the homography board (mm) -> ideal pixels; ``px_per_mm`` is the square root of its
    Jacobian's determinant at the board's centre (the scale of areas), ``px_per_mm_xy`` the scale
    along the image's axes there, and ``tilt_deg`` the plane's angle from the camera axis (the
    homography decomposed with K: H ~ K [r1 r2 t]).
    """
    ideal = undistort_points(calibration, detection.image_points)
    board = detection.object_points[:, :2]
    H, _ = cv2.findHomography(board, ideal, 0)
    if H is None:
        raise CalibrationError(f"{name}: the target's corners do not fit a plane")
    mapped = cv2.perspectiveTransform(board.reshape(-1, 1, 2), H).reshape(-1, 2)
    rms = float(np.sqrt(np.mean(np.sum((mapped - ideal) ** 2, axis=1))))
    return plane_from_homography(name, H, board.mean(axis=0), calibration.camera_matrix, rms)


def plane_from_homography(name: str, H: np.ndarray, centre: np.ndarray, camera_matrix: np.ndarray,
                          rms: float = 0.0) -> PlaneScale:
    """The ``PlaneScale`` of homography ``H`` (board mm -> ideal px): scales at the board point ``centre`` (mm),
    tilt from the camera matrix (``plane_scale``; the simulator's truth)."""
    J = homography_jacobian(H, centre)
    # Image-axis scales: the length on the board of a 1 px step along x (or y) in the image, inverted.
    inverse = np.linalg.inv(J)
    per_x, per_y = 1.0 / np.linalg.norm(inverse[:, 0]), 1.0 / np.linalg.norm(inverse[:, 1])
    B = np.linalg.inv(camera_matrix) @ H
    r1, r2 = B[:, 0] / np.linalg.norm(B[:, 0]), B[:, 1] / np.linalg.norm(B[:, 1])
    normal = np.cross(r1, r2)
    normal /= np.linalg.norm(normal)
    tilt = math.degrees(math.acos(min(1.0, abs(float(normal[2])))))
    return PlaneScale(name, float(math.sqrt(abs(np.linalg.det(J)))), (float(per_x), float(per_y)), tilt, H, rms)
