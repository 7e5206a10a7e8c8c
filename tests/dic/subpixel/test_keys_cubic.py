"""Tests of dic/subpixel/keys_cubic.py: Keys' a = -0.5 weights interpolate, sum to one and reproduce quadratics."""

import numpy as np
import pytest

from livedic.dic.subpixel.keys_cubic import keys_weights
from tests.dic.subpixel.conftest import keys_numpy

FRACTIONS = np.linspace(0.0, 0.999, 37)


def _weights(t):
    out = np.empty(4)
    keys_weights(float(t), out)
    return out


def test_at_a_pixel_the_weights_pick_that_pixel():
    np.testing.assert_allclose(_weights(0.0), [0.0, 1.0, 0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("t", FRACTIONS)
def test_weights_are_keys_kernel_at_the_tap_distances_and_sum_to_one(t):
    w = _weights(t)
    np.testing.assert_allclose(w, keys_numpy(t), atol=1e-14)
    assert w.sum() == pytest.approx(1.0, abs=1e-14)


def test_quadratics_are_reproduced_exactly_and_cubics_are_not():
    taps = np.array([-1.0, 0.0, 1.0, 2.0])
    quadratic = lambda x: 3.0 - 2.0 * x + 0.7 * x * x
    cubic = lambda x: x ** 3
    errors = []
    for t in FRACTIONS:
        w = _weights(t)
        assert w @ quadratic(taps) == pytest.approx(quadratic(t), abs=1e-13)
        errors.append(abs(w @ cubic(taps) - cubic(t)))
    assert max(errors) > 1e-3                                 # a = -0.5 is third-order accurate, not exact on cubics
