"""Classic surface fit: quadratic through the 3x3 integer ZNCC neighbourhood of the integer peak.

The baseline sub-pixel method of the paper (section 3.2, "surface fitting
method"): ZNCC at the 9 integer displacements around (u0, v0), then the closed
form least-squares quadratic of ``dic.subpixel.peak_fit.fit_peak_3x3`` at grid
spacing 1 px: ``u = u0 + dx``, ``v = v0 + dy``. No interpolation is needed.
Its error is a systematic, shift-dependent bias (the correlation peak is not a
quadratic over +-1 px): of order 0.01-0.05 px on R = 4 px speckle.

If (u0, v0) is not the maximum of its 3x3 neighbourhood (a search that stopped
short of the peak), the centre moves to the best neighbour and the 3x3 is
re-evaluated, at most ``max_moves`` times (default 2); the fit is only made
around a local maximum.

Status: OK; OUTSIDE_TARGET when a neighbour's subset leaves the deformed image
(the peak sits on the image edge: no silent extrapolated number);
NOT_CONVERGED when the centre is still not a local maximum after ``max_moves``
or the fitted quadratic has no maximum within one pixel. Codes other than OK
are copied through; u, v NaN where not OK. ``zncc`` is the fitted quadratic's
value at its peak (clipped to 1). The target needs 1 px of margin.
"""

from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.correlation import prepare_reference_subset, subset_inside, zncc_at_integer
from livedic.dic.method_options import is_int_at_least, resolve_options
from livedic.dic.result import SubpixelResult
from livedic.dic.status import (BAD_GUESS, FLAT_REFERENCE, FLAT_TARGET, NOT_CONVERGED, OK, OUTSIDE_REFERENCE,
                                OUTSIDE_TARGET)
from livedic.dic.subpixel.peak_fit import fit_peak_3x3

DEFAULTS = {"max_moves": 2}
CHECKS = {"max_moves": (is_int_at_least(0), "an integer >= 0")}


@njit(cache=True)
def _refine_one(reference, target, x, y, u0, v0, half, max_moves, fhat, out):
    height, width = target.shape
    if not subset_inside(height, width, x, y, half):
        return OUTSIDE_REFERENCE
    if prepare_reference_subset(reference, x, y, half, fhat) == 0.0:
        return FLAT_REFERENCE
    c3 = np.empty((3, 3))
    u = u0
    v = v0
    for move in range(max_moves + 1):
        if not subset_inside(height, width, x + u, y + v, half + 1):
            return OUTSIDE_TARGET
        bu = 0
        bv = 0
        for dv in range(-1, 2):
            for du in range(-1, 2):
                c3[dv + 1, du + 1] = zncc_at_integer(fhat, target, x, y, half, u + du, v + dv)
                if c3[dv + 1, du + 1] > c3[bv + 1, bu + 1]:
                    bu = du
                    bv = dv
        if bu == 0 and bv == 0:
            break
        if move == max_moves:
            return NOT_CONVERGED
        u += bu
        v += bv
    if c3[1, 1] == -1.0:
        return FLAT_TARGET
    dx, dy, peak, ok = fit_peak_3x3(c3)
    if not ok:
        return NOT_CONVERGED
    out[0] = u + dx
    out[1] = v + dy
    out[2] = min(peak, 1.0)
    return OK


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, u0s, v0s, half, max_moves, status, out_u, out_v, out_c):
    """Refine every point with status OK; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        if status[i] != OK:
            continue
        fhat = np.empty(side * side)
        out = np.empty(3)
        st = _refine_one(reference, target, xs[i], ys[i], u0s[i], v0s[i], half, max_moves, fhat, out)
        status[i] = st
        if st == OK:
            out_u[i] = out[0]
            out_v[i] = out[1]
            out_c[i] = out[2]


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int, *, seed: int = 0,
           **options: Any) -> SubpixelResult:
    """Sub-pixel displacement by the classic 3x3 quadratic surface fit (1 px spacing).

    Parameters
    ----------
    reference, deformed : ndarray of float32, shape (H, W)
        Validated, C-contiguous images of equal size.
    xs, ys : ndarray of int64, shape (N,)
        Snapped point positions.
    u0, v0 : ndarray of float64, shape (N,)
        Integer-valued start (the integer search result); rounded if not integer.
    status : ndarray of int8, shape (N,)
        Only points with ``Status.OK`` are refined; other codes are copied through.
    half : int
        Subset half-width.
    seed : int
        Unused (the method is deterministic); accepted for a uniform interface.
    **options
        ``max_moves`` (2): recentring steps allowed when the start is not a local maximum.

    Returns
    -------
    SubpixelResult
        u, v (NaN where not OK), zncc (fitted peak value), status.

    Raises
    ------
    ValueError
        Unknown option or bad option value.
    """
    params = resolve_options("surface-fit", options, DEFAULTS, CHECKS)
    n = np.asarray(xs).shape[0]
    st = np.array(status, dtype=np.int8, copy=True)
    u0a = np.asarray(u0, dtype=np.float64)
    v0a = np.asarray(v0, dtype=np.float64)
    finite = np.isfinite(u0a) & np.isfinite(v0a)
    st[(st == OK) & ~finite] = BAD_GUESS
    u0i = np.floor(np.clip(np.where(finite, u0a, 0.0), -1e12, 1e12) + 0.5).astype(np.int64)
    v0i = np.floor(np.clip(np.where(finite, v0a, 0.0), -1e12, 1e12) + 0.5).astype(np.int64)
    out_u = np.full(n, np.nan)
    out_v = np.full(n, np.nan)
    out_c = np.full(n, np.nan)
    if n:
        _batch(reference, deformed, np.ascontiguousarray(xs, dtype=np.int64), np.ascontiguousarray(ys, dtype=np.int64),
               u0i, v0i, int(half), int(params["max_moves"]), st, out_u, out_v, out_c)
    return SubpixelResult(u=out_u, v=out_v, zncc=out_c, status=st)
