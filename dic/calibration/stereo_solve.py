"""Solving a stereo rig from target image pairs (``cv2.stereoCalibrate``): ``calibrate_stereo``.

Each camera is first calibrated alone (``calibrate``: Zhang's method on every view in which it saw the target),
then the pose between them is solved from the corners seen in both views of each pair (ChArUco corners matched
by id; a chessboard numbered from the other end in one view is turned to match, ``match_pair``), with both
cameras' intrinsics refined together with it (``DEFAULT_STEREO_FLAGS``; at a narrow field both cameras' principal
points fixed at the images' centres and k2, p1, p2 at 0, as ``determinacy`` decides from each camera's own fit). A
pair is refused when the reprojection RMS in either of its views exceeds the bound (``DEFAULT_MAX_ERROR_PX``, the 2D
calibration's): one pair whose board moved between the two exposures would bend R and T for every measurement made
with them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np

from livedic.dic.calibration.camera import CameraCalibration, ImageFit
from livedic.dic.calibration.determinacy import DEFAULT_UNCERTAINTY_BOUNDS, NARROW_FIELD_FLAGS, UncertaintyBounds
from livedic.dic.calibration.solve import DEFAULT_MAX_ERROR_PX, MIN_VIEWS, CalibrationRefused, calibrate
from livedic.dic.calibration.stereo import PairFit, StereoCalibration
from livedic.dic.calibration.targets import MIN_CHARUCO_CORNERS, Detection, TargetSpec

# Refining both cameras' intrinsics with R and T (CALIB_USE_INTRINSIC_GUESS) rather than fixing those of each
# camera's own fit: on rendered pairs the epipolar constraint of every pair corrects the focal lengths each camera
# alone confuses with its distance to the board (measured: docs/guide/calibration.md, "Stereo"). k3 stays out, as
# in the 2D fit.
DEFAULT_STEREO_FLAGS = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3
# Levenberg-Marquardt to convergence: OpenCV's default (30 iterations, 1e-6) stops short on pairs of long lenses.
_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-10)


@dataclass(frozen=True)
class TargetPair:
    """One image pair: both names and what was found in each (a Detection, or None when the target was not)."""

    left: str
    right: str
    left_found: Detection | None
    right_found: Detection | None

    @property
    def label(self) -> str:
        return f"{self.left} | {self.right}"


def calibrate_stereo(pairs: Sequence[TargetPair], left_size: tuple[int, int], right_size: tuple[int, int], *,
                     spec: TargetSpec, square_mm: float, max_error_px: float = DEFAULT_MAX_ERROR_PX,
                     flags: int = DEFAULT_STEREO_FLAGS,
                     bounds: UncertaintyBounds = DEFAULT_UNCERTAINTY_BOUNDS) -> StereoCalibration:
    """The rig seen in ``pairs``: each camera's intrinsics and distortion, R and T left -> right, per-pair errors.

    Parameters
    ----------
    pairs : sequence of TargetPair
        The image pairs in order; a pair whose target is missing in one view, or with fewer common corners
        than a view needs, is skipped (with its reason in ``StereoCalibration.skipped``).
    left_size, right_size : (width, height)
    spec, square_mm
        The target.
    max_error_px : float
        Refuse when the overall RMS, a camera's own fit, or either view of any pair exceeds it.
    flags : int
        ``cv2.stereoCalibrate`` flags (default ``DEFAULT_STEREO_FLAGS``); the narrow field's
        (``determinacy.NARROW_FIELD_FLAGS``) are added when a camera's views cannot locate its principal point.
    bounds : UncertaintyBounds
        Refuse when a camera's own fit leaves a parameter's standard deviation above them.

    Raises
    ------
    CalibrationRefused
        Fewer than ``MIN_VIEWS`` usable pairs, a reprojection RMS above ``max_error_px``, or a camera's parameter
        determined worse than ``bounds``.
    """
    seen = [pair for pair in pairs if pair.left_found is not None and pair.right_found is not None]
    if len(seen) < MIN_VIEWS:
        raise CalibrationRefused(f"the target was seen in both views of {len(seen)} of {len(pairs)} pair(s); a "
                                 f"stereo calibration needs at least {MIN_VIEWS} pairs at different tilts (10-20 is "
                                 "better)")
    left = _camera(pairs, "left", left_size, spec, square_mm, max_error_px, bounds)
    right = _camera(pairs, "right", right_size, spec, square_mm, max_error_px, bounds)
    # One lens model for the rig: when either camera's views cannot locate its principal point, both are fixed
    # (stereoCalibrate's flags hold for both cameras).
    if left.fixed_reason and not right.fixed_reason:
        right = _camera(pairs, "right", right_size, spec, square_mm, max_error_px, bounds,
                        f"as the left camera's: {left.fixed_reason}")
    elif right.fixed_reason and not left.fixed_reason:
        left = _camera(pairs, "left", left_size, spec, square_mm, max_error_px, bounds,
                       f"as the right camera's: {right.fixed_reason}")
    if left.fixed_reason:
        flags |= NARROW_FIELD_FLAGS
    used: list[tuple[TargetPair, Detection, Detection]] = []
    skipped: list[str] = []
    for pair in pairs:
        if pair.left_found is None or pair.right_found is None:
            side = "either view" if pair.left_found is pair.right_found else \
                "the left view" if pair.left_found is None else "the right view"
            skipped.append(f"{pair.label}: no target in {side}")
            continue
        matched = match_pair(pair.left_found, pair.right_found, spec, square_mm, left, right)
        if matched is None:
            skipped.append(f"{pair.label}: fewer than {MIN_CHARUCO_CORNERS} corners seen in both views")
            continue
        used.append((pair, *matched))
    if len(used) < MIN_VIEWS:
        raise CalibrationRefused(f"{len(used)} of {len(pairs)} pair(s) show at least {MIN_CHARUCO_CORNERS} corners "
                                 f"in both views; a stereo calibration needs at least {MIN_VIEWS}: show more of the "
                                 "board to both cameras")
    objects = [lp.object_points.astype(np.float32) for _, lp, _ in used]
    rms, K1, D1, K2, D2, R, T, _, _, _, _, errors = cv2.stereoCalibrateExtended(
        objects, [lp.image_points.astype(np.float32).reshape(-1, 1, 2) for _, lp, _ in used],
        [rp.image_points.astype(np.float32).reshape(-1, 1, 2) for _, _, rp in used],
        left.camera_matrix.copy(), left.dist_coeffs.copy(), right.camera_matrix.copy(), right.dist_coeffs.copy(),
        (int(left_size[0]), int(left_size[1])), np.eye(3), np.zeros((3, 1)), flags=int(flags), criteria=_CRITERIA)
    errors = np.asarray(errors, dtype=np.float64).reshape(-1, 2)
    fits = tuple(PairFit(pair.left, pair.right, int(lp.ids.size), float(e[0]), float(e[1]))
                 for (pair, lp, _), e in zip(used, errors))
    _refuse_above(fits, float(rms), max_error_px)
    return StereoCalibration(_refitted(left, _views(pairs, "left"), K1, D1),
                             _refitted(right, _views(pairs, "right"), K2, D2),
                             np.asarray(R, dtype=np.float64), np.asarray(T, dtype=np.float64).ravel(), float(rms),
                             fits, tuple(skipped))


def match_pair(left: Detection, right: Detection, spec: TargetSpec, square_mm: float,
               left_camera: CameraCalibration, right_camera: CameraCalibration) -> tuple[Detection, Detection] | None:
    """The corners seen in both views, in the same order (None: fewer than ``MIN_CHARUCO_CORNERS`` in common).

    A chessboard has no mark telling its ends apart: the detector may number one view from the other end (a
    half turn; a quarter turn too on a square grid). Of the numberings the board's symmetry allows, the right
    view's is the one whose implied turn between the cameras (from each camera's pose of the board) is the
    smallest: the true numbering gives the rig's angle, a half-turned one at least 180 degrees less that angle,
    so the choice is right for any rig whose cameras are less than 90 degrees apart.
    """
    if spec.kind == "chessboard":
        right = min(_numberings(right, spec, square_mm), key=lambda r: _turn_between(left, r, left_camera, right_camera))
    common, in_left, in_right = np.intersect1d(left.ids, right.ids, return_indices=True)
    if common.size < MIN_CHARUCO_CORNERS:
        return None
    return (Detection(left.image_points[in_left], common, left.object_points[in_left]),
            Detection(right.image_points[in_right], common, right.object_points[in_right]))


def _numberings(found: Detection, spec: TargetSpec, square_mm: float) -> list[Detection]:
    """``found`` (a whole chessboard) under each turn of the grid onto itself: the ids it might have had."""
    cols, rows = spec.inner_corners
    col, row = found.ids % cols, found.ids // cols
    turns = [(col, row), (cols - 1 - col, rows - 1 - row)]
    if cols == rows:
        turns += [(row, cols - 1 - col), (rows - 1 - row, col)]
    objects = spec.object_points(square_mm)
    return [Detection(found.image_points, r * cols + c, objects[r * cols + c]) for c, r in turns]


def _turn_between(left: Detection, right: Detection, left_camera: CameraCalibration,
                  right_camera: CameraCalibration) -> float:
    """Angle (rad) of the rotation left camera -> right camera implied by each camera's pose of the board."""
    poses = []
    for found, camera in ((left, left_camera), (right, right_camera)):
        ok, rvec, _ = cv2.solvePnP(found.object_points, found.image_points, camera.camera_matrix, camera.dist_coeffs)
        if not ok:
            return float("inf")
        poses.append(cv2.Rodrigues(rvec)[0])
    turn = poses[1] @ poses[0].T
    return float(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))


def _camera(pairs: Sequence[TargetPair], side: str, size: tuple[int, int], spec: TargetSpec, square_mm: float,
            max_error_px: float, bounds: UncertaintyBounds, narrow_field: str | None = None) -> CameraCalibration:
    """One camera calibrated alone from every view in which it saw the target (the stereo fit's start;
    ``narrow_field``: a reason to fix the narrow field's parameters whatever its own views say)."""
    missing = tuple(getattr(pair, side) for pair in pairs if getattr(pair, f"{side}_found") is None)
    try:
        return calibrate(_views(pairs, side), size, target=spec.text, square_mm=square_mm, max_error_px=max_error_px,
                         skipped=missing, bounds=bounds, narrow_field=narrow_field)
    except CalibrationRefused as refused:
        raise CalibrationRefused(f"the {side} camera: {refused}") from None


def _views(pairs: Sequence[TargetPair], side: str) -> list[tuple[str, Detection]]:
    """(image name, detection) of every image of camera ``side`` ("left" or "right") that shows the target."""
    return [(getattr(pair, side), found) for pair in pairs if (found := getattr(pair, f"{side}_found")) is not None]


def _refitted(camera: CameraCalibration, views: Sequence[tuple[str, Detection]], K: np.ndarray,
              dist: np.ndarray) -> CameraCalibration:
    """``camera`` with the stereo fit's intrinsics, its per-image errors taken again with them (each board's pose
    refitted), so the file's numbers are of the lens it holds."""
    K, dist = np.asarray(K, dtype=np.float64), np.asarray(dist, dtype=np.float64).ravel()
    fits, squares = [], 0.0
    for name, found in views:
        _, rvec, tvec = cv2.solvePnP(found.object_points, found.image_points, K, dist)
        projected, _ = cv2.projectPoints(found.object_points, rvec, tvec, K, dist)
        square = np.sum((projected.reshape(-1, 2) - found.image_points) ** 2, axis=1)
        fits.append(ImageFit(name, int(square.size), float(np.sqrt(np.mean(square)))))
        squares += float(np.sum(square))
    rms = float(np.sqrt(squares / max(1, sum(fit.corners for fit in fits))))
    return replace(camera, camera_matrix=K, dist_coeffs=dist, rms_px=rms, images=tuple(fits))


def _refuse_above(fits: Sequence[PairFit], rms: float, max_error_px: float) -> None:
    """CalibrationRefused naming the worst pairs when the overall RMS or a view of a pair exceeds the bound."""
    worst = sorted(fits, key=lambda f: max(f.rms_left_px, f.rms_right_px), reverse=True)
    bad = [f for f in worst if max(f.rms_left_px, f.rms_right_px) > max_error_px]
    if rms <= max_error_px and not bad:
        return
    names = ", ".join(f"{f.left} | {f.right} ({f.rms_left_px:.2f} / {f.rms_right_px:.2f} px)"
                      for f in (bad or worst)[:3])
    raise CalibrationRefused(f"stereo reprojection error {rms:.3f} px overall, above the bound {max_error_px:g} px "
                             f"in {len(bad)} of {len(fits)} pair(s); worst (left / right): {names}: remove pairs "
                             "where the board moved between the two exposures, was blurred or mis-detected, or raise "
                             "--max-error")

