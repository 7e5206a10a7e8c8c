"""Tests of dic/speckle/render.py: grey levels at 8, 12 or 16 bits with one scale per pattern, noise, float
output, and the displacement and argument checks."""

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, affine, render, translation
from tests.dic.speckle.conftest import DENSITY, SHAPE


def test_translation_helper_equals_tuple(pattern):
    a = render(pattern, (0.25, -1.5), bit_depth=None)
    b = render(pattern, translation(0.25, -1.5), bit_depth=None)
    np.testing.assert_array_equal(a, b)


def test_one_global_scale_for_all_images(pattern):
    ref = render(pattern, None, bit_depth=8)
    assert ref.max() == round(0.8 * 255)
    # compression brightens the pattern: a per-image normalisation would hide that
    squeeze = affine(ux=-0.15, vy=-0.15, centre=(48, 36))
    for displacement in ((2.5, -1.25), squeeze):
        img = render(pattern, displacement, bit_depth=8)
        exact = render(pattern, displacement, bit_depth=None)
        expected = np.rint(np.clip(pattern.grey_scale(8) * exact, 0, 255))
        np.testing.assert_array_equal(img, expected)
    big = SpecklePattern((128, 160), density=DENSITY, seed=1)
    reference = render(big).astype(float)
    moved = render(big, (0.5, 0.3)).astype(float)
    assert abs(moved.mean() / reference.mean() - 1) < 0.02
    # frames whose brightest spot is brighter / dimmer than the reference's keep the
    # reference's scale: a per-image normalisation would put every maximum at 204
    for shift in ((0.0, 40.0), (-40.0, 0.0)):
        exact_max = render(big, shift, bit_depth=None).max()
        assert abs(exact_max / big.peak - 1) > 0.1
        assert render(big, shift).max() == round(0.8 * 255 * exact_max / big.peak)


@pytest.mark.parametrize("depth, dtype, full", [(8, np.uint8, 255), (12, np.uint16, 4095), (16, np.uint16, 65535)])
def test_bit_depths(pattern, depth, dtype, full):
    img = render(pattern, (0.5, 0.5), bit_depth=depth, noise_sigma=3.0 * full / 255, noise_seed=4)
    assert img.dtype == dtype and img.shape == SHAPE
    assert img.max() <= full
    clean = render(pattern, None, bit_depth=depth)
    assert clean.max() == round(0.8 * full)
    np.testing.assert_allclose(clean / full, render(pattern, None, bit_depth=8) / 255,
                               atol=0.5 / 255 + 0.5 / full + 1e-12)


def test_float_output_is_exact_without_rounding(pattern):
    img = render(pattern, (0.5, 0.5), bit_depth=None)
    assert img.dtype == np.float64
    assert np.any(img != np.round(img))


def test_noise_level_and_independence():
    p = SpecklePattern((128, 160), density=DENSITY, seed=2)
    clean = render(p, None, bit_depth=16).astype(float)
    n1 = render(p, None, bit_depth=16, noise_sigma=40.0, noise_seed=1).astype(float) - clean
    n2 = render(p, None, bit_depth=16, noise_sigma=40.0, noise_seed=2).astype(float) - clean
    n1_again = render(p, None, bit_depth=16, noise_sigma=40.0, noise_seed=1).astype(float) - clean
    for n in (n1, n2):
        assert abs(n.std() / 40.0 - 1) < 0.03
        assert abs(n.mean()) < 1.0
    assert abs(np.corrcoef(n1.ravel(), n2.ravel())[0, 1]) < 0.03
    np.testing.assert_array_equal(n1, n1_again)
    fl = render(p, None, bit_depth=None, noise_sigma=0.05, noise_seed=3) - render(p, None, bit_depth=None)
    assert abs(fl.std() / 0.05 - 1) < 0.03
    # 8-bit: noise is added before rounding, so small noise dithers rather than vanishing
    q = render(p, None, noise_sigma=0.6, noise_seed=5).astype(float) - render(p, None).astype(float)
    assert 0.5 < q.std() < 0.9


@pytest.mark.parametrize("kwargs, match", [
    ({"bit_depth": 10}, "bit_depth"),
    ({"bit_depth": True}, "bit_depth"),
    ({"noise_sigma": -1.0}, "noise_sigma"),
    ({"noise_sigma": float("nan")}, "noise_sigma"),
    ({"noise_seed": -3}, "noise_seed"),
    ({"displacement": (1.0,)}, "displacement"),
    ({"displacement": "left"}, "displacement"),
    ({"displacement": (float("inf"), 0.0)}, "translation u"),
    ({"displacement": lambda X, Y: (X[:, :1], Y)}, "shape"),
    ({"displacement": lambda X, Y: X}, "pair"),
    ({"displacement": lambda X, Y: (X * np.nan, Y)}, "NaN"),
    ({"displacement": (500.0, 0.0)}, "margin"),
    ({"displacement": affine(ux=-0.5, centre=(0, 0))}, "margin"),
])
def test_bad_render_arguments(pattern, kwargs, match):
    with pytest.raises(ValueError, match=match):
        render(pattern, **kwargs)


def test_no_displacement_is_the_reference_and_a_zero_translation_too(pattern):
    reference = render(pattern, bit_depth=None)
    np.testing.assert_array_equal(render(pattern, None, bit_depth=None), reference)
    np.testing.assert_array_equal(render(pattern, (0, 0), bit_depth=None), reference)
    np.testing.assert_array_equal(render(pattern, translation(0.0, 0.0), bit_depth=None), reference)


def test_grey_levels_are_the_scaled_intensity_rounded_and_clipped(pattern):
    exact = render(pattern, (0.3, 0.1), bit_depth=None)
    for depth, full in ((8, 255), (12, 4095)):
        np.testing.assert_array_equal(render(pattern, (0.3, 0.1), bit_depth=depth),
                                      np.rint(np.clip(pattern.grey_scale(depth) * exact, 0, full)))
    # heavy noise pushes pixels past both ends: they are clipped, never wrapped
    noisy = render(pattern, (0.3, 0.1), noise_sigma=300.0, noise_seed=1)
    assert noisy.min() == 0 and noisy.max() == 255


@pytest.mark.parametrize("kwargs, match", [({"pixel_integration": 1}, "pixel_integration"),
                                           ({"noise_seed": 1.5}, "noise_seed"),
                                           ({"noise_sigma": "1"}, "noise_sigma")])
def test_more_bad_arguments_are_one_line_errors(pattern, kwargs, match):
    with pytest.raises(ValueError, match=match) as error:
        render(pattern, **kwargs)
    assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="pattern must be a SpecklePattern"):
        render(np.zeros((4, 4)))
