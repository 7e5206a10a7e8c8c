"""The speckle simulator's numba kernels: spot profiles splatted for translations, tiles gathered from a bin
grid for the other fields (inverse map, branch-free exp), grey-level conversion. Summation order is fixed.
"""

import math

import numpy as np
from numba import njit, prange

# Rows of the image a thread owns when splatting a translation.
_BAND_ROWS = 8
# Field kinds understood by the numba kernels (_ARRAYS, _TABLE: precomputed inverse).
_TRANSLATION, _AFFINE, _SINUSOID, _ARRAYS, _TABLE = 0, 1, 2, 3, 4
# Pixel tile (side) over which the gather kernel shares one candidate list.
_TILE = 8


@njit(cache=True)
def _spot_profile(centre, first, count, radius, integrate, out):
    """1-D factor of one spot on pixels first..first+count-1 into ``out[:count]``.

    Point sampling: exp(-(i - c)^2 / R^2). Pixel integration: the mean of that
    over [i - 0.5, i + 0.5], (sqrt(pi) R / 2) [erf((i + .5 - c)/R) - erf((i - .5 - c)/R)],
    written with erfc on the positive side to keep tail accuracy.
    """
    inv_r = 1.0 / radius
    half_root_pi_r = 0.5 * math.sqrt(math.pi) * radius
    for i in range(count):
        d = (first + i) - centre
        if integrate:
            a = (d - 0.5) * inv_r
            b = (d + 0.5) * inv_r
            if a >= 0.0:
                out[i] = half_root_pi_r * (math.erfc(a) - math.erfc(b))
            elif b <= 0.0:
                out[i] = half_root_pi_r * (math.erfc(-b) - math.erfc(-a))
            else:
                out[i] = half_root_pi_r * (math.erf(b) - math.erf(a))
        else:
            t = d * inv_r
            out[i] = math.exp(-t * t)


@njit(cache=True)
def _window(centre, reach, n):
    """First pixel and count of pixels i in [0, n) with |i - centre| <= reach."""
    lo = max(int(math.ceil(centre - reach)), 0)
    hi = min(int(math.floor(centre + reach)), n - 1)
    return lo, max(hi - lo + 1, 0)


@njit(cache=True, parallel=True, nogil=True)
def _splat_translation(xs, ys, u, v, radius, reach, integrate, out):
    """Add the spots centred at (xs + u, ys + v) into ``out`` (H, W).

    ``ys`` is sorted ascending. Each spot is the separable product of a row and
    a column profile; threads own bands of rows, so no two write the same pixel.
    """
    H, W = out.shape
    n = xs.shape[0]
    width = int(2.0 * reach) + 3
    col0 = np.empty(n, dtype=np.int64)
    ncol = np.empty(n, dtype=np.int64)
    row0 = np.empty(n, dtype=np.int64)
    nrow = np.empty(n, dtype=np.int64)
    px = np.empty((n, width))
    py = np.empty((n, width))
    for k in prange(n):
        cx = xs[k] + u
        cy = ys[k] + v
        c0, nc = _window(cx, reach, W)
        r0, nr = _window(cy, reach, H)
        if nc == 0 or nr == 0:
            nc = 0
            nr = 0
        col0[k], ncol[k], row0[k], nrow[k] = c0, nc, r0, nr
        _spot_profile(cx, c0, nc, radius, integrate, px[k])
        _spot_profile(cy, r0, nr, radius, integrate, py[k])
    n_bands = (H + _BAND_ROWS - 1) // _BAND_ROWS
    for b in prange(n_bands):
        top = b * _BAND_ROWS
        bottom = min(top + _BAND_ROWS, H)
        lo = np.searchsorted(ys, top - reach - v - 1.0)
        hi = np.searchsorted(ys, bottom - 1 + reach - v + 1.0, side="right")
        for k in range(lo, hi):
            nc = ncol[k]
            if nc == 0:
                continue
            c0 = col0[k]
            r_first = max(row0[k], top)
            r_last = min(row0[k] + nrow[k], bottom)
            for r in range(r_first, r_last):
                w = py[k, r - row0[k]]
                for i in range(nc):
                    out[r, c0 + i] += w * px[k, i]


@njit(cache=True)
def _sum_near(X, Y, gx, gy, ga, start, ncx, ncy, x0, y0, cell, inv_r2, reach2):
    """Sum of ga_k exp(-d^2 / R^2) over centres k within the cutoff of (X, Y) (``ga``: each spot's amplitude,
    in the grid's order; ones: the plain sum, bit for bit)."""
    cx = int(math.floor((X - x0) / cell))
    cy = int(math.floor((Y - y0) / cell))
    c_lo = max(cx - 1, 0)
    c_hi = min(cx + 2, ncx)
    total = 0.0
    if c_lo >= c_hi:
        return total
    for j in range(max(cy - 1, 0), min(cy + 2, ncy)):
        for k in range(start[j * ncx + c_lo], start[j * ncx + c_hi]):
            dx = gx[k] - X
            dy = gy[k] - Y
            d2 = dx * dx + dy * dy
            if d2 < reach2:
                total += ga[k] * math.exp(-d2 * inv_r2)
    return total


@njit(cache=True)
def _invert_1d(s, A, k, phase):
    """t solving t + A sin(k t + phase) = s, for |A| k < 1 (safeguarded Newton)."""
    lo = s - abs(A)
    hi = s + abs(A)
    t = s - A * math.sin(k * s + phase)
    for _ in range(100):
        f = t + A * math.sin(k * t + phase) - s
        if f > 0.0:
            hi = t
        else:
            lo = t
        step = f / (1.0 + A * k * math.cos(k * t + phase))
        t_new = t - step
        if not (lo <= t_new <= hi):
            t_new = 0.5 * (lo + hi)
        if abs(t_new - t) <= 1e-13 * (1.0 + abs(t)):
            return t_new, True
        t = t_new
    return t, abs(t + A * math.sin(k * t + phase) - s) <= 1e-10


@njit(cache=True)
def _inverse_map(kind, p, x, y):
    """Reference point (X, Y) with (X, Y) + U(X, Y) = (x, y) for a translation or affine field."""
    if kind == _TRANSLATION:
        return x - p[0], y - p[1]
    # affine: p = [cx, cy, u, v, inverse of I + grad U (row-major)]
    rx = x - p[0] - p[2]
    ry = y - p[1] - p[3]
    return p[0] + p[4] * rx + p[5] * ry, p[1] + p[6] * rx + p[7] * ry


@njit(cache=True, inline="always")
def _exp_neg(t):
    """exp(-t) for 0 <= t <= 36, branch-free so LLVM vectorises the caller.

    Degree-14 Taylor polynomial of exp(-z), z = t / 64 <= 0.5625, in Estrin form,
    then six squarings: relative error below 5e-14.
    """
    z = t * (-1.0 / 64.0)
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    q0 = (1.0 + z) + (0.5 + z * (1.0 / 6.0)) * z2
    q1 = (1.0 / 24.0 + z * (1.0 / 120.0)) + (1.0 / 720.0 + z * (1.0 / 5040.0)) * z2
    q2 = (1.0 / 40320.0 + z * (1.0 / 362880.0)) + (1.0 / 3628800.0 + z * (1.0 / 39916800.0)) * z2
    q3 = (1.0 / 479001600.0 + z * (1.0 / 6227020800.0)) + (1.0 / 87178291200.0) * z2
    p = (q0 + q1 * z4) + (q2 + q3 * z4) * z8
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    return p * p


@njit(cache=True)
def _accumulate(candx, candy, n_cand, X, Y, n_pix, weight, inv_r2, cut2, acc):
    """acc[i] += weight * sum over candidates within the cutoff of exp(-d^2 / R^2)."""
    for k in range(n_cand):
        cx = candx[k]
        cy = candy[k]
        for i in range(n_pix):
            dx = cx - X[i]
            dy = cy - Y[i]
            t = (dx * dx + dy * dy) * inv_r2
            e = weight * _exp_neg(min(t, 36.0))
            acc[i] += e if t < cut2 else 0.0


@njit(cache=True, parallel=True, nogil=True)
def _gather_tiles(kind, p, table, Xa, Ya, weight, nodes, weights, gx, gy, start, ncx, ncy, x0, y0, cell,
                  inv_r2, cut2, reach, lo_x, hi_x, lo_y, hi_y, out, excess):
    """out[r, c] += sum_q w_q I(X_q, Y_q) over _TILE x _TILE pixel tiles.

    (X_q, Y_q) is the reference point of pixel (c, r) + node q: read from
    ``Xa, Ya`` (H, W) when ``kind`` is _ARRAYS (one node, weight ``weight``),
    from ``table`` (nodes, n) for _TABLE (a field of one coordinate: the
    reference coordinate along direction p[1] (1 = y) is the pixel's minus
    table[node, index along axis p[0] (1 = y)]), else from _inverse_map. Each tile gathers the centres within the cutoff of
    its reference bounding box once, then sums them branch-free over its pixels.
    excess[tile row] is the largest excursion of (X, Y) beyond [lo, hi] (NaN
    for non-finite points); such tiles are left unsummed and the caller raises.
    """
    H, W = out.shape
    nq = nodes.shape[0]
    n_ty = (H + _TILE - 1) // _TILE
    n_tx = (W + _TILE - 1) // _TILE
    reach2 = reach * reach
    for ty in prange(n_ty):
        X = np.empty(_TILE * _TILE)
        Y = np.empty(_TILE * _TILE)
        acc = np.empty(_TILE * _TILE)
        cap = 1024
        candx = np.empty(cap)
        candy = np.empty(cap)
        r0 = ty * _TILE
        nr = min(_TILE, H - r0)
        worst = 0.0
        for tx in range(n_tx):
            c0 = tx * _TILE
            nc = min(_TILE, W - c0)
            n_pix = nr * nc
            acc[:n_pix] = 0.0
            for qa in range(nq):
                for qb in range(nq):
                    w = weight * weights[qa] * weights[qb]
                    mnx = np.inf
                    mxx = -np.inf
                    mny = np.inf
                    mxy = -np.inf
                    for a in range(nr):
                        for b in range(nc):
                            i = a * nc + b
                            if kind == _ARRAYS:
                                Xi = Xa[r0 + a, c0 + b]
                                Yi = Ya[r0 + a, c0 + b]
                            elif kind == _TABLE:
                                Xi = c0 + b + nodes[qa]
                                Yi = r0 + a + nodes[qb]
                                d = table[qb, r0 + a] if p[0] != 0.0 else table[qa, c0 + b]
                                if p[1] != 0.0:
                                    Yi -= d
                                else:
                                    Xi -= d
                            else:
                                Xi, Yi = _inverse_map(kind, p, c0 + b + nodes[qa], r0 + a + nodes[qb])
                            X[i] = Xi
                            Y[i] = Yi
                            mnx = min(mnx, Xi)
                            mxx = max(mxx, Xi)
                            mny = min(mny, Yi)
                            mxy = max(mxy, Yi)
                    e = max(lo_x - mnx, mxx - hi_x, lo_y - mny, mxy - hi_y)
                    if not e <= 0.0:      # outside the speckled margin, or NaN
                        if e > worst or e != e:
                            worst = e
                        continue
                    cxa = max(int(math.floor((mnx - reach - x0) / cell)), 0)
                    cxb = min(int(math.floor((mxx + reach - x0) / cell)) + 1, ncx)
                    cya = max(int(math.floor((mny - reach - y0) / cell)), 0)
                    cyb = min(int(math.floor((mxy + reach - y0) / cell)) + 1, ncy)
                    if cxb <= cxa or cyb <= cya:
                        continue
                    bound = 0
                    for j in range(cya, cyb):
                        bound += start[j * ncx + cxb] - start[j * ncx + cxa]
                    if bound > cap:
                        cap = 2 * bound
                        candx = np.empty(cap)
                        candy = np.empty(cap)
                    n_cand = 0
                    for j in range(cya, cyb):
                        for k in range(start[j * ncx + cxa], start[j * ncx + cxb]):
                            px = gx[k]
                            py = gy[k]
                            ddx = max(mnx - px, 0.0, px - mxx)
                            ddy = max(mny - py, 0.0, py - mxy)
                            if ddx * ddx + ddy * ddy < reach2:
                                candx[n_cand] = px
                                candy[n_cand] = py
                                n_cand += 1
                    _accumulate(candx, candy, n_cand, X, Y, n_pix, w, inv_r2, cut2, acc)
            for a in range(nr):
                for b in range(nc):
                    out[r0 + a, c0 + b] += acc[a * nc + b]
        excess[ty] = worst


@njit(cache=True, parallel=True, nogil=True)
def _to_grey(image, scale, noise, full, out):
    """out = round(clip(scale * image + noise, 0, full)); ``noise`` is (H, W) or (0, 0) for none."""
    H, W = image.shape
    noisy = noise.shape[0] > 0
    for r in prange(H):
        for c in range(W):
            g = scale * image[r, c]
            if noisy:
                g += noise[r, c]
            out[r, c] = np.rint(min(max(g, 0.0), full))


@njit(cache=True, parallel=True, nogil=True)
def _invert_1d_table(coords, A, k, phase, table, ok):
    """table[j] = t solving t + A sin(k t + phase) = coords[j]; ok[j] its success flag."""
    for j in prange(coords.shape[0]):
        table[j], ok[j] = _invert_1d(coords[j], A, k, phase)


@njit(cache=True)
def _gather_points(X, Y, weight, gx, gy, ga, start, ncx, ncy, x0, y0, cell, inv_r2, reach2, out):
    """out += weight * I(X, Y) elementwise, for X, Y of shape (H, W) (serial: for sparse points); ``ga``: each
    spot's amplitude (``_sum_near``)."""
    H, W = out.shape
    for r in range(H):
        for c in range(W):
            out[r, c] += weight * _sum_near(X[r, c], Y[r, c], gx, gy, ga, start, ncx, ncy, x0, y0,
                                            cell, inv_r2, reach2)
