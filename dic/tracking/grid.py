"""Where a tracker's points go in a rectangle: ``grid_in_roi`` (a grid every ``step`` px centred in the
ROI, each subset inside the image) and ``step_for_count`` (the step giving about N points)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from livedic.dic.region import centred_axis
from livedic.dic.validation import check_subset


def grid_in_roi(shape: tuple[int, int], roi: Sequence[int] | None, step: int,
                subset: int) -> np.ndarray:
    """Points every ``step`` px over a region of interest, where a whole subset fits.

    Parameters
    ----------
    shape : tuple of int, (H, W)
        Image size.
    roi : tuple of int, (x, y, w, h), or None
        Region of interest (column, row of its top-left pixel, width, height);
        None for the whole image. Points are placed so their subsets stay inside
        both the ROI and the image, and the grid is centred in the ROI.
    step : int
        Grid spacing, pixels (>= 1).
    subset : int
        Odd subset side, pixels.

    Returns
    -------
    ndarray of float64, shape (N, 2)
        (x, y) positions, row by row.

    Raises
    ------
    ValueError
        Bad step, subset or ROI, or an ROI too small (or too far outside the
        image) to hold one subset.
    """
    height, width = int(shape[0]), int(shape[1])
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
        raise ValueError(f"grid step must be a positive integer number of pixels, got {step!r}")
    half = check_subset(subset, (height, width))
    if roi is None:
        roi = (0, 0, width, height)
    try:
        x0, y0, w, h = (int(v) for v in roi)
    except (TypeError, ValueError):
        raise ValueError(f"ROI must be four integers x, y, w, h, got {roi!r}") from None
    if w <= 0 or h <= 0:
        raise ValueError(f"ROI width and height must be positive, got {w}x{h}")
    left = max(x0, 0) + half
    top = max(y0, 0) + half
    right = min(x0 + w, width) - 1 - half
    bottom = min(y0 + h, height) - 1 - half
    if right < left or bottom < top:
        raise ValueError(f"ROI {x0},{y0},{w},{h} inside the {width}x{height} image cannot hold a "
                         f"{subset}x{subset} subset: enlarge the ROI or use a smaller subset")

    xs, ys = np.meshgrid(centred_axis(left, right, step), centred_axis(top, bottom, step))
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64)


def step_for_count(roi: Sequence[int], n_points: int, subset: int) -> int:
    """Grid step giving about ``n_points`` points over ``roi`` = (x, y, w, h) (>= 1)."""
    _, _, w, h = roi
    half = int(subset) // 2
    w_eff = max(int(w) - 2 * half, 1)
    h_eff = max(int(h) - 2 * half, 1)
    if n_points <= 1:
        return max(w_eff, h_eff)
    step = int(np.sqrt(w_eff * h_eff / float(n_points)))
    best = max(step, 1)
    best_err = None
    for candidate in range(max(step - 2, 1), step + 3):
        count = (w_eff // candidate + 1) * (h_eff // candidate + 1)
        err = abs(count - n_points)
        if best_err is None or err < best_err:
            best, best_err = candidate, err
    return best
