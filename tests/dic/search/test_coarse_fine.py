"""dic.search.coarse_fine: a lattice of step ``step``, then the full fine window around its best node."""

import numpy as np

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from tests.dic.search.conftest import SUBSET, check_beyond_radius_is_not_ok, interior_points

RADIUS = 8


def test_step_1_is_the_exhaustive_search(pattern, reference):
    deformed = render(pattern, (5, -2))
    points = interior_points(15, RADIUS, seed=1)
    a = integer_search(reference, deformed, points, method="coarse-fine", subset=SUBSET, radius=RADIUS, step=1)
    b = integer_search(reference, deformed, points, method="exhaustive", subset=SUBSET, radius=RADIUS)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.evaluations, b.evaluations)


def test_finds_a_shift_off_the_lattice_with_fewer_evaluations(pattern, reference):
    # (4, -5) is on no node of the step-3 lattice centred on 0: the fine window must close the gap
    deformed = render(pattern, (4, -5))
    points = interior_points(15, RADIUS, seed=2)
    r = integer_search(reference, deformed, points, method="coarse-fine", subset=SUBSET, radius=RADIUS, step=3)
    assert np.mean((r.u == 4) & (r.v == -5)) >= 0.9
    assert np.all(r.evaluations < (2 * RADIUS + 1) ** 2)


def test_a_coarser_lattice_evaluates_fewer_positions(pattern, reference):
    deformed = render(pattern, (2, 2))
    points = interior_points(10, RADIUS, seed=4)
    fine = integer_search(reference, deformed, points, method="coarse-fine", radius=RADIUS, step=2)
    coarse = integer_search(reference, deformed, points, method="coarse-fine", radius=RADIUS, step=4)
    assert coarse.evaluations.mean() < fine.evaluations.mean()


def test_a_shift_beyond_the_radius_is_not_reported_as_a_match(pattern, reference):
    check_beyond_radius_is_not_ok(pattern, reference, "coarse-fine")
