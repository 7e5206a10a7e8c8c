"""Tests of dic/result.py: the records passed between stages, and the measurement's ZNCC kept within [-1, 1]."""

import numpy as np

from livedic.dic.result import IntegerSearchResult, Measurement, SubpixelResult


def _measurement(zncc):
    n = len(zncc)
    return Measurement(x=np.zeros(n), y=np.zeros(n), u=np.zeros(n), v=np.zeros(n), zncc=np.asarray(zncc),
                       ok=np.ones(n, dtype=bool), status=np.zeros(n, dtype=np.int8))


def test_zncc_a_hair_above_one_is_clipped_and_nan_stays_nan():
    m = _measurement([1.0000002, -1.0000001, 0.5, np.nan])
    assert m.zncc[:3].tolist() == [1.0, -1.0, 0.5] and np.isnan(m.zncc[3])
    assert m.zncc.dtype == np.float64 and m.ok.all()


def test_zncc_within_range_is_kept_as_it_is():
    values = np.array([0.9, -0.2], dtype=np.float32)
    m = _measurement(values)
    assert m.zncc.dtype == np.float64 and m.zncc.tolist() == values.astype(np.float64).tolist()


def test_optional_fields_default_to_none():
    m = _measurement([0.9])
    assert all(getattr(m, name) is None for name in ("ux", "uy", "vx", "vy", "iterations", "evaluations"))
    s = SubpixelResult(u=np.zeros(1), v=np.zeros(1), zncc=np.ones(1), status=np.zeros(1, dtype=np.int8))
    assert all(getattr(s, name) is None for name in ("ux", "uy", "vx", "vy", "iterations", "evaluations"))
    r = IntegerSearchResult(*(np.zeros(2, dtype=np.int64) for _ in range(8)))
    assert r.calls.shape == (2,)
