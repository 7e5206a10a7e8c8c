"""Integer-pixel searches on exact simulated speckle (dic.speckle): physics and contract."""

import numba
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from livedic.dic.search import SEARCH_METHODS, integer_search, method_options, search_points
from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.status import Status

SIZE = 256


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern((SIZE, SIZE), n_speckles=1000, radius=4.0, seed=3)


@pytest.fixture(scope="module")
def reference(pattern):
    return render(pattern)


def _points(n, half, radius, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = half + radius + 1, SIZE - half - radius - 1
    return rng.integers(lo, hi, size=(n, 2)).astype(np.float64)


def _success(found, truth):
    return np.mean((found.u == truth.u) & (found.v == truth.v))


@pytest.mark.parametrize("method", SEARCH_METHODS)
def test_every_method_finds_an_exact_integer_shift(pattern, reference, method):
    deformed = render(pattern, (5, -3))
    pts = _points(40, 15, 12, seed=1)
    r = integer_search(reference, deformed, pts, method=method, subset=31, radius=12, seed=4)
    assert np.all(r.status == Status.OK)
    hit = (r.u == 5) & (r.v == -3)
    if method in ("exhaustive", "improved-wso"):
        assert hit.all()
        assert np.all(r.zncc > 0.99)
    else:
        assert hit.mean() >= 0.9
    assert np.all(r.evaluations >= 1) and np.all(r.calls >= r.evaluations)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(u=st.integers(-10, 10), v=st.integers(-10, 10), seed=st.integers(0, 2**32 - 1))
def test_improved_wso_agrees_with_exhaustive_on_random_shifts(pattern, reference, u, v, seed):
    deformed = render(pattern, (u, v))
    pts = _points(20, 15, 12, seed=seed % 1000)
    truth = integer_search(reference, deformed, pts, method="exhaustive", subset=31, radius=12)
    found = integer_search(reference, deformed, pts, method="improved-wso", subset=31, radius=12, seed=seed)
    assert np.all(truth.u == u) and np.all(truth.v == v)
    np.testing.assert_array_equal(found.u, truth.u)
    np.testing.assert_array_equal(found.v, truth.v)


def test_fixing_the_gbest_bug_of_the_reference_wso_matters(pattern, reference):
    deformed = render(pattern, (6, 0))
    pts = _points(60, 10, 16, seed=2)
    truth = integer_search(reference, deformed, pts, method="exhaustive", radius=16)
    fixed = integer_search(reference, deformed, pts, method="wso", radius=16, fix_gbest=True)
    buggy = integer_search(reference, deformed, pts, method="wso", radius=16, fix_gbest=False)
    assert _success(fixed, truth) >= 0.9
    assert _success(buggy, truth) <= 0.5
    # the buggy variant returns the stale leader's position with its own ZNCC
    assert np.all(buggy.zncc <= truth.zncc + 1e-12)


def test_paper_variant_of_wso_runs_and_finds_most_shifts(pattern, reference):
    deformed = render(pattern, (4, 2))
    pts = _points(40, 10, 16, seed=3)
    r = integer_search(reference, deformed, pts, method="wso", radius=16, variant="paper")
    assert np.all(r.status == Status.OK)
    assert np.mean((r.u == 4) & (r.v == 2)) >= 0.6


@pytest.fixture(scope="module")
def evaluation_run(pattern, reference):
    deformed = render(pattern, (7, -2))
    pts = _points(60, 10, 16, seed=5)
    return {m: integer_search(reference, deformed, pts, method=m, radius=16, seed=1)
            for m in ("exhaustive", "coarse-fine", "wso", "improved-wso")}


def test_evaluation_counts(evaluation_run):
    ex = evaluation_run["exhaustive"]
    assert np.all(ex.evaluations == 33 * 33) and np.all(ex.calls == 33 * 33)
    cf = evaluation_run["coarse-fine"]
    assert np.all(cf.evaluations == 11 * 11 + 5 * 5 - 1)   # the coarse best is revisited once
    assert np.all(cf.calls == cf.evaluations + 1)
    iw = evaluation_run["improved-wso"]
    assert iw.evaluations.mean() < 0.5 * ex.evaluations.mean()


@pytest.fixture(scope="module")
def radius10_run(pattern, reference):
    """Shifts 1..10 px (along x and in a random direction of that length), radius 10, subset 21."""
    rng = np.random.default_rng(10)
    runs = []
    for d in range(1, 11):
        th = rng.uniform(0.0, 2.0 * np.pi)
        for shift in ((d, 0), (int(np.floor(d * np.cos(th) + 0.5)), int(np.floor(d * np.sin(th) + 0.5)))):
            deformed = render(pattern, shift)
            pts = _points(100, 10, 10, seed=100 + len(runs))
            runs.append({m: integer_search(reference, deformed, pts, method=m, subset=21, radius=10, seed=len(runs))
                         for m in ("exhaustive", "coarse-fine", "wso", "improved-wso")})
    return runs


def test_improved_wso_finds_every_shift_of_1_to_10_px_at_radius_10(radius10_run):
    # 2000 searches; measured 0 failures in 40000 (4 patterns, 500 points x 20 shifts each)
    for run in radius10_run:
        truth, found = run["exhaustive"], run["improved-wso"]
        np.testing.assert_array_equal(found.u, truth.u)
        np.testing.assert_array_equal(found.v, truth.v)


def test_improved_wso_evaluates_less_than_the_original_wso(radius10_run, evaluation_run):
    iw = np.mean([run["improved-wso"].evaluations.mean() for run in radius10_run])
    ws = np.mean([run["wso"].evaluations.mean() for run in radius10_run])
    assert iw < ws   # measured 157 against 163 (radius 10); 214 against 264 at radius 16
    assert evaluation_run["improved-wso"].evaluations.mean() < evaluation_run["wso"].evaluations.mean()


def test_paper_claim_improved_wso_evaluates_less_than_coarse_fine(radius10_run, evaluation_run):
    # The paper's claim, reproduced with the coarse-to-fine pyramid (dic.search.pyramid): measured
    # ~68 distinct evaluations at radius 10 and ~58 at radius 16, against 72 and 145 for coarse-fine
    # step 3. Without the pyramid (PAPER_LITERAL) the swarm needed 157-214 and still missed.
    iw = np.mean([run["improved-wso"].evaluations.mean() for run in radius10_run])
    cf = np.mean([run["coarse-fine"].evaluations.mean() for run in radius10_run])
    assert iw < cf
    assert evaluation_run["improved-wso"].evaluations.mean() < evaluation_run["coarse-fine"].evaluations.mean()


@pytest.mark.parametrize("generator", ["simulator R=4", "fft-filtered noise", "sparse dots", "hard discs R=2"])
def test_improved_wso_equals_exhaustive_at_large_radius(generator):
    """Radius 32, shift ~0.9 x radius, noise sigma 2, on four pattern generators (border points included)."""
    from livedic.bench import patterns

    size, radius, shift = 288, 32, (21.6, -19.3)
    ref, dfm = patterns.pair(generator, (size, size), shift, noise_sigma=2.0, seed=3)
    rng = np.random.default_rng(7)
    lo, hi = 10 + radius + 4, size - 10 - radius - 4
    pts = rng.uniform(lo, hi, size=(120, 2)).round()
    truth = integer_search(ref, dfm, pts, method="exhaustive", radius=radius)
    found = integer_search(ref, dfm, pts, method="improved-wso", radius=radius, seed=5)
    # points where even the exhaustive search misses the shift (a dot-free subset) test no search
    real = (truth.status == Status.OK) & (np.abs(truth.u - shift[0]) <= 1) & (np.abs(truth.v - shift[1]) <= 1)
    assert real.mean() > 0.95
    np.testing.assert_array_equal(found.u[real], truth.u[real])
    np.testing.assert_array_equal(found.v[real], truth.v[real])
    assert found.evaluations[real].mean() < 0.1 * truth.evaluations[real].mean()


def test_fft_cc_is_the_exhaustive_search_by_fft(pattern, reference):
    """Same integer, same ZNCC (to rounding), same statuses, clipped boxes and flat subsets included."""
    deformed = render(pattern, (9.4, -6.2))
    deformed[180:215, 150:190] = 77.0                       # a flat target patch
    ref = reference.copy()
    ref[20:50, 200:240] = 12.0                              # a flat reference patch
    pts = np.array([(30, 30), (128, 128), (220, 35), (160, 200), (15, 240), (128, 20), (60, 200), (245, 128)],
                   dtype=np.float64)
    a = integer_search(ref, deformed, pts, method="exhaustive", radius=14)
    b = integer_search(ref, deformed, pts, method="fft-cc", radius=14)
    np.testing.assert_array_equal(a.status, b.status)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_allclose(a.zncc, b.zncc, atol=1e-9, equal_nan=True)
    np.testing.assert_array_equal(a.evaluations, b.evaluations)
    assert Status.FLAT_REFERENCE in a.status and (a.u[1], a.v[1]) == (9, -6)


def test_paper_literal_options_and_polish_variants_run(pattern, reference):
    from livedic.dic.search.improved_wso import PAPER_LITERAL
    deformed = render(pattern, (6, -4))
    pts = _points(40, 10, 10, seed=9)
    truth = integer_search(reference, deformed, pts, method="exhaustive", radius=10)
    for opts in (PAPER_LITERAL, {"polish_method": "three-step"}, {"sd_of": "pbest", "stall": 0},
                 {"v_max": 0.25, "polish_from": "pbest"}, {"polish": False}):
        r = integer_search(reference, deformed, pts, method="improved-wso", radius=10, seed=3, **opts)
        assert np.all(r.status == Status.OK) and np.all(r.calls >= r.evaluations)
        assert _success(r, truth) >= 0.9
    lit = integer_search(reference, deformed, pts, method="improved-wso", radius=10, seed=3, **PAPER_LITERAL)
    new = integer_search(reference, deformed, pts, method="improved-wso", radius=10, seed=3)
    assert new.calls.mean() < 0.6 * lit.calls.mean()   # the stall rule ends most runs early


@pytest.mark.parametrize("method", ["pso", "wso", "improved-wso"])
def test_seeded_results_are_reproducible_and_thread_independent(pattern, reference, method):
    deformed = render(pattern, (3, 3))
    pts = _points(50, 10, 16, seed=6)
    a = integer_search(reference, deformed, pts, method=method, radius=16, seed=11)
    b = integer_search(reference, deformed, pts, method=method, radius=16, seed=11)
    c = integer_search(reference, deformed, pts, method=method, radius=16, seed=12)
    for name in ("u", "v", "zncc", "evaluations", "calls"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.calls, c.calls) or not np.array_equal(a.evaluations, c.evaluations)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = integer_search(reference, deformed, pts, method=method, radius=16, seed=11)
    finally:
        numba.set_num_threads(threads)
    for name in ("u", "v", "zncc", "evaluations", "calls"):
        np.testing.assert_array_equal(getattr(a, name), getattr(one, name))


@pytest.mark.parametrize("method", SEARCH_METHODS)
def test_guess_offsets_the_search_box(pattern, reference, method):
    deformed = render(pattern, (23, -17))
    pts = _points(20, 10, 30, seed=7)
    r = integer_search(reference, deformed, pts, method=method, radius=3, guess=(22, -16), seed=2)
    assert np.all(r.status == Status.OK)
    assert np.all(np.abs(r.u - 22) <= 3) and np.all(np.abs(r.v + 16) <= 3)
    if method in ("exhaustive", "improved-wso", "coarse-fine"):
        assert np.all((r.u == 23) & (r.v == -17))


@pytest.mark.parametrize("method", SEARCH_METHODS)
def test_bad_guess_and_border_points_get_a_status_never_a_crash(pattern, reference, method):
    deformed = render(pattern, (2, 1))
    pts = np.array([(128, 128), (128, 128), (3, 128), (250, 250), (10, 128), (128, 10), (1e6, 5.0)])
    guess = np.array([(0, 0), (np.nan, 0), (0, 0), (0, 0), (-5, 0), (0, -9), (0, 0)], dtype=float)
    r = integer_search(reference, deformed, pts, method=method, subset=21, radius=2, guess=guess)
    expected = [Status.OK, Status.BAD_GUESS, Status.OUTSIDE_REFERENCE, Status.OUTSIDE_REFERENCE,
                Status.OUTSIDE_TARGET, Status.OUTSIDE_TARGET, Status.OUTSIDE_REFERENCE]
    assert list(r.status) == [int(s) for s in expected]
    assert r.u[0] == 2 and r.v[0] == 1
    assert np.all(np.isnan(r.zncc[1:])) and np.all(r.u[1:] == 0) and np.all(r.evaluations[1:] == 0)


def test_margin_keeps_the_target_subset_away_from_the_edge(pattern, reference):
    deformed = render(pattern, (-4, 0))
    half, margin = 10, 3
    xs = np.array([half + 2], dtype=np.int64)
    ys = np.array([128], dtype=np.int64)
    r = search_points(reference, deformed, xs, ys, np.zeros(1), np.zeros(1), half, 8, "exhaustive", margin=margin)
    assert r.status[0] == Status.OK
    # the true shift (-4) would put the subset 2 px from the edge: the box stops at u = margin - 2
    assert xs[0] + r.u[0] - half - margin >= 0
    assert r.evaluations[0] == (8 - 1 + 1) * (2 * 8 + 1)


def test_flat_images_are_flagged():
    flat = np.full((64, 64), 100, dtype=np.uint8)
    texture = render(SpecklePattern((64, 64), n_speckles=60, seed=1))
    for method in SEARCH_METHODS:
        r = integer_search(flat, texture, [(32, 32)], method=method, subset=15, radius=3)
        assert r.status[0] == Status.FLAT_REFERENCE
        r = integer_search(texture, flat, [(32, 32)], method=method, subset=15, radius=3)
        assert r.status[0] == Status.FLAT_TARGET and np.isnan(r.zncc[0])


def test_unknown_method_or_option_is_rejected(reference):
    with pytest.raises(ValueError, match="improved-wso"):
        integer_search(reference, reference, [(128, 128)], method="simplex")
    with pytest.raises(ValueError, match="population"):
        integer_search(reference, reference, [(128, 128)], method="improved-wso", populaton=10)
    with pytest.raises(ValueError, match="step"):
        integer_search(reference, reference, [(128, 128)], method="coarse-fine", population=10)
    with pytest.raises(ValueError, match="variant"):
        integer_search(reference, reference, [(128, 128)], method="wso", variant="matlab")
    with pytest.raises(ValueError, match="population"):
        integer_search(reference, reference, [(128, 128)], method="pso", population=0)
    with pytest.raises(ValueError, match="radius"):
        integer_search(reference, reference, [(128, 128)], radius=-1)
    assert method_options("improved-wso")["population"] == 20


def test_identity_gives_zero_displacement(reference):
    r = integer_search(reference, reference, _points(30, 10, 16), radius=16)
    hit = (r.u == 0) & (r.v == 0)
    # radius 16 is not 100 % for the stochastic default (measured 99.945 %, side-lobe traps): one of
    # these 30 points is trapped at u = 7 (the stall rule ends its run early; stall=10 would find it)
    assert hit.sum() >= 29 and np.all(r.zncc[hit] > 1 - 1e-9)
    ex = integer_search(reference, reference, _points(30, 10, 16), radius=16, method="exhaustive")
    assert np.all(ex.u == 0) and np.all(ex.v == 0)
