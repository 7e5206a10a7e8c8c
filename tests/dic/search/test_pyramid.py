"""dic.search.pyramid: how many levels a search gets, and the Burt-Adelson pyramid it runs on."""

import numpy as np
import pytest

from livedic.dic.search.pyramid import build_pyramid, levels_for


@pytest.mark.parametrize("radius, top_radius, expected", [(3, 3, 0), (2, 3, 0), (4, 3, 1), (10, 3, 2), (48, 3, 4),
                                                          (48, 6, 3)])
def test_levels_bring_the_top_box_radius_within_the_top_radius(radius, top_radius, expected):
    levels = levels_for(radius, top_radius, 10, (4096, 4096))
    assert levels == expected
    assert radius >> levels <= top_radius


def test_levels_are_capped_so_the_top_level_still_holds_a_subset():
    # a 21 px subset (+2) needs 23 px at the top level: a 64 px image allows one halving, not the four wanted
    assert levels_for(48, 3, 10, (64, 64)) == 1
    assert levels_for(48, 3, 10, (40, 4096)) == 0


def test_levels_have_half_the_size_rounded_up():
    image = np.zeros((101, 64), dtype=np.float32)
    shapes = [level.shape for level in build_pyramid(image, 3)]
    assert shapes == [(101, 64), (51, 32), (26, 16), (13, 8)]


def test_the_filter_keeps_a_constant_and_samples_a_ramp_at_every_second_pixel():
    flat = np.full((40, 40), 123.0, dtype=np.float32)
    for level in build_pyramid(flat, 2):
        np.testing.assert_allclose(level, 123.0, rtol=1e-6)
    ramp = np.tile(np.arange(64, dtype=np.float32), (32, 1))          # f(x) = x
    coarse = build_pyramid(ramp, 1)[1]
    # the symmetric binomial filter reproduces a linear function: pixel j of level 1 is f(2j), away from the border
    np.testing.assert_allclose(coarse[:, 1:-1], np.tile(2.0 * np.arange(1, 31), (16, 1)), atol=1e-4)
