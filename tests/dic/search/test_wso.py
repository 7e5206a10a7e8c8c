"""dic.search.wso: the original White Shark Optimizer, ``variant="code"`` (reference code) or ``"paper"``."""

import numpy as np

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from tests.dic.search.conftest import (SUBSET, check_beyond_radius_is_not_ok, check_each_point_has_its_own_stream,
                                       check_finds_most_exact_shifts, interior_points)


def test_finds_exact_shifts_at_a_small_radius(pattern, reference):
    check_finds_most_exact_shifts(pattern, reference, "wso", ((-4, 4), (2, 0)))


def test_no_iterations_evaluate_only_the_initial_population(pattern, reference):
    r = integer_search(reference, render(pattern, (2, 1)), interior_points(8, 8), method="wso", subset=SUBSET,
                       radius=8, seed=3, population=5, iterations=0)
    assert np.all(r.calls <= 5) and np.all(r.evaluations <= r.calls)


def test_the_two_variants_are_different_searches_in_the_same_box(pattern, reference):
    deformed = render(pattern, (3, -3))
    points = interior_points(12, 8, seed=4)
    code = integer_search(reference, deformed, points, method="wso", radius=8, seed=5, variant="code")
    paper = integer_search(reference, deformed, points, method="wso", radius=8, seed=5, variant="paper")
    assert not np.array_equal(code.calls, paper.calls)
    for r in (code, paper):
        assert np.all(np.abs(r.u) <= 8) and np.all(np.abs(r.v) <= 8)


def test_each_point_has_its_own_random_stream(pattern, reference):
    check_each_point_has_its_own_stream(pattern, reference, "wso")


def test_a_shift_beyond_the_radius_is_not_reported_as_a_match(pattern, reference):
    check_beyond_radius_is_not_ok(pattern, reference, "wso")
