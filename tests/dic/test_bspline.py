import numpy as np
import pytest

from livedic.dic.bspline import _horizon, GAIN, PAD, POLE, BSplineCoefficients, interpolate, prefilter, sample_shift
from livedic.dic.subpixel.icgn import prepare_target
from tests.conftest import blurred_noise


def _cubic(x, y):
    return 3.0 + 0.5 * x - 0.25 * y + 0.02 * x * x - 0.01 * x * y + 0.003 * y * y \
        + 4e-4 * x ** 3 - 2e-4 * x * x * y + 1e-4 * x * y * y - 3e-4 * y ** 3


def _cubic_gradient(x, y):
    gx = 0.5 + 0.04 * x - 0.01 * y + 1.2e-3 * x * x - 4e-4 * x * y + 1e-4 * y * y
    gy = -0.25 - 0.01 * x + 0.006 * y - 2e-4 * x * x + 2e-4 * x * y - 9e-4 * y * y
    return gx, gy


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-9), (np.float32, 2e-5)])
def test_reproduces_samples_at_integer_positions(dtype, tol):
    image = blurred_noise((37, 53), seed=2).astype(np.float64)
    coeffs = prefilter(image, dtype=dtype)
    rows, cols = np.mgrid[0:37, 0:53]
    values = interpolate(coeffs, cols, rows)
    # exact up to the storage precision of the coefficients, the borders included
    assert np.max(np.abs(values - image)) <= tol * np.max(np.abs(image))


def test_reproduces_cubic_polynomials_and_their_gradient():
    rows, cols = np.mgrid[0:64, 0:64].astype(np.float64)
    image = _cubic(cols, rows)
    coeffs = prefilter(image, dtype=np.float64)
    rng = np.random.default_rng(0)
    # away from the mirror boundary (its effect decays as 0.268^distance)
    x = rng.uniform(20, 43, 500)
    y = rng.uniform(20, 43, 500)
    values, gx, gy = interpolate(coeffs, x, y, gradient=True)
    ex, ey = _cubic_gradient(x, y)
    np.testing.assert_allclose(values, _cubic(x, y), rtol=0, atol=1e-9)
    np.testing.assert_allclose(gx, ex, rtol=0, atol=1e-9)
    np.testing.assert_allclose(gy, ey, rtol=0, atol=1e-9)


def test_quartic_is_not_reproduced():
    """The test above can fail: a degree-4 term is outside the cubic spline space."""
    rows, cols = np.mgrid[0:64, 0:64].astype(np.float64)
    image = 1e-3 * (cols - 30.3) ** 4
    coeffs = prefilter(image, dtype=np.float64)
    x = np.array([31.5, 32.25])
    y = np.array([30.0, 30.0])
    assert np.max(np.abs(interpolate(coeffs, x, y) - 1e-3 * (x - 30.3) ** 4)) > 1e-5


def test_matches_scipy_spline_with_mirror_boundaries():
    ndimage = pytest.importorskip("scipy.ndimage")
    image = blurred_noise((30, 41), seed=5).astype(np.float64)
    coeffs = prefilter(image, dtype=np.float64)
    interior = coeffs.coefficients[PAD:-PAD, PAD:-PAD]
    np.testing.assert_allclose(interior, ndimage.spline_filter(image, order=3, mode="mirror"), atol=1e-9)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 40, 300)
    y = rng.uniform(0, 29, 300)
    expected = ndimage.map_coordinates(image, [y, x], order=3, mode="mirror")
    np.testing.assert_allclose(interpolate(coeffs, x, y), expected, atol=1e-9)


def _filtered_line(line):
    """The prefilter of one line, one operation after another in Python floats (IEEE doubles): the reference
    for the kernels, which filter many lines at once but must do the same arithmetic on each."""
    z, n = POLE, len(line)
    if n == 1:
        return list(line)
    if n > _horizon(POLE):
        acc, zk = 0.0, 1.0
        for k in range(_horizon(POLE)):
            acc += zk * line[k]
            zk *= z
    else:
        z2n = z ** (2 * n - 2)
        acc = line[0] + z ** (n - 1) * line[n - 1]
        zk = z
        for k in range(1, n - 1):
            acc += (zk + z2n / zk) * line[k]
            zk *= z
        acc = acc / (1.0 - z2n)
    c = [acc]
    for k in range(1, n):
        c.append(line[k] + z * c[-1])
    c[-1] = (z / (z * z - 1.0)) * (c[-1] + z * c[-2])
    for k in range(n - 2, -1, -1):
        c[k] = z * (c[k + 1] - c[k])
    return [GAIN * value for value in c]


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (9, 1), (2, 40), (40, 2), (29, 31), (33, 70), (70, 130)])
def test_prefilter_is_the_recursive_filter_bit_for_bit(shape):
    """Rows, then columns, each stored as float32 (the coefficients' storage) in between, whatever the image's
    size against the kernels' blocks of lines and the horizon of the causal sum."""
    image = (blurred_noise(shape, seed=7) * 200).astype(np.uint8)
    rows = np.array([np.float32(_filtered_line([float(v) for v in row])) for row in image], dtype=np.float32)
    expected = np.array([_filtered_line([float(v) for v in column]) for column in rows.T], dtype=np.float32).T
    got = prefilter(image).coefficients[PAD:PAD + shape[0], PAD:PAD + shape[1]]
    assert got.tobytes() == expected.tobytes()


def test_prefilter_reads_views_and_8_16_bit_frames_as_they_are_and_reuses_a_buffer():
    """The same coefficients, bit for bit, from a strided 8- or 16-bit window as from its float32 copy
    (what ``prepare_target`` made before); ``out`` gives them in an earlier frame's buffer."""
    frame = (blurred_noise((90, 120), seed=8) * 60000).astype(np.uint16)
    for image in (frame, (frame // 257).astype(np.uint8)):
        window = image[11:80, 7:101]
        expected = prefilter(np.ascontiguousarray(window, dtype=np.float32)).flat
        assert prefilter(window).flat.tobytes() == expected.tobytes()
        assert prepare_target(window).flat.tobytes() == expected.tobytes()
        earlier = prepare_target(image[1:70, 20:114])
        again = prepare_target(window, out=earlier)
        assert again is earlier and again.flat.tobytes() == expected.tobytes()
        assert prepare_target(image[:10, :10], out=earlier) is not earlier      # another size: a new buffer
    wide = frame.astype(np.int64) * 1000 + 1          # grey levels float32 rounds: rounded as as_image does
    expected = prefilter(wide.astype(np.float32)).flat
    assert prepare_target(wide).flat.tobytes() == expected.tobytes()


def test_outside_domain_and_nan_give_nan():
    image = blurred_noise((20, 25), seed=1)
    coeffs = prefilter(image)
    x = np.array([-0.01, 24.0, 24.01, 3.0, np.nan])
    y = np.array([5.0, 19.0, 5.0, -1.0, 5.0])
    values = interpolate(coeffs, x, y)
    assert np.isnan(values[[0, 2, 3, 4]]).all()
    assert np.isfinite(values[1])


def test_coefficient_buffer_layout():
    image = blurred_noise((12, 17), seed=3)
    coeffs = prefilter(image)
    assert isinstance(coeffs, BSplineCoefficients)
    assert coeffs.coefficients.dtype == np.float32
    assert coeffs.coefficients.shape == (12 + 2 * PAD, 17 + 2 * PAD)
    stride = coeffs.coefficients.shape[1]
    view = coeffs.flat[coeffs.origin:coeffs.origin + coeffs.coefficients.size].reshape(coeffs.coefficients.shape)
    np.testing.assert_array_equal(view, coeffs.coefficients)
    assert np.all(coeffs.flat[:coeffs.origin] == 0) and coeffs.origin >= stride
    # mirrored padding: coefficient -k equals coefficient k
    np.testing.assert_array_equal(coeffs.coefficients[PAD:-PAD, PAD - 1], coeffs.coefficients[PAD:-PAD, PAD + 1])
    with pytest.raises(ValueError, match="2-D"):
        prefilter(np.zeros(5))


@pytest.mark.parametrize("half", [3, 10, 12])
def test_separable_shift_sampler_matches_pointwise_interpolation(half):
    image = blurred_noise((60, 70), seed=4)
    coeffs = prefilter(image)
    side = 2 * half + 1
    lanes = -(-side // 8) * 8
    tmp = np.zeros((side + 3) * lanes, dtype=np.float32)
    out = np.zeros(side * lanes, dtype=np.float32)
    x, y = 31.37, 28.81
    sample_shift(coeffs.flat, coeffs.origin, coeffs.coefficients.shape[1], x, y, half, tmp, out, lanes)
    got = out.reshape(side, lanes)
    dy, dx = np.mgrid[-half:half + 1, -half:half + 1]
    expected = interpolate(prefilter(image, dtype=np.float64), x + dx, y + dy)
    np.testing.assert_allclose(got[:, :side], expected, rtol=0, atol=2e-4 * np.abs(expected).max())
    assert np.all(got[:, side:] == 0)


def test_float32_lanes_is_a_vector_width_and_lays_out_the_icgn_subsets():
    """IC-GN's subset rows are whole vectors of the width the kernels are compiled for (8 AVX2, 16 AVX-512)."""
    from livedic.dic.bspline import float32_lanes
    from livedic.dic.subpixel.icgn import prepare_reference
    lanes = float32_lanes()
    assert lanes in (8, 16)
    image = blurred_noise((64, 64), seed=3).astype(np.float32)
    for half in (5, 10, 15):
        prep = prepare_reference(image, np.array([32]), np.array([32]), half)
        assert prep.lanes % lanes == 0 and 2 * half + 1 <= prep.lanes < 2 * half + 1 + lanes


def test_float32_lanes_falls_back_to_the_avx2_width_without_assembly(monkeypatch):
    from livedic.dic import bspline
    monkeypatch.setattr(bspline, "njit", lambda **options: (lambda f: (_ for _ in ()).throw(RuntimeError("no JIT"))))
    bspline.float32_lanes.cache_clear()
    try:
        assert bspline.float32_lanes() == 8
    finally:
        bspline.float32_lanes.cache_clear()


# ---------------------------------------------------------------------------
# quintic B-spline (degree=5)


def _quintic(x, y):
    return _cubic(x, y) + 2e-6 * (x - 30.3) ** 4 - 1e-7 * (y - 31.1) ** 5 + 3e-7 * x * x * y * y * 1e-1


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-9), (np.float32, 3e-5)])
def test_quintic_reproduces_samples_at_integer_positions(dtype, tol):
    image = blurred_noise((37, 53), seed=2).astype(np.float64)
    coeffs = prefilter(image, dtype=dtype, degree=5)
    assert coeffs.degree == 5
    rows, cols = np.mgrid[0:37, 0:53]
    values = interpolate(coeffs, cols, rows)
    assert np.max(np.abs(values - image)) <= tol * np.max(np.abs(image))


def test_quintic_reproduces_polynomials_up_to_degree_5_and_their_gradient():
    rows, cols = np.mgrid[0:72, 0:72].astype(np.float64)
    image = _quintic(cols, rows)
    coeffs = prefilter(image, dtype=np.float64, degree=5)
    rng = np.random.default_rng(0)
    # away from the mirror boundary (its effect decays as 0.43^distance)
    x = rng.uniform(30, 41, 400)
    y = rng.uniform(30, 41, 400)
    values, gx, gy = interpolate(coeffs, x, y, gradient=True)
    h = 1e-5
    np.testing.assert_allclose(values, _quintic(x, y), rtol=0, atol=1e-8)
    np.testing.assert_allclose(gx, (_quintic(x + h, y) - _quintic(x - h, y)) / (2 * h), rtol=0, atol=1e-6)
    np.testing.assert_allclose(gy, (_quintic(x, y + h) - _quintic(x, y - h)) / (2 * h), rtol=0, atol=1e-6)


def test_quartic_is_reproduced_by_the_quintic_not_by_the_cubic():
    rows, cols = np.mgrid[0:64, 0:64].astype(np.float64)
    image = 1e-3 * (cols - 30.3) ** 4
    x = np.array([31.5, 32.25, 30.7])
    y = np.array([30.0, 30.0, 33.4])
    truth = 1e-3 * (x - 30.3) ** 4
    assert np.max(np.abs(interpolate(image, x, y, degree=5) - truth)) < 1e-9
    assert np.max(np.abs(interpolate(image, x, y, degree=3) - truth)) > 1e-5


def test_quintic_matches_scipy_spline_with_mirror_boundaries():
    ndimage = pytest.importorskip("scipy.ndimage")
    image = blurred_noise((30, 41), seed=5).astype(np.float64)
    coeffs = prefilter(image, dtype=np.float64, degree=5)
    interior = coeffs.coefficients[PAD:-PAD, PAD:-PAD]
    np.testing.assert_allclose(interior, ndimage.spline_filter(image, order=5, mode="mirror"), atol=1e-9)
    rng = np.random.default_rng(1)
    # the whole domain, the borders included (taps reach 3 px right of floor(x): the padding)
    x = np.concatenate([rng.uniform(0, 40, 300), [0.0, 40.0, 39.99, 0.3]])
    y = np.concatenate([rng.uniform(0, 29, 300), [0.0, 29.0, 28.7, 28.99]])
    expected = ndimage.map_coordinates(image, [y, x], order=5, mode="mirror")
    np.testing.assert_allclose(interpolate(coeffs, x, y), expected, atol=1e-9)


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (2, 40), (33, 70)])
def test_quintic_prefilter_round_trips_small_and_odd_shapes(shape):
    """Lines shorter than the poles' horizons (exact periodic initial sums) as well as long ones."""
    ndimage = pytest.importorskip("scipy.ndimage")
    image = blurred_noise(shape, seed=3).astype(np.float64)
    coeffs = prefilter(image, dtype=np.float64, degree=5)
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    np.testing.assert_allclose(interpolate(coeffs, cols, rows), image, atol=1e-9)
    if min(shape) > 8:      # scipy's initial sums of very short lines are rounded to float32
        np.testing.assert_allclose(coeffs.coefficients[PAD:-PAD, PAD:-PAD],
                                   ndimage.spline_filter(image, order=5, mode="mirror"), atol=1e-9)


def test_prefilter_degree_is_checked_and_a_buffer_of_another_degree_is_not_reused():
    image = blurred_noise((20, 24), seed=1)
    cubic = prefilter(image)
    quintic = prefilter(image, out=cubic, degree=5)
    assert quintic is not cubic and quintic.degree == 5 and cubic.degree == 3
    assert prefilter(image, out=quintic, degree=5) is quintic
    for bad in (4, "5", True, 3.5):
        with pytest.raises(ValueError, match="degree must be one of 3, 5"):
            prefilter(image, degree=bad)


# ---------------------------------------------------------------------------
# septic B-spline (degree=7)


def _beta(n, x):
    """The centred B-spline of degree ``n``, from its definition (a sum of truncated powers)."""
    from math import comb, factorial
    x = np.asarray(x, dtype=np.float64)
    return sum((-1) ** k * comb(n + 1, k) * np.maximum(x + (n + 1) / 2 - k, 0.0) ** n
               for k in range(n + 2)) / factorial(n)


def _beta7(x):
    """The septic B-spline: the slow reference."""
    return _beta(7, x)


def _mirror_index(i, n):
    if n == 1:
        return 0
    period = 2 * n - 2
    i = i % period
    return period - i if i >= n else i


def _septic_reference(image, x, y):
    """Slow septic interpolation: coefficients from a dense solve of the interpolation condition with mirrored
    coefficients (the prefilter's boundary condition), values from ``_beta7`` at every tap."""
    def solve(n):
        a = np.zeros((n, n))
        for i in range(n):
            for j in range(i - 3, i + 4):
                a[i, _mirror_index(j, n)] += _beta7(i - j)
        return np.linalg.inv(a)
    height, width = image.shape
    coeffs = solve(height) @ image @ solve(width).T
    out = np.zeros(np.shape(x))
    for idx in np.ndindex(out.shape):
        px, py = x[idx], y[idx]
        for j in range(int(py) - 4, int(py) + 5):
            for k in range(int(px) - 4, int(px) + 5):
                out[idx] += _beta7(px - k) * _beta7(py - j) * coeffs[_mirror_index(j, height), _mirror_index(k, width)]
    return coeffs, out


def test_septic_weights_are_the_b_spline_and_sum_to_one():
    from livedic.dic.bspline import derivative_weights7, weights7
    for t in np.linspace(0.0, 1.0, 23):
        w = np.array(weights7(t))
        np.testing.assert_allclose(w, _beta7(t + 3 - np.arange(8)), rtol=0, atol=1e-12)   # the sum cancels to ~1e-14
        assert abs(w.sum() - 1.0) < 1e-15
        x = t + 3 - np.arange(8)     # d/dx beta7(x) = beta6(x + 1/2) - beta6(x - 1/2)
        np.testing.assert_allclose(derivative_weights7(t), _beta(6, x + 0.5) - _beta(6, x - 0.5), rtol=0, atol=1e-12)
        assert abs(sum(derivative_weights7(t))) < 1e-15


@pytest.mark.parametrize("dtype, tol", [(np.float64, 1e-9), (np.float32, 5e-5)])
def test_septic_reproduces_samples_at_integer_positions(dtype, tol):
    image = blurred_noise((37, 53), seed=2).astype(np.float64)
    coeffs = prefilter(image, dtype=dtype, degree=7)
    assert coeffs.degree == 7
    rows, cols = np.mgrid[0:37, 0:53]
    values = interpolate(coeffs, cols, rows)      # the last row and column too (taps shifted one left there)
    assert np.max(np.abs(values - image)) <= tol * np.max(np.abs(image))


def _septic_poly(x, y):
    return _quintic(x, y) + 3e-10 * (x - 29.7) ** 6 * (1.0 + 1e-2 * (y - 40.2)) - 2e-11 * (y - 41.3) ** 7


def test_septic_reproduces_polynomials_up_to_degree_7_and_their_gradient():
    rows, cols = np.mgrid[0:96, 0:96].astype(np.float64)
    image = _septic_poly(cols, rows)
    coeffs = prefilter(image, dtype=np.float64, degree=7)
    rng = np.random.default_rng(0)
    # away from the mirror boundary (its effect decays as 0.54^distance: 1e-14 at 42 px)
    x = rng.uniform(42, 53, 400)
    y = rng.uniform(42, 53, 400)
    values, gx, gy = interpolate(coeffs, x, y, gradient=True)
    h = 1e-5
    np.testing.assert_allclose(values, _septic_poly(x, y), rtol=0, atol=1e-8)
    np.testing.assert_allclose(gx, (_septic_poly(x + h, y) - _septic_poly(x - h, y)) / (2 * h), rtol=0, atol=1e-5)
    np.testing.assert_allclose(gy, (_septic_poly(x, y + h) - _septic_poly(x, y - h)) / (2 * h), rtol=0, atol=1e-5)


def test_sextic_is_reproduced_by_the_septic_not_by_the_quintic():
    rows, cols = np.mgrid[0:96, 0:96].astype(np.float64)
    image = 1e-6 * (cols - 47.3) ** 6
    x = np.array([48.5, 47.25, 46.7])
    y = np.array([47.0, 47.0, 49.4])
    truth = 1e-6 * (x - 47.3) ** 6
    assert np.max(np.abs(interpolate(image, x, y, degree=7) - truth)) < 1e-9
    assert np.max(np.abs(interpolate(image, x, y, degree=5) - truth)) > 2e-8     # 4.7e-8 measured


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (2, 40), (23, 31)])
def test_septic_matches_a_slow_reference_on_the_whole_domain(shape):
    """Coefficients and values against ``_septic_reference``: lines shorter than the poles' horizons (exact
    periodic initial sums) and long ones, the borders included (x = W - 1 exactly: taps shifted one left)."""
    image = blurred_noise(shape, seed=3).astype(np.float64)
    coeffs = prefilter(image, dtype=np.float64, degree=7)
    rng = np.random.default_rng(1)
    height, width = shape
    x = np.concatenate([rng.uniform(0, width - 1, 60), [0.0, width - 1.0, max(width - 1.01, 0.0), 0.3 * (width > 1)]])
    y = np.concatenate([rng.uniform(0, height - 1, 60), [0.0, height - 1.0, height - 1.0, 0.0]])
    expected_coeffs, expected = _septic_reference(image, x, y)
    np.testing.assert_allclose(coeffs.coefficients[PAD:PAD + height, PAD:PAD + width], expected_coeffs, atol=1e-9)
    np.testing.assert_allclose(interpolate(coeffs, x, y), expected, atol=1e-9)


def test_septic_shift_sampler_matches_pointwise_interpolation():
    from livedic.dic.bspline import sample_shift7
    image = blurred_noise((60, 70), seed=4)
    coeffs = prefilter(image, degree=7)
    half = 10
    side = 2 * half + 1
    lanes = -(-side // 8) * 8
    tmp = np.zeros((side + 7) * lanes, dtype=np.float32)
    out = np.zeros(side * lanes, dtype=np.float32)
    x, y = 31.37, 28.81
    sample_shift7(coeffs.flat, coeffs.origin, coeffs.coefficients.shape[1], x, y, half, tmp, out, lanes)
    got = out.reshape(side, lanes)
    dy, dx = np.mgrid[-half:half + 1, -half:half + 1]
    expected = interpolate(prefilter(image, dtype=np.float64, degree=7), x + dx, y + dy)
    np.testing.assert_allclose(got[:, :side], expected, rtol=0, atol=2e-4 * np.abs(expected).max())
    assert np.all(got[:, side:] == 0)


def test_septic_buffer_is_not_reused_for_another_degree():
    image = blurred_noise((20, 24), seed=1)
    quintic = prefilter(image, degree=5)
    septic = prefilter(image, out=quintic, degree=7)
    assert septic is not quintic and septic.degree == 7
    assert prefilter(image, out=septic, degree=7) is septic
    with pytest.raises(ValueError, match="degree must be one of 3, 5, 7"):
        prefilter(image, degree=6)
