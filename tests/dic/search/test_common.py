"""Tests of dic/search/_common.py: search boxes and their statuses, the cached fitness, the hill climb, outputs."""

import cv2
import numpy as np
import pytest

from livedic.dic.correlation import prepare_reference_subset, zncc_at_integer
from livedic.dic.search._common import (begin_point, finish_point, fitness, hill_climb, new_cache, new_outputs,
                                        search_boxes)
from livedic.dic.speckle import render
from livedic.dic.status import Status

HALF = 10
SHIFT = (3, -2)


@pytest.fixture(scope="module")
def pair(pattern, reference):
    """Reference (float32) and the same pattern moved by the integer SHIFT, exactly."""
    return reference.astype(np.float32), render(pattern, SHIFT).astype(np.float32)


def test_a_box_is_the_radius_around_the_rounded_guess_clipped_to_the_image():
    shape = (100, 120)
    xs, ys = np.array([60, 15, 60]), np.array([50, 50, 85])
    ulo, uhi, vlo, vhi, cu, cv, status = search_boxes(shape, xs, ys, np.array([1.5, 0.0, -0.5]),
                                                      np.array([-2.4, 0.0, 0.0]), HALF, 5, 3)
    assert cu.tolist() == [2, 0, 0] and cv.tolist() == [-2, 0, 0]           # halves round up
    assert (ulo[0], uhi[0], vlo[0], vhi[0]) == (-3, 7, -7, 3)
    assert ulo[1] == HALF + 3 - 15                                          # the target subset keeps the margin
    assert vhi[2] == 100 - 1 - (HALF + 3) - 85
    assert status.tolist() == [Status.OK] * 3


def test_unsearchable_points_get_their_status_by_precedence_and_a_one_pixel_box():
    shape = (100, 120)
    xs = np.array([5, 5, 60, 60, 60])
    ys = np.array([50, 50, 50, 50, 50])
    gu = np.array([0.0, np.nan, np.nan, 1e300, 0.0])
    gv = np.array([0.0, 0.0, 0.0, 0.0, -np.inf])
    ulo, uhi, vlo, vhi, cu, cv, status = search_boxes(shape, xs, ys, gu, gv, HALF, 4, 0)
    assert status.tolist() == [Status.OUTSIDE_REFERENCE, Status.OUTSIDE_REFERENCE, Status.BAD_GUESS,
                               Status.OUTSIDE_TARGET, Status.BAD_GUESS]
    assert np.all(ulo == 0) and np.all(uhi == 0) and np.all(vlo == 0) and np.all(vhi == 0)
    assert cu[2] == 0 and cv[4] == 0                                         # no finite guess: 0


def test_fitness_is_the_zncc_and_is_computed_once_per_position(pair):
    reference, target = pair
    fhat = np.empty((2 * HALF + 1) ** 2)
    assert prepare_reference_subset(reference, 64, 64, HALF, fhat) > 0
    cache = new_cache(-5, 5, -5, 5)
    assert cache.shape == (11, 11) and np.isnan(cache).all()
    counts = np.zeros(2, dtype=np.int64)
    first = fitness(fhat, target, 64, 64, HALF, 3, -2, -5, -5, cache, counts)
    again = fitness(fhat, target, 64, 64, HALF, 3, -2, -5, -5, cache, counts)
    assert first == again == zncc_at_integer(fhat, target, 64, 64, HALF, 3, -2)
    assert first == pytest.approx(1.0, abs=1e-9)
    assert counts.tolist() == [1, 2] and cache[-2 + 5, 3 + 5] == first


def test_the_hill_climb_ends_on_the_true_shift_from_near_it(pair):
    reference, target = pair
    fhat = np.empty((2 * HALF + 1) ** 2)
    prepare_reference_subset(reference, 60, 70, HALF, fhat)
    counts = np.zeros(2, dtype=np.int64)
    cache = new_cache(-6, 6, -6, 6)
    u, v, c = hill_climb(fhat, target, 60, 70, HALF, 2, -1, -6, 6, -6, 6, cache, counts)
    assert (u, v) == SHIFT and c == pytest.approx(1.0, abs=1e-9)
    assert counts[0] == np.count_nonzero(~np.isnan(cache)) and counts[1] >= counts[0]


def test_the_hill_climb_stays_in_its_box():
    # a box that excludes the true shift: the climb stops on the box's best edge, never outside
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.uniform(0, 255, (80, 80)).astype(np.float32), (0, 0), 3.0)
    target = np.roll(image, (0, 4), axis=(0, 1))                          # content moves +4 in x
    fhat = np.empty((2 * HALF + 1) ** 2)
    prepare_reference_subset(image, 40, 40, HALF, fhat)
    u, v, _ = hill_climb(fhat, target, 40, 40, HALF, 0, 0, -2, 2, -2, 2, new_cache(-2, 2, -2, 2),
                         np.zeros(2, dtype=np.int64))
    assert -2 <= u <= 2 and -2 <= v <= 2 and u == 2


def test_begin_point_flags_a_flat_reference_and_skips_points_not_ok():
    flat = np.full((40, 40), 7.0, dtype=np.float32)
    fhat = np.empty((2 * HALF + 1) ** 2)
    status = np.array([Status.OK, Status.OUTSIDE_REFERENCE, Status.BAD_GUESS], dtype=np.int8)
    assert not begin_point(flat, 20, 20, HALF, fhat, status, 0) and status[0] == Status.FLAT_REFERENCE
    assert not begin_point(flat, 20, 20, HALF, fhat, status, 1) and status[1] == Status.OUTSIDE_REFERENCE
    assert not begin_point(flat, 20, 20, HALF, fhat, status, 2) and status[2] == Status.FLAT_REFERENCE
    textured = np.add.outer(np.arange(40.0), np.arange(40.0) ** 2).astype(np.float32)
    status[2] = Status.BAD_GUESS
    assert not begin_point(textured, 20, 20, HALF, fhat, status, 2) and status[2] == Status.BAD_GUESS
    status[0] = Status.OK
    assert begin_point(textured, 20, 20, HALF, fhat, status, 0)


def test_finish_point_writes_a_match_and_flags_a_flat_target():
    u, v, c, evals, calls = new_outputs(2)
    assert u.dtype == v.dtype == evals.dtype == calls.dtype == np.int64 and np.isnan(c).all()
    status = np.zeros(2, dtype=np.int8)
    finish_point(0, 3, -1, 0.97, np.array([5, 9]), status, u, v, c, evals, calls)
    finish_point(1, 2, 2, -1.0, np.array([4, 4]), status, u, v, c, evals, calls)
    assert (u[0], v[0], c[0], evals[0], calls[0]) == (3, -1, 0.97, 5, 9) and status[0] == Status.OK
    assert status[1] == Status.FLAT_TARGET and np.isnan(c[1]) and evals[1] == 4
