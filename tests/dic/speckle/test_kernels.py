"""Tests of dic/speckle/kernels.py: spot profiles, windows, the branch-free exp, the 1-D inverse, the inverse
maps and the grey-level conversion, each against its closed form."""

import math

import numpy as np
import pytest

from livedic.dic.speckle.kernels import (_AFFINE, _TRANSLATION, _exp_neg, _invert_1d, _invert_1d_table,
                                         _inverse_map, _spot_profile, _to_grey, _window)


def test_point_sampled_profile_is_the_gaussian():
    out = np.empty(7)
    _spot_profile(3.3, 0, 7, 2.0, False, out)
    np.testing.assert_allclose(out, np.exp(-((np.arange(7) - 3.3) / 2.0) ** 2), rtol=1e-15)


@pytest.mark.parametrize("centre", [3.3, 0.05, 12.0])
def test_pixel_integrated_profile_is_the_mean_over_each_pixel(centre):
    out = np.empty(8)
    _spot_profile(centre, 2, 8, 1.5, True, out)
    s = (np.arange(2000) + 0.5) / 2000 - 0.5                       # midpoint rule over each pixel
    expected = [np.exp(-((i + s - centre) / 1.5) ** 2).mean() for i in range(2, 10)]
    np.testing.assert_allclose(out, expected, rtol=1e-6, atol=1e-14)


def test_far_tail_of_the_integrated_profile_keeps_its_relative_accuracy():
    out = np.empty(1)
    _spot_profile(0.0, 9, 1, 1.0, True, out)                       # ~1e-36: erf differences would give 0
    exact = 0.5 * math.sqrt(math.pi) * (math.erfc(8.5) - math.erfc(9.5))
    assert out[0] == pytest.approx(exact, rel=1e-12) and out[0] > 0


@pytest.mark.parametrize("centre, reach, n, expected", [(5.0, 2.0, 20, (3, 5)), (5.2, 2.0, 20, (4, 4)),
                                                        (0.5, 3.0, 20, (0, 4)), (18.0, 3.0, 20, (15, 5)),
                                                        (-10.0, 2.0, 20, (None, 0)), (40.0, 2.0, 20, (None, 0))])
def test_window_is_the_pixels_within_reach_inside_the_image(centre, reach, n, expected):
    first, count = _window(centre, reach, n)
    assert count == expected[1] and (count == 0 or first == expected[0])     # no first pixel of an empty window


def test_branch_free_exp_is_within_its_stated_relative_error():
    t = np.linspace(0.0, 36.0, 20001)
    got = np.array([_exp_neg(v) for v in t])
    assert np.max(np.abs(got / np.exp(-t) - 1.0)) < 5e-14


@pytest.mark.parametrize("A, k, phase", [(1.8, 2 * math.pi / 40, 0.4), (-3.0, 0.3, 1.0), (0.0, 1.0, 0.0)])
def test_the_1d_inverse_solves_its_equation(A, k, phase):
    s = np.linspace(-50, 50, 101)
    table, ok = np.empty(s.size), np.empty(s.size, dtype=np.bool_)
    _invert_1d_table(s, A, k, phase, table, ok)
    assert ok.all()
    np.testing.assert_allclose(table + A * np.sin(k * table + phase), s, atol=1e-10)
    assert _invert_1d(s[3], A, k, phase)[0] == table[3]


def test_inverse_maps_of_a_translation_and_an_affine_map():
    assert _inverse_map(_TRANSLATION, np.array([1.5, -2.0]), 10.0, 20.0) == (8.5, 22.0)
    F = np.array([[1.1, 0.2], [-0.1, 0.9]])                       # I + grad U
    Finv = np.linalg.inv(F)
    cx, cy, u, v = 4.0, 7.0, 0.5, -0.3
    p = np.array([cx, cy, u, v, *Finv.ravel()])
    X, Y = 13.0, -2.0
    x, y = np.array([cx + u, cy + v]) + F @ np.array([X - cx, Y - cy])
    assert _inverse_map(_AFFINE, p, x, y) == pytest.approx((X, Y), abs=1e-12)


def test_grey_conversion_scales_adds_noise_rounds_and_clips():
    image = np.array([[0.0, 0.2, 0.5], [0.999, 1.5, -0.1]])
    out = np.empty(image.shape, dtype=np.uint8)
    _to_grey(image, 204.0, np.zeros((0, 0)), 255.0, out)
    assert out.tolist() == [[0, 41, 102], [204, 255, 0]]
    noise = np.full(image.shape, 0.6)
    _to_grey(image, 204.0, noise, 255.0, out)
    assert out.tolist() == [[1, 41, 103], [204, 255, 0]]
