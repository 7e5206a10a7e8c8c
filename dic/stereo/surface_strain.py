"""Strain on the specimen's surface, in its tangent plane, from the 3D points of the reference and a frame.

Per point, over its window of grid neighbours (``dic.strain.strain_window`` on the left reference positions,
the 2D convention: ``window`` points a side):

1. the reference tangent plane: least-squares plane (SVD) through the window's reference 3D points, and the
   frame ``e1, e2, e3`` of ``dic.stereo.frame.tangent_basis`` (e3 its normal away from the camera, e1 the
   left camera's x projected on it, e2 = e3 x e1: for a specimen facing the camera, x and y are the image's);
2. each neighbour's reference in-plane coordinates ``(a, b) = ((X - X_i) . e1, (X - X_i) . e2)`` (mm);
3. per frame, the 3D displacements ``d = x - X`` fitted by planes in (a, b) over the window's valid points
   (``dic.strain.displacement_gradients``: the same least squares, valid-point rules and ``StrainStatus``
   as the 2D strain), giving the surface deformation gradient ``F = [e1 e2] + grad d`` (3 x 2);
4. F expressed in the current tangent plane: its normal ``n = F_a x F_b`` and the frame ``e1, e2`` turned by
   the smallest rotation taking e3 to n, so ``F2 = [e1' e2']^T F`` (2 x 2) with ``F2^T F2 = F^T F``; then the
   chosen measure (``dic.strain.strain_tensor``).

A rigid motion of the surface in space (translation towards the cameras, tilt) gives ``F^T F = I``: zero
Green-Lagrange and true strain, whatever W and the tilt. The default measure is Green-Lagrange
(``SURFACE_MEASURE``): specimens rotate in 3D, and the engineering measure reads a rotation theta as
cos(theta) - 1 (1 degree: -1.5e-4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from livedic.dic.correlation import DEFAULT_SUBSET
from livedic.dic.stereo.frame import tangent_basis
from livedic.dic.strain import (DEFAULT_WINDOW, MEASURES, StrainField, StrainWindow, displacement_gradients,
                                principal_strains, strain_tensor, strain_window)
from livedic.dic.strain.field import StrainStatus

SURFACE_MEASURE = "green"


@dataclass(frozen=True)
class SurfaceWindow:
    """Each point's neighbourhood with its reference tangent frame, found once on the reference points.

    Attributes
    ----------
    window : StrainWindow
        The neighbourhoods; ``dx, dy`` are the neighbours' reference in-plane coordinates (mm) and ``step``
        the grid step in mm.
    basis : ndarray, shape (N, 3, 3)
        Rows e1, e2, e3 of each point's reference tangent frame (NaN where its plane could not be fitted).
    step_px, vsg_px : float
        The grid step and the virtual strain gauge in the left image (px).
    """

    window: StrainWindow
    basis: np.ndarray
    step_px: float
    vsg_px: float

    @property
    def vsg_mm(self) -> float:
        """Virtual strain gauge on the specimen (mm): the image one at the grid's typical mm per px."""
        return self.vsg_px * self.window.step / self.step_px


def surface_window(points_px: npt.ArrayLike, reference_xyz: npt.ArrayLike, *, window: int = DEFAULT_WINDOW,
                   step: float | None = None, subset: int = DEFAULT_SUBSET) -> SurfaceWindow:
    """The neighbourhoods and reference tangent frames for surface strain.

    Parameters
    ----------
    points_px : array_like, shape (N, 2)
        The left reference positions (the grid), px.
    reference_xyz : array_like, shape (N, 3)
        Their reference 3D points (mm), NaN where not measured (``StereoMatch.xyz``).
    window, step, subset
        As ``dic.strain.strain_window`` (window points a side, grid step px, subset side px).

    Returns
    -------
    SurfaceWindow
    """
    grid = strain_window(points_px, window=window, step=step, subset=subset)
    xyz = np.asarray(reference_xyz, dtype=np.float64).reshape(-1, 3)
    if len(xyz) != grid.n_points:
        raise ValueError(f"got {grid.n_points} points but {len(xyz)} reference 3D points")
    finite = np.all(np.isfinite(xyz), axis=1)
    n = grid.n_points
    basis = np.full((n, 3, 3), np.nan)
    a = np.full(len(grid.index), np.nan)
    b = np.full(len(grid.index), np.nan)
    for i in range(n):
        members = grid.index[grid.start[i]:grid.start[i + 1]]
        used = members[finite[members]]
        if not finite[i] or len(used) < 3:
            continue
        centred = xyz[used] - xyz[used].mean(axis=0)
        _, singular, vt = np.linalg.svd(centred, full_matrices=False)
        if singular[1] <= 1e-9 * singular[0]:
            continue
        frame = tangent_basis(vt[2], xyz[i])
        basis[i] = frame
        offsets = (xyz[members] - xyz[i]) @ frame[:2].T
        a[grid.start[i]:grid.start[i + 1]] = offsets[:, 0]
        b[grid.start[i]:grid.start[i + 1]] = offsets[:, 1]
    # the grid step in mm: image step times the median mm per px between neighbours
    pixel_distance = np.hypot(grid.dx, grid.dy)
    centre = np.repeat(np.arange(n), np.diff(grid.start))
    space_distance = np.linalg.norm(xyz[grid.index] - xyz[centre], axis=1)
    ratio = space_distance / np.where(pixel_distance > 0, pixel_distance, np.nan)
    mm_per_px = float(np.nanmedian(ratio)) if np.any(np.isfinite(ratio)) else np.nan
    # a member without a finite offset (its centre's plane not fitted) sits far away: its fit never counts it
    in_plane = StrainWindow(start=grid.start, index=grid.index, dx=np.nan_to_num(a, nan=0.0),
                            dy=np.nan_to_num(b, nan=0.0), window=grid.window, step=grid.step * mm_per_px,
                            subset=grid.subset)
    return SurfaceWindow(window=in_plane, basis=basis, step_px=grid.step, vsg_px=grid.vsg_px)


def surface_strain(surface: SurfaceWindow, reference_xyz: npt.ArrayLike, current_xyz: npt.ArrayLike,
                   ok: npt.ArrayLike, *, measure: str = SURFACE_MEASURE) -> StrainField:
    """Strain in each point's tangent plane from the reference to the current 3D points (module notes).

    Parameters
    ----------
    surface : SurfaceWindow
        From ``surface_window`` on the reference points.
    reference_xyz, current_xyz : array_like, shape (N, 3)
        The points in the reference and in this frame (mm); NaN where not measured.
    ok : array_like of bool, shape (N,)
        Which current points are valid (``StereoPoints.ok``).
    measure : str
        One of ``dic.strain.MEASURES``.

    Returns
    -------
    StrainField
        exx, eyy, exy in each point's tangent frame (e1 ~ the image's x, e2 ~ its y), principal strains,
        ux, uy, vx, vy = F2 - I, ``StrainStatus`` codes; ``vsg_px`` the image one (``surface.vsg_mm`` in mm).
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown strain measure {measure!r}: choose one of {', '.join(MEASURES)}")
    reference = np.asarray(reference_xyz, dtype=np.float64).reshape(-1, 3)
    current = np.asarray(current_xyz, dtype=np.float64).reshape(-1, 3)
    n = surface.window.n_points
    if reference.shape != (n, 3) or current.shape != (n, 3):
        raise ValueError(f"the surface window holds {n} points; got {len(reference)} reference and "
                         f"{len(current)} current 3D points")
    d = current - reference
    valid = np.asarray(ok, dtype=bool).reshape(-1) & np.all(np.isfinite(d), axis=1)
    dxa, dxb, dya, dyb, status = displacement_gradients(surface.window, d[:, 0], d[:, 1], valid)
    dza, dzb, _, _, _ = displacement_gradients(surface.window, d[:, 2], d[:, 2], valid)
    no_plane = ~np.all(np.isfinite(surface.basis), axis=(1, 2))
    status[no_plane & (status == StrainStatus.OK)] = StrainStatus.TOO_FEW_POINTS
    e1, e2, e3 = surface.basis[:, 0], surface.basis[:, 1], surface.basis[:, 2]
    F = np.stack([e1, e2], axis=2) + np.stack([np.column_stack([dxa, dya, dza]), np.column_stack([dxb, dyb, dzb])],
                                              axis=2)
    F2 = _in_current_plane(F, e1, e2, e3)
    good = status == StrainStatus.OK
    ux, uy, vx, vy = (np.where(good, value, np.nan) for value in
                      (F2[:, 0, 0] - 1.0, F2[:, 0, 1], F2[:, 1, 0], F2[:, 1, 1] - 1.0))
    exx, eyy, exy = strain_tensor(ux, uy, vx, vy, measure)
    p1, p2, angle = principal_strains(exx, eyy, exy)
    return StrainField(exx=exx, eyy=eyy, exy=exy, e1=p1, e2=p2, angle=angle, ux=ux, uy=uy, vx=vx, vy=vy,
                       status=status, measure=measure, vsg_px=surface.vsg_px)


def _in_current_plane(F: np.ndarray, e1: np.ndarray, e2: np.ndarray, e3: np.ndarray) -> np.ndarray:
    """F (N, 3, 2) in the current tangent frame: e1, e2 turned by the smallest rotation taking e3 to F's normal."""
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.cross(F[:, :, 0], F[:, :, 1])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        # Rodrigues' rotation of v about axis k = e3 x n by the angle between them: v c + (k x v) + k (k.v)(1 - c)/s^2
        axis = np.cross(e3, normal)
        cosine = np.sum(e3 * normal, axis=1, keepdims=True)
        scale = 1.0 / (1.0 + cosine)

        def turned(v: np.ndarray) -> np.ndarray:
            return v * cosine + np.cross(axis, v) + axis * np.sum(axis * v, axis=1, keepdims=True) * scale

        t1, t2 = turned(e1), turned(e2)
    return np.stack([np.einsum("ni,nij->nj", t1, F), np.einsum("ni,nij->nj", t2, F)], axis=1)
