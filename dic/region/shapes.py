"""The shapes a region is drawn with: rectangles, polygons and circles in image pixels, parsed from the
command line's ``rect:``, ``polygon:`` and ``circle:`` forms, and rasterised to boolean masks.

A pixel belongs to a shape when its centre does (x along columns, y along rows).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Union

import numpy as np


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
