import numpy as np
import pytest

from livedic.dic import Status
from livedic.dic.bspline import PAD, interpolate
from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.subpixel import icgn

HALF = 10
SHAPE = (128, 128)


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern(SHAPE, density=1000 / 65536, radius=4.0, seed=7)


@pytest.fixture(scope="module")
def grid():
    g = np.arange(20, 109, 8)
    xs, ys = np.meshgrid(g, g)
    return xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)


def _ok(n):
    return np.zeros(n, dtype=np.int8)


@pytest.mark.parametrize("shift", [0.1, 0.25, 0.5, 0.75, 0.9])
def test_subpixel_shift_8bit_within_budget(pattern, grid, shift):
    """Noise-free 8-bit images: |mean error| < 0.002 px, SD < 0.008 px (quantisation limited, ~0.004)."""
    xs, ys = grid
    u, v = 1.0 + shift, -shift / 2
    ref = render(pattern)
    dfm = render(pattern, (u, v))
    r = icgn.refine(ref, dfm, xs, ys, np.full(xs.size, round(u)), np.full(xs.size, round(v)), _ok(xs.size), HALF)
    assert np.all(r.status == Status.OK)
    for err in (r.u - u, r.v - v):
        assert abs(err.mean()) < 0.002
        assert err.std() < 0.008


def test_subpixel_shift_float_images_is_tight(pattern, grid):
    """Without quantisation the only error left is interpolation: below 0.002 px everywhere."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    for u, v in [(0.3, 0.0), (-0.55, 0.45), (2.2, -1.7)]:
        dfm = render(pattern, (u, v), bit_depth=None)
        r = icgn.refine(ref, dfm, xs, ys, np.round(np.full(xs.size, u)), np.round(np.full(xs.size, v)),
                        _ok(xs.size), HALF)
        assert np.all(r.status == Status.OK)
        assert np.max(np.abs(r.u - u)) < 0.002
        assert np.max(np.abs(r.v - v)) < 0.002
        # ZNCC ~ 1 at convergence on noise-free images
        assert np.min(r.zncc) > 0.9999
        assert np.all(r.iterations >= 1)


def test_recovers_affine_deformation_and_gradients(pattern, grid):
    xs, ys = grid
    field = affine(1.3, -0.7, ux=0.004, uy=0.002, vx=-0.003, vy=0.006, centre=(64.0, 64.0))
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, field, bit_depth=None)
    tu, tv = field(xs.astype(float), ys.astype(float))
    r = icgn.refine(ref, dfm, xs, ys, np.round(tu), np.round(tv), _ok(xs.size), HALF)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u - tu)) < 0.003
    assert np.max(np.abs(r.v - tv)) < 0.003
    for got, want in ((r.ux, 0.004), (r.uy, 0.002), (r.vx, -0.003), (r.vy, 0.006)):
        assert abs(np.median(got) - want) < 2e-4
        assert np.max(np.abs(got - want)) < 1e-3


def test_float_start_two_pixels_off_converges(pattern, grid):
    """The live-tracking case: a float guess up to 2 px from the truth, no search."""
    xs, ys = grid
    ref = render(pattern)
    dfm = render(pattern, (3.37, -1.62))
    rng = np.random.default_rng(3)
    radius = 2.0 * np.sqrt(rng.uniform(0, 1, xs.size))
    angle = rng.uniform(0, 2 * np.pi, xs.size)
    u0 = 3.37 + radius * np.cos(angle)
    v0 = -1.62 + radius * np.sin(angle)
    r = icgn.refine(ref, dfm, xs, ys, u0, v0, _ok(xs.size), HALF)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u - 3.37)) < 0.05     # weakest 8-bit subsets: ~0.02
    assert np.max(np.abs(r.v + 1.62)) < 0.05
    # the same fixed point as from the integer start, and as without the translation pre-stage
    near = icgn.refine(ref, dfm, xs, ys, np.full(xs.size, 3.0), np.full(xs.size, -2.0), _ok(xs.size), HALF)
    np.testing.assert_allclose(r.u, near.u, atol=1e-3)
    np.testing.assert_allclose(r.v, near.v, atol=1e-3)
    plain = icgn.refine(ref, dfm, xs, ys, u0, v0, _ok(xs.size), HALF, translation_iterations=0)
    both = plain.status == Status.OK
    assert both.mean() > 0.95
    np.testing.assert_allclose(plain.u[both], r.u[both], atol=1e-3)
    # the pre-stage saves 1st-order iterations: it moves the shift separably at a fraction of the cost
    assert r.iterations.mean() < 6


def test_invariant_to_affine_intensity_change(pattern, grid):
    xs, ys = grid
    ref = render(pattern).astype(np.float32)
    dfm = render(pattern, (0.4, 0.65)).astype(np.float32)
    a = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.ones(xs.size), _ok(xs.size), HALF)
    b = icgn.refine(ref, 1.5 * dfm + 20.0, xs, ys, np.zeros(xs.size), np.ones(xs.size), _ok(xs.size), HALF)
    assert np.all(a.status == Status.OK) and np.all(b.status == Status.OK)
    np.testing.assert_allclose(b.u, a.u, atol=2e-5)
    np.testing.assert_allclose(b.v, a.v, atol=2e-5)
    np.testing.assert_allclose(b.zncc, a.zncc, atol=1e-6)


def test_prepared_path_equals_refine_and_carries_gradients(pattern, grid):
    xs, ys = grid
    field = affine(0.8, 0.3, ux=0.003, vy=-0.002, centre=(64.0, 64.0))
    ref = render(pattern)
    dfm = render(pattern, field)
    u0 = np.full(xs.size, 1.0)
    v0 = np.zeros(xs.size)
    whole = icgn.refine(ref, dfm, xs, ys, u0, v0, _ok(xs.size), HALF)
    assert np.all(whole.status == Status.OK)
    prep = icgn.prepare_reference(ref, xs, ys, HALF)
    coeffs = icgn.prepare_target(dfm)
    split = icgn.refine_prepared(prep, coeffs, u0, v0, status=_ok(xs.size))
    for name in ("u", "v", "ux", "uy", "vx", "vy", "zncc", "iterations"):
        np.testing.assert_array_equal(getattr(split, name), getattr(whole, name))
    np.testing.assert_array_equal(split.status, whole.status)
    # a start that carries the previous frame's gradients converges to the same result
    again = icgn.refine_prepared(prep, coeffs, whole.u + 0.05, whole.v - 0.05, whole.ux, whole.uy, whole.vx, whole.vy)
    assert np.all(again.status == Status.OK)
    np.testing.assert_allclose(again.u, whole.u, atol=2e-3)
    np.testing.assert_allclose(again.vy, whole.vy, atol=5e-4)


def test_prepared_path_on_a_selection_touches_only_those_points(pattern, grid):
    """``points=``: the selected rows, in the order asked, equal to the whole run's; nothing else is refined."""
    xs, ys = grid
    ref = render(pattern)
    dfm = render(pattern, (0.8, -0.4))
    prep = icgn.prepare_reference(ref, xs, ys, HALF)
    coeffs = icgn.prepare_target(dfm)
    u0 = np.linspace(0.5, 1.2, xs.size)
    v0 = np.linspace(-0.9, 0.1, xs.size)
    order = np.arange(xs.size) % 2
    whole = icgn.refine_prepared(prep, coeffs, u0, v0, order=order)
    pick = np.array([xs.size - 1, 3, 0, 7])
    part = icgn.refine_prepared(prep, coeffs, u0[pick], v0[pick], order=order[pick], points=pick,
                                status=np.array([Status.OK, Status.OK, Status.OUTSIDE_TARGET, Status.OK], np.int8))
    assert part.u.shape == (pick.size,)
    for name in ("u", "v", "ux", "uy", "vx", "vy", "zncc", "iterations", "status"):
        expected = getattr(whole, name)[pick]
        if name in ("u", "v", "ux", "uy", "vx", "vy", "zncc"):
            expected[2] = np.nan
        elif name == "iterations":
            expected[2] = 0
        else:
            expected[2] = Status.OUTSIDE_TARGET
        np.testing.assert_array_equal(getattr(part, name), expected)
    empty = icgn.refine_prepared(prep, coeffs, [], [], points=np.array([], dtype=np.int64))
    assert empty.u.shape == (0,)
    for bad in (np.array([xs.size]), np.array([-1]), np.ones(xs.size, dtype=bool)):
        with pytest.raises(ValueError, match="indices of the"):
            icgn.refine_prepared(prep, coeffs, np.zeros(bad.size), np.zeros(bad.size), points=bad)


def test_border_points_and_leaving_warps_get_a_status(pattern):
    ref = render(pattern)
    dfm = render(pattern, (2.0, 0.0))
    xs = np.array([5, 64, 64, 116, 64, 64], dtype=np.int64)
    ys = np.array([64, 3, 64, 64, 64, 64], dtype=np.int64)
    u0 = np.array([0.0, 0.0, -60.0, 0.4, np.nan, 2.0])
    v0 = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    status = np.array([0, 0, 0, 0, 0, Status.LOW_CORRELATION], dtype=np.int8)
    r = icgn.refine(ref, dfm, xs, ys, u0, v0, status, HALF)
    assert list(r.status) == [Status.OUTSIDE_REFERENCE, Status.OUTSIDE_REFERENCE, Status.OUTSIDE_TARGET,
                              Status.OUTSIDE_TARGET, Status.BAD_GUESS, Status.LOW_CORRELATION]
    for name in ("u", "v", "zncc", "ux", "uy", "vx", "vy"):
        assert np.isnan(getattr(r, name)).all()


def test_flat_subsets_and_iteration_cap(pattern):
    ref = render(pattern).astype(np.float32)
    ref[:, :40] = 90.0
    dfm = ref.copy()
    dfm[:, 70:] = 50.0
    xs = np.array([15, 95, 55], dtype=np.int64)
    ys = np.array([64, 64, 64], dtype=np.int64)
    r = icgn.refine(ref, dfm, xs, ys, np.zeros(3), np.zeros(3), _ok(3), HALF)
    assert r.status[0] == Status.FLAT_REFERENCE
    assert r.status[1] == Status.FLAT_TARGET
    assert r.status[2] == Status.OK
    # one iteration from 0.7 px off cannot reach the 0.001 criterion
    dfm = render(pattern, (0.7, 0.0))
    g = np.arange(20, 109, 22)
    gx, gy = np.meshgrid(g, g)
    capped = icgn.refine(render(pattern), dfm, gx.ravel(), gy.ravel(), np.zeros(gx.size), np.zeros(gx.size),
                         _ok(gx.size), HALF, max_iterations=1, translation_iterations=0)
    assert np.all(capped.status == Status.NOT_CONVERGED)
    assert np.isnan(capped.u).all()


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


@pytest.mark.parametrize("degree", [3, 5, 7])
def test_affine_sums_kernel_matches_numpy(pattern, degree):
    """The vectorised sampler + sums against plain NumPy (cubic) or ``dic.bspline.interpolate``'s float64
    evaluation (quintic, septic) for one point, with rows split into runs."""
    ref = render(pattern, bit_depth=None).astype(np.float32)
    dfm = render(pattern, (1.3, -0.4), bit_depth=None).astype(np.float32)
    x0, y0 = 61, 58
    prep = icgn.prepare_reference(ref, np.array([x0]), np.array([y0]), HALF)
    coeffs = icgn.prepare_target(dfm, degree=degree)
    side = 2 * HALF + 1
    dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1].astype(np.float64)
    fhat = prep.fhat[0].reshape(side, prep.lanes)[:, :side]
    fx = prep.fx[0].reshape(side, prep.lanes)[:, :side]
    fy = prep.fy[0].reshape(side, prep.lanes)[:, :side]
    g, tmp, kx, ky, lane_dx, lane_mask, run_mask, sums = icgn.refine_point_scratch(HALF, prep.lanes)
    # small gradients: every row one run; ux alone (a tensile test's contraction, either sign): the tap
    # origin steps once in x along most rows (one pass, 5 columns); large ones: several runs in x and y
    for p in [(1.31, 0.0004, -0.0002, -0.41, 0.0003, 0.0001), (1.37, 0.04, -0.003, -0.41, 0.0, 0.02),
              (1.62, -0.045, 0.002, -0.41, 0.0, -0.01), (1.37, 0.06, -0.03, -0.41, -0.05, 0.04)]:
        icgn._affine_sums(coeffs.flat, coeffs.origin, coeffs.coefficients.shape[1], x0, y0, HALF, *p,
                          prep.fhat[0], prep.fx[0], prep.fy[0], prep.lanes, lane_dx, lane_mask, kx, ky, run_mask,
                          degree, sums)
        u, ux, uy, v, vx, vy = p
        xw, yw = x0 + u + (1 + ux) * dx + uy * dy, y0 + v + vx * dx + (1 + vy) * dy
        values = _numpy_bspline(coeffs, xw, yw) if degree == 3 else interpolate(coeffs, xw, yw)
        expected = [values.sum(), (values ** 2).sum(), (fhat * values).sum(), (fx * values).sum(),
                    (fx * values * dx).sum(), (fx * values * dy).sum(), (fy * values).sum(),
                    (fy * values * dx).sum(), (fy * values * dy).sum()]
        scale = [values.sum(), (values ** 2).sum(), 1.0] + [np.abs(fx * values).sum() * HALF] * 6
        for got, want, s in zip(sums, expected, scale):
            assert abs(got - want) < 2e-6 * s


def test_reference_preparation_matches_numpy(pattern):
    ref = render(pattern).astype(np.float32)
    x0, y0 = 50, 70
    prep = icgn.prepare_reference(ref, np.array([x0]), np.array([y0]), HALF)
    side = 2 * HALF + 1
    f = ref[y0 - HALF:y0 + HALF + 1, x0 - HALF:x0 + HALF + 1].astype(np.float64)
    big = ref[y0 - HALF - 2:y0 + HALF + 3, x0 - HALF - 2:x0 + HALF + 3].astype(np.float64)
    fx = (big[2:-2, :-4] - big[2:-2, 4:] + 8 * (big[2:-2, 3:-1] - big[2:-2, 1:-3])) / 12
    fy = (big[:-4, 2:-2] - big[4:, 2:-2] + 8 * (big[3:-1, 2:-2] - big[1:-3, 2:-2])) / 12
    dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1]
    jac = np.stack([fx, fx * dx, fx * dy, fy, fy * dx, fy * dy]).reshape(6, -1)
    ft = f - f.mean()
    fhat = (ft / np.sqrt((ft ** 2).sum())).ravel()
    raw = jac @ jac.T
    centred = jac - jac.mean(axis=1, keepdims=True)
    s = jac @ fhat
    projected = centred @ centred.T - np.outer(s, s)
    np.testing.assert_allclose(prep.hinv[0] @ projected, np.eye(6), atol=1e-6)
    np.testing.assert_allclose(prep.hinv0[0] @ projected[np.ix_([0, 3], [0, 3])], np.eye(2), atol=1e-6)
    opencorr = icgn.prepare_reference(ref, np.array([x0]), np.array([y0]), HALF, hessian="opencorr")
    np.testing.assert_allclose(opencorr.hinv[0] @ raw, np.eye(6), atol=1e-6)
    np.testing.assert_allclose(prep.sum_j[0], jac.sum(axis=1), rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(prep.sum_jf[0], s, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(prep.fhat[0].reshape(side, prep.lanes)[:, :side], fhat.reshape(side, side),
                               atol=1e-6)
    np.testing.assert_allclose(prep.norm[0], np.sqrt((ft ** 2).sum()), rtol=1e-9)
    assert prep.status[0] == Status.OK


def test_bad_arguments_raise(pattern):
    ref = render(pattern)
    prep = icgn.prepare_reference(ref, np.array([64]), np.array([64]), HALF)
    with pytest.raises(ValueError, match="same size"):
        icgn.refine_prepared(prep, icgn.prepare_target(ref[:100]), [0.0], [0.0])
    with pytest.raises(ValueError, match="prepare_target"):
        icgn.refine_prepared(prep, ref, [0.0], [0.0])
    with pytest.raises(ValueError, match="max_iterations"):
        icgn.refine_prepared(prep, icgn.prepare_target(ref), [0.0], [0.0], max_iterations=0)
    with pytest.raises(ValueError, match="shape"):
        icgn.refine_prepared(prep, icgn.prepare_target(ref), [0.0, 1.0], [0.0, 1.0])


def test_order_zero_is_a_pure_shift(pattern, grid):
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (0.45, -1.3), bit_depth=None)
    r = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.full(xs.size, -1.0), _ok(xs.size), HALF, order=0,
                    ux0=np.full(xs.size, 0.5))        # start gradients are ignored by order 0
    assert np.all(r.status == Status.OK)
    assert r.ux is None and r.vy is None
    assert np.max(np.abs(r.u - 0.45)) < 0.002
    assert np.max(np.abs(r.v + 1.3)) < 0.002
    assert np.min(r.zncc) > 0.9999


def test_float32_fast_path_sits_at_the_float64_fixed_point(pattern, grid):
    """From the converged result, one IC-GN step evaluated in float64 NumPy moves < 2e-5 px.

    The kernel samples in float32 with FMA/reassociation; this bounds what that costs.
    """
    xs, ys = grid
    ref = render(pattern)
    dfm = render(pattern, (0.37, -0.58))
    prep = icgn.prepare_reference(ref, xs, ys, HALF)
    coeffs = icgn.prepare_target(dfm)
    r = icgn.refine_prepared(prep, coeffs, np.zeros(xs.size), np.full(xs.size, -1.0), tolerance=1e-6,
                             max_iterations=30)
    assert np.all(r.status == Status.OK)
    side = 2 * HALF + 1
    dy, dx = np.mgrid[-HALF:HALF + 1, -HALF:HALF + 1].astype(np.float64)
    for i in range(0, xs.size, 7):
        u, ux, uy, v, vx, vy = r.u[i], r.ux[i], r.uy[i], r.v[i], r.vx[i], r.vy[i]
        g = _numpy_bspline(coeffs, xs[i] + u + (1 + ux) * dx + uy * dy, ys[i] + v + vx * dx + (1 + vy) * dy)
        fhat = prep.fhat[i].reshape(side, prep.lanes)[:, :side].astype(np.float64)
        fx = prep.fx[i].reshape(side, prep.lanes)[:, :side].astype(np.float64)
        fy = prep.fy[i].reshape(side, prep.lanes)[:, :side].astype(np.float64)
        jac = np.stack([fx, fx * dx, fx * dy, fy, fy * dx, fy * dy]).reshape(6, -1)
        gt = g - g.mean()
        e = prep.norm[i] * (gt / np.sqrt((gt ** 2).sum()) - fhat).ravel()
        dp = prep.hinv[i] @ (jac @ e)
        assert np.sqrt(dp[0] ** 2 + dp[3] ** 2 + HALF ** 2 * (dp[[1, 2, 4, 5]] ** 2).sum()) < 2e-5


# ---------------------------------------------------------------------------
# quintic B-spline targets (prepare_target(..., degree=5))


def _band_limited(shape, shift=(0.0, 0.0)):
    """A sum of sinusoids well below Nyquist, shifted exactly by (u, v): content at (x, y) of the reference is at
    (x + u, y + v) in the shifted image. float64, no rounding."""
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float64)
    x = cols - shift[0]
    y = rows - shift[1]
    image = np.full(shape, 100.0)
    for kx, ky, phase, amp in [(0.31, 0.17, 0.3, 20.0), (-0.23, 0.41, 1.1, 15.0), (0.52, -0.29, 2.0, 12.0),
                               (0.11, 0.63, 0.7, 10.0), (0.67, 0.07, 1.7, 8.0)]:
        image += amp * np.sin(kx * x + ky * y + phase)
    return image


@pytest.mark.parametrize("shift", [(0.3, -0.2), (1.7, 0.45), (-0.55, 2.25)])
def test_quintic_recovers_an_exact_translation_of_a_band_limited_image(grid, shift):
    """Unrounded, noise-free images: the quintic target recovers the shift to < 1e-4 px, within ~20x better
    than the cubic (the only error left is interpolation)."""
    xs, ys = grid
    ref = _band_limited(SHAPE).astype(np.float32)
    dfm = _band_limited(SHAPE, shift).astype(np.float32)
    errors = {}
    for degree in (3, 5):
        r = icgn.refine(ref, dfm, xs, ys, np.round(np.full(xs.size, shift[0])), np.round(np.full(xs.size, shift[1])),
                        _ok(xs.size), HALF, degree=degree)
        assert np.all(r.status == Status.OK)
        errors[degree] = max(np.max(np.abs(r.u - shift[0])), np.max(np.abs(r.v - shift[1])))
    assert errors[5] < 1e-4
    assert errors[5] < errors[3] / 5


@pytest.mark.parametrize("shift", [0.3, 0.7])
def test_quintic_bias_on_rendered_subpixel_shift_is_lower_than_cubic(pattern, grid, shift):
    """The classic interpolation bias of a rendered speckle shifted by a fraction of a pixel, no quantisation."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (shift, -shift), bit_depth=None)
    bias = {}
    for degree in (3, 5):
        r = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.zeros(xs.size), _ok(xs.size), HALF, degree=degree)
        assert np.all(r.status == Status.OK)
        bias[degree] = max(abs(np.mean(r.u - shift)), abs(np.mean(r.v + shift)))
    assert bias[5] < bias[3] / 2


def test_quintic_affine_and_translation_steps_recover_an_affine_warp(pattern, grid):
    """A start 2 px off takes the translation pre-stage (``sample_shift5``), then the affine steps."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, affine(1.4, -0.6, 0.02, -0.01, 0.005, 0.015, centre=(64, 64)), bit_depth=None)
    cubic = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size) - 0.6, np.zeros(xs.size) + 1.4, _ok(xs.size), HALF)
    quintic = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size) - 0.6, np.zeros(xs.size) + 1.4, _ok(xs.size), HALF,
                          degree=5)
    assert np.all(quintic.status == Status.OK) and np.all(cubic.status == Status.OK)
    for name in ("u", "v", "ux", "uy", "vx", "vy"):
        np.testing.assert_allclose(getattr(quintic, name), getattr(cubic, name), rtol=0, atol=0.02)


def test_quintic_order_zero_and_bad_degree(pattern, grid):
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (0.4, -1.3), bit_depth=None)
    r = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.zeros(xs.size) - 1, _ok(xs.size), HALF, degree=5,
                    order=0)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u - 0.4)) < 0.01 and np.max(np.abs(r.v + 1.3)) < 0.01
    with pytest.raises(ValueError, match="degree must be one of 3, 5"):
        icgn.prepare_target(dfm, degree=4)


# ---------------------------------------------------------------------------
# septic B-spline targets (prepare_target(..., degree=7))


@pytest.mark.parametrize("shift", [(0.3, -0.2), (1.7, 0.45), (-0.55, 2.25)])
def test_septic_recovers_an_exact_translation_of_a_band_limited_image(shift):
    """Unrounded, noise-free images, points 34 px or more from the edges (the septic prefilter's mirror boundary
    weighs 0.54^k on coefficients k px in, the quintic's 0.43^k): the septic target recovers the shift to
    < 1e-6 px (measured 2-4e-7), at least 2x better than the quintic (1.5-1.7e-6) and 100x the cubic."""
    g = np.arange(44, 85, 8)
    xs, ys = (a.ravel().astype(np.int64) for a in np.meshgrid(g, g))
    ref = _band_limited(SHAPE).astype(np.float32)
    dfm = _band_limited(SHAPE, shift).astype(np.float32)
    errors = {}
    for degree in (3, 5, 7):
        r = icgn.refine(ref, dfm, xs, ys, np.round(np.full(xs.size, shift[0])), np.round(np.full(xs.size, shift[1])),
                        _ok(xs.size), HALF, degree=degree)
        assert np.all(r.status == Status.OK)
        errors[degree] = max(np.max(np.abs(r.u - shift[0])), np.max(np.abs(r.v - shift[1])))
    assert errors[7] < 1e-6
    assert errors[7] < errors[5] / 2 and errors[7] < errors[3] / 100


def test_septic_translation_and_affine_steps_recover_an_affine_warp_and_order_zero(pattern, grid):
    """A start 2 px off takes the translation pre-stage (``sample_shift7``), then the affine steps; order 0 stops
    after the translation steps."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, affine(1.4, -0.6, 0.02, -0.01, 0.005, 0.015, centre=(64, 64)), bit_depth=None)
    quintic = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size) - 0.6, np.zeros(xs.size) + 1.4, _ok(xs.size), HALF,
                          degree=5)
    septic = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size) - 0.6, np.zeros(xs.size) + 1.4, _ok(xs.size), HALF,
                         degree=7)
    assert np.all(septic.status == Status.OK) and np.all(quintic.status == Status.OK)
    for name in ("u", "v", "ux", "uy", "vx", "vy"):
        np.testing.assert_allclose(getattr(septic, name), getattr(quintic, name), rtol=0, atol=0.005)
    shifted = render(pattern, (0.4, -1.3), bit_depth=None)
    r = icgn.refine(ref, shifted, xs, ys, np.zeros(xs.size), np.zeros(xs.size) - 1, _ok(xs.size), HALF, degree=7,
                    order=0)
    assert np.all(r.status == Status.OK)
    assert np.max(np.abs(r.u - 0.4)) < 0.01 and np.max(np.abs(r.v + 1.3)) < 0.01


@pytest.mark.parametrize("shift", [0.3, 0.7])
def test_septic_bias_on_rendered_subpixel_shift_is_the_quintics_far_below_the_cubics(pattern, grid, shift):
    """Smooth rendered speckle: the quintic already leaves ~1.5e-6 px; the septic stays there (measured 1.8e-6 and
    2.6e-6: the grid comes within 10 px of the edges, where its prefilter's boundary weighs more), the cubic 6e-5."""
    xs, ys = grid
    ref = render(pattern, bit_depth=None)
    dfm = render(pattern, (shift, -shift), bit_depth=None)
    bias = {}
    for degree in (3, 7):
        r = icgn.refine(ref, dfm, xs, ys, np.zeros(xs.size), np.zeros(xs.size), _ok(xs.size), HALF, degree=degree)
        assert np.all(r.status == Status.OK)
        bias[degree] = max(abs(np.mean(r.u - shift)), abs(np.mean(r.v + shift)))
    assert bias[7] < 1e-5 and bias[7] < bias[3] / 10
