"""A small exact speckle pair for the per-search tests, and the check every search must pass beyond its radius."""

import numpy as np
import pytest

from livedic.dic.quality import Gates
from livedic.dic.search import integer_search
from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.status import Status

SIZE = 128
SUBSET = 21


@pytest.fixture(scope="package")
def pattern():
    return SpecklePattern((SIZE, SIZE), n_speckles=250, radius=3.0, seed=5)


@pytest.fixture(scope="package")
def reference(pattern):
    return render(pattern)


def interior_points(n, reach, seed=0):
    """``n`` random pixel positions whose subset stays inside the image for any shift up to ``reach`` px."""
    rng = np.random.default_rng(seed)
    lo, hi = SUBSET // 2 + reach + 1, SIZE - SUBSET // 2 - reach - 1
    return rng.integers(lo, hi, size=(n, 2)).astype(np.float64)


def check_beyond_radius_is_not_ok(pattern, reference, method, **options):
    """A shift of (9, -7) px searched with radius 4: the answer stays in the box, never claims the truth,
    and correlates too poorly to pass the measurement's correlation gate (so it is not reported ok)."""
    deformed = render(pattern, (9, -7))
    points = interior_points(12, 12, seed=3)
    r = integer_search(reference, deformed, points, method=method, subset=SUBSET, radius=4, seed=1, **options)
    assert np.all(r.status == Status.OK)                     # the search itself ran on every point ...
    assert np.all(np.abs(r.u) <= 4) and np.all(np.abs(r.v) <= 4)
    assert not np.any((r.u == 9) & (r.v == -7))
    assert np.all(r.zncc < Gates().min_zncc)                 # ... and its best match is rejected as a match
    return r


def check_each_point_has_its_own_stream(pattern, reference, method, **options):
    """A stochastic search seeds each point from (seed, its index): the first k points of a batch get the same
    answer, evaluations and calls when searched alone, and another seed changes the runs."""
    deformed = render(pattern, (3, -2))
    points = interior_points(16, 8, seed=5)
    full = integer_search(reference, deformed, points, method=method, subset=SUBSET, radius=8, seed=7, **options)
    head = integer_search(reference, deformed, points[:6], method=method, subset=SUBSET, radius=8, seed=7, **options)
    for name in ("u", "v", "zncc", "evaluations", "calls"):
        np.testing.assert_array_equal(getattr(full, name)[:6], getattr(head, name))
    other = integer_search(reference, deformed, points, method=method, subset=SUBSET, radius=8, seed=8, **options)
    assert not (np.array_equal(full.calls, other.calls) and np.array_equal(full.evaluations, other.evaluations))


def check_finds_most_exact_shifts(pattern, reference, method, shifts, radius=4):
    """At least 90 % of 20 points find each exact integer ``shift`` (a swarm may stall on a side lobe)."""
    points = interior_points(20, radius, seed=1)
    for shift in shifts:
        r = integer_search(reference, render(pattern, shift), points, method=method, subset=SUBSET, radius=radius,
                           seed=2)
        assert np.mean((r.u == shift[0]) & (r.v == shift[1])) >= 0.9, shift
