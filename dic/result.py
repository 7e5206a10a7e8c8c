"""Result records passed between the stages of a measurement.

Arrays are structure-of-arrays, one entry per point, so numba kernels fill them
in place and callers slice them without copying.
"""

from dataclasses import dataclass

import numpy as np


@dataclass
class IntegerSearchResult:
    """Integer-pixel match per point.

    xs, ys : int64 (N,)   snapped point positions in the reference
    u, v : int64 (N,)     integer displacement of the best match
    zncc : float64 (N,)   ZNCC there (NaN where status is not OK)
    status : int8 (N,)    ``dic.status.Status`` codes
    evaluations : int64 (N,)  distinct positions whose ZNCC was computed
    calls : int64 (N,)        fitness calls, repeats included
    """
    xs: np.ndarray
    ys: np.ndarray
    u: np.ndarray
    v: np.ndarray
    zncc: np.ndarray
    status: np.ndarray
    evaluations: np.ndarray
    calls: np.ndarray


@dataclass
class SubpixelResult:
    """Refined displacement per point.

    u, v : float64 (N,)   displacement; NaN where status is not OK
    zncc : float64 (N,)   correlation at the result
    status : int8 (N,)
    ux, uy, vx, vy : float64 (N,) or None   displacement gradients (1st-order methods)
    iterations : int64 (N,) or None          iterations used (iterative methods)
    evaluations : int64 (N,) or None         ZNCC evaluations of the integer search that started it
    """
    u: np.ndarray
    v: np.ndarray
    zncc: np.ndarray
    status: np.ndarray
    ux: np.ndarray | None = None
    uy: np.ndarray | None = None
    vx: np.ndarray | None = None
    vy: np.ndarray | None = None
    iterations: np.ndarray | None = None
    evaluations: np.ndarray | None = None


@dataclass
class Measurement:
    """What ``dic.measure`` returns: one entry per point.

    x, y : float64 (N,)  point positions actually used (snapped to pixel centres)
    u, v : float64 (N,)  displacement, content at (x, y) in the reference is at (x+u, y+v)
    zncc : float64 (N,)  correlation of the final match, within [-1, 1] (NaN where none)
    ok : bool (N,)       True where ``status == Status.OK``
    status : int8 (N,)   ``dic.status.Status`` code per point
    ux, uy, vx, vy       displacement gradients (1st-order sub-pixel methods) or None
    iterations           sub-pixel iterations (iterative methods) or None
    evaluations          integer-search ZNCC evaluations per point, or None without a search
    """
    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    v: np.ndarray
    zncc: np.ndarray
    ok: np.ndarray
    status: np.ndarray
    ux: np.ndarray | None = None
    uy: np.ndarray | None = None
    vx: np.ndarray | None = None
    vy: np.ndarray | None = None
    iterations: np.ndarray | None = None
    evaluations: np.ndarray | None = None

    def __post_init__(self) -> None:
        # Rounding in the solvers' sums lets a perfect match score a hair above 1 (1.0000002 for a frame
        # tracked against itself): ZNCC lies within [-1, 1] by definition, so it is clipped here, where every
        # measurement is assembled, after the gates have judged it (which points are ok does not change).
        zncc = np.asarray(self.zncc, dtype=np.float64)
        if np.any(np.abs(zncc) > 1.0):
            zncc = np.clip(zncc, -1.0, 1.0)
        self.zncc = zncc
