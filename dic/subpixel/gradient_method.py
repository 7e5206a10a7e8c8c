"""Gradient-based sub-pixel refinement: one linearised least-squares step (Davis & Freeman 1998).

Around the integer match ``(u0, v0)`` the deformed subset is expanded to first
order, ``g(x_i + u0 + du, y_i + v0 + dv) ~ G_i + du Gx_i + dv Gy_i`` with
``G_i = g(x_i + u0, y_i + v0)`` and ``Gx, Gy`` the gradients of ``g`` at those
integer pixels, and ``(du, dv)`` solves the 2x2 normal equations

    [sum Gx^2   sum Gx Gy] [du]   [sum (f'_i - G_i) Gx_i]
    [sum Gx Gy  sum Gy^2 ] [dv] = [sum (f'_i - G_i) Gy_i]

No interpolation and no iteration: it is the cheapest sub-pixel method after
the correlation surface fit. The reference is intensity-normalised to the
target subset, ``f'_i = mean g + (|g~| / |f~|)(f_i - mean f)``, so an affine
intensity change ``g -> a g + b`` between the images does not bias it
(algorithms.md section 6.2). Gradients use the 4th-order central difference
(``dic.gradient``; ``gradient="central"`` for the 2nd-order one).

The truncated Taylor series makes the error grow with the distance from the
integer pixel: it is largest near 0.5 px (Pan et al. 2006 compare it with the
surface fit and Newton-Raphson). ``u0, v0`` are rounded to the nearest
integer: the method is defined around an integer match; a step longer than
one pixel (a start that was not the peak) is reported as NOT_CONVERGED. It
needs speckle-like texture: on a smooth, ramp-like subset the normalisation
cannot tell a shift from an intensity offset.

``zncc`` is that of the linearised subset ``G + du Gx + dv Gy`` against the
reference (the method never resamples the target).

References
----------
C. Q. Davis and D. M. Freeman, "Statistics of subpixel registration algorithms
based on spatiotemporal gradients or block matching", Opt. Eng. 37(4):1290-1298
(1998), :DOI:`10.1117/1.601966`.

B. Pan, H. Xie, B. Xu and F. Dai, "Performance of sub-pixel registration
algorithms in digital image correlation", Meas. Sci. Technol. 17:1615-1621
(2006), :DOI:`10.1088/0957-0233/17/6/045`.
"""

import numpy as np
from numba import njit, prange

from livedic.dic.correlation import FLAT_VARIANCE as _FLAT
from livedic.dic.gradient import diff2_x, diff2_y, diff4_x, diff4_y
from livedic.dic.result import SubpixelResult
from livedic.dic.status import (BAD_GUESS as _BAD_GUESS, FLAT_REFERENCE as _FLAT_REFERENCE, FLAT_TARGET as _FLAT_TARGET,
                        NOT_CONVERGED as _NOT_CONVERGED, OK as _OK, OUTSIDE_REFERENCE as _OUTSIDE_REFERENCE,
                        OUTSIDE_TARGET as _OUTSIDE_TARGET)
from livedic.dic.validation import as_image, check_same_shape

_MAX_STEP = 1.0   # a step beyond one pixel means the start was not the integer peak


@njit(cache=True)
def _gradient_one(reference, deformed, x0, y0, half, u0, v0, fourth):
    """One Davis-Freeman step for one point; return (status, u, v, zncc)."""
    height, width = reference.shape
    if x0 - half < 0 or y0 - half < 0 or x0 + half >= width or y0 + half >= height:
        return _OUTSIDE_REFERENCE, np.nan, np.nan, np.nan
    if not (np.isfinite(u0) and np.isfinite(v0)):
        return _BAD_GUESS, np.nan, np.nan, np.nan
    iu = int(np.floor(u0 + 0.5))
    iv = int(np.floor(v0 + 0.5))
    tx = x0 + iu
    ty = y0 + iv
    reach = half + (2 if fourth else 1)   # the difference stencil reaches beyond the subset
    if tx - reach < 0 or ty - reach < 0 or tx + reach >= width or ty + reach >= height:
        return _OUTSIDE_TARGET, np.nan, np.nan, np.nan
    side = 2 * half + 1
    n = side * side
    sf = 0.0
    sff = 0.0
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            f = np.float64(reference[y0 + dy, x0 + dx])
            sf += f
            sff += f * f
    fmean = sf / n
    fvar = sff - sf * fmean
    if fvar <= _FLAT * n * (1.0 + fmean * fmean):
        return _FLAT_REFERENCE, np.nan, np.nan, np.nan
    # one pass: every sum the step and the linearised ZNCC need (f~ = f - mean f)
    s_g = 0.0
    s_gg = 0.0
    s_x = 0.0
    s_y = 0.0
    s_xx = 0.0
    s_xy = 0.0
    s_yy = 0.0
    s_gx = 0.0
    s_gy = 0.0
    s_fg = 0.0
    s_fx = 0.0
    s_fy = 0.0
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            ft = reference[y0 + dy, x0 + dx] - fmean
            r = ty + dy
            c = tx + dx
            g = np.float64(deformed[r, c])
            if fourth:
                gx = diff4_x(deformed, r, c)
                gy = diff4_y(deformed, r, c)
            else:
                gx = diff2_x(deformed, r, c)
                gy = diff2_y(deformed, r, c)
            s_g += g
            s_gg += g * g
            s_x += gx
            s_y += gy
            s_xx += gx * gx
            s_xy += gx * gy
            s_yy += gy * gy
            s_gx += g * gx
            s_gy += g * gy
            s_fg += ft * g
            s_fx += ft * gx
            s_fy += ft * gy
    gmean = s_g / n
    gvar = s_gg - s_g * gmean
    if gvar <= _FLAT * n * (1.0 + gmean * gmean):
        return _FLAT_TARGET, np.nan, np.nan, np.nan
    scale = np.sqrt(gvar / fvar)
    # sum (f'_i - G_i) Gx_i with f'_i = mean g + scale * f~_i
    bx = gmean * s_x + scale * s_fx - s_gx
    by = gmean * s_y + scale * s_fy - s_gy
    det = s_xx * s_yy - s_xy * s_xy
    if not det > 1e-12 * (s_xx * s_yy + 1e-300):
        return _FLAT_TARGET, np.nan, np.nan, np.nan
    du = (s_yy * bx - s_xy * by) / det
    dv = (s_xx * by - s_xy * bx) / det
    if not (abs(du) <= _MAX_STEP and abs(dv) <= _MAX_STEP):
        return _NOT_CONVERGED, np.nan, np.nan, np.nan
    # ZNCC of the linearised subset m = G + du Gx + dv Gy against f
    s_m = s_g + du * s_x + dv * s_y
    s_mm = (s_gg + du * du * s_xx + dv * dv * s_yy + 2.0 * du * s_gx + 2.0 * dv * s_gy
            + 2.0 * du * dv * s_xy)
    s_fm = s_fg + du * s_fx + dv * s_fy
    mvar = s_mm - s_m * s_m / n
    zncc = s_fm / np.sqrt(fvar * mvar) if mvar > 0.0 else np.nan
    return _OK, iu + du, iv + dv, zncc


@njit(cache=True, parallel=True, nogil=True)
def _gradient_batch(reference, deformed, xs, ys, half, u0, v0, fourth, status, out_u, out_v, out_zncc):
    for i in prange(xs.shape[0]):
        out_u[i] = np.nan
        out_v[i] = np.nan
        out_zncc[i] = np.nan
        if status[i] != _OK:
            continue
        st, u, v, zn = _gradient_one(reference, deformed, xs[i], ys[i], half, u0[i], v0[i], fourth)
        status[i] = st
        if st == _OK:
            out_u[i] = u
            out_v[i] = v
            out_zncc[i] = zn


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int, *,
           gradient: str = "4th") -> SubpixelResult:
    """Gradient-method refinement of every point whose ``status`` is OK.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images of equal shape (converted to float32).
    xs, ys : ndarray of int64, shape (N,)
        Subset centres.
    u0, v0 : ndarray of float64, shape (N,)
        Integer-pixel match (rounded to the nearest integer if not); NaN gives ``BAD_GUESS``.
    status : ndarray of int8, shape (N,)
        Refine only where OK; other codes are copied through.
    half : int
        Subset half-width M.
    gradient : {"4th", "central"}
        Difference operator for the target gradients.

    Returns
    -------
    SubpixelResult
        u, v, zncc (of the linearised subset), status; NaN where not OK.
        ``NOT_CONVERGED`` where the step exceeds one pixel (the start was not
        the integer peak); ``OUTSIDE_TARGET`` where the subset plus the
        difference stencil leaves the deformed image.
    """
    if gradient not in ("4th", "central"):
        raise ValueError(f"gradient must be '4th' or 'central', got {gradient!r}")
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    xs = np.ascontiguousarray(xs, dtype=np.int64)
    ys = np.ascontiguousarray(ys, dtype=np.int64)
    npts = xs.shape[0]
    st = np.array(status, dtype=np.int8, copy=True)
    out_u = np.empty(npts)
    out_v = np.empty(npts)
    out_zncc = np.empty(npts)
    _gradient_batch(reference, deformed, xs, ys, int(half), np.ascontiguousarray(u0, dtype=np.float64),
                    np.ascontiguousarray(v0, dtype=np.float64), gradient == "4th", st, out_u, out_v, out_zncc)
    return SubpixelResult(u=out_u, v=out_v, zncc=out_zncc, status=st)
