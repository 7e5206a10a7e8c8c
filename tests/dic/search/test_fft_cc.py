"""dic.search.fft_cc: the exhaustive ZNCC map computed by FFT (equality with exhaustive: test_search.py here)."""

import numpy as np

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from tests.dic.search.conftest import SUBSET, check_beyond_radius_is_not_ok, interior_points


def test_exact_shifts_at_the_box_corners(pattern, reference):
    points = interior_points(10, 6)
    for shift in ((6, 6), (-6, -6), (6, -6)):
        r = integer_search(reference, render(pattern, shift), points, method="fft-cc", subset=SUBSET, radius=6)
        assert np.all(r.u == shift[0]) and np.all(r.v == shift[1])
        np.testing.assert_allclose(r.zncc, 1.0, atol=1e-6)


def test_beyond_the_radius_it_gives_the_exhaustive_answer_and_no_match(pattern, reference):
    r = check_beyond_radius_is_not_ok(pattern, reference, "fft-cc")
    deformed = render(pattern, (9, -7))
    truth = integer_search(reference, deformed, _points(), method="exhaustive", subset=SUBSET, radius=4)
    np.testing.assert_array_equal(r.u, truth.u)
    np.testing.assert_array_equal(r.v, truth.v)
    np.testing.assert_allclose(r.zncc, truth.zncc, atol=1e-9)


def _points():
    return interior_points(12, 12, seed=3)          # the points check_beyond_radius_is_not_ok searches
