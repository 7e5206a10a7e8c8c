"""Physics of the exact speckle simulator (dic.speckle).

Ground truth here is the Zhou & Goodson sum evaluated by brute force in numpy
over every centre of the pattern, with inverse maps solved independently
(closed form, scipy's brentq, or Newton with an analytic Jacobian): the
simulator's bin grid, tiling, cutoff,
polynomial exp and Newton iterations are all checked against it.
"""

import math

import numba
import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, affine, render
from tests.dic.speckle.conftest import DENSITY, REL_TOL, SHAPE, brute, pixel_grid

# --------------------------------------------------------------------------- #
# Exactness of reference and deformed images
# --------------------------------------------------------------------------- #

def test_reference_is_the_analytic_sum_at_pixel_centres(pattern):
    ref = render(pattern, None, bit_depth=None)
    assert ref.shape == SHAPE and ref.dtype == np.float64
    x, y = pixel_grid(SHAPE)
    truth = brute(pattern, x, y)
    assert np.max(np.abs(ref - truth)) < REL_TOL * truth.mean()


def test_integer_translation_is_an_exact_shift(pattern):
    ref = render(pattern, None, bit_depth=None)
    moved = render(pattern, (3, -2), bit_depth=None)
    # content at X moves to X + (3, -2): g(x, y) = I(x - 3, y + 2)
    np.testing.assert_allclose(moved[:-2, 3:], ref[2:, :-3], rtol=1e-9, atol=1e-12)
    assert not np.allclose(moved, ref, atol=1e-3)


def test_subpixel_translation_matches_brute_force(pattern):
    u, v = 0.3, 0.7
    moved = render(pattern, (u, v), bit_depth=None)
    x, y = pixel_grid(SHAPE)
    truth = brute(pattern, x - u, y - v)
    assert np.max(np.abs(moved - truth)) < REL_TOL * truth.mean()
    # the opposite sign convention would be far off
    assert np.max(np.abs(moved - brute(pattern, x + u, y + v))) > 0.1


# --------------------------------------------------------------------------- #
# Cutoff and pattern statistics
# --------------------------------------------------------------------------- #

@pytest.mark.parametrize("cutoff", [3.0, 5.0])
def test_cutoff_error_is_within_its_documented_bound(cutoff):
    p = SpecklePattern(SHAPE, density=DENSITY, radius=4.0, seed=3, cutoff=cutoff)
    x, y = pixel_grid(SHAPE)
    field = affine(ux=0.03, vy=0.02, centre=(48, 36))
    X = 48 + (x - 48) / 1.03
    Y = 36 + (y - 36) / 1.02
    mean = brute(p, x, y).mean()
    for image, truth in ((render(p, None, bit_depth=None), brute(p, x, y)),          # splat path
                         (render(p, field, bit_depth=None), brute(p, X, Y))):        # tile path
        err = np.max(np.abs(image - truth))
        # expected omitted intensity is exp(-cutoff^2) of the mean; allow local clustering
        assert err < 50 * math.exp(-cutoff**2) * mean + 1e-12
        assert np.all(image <= truth + 1e-12)      # truncation only ever drops terms


def test_intensity_method_is_the_analytic_sum(pattern):
    rng = np.random.default_rng(4)
    X = rng.uniform(-30, 120, (5, 40))     # includes points in the margin
    Y = rng.uniform(-30, 100, (5, 40))
    truth = brute(pattern, X, Y)
    got = pattern.intensity(X, Y)
    assert got.shape == X.shape
    assert np.max(np.abs(got - truth)) < REL_TOL * truth.mean()


def test_cutoff_three_is_measurably_truncated():
    p = SpecklePattern(SHAPE, density=DENSITY, radius=4.0, seed=3, cutoff=3.0)
    x, y = pixel_grid(SHAPE)
    assert np.max(np.abs(render(p, None, bit_depth=None) - brute(p, x, y))) > 1e-8


def test_speckle_counts_and_margin_density():
    H, W = SHAPE
    p = SpecklePattern(SHAPE, n_speckles=150, radius=3.0, seed=1, margin=60)
    xs, ys = p.centres[:, 0], p.centres[:, 1]
    inside = (xs >= -0.5) & (xs < W - 0.5) & (ys >= -0.5) & (ys < H - 0.5)
    assert inside.sum() == 150 == p.n_speckles
    assert np.all((xs >= -60.5) & (xs <= W - 0.5 + 60) & (ys >= -60.5) & (ys <= H - 0.5 + 60))
    density = 150 / (H * W)
    for band, area in ((xs < -0.5, 60 * (H + 120)), (xs >= W - 0.5, 60 * (H + 120)),
                       (ys < -0.5, 60 * (W + 120)), (ys >= H - 0.5, 60 * (W + 120))):
        count = band.sum()
        expected = density * area
        assert abs(count - expected) < 5 * math.sqrt(expected)
    p2 = SpecklePattern((512, 640), density=0.02, radius=2.0, seed=0)
    assert p2.n_speckles == round(0.02 * 512 * 640)
    paper = SpecklePattern()                      # the paper's setting by default
    assert (paper.shape, paper.n_speckles, paper.radius) == ((256, 256), 1000, 4.0)
    # centres in the image are uniform: each quadrant holds about a quarter
    xs, ys = paper.centres[:, 0], paper.centres[:, 1]
    inside = (xs >= -0.5) & (xs < 255.5) & (ys >= -0.5) & (ys < 255.5)
    quadrant = (xs[inside] >= 127.5).astype(int) + 2 * (ys[inside] >= 127.5)
    assert np.all(np.abs(np.bincount(quadrant, minlength=4) - 250) < 5 * math.sqrt(250 * 0.75))


def test_seeds_reproduce_and_differ():
    a = render(SpecklePattern(SHAPE, density=DENSITY, seed=11))
    b = render(SpecklePattern(SHAPE, density=DENSITY, seed=11))
    c = render(SpecklePattern(SHAPE, density=DENSITY, seed=12))
    np.testing.assert_array_equal(a, b)
    assert np.mean(a != c) > 0.5


def test_result_does_not_depend_on_thread_count(pattern):
    field = affine(u=0.3, ux=0.01, centre=(48, 36))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = (render(pattern, (0.4, 0.2), bit_depth=None), render(pattern, field, bit_depth=None))
    finally:
        numba.set_num_threads(before)
    many = (render(pattern, (0.4, 0.2), bit_depth=None), render(pattern, field, bit_depth=None))
    for a, b in zip(one, many):
        np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------- #
# Input validation
# --------------------------------------------------------------------------- #

@pytest.mark.parametrize("kwargs, match", [
    ({"shape": (0, 10)}, "shape H"),
    ({"shape": (10,)}, "shape must be"),
    ({"shape": (10.5, 10)}, "shape H"),
    ({"radius": 0.0}, "radius"),
    ({"radius": -1.0}, "radius"),
    ({"n_speckles": 0}, "n_speckles"),
    ({"n_speckles": -5}, "n_speckles"),
    ({"density": -0.1}, "density"),
    ({"density": 0.01, "n_speckles": 10}, "either n_speckles or density"),
    ({"seed": -1}, "seed"),
    ({"margin": 5.0}, "margin"),
    ({"cutoff": 2.0}, "cutoff"),
])
def test_bad_pattern_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SpecklePattern(**kwargs)

