"""Tests of dic/region/placement.py: the Region's pixels and checks, placeable subsets, grids on a region."""

import numpy as np
import pytest

from livedic.dic.region import (Circle, Polygon, Rectangle, Region, bounding_box, centred_axis, grid_in_region,
                                placeable, shape_mask, step_for_area)
from livedic.dic.region.placement import STRADDLE_SHARES, straddling
from livedic.dic.tracking import grid_in_roi

SHAPE = (120, 160)


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


def test_a_polygon_outside_the_image_is_refused_and_one_inside_is_not():
    with pytest.raises(ValueError, match="lies outside the 160x120 image"):
        Region(outline=Polygon(((200, 10), (250, 10), (220, 50)))).check(SHAPE)
    Region(outline=Polygon(((10, 10), (150, 10), (80, 110)))).check(SHAPE)       # raises nothing
    Region(mask=np.ones(SHAPE, dtype=bool)).check(SHAPE)


def test_the_region_is_outline_and_mask_and_within_less_the_exclusions():
    mask = np.zeros(SHAPE, dtype=bool)
    mask[:, :100] = True
    within = np.zeros(SHAPE, dtype=bool)
    within[20:, :] = True
    spec = Region(outline=Rectangle(10, 10, 120, 100), mask=mask, exclude=(Rectangle(50, 50, 10, 10),))
    expected = shape_mask(Rectangle(10, 10, 120, 100), SHAPE) & mask & within
    expected[50:60, 50:60] = False
    assert np.array_equal(spec.pixels(SHAPE, within), expected)
    assert within[20:, :].all()                       # the caller's array is not changed
    assert Region().pixels(SHAPE).all() and not Region().given
    assert spec.given and Region(mask=mask).given


def test_a_region_describes_itself_and_its_metadata():
    spec = Region(outline=Rectangle(1, 2, 3, 4), mask=np.ones(SHAPE, bool), mask_name="m.png",
                  exclude=(Circle(5, 6, 7),))
    assert spec.describe() == ("ROI " + Rectangle(1, 2, 3, 4).describe() + ", mask m.png, excluding "
                               + Circle(5, 6, 7).describe())
    assert spec.as_metadata() == {"roi": Rectangle(1, 2, 3, 4).describe(), "mask": "m.png",
                                  "exclude": [Circle(5, 6, 7).describe()]}
    assert Region().describe() == "the whole image"
    assert Region().as_metadata() == {"roi": None, "mask": None, "exclude": []}


def test_a_margin_grows_the_subset_on_each_side():
    region = np.zeros(SHAPE, dtype=bool)
    region[10:90, 20:140] = True
    assert np.array_equal(placeable(region, 11, margin=3), placeable(region, 17))
    allowed = placeable(region, 11, margin=3)
    rows, cols = np.nonzero(allowed)
    assert (rows.min(), rows.max(), cols.min(), cols.max()) == (18, 81, 28, 131)


def test_subsets_across_the_mask_edge_straddle_it_and_the_others_do_not():
    mask = np.zeros(SHAPE, dtype=bool)
    mask[:, :80] = True                               # edge between columns 79 and 80
    points = np.array([(79.0, 60.0), (75.0, 60.0), (85.0, 60.0), (40.0, 60.0), (120.0, 60.0), (90.0, 60.0)])
    # share inside: 11/21, 15/21, 5/21, all, none, 0
    assert straddling(points, mask, 21).tolist() == [True, True, True, False, False, False]
    # one column of 21 inside (4.8 %) is under the lower share: the found edge is good to a pixel or so
    assert 1 / 21 < STRADDLE_SHARES[0] and not straddling(np.array([(89.0, 60.0)]), mask, 21)[0]
    assert straddling(np.array([(88.0, 60.0)]), mask, 21)[0]


def test_step_for_area_gives_about_n_points():
    assert step_for_area(10000, 100) == 10
    assert step_for_area(10000, 1) == 100 and step_for_area(0, 50) == 1
    assert step_for_area(5, 1000) == 1


def test_bounding_box_of_a_mask():
    mask = np.zeros(SHAPE, dtype=bool)
    assert bounding_box(mask) is None
    mask[7, 30] = mask[40, 12] = True
    assert bounding_box(mask) == (12, 7, 19, 34)


@pytest.mark.parametrize("lo, hi, step, expected", [(0, 10, 5, [0, 5, 10]), (0, 11, 5, [0, 5, 10]),
                                                    (0, 12, 5, [1, 6, 11]), (3, 3, 4, [3]), (0, 3, 5, [1])])
def test_centred_axis_splits_the_leftover_at_both_ends(lo, hi, step, expected):
    assert centred_axis(lo, hi, step).tolist() == expected


def test_a_grid_on_no_allowed_pixel_is_empty_and_a_bad_step_is_refused():
    assert grid_in_region(np.zeros(SHAPE, dtype=bool), 5).shape == (0, 2)
    for step in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="grid step"):
            grid_in_region(np.ones(SHAPE, dtype=bool), step)


def test_a_grid_keeps_only_allowed_points():
    allowed = placeable(Region(outline=Circle(80, 60, 50)).pixels(SHAPE), 11)
    points = grid_in_region(allowed, 4).astype(int)
    assert len(points) > 50 and allowed[points[:, 1], points[:, 0]].all()
