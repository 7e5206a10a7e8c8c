"""What a command line gives, checked and parsed: one value at a time, each error one line naming the option.

``UsageError`` is bad input (the CLI prints it, exit 2); ``check_*`` and ``parse_*`` raise ValueError with the
option as the command line spells it; ``argument_type`` makes an argparse ``type=`` of a check.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from livedic.dic import SEARCH_METHODS, SUBPIXEL_METHODS
from livedic.dic.image_filter import Prefilter
from livedic.dic.interpolation import Interpolation
from livedic.dic.region import Circle, Polygon, Rectangle, Shape, parse_shape

T = TypeVar("T")


class UsageError(ValueError):
    """Bad command-line input; the message is shown to the user as is."""


# ----------------------------------------------------------------------------- single values

def check_search(name: str) -> str:
    """``name`` if it is an integer search method, else ValueError (one line)."""
    if name not in SEARCH_METHODS:
        raise ValueError(f"unknown search method {name!r}: choose one of {', '.join(SEARCH_METHODS)}")
    return name


def check_subpixel(name: str) -> str:
    """``name`` if it is a sub-pixel method (``none`` included), else ValueError (one line)."""
    if name not in SUBPIXEL_METHODS:
        raise ValueError(f"unknown sub-pixel method {name!r}: choose one of {', '.join(SUBPIXEL_METHODS)}")
    return name


def check_prefilter(text: object) -> str:
    """``--prefilter``'s canonical text ("none", "gaussian:0.6"), or ValueError (one line; ``dic.image_filter``)."""
    return str(Prefilter.parse(text))   # type: ignore[arg-type]


def check_interpolation(text: object) -> str:
    """``--interpolation``'s canonical name ("bspline3", "bspline5"), or ValueError (one line; ``dic.interpolation``)."""
    return str(Interpolation.parse(text))   # type: ignore[arg-type]


def argument_type(check: Callable[[str], T]) -> Callable[[str], T]:
    """An argparse ``type=`` from a check: its ValueError message becomes argparse's error as is.

    (argparse replaces a plain ValueError's message by "invalid <type> value"; an
    ``ArgumentTypeError`` keeps the one line the check wrote.)
    """
    def convert(text: str) -> T:
        try:
            return check(text)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
    convert.__name__ = check.__name__
    return convert


search_method = argument_type(check_search)
subpixel_method = argument_type(check_subpixel)
prefilter_text = argument_type(check_prefilter)
interpolation_name = argument_type(check_interpolation)


def parse_numbers(text: object, count: int, what: str, example: str) -> list[float]:
    """``"a,b,..."`` -> ``count`` finite floats, or ValueError naming ``what`` with an ``example``."""
    try:
        values = [float(part) for part in str(text).split(",")]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be {count} comma-separated numbers, e.g. {example}; got {text!r}")
    return values


ROI_AUTO = "auto"      # --roi auto: the speckled specimen found in the image
ROI_FULL = "full"      # --roi full: the whole image


def parse_roi(text: str | None) -> str | Rectangle | Polygon | None:
    """``--roi``: None when not given, ``"auto"``, ``"full"``, or a ``dic.region`` Rectangle or Polygon.

    ``X,Y,W,H`` is a rectangle (rounded to whole pixels); ``rect:X,Y,W,H`` and
    ``polygon:X1,Y1,X2,Y2,X3,Y3[,...]`` name their shape.
    """
    if text is None:
        return None
    word = str(text).strip().lower()
    if word in (ROI_AUTO, ROI_FULL):
        return word
    if ":" not in word:
        x, y, w, h = (int(round(v)) for v in parse_numbers(text, 4, "--roi", "100,50,400,800"))
        if w <= 0 or h <= 0:
            raise ValueError(f"--roi width and height must be positive, got {text!r}")
        return Rectangle(x, y, w, h)
    try:
        shape = parse_shape(text)
    except ValueError as error:
        raise ValueError(f"--roi {error}") from None
    if isinstance(shape, Circle):
        raise ValueError(f"--roi {text}: a region is a rectangle (X,Y,W,H) or a polygon (polygon:X1,Y1,...); "
                         f"circles are for --exclude")
    return shape


def read_mask(path: str) -> np.ndarray:
    """``--mask FILE.png``: True where the image is white (above half its grey range); UsageError if unusable."""
    from livedic.acquire.files.image_file import read_grey_image
    try:
        image, _ = read_grey_image(path)
    except ValueError as error:
        raise UsageError(f"--mask {error}") from None
    full = 255 if image.dtype == np.uint8 else 65535
    mask = image > full // 2
    if not mask.any():
        raise UsageError(f"--mask {path} has no white pixel: white (or light grey) marks the specimen, black the rest")
    return mask


def parse_exclusion(text: str) -> Shape:
    """``--exclude`` ``circle:X,Y,R``, ``rect:X,Y,W,H`` or ``polygon:X1,Y1,...`` -> a ``dic.region`` shape."""
    try:
        return parse_shape(text)
    except ValueError as error:
        raise ValueError(f"--exclude {error}") from None


def parse_p0(text: str | None) -> tuple[float, float] | None:
    """``--p0`` "X,Y" -> (x, y) floats, or None when not given."""
    if text is None:
        return None
    x, y = parse_numbers(text, 2, "--p0", "512,400")
    return x, y


def parse_color_range(text: str | None) -> tuple[float, float] | None:
    """``--color-range`` "LO,HI" -> (lo, hi) in px, or None when not given.

    Raises
    ------
    ValueError
        Not two finite comma-separated numbers, or LO not below HI.
    """
    if text is None:
        return None
    lo, hi = parse_numbers(text, 2, "--color-range", "-2,2")
    if not lo < hi:
        raise ValueError(f"--color-range {text}: LO must be below HI, e.g. -2,2")
    return lo, hi
