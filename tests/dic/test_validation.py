"""Tests of dic/validation.py: images, subsets, radii, points and guesses checked at dic's boundary, one-line errors."""

import numpy as np
import pytest

from livedic.dic.validation import (as_guess, as_image, as_points, check_radius, check_same_shape, check_subset,
                                    checked_image)


def _one_line(call, match):
    with pytest.raises(ValueError, match=match) as error:
        call()
    assert "\n" not in str(error.value)


def test_an_image_becomes_contiguous_float32():
    image = np.arange(30, dtype=np.uint16).reshape(5, 6)[:, ::2]
    out = as_image(image, "reference")
    assert out.dtype == np.float32 and out.flags.c_contiguous and np.array_equal(out, image)
    assert checked_image(image, "reference") is not None and checked_image(image, "x").dtype == np.uint16


@pytest.mark.parametrize("image, match", [
    (np.zeros((4, 4, 3)), "2-D grey"), (np.zeros((4, 4), dtype=bool), "dtype bool"),
    (np.zeros((2, 10)), "10x2 pixels: too small"), (np.array([[0, 1, 2]] * 3, dtype=float) * np.nan, "NaN"),
    (np.array(["a"] * 9).reshape(3, 3), "dtype"),
])
def test_bad_images_are_one_line_errors_naming_the_image(image, match):
    _one_line(lambda: as_image(image, "deformed"), match)
    with pytest.raises(ValueError, match="deformed"):
        as_image(image, "deformed")


def test_images_of_different_sizes_are_refused():
    check_same_shape(np.zeros((4, 5)), np.zeros((4, 5)))
    _one_line(lambda: check_same_shape(np.zeros((4, 5)), np.zeros((5, 4))), "reference is 5x4 but deformed is 4x5")


def test_the_subset_gives_its_half_width_or_a_one_line_error():
    assert check_subset(21, (100, 100)) == 10 and check_subset(np.int64(3), (3, 3)) == 1
    for subset, match in ((20, "odd integer >= 3"), (1, "odd integer >= 3"), (21.0, "odd integer number"),
                          (True, "odd integer number"), (51, "larger than the image")):
        _one_line(lambda: check_subset(subset, (40, 60)), match)


def test_the_radius_is_a_non_negative_integer():
    assert check_radius(0) == 0 and check_radius(np.int32(7)) == 7
    for radius in (-1, 2.0, True, None):
        _one_line(lambda: check_radius(radius), "search radius")


def test_points_become_float64_pairs():
    assert as_points((3, 4)).tolist() == [[3.0, 4.0]]
    points = as_points([[1, 2], [3, 4], [5, 6]])
    assert points.dtype == np.float64 and points.shape == (3, 2) and points.flags.c_contiguous
    _one_line(lambda: as_points(np.zeros((3, 3))), r"shape \(N, 2\)")
    _one_line(lambda: as_points([[1.0, np.inf]]), "NaN or infinite")


def test_a_guess_is_one_pair_for_all_or_one_per_point_and_may_hold_nan():
    assert as_guess(None, 3).tolist() == [[0.0, 0.0]] * 3
    assert as_guess((1.5, -2), 2).tolist() == [[1.5, -2.0]] * 2
    nan_row = as_guess([[np.nan, 0.0], [1.0, 2.0]], 2)
    assert np.isnan(nan_row[0, 0]) and nan_row[1].tolist() == [1.0, 2.0]
    _one_line(lambda: as_guess(np.zeros((3, 2)), 2), r"one per point \(shape \(2, 2\)\)")
