"""Tests of dic/tracking/results.py: each point's last good values, rows taken from a result, bit-for-bit
comparison and the median test's inputs."""

import numpy as np

from livedic.dic.result import Measurement
from livedic.dic.subpixel.icgn2 import SECOND_ORDER
from livedic.dic.tracking import last_good_after
from livedic.dic.tracking.results import _Curved, _gradients_of, _median_test_inputs, _same_bits, _take


def _first_order(n=4):
    rng = np.random.default_rng(0)
    return Measurement(x=np.arange(n, dtype=float), y=np.zeros(n), u=rng.normal(size=n), v=rng.normal(size=n),
                       zncc=np.full(n, 0.9), ok=np.array([True, False, True, True][:n]),
                       status=np.zeros(n, dtype=np.int8), ux=rng.normal(size=n), uy=rng.normal(size=n),
                       vx=rng.normal(size=n), vy=rng.normal(size=n), iterations=np.arange(n))


def test_last_good_keeps_a_lost_points_last_ok_result():
    def result(u, ok):
        u = np.asarray(u, dtype=np.float64)
        return Measurement(x=np.zeros(2), y=np.zeros(2), u=u, v=-u, zncc=np.ones(2), ok=np.asarray(ok),
                           status=np.zeros(2, dtype=np.int8))
    good = last_good_after(None, result([1.0, 2.0], [True, False]))
    good = last_good_after(good, result([np.nan, 3.0], [False, True]))
    assert good["u"].tolist() == [1.0, 3.0] and good["v"].tolist() == [-1.0, -3.0]
    assert good["ever"].tolist() == [True, True] and good["ux"].tolist() == [0.0, 0.0]


def test_last_good_takes_the_gradients_of_ok_points_too():
    m = _first_order()
    good = last_good_after(None, m)
    assert good["ux"].tolist() == np.where(m.ok, m.ux, 0.0).tolist()
    assert good["ever"].tolist() == m.ok.tolist()
    again = last_good_after(good, Measurement(x=m.x, y=m.y, u=m.u + 1, v=m.v, zncc=m.zncc, ok=~m.ok,
                                              status=m.status))
    assert again["u"].tolist() == (m.u + np.where(m.ok, 0.0, 1.0)).tolist()
    assert again["ux"].tolist() == good["ux"].tolist()         # a result without gradients keeps the last ones
    assert again["ever"].all()


def test_take_keeps_the_rows_of_every_field_and_the_record_kind():
    m = _first_order()
    rows = _take(m, m.ok)
    assert type(rows) is Measurement and rows.u.tolist() == m.u[m.ok].tolist()
    assert rows.iterations.tolist() == [0, 2, 3] and rows.evaluations is None
    terms = {name: np.arange(4.0) + k for k, name in enumerate(SECOND_ORDER)}
    curved = _Curved(**{name: getattr(m, name) for name in ("x", "y", "u", "v", "zncc", "ok", "status", "ux", "uy",
                                                            "vx", "vy", "iterations", "evaluations")}, **terms)
    picked = _take(curved, np.array([3, 0]))
    assert type(picked) is _Curved and getattr(picked, SECOND_ORDER[0]).tolist() == [3.0, 0.0]
    plain = _take(curved, slice(None), Measurement)             # back to a plain record, second order dropped
    assert type(plain) is Measurement and plain.vy.tolist() == m.vy.tolist()


def test_same_bits_tells_nan_equal_and_signed_zeros_apart():
    assert _same_bits(np.array([1.0, np.nan]), np.array([1.0, np.nan]))
    assert not _same_bits(np.array([0.0]), np.array([-0.0]))
    assert not _same_bits(np.array([1.0]), np.array([1.0], dtype=np.float32))
    assert not _same_bits(np.array([1.0, 2.0]), np.array([[1.0, 2.0]]))


def test_median_test_inputs_are_ok_u_v_and_the_gradients_copied_when_asked():
    m = _first_order()
    inputs = _median_test_inputs(m)
    assert len(inputs) == 7 and inputs[0] is m.ok and inputs[3] is m.ux
    copied = _median_test_inputs(m, copy=True)
    m.u[0] = 99.0
    assert copied[1][0] != 99.0
    bare = Measurement(x=m.x, y=m.y, u=m.u, v=m.v, zncc=m.zncc, ok=m.ok, status=m.status)
    assert len(_median_test_inputs(bare)) == 3 and _gradients_of(bare) is None
    assert _gradients_of(m) == (m.ux, m.uy, m.vx, m.vy)
