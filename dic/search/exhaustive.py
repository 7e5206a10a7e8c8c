"""Exhaustive integer search: ZNCC at every integer position of the box.

The ground truth the other searches are scored against ("success" = the same
integer position as this search over the same box). Cost: one ZNCC per box
position, ``(2 * radius + 1) ** 2`` for a box that the image does not clip.
Ties keep the first position in row-major order (v outer, u inner).
"""

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.method_options import Checks
from livedic.dic.search._common import SearchOutputs, begin_point, finish_point, fitness, new_cache

DEFAULTS: dict[str, Any] = {}
CHECKS: Checks = {}


@njit(cache=True)
def _search_one(fhat, target, x, y, half, ulo, uhi, vlo, vhi, cache, counts):
    bu = ulo
    bv = vlo
    bc = -np.inf
    for v in range(vlo, vhi + 1):
        for u in range(ulo, uhi + 1):
            c = fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts)
            if c > bc:
                bu = u
                bv = v
                bc = c
    return bu, bv, bc


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, ulo, uhi, vlo, vhi, half, status,
           out_u, out_v, out_c, out_evals, out_calls):
    """Search every point; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        u, v, c = _search_one(fhat, target, xs[i], ys[i], half, ulo[i], uhi[i], vlo[i], vhi[i], cache, counts)
        finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls)


def run(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, ulo: np.ndarray,
        uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray, seed: np.uint64 | int,
        params: Mapping[str, Any], outputs: SearchOutputs, centre: tuple[np.ndarray, np.ndarray] | None) -> None:
    _batch(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, half, status, *outputs)
