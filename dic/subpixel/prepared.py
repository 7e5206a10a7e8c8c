"""What every prepared IC-GN order checks and sets up before its kernel runs, and does to its result after.

``dic.subpixel.icgn.refine_prepared`` (orders 0-1) and ``dic.subpixel.icgn2.refine_prepared`` (orders 0-2)
share their contract: which prepared points to refine, per-point shape-function orders, iteration caps and
tolerances, start values (NaN start = ``BAD_GUESS``), the caller's status merged with the reference's. The
checks raise ValueError with one line naming the bad argument.
"""

from typing import Protocol

import numpy as np
import numpy.typing as npt

from livedic.dic.bspline import BSplineCoefficients
from livedic.dic.status import Status

PerPoint = npt.ArrayLike | None
"""One value for every point, one per point (N,), or None for the default."""


class PreparedPoints(Protocol):
    """What the checks read of prepared reference data (``dic.subpixel.icgn.IcgnReference``)."""
    xs: np.ndarray
    shape: tuple


_ORDER_WORDS = ("0 (shift)", "1 (affine)", "2 (quadratic)")


def checked_points(ref_prep: PreparedPoints, target_coeffs: BSplineCoefficients,
                   points: npt.ArrayLike | None, *, degrees: tuple[int, ...] = (3, 5)) -> np.ndarray:
    """The indices of the prepared points to refine (int64), after checking the target's coefficients.

    ``ref_prep`` is an ``IcgnReference`` (the first-order data of any IC-GN order); ValueError (one
    line) for coefficients not from ``prepare_target``, of another size, of a B-spline degree the
    method cannot sample (not in ``degrees``), or bad indices.
    """
    if not isinstance(target_coeffs, BSplineCoefficients):
        raise ValueError("target_coeffs must come from prepare_target (a BSplineCoefficients)")
    if tuple(target_coeffs.shape) != tuple(ref_prep.shape):
        raise ValueError(f"target is {target_coeffs.shape[1]}x{target_coeffs.shape[0]} but the reference is "
                         f"{ref_prep.shape[1]}x{ref_prep.shape[0]}: both images must have the same size")
    if target_coeffs.coefficients.dtype != np.float32:
        raise ValueError("IC-GN samples float32 coefficients: use prepare_target (or prefilter(..., np.float32))")
    if target_coeffs.degree not in degrees:
        raise ValueError(f"this method samples the cubic B-spline only, the target's is of degree "
                         f"{target_coeffs.degree}: use --interpolation bspline3, or --subpixel icgn")
    n_prepared = ref_prep.xs.shape[0]
    points = np.arange(n_prepared) if points is None else np.asarray(points)
    if points.ndim != 1 or not (points.size == 0 or np.issubdtype(points.dtype, np.integer)) or \
            (points.size and (points.min() < 0 or points.max() >= n_prepared)):
        raise ValueError(f"points must be a 1-D array of indices of the {n_prepared} prepared points")
    return np.ascontiguousarray(points, dtype=np.int64)


def point_orders(order: npt.ArrayLike, n_points: int, max_order: int) -> tuple[np.ndarray, bool]:
    """``order`` (one for all, or one per point) as an int64 array of ``n_points``, and whether it was per point.

    ValueError unless every order is an integer from 0 to ``max_order`` (a bool is not an order).
    """
    per_point = np.ndim(order) > 0
    if per_point:
        orders = np.asarray(order).astype(np.int64)
        valid = orders.shape == (n_points,) and bool(np.all((orders >= 0) & (orders <= max_order)))
    else:
        valid = order in range(max_order + 1) and not isinstance(order, bool)
        orders = np.full(n_points, order if valid else 0, dtype=np.int64)
    if not valid:
        words = _ORDER_WORDS[:max_order + 1]
        raise ValueError(f"order must be {', '.join(words[:-1])} or {words[-1]}, or one of them per point, "
                         f"got {order!r}")
    return orders, per_point


def check_iterations(max_iterations: int, tolerance: float, translation_iterations: int,
                     translation_tolerance: float) -> None:
    """ValueError for an iteration cap below 1, a negative translation pre-stage cap or a tolerance <= 0."""
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    if int(translation_iterations) < 0:
        raise ValueError(f"translation_iterations must be >= 0, got {translation_iterations}")
    if not (tolerance > 0 and translation_tolerance > 0):
        raise ValueError(f"tolerances must be > 0, got {tolerance} and {translation_tolerance}")


def start_values(values: npt.ArrayLike | None, n_points: int, name: str, default: float) -> np.ndarray:
    """A start array of ``n_points`` float64 from ``values`` (None: ``default``; a scalar: broadcast)."""
    if values is None:
        return np.full(n_points, default, dtype=np.float64)
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim == 0:
        return np.full(n_points, float(arr))
    if arr.shape != (n_points,):
        raise ValueError(f"{name} must have shape ({n_points},) (one value per point), got {arr.shape}")
    return arr


def start_status(prepared_status: np.ndarray, status: npt.ArrayLike | None, n_points: int) -> np.ndarray:
    """The status to refine from (int8): the prepared points' own, overridden where the caller's is not OK."""
    if status is not None:
        status = np.asarray(status)
        if status.shape != (n_points,):
            raise ValueError(f"status must have shape ({n_points},), got {status.shape}")
        prepared_status = np.where(status != Status.OK, status, prepared_status)
    return np.ascontiguousarray(prepared_status, dtype=np.int8)
