"""Tests of dic/tracking/grid.py: grids centred in an ROI with every subset inside, and the step for N points."""

import numpy as np
import pytest

from livedic.dic.tracking import grid_in_roi, step_for_count


def test_grid_stays_in_roi_and_image_and_is_centred():
    points = grid_in_roi((200, 300), (40, 30, 101, 80), 10, 21)
    x, y = points[:, 0], points[:, 1]
    assert x.min() - 10 >= 40 and x.max() + 10 <= 140 and y.min() - 10 >= 30 and y.max() + 10 <= 109
    assert np.all(np.diff(np.unique(x)) == 10) and np.all(np.diff(np.unique(y)) == 10)
    assert abs((x.min() - 40) - (140 - x.max())) <= 1       # centred
    clipped = grid_in_roi((100, 100), (-50, -50, 400, 400), 20, 11)   # ROI beyond the image: clipped to it
    assert clipped.min() >= 5 and clipped.max() <= 94
    assert len(grid_in_roi((64, 64), None, 8, 21)) == 36      # centres 10..53 hold 6 steps of 8


@pytest.mark.parametrize("roi, step, subset, words", [
    ((0, 0, 10, 10), 5, 21, "cannot hold"), ((0, 0, 50, 50), 0, 21, "step"),
    ((0, 0, 50, 50), 5, 20, "odd"), ((0, 0, -5, 50), 5, 21, "positive"), ((0, 0, 5), 5, 21, "four"),
])
def test_bad_grid_raises(roi, step, subset, words):
    with pytest.raises(ValueError, match=words):
        grid_in_roi((100, 100), roi, step, subset)


def test_step_for_count_gives_about_the_wanted_number():
    roi = (346, 185, 332, 655)
    step = step_for_count(roi, 1000, 21)
    assert 800 <= len(grid_in_roi((1024, 1024), roi, step, 21)) <= 1250


def test_a_grid_is_row_by_row_at_integer_pixels():
    points = grid_in_roi((50, 60), (0, 0, 60, 50), 7, 11)
    assert points.dtype == np.float64 and np.array_equal(points, np.round(points))
    order = np.lexsort((points[:, 0], points[:, 1]))
    assert np.array_equal(order, np.arange(len(points)))       # sorted by row, then column


def test_an_roi_that_holds_exactly_one_subset_gives_one_point_at_its_centre():
    assert grid_in_roi((100, 100), (30, 40, 21, 21), 5, 21).tolist() == [[40.0, 50.0]]


@pytest.mark.parametrize("n_points", [10, 100, 400])
def test_step_for_count_is_the_best_step_near_the_square_root(n_points):
    roi, subset = (0, 0, 300, 200), 11
    step = step_for_count(roi, n_points, subset)
    count = lambda s: (290 // s + 1) * (190 // s + 1)            # the count step_for_count reasons with
    assert all(abs(count(step) - n_points) <= abs(count(s) - n_points) for s in range(max(step - 2, 1), step + 3))


def test_step_for_one_point_spans_the_roi():
    assert step_for_count((0, 0, 300, 200), 1, 11) == 290
    assert len(grid_in_roi((200, 300), (0, 0, 300, 200), step_for_count((0, 0, 300, 200), 1, 11), 11)) == 1
