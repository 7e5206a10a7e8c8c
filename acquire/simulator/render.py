"""The simulator's numba kernels: the Zhou-Goodson speckle sum sampled along deformed rows, the painted
coupon on its background, and camera noise and quantisation to Mono8 / Mono12.
"""

import math

import numpy as np
from numba import njit, prange

from livedic.acquire.simulator.options import FULL_SCALE

# Paint model: pixel = full * (PAINT_FLOOR + PAINT_GAIN * exp(-I)), I the Zhou-Goodson sum.
PAINT_FLOOR = 0.06
PAINT_GAIN = 0.88


# --------------------------------------------------------------------------- #
# Rendering kernels
# --------------------------------------------------------------------------- #

@njit(cache=True)
def _row_intensity(xs, ys, amp, inv_r, reach2, delta, q, Yr, a, b, lo, hi, c_lo, c_hi, acc):
    """acc[c - c_lo] = sum_k amp_k exp(-((a + b c - x_k)^2 + (Yr - y_k)^2) / R^2) over |d| < reach.

    Centres k in [lo, hi) (those within reach of the row); ``amp`` is 1 for
    every spot of unfaded paint (an exact product: the sum is then bit for bit
    the plain one). Along the row the
    Gaussian is stepped by the exact recurrence g(c+1) = g(c) s(c),
    s(c+1) = s(c) q with q = exp(-2 delta^2), delta = b / R: two exp per spot,
    relative rounding drift below 1e-14 over a spot's width.
    """
    for c in range(c_hi - c_lo):
        acc[c] = 0.0
    inv_r2 = inv_r * inv_r
    for k in range(lo, hi):
        dy = ys[k] - Yr
        d2y = dy * dy
        if d2y >= reach2:
            continue
        half = math.sqrt(reach2 - d2y)
        xk = xs[k]
        # columns with (a + b c - xk)^2 < half^2
        first = max(int(math.floor((xk - half - a) / b)) + 1, c_lo)
        last = min(int(math.ceil((xk + half - a) / b)) - 1, c_hi - 1)
        if last < first:
            continue
        t = (a + b * first - xk) * inv_r
        g = amp[k] * math.exp(-(t * t + d2y * inv_r2))
        step = math.exp(-(2.0 * t * delta + delta * delta))
        for c in range(first - c_lo, last - c_lo + 1):
            acc[c] += g
            g *= step
            step *= q


@njit(cache=True, parallel=True)
def _render_rows(xs, ys, radius, reach, Y, alpha, beta, col_lo, col_hi, out):
    """Zhou-Goodson intensity sampled at X = alpha_r + beta_r c, Y = Y_r (float64 out, (H, W)).

    ``ys`` sorted ascending; only columns col_lo[r] <= c < col_hi[r] are written.
    Equal (to rounding) to ``SpecklePattern.intensity`` at the same points.
    """
    H, W = out.shape
    inv_r = 1.0 / radius
    reach2 = reach * reach
    amp = np.ones(xs.shape[0])
    for r in prange(H):
        c_lo, c_hi = col_lo[r], col_hi[r]
        if c_hi <= c_lo:
            continue
        delta = beta[r] * inv_r
        lo = np.searchsorted(ys, Y[r] - reach)
        hi = np.searchsorted(ys, Y[r] + reach, side="right")
        _row_intensity(xs, ys, amp, inv_r, reach2, delta, math.exp(-2.0 * delta * delta), Y[r], alpha[r], beta[r],
                       lo, hi, c_lo, c_hi, out[r, c_lo:c_hi])


@njit(cache=True, parallel=True)
def render_specimen(xs, ys, amp, radius, reach, Y, alpha, beta, left, right, row_cover, background, full, floor,
                     gain, out):
    """Grey image (float32 out, (H, W)) of the coupon: painted speckle inside [left, right], background outside.

    Each row r: background[r] everywhere, blended towards the paint
    ``full (floor + gain exp(-I))`` by the pixel's coverage of the specimen
    (1 px linear ramp at the deformed edges ``left[r]``, ``right[r]``, times
    ``row_cover[r]``: 1, or less at a crack face, 0 in the crack). Spot k's
    optical density is scaled by ``amp[k]`` (1: unfaded).
    """
    H, W = out.shape
    inv_r = 1.0 / radius
    reach2 = reach * reach
    for r in prange(H):
        bg = background[r]
        for c in range(W):
            out[r, c] = bg
        rc = row_cover[r]
        if rc <= 0.0:
            continue
        c_lo = max(int(math.floor(left[r])) - 1, 0)
        c_hi = min(int(math.ceil(right[r])) + 2, W)
        if c_hi <= c_lo:
            continue
        acc = np.empty(c_hi - c_lo)
        delta = beta[r] * inv_r
        lo = np.searchsorted(ys, Y[r] - reach)
        hi = np.searchsorted(ys, Y[r] + reach, side="right")
        _row_intensity(xs, ys, amp, inv_r, reach2, delta, math.exp(-2.0 * delta * delta), Y[r], alpha[r], beta[r],
                       lo, hi, c_lo, c_hi, acc)
        for c in range(c_lo, c_hi):
            cover = min(c - left[r], right[r] - c) + 0.5
            if cover <= 0.0:
                continue
            if cover > 1.0:
                cover = 1.0
            cover *= rc
            paint = full * (floor + gain * math.exp(-acc[c - c_lo]))
            out[r, c] = bg + cover * (paint - bg)


@njit(cache=True, parallel=True)
def _quantise_into(image, noise, sigma, full, out):
    """out = rint(clip(image + sigma * noise, 0, full)) (noise may be empty for none)."""
    H, W = image.shape
    with_noise = noise.shape[0] == H
    for r in prange(H):
        for c in range(W):
            value = image[r, c]
            if with_noise:
                value += sigma * noise[r, c]
            if value < 0.0:
                value = 0.0
            elif value > full:
                value = full
            out[r, c] = np.rint(value)


def paint(intensity: np.ndarray, full: float) -> np.ndarray:
    """Grey level of speckled paint for the Zhou-Goodson intensity (float)."""
    return full * (PAINT_FLOOR + PAINT_GAIN * np.exp(-intensity))


def quantise(image: np.ndarray, bit: int, noise_sigma: float, noise_seed: int | tuple[int, ...]) -> np.ndarray:
    """Add camera noise (seeded: ``numpy.random.default_rng(noise_seed)``), clip and round to Mono8 / Mono12."""
    full = FULL_SCALE[bit]
    out = np.empty(image.shape, dtype=np.uint8 if bit == 8 else np.uint16)
    if noise_sigma > 0.0:
        noise = np.random.default_rng(noise_seed).standard_normal(image.shape, dtype=np.float32)
    else:
        noise = np.empty((0, 0), dtype=np.float32)
    _quantise_into(np.ascontiguousarray(image, dtype=np.float32), noise, np.float32(noise_sigma),
                   np.float32(full), out)
    return out
