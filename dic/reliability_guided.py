"""Reliability-guided measurement: search a few seeds, then hand each result to its neighbours.

Searching every point over a wide box is slow and, where a search misses the
true peak, wrong. Pan (2009) measures a few *seed* points with a full search
and then propagates: the most reliable solved point (highest ZNCC) hands its
deformation to its unsolved neighbours, whose IC-GN starts from it; each newly
solved point joins the queue. Correct starts converge in 2-3 iterations, and a
point is reached first from the best correlated of its neighbours, so one bad
subset does not spread. Here, following the issue that asked for it:

* **Seeds**: up to ``SEEDS`` points spread over the region (the best-textured
  point of each cell of a 3 x 3 grid over the unsolved points' bounding box),
  searched over the full radius by the chosen integer search, then IC-GN.
* **Propagation** (``_propagate``, compiled): a max-heap on ZNCC; the start for
  neighbour k of solved point j is j's warp carried to k,
  ``u_k = u_j + ux_j (x_k - x_j) + uy_j (y_k - y_j)`` (same for v), and j's
  gradients. A result is accepted when IC-GN converges with ZNCC >= ``accept``.
  A point that fails is tried from up to ``MAX_TRIES`` different neighbours.
* **A point that fails from its neighbours gets its own full search** (then
  IC-GN); accepted, it propagates in turn.
* **Disconnected regions** (not reached: a hole, a second specimen) get their
  own seeds in the next round; when every seed of a round fails, the next round
  takes twice as many, so a region with nothing measurable is searched point by
  point in a few rounds rather than one seed at a time.
* **Repair**: after propagation, points that fail the normalised median test
  (``dic.quality.median_test``) are solved again from their best ok neighbour
  and keep the new result if it correlates better and agrees with the neighbours.

Within a region points are solved one after another (the heap order is the
method). Large point sets are split into 4 regions (quadrants at the median x
and y), each with its own seeds and heap, run in parallel; the split does not
depend on the thread count, so neither do the results. Seeds and full searches
run in parallel batches.

References
----------
B. Pan, "Reliability-guided digital image correlation for image deformation
measurement", Appl. Opt. 48(8):1535-1542 (2009), :DOI:`10.1364/AO.48.001535`.
"""

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.bspline import BSplineCoefficients
from livedic.dic.neighbours import NeighbourGraph
from livedic.dic.status import LOW_CORRELATION, OK
from livedic.dic.subpixel.icgn import IcgnReference, refine_point, refine_point_scratch

IntegerSearch = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
"""``search(idx) -> (u, v, status, evaluations)``: the full integer search of points ``idx``."""
Repair = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``repair(params, ok) -> outlier mask``: points to solve again from their best neighbour."""

SEEDS = 9
MAX_TRIES = 3
# Points per region below which the measurement is not split into parallel regions.
MIN_REGION_POINTS = 500
# IC-GN settings of the propagation (those of dic.subpixel.icgn.refine_prepared and the tracker)
ICGN_OPTIONS = {"max_iterations": 50, "tolerance": 0.001, "translation_iterations": 4, "translation_tolerance": 0.02}


@njit(cache=True)
def _heap_push(keys, items, size, key, item):
    i = size
    keys[i] = key
    items[i] = item
    while i > 0:
        parent = (i - 1) // 2
        if keys[parent] >= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        items[parent], items[i] = items[i], items[parent]
        i = parent
    return size + 1


@njit(cache=True)
def _heap_pop(keys, items, size):
    """Remove the largest key; returns (item, new size)."""
    top = items[0]
    size -= 1
    keys[0] = keys[size]
    items[0] = items[size]
    i = 0
    while True:
        left = 2 * i + 1
        right = left + 1
        best = i
        if left < size and keys[left] > keys[best]:
            best = left
        if right < size and keys[right] > keys[best]:
            best = right
        if best == i:
            break
        keys[best], keys[i] = keys[i], keys[best]
        items[best], items[i] = items[i], items[best]
        i = best
    return top, size


@njit(cache=True)
def _carry(params, j, k, xs, ys, order_k, out):
    """Warp of point j evaluated at point k: the start of k's IC-GN (gradients dropped for order 0)."""
    dx = float(xs[k] - xs[j])
    dy = float(ys[k] - ys[j])
    out[0] = params[j, 0] + params[j, 1] * dx + params[j, 2] * dy
    out[3] = params[j, 3] + params[j, 4] * dx + params[j, 5] * dy
    if order_k == 0:
        out[1] = out[2] = out[4] = out[5] = 0.0
    else:
        out[1] = params[j, 1]
        out[2] = params[j, 2]
        out[4] = params[j, 4]
        out[5] = params[j, 5]


@njit(cache=True, parallel=True, nogil=True)
def _propagate(flat, origin, stride, height, width, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j,
               sum_jf, sum_f, order, start, index, part, n_parts, params, status, zncc, iterations, state, tries,
               accept, max_tries, max_iterations, tolerance, translation_iterations, translation_tolerance, degree):
    """Propagate from every solved point (state 1) into pending ones (state 0); returns points solved.

    state: 0 pending, 1 solved, 2 given up. ``tries`` counts the failed
    attempts of each pending point; its last attempt's status and ZNCC stay.
    Each region ``part`` has its own heap and only hands results to points of
    the same region, so the regions run in parallel and the result does not
    depend on the number of threads.
    """
    n = xs.shape[0]
    solved = np.zeros(n_parts, dtype=np.int64)
    for region in prange(n_parts):
        keys = np.empty(n)
        items = np.empty(n, dtype=np.int64)
        size = 0
        for i in range(n):
            if state[i] == 1 and part[i] == region:
                size = _heap_push(keys, items, size, zncc[i], i)
        scratch = refine_point_scratch(half, lanes)
        p = np.empty(6)
        while size > 0:
            j, size = _heap_pop(keys, items, size)
            for m in range(start[j], start[j + 1]):
                k = index[m]
                if part[k] != region or state[k] != 0 or tries[k] >= max_tries:
                    continue
                _carry(params, j, k, xs, ys, order[k], p)
                st, zn, it = refine_point(flat, origin, stride, height, width, xs[k], ys[k], half, fhat[k], fx[k],
                                          fy[k], norm[k], hinv[k], hinv0[k], sum_j[k], sum_jf[k], sum_f[k], p,
                                          order[k], max_iterations, tolerance, translation_iterations,
                                          translation_tolerance, scratch, degree)
                iterations[k] += it
                if st == OK and zn >= accept:
                    for c in range(6):
                        params[k, c] = p[c]
                    status[k] = OK
                    zncc[k] = zn
                    state[k] = 1
                    solved[region] += 1
                    size = _heap_push(keys, items, size, zn, k)
                else:
                    tries[k] += 1
                    status[k] = st if st != OK else LOW_CORRELATION
                    zncc[k] = zn
    return solved.sum()


@njit(cache=True, parallel=True, nogil=True)
def _solve(flat, origin, stride, height, width, xs, ys, half, lanes, fhat, fx, fy, norm, hinv, hinv0, sum_j, sum_jf,
           sum_f, order, idx, starts, out_status, out_zncc, out_iterations, max_iterations, tolerance,
           translation_iterations, translation_tolerance, degree):
    """IC-GN for the points ``idx`` from ``starts`` (len(idx), 6), refined in place, in parallel."""
    for t in prange(idx.shape[0]):
        k = idx[t]
        scratch = refine_point_scratch(half, lanes)
        st, zn, it = refine_point(flat, origin, stride, height, width, xs[k], ys[k], half, fhat[k], fx[k], fy[k],
                                  norm[k], hinv[k], hinv0[k], sum_j[k], sum_jf[k], sum_f[k], starts[t], order[k],
                                  max_iterations, tolerance, translation_iterations, translation_tolerance, scratch,
                                  degree)
        out_status[t] = st
        out_zncc[t] = zn
        out_iterations[t] = it


class _Problem:
    """The prepared data of one reliability-guided measurement and its per-point state."""

    def __init__(self, prep, coeffs, order, graph, accept, options) -> None:
        self.prep = prep
        self.coeffs = coeffs
        self.order = np.ascontiguousarray(order, dtype=np.int64)
        self.start, self.index = graph
        self.accept = float(accept)
        self.options = {**ICGN_OPTIONS, **(options or {})}
        n = prep.xs.shape[0]
        self.params = np.full((n, 6), np.nan)
        self.status = prep.status.copy()
        self.zncc = np.full(n, np.nan)
        self.iterations = np.zeros(n, dtype=np.int64)
        self.tries = np.zeros(n, dtype=np.int64)

    def _kernel_args(self):
        p, c = self.prep, self.coeffs
        height, width = p.shape
        return (c.flat, c.origin, c.coefficients.shape[1], height, width, p.xs, p.ys, p.half, p.lanes, p.fhat, p.fx,
                p.fy, p.norm, p.hinv, p.hinv0, p.sum_j, p.sum_jf, p.sum_f, self.order)

    def _option_args(self):
        """The iteration options, then the B-spline degree of the target coefficients (the kernels' last arguments)."""
        o = self.options
        return (int(o["max_iterations"]), float(o["tolerance"]), int(o["translation_iterations"]),
                float(o["translation_tolerance"]), int(self.coeffs.degree))

    def solve(self, idx, starts):
        """IC-GN for points ``idx`` from ``starts`` (len(idx), 6); returns the accepted mask (results stored)."""
        starts = np.ascontiguousarray(starts, dtype=np.float64).copy()
        st = np.empty(idx.size, dtype=np.int8)
        zn = np.empty(idx.size)
        it = np.empty(idx.size, dtype=np.int64)
        if idx.size:
            _solve(*self._kernel_args(), np.ascontiguousarray(idx, dtype=np.int64), starts, st, zn, it,
                   *self._option_args())
        accepted = (st == OK) & (zn >= self.accept)
        self.iterations[idx] += it
        self.status[idx] = np.where((st == OK) & ~accepted, LOW_CORRELATION, st)
        self.zncc[idx] = zn
        self.params[idx[accepted]] = starts[accepted]
        self.status[idx[accepted]] = OK
        return accepted

    def propagate(self, state, part, n_parts):
        return _propagate(*self._kernel_args(), self.start, self.index, part, n_parts, self.params, self.status,
                          self.zncc, self.iterations, state, self.tries, self.accept, MAX_TRIES,
                          *self._option_args())


def regions(xs: np.ndarray, ys: np.ndarray, n_active: int) -> tuple[np.ndarray, int]:
    """Region of each point (``part``) and the number of regions: 4 quadrants split at the medians
    when there are at least ``4 * MIN_REGION_POINTS`` points to measure, else one region.

    A fixed number of regions (not one per thread) keeps results independent of the thread count.
    """
    n = xs.shape[0]
    if n_active < 4 * MIN_REGION_POINTS:
        return np.zeros(n, dtype=np.int64), 1
    right = xs > np.median(xs)
    below = ys > np.median(ys)
    return (2 * below + right).astype(np.int64), 4


def _spread_seeds(candidates, xs, ys, energy, count):
    """Up to about ``count`` candidates spread over their bounding box: the best-textured of each grid cell."""
    if candidates.size <= count:
        return candidates
    cells = int(np.ceil(np.sqrt(count)))
    x, y = xs[candidates], ys[candidates]
    span_x = max(x.max() - x.min(), 1)
    span_y = max(y.max() - y.min(), 1)
    cx = np.minimum(((x - x.min()) * cells) // (span_x + 1), cells - 1)
    cy = np.minimum(((y - y.min()) * cells) // (span_y + 1), cells - 1)
    cell = cy * cells + cx
    # within each cell the best texture first; the cell's first entry is its seed
    order = np.lexsort((-np.nan_to_num(energy[candidates], nan=-np.inf), cell))
    first = np.ones(order.size, dtype=bool)
    first[1:] = cell[order][1:] != cell[order][:-1]
    return candidates[order[first]]


def guided_icgn(prep: IcgnReference, coeffs: BSplineCoefficients, search: IntegerSearch, graph: NeighbourGraph, *,
                order: np.ndarray, accept: float, energy: np.ndarray, active: np.ndarray | None = None,
                options: Mapping[str, Any] | None = None,
                repair: Repair | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reliability-guided IC-GN over every point of ``prep`` whose reference status is OK.

    Parameters
    ----------
    prep : dic.subpixel.icgn.IcgnReference
    coeffs : dic.bspline.BSplineCoefficients
        The deformed image, from ``dic.subpixel.icgn.prepare_target``.
    search : callable
        ``search(idx) -> (u, v, status, evaluations)``: the full integer search of points ``idx``.
    graph : (start, index)
        Neighbours (``dic.neighbours.neighbour_graph``) of the prepared points.
    order : ndarray of int, shape (N,)
        Shape-function order per point: 1 affine, 0 translation only.
    accept : float
        Lowest ZNCC at which a converged result is accepted and propagated.
    energy : ndarray of float64, shape (N,)
        Texture per point (``dic.quality.Texture.energy``): seeds are the best-textured.
    active : ndarray of bool, shape (N,), optional
        Points to measure (default all); the others keep their reference status and are skipped.
    options : dict, optional
        IC-GN options (``ICGN_OPTIONS``).
    repair : callable, optional
        ``repair(params, ok) -> outlier mask``: points to solve again from their best neighbour.

    Returns
    -------
    params : ndarray of float64, shape (N, 6)
        (u, ux, uy, v, vx, vy), NaN where not accepted.
    status : ndarray of int8, shape (N,)
    zncc : ndarray of float64, shape (N,)
        Of the accepted result, or of the last attempt.
    iterations, evaluations : ndarray of int64, shape (N,)
        IC-GN iterations and integer-search evaluations spent on each point.
    """
    problem = _Problem(prep, coeffs, order, graph, accept, options)
    todo = problem.status == OK if active is None else (problem.status == OK) & active
    state = np.where(todo, 0, 2).astype(np.int8)
    evaluations = np.zeros(prep.xs.shape[0], dtype=np.int64)
    part, n_parts = regions(prep.xs, prep.ys, np.flatnonzero(state == 0).size)
    seeds_wanted = np.full(n_parts, SEEDS)
    while True:
        # points IC-GN could not reach from a neighbour are searched in full; else new seeds where none reached
        failed = np.flatnonzero((state == 0) & (problem.tries > 0))
        if failed.size:
            _search_and_solve(problem, search, failed, state, evaluations)
        else:
            seeds = _next_seeds(state, part, seeds_wanted, prep.xs, prep.ys, energy)
            if seeds is None:
                break
            accepted = _search_and_solve(problem, search, seeds, state, evaluations)
            _adapt_seed_counts(seeds_wanted, part[seeds], accepted)
        problem.propagate(state, part, n_parts)
    if repair is not None:
        _repair(problem, state, repair)
    problem.params[problem.status != OK] = np.nan
    return problem.params, problem.status, problem.zncc, problem.iterations, evaluations


def _search_and_solve(problem: _Problem, search: IntegerSearch, idx: np.ndarray, state: np.ndarray,
                      evaluations: np.ndarray) -> np.ndarray:
    """The full integer search of points ``idx``, then IC-GN from what it found; returns the accepted mask.

    Points the search found are solved (state 1 if accepted, else 2); the others keep its status (state 2).
    """
    u, v, st, ev = search(idx)
    evaluations[idx] += ev
    starts = np.zeros((idx.size, 6))
    starts[:, 0] = u
    starts[:, 3] = v
    found = st == OK
    accepted = np.zeros(idx.size, dtype=bool)
    if found.any():
        accepted[found] = problem.solve(idx[found], starts[found])
    problem.status[idx[~found]] = st[~found]
    state[idx] = np.where(accepted, 1, 2)
    return accepted


def _next_seeds(state: np.ndarray, part: np.ndarray, seeds_wanted: np.ndarray, xs: np.ndarray, ys: np.ndarray,
                energy: np.ndarray) -> np.ndarray | None:
    """Seeds spread over the pending points of each region (``seeds_wanted`` a region); None: none pending."""
    per_region = []
    for region in range(seeds_wanted.size):
        unreached = np.flatnonzero((state == 0) & (part == region))
        if unreached.size:
            per_region.append(_spread_seeds(unreached, xs, ys, energy, int(seeds_wanted[region])))
    return np.concatenate(per_region) if per_region else None


def _adapt_seed_counts(seeds_wanted: np.ndarray, seed_regions: np.ndarray, accepted: np.ndarray) -> None:
    """Back to ``SEEDS`` in a region where a seed was accepted; twice as many next time where none was."""
    for region in range(seeds_wanted.size):
        mine = seed_regions == region
        if mine.any():
            seeds_wanted[region] = SEEDS if accepted[mine].any() else 2 * seeds_wanted[region]


def propagate(prep: IcgnReference, coeffs: BSplineCoefficients, graph: NeighbourGraph, *, order: np.ndarray,
              accept: float, params: np.ndarray, zncc: np.ndarray, solved: np.ndarray, pending: np.ndarray,
              options: Mapping[str, Any] | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hand the warps of ``solved`` points to ``pending`` ones, most reliable first (one region).

    What a tracker does for points it lost: before a wide search, try IC-GN
    from the best correlated neighbour that was measured in this frame.

    Parameters
    ----------
    prep, coeffs, graph, order, accept, options
        As for ``guided_icgn``.
    params : ndarray of float64, shape (N, 6)
        (u, ux, uy, v, vx, vy) of the solved points (others ignored).
    zncc : ndarray of float64, shape (N,)
        ZNCC of the solved points: the heap order.
    solved, pending : ndarray of bool, shape (N,)
        Points to propagate from, and points to solve.

    Returns
    -------
    accepted : ndarray of bool, shape (N,)
        Pending points solved from a neighbour.
    params, status, zncc, iterations : ndarrays, shape (N, 6), (N,), (N,), (N,)
        The results (rows of the accepted points are new; others as given or NaN).
    """
    problem = _Problem(prep, coeffs, order, graph, accept, options)
    problem.params[:] = params
    problem.zncc[:] = zncc
    state = np.full(prep.xs.shape[0], 2, dtype=np.int8)
    state[solved] = 1
    state[pending & ~solved & (problem.status == OK)] = 0
    before = state == 0
    problem.propagate(state, np.zeros(state.shape[0], dtype=np.int64), 1)
    accepted = before & (state == 1)
    return accepted, problem.params, problem.status, problem.zncc, problem.iterations


def _repair(problem, state, find_outliers) -> None:
    """Solve the points ``find_outliers`` flags again from their best ok neighbour; keep what is better.

    The same propagation as the first pass, with the outliers pending and every other ok point solved.
    """
    ok = problem.status == OK
    outliers = np.flatnonzero(find_outliers(problem.params, ok))
    if not outliers.size:
        return
    before = (problem.params[outliers].copy(), problem.status[outliers].copy(), problem.zncc[outliers].copy())
    repair_state = np.where(ok, 1, 2).astype(np.int8)
    repair_state[outliers] = 0
    problem.tries[outliers] = 0
    problem.propagate(repair_state, np.zeros(state.shape[0], dtype=np.int64), 1)
    better = (repair_state[outliers] == 1) & (problem.zncc[outliers] > np.nan_to_num(before[2], nan=-np.inf))
    # what did not improve goes back to its first result (the quality gates judge it)
    keep_old = outliers[~better]
    problem.params[keep_old] = before[0][~better]
    problem.status[keep_old] = before[1][~better]
    problem.zncc[keep_old] = before[2][~better]
