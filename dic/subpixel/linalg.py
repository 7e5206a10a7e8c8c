"""Small dense linear algebra for numba kernels (6x6 Gauss-Newton systems)."""

import numpy as np
from numba import njit


@njit(cache=True)
def cholesky_lower(a, k, low):
    """Lower Cholesky factor of the symmetric positive-definite ``a[:k, :k]`` into ``low[:k, :k]``.

    Entries above the diagonal of ``low[:k, :k]`` are set to 0. Returns False
    (``low`` undefined) when a pivot is not positive relative to the diagonal
    scale, i.e. the matrix is singular for practical purposes.
    """
    for i in range(k):
        for j in range(k):
            low[i, j] = 0.0
    for i in range(k):
        for j in range(i + 1):
            s = a[i, j]
            for m in range(j):
                s -= low[i, m] * low[j, m]
            if i == j:
                if not (s > 1e-12 * a[i, i]) or not (a[i, i] > 0.0):
                    return False
                low[i, i] = np.sqrt(s)
            else:
                low[i, j] = s / low[j, j]
    return True
