"""Quality gates: a point is ``ok`` only when its displacement can be trusted.

Each gate turns a point that cannot be trusted into NaN with its own ``dic.Status`` code;
what passes every gate is ``ok``.

1. **Correlation** (``LOW_CORRELATION``): ZNCC below ``min_zncc`` (default ``MIN_ZNCC``).
2. **Texture** (``POOR_TEXTURE``), from the reference subset alone (``texture``): the squared
   gradient per pixel along the subset's weakest direction below ``TEXTURE_FRACTION`` of the
   image's well-textured points (their 75th percentile), or the structure tensor's condition
   number above ``APERTURE_MAX`` (texture in one direction only). A first-order fit whose
   variance inflation of u or v, ``[H^-1]_uu / [H_uv^-1]_uu``, exceeds ``VIF_MAX`` falls back
   to a translation-only fit for that point (its gradients NaN).
3. **Neighbours** (``OUTLIER``): the normalised median test of Westerweel & Scarano (2005) on
   u and v over each point's neighbours (``dic.neighbours``): ``|x - median| / (median |x_j -
   median_j| + eps)`` above ``OUTLIER_THRESHOLD`` with ``eps`` = ``OUTLIER_EPSILON``. Needs at
   least ``MIN_NEIGHBOURS`` ok neighbours; an isolated point is not tested.
4. **Border**: a subset whose warped image, with the interpolation's support, does not lie
   inside the deformed image is ``OUTSIDE_TARGET`` (``dic.bspline.INTERPOLATION_MARGIN``).

How each threshold was chosen and measured (``livedic bench validate`` reruns it), and the
reference: docs/guide/quality.md ("How each gate was set").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from livedic.dic.status import LOW_CORRELATION, OK, OUTLIER, POOR_TEXTURE

if TYPE_CHECKING:
    from livedic.dic.neighbours import NeighbourGraph
    from livedic.dic.subpixel.icgn import IcgnReference

MIN_ZNCC = 0.5
TEXTURE_FRACTION = 0.05
APERTURE_MAX = 50.0
VIF_MAX = 10.0
OUTLIER_THRESHOLD = 2.0
OUTLIER_EPSILON = 0.1
MIN_NEIGHBOURS = 3
# "well-textured points of the same image": this percentile of the texture of the measured points.
_TYPICAL_PERCENTILE = 75


Gradients = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""The displacement gradients (ux, uy, vx, vy), float64 (N,) each."""


@dataclass(frozen=True)
class Gates:
    """Thresholds of the quality gates; the defaults are the measured ones (docs/guide/quality.md)."""
    min_zncc: float = MIN_ZNCC
    texture_fraction: float = TEXTURE_FRACTION
    aperture_max: float = APERTURE_MAX
    vif_max: float = VIF_MAX
    outlier_threshold: float = OUTLIER_THRESHOLD
    outlier_epsilon: float = OUTLIER_EPSILON

    def __post_init__(self):
        if not -1.0 <= self.min_zncc <= 1.0:
            raise ValueError(f"min_zncc must be between -1 and 1, got {self.min_zncc}")
        if not 0.0 <= self.texture_fraction < 1.0:
            raise ValueError(f"texture_fraction must be in [0, 1), got {self.texture_fraction}")
        for name in ("aperture_max", "vif_max", "outlier_threshold"):
            if not getattr(self, name) >= 1.0:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.outlier_epsilon > 0.0:
            raise ValueError(f"outlier_epsilon must be > 0 px, got {self.outlier_epsilon}")


@dataclass
class Texture:
    """Texture of each reference subset (``texture``).

    energy : float64 (N,)     mean squared gradient |grad f|^2 per pixel (grey levels^2 / px^2)
    weakest : float64 (N,)    the same along the subset's weakest direction (smaller eigenvalue of the
                              structure tensor, per pixel): what pins the displacement along that direction
    aperture : float64 (N,)   condition number of the 2x2 structure tensor (1: isotropic; inf: one direction)
    vif : float64 (N,)        variance inflation of u, v by the 4 gradient parameters of a 1st-order warp
    """
    energy: np.ndarray
    weakest: np.ndarray
    aperture: np.ndarray
    vif: np.ndarray

    def poor(self, gates: Gates = Gates()) -> np.ndarray:
        """True where the subset is too poorly textured to measure (``POOR_TEXTURE``)."""
        finite = np.isfinite(self.weakest)
        typical = np.percentile(self.weakest[finite], _TYPICAL_PERCENTILE) if finite.any() else 0.0
        weak = self.weakest < gates.texture_fraction * typical
        return finite & (weak | ~(self.aperture <= gates.aperture_max))

    def translation_only(self, gates: Gates = Gates()) -> np.ndarray:
        """True where a first-order warp is ill-determined and translation-only should be fitted."""
        return np.isfinite(self.energy) & ~(self.vif <= gates.vif_max)


def texture(prep: IcgnReference) -> Texture:
    """Texture measures of the reference subsets (see ``Texture``), from IC-GN's reference data.

    The step matrix ``H`` of IC-GN (``dic.subpixel.icgn.prepare_reference``) is
    the curvature of the ZNSSD at the match: its (u, v) block ``H_uv`` is the
    subset's gradient structure tensor (less the parts the ZNCC normalisation
    absorbs), and ``[H^-1]_uu / [H_uv^-1]_uu`` is how much fitting the four
    gradient parameters inflates the variance of u.

    Parameters
    ----------
    prep : dic.subpixel.icgn.IcgnReference

    Returns
    -------
    Texture
        NaN where the reference subset is unusable (``prep.status`` not OK).
    """
    n = prep.xs.shape[0]
    side = 2 * prep.half + 1
    ok = prep.status == OK
    a = prep.hinv0[:, 0, 0]
    b = prep.hinv0[:, 0, 1]
    d = prep.hinv0[:, 1, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        det = a * d - b * b
        h00, h11, h01 = d / det, a / det, -b / det          # H_uv = inverse of hinv0
        trace = h00 + h11
        disc = np.sqrt(np.maximum(0.25 * trace * trace - (h00 * h11 - h01 * h01), 0.0))
        lmin = 0.5 * trace - disc
        aperture = np.where(lmin > 1e-12 * trace, (0.5 * trace + disc) / lmin, np.inf)
        vif = np.maximum(prep.hinv[:, 0, 0] / a, prep.hinv[:, 3, 3] / d)
        energy = trace / (side * side)
        weakest = lmin / (side * side)
    nan = np.full(n, np.nan)
    return Texture(*(np.where(ok, value, nan) for value in (energy, weakest, aperture, vif)))


@njit(cache=True)
def _median(values, count):
    """Median of values[:count], sorted in place by insertion (count is a handful of neighbours)."""
    for i in range(1, count):
        x = values[i]
        j = i - 1
        while j >= 0 and values[j] > x:
            values[j + 1] = values[j]
            j -= 1
        values[j + 1] = x
    if count % 2 == 1:
        return values[count // 2]
    return 0.5 * (values[count // 2 - 1] + values[count // 2])


@njit(cache=True)
def _plane_gradient(x, y, f, ok, i, start, index, weights, out):
    """Gradient (df/dx, df/dy) at point i of a plane fitted to i and its ok neighbours, robustly.

    Huber-weighted least squares (3 reweighting passes, scale from the median
    absolute residual, floored at 0.01 px), so one wrong neighbour barely tilts
    the plane. Returns False where fewer than 3 points or a degenerate layout.
    """
    for it in range(4):
        sw = sx = sy = sxx = sxy = syy = sf = sxf = syf = 0.0
        count = 0
        for m in range(start[i], start[i + 1] + 1):     # the neighbours, then i itself
            j = i if m == start[i + 1] else index[m]
            if not ok[j]:
                continue
            w = weights[count] if it > 0 else 1.0
            dx = x[j] - x[i]
            dy = y[j] - y[i]
            sw += w
            sx += w * dx
            sy += w * dy
            sxx += w * dx * dx
            sxy += w * dx * dy
            syy += w * dy * dy
            sf += w * f[j]
            sxf += w * dx * f[j]
            syf += w * dy * f[j]
            count += 1
        if count < 3:
            return False
        # normal equations of f = a + b dx + c dy
        a11, a12, a13 = sw, sx, sy
        a22, a23, a33 = sxx, sxy, syy
        det = (a11 * (a22 * a33 - a23 * a23) - a12 * (a12 * a33 - a23 * a13) + a13 * (a12 * a23 - a22 * a13))
        if not abs(det) > 1e-9 * max(a22 * a33, 1e-300) * max(a11, 1.0):
            return False
        c0 = (sf * (a22 * a33 - a23 * a23) - a12 * (sxf * a33 - a23 * syf) + a13 * (sxf * a23 - a22 * syf)) / det
        c1 = (a11 * (sxf * a33 - a23 * syf) - sf * (a12 * a33 - a23 * a13) + a13 * (a12 * syf - sxf * a13)) / det
        c2 = (a11 * (a22 * syf - sxf * a23) - a12 * (a12 * syf - sxf * a13) + sf * (a12 * a23 - a22 * a13)) / det
        out[0] = c1
        out[1] = c2
        if it == 3:
            break
        # residuals -> Huber weights for the next pass
        count = 0
        for m in range(start[i], start[i + 1] + 1):
            j = i if m == start[i + 1] else index[m]
            if not ok[j]:
                continue
            r = f[j] - (c0 + c1 * (x[j] - x[i]) + c2 * (y[j] - y[i]))
            weights[count] = abs(r)
            count += 1
        for m in range(count):
            out[2 + m] = weights[m]
        scale = max(1.4826 * _median(out[2:2 + count], count), 0.01)
        for m in range(count):
            weights[m] = 1.0 if weights[m] <= 1.345 * scale else 1.345 * scale / weights[m]
    return True


@njit(cache=True, inline="always")
def _order(values, a, b):
    """values[a], values[b] in ascending order (a comparator of a sorting network)."""
    x = values[a]
    y = values[b]
    swap = y < x
    values[a] = y if swap else x            # selects, not a branch: data-dependent branches mispredict
    values[b] = x if swap else y


@njit(cache=True)
def _median_of_eight(values):
    """``_median`` of values[:8] by a 19-comparator sorting network (Knuth, TAOCP 5.3.4): no data-dependent
    loop, where the insertion sort's branches are mispredicted (8 neighbours: every point inside a grid).
    The middle pair may differ from the insertion sort's only by which of equal values (0 and -0) sits where.
    Called, not inlined at numba's level: inlined into the median test's two residuals, its compilation took
    ~27 s (LLVM still inlines the compiled function where it pays)."""
    _order(values, 0, 2)
    _order(values, 1, 3)
    _order(values, 4, 6)
    _order(values, 5, 7)
    _order(values, 0, 4)
    _order(values, 1, 5)
    _order(values, 2, 6)
    _order(values, 3, 7)
    _order(values, 0, 1)
    _order(values, 2, 3)
    _order(values, 4, 5)
    _order(values, 6, 7)
    _order(values, 2, 4)
    _order(values, 3, 5)
    _order(values, 1, 4)
    _order(values, 3, 6)
    _order(values, 1, 2)
    _order(values, 3, 4)
    _order(values, 5, 6)
    return 0.5 * (values[3] + values[4])


@njit(cache=True, inline="always")
def _normalised_residual(x, y, field, gx, gy, ok, i, start, index, epsilon, values):
    """Westerweel-Scarano residual of point i on one component; NaN if fewer than MIN_NEIGHBOURS ok.

    Each ok neighbour j predicts the point's value with its own gradient,
    ``f_j + gx_j (x_i - x_j) + gy_j (y_i - y_j)``; the residual is the
    distance to the median prediction over the spread of the predictions.
    With zero gradients this is the original test; with them a linear field
    (a strained specimen) gives no residual, at its edges too.
    """
    count = 0
    for m in range(start[i], start[i + 1]):
        j = index[m]
        if ok[j]:
            values[count] = field[j] + gx[j] * (x[i] - x[j]) + gy[j] * (y[i] - y[j])
            count += 1
    if count < MIN_NEIGHBOURS:
        return np.nan
    # Eight (every point inside a grid): the sorting network, unless a value is NaN (its place in a sort is the
    # algorithm's). The median's sign of zero cannot matter: only |value - median| is used.
    eight = count == 8
    if eight:
        total = 0.0
        for m in range(8):
            total += values[m]
        eight = total == total
    med = _median_of_eight(values) if eight else _median(values, count)
    for m in range(count):
        values[m] = abs(values[m] - med)
    spread = _median_of_eight(values) if eight else _median(values, count)
    return abs(field[i] - med) / (spread + epsilon)


_CHUNK = 256


@njit(cache=True, parallel=True, nogil=True)
def _local_gradients(x, y, u, v, ok, start, index, out):
    """Robust plane gradients (du/dx, du/dy, dv/dx, dv/dy) into out (N, 4) for the ok points whose
    row of ``out`` holds a NaN (rows without NaN are given gradients, kept); NaN where unknown."""
    n = u.shape[0]
    kmax = 1
    for i in range(n):
        kmax = max(kmax, start[i + 1] - start[i])
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        weights = np.empty(kmax + 1)
        scratch = np.empty(kmax + 3)
        for i in range(c * _CHUNK, min((c + 1) * _CHUNK, n)):
            if not ok[i]:
                continue
            if np.isfinite(out[i, 0]) and np.isfinite(out[i, 1]) and np.isfinite(out[i, 2]) and \
                    np.isfinite(out[i, 3]):
                continue
            for q in range(4):
                out[i, q] = np.nan
            if _plane_gradient(x, y, u, ok, i, start, index, weights, scratch):
                out[i, 0] = scratch[0]
                out[i, 1] = scratch[1]
            if _plane_gradient(x, y, v, ok, i, start, index, weights, scratch):
                out[i, 2] = scratch[0]
                out[i, 3] = scratch[1]


_LARGEST = float(np.finfo(np.float64).max)


@njit(cache=True)
def _nan_to_num(a):
    """``np.nan_to_num(a)`` in place on a C-contiguous array (NaN -> 0, +-inf -> +-the largest float)."""
    flat = a.reshape(-1)
    for i in range(flat.shape[0]):
        value = flat[i]
        if value != value:
            flat[i] = 0.0
        elif value == np.inf:
            flat[i] = _LARGEST
        elif value == -np.inf:
            flat[i] = -_LARGEST


@njit(cache=True, parallel=True, nogil=True)
def _median_test(x, y, u, v, grads, ok, start, index, epsilon, threshold, outlier, residual):
    n = u.shape[0]
    kmax = 1
    for i in range(n):
        kmax = max(kmax, start[i + 1] - start[i])
    for c in prange((n + _CHUNK - 1) // _CHUNK):
        values = np.empty(kmax)
        for i in range(c * _CHUNK, min((c + 1) * _CHUNK, n)):
            outlier[i] = False
            residual[i] = np.nan
            if not ok[i]:
                continue
            ru = _normalised_residual(x, y, u, grads[:, 0], grads[:, 1], ok, i, start, index, epsilon, values)
            if np.isnan(ru):
                continue
            rv = _normalised_residual(x, y, v, grads[:, 2], grads[:, 3], ok, i, start, index, epsilon, values)
            r = max(ru, rv)
            residual[i] = r
            outlier[i] = r > threshold


def median_test(x: np.ndarray, y: np.ndarray, u: np.ndarray, v: np.ndarray, ok: np.ndarray, graph: NeighbourGraph, *,
                gradients: Gradients | None = None, epsilon: float = OUTLIER_EPSILON,
                threshold: float = OUTLIER_THRESHOLD) -> tuple[np.ndarray, np.ndarray]:
    """Normalised median test (Westerweel & Scarano 2005) on the displacement of each ok point.

    Parameters
    ----------
    x, y : ndarray of float64, shape (N,)
        Point positions.
    u, v : ndarray of float64, shape (N,)
        Displacements.
    ok : ndarray of bool, shape (N,)
        Points that count (as neighbours and as candidates).
    graph : (start, index)
        Neighbours, from ``dic.neighbours.neighbour_graph``.
    gradients : tuple of 4 ndarrays (ux, uy, vx, vy), optional
        Displacement gradients per point (first-order methods). Where missing
        or NaN they are estimated from each point's neighbourhood by a robust
        (Huber) plane fit. Neighbours predict the point through them, so a
        strained field's edge points are not outliers (``_normalised_residual``).
    epsilon : float
        Noise level added to the neighbours' spread, px.
    threshold : float
        Normalised residual above which a point is an outlier.

    Returns
    -------
    outlier : ndarray of bool, shape (N,)
        Ok points whose u or v deviates from what their ok neighbours predict.
    residual : ndarray of float64, shape (N,)
        The larger normalised residual of u and v (NaN: not tested).
    """
    start, index = graph
    n = u.shape[0]
    outlier = np.zeros(n, dtype=np.bool_)
    residual = np.full(n, np.nan)
    if not n:
        return outlier, residual
    as64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    x, y, u, v = as64(x), as64(y), as64(u), as64(v)
    ok = np.ascontiguousarray(ok, dtype=np.bool_)
    if gradients is None:
        grads = np.full((n, 4), np.nan)
    else:
        grads = np.column_stack([as64(g) if g is not None else np.full(n, np.nan) for g in gradients])
    _local_gradients(x, y, u, v, ok, start, index, grads)
    _nan_to_num(grads)
    _median_test(x, y, u, v, grads, ok, start, index, float(epsilon), float(threshold), outlier, residual)
    return outlier, residual


def gate_status(status: np.ndarray, zncc: np.ndarray, x: np.ndarray, y: np.ndarray, u: np.ndarray, v: np.ndarray,
                graph: NeighbourGraph | None, gates: Gates = Gates(), *, gradients: Gradients | None = None,
                poor_texture: np.ndarray | None = None,
                known_outliers: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Status after the correlation, texture and neighbour gates (a new array).

    Parameters
    ----------
    status : ndarray of int8, shape (N,)
        Status from the solver (border and convergence already decided there).
    zncc, x, y, u, v : ndarray of float64, shape (N,)
    graph : (start, index) or None
        Neighbours for the median test; None skips it.
    gates : Gates
    gradients : tuple of 4 ndarrays (ux, uy, vx, vy), optional
        For the median test (``median_test``).
    poor_texture : ndarray of bool, shape (N,), optional
        From ``Texture.poor``.
    known_outliers : (ok, outlier) of ndarray of bool, shape (N,), optional
        The outliers ``median_test`` found over the points ``ok`` on these same u, v and gradients
        (with ``gates``' thresholds): taken instead of testing again where the points still OK here
        are those (``Tracker`` tests the same frame twice).

    Returns
    -------
    ndarray of int8, shape (N,)
        ``POOR_TEXTURE`` > ``LOW_CORRELATION`` > ``OUTLIER`` over points that were OK.
    """
    status = np.asarray(status).astype(np.int8, copy=True)
    ok = status == OK
    low = ok & ~(np.asarray(zncc) >= gates.min_zncc)
    status[low] = LOW_CORRELATION
    if poor_texture is not None:
        status[ok & poor_texture] = POOR_TEXTURE
    if graph is not None:
        still = status == OK
        if known_outliers is not None and np.array_equal(known_outliers[0], still):
            outlier = known_outliers[1]
        else:
            outlier, _ = median_test(x, y, u, v, still, graph, gradients=gradients, epsilon=gates.outlier_epsilon,
                                     threshold=gates.outlier_threshold)
        status[outlier] = OUTLIER
    return status
