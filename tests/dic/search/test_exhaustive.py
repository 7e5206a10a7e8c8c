"""dic.search.exhaustive: every position of the box, the reference the other searches are scored against."""

import numpy as np
import pytest

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from livedic.dic.status import Status
from tests.dic.search.conftest import SUBSET, check_beyond_radius_is_not_ok, interior_points

RADIUS = 5


@pytest.mark.parametrize("shift", [(0, 0), (RADIUS, -RADIUS), (-RADIUS, RADIUS), (RADIUS, RADIUS), (2, -3)])
def test_finds_the_exact_shift_anywhere_in_the_box_edges_included(pattern, reference, shift):
    deformed = render(pattern, shift)
    r = integer_search(reference, deformed, interior_points(15, RADIUS), method="exhaustive", subset=SUBSET,
                       radius=RADIUS)
    assert np.all(r.status == Status.OK)
    assert np.all(r.u == shift[0]) and np.all(r.v == shift[1])
    np.testing.assert_allclose(r.zncc, 1.0, atol=1e-6)


def test_evaluates_every_position_of_the_box_once(pattern, reference):
    r = integer_search(reference, render(pattern, (1, 2)), interior_points(6, RADIUS), method="exhaustive",
                       subset=SUBSET, radius=RADIUS)
    assert np.all(r.evaluations == (2 * RADIUS + 1) ** 2)
    assert np.all(r.calls == r.evaluations)


def test_the_result_does_not_depend_on_the_seed(pattern, reference):
    deformed = render(pattern, (3, -1))
    points = interior_points(10, RADIUS)
    a = integer_search(reference, deformed, points, method="exhaustive", radius=RADIUS, seed=1)
    b = integer_search(reference, deformed, points, method="exhaustive", radius=RADIUS, seed=99)
    for name in ("u", "v", "zncc", "evaluations"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_shift_beyond_the_radius_is_not_reported_as_a_match(pattern, reference):
    check_beyond_radius_is_not_ok(pattern, reference, "exhaustive")
