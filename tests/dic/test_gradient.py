"""Tests of dic/gradient.py: 4th-order and central differences, exact on polynomials, and their border stencils."""

import numpy as np
import pytest

from livedic.dic.gradient import gradient_4th, gradient_central


@pytest.mark.parametrize("operator", [gradient_4th, gradient_central])
def test_gradient_of_a_linear_ramp_is_exact_everywhere(operator):
    rows, cols = np.mgrid[0:9, 0:11].astype(np.float64)
    ramp = 2.5 * cols - 1.25 * rows + 7.0
    gx, gy = operator(ramp)
    # the border falls back to lower-order differences, which are still exact for a ramp
    np.testing.assert_allclose(gx, 2.5, atol=1e-12)
    np.testing.assert_allclose(gy, -1.25, atol=1e-12)


def test_fourth_order_is_exact_for_quartics_inside_and_central_is_not():
    rows, cols = np.mgrid[0:12, 0:14].astype(np.float64)
    image = 1e-3 * cols ** 4 + 0.01 * cols ** 3 - 2e-3 * rows ** 4 + cols * rows
    gx, gy = gradient_4th(image)
    ex = 4e-3 * cols ** 3 + 0.03 * cols ** 2 + rows
    ey = -8e-3 * rows ** 3 + cols
    np.testing.assert_allclose(gx[2:-2, 2:-2], ex[2:-2, 2:-2], atol=1e-9)
    np.testing.assert_allclose(gy[2:-2, 2:-2], ey[2:-2, 2:-2], atol=1e-9)
    cx, _ = gradient_central(image)
    assert np.max(np.abs(cx[2:-2, 2:-2] - ex[2:-2, 2:-2])) > 1e-3


def test_gradient_dtype_and_input_checks():
    gx, gy = gradient_4th(np.arange(20, dtype=np.uint8).reshape(4, 5), dtype=np.float32)
    assert gx.dtype == np.float32 and gx.shape == (4, 5)
    np.testing.assert_allclose(gx, 1.0)
    np.testing.assert_allclose(gy, 5.0)
    with pytest.raises(ValueError, match="2-D"):
        gradient_4th(np.zeros(4))


@pytest.mark.parametrize("operator", [gradient_4th, gradient_central])
def test_the_border_uses_the_stencils_that_fit(operator):
    image = np.array([[0.0, 1.0, 4.0, 9.0, 16.0, 25.0, 36.0]])                # x^2 along one row
    image = np.repeat(image, 3, axis=0)
    gx, gy = operator(image)
    assert gx[0, 0] == 1.0 and gx[0, -1] == 36.0 - 25.0                      # one-sided on the edge
    assert gx[0, 1] == 0.5 * (4.0 - 0.0) and gx[0, -2] == 0.5 * (36.0 - 16.0)  # central one pixel in
    assert gx[0, 3] == pytest.approx(6.0, abs=1e-12)                          # exact inside for x^2 either way
    assert np.all(gy == 0)


def test_a_single_column_or_row_has_no_gradient_across_it():
    column = np.arange(6.0).reshape(6, 1) ** 2
    gx, gy = gradient_4th(column)
    assert np.all(gx == 0) and gy[3, 0] == pytest.approx(6.0, abs=1e-12)
    gx, gy = gradient_central(column.T)
    assert np.all(gy == 0) and gx[0, 3] == pytest.approx(6.0, abs=1e-12)


def test_float64_images_keep_their_precision_and_bad_dtypes_are_refused():
    image = 1e8 + np.add.outer(np.zeros(6), 1e-3 * np.arange(7.0))         # a tiny ramp on a large offset
    gx, _ = gradient_4th(image)
    np.testing.assert_allclose(gx, 1e-3, rtol=1e-4)                          # float32 would lose it all
    with pytest.raises(ValueError, match="dtype"):
        gradient_central(np.zeros((4, 4), dtype=bool))
    with pytest.raises(ValueError, match="2-D"):
        gradient_central(np.zeros((2, 4, 4)))
