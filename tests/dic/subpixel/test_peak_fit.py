import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from livedic.dic.subpixel.peak_fit import fit_peak_3x3


def _quadratic_grid(px, py, curv_x, curv_y, cross, top):
    g = np.empty((3, 3))
    for r in range(3):
        for q in range(3):
            x, y = q - 1 - px, r - 1 - py
            g[r, q] = top - curv_x * x * x - curv_y * y * y - cross * x * y
    return g


@settings(max_examples=200, deadline=None)
@given(px=st.floats(-0.99, 0.99), py=st.floats(-0.99, 0.99),
       cx=st.floats(0.05, 2.0), cy=st.floats(0.05, 2.0), rho=st.floats(-0.9, 0.9))
def test_recovers_exact_quadratic_peak(px, py, cx, cy, rho):
    cross = rho * 2.0 * np.sqrt(cx * cy)   # keeps the surface strictly concave
    dx, dy, peak, ok = fit_peak_3x3(_quadratic_grid(px, py, cx, cy, cross, 0.9))
    assert ok
    assert dx == pytest.approx(px, abs=1e-9)
    assert dy == pytest.approx(py, abs=1e-9)
    assert peak == pytest.approx(0.9, abs=1e-9)


def test_rejects_surface_without_maximum():
    saddle = _quadratic_grid(0.2, 0.1, 1.0, -1.0, 0.0, 0.5)
    assert not fit_peak_3x3(saddle)[3]
    flat = np.full((3, 3), 0.7)
    assert not fit_peak_3x3(flat)[3]


def test_rejects_peak_beyond_one_step():
    assert not fit_peak_3x3(_quadratic_grid(1.6, 0.0, 0.3, 0.3, 0.0, 0.9))[3]
