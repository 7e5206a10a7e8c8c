"""Inverse-compositional Gauss-Newton (IC-GN) sub-pixel refinement, 1st-order shape function.

IC-GN minimises the ZNSSD between the reference subset and the warped target subset,
linearised around the *reference*: the steepest-descent images and the step matrix are
computed once per point and reused for every iteration and every later frame (Baker &
Matthews 2004; OpenCorr's ``ICGN2D1``, Pan, Li & Tong 2013):

- warp ``x' = x0 + u + (1 + ux) dx + uy dy``, ``y' = y0 + v + vx dx + (1 + vy) dy``;
- target sampled by the B-spline of its coefficients (``prepare_target(degree=3)``, bicubic, or 5,
  biquintic, or 7, biseptic); update ``W(p) <- W(p) W(dp)^-1``;
- ZNSSD ``= sum e_i^2 / |f~|^2``, reported as ZNCC ``= 1 - ZNSSD/2``;
- converged when ``sqrt(du^2 + dv^2 + M^2 (dux^2 + duy^2 + dvx^2 + dvy^2)) < 0.001``
  (M the subset half-width), at most 10 iterations by default.

Live tracking uses the OpenCorr split: ``prepare_reference`` once per session,
``prepare_target`` once per frame, ``refine_prepared`` per frame with the previous result as
start. ``refine`` chains the three. ``hessian="projected"`` (default) or ``"opencorr"``
(``sum J J^T``): the same fixed point, so the same converged result. From a start more than
a pixel off with no displacement gradients, translation-only steps come first
(``translation_iterations``, 0 for plain IC-GN); they change the path, not the result.
``iterations`` counts both kinds. Sums are float32 per row, float64 per subset and in all
solves: within ~1e-7 relative of a float64 evaluation (checked in the tests).

The step matrix, the translation pre-stage, the vectorised sampler, their measurements and
the references: docs/guide/measure.md ("IC-GN: the step matrix and the translation pre-stage").
"""

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit, prange
from numpy import float32 as _F32

from livedic.dic.bspline import (FASTMATH, PAD, float32_lanes, BSplineCoefficients, check_degree, prefilter, sample_shift,
                                 sample_shift5, sample_shift7, warped_subset_inside)
from livedic.dic.correlation import FLAT_VARIANCE as _FLAT
from livedic.dic.gradient import diff4_x, diff4_y
from livedic.dic.subpixel.hessian import fold_row, gauss_newton_matrix, subtract_normalisation
from livedic.dic.subpixel.linalg import cholesky_lower
from livedic.dic.result import SubpixelResult
from livedic.dic.subpixel.prepared import (PerPoint, check_iterations, checked_points, point_orders, start_status,
                                           start_values)
from livedic.dic.status import (BAD_GUESS as _BAD_GUESS, FLAT_REFERENCE as _FLAT_REFERENCE, FLAT_TARGET as _FLAT_TARGET,
                        NOT_CONVERGED as _NOT_CONVERGED, OK as _OK, OUTSIDE_REFERENCE as _OUTSIDE_REFERENCE,
                        OUTSIDE_TARGET as _OUTSIDE_TARGET, Status)
from livedic.dic.validation import as_image, check_same_shape, checked_image

# |ux|, |uy|, |vx|, |vy| beyond this is no longer a small-strain subset: declared diverged.
_MAX_GRADIENT = 1.0
_NO_RUN = -(1 << 62)  # tap origin of pad lanes in split rows
_GRADIENT_COLUMNS = np.array([1, 2, 4, 5])  # ux, uy, vx, vy in (u, ux, uy, v, vx, vy)
_CHUNK = 32  # points per parallel task (scratch arrays are per task, not per point)
# Frame dtypes whose grey levels float32 holds exactly (``prepare_target`` reads them unconverted).
_EXACT_IN_FLOAT32 = tuple(np.dtype(t) for t in (np.uint8, np.uint16, np.float32))


@dataclass
class IcgnReference:
    """Everything IC-GN needs from the reference image, computed once per session.

    xs, ys : int64 (N,)        point positions (pixel centres)
    half : int                  subset half-width M; subsets have side = 2M+1 pixels
    shape : (H, W)              reference image shape
    lanes : int                 row stride of the per-point subsets: side rounded up to a
                                multiple of ``float32_lanes()`` (whole vectors); entries past side are 0
    fhat : float32 (N, side*lanes)  normalised zero-mean subset (f - mean f) / |f - mean f|,
                                row-major, pixel (dx, dy) at [(dy + M) * lanes + dx + M]
    fx, fy : float32 (N, side*lanes)  reference gradients: the steepest-descent images are
                                ``J = [fx, fx dx, fx dy, fy, fy dx, fy dy]``
    norm : float64 (N,)         |f - mean f|
    hinv : float64 (N, 6, 6)    inverse of the step matrix H (docs/guide/measure.md), order (u, ux, uy, v, vx, vy)
    hinv0 : float64 (N, 2, 2)   inverse of the (u, v) block, for translation-only steps
    sum_j : float64 (N, 6)      sum_i J_i
    sum_jf : float64 (N, 6)     sum_i J_i fhat_i
    sum_f : float64 (N,)        sum_i fhat_i (zero up to float32 rounding)
    status : int8 (N,)          OK, OUTSIDE_REFERENCE or FLAT_REFERENCE
    hessian : str               "projected" or "opencorr"
    """
    xs: np.ndarray
    ys: np.ndarray
    half: int
    shape: tuple
    lanes: int
    fhat: np.ndarray
    fx: np.ndarray
    fy: np.ndarray
    norm: np.ndarray
    hinv: np.ndarray
    hinv0: np.ndarray
    sum_j: np.ndarray
    sum_jf: np.ndarray
    sum_f: np.ndarray
    status: np.ndarray
    hessian: str = "projected"


# ---------------------------------------------------------------------------
# small dense linear algebra


@njit(cache=True)
def _invert_spd(a, out, low, linv):
    """Inverse of the symmetric positive-definite ``a`` (k, k) into ``out`` by Cholesky.

    ``low``, ``linv`` : (k, k) scratch. Returns False (``out`` undefined) when a
    pivot is not positive relative to the diagonal scale, i.e. the matrix is
    singular for practical purposes.
    """
    k = a.shape[0]
    for i in range(k):
        for j in range(k):
            linv[i, j] = 0.0
    if not cholesky_lower(a, k, low):
        return False
    # inverse of the lower factor, then out = L^-T L^-1
    for i in range(k):
        linv[i, i] = 1.0 / low[i, i]
        for j in range(i):
            s = 0.0
            for m in range(j, i):
                s -= low[i, m] * linv[m, j]
            linv[i, j] = s / low[i, i]
    for i in range(k):
        for j in range(k):
            s = 0.0
            for m in range(max(i, j), k):
                s += linv[m, i] * linv[m, j]
            out[i, j] = s
    return True


# ---------------------------------------------------------------------------
# reference preparation


@njit(cache=True, fastmath=FASTMATH)
def _prepare_one(reference, x, y, half, lanes, fhat, fx, fy, hinv, hinv0, sum_j, sum_jf, projected, work):
    """Fill the per-point arrays of one point (row stride ``lanes``); return (status, norm, sum_f).

    work : (hess (6, 6), h0 (2, 2), low (6, 6), linv (6, 6), row (17,), mom (30,)) scratch.
    The Hessian is accumulated as moments (``dic.subpixel.hessian``): per row, sums of
    fx^2, fx fy, fy^2 times (1, dx, dx^2), folded with dy at the row end.
    """
    hess, h0, low, linv, row, mom = work
    height, width = reference.shape
    if x - half < 0 or y - half < 0 or x + half >= width or y + half >= height:
        return _OUTSIDE_REFERENCE, np.nan, 0.0
    side = 2 * half + 1
    n = side * side
    flat = reference.reshape(-1)      # unsigned flat indices: no negative-index fix-up, loops vectorise
    wu = np.uint64(width)
    # one pass for the sum and the sum of squares: the values are grey levels (<= 65535), so in
    # float64 sum(f^2) - n mean^2 keeps ~6 significant digits where the subset has texture at all
    total = 0.0
    total_sq = 0.0
    for dy in range(-half, half + 1):
        o = np.uint64((y + dy) * width + x - half)
        for i in range(side):
            f = np.float64(flat[o + np.uint64(i)])
            total += f
            total_sq += f * f
    mean = total / n
    sq = max(total_sq - total * mean, 0.0)
    if sq <= _FLAT * n * (1.0 + mean * mean):
        return _FLAT_REFERENCE, np.nan, 0.0
    norm = np.sqrt(sq)
    inner = x - half - 2 >= 0 and y - half - 2 >= 0 and x + half + 2 < width and y + half + 2 < height
    for m in range(mom.shape[0]):
        mom[m] = 0.0
    sum_f = 0.0
    inv_norm = 1.0 / norm
    # float32 arithmetic on the float32 image (8 lanes a vector); what is stored is float32 anyway
    twelfth = _F32(1.0 / 12.0)
    mean32 = _F32(mean)
    inv_norm32 = _F32(inv_norm)
    for dy in range(-half, half + 1):
        r = y + dy
        k0 = (dy + half) * lanes
        if inner:   # the 4th-order stencil fits: no border logic
            ku = np.uint64(k0)
            o = np.uint64(r * width + x - half)
            for i in range(side):
                c = o + np.uint64(i)
                k = ku + np.uint64(i)
                fx[k] = ((flat[c - np.uint64(2)] - flat[c + np.uint64(2)])
                         + _F32(8.0) * (flat[c + np.uint64(1)] - flat[c - np.uint64(1)])) * twelfth
                fy[k] = ((flat[c - 2 * wu] - flat[c + 2 * wu])
                         + _F32(8.0) * (flat[c + wu] - flat[c - wu])) * twelfth
                fhat[k] = (flat[c] - mean32) * inv_norm32
        else:
            for i in range(side):
                c = x - half + i
                fx[k0 + i] = np.float32(diff4_x(reference, r, c))
                fy[k0 + i] = np.float32(diff4_y(reference, r, c))
                fhat[k0 + i] = np.float32((reference[r, c] - mean) * inv_norm)
        # Row moments from the stored float32 values, so H matches what the iteration sees.
        r0 = r1 = r2 = r3 = r4 = r5 = r6 = r7 = r8 = 0.0
        r9 = r10 = r11 = r12 = r13 = r14 = r15 = r16 = 0.0
        ku = np.uint64(k0)
        for i in range(side):
            k = ku + np.uint64(i)
            fh = np.float64(fhat[k])
            a = np.float64(fx[k])
            b = np.float64(fy[k])
            fdx = float(i - half)
            sum_f += fh
            xx = a * a
            xy = a * b
            yy = b * b
            r0 += xx
            r1 += xx * fdx
            r2 += xx * fdx * fdx
            r3 += xy
            r4 += xy * fdx
            r5 += xy * fdx * fdx
            r6 += yy
            r7 += yy * fdx
            r8 += yy * fdx * fdx
            r9 += a
            r10 += a * fdx
            r11 += b
            r12 += b * fdx
            r13 += a * fh
            r14 += a * fh * fdx
            r15 += b * fh
            r16 += b * fh * fdx
        row[0] = r0
        row[1] = r1
        row[2] = r2
        row[3] = r3
        row[4] = r4
        row[5] = r5
        row[6] = r6
        row[7] = r7
        row[8] = r8
        row[9] = r9
        row[10] = r10
        row[11] = r11
        row[12] = r12
        row[13] = r13
        row[14] = r14
        row[15] = r15
        row[16] = r16
        fdy = float(dy)
        fold_row(row, fdy, mom)     # moments (1, dx, dy, dx^2, dx dy, dy^2) of xx, xy, yy
        for vec in range(4):    # moments (1, dx, dy) of fx, fy, fx fhat, fy fhat
            s1 = row[9 + 2 * vec]
            o = 18 + 3 * vec
            mom[o] += s1
            mom[o + 1] += row[10 + 2 * vec]
            mom[o + 2] += s1 * fdy
    # parameter a = (component ga in (x, y), moment ma in (1, dx, dy))
    for pa in range(6):
        ga = pa // 3
        ma = pa % 3
        sum_j[pa] = mom[18 + 3 * ga + ma]
        sum_jf[pa] = mom[24 + 3 * ga + ma]
    gauss_newton_matrix(mom, hess)
    if projected:
        # H = sum J~ J~^T - (sum J fhat)(sum J fhat)^T with J~ = J - mean J (docs/guide/measure.md, IC-GN)
        subtract_normalisation(hess, sum_j, sum_jf, n)
    if not _invert_spd(hess, hinv, low, linv):
        return _FLAT_REFERENCE, np.nan, 0.0
    h0[0, 0] = hess[0, 0]
    h0[0, 1] = hess[0, 3]
    h0[1, 0] = hess[3, 0]
    h0[1, 1] = hess[3, 3]
    if not _invert_spd(h0, hinv0, low[:2, :2], linv[:2, :2]):
        return _FLAT_REFERENCE, np.nan, 0.0
    return _OK, norm, sum_f


@njit(cache=True, parallel=True, nogil=True)
def _prepare_batch(reference, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j, sum_jf, sum_f, status,
                   projected):
    npts = xs.shape[0]
    n_chunks = (npts + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        work = (np.empty((6, 6)), np.empty((2, 2)), np.empty((6, 6)), np.empty((6, 6)), np.empty(17),
                np.empty(30))
        for i in range(c * _CHUNK, min((c + 1) * _CHUNK, npts)):
            st, nm, sf = _prepare_one(reference, xs[i], ys[i], half, lanes, fhat[i], fx[i], fy[i],
                                      hinv[i], hinv0[i], sum_j[i], sum_jf[i], projected, work)
            status[i] = st
            norm[i] = nm
            sum_f[i] = sf


def prepare_reference(reference: np.ndarray, xs: npt.ArrayLike, ys: npt.ArrayLike, half: int, *,
                      hessian: str = "projected") -> IcgnReference:
    """Per-point reference data for IC-GN (once per session).

    Parameters
    ----------
    reference : ndarray, shape (H, W)
        Reference image (converted to float32).
    xs, ys : ndarray of int, shape (N,)
        Subset centres (pixel centres).
    half : int
        Subset half-width M (subset side 2M + 1).
    hessian : {"projected", "opencorr"}
        Step matrix of the iteration (docs/guide/measure.md, IC-GN): the default is the exact
        derivative of the update equation at a zero-residual solution;
        "opencorr" is OpenCorr's ``sum J J^T``. Both converge to the same point.

    Returns
    -------
    IcgnReference
        ``status`` is OUTSIDE_REFERENCE where the subset leaves the image and
        FLAT_REFERENCE where it has no texture or a singular Hessian.
    """
    reference = as_image(reference, "reference")
    xs = np.ascontiguousarray(xs, dtype=np.int64)
    ys = np.ascontiguousarray(ys, dtype=np.int64)
    if xs.shape != ys.shape or xs.ndim != 1:
        raise ValueError(f"xs and ys must be 1-D arrays of equal length, got {xs.shape} and {ys.shape}")
    half = int(half)
    if half < 1:
        raise ValueError(f"subset half-width must be >= 1, got {half}")
    if hessian not in ("projected", "opencorr"):
        raise ValueError(f"hessian must be 'projected' or 'opencorr', got {hessian!r}")
    npts = xs.shape[0]
    side = 2 * half + 1
    lanes = -(-side // float32_lanes()) * float32_lanes()
    n = side * lanes
    # one block: a new key frame's ~9 MB at 1,000 points, which numpy places on huge pages where it can (an
    # allocation of 4 MB or more): three separate ones took a page fault every 4 kB, ~3-4 ms a build
    fhat, fx, fy = np.zeros((3, npts, n), dtype=np.float32)
    norm = np.empty(npts)
    hinv = np.zeros((npts, 6, 6))
    hinv0 = np.zeros((npts, 2, 2))
    sum_j = np.zeros((npts, 6))
    sum_jf = np.zeros((npts, 6))
    sum_f = np.zeros(npts)
    status = np.empty(npts, dtype=np.int8)
    _prepare_batch(reference, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j, sum_jf, sum_f, status,
                   hessian == "projected")
    return IcgnReference(xs, ys, half, reference.shape, lanes, fhat, fx, fy, norm, hinv, hinv0,
                         sum_j, sum_jf, sum_f, status, hessian)


def prepare_target(deformed: np.ndarray, *, out: BSplineCoefficients | None = None,
                   degree: int = 3) -> BSplineCoefficients:
    """B-spline coefficients of a target frame (once per frame): ``dic.bspline.prefilter``, float32, of
    ``degree`` 3 (cubic), 5 (quintic) or 7 (septic); IC-GN samples the target with the spline they record.

    The grey levels are those of ``dic.validation.as_image`` (float32); 8- and 16-bit frames, whose
    values float32 holds exactly, are read as they are (no float32 copy of the frame is made).
    ``out``: the coefficients of an earlier frame of the same size, overwritten (``prefilter``).
    """
    image = checked_image(deformed, "deformed")
    if image.dtype not in _EXACT_IN_FLOAT32:
        image = as_image(image, "deformed")
    return prefilter(image, dtype=np.float32, out=out, degree=check_degree(degree))


# ---------------------------------------------------------------------------
# iteration kernels


@njit(cache=True, fastmath=FASTMATH)
def _sums_shift(g, fhat, fx, fy):
    """(sum g, g^2, fhat g, fx g, fy g) in float64 over a padded subset (pad entries are 0)."""
    sg = 0.0
    sgg = 0.0
    sfg = 0.0
    a0 = 0.0
    b0 = 0.0
    for k in range(g.shape[0]):
        gk = np.float64(g[k])
        sg += gk
        sgg += gk * gk
        sfg += np.float64(fhat[k]) * gk
        a0 += np.float64(fx[k]) * gk
        b0 += np.float64(fy[k]) * gk
    return sg, sgg, sfg, a0, b0


@njit(cache=True, fastmath=FASTMATH, inline="always")
def bspline_tap(flat, origin, stride, tx, ty):
    """Cubic B-spline value from the 4 x 4 coefficients starting at flat[origin] (rows ``stride`` apart)
    at fractional offsets (tx, ty) in [0, 1) (float32): the inner step of every IC-GN row sum, inlined
    into the lane loops so they stay whole vector passes."""
    s = _F32(1.0) - tx
    t2 = tx * tx
    t3 = t2 * tx
    wx0 = s * s * s * _F32(1.0 / 6.0)
    wx3 = t3 * _F32(1.0 / 6.0)
    wx1 = _F32(2.0 / 3.0) - t2 + _F32(0.5) * t3
    wx2 = _F32(1.0) - wx0 - wx1 - wx3
    s = _F32(1.0) - ty
    t2 = ty * ty
    t3 = t2 * ty
    wy0 = s * s * s * _F32(1.0 / 6.0)
    wy3 = t3 * _F32(1.0 / 6.0)
    wy1 = _F32(2.0 / 3.0) - t2 + _F32(0.5) * t3
    wy2 = _F32(1.0) - wy0 - wy1 - wy3
    one = np.uint64(1)
    o0 = origin
    o1 = o0 + stride
    o2 = o1 + stride
    o3 = o2 + stride
    c0 = wy0 * flat[o0] + wy1 * flat[o1] + wy2 * flat[o2] + wy3 * flat[o3]
    c1 = wy0 * flat[o0 + one] + wy1 * flat[o1 + one] + wy2 * flat[o2 + one] + wy3 * flat[o3 + one]
    two = np.uint64(2)
    c2 = wy0 * flat[o0 + two] + wy1 * flat[o1 + two] + wy2 * flat[o2 + two] + wy3 * flat[o3 + two]
    three = np.uint64(3)
    c3 = wy0 * flat[o0 + three] + wy1 * flat[o1 + three] + wy2 * flat[o2 + three] + wy3 * flat[o3 + three]
    return wx0 * c0 + wx1 * c1 + wx2 * c2 + wx3 * c3


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _quintic_weights(t):
    """The 6 quintic B-spline weights of the taps at -2 .. 3 for a fractional offset t in [0, 1) (float32)."""
    s = _F32(1.0) - t
    t2 = t * t
    s2 = s * s
    c = _F32(1.0 / 120.0)
    w0 = s2 * s2 * s * c
    w5 = t2 * t2 * t * c
    w1 = (_F32(26.0) + t * (_F32(-50.0) + t * (_F32(20.0) + t * (_F32(20.0) + t * (_F32(-20.0) + _F32(5.0) * t))))) * c
    w2 = (_F32(66.0) + t2 * (_F32(-60.0) + t2 * (_F32(30.0) - _F32(10.0) * t))) * c
    w3 = (_F32(26.0) + t * (_F32(50.0) + t * (_F32(20.0) + t * (_F32(-20.0) + t * (_F32(-20.0) + _F32(10.0) * t))))) * c
    return w0, w1, w2, w3, _F32(1.0) - w0 - w1 - w2 - w3 - w5, w5


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _column6(flat, o0, stride, wy):
    """One column of 6 coefficients from flat[o0] (rows ``stride`` apart, uint64 indices) weighted in y by ``wy``."""
    o1 = o0 + stride
    o2 = o1 + stride
    o3 = o2 + stride
    o4 = o3 + stride
    return (wy[0] * flat[o0] + wy[1] * flat[o1] + wy[2] * flat[o2] + wy[3] * flat[o3] + wy[4] * flat[o4]
            + wy[5] * flat[o4 + stride])


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _quintic_row(flat, o, stride, wx, wy):
    """sum_k wx[k] * (column k of 6 from flat[o + k], weighted by wy): 6 x 6 taps."""
    one = np.uint64(1)
    return (wx[0] * _column6(flat, o, stride, wy) + wx[1] * _column6(flat, o + one, stride, wy)
            + wx[2] * _column6(flat, o + np.uint64(2), stride, wy) + wx[3] * _column6(flat, o + np.uint64(3), stride, wy)
            + wx[4] * _column6(flat, o + np.uint64(4), stride, wy) + wx[5] * _column6(flat, o + np.uint64(5), stride, wy))


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _row_sums5(flat, base, stride, ax, sx, ay, sy, lanes, lane_dx, mask, fhat, fx, fy, koff, xstep):
    """``_row_sums`` (or, with ``xstep``, ``_row_sums_xstep``: 7 columns) of quintic coefficients.

    Lane l's 36 taps start at flat[base + l] (its tap origin 2 px left and up of floor(x'), floor(y')).
    ``xstep`` is the same for every lane: the branch on it is hoisted out of the loop, which stays one
    vector pass.
    """
    st = np.uint64(stride)
    ko = np.uint64(koff)
    one = np.uint64(1)
    sg = _F32(0.0)
    sgg = _F32(0.0)
    sfg = _F32(0.0)
    pa = _F32(0.0)
    pax = _F32(0.0)
    pb = _F32(0.0)
    pbx = _F32(0.0)
    for l in range(lanes):
        lu = np.uint64(l)
        d = lane_dx[lu]
        xo = ax + sx * d
        wy = _quintic_weights(ay + sy * d)
        o = base + lu
        if xstep:   # as ``_row_sums_xstep``: every lane reads the same 7 columns, weighs the first or last 6
            stepped = xo >= _F32(1.0)
            w0, w1, w2, w3, w4, w5 = _quintic_weights(xo - _F32(1.0) if stepped else xo)
            c0 = _column6(flat, o, st, wy)
            c1 = _column6(flat, o + one, st, wy)
            c2 = _column6(flat, o + np.uint64(2), st, wy)
            c3 = _column6(flat, o + np.uint64(3), st, wy)
            c4 = _column6(flat, o + np.uint64(4), st, wy)
            c5 = _column6(flat, o + np.uint64(5), st, wy)
            c6 = _column6(flat, o + np.uint64(6), st, wy)
            if stepped:
                g = (w0 * c1 + w1 * c2 + w2 * c3 + w3 * c4 + w4 * c5 + w5 * c6) * mask[lu]
            else:
                g = (w0 * c0 + w1 * c1 + w2 * c2 + w3 * c3 + w4 * c4 + w5 * c5) * mask[lu]
        else:
            g = _quintic_row(flat, o, st, _quintic_weights(xo), wy) * mask[lu]
        k = ko + lu
        sg += g
        sgg += g * g
        sfg += fhat[k] * g
        a = fx[k] * g
        b = fy[k] * g
        pa += a
        pax += a * d
        pb += b
        pbx += b * d
    return sg, sgg, sfg, pa, pax, pb, pbx


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _septic_weights(t):
    """The 8 septic B-spline weights of the taps at -3 .. 4 for a fractional offset t in [0, 1) (float32;
    the polynomials of ``dic.bspline.weights7``)."""
    s = _F32(1.0) - t
    s2 = s * s
    t2 = t * t
    c = _F32(1.0 / 5040.0)
    w0 = s2 * s2 * s2 * s * c
    w7 = t2 * t2 * t2 * t * c
    w1 = (_F32(120.0) + t * (_F32(-392.0) + t * (_F32(504.0) + t * (_F32(-280.0) + t2 * (
        _F32(84.0) + t * (_F32(-42.0) + _F32(7.0) * t)))))) * c
    w2 = (_F32(1191.0) + t * (_F32(-1715.0) + t * (_F32(315.0) + t * (_F32(665.0) + t * (
        _F32(-315.0) + t * (_F32(-105.0) + t * (_F32(105.0) - _F32(21.0) * t))))))) * c
    w4 = (_F32(1191.0) + t * (_F32(1715.0) + t * (_F32(315.0) + t * (_F32(-665.0) + t * (
        _F32(-315.0) + t * (_F32(105.0) + t * (_F32(105.0) - _F32(35.0) * t))))))) * c
    w5 = (_F32(120.0) + t * (_F32(392.0) + t * (_F32(504.0) + t * (_F32(280.0) + t2 * (
        _F32(-84.0) + t * (_F32(-42.0) + _F32(21.0) * t)))))) * c
    w6 = (_F32(1.0) + t * (_F32(7.0) + t * (_F32(21.0) + t * (_F32(35.0) + t * (
        _F32(35.0) + t * (_F32(21.0) + t * (_F32(7.0) - _F32(7.0) * t))))))) * c
    return w0, w1, w2, _F32(1.0) - w0 - w1 - w2 - w4 - w5 - w6 - w7, w4, w5, w6, w7


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _column8(flat, o0, stride, wy):
    """One column of 8 coefficients from flat[o0] (rows ``stride`` apart, uint64 indices) weighted in y by ``wy``."""
    o1 = o0 + stride
    o2 = o1 + stride
    o3 = o2 + stride
    o4 = o3 + stride
    o5 = o4 + stride
    o6 = o5 + stride
    return (wy[0] * flat[o0] + wy[1] * flat[o1] + wy[2] * flat[o2] + wy[3] * flat[o3] + wy[4] * flat[o4]
            + wy[5] * flat[o5] + wy[6] * flat[o6] + wy[7] * flat[o6 + stride])


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _row_sums7(flat, base, stride, ax, sx, ay, sy, lanes, lane_dx, mask, fhat, fx, fy, koff, xstep):
    """``_row_sums5`` of septic coefficients: lane l's 64 taps start at flat[base + l] (3 px left and up of
    floor(x'), floor(y')); with ``xstep`` every lane reads the same 9 columns and weighs the first or last 8."""
    st = np.uint64(stride)
    ko = np.uint64(koff)
    sg = _F32(0.0)
    sgg = _F32(0.0)
    sfg = _F32(0.0)
    pa = _F32(0.0)
    pax = _F32(0.0)
    pb = _F32(0.0)
    pbx = _F32(0.0)
    for l in range(lanes):
        lu = np.uint64(l)
        d = lane_dx[lu]
        xo = ax + sx * d
        wy = _septic_weights(ay + sy * d)
        o = base + lu
        if xstep:
            stepped = xo >= _F32(1.0)
            w0, w1, w2, w3, w4, w5, w6, w7 = _septic_weights(xo - _F32(1.0) if stepped else xo)
            c0 = _column8(flat, o, st, wy)
            c1 = _column8(flat, o + np.uint64(1), st, wy)
            c2 = _column8(flat, o + np.uint64(2), st, wy)
            c3 = _column8(flat, o + np.uint64(3), st, wy)
            c4 = _column8(flat, o + np.uint64(4), st, wy)
            c5 = _column8(flat, o + np.uint64(5), st, wy)
            c6 = _column8(flat, o + np.uint64(6), st, wy)
            c7 = _column8(flat, o + np.uint64(7), st, wy)
            c8 = _column8(flat, o + np.uint64(8), st, wy)
            if stepped:
                g = (w0 * c1 + w1 * c2 + w2 * c3 + w3 * c4 + w4 * c5 + w5 * c6 + w6 * c7 + w7 * c8) * mask[lu]
            else:
                g = (w0 * c0 + w1 * c1 + w2 * c2 + w3 * c3 + w4 * c4 + w5 * c5 + w6 * c6 + w7 * c7) * mask[lu]
        else:
            w0, w1, w2, w3, w4, w5, w6, w7 = _septic_weights(xo)
            g = (w0 * _column8(flat, o, st, wy) + w1 * _column8(flat, o + np.uint64(1), st, wy)
                 + w2 * _column8(flat, o + np.uint64(2), st, wy) + w3 * _column8(flat, o + np.uint64(3), st, wy)
                 + w4 * _column8(flat, o + np.uint64(4), st, wy) + w5 * _column8(flat, o + np.uint64(5), st, wy)
                 + w6 * _column8(flat, o + np.uint64(6), st, wy)
                 + w7 * _column8(flat, o + np.uint64(7), st, wy)) * mask[lu]
        k = ko + lu
        sg += g
        sgg += g * g
        sfg += fhat[k] * g
        a = fx[k] * g
        b = fy[k] * g
        pa += a
        pax += a * d
        pb += b
        pbx += b * d
    return sg, sgg, sfg, pa, pax, pb, pbx


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _row_sums(flat, base, stride, ax, sx, ay, sy, lanes, lane_dx, mask, fhat, fx, fy, koff):
    """Sample one subset row at an affine warp and return its 7 IC-GN sums (float32).

    Lane l sits at dx = lane_dx[l]; its 16 taps start at flat[base + l] (rows
    ``stride`` apart) and its fractional offsets are ax + sx dx, ay + sy dx. Its
    value is weighted by mask[l] (0: a lane past the subset, or outside the run
    being sampled). Returns sum g, g^2, fhat g, fx g, fx g dx, fy g, fy g dx.
    All lanes are whole vectors (``float32_lanes``): no scalar remainder.
    """
    st = np.uint64(stride)
    ko = np.uint64(koff)
    sg = _F32(0.0)
    sgg = _F32(0.0)
    sfg = _F32(0.0)
    pa = _F32(0.0)
    pax = _F32(0.0)
    pb = _F32(0.0)
    pbx = _F32(0.0)
    for l in range(lanes):
        lu = np.uint64(l)
        d = lane_dx[lu]
        tx = ax + sx * d
        ty = ay + sy * d
        g = bspline_tap(flat, base + lu, st, tx, ty) * mask[lu]
        k = ko + lu
        sg += g
        sgg += g * g
        sfg += fhat[k] * g
        a = fx[k] * g
        b = fy[k] * g
        pa += a
        pax += a * d
        pb += b
        pbx += b * d
    return sg, sgg, sfg, pa, pax, pb, pbx


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _row_sums_xstep(flat, base, stride, ax, sx, ay, sy, lanes, lane_dx, mask, fhat, fx, fy, koff):
    """``_row_sums`` for a row whose tap origin steps by one column part-way along it.

    Lane l's x offset from the row's left-most tap origin is ax + sx dx, in [0, 2): lanes past
    the step (offset >= 1) take their 4 x weights one column later, so every lane reads the same
    5 columns from flat[base + l] and the row stays one vector pass instead of a masked pass per
    run of equal origin (docs/guide/performance.md). The 5th weight of the lanes before the step
    is 0: the same B-spline value.
    """
    st = np.uint64(stride)
    ko = np.uint64(koff)
    one = np.uint64(1)
    two = np.uint64(2)
    three = np.uint64(3)
    four = np.uint64(4)
    sg = _F32(0.0)
    sgg = _F32(0.0)
    sfg = _F32(0.0)
    pa = _F32(0.0)
    pax = _F32(0.0)
    pb = _F32(0.0)
    pbx = _F32(0.0)
    for l in range(lanes):
        lu = np.uint64(l)
        d = lane_dx[lu]
        xo = ax + sx * d
        stepped = xo >= _F32(1.0)
        tx = xo - _F32(1.0) if stepped else xo
        ty = ay + sy * d
        s = _F32(1.0) - tx
        t2 = tx * tx
        t3 = t2 * tx
        w0 = s * s * s * _F32(1.0 / 6.0)
        w3 = t3 * _F32(1.0 / 6.0)
        w1 = _F32(2.0 / 3.0) - t2 + _F32(0.5) * t3
        w2 = _F32(1.0) - w0 - w1 - w3
        e0 = _F32(0.0) if stepped else w0
        e1 = w0 if stepped else w1
        e2 = w1 if stepped else w2
        e3 = w2 if stepped else w3
        e4 = w3 if stepped else _F32(0.0)
        s = _F32(1.0) - ty
        t2 = ty * ty
        t3 = t2 * ty
        wy0 = s * s * s * _F32(1.0 / 6.0)
        wy3 = t3 * _F32(1.0 / 6.0)
        wy1 = _F32(2.0 / 3.0) - t2 + _F32(0.5) * t3
        wy2 = _F32(1.0) - wy0 - wy1 - wy3
        o0 = base + lu
        o1 = o0 + st
        o2 = o1 + st
        o3 = o2 + st
        c0 = wy0 * flat[o0] + wy1 * flat[o1] + wy2 * flat[o2] + wy3 * flat[o3]
        c1 = wy0 * flat[o0 + one] + wy1 * flat[o1 + one] + wy2 * flat[o2 + one] + wy3 * flat[o3 + one]
        c2 = wy0 * flat[o0 + two] + wy1 * flat[o1 + two] + wy2 * flat[o2 + two] + wy3 * flat[o3 + two]
        c3 = wy0 * flat[o0 + three] + wy1 * flat[o1 + three] + wy2 * flat[o2 + three] + wy3 * flat[o3 + three]
        c4 = wy0 * flat[o0 + four] + wy1 * flat[o1 + four] + wy2 * flat[o2 + four] + wy3 * flat[o3 + four]
        g = (e0 * c0 + e1 * c1 + e2 * c2 + e3 * c3 + e4 * c4) * mask[lu]
        k = ko + lu
        sg += g
        sgg += g * g
        sfg += fhat[k] * g
        a = fx[k] * g
        b = fy[k] * g
        pa += a
        pax += a * d
        pb += b
        pbx += b * d
    return sg, sgg, sfg, pa, pax, pb, pbx


@njit(cache=True, fastmath=FASTMATH)
def _affine_sums(flat, origin, stride, x0, y0, half, u, ux, uy, v, vx, vy, fhat, fx, fy, lanes, lane_dx, lane_mask,
                 kx, ky, run_mask, degree, out):
    """out (9,) <- sums over the subset warped by p: g, g^2, fhat g, fx g, fx g dx, fx g dy, fy g, fy g dx, fy g dy.

    ``degree`` 3 (cubic: ``_row_sums``, ``_row_sums_xstep``), 5 (quintic: ``_row_sums5``) or 7 (septic:
    ``_row_sums7``); it is chosen per row, outside the lane loops, which stay whole vector passes.

    One row at a time. Along a row x' = bx + dx + ux dx and y' = by + vx dx, so
    the tap origin (floor(bx + ux dx) + dx, floor(by + vx dx)) advances by one
    pixel per lane until floor(bx + ux dx) or floor(by + vx dx) steps: a row is
    one run of consecutive memory (one vector pass), or two a column apart (one
    pass of ``_row_sums_xstep``), or, rarely, more (one masked pass each). Rows are summed in float32 (<= 3 terms per lane), the subset in float64.
    The caller guarantees every sample lies in the spline domain. Lanes that
    are computed and discarded (past the subset, or outside the run of a masked
    pass) read at most 2M + 10 columns beside a real tap (septic, 16 lanes: 2M + 24), which stays inside
    the coefficient buffer thanks to its SLACK rows and PAD (the subset side is <= the image
    width). ``flat`` is that buffer, padded coefficient [0, 0] at ``origin``.
    """
    side = 2 * half + 1
    sx = _F32(ux)
    sy = _F32(vx)
    quintic = degree == 5
    septic = degree == 7
    reach = 3 if septic else (2 if quintic else 1)     # taps left of / above floor(x'), floor(y')
    sg = 0.0
    sgg = 0.0
    sfg = 0.0
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    b0 = 0.0
    b1 = 0.0
    b2 = 0.0
    for j in range(side):
        dy = j - half
        bx = x0 + u + uy * dy
        by = y0 + v + (1.0 + vy) * dy
        kx0 = int(np.floor(bx - ux * half))
        kx1 = int(np.floor(bx + ux * half))
        ky0 = int(np.floor(by - vx * half))
        koff = j * lanes
        if ky0 == int(np.floor(by + vx * half)) and abs(kx1 - kx0) <= 1:
            # One vector pass: the tap origin is the same along the row, or steps once in x.
            steps = kx0 != kx1
            kx0 = min(kx0, kx1)
            base = np.uint64(origin + (ky0 + PAD - reach) * stride + kx0 + PAD - reach - half)
            if septic:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums7(
                    flat, base, stride, _F32(bx - kx0), sx, _F32(by - ky0), sy, lanes, lane_dx, lane_mask,
                    fhat, fx, fy, koff, steps)
            elif quintic:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums5(
                    flat, base, stride, _F32(bx - kx0), sx, _F32(by - ky0), sy, lanes, lane_dx, lane_mask,
                    fhat, fx, fy, koff, steps)
            elif steps:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums_xstep(
                    flat, base, stride, _F32(bx - kx0), sx, _F32(by - ky0), sy, lanes, lane_dx, lane_mask,
                    fhat, fx, fy, koff)
            else:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums(
                    flat, base, stride, _F32(bx - kx0), sx, _F32(by - ky0), sy, lanes, lane_dx, lane_mask,
                    fhat, fx, fy, koff)
            sg += rsg
            sgg += rsgg
            sfg += rsfg
            a0 += rpa
            a1 += rpax
            a2 += rpa * dy
            b0 += rpb
            b1 += rpbx
            b2 += rpb * dy
            continue
        # The tap origin steps inside this row: one masked pass per run of equal origin.
        for l in range(side):
            kx[l] = int(np.floor(bx + ux * (l - half)))
            ky[l] = int(np.floor(by + vx * (l - half)))
        for l in range(side, lanes):
            kx[l] = _NO_RUN  # matches no run: pad lanes contribute nothing
            ky[l] = _NO_RUN
        l = 0
        while l < side:
            kxa = kx[l]
            kya = ky[l]
            base = np.uint64(origin + (kya + PAD - reach) * stride + kxa + PAD - reach - half)
            for m in range(lanes):
                run_mask[m] = 1.0 if (kx[m] == kxa and ky[m] == kya) else 0.0
            if septic:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums7(
                    flat, base, stride, _F32(bx - kxa), sx, _F32(by - kya), sy, lanes, lane_dx, run_mask,
                    fhat, fx, fy, koff, False)
            elif quintic:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums5(
                    flat, base, stride, _F32(bx - kxa), sx, _F32(by - kya), sy, lanes, lane_dx, run_mask,
                    fhat, fx, fy, koff, False)
            else:
                rsg, rsgg, rsfg, rpa, rpax, rpb, rpbx = _row_sums(
                    flat, base, stride, _F32(bx - kxa), sx, _F32(by - kya), sy, lanes, lane_dx, run_mask,
                    fhat, fx, fy, koff)
            sg += rsg
            sgg += rsgg
            sfg += rsfg
            a0 += rpa
            a1 += rpax
            a2 += rpa * dy
            b0 += rpb
            b1 += rpbx
            b2 += rpb * dy
            while l < side and kx[l] == kxa and ky[l] == kya:
                l += 1
    out[0] = sg
    out[1] = sgg
    out[2] = sfg
    out[3] = a0
    out[4] = a1
    out[5] = a2
    out[6] = b0
    out[7] = b1
    out[8] = b2


@njit(cache=True)
def refine_point(flat, origin, stride, height, width, x0, y0, half, fhat, fx, fy, norm, hinv, hinv0, sum_j, sum_jf,
                 sum_f, p, order, max_iterations, tolerance, translation_iterations, translation_tolerance, scratch,
                 degree):
    """Refine p = [u, ux, uy, v, vx, vy] (6,) in place; return (status, zncc, iterations).

    ``degree``: of the target's B-spline coefficients (``BSplineCoefficients.degree``), 3, 5 or 7.

    The per-point kernel of ``refine_prepared``, for kernels that refine one point at a time
    (``dic.reliability_guided``); ``scratch`` from ``refine_point_scratch``, one per task.
    order 0: translation-only IC-GN to ``tolerance`` (gradients ignored, left 0).
    order 1: translation pre-stage (start without gradients only), then 1st-order IC-GN.
    """
    g, tmp, kx, ky, lane_dx, lane_mask, run_mask, sums = scratch
    side = 2 * half + 1
    lanes = lane_dx.shape[0]
    n = side * side
    u, ux, uy, v, vx, vy = p[0], p[1], p[2], p[3], p[4], p[5]
    iterations = 0
    zncc = np.nan
    if order == 0:
        steps = max_iterations
        step_tol = tolerance
        ux = uy = vx = vy = 0.0
    else:
        steps = translation_iterations if (ux == 0.0 and uy == 0.0 and vx == 0.0 and vy == 0.0) else 0
        step_tol = translation_tolerance
    # --- translation-only steps: the separable sampler, the (u, v) block of H ---
    tt2 = step_tol * step_tol
    shifted = False
    for _ in range(steps):
        if not warped_subset_inside(height, width, x0, y0, half, u, 0.0, 0.0, v, 0.0, 0.0):
            return _OUTSIDE_TARGET, zncc, iterations
        if degree == 7:
            sample_shift7(flat, origin, stride, x0 + u, y0 + v, half, tmp, g, lanes)
        elif degree == 5:
            sample_shift5(flat, origin, stride, x0 + u, y0 + v, half, tmp, g, lanes)
        else:
            sample_shift(flat, origin, stride, x0 + u, y0 + v, half, tmp, g, lanes)
        sg, sgg, sfg, a0, b0 = _sums_shift(g, fhat, fx, fy)
        mean = sg / n
        var = sgg - sg * mean
        if var <= _FLAT * n * (1.0 + mean * mean):
            return _FLAT_TARGET, zncc, iterations
        inv_dg = 1.0 / np.sqrt(var)
        zncc = (sfg - mean * sum_f) * inv_dg
        r0 = norm * ((a0 - mean * sum_j[0]) * inv_dg - sum_jf[0])
        r1 = norm * ((b0 - mean * sum_j[3]) * inv_dg - sum_jf[3])
        du = hinv0[0, 0] * r0 + hinv0[0, 1] * r1
        dv = hinv0[1, 0] * r0 + hinv0[1, 1] * r1
        u -= du
        v -= dv
        iterations += 1
        if not (np.isfinite(u) and np.isfinite(v)):
            return _NOT_CONVERGED, zncc, iterations
        if du * du + dv * dv < tt2:
            shifted = True
            break
    if order == 0:
        p[0] = u
        p[3] = v
        for m in (1, 2, 4, 5):
            p[m] = 0.0
        return (_OK if shifted else _NOT_CONVERGED), zncc, iterations
    # --- 1st-order IC-GN ---
    half2 = float(half * half)
    tol2 = tolerance * tolerance
    converged = False
    for _ in range(max_iterations):
        if not warped_subset_inside(height, width, x0, y0, half, u, ux, uy, v, vx, vy):
            return _OUTSIDE_TARGET, zncc, iterations
        _affine_sums(flat, origin, stride, x0, y0, half, u, ux, uy, v, vx, vy, fhat, fx, fy, lanes, lane_dx, lane_mask,
                     kx, ky, run_mask, degree, sums)
        mean = sums[0] / n
        var = sums[1] - sums[0] * mean
        if var <= _FLAT * n * (1.0 + mean * mean):
            return _FLAT_TARGET, zncc, iterations
        inv_dg = 1.0 / np.sqrt(var)
        zncc = (sums[2] - mean * sum_f) * inv_dg
        r0 = norm * ((sums[3] - mean * sum_j[0]) * inv_dg - sum_jf[0])
        r1 = norm * ((sums[4] - mean * sum_j[1]) * inv_dg - sum_jf[1])
        r2 = norm * ((sums[5] - mean * sum_j[2]) * inv_dg - sum_jf[2])
        r3 = norm * ((sums[6] - mean * sum_j[3]) * inv_dg - sum_jf[3])
        r4 = norm * ((sums[7] - mean * sum_j[4]) * inv_dg - sum_jf[4])
        r5 = norm * ((sums[8] - mean * sum_j[5]) * inv_dg - sum_jf[5])
        d0 = hinv[0, 0] * r0 + hinv[0, 1] * r1 + hinv[0, 2] * r2 + hinv[0, 3] * r3 + hinv[0, 4] * r4 + hinv[0, 5] * r5
        d1 = hinv[1, 0] * r0 + hinv[1, 1] * r1 + hinv[1, 2] * r2 + hinv[1, 3] * r3 + hinv[1, 4] * r4 + hinv[1, 5] * r5
        d2 = hinv[2, 0] * r0 + hinv[2, 1] * r1 + hinv[2, 2] * r2 + hinv[2, 3] * r3 + hinv[2, 4] * r4 + hinv[2, 5] * r5
        d3 = hinv[3, 0] * r0 + hinv[3, 1] * r1 + hinv[3, 2] * r2 + hinv[3, 3] * r3 + hinv[3, 4] * r4 + hinv[3, 5] * r5
        d4 = hinv[4, 0] * r0 + hinv[4, 1] * r1 + hinv[4, 2] * r2 + hinv[4, 3] * r3 + hinv[4, 4] * r4 + hinv[4, 5] * r5
        d5 = hinv[5, 0] * r0 + hinv[5, 1] * r1 + hinv[5, 2] * r2 + hinv[5, 3] * r3 + hinv[5, 4] * r4 + hinv[5, 5] * r5
        iterations += 1
        # W(p) <- W(p) W(dp)^-1
        det = (1.0 + d1) * (1.0 + d5) - d2 * d4
        i11 = (1.0 + d5) / det
        i12 = -d2 / det
        i21 = -d4 / det
        i22 = (1.0 + d1) / det
        it1 = -(i11 * d0 + i12 * d3)
        it2 = -(i21 * d0 + i22 * d3)
        m11 = 1.0 + ux
        m12 = uy
        m21 = vx
        m22 = 1.0 + vy
        u = u + m11 * it1 + m12 * it2
        v = v + m21 * it1 + m22 * it2
        ux = m11 * i11 + m12 * i21 - 1.0
        uy = m11 * i12 + m12 * i22
        vx = m21 * i11 + m22 * i21
        vy = m21 * i12 + m22 * i22 - 1.0
        if not (np.isfinite(u) and np.isfinite(v) and abs(ux) < _MAX_GRADIENT and abs(uy) < _MAX_GRADIENT
                and abs(vx) < _MAX_GRADIENT and abs(vy) < _MAX_GRADIENT):
            return _NOT_CONVERGED, zncc, iterations
        if d0 * d0 + d3 * d3 + half2 * (d1 * d1 + d2 * d2 + d4 * d4 + d5 * d5) < tol2:
            converged = True
            break
    p[0] = u
    p[1] = ux
    p[2] = uy
    p[3] = v
    p[4] = vx
    p[5] = vy
    if not converged:
        return _NOT_CONVERGED, zncc, iterations
    return _OK, zncc, iterations


@njit(cache=True)
def refine_point_scratch(half, lanes):
    """Per-task scratch arrays for ``refine_point``."""
    side = 2 * half + 1
    g = np.zeros(side * lanes, dtype=np.float32)
    tmp = np.zeros((side + 7) * lanes, dtype=np.float32)     # side + 3 rows for the cubic, + 5 quintic, + 7 septic
    kx = np.empty(lanes, dtype=np.int64)
    ky = np.empty(lanes, dtype=np.int64)
    lane_dx = np.empty(lanes, dtype=np.float32)
    lane_mask = np.zeros(lanes, dtype=np.float32)
    run_mask = np.zeros(lanes, dtype=np.float32)
    for l in range(lanes):
        lane_dx[l] = l - half
        if l < side:
            lane_mask[l] = 1.0
    sums = np.empty(9)
    return g, tmp, kx, ky, lane_dx, lane_mask, run_mask, sums


@njit(cache=True, parallel=True, nogil=True)
def _icgn_batch(flat, origin, stride, height, width, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j,
                sum_jf, sum_f, points, params, status, order, max_iterations, tolerance, translation_iterations,
                translation_tolerance, degree, out_zncc, out_iter):
    """Refine the prepared points ``points`` (M,) whose ``status`` is OK.

    Row j of params (M, 6) in/out, status (M,) in/out, order (M,) and the outputs
    is the prepared point ``points[j]``.
    """
    npts = points.shape[0]
    n_chunks = (npts + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        scratch = refine_point_scratch(half, lanes)
        for j in range(c * _CHUNK, min((c + 1) * _CHUNK, npts)):
            out_iter[j] = 0
            out_zncc[j] = np.nan
            if status[j] != _OK:
                continue
            ok = True
            for m in range(6):
                if not np.isfinite(params[j, m]):
                    ok = False
            if not ok:
                status[j] = _BAD_GUESS
                continue
            i = points[j]
            st, zn, it = refine_point(flat, origin, stride, height, width, xs[i], ys[i], half, fhat[i], fx[i], fy[i],
                                      norm[i], hinv[i], hinv0[i], sum_j[i], sum_jf[i], sum_f[i], params[j], order[j],
                                      max_iterations, tolerance, translation_iterations, translation_tolerance,
                                      scratch, degree)
            status[j] = st
            out_iter[j] = it
            if st == _OK:
                out_zncc[j] = zn


# ---------------------------------------------------------------------------
# public API


def refine_prepared(ref_prep: IcgnReference, target_coeffs: BSplineCoefficients, u0: npt.ArrayLike, v0: npt.ArrayLike,
                    ux0: PerPoint = None, uy0: PerPoint = None, vx0: PerPoint = None, vy0: PerPoint = None,
                    status: PerPoint = None, *, points: npt.ArrayLike | None = None, order: npt.ArrayLike = 1,
                    max_iterations: int = 50, tolerance: float = 0.001, translation_iterations: int = 4,
                    translation_tolerance: float = 0.02) -> SubpixelResult:
    """IC-GN from prepared reference data and target coefficients.

    Parameters
    ----------
    ref_prep : IcgnReference
        From ``prepare_reference``.
    target_coeffs : BSplineCoefficients
        From ``prepare_target`` (same image shape as the reference).
    u0, v0 : array_like, shape (N,)
        Start displacement (float; NaN marks a point as ``BAD_GUESS``).
    ux0, uy0, vx0, vy0 : array_like, shape (N,), optional
        Start displacement gradients (e.g. the previous frame's result); zero if omitted.
    status : ndarray of int8, shape (N,), optional
        Refine only where OK (combined with ``ref_prep.status``); other codes are copied through.
    points : ndarray of int, shape (N,), optional
        Which of the prepared points to refine (indices into ``ref_prep``'s points;
        default all of them, in order). The start arrays, ``status``, a per-point
        ``order`` and the result have one entry per index: the other prepared
        points are not touched.
    order : {1, 0} or ndarray of int, shape (N,)
        Shape function: 1 (default) affine, p = (u, ux, uy, v, vx, vy); 0 rigid
        shift (u, v), the translation steps alone iterated to ``tolerance``
        (start gradients ignored; ``ux..vy`` are then None). Per point: a 0/1
        array, ``ux..vy`` then NaN at the order-0 points.
    max_iterations : int
        Cap on the iterations of the chosen order. OpenCorr uses 10; with noise
        sigma = 2 on the paper's speckle that flags 0.35 % of points NOT_CONVERGED
        (23 of 6,561), 20 flags 3 and 50 none, while converged points come out
        bit-identical, so the default is 50: typical points stop after ~5
        iterations and only hard ones use more. Reaching it unconverged gives NOT_CONVERGED. Translation pre-stage steps of
        ``order=1`` are capped separately by ``translation_iterations``.
    tolerance : float
        Convergence threshold on the scaled increment norm (0.001).
    translation_iterations : int
        Cap on the translation pre-stage of ``order=1`` (module notes); 0 disables it.
    translation_tolerance : float
        The pre-stage stops once a step moves the shift by less than this, px.

    Returns
    -------
    SubpixelResult
        u, v, zncc, status, iterations (translation and 1st-order steps
        together), and ux, uy, vx, vy for ``order=1``; NaN where status is not
        OK. ``zncc`` is that of the last sampled subset (before the final,
        below-tolerance update), as in OpenCorr.

    Raises
    ------
    ValueError
        Coefficients not from ``prepare_target`` or of another image size,
        start arrays of the wrong length, bad options.
    """
    points = checked_points(ref_prep, target_coeffs, points, degrees=(3, 5, 7))
    npts = points.shape[0]
    orders, per_point = point_orders(order, npts, max_order=1)
    check_iterations(max_iterations, tolerance, translation_iterations, translation_tolerance)
    params = np.empty((npts, 6))
    for c, (name, start) in enumerate(zip(("u", "ux", "uy", "v", "vx", "vy"), (u0, ux0, uy0, v0, vx0, vy0))):
        params[:, c] = start_values(start, npts, f"{name}0", np.nan if name in ("u", "v") else 0.0)
    shift_only = np.flatnonzero(orders == 0)        # usually none: no fancy-index assignment then
    if shift_only.size:
        params[np.ix_(shift_only, _GRADIENT_COLUMNS)] = 0.0
    st = start_status(ref_prep.status[points], status, npts)
    out_zncc = np.empty(npts)
    out_iter = np.empty(npts, dtype=np.int64)
    height, width = ref_prep.shape
    _icgn_batch(target_coeffs.flat, target_coeffs.origin, target_coeffs.coefficients.shape[1], height, width,
                ref_prep.xs, ref_prep.ys, ref_prep.half, ref_prep.lanes, ref_prep.fhat, ref_prep.fx, ref_prep.fy,
                ref_prep.norm, ref_prep.hinv, ref_prep.hinv0, ref_prep.sum_j, ref_prep.sum_jf, ref_prep.sum_f,
                points, params, st, orders, int(max_iterations), float(tolerance), int(translation_iterations),
                float(translation_tolerance), target_coeffs.degree, out_zncc, out_iter)
    ok = st == Status.OK
    params[~ok] = np.nan
    grads = {}
    if per_point or order == 1:
        if shift_only.size:
            params[np.ix_(shift_only, _GRADIENT_COLUMNS)] = np.nan
        grads = dict(ux=params[:, 1].copy(), uy=params[:, 2].copy(), vx=params[:, 4].copy(), vy=params[:, 5].copy())
    return SubpixelResult(u=params[:, 0].copy(), v=params[:, 3].copy(), zncc=np.where(ok, out_zncc, np.nan),
                          status=st, iterations=out_iter, **grads)


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int,
           **options: Any) -> SubpixelResult:
    """IC-GN refinement of every point whose ``status`` is OK (the ``dic.measure`` contract).

    ``prepare_reference`` + ``prepare_target`` + ``refine_prepared``.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images of equal shape (converted to float32).
    xs, ys : ndarray of int64, shape (N,)
        Subset centres.
    u0, v0 : ndarray of float64, shape (N,)
        Start: an integer search result or a float guess; NaN gives ``BAD_GUESS``.
    status : ndarray of int8, shape (N,)
        Refine only where OK; other codes are copied through.
    half : int
        Subset half-width M.
    **options
        ``degree`` (of ``prepare_target``: 3, 5 or 7); ``hessian`` (of ``prepare_reference``); ``order``,
        ``max_iterations``, ``tolerance``, ``translation_iterations``, ``translation_tolerance`` and
        start gradients ``ux0, uy0, vx0, vy0`` (of ``refine_prepared``).

    Returns
    -------
    SubpixelResult

    Examples
    --------
    >>> from livedic.dic.speckle import SpecklePattern, render
    >>> pattern = SpecklePattern((96, 96), n_speckles=140, seed=1)
    >>> ref, dfm = render(pattern, bit_depth=None), render(pattern, (1.3, -0.6), bit_depth=None)
    >>> r = refine(ref, dfm, np.array([48]), np.array([48]), np.array([1.0]), np.array([-1.0]),
    ...            np.zeros(1, np.int8), 10)
    >>> round(float(r.u[0]), 3), round(float(r.v[0]), 3), int(r.status[0])
    (1.3, -0.6, 0)
    """
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    options = dict(options)
    hessian = options.pop("hessian", "projected")
    degree = options.pop("degree", 3)
    prep = prepare_reference(reference, xs, ys, half, hessian=hessian)
    coeffs = prepare_target(deformed, degree=degree)
    return refine_prepared(prep, coeffs, u0, v0, status=status, **options)
