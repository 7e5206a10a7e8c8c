"""Improved surface fit: the paper's sub-pixel method (interpolated lattice + improved WSO + 3x3 fit).

LI Jun, LEI Zongyu et al., Laser Technology 49(3):368 (2025),
DOI 10.7510/jgjs.issn.1001-3806.2025.03.008, section 2.6 and Fig. 6/7.

Per point, starting from the integer peak (u0, v0):

1. **Lattice.** Nodes ``(u0 + h i, v0 + h j)``, h = ``spacing`` (0.2 px), ``i, j`` in
   ``-m..m`` with ``m = max(1, round(extent / h))``; the target subset at a node is
   interpolated from the deformed image intensities (Keys bicubic, ``dic.subpixel.lattice``).
2. **Search.** The improved WSO (``dic.search.improved_wso``) searches the node indices.
3. **Polish.** An 8-neighbour hill climb moves to a local maximum, past the lattice border
   if needed (up to ``m`` further nodes), so the fit is never extrapolated.
4. **Fit.** ``fit_peak_3x3`` on the 3x3 ZNCC values around that node at spacing h.

Status: OK; OUTSIDE_TARGET when a node needed (or the start node) would interpolate outside
the deformed image; FLAT_TARGET when the best node has no texture; NOT_CONVERGED when the
climb ends on the extended border (the integer start was wrong) or the fitted quadratic has
no maximum within one node. Input codes other than OK are copied through; u, v NaN where not
OK. ``zncc`` is the fitted quadratic's peak value (within ~1e-4 of the exact ZNCC). Margin:
``2 ceil(extent) + 1`` px beyond the subset at most; dic.measure reserves 3.

Settings chosen, the spacing study and the accuracy and speed measured: docs/guide/measure.md
("The improved surface fit: settings and measurements").
"""

from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic._random import new_state
from livedic.dic.correlation import prepare_reference_subset, round_half_up, subset_inside
from livedic.dic.method_options import is_int_at_least, is_real_in, resolve_options, seed_to_uint
from livedic.dic.result import SubpixelResult
from livedic.dic.search.improved_wso import DEFAULTS as _IWSO, fitness_sd, iwso_init, iwso_move, iwso_tell
from livedic.dic.status import (BAD_GUESS, FLAT_REFERENCE, FLAT_TARGET, NOT_CONVERGED, OK, OUTSIDE_REFERENCE,
                                OUTSIDE_TARGET)
from livedic.dic.subpixel.lattice import build_plane, lattice_tables, node_zncc, valid_range
from livedic.dic.subpixel.peak_fit import fit_peak_3x3

DEFAULTS = {"spacing": 0.2, "extent": 1.0, "population": 4, "iterations": 10, "sd_tol": _IWSO["sd_tol"]}
CHECKS = {
    "spacing": (is_real_in(0.05, 4.0), "a lattice spacing in [0.05, 4] px"),
    "extent": (is_real_in(0.0, 4.0, low_open=True), "a lattice half-extent in (0, 4] px"),
    "population": (is_int_at_least(1), "an integer >= 1"),
    "iterations": (is_int_at_least(0), "an integer >= 0"),
    "sd_tol": (is_real_in(0.0, 1.0), "a number in [0, 1]"),
}

_MU = _IWSO["mu"]
_P_MIN = _IWSO["p_min"]
_P_MAX = _IWSO["p_max"]
_A1 = _IWSO["a1"]
_A2 = _IWSO["a2"]
_TENT_A = _IWSO["tent_a"]
_BOUNDARY = 2   # same boundary rule as the integer search default ("random")
_CHUNK = 64     # points per workspace allocation in the batch kernel


@njit(cache=True)
def _node(fhat2, target, planes, ready, ix, ph, wts, org_x, org_y, offset, ixmin, iymin, side,
          i, j, L, cache, counts):
    """Cached ZNCC at lattice node (i, j) (indices -L..L); counts[0] distinct, counts[1] calls."""
    counts[1] += 1
    ki = i + L
    kj = j + L
    c = cache[kj, ki]
    if np.isnan(c):
        p = ph[ki]
        if not ready[p]:
            build_plane(target, planes, p, wts, org_x, org_y, offset)
            ready[p] = True
        c = node_zncc(fhat2, planes, p, ix[ki] - ixmin, ix[kj] - iymin, wts[ph[kj]], side)
        cache[kj, ki] = c
        counts[0] += 1
    return c


@njit(cache=True)
def _refine_one(reference, target, x, y, u0, v0, half, spacing, m, L, ix, ph, lr, rr, wts, n_pop, n_iter,
                sd_tol, rng, fhat, fhat2, planes, ready, cache, counts, out):
    """One point; out = (u, v, zncc); returns a status code."""
    height, width = target.shape
    side = 2 * half + 1
    if not subset_inside(height, width, x, y, half):
        return OUTSIDE_REFERENCE
    if prepare_reference_subset(reference, x, y, half, fhat) == 0.0:
        return FLAT_REFERENCE
    for r in range(side):
        for c in range(side):
            fhat2[r, c] = np.float32(fhat[r * side + c])
    cx = x + u0
    cy = y + v0
    ilo, ihi = valid_range(width, cx, half, lr, rr, 0, 2 * L, L)
    jlo, jhi = valid_range(height, cy, half, lr, rr, 0, 2 * L, L)
    if ilo > ihi or jlo > jhi:
        return OUTSIDE_TARGET
    ilo -= L
    ihi -= L
    jlo -= L
    jhi -= L
    # plane origin: first column/row any node can read (tap -1 included for rows)
    ixmin = ix[0]
    iymin = ix[0]
    org_x = cx - half + ixmin
    org_y = cy - half + iymin - 1
    # per-point offset: the integer target subset's centre pixel, keeps float32 sums well conditioned
    offset = target[cy, cx]
    ready[:] = False
    cache[:, :] = np.nan
    counts[:] = 0

    # improved WSO over the node indices inside [-m, m]
    lo = np.array((max(ilo, -m), max(jlo, -m)), dtype=np.float64)
    hi = np.array((min(ihi, m), min(jhi, m)), dtype=np.float64)
    pos = np.empty((n_pop, 2))
    vel = np.empty((n_pop, 2))
    pbest = np.empty((n_pop, 2))
    pfit = np.empty(n_pop)
    fit = np.empty(n_pop)
    iwso_init(pos, vel, lo, hi, rng, _TENT_A)
    g = 0
    for s in range(n_pop):
        fit[s] = _node(fhat2, target, planes, ready, ix, ph, wts, org_x, org_y, offset, ixmin, iymin, side,
                       round_half_up(pos[s, 0]), round_half_up(pos[s, 1]), L, cache, counts)
        pfit[s] = fit[s]
        pbest[s, 0] = pos[s, 0]
        pbest[s, 1] = pos[s, 1]
        if fit[s] > fit[g]:
            g = s
    for k in range(1, n_iter + 1):
        iwso_move(pos, vel, pbest, g, k, n_iter, lo, hi, _MU, _P_MIN, _P_MAX, _A1, _A2, _BOUNDARY, rng)
        for s in range(n_pop):
            fit[s] = _node(fhat2, target, planes, ready, ix, ph, wts, org_x, org_y, offset, ixmin, iymin, side,
                           round_half_up(pos[s, 0]), round_half_up(pos[s, 1]), L, cache, counts)
        g = iwso_tell(pos, fit, pbest, pfit, g)
        if fitness_sd(fit) < sd_tol:
            break

    # hill climb over the extended lattice [ilo, ihi] x [jlo, jhi] (within -L..L)
    ci = round_half_up(pbest[g, 0])
    cj = round_half_up(pbest[g, 1])
    best = _node(fhat2, target, planes, ready, ix, ph, wts, org_x, org_y, offset, ixmin, iymin, side,
                 ci, cj, L, cache, counts)
    for _ in range((2 * L + 1) * (2 * L + 1)):
        bi = ci
        bj = cj
        bc = best
        for dj in range(-1, 2):
            nj = cj + dj
            if nj < jlo or nj > jhi:
                continue
            for di in range(-1, 2):
                ni = ci + di
                if (di == 0 and dj == 0) or ni < ilo or ni > ihi:
                    continue
                c = _node(fhat2, target, planes, ready, ix, ph, wts, org_x, org_y, offset, ixmin, iymin, side,
                          ni, nj, L, cache, counts)
                if c > bc:
                    bi = ni
                    bj = nj
                    bc = c
        if bi == ci and bj == cj:
            break
        ci = bi
        cj = bj
        best = bc
    # the 3x3 around the peak node must exist
    if ci - 1 < ilo or ci + 1 > ihi or cj - 1 < jlo or cj + 1 > jhi:
        if ci - 1 < -L or ci + 1 > L or cj - 1 < -L or cj + 1 > L:
            return NOT_CONVERGED
        return OUTSIDE_TARGET
    c3 = np.empty((3, 3))
    for dj in range(-1, 2):
        for di in range(-1, 2):
            c3[dj + 1, di + 1] = cache[cj + dj + L, ci + di + L]
    if best == -1.0:
        return FLAT_TARGET
    dx, dy, peak, ok = fit_peak_3x3(c3)
    if not ok:
        return NOT_CONVERGED
    out[0] = u0 + spacing * (ci + dx)
    out[1] = v0 + spacing * (cj + dy)
    out[2] = min(peak, 1.0)
    return OK


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, u0s, v0s, half, spacing, m, L, ix, ph, lr, rr, wts, n_pop, n_iter, sd_tol,
           seed, status, out_u, out_v, out_c, out_evals):
    """Refine every point with status OK; arrays (N,), status updated in place.

    Points are processed in fixed chunks of ``_CHUNK`` so each chunk allocates its
    workspace once; every point still draws from its own random stream, so the
    result does not depend on the thread count.
    """
    side = 2 * half + 1
    n_phase = wts.shape[0]
    rows = side + (ix[-1] - ix[0]) + 3
    cols = side + (ix[-1] - ix[0])
    n = xs.shape[0]
    n_chunks = (n + _CHUNK - 1) // _CHUNK
    for chunk in prange(n_chunks):
        fhat = np.empty(side * side)
        fhat2 = np.empty((side, side), dtype=np.float32)
        planes = np.empty((n_phase, rows, cols), dtype=np.float32)
        ready = np.zeros(n_phase, dtype=np.bool_)
        cache = np.empty((2 * L + 1, 2 * L + 1))
        counts = np.zeros(2, dtype=np.int64)
        out = np.empty(3)
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            if status[i] != OK:
                continue
            rng = new_state(seed, i)
            st = _refine_one(reference, target, xs[i], ys[i], u0s[i], v0s[i], half, spacing, m, L, ix, ph, lr, rr,
                             wts, n_pop, n_iter, sd_tol, rng, fhat, fhat2, planes, ready, cache, counts, out)
            out_evals[i] = counts[0]
            status[i] = st
            if st == OK:
                out_u[i] = out[0]
                out_v[i] = out[1]
                out_c[i] = out[2]


def lattice_half_nodes(spacing: float, extent: float) -> int:
    """Nodes each side of the centre for a lattice of ``spacing`` reaching +-``extent`` px."""
    return max(1, int(round(extent / spacing)))


def refine(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
           v0: np.ndarray, status: np.ndarray, half: int, *, seed: int = 0,
           **options: Any) -> SubpixelResult:
    """Sub-pixel displacement by the paper's improved surface fit.

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
        Seed of the lattice WSO (results are reproducible and thread-count independent).
    **options
        ``spacing`` (0.2 px), ``extent`` (1.0 px), ``population`` (8), ``iterations`` (10),
        ``sd_tol`` (0.001).

    Returns
    -------
    SubpixelResult
        u, v (NaN where not OK), zncc (the fitted quadratic's peak value), status.

    Raises
    ------
    ValueError
        Unknown option or bad option value.
    """
    return refine_with_counts(reference, deformed, xs, ys, u0, v0, status, half, seed=seed, **options)[0]


def refine_with_counts(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, u0: np.ndarray,
                       v0: np.ndarray, status: np.ndarray, half: int, *,
                       seed: int = 0, **options: Any) -> tuple[SubpixelResult, np.ndarray]:
    """``refine`` plus the number of distinct lattice nodes evaluated per point (int64 (N,))."""
    params = resolve_options("improved-surface-fit", options, DEFAULTS, CHECKS)
    stream_seed = seed_to_uint(seed)
    spacing = float(params["spacing"])
    m = lattice_half_nodes(spacing, float(params["extent"]))
    L = 2 * m
    ix, ph, lr, rr, wts = lattice_tables(spacing, L)
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
    evals = np.zeros(n, dtype=np.int64)
    if n:
        _batch(reference, deformed, np.ascontiguousarray(xs, dtype=np.int64),
               np.ascontiguousarray(ys, dtype=np.int64), u0i, v0i, int(half), spacing, m, L, ix, ph, lr, rr, wts,
               int(params["population"]), int(params["iterations"]), float(params["sd_tol"]), stream_seed, st,
               out_u, out_v, out_c, evals)
    return SubpixelResult(u=out_u, v=out_v, zncc=out_c, status=st), evals
