"""Forward-additive Newton-Raphson (Gauss-Newton) sub-pixel refinement.

The classic DIC refinement (Bruck et al. 1989; Vendroux & Knauss 1998; OpenCorr's ``NR2D1``,
vincentjzy/OpenCorr ``src/oc_nr.cpp``): minimise the ZNSSD between the reference subset and
the target subset warped by ``p``, linearising the *target* at the current warp, and update
``p <- p + dp``; the target gradients and the matrix are recomputed every iteration.

- shape function ``order=1`` (default): p = (u, ux, uy, v, vx, vy),
  ``x' = x0 + u + (1 + ux) dx + uy dy``, ``y' = y0 + v + vx dx + (1 + vy) dy``;
  ``order=0``: p = (u, v), a rigid shift of the subset;
- target value and gradient by bicubic B-spline interpolation (``dic.bspline``);
- ``J_i = [gx, gx dx, gx dy, gy, gy dx, gy dy]`` (order 0: ``[gx, gy]``),
  ``H = sum J_i^T J_i``, ``b = sum J_i^T [(|g~|/|f~|)(f_i - mean f) - (g_i - mean g)]``,
  ``dp = H^-1 b``;
- converged when ``sqrt(du^2 + dv^2 + M^2 (dux^2 + duy^2 + dvx^2 + dvy^2)) < 0.001``
  (M the subset half-width), at most ``max_iterations`` (20) iterations.

``hessian="projected"`` uses the exact derivative (same fixed point, fewer iterations); the
default stays the classic ``sum J^T J``. Its convergence, its bias on noisy images and the
references: docs/guide/measure.md ("Newton-Raphson: convergence and bias").
"""

import numpy as np
import numpy.typing as npt
from numba import njit, prange

from livedic.dic.bspline import PAD, prefilter, value_gradient_at, warped_subset_inside
from livedic.dic.correlation import FLAT_VARIANCE as _FLAT
from livedic.dic.subpixel.hessian import fold_row, gauss_newton_matrix, subtract_normalisation
from livedic.dic.subpixel.linalg import cholesky_lower
from livedic.dic.result import SubpixelResult
from livedic.dic.status import (BAD_GUESS as _BAD_GUESS, FLAT_REFERENCE as _FLAT_REFERENCE, FLAT_TARGET as _FLAT_TARGET,
                        NOT_CONVERGED as _NOT_CONVERGED, OK as _OK, OUTSIDE_REFERENCE as _OUTSIDE_REFERENCE,
                        OUTSIDE_TARGET as _OUTSIDE_TARGET, Status)
from livedic.dic.validation import as_image, check_same_shape

_MAX_GRADIENT = 1.0  # |ux|.. beyond this the iteration is declared diverged
_CHUNK = 16


@njit(cache=True)
def _solve_spd(a, b, k, out):
    """Solve a[:k, :k] x = b[:k] (symmetric positive definite) by Cholesky; False if singular."""
    low = np.zeros((6, 6))
    if not cholesky_lower(a, k, low):
        return False
    y = np.zeros(6)
    for i in range(k):
        s = b[i]
        for m in range(i):
            s -= low[i, m] * y[m]
        y[i] = s / low[i, i]
    for i in range(k - 1, -1, -1):
        s = y[i]
        for m in range(i + 1, k):
            s -= low[m, i] * out[m]
        out[i] = s / low[i, i]
    return True


@njit(cache=True)
def _nr_sums(coeffs, x0, y0, half, ftilde, p, acc, r):
    """One pass over the warped subset: acc (39,) <- the sums that H, b, mean and |g~| need.

    Layout: [0:3] sum g, g^2, ftilde g; then for the pairs (gx gx, gx gy, gy gy)
    the moments (1, dx, dy, dx^2, dx dy, dy^2) at [3:21]; then for G in (gx, gy)
    and weight in (ftilde, g, 1) the moments (1, dx, dy) at [21:39]. r : (24,) row scratch.
    """
    side = 2 * half + 1
    u, ux, uy, v, vx, vy = p[0], p[1], p[2], p[3], p[4], p[5]
    for m in range(acc.shape[0]):
        acc[m] = 0.0
    k = 0
    for j in range(side):
        dy = float(j - half)
        bx = x0 + u + uy * dy + PAD
        by = y0 + v + (1.0 + vy) * dy + PAD
        # per-row sums, moments in dx only: pairs x (1, dx, dx^2), vectors x (1, dx)
        for m in range(24):
            r[m] = 0.0
        for i in range(side):
            dx = float(i - half)
            xw = bx + (1.0 + ux) * dx
            yw = by + vx * dx
            g, gx, gy = value_gradient_at(coeffs, xw - PAD, yw - PAD)
            ft = ftilde[k]
            k += 1
            acc[0] += g
            acc[1] += g * g
            acc[2] += ft * g
            xx = gx * gx
            xy = gx * gy
            yy = gy * gy
            r[0] += xx
            r[1] += xx * dx
            r[2] += xx * dx * dx
            r[3] += xy
            r[4] += xy * dx
            r[5] += xy * dx * dx
            r[6] += yy
            r[7] += yy * dx
            r[8] += yy * dx * dx
            q = 9
            for G in (gx, gy):
                for w in (ft, g, 1.0):
                    t = G * w
                    r[q] += t
                    r[q + 1] += t * dx
                    q += 2
        # fold the row into the subset moments
        fold_row(r, dy, acc[3:21])
        for vec in range(6):
            s1, sx = r[9 + 2 * vec], r[9 + 2 * vec + 1]
            o = 21 + 3 * vec
            acc[o] += s1
            acc[o + 1] += sx
            acc[o + 2] += s1 * dy


@njit(cache=True)
def _nr_one(coeffs, height, width, x0, y0, half, ftilde, fnorm, p, order, projected, max_iterations, tolerance,
            acc, row, hess, rhs, dp, sum_j, sum_jhat):
    """Refine p (6,) in place; return (status, zncc, iterations). acc .. sum_jhat: scratch."""
    side = 2 * half + 1
    n = side * side
    half2 = float(half * half)
    tol2 = tolerance * tolerance
    zncc = np.nan
    k = 6 if order == 1 else 2
    for it in range(1, max_iterations + 1):
        if not warped_subset_inside(height, width, x0, y0, half, p[0], p[1], p[2], p[3], p[4], p[5]):
            return _OUTSIDE_TARGET, zncc, it - 1
        _nr_sums(coeffs, x0, y0, half, ftilde, p, acc, row)
        mean = acc[0] / n
        var = acc[1] - acc[0] * mean
        if var <= _FLAT * n * (1.0 + mean * mean):
            return _FLAT_TARGET, zncc, it - 1
        gnorm = np.sqrt(var)
        zncc = acc[2] / (fnorm * gnorm)
        scale = gnorm / fnorm
        # parameter a -> (gradient component G, moment index in (1, dx, dy))
        for a in range(6):
            base = 21 + 9 * (a // 3) + a % 3
            # b_a = scale * sum G f~ m - sum G g m + mean * sum G m
            rhs[a] = scale * acc[base] - acc[base + 3] + mean * acc[base + 6]
        gauss_newton_matrix(acc[3:21], hess)
        if projected:
            # H = sum J~ J~^T - (sum J ghat)(sum J ghat)^T, J~ = J - mean J, ghat = g~ / |g~|
            for a in range(6):
                base = 21 + 9 * (a // 3) + a % 3
                sum_j[a] = acc[base + 6]
                sum_jhat[a] = (acc[base + 3] - mean * sum_j[a]) / gnorm
            subtract_normalisation(hess, sum_j, sum_jhat, n)
        if order == 0:
            hess[1, 0] = hess[3, 0]
            hess[0, 1] = hess[0, 3]
            hess[1, 1] = hess[3, 3]
            rhs[1] = rhs[3]
        if not _solve_spd(hess, rhs, k, dp):
            return _FLAT_TARGET, zncc, it
        if order == 0:
            p[0] += dp[0]
            p[3] += dp[1]
            norm2 = dp[0] * dp[0] + dp[1] * dp[1]
        else:
            for a in range(6):
                p[a] += dp[a]
            norm2 = dp[0] * dp[0] + dp[3] * dp[3] + half2 * (dp[1] * dp[1] + dp[2] * dp[2] + dp[4] * dp[4]
                                                               + dp[5] * dp[5])
        if not (np.isfinite(p[0]) and np.isfinite(p[3]) and abs(p[1]) < _MAX_GRADIENT and abs(p[2]) < _MAX_GRADIENT
                and abs(p[4]) < _MAX_GRADIENT and abs(p[5]) < _MAX_GRADIENT):
            return _NOT_CONVERGED, zncc, it
        if norm2 < tol2:
            return _OK, zncc, it
    return _NOT_CONVERGED, zncc, max_iterations


@njit(cache=True, parallel=True, nogil=True)
def _nr_batch(reference, coeffs, xs, ys, half, params, status, order, projected, max_iterations, tolerance,
              out_zncc, out_iter):
    """Refine every point whose status is OK; params (N, 6) in/out, status (N,) in/out."""
    npts = xs.shape[0]
    height, width = reference.shape
    side = 2 * half + 1
    n = side * side
    n_chunks = (npts + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        ftilde = np.empty(n)
        acc = np.empty(39)
        row = np.empty(24)
        hess = np.zeros((6, 6))
        rhs = np.zeros(6)
        dp = np.zeros(6)
        sum_j = np.empty(6)
        sum_jhat = np.empty(6)
        for i in range(c * _CHUNK, min((c + 1) * _CHUNK, npts)):
            out_iter[i] = 0
            out_zncc[i] = np.nan
            if status[i] != _OK:
                continue
            x0 = xs[i]
            y0 = ys[i]
            if x0 - half < 0 or y0 - half < 0 or x0 + half >= width or y0 + half >= height:
                status[i] = _OUTSIDE_REFERENCE
                continue
            finite = True
            for m in range(6):
                if not np.isfinite(params[i, m]):
                    finite = False
            if not finite:
                status[i] = _BAD_GUESS
                continue
            total = 0.0
            for dy in range(-half, half + 1):
                for dx in range(-half, half + 1):
                    total += reference[y0 + dy, x0 + dx]
            mean = total / n
            sq = 0.0
            k = 0
            for dy in range(-half, half + 1):
                for dx in range(-half, half + 1):
                    d = reference[y0 + dy, x0 + dx] - mean
                    ftilde[k] = d
                    sq += d * d
                    k += 1
            if sq <= _FLAT * n * (1.0 + mean * mean):
                status[i] = _FLAT_REFERENCE
                continue
            st, zn, it = _nr_one(coeffs, height, width, x0, y0, half, ftilde, np.sqrt(sq), params[i], order,
                                 projected, max_iterations, tolerance, acc, row, hess, rhs, dp, sum_j, sum_jhat)
            status[i] = st
            out_iter[i] = it
            if st == _OK:
                out_zncc[i] = zn


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int, *, order: int = 1,
           max_iterations: int = 20, tolerance: float = 0.001, hessian: str = "opencorr",
           ux0: npt.ArrayLike | None = None, uy0: npt.ArrayLike | None = None, vx0: npt.ArrayLike | None = None,
           vy0: npt.ArrayLike | None = None) -> SubpixelResult:
    """Forward-additive Newton-Raphson refinement of every point whose ``status`` is OK.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images of equal shape (converted to float32).
    xs, ys : ndarray of int64, shape (N,)
        Subset centres.
    u0, v0 : ndarray of float64, shape (N,)
        Start (integer search result or float guess); NaN gives ``BAD_GUESS``.
    status : ndarray of int8, shape (N,)
        Refine only where OK; other codes are copied through.
    half : int
        Subset half-width M.
    order : {0, 1}
        Shape function: 0 = rigid shift (u, v); 1 = affine (u, ux, uy, v, vx, vy).
    max_iterations : int
        Iteration cap (20); reaching it unconverged gives ``NOT_CONVERGED``.
    tolerance : float
        Threshold on the scaled increment norm (0.001).
    hessian : {"opencorr", "projected"}
        "opencorr" (default, the classic method): ``H = sum J J^T``.
        "projected": ``H = sum J~ J~^T - (sum J ghat)(sum J ghat)^T`` with
        ``J~ = J - mean J`` and ``ghat`` the normalised target subset, the exact
        derivative of ``b`` at a zero-residual solution (as IC-GN's default,
        ``dic.subpixel.icgn``): same fixed point, quadratic instead of linear
        convergence along the strain parameters, same cost per iteration.
    ux0, uy0, vx0, vy0 : ndarray, shape (N,), optional
        Start displacement gradients (order 1); zero if omitted.

    Returns
    -------
    SubpixelResult
        u, v, zncc, status, iterations; ux, uy, vx, vy for ``order=1``. NaN where not OK.
        ``zncc`` is that of the last sampled subset (before the final, < tolerance, update).
    """
    if order not in (0, 1):
        raise ValueError(f"order must be 0 (shift) or 1 (affine), got {order!r}")
    if hessian not in ("opencorr", "projected"):
        raise ValueError(f"hessian must be 'opencorr' or 'projected', got {hessian!r}")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    if not tolerance > 0:
        raise ValueError(f"tolerance must be > 0, got {tolerance}")
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    xs = np.ascontiguousarray(xs, dtype=np.int64)
    ys = np.ascontiguousarray(ys, dtype=np.int64)
    npts = xs.shape[0]
    params = np.zeros((npts, 6))
    params[:, 0] = u0
    params[:, 3] = v0
    if order == 1:
        for col, values in ((1, ux0), (2, uy0), (4, vx0), (5, vy0)):
            if values is not None:
                params[:, col] = values
    st = np.array(status, dtype=np.int8, copy=True)
    coeffs = prefilter(deformed, dtype=np.float32)
    out_zncc = np.empty(npts)
    out_iter = np.empty(npts, dtype=np.int64)
    _nr_batch(reference, coeffs.coefficients, xs, ys, int(half), params, st, int(order), hessian == "projected",
              int(max_iterations), float(tolerance), out_zncc, out_iter)
    ok = st == Status.OK
    params[~ok] = np.nan
    grads = {}
    if order == 1:
        grads = dict(ux=params[:, 1].copy(), uy=params[:, 2].copy(), vx=params[:, 4].copy(), vy=params[:, 5].copy())
    return SubpixelResult(u=params[:, 0].copy(), v=params[:, 3].copy(), zncc=np.where(ok, out_zncc, np.nan),
                          status=st, iterations=out_iter, **grads)
