"""Tests of dic/subpixel/linalg.py: the lower Cholesky factor of a leading block, and singular blocks refused."""

import numpy as np

from livedic.dic.subpixel.linalg import cholesky_lower


def test_the_factor_of_a_positive_definite_block_reproduces_it():
    rng = np.random.default_rng(0)
    m = rng.normal(size=(6, 6))
    a = m @ m.T + 6 * np.eye(6)
    for k in (6, 4, 1):
        low = np.full((6, 6), np.nan)
        assert cholesky_lower(a, k, low)
        block = low[:k, :k]
        np.testing.assert_allclose(block @ block.T, a[:k, :k], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(block, np.linalg.cholesky(a[:k, :k]), rtol=1e-12, atol=1e-12)
        assert np.all(np.triu(block, 1) == 0)


def test_singular_or_indefinite_blocks_are_refused():
    v = np.arange(1.0, 7.0)
    assert not cholesky_lower(np.outer(v, v), 6, np.empty((6, 6)))           # rank one
    indefinite = np.diag([1.0, -1.0, 1.0])
    assert not cholesky_lower(indefinite, 3, np.empty((3, 3)))
    assert not cholesky_lower(np.zeros((2, 2)), 2, np.empty((2, 2)))
    nan = np.eye(2)
    nan[1, 1] = np.nan
    assert not cholesky_lower(nan, 2, np.empty((2, 2)))
