"""Shared by the speckle simulator's tests: a small non-square pattern and the brute-force analytic intensity."""

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern

SHAPE = (72, 96)          # (H, W): not square, so a swapped axis shows
DENSITY = 1000 / 256**2   # the paper's 256 x 256 / 1000 speckles
REL_TOL = 1e-9            # relative to the mean intensity; the 5R cutoff is ~1e-11


@pytest.fixture(scope="module")
def pattern():
    return SpecklePattern(SHAPE, density=DENSITY, radius=4.0, seed=7)


def brute(pattern, X, Y):
    """Analytic intensity (I0 = 1) at reference points, summed over every centre."""
    X = np.asarray(X, dtype=np.float64)[..., None]
    Y = np.asarray(Y, dtype=np.float64)[..., None]
    xs, ys = pattern.centres[:, 0], pattern.centres[:, 1]
    return np.exp(-((X - xs) ** 2 + (Y - ys) ** 2) / pattern.radius**2).sum(axis=-1)


def pixel_grid(shape):
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    return cols.astype(np.float64), rows.astype(np.float64)
