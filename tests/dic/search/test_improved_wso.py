"""dic.search.improved_wso: the paper's improved WSO, polished by a hill climb, on an image pyramid by default."""

import numpy as np
import pytest

from livedic.dic.search import integer_search
from livedic.dic.speckle import render
from livedic.dic.status import Status
from tests.dic.search.conftest import (SUBSET, check_beyond_radius_is_not_ok, check_each_point_has_its_own_stream,
                                       interior_points)


@pytest.mark.parametrize("pyramid", [True, False])
def test_finds_every_exact_shift_at_the_box_corners(pattern, reference, pyramid):
    points = interior_points(20, 6, seed=1)
    for shift in ((6, -6), (-6, 6), (0, 0)):
        r = integer_search(reference, render(pattern, shift), points, method="improved-wso", subset=SUBSET,
                           radius=6, seed=2, pyramid=pyramid)
        assert np.all(r.status == Status.OK)
        assert np.all(r.u == shift[0]) and np.all(r.v == shift[1])


def test_each_point_has_its_own_random_stream(pattern, reference):
    check_each_point_has_its_own_stream(pattern, reference, "improved-wso")


@pytest.mark.parametrize("pyramid", [True, False])
def test_a_shift_beyond_the_radius_is_not_reported_as_a_match(pattern, reference, pyramid):
    check_beyond_radius_is_not_ok(pattern, reference, "improved-wso", pyramid=pyramid)
