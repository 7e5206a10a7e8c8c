"""The sub-pixel methods behind one interface (dic.subpixel.method): what callers ask instead of a name."""

import numpy as np
import pytest

from livedic.dic import SUBPIXEL_METHODS, measure
from livedic.dic.subpixel.method import METHODS, subpixel_method
from tests.conftest import blurred_noise


def _shifted(image, dx, dy):
    """``image``'s content moved by (dx, dy), exactly for a periodic band-limited image (Fourier shift)."""
    fy, fx = np.meshgrid(np.fft.fftfreq(image.shape[0]), np.fft.fftfreq(image.shape[1]), indexing="ij")
    return np.fft.ifft2(np.fft.fft2(image) * np.exp(-2j * np.pi * (fx * dx + fy * dy))).real


def test_every_method_is_registered_once_with_its_module():
    assert tuple(METHODS) == SUBPIXEL_METHODS and len(set(SUBPIXEL_METHODS)) == len(SUBPIXEL_METHODS)
    for name, method in METHODS.items():
        assert method.name == name
        assert method.module is None or callable(method.module.refine)
        assert not method.prepared or callable(method.module.refine_prepared)


def test_an_unknown_method_is_one_line_naming_the_choices():
    with pytest.raises(ValueError) as error:
        subpixel_method("magic")
    assert str(error.value).startswith("unknown sub-pixel method 'magic': choose one of none, ")


@pytest.mark.parametrize("name", SUBPIXEL_METHODS)
def test_the_traits_say_what_the_measurement_gives(name):
    """A first-order method returns gradients (exact zero for a shift); a peak fit returns none; every
    method finds a known sub-pixel shift of a texture that is not the simulator's."""
    reference = blurred_noise((96, 96), seed=3)
    shift = (0.4, -0.3)
    moved = _shifted(reference, *shift)
    m = measure(reference, moved, [(48, 48)], subpixel=name)
    method = METHODS[name]
    assert m.ok[0]
    assert (m.ux is not None) == method.first_order
    if method.module is None:
        assert (m.u[0], m.v[0]) == (0.0, 0.0)          # integer result: the nearest whole pixel
    else:
        bound = 0.01 if method.first_order else 0.1       # a peak fit's own bias (docs/guide/measure.md)
        assert abs(m.u[0] - shift[0]) < bound and abs(m.v[0] - shift[1]) < bound
    if method.first_order:
        assert max(abs(m.ux[0]), abs(m.uy[0]), abs(m.vx[0]), abs(m.vy[0])) < 0.01
