"""FFT-CC: ZNCC at every integer position of the box at once, by FFT.

The cross term ``sum fhat(dx, dy) g(x + u + dx, y + v + dy)`` over all (u, v)
of a box is the cross-correlation of the normalised reference subset with a
window of the deformed image (box plus subset), computed as a product of
Fourier transforms; because ``sum fhat = 0`` the target's mean drops out of it.
The target's norm at every position comes from integral images of ``g`` and
``g^2`` (computed once per image). ZNCC = cross / |g - mean g|, exactly the
exhaustive search's value up to rounding (~1e-12), at a cost that grows with
``log(box)`` per position instead of the subset area. This follows OpenCorr's
``FFTCC2D`` (vincentjzy/OpenCorr ``src/oc_fftcc.cpp``), with one change: OpenCorr
correlates two subsets of the same size, so its shifts wrap around beyond half a
subset; here the target window covers the whole search box, so every
displacement of the box is a true (unwrapped) position, as in the exhaustive
search. Ties keep the first position in row-major order (v outer, u inner), as
there.

Points are processed in chunks of equal window size with batched ``numpy.fft``
(real transforms, float64); a point's ``evaluations`` is its box size.

References
----------
B. Pan, H. Xie, Z. Wang, "Equivalence of digital image correlation criteria for
pattern matching", Appl. Opt. 49(28):5501-5509 (2010), :DOI:`10.1364/AO.49.005501`.
"""

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.correlation import FLAT_VARIANCE
from livedic.dic.method_options import Checks
from livedic.dic.search._common import SearchOutputs
from livedic.dic.status import FLAT_REFERENCE, FLAT_TARGET, OK

DEFAULTS: dict[str, Any] = {}
CHECKS: Checks = {}
# Points per batched FFT: bounds the transform arrays to ~50 MB for a 64 x 64 window.
_CHUNK_BYTES = 50_000_000


def _integral(image):
    """Integral images of g and g^2 with a leading row and column of zeros (float64)."""
    g = image.astype(np.float64)
    s1 = np.zeros((g.shape[0] + 1, g.shape[1] + 1))
    s2 = np.zeros_like(s1)
    np.cumsum(np.cumsum(g, axis=0), axis=1, out=s1[1:, 1:])
    np.cumsum(np.cumsum(g * g, axis=0), axis=1, out=s2[1:, 1:])
    return s1, s2


@njit(cache=True, parallel=True, nogil=True)
def _gather(reference, deformed, xs, ys, ulo, vlo, half, fhat, window, flat):
    """Normalised reference subsets into fhat (k, side, side) and target windows into window (k, hw, ww)."""
    side = 2 * half + 1
    n = side * side
    hw, ww = window.shape[1], window.shape[2]
    for k in prange(xs.shape[0]):
        total = 0.0
        for dy in range(side):
            for dx in range(side):
                total += reference[ys[k] - half + dy, xs[k] - half + dx]
        mean = total / n
        sq = 0.0
        for dy in range(side):
            for dx in range(side):
                d = reference[ys[k] - half + dy, xs[k] - half + dx] - mean
                fhat[k, dy, dx] = d
                sq += d * d
        flat[k] = sq <= FLAT_VARIANCE * n * (1.0 + mean * mean)
        scale = 0.0 if flat[k] else 1.0 / np.sqrt(sq)
        for dy in range(side):
            for dx in range(side):
                fhat[k, dy, dx] *= scale
        top = ys[k] + vlo[k] - half
        left = xs[k] + ulo[k] - half
        for r in range(hw):
            for c in range(ww):
                window[k, r, c] = deformed[top + r, left + c]


@njit(cache=True, parallel=True, nogil=True)
def _best(cross, s1, s2, xs, ys, ulo, vlo, half, nu, nv, best_u, best_v, best_c):
    """ZNCC = cross / |g - mean g| at every position (flat target: -1); the first maximum per point."""
    side = 2 * half + 1
    n = side * side
    for k in prange(xs.shape[0]):
        bc = -np.inf
        bu = 0
        bv = 0
        for j in range(nv):
            top = ys[k] + vlo[k] - half + j
            for i in range(nu):
                left = xs[k] + ulo[k] - half + i
                sg = s1[top + side, left + side] - s1[top, left + side] - s1[top + side, left] + s1[top, left]
                sgg = s2[top + side, left + side] - s2[top, left + side] - s2[top + side, left] + s2[top, left]
                var = sgg - sg * sg / n
                mean = sg / n
                if var > FLAT_VARIANCE * n * (1.0 + mean * mean):
                    c = cross[k, j, i] / np.sqrt(var)
                else:
                    c = -1.0
                if c > bc:
                    bc = c
                    bu = i
                    bv = j
        best_u[k] = ulo[k] + bu
        best_v[k] = vlo[k] + bv
        best_c[k] = bc


def _fast_length(n):
    """Smallest 2^a 3^b 5^c >= n (fast for pocketfft)."""
    best = 1 << int(np.ceil(np.log2(max(n, 1))))
    for p3 in (1, 3, 9, 27):
        for p5 in (1, 5, 25):
            base = p3 * p5
            if base > best:
                continue
            m = base
            while m < n:
                m *= 2
            best = min(best, m)
    return best


def _search_group(reference, deformed, tables, xs, ys, ulo, vlo, nu, nv, half):
    """Best integer match (u, v, zncc) and a flat-reference flag for points sharing one box size."""
    side = 2 * half + 1
    k = xs.shape[0]
    hw, ww = nv + side - 1, nu + side - 1
    shape = (_fast_length(hw), _fast_length(ww))
    fhat = np.empty((k, side, side))
    window = np.empty((k, hw, ww))
    flat = np.empty(k, dtype=np.bool_)
    _gather(reference, deformed, xs, ys, ulo, vlo, half, fhat, window, flat)
    spectrum = np.fft.rfft2(window, s=shape)
    spectrum *= np.conj(np.fft.rfft2(fhat, s=shape))
    cross = np.ascontiguousarray(np.fft.irfft2(spectrum, s=shape)[:, :nv, :nu])
    best_u = np.empty(k, dtype=np.int64)
    best_v = np.empty(k, dtype=np.int64)
    best_c = np.empty(k)
    _best(cross, tables[0], tables[1], xs, ys, ulo, vlo, half, nu, nv, best_u, best_v, best_c)
    return best_u, best_v, best_c, flat


def run(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, ulo: np.ndarray,
        uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray, seed: np.uint64,
        params: Mapping[str, Any], outputs: SearchOutputs, centre: tuple[np.ndarray, np.ndarray]) -> None:
    """Search every point whose status is OK (the ``dic.search`` kernel contract)."""
    out_u, out_v, out_c, out_evals, out_calls = outputs
    todo = np.flatnonzero(status == OK)
    if todo.size == 0:
        return
    tables = _integral(deformed)
    nu_all = uhi - ulo + 1
    nv_all = vhi - vlo + 1
    keys = nv_all[todo] * (1 << 32) + nu_all[todo]
    for key in np.unique(keys):
        group = todo[keys == key]
        nv, nu = int(nv_all[group[0]]), int(nu_all[group[0]])
        side = 2 * half + 1
        per_point = 16 * (_fast_length(nv + side - 1) * (_fast_length(nu + side - 1) // 2 + 1)) * 3
        chunk = max(1, _CHUNK_BYTES // per_point)
        for begin in range(0, group.size, chunk):
            idx = group[begin:begin + chunk]
            bu, bv, value, flat = _search_group(reference, deformed, tables, xs[idx], ys[idx], ulo[idx], vlo[idx],
                                                nu, nv, half)
            out_evals[idx] = np.where(flat, 0, nu * nv)
            out_calls[idx] = out_evals[idx]
            flat_target = ~flat & (value == -1.0)
            status[idx[flat]] = FLAT_REFERENCE
            status[idx[flat_target]] = FLAT_TARGET
            keep = ~flat & ~flat_target
            good = idx[keep]
            out_u[good] = bu[keep]
            out_v[good] = bv[keep]
            out_c[good] = value[keep]
