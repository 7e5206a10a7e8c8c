"""Classic and improved surface fit on exact simulated speckle (dic.speckle)."""

import numba
import numpy as np
import pytest

from livedic.dic.search import search_points
from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.status import Status
from livedic.dic.subpixel import improved_surface_fit, surface_fit
from livedic.dic.subpixel.lattice import build_plane, lattice_tables, node_zncc

SIZE = 256
HALF = 10  # subset 21


@pytest.fixture(scope="module")
def pattern():
    # the paper's simulation: 256 x 256, 1000 speckles of size (R) 4 px, 8-bit, noise free
    return SpecklePattern((SIZE, SIZE), n_speckles=1000, radius=4.0, seed=0)


@pytest.fixture(scope="module")
def reference(pattern):
    return render(pattern).astype(np.float32)


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(42)
    xy = rng.integers(HALF + 6, SIZE - HALF - 6, size=(200, 2))
    return xy[:, 0].astype(np.int64), xy[:, 1].astype(np.int64)


def _start(reference, deformed, points, radius=2, margin=3):
    xs, ys = points
    zero = np.zeros(xs.shape[0])
    found = search_points(reference, deformed, xs, ys, zero, zero, HALF, radius, "exhaustive", margin=margin)
    return found


def _refine(module, reference, deformed, points, found, **options):
    xs, ys = points
    return module.refine(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float), found.status,
                         HALF, **options)


def _keys(t):
    a = -0.5
    s = np.abs(np.array([1.0 + t, t, 1.0 - t, 2.0 - t]))
    near = (a + 2) * s ** 3 - (a + 3) * s ** 2 + 1
    far = a * s ** 3 - 5 * a * s ** 2 + 8 * a * s - 4 * a
    return np.where(s <= 1, near, np.where(s < 2, far, 0.0))


def _zncc_numpy(reference, deformed, x, y, u, v):
    """Independent ZNCC at a sub-pixel (u, v): Keys a = -0.5 interpolation of the deformed image."""
    f = reference[y - HALF:y + HALF + 1, x - HALF:x + HALF + 1].astype(np.float64)
    x0, y0 = int(np.floor(x + u)), int(np.floor(y + v))
    wx, wy = _keys(x + u - x0), _keys(y + v - y0)
    g = np.zeros_like(f)
    for m in range(4):
        for k in range(4):
            g += wy[m] * wx[k] * deformed[y0 - HALF + m - 1:y0 + HALF + m, x0 - HALF + k - 1:x0 + HALF + k]
    f = f - f.mean()
    g = g - g.mean()
    return float(np.sum(f * g) / np.sqrt(np.sum(f * f) * np.sum(g * g)))


@pytest.mark.parametrize("shift", [(0.3, -0.2), (0.5, 0.5), (-0.8, 0.1), (1.4, -1.7)])
def test_surface_fit_recovers_subpixel_shifts_within_its_bound(pattern, reference, points, shift):
    deformed = render(pattern, shift).astype(np.float32)
    found = _start(reference, deformed, points)
    r = _refine(surface_fit, reference, deformed, points, found)
    assert np.all(r.status == Status.OK)
    err_u, err_v = r.u - shift[0], r.v - shift[1]
    assert abs(err_u.mean()) < 0.02 and abs(err_v.mean()) < 0.02
    assert np.percentile(np.hypot(err_u, err_v), 95) < 0.1
    assert np.all(np.abs(err_u) < 0.3) and np.all(np.abs(err_v) < 0.3)


def test_improved_surface_fit_mean_bias_is_below_0_006_px(pattern, reference, points):
    worst = 0.0
    for s in np.round(np.arange(0.0, 1.01, 0.1), 2):
        deformed = render(pattern, (s, 0.0)).astype(np.float32)
        found = _start(reference, deformed, points)
        r = _refine(improved_surface_fit, reference, deformed, points, found)
        assert np.all(r.status == Status.OK)
        worst = max(worst, abs(np.mean(r.u) - s), abs(np.mean(r.v)))
        assert np.std(r.u) < 0.01
    assert worst <= 0.006


def test_improved_fit_beats_classic_fit_per_point(pattern, reference, points):
    shift = (0.3, 0.7)
    deformed = render(pattern, shift).astype(np.float32)
    found = _start(reference, deformed, points)
    classic = _refine(surface_fit, reference, deformed, points, found)
    improved = _refine(improved_surface_fit, reference, deformed, points, found)
    rms = lambda r: np.sqrt(np.mean((r.u - shift[0]) ** 2 + (r.v - shift[1]) ** 2))
    assert rms(improved) < 0.25 * rms(classic)


def test_zncc_at_the_improved_peak_is_at_least_the_integer_peak(pattern, reference, points):
    deformed = render(pattern, (0.4, -0.3)).astype(np.float32)
    found = _start(reference, deformed, points)
    r = _refine(improved_surface_fit, reference, deformed, points, found)
    xs, ys = points
    assert np.all(r.zncc >= found.zncc - 1e-9)
    for i in range(0, xs.shape[0], 10):
        exact = _zncc_numpy(reference, deformed, xs[i], ys[i], r.u[i], r.v[i])
        assert exact >= found.zncc[i] - 1e-9
        assert exact == pytest.approx(r.zncc[i], abs=2e-4)


def test_lattice_kernel_matches_numpy_keys_interpolation(pattern, reference):
    deformed = render(pattern, (0.35, 0.6)).astype(np.float32)
    x, y, half = 120, 90, HALF
    side = 2 * half + 1
    f = reference[y - half:y + half + 1, x - half:x + half + 1].astype(np.float64)
    fhat = (f - f.mean()) / np.sqrt(np.sum((f - f.mean()) ** 2))
    ix, ph, lr, rr, wts = lattice_tables(0.2, 10)
    planes = np.empty((wts.shape[0], side + 7, side + 4), dtype=np.float32)
    org_x, org_y = x - half + ix[0], y - half + ix[0] - 1
    for p in range(wts.shape[0]):
        build_plane(deformed, planes, p, wts, org_x, org_y, float(deformed[y, x]))
    for i, j in [(0, 0), (2, 3), (-4, 1), (7, -6), (-10, 10)]:
        ki, kj = i + 10, j + 10
        c = node_zncc(fhat.astype(np.float32), planes, ph[ki], ix[ki] - ix[0], ix[kj] - ix[0], wts[ph[kj]], side)
        assert c == pytest.approx(_zncc_numpy(reference, deformed, x, y, 0.2 * i, 0.2 * j), abs=1e-6)


def test_spacing_one_reproduces_the_classic_fit_and_error_grows_with_spacing(pattern, reference, points):
    deformed = render(pattern, (0.2, 0.0)).astype(np.float32)
    found = _start(reference, deformed, points)
    classic = _refine(surface_fit, reference, deformed, points, found)
    sd = {}
    for h in (0.2, 1.0, 2.0):
        r = _refine(improved_surface_fit, reference, deformed, points, found, spacing=h)
        assert np.all(r.status == Status.OK)
        sd[h] = np.std(r.u)
        if h == 1.0:
            np.testing.assert_allclose(r.u, classic.u, atol=1e-5)
            np.testing.assert_allclose(r.v, classic.v, atol=1e-5)
    assert sd[0.2] < sd[1.0] < sd[2.0]  # the paper's Fig. 7 trend


def test_other_status_codes_are_copied_through(pattern, reference, points):
    deformed = render(pattern, (0.5, 0.25)).astype(np.float32)
    found = _start(reference, deformed, points)
    status = found.status.copy()
    status[::3] = Status.LOW_CORRELATION
    xs, ys = points
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float), status, HALF)
        assert np.all(r.status[::3] == Status.LOW_CORRELATION)
        assert np.all(np.isnan(r.u[::3])) and np.all(np.isnan(r.v[::3]))
        assert np.all(r.status[1::3] == Status.OK) and np.all(np.isfinite(r.u[1::3]))


def test_peaks_against_the_image_edge_are_flagged_not_extrapolated(pattern, reference):
    # the true peak lies towards the image edge and the nodes needed to bracket it would leave the image
    deformed = render(pattern, (-0.3, 0.3)).astype(np.float32)
    xs = np.array([HALF, 128, 128], dtype=np.int64)
    ys = np.array([128, SIZE - 1 - HALF, 128], dtype=np.int64)
    zero = np.zeros(3)
    ok = np.zeros(3, dtype=np.int8)
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(reference, deformed, xs, ys, zero, zero, ok, HALF)
        assert list(r.status) == [Status.OUTSIDE_TARGET, Status.OUTSIDE_TARGET, Status.OK]
        assert np.all(np.isnan(r.u[:2])) and np.all(np.isnan(r.v[:2]))
        assert r.u[2] == pytest.approx(-0.3, abs=0.1) and r.v[2] == pytest.approx(0.3, abs=0.1)


def test_flat_reference_and_bad_start(reference):
    flat = np.full((64, 64), 50.0, dtype=np.float32)
    xs = np.array([32, 32], dtype=np.int64)
    ys = np.array([32, 32], dtype=np.int64)
    u0 = np.array([0.0, np.nan])
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(flat, flat, xs, ys, u0, np.zeros(2), np.zeros(2, dtype=np.int8), HALF)
        assert list(r.status) == [Status.FLAT_REFERENCE, Status.BAD_GUESS]


def test_improved_fit_is_reproducible_and_thread_independent(pattern, reference, points):
    deformed = render(pattern, (0.7, -0.45)).astype(np.float32)
    found = _start(reference, deformed, points)
    a = _refine(improved_surface_fit, reference, deformed, points, found)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        b = _refine(improved_surface_fit, reference, deformed, points, found)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)


def test_unknown_option_is_rejected(reference, points):
    xs, ys = points
    z = np.zeros(xs.shape[0])
    st = np.zeros(xs.shape[0], dtype=np.int8)
    with pytest.raises(ValueError, match="spacing"):
        improved_surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spaceing=0.1)
    with pytest.raises(ValueError, match="spacing"):
        improved_surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spacing=-1.0)
    with pytest.raises(ValueError, match="max_moves"):
        surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spacing=0.2)
