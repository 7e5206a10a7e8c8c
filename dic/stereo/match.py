"""Left -> right matching on the reference pair: where each left grid point's material is in the right view.

Two stages, both on the dic building blocks:

1. **Epipolar seed.** The point's ray (left ideal pixels -> a line of sight) is cut to a depth range
   (``depth_mm``; by default +-``DEPTH_RANGE`` around the rig's working distance, where the two optical axes
   pass closest). Its image in the right view is a segment of the epipolar line (straight in ideal pixels),
   sampled every pixel, each sample put through the right lens's distortion; the integer position of best ZNCC
   (``dic.correlation``'s kernels, the left subset against the right image) is the seed. A 2D search box would
   cost the square of this and find more wrong peaks.
2. **IC-GN.** From the seed, with start gradients from the homography of a plane through the seed point facing
   the rig (normal along the bisector of the optical axes), IC-GN refines a warp between the views: second order
   (``dic.subpixel.icgn2``, ``order=2``, the default) or first order (``dic.subpixel.icgn``, ``order=1``).
   The perspective between the views curves the warp across a subset: on rendered 25 and 35 degree rigs
   (docs/guide/stereo.md) the affine warp leaves 0.007-0.010 px RMS at 21 px subsets and 0.015-0.021 px at
   31 px, the second-order one 0.003 and 0.002 px.

Flags, never ok: IC-GN's own failures (``StereoStatus.NOT_MATCHED``, the ``dic.status.Status`` kept in
``match_status``), ZNCC below ``min_zncc`` (``LOW_CORRELATION``), a match off the epipolar line by more than
``max_epipolar_px`` or behind a camera (``dic.stereo.triangulate``), a match whose disparity disagrees with its
neighbours' (``OUTLIER``, ``dic.quality.median_test`` with the warp's gradients). The ZNCC bound is higher than
the tracker's (``MIN_STEREO_ZNCC``): the epipolar search tries hundreds of positions and the second-order warp
has 12 parameters to fit, so a wrong match scores higher by chance than a tracked point does (measured: an
unrelated right image gave wrong matches up to ZNCC 0.86, a few of them on the epipolar line).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit, prange

from livedic.dic.calibration import StereoCalibration, distort_points, undistort_points
from livedic.dic.correlation import (DEFAULT_SUBSET, prepare_reference_subset, round_half_up, snap_points,
                                     subset_inside, zncc_at_integer)
from livedic.dic.neighbours import neighbour_graph
from livedic.dic.quality import median_test
from livedic.dic.status import FLAT_REFERENCE, OK, OUTSIDE_REFERENCE, OUTSIDE_TARGET, Status
from livedic.dic.stereo.status import StereoStatus
from livedic.dic.stereo.triangulate import DEFAULT_MAX_EPIPOLAR_PX, Triangulation, triangulate
from livedic.dic.subpixel import icgn, icgn2
from livedic.dic.validation import as_image, as_points, check_subset

# Default depth range: the working distance (where the optical axes pass closest) times 1 -+ this.
DEPTH_RANGE = 0.2
# Samples of the epipolar segment per pixel of its length (the ZNCC peak of 3-5 px speckles is ~3 px wide).
SAMPLES_PER_PX = 1.0
ORDERS = (1, 2)
# A left -> right match is kept from this ZNCC up (module notes). Views of one speckled surface correlate at
# 0.99+ (rendered: 0.9999); wrong matches on an unrelated image reached 0.86.
MIN_STEREO_ZNCC = 0.9


@dataclass(frozen=True)
class StereoMatch:
    """The reference pair's correspondences.

    Attributes
    ----------
    left : ndarray, shape (N, 2)
        Left positions (px): the points given, snapped to pixel centres (the subsets' centres).
    right : ndarray, shape (N, 2)
        Where the same material is in the right image (px, sub-pixel); NaN where ``status`` is not OK.
    gradients : ndarray, shape (N, 4)
        ux, uy, vx, vy of the left -> right warp (the perspective between the views at the subset); NaN where
        not OK.
    zncc : ndarray, shape (N,)
        ZNCC of the refined match (kept where it was judged too low).
    triangulation : Triangulation
        The reference 3D points (``triangulation.xyz``) and their quality.
    status : ndarray of int8, shape (N,)
        ``StereoStatus`` codes.
    match_status : ndarray of int8, shape (N,)
        The seed's and IC-GN's ``dic.status.Status`` (why a NOT_MATCHED point failed).
    """

    left: np.ndarray
    right: np.ndarray
    gradients: np.ndarray
    zncc: np.ndarray
    triangulation: Triangulation
    status: np.ndarray
    match_status: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        return self.status == StereoStatus.OK

    @property
    def xyz(self) -> np.ndarray:
        """The reference 3D points (mm, left camera frame), NaN where not OK."""
        return self.triangulation.xyz


def working_distance(calibration: StereoCalibration) -> float:
    """Depth (mm, along the left axis) of the point where the two cameras' optical axes pass closest.

    Raises ValueError for (nearly) parallel axes, whose closest point is not defined: give ``depth_mm`` then.
    """
    left_axis = np.array([0.0, 0.0, 1.0])
    right_centre = -calibration.rotation.T @ calibration.translation_mm
    right_axis = calibration.rotation.T @ left_axis
    # closest points of the lines s * a and c + t * b: solve the 2 x 2 normal equations
    ab = float(left_axis @ right_axis)
    if 1.0 - ab * ab < 1e-6:
        raise ValueError("the cameras' axes are parallel: give the specimen's depth range (depth_mm)")
    rhs = np.array([left_axis @ right_centre, right_axis @ right_centre])
    s, _ = np.linalg.solve(np.array([[1.0, -ab], [ab, -1.0]]), rhs)
    if not s > 0.0:
        raise ValueError("the cameras' axes meet behind the left camera: give the specimen's depth range (depth_mm)")
    return float(s)


def epipolar_candidates(calibration: StereoCalibration, left_xy: np.ndarray,
                        depth_mm: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Right image positions (px) along each left point's epipolar segment for depths in ``depth_mm``.

    Returns x, y of shape (N, M), M the longest segment's samples; shorter rows padded with NaN.
    """
    near, far = depth_mm
    ideal = undistort_points(calibration.left, left_xy)
    rays = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(calibration.left.camera_matrix).T
    ends = []
    for depth in (near, far):
        in_right = (rays * depth) @ calibration.rotation.T + calibration.translation_mm
        projected = in_right @ calibration.right.camera_matrix.T
        ends.append(projected[:, :2] / projected[:, 2:3])
    length = np.linalg.norm(ends[1] - ends[0], axis=1)
    counts = np.ceil(length * SAMPLES_PER_PX).astype(np.int64) + 1
    steps = np.arange(int(counts.max()) if len(counts) else 1)
    fraction = steps[None, :] / np.maximum(counts - 1, 1)[:, None]
    samples = ends[0][:, None, :] + fraction[..., None] * (ends[1] - ends[0])[:, None, :]
    samples[steps[None, :] >= counts[:, None]] = np.nan
    image = distort_points(calibration.right, samples.reshape(-1, 2)).reshape(samples.shape)
    return np.ascontiguousarray(image[..., 0]), np.ascontiguousarray(image[..., 1])


@njit(cache=True, parallel=True)
def _scan(left, right, xs, ys, half, cand_x, cand_y, best_u, best_v, best_zncc, status):
    """Best integer ZNCC of each left subset over its candidate right positions (NaN candidates skipped)."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        x, y = xs[i], ys[i]
        best_zncc[i] = -2.0
        if not subset_inside(left.shape[0], left.shape[1], x, y, half):
            status[i] = OUTSIDE_REFERENCE
            continue
        if prepare_reference_subset(left, x, y, half, fhat) == 0.0:
            status[i] = FLAT_REFERENCE
            continue
        status[i] = OUTSIDE_TARGET
        last_x, last_y = -1, -1
        for j in range(cand_x.shape[1]):
            if not (np.isfinite(cand_x[i, j]) and np.isfinite(cand_y[i, j])):
                continue
            cx, cy = round_half_up(cand_x[i, j]), round_half_up(cand_y[i, j])
            if (cx == last_x and cy == last_y) or not subset_inside(right.shape[0], right.shape[1], cx, cy, half):
                continue
            last_x, last_y = cx, cy
            c = zncc_at_integer(fhat, right, x, y, half, cx - x, cy - y)
            if c > best_zncc[i]:
                best_zncc[i] = c
                best_u[i] = cx - x
                best_v[i] = cy - y
                status[i] = OK


def view_homography(calibration: StereoCalibration, point_mm: np.ndarray) -> np.ndarray:
    """Left ideal px -> right ideal px through the plane at ``point_mm`` (N, 3) facing the rig, (N, 3, 3).

    The plane's normal is the bisector of the two optical axes (a specimen both cameras look at squarely):
    ``H = K_r (R + T n^T / d) K_l^-1`` for the plane ``n . X = d``.
    """
    normal = np.array([0.0, 0.0, 1.0]) + calibration.rotation.T @ np.array([0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    distance = np.asarray(point_mm, dtype=np.float64).reshape(-1, 3) @ normal
    K_left_inverse = np.linalg.inv(calibration.left.camera_matrix)
    shift = np.outer(calibration.translation_mm, normal)
    plane = calibration.rotation[None] + shift[None] / distance[:, None, None]
    return calibration.right.camera_matrix[None] @ plane @ K_left_inverse[None]


def homography_gradients(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """ux, uy, vx, vy (N, 4) of the maps ``H`` (N, 3, 3) at points ``xy`` (N, 2): the Jacobian minus identity."""
    h = np.einsum("nij,nj->ni", H, np.column_stack([xy, np.ones(len(xy))]))
    u, v, w = h[:, 0] / h[:, 2], h[:, 1] / h[:, 2], h[:, 2]
    ux = (H[:, 0, 0] - u * H[:, 2, 0]) / w - 1.0
    uy = (H[:, 0, 1] - u * H[:, 2, 1]) / w
    vx = (H[:, 1, 0] - v * H[:, 2, 0]) / w
    vy = (H[:, 1, 1] - v * H[:, 2, 1]) / w - 1.0
    return np.column_stack([ux, uy, vx, vy])


def match_stereo(calibration: StereoCalibration, left: np.ndarray, right: np.ndarray, points: npt.ArrayLike, *,
                 subset: int = DEFAULT_SUBSET, depth_mm: tuple[float, float] | None = None, order: int = 2,
                 min_zncc: float = MIN_STEREO_ZNCC, max_epipolar_px: float = DEFAULT_MAX_EPIPOLAR_PX) -> StereoMatch:
    """Match each left point into the right image of the reference pair (module notes).

    Parameters
    ----------
    calibration : StereoCalibration
        Its cameras' image sizes must be the images'.
    left, right : ndarray, shape (H, W)
        The reference pair (grey, any dtype ``dic.validation.as_image`` takes), of equal size.
    points : array_like, shape (N, 2)
        (x, y) left positions, snapped to pixel centres.
    subset : int
        Odd subset side (px).
    depth_mm : (float, float), optional
        Nearest and furthest depth (mm along the left camera's axis) the specimen's points can have; default
        ``working_distance(calibration) * (1 -+ DEPTH_RANGE)``.
    order : {1, 2}
        IC-GN shape function: 1 affine, 2 second order.
    min_zncc : float
        Matches below this ZNCC are flagged ``LOW_CORRELATION``.
    max_epipolar_px : float
        Matches further from the epipolar line than this are flagged ``EPIPOLAR``.

    Returns
    -------
    StereoMatch

    Raises
    ------
    ValueError
        Images of different sizes or not the calibration's, bad points, subset, depth range or order.
    """
    left = as_image(left, "left")
    right = as_image(right, "right")
    if left.shape != right.shape:
        raise ValueError(f"the left image is {left.shape[1]}x{left.shape[0]} but the right one "
                         f"{right.shape[1]}x{right.shape[0]}: give a pair from the same rig")
    calibration.left.check_size(left.shape[1], left.shape[0], "the left images")
    calibration.right.check_size(right.shape[1], right.shape[0], "the right images")
    half = check_subset(subset, left.shape)
    if order not in ORDERS:
        raise ValueError(f"order must be 1 (affine) or 2 (second order), got {order!r}")
    if depth_mm is None:
        distance = working_distance(calibration)
        depth_mm = (distance * (1.0 - DEPTH_RANGE), distance * (1.0 + DEPTH_RANGE))
    near, far = (float(d) for d in depth_mm)
    if not 0.0 < near < far or not np.isfinite(far):
        raise ValueError(f"depth_mm must be (near, far) with 0 < near < far, got {depth_mm!r}")
    xs, ys = snap_points(as_points(points))
    left_xy = np.column_stack([xs, ys]).astype(np.float64)
    n = len(xs)
    cand_x, cand_y = epipolar_candidates(calibration, left_xy, (near, far))
    u0, v0, seed_zncc = np.zeros(n), np.zeros(n), np.empty(n)
    seed_status = np.empty(n, dtype=np.int8)
    _scan(left, right, xs, ys, half, cand_x, cand_y, u0, v0, seed_zncc, seed_status)
    seeded = seed_status == OK
    seed_right = np.where(seeded[:, None], left_xy + np.column_stack([u0, v0]), np.nan)
    seed_xyz = triangulate(calibration, left_xy, seed_right, max_epipolar_px=np.inf).xyz
    start = np.zeros((n, 4))
    usable = seeded & np.all(np.isfinite(seed_xyz), axis=1)
    if np.any(usable):
        ideal = undistort_points(calibration.left, left_xy[usable])
        start[usable] = homography_gradients(view_homography(calibration, seed_xyz[usable]), ideal)
    refined = _refine(left, right, xs, ys, half, u0, v0, start, seed_status, order)
    match_status = refined.status.astype(np.int8)
    matched = match_status == Status.OK
    right_xy = np.where(matched[:, None], left_xy + np.column_stack([refined.u, refined.v]), np.nan)
    gradients = np.column_stack([refined.ux, refined.uy, refined.vx, refined.vy])
    low = matched & ~(refined.zncc >= min_zncc)
    right_xy[low] = np.nan
    triangulation = triangulate(calibration, left_xy, right_xy, max_epipolar_px=max_epipolar_px)
    status = np.where(matched, triangulation.status, StereoStatus.NOT_MATCHED).astype(np.int8)
    status[low] = StereoStatus.LOW_CORRELATION
    status[_outliers(left_xy, right_xy, gradients, status == StereoStatus.OK)] = StereoStatus.OUTLIER
    ok = status == StereoStatus.OK
    return StereoMatch(left=left_xy, right=np.where(ok[:, None], right_xy, np.nan),
                       gradients=np.where(ok[:, None], gradients, np.nan), zncc=refined.zncc,
                       triangulation=triangulation, status=status, match_status=match_status)


def _outliers(left_xy: np.ndarray, right_xy: np.ndarray, gradients: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Matches whose disparity (right - left) disagrees with their ok neighbours' (normalised median test)."""
    if np.count_nonzero(ok) < 2:
        return np.zeros(len(ok), dtype=bool)
    disparity = np.where(ok[:, None], right_xy - left_xy, 0.0)
    ux, uy, vx, vy = (np.where(ok, g, np.nan) for g in gradients.T)
    flagged, _ = median_test(left_xy[:, 0], left_xy[:, 1], disparity[:, 0], disparity[:, 1], ok,
                             neighbour_graph(left_xy), gradients=(ux, uy, vx, vy))
    return flagged


def _refine(left, right, xs, ys, half, u0, v0, start, status, order):
    """IC-GN of the chosen order from the seeds (left subsets warped into the right image)."""
    first = icgn.prepare_reference(left, xs, ys, half)
    coefficients = icgn.prepare_target(right)
    ux0, uy0, vx0, vy0 = start.T
    if order == 1:
        return icgn.refine_prepared(first, coefficients, u0, v0, ux0, uy0, vx0, vy0, status=status)
    return icgn2.refine_prepared(icgn2.prepare_from(first), coefficients, u0, v0, ux0, uy0, vx0, vy0, status=status)
