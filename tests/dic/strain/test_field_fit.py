"""Tests of dic/strain/field_fit.py: displacement anywhere from a local quadratic fit to the tracked points."""

import numpy as np
import pytest

from livedic.dic.strain.field_fit import (MIN_POINTS, REACH, _solve_in_place, displacement_at, fit_at, fit_weights,
                                          neighbourhoods)

STEP = 10.0


def grid(n=12, step=STEP):
    axis = np.arange(n) * step
    xs, ys = np.meshgrid(axis, axis)
    return np.column_stack([xs.ravel(), ys.ravel()])


def quadratic(xy):
    x, y = xy[:, 0], xy[:, 1]
    u = 0.3 + 0.01 * x - 0.02 * y + 1e-4 * x * x + 2e-4 * x * y - 3e-4 * y * y
    v = -1.0 + 0.005 * x + 0.03 * y - 2e-4 * x * x + 1e-4 * y * y
    return u, v


WHERE = np.array([(55.0, 55.0), (43.2, 61.7), (30.5, 80.1), (70.0, 20.0)])


def test_a_quadratic_field_is_reproduced_exactly_between_the_points():
    points = grid()
    u, v = quadratic(points)
    fu, fv = displacement_at(WHERE, points, u, v, np.ones(len(points), bool), STEP)
    tu, tv = quadratic(WHERE)
    np.testing.assert_allclose(fu, tu, atol=1e-9)
    np.testing.assert_allclose(fv, tv, atol=1e-9)


def test_points_not_ok_or_not_finite_are_left_out_of_the_fit():
    points = grid()
    u, v = quadratic(points)
    ok = np.ones(len(points), bool)
    near = np.hypot(*(points - WHERE[0]).T) < 15
    ok[np.flatnonzero(near)[:2]] = False
    u[ok == False] = 1e6                               # noqa: E712  a wrong value on the not-ok points
    v[np.flatnonzero(near)[2]] = np.nan                # and a NaN on an ok one
    fu, fv = displacement_at(WHERE[:1], points, u, v, ok, STEP)
    tu, tv = quadratic(WHERE[:1])
    np.testing.assert_allclose([fu[0], fv[0]], [tu[0], tv[0]], atol=1e-9)


def test_too_few_points_or_points_along_a_line_give_nan():
    points = grid()
    u, v = quadratic(points)
    far = np.array([(500.0, 500.0)])                   # no point in reach
    assert np.isnan(displacement_at(far, points, u, v, np.ones(len(points), bool), STEP)).all()
    line = np.column_stack([np.arange(30) * 2.0, np.full(30, 40.0)])   # 30 points, all on y = 40
    lu, lv = quadratic(line)
    assert np.isnan(displacement_at([(30.0, 40.0)], line, lu, lv, np.ones(30, bool), 2.0)).all()
    ok = np.zeros(len(points), bool)
    near = np.flatnonzero(np.hypot(*(points - WHERE[0]).T) <= REACH * STEP)
    ok[near[:MIN_POINTS - 1]] = True                   # one point short
    assert np.isnan(displacement_at(WHERE[:1], points, u, v, ok, STEP)).all()
    ok[near[:MIN_POINTS]] = True
    assert np.isfinite(displacement_at(WHERE[:1], points, u, v, ok, STEP)).all()


def test_neighbourhoods_are_the_points_within_reach_steps():
    points = np.random.default_rng(4).uniform(0, 100, size=(200, 2))
    start, index = neighbourhoods(WHERE, points, STEP, reach=2.0)
    for k, w in enumerate(WHERE):
        expected = np.flatnonzero(np.hypot(*(points - w).T) <= 20.0)
        assert index[start[k]:start[k + 1]].tolist() == expected.tolist()


def test_fit_at_on_given_neighbourhoods_equals_displacement_at():
    points = grid()
    u, v = quadratic(points)
    u = u + np.random.default_rng(1).normal(0, 0.01, u.shape)      # noise: the fit is least squares, not exact
    ok = np.ones(len(points), bool)
    start, index = neighbourhoods(WHERE, points, STEP)
    np.testing.assert_array_equal(fit_at(WHERE, start, index, points, u, v, ok, STEP),
                                  displacement_at(WHERE, points, u, v, ok, STEP))


def test_fit_weights_reproduce_the_fit_and_constants():
    points = grid()
    u, _ = quadratic(points)
    u = u + np.random.default_rng(2).normal(0, 0.01, u.shape)
    start, index = neighbourhoods(WHERE[1:2], points, STEP)
    near = index[start[0]:start[1]]
    weights = fit_weights(WHERE[1], near, points, STEP)
    fitted, _ = displacement_at(WHERE[1:2], points, u, u, np.ones(len(points), bool), STEP)
    assert weights @ u[near] == pytest.approx(fitted[0], abs=1e-9)
    assert weights.sum() == pytest.approx(1.0, abs=1e-12)              # a constant field is kept as it is
    assert np.isnan(fit_weights(WHERE[1], near[:MIN_POINTS - 1], points, STEP)).all()


def test_the_small_solver_solves_and_refuses_a_singular_system():
    a = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]])
    b = np.array([[1.0, 0.0], [2.0, 1.0], [3.0, -1.0]])
    x = b.copy()
    assert _solve_in_place(a.copy(), x)
    np.testing.assert_allclose(a @ x, b, atol=1e-12)
    singular = np.array([[1.0, 2.0], [2.0, 4.0]])
    assert not _solve_in_place(singular, np.ones((2, 1)))
