"""Where points may go: a ``Region`` (outline, mask, exclusions) as a boolean image, the pixels where a
whole subset fits inside it (``placeable``), and the grids of points laid on it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from livedic.dic.region.shapes import Rectangle, Shape, shape_mask


@dataclass(frozen=True)
class Region:
    """What the user said: an outline, a mask image, exclusions (any of them may be absent).

    Attributes
    ----------
    outline : Shape or None
        ``--roi``: a rectangle or a polygon; None: no outline.
    mask : ndarray (H, W) of bool, or None
        ``--mask``: True on the specimen.
    mask_name : str or None
        Where the mask came from (messages, metadata).
    exclude : tuple of Shape
        ``--exclude``: areas no subset may reach into.
    """
    outline: Shape | None = None
    mask: np.ndarray | None = field(default=None, compare=False, repr=False)
    mask_name: str | None = None
    exclude: tuple = ()

    @property
    def given(self) -> bool:
        """Whether an outline or a mask says where the specimen is (else it is to be found)."""
        return self.outline is not None or self.mask is not None

    def check(self, image_shape: tuple) -> None:
        """ValueError (one line) when the outline or the mask does not fit an image of ``image_shape``."""
        height, width = (int(v) for v in image_shape[:2])
        if self.mask is not None and self.mask.shape != (height, width):
            mh, mw = self.mask.shape
            name = f"mask {self.mask_name}" if self.mask_name else "the mask"
            raise ValueError(f"{name} is {mw}x{mh} px but the images are {width}x{height}: draw it on a frame "
                             f"of this camera")
        if self.outline is not None:
            x0, y0, x1, y1 = self.outline.bounds
            if isinstance(self.outline, Rectangle):
                if x0 < 0 or y0 < 0 or x1 > width - 1 or y1 > height - 1:
                    x, y, w, h = (self.outline.x, self.outline.y, self.outline.w, self.outline.h)
                    raise ValueError(f"ROI {x:g},{y:g},{w:g},{h:g} extends beyond the {width}x{height} image: "
                                     f"give X,Y,W,H with X+W <= {width} and Y+H <= {height}")
            elif x1 < 0 or y1 < 0 or x0 > width - 1 or y0 > height - 1:
                raise ValueError(f"ROI {self.outline.describe()} lies outside the {width}x{height} image")

    def pixels(self, image_shape: tuple, within: np.ndarray | None = None) -> np.ndarray:
        """Boolean (H, W): inside the outline and the mask (and ``within``: the found specimen), not excluded."""
        height, width = (int(v) for v in image_shape[:2])
        region = np.ones((height, width), dtype=bool) if within is None else within.copy()
        if self.outline is not None:
            region &= shape_mask(self.outline, (height, width))
        if self.mask is not None:
            region &= self.mask
        for shape in self.exclude:
            shape.fill(region, False)
        return region

    def describe(self) -> str:
        parts = []
        if self.outline is not None:
            parts.append(f"ROI {self.outline.describe()}")
        if self.mask is not None:
            parts.append(f"mask {self.mask_name or '(array)'}")
        parts += [f"excluding {shape.describe()}" for shape in self.exclude]
        return ", ".join(parts) if parts else "the whole image"

    def as_metadata(self) -> dict:
        return {"roi": self.outline.describe() if self.outline is not None else None,
                "mask": self.mask_name if self.mask is not None else None,
                "exclude": [shape.describe() for shape in self.exclude]}


def placeable(region: np.ndarray, subset: int, margin: int = 0) -> np.ndarray:
    """Boolean (H, W): the pixel centres whose whole subset (grown by ``margin`` px) lies in ``region``.

    Outside the image counts as outside the region: a subset must also fit in the image.
    """
    import cv2
    side = int(subset) + 2 * int(margin)
    canvas = np.asarray(region, dtype=np.uint8)
    kernel = np.ones((side, side), dtype=np.uint8)
    return cv2.erode(canvas, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)


# A subset straddles an edge when between these shares of it lie inside: the found edge is good to a pixel
# or two (~5 % of a 21 px subset's pixels), so fewer is not taken for a straddle.
STRADDLE_SHARES = (0.05, 0.95)


def straddling(points: np.ndarray, mask: np.ndarray, subset: int) -> np.ndarray:
    """Boolean (N,): points whose subset lies partly on ``mask`` and partly off it (across the specimen's edge).

    Such a subset sees two motions (the specimen's and the background's, a hole's far side) and is measured
    as a compromise that can pass every gate (docs/guide/quality.md: when is a point ok?).
    """
    import cv2
    share = cv2.boxFilter(np.asarray(mask, dtype=np.float32), -1, (int(subset), int(subset)),
                          borderType=cv2.BORDER_CONSTANT)
    xy = np.floor(np.asarray(points, dtype=np.float64).reshape(-1, 2) + 0.5).astype(np.int64)
    height, width = mask.shape
    xs, ys = np.clip(xy[:, 0], 0, width - 1), np.clip(xy[:, 1], 0, height - 1)
    values = share[ys, xs]
    return (values > STRADDLE_SHARES[0]) & (values < STRADDLE_SHARES[1])


def step_for_area(area_px: float, n_points: int) -> int:
    """Grid step giving about ``n_points`` points over ``area_px`` pixels where points may go (>= 1)."""
    if n_points <= 1 or area_px <= 0:
        return max(int(math.sqrt(max(area_px, 1.0))), 1)
    return max(int(round(math.sqrt(area_px / float(n_points)))), 1)


def bounding_box(mask: np.ndarray) -> tuple | None:
    """(x, y, w, h) of the True pixels of ``mask``, or None when there are none (rows and columns scanned
    with ``any``: a tenth of ``np.nonzero``'s time on a large mask)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return int(cols[0]), int(rows[0]), int(cols[-1] - cols[0] + 1), int(rows[-1] - rows[0] + 1)


def centred_axis(lo: int, hi: int, step: int) -> np.ndarray:
    """Positions every ``step`` px from ``lo`` to ``hi`` (inclusive), the leftover split evenly at both ends."""
    span = hi - lo
    count = span // step + 1
    start = lo + (span - (count - 1) * step) // 2
    return start + step * np.arange(count)


def grid_in_region(allowed: np.ndarray, step: int) -> np.ndarray:
    """Points every ``step`` px where ``allowed`` (a ``placeable`` map) is True, (N, 2) float64, row by row.

    The grid is centred on the allowed pixels' bounding box, as ``dic.tracking.grid_in_roi`` centres
    its grid in the ROI, so a rectangle gives the same points either way.
    """
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
        raise ValueError(f"grid step must be a positive integer number of pixels, got {step!r}")
    box = bounding_box(allowed)
    if box is None:
        return np.empty((0, 2))
    x, y, w, h = box
    xs, ys = np.meshgrid(centred_axis(x, x + w - 1, step), centred_axis(y, y + h - 1, step))
    keep = allowed[ys, xs]
    return np.column_stack([xs[keep], ys[keep]]).astype(np.float64)
