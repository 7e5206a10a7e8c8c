"""IC-GN with the 2nd-order shape function (``dic.subpixel.icgn2``): analytic fields, statuses, kernels, tracking."""

import numpy as np
import pytest

from livedic.dic import Status, Tracker, grid_in_roi, measure
from livedic.dic.bspline import PAD
from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.subpixel import icgn, icgn2

HALF = 10
SHAPE = (160, 160)
CENTRE = 80.0
# A quadratic field: (u, ux, uy, uxx, uxy, uyy, v, vx, vy, vxx, vxy, vyy) about CENTRE.
QUADRATIC = np.array([0.8, 0.004, 0.002, 0.0015, 0.0005, -0.0008, -0.6, -0.001, 0.006, -0.0006, 0.0007, 0.0012])


def _quadratic(X, Y):
    dx, dy = X - CENTRE, Y - CENTRE
    p = QUADRATIC
    u = p[0] + p[1] * dx + p[2] * dy + 0.5 * p[3] * dx * dx + p[4] * dx * dy + 0.5 * p[5] * dy * dy
    v = p[6] + p[7] * dx + p[8] * dy + 0.5 * p[9] * dx * dx + p[10] * dx * dy + 0.5 * p[11] * dy * dy
    return u, v


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern(SHAPE, density=1000 / 65536, radius=4.0, seed=7)


@pytest.fixture(scope="module")
def grid():
    g = np.arange(30, 131, 10)
    xs, ys = np.meshgrid(g, g)
    return xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)


def _ok(n):
    return np.zeros(n, dtype=np.int8)


def test_quadratic_field_recovered_exactly_where_first_order_is_biased(pattern, grid):
    """Exact (float) images of a quadratic field, 121 points, subset 21, integer starts.

    First-order IC-GN fits the best affine warp: its centre is off by about
    (1/2) uxx <dx^2> + (1/2) uyy <dy^2> with <dx^2> = M (M + 1) / 3 = 36.7 px^2
    for uniform texture, here 0.0128 px in u and 0.0110 px in v; measured mean
    0.0117 / 0.0092 px and up to 0.057 px at single points (the texture weighs
    the subset unevenly). icgn2 (every point at order 2: ``vif_max`` inf)
    recovers u, v within 0.0005 px and the six curvature terms within 1 % (medians).
    """
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, _quadratic, bit_depth=None)
    tu, tv = _quadratic(xs.astype(float), ys.astype(float))
    start = (np.round(tu), np.round(tv))
    first = icgn.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF)
    second = icgn2.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF, vif_max=np.inf)
    assert np.all(first.status == Status.OK) and np.all(second.status == Status.OK)
    m2 = HALF * (HALF + 1) / 3.0
    bias_u = 0.5 * (QUADRATIC[3] + QUADRATIC[5]) * m2
    bias_v = 0.5 * (QUADRATIC[9] + QUADRATIC[11]) * m2
    assert 0.5 * bias_u < np.mean(first.u - tu) < 1.5 * bias_u
    assert 0.5 * bias_v < np.mean(first.v - tv) < 1.5 * bias_v
    assert np.max(np.hypot(first.u - tu, first.v - tv)) > 0.03
    assert np.max(np.abs(second.u - tu)) < 0.002
    assert np.max(np.abs(second.v - tv)) < 0.002
    for name, want in zip(icgn2.SECOND_ORDER, QUADRATIC[[3, 4, 5, 9, 10, 11]]):
        assert abs(np.median(getattr(second, name)) - want) < 0.01 * np.max(np.abs(QUADRATIC[[3, 4, 5, 9, 10, 11]]))
    # the slope at the centre: ux(dx, dy) = ux + uxx dx + uxy dy at the point
    dx, dy = xs - CENTRE, ys - CENTRE
    want_ux = QUADRATIC[1] + QUADRATIC[3] * dx + QUADRATIC[4] * dy
    assert np.max(np.abs(second.ux - want_ux)) < 2e-4
    assert np.min(second.zncc) > 0.9999


@pytest.mark.parametrize("field", [(0.3, 0.0), (-0.55, 0.45), (2.2, -1.7),
                                   affine(1.3, -0.7, ux=0.004, uy=0.002, vx=-0.003, vy=0.006, centre=(80.0, 80.0))])
def test_translation_and_affine_fields_equal_icgn(pattern, grid, field):
    """Exact images of shifts and an affine field: icgn2 agrees with icgn within 0.001 px (measured: 0.0007)
    and with the truth within 0.002 px (0.0007), gradients within 5e-4 (6e-5), curvature < 1e-4 /px (3e-5)
    where it is reported (where the curvature test keeps order 2)."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, field, bit_depth=None)
    if callable(field):
        tu, tv = field(xs.astype(float), ys.astype(float))
    else:
        tu, tv = np.full(xs.size, field[0]), np.full(xs.size, field[1])
    first = icgn.refine(ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF)
    second = icgn2.refine(ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF)
    assert np.all(second.status == Status.OK)
    assert np.max(np.hypot(second.u - first.u, second.v - first.v)) < 0.001
    assert np.max(np.hypot(second.u - tu, second.v - tv)) < 0.002
    for name in ("ux", "uy", "vx", "vy"):
        assert np.nanmax(np.abs(getattr(second, name) - getattr(first, name))) < 5e-4
    curvature = np.stack([getattr(second, name) for name in icgn2.SECOND_ORDER])
    finite = np.isfinite(curvature)
    assert not finite.any() or np.max(np.abs(curvature[finite])) < 1e-4


def test_first_order_fallback_is_icgn_exactly(pattern, grid):
    """Points above ``VIF2_MAX`` (and every point with order=1) give icgn's result bit for bit, curvature NaN
    (the curvature test off, so that every other point reports order 2)."""
    xs, ys = grid
    ref = render(pattern)
    dfm = render(pattern, _quadratic)
    tu, tv = _quadratic(xs.astype(float), ys.astype(float))
    prep1 = icgn.prepare_reference(ref, xs, ys, HALF)
    coeffs = icgn.prepare_target(dfm)
    first = icgn.refine_prepared(prep1, coeffs, np.round(tu), np.round(tv))
    prep = icgn2.prepare_from(prep1, vif_max=5.0, curvature_threshold=0.0)   # a low VIF threshold: some fall back
    vif = np.maximum(prep.hinv2[:, 0, 0] / prep1.hinv0[:, 0, 0], prep.hinv2[:, 6, 6] / prep1.hinv0[:, 1, 1])
    np.testing.assert_array_equal(prep.max_order == 1, vif > 5.0)
    assert 0 < np.sum(prep.max_order == 1) < xs.size
    second = icgn2.refine_prepared(prep, coeffs, np.round(tu), np.round(tv))
    low = prep.max_order == 1
    np.testing.assert_array_equal(second.u[low], first.u[low])
    np.testing.assert_array_equal(second.iterations[low], first.iterations[low])
    assert np.isnan(second.uxx[low]).all() and np.isfinite(second.uxx[~low]).all()
    affine_only = icgn2.refine_prepared(prep, coeffs, np.round(tu), np.round(tv), order=1)
    np.testing.assert_array_equal(affine_only.u, first.u)
    np.testing.assert_array_equal(affine_only.vy, first.vy)
    assert np.isnan(affine_only.vyy).all()


def test_order_zero_is_a_pure_shift(pattern, grid):
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (0.45, -1.3), bit_depth=None)
    r = icgn2.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.full(xs.size, -1.0), _ok(xs.size), HALF, order=0,
                     ux0=np.full(xs.size, 0.5), uxx0=np.full(xs.size, 0.01))   # ignored by order 0
    assert np.all(r.status == Status.OK)
    assert np.isnan(r.ux).all() and np.isnan(r.uxx).all()
    assert np.max(np.abs(r.u - 0.45)) < 0.002 and np.max(np.abs(r.v + 1.3)) < 0.002


def test_statuses(pattern):
    """Border, leaving warp, NaN start, status passed through, flat subsets and the iteration cap."""
    ref = render(pattern)
    dfm = render(pattern, (2.0, 0.0))
    xs = np.array([5, 80, 80, 148, 80, 80], dtype=np.int64)
    ys = np.array([80, 3, 80, 80, 80, 80], dtype=np.int64)
    u0 = np.array([0.0, 0.0, -70.0, 0.4, np.nan, 2.0])
    status = np.array([0, 0, 0, 0, 0, Status.LOW_CORRELATION], dtype=np.int8)
    r = icgn2.refine(ref, dfm, xs, ys, u0, np.zeros(6), status, HALF)
    assert list(r.status) == [Status.OUTSIDE_REFERENCE, Status.OUTSIDE_REFERENCE, Status.OUTSIDE_TARGET,
                              Status.OUTSIDE_TARGET, Status.BAD_GUESS, Status.LOW_CORRELATION]
    for name in ("u", "v", "zncc", "ux", "uxx", "vyy"):
        assert np.isnan(getattr(r, name)).all()
    # a start with curvature goes straight to the 2nd-order iteration, whose range check finds the edge
    # (affine corner at x = 156, the last column the margin allows; the curvature adds 2.5 px)
    edge = icgn2.refine(ref, dfm, np.array([144]), np.array([80]), np.array([2.0]), np.array([0.0]), _ok(1), HALF,
                        uxx0=np.array([0.05]))
    assert edge.status[0] == Status.OUTSIDE_TARGET
    flat = ref.astype(np.float32)
    flat[:, :50] = 90.0
    flat_target = flat.copy()
    flat_target[:, 100:] = 50.0
    r = icgn2.refine(flat, flat_target, np.array([20, 125, 75]), np.array([80, 80, 80]), np.zeros(3), np.zeros(3),
                     _ok(3), HALF, uxx0=np.full(3, 1e-6))
    assert list(r.status) == [Status.FLAT_REFERENCE, Status.FLAT_TARGET, Status.OK]
    # from 0.7 px off with curvature given (no first-order stage without the curvature test), one iteration cannot
    # reach 0.001
    g = np.arange(30, 131, 25)
    gx, gy = np.meshgrid(g, g)
    n = gx.size
    capped = icgn2.refine(ref, render(pattern, (0.7, 0.0)), gx.ravel(), gy.ravel(), np.zeros(n), np.zeros(n),
                          _ok(n), HALF, max_iterations=1, uxx0=np.full(n, 1e-6), curvature_threshold=0.0)
    assert np.all(capped.status == Status.NOT_CONVERGED)
    assert np.isnan(capped.u).all()


def test_compose_inverse_is_the_warp_composition_to_second_order():
    """W(p) W(dp)^-1 against the numerically inverted and composed warps over a 21 x 21 subset.

    The 6 x 6 matrix truncates the composed squares at second order: measured 2.7e-4 px at the
    subset's corners for curvatures of 1e-3 /px; exact for dp = 0 and, for affine warps, the
    update of ``dic.subpixel.icgn`` to rounding.
    """
    p = np.array([2.0, 0.01, -0.004, 1e-3, -5e-4, 8e-4, -1.5, 0.003, 0.02, -6e-4, 4e-4, 1e-3])
    dp = np.array([0.1, 1e-3, -2e-3, 1e-4, 2e-4, -1e-4, -0.05, 5e-4, 1e-3, -2e-4, 1e-4, 3e-4])
    scratch = (np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 12)))

    def warp(par, dx, dy):
        u = par[0] + par[1] * dx + par[2] * dy + 0.5 * par[3] * dx * dx + par[4] * dx * dy + 0.5 * par[5] * dy * dy
        v = par[6] + par[7] * dx + par[8] * dy + 0.5 * par[9] * dx * dx + par[10] * dx * dy + 0.5 * par[11] * dy * dy
        return dx + u, dy + v

    d = np.arange(-HALF, HALF + 1.0)
    dx, dy = np.meshgrid(d, d)
    x, y = dx.copy(), dy.copy()
    for _ in range(50):            # the inverse of W(dp) by fixed-point iteration (dp is small)
        wx, wy = warp(dp, x, y)
        x -= wx - dx
        y -= wy - dy
    want_x, want_y = warp(p, x, y)
    q = p.copy()
    assert icgn2.compose_inverse(q, dp, scratch)
    got_x, got_y = warp(q, dx, dy)
    assert max(np.abs(got_x - want_x).max(), np.abs(got_y - want_y).max()) < 1e-3
    same = p.copy()
    icgn2.compose_inverse(same, np.zeros(12), scratch)
    np.testing.assert_allclose(same, p, atol=1e-15)
    # affine: IC-GN's closed-form update
    pa, da = p.copy(), dp.copy()
    pa[[3, 4, 5, 9, 10, 11]] = 0.0
    da[[3, 4, 5, 9, 10, 11]] = 0.0
    qa = pa.copy()
    icgn2.compose_inverse(qa, da, scratch)
    a = np.array([[1 + pa[1], pa[2], pa[0]], [pa[7], 1 + pa[8], pa[6]], [0, 0, 1]])
    b = np.array([[1 + da[1], da[2], da[0]], [da[7], 1 + da[8], da[6]], [0, 0, 1]])
    c = a @ np.linalg.inv(b)
    np.testing.assert_allclose(qa[[0, 1, 2, 6, 7, 8]], [c[0, 2], c[0, 0] - 1, c[0, 1], c[1, 2], c[1, 0], c[1, 1] - 1],
                               atol=1e-14)
    assert np.all(qa[[3, 4, 5, 9, 10, 11]] == 0.0)


def _numpy_bspline(coeffs, x, y):
    """Cubic B-spline value at image points (x, y) from padded coefficients, in plain NumPy."""
    def w(t):
        return np.stack([(1 - t) ** 3 / 6, 2 / 3 - t ** 2 + t ** 3 / 2,
                         2 / 3 - (1 - t) ** 2 + (1 - t) ** 3 / 2, t ** 3 / 6])
    c = coeffs.coefficients.astype(np.float64)
    ix = np.floor(x).astype(int)
    iy = np.floor(y).astype(int)
    wx = w(x - ix)
    wy = w(y - iy)
    out = np.zeros(x.shape)
    for m in range(4):
        for q in range(4):
            out += wy[m] * wx[q] * c[iy - 1 + m + PAD, ix - 1 + q + PAD]
    return out


def test_quadratic_sums_kernel_matches_numpy(pattern):
    """The vectorised sampler + 15 sums against plain NumPy, gentle warps (one run a row) and strong
    curvature (tap origins step inside rows, in runs that a parabola leaves and re-enters)."""
    ref = render(pattern, bit_depth=None).astype(np.float32)
    dfm = render(pattern, (1.3, -0.4), bit_depth=None).astype(np.float32)
    x0, y0 = 81, 78
    prep = icgn2.prepare_reference(ref, np.array([x0]), np.array([y0]), HALF)
    first = prep.first
    coeffs = icgn.prepare_target(dfm)
    side = 2 * HALF + 1
    dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1].astype(np.float64)
    fhat = first.fhat[0].reshape(side, first.lanes)[:, :side]
    fx = first.fx[0].reshape(side, first.lanes)[:, :side]
    fy = first.fy[0].reshape(side, first.lanes)[:, :side]
    scratch, _, sums, _, _, _ = icgn2.refine_point_scratch2(HALF, first.lanes)
    _, _, kx, ky, lane_dx, lane_mask, run_mask, _ = scratch
    for p in [np.array([1.31, 4e-4, -2e-4, 1e-5, -2e-5, 1e-5, -0.41, 3e-4, 1e-4, 2e-5, 1e-5, -1e-5]),
              np.array([1.37, 0.06, -0.03, 0.02, -0.008, 0.01, -0.41, -0.05, 0.04, -0.015, 0.012, 0.02])]:
        inside = icgn2._quadratic_sums(coeffs.flat, coeffs.origin, coeffs.coefficients.shape[1], SHAPE[0], SHAPE[1],
                                       x0, y0, HALF, p, first.fhat[0], first.fx[0], first.fy[0], first.lanes, lane_dx,
                                       lane_mask, kx, ky, run_mask, sums)
        assert inside
        u = p[0] + p[1] * dx + p[2] * dy + 0.5 * p[3] * dx ** 2 + p[4] * dx * dy + 0.5 * p[5] * dy ** 2
        v = p[6] + p[7] * dx + p[8] * dy + 0.5 * p[9] * dx ** 2 + p[10] * dx * dy + 0.5 * p[11] * dy ** 2
        g = _numpy_bspline(coeffs, x0 + dx + u, y0 + dy + v)
        monomials = [np.ones_like(dx), dx, dy, 0.5 * dx ** 2, dx * dy, 0.5 * dy ** 2]
        expected = [g.sum(), (g ** 2).sum(), (fhat * g).sum()]
        expected += [(fx * g * m).sum() for m in monomials] + [(fy * g * m).sum() for m in monomials]
        scale = [g.sum(), (g ** 2).sum(), 1.0] + [np.abs(fx * g).sum() * HALF * HALF] * 12
        for got, want, s in zip(sums, expected, scale):
            assert abs(got - want) < 2e-6 * s


def test_reference_preparation_matches_numpy(pattern):
    """The 12 x 12 step matrices (projected and OpenCorr's) and sums against NumPy on the stored subsets."""
    ref = render(pattern).astype(np.float32)
    x0, y0 = 70, 90
    for hessian in ("projected", "opencorr"):
        prep = icgn2.prepare_reference(ref, np.array([x0]), np.array([y0]), HALF, hessian=hessian)
        first = prep.first
        side = 2 * HALF + 1
        fhat = first.fhat[0].reshape(side, first.lanes)[:, :side].astype(np.float64).ravel()
        fx = first.fx[0].reshape(side, first.lanes)[:, :side].astype(np.float64)
        fy = first.fy[0].reshape(side, first.lanes)[:, :side].astype(np.float64)
        dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1]
        monomials = [np.ones_like(dx), dx, dy, 0.5 * dx ** 2, dx * dy, 0.5 * dy ** 2]
        jac = np.stack([fx * m for m in monomials] + [fy * m for m in monomials]).reshape(12, -1)
        s = jac @ fhat
        if hessian == "projected":
            centred = jac - jac.mean(axis=1, keepdims=True)
            matrix = centred @ centred.T - np.outer(s, s)
        else:
            matrix = jac @ jac.T
        np.testing.assert_allclose(prep.hinv2[0] @ matrix, np.eye(12), atol=1e-6)
        np.testing.assert_allclose(prep.sum_j2[0], jac.sum(axis=1), rtol=1e-9, atol=1e-6)
        np.testing.assert_allclose(prep.sum_jf2[0], s, rtol=1e-9, atol=1e-9)
        assert prep.max_order[0] == 2


def test_prepared_path_on_a_selection_and_warm_starts(pattern, grid):
    """``points=`` refines only those points, as ``refine``; without the curvature test a start with curvature
    (the tracker's) skips the first-order stage and converges in fewer iterations to the same result (within
    2e-4 px)."""
    xs, ys = grid
    ref = render(pattern)
    dfm = render(pattern, _quadratic)
    tu, tv = _quadratic(xs.astype(float), ys.astype(float))
    prep = icgn2.prepare_reference(ref, xs, ys, HALF, curvature_threshold=0.0)
    coeffs = icgn2.prepare_target(dfm)
    whole = icgn2.refine(ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF, curvature_threshold=0.0)
    pick = np.array([3, 50, 7])
    part = icgn2.refine_prepared(prep, coeffs, np.round(tu[pick]), np.round(tv[pick]), points=pick)
    np.testing.assert_array_equal(part.u, whole.u[pick])
    ok = np.flatnonzero((whole.status == Status.OK) & np.isfinite(whole.uxx))
    warm = icgn2.refine_prepared(prep, coeffs, whole.u[ok] + 0.05, whole.v[ok] - 0.05, whole.ux[ok], whole.uy[ok],
                                 whole.vx[ok], whole.vy[ok], points=ok,
                                 **{f"{n}0": getattr(whole, n)[ok] for n in icgn2.SECOND_ORDER})
    assert np.all(warm.status == Status.OK)
    assert np.max(np.abs(warm.u - whole.u[ok])) < 2e-4
    assert warm.iterations.mean() < whole.iterations[ok].mean()


def test_bad_arguments_raise(pattern):
    ref = render(pattern)
    prep = icgn2.prepare_reference(ref, np.array([80]), np.array([80]), HALF)
    coeffs = icgn2.prepare_target(ref)
    with pytest.raises(ValueError, match="same size"):
        icgn2.refine_prepared(prep, icgn2.prepare_target(ref[:100]), [0.0], [0.0])
    with pytest.raises(ValueError, match="prepare_target"):
        icgn2.refine_prepared(prep, ref, [0.0], [0.0])
    with pytest.raises(ValueError, match="Icgn2Reference"):
        icgn2.refine_prepared(prep.first, coeffs, [0.0], [0.0])
    with pytest.raises(ValueError, match="order"):
        icgn2.refine_prepared(prep, coeffs, [0.0], [0.0], order=3)
    with pytest.raises(ValueError, match="max_iterations"):
        icgn2.refine_prepared(prep, coeffs, [0.0], [0.0], max_iterations=0)
    with pytest.raises(ValueError, match="shape"):
        icgn2.refine_prepared(prep, coeffs, [0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="vif_max"):
        icgn2.prepare_from(prep.first, vif_max=0.5)
    for bad in (-1.0, np.inf, True):
        with pytest.raises(ValueError, match="curvature_threshold"):
            icgn2.prepare_from(prep.first, curvature_threshold=bad)
    with pytest.raises(ValueError, match="cubic B-spline only"):
        icgn2.refine_prepared(prep, icgn.prepare_target(ref, degree=5), [0.0], [0.0])


def test_measure_with_icgn2_guided_and_plain(pattern):
    """``dic.measure(subpixel="icgn2")``: reliability-guided (first-order propagation, then icgn2) and
    ``guided=False`` give the same points, within 0.001 px of the quadratic field (exact images) at
    the points refined at order 2; icgn's RMS there is ~0.02 px."""
    ref = 200.0 * render(pattern, bit_depth=None)
    dfm = 200.0 * render(pattern, _quadratic, bit_depth=None)
    axis = np.arange(30.0, 131.0, 10.0)
    points = np.array([(x, y) for y in axis for x in axis])
    tu, tv = _quadratic(points[:, 0], points[:, 1])
    guided = measure(ref, dfm, points, subpixel="icgn2", radius=6)
    plain = measure(ref, dfm, points, subpixel="icgn2", radius=6, guided=False)
    first = measure(ref, dfm, points, subpixel="icgn", radius=6)
    assert guided.ok.all() and plain.ok.all()
    np.testing.assert_allclose(guided.u, plain.u, atol=1e-4)
    prep = icgn2.prepare_reference(ref, points[:, 0], points[:, 1], HALF)
    second = prep.max_order == 2
    assert second.mean() > 0.9
    error = np.hypot(guided.u - tu, guided.v - tv)
    assert np.max(error[second]) < 0.001
    assert np.sqrt(np.mean(np.hypot(first.u - tu, first.v - tv) ** 2)) > 0.01
    assert guided.ux is not None and np.isfinite(guided.ux).all()


def test_tracker_follows_a_neck_with_less_bias_than_icgn():
    """The simulated tensile test (512 x 512, 16 frames, noise sigma 1, paced off), 880 points every 7 px,
    subset 21, tracked frame to frame by ``Tracker`` with icgn and with icgn2.

    Where the neck's curvature is steep at the last frame (|d2v/dY2| >= half its largest value
    over the grid: its flanks, 260 of the 880 points), first-order IC-GN carries the shape
    function's bias (the simulator's notes: up to ~0.25 px at 512 px): measured RMS 0.061 px
    (max 0.195), icgn2 0.019 px (max 0.048). Elsewhere icgn2's RMS was 0.020 px (icgn 0.033 px,
    which still holds the bias at the ends of the plastic zone; bounded here at 0.03 px).
    """
    from livedic.acquire.simulator.sources import open_synthetic

    source = open_synthetic("synthetic:tensile?frames=16&size=512x512&pace=0&noise=1.0&seed=0&strain=0.05&neck=0.15")
    source.prepare()
    frames = [frame.image for frame in source]
    points = grid_in_roi(frames[0].shape, source.suggested_roi, 7, 21)
    last = len(frames) - 1
    x, y = points[:, 0], points[:, 1]
    h = 5.0
    curvature = np.abs(source.truth(last, x, y + h)[1] - 2.0 * source.truth(last, x, y)[1]
                       + source.truth(last, x, y - h)[1]) / h ** 2
    flank = curvature >= 0.5 * curvature.max()
    assert 20 < flank.sum() < 0.5 * flank.size
    errors = {}
    for subpixel in ("icgn", "icgn2"):
        tracker = Tracker(frames[0], points, subpixel=subpixel)
        for image in frames[1:]:
            result = tracker.track(image)
        assert result.ok.mean() > 0.99, subpixel
        tu, tv = source.truth(last, result.x, result.y)
        errors[subpixel] = np.hypot(result.u - tu, result.v - tv)
        if subpixel == "icgn2":
            assert set(tracker.last_second_order) == set(icgn2.SECOND_ORDER)
            # the neck's flanks keep order 2 (their curvature is told from noise); most points elsewhere do not
            second = np.isfinite(tracker.last_second_order["vyy"])
            assert second[result.ok & flank].mean() > 0.9 and second[result.ok & ~flank].mean() < 0.5
    rms = {name: np.sqrt(np.nanmean(e[flank] ** 2)) for name, e in errors.items()}
    assert rms["icgn2"] < 0.5 * rms["icgn"], rms
    assert rms["icgn"] > 0.04, rms
    assert np.sqrt(np.nanmean(errors["icgn2"][~flank] ** 2)) < 0.03


def _noisy(image, rng, sigma=1.0):
    """An 8-bit camera frame of ``image`` (grey levels 0..1 scaled to 20..220) with Gaussian noise ``sigma``."""
    return np.clip(np.floor(20.0 + 200.0 * image + rng.normal(0.0, sigma, image.shape) + 0.5), 0, 255)


def _dense_grid():
    g = np.arange(24, 137, 4)
    xs, ys = np.meshgrid(g, g)
    return xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)


def test_curvature_test_gives_icgn_noise_on_a_uniform_strain(pattern):
    """A uniform 0.2 % strain, noise sigma 1 on 8-bit reference and target, 841 points, two image pairs.

    The fitted curvature is noise: its Wald statistic stays below the threshold (``curvature_threshold_bic``)
    at all but a few points (measured 0.7-1.2 %), which report their first-order result: icgn's, bit for bit.
    The error SD is then near icgn's (measured 1.11x), against 2.1x with every point at order 2.
    """
    rng = np.random.default_rng(5)
    xs, ys = _dense_grid()
    field = affine(0.3, -0.2, ux=-0.0006, vy=0.002, centre=(CENTRE, CENTRE))
    tu, tv = field(xs.astype(float), ys.astype(float))
    clean_ref, clean_dfm = render(pattern, bit_depth=None), render(pattern, field, bit_depth=None)
    errors = {"icgn": [], "selected": [], "order 2": []}
    shares = []
    for _ in range(2):
        ref, dfm = _noisy(clean_ref, rng), _noisy(clean_dfm, rng)
        start = (np.round(tu), np.round(tv))
        first = icgn.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF)
        selected = icgn2.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF)
        every = icgn2.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF, curvature_threshold=0.0)
        assert np.all(selected.status == Status.OK)
        low = np.isnan(selected.uxx)
        np.testing.assert_array_equal(selected.u[low], first.u[low])
        np.testing.assert_array_equal(selected.vy[low], first.vy[low])
        shares.append(np.mean(~low))
        for name, r in (("icgn", first), ("selected", selected), ("order 2", every)):
            errors[name].append(np.concatenate([r.u - tu, r.v - tv]))
    sd = {name: np.std(np.concatenate(e)) for name, e in errors.items()}

    assert max(shares) < 0.03, shares
    assert sd["selected"] < 1.2 * sd["icgn"], sd
    assert sd["order 2"] > 1.6 * sd["icgn"], sd


def test_curvature_test_keeps_a_known_quadratic_field_at_order_2(pattern):
    """A quadratic field (uxx = vyy = 0.002 /px about the centre), noise sigma 1, 841 points: icgn is biased
    by ~0.036 px; the curvature is told from noise at >= 90 % of the points, which keep order 2, and icgn2's
    mean error stays below 0.005 px with its SD within 1.2x order 2's."""
    rng = np.random.default_rng(6)
    xs, ys = _dense_grid()

    def field(X, Y):
        dx, dy = X - CENTRE, Y - CENTRE
        return 0.3 + 0.002 * dx + 0.001 * dx * dx, -0.2 + 0.002 * dy + 0.001 * dy * dy

    tu, tv = field(xs.astype(float), ys.astype(float))
    ref, dfm = _noisy(render(pattern, bit_depth=None), rng), _noisy(render(pattern, field, bit_depth=None), rng)
    start = (np.round(tu), np.round(tv))
    first = icgn.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF)
    selected = icgn2.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF)
    every = icgn2.refine(ref, dfm, xs, ys, *start, _ok(xs.size), HALF, curvature_threshold=0.0)
    assert np.mean(first.u - tu) > 0.025 and np.mean(first.v - tv) > 0.025
    ok = selected.status == Status.OK
    assert ok.mean() > 0.99
    assert np.isfinite(selected.uxx[ok]).mean() > 0.9
    assert abs(np.mean(selected.u[ok] - tu[ok])) < 0.005 and abs(np.mean(selected.v[ok] - tv[ok])) < 0.005
    error = np.concatenate([selected.u - tu, selected.v - tv])[np.concatenate([ok, ok])]
    every_error = np.concatenate([every.u - tu, every.v - tv])
    assert np.std(error) < 1.2 * np.nanstd(every_error)
