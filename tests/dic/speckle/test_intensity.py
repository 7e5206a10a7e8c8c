"""Tests of dic/speckle/intensity.py: every pixel mapped back to the reference exactly (closed form, 1-D table,
Newton for any callable), point-sampled or integrated over the pixel, and fields that cannot be inverted."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from livedic.dic.speckle import SpecklePattern, affine, render, sinusoid
from livedic.dic.speckle.intensity import INVERSE_TOLERANCE, _invert_callable
from tests.dic.speckle.conftest import DENSITY, REL_TOL, SHAPE, brute


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


def test_non_invertible_fields_raise(pattern):
    with pytest.raises(ValueError, match="not invertible"):
        render(pattern, lambda X, Y: (-2.0 * X, 0.0 * Y))
    with pytest.raises(ValueError, match="folds"):
        render(pattern, affine(ux=-1.5))
    with pytest.raises(ValueError, match="folds"):
        render(pattern, sinusoid(5.0, 20.0, axis="x", direction="u"))
    with pytest.raises(ValueError, match="pattern must be"):
        render(np.zeros((4, 4)))


def test_the_callable_inverse_reaches_its_tolerance():
    def field(X, Y):
        return 0.7 * np.sin(X / 15.0) + 0.01 * Y, -0.4 + 0.002 * X * np.cos(Y / 20.0)

    rows, cols = np.mgrid[0:20, 0:30].astype(np.float64)
    X, Y = _invert_callable(field, cols, rows)
    U, V = field(X, Y)
    assert np.max(np.abs(X + U - cols)) <= INVERSE_TOLERANCE
    assert np.max(np.abs(Y + V - rows)) <= INVERSE_TOLERANCE


def test_a_failing_callable_is_one_line_naming_its_error(pattern):
    def broken(X, Y):
        raise KeyError("boom")

    with pytest.raises(ValueError, match="displacement callable failed .*KeyError") as error:
        render(pattern, broken)
    assert "\n" not in str(error.value)
    scalar = render(pattern, lambda X, Y: (0.5, -0.25), bit_depth=None)      # scalars broadcast to X's shape
    np.testing.assert_allclose(scalar, render(pattern, (0.5, -0.25), bit_depth=None), atol=REL_TOL * scalar.mean())
