"""Tests of dic/_random.py: per-point SplitMix64 streams, reproducible, distinct and uniform on [0, 1)."""

import numpy as np
from numba import njit

from livedic.dic._random import new_state, uniform


@njit(cache=False)
def _draws(seed, stream, n):
    state = new_state(seed, stream)
    out = np.empty(n)
    for i in range(n):
        out[i] = uniform(state)
    return out


def test_a_stream_is_reproducible_and_streams_and_seeds_differ():
    a = _draws(np.uint64(7), np.uint64(3), 1000)
    np.testing.assert_array_equal(a, _draws(np.uint64(7), np.uint64(3), 1000))
    for other in (_draws(np.uint64(7), np.uint64(4), 1000), _draws(np.uint64(8), np.uint64(3), 1000)):
        assert not np.any(a == other)                       # 53-bit values: a coincidence is ~1e-13
        assert abs(np.corrcoef(a, other)[0, 1]) < 0.1


def test_draws_are_uniform_on_the_half_open_unit_interval():
    x = _draws(np.uint64(12345), np.uint64(0), 200_000)
    assert x.min() >= 0.0 and x.max() < 1.0
    counts, _ = np.histogram(x, bins=20, range=(0.0, 1.0))
    expected = x.size / 20
    chi2 = float(np.sum((counts - expected) ** 2 / expected))
    assert chi2 < 50.0                                       # 19 degrees of freedom: p ~ 1e-4
    assert abs(x.mean() - 0.5) < 0.005 and abs(x.var() - 1 / 12) < 0.002


def test_the_state_advances_in_place():
    state = new_state(np.uint64(1), np.uint64(2))
    assert state.dtype == np.uint64 and state.shape == (1,)
    before = int(state[0])
    first = uniform(state)
    assert int(state[0]) != before and uniform(state) != first
