"""Image gradients at integer pixels by finite differences.

``gradient_4th``: the 4th-order central difference
``(I[x-2] - 8 I[x-1] + 8 I[x+1] - I[x+2]) / 12`` (OpenCorr's ``Gradient2D4``),
exact for polynomials up to degree 4. IC-GN takes its reference gradients from
it, at the pixels themselves, so no interpolation error enters the Hessian.
``gradient_central``: the 2nd-order ``(I[x+1] - I[x-1]) / 2``.

Unlike OpenCorr, which leaves a 2-pixel frame of zeros, the border is filled
with the best stencil that fits: central difference one pixel in, one-sided
``I[1] - I[0]`` on the edge. The order there is lower, not zero.
"""

import numpy as np
import numpy.typing as npt
from numba import njit, prange


@njit(cache=True, inline="always")
def diff4_x(image, r, c):
    """d/dx at integer pixel (r, c): 4th-order inside, lower order within 2 px of the border."""
    w = image.shape[1]
    if c >= 2 and c < w - 2:
        return ((image[r, c - 2] - image[r, c + 2]) + 8.0 * (image[r, c + 1] - image[r, c - 1])) * (1.0 / 12.0)
    if c >= 1 and c < w - 1:
        return 0.5 * (image[r, c + 1] - image[r, c - 1])
    if w == 1:
        return 0.0
    if c == 0:
        return float(image[r, 1] - image[r, 0])
    return float(image[r, c] - image[r, c - 1])


@njit(cache=True, inline="always")
def diff4_y(image, r, c):
    """d/dy at integer pixel (r, c): 4th-order inside, lower order within 2 px of the border."""
    h = image.shape[0]
    if r >= 2 and r < h - 2:
        return ((image[r - 2, c] - image[r + 2, c]) + 8.0 * (image[r + 1, c] - image[r - 1, c])) * (1.0 / 12.0)
    if r >= 1 and r < h - 1:
        return 0.5 * (image[r + 1, c] - image[r - 1, c])
    if h == 1:
        return 0.0
    if r == 0:
        return float(image[1, c] - image[0, c])
    return float(image[r, c] - image[r - 1, c])


@njit(cache=True, inline="always")
def diff2_x(image, r, c):
    """d/dx at (r, c) by the central difference; one-sided on the border."""
    w = image.shape[1]
    if c >= 1 and c < w - 1:
        return 0.5 * (image[r, c + 1] - image[r, c - 1])
    if w == 1:
        return 0.0
    if c == 0:
        return float(image[r, 1] - image[r, 0])
    return float(image[r, c] - image[r, c - 1])


@njit(cache=True, inline="always")
def diff2_y(image, r, c):
    """d/dy at (r, c) by the central difference; one-sided on the border."""
    h = image.shape[0]
    if r >= 1 and r < h - 1:
        return 0.5 * (image[r + 1, c] - image[r - 1, c])
    if h == 1:
        return 0.0
    if r == 0:
        return float(image[1, c] - image[0, c])
    return float(image[r, c] - image[r - 1, c])


@njit(cache=True, parallel=True, nogil=True)
def _gradient_batch(image, fourth, gx, gy):
    """Fill gx, gy (H, W) with the gradients of ``image`` (H, W)."""
    h, w = image.shape
    for r in prange(h):
        for c in range(w):
            if fourth:
                gx[r, c] = diff4_x(image, r, c)
                gy[r, c] = diff4_y(image, r, c)
            else:
                gx[r, c] = diff2_x(image, r, c)
                gy[r, c] = diff2_y(image, r, c)


def _gradient(image, fourth, dtype):
    image = np.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"image must be 2-D (H, W), got shape {image.shape}")
    if image.dtype.kind not in "uif":
        raise ValueError(f"image has dtype {image.dtype}: give an integer or float grey image")
    src = np.ascontiguousarray(image, dtype=np.float64 if image.dtype == np.float64 else np.float32)
    gx = np.empty(image.shape, dtype=dtype)
    gy = np.empty(image.shape, dtype=dtype)
    _gradient_batch(src, fourth, gx, gy)
    return gx, gy


def gradient_4th(image: np.ndarray, dtype: npt.DTypeLike = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """4th-order central-difference gradient of ``image``.

    Parameters
    ----------
    image : ndarray, shape (H, W)
    dtype : dtype of the result

    Returns
    -------
    gx, gy : ndarray, shape (H, W)
        d/dx (along columns) and d/dy (along rows), grey levels per pixel.

    Examples
    --------
    >>> ramp = np.add.outer(3.0 * np.arange(6), 0.5 * np.arange(7))   # 3 per row, 0.5 per column
    >>> gx, gy = gradient_4th(ramp)
    >>> float(gx[3, 3]), float(gy[3, 3])
    (0.5, 3.0)
    """
    return _gradient(image, True, dtype)


def gradient_central(image: np.ndarray, dtype: npt.DTypeLike = np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Central-difference gradient ``(I[x+1] - I[x-1]) / 2`` of ``image``; see ``gradient_4th``."""
    return _gradient(image, False, dtype)
