"""Quadratic surface fit to a 3x3 neighbourhood of correlation values.

Model ``C(x, y) = a0 + a1 x + a2 y + a3 x^2 + a4 xy + a5 y^2`` on x, y in {-1, 0, 1}
(grid units), solved in closed form by least squares; the peak is where the
gradient vanishes. Used at 1 px spacing by the classic surface-fit method and
at 0.2 px by the paper's improved surface fit.
"""

from numba import njit


@njit(cache=True)
def fit_peak_3x3(c):
    """Peak offset of a quadratic fitted to ``c`` (3, 3), indexed c[row=dy+1, col=dx+1].

    Returns ``(dx, dy, peak_value, ok)`` in grid units. ``ok`` is False when the
    fitted surface has no maximum (not concave) or the maximum lies more than one
    grid step away; dx, dy are then 0.
    """
    s0 = 0.0
    sx = 0.0
    sy = 0.0
    sxx = 0.0
    syy = 0.0
    sxy = 0.0
    for r in range(3):
        y = r - 1.0
        for q in range(3):
            x = q - 1.0
            v = c[r, q]
            s0 += v
            sx += x * v
            sy += y * v
            sxx += x * x * v
            syy += y * y * v
            sxy += x * y * v
    a0 = (5.0 * s0 - 3.0 * (sxx + syy)) / 9.0
    a1 = sx / 6.0
    a2 = sy / 6.0
    a3 = sxx / 2.0 - s0 / 3.0
    a5 = syy / 2.0 - s0 / 3.0
    a4 = sxy / 4.0
    det = 4.0 * a3 * a5 - a4 * a4
    if not (det > 0.0 and a3 < 0.0):
        return 0.0, 0.0, c[1, 1], False
    dx = (a2 * a4 - 2.0 * a1 * a5) / det
    dy = (a1 * a4 - 2.0 * a2 * a3) / det
    if abs(dx) > 1.0 or abs(dy) > 1.0:
        return 0.0, 0.0, c[1, 1], False
    peak = a0 + a1 * dx + a2 * dy + a3 * dx * dx + a4 * dx * dy + a5 * dy * dy
    return dx, dy, peak, True
