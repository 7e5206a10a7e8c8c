"""One stereo frame: both views' tracked positions -> 3D points, displacements U, V, W, 3D extensometers.

The reference pair gives each left point its right correspondence (``dic.stereo.match``) and its reference 3D
point. In each new pair both views are tracked from their own reference image by the 2D tracker as it is; the
right view tracks the subsets centred on the matched right positions snapped to pixel centres
(``right_track_points``), and ``follow`` carries the sub-pixel offset between the snapped centre and the
matched position along with the subset's warp, so both views follow the same material point. The current
positions are triangulated (``dic.stereo.triangulate``) and U, V, W = current - reference (mm, left camera
frame; ``specimen_frame`` turns them to the specimen's best-fit plane, W along its normal).

A point is OK only where the reference match, both views' tracking and the triangulation are; elsewhere NaN
and the first reason in this order: ``NOT_MATCHED`` (or the reference's own code), ``LEFT_NOT_OK``,
``RIGHT_NOT_OK``, then the triangulation's (``NOT_FINITE``, ``EPIPOLAR``, ``BEHIND_CAMERA``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from livedic.dic.calibration import StereoCalibration
from livedic.dic.correlation import snap_points
from livedic.dic.stereo.match import StereoMatch
from livedic.dic.stereo.status import StereoStatus
from livedic.dic.stereo.triangulate import DEFAULT_MAX_EPIPOLAR_PX, Triangulation, triangulate


@dataclass(frozen=True)
class StereoPoints:
    """3D points of one frame and their displacements from the reference.

    Attributes
    ----------
    xyz : ndarray, shape (N, 3)
        X, Y, Z (mm, left camera frame); NaN where not OK.
    displacement : ndarray, shape (N, 3)
        U, V, W = xyz - the reference's (mm); NaN where not OK.
    status : ndarray of int8, shape (N,)
        ``StereoStatus`` codes.
    triangulation : Triangulation
        The triangulation's quality values (epipolar distance, reprojection errors).
    """

    xyz: np.ndarray
    displacement: np.ndarray
    status: np.ndarray
    triangulation: Triangulation

    @property
    def ok(self) -> np.ndarray:
        return self.status == StereoStatus.OK


def right_track_points(match: StereoMatch) -> tuple[np.ndarray, np.ndarray]:
    """The right view's tracking points: the matched positions snapped to pixel centres (the tracker's subset
    centres, NaN where unmatched) and each match's offset from its centre (px, (N, 2), zero where unmatched)."""
    centres = np.full_like(match.right, np.nan)
    offsets = np.zeros_like(match.right)
    ok = match.ok
    if np.any(ok):
        xs, ys = snap_points(match.right[ok])
        centres[ok] = np.column_stack([xs, ys])
        offsets[ok] = match.right[ok] - centres[ok]
    return centres, offsets


def follow(centres_now: npt.ArrayLike, offsets: npt.ArrayLike, ux: npt.ArrayLike | None = None,
           uy: npt.ArrayLike | None = None, vx: npt.ArrayLike | None = None,
           vy: npt.ArrayLike | None = None) -> np.ndarray:
    """Current positions of material points ``offsets`` (N, 2) px away from tracked subset centres.

    ``centres_now`` (N, 2): where the tracker put the centres; the subset's warp gradients (None: a rigid shift)
    carry the offset: ``x = centre + (I + grad u) offset``.
    """
    centres = np.asarray(centres_now, dtype=np.float64).reshape(-1, 2)
    offset = np.asarray(offsets, dtype=np.float64).reshape(-1, 2)
    if ux is None or uy is None or vx is None or vy is None:
        return centres + offset
    ux, uy, vx, vy = (np.asarray(g, dtype=np.float64) for g in (ux, uy, vx, vy))
    return centres + offset + np.column_stack([ux * offset[:, 0] + uy * offset[:, 1],
                                               vx * offset[:, 0] + vy * offset[:, 1]])


def stereo_points(calibration: StereoCalibration, reference: StereoMatch, left_xy: npt.ArrayLike,
                 left_ok: npt.ArrayLike, right_xy: npt.ArrayLike, right_ok: npt.ArrayLike, *,
                 max_epipolar_px: float = DEFAULT_MAX_EPIPOLAR_PX) -> StereoPoints:
    """Triangulate one frame's tracked positions and take the displacements from the reference (module notes).

    Parameters
    ----------
    calibration : StereoCalibration
    reference : StereoMatch
        The reference pair's match (its 3D points and status).
    left_xy, right_xy : array_like, shape (N, 2)
        Current image positions (px) of the reference's points in each view (the right ones through ``follow``).
    left_ok, right_ok : array_like of bool, shape (N,)
        Each view's tracking status (the tracker's ``ok``).
    max_epipolar_px : float
        As ``triangulate``'s.

    Returns
    -------
    StereoPoints
    """
    n = len(reference.status)
    left_ok = np.asarray(left_ok, dtype=bool).reshape(-1)
    right_ok = np.asarray(right_ok, dtype=bool).reshape(-1)
    if left_ok.shape != (n,) or right_ok.shape != (n,):
        raise ValueError(f"the reference holds {n} points; got {left_ok.size} left and {right_ok.size} right flags")
    triangulation = triangulate(calibration, left_xy, right_xy, max_epipolar_px=max_epipolar_px)
    if len(triangulation.status) != n:
        raise ValueError(f"the reference holds {n} points; got {len(triangulation.status)} positions")
    status = triangulation.status.copy()
    status[~right_ok] = StereoStatus.RIGHT_NOT_OK
    status[~left_ok] = StereoStatus.LEFT_NOT_OK
    status = np.where(reference.ok, status, reference.status).astype(np.int8)
    ok = status == StereoStatus.OK
    xyz = np.where(ok[:, None], triangulation.xyz, np.nan)
    return StereoPoints(xyz=xyz, displacement=xyz - reference.xyz, status=status, triangulation=triangulation)


@dataclass(frozen=True)
class SpecimenFrame:
    """The specimen's best-fit plane: ``q = rotation @ (X - origin)``; rows of ``rotation`` are the plane's x, y
    (x along the left camera's x projected on the plane) and its normal, pointing away from the cameras."""

    origin: np.ndarray
    rotation: np.ndarray

    def to_specimen(self, xyz: npt.ArrayLike) -> np.ndarray:
        """Points (N, 3) in mm in the specimen frame."""
        return (np.asarray(xyz, dtype=np.float64) - self.origin) @ self.rotation.T

    def turn(self, vectors: npt.ArrayLike) -> np.ndarray:
        """Vectors (N, 3), e.g. displacements U, V, W, in the specimen frame's axes (W along its normal)."""
        return np.asarray(vectors, dtype=np.float64) @ self.rotation.T


def tangent_basis(normal: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """Rows e1, e2, e3 of a right-handed frame: e3 the unit ``normal`` turned to point along ``towards``
    (away from the camera), e1 the camera's x axis projected on the plane, e2 = e3 x e1 (the image's y)."""
    e3 = normal / np.linalg.norm(normal)
    if e3 @ towards < 0.0:
        e3 = -e3
    e1 = np.array([1.0, 0.0, 0.0]) - e3[0] * e3
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(e3, e1), e3])


def specimen_frame(reference_xyz: npt.ArrayLike) -> SpecimenFrame:
    """The best-fit plane (least squares, SVD) through the finite reference points (N, 3), at their centroid."""
    points = np.asarray(reference_xyz, dtype=np.float64).reshape(-1, 3)
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) < 3:
        raise ValueError(f"a specimen plane needs at least 3 measured points, got {len(points)}")
    origin = points.mean(axis=0)
    _, singular, vt = np.linalg.svd(points - origin, full_matrices=False)
    if singular[1] <= 1e-9 * singular[0]:
        raise ValueError("the measured points lie on a line: no specimen plane")
    return SpecimenFrame(origin, tangent_basis(vt[2], origin))


@dataclass(frozen=True)
class Extensometer3D:
    """A 3D extensometer's readings: the reference and current lengths (mm) and the engineering strain."""

    length0_mm: np.ndarray
    length_mm: np.ndarray
    strain: np.ndarray


def extensometer_3d(reference_xyz: npt.ArrayLike, current_xyz: npt.ArrayLike, ends: npt.ArrayLike) -> Extensometer3D:
    """Lengths in space between pairs of tracked points: ``ends`` (K, 2) point indices; NaN where an end is NaN.

    The distance in 3D is free of out-of-plane motion and of the specimen's tilt, which a 2D length reads.
    """
    reference = np.asarray(reference_xyz, dtype=np.float64).reshape(-1, 3)
    current = np.asarray(current_xyz, dtype=np.float64).reshape(-1, 3)
    pairs = np.asarray(ends, dtype=np.int64).reshape(-1, 2)
    if pairs.size and (pairs.min() < 0 or pairs.max() >= len(reference)):
        raise ValueError(f"extensometer ends must be point indices in [0, {len(reference)})")
    length0 = np.linalg.norm(reference[pairs[:, 1]] - reference[pairs[:, 0]], axis=1)
    length = np.linalg.norm(current[pairs[:, 1]] - current[pairs[:, 0]], axis=1)
    return Extensometer3D(length0, length, (length - length0) / length0)
