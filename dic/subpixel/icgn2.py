"""Inverse-compositional Gauss-Newton (IC-GN) with the 2nd-order shape function (12 parameters).

Fits a displacement that bends inside the subset (a neck, a notch, a crack tip), where a
first-order subset settles on the best affine warp and is biased. The warp (Lu & Cary 2000)

    u(dx, dy) = u + ux dx + uy dy + 1/2 uxx dx^2 + uxy dx dy + 1/2 uyy dy^2

(the same for v), p = (u, ux, uy, uxx, uxy, uyy, v, vx, vy, vxx, vxy, vyy); the iteration is
OpenCorr's ``ICGN2D2`` (Gao et al. 2015): steepest-descent images and the 12 x 12 step matrix
from the reference only, the target sampled by bicubic B-spline at the quadratically warped
subset, the ZNSSD residual of ``dic.subpixel.icgn``, the update ``W(p) <- W(p) W(dp)^-1``
composed to second order, converged when the largest displacement change over the subset is
below 0.001 px. ``hessian`` ("projected" or "opencorr") as in ``dic.subpixel.icgn``: same
fixed point. A start without second-order terms is first refined by first-order IC-GN;
``iterations`` counts every step of both. ``order`` per point: 2 (default), 1 (exactly
``dic.subpixel.icgn``) or 0 (rigid shift, ``dic.quality``'s fallback). A point whose variance
inflation exceeds ``VIF2_MAX`` or whose 12 x 12 matrix is singular is refined to first order
(``Icgn2Reference.max_order`` 1, curvature NaN).

Model selection per point: the six fitted curvature terms are tested against their own noise, the
Wald statistic ``c^T [H^-1]_cc^-1 c / s^2`` (``s^2`` the residual variance); below
``curvature_threshold`` (default ``curvature_threshold_bic``, the Bayesian information criterion)
the curvature is not told from noise and the point reports its first-order IC-GN result (icgn's,
about half the noise), curvature NaN. The first-order stage then runs for every start (with a
threshold of 0, only for a start without curvature, as before).

Why, the noise cost, the first-order fallback, the speed and the references:
docs/guide/measure.md ("IC-GN2: the second-order shape function") and
docs/guide/performance.md ("Sub-pixel kernels").
"""

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from numba import njit, prange
from numpy import float32 as _F32

from livedic.dic.bspline import FASTMATH, BSplineCoefficients, INTERPOLATION_MARGIN, PAD
from livedic.dic.result import SubpixelResult
from livedic.dic.status import (BAD_GUESS as _BAD_GUESS, NOT_CONVERGED as _NOT_CONVERGED, OK as _OK,
                                OUTSIDE_TARGET as _OUTSIDE_TARGET, FLAT_TARGET as _FLAT_TARGET, Status)
from livedic.dic.correlation import FLAT_VARIANCE as _FLAT
from livedic.dic.subpixel.icgn import (IcgnReference, _invert_spd, bspline_tap,
                                       prepare_reference as _prepare_first, prepare_target, refine_point,
                                       refine_point_scratch)
from livedic.dic.subpixel.prepared import (PerPoint, check_iterations, checked_points, point_orders, start_status,
                                           start_values)
from livedic.dic.validation import as_image, check_same_shape

# Parameter order (OpenCorr's Deformation2D2).
PARAMETERS = ("u", "ux", "uy", "uxx", "uxy", "uyy", "v", "vx", "vy", "vxx", "vxy", "vyy")
SECOND_ORDER = ("uxx", "uxy", "uyy", "vxx", "vxy", "vyy")
# Where the first-order parameters (u, ux, uy, v, vx, vy) sit in p, and the second-order ones.
_FIRST_INDEX = np.array([0, 1, 2, 6, 7, 8], dtype=np.int64)
_SECOND_INDEX = np.array([3, 4, 5, 9, 10, 11], dtype=np.int64)
# Monomial of each parameter within a component: (1, dx, dy, dx^2/2, dx dy, dy^2/2) as
# coefficient * dx^a * dy^b.
_MONO_A = np.array([0, 1, 0, 2, 1, 0], dtype=np.int64)
_MONO_B = np.array([0, 0, 1, 0, 1, 2], dtype=np.int64)
_MONO_C = np.array([1.0, 1.0, 1.0, 0.5, 1.0, 0.5])
# |ux|.. beyond this, or a curvature term times M beyond it, is no longer a subset warp: declared diverged.
_MAX_GRADIENT = 1.0
# Variance inflation of u, v by the 10 parameters beyond the shift above which a point is refined to
# first order (how many points that is: docs/guide/measure.md, "IC-GN2").
VIF2_MAX = 20.0
# A point whose curvature terms' Wald statistic is below ``len(SECOND_ORDER) * ln(n)`` (n pixels in the subset: the
# Bayesian information criterion's penalty for the six added parameters) reports its first-order result (module
# notes; why this criterion, measured: docs/guide/measure.md, "IC-GN2").
_NO_RUN = -(1 << 62)  # tap origin of pad lanes in split rows
_CHUNK = 32           # points per parallel task


@dataclass
class Icgn2Reference:
    """Everything 2nd-order IC-GN needs from the reference image, computed once per session.

    first : IcgnReference        the first-order data (subsets, gradients, 6 x 6 and 2 x 2 step
                                 matrices): the first-order stage, the shift fallback and the
                                 texture gates (``dic.quality.texture``) use it as it is
    hinv2 : float64 (N, 12, 12)  inverse of the 12 x 12 step matrix, parameter order ``PARAMETERS``
    sum_j2 : float64 (N, 12)     sum_i J_i
    sum_jf2 : float64 (N, 12)    sum_i J_i fhat_i
    max_order : int8 (N,)        2, or 1 where the 12 x 12 matrix is singular (refined to first order)
    curvature_info : float64 (N, 6, 6)  ``[H^-1]_cc^-1``, the inverse of the curvature block (``SECOND_ORDER``) of
                                 ``hinv2``: the curvature terms' Wald statistic (0 where ``max_order`` < 2)
    curvature_threshold : float  the first-order result is reported where that statistic is below it (0: never)
    """
    first: IcgnReference
    hinv2: np.ndarray
    sum_j2: np.ndarray
    sum_jf2: np.ndarray
    max_order: np.ndarray
    curvature_info: np.ndarray
    curvature_threshold: float

    @property
    def xs(self) -> np.ndarray:
        return self.first.xs

    @property
    def ys(self) -> np.ndarray:
        return self.first.ys

    @property
    def half(self) -> int:
        return self.first.half

    @property
    def shape(self) -> tuple[int, int]:
        return self.first.shape

    @property
    def status(self) -> np.ndarray:
        return self.first.status


@dataclass
class Icgn2Result(SubpixelResult):
    """``SubpixelResult`` plus the second-order terms (NaN where not estimated: status not OK, order < 2)."""
    uxx: np.ndarray | None = None
    uxy: np.ndarray | None = None
    uyy: np.ndarray | None = None
    vxx: np.ndarray | None = None
    vxy: np.ndarray | None = None
    vyy: np.ndarray | None = None


# ---------------------------------------------------------------------------
# reference preparation


@njit(cache=True)
def _prepare2_one(half, lanes, fhat, fx, fy, projected, hinv2, sum_j2, sum_jf2, work):
    """Fill the 12-parameter step matrix inverse and sums of one point; False if the matrix is singular.

    The matrix entries are moments ``dx^a dy^b`` (a + b <= 4) of fx^2, fx fy, fy^2,
    accumulated per row in powers of dx and folded with the row's dy; the sums are
    moments (a + b <= 2) of fx, fy, fx fhat, fy fhat. Read from the stored float32
    values, as the first-order preparation does, so they match what the iteration sees.
    """
    hess, low, linv, mom, vec, rowm, rowv = work
    side = 2 * half + 1
    n = side * side
    for a in range(3):
        for e in range(5):
            for f in range(5):
                mom[a, e, f] = 0.0
    for a in range(4):
        for e in range(3):
            for f in range(3):
                vec[a, e, f] = 0.0
    for j in range(side):
        for a in range(3):
            for e in range(5):
                rowm[a, e] = 0.0
        for a in range(4):
            for e in range(3):
                rowv[a, e] = 0.0
        k0 = j * lanes
        for i in range(side):
            k = k0 + i
            gx = np.float64(fx[k])
            gy = np.float64(fy[k])
            fh = np.float64(fhat[k])
            d = float(i - half)
            xx = gx * gx
            xy = gx * gy
            yy = gy * gy
            w = 1.0
            for e in range(5):
                rowm[0, e] += xx * w
                rowm[1, e] += xy * w
                rowm[2, e] += yy * w
                if e < 3:
                    rowv[0, e] += gx * w
                    rowv[1, e] += gy * w
                    rowv[2, e] += gx * fh * w
                    rowv[3, e] += gy * fh * w
                w *= d
        dy = float(j - half)
        for e in range(5):
            w = 1.0
            for f in range(5 - e):
                for a in range(3):
                    mom[a, e, f] += rowm[a, e] * w
                if e + f <= 2:
                    for a in range(4):
                        vec[a, e, f] += rowv[a, e] * w
                w *= dy
    for i in range(12):
        gi = i // 6
        mi = i % 6
        ci = _MONO_C[mi]
        sum_j2[i] = ci * vec[gi, _MONO_A[mi], _MONO_B[mi]]
        sum_jf2[i] = ci * vec[2 + gi, _MONO_A[mi], _MONO_B[mi]]
        for jj in range(12):
            gj = jj // 6
            mj = jj % 6
            hess[i, jj] = ci * _MONO_C[mj] * mom[gi + gj, _MONO_A[mi] + _MONO_A[mj], _MONO_B[mi] + _MONO_B[mj]]
    if projected:
        # the two rank-one terms of the ZNSSD's normalisation (docs/guide/measure.md, IC-GN)
        for i in range(12):
            for jj in range(12):
                hess[i, jj] -= sum_j2[i] * sum_j2[jj] / n + sum_jf2[i] * sum_jf2[jj]
    return _invert_spd(hess, hinv2, low, linv)


@njit(cache=True, parallel=True, nogil=True)
def _prepare2_batch(half, lanes, fhat, fx, fy, status, projected, hinv2, sum_j2, sum_jf2, max_order):
    npts = fhat.shape[0]
    n_chunks = (npts + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        work = (np.empty((12, 12)), np.empty((12, 12)), np.empty((12, 12)), np.empty((3, 5, 5)),
                np.empty((4, 3, 3)), np.empty((3, 5)), np.empty((4, 3)))
        for i in range(c * _CHUNK, min((c + 1) * _CHUNK, npts)):
            max_order[i] = 1
            if status[i] != _OK:
                continue
            if _prepare2_one(half, lanes, fhat[i], fx[i], fy[i], projected, hinv2[i], sum_j2[i], sum_jf2[i], work):
                max_order[i] = 2


def curvature_threshold_bic(half: int) -> float:
    """The Bayesian information criterion's threshold on the curvature's Wald statistic: 6 ln n, n = (2 half + 1)^2."""
    return len(SECOND_ORDER) * math.log((2 * half + 1) ** 2)


def prepare_from(first: IcgnReference, *, vif_max: float = VIF2_MAX,
                 curvature_threshold: float | None = None) -> Icgn2Reference:
    """Extend first-order reference data (``dic.subpixel.icgn.prepare_reference``) to 12 parameters.

    Parameters
    ----------
    first : IcgnReference
    vif_max : float
        A point whose variance inflation of u or v by the 10 parameters beyond
        the shift, ``[H^-1]_uu / [H_uv^-1]_uu`` of the 12 x 12 matrix, exceeds
        this is refined to first order (``max_order`` 1; module notes).
    curvature_threshold : float or None
        A point whose six curvature terms' Wald statistic (their fitted values
        against their own noise, chi-square with 6 degrees of freedom where the
        field is first order) is below this reports its first-order result,
        curvature NaN (module notes); 0 never does (every point at order 2);
        None: ``curvature_threshold_bic`` (36.5 for a 21 px subset).

    Returns
    -------
    Icgn2Reference
        Holding ``first`` itself (not a copy).
    """
    if isinstance(vif_max, bool) or not isinstance(vif_max, (int, float, np.floating)) or not vif_max >= 1.0:
        raise ValueError(f"vif_max must be a number >= 1, got {vif_max!r}")
    if curvature_threshold is None:
        curvature_threshold = curvature_threshold_bic(first.half)
    if isinstance(curvature_threshold, bool) or not isinstance(curvature_threshold, (int, float, np.floating)) \
            or not 0.0 <= curvature_threshold < np.inf:
        raise ValueError(f"curvature_threshold must be a finite number >= 0, got {curvature_threshold!r}")
    if not isinstance(first, IcgnReference):
        raise ValueError("first must come from dic.subpixel.icgn.prepare_reference (an IcgnReference)")
    npts = first.xs.shape[0]
    hinv2 = np.zeros((npts, 12, 12))
    sum_j2 = np.zeros((npts, 12))
    sum_jf2 = np.zeros((npts, 12))
    max_order = np.ones(npts, dtype=np.int8)
    _prepare2_batch(first.half, first.lanes, first.fhat, first.fx, first.fy, first.status,
                    first.hessian == "projected", hinv2, sum_j2, sum_jf2, max_order)
    with np.errstate(divide="ignore", invalid="ignore"):
        vif = np.maximum(hinv2[:, 0, 0] / first.hinv0[:, 0, 0], hinv2[:, 6, 6] / first.hinv0[:, 1, 1])
    max_order[(max_order == 2) & ~(vif <= vif_max)] = 1
    return Icgn2Reference(first, hinv2, sum_j2, sum_jf2, max_order, _curvature_info(hinv2, max_order == 2),
                          float(curvature_threshold))


def _curvature_info(hinv2: np.ndarray, second: np.ndarray) -> np.ndarray:
    """``[H^-1]_cc^-1`` per point (N, 6, 6) where ``second``, else 0: the curvature terms' information matrix."""
    info = np.zeros((hinv2.shape[0], 6, 6))
    block = hinv2[np.ix_(np.flatnonzero(second), _SECOND_INDEX, _SECOND_INDEX)]
    info[second] = np.linalg.inv(block)
    return info


def prepare_reference(reference: np.ndarray, xs: npt.ArrayLike, ys: npt.ArrayLike, half: int, *,
                      hessian: str = "projected", vif_max: float = VIF2_MAX,
                      curvature_threshold: float | None = None) -> Icgn2Reference:
    """Per-point reference data for 2nd-order IC-GN (once per session).

    ``dic.subpixel.icgn.prepare_reference`` (same arguments, same ``status``)
    followed by ``prepare_from`` (``vif_max``, ``curvature_threshold``).

    Returns
    -------
    Icgn2Reference
    """
    return prepare_from(_prepare_first(reference, xs, ys, half, hessian=hessian), vif_max=vif_max,
                        curvature_threshold=curvature_threshold)


# ---------------------------------------------------------------------------
# iteration kernels


@njit(cache=True, inline="always")
def _quadratic_range(c, s, q, half):
    """(min, max) of c + s d + q d^2 over d in [-half, half]: the ends and, inside, the vertex."""
    h = float(half)
    lo_end = c - s * h + q * h * h
    hi_end = c + s * h + q * h * h
    lo = min(lo_end, hi_end)
    hi = max(lo_end, hi_end)
    if q != 0.0:
        dv = -s / (2.0 * q)
        if -h < dv < h:
            value = c + s * dv + q * dv * dv
            lo = min(lo, value)
            hi = max(hi, value)
    return lo, hi


@njit(cache=True, fastmath=FASTMATH, inline="always")
def _row_sums2(flat, base, stride, ax, sx, qx, ay, sy, qy, lanes, lane_dx, mask, fhat, fx, fy, koff):
    """Sample one subset row at a quadratic warp and return its 9 sums (float32).

    Lane l sits at dx = lane_dx[l]; its 16 taps start at flat[base + l] and its
    fractional offsets are ax + sx dx + qx dx^2, ay + sy dx + qy dx^2 (the
    affine sampler of ``dic.subpixel.icgn`` with a quadratic term). Returns
    sum g, g^2, fhat g, fx g, fx g dx, fx g dx^2, fy g, fy g dx, fy g dx^2.
    """
    st = np.uint64(stride)
    ko = np.uint64(koff)
    sg = _F32(0.0)
    sgg = _F32(0.0)
    sfg = _F32(0.0)
    pa = _F32(0.0)
    pax = _F32(0.0)
    paxx = _F32(0.0)
    pb = _F32(0.0)
    pbx = _F32(0.0)
    pbxx = _F32(0.0)
    for l in range(lanes):
        lu = np.uint64(l)
        d = lane_dx[lu]
        tx = ax + (sx + qx * d) * d
        ty = ay + (sy + qy * d) * d
        g = bspline_tap(flat, base + lu, st, tx, ty) * mask[lu]
        k = ko + lu
        sg += g
        sgg += g * g
        sfg += fhat[k] * g
        a = fx[k] * g
        b = fy[k] * g
        ad = a * d
        bd = b * d
        pa += a
        pax += ad
        paxx += ad * d
        pb += b
        pbx += bd
        pbxx += bd * d
    return sg, sgg, sfg, pa, pax, paxx, pb, pbx, pbxx


@njit(cache=True, fastmath=FASTMATH)
def _quadratic_sums(flat, origin, stride, height, width, x0, y0, half, p, fhat, fx, fy, lanes, lane_dx, lane_mask,
                    kx, ky, run_mask, out):
    """out (15,) <- sums over the subset warped by p (12,): g, g^2, fhat g, then sum J_k g for the 12 parameters.

    Returns False (``out`` undefined) where a sample would come closer than
    ``INTERPOLATION_MARGIN`` px to the image edge: each row's x' and y' ranges
    (ends and vertex of the row's parabola) are checked before it is sampled.
    Rows are one run of consecutive taps, or a few (docs/guide/performance.md, "Sub-pixel kernels").
    """
    side = 2 * half + 1
    lo_edge = float(INTERPOLATION_MARGIN)
    right = width - 1.0 - INTERPOLATION_MARGIN
    bottom = height - 1.0 - INTERPOLATION_MARGIN
    u, ux, uy, uxx, uxy, uyy = p[0], p[1], p[2], p[3], p[4], p[5]
    v, vx, vy, vxx, vxy, vyy = p[6], p[7], p[8], p[9], p[10], p[11]
    qx = 0.5 * uxx
    qy = 0.5 * vxx
    qx32 = _F32(qx)
    qy32 = _F32(qy)
    sg = 0.0
    sgg = 0.0
    sfg = 0.0
    a0 = a1 = a2 = a3 = a4 = a5 = 0.0
    b0 = b1 = b2 = b3 = b4 = b5 = 0.0
    for j in range(side):
        dy = float(j - half)
        # along the row: x'(d) - d = bx + sx d + qx d^2, y'(d) = by + sy d + qy d^2
        bx = x0 + u + uy * dy + 0.5 * uyy * dy * dy
        sx = ux + uxy * dy
        by = y0 + dy + v + vy * dy + 0.5 * vyy * dy * dy
        sy = vx + vxy * dy
        xlo, xhi = _quadratic_range(bx, 1.0 + sx, qx, half)
        ylo, yhi = _quadratic_range(by, sy, qy, half)
        if not (xlo >= lo_edge and ylo >= lo_edge and xhi <= right and yhi <= bottom):
            return False
        tlo, thi = _quadratic_range(bx, sx, qx, half)
        kx0 = int(np.floor(tlo))
        ky0 = int(np.floor(ylo))
        koff = j * lanes
        if kx0 == int(np.floor(thi)) and ky0 == int(np.floor(yhi)):
            base = np.uint64(origin + (ky0 + PAD - 1) * stride + kx0 + PAD - 1 - half)
            rsg, rsgg, rsfg, ra, rax, raxx, rb, rbx, rbxx = _row_sums2(
                flat, base, stride, _F32(bx - kx0), _F32(sx), qx32, _F32(by - ky0), _F32(sy), qy32, lanes, lane_dx,
                lane_mask, fhat, fx, fy, koff)
        else:
            # the tap origin steps inside this row: one masked pass per run of equal origin
            for l in range(side):
                d = float(l - half)
                kx[l] = int(np.floor(bx + (sx + qx * d) * d))
                ky[l] = int(np.floor(by + (sy + qy * d) * d))
            for l in range(side, lanes):
                kx[l] = _NO_RUN
                ky[l] = _NO_RUN
            rsg = rsgg = rsfg = ra = rax = raxx = rb = rbx = rbxx = _F32(0.0)
            done = 0
            # runs need not be contiguous on a parabola: take the first lane not yet summed each time
            for m in range(lanes):
                run_mask[m] = 0.0
            l = 0
            while done < side:
                while kx[l] == _NO_RUN:
                    l += 1
                kxa = kx[l]
                kya = ky[l]
                base = np.uint64(origin + (kya + PAD - 1) * stride + kxa + PAD - 1 - half)
                for m in range(lanes):
                    if kx[m] == kxa and ky[m] == kya:
                        run_mask[m] = 1.0
                        kx[m] = _NO_RUN
                        done += 1
                    else:
                        run_mask[m] = 0.0
                r = _row_sums2(flat, base, stride, _F32(bx - kxa), _F32(sx), qx32, _F32(by - kya), _F32(sy), qy32,
                               lanes, lane_dx, run_mask, fhat, fx, fy, koff)
                rsg += r[0]
                rsgg += r[1]
                rsfg += r[2]
                ra += r[3]
                rax += r[4]
                raxx += r[5]
                rb += r[6]
                rbx += r[7]
                rbxx += r[8]
        sg += rsg
        sgg += rsgg
        sfg += rsfg
        # J_k g for (1, dx, dy, dx^2/2, dx dy, dy^2/2) of fx, then of fy
        a0 += ra
        a1 += rax
        a2 += ra * dy
        a3 += 0.5 * raxx
        a4 += rax * dy
        a5 += 0.5 * ra * dy * dy
        b0 += rb
        b1 += rbx
        b2 += rb * dy
        b3 += 0.5 * rbxx
        b4 += rbx * dy
        b5 += 0.5 * rb * dy * dy
    out[0] = sg
    out[1] = sgg
    out[2] = sfg
    out[3] = a0
    out[4] = a1
    out[5] = a2
    out[6] = a3
    out[7] = a4
    out[8] = a5
    out[9] = b0
    out[10] = b1
    out[11] = b2
    out[12] = b3
    out[13] = b4
    out[14] = b5
    return True


@njit(cache=True)
def _warp_matrix(p, w):
    """The 6 x 6 warp matrix of p acting on (dx^2, dx dy, dy^2, dx, dy, 1) (OpenCorr Deformation2D2::setWarp)."""
    u, ux, uy, uxx, uxy, uyy = p[0], p[1], p[2], p[3], p[4], p[5]
    v, vx, vy, vxx, vxy, vyy = p[6], p[7], p[8], p[9], p[10], p[11]
    w[0, 0] = 1.0 + 2.0 * ux + ux * ux + u * uxx
    w[0, 1] = 2.0 * u * uxy + 2.0 * (1.0 + ux) * uy
    w[0, 2] = uy * uy + u * uyy
    w[0, 3] = 2.0 * u * (1.0 + ux)
    w[0, 4] = 2.0 * u * uy
    w[0, 5] = u * u
    w[1, 0] = 0.5 * (v * uxx + 2.0 * (1.0 + ux) * vx + u * vxx)
    w[1, 1] = 1.0 + uy * vx + ux * vy + v * uxy + u * vxy + vy + ux
    w[1, 2] = 0.5 * (v * uyy + 2.0 * uy * (1.0 + vy) + u * vyy)
    w[1, 3] = v + v * ux + u * vx
    w[1, 4] = u + v * uy + u * vy
    w[1, 5] = u * v
    w[2, 0] = vx * vx + v * vxx
    w[2, 1] = 2.0 * v * vxy + 2.0 * vx * (1.0 + vy)
    w[2, 2] = 1.0 + 2.0 * vy + vy * vy + v * vyy
    w[2, 3] = 2.0 * v * vx
    w[2, 4] = 2.0 * v * (1.0 + vy)
    w[2, 5] = v * v
    w[3, 0] = 0.5 * uxx
    w[3, 1] = uxy
    w[3, 2] = 0.5 * uyy
    w[3, 3] = 1.0 + ux
    w[3, 4] = uy
    w[3, 5] = u
    w[4, 0] = 0.5 * vxx
    w[4, 1] = vxy
    w[4, 2] = 0.5 * vyy
    w[4, 3] = vx
    w[4, 4] = 1.0 + vy
    w[4, 5] = v
    for c in range(5):
        w[5, c] = 0.0
    w[5, 5] = 1.0


@njit(cache=True)
def _invert6(a, out, work):
    """Inverse of the 6 x 6 ``a`` into ``out`` by Gauss-Jordan with partial pivoting; False if singular.

    ``work`` (6, 12) scratch.
    """
    n = 6
    for i in range(n):
        for j in range(n):
            work[i, j] = a[i, j]
            work[i, n + j] = 1.0 if i == j else 0.0
    for col in range(n):
        pivot = col
        best = abs(work[col, col])
        for r in range(col + 1, n):
            if abs(work[r, col]) > best:
                best = abs(work[r, col])
                pivot = r
        if not (best > 1e-12):
            return False
        if pivot != col:
            for j in range(2 * n):
                t = work[col, j]
                work[col, j] = work[pivot, j]
                work[pivot, j] = t
        inv_p = 1.0 / work[col, col]
        for j in range(2 * n):
            work[col, j] *= inv_p
        for r in range(n):
            if r != col:
                factor = work[r, col]
                if factor != 0.0:
                    for j in range(2 * n):
                        work[r, j] -= factor * work[col, j]
    for i in range(n):
        for j in range(n):
            out[i, j] = work[i, n + j]
    return True


@njit(cache=True)
def compose_inverse(p, dp, scratch):
    """p <- the parameters of W(p) W(dp)^-1 (the IC-GN update), in place; False if W(dp) is singular.

    Only rows 3 and 4 of the product are formed: they are the warp's parameters.
    ``scratch`` = (w (6, 6), wd (6, 6), wi (6, 6), work (6, 12)).
    """
    w, wd, wi, work = scratch
    _warp_matrix(p, w)
    _warp_matrix(dp, wd)
    if not _invert6(wd, wi, work):
        return False
    for half_row in range(2):
        row = 3 + half_row
        o = 6 * half_row
        m0 = m1 = m2 = m3 = m4 = m5 = 0.0
        for k in range(6):
            a = w[row, k]
            m0 += a * wi[k, 0]
            m1 += a * wi[k, 1]
            m2 += a * wi[k, 2]
            m3 += a * wi[k, 3]
            m4 += a * wi[k, 4]
            m5 += a * wi[k, 5]
        p[o] = m5
        p[o + 1] = m3
        p[o + 2] = m4
        p[o + 3] = 2.0 * m0
        p[o + 4] = m1
        p[o + 5] = 2.0 * m2
    p[1] -= 1.0      # row 3 holds 1 + ux
    p[8] -= 1.0      # row 4 holds 1 + vy
    return True


@njit(cache=True)
def refine_point_scratch2(half, lanes):
    """Per-task scratch arrays for ``refine_point2``."""
    return (refine_point_scratch(half, lanes), np.empty(6), np.empty(15), np.empty(12), np.empty(12),
            (np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 12))))


# The 2nd-order sampler (``_quadratic_sums``) is written for the cubic B-spline; other targets are refused.
_CUBIC = 3


@njit(cache=True)
def _curvature_statistic(p, zncc, norm, n, curvature_info):
    """Wald statistic of the six curvature terms of p: ``c^T [H^-1]_cc^-1 c / s^2`` (chi-square, 6 degrees).

    ``s^2`` is the residual variance in grey levels, ``|f - mean f|^2 2 (1 - zncc) / (n - 14)`` (12
    parameters and the ZNSSD's offset and scale); ``curvature_info`` is ``[H^-1]_cc^-1``
    (``Icgn2Reference.curvature_info``), so ``s^2 [H^-1]_cc`` is the curvature terms' covariance.
    """
    s2 = norm * norm * 2.0 * (1.0 - zncc) / (n - 14)
    q = 0.0
    for a in range(6):
        ca = p[_SECOND_INDEX[a]]
        for b in range(6):
            q += ca * curvature_info[a, b] * p[_SECOND_INDEX[b]]
    if not s2 > 0.0:
        return np.inf
    return q / s2


@njit(cache=True)
def refine_point2(flat, origin, stride, height, width, x0, y0, half, fhat, fx, fy, norm, hinv, hinv0, sum_j, sum_jf,
                  sum_f, hinv2, sum_j2, sum_jf2, p, order, max_iterations, tolerance, translation_iterations,
                  translation_tolerance, scratch2, curvature_info, curvature_threshold, degree):
    """Refine p (12,) in place (``PARAMETERS`` order); return (status, zncc, iterations). ``degree``: the
    target's B-spline (only 3 reaches here: ``refine_prepared`` refuses others), for the first-order steps.

    order 0: shift, order 1: affine (``dic.subpixel.icgn.refine_point`` on the
    first-order parameters, curvature left 0); order 2: the first-order stage
    runs (module notes: always where ``curvature_threshold`` > 0, else only for
    a start without curvature), then the 2nd-order iteration runs to
    ``tolerance``, from the first-order result where the start has no
    curvature. Where the curvature's Wald statistic (``_curvature_statistic``)
    is below ``curvature_threshold``, p holds the first-order result and NaN
    curvature (the first-order model selected).
    """
    scratch, p6, sums, r, dp, comp = scratch2
    g, tmp, kx, ky, lane_dx, lane_mask, run_mask, _ = scratch
    lanes = lane_dx.shape[0]
    side = 2 * half + 1
    n = side * side
    iterations = 0
    zncc = np.nan
    flat_start = True
    for m in range(6):
        if p[_SECOND_INDEX[m]] != 0.0:
            flat_start = False
    first_ok = False
    first_zncc = np.nan
    if order < 2 or flat_start or curvature_threshold > 0.0:
        for m in range(6):
            p6[m] = p[_FIRST_INDEX[m]]
        st, zncc, iterations = refine_point(flat, origin, stride, height, width, x0, y0, half, fhat, fx, fy, norm,
                                            hinv, hinv0, sum_j, sum_jf, sum_f, p6, min(order, 1), max_iterations,
                                            tolerance, translation_iterations, translation_tolerance, scratch,
                                            degree)
        first_ok = st == _OK
        first_zncc = zncc
        if order < 2 or flat_start:
            for m in range(6):
                p[_FIRST_INDEX[m]] = p6[m]
                p[_SECOND_INDEX[m]] = 0.0
            if order < 2 or st != _OK:
                return st, zncc, iterations
    half2 = float(half * half)
    half4 = half2 * half2
    tol2 = tolerance * tolerance
    for _ in range(max_iterations):
        if not _quadratic_sums(flat, origin, stride, height, width, x0, y0, half, p, fhat, fx, fy, lanes, lane_dx,
                               lane_mask, kx, ky, run_mask, sums):
            return _OUTSIDE_TARGET, zncc, iterations
        mean = sums[0] / n
        var = sums[1] - sums[0] * mean
        if var <= _FLAT * n * (1.0 + mean * mean):
            return _FLAT_TARGET, zncc, iterations
        inv_dg = 1.0 / np.sqrt(var)
        zncc = (sums[2] - mean * sum_f) * inv_dg
        for k in range(12):
            r[k] = norm * ((sums[3 + k] - mean * sum_j2[k]) * inv_dg - sum_jf2[k])
        for k in range(12):
            s = 0.0
            for m in range(12):
                s += hinv2[k, m] * r[m]
            dp[k] = s
        iterations += 1
        if not compose_inverse(p, dp, comp):
            return _NOT_CONVERGED, zncc, iterations
        finite = True
        for k in range(12):
            if not np.isfinite(p[k]):
                finite = False
        if not finite or abs(p[1]) >= _MAX_GRADIENT or abs(p[2]) >= _MAX_GRADIENT or abs(p[7]) >= _MAX_GRADIENT \
                or abs(p[8]) >= _MAX_GRADIENT:
            return _NOT_CONVERGED, zncc, iterations
        for m in range(6):
            if abs(p[_SECOND_INDEX[m]]) * half >= _MAX_GRADIENT:
                return _NOT_CONVERGED, zncc, iterations
        step = (dp[0] * dp[0] + dp[6] * dp[6]
                + half2 * (dp[1] * dp[1] + dp[2] * dp[2] + dp[7] * dp[7] + dp[8] * dp[8])
                + half4 * (0.25 * (dp[3] * dp[3] + dp[5] * dp[5] + dp[9] * dp[9] + dp[11] * dp[11])
                           + dp[4] * dp[4] + dp[10] * dp[10]))
        if step < tol2:
            if first_ok and _curvature_statistic(p, zncc, norm, n, curvature_info) < curvature_threshold:
                for m in range(6):      # the curvature is not told from noise: the first-order result, less noisy
                    p[_FIRST_INDEX[m]] = p6[m]
                    p[_SECOND_INDEX[m]] = np.nan
                return _OK, first_zncc, iterations
            return _OK, zncc, iterations
    return _NOT_CONVERGED, zncc, iterations


@njit(cache=True, parallel=True, nogil=True)
def _icgn2_batch(flat, origin, stride, height, width, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j,
                 sum_jf, sum_f, hinv2, sum_j2, sum_jf2, points, params, status, order, max_iterations, tolerance,
                 translation_iterations, translation_tolerance, out_zncc, out_iter, curvature_info, curvature_threshold,
                 degree):
    """Refine the prepared points ``points`` (M,) whose ``status`` is OK; row j of params (M, 12) in/out."""
    npts = points.shape[0]
    n_chunks = (npts + _CHUNK - 1) // _CHUNK
    for c in prange(n_chunks):
        scratch2 = refine_point_scratch2(half, lanes)
        for j in range(c * _CHUNK, min((c + 1) * _CHUNK, npts)):
            out_iter[j] = 0
            out_zncc[j] = np.nan
            if status[j] != _OK:
                continue
            ok = True
            for m in range(12):
                if not np.isfinite(params[j, m]):
                    ok = False
            if not ok:
                status[j] = _BAD_GUESS
                continue
            i = points[j]
            st, zn, it = refine_point2(flat, origin, stride, height, width, xs[i], ys[i], half, fhat[i], fx[i],
                                       fy[i], norm[i], hinv[i], hinv0[i], sum_j[i], sum_jf[i], sum_f[i], hinv2[i],
                                       sum_j2[i], sum_jf2[i], params[j], order[j], max_iterations, tolerance,
                                       translation_iterations, translation_tolerance, scratch2, curvature_info[i],
                                       curvature_threshold, degree)
            status[j] = st
            out_iter[j] = it
            if st == _OK:
                out_zncc[j] = zn


# ---------------------------------------------------------------------------
# public API


def refine_prepared(ref_prep: Icgn2Reference, target_coeffs: BSplineCoefficients, u0: npt.ArrayLike,
                    v0: npt.ArrayLike, ux0: PerPoint = None, uy0: PerPoint = None, vx0: PerPoint = None,
                    vy0: PerPoint = None, status: PerPoint = None, *, uxx0: PerPoint = None, uxy0: PerPoint = None,
                    uyy0: PerPoint = None, vxx0: PerPoint = None, vxy0: PerPoint = None, vyy0: PerPoint = None,
                    points: npt.ArrayLike | None = None, order: npt.ArrayLike = 2, max_iterations: int = 50,
                    tolerance: float = 0.001, translation_iterations: int = 4, translation_tolerance: float = 0.02
                    ) -> Icgn2Result:
    """2nd-order IC-GN from prepared reference data and target coefficients.

    Parameters
    ----------
    ref_prep : Icgn2Reference
        From ``prepare_reference`` or ``prepare_from``.
    target_coeffs : BSplineCoefficients
        From ``prepare_target`` (same image shape as the reference).
    u0, v0 : array_like, shape (N,)
        Start displacement (NaN marks a point as ``BAD_GUESS``).
    ux0, uy0, vx0, vy0 : array_like, shape (N,), optional
        Start displacement gradients; zero if omitted.
    status : ndarray of int8, shape (N,), optional
        Refine only where OK (combined with the reference's status); other codes are copied through.
    uxx0, uxy0, uyy0, vxx0, vxy0, vyy0 : array_like, shape (N,), optional
        Start second-order terms; zero if omitted. A point whose six are all
        zero is refined to first order first (module notes).
    points : ndarray of int, shape (N,), optional
        Which prepared points to refine (default all, in order); as in
        ``dic.subpixel.icgn.refine_prepared``.
    order : {2, 1, 0} or ndarray of int, shape (N,)
        Shape function: 2 (default) quadratic, 1 affine, 0 rigid shift; per
        point as an array. Points whose 12 x 12 matrix is singular
        (``ref_prep.max_order``) get at most 1.
    max_iterations : int
        Cap on the iterations of each stage (first-order, then 2nd-order); 50 as ``dic.subpixel.icgn``.
    tolerance : float
        Convergence threshold on the largest displacement change over the subset, px (0.001).
    translation_iterations, translation_tolerance
        The first-order stage's translation pre-stage (``dic.subpixel.icgn``).

    Returns
    -------
    Icgn2Result
        u, v, zncc, status, iterations (all stages), ux, uy, vx, vy (NaN at
        order-0 points) and uxx, uxy, uyy, vxx, vxy, vyy (NaN at points refined
        below order 2); everything NaN where status is not OK.

    Raises
    ------
    ValueError
        Coefficients not from ``prepare_target`` or of another image size,
        start arrays of the wrong length, bad options.
    """
    if not isinstance(ref_prep, Icgn2Reference):
        raise ValueError("ref_prep must come from dic.subpixel.icgn2.prepare_reference (an Icgn2Reference)")
    first = ref_prep.first
    points = checked_points(first, target_coeffs, points, degrees=(_CUBIC,))
    npts = points.shape[0]
    orders, _ = point_orders(order, npts, max_order=2)
    orders = np.minimum(orders, ref_prep.max_order[points])
    check_iterations(max_iterations, tolerance, translation_iterations, translation_tolerance)
    starts = (u0, ux0, uy0, uxx0, uxy0, uyy0, v0, vx0, vy0, vxx0, vxy0, vyy0)      # in PARAMETERS' order
    params = np.empty((npts, 12))
    for c, (name, start) in enumerate(zip(PARAMETERS, starts)):
        params[:, c] = start_values(start, npts, f"{name}0", np.nan if name in ("u", "v") else 0.0)
    params[np.ix_(orders == 0, [1, 2, 7, 8])] = 0.0
    params[np.ix_(orders < 2, _SECOND_INDEX)] = 0.0
    st = start_status(first.status[points], status, npts)
    out_zncc = np.empty(npts)
    out_iter = np.empty(npts, dtype=np.int64)
    # (mypy reads numba's Dispatcher.__call__ stub, which takes fewer arguments than this kernel's)
    _icgn2_batch(target_coeffs.flat, target_coeffs.origin, target_coeffs.coefficients.shape[1], *first.shape,  # type: ignore[call-arg]
                 first.xs, first.ys, first.half, first.lanes, first.fhat, first.fx, first.fy, first.norm, first.hinv,
                 first.hinv0, first.sum_j, first.sum_jf, first.sum_f, ref_prep.hinv2, ref_prep.sum_j2,
                 ref_prep.sum_jf2, points, params, st, orders, int(max_iterations), float(tolerance),
                 int(translation_iterations), float(translation_tolerance), out_zncc, out_iter,
                 ref_prep.curvature_info, ref_prep.curvature_threshold, target_coeffs.degree)
    ok = st == Status.OK
    params[~ok] = np.nan
    params[np.ix_(orders == 0, [1, 2, 7, 8])] = np.nan
    params[np.ix_(orders < 2, _SECOND_INDEX)] = np.nan
    values = {name: params[:, c].copy() for c, name in enumerate(PARAMETERS)}
    return Icgn2Result(zncc=np.where(ok, out_zncc, np.nan), status=st, iterations=out_iter, **values)


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int,
           **options: Any) -> Icgn2Result:
    """2nd-order IC-GN refinement of every point whose ``status`` is OK (the ``dic.measure`` contract).

    ``prepare_reference`` + ``prepare_target`` + ``refine_prepared``.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images of equal shape.
    xs, ys : ndarray of int64, shape (N,)
        Subset centres.
    u0, v0 : ndarray of float64, shape (N,)
        Start: an integer search result or a float guess; NaN gives ``BAD_GUESS``.
    status : ndarray of int8, shape (N,)
        Refine only where OK; other codes are copied through.
    half : int
        Subset half-width M.
    **options
        ``hessian``, ``vif_max``, ``curvature_threshold`` (of ``prepare_reference``); ``order``, ``max_iterations``,
        ``tolerance``, ``translation_iterations``, ``translation_tolerance`` and
        start values ``ux0 ... vyy0`` (of ``refine_prepared``).

    Returns
    -------
    Icgn2Result

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
    vif_max = options.pop("vif_max", VIF2_MAX)
    threshold = options.pop("curvature_threshold", None)
    prep = prepare_reference(reference, xs, ys, half, hessian=hessian, vif_max=vif_max, curvature_threshold=threshold)
    return refine_prepared(prep, prepare_target(deformed), u0, v0, status=status, **options)


__all__ = ["Icgn2Reference", "Icgn2Result", "PARAMETERS", "SECOND_ORDER", "VIF2_MAX", "curvature_threshold_bic", "prepare_reference",
           "prepare_from", "prepare_target", "refine_prepared", "refine", "refine_point2", "refine_point_scratch2",
           "compose_inverse"]
