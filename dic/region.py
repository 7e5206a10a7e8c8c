"""Where points may go: the region of interest, masks and exclusions, and the speckled specimen.

A *region* is a boolean image, True where a subset may lie. It is built from an
outline (a rectangle or a polygon, ``--roi``), a mask image (``--mask``, white =
specimen) and exclusions (circles, rectangles, polygons: a hole, a clip, a
marker), or, when none is given, found in the reference image by its speckle
(``find_specimen``). A point is placed only where its whole subset lies inside
the region (``placeable``): no subset reaches into an excluded area, the
background or a hole.

Shapes are in image pixels: x along columns, y along rows, a pixel's centre at
integer coordinates; a pixel belongs to a shape when its centre does.

Finding the specimen. DIC needs texture in every direction inside a subset: the
smaller eigenvalue of the image's structure tensor (the mean of grad I grad I^T
over a speckle-sized window) is large on a speckle pattern and ~0 on a uniform
background, a saturated patch, a dark hole, and along a single straight edge
(where only one direction has texture). Its logarithm separates the two
populations by orders of magnitude on real images (Otsu's threshold on it); the
speckled pixels, cleaned of isolated specks and of gaps between speckles, and
kept in pieces large enough to hold several subsets, are the specimen. See
``find_specimen`` for the rules and their reasons.

Pure functions on numpy arrays (OpenCV for filters and polygon filling); no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence, Union

import numpy as np

__all__ = ["Rectangle", "Polygon", "Circle", "Shape", "Region", "Specimen", "shape_mask", "placeable", "straddling",
           "bounding_box", "centred_axis",
           "grid_in_region", "step_for_area", "speckle_texture", "find_specimen", "parse_shape",
           "TEXTURE_WINDOW"]

# The structure tensor's window, px: about a speckle and its gap (3-5 px speckles), so that a window
# anywhere on the pattern holds texture in every direction.
TEXTURE_WINDOW = 9
# Texture is measured on the image blurred by this Gaussian (px): a camera's white noise loses ~20x its
# gradient energy, a speckle of 3-5 px a fraction of it, so a noisy background falls away from the speckle.
NOISE_BLUR_SIGMA = 1.0
# Texture below this share of the image's 99th percentile is taken as that floor (exact zeros and float
# rounding on a uniform area would otherwise stretch the logarithm's scale without meaning).
LOG_FLOOR = 1e-3
# Two populations are told apart when Otsu's classes of log10(texture) are at least this far apart
# (decades): speckle against a background, a hole or saturation is 2-4 decades apart on the public
# images; one speckled population split in two by Otsu is less than one decade apart.
SEPARATION_DECADES = 1.0
# With one population (the image is speckle throughout), pixels below this share of its median texture
# are flat: a scratch, a saturated spot.
FLAT_SHARE = 0.02
# A speckled piece is kept when it can hold this many subsets, and is at least this share of the largest.
MIN_PIECE_SUBSETS = 4
MIN_PIECE_SHARE = 0.05


# ----------------------------------------------------------------------------- shapes

@dataclass(frozen=True)
class Rectangle:
    """Columns x .. x + w - 1, rows y .. y + h - 1 (``--roi X,Y,W,H``)."""
    x: float
    y: float
    w: float
    h: float

    def __post_init__(self):
        if not (self.w > 0 and self.h > 0):
            raise ValueError(f"rectangle {self.describe()}: width and height must be positive")

    def describe(self) -> str:
        return f"rect:{self.x:g},{self.y:g},{self.w:g},{self.h:g}"

    @property
    def bounds(self) -> tuple:
        """(x0, y0, x1, y1), the last column and row included."""
        return self.x, self.y, self.x + self.w - 1, self.y + self.h - 1

    def fill(self, mask: np.ndarray, value: bool = True) -> None:
        height, width = mask.shape
        x0, y0 = max(int(math.ceil(self.x)), 0), max(int(math.ceil(self.y)), 0)
        x1, y1 = min(int(math.floor(self.x + self.w - 1)), width - 1), min(int(math.floor(self.y + self.h - 1)),
                                                                           height - 1)
        if x1 >= x0 and y1 >= y0:
            mask[y0:y1 + 1, x0:x1 + 1] = value


@dataclass(frozen=True)
class Polygon:
    """A closed polygon through ``vertices`` ((x, y), ...), at least three."""
    vertices: tuple

    def __post_init__(self):
        vertices = tuple((float(x), float(y)) for x, y in self.vertices)
        object.__setattr__(self, "vertices", vertices)
        if len(vertices) < 3:
            raise ValueError(f"polygon {self.describe()}: needs at least 3 vertices")
        if _polygon_area(np.array(vertices)) <= 0:
            raise ValueError(f"polygon {self.describe()}: its vertices enclose no area")

    def describe(self) -> str:
        return "polygon:" + ",".join(f"{x:g},{y:g}" for x, y in self.vertices)

    @property
    def bounds(self) -> tuple:
        xy = np.array(self.vertices)
        return float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()), float(xy[:, 1].max())

    def fill(self, mask: np.ndarray, value: bool = True) -> None:
        import cv2
        shift = 8          # vertices with 8 fractional bits: sub-pixel polygons are filled as drawn
        vertices = np.round(np.array(self.vertices) * (1 << shift)).astype(np.int32)
        canvas = np.zeros(mask.shape, dtype=np.uint8)
        cv2.fillPoly(canvas, [vertices], 1, lineType=cv2.LINE_8, shift=shift)
        mask[canvas.astype(bool)] = value


@dataclass(frozen=True)
class Circle:
    """Pixels whose centre is within ``r`` of (x, y) (``--exclude circle:X,Y,R``)."""
    x: float
    y: float
    r: float

    def __post_init__(self):
        if not self.r > 0:
            raise ValueError(f"circle {self.describe()}: the radius must be positive")

    def describe(self) -> str:
        return f"circle:{self.x:g},{self.y:g},{self.r:g}"

    @property
    def bounds(self) -> tuple:
        return self.x - self.r, self.y - self.r, self.x + self.r, self.y + self.r

    def fill(self, mask: np.ndarray, value: bool = True) -> None:
        height, width = mask.shape
        x0, x1 = max(int(math.ceil(self.x - self.r)), 0), min(int(math.floor(self.x + self.r)), width - 1)
        y0, y1 = max(int(math.ceil(self.y - self.r)), 0), min(int(math.floor(self.y + self.r)), height - 1)
        if x1 < x0 or y1 < y0:
            return
        cols = np.arange(x0, x1 + 1) - self.x
        rows = np.arange(y0, y1 + 1) - self.y
        inside = rows[:, None] ** 2 + cols[None, :] ** 2 <= self.r * self.r
        mask[y0:y1 + 1, x0:x1 + 1][inside] = value


Shape = Union[Rectangle, Polygon, Circle]

_SHAPE_KINDS = {"rect": (Rectangle, "X,Y,W,H", 4), "circle": (Circle, "X,Y,R", 3),
                "polygon": (Polygon, "X1,Y1,X2,Y2,X3,Y3[,...]", None)}


def _polygon_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def parse_shape(text: str, *, default: str | None = None) -> Shape:
    """``rect:X,Y,W,H``, ``circle:X,Y,R`` or ``polygon:X1,Y1,X2,Y2,...`` -> a shape.

    ``default`` is the kind read when ``text`` has no ``KIND:`` prefix (``--roi X,Y,W,H`` is a rectangle).

    Raises
    ------
    ValueError
        An unknown kind, the wrong count of numbers, a number that is not finite, or a degenerate shape.
    """
    kind, sep, numbers = str(text).strip().partition(":")
    if not sep:
        if default is None:
            raise ValueError(f"{text!r} names no shape: write rect:X,Y,W,H, circle:X,Y,R or polygon:X1,Y1,X2,Y2,...")
        kind, numbers = default, text
    kind = kind.strip().lower()
    if kind not in _SHAPE_KINDS:
        raise ValueError(f"unknown shape {kind!r} in {text!r}: use rect:X,Y,W,H, circle:X,Y,R or "
                         f"polygon:X1,Y1,X2,Y2,X3,Y3[,...]")
    cls, form, count = _SHAPE_KINDS[kind]
    try:
        values = [float(part) for part in numbers.split(",")]
    except ValueError:
        values = []
    ok_count = (len(values) == count) if count else (len(values) >= 6 and len(values) % 2 == 0)
    if not ok_count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{kind} {numbers!r}: expected {kind}:{form} (finite numbers, px)")
    if cls is Polygon:
        return Polygon(tuple(zip(values[0::2], values[1::2])))
    return cls(*values)


def shape_mask(shape: Shape, image_shape: tuple) -> np.ndarray:
    """Boolean (H, W) image, True on the pixels of ``shape``."""
    mask = np.zeros(tuple(int(v) for v in image_shape[:2]), dtype=bool)
    shape.fill(mask, True)
    return mask


# ----------------------------------------------------------------------------- regions

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


# ----------------------------------------------------------------------------- the speckled specimen

def speckle_texture(image: np.ndarray, window: int = TEXTURE_WINDOW) -> np.ndarray:
    """The smaller eigenvalue of the structure tensor over ``window`` x ``window`` px, (H, W) float32.

    Grey levels^2 / px^2 (central differences): large where the image has texture in every direction,
    ~0 on a uniform area and along a single straight edge.
    """
    import cv2
    f = np.asarray(image, dtype=np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    size = (int(window), int(window))
    a = cv2.boxFilter(gx * gx, -1, size, borderType=cv2.BORDER_REFLECT)
    b = cv2.boxFilter(gx * gy, -1, size, borderType=cv2.BORDER_REFLECT)
    c = cv2.boxFilter(gy * gy, -1, size, borderType=cv2.BORDER_REFLECT)
    half_trace = 0.5 * (a + c)
    radius = np.sqrt(np.maximum(0.25 * (a - c) ** 2 + b * b, 0.0))
    return np.maximum(half_trace - radius, 0.0)


@dataclass(frozen=True)
class Specimen:
    """The speckled part of an image (``find_specimen``).

    Attributes
    ----------
    mask : ndarray (H, W) of bool
        True on the speckled specimen.
    threshold : float
        Texture (``speckle_texture``) above which a pixel counts as speckled.
    separated : bool
        True when the image had two populations (specimen and background, holes, saturation) told apart;
        False when it is speckle throughout (then only flat spots are left out).
    pieces : int
        Speckled pieces kept.
    share : float
        The mask's share of the image.
    """
    mask: np.ndarray = field(repr=False)
    threshold: float
    separated: bool
    pieces: int
    share: float

    @property
    def bounds(self) -> tuple | None:
        """(x, y, w, h) of the mask's bounding box, or None when it is empty."""
        return bounding_box(self.mask)

    def describe(self) -> str:
        if not self.mask.any():
            return "no speckled area found"
        x, y, w, h = self.bounds
        what = "the speckled specimen" if self.separated else "speckle over the whole image"
        pieces = f" in {self.pieces} pieces" if self.pieces > 1 else ""
        return (f"{what}{pieces}: {100 * self.share:.0f} % of the image, within {x},{y},{w},{h} "
                f"(background, holes and flat or saturated areas left out)")


def _otsu(values: np.ndarray, bins: int = 256) -> float:
    histogram, edges = np.histogram(values, bins=bins)
    centres = 0.5 * (edges[:-1] + edges[1:])
    weight = np.cumsum(histogram).astype(np.float64)
    total = weight[-1]
    mean = np.cumsum(histogram * centres)
    between = (mean[-1] * weight - mean * total) ** 2 / np.maximum(weight * (total - weight), 1e-12)
    return float(centres[int(np.argmax(between[:-1]))])


def find_specimen(image: np.ndarray, subset: int) -> Specimen:
    """The speckled area of ``image``: where a subset can be correlated (module notes).

    Rules, each for a reason:

    1. Texture is ``speckle_texture`` (texture in every direction, over about a speckle) of the image
       blurred by ``NOISE_BLUR_SIGMA`` (a noisy background is not texture that moves with the specimen).
    2. Two populations (a specimen on a background, holes, saturated glare) are told apart by Otsu's
       threshold on log10(texture) when its two classes are at least ``SEPARATION_DECADES`` apart;
       otherwise the image is speckle throughout and only pixels below ``FLAT_SHARE`` of its median
       texture are flat.
    3. The speckled pixels are closed over half a subset (the gaps between speckles of a sparse
       pattern are specimen), opened over a subset (isolated specks of dust or noise on the background
       are not), and their boundary pulled in by half the texture window (the window spreads an edge's
       texture outwards).
    4. Pieces that cannot hold ``MIN_PIECE_SUBSETS`` subsets, or under ``MIN_PIECE_SHARE`` of the
       largest, are dropped.

    Parameters
    ----------
    image : ndarray (H, W)
        The reference frame (any grey dtype).
    subset : int
        Subset side, px: sets the scale of the clean-up.

    Returns
    -------
    Specimen
    """
    import cv2
    smooth = cv2.GaussianBlur(np.asarray(image, dtype=np.float32), (0, 0), NOISE_BLUR_SIGMA,
                              borderType=cv2.BORDER_REPLICATE)
    texture = speckle_texture(smooth)
    top = float(np.percentile(texture[::2, ::2], 99))
    if not top > 0:
        empty = np.zeros(texture.shape, dtype=bool)
        return Specimen(empty, float("inf"), False, 0, 0.0)
    logs = np.log10(np.maximum(texture, LOG_FLOOR * top))
    sample = logs[::2, ::2].ravel()
    split = _otsu(sample)
    low, high = sample[sample <= split], sample[sample > split]
    separated = low.size > 0 and high.size > 0 and float(np.median(high) - np.median(low)) >= SEPARATION_DECADES
    if separated:
        threshold = float(10.0 ** split)
    else:
        threshold = FLAT_SHARE * float(np.median(texture))
    speckled = (texture > threshold).astype(np.uint8)

    half = max(int(subset) // 2, 1)
    close = np.ones((half | 1, half | 1), np.uint8)
    speckled = cv2.morphologyEx(speckled, cv2.MORPH_CLOSE, close, borderType=cv2.BORDER_REPLICATE)
    opening = np.ones((int(subset) | 1, int(subset) | 1), np.uint8)
    speckled = cv2.morphologyEx(speckled, cv2.MORPH_OPEN, opening, borderType=cv2.BORDER_REPLICATE)
    pull = TEXTURE_WINDOW // 2
    speckled = cv2.erode(speckled, np.ones((2 * pull + 1, 2 * pull + 1), np.uint8), borderType=cv2.BORDER_REPLICATE)

    count, labels, stats, _ = cv2.connectedComponentsWithStats(speckled, connectivity=4)
    areas = stats[1:, cv2.CC_STAT_AREA] if count > 1 else np.zeros(0, dtype=np.int64)
    if areas.size == 0:
        return Specimen(np.zeros(texture.shape, dtype=bool), threshold, separated, 0, 0.0)
    least = max(MIN_PIECE_SUBSETS * int(subset) ** 2, MIN_PIECE_SHARE * float(areas.max()))
    keep = np.flatnonzero(areas >= least) + 1
    mask = np.isin(labels, keep)
    return Specimen(mask, threshold, separated, int(keep.size), float(mask.mean()))
