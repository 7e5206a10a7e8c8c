"""The view's colour scales and point sizes: pure functions on numpy arrays (no rerun).

The colour map (turbo) and its packing to Rerun's 0xRRGGBBAA, the automatic limits that only grow to "nice"
numbers, and the typical spacing of the points that sets the discs' size. The rules are described in
docs/guide/live-view.md; ``livedic export`` uses the same limits for its maps.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

MIN_COLOUR_LIMIT_PX = 0.05       # the automatic scale starts at +-this, so reference-frame noise is one colour
MIN_COLOUR_LIMIT_STRAIN = 1e-3   # e_yy's scale starts at +-0.1 %: strain noise (~1e-4) is one colour
MIN_COLOUR_LIMIT_MM = 0.01       # W's scale (stereo) starts at +-10 um: a rig's out-of-plane noise is one colour
NICE_MANTISSAS = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
AXIS_MANTISSAS = (1.0, 2.0, 5.0, 10.0)   # the transverse-vs-axial axes grow in fewer, bigger steps
_LIMIT_PERCENTILES = (0.5, 99.5)
_SPACING_QUERIES = 128           # points sampled to estimate the typical spacing (once per point set)


def colormap_lut() -> np.ndarray:
    """(256, 3) uint8 RGB 'turbo' colour map (OpenCV's table)."""
    import cv2
    ramp = np.arange(256, dtype=np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)[:, 0, ::-1].copy()


def pack_colours(rgb: npt.ArrayLike) -> np.ndarray:
    """(N, 3) uint8 RGB -> (N,) uint32 0xRRGGBBAA, opaque: what Rerun stores, without its per-call conversion."""
    rgb = np.asarray(rgb, dtype=np.uint32).reshape(-1, 3)
    return (rgb[:, 0] << 24) | (rgb[:, 1] << 16) | (rgb[:, 2] << 8) | np.uint32(255)


def nice_ceil(value: float, mantissas: Sequence[float] = NICE_MANTISSAS) -> float:
    """The smallest "nice" number (1, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 times a power of ten) >= ``value`` > 0.

    ``mantissas`` (ascending, ending with 10) replaces the nice mantissas.
    """
    exponent = np.floor(np.log10(value))
    for mantissa in mantissas:
        candidate = mantissa * 10.0 ** exponent
        if candidate >= value * (1 - 1e-9):   # 0.3 / 0.1 and friends land a rounding error above a mantissa
            return float(f"{candidate:.3g}")
    return float(f"{10.0 ** (exponent + 1):.3g}")


def grow_limits(limits: tuple[float, float], values: np.ndarray) -> tuple[float, float]:
    """Automatic colour limits after a frame: ``limits`` (lo < 0 < hi) widened to cover ``values``.

    The 0.5th/99.5th percentiles of the finite ``values`` are covered; an end that
    must move goes out to the next nice number. The result contains ``limits``.
    """
    lo, hi = limits
    values = values[np.isfinite(values)]
    if values.size == 0 or (values.min() >= lo and values.max() <= hi):
        return lo, hi               # inside already (the percentiles lie between min and max): most frames
    low, high = np.percentile(values, _LIMIT_PERCENTILES)
    if low < lo:
        lo = -nice_ceil(-low)
    if high > hi:
        hi = nice_ceil(high)
    return float(lo), float(hi)


def grow_to_cover(limits: tuple[float, float], value: float,
                  mantissas: Sequence[float] = AXIS_MANTISSAS) -> tuple[float, float]:
    """``limits`` (lo <= 0 <= hi) widened to cover one finite ``value``: an end that moves goes out to the next
    1, 2 or 5 times a power of ten (``mantissas``)."""
    lo, hi = limits
    if value < lo:
        lo = -nice_ceil(-value, mantissas)
    if value > hi:
        hi = nice_ceil(value, mantissas)
    return float(lo), float(hi)


def typical_spacing(x: npt.ArrayLike, y: npt.ArrayLike) -> float | None:
    """Typical distance between neighbouring points (docs/guide/live-view.md), or None for fewer than 2 points.

    The median, over up to ``_SPACING_QUERIES`` points spread through the set, of
    the distance to the second-nearest distinct point (nearest for 2 points).
    """
    positions = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    positions = np.unique(positions[np.isfinite(positions).all(axis=1)], axis=0)
    count = len(positions)
    if count < 2:
        return None
    extent = positions.max(axis=0) - positions.min(axis=0)
    axis = int(extent[1] > extent[0])        # search along the longer side: fewer points per window
    positions = positions[np.argsort(positions[:, axis], kind="stable")]
    along = positions[:, axis]
    neighbour = min(2, count - 1)            # index 0 of the sorted distances is the query itself
    # a first window: the spacing of a grid with this many points over the bounding box
    start_window = max(np.sqrt(max(extent[0], 1.0) * max(extent[1], 1.0) / count), 1e-6)
    distances = []
    for q in np.unique(np.linspace(0, count - 1, min(count, _SPACING_QUERIES)).astype(np.int64)):
        query, window = positions[q], start_window
        while True:      # points outside the window along ``axis`` are farther than ``window``
            first = np.searchsorted(along, query[axis] - window, side="left")
            last = np.searchsorted(along, query[axis] + window, side="right")
            d2 = ((positions[first:last] - query) ** 2).sum(axis=1)
            if last - first > neighbour:
                kth = np.partition(d2, neighbour)[neighbour]
                if kth <= window * window or last - first == count:
                    distances.append(kth)
                    break
            window *= 2.0
    return float(np.sqrt(np.median(distances)))
