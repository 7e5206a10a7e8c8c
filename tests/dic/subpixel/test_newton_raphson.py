import numpy as np
import pytest

from livedic.dic import Status
from livedic.dic.bspline import PAD, prefilter
from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.subpixel import newton_raphson as nr

HALF = 10
SHAPE = (128, 128)


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern(SHAPE, density=1000 / 65536, radius=4.0, seed=11)


@pytest.fixture(scope="module")
def grid():
    g = np.arange(20, 109, 11)
    xs, ys = np.meshgrid(g, g)
    return xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)


def _ok(n):
    return np.zeros(n, dtype=np.int8)


@pytest.mark.parametrize("order", [0, 1])
@pytest.mark.parametrize("shift", [0.2, 0.5, 0.85])
def test_subpixel_shift_8bit_within_budget(pattern, grid, order, shift):
    """Noise-free 8-bit images: |mean error| < 0.003 px, SD < 0.008 px."""
    xs, ys = grid
    u, v = shift, 1.0 - shift / 2
    r = nr.refine(render(pattern), render(pattern, (u, v)), xs, ys, np.full(xs.size, round(u)),
                  np.full(xs.size, round(v)), _ok(xs.size), HALF, order=order)
    assert np.all(r.status == Status.OK)
    for err in (r.u - u, r.v - v):
        assert abs(err.mean()) < 0.003
        assert err.std() < 0.008
    assert (r.ux is None) == (order == 0)


@pytest.mark.parametrize("order", [0, 1])
def test_float_images_are_tight(pattern, grid, order):
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (-1.35, 0.6), bit_depth=None)
    r = nr.refine(ref, dfm, xs, ys, np.full(xs.size, -1.0), np.full(xs.size, 1.0), _ok(xs.size), HALF, order=order)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u + 1.35)) < 0.002
    assert np.max(np.abs(r.v - 0.6)) < 0.002
    assert np.min(r.zncc) > 0.9999
    assert np.all((r.iterations >= 1) & (r.iterations <= 20))


def test_recovers_affine_deformation_and_gradients(pattern, grid):
    xs, ys = grid
    field = affine(-0.6, 1.2, ux=-0.005, uy=0.003, vx=0.002, vy=0.004, centre=(64.0, 64.0))
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, field, bit_depth=None)
    tu, tv = field(xs.astype(float), ys.astype(float))
    r = nr.refine(ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u - tu)) < 0.003
    assert np.max(np.abs(r.v - tv)) < 0.003
    for got, want in ((r.ux, -0.005), (r.uy, 0.003), (r.vx, 0.002), (r.vy, 0.004)):
        assert abs(np.median(got) - want) < 2e-4
        assert np.max(np.abs(got - want)) < 1e-3


def test_invariant_to_affine_intensity_change(pattern, grid):
    xs, ys = grid
    ref = render(pattern).astype(np.float32)
    dfm = render(pattern, (0.3, -0.45)).astype(np.float32)
    a = nr.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.zeros(xs.size), _ok(xs.size), HALF)
    b = nr.refine(ref, 1.5 * dfm + 20.0, xs, ys, np.zeros(xs.size), np.zeros(xs.size), _ok(xs.size), HALF)
    assert np.all(a.status == Status.OK) and np.all(b.status == Status.OK)
    np.testing.assert_allclose(b.u, a.u, atol=2e-5)
    np.testing.assert_allclose(b.v, a.v, atol=2e-5)
    np.testing.assert_allclose(b.vy, a.vy, atol=2e-6)


def test_border_nan_and_passthrough_get_a_status(pattern):
    ref = render(pattern)
    dfm = render(pattern, (2.0, 0.0))
    xs = np.array([4, 64, 116, 64, 64], dtype=np.int64)
    ys = np.array([64, 64, 64, 64, 64], dtype=np.int64)
    u0 = np.array([0.0, 90.0, 0.4, np.nan, 2.0])
    status = np.array([0, 0, 0, 0, Status.LOW_CORRELATION], dtype=np.int8)
    r = nr.refine(ref, dfm, xs, ys, u0, np.zeros(5), status, HALF)
    assert list(r.status) == [Status.OUTSIDE_REFERENCE, Status.OUTSIDE_TARGET, Status.OUTSIDE_TARGET,
                              Status.BAD_GUESS, Status.LOW_CORRELATION]
    assert np.isnan(r.u).all() and np.isnan(r.zncc).all() and np.isnan(r.vy).all()


def test_flat_subsets_and_iteration_cap(pattern):
    ref = render(pattern).astype(np.float32)
    ref[:, :40] = 90.0
    dfm = ref.copy()
    dfm[:, 70:] = 50.0
    r = nr.refine(ref, dfm, np.array([15, 95]), np.array([64, 64]), np.zeros(2), np.zeros(2), _ok(2), HALF)
    assert list(r.status) == [Status.FLAT_REFERENCE, Status.FLAT_TARGET]
    capped = nr.refine(render(pattern), render(pattern, (0.7, 0.0)), np.array([40, 80]), np.array([50, 70]),
                       np.zeros(2), np.zeros(2), _ok(2), HALF, max_iterations=1)
    assert np.all(capped.status == Status.NOT_CONVERGED)
    assert np.isnan(capped.u).all()


def _numpy_bspline(coeffs, x, y):
    """Cubic B-spline value and gradient at image points from padded coefficients, in plain NumPy."""
    def w(t):
        return np.stack([(1 - t) ** 3 / 6, 2 / 3 - t ** 2 + t ** 3 / 2, 2 / 3 - (1 - t) ** 2 + (1 - t) ** 3 / 2,
                         t ** 3 / 6])

    def dw(t):
        return np.stack([-(1 - t) ** 2 / 2, 1.5 * t ** 2 - 2 * t, -1.5 * t ** 2 + t + 0.5, t ** 2 / 2])
    c = coeffs.coefficients.astype(np.float64)
    ix = np.floor(x).astype(int)
    iy = np.floor(y).astype(int)
    tx, ty = x - ix, y - iy
    g = np.zeros(x.shape)
    gx = np.zeros(x.shape)
    gy = np.zeros(x.shape)
    for m in range(4):
        for q in range(4):
            tap = c[iy - 1 + m + PAD, ix - 1 + q + PAD]
            g += w(ty)[m] * w(tx)[q] * tap
            gx += w(ty)[m] * dw(tx)[q] * tap
            gy += dw(ty)[m] * w(tx)[q] * tap
    return g, gx, gy


def test_sums_kernel_matches_numpy(pattern):
    """One pass of the N-R kernel (value, gradient, moments) against NumPy for one point."""
    ref = render(pattern, bit_depth=None).astype(np.float32)
    dfm = render(pattern, (0.7, 0.2), bit_depth=None).astype(np.float32)
    x0, y0 = 60, 66
    p = np.array([0.73, 0.02, -0.01, 0.18, 0.015, -0.02])
    f = ref[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1].astype(np.float64)
    ft = (f - f.mean()).ravel()
    coeffs = prefilter(dfm)
    acc = np.empty(39)
    nr._nr_sums(coeffs.coefficients, x0, y0, HALF, ft, p, acc, np.empty(24))
    dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1].astype(np.float64)
    dx, dy = dx.ravel(), dy.ravel()
    g, gx, gy = _numpy_bspline(coeffs, x0 + p[0] + (1 + p[1]) * dx + p[2] * dy,
                               y0 + p[3] + p[4] * dx + (1 + p[5]) * dy)
    moments = [np.ones_like(dx), dx, dy, dx * dx, dx * dy, dy * dy]
    expected = [g.sum(), (g * g).sum(), (ft * g).sum()]
    for pair in (gx * gx, gx * gy, gy * gy):
        expected += [(pair * m).sum() for m in moments]
    for comp in (gx, gy):
        for weight in (ft, g, np.ones_like(g)):
            expected += [(comp * weight * m).sum() for m in moments[:3]]
    expected = np.array(expected)
    np.testing.assert_allclose(acc, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())


def test_bad_arguments_raise(pattern):
    ref = render(pattern)
    one = (np.array([64]), np.array([64]), np.zeros(1), np.zeros(1), _ok(1), HALF)
    with pytest.raises(ValueError, match="order"):
        nr.refine(ref, ref, *one, order=2)
    with pytest.raises(ValueError, match="max_iterations"):
        nr.refine(ref, ref, *one, max_iterations=0)
    with pytest.raises(ValueError, match="same size"):
        nr.refine(ref, ref[:100], *one)


def test_projected_hessian_same_answer_fewer_iterations(pattern, grid):
    xs, ys = grid
    field = affine(0.4, -0.3, ux=0.005, uy=0.003, vx=0.002, vy=-0.008, centre=(64.0, 64.0))
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, field, bit_depth=None)
    tu, tv = field(xs.astype(float), ys.astype(float))
    args = (ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF)
    classic = nr.refine(*args)
    projected = nr.refine(*args, hessian="projected")
    assert np.all(projected.status == Status.OK)
    both = classic.status == Status.OK
    np.testing.assert_allclose(projected.u[both], classic.u[both], atol=1e-3)
    assert np.max(np.abs(projected.u - tu)) < 0.002
    assert projected.iterations.mean() < classic.iterations[both].mean()
    with pytest.raises(ValueError, match="hessian"):
        nr.refine(*args, hessian="exact")
