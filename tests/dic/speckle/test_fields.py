"""Tests of dic/speckle/fields.py: translation, affine and sinusoid fields, their values, checks and kernel
parameters (the inverse a kernel applies)."""

import math

import numpy as np
import pytest

from livedic.dic.speckle import affine, sinusoid, translation
from livedic.dic.speckle.kernels import _AFFINE, _SINUSOID, _TRANSLATION, _inverse_map

XY = (np.array([[0.0, 10.0], [25.5, -3.0]]), np.array([[5.0, 5.0], [40.0, 2.5]]))


def test_a_translation_is_the_same_everywhere():
    field = translation(1.5, -2)
    U, V = field(*XY)
    assert U.shape == V.shape == (2, 2) and np.all(U == 1.5) and np.all(V == -2.0)
    assert field.kind == "translation" and field.params == {"u": 1.5, "v": -2.0}
    assert repr(field) == "translation(u=1.5, v=-2.0)"
    kind, p = field._kernel_params()
    assert kind == _TRANSLATION and p.tolist() == [1.5, -2.0]


def test_an_affine_field_is_linear_about_its_centre_and_its_kernel_inverts_it():
    field = affine(u=0.5, v=-1.0, ux=0.02, uy=-0.01, vx=0.03, vy=-0.04, centre=(30.0, 20.0))
    X, Y = XY
    U, V = field(X, Y)
    np.testing.assert_allclose(U, 0.5 + 0.02 * (X - 30) - 0.01 * (Y - 20), rtol=0, atol=1e-15)
    np.testing.assert_allclose(V, -1.0 + 0.03 * (X - 30) - 0.04 * (Y - 20), rtol=0, atol=1e-15)
    kind, p = field._kernel_params()
    assert kind == _AFFINE
    for x, y in zip(X.ravel(), Y.ravel()):        # the kernel's inverse maps the moved point back
        u, v = field(np.array(x), np.array(y))
        back = _inverse_map(kind, p, x + float(u), y + float(v))
        assert back == pytest.approx((x, y), abs=1e-12)


def test_a_sinusoid_varies_one_component_along_one_axis():
    X, Y = XY
    for axis, direction in (("x", "v"), ("y", "u"), ("x", "u"), ("y", "v")):
        U, V = sinusoid(2.0, 50.0, axis=axis, direction=direction, phase=0.3)(X, Y)
        expected = 2.0 * np.sin(2 * math.pi * (X if axis == "x" else Y) / 50.0 + 0.3)
        moved, still = (U, V) if direction == "u" else (V, U)
        np.testing.assert_allclose(moved, expected, atol=1e-15)
        assert np.all(still == 0)
    kind, p = sinusoid(2.0, 50.0, axis="y", direction="v")._kernel_params()
    assert kind == _SINUSOID and p.tolist() == pytest.approx([2.0, 2 * math.pi / 50.0, 0.0, 1.0, 1.0])


def test_fields_broadcast_their_arguments():
    U, V = affine(ux=0.1)(np.arange(3.0)[None, :], np.zeros((2, 1)))
    assert U.shape == V.shape == (2, 3)


@pytest.mark.parametrize("build, match", [
    (lambda: translation(float("nan"), 0), "translation u"),
    (lambda: translation(0, True), "translation v"),
    (lambda: affine(vy="0.1"), "affine vy"),
    (lambda: affine(centre=(1.0,)), "centre must be a pair"),
    (lambda: affine(centre=(1.0, float("inf"))), "affine centre y"),
    (lambda: sinusoid(1.0, 0.0), "period must be > 0"),
    (lambda: sinusoid(1.0, 10.0, axis="z"), "axis"),
    (lambda: sinusoid(1.0, 10.0, direction="w"), "direction"),
])
def test_bad_field_arguments_are_one_line_errors(build, match):
    with pytest.raises(ValueError, match=match) as error:
        build()
    assert "\n" not in str(error.value)


def test_fields_that_fold_the_material_are_refused_when_inverted():
    with pytest.raises(ValueError, match="folds"):
        affine(ux=-1.0)._kernel_params()
    with pytest.raises(ValueError, match="folds"):
        affine(uy=1.0, vx=1.0)._kernel_params()                   # det = 1 - 1 = 0
    with pytest.raises(ValueError, match="folds"):
        sinusoid(10.0, 2 * math.pi * 10.0, axis="x", direction="u")._kernel_params()   # 2 pi A / P = 1
    # across its own axis any amplitude is a shear, invertible
    assert sinusoid(10.0, 20.0, axis="x", direction="v")._kernel_params()[0] == _SINUSOID
