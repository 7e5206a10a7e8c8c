"""Neighbours of measurement points: which points are next to which.

Reliability-guided propagation hands a point's deformation to its neighbours,
and the normalised median test compares a point with them, so both need, per
point, its nearest neighbours. Points may form a regular grid (then the 8
nearest are the grid's 8-neighbourhood) or any scattered set (a points file).

``neighbour_graph`` returns the neighbours in compressed-row form: the
neighbours of point ``i`` are ``index[start[i]:start[i + 1]]``, nearest first.
Neighbours are at most ``max_distance`` away (default 2.5 times the typical
nearest-neighbour spacing), so points across a wide gap (a hole, the far edge
of a specimen) are not neighbours: propagation must not jump it, and a median
of far-away values says nothing about a point.
"""

import numpy as np
import numpy.typing as npt
from numba import njit

DEFAULT_NEIGHBOURS = 8
# max_distance in units of the typical nearest-neighbour spacing: keeps a grid's diagonal
# neighbours (1.41 steps) and the next ring's axis neighbours (2 steps), not more.
SPACING_REACH = 2.5
_SPACING_SAMPLE = 64

NeighbourGraph = tuple[np.ndarray, np.ndarray]
"""(start, index): point i's neighbours are ``index[start[i]:start[i + 1]]`` (see ``neighbour_graph``)."""


@njit(cache=True)
def _nearest_distance_sample(x, y, sample):
    """Distance from each sampled point to its nearest other point (brute force over all points)."""
    out = np.empty(sample.shape[0])
    for s in range(sample.shape[0]):
        i = sample[s]
        best = np.inf
        for j in range(x.shape[0]):
            if j == i:
                continue
            d = (x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2
            if d < best and d > 0.0:
                best = d
        out[s] = np.sqrt(best)
    return out


def typical_spacing(points: npt.ArrayLike) -> float:
    """Typical distance between neighbouring ``points`` (N, 2); inf for fewer than 2 distinct points.

    The larger of the median nearest-neighbour distance (on a sample of the
    points) and the mean spacing ``sqrt(area / N)`` of their bounding box: equal
    on a grid, while for scattered points the nearest neighbour is often much
    closer than the typical one.
    """
    xy = np.asarray(points, dtype=np.float64)
    if xy.shape[0] < 2:
        return np.inf
    extent = xy.max(axis=0) - xy.min(axis=0)
    mean_spacing = float(np.sqrt(max(extent[0], 1.0) * max(extent[1], 1.0) / xy.shape[0]))
    step = max(xy.shape[0] // _SPACING_SAMPLE, 1)
    sample = np.arange(0, xy.shape[0], step, dtype=np.int64)
    distances = _nearest_distance_sample(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]), sample)
    finite = distances[np.isfinite(distances)]
    return max(float(np.median(finite)), mean_spacing) if finite.size else np.inf


@njit(cache=True)
def _graph(x, y, k, reach, cell, start, index):
    n = x.shape[0]
    x0 = x.min()
    y0 = y.min()
    ncx = int((x.max() - x0) / cell) + 1
    ncy = int((y.max() - y0) / cell) + 1
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    count = np.zeros(ncx * ncy + 1, dtype=np.int64)
    for i in range(n):
        cx[i] = int((x[i] - x0) / cell)
        cy[i] = int((y[i] - y0) / cell)
        count[cy[i] * ncx + cx[i] + 1] += 1
    for c in range(ncx * ncy):
        count[c + 1] += count[c]
    members = np.empty(n, dtype=np.int64)
    fill = count.copy()
    for i in range(n):
        c = cy[i] * ncx + cx[i]
        members[fill[c]] = i
        fill[c] += 1
    best_d = np.empty(k)
    best_j = np.empty(k, dtype=np.int64)
    reach2 = reach * reach
    total = 0
    for i in range(n):
        found = 0
        for gy in range(max(cy[i] - 1, 0), min(cy[i] + 2, ncy)):
            for gx in range(max(cx[i] - 1, 0), min(cx[i] + 2, ncx)):
                c = gy * ncx + gx
                for m in range(count[c], count[c + 1]):
                    j = members[m]
                    if j == i:
                        continue
                    d = (x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2
                    if d > reach2:
                        continue
                    # insertion into the sorted k best (ties: lower index first, for determinism)
                    if found < k:
                        pos = found
                        found += 1
                    elif d < best_d[k - 1] or (d == best_d[k - 1] and j < best_j[k - 1]):
                        pos = k - 1
                    else:
                        continue
                    while pos > 0 and (best_d[pos - 1] > d or (best_d[pos - 1] == d and best_j[pos - 1] > j)):
                        best_d[pos] = best_d[pos - 1]
                        best_j[pos] = best_j[pos - 1]
                        pos -= 1
                    best_d[pos] = d
                    best_j[pos] = j
        for m in range(found):
            index[total + m] = best_j[m]
        total += found
        start[i + 1] = total
    return total


def neighbour_graph(points: npt.ArrayLike, *, k: int = DEFAULT_NEIGHBOURS,
                    max_distance: float | None = None) -> NeighbourGraph:
    """The ``k`` nearest neighbours of every point, within ``max_distance``.

    Parameters
    ----------
    points : array_like, shape (N, 2)
        (x, y) positions.
    k : int
        Neighbours kept per point (nearest first; fewer where fewer are in reach).
    max_distance : float, optional
        Farthest neighbour, px. Default ``SPACING_REACH`` (2.5) times the typical
        nearest-neighbour spacing (``typical_spacing``).

    Returns
    -------
    start : ndarray of int64, shape (N + 1,)
    index : ndarray of int64, shape (start[-1],)
        Neighbours of point ``i``: ``index[start[i]:start[i + 1]]``, nearest first.

    Examples
    --------
    >>> xy = np.array([(x, y) for y in range(3) for x in range(3)], dtype=float) * 10
    >>> start, index = neighbour_graph(xy)
    >>> sorted(index[start[4]:start[5]].tolist())     # the centre sees all 8 others
    [0, 1, 2, 3, 5, 6, 7, 8]
    >>> index[start[0]:start[1]].tolist()[:3]          # a corner: 2 at 10 px, then the diagonal
    [1, 3, 4]
    """
    xy = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    n = xy.shape[0]
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k must be a positive integer, got {k!r}")
    if max_distance is None:
        max_distance = SPACING_REACH * typical_spacing(xy)
    start = np.zeros(n + 1, dtype=np.int64)
    if n < 2 or not np.isfinite(max_distance) or max_distance <= 0:
        return start, np.zeros(0, dtype=np.int64)
    index = np.empty(n * int(k), dtype=np.int64)
    total = _graph(np.ascontiguousarray(xy[:, 0]), np.ascontiguousarray(xy[:, 1]), int(k), float(max_distance),
                   float(max_distance), start, index)
    return start, index[:total].copy()
