"""Tests of stream/session/parsing.py: each command-line value checked and parsed, every error one line naming the option."""

import argparse

import cv2
import numpy as np
import pytest

from livedic.dic import SEARCH_METHODS, SUBPIXEL_METHODS
from livedic.dic.region import Circle, Polygon, Rectangle
from livedic.stream.session.parsing import (ROI_AUTO, ROI_FULL, UsageError, argument_type, check_interpolation,
                                            check_search,
                                            check_subpixel, parse_color_range, parse_exclusion, parse_numbers,
                                            parse_p0, parse_roi, read_mask, search_method)


def test_interpolation_names_are_checked_and_canonical():
    assert check_interpolation(" BSpline5") == "bspline5" and check_interpolation("bspline3") == "bspline3"
    with pytest.raises(ValueError, match="^unknown interpolation 'cubic': choose one of bspline3, bspline5, bspline7$"):
        check_interpolation("cubic")


def test_method_names_are_checked():
    assert all(check_search(name) == name for name in SEARCH_METHODS)
    assert all(check_subpixel(name) == name for name in SUBPIXEL_METHODS)
    with pytest.raises(ValueError, match="^unknown search method 'magic': choose one of "):
        check_search("magic")
    with pytest.raises(ValueError, match="^unknown sub-pixel method 'magic': choose one of "):
        check_subpixel("magic")


def test_an_argument_type_keeps_the_checks_one_line_as_argparses_error(capsys):
    parser = argparse.ArgumentParser(prog="livedic")
    parser.add_argument("--search", type=search_method)
    assert parser.parse_args(["--search", SEARCH_METHODS[0]]).search == SEARCH_METHODS[0]
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--search", "magic"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("livedic: error: argument --search: unknown search method 'magic'")
    assert argument_type(check_search).__name__ == "check_search"


def test_numbers_are_counted_and_finite():
    assert parse_numbers(" 1, 2.5 ,-3", 3, "--x", "1,2,3") == [1.0, 2.5, -3.0]
    for bad in ("1,2", "1,2,3,4", "1,nan,3", "1,inf,3", "a,b,c", ""):
        with pytest.raises(ValueError, match=r"^--x must be 3 comma-separated numbers, e.g. 1,2,3; got "):
            parse_numbers(bad, 3, "--x", "1,2,3")


def test_rois():
    assert parse_roi(None) is None
    assert parse_roi(" AUTO ") == ROI_AUTO and parse_roi("full") == ROI_FULL
    assert parse_roi("10.4,20.6,30,40") == Rectangle(10, 21, 30, 40)             # rounded to whole pixels
    assert parse_roi("rect:1,2,3,4") == Rectangle(1, 2, 3, 4)
    assert isinstance(parse_roi("polygon:0,0,10,0,0,10"), Polygon)


@pytest.mark.parametrize("text, message", [
    ("polygon:0,0,10,0", "expected polygon"),
    ("circle:1,2,3", "circles are for --exclude"),
    ("10,10,0,5", "must be positive"),
    ("ellipse:1,2,3,4", "unknown shape"),
])
def test_bad_regions_are_one_line(text, message):
    with pytest.raises(ValueError, match=message) as error:
        parse_roi(text)
    assert "\n" not in str(error.value)


def test_exclusions_take_every_shape_and_name_the_option():
    assert isinstance(parse_exclusion("circle:1,2,3"), Circle)
    assert isinstance(parse_exclusion("rect:1,2,3,4"), Rectangle)
    with pytest.raises(ValueError, match="^--exclude "):
        parse_exclusion("ellipse:1,2,3,4")


def test_p0_and_colour_range():
    assert parse_p0(None) is None and parse_p0("512,400.5") == (512.0, 400.5)
    with pytest.raises(ValueError, match="^--p0 must be 2 comma-separated numbers, e.g. 512,400"):
        parse_p0("512")
    assert parse_color_range(None) is None and parse_color_range("-2,2") == (-2.0, 2.0)
    with pytest.raises(ValueError, match="^--color-range 2,2: LO must be below HI"):
        parse_color_range("2,2")


@pytest.mark.parametrize("dtype, white", [(np.uint8, 200), (np.uint16, 40000)])
def test_a_mask_is_white_on_the_specimen(tmp_path, dtype, white):
    image = np.zeros((20, 30), dtype)
    image[5:15, 10:20] = white
    image[0, 0] = white // 3                                   # below half the grey range: not specimen
    path = str(tmp_path / "mask.png")
    assert cv2.imwrite(path, image)
    mask = read_mask(path)
    assert mask.shape == (20, 30) and mask.sum() == 100 and mask[5:15, 10:20].all()


def test_an_unusable_mask_is_a_usage_error(tmp_path):
    black = str(tmp_path / "black.png")
    assert cv2.imwrite(black, np.zeros((8, 8), np.uint8))
    with pytest.raises(UsageError, match=r"has no white pixel: white \(or light grey\) marks the specimen"):
        read_mask(black)
    with pytest.raises(UsageError, match="^--mask "):
        read_mask(str(tmp_path / "missing.png"))
    assert issubclass(UsageError, ValueError)
