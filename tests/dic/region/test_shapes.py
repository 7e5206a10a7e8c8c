"""Shapes (``dic.region.shapes``): drawn on exact pixels, read from text."""

import numpy as np
import pytest

from livedic.dic.region import Circle, Polygon, Rectangle, parse_shape, shape_mask

SHAPE = (120, 160)


def test_a_rectangle_covers_exactly_its_pixels():
    mask = shape_mask(Rectangle(10, 20, 30, 40), SHAPE)
    assert mask.sum() == 30 * 40
    assert mask[20, 10] and mask[59, 39] and not mask[60, 39] and not mask[59, 40]


def test_a_circle_holds_the_pixels_whose_centre_is_within_its_radius():
    circle = Circle(70.3, 50.6, 11.5)
    mask = shape_mask(circle, SHAPE)
    rows, cols = np.indices(SHAPE)
    expected = (cols - 70.3) ** 2 + (rows - 50.6) ** 2 <= 11.5 ** 2
    assert np.array_equal(mask, expected)


def test_a_polygon_fills_its_area():
    square = shape_mask(Polygon(((10, 20), (39, 20), (39, 59), (10, 59))), SHAPE)
    assert np.array_equal(square, shape_mask(Rectangle(10, 20, 30, 40), SHAPE))
    triangle = shape_mask(Polygon(((0, 0), (100, 0), (0, 100))), SHAPE)
    rows, cols = np.indices(SHAPE)
    assert np.array_equal(triangle, (rows + cols <= 100))       # the pixel centres inside or on its edges


@pytest.mark.parametrize("text, expected", [
    ("circle:10,20,5", Circle(10, 20, 5)),
    ("rect:1,2,3,4", Rectangle(1, 2, 3, 4)),
    ("polygon:0,0,10,0,0,10", Polygon(((0, 0), (10, 0), (0, 10)))),
    (" Circle:1.5,2.5,3 ", Circle(1.5, 2.5, 3)),
])
def test_shapes_are_read_from_text(text, expected):
    assert parse_shape(text) == expected


@pytest.mark.parametrize("text", ["circle:1,2", "ellipse:1,2,3", "polygon:0,0,1,1", "rect:0,0,-3,4",
                                  "circle:1,2,0", "polygon:0,0,1,1,2,2", "circle:a,b,c", "circle:1,2,nan", "10,20,5"])
def test_malformed_shapes_are_one_line_errors(text):
    with pytest.raises(ValueError) as error:
        parse_shape(text)
    assert "\n" not in str(error.value)
