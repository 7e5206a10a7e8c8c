"""Coarse-fine integer search (algorithms.md section 5).

Coarse stage: ZNCC on the lattice ``c + k * step`` (k integer) inside the box,
``c`` = the rounded guess, so the guess itself is always a node and the lattice
stays symmetric about it. Fine stage: every integer position within
``step - 1`` of the coarse best, clipped to the box; the best of both stages is
returned. A box edge is at most ``step - 1`` from the nearest node, so the fine
window can reach it.

Cost ``~(2 radius / step + 1)^2 + (2 step - 1)^2`` distinct evaluations (nodes
revisited by the fine stage count once in ``evaluations``, twice in ``calls``).
It fails when ``step`` exceeds the half-width of the correlation peak (about the
speckle radius) and a side lobe beats the sampled flank of the true peak.
"""

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.method_options import is_int_at_least
from livedic.dic.search._common import SearchOutputs, begin_point, finish_point, fitness, new_cache

DEFAULTS = {"step": 3}
CHECKS = {"step": (is_int_at_least(1), "an integer >= 1 (coarse lattice step, pixels)")}


@njit(cache=True)
def _search_one(fhat, target, x, y, half, cu, cv, ulo, uhi, vlo, vhi, step, cache, counts):
    # first lattice node >= lo that is congruent to the centre modulo step
    u_start = cu - ((cu - ulo) // step) * step
    v_start = cv - ((cv - vlo) // step) * step
    bu = u_start
    bv = v_start
    bc = -np.inf
    for v in range(v_start, vhi + 1, step):
        for u in range(u_start, uhi + 1, step):
            c = fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts)
            if c > bc:
                bu = u
                bv = v
                bc = c
    cu2 = bu
    cv2 = bv
    for v in range(max(vlo, cv2 - step + 1), min(vhi, cv2 + step - 1) + 1):
        for u in range(max(ulo, cu2 - step + 1), min(uhi, cu2 + step - 1) + 1):
            c = fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts)
            if c > bc:
                bu = u
                bv = v
                bc = c
    return bu, bv, bc


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, ulo, uhi, vlo, vhi, cus, cvs, half, step, status,
           out_u, out_v, out_c, out_evals, out_calls):
    """Search every point; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        # lattice anchor: the rounded guess, clamped into the box
        cu = min(max(cus[i], ulo[i]), uhi[i])
        cv = min(max(cvs[i], vlo[i]), vhi[i])
        u, v, c = _search_one(fhat, target, xs[i], ys[i], half, cu, cv, ulo[i], uhi[i], vlo[i], vhi[i],
                              step, cache, counts)
        finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls)


def run(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, ulo: np.ndarray,
        uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray, seed: np.uint64,
        params: Mapping[str, Any], outputs: SearchOutputs, centre: tuple[np.ndarray, np.ndarray]) -> None:
    _batch(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, centre[0], centre[1], half,
           int(params["step"]), status, *outputs)
