"""Tests of dic/subpixel/improved_surface_fit.py: the paper's lattice + improved WSO + 3x3 fit, on exact speckle."""

import numba
import numpy as np
import pytest

from livedic.dic.speckle import render
from livedic.dic.status import Status
from livedic.dic.subpixel import improved_surface_fit, surface_fit
from livedic.dic.subpixel.improved_surface_fit import lattice_half_nodes, refine_with_counts
from tests.dic.subpixel.conftest import HALF, integer_start, refine_with, zncc_numpy


def test_improved_surface_fit_mean_bias_is_below_0_006_px(pattern, reference, points):
    worst = 0.0
    for s in np.round(np.arange(0.0, 1.01, 0.1), 2):
        deformed = render(pattern, (s, 0.0)).astype(np.float32)
        found = integer_start(reference, deformed, points)
        r = refine_with(improved_surface_fit, reference, deformed, points, found)
        assert np.all(r.status == Status.OK)
        worst = max(worst, abs(np.mean(r.u) - s), abs(np.mean(r.v)))
        assert np.std(r.u) < 0.01
    assert worst <= 0.006


def test_improved_fit_beats_classic_fit_per_point(pattern, reference, points):
    shift = (0.3, 0.7)
    deformed = render(pattern, shift).astype(np.float32)
    found = integer_start(reference, deformed, points)
    classic = refine_with(surface_fit, reference, deformed, points, found)
    improved = refine_with(improved_surface_fit, reference, deformed, points, found)
    rms = lambda r: np.sqrt(np.mean((r.u - shift[0]) ** 2 + (r.v - shift[1]) ** 2))
    assert rms(improved) < 0.25 * rms(classic)


def test_zncc_at_the_improved_peak_is_at_least_the_integer_peak(pattern, reference, points):
    deformed = render(pattern, (0.4, -0.3)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    r = refine_with(improved_surface_fit, reference, deformed, points, found)
    xs, ys = points
    assert np.all(r.zncc >= found.zncc - 1e-9)
    for i in range(0, xs.shape[0], 10):
        exact = zncc_numpy(reference, deformed, xs[i], ys[i], r.u[i], r.v[i])
        assert exact >= found.zncc[i] - 1e-9
        assert exact == pytest.approx(r.zncc[i], abs=2e-4)


def test_spacing_one_reproduces_the_classic_fit_and_error_grows_with_spacing(pattern, reference, points):
    deformed = render(pattern, (0.2, 0.0)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    classic = refine_with(surface_fit, reference, deformed, points, found)
    sd = {}
    for h in (0.2, 1.0, 2.0):
        r = refine_with(improved_surface_fit, reference, deformed, points, found, spacing=h)
        assert np.all(r.status == Status.OK)
        sd[h] = np.std(r.u)
        if h == 1.0:
            np.testing.assert_allclose(r.u, classic.u, atol=1e-5)
            np.testing.assert_allclose(r.v, classic.v, atol=1e-5)
    assert sd[0.2] < sd[1.0] < sd[2.0]  # the paper's Fig. 7 trend


def test_improved_fit_is_reproducible_and_thread_independent(pattern, reference, points):
    deformed = render(pattern, (0.7, -0.45)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    a = refine_with(improved_surface_fit, reference, deformed, points, found)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        b = refine_with(improved_surface_fit, reference, deformed, points, found)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)


def test_unknown_option_or_bad_value_is_rejected(reference, points):
    xs, ys = points
    z = np.zeros(xs.shape[0])
    st = np.zeros(xs.shape[0], dtype=np.int8)
    with pytest.raises(ValueError, match="spacing"):
        improved_surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spaceing=0.1)
    with pytest.raises(ValueError, match="spacing"):
        improved_surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spacing=-1.0)


@pytest.mark.parametrize("spacing, extent, nodes", [(0.2, 1.0, 5), (0.2, 0.05, 1), (0.5, 1.0, 2), (1.0, 1.0, 1),
                                                    (0.3, 1.0, 3)])
def test_the_lattice_reaches_the_extent_with_at_least_one_node_each_side(spacing, extent, nodes):
    assert lattice_half_nodes(spacing, extent) == nodes


def test_distinct_node_evaluations_stay_within_the_extended_lattice(pattern, reference, points):
    deformed = render(pattern, (0.45, -0.15)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    xs, ys = points
    result, evals = refine_with_counts(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float),
                                       found.status, HALF)
    m = lattice_half_nodes(0.2, 1.0)
    assert np.all(result.status == Status.OK)
    assert np.all(evals >= 9) and np.all(evals <= (4 * m + 1) ** 2)     # the 3x3 at least, the 2m-wide lattice at most
    skipped = found.status.copy()
    skipped[:] = Status.LOW_CORRELATION
    _, none = refine_with_counts(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float),
                                 skipped, HALF)
    assert np.all(none == 0)                                           # points not OK are never refined


def test_no_points_give_empty_results(reference):
    empty = np.zeros(0, dtype=np.int64)
    r = improved_surface_fit.refine(reference, reference, empty, empty, np.zeros(0), np.zeros(0),
                                    np.zeros(0, dtype=np.int8), HALF)
    assert r.u.shape == r.v.shape == r.zncc.shape == r.status.shape == (0,)


def test_a_non_integer_start_is_rounded_to_the_integer_peak(pattern, reference, points):
    deformed = render(pattern, (1.3, -0.6)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    xs, ys = points
    exact = refine_with(improved_surface_fit, reference, deformed, points, found)
    nudged = improved_surface_fit.refine(reference, deformed, xs, ys, found.u + 0.3, found.v - 0.4, found.status, HALF)
    np.testing.assert_array_equal(exact.u, nudged.u)
    np.testing.assert_array_equal(exact.v, nudged.v)
