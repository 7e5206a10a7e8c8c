"""Tests of dic/subpixel/hessian.py: the Gauss-Newton matrix assembled from gradient moments equals sum J J^T,
and the normalisation terms subtract as written."""

import numpy as np

from livedic.dic.subpixel.hessian import fold_row, gauss_newton_matrix, subtract_normalisation

HALF = 3


def _subset_gradients(seed=0):
    rng = np.random.default_rng(seed)
    side = 2 * HALF + 1
    return rng.normal(size=(side, side)), rng.normal(size=(side, side))


def _steepest_descent(gx, gy):
    """J (n, 6) = (gx, gx dx, gx dy, gy, gy dx, gy dy) per subset pixel, written out directly."""
    d = np.arange(-HALF, HALF + 1, dtype=np.float64)
    dy, dx = np.meshgrid(d, d, indexing="ij")
    return np.column_stack([gx.ravel(), (gx * dx).ravel(), (gx * dy).ravel(),
                            gy.ravel(), (gy * dx).ravel(), (gy * dy).ravel()])


def _moments(gx, gy):
    """The subset moments (18,) accumulated row by row, as the kernels do."""
    moments = np.zeros(18)
    d = np.arange(-HALF, HALF + 1, dtype=np.float64)
    for r, dy in enumerate(d):
        row = np.zeros(9)
        for pair, product in enumerate((gx[r] * gx[r], gx[r] * gy[r], gy[r] * gy[r])):
            row[3 * pair:3 * pair + 3] = product.sum(), (product * d).sum(), (product * d * d).sum()
        fold_row(row, dy, moments)
    return moments


def test_the_matrix_from_moments_is_sum_j_j_transpose():
    gx, gy = _subset_gradients()
    hess = np.empty((6, 6))
    gauss_newton_matrix(_moments(gx, gy), hess)
    j = _steepest_descent(gx, gy)
    np.testing.assert_allclose(hess, j.T @ j, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(hess, hess.T)


def test_the_normalisation_terms_give_the_centred_matrix_less_the_projection():
    gx, gy = _subset_gradients(1)
    j = _steepest_descent(gx, gy)
    n = j.shape[0]
    s = np.random.default_rng(2).normal(size=n)
    s = (s - s.mean()) / np.linalg.norm(s - s.mean())          # a zero-mean, unit-norm subset
    sum_j, sum_jhat = j.sum(axis=0), j.T @ s
    hess = j.T @ j
    subtract_normalisation(hess, sum_j, sum_jhat, n)
    centred = j - j.mean(axis=0)
    np.testing.assert_allclose(hess, centred.T @ centred - np.outer(sum_jhat, sum_jhat), rtol=1e-10, atol=1e-10)
