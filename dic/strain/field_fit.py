"""Displacement at any position from the tracked points around it: local least-squares surfaces.

A virtual extensometer's end, or a material point that must be placed in a new reference frame,
lies between the tracked points. Its displacement is a least-squares quadratic surface
u = a0 + a1 dx + a2 dy + a3 dx^2 + a4 dx dy + a5 dy^2 (and the same for v) fitted to the ok
points within ``REACH`` grid steps (about 20 on a grid), evaluated at the position: exact to
second order, and averaging the points' noise. Measured on the simulated tensile test
(``livedic bench strain``): a plane over 2 steps is biased by the curvature of the field near a
neck (a transverse gauge through it read 1 % low at the last frame), the quadratic over 2.5
steps is not, and over 3 steps the third-order terms grow back. A position whose neighbourhood
holds fewer than ``MIN_POINTS`` valid points, or points along a line only, gets NaN.

A band (``band_neighbourhoods``, terms ``BAND``) is the other neighbourhood: the points within
``BAND_HALF_HEIGHT`` steps of the position along a direction s, at any distance across it (t), fitted
with 1, s, t, s t, s^2: quadratic along s (a neck's curvature), linear across (a rotation, a gradient
across the width). An extensometer's end on a line across the specimen averages every point across
the width (``dic.strain.extensometer``, ``BAND``).
"""

import math

import numpy as np
from numba import njit

REACH = 2.5                # grid steps
MIN_POINTS = 10            # 6 coefficients, with some to spare
MIN_SPREAD = 0.2           # smaller eigenvalue of the points' position covariance, in step^2
BAND_HALF_HEIGHT = 3.5     # grid steps either side of an end along its extensometer (``band_neighbourhoods``)


@njit(cache=True)
def _near(ex, ey, x, y, reach):
    """CSR lists of the points within ``reach`` (Euclidean) of each position (ex, ey)."""
    n_ends = ex.shape[0]
    counts = np.zeros(n_ends + 1, dtype=np.int64)
    r2 = reach * reach
    for k in range(n_ends):
        for j in range(x.shape[0]):
            if (x[j] - ex[k]) ** 2 + (y[j] - ey[k]) ** 2 <= r2:
                counts[k + 1] += 1
    for k in range(n_ends):
        counts[k + 1] += counts[k]
    index = np.empty(counts[n_ends], dtype=np.int64)
    for k in range(n_ends):
        fill = counts[k]
        for j in range(x.shape[0]):
            if (x[j] - ex[k]) ** 2 + (y[j] - ey[k]) ** 2 <= r2:
                index[fill] = j
                fill += 1
    return counts, index


@njit(cache=True)
def _solve_in_place(a, b):
    """Solve a x = b (small dense, partial pivoting) into b; False when a is (nearly) singular."""
    n = a.shape[0]
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(a[i, i]))
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if abs(a[pivot, col]) <= 1e-10 * scale:
            return False
        if pivot != col:
            for k in range(n):
                a[col, k], a[pivot, k] = a[pivot, k], a[col, k]
            for k in range(b.shape[1]):
                b[col, k], b[pivot, k] = b[pivot, k], b[col, k]
        for row in range(col + 1, n):
            f = a[row, col] / a[col, col]
            for k in range(col, n):
                a[row, k] -= f * a[col, k]
            for k in range(b.shape[1]):
                b[row, k] -= f * b[col, k]
    for col in range(n - 1, -1, -1):
        for k in range(b.shape[1]):
            acc = b[col, k]
            for j in range(col + 1, n):
                acc -= a[col, j] * b[j, k]
            b[col, k] = acc / a[col, col]
    return True


# The surfaces' terms s^a t^b, (a, b) each, in the end's own frame (s along ``axis``, t across it), in grid steps.
QUADRATIC = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
# A band across the gauge line: quadratic along it (a neck's curvature), linear across it (a rotation or a
# gradient across the width is no elongation), no t^2: a line of points across the specimen pins no curvature.
BAND = ((0, 0), (1, 0), (0, 1), (1, 1), (2, 0))


@njit(cache=True)
def _local_fits(ends, axes, start, index, x, y, u, v, valid, step, powers, min_points, min_spread, straddle,
                out_u, out_v):
    """Least-squares surfaces of u and v with the terms ``powers`` around each position, evaluated there;
    NaN where not possible. ``straddle``: also NaN unless valid points lie within half a step of the position on
    each side along and across its axis (interpolated, never extrapolated)."""
    terms = powers.shape[0]
    basis = np.empty(terms)
    for k in range(ends.shape[0]):
        out_u[k] = np.nan
        out_v[k] = np.nan
        ax = axes[k, 0]
        ay = axes[k, 1]
        count = 0
        sx = 0.0
        sy = 0.0
        for m in range(start[k], start[k + 1]):
            j = index[m]
            if valid[j]:
                count += 1
                sx += (x[j] - ends[k, 0]) / step
                sy += (y[j] - ends[k, 1]) / step
        if count < min_points:
            continue
        mx = sx / count
        my = sy / count
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        normal = np.zeros((terms, terms))
        rhs = np.zeros((terms, 2))
        lo_s = np.inf
        hi_s = -np.inf
        lo_t = np.inf
        hi_t = -np.inf
        for m in range(start[k], start[k + 1]):
            j = index[m]
            if not valid[j]:
                continue
            # Offsets in grid steps keep the normal matrix well scaled.
            px = (x[j] - ends[k, 0]) / step
            py = (y[j] - ends[k, 1]) / step
            sxx += (px - mx) ** 2
            sxy += (px - mx) * (py - my)
            syy += (py - my) ** 2
            ps = px * ax + py * ay
            pt = py * ax - px * ay
            lo_s = min(lo_s, ps)
            hi_s = max(hi_s, ps)
            lo_t = min(lo_t, pt)
            hi_t = max(hi_t, pt)
            for r in range(terms):
                basis[r] = ps ** powers[r, 0] * pt ** powers[r, 1]
            for r in range(terms):
                rhs[r, 0] += basis[r] * u[j]
                rhs[r, 1] += basis[r] * v[j]
                for c in range(terms):
                    normal[r, c] += basis[r] * basis[c]
        half_trace = 0.5 * (sxx + syy) / count
        gap = math.sqrt((0.5 * (sxx - syy) / count) ** 2 + (sxy / count) ** 2)
        if half_trace - gap < min_spread:
            continue
        if straddle and (lo_s > 0.5 or hi_s < -0.5 or lo_t > 0.5 or hi_t < -0.5):
            continue
        if not _solve_in_place(normal, rhs):
            continue
        out_u[k] = rhs[0, 0]       # the surface at the end (offset 0): the constant term comes first
        out_v[k] = rhs[0, 1]


def neighbourhoods(where: np.ndarray, points: np.ndarray, step: float,
                   reach: float = REACH) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists (start, index) of the ``points`` (N, 2) within ``reach`` grid steps of each of ``where`` (M, 2)."""
    where = np.asarray(where, dtype=np.float64).reshape(-1, 2)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return _near(np.ascontiguousarray(where[:, 0]), np.ascontiguousarray(where[:, 1]),
                 np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]), float(reach) * float(step))


def band_neighbourhoods(where: np.ndarray, axes: np.ndarray, points: np.ndarray, step: float,
                        half_height: float = BAND_HALF_HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """CSR lists (start, index) of the ``points`` (N, 2) in the band across each of ``where`` (M, 2): within
    ``half_height`` grid steps of it along its unit ``axes`` (M, 2), at any distance across (a gauge-mark line
    across the specimen)."""
    where = np.asarray(where, dtype=np.float64).reshape(-1, 2)
    axes = np.asarray(axes, dtype=np.float64).reshape(-1, 2)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    along = np.abs((points[None, :, :] - where[:, None, :]) @ axes[:, :, None])[..., 0]     # (M, N)
    members = [np.flatnonzero(row <= half_height * step * (1 + 1e-12)) for row in along]
    start = np.zeros(len(where) + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(m) for m in members])
    index = np.concatenate(members).astype(np.int64) if members else np.empty(0, dtype=np.int64)
    return start, index


def fit_at(where: np.ndarray, start: np.ndarray, index: np.ndarray, points: np.ndarray, u: np.ndarray, v: np.ndarray,
           ok: np.ndarray, step: float, *, axes: np.ndarray | None = None, powers: tuple = QUADRATIC,
           straddle: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) at each of ``where`` (M, 2) from the fit over its neighbourhood (``neighbourhoods``,
    ``band_neighbourhoods``).

    ``powers``: the surface's terms s^a t^b (``QUADRATIC``: the full quadratic; ``BAND``), s along each
    position's unit ``axes`` (M, 2; default x). NaN where the neighbourhood holds too few valid (ok and
    finite) points or points along a line; with ``straddle``, also where the valid points do not surround the
    position within half a step along and across (a band's end: interpolated, never extrapolated).
    """
    where = np.ascontiguousarray(np.asarray(where, dtype=np.float64).reshape(-1, 2))
    axes = np.tile([1.0, 0.0], (len(where), 1)) if axes is None else np.asarray(axes, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    valid = np.asarray(ok, dtype=bool) & np.isfinite(u) & np.isfinite(v)
    out_u, out_v = np.empty(len(where)), np.empty(len(where))
    _local_fits(where, np.ascontiguousarray(axes.reshape(-1, 2)), start, index,
                np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]), u, v, valid, float(step),
                np.asarray(powers, dtype=np.int64), MIN_POINTS, MIN_SPREAD, bool(straddle), out_u, out_v)
    return out_u, out_v


def displacement_at(where: np.ndarray, points: np.ndarray, u: np.ndarray, v: np.ndarray, ok: np.ndarray,
                    step: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) at the positions ``where`` (M, 2) from the tracked ``points`` (N, 2) and their ``u, v, ok``.

    Parameters
    ----------
    where : array (M, 2)
        Reference positions (x, y), px.
    points : array (N, 2)
        Reference positions of the tracked points, px.
    u, v : arrays (N,)
        Their displacements, px.
    ok : array (N,) of bool
    step : float
        The points' grid step (typical spacing), px.

    Returns
    -------
    u, v : arrays (M,), NaN where no fit is possible.
    """
    start, index = neighbourhoods(where, points, step)
    return fit_at(where, start, index, points, u, v, ok, step)


def fit_weights(where: np.ndarray, index: np.ndarray, points: np.ndarray, step: float, *,
                axis: tuple[float, float] = (1.0, 0.0), powers: tuple = QUADRATIC) -> np.ndarray:
    """The weights w of the fit (``fit_at``) at ``where`` (x, y) over ``points[index]``: u(where) = w . u[index].

    All the points valid; the fit is linear in the displacements, so a point noise sigma (independent
    between points) gives the fitted value a noise sigma |w|. NaN weights where the fit is not possible.
    """
    index = np.asarray(index, dtype=np.int64)
    offsets = (np.asarray(points, dtype=np.float64).reshape(-1, 2)[index] - np.asarray(where, dtype=np.float64)) / step
    ax, ay = axis
    s = offsets[:, 0] * ax + offsets[:, 1] * ay
    t = offsets[:, 1] * ax - offsets[:, 0] * ay
    design = np.column_stack([s ** a * t ** b for a, b in powers]) if index.size else np.empty((0, len(powers)))
    if index.size < MIN_POINTS or np.linalg.matrix_rank(design) < len(powers):
        return np.full(index.size, np.nan)
    return np.linalg.pinv(design)[0]
