"""Regions (``dic.region``): shapes drawn on exact pixels, subsets kept inside, the speckled specimen found."""

import numpy as np
import pytest

from livedic.dic.region import (Circle, Polygon, Rectangle, Region, find_specimen, grid_in_region, parse_shape,
                                placeable, shape_mask)
from livedic.dic.tracking import grid_in_roi
from tests.conftest import blurred_noise, specimen_scene

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


def test_no_placeable_subset_reaches_into_an_exclusion_or_out_of_the_region():
    region_spec = Region(outline=Rectangle(5, 8, 140, 100), exclude=(Circle(80, 60, 14.2), Rectangle(20, 30, 6, 9)))
    region = region_spec.pixels(SHAPE)
    subset = 11
    allowed = placeable(region, subset)
    half = subset // 2
    rows, cols = np.nonzero(allowed)
    assert rows.size > 0
    for row, col in zip(rows, cols):                # brute force: every pixel of every subset is in the region
        assert region[row - half:row + half + 1, col - half:col + half + 1].all()
    # and every centre whose subset is inside is allowed (nothing lost needlessly)
    inside = np.zeros(SHAPE, dtype=bool)
    for row in range(half, SHAPE[0] - half):
        for col in range(half, SHAPE[1] - half):
            inside[row, col] = region[row - half:row + half + 1, col - half:col + half + 1].all()
    assert np.array_equal(inside, allowed)


def test_a_grid_over_a_rectangle_is_the_roi_grid():
    roi = (13, 7, 101, 77)
    allowed = placeable(shape_mask(Rectangle(*roi), SHAPE), 21)
    for step in (1, 5, 12):
        assert np.array_equal(grid_in_region(allowed, step), grid_in_roi(SHAPE, roi, step, 21))


def test_a_mask_of_another_size_is_refused():
    with pytest.raises(ValueError, match="100x80 px but the images are 160x120"):
        Region(mask=np.ones((80, 100), dtype=bool), mask_name="m.png").check(SHAPE)


def test_a_rectangle_beyond_the_image_is_refused():
    with pytest.raises(ValueError, match="extends beyond"):
        Region(outline=Rectangle(100, 10, 100, 10)).check(SHAPE)


# ----------------------------------------------------------------------------- the specimen


def test_the_specimen_is_found_on_its_background_to_a_pixel_or_two():
    image, truth = specimen_scene(noise=3.0)
    found = find_specimen(image, 21)
    assert found.separated
    wrong = found.mask ^ truth
    assert wrong.sum() <= 4 * truth.shape[0]          # at most ~2 px along each of the two long edges
    assert not (found.mask & ~truth)[:, :95].any() and not (found.mask & ~truth)[:, 205:].any()
    assert found.bounds[0] in range(98, 103) and found.bounds[2] in range(96, 103)


def test_a_hole_is_left_out_and_no_subset_reaches_into_it():
    hole = (150, 200, 25)
    image, truth = specimen_scene(hole=hole, seed=3)
    found = find_specimen(image, 21)
    allowed = placeable(found.mask, 21, 2)
    rows, cols = np.nonzero(allowed)
    # the nearest allowed centre keeps a subset's half-diagonal plus the margin from the hole
    nearest = np.sqrt((cols - hole[0]) ** 2 + (rows - hole[1]) ** 2).min()
    assert nearest >= hole[2] + 10
    assert found.mask[hole[1], hole[0]] == False  # noqa: E712


def test_the_same_scene_at_16_bits_gives_the_same_specimen():
    image8, _ = specimen_scene(seed=5)
    image16 = image8.astype(np.uint16) * 257
    assert np.array_equal(find_specimen(image8, 21).mask, find_specimen(image16, 21).mask)


def test_an_image_speckled_throughout_is_all_specimen_but_its_flat_and_saturated_spots():
    image = blurred_noise((300, 300), seed=2, sigma=1.5)
    image = np.clip(40 + (image - image.min()) / np.ptp(image) * 180, 0, 255).astype(np.uint8)
    image[100:160, 100:160] = 255                        # glare: saturated, no texture
    found = find_specimen(image, 21)
    assert not found.separated or found.mask.mean() > 0.9
    assert not found.mask[110:150, 110:150].any()
    assert found.mask[:80, :80].all() and found.mask[200:, 200:].all()


def test_a_blank_image_has_no_specimen():
    found = find_specimen(np.full((64, 64), 90, np.uint8), 21)
    assert not found.mask.any() and found.bounds is None
    assert "no speckled area" in found.describe()
