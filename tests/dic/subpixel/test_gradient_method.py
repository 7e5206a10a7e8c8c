import numpy as np
import pytest

from livedic.dic import Status
from livedic.dic.gradient import gradient_4th
from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.subpixel import gradient_method as gm

HALF = 10


# ---------------------------------------------------------------- gradient method

@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern((128, 128), density=1000 / 65536, radius=4.0, seed=5)


@pytest.fixture(scope="module")
def grid():
    g = np.arange(20, 109, 8)
    xs, ys = np.meshgrid(g, g)
    return xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)


def _errors(pattern, grid, shift, **options):
    xs, ys = grid
    r = gm.refine(render(pattern), render(pattern, (shift, 0.0)), xs, ys, np.full(xs.size, float(round(shift))),
                  np.zeros(xs.size), np.zeros(xs.size, np.int8), HALF, **options)
    assert np.all(r.status == Status.OK)
    return r.u - shift, r.v, r


def test_accurate_near_integer_shifts(pattern, grid):
    """Within 0.1 px of the integer peak the first-order expansion holds: |bias| < 0.01 px, SD < 0.02 px."""
    for shift in (0.1, 0.9, 1.05):
        eu, ev, _ = _errors(pattern, grid, shift)
        assert abs(eu.mean()) < 0.01 and eu.std() < 0.02
        assert abs(ev.mean()) < 0.005 and ev.std() < 0.02


def test_worst_near_half_pixel(pattern, grid):
    """The truncated Taylor series: at 0.5 px the error is several times the 0.1 px error, yet < 0.1 px."""
    near, _, _ = _errors(pattern, grid, 0.1)
    half_px, _, _ = _errors(pattern, grid, 0.5)
    rms_near = np.sqrt(np.mean(near ** 2))
    rms_half = np.sqrt(np.mean(half_px ** 2))
    assert rms_half > 3 * rms_near
    assert rms_half < 0.1
    # the linearised subset still correlates well
    _, _, r = _errors(pattern, grid, 0.5)
    assert np.min(r.zncc) > 0.99


def test_central_difference_option_works_too(pattern, grid):
    eu, _, _ = _errors(pattern, grid, 0.2, gradient="central")
    assert abs(eu.mean()) < 0.03 and eu.std() < 0.04
    with pytest.raises(ValueError, match="gradient"):
        _errors(pattern, grid, 0.2, gradient="sobel")


def test_invariant_to_affine_intensity_change(pattern, grid):
    xs, ys = grid
    ref = render(pattern).astype(np.float32)
    dfm = render(pattern, (0.3, 0.2)).astype(np.float32)
    args = (xs, ys, np.zeros(xs.size), np.zeros(xs.size), np.zeros(xs.size, np.int8), HALF)
    a = gm.refine(ref, dfm, *args)
    b = gm.refine(ref, 1.5 * dfm + 20.0, *args)
    np.testing.assert_allclose(b.u, a.u, atol=1e-6)
    np.testing.assert_allclose(b.v, a.v, atol=1e-6)


def test_float_start_is_rounded(pattern, grid):
    xs, ys = grid
    ref, dfm = render(pattern), render(pattern, (2.2, -0.9))
    st = np.zeros(xs.size, np.int8)
    a = gm.refine(ref, dfm, xs, ys, np.full(xs.size, 2.0), np.full(xs.size, -1.0), st, HALF)
    b = gm.refine(ref, dfm, xs, ys, np.full(xs.size, 2.3), np.full(xs.size, -0.6), st, HALF)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)


def test_border_nan_flat_and_passthrough_get_a_status(pattern):
    ref = render(pattern).astype(np.float32)
    dfm = render(pattern, (1.0, 0.0)).astype(np.float32)
    ref[:, :35] = 80.0
    dfm[:, 80:] = 40.0
    xs = np.array([5, 116, 64, 17, 100, 64], dtype=np.int64)
    ys = np.array([64, 64, 64, 64, 64, 64], dtype=np.int64)
    u0 = np.array([0.0, 1.0, np.nan, 0.0, 1.0, 1.0])
    status = np.array([0, 0, 0, 0, 0, Status.OUTSIDE_TARGET], dtype=np.int8)
    r = gm.refine(ref, dfm, xs, ys, u0, np.zeros(6), status, HALF)
    # x = 116 + 1 + 10 + 2 (stencil) reaches column 129: outside the 128-px image
    assert list(r.status) == [Status.OUTSIDE_REFERENCE, Status.OUTSIDE_TARGET, Status.BAD_GUESS,
                              Status.FLAT_REFERENCE, Status.FLAT_TARGET, Status.OUTSIDE_TARGET]
    assert np.isnan(r.u).all() and np.isnan(r.zncc).all()


def test_step_beyond_one_pixel_is_flagged(pattern, grid):
    """Started 1.7 px from the truth (not at the integer peak) the one-step estimate exceeds 1 px -> NOT_CONVERGED."""
    xs, ys = grid
    r = gm.refine(render(pattern), render(pattern, (1.7, 0.0)), xs, ys, np.zeros(xs.size), np.zeros(xs.size),
                  np.zeros(xs.size, np.int8), HALF)
    assert np.mean(r.status == Status.NOT_CONVERGED) > 0.9
    assert np.isnan(r.u[r.status != Status.OK]).all()


def test_one_point_matches_numpy(pattern):
    ref = render(pattern).astype(np.float64)
    dfm = render(pattern, (0.35, -0.25)).astype(np.float64)
    x0, y0 = 57, 61
    r = gm.refine(ref, dfm, np.array([x0]), np.array([y0]), np.zeros(1), np.zeros(1), np.zeros(1, np.int8), HALF)
    f = ref[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1]
    g = dfm[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1]
    gx, gy = gradient_4th(dfm)
    gx = gx[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1].ravel()
    gy = gy[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1].ravel()
    ft = f - f.mean()
    gt = g - g.mean()
    fprime = (g.mean() + np.sqrt((gt ** 2).sum() / (ft ** 2).sum()) * ft).ravel()
    a = np.column_stack([gx, gy])
    du, dv = np.linalg.lstsq(a, fprime - g.ravel(), rcond=None)[0]
    assert r.u[0] == pytest.approx(du, abs=1e-9)
    assert r.v[0] == pytest.approx(dv, abs=1e-9)
