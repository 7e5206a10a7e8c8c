"""dic.search.pso: inertia-weight particle swarm over the integer box."""

import numpy as np

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from tests.dic.search.conftest import (SUBSET, check_beyond_radius_is_not_ok, check_each_point_has_its_own_stream,
                                       check_finds_most_exact_shifts, interior_points)


def test_finds_exact_shifts_at_a_small_radius(pattern, reference):
    check_finds_most_exact_shifts(pattern, reference, "pso", ((4, -4), (-1, 3)))


def test_no_iterations_evaluate_only_the_initial_swarm(pattern, reference):
    r = integer_search(reference, render(pattern, (2, 1)), interior_points(8, 8), method="pso", subset=SUBSET,
                       radius=8, seed=3, population=6, iterations=0)
    assert np.all(r.calls <= 6) and np.all(r.evaluations <= r.calls)
    full = integer_search(reference, render(pattern, (2, 1)), interior_points(8, 8), method="pso", subset=SUBSET,
                          radius=8, seed=3, population=6, iterations=30)
    assert full.calls.sum() > r.calls.sum()


def test_each_point_has_its_own_random_stream(pattern, reference):
    check_each_point_has_its_own_stream(pattern, reference, "pso")


def test_a_shift_beyond_the_radius_is_not_reported_as_a_match(pattern, reference):
    check_beyond_radius_is_not_ok(pattern, reference, "pso")
