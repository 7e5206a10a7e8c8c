"""Zero-mean normalised correlation (ZNCC) and ZNSSD over square subsets.

Both criteria are invariant to an affine intensity change ``g -> a*g + b`` of
either image (Pan et al. 2009, DOI 10.1088/0957-0233/20/6/062001), which is
why DIC uses them: lighting drifts during a test, the pattern does not.
ZNSSD = 2 (1 - ZNCC), so one kernel serves both.

Kernels here take a *normalised reference subset* ``fhat = (f - mean f)/|f - mean f|``,
prepared once per point, so one correlation at an integer displacement costs
three multiply-adds per pixel (``sum(fhat*g)``, ``sum(g)``, ``sum(g*g)``):
because ``sum(fhat) == 0`` the target mean cancels from the numerator.
"""

import numpy as np
import numpy.typing as npt
from numba import njit, prange

from livedic.dic.status import FLAT_REFERENCE, FLAT_TARGET, OK, OUTSIDE_REFERENCE, OUTSIDE_TARGET
from livedic.dic.validation import as_image, as_points, check_same_shape, check_subset

# Relative variance below which a subset is "flat" (no texture to correlate).
FLAT_VARIANCE = 1e-10


@njit(cache=True)
def prepare_reference_subset(reference, x, y, half, fhat):
    """Fill ``fhat`` (n,) with the normalised subset at integer (x, y); return |f - mean|.

    Returns 0.0 for a flat subset, in which case ``fhat`` is left as zeros.
    """
    side = 2 * half + 1
    n = side * side
    total = 0.0
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            total += np.float64(reference[y + dy, x + dx])
    mean = total / n
    sq = 0.0
    k = 0
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            d = np.float64(reference[y + dy, x + dx]) - mean
            fhat[k] = d
            sq += d * d
            k += 1
    if sq <= FLAT_VARIANCE * n * (1.0 + mean * mean):
        fhat[:] = 0.0
        return 0.0
    norm = np.sqrt(sq)
    for k in range(n):
        fhat[k] /= norm
    return norm


@njit(cache=True)
def zncc_at_integer(fhat, target, x, y, half, u, v):
    """ZNCC of the prepared subset against the target subset centred at (x+u, y+v).

    ``u, v`` are integers and the caller guarantees the target subset is inside
    the image. A flat target subset scores -1 (the worst value), so optimisers
    move away from it instead of stalling on NaN.
    """
    side = 2 * half + 1
    n = side * side
    cross = 0.0
    sum_g = 0.0
    sum_gg = 0.0
    k = 0
    for dy in range(-half, half + 1):
        row = y + v + dy
        for dx in range(-half, half + 1):
            g = np.float64(target[row, x + u + dx])
            cross += fhat[k] * g
            sum_g += g
            sum_gg += g * g
            k += 1
    var = sum_gg - sum_g * sum_g / n
    mean = sum_g / n
    if var <= FLAT_VARIANCE * n * (1.0 + mean * mean):
        return -1.0
    return cross / np.sqrt(var)


@njit(cache=True)
def zncc_of_samples(fhat, samples):
    """ZNCC of the prepared subset against already-sampled target values ``samples`` (n,)."""
    n = samples.shape[0]
    cross = 0.0
    sum_g = 0.0
    sum_gg = 0.0
    for k in range(n):
        g = np.float64(samples[k])
        cross += fhat[k] * g
        sum_g += g
        sum_gg += g * g
    var = sum_gg - sum_g * sum_g / n
    mean = sum_g / n
    if var <= FLAT_VARIANCE * n * (1.0 + mean * mean):
        return -1.0
    return cross / np.sqrt(var)


@njit(cache=True)
def subset_inside(shape0, shape1, cx, cy, reach):
    """True if the square of half-width ``reach`` around integer (cx, cy) lies in the image."""
    return cx - reach >= 0 and cy - reach >= 0 and cx + reach < shape1 and cy + reach < shape0


@njit(cache=True, parallel=True, nogil=True)
def _zncc_batch(reference, target, xs, ys, us, vs, half, out_c, out_status):
    n_side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(n_side * n_side)
        x, y, u, v = xs[i], ys[i], us[i], vs[i]
        if not subset_inside(reference.shape[0], reference.shape[1], x, y, half):
            out_status[i] = OUTSIDE_REFERENCE
            out_c[i] = np.nan
            continue
        if prepare_reference_subset(reference, x, y, half, fhat) == 0.0:
            out_status[i] = FLAT_REFERENCE
            out_c[i] = np.nan
            continue
        if not subset_inside(target.shape[0], target.shape[1], x + u, y + v, half):
            out_status[i] = OUTSIDE_TARGET
            out_c[i] = np.nan
            continue
        c = zncc_at_integer(fhat, target, x, y, half, u, v)
        if c == -1.0:
            out_status[i] = FLAT_TARGET
            out_c[i] = np.nan
            continue
        out_status[i] = OK
        out_c[i] = c


@njit(cache=True, parallel=True, nogil=True)
def _reference_status_batch(reference, xs, ys, half, out_status):
    """``_zncc_batch``'s status of the reference against itself, without the ZNCC: OUTSIDE_REFERENCE, else
    FLAT_REFERENCE (``prepare_reference_subset``'s two-pass test), else FLAT_TARGET (``zncc_at_integer``'s
    one-pass test on the same pixels, which rounding may fail alone), else OK."""
    side = 2 * half + 1
    n = side * side
    for i in prange(xs.shape[0]):
        x, y = xs[i], ys[i]
        if not subset_inside(reference.shape[0], reference.shape[1], x, y, half):
            out_status[i] = OUTSIDE_REFERENCE
            continue
        total = 0.0                 # the pixels' sum (both tests' mean) and sum of squares, as both tests add them
        total_sq = 0.0
        for dy in range(-half, half + 1):
            for dx in range(-half, half + 1):
                g = np.float64(reference[y + dy, x + dx])
                total += g
                total_sq += g * g
        mean = total / n
        sq = 0.0
        for dy in range(-half, half + 1):
            for dx in range(-half, half + 1):
                d = np.float64(reference[y + dy, x + dx]) - mean
                sq += d * d
        if sq <= FLAT_VARIANCE * n * (1.0 + mean * mean):
            out_status[i] = FLAT_REFERENCE
            continue
        var = total_sq - total * total / n
        out_status[i] = FLAT_TARGET if var <= FLAT_VARIANCE * n * (1.0 + mean * mean) else OK


# Subset side (px) every measurement uses unless told otherwise: about 4-5 speckles of 3-5 px across.
DEFAULT_SUBSET = 21


def zncc(reference: np.ndarray, deformed: np.ndarray, points: npt.ArrayLike, displacements: npt.ArrayLike, *,
         subset: int = DEFAULT_SUBSET) -> tuple[np.ndarray, np.ndarray]:
    """ZNCC between reference subsets and deformed subsets at integer displacements.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images of equal shape.
    points : array_like, shape (N, 2)
        (x, y) subset centres in the reference, snapped to the nearest pixel.
    displacements : array_like, shape (N, 2)
        Integer (u, v): the deformed subset is centred at (x + u, y + v).
    subset : int
        Odd subset side in pixels.

    Returns
    -------
    zncc : ndarray, shape (N,)
        Correlation in [-1, 1]; NaN where ``status`` is not OK.
    status : ndarray of int8, shape (N,)
        A ``Status`` code per point: why it has no value (outside an image, flat).

    Notes
    -----
    ZNSSD is ``2 * (1 - zncc)``.
    """
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    half = check_subset(subset, reference.shape)
    xy = as_points(points)
    uv = np.asarray(displacements, dtype=np.float64).reshape(-1, 2)
    if uv.shape[0] != xy.shape[0]:
        raise ValueError(f"got {xy.shape[0]} points but {uv.shape[0]} displacements: give one (u, v) per point")
    if not np.all(np.isfinite(uv)) or np.any(uv != np.round(uv)):
        raise ValueError("displacements must be finite integers: use dic.measure for sub-pixel values")
    xs, ys = snap_points(xy)
    out_c = np.empty(xs.shape[0])
    out_status = np.empty(xs.shape[0], dtype=np.int8)
    _zncc_batch(reference, deformed, xs, ys, uv[:, 0].astype(np.int64), uv[:, 1].astype(np.int64),
                half, out_c, out_status)
    return out_c, out_status


def snap_points(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integer pixel (xs, ys) nearest to float points (N, 2); halves round up."""
    snapped = np.floor(xy + 0.5).astype(np.int64)
    return np.ascontiguousarray(snapped[:, 0]), np.ascontiguousarray(snapped[:, 1])


@njit(cache=True)
def round_half_up(x):
    """Nearest integer to float ``x``, halves rounded up (``floor(x + 0.5)``, the rule of ``snap_points``), as int64."""
    return np.int64(np.floor(x + 0.5))
