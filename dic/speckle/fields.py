"""Displacement fields the speckle kernels can invert exactly: ``translation``, ``affine``, ``sinusoid``
(``DisplacementField``: the field, its evaluation and its kernel parameters)."""

import math
import numbers

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.dic.speckle.kernels import _AFFINE, _SINUSOID, _TRANSLATION

Displacement = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``(X, Y) -> (U, V)`` on float64 arrays of reference coordinates (Lagrangian)."""


class DisplacementField:
    """A displacement field ``(X, Y) -> (U, V)`` that the kernels can invert exactly.

    Built by :func:`translation`, :func:`affine` and :func:`sinusoid`. Calling it
    evaluates the field in numpy on REFERENCE coordinates; :func:`render` inverts
    it in closed form (translation, affine) or through a per-column table solved
    by safeguarded Newton (sinusoid), skipping the general numpy iteration.

    Attributes
    ----------
    kind : str
        ``"translation"``, ``"affine"`` or ``"sinusoid"``.
    params : dict
        The arguments it was built with.
    """

    def __init__(self, kind: str, params: dict[str, Any], evaluate: Displacement,
                 kernel_params: Callable[[], tuple[int, np.ndarray]]) -> None:
        self.kind = kind
        self.params = dict(params)
        self._evaluate = evaluate
        self._kernel_params = kernel_params

    def __call__(self, X: npt.ArrayLike, Y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Displacement at reference points.

        Parameters
        ----------
        X, Y : ndarray of float64, shape (...)
            Reference coordinates (x = column, y = row), same shape.

        Returns
        -------
        U, V : ndarray of float64, shape (...)
            Displacement components, same shape as ``X``.
        """
        X = np.asarray(X, dtype=np.float64)
        Y = np.asarray(Y, dtype=np.float64)
        U, V = self._evaluate(X, Y)
        shape = np.broadcast_shapes(X.shape, Y.shape)
        return (np.broadcast_to(np.asarray(U, dtype=np.float64), shape).copy(),
                np.broadcast_to(np.asarray(V, dtype=np.float64), shape).copy())

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        return f"{self.kind}({args})"


def _finite(value: float, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite real number, got {value!r}")
    return float(value)


def translation(u: float, v: float) -> DisplacementField:
    """Rigid translation: content at (X, Y) moves to (X + u, Y + v).

    Parameters
    ----------
    u, v : float
        Displacement in px along x (columns) and y (rows).

    Returns
    -------
    DisplacementField
    """
    u = _finite(u, "translation u")
    v = _finite(v, "translation v")

    def evaluate(X, Y):
        return np.full(X.shape, u), np.full(Y.shape, v)

    def kernel_params():
        return _TRANSLATION, np.array([u, v])

    return DisplacementField("translation", {"u": u, "v": v}, evaluate, kernel_params)


def affine(u: float = 0.0, v: float = 0.0, ux: float = 0.0, uy: float = 0.0, vx: float = 0.0, vy: float = 0.0,
           centre: tuple[float, float] = (0.0, 0.0)) -> DisplacementField:
    """Homogeneous (first-order) deformation about ``centre``.

    ``U = u + ux (X - cx) + uy (Y - cy)`` and ``V = v + vx (X - cx) + vy (Y - cy)``,
    so ``ux`` is the engineering strain along x, ``vy`` along y, and
    ``uy, vx`` the shear gradients.

    Parameters
    ----------
    u, v, ux, uy, vx, vy : float
        Displacement (px) at the centre and its gradients (px/px).
    centre : tuple of float, (cx, cy)
        Point whose displacement is (u, v), in reference pixel coordinates.

    Returns
    -------
    DisplacementField
        :func:`render` raises ValueError if ``det(I + grad U) <= 0`` (the
        map folds the material and has no inverse).
    """
    u, v = _finite(u, "affine u"), _finite(v, "affine v")
    ux, uy = _finite(ux, "affine ux"), _finite(uy, "affine uy")
    vx, vy = _finite(vx, "affine vx"), _finite(vy, "affine vy")
    try:
        cx, cy = centre
    except (TypeError, ValueError):
        raise ValueError(f"affine centre must be a pair (cx, cy), got {centre!r}") from None
    cx, cy = _finite(cx, "affine centre x"), _finite(cy, "affine centre y")

    def evaluate(X, Y):
        dX, dY = X - cx, Y - cy
        return u + ux * dX + uy * dY, v + vx * dX + vy * dY

    def kernel_params():
        a, b, c, d = 1.0 + ux, uy, vx, 1.0 + vy
        det = a * d - b * c
        if not det > 0.0:
            raise ValueError(f"affine field has det(I + grad U) = {det:.3g} <= 0: it folds the material "
                             "and cannot be inverted; use gradients with (1+ux)(1+vy) - uy*vx > 0")
        return _AFFINE, np.array([cx, cy, u, v, d / det, -b / det, -c / det, a / det])

    params = {"u": u, "v": v, "ux": ux, "uy": uy, "vx": vx, "vy": vy, "centre": (cx, cy)}
    return DisplacementField("affine", params, evaluate, kernel_params)


def sinusoid(amplitude: float, period: float, *, axis: str = "x", direction: str = "v",
             phase: float = 0.0) -> DisplacementField:
    """One displacement component varying sinusoidally along one axis.

    ``direction = A sin(2 pi * axis / period + phase)``, the other component
    zero. The default (``axis="x", direction="v"``) is ``V = A sin(2 pi X / P)``:
    a wavy shear like the DIC Challenge 2.0 star, but with one period. With
    ``axis`` and ``direction`` along the same line (e.g. ``axis="x",
    direction="u"``) the field stretches and compresses; it is invertible only
    if ``2 pi |A| / P < 1``.

    Parameters
    ----------
    amplitude : float
        A, in px.
    period : float
        P, in px (> 0).
    axis : {"x", "y"}
        Reference coordinate the sine runs along.
    direction : {"u", "v"}
        Displacement component that varies.
    phase : float
        Phase in radians.

    Returns
    -------
    DisplacementField
    """
    A = _finite(amplitude, "sinusoid amplitude")
    P = _finite(period, "sinusoid period")
    phase = _finite(phase, "sinusoid phase")
    if P <= 0.0:
        raise ValueError(f"sinusoid period must be > 0 px, got {P}")
    if axis not in ("x", "y"):
        raise ValueError(f"sinusoid axis must be 'x' or 'y', got {axis!r}")
    if direction not in ("u", "v"):
        raise ValueError(f"sinusoid direction must be 'u' or 'v', got {direction!r}")
    k = 2.0 * math.pi / P

    def evaluate(X, Y):
        s = A * np.sin(k * (X if axis == "x" else Y) + phase)
        zero = np.zeros(np.broadcast_shapes(X.shape, Y.shape))
        return (s, zero) if direction == "u" else (zero, s)

    def kernel_params():
        along = (axis == "x") == (direction == "u")
        if along and abs(A) * k >= 1.0:
            raise ValueError(f"sinusoid with 2*pi*|A|/P = {abs(A) * k:.3g} >= 1 along its own axis folds the "
                             "material and cannot be inverted; lower the amplitude or lengthen the period")
        return _SINUSOID, np.array([A, k, phase, float(axis == "y"), float(direction == "v")])

    params = {"amplitude": A, "period": P, "axis": axis, "direction": direction, "phase": phase}
    return DisplacementField("sinusoid", params, evaluate, kernel_params)
