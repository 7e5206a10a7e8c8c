"""Exact rendering of the 3D coupon (coupon3d) through one camera: every sample's ray intersected with the deformed
surface, the material point found there and the speckle painted at it. No image is warped or interpolated.

``material_seen`` is the kernel: for each ideal pixel position (the lens's distortion already undone), the ray
from the camera's centre is written in the coupon's local frame (before its rigid motion, ``ray_frame``), and
(lambda, Y0) solve ``origin + lambda d = (X0 a(Y0), y(Y0), z(Y0))`` on its y and z rows by Newton's method
(a plane's answer to start; the neck's z(Y0) bends it), then X0 = x / a(Y0). NaN where the ray misses the coupon.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from livedic.acquire.simulator.coupon3d import NECK_WIDTH_MM, NU_NECK, NU_UNIFORM, Coupon, CouponState

# Newton's method stops when its step is below this (mm), or after NEWTON_STEPS steps (then NaN).
NEWTON_TOLERANCE_MM = 1e-11
NEWTON_STEPS = 30


@njit(cache=True)
def _sech2(u):
    u = min(abs(u), 300.0)
    c = math.cosh(u)
    return 1.0 / (c * c)


@njit(cache=True, parallel=True)
def material_seen(ideal, fx, fy, cx, cy, origin, M, e, e_n, half_thickness, half_width, half_length, out):
    """out[r, c] = (X0, Y0) mm of the material seen at ideal pixel ideal[r, c] (NaN: none).

    ``origin`` (3,) the camera's centre and ``M`` (3, 3) camera rays -> the coupon's local frame (``ray_frame``);
    ``e``, ``e_n`` the uniform and neck strains, ``half_thickness`` t / 2 (mm).
    """
    H, W = out.shape[0], out.shape[1]
    s = NECK_WIDTH_MM
    w_uniform = half_thickness * NU_UNIFORM * e
    recess = half_thickness * NU_NECK * e_n         # the neck's extra depth at its centre
    widest = 1.0 - NU_UNIFORM * e                   # the largest lateral stretch (outside the neck)
    for r in prange(H):
        for c in range(W):
            rx = (ideal[r, c, 0] - cx) / fx
            ry = (ideal[r, c, 1] - cy) / fy
            dx = M[0, 0] * rx + M[0, 1] * ry + M[0, 2]
            dy = M[1, 0] * rx + M[1, 1] * ry + M[1, 2]
            dz = M[2, 0] * rx + M[2, 1] * ry + M[2, 2]
            out[r, c, 0] = np.nan
            out[r, c, 1] = np.nan
            if abs(dz) < 1e-12:
                continue
            lam = (w_uniform - origin[2]) / dz          # the plane z = t/2 nu e
            # The surface lies within `recess` behind that plane and |X0| >= |x| / (1 - nu e): a ray whose x there is
            # further out than the coupon's edge plus what the recess can shift it misses (half the image: background).
            if abs(origin[0] + lam * dx) - recess * abs(dx / dz) > half_width * widest:
                continue
            Y0 = (origin[1] + lam * dy) / (1.0 + e)
            converged = False
            for _ in range(NEWTON_STEPS):
                g = _sech2(Y0 / s)
                th = math.tanh(Y0 / s)
                dg = -2.0 / s * g * th
                f1 = origin[1] + lam * dy - (Y0 * (1.0 + e) + e_n * s * th)
                f2 = origin[2] + lam * dz - half_thickness * (NU_UNIFORM * e + NU_NECK * e_n * g)
                y1 = 1.0 + e + e_n * g                      # dy/dY0
                z1 = half_thickness * NU_NECK * e_n * dg    # dz/dY0
                # J = [[dy, -y1], [dz, -z1]] times (dlam, dY0) = -(f1, f2)
                det = -dy * z1 + y1 * dz
                if det == 0.0:
                    break
                dlam = (-f1 * -z1 + y1 * -f2) / det
                dY0 = (dy * -f2 - dz * -f1) / det
                lam += dlam
                Y0 += dY0
                if abs(dY0) < NEWTON_TOLERANCE_MM and abs(dlam) * (abs(dx) + abs(dy) + abs(dz)) < NEWTON_TOLERANCE_MM:
                    converged = True
                    break
            if not converged or lam <= 0.0 or abs(Y0) > half_length:
                continue
            a = 1.0 - NU_UNIFORM * e - NU_NECK * e_n * _sech2(Y0 / s)
            X0 = (origin[0] + lam * dx) / a
            if abs(X0) > half_width:
                continue
            out[r, c, 0] = X0
            out[r, c, 1] = Y0


def ray_frame(camera_rotation: np.ndarray, camera_translation: np.ndarray, placement_rotation: np.ndarray,
              placement_centre: np.ndarray, state: CouponState) -> tuple[np.ndarray, np.ndarray]:
    """(origin, M): a camera's centre and its rays (camera frame -> direction) in the coupon's local frame.

    The camera maps world X to ``camera_rotation @ X + camera_translation``; the coupon's frame is
    ``placement_rotation`` (columns: its axes in the world) at ``placement_centre``; ``state`` its rigid motion.
    """
    centre_world = -camera_rotation.T @ camera_translation
    to_local = state.rotation.T @ placement_rotation.T
    origin = to_local @ (centre_world - placement_centre) - state.rotation.T @ np.array([0.0, 0.0, state.w0_mm])
    return np.ascontiguousarray(origin), np.ascontiguousarray(to_local @ camera_rotation.T)


def material_grid(ideal: np.ndarray, camera_matrix: np.ndarray, origin: np.ndarray, M: np.ndarray,
                  coupon: Coupon, state: CouponState) -> np.ndarray:
    """(X0, Y0) mm seen at ideal pixel positions ``ideal`` (..., 2) (NaN off the coupon), via ``material_seen``."""
    shape = ideal.shape
    grid = np.ascontiguousarray(ideal.reshape(-1, 1, 2) if ideal.ndim != 3 else ideal, dtype=np.float64)
    out = np.empty(grid.shape)
    K = camera_matrix
    material_seen(grid, float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), origin, M, float(state.e),
                  float(state.e_n), 0.5 * coupon.thickness_mm, 0.5 * coupon.width_mm, 0.5 * coupon.length_mm, out)
    return out.reshape(shape)
