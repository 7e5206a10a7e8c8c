"""ZNCC on a sub-pixel lattice ``(u0 + h i, v0 + h j)`` from Keys-interpolated image intensities.

Support for the improved surface fit (``dic.subpixel.improved_surface_fit``):
the target subset at a lattice node is interpolated from the deformed *image*
with Keys bicubic convolution (a = -0.5, ``dic.subpixel.keys_cubic.keys_weights``);
the ZNCC map itself is never interpolated.

Speed: a node offset ``h i`` splits into an integer part ``ix[i]`` and a phase
``frac(h i)``; at h = 0.2 there are only 5 phases. Per point, the horizontal
Keys pass of the neighbourhood is computed once per x-phase (lazily, when a node
with that phase is first needed) into a small "phase plane"; a node then costs
one vertical 4-tap pass over the subset fused with the ZNCC sums. Planes hold
the image minus a per-point offset (ZNCC is offset invariant) in float32; the
ZNCC sums are accumulated per row in float32 and across rows in float64.

Lattice tables (per call, shared by all points; index k = i + L for i in -L..L):
``ix`` integer offset, ``ph`` phase id, ``lr``/``rr`` leftmost/rightmost pixel
offset read (taps -1..2 for a non-zero phase, 0 for phase 0), ``wts`` (P, 4)
Keys weights per phase.
"""

import numpy as np
from numba import njit, uint64

from livedic.dic.bspline import FASTMATH
from livedic.dic.correlation import FLAT_VARIANCE
from livedic.dic.subpixel.keys_cubic import keys_weights


def lattice_tables(spacing: float, half_nodes: int) -> tuple[np.ndarray, ...]:
    """Tables for lattice indices -half_nodes..half_nodes at ``spacing`` px (Python side)."""
    idx = np.arange(-half_nodes, half_nodes + 1)
    offsets = idx * spacing
    ix = np.floor(offsets + 1e-9).astype(np.int64)
    frac = offsets - ix
    frac[np.abs(frac) < 1e-9] = 0.0
    # phase ids: distinct fractions (rounded to kill float noise), 0 first
    keys = np.round(frac, 9)
    uniq = np.unique(keys)
    ph = np.searchsorted(uniq, keys).astype(np.int64)
    wts = np.empty((uniq.shape[0], 4))
    for p, t in enumerate(uniq):
        keys_weights(float(t), wts[p])
        if t == 0.0:
            wts[p] = (0.0, 1.0, 0.0, 0.0)
    zero = keys == 0.0
    lr = np.where(zero, ix, ix - 1).astype(np.int64)
    rr = np.where(zero, ix, ix + 2).astype(np.int64)
    return ix, ph, lr, rr, wts


@njit(cache=True)
def node_inside(size, c0, half, lr, rr, k):
    """True if the interpolation footprint of lattice index k at integer centre c0 fits in [0, size)."""
    return c0 + lr[k] - half >= 0 and c0 + rr[k] + half <= size - 1


@njit(cache=True)
def valid_range(size, c0, half, lr, rr, lo_k, hi_k, mid_k):
    """Contiguous run of valid lattice indices around ``mid_k`` within [lo_k, hi_k]; (1, 0) if mid invalid."""
    if not node_inside(size, c0, half, lr, rr, mid_k):
        return 1, 0
    a = mid_k
    while a - 1 >= lo_k and node_inside(size, c0, half, lr, rr, a - 1):
        a -= 1
    b = mid_k
    while b + 1 <= hi_k and node_inside(size, c0, half, lr, rr, b + 1):
        b += 1
    return a, b


@njit(cache=True, fastmath=FASTMATH)
def build_plane(target, planes, p, wts, x_org, y_org, offset):
    """Horizontal Keys pass for x-phase p into planes[p] (rows, cols), float32.

    planes[p][r, c] = sum_t wts[p, t] * target[y_org + r, x_org + c - 1 + t] - offset,
    reads clamped to the image (clamped values only ever meet zero weights).
    Indices are uint64 in the fast path: numba then drops its negative-index
    wrap-around selects and LLVM vectorises the row (about 6x faster).
    """
    height, width = target.shape
    rows = planes.shape[1]
    cols = planes.shape[2]
    w0 = np.float32(wts[p, 0])
    w1 = np.float32(wts[p, 1])
    w2 = np.float32(wts[p, 2])
    w3 = np.float32(wts[p, 3])
    off = np.float32(offset)
    flat = planes[p].ravel()
    if x_org - 1 >= 0 and x_org + cols + 1 <= width - 1:
        src = target.ravel()
        for r in range(rows):
            yy = min(max(y_org + r, 0), height - 1)
            b0 = uint64(yy * width + x_org - 1)
            b1 = b0 + uint64(1)
            b2 = b0 + uint64(2)
            b3 = b0 + uint64(3)
            o = uint64(r * cols)
            for c in range(cols):
                cu = uint64(c)
                flat[o + cu] = w0 * src[b0 + cu] + w1 * src[b1 + cu] + w2 * src[b2 + cu] + w3 * src[b3 + cu] - off
    else:
        for r in range(rows):
            yy = min(max(y_org + r, 0), height - 1)
            for c in range(cols):
                acc = np.float32(0.0)
                for t in range(4):
                    xx = min(max(x_org + c - 1 + t, 0), width - 1)
                    acc += np.float32(wts[p, t]) * target[yy, xx]
                flat[r * cols + c] = acc - off


@njit(cache=True, fastmath=FASTMATH)
def node_zncc(fhat2, planes, p, c0, r0, wy, side):
    """ZNCC of the prepared subset ``fhat2`` (side, side) float32 against the node whose
    samples are ``sum_t wy[t] * planes[p][r + r0 + t, c + c0]``; -1 for a flat target.

    Sums run in float32 along a row (vectorised) and in float64 across rows;
    uint64 indices as in ``build_plane``.
    """
    n = side * side
    cols = planes.shape[2]
    flat = planes[p].ravel()
    f = fhat2.ravel()
    cross = 0.0
    sg = 0.0
    sgg = 0.0
    w0 = np.float32(wy[0])
    w1 = np.float32(wy[1])
    w2 = np.float32(wy[2])
    w3 = np.float32(wy[3])
    step = uint64(cols)
    for r in range(side):
        b0 = uint64((r + r0) * cols + c0)
        b1 = b0 + step
        b2 = b1 + step
        b3 = b2 + step
        fb = uint64(r * side)
        rc = np.float32(0.0)
        rs = np.float32(0.0)
        rss = np.float32(0.0)
        for c in range(side):
            cu = uint64(c)
            s = w0 * flat[b0 + cu] + w1 * flat[b1 + cu] + w2 * flat[b2 + cu] + w3 * flat[b3 + cu]
            rc += f[fb + cu] * s
            rs += s
            rss += s * s
        cross += rc
        sg += rs
        sgg += rss
    var = sgg - sg * sg / n
    mean = sg / n
    if var <= FLAT_VARIANCE * n * (1.0 + mean * mean):
        return -1.0
    return cross / np.sqrt(var)
