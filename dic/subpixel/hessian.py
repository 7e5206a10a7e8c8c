"""The 6x6 Gauss-Newton matrix of the first-order shape function, assembled from gradient moments.

With p = (u, ux, uy, v, vx, vy) the steepest-descent image of the subset pixel
at (dx, dy) is ``J = (gx, gx dx, gx dy, gy, gy dx, gy dy)``, so every entry of
``H = sum J J^T`` is a moment ``(1, dx, dy, dx^2, dx dy, dy^2)`` of one of the
products ``gx^2, gx gy, gy^2``: 18 sums instead of 36 entries. They are
accumulated row by row: a row's sums in dx only, then folded with the row's dy
(``fold_row``), then spread into H (``gauss_newton_matrix``).

IC-GN (``dic.subpixel.icgn``: reference gradients, once per point) and
Newton-Raphson (``dic.subpixel.newton_raphson``: target gradients, every
iteration) both build their step matrix here, and both may subtract the two
rank-one terms of the ZNSSD's normalisation (``subtract_normalisation``).

The functions are inlined into the calling kernel (``inline="always"``), so they
are compiled with the caller's floating-point flags and cost no call.

Layouts
-------
row : (9,) per product (gx^2, gx gy, gy^2), the row's sums times (1, dx, dx^2)
moments : (18,) per product (gx^2, gx gy, gy^2), the subset's moments (1, dx, dy, dx^2, dx dy, dy^2)
"""

from numba import njit


@njit(cache=True, inline="always")
def fold_row(row, dy, moments):
    """Add one subset row (``row``, at offset ``dy``) to the subset ``moments``."""
    for pair in range(3):
        s1 = row[3 * pair]
        sx = row[3 * pair + 1]
        o = 6 * pair
        moments[o] += s1
        moments[o + 1] += sx
        moments[o + 2] += s1 * dy
        moments[o + 3] += row[3 * pair + 2]
        moments[o + 4] += sx * dy
        moments[o + 5] += s1 * dy * dy


@njit(cache=True, inline="always")
def gauss_newton_matrix(moments, hess):
    """``hess`` (6, 6) <- ``sum J J^T`` from the subset ``moments`` (18,).

    Parameter a is (gradient component ga in (x, y), moment ma in (1, dx, dy));
    ``H[a, b] = sum G_a G_b m_a m_b`` is the moment ``m_a m_b`` of the product ``G_a G_b``.
    """
    for a in range(6):
        ga = a // 3
        ma = a % 3
        for b in range(6):
            gb = b // 3
            mb = b % 3
            lo = min(ma, mb)
            hi = max(ma, mb)
            # (1,1)->1 (1,dx)->dx (1,dy)->dy (dx,dx)->dx^2 (dx,dy)->dx dy (dy,dy)->dy^2
            if lo == 0:
                mo = hi
            elif lo == 1:
                mo = 2 + hi
            else:
                mo = 5
            hess[a, b] = moments[6 * (ga + gb) + mo]


@njit(cache=True, inline="always")
def subtract_normalisation(hess, sum_j, sum_jhat, n):
    """``hess -= sum_j sum_j^T / n + sum_jhat sum_jhat^T``: the exact derivative at a zero residual.

    ``sum_j`` (6,) is ``sum J`` over the ``n`` subset pixels and ``sum_jhat`` (6,)
    is ``sum J s`` with ``s`` the normalised (zero-mean, unit-norm) subset whose
    mean and norm the ZNSSD divides out: what remains is ``sum J~ J~^T - sum_jhat
    sum_jhat^T`` with ``J~ = J - mean J``.
    """
    for a in range(6):
        for b in range(6):
            hess[a, b] -= sum_j[a] * sum_j[b] / n + sum_jhat[a] * sum_jhat[b]
