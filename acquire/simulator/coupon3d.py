"""The stereo simulator's specimen: a flat speckled coupon with an exactly known 3D motion (no pixels).

Material coordinates (X0, Y0) mm lie on the coupon's front surface in the reference, origin at its centre,
X0 across the coupon, Y0 along its axis (the pull). The coupon's frame has x = X0's direction, y = Y0's and
z = x cross y, pointing into the coupon (away from the cameras, as OpenCV's camera z). In frame i (schedule
tau = i / (frames - 1)) a material point moves to, in that frame::

    y = Y0 (1 + e) + e_n s tanh(Y0 / s)                      axial strain e + e_n sech^2(Y0 / s)
    x = X0 (1 - nu e - nu_p e_n g(Y0))                        lateral contraction, g = sech^2(Y0 / s)
    z = t / 2 (nu e + nu_p e_n g(Y0))                         the thickness loss: the front surface recedes

with e = strain tau (uniform) and e_n = neck tau^2 (the neck, centred at Y0 = 0), then turned about the coupon's
x and y axes through its centre (``rot_x``, ``rot_y`` degrees times tau) and moved by w0 tau along its z.
Truth: each point's position, its displacement and the Green-Lagrange strain of the surface in its tangent
plane, E = (F^T F - I) / 2 with F = d(position) / d(X0, Y0) (3 x 2), exact (docs/guide/sources.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from livedic.acquire.simulator.options import DEFAULT_THICKNESS_MM

# Poisson's ratios of the uniform (elastic-like) strain and of the neck's (plastic: volume kept).
NU_UNIFORM = 0.3
NU_NECK = 0.5
# The coupon: a 20 mm wide strip (ISO 6892-1 type 1's gauge width), longer than any view of it.
COUPON_WIDTH_MM = 20.0
COUPON_LENGTH_MM = 80.0
# s in sech^2(Y0 / s): the neck's half-width (mm).
NECK_WIDTH_MM = 5.0


@dataclass(frozen=True)
class CouponState:
    """The motion in one frame: uniform strain ``e``, the neck's peak extra strain ``e_n``, the rigid rotation
    (coupon frame, about its centre) and the translation ``w0_mm`` along the coupon's z."""

    e: float
    e_n: float
    rotation: np.ndarray
    w0_mm: float


@dataclass(frozen=True)
class CouponMotion:
    """A tensile test's schedule: every quantity reached at the last frame, growing with tau (the neck as tau^2).

    Parameters
    ----------
    frames : int
        Frames of the test (frame 0 is the undeformed reference).
    strain : float
        Uniform axial strain (engineering) at the last frame.
    neck : float
        Extra axial strain at the neck's centre (Y0 = 0) at the last frame.
    w0_mm : float
        Out-of-plane translation along the coupon's z (+: away from the cameras) at the last frame.
    rot_x_deg, rot_y_deg : float
        Rotation about the coupon's x (across) and y (axis) through its centre at the last frame.
    """

    frames: int
    strain: float = 0.01
    neck: float = 0.0
    w0_mm: float = 0.0
    rot_x_deg: float = 0.0
    rot_y_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.frames < 2:
            raise ValueError(f"a test needs frames >= 2, got {self.frames}")
        if not (-0.5 < self.strain < 1.0 and 0.0 <= self.neck < 1.0):
            raise ValueError(f"strain must be in (-0.5, 1) and neck in [0, 1), got {self.strain}, {self.neck}")

    def tau(self, i: int) -> float:
        """The schedule: 0 at frame 0, 1 at the last frame."""
        if not 0 <= i < self.frames:
            raise ValueError(f"frame index {i} outside 0..{self.frames - 1}")
        return i / (self.frames - 1)

    def state(self, i: int) -> CouponState:
        tau = self.tau(i)
        rx, ry = math.radians(self.rot_x_deg * tau), math.radians(self.rot_y_deg * tau)
        rotation = cv2.Rodrigues(np.array([rx, 0.0, 0.0]))[0] @ cv2.Rodrigues(np.array([0.0, ry, 0.0]))[0]
        return CouponState(self.strain * tau, self.neck * tau * tau, rotation, self.w0_mm * tau)


@dataclass(frozen=True)
class Coupon:
    """The coupon's geometry: ``width_mm`` x ``length_mm`` front surface, ``thickness_mm`` thick."""

    width_mm: float = COUPON_WIDTH_MM
    length_mm: float = COUPON_LENGTH_MM
    thickness_mm: float = DEFAULT_THICKNESS_MM

    def contains(self, X0: npt.ArrayLike, Y0: npt.ArrayLike) -> np.ndarray:
        """Whether material points (mm) lie on the coupon's front surface."""
        return (np.abs(X0) <= 0.5 * self.width_mm) & (np.abs(Y0) <= 0.5 * self.length_mm)

    def surface(self, state: CouponState, X0: npt.ArrayLike, Y0: npt.ArrayLike) -> np.ndarray:
        """Positions (..., 3) in the reference coupon frame (mm) of material points (X0, Y0) in ``state``."""
        X0, Y0 = np.broadcast_arrays(np.asarray(X0, dtype=np.float64), np.asarray(Y0, dtype=np.float64))
        s = NECK_WIDTH_MM
        g = 1.0 / np.cosh(Y0 / s) ** 2
        local = np.stack([X0 * (1.0 - NU_UNIFORM * state.e - NU_NECK * state.e_n * g),
                          Y0 * (1.0 + state.e) + state.e_n * s * np.tanh(Y0 / s),
                          0.5 * self.thickness_mm * (NU_UNIFORM * state.e + NU_NECK * state.e_n * g)], axis=-1)
        return local @ state.rotation.T + np.array([0.0, 0.0, state.w0_mm])

    def strain(self, state: CouponState, X0: npt.ArrayLike, Y0: npt.ArrayLike) -> np.ndarray:
        """Green-Lagrange strain of the surface (..., 3): Exx, Eyy, Exy along the material axes X0, Y0.

        Rigid motion leaves it unchanged; the recess of the front surface in the neck adds (dz/dY0)^2 / 2 to Eyy.
        """
        X0, Y0 = np.broadcast_arrays(np.asarray(X0, dtype=np.float64), np.asarray(Y0, dtype=np.float64))
        s = NECK_WIDTH_MM
        g = 1.0 / np.cosh(Y0 / s) ** 2
        dg = -2.0 / s * g * np.tanh(Y0 / s)
        a = 1.0 - NU_UNIFORM * state.e - NU_NECK * state.e_n * g      # dx/dX0
        dx_dY0 = -X0 * NU_NECK * state.e_n * dg
        dy_dY0 = 1.0 + state.e + state.e_n * g
        dz_dY0 = 0.5 * self.thickness_mm * NU_NECK * state.e_n * dg
        exx = 0.5 * (a * a - 1.0)
        eyy = 0.5 * (dx_dY0 ** 2 + dy_dY0 ** 2 + dz_dY0 ** 2 - 1.0)
        exy = 0.5 * a * dx_dY0
        return np.stack([exx, eyy, exy], axis=-1)


@dataclass(frozen=True)
class CouponTruth:
    """Exact truth of material points in one frame (arrays over the points; left camera frame: the world).

    position_mm : (N, 3)       where each point is, left camera frame (mm)
    displacement_mm : (N, 3)   its motion since the reference, left camera frame (mm)
    displacement_specimen_mm : (N, 3)
        the same motion in the reference coupon frame: U across, V along the axis, W along its normal
        (+: away from the cameras)
    strain : (N, 3)            Green-Lagrange Exx, Eyy, Exy in the surface's tangent plane (material axes)
    """

    frame: int
    material_mm: np.ndarray
    position_mm: np.ndarray
    displacement_mm: np.ndarray
    displacement_specimen_mm: np.ndarray
    strain: np.ndarray
