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
from scipy.optimize import brentq

from livedic.dic.speckle import SpecklePattern, affine, render, sinusoid, translation

SHAPE = (72, 96)          # (H, W): not square, so a swapped axis shows
DENSITY = 1000 / 256**2   # the paper's 256 x 256 / 1000 speckles
REL_TOL = 1e-9            # relative to the mean intensity; the 5R cutoff is ~1e-11


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern(SHAPE, density=DENSITY, radius=4.0, seed=7)


def brute(pattern, X, Y):
    """Analytic intensity (I0 = 1) at reference points, summed over every centre."""
    X = np.asarray(X, dtype=np.float64)[..., None]
    Y = np.asarray(Y, dtype=np.float64)[..., None]
    xs, ys = pattern.centres[:, 0], pattern.centres[:, 1]
    return np.exp(-((X - xs) ** 2 + (Y - ys) ** 2) / pattern.radius**2).sum(axis=-1)


def pixel_grid(shape):
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    return cols.astype(np.float64), rows.astype(np.float64)


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


def test_translation_helper_equals_tuple(pattern):
    a = render(pattern, (0.25, -1.5), bit_depth=None)
    b = render(pattern, translation(0.25, -1.5), bit_depth=None)
    np.testing.assert_array_equal(a, b)


def _check_inverse_map(pattern, field, image, solve, n=300, seed=0, forward_differs=True):
    """For sample pixels x: X solved independently must satisfy X + U(X) = x and g(x) = I(X)."""
    rng = np.random.default_rng(seed)
    rows = rng.integers(0, SHAPE[0], n)
    cols = rng.integers(0, SHAPE[1], n)
    X, Y = solve(cols.astype(float), rows.astype(float))
    U, V = field(X, Y)
    np.testing.assert_allclose(X + U, cols, atol=1e-9)
    np.testing.assert_allclose(Y + V, rows, atol=1e-9)
    truth = brute(pattern, X, Y)
    assert np.max(np.abs(image[rows, cols] - truth)) < REL_TOL * truth.mean()
    if forward_differs:   # power check: the common mistake I(x - U(x)) gives visibly different values
        Uf, Vf = field(cols.astype(float), rows.astype(float))
        assert np.max(np.abs(image[rows, cols] - brute(pattern, cols - Uf, rows - Vf))) > 1e-3


def test_affine_inverse_map_is_exact(pattern):
    field = affine(u=1.2, v=-0.7, ux=0.04, uy=-0.02, vx=0.03, vy=-0.05, centre=(40.0, 30.0))
    image = render(pattern, field, bit_depth=None)
    F = np.array([[1.04, -0.02], [0.03, 0.95]])

    def solve(x, y):
        rhs = np.stack([x - 40.0 - 1.2, y - 30.0 + 0.7])
        XY = np.linalg.solve(F, rhs)
        return XY[0] + 40.0, XY[1] + 30.0

    _check_inverse_map(pattern, field, image, solve)


@pytest.mark.parametrize("axis, direction", [("x", "v"), ("y", "u"), ("x", "u"), ("y", "v")])
def test_sinusoid_inverse_map_is_exact(pattern, axis, direction):
    A, P, phase = 1.8, 40.0, 0.4        # 2 pi A / P = 0.28: invertible along its own axis
    field = sinusoid(A, P, axis=axis, direction=direction, phase=phase)
    image = render(pattern, field, bit_depth=None)
    k = 2 * math.pi / P

    def solve(x, y):
        X, Y = x.copy(), y.copy()
        along = X if axis == "x" else Y          # coordinate the sine runs along
        moved = X if direction == "u" else Y     # coordinate that is displaced
        for i in range(x.size):
            if (axis == "x") == (direction == "u"):
                s = along[i]
                moved[i] = brentq(lambda t: t + A * math.sin(k * t + phase) - s, s - 2 * A, s + 2 * A,
                                  xtol=1e-14, rtol=1e-15)
            else:
                moved[i] = moved[i] - A * math.sin(k * along[i] + phase)
        return X, Y

    # across its axis (e.g. V(X)), X = x exactly, so I(x - U(x)) is already right
    _check_inverse_map(pattern, field, image, solve, forward_differs=(axis == "x") == (direction == "u"))


def test_general_callable_inverse_map_is_exact(pattern):
    def field(X, Y):   # a smooth, non-affine, non-separable field
        return 0.5 + 0.002 * (X - 48.0) ** 2 - 0.01 * Y, -0.3 + 0.0008 * X * Y

    image = render(pattern, field, bit_depth=None)

    def solve(x, y):   # Newton with the analytic Jacobian, independent of the simulator's iteration
        X, Y = x.copy(), y.copy()
        for _ in range(40):
            U, V = field(X, Y)
            rx, ry = X + U - x, Y + V - y
            a, b = 1 + 0.004 * (X - 48.0), -0.01
            c, d = 0.0008 * Y, 1 + 0.0008 * X
            det = a * d - b * c
            X, Y = X - (d * rx - b * ry) / det, Y - (a * ry - c * rx) / det
        return X, Y

    _check_inverse_map(pattern, field, image, solve, n=150)


def test_helpers_agree_with_the_general_callable_path(pattern):
    for field in (affine(u=0.4, ux=0.02, vy=-0.01, uy=0.01, centre=(48, 36)), sinusoid(1.5, 30.0, direction="u")):
        fast = render(pattern, field, bit_depth=None)
        slow = render(pattern, lambda X, Y, f=field: f(X, Y), bit_depth=None)
        assert np.max(np.abs(fast - slow)) < REL_TOL * fast.mean()


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
# Grey levels, bit depth, noise
# --------------------------------------------------------------------------- #

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


# --------------------------------------------------------------------------- #
# Pixel integration
# --------------------------------------------------------------------------- #

def test_pixel_integration_approaches_point_sampling_for_large_spots():
    diffs = {}
    for R in (2.0, 16.0):
        p = SpecklePattern((64, 80), density=DENSITY * 16 / R**2, radius=R, seed=5)
        point = render(p, (0.2, 0.6), bit_depth=None)
        area = render(p, (0.2, 0.6), bit_depth=None, pixel_integration=True)
        diffs[R] = np.max(np.abs(area - point)) / point.mean()
        # averaging over pixels keeps the mean intensity (up to border effects)
        assert abs(area[8:-8, 8:-8].mean() / point[8:-8, 8:-8].mean() - 1) < 0.01
    assert diffs[16.0] < 2e-3
    assert diffs[2.0] > 0.05
    assert diffs[16.0] < diffs[2.0] / 30     # error falls roughly as 1/R^2


def test_pixel_integration_erf_matches_brute_quadrature(pattern):
    u, v = 0.3, -0.45
    erf_form = render(pattern, (u, v), bit_depth=None, pixel_integration=True)
    gauss_legendre = render(pattern, lambda X, Y: (np.full_like(X, u), np.full_like(Y, v)),
                            bit_depth=None, pixel_integration=True)
    assert np.max(np.abs(erf_form - gauss_legendre)) < 1e-8 * erf_form.mean()
    # independent check on a few pixels: midpoint rule with 40 x 40 points per pixel
    s = (np.arange(40) + 0.5) / 40 - 0.5
    for r, c in ((5, 7), (40, 60), (71, 95)):
        X, Y = np.meshgrid(c + s - u, r + s - v)
        assert erf_form[r, c] == pytest.approx(brute(pattern, X, Y).mean(), rel=1e-4)


def test_pixel_integration_of_affine_field(pattern):
    field = affine(ux=0.05, vy=-0.03, centre=(48, 36))
    img = render(pattern, field, bit_depth=None, pixel_integration=True)
    s = (np.arange(40) + 0.5) / 40 - 0.5
    for r, c in ((10, 12), (50, 80)):
        x, y = np.meshgrid(c + s, r + s)
        truth = brute(pattern, 48 + (x - 48) / 1.05, 36 + (y - 36) / 0.97).mean()
        assert img[r, c] == pytest.approx(truth, rel=1e-4)


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


def test_non_invertible_fields_raise(pattern):
    with pytest.raises(ValueError, match="not invertible"):
        render(pattern, lambda X, Y: (-2.0 * X, 0.0 * Y))
    with pytest.raises(ValueError, match="folds"):
        render(pattern, affine(ux=-1.5))
    with pytest.raises(ValueError, match="folds"):
        render(pattern, sinusoid(5.0, 20.0, axis="x", direction="u"))
    with pytest.raises(ValueError, match="pattern must be"):
        render(np.zeros((4, 4)))
