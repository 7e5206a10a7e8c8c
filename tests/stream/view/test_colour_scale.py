"""Tests of stream/view/colour_scale.py: the colour map and its packing, limits that only grow to nice numbers, spacing."""

import numpy as np
import pytest

from livedic.stream.view.colour_scale import (AXIS_MANTISSAS, colormap_lut, grow_limits, grow_to_cover, nice_ceil,
                                              pack_colours, typical_spacing)
from tests.stream.view.test_logger import _grid_with_p0


def test_typical_spacing_ignores_p0_beside_a_grid_point_and_duplicates():
    x, y = _grid_with_p0(step=16)
    assert typical_spacing(np.concatenate([x, x[:20]]), np.concatenate([y, y[:20]])) == pytest.approx(16.0)
    assert typical_spacing([5.0], [7.0]) is None
    assert typical_spacing([0.0, 30.0], [0.0, 40.0]) == pytest.approx(50.0)


def test_nice_numbers_and_growing_limits():
    assert [nice_ceil(v) for v in (0.051, 0.3, 0.31, 7.0, 8.5, 1234.0)] == [0.06, 0.3, 0.4, 8.0, 10.0, 1500.0]
    assert grow_limits((-0.05, 0.05), np.array([1e-7, -1e-7])) == (-0.05, 0.05)
    assert grow_limits((-0.05, 0.05), np.linspace(-0.3, 2.2, 1000)) == (-0.3, 2.5)
    assert grow_limits((-1.0, 3.0), np.linspace(-0.1, 0.2, 50)) == (-1.0, 3.0)       # never shrinks
    with_outlier = np.concatenate([np.linspace(-1.0, 1.0, 999), [40.0]])
    assert grow_limits((-0.05, 0.05), with_outlier) == (-1.0, 1.0)                     # one stray point ignored


def test_the_colour_map_runs_from_dark_blue_to_dark_red_and_packs_opaque():
    lut = colormap_lut()
    assert lut.shape == (256, 3) and lut.dtype == np.uint8
    assert lut[0, 2] > lut[0, 0] and lut[-1, 0] > lut[-1, 2]               # turbo: blue end, red end
    packed = pack_colours([[1, 2, 3], [255, 0, 128]])
    assert packed.dtype == np.uint32 and list(packed) == [0x010203FF, 0xFF0080FF]


@pytest.mark.parametrize("value", [1e-7, 0.0123, 0.7, 3.3, 99.0, 12345.0])
def test_a_nice_ceiling_is_the_smallest_nice_number_at_or_above(value):
    nice = nice_ceil(value)
    assert nice >= value * (1 - 1e-9)
    exponent = np.floor(np.log10(nice))
    mantissa = round(nice / 10 ** exponent, 6)
    assert mantissa in (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)
    assert nice_ceil(nice) == nice                                           # a nice number is its own ceiling
    assert nice_ceil(value, AXIS_MANTISSAS) >= nice


def test_growing_to_cover_one_value_goes_to_1_2_or_5():
    assert grow_to_cover((-1.0, 1.0), 0.5) == (-1.0, 1.0)
    assert grow_to_cover((-1.0, 1.0), 1.3) == (-1.0, 2.0)
    assert grow_to_cover((-1.0, 1.0), -2.6) == (-5.0, 1.0)
    assert grow_to_cover((0.0, 100.0), 101.0) == (0.0, 200.0)


def test_nan_values_never_move_the_limits():
    assert grow_limits((-0.05, 0.05), np.array([np.nan, np.inf, -np.inf])) == (-0.05, 0.05)
    assert grow_limits((-0.05, 0.05), np.array([])) == (-0.05, 0.05)


def test_typical_spacing_is_invariant_to_translation_rotation_and_non_finite_points():
    x, y = np.meshgrid(np.arange(0.0, 200.0, 12.0), np.arange(0.0, 120.0, 12.0))
    x, y = x.ravel(), y.ravel()
    assert typical_spacing(x, y) == pytest.approx(12.0)
    angle = 0.3
    xr, yr = np.cos(angle) * x - np.sin(angle) * y + 500.0, np.sin(angle) * x + np.cos(angle) * y - 70.0
    assert typical_spacing(xr, yr) == pytest.approx(12.0, rel=1e-9)
    assert typical_spacing(np.r_[x, np.nan], np.r_[y, 3.0]) == pytest.approx(12.0)
    assert typical_spacing([], []) is None and typical_spacing([1.0, 1.0], [2.0, 2.0]) is None    # one distinct
