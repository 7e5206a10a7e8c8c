"""Shared by the surface-fit tests (test_surface_fit, test_improved_surface_fit, test_lattice): the paper's
simulated speckle, its integer start, and an independent numpy ZNCC with Keys interpolation."""

import numpy as np
import pytest

from livedic.dic.search import search_points
from livedic.dic.speckle import SpecklePattern, render

SIZE = 256
HALF = 10  # subset 21


@pytest.fixture(scope="module")
def pattern():
    # the paper's simulation: 256 x 256, 1000 speckles of size (R) 4 px, 8-bit, noise free
    return SpecklePattern((SIZE, SIZE), n_speckles=1000, radius=4.0, seed=0)


@pytest.fixture(scope="module")
def reference(pattern):
    return render(pattern).astype(np.float32)


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(42)
    xy = rng.integers(HALF + 6, SIZE - HALF - 6, size=(200, 2))
    return xy[:, 0].astype(np.int64), xy[:, 1].astype(np.int64)


def integer_start(reference, deformed, points, radius=2, margin=3):
    """The exhaustive integer search at the points, from (0, 0)."""
    xs, ys = points
    zero = np.zeros(xs.shape[0])
    found = search_points(reference, deformed, xs, ys, zero, zero, HALF, radius, "exhaustive", margin=margin)
    return found


def refine_with(module, reference, deformed, points, found, **options):
    """``module.refine`` at the points from the integer result ``found``."""
    xs, ys = points
    return module.refine(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float), found.status,
                         HALF, **options)


def keys_numpy(t):
    """Keys (a = -0.5) weights of taps -1, 0, 1, 2 at fraction t, written from the kernel formula."""
    a = -0.5
    s = np.abs(np.array([1.0 + t, t, 1.0 - t, 2.0 - t]))
    near = (a + 2) * s ** 3 - (a + 3) * s ** 2 + 1
    far = a * s ** 3 - 5 * a * s ** 2 + 8 * a * s - 4 * a
    return np.where(s <= 1, near, np.where(s < 2, far, 0.0))


def zncc_numpy(reference, deformed, x, y, u, v):
    """Independent ZNCC at a sub-pixel (u, v): Keys a = -0.5 interpolation of the deformed image."""
    f = reference[y - HALF:y + HALF + 1, x - HALF:x + HALF + 1].astype(np.float64)
    x0, y0 = int(np.floor(x + u)), int(np.floor(y + v))
    wx, wy = keys_numpy(x + u - x0), keys_numpy(y + v - y0)
    g = np.zeros_like(f)
    for m in range(4):
        for k in range(4):
            g += wy[m] * wx[k] * deformed[y0 - HALF + m - 1:y0 + HALF + m, x0 - HALF + k - 1:x0 + HALF + k]
    f = f - f.mean()
    g = g - g.mean()
    return float(np.sum(f * g) / np.sqrt(np.sum(f * f) * np.sum(g * g)))
