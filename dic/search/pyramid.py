"""Coarse-to-fine image pyramid for an integer search over a large box.

A stochastic search must land a sample in the narrow zone where the true
correlation peak beats the side lobes (about 25 px^2 for speckle of R = 4 px
and a 21 px subset); its chance falls with the box area, so a swarm tuned at
radius 10 misses at radius 32 (``dic.search.improved_wso`` has the numbers).
Halving the images halves the box side and widens the peak relative to it.
``pyramid_search`` therefore:

1. builds Burt-Adelson pyramids of both images (5-tap binomial filter, then
   every second pixel; level l pixel (i, j) is level 0 pixel (2^l i, 2^l j));
2. runs the given search (the improved WSO) at the top level ``L``, the
   smallest level at which the box radius is at most ``top_radius``, with the
   same subset *side* in coarse pixels (as pyramidal Lucas-Kanade keeps its
   window), so the coarse subset sees 2^L times the area: a more distinctive
   pattern, and the speckle's fine detail averaged away with the noise;
   Where the swarm's best ZNCC stays below ``VERIFY_ZNCC`` (0.7; a correct coarse
   peak correlates well, a stalled swarm does not), the small top box is searched
   exhaustively and the better match kept;
3. at each finer level, climbs (8-neighbour hill climb, ``dic.search._common``)
   from twice the coarser result, which is right to +-1 coarse pixel, to the
   local ZNCC maximum; at level 0 inside the original box.

Near the image border a coarse subset of that side may not fit with its whole
box: there the subset shrinks (to no less than the level-0 subset's footprint
and 7 x 7), and a point that fits no coarse level with the top level's box
starts lower: searched exhaustively at the highest level it fits (its box
there is larger than ``top_radius``), or by the plain search at level 0. The
image must never clip a level's box: a clipped box may exclude the true match,
and the climbs below would then polish a side lobe. Evaluations of every level
count in ``evaluations`` (each costs the same: one subset's ZNCC).

References
----------
P. J. Burt and E. H. Adelson, "The Laplacian pyramid as a compact image code",
IEEE Trans. Commun. 31(4):532-540 (1983), :DOI:`10.1109/TCOM.1983.1095851`.
"""

from collections.abc import Mapping
from types import ModuleType
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic.search import exhaustive
from livedic.dic.search._common import SearchOutputs, begin_point, hill_climb, new_cache, new_outputs
from livedic.dic.status import FLAT_TARGET, OK, OUTSIDE_TARGET

# Smallest subset half-width used on a coarse level (a 7 x 7 subset).
MIN_COARSE_HALF = 3
# A top-level swarm result below this ZNCC is checked by an exhaustive search of the top box (``_verify``).
VERIFY_ZNCC = 0.7


@njit(cache=True, inline="always")
def _mirror(k, n):
    """Index k reflected into [0, n) (whole-sample symmetric, as the B-spline prefilter)."""
    if k < 0:
        k = -k
    elif k >= n:
        k = 2 * (n - 1) - k
    return min(max(k, 0), n - 1)


@njit(cache=True, parallel=True, nogil=True)
def _reduce(image, out):
    """Burt-Adelson REDUCE: 5-tap binomial (1 4 6 4 1)/16 along both axes, every second pixel kept."""
    height, width = image.shape
    oh, ow = out.shape
    rows = np.empty((height, ow), dtype=np.float32)
    inner_lo = 1                              # first output column whose taps 2j-2..2j+2 are all inside
    inner_hi = max(min(ow, (width - 3) // 2 + 1), inner_lo)
    for r in prange(height):
        for j in range(ow):
            c = 2 * j
            if inner_lo <= j < inner_hi:
                rows[r, j] = (image[r, c - 2] + image[r, c + 2] + 4.0 * (image[r, c - 1] + image[r, c + 1])
                              + 6.0 * image[r, c]) * 0.0625
            else:
                rows[r, j] = (image[r, _mirror(c - 2, width)] + image[r, _mirror(c + 2, width)]
                              + 4.0 * (image[r, _mirror(c - 1, width)] + image[r, _mirror(c + 1, width)])
                              + 6.0 * image[r, c]) * 0.0625
    for i in prange(oh):
        c = 2 * i
        if c >= 2 and c + 2 < height:
            for j in range(ow):
                out[i, j] = (rows[c - 2, j] + rows[c + 2, j] + 4.0 * (rows[c - 1, j] + rows[c + 1, j])
                             + 6.0 * rows[c, j]) * 0.0625
        else:
            m2, m1, p1, p2 = _mirror(c - 2, height), _mirror(c - 1, height), _mirror(c + 1, height), \
                _mirror(c + 2, height)
            for j in range(ow):
                out[i, j] = (rows[m2, j] + rows[p2, j] + 4.0 * (rows[m1, j] + rows[p1, j]) + 6.0 * rows[c, j]) * 0.0625


def build_pyramid(image: np.ndarray, levels: int) -> list[np.ndarray]:
    """``[image, image/2, ..., image/2^levels]`` as float32 arrays (level l has ceil(H / 2^l) rows)."""
    out = [np.ascontiguousarray(image, dtype=np.float32)]
    for _ in range(levels):
        previous = out[-1]
        coarse = np.empty(((previous.shape[0] + 1) // 2, (previous.shape[1] + 1) // 2), dtype=np.float32)
        _reduce(previous, coarse)
        out.append(coarse)
    return out


def levels_for(radius: int, top_radius: int, half: int, shape: tuple[int, ...]) -> int:
    """Pyramid levels so that the box radius at the top is <= ``top_radius`` (0: no pyramid).

    Capped so that the top level still holds a subset and its search box.
    """
    levels = 0
    while (radius >> levels) > top_radius:
        levels += 1
    while levels > 0 and min(shape) / 2 ** levels < 2 * half + 1 + 2:
        levels -= 1
    return levels


@njit(cache=True, parallel=True, nogil=True)
def _climb(reference, target, xs, ys, start_u, start_v, ulo, uhi, vlo, vhi, halves, status, out_u, out_v, out_c,
           out_evals, out_calls):
    """Hill climb to the local ZNCC maximum from (start_u, start_v) inside each point's box.

    ``halves`` (N,): subset half-width per point (coarse levels shrink it at the image border).
    """
    for i in prange(xs.shape[0]):
        half = halves[i]
        side = 2 * half + 1
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        u0 = min(max(start_u[i], ulo[i]), uhi[i])
        v0 = min(max(start_v[i], vlo[i]), vhi[i])
        u, v, c = hill_climb(fhat, target, xs[i], ys[i], half, u0, v0, ulo[i], uhi[i], vlo[i], vhi[i], cache, counts)
        out_evals[i] += counts[0]
        out_calls[i] += counts[1]
        if c == -1.0:
            status[i] = FLAT_TARGET
            continue
        out_u[i] = u
        out_v[i] = v
        out_c[i] = c


def min_half(half: int, level: int) -> int:
    """Smallest coarse subset half-width at ``level``: it still covers the level-0 subset, and is >= 3."""
    return max(int(np.ceil(((2 * half + 1) / 2 ** level - 1) / 2)), MIN_COARSE_HALF)


def _geometry(shape, xs, ys, ulo, uhi, vlo, vhi, level, half):
    """A level's point positions, box covering the level-0 box, and the largest subset half-width that fits.

    The half-width is ``half`` where the subset and the whole box fit in the
    level's image, else the largest that does (possibly < 0: nothing fits).
    """
    scale = 1 << level
    height, width = shape
    lx = np.floor(xs / scale + 0.5).astype(np.int64)
    ly = np.floor(ys / scale + 0.5).astype(np.int64)
    lo_u = np.floor_divide(ulo, scale)
    hi_u = -np.floor_divide(-uhi, scale)
    lo_v = np.floor_divide(vlo, scale)
    hi_v = -np.floor_divide(-vhi, scale)
    room = np.minimum.reduce([lx, width - 1 - lx, ly, height - 1 - ly, lx + lo_u, width - 1 - (lx + hi_u),
                              ly + lo_v, height - 1 - (ly + hi_v)])
    return lx, ly, lo_u, hi_u, lo_v, hi_v, np.minimum(room, half)


def pyramid_search(module: ModuleType, reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray,
                   ulo: np.ndarray, uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray,
                   seed: np.uint64, params: Mapping[str, Any], outputs: SearchOutputs,
                   centre: tuple[np.ndarray, np.ndarray], *, levels: int, top_radius: int) -> None:
    """Coarse-to-fine search (module notes): ``module.run`` at the top level, hill climbs below.

    Same contract as a search module's ``run`` (boxes, status and outputs of
    level 0), plus the number of ``levels`` (>= 1) and the ``top_radius`` the
    search proper is used up to.
    """
    out_u, out_v, out_c, out_evals, out_calls = outputs
    refs = build_pyramid(reference, levels)
    defs = build_pyramid(deformed, levels)
    todo = np.flatnonzero(status == OK)
    # per point: the highest level where a subset covering the level-0 one fits with the whole box;
    # an image edge must not clip the box, or the true match could lie outside it
    top = np.zeros(xs.shape[0], dtype=np.int64)
    geometry = {}
    for level in range(1, levels + 1):
        geometry[level] = _geometry(refs[level].shape, xs, ys, ulo, uhi, vlo, vhi, level, half)
        fits = geometry[level][6] >= min_half(half, level)
        top[todo[fits[todo]]] = level
    candidate_u = np.zeros(xs.shape[0], dtype=np.int64)
    candidate_v = np.zeros(xs.shape[0], dtype=np.int64)
    for level in range(levels, 0, -1):
        lx, ly, lo_u, hi_u, lo_v, hi_v, halves = geometry[level]
        ref, tar = refs[level], defs[level]
        start = todo[top[todo] == level]
        # the search proper where its box is small; a point that the image edge kept from the top
        # level has a larger box here, and is searched exhaustively (rare: near the border only)
        small = np.maximum(hi_u - lo_u, hi_v - lo_v) <= 2 * top_radius
        for h in np.unique(halves[start]):
            for use_module in (True, False):
                group = start[(halves[start] == h) & (small[start] == use_module)]
                if not group.size:
                    continue
                st = np.zeros(group.size, dtype=np.int8)
                level_out = new_outputs(group.size)
                scale = 1 << level
                centre_level = (np.floor(centre[0][group] / scale + 0.5).astype(np.int64),
                                np.floor(centre[1][group] / scale + 0.5).astype(np.int64))
                (module if use_module else exhaustive).run(
                    ref, tar, lx[group], ly[group], lo_u[group], hi_u[group], lo_v[group], hi_v[group], int(h), st,
                    seed, params, level_out, centre_level)
                if use_module:
                    _verify(ref, tar, lx, ly, lo_u, hi_u, lo_v, hi_v, int(h), group, st, level_out)
                _take(level_out, st, group, candidate_u, candidate_v, out_evals, out_calls, top)
        below = todo[top[todo] > level]
        if below.size:
            # the coarser answer is right to +-1 coarse pixel: climb from twice it
            level_out = new_outputs(below.size)
            st = np.where(halves[below] >= 1, OK, OUTSIDE_TARGET).astype(np.int8)
            _climb(ref, tar, lx[below], ly[below], 2 * candidate_u[below], 2 * candidate_v[below], lo_u[below],
                   hi_u[below], lo_v[below], hi_v[below], np.maximum(halves[below], 1), st, *level_out)
            _take(level_out, st, below, candidate_u, candidate_v, out_evals, out_calls, top)
    # level 0: points that never fitted a coarse level (or failed there) run the plain search; the others climb
    plain = todo[top[todo] == 0]
    refined = todo[top[todo] > 0]
    for idx, run in ((plain, "plain"), (refined, "climb")):
        if not idx.size:
            continue
        st = status[idx].copy()
        part = new_outputs(idx.size)
        if run == "plain":
            module.run(reference, deformed, xs[idx], ys[idx], ulo[idx], uhi[idx], vlo[idx], vhi[idx], half, st,
                       seed, params, part, (centre[0][idx], centre[1][idx]))
        else:
            _climb(reference, deformed, xs[idx], ys[idx], 2 * candidate_u[idx], 2 * candidate_v[idx], ulo[idx],
                   uhi[idx], vlo[idx], vhi[idx], np.full(idx.size, half, dtype=np.int64), st, *part)
        part_u, part_v, part_c, part_evals, part_calls = part
        out_evals[idx] += part_evals
        out_calls[idx] += part_calls
        status[idx] = st
        done = st == OK
        out_u[idx[done]] = part_u[done]
        out_v[idx[done]] = part_v[done]
        out_c[idx[done]] = part_c[done]


def _verify(ref, tar, lx, ly, lo_u, hi_u, lo_v, hi_v, half, group, status, level_out) -> None:
    """Search exhaustively the (small) top box of the points where the swarm's best ZNCC is below ``VERIFY_ZNCC``.

    A coarse level's correct peak correlates well (its noise is averaged away); a
    swarm that stalled on a side lobe ends far below. Measured on the radius study:
    1 search in 37,607 at radius 48 (a 9 x 9 subset on a 32 x 32 px level of the
    R = 2 pattern) ended on ZNCC 0.32 where the true coarse peak has 0.95, and the
    whole search missed. The check costs at most (2 top_radius + 1)^2 evaluations,
    for the few points it concerns; the better match is kept.
    """
    u, v, zncc, evals, calls = level_out
    doubtful = np.flatnonzero((status == OK) & ~(zncc >= VERIFY_ZNCC))
    if not doubtful.size:
        return
    idx = group[doubtful]
    st = np.zeros(idx.size, dtype=np.int8)
    check = new_outputs(idx.size)
    exhaustive.run(ref, tar, lx[idx], ly[idx], lo_u[idx], hi_u[idx], lo_v[idx], hi_v[idx], half, st, 0, {}, check,
                   None)
    better = (st == OK) & (check[2] > zncc[doubtful])
    for mine, theirs in zip((u, v, zncc), check[:3]):
        mine[doubtful[better]] = theirs[better]
    evals[doubtful] += check[3]
    calls[doubtful] += check[4]


def _take(level_out, level_status, idx, candidate_u, candidate_v, out_evals, out_calls, top) -> None:
    """Keep a level's answers; points that failed there drop to a plain search at level 0."""
    u, v, _, evals, calls = level_out
    out_evals[idx] += evals
    out_calls[idx] += calls
    good = level_status == OK
    candidate_u[idx[good]] = u[good]
    candidate_v[idx[good]] = v[good]
    top[idx[~good]] = 0
