"""Keys bicubic convolution weights, the interpolation kernel of the surface-fit methods.

``keys_weights``: bicubic convolution (Keys 1981, DOI 10.1109/TASSP.1981.1163711)
with a = -0.5, the MATLAB ``interp2(..., 'cubic')`` kernel the paper's improved
surface fit is built on. B-spline interpolation for IC-GN / N-R is ``dic.bspline``.
"""

from numba import njit

KEYS_A = -0.5


@njit(cache=True)
def keys_weights(t, out):
    """Fill ``out`` (4,) with Keys weights for taps at offsets -1, 0, 1, 2 of fraction t in [0, 1)."""
    a = KEYS_A
    s = 1.0 + t
    out[0] = a * s * s * s - 5.0 * a * s * s + 8.0 * a * s - 4.0 * a
    s = t
    out[1] = (a + 2.0) * s * s * s - (a + 3.0) * s * s + 1.0
    s = 1.0 - t
    out[2] = (a + 2.0) * s * s * s - (a + 3.0) * s * s + 1.0
    s = 2.0 - t
    out[3] = a * s * s * s - 5.0 * a * s * s + 8.0 * a * s - 4.0 * a
