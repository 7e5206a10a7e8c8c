"""Improved White Shark Optimizer: the paper's integer-pixel search.

LI Jun, LEI Zongyu, CAI Zizheng, FU Haibo, "DIC displacement measurement method
based on the improved white shark optimizer", Laser Technology 49(3):368 (2025),
DOI 10.7510/jgjs.issn.1001-3806.2025.03.008, sections 2.1-2.5 (Eqs. 6-11).

A simplified WSO over continuous displacements (u, v) in the search box, fitness
``ZNCC(floor(x + 0.5))`` (maximised):

1. **Tent-map initialisation** (Eq. 6, a0 = ``tent_a`` = 0.5): one chaotic
   sequence per dimension, ``x = lo + z (hi - lo)``. In float64 the a0 = 0.5 map
   is a bit shift that collapses to exactly 0 (or 1) within ~55 steps, so a value
   within 1e-9 of 0 or 1, or equal to its predecessor, is replaced by a fresh
   U(0.05, 0.95) draw (algorithms.md section 2). Velocities start at 0.
2. **Velocity** (Eq. 9): ``v <- mu [v + p1 (gbest - x) c1 + p2 (pbest_i - x) c2]``,
   mu = 0.7, c1, c2 ~ U(0, 1) per dimension, the shark's *own* pbest, and
   ``p1 = p_max + (p_max - p_min) e^{-(4k/K)^2}``, ``p2 = p_min + (p_max - p_min) e^{-(4k/K)^2}``
   (Eq. 11, p_min = 0.5, p_max = 1.5), k = 1..K.
3. **Position** (Eq. 10): ``x <- x + K_t v`` with the dynamic nonlinear time factor
   ``K_t = 10 / (a1 + exp(a2 (2k/K - 1))) + 0.5`` (Eq. 7, a1 = 6.25, a2 = 5:
   2.10 at k = 0, 1.88 at K/2, 0.56 at K). The paper does not say how sharks
   are kept in the box; ``boundary`` picks the rule for a coordinate that leaves
   it: ``"random"`` (default) re-draws it uniformly in the box with velocity 0,
   ``"reflect"`` mirrors it and reverses the velocity, ``"clip"`` puts it on the
   wall with velocity 0. Measured (see below) "random" is best: with p1 = 2.5
   and K_t = 2.1 the early swarm overshoots a lot, "clip" then parks sharks on
   the walls and corners, which become attractors (92 % success).
4. **Termination** (Eq. 8): stop when the sample standard deviation (n - 1, as
   Eq. 8 writes it; n vs n - 1 changes it by 2.6 % at n = 20, immaterial) of
   the population's fitness is below ``sd_tol`` (0.001), or after K iterations.
   ``sd_of="current"`` (default) takes the fitness at the current rounded
   positions, ``"pbest"`` that of the personal bests. Either rarely fires: the
   swarm only gathers in the last ~10 % of the schedule (p1, p2, K_t are
   functions of k / K), and the pbest variant only cut calls 975 -> 863 at the
   same distinct evaluations. **Addition** (not in the paper): ``stall`` = T
   stops after T iterations without a gbest improvement (default 5; 0 = off).
5. **Polish** -- the paper's "three-step search" (section 2.4, Fig. 4). What the
   paper describes is *not* Koga's three-step search (steps 4, 2, 1) but an
   8-neighbour hill climb (block-based gradient descent, BBGDS-like): from the
   start evaluate the 8 neighbours, move to the best while it beats the
   centre, stop when the centre is best (``polish_method="hill-climb"``,
   default); ``"three-step"`` runs Koga's 4, 2, 1 steps first, then the climb.
   Reading "the global optimum still cannot be found in individual cases" as
   a polish that must rescue a trapped swarm, it climbs from up to
   ``polish_starts`` distinct starts, best first, and keeps the best local
   maximum: ``polish_from="evaluated"`` (default) takes the best positions
   evaluated so far (the point's cache), ``"pbest"`` the personal bests; a
   start within ``basin_sep`` px (Chebyshev) of an earlier start or climb
   result is skipped. From pbests it changes nothing (by the end all pbests
   sit in the gbest basin). The result is always a local maximum.
   ``PAPER_LITERAL`` holds the options of the literal reading (no stall, one
   climb from gbest), the defaults before these levers.

Population size, K, the box rule, the stall and polish levers and the image pyramid (``pyramid=True``,
``top_radius=3``; not in the paper: the swarm searches the box at the pyramid level where its radius is at
most ``top_radius``, hill climbs refine it level by level) were chosen by measurement: the figures, and
which of the paper's claims hold, are in docs/guide/measure.md ("The improved WSO: choices and
measurements"); ``livedic bench paper`` measures them again.

The swarm update is written ask/tell style (``iwso_init``, ``iwso_move``,
``iwso_tell``, ``fitness_sd``) so the same code also searches the 0.2 px lattice
of the improved surface fit (``dic.subpixel.improved_surface_fit``).
"""

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic._random import uniform, new_state
from livedic.dic.correlation import round_half_up
from livedic.dic.method_options import is_bool, is_int_at_least, is_real_in
from livedic.dic.search._common import SearchOutputs, begin_point, finish_point, fitness, hill_climb, new_cache

DEFAULTS = {"population": 20, "iterations": 50, "mu": 0.7, "p_min": 0.5, "p_max": 1.5,
            "a1": 6.25, "a2": 5.0, "sd_tol": 1e-3, "tent_a": 0.5, "polish": True,
            "boundary": "random", "sd_of": "current", "stall": 5, "v_max": 0.0,
            "polish_method": "hill-climb", "polish_starts": 5, "polish_from": "evaluated", "basin_sep": 3,
            "pyramid": True, "top_radius": 3}
# The defaults before the stall / multi-start polish / pyramid levers (the paper read literally).
PAPER_LITERAL = {"stall": 0, "polish_starts": 1, "polish_from": "pbest", "basin_sep": 2, "pyramid": False}
CHECKS = {
    "population": (is_int_at_least(1), "an integer >= 1"),
    "iterations": (is_int_at_least(0), "an integer >= 0"),
    "mu": (is_real_in(0.0, 2.0, low_open=True), "a number in (0, 2]"),
    "p_min": (is_real_in(0.0, 10.0), "a number in [0, 10]"),
    "p_max": (is_real_in(0.0, 10.0), "a number in [0, 10]"),
    "a1": (is_real_in(0.0, 1e6, low_open=True), "a positive number"),
    "a2": (is_real_in(0.0, 1e3), "a number >= 0"),
    "sd_tol": (is_real_in(0.0, 1.0), "a number in [0, 1] (0: never stop early)"),
    "tent_a": (is_real_in(0.0, 1.0, low_open=True, high_open=True), "a number in (0, 1)"),
    "polish": (is_bool, "True or False"),
    "boundary": (lambda v: v in _BOUNDARY, "one of 'clip', 'reflect', 'random'"),
    "sd_of": (lambda v: v in _SD_OF, "one of 'current', 'pbest'"),
    "stall": (is_int_at_least(0), "an integer >= 0 (0: off)"),
    "v_max": (is_real_in(0.0, 1.0), "a fraction of the box width in [0, 1] (0: no clamp)"),
    "polish_method": (lambda v: v in _POLISH, "one of 'hill-climb', 'three-step'"),
    "polish_starts": (is_int_at_least(1), "an integer >= 1"),
    "polish_from": (lambda v: v in _POLISH_FROM, "one of 'pbest', 'evaluated'"),
    "basin_sep": (is_int_at_least(0), "an integer >= 0 (pixels)"),
    "pyramid": (is_bool, "True or False"),
    "top_radius": (is_int_at_least(2), "an integer >= 2 (pixels)"),
}
_BOUNDARY: dict[str, int] = {"clip": 0, "reflect": 1, "random": 2}
_SD_OF: dict[str, int] = {"current": 0, "pbest": 1}
_POLISH: dict[str, int] = {"hill-climb": 0, "three-step": 1}
_POLISH_FROM: dict[str, int] = {"pbest": 0, "evaluated": 1}


@njit(cache=True)
def tent_sequence(out, rng, tent_a):
    """Fill ``out`` (n,) with successive Tent-map values in (0, 1), guarded against collapse."""
    z = 0.05 + 0.9 * uniform(rng)
    prev = -1.0
    for i in range(out.shape[0]):
        if z <= tent_a:
            z = z / tent_a
        else:
            z = (1.0 - z) / (1.0 - tent_a)
        if z < 1e-9 or z > 1.0 - 1e-9 or z == prev:
            z = 0.05 + 0.9 * uniform(rng)
        out[i] = z
        prev = z


@njit(cache=True)
def iwso_init(pos, vel, lo, hi, rng, tent_a):
    """Tent-map positions in the box [lo, hi] (2,), zero velocities; pos, vel (n, 2)."""
    z = np.empty(pos.shape[0])
    for d in range(2):
        tent_sequence(z, rng, tent_a)
        for i in range(pos.shape[0]):
            pos[i, d] = lo[d] + z[i] * (hi[d] - lo[d])
            vel[i, d] = 0.0


@njit(cache=True)
def iwso_move(pos, vel, pbest, g, k, n_iter, lo, hi, mu, p_min, p_max, a1, a2, boundary, rng):
    """One velocity (Eq. 9, 11) and position (Eq. 10, 7) update at iteration k (1..K).

    ``boundary``: 0 clip and stop (absorbing), 1 reflect (velocity reversed),
    2 re-draw the coordinate uniformly in the box (velocity 0).
    """
    iwso_move_clamped(pos, vel, pbest, g, k, n_iter, lo, hi, mu, p_min, p_max, a1, a2, boundary, np.inf, rng)


@njit(cache=True)
def iwso_move_clamped(pos, vel, pbest, g, k, n_iter, lo, hi, mu, p_min, p_max, a1, a2, boundary, vmax, rng):
    """``iwso_move`` with each velocity component clamped to [-vmax, vmax] (inf: no clamp)."""
    e = np.exp(-(4.0 * k / n_iter) ** 2)
    p1 = p_max + (p_max - p_min) * e
    p2 = p_min + (p_max - p_min) * e
    kt = 10.0 / (a1 + np.exp(a2 * (2.0 * k / n_iter - 1.0))) + 0.5
    for i in range(pos.shape[0]):
        for d in range(2):
            c1 = uniform(rng)
            c2 = uniform(rng)
            vd = mu * (vel[i, d] + p1 * (pbest[g, d] - pos[i, d]) * c1 + p2 * (pbest[i, d] - pos[i, d]) * c2)
            if vd > vmax:
                vd = vmax
            elif vd < -vmax:
                vd = -vmax
            xd = pos[i, d] + kt * vd
            if xd < lo[d] or xd > hi[d]:
                if boundary == 1:
                    xd = 2.0 * lo[d] - xd if xd < lo[d] else 2.0 * hi[d] - xd
                    xd = min(max(xd, lo[d]), hi[d])
                    vd = -vd
                elif boundary == 2:
                    xd = lo[d] + uniform(rng) * (hi[d] - lo[d])
                    vd = 0.0
                else:
                    xd = min(max(xd, lo[d]), hi[d])
                    vd = 0.0
            pos[i, d] = xd
            vel[i, d] = vd


@njit(cache=True)
def iwso_tell(pos, fit, pbest, pfit, g):
    """Update personal bests from ``fit`` (n,) at ``pos``; return the index of the global best."""
    for i in range(pos.shape[0]):
        if fit[i] > pfit[i]:
            pfit[i] = fit[i]
            pbest[i, 0] = pos[i, 0]
            pbest[i, 1] = pos[i, 1]
            if fit[i] > pfit[g]:
                g = i
    return g


@njit(cache=True)
def fitness_sd(fit):
    """Sample standard deviation (n - 1) of the population fitness (Eq. 8); 0 for n = 1."""
    n = fit.shape[0]
    if n < 2:
        return 0.0
    m = 0.0
    for i in range(n):
        m += fit[i]
    m /= n
    s = 0.0
    for i in range(n):
        s += (fit[i] - m) ** 2
    return np.sqrt(s / (n - 1))


@njit(cache=True)
def three_step(fhat, target, x, y, half, u, v, ulo, uhi, vlo, vhi, cache, counts):
    """Koga's three-step search from (u, v): steps 4, 2, 1, each moving to the best of the
    centre and its 8 neighbours at that step (clipped to the box); returns (u, v, zncc)."""
    best = fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts)
    step = 4
    while step >= 1:
        bu = u
        bv = v
        bc = best
        for dv in range(-1, 2):
            nv = v + dv * step
            if nv < vlo or nv > vhi:
                continue
            for du in range(-1, 2):
                nu = u + du * step
                if (du == 0 and dv == 0) or nu < ulo or nu > uhi:
                    continue
                c = fitness(fhat, target, x, y, half, nu, nv, ulo, vlo, cache, counts)
                if c > bc:
                    bu = nu
                    bv = nv
                    bc = c
        u = bu
        v = bv
        best = bc
        step //= 2
    return u, v, best


@njit(cache=True)
def _near(u, v, us, vs, m, sep):
    for j in range(m):
        if abs(u - us[j]) <= sep and abs(v - vs[j]) <= sep:
            return True
    return False


@njit(cache=True)
def _polish(fhat, target, x, y, half, ulo, uhi, vlo, vhi, pbest, pfit, g, method, starts, source, sep,
            cache, counts):
    """Polish from up to ``starts`` distinct candidates (best first): the rounded personal
    bests (source 0) or the best evaluated positions of the cache (source 1); a candidate
    within ``sep`` px (Chebyshev) of an earlier start or result is skipped. Returns the
    best local maximum found (u, v, zncc)."""
    n = pfit.shape[0]
    if source == 0:
        m = n
        cu = np.empty(m, dtype=np.int64)
        cv = np.empty(m, dtype=np.int64)
        cf = np.empty(m)
        for i in range(n):
            cu[i] = round_half_up(pbest[i, 0])
            cv[i] = round_half_up(pbest[i, 1])
            cf[i] = pfit[i]
        # the global best first even on ties
        cf[g] = np.inf
    else:
        m = 0
        for r in range(cache.shape[0]):
            for c in range(cache.shape[1]):
                if not np.isnan(cache[r, c]):
                    m += 1
        cu = np.empty(m, dtype=np.int64)
        cv = np.empty(m, dtype=np.int64)
        cf = np.empty(m)
        m = 0
        for r in range(cache.shape[0]):
            for c in range(cache.shape[1]):
                if not np.isnan(cache[r, c]):
                    cu[m] = ulo + c
                    cv[m] = vlo + r
                    cf[m] = cache[r, c]
                    m += 1
    order = np.argsort(-cf)
    us = np.empty(2 * starts, dtype=np.int64)
    vs = np.empty(2 * starts, dtype=np.int64)
    nused = 0
    done = 0
    bu = cu[order[0]]
    bv = cv[order[0]]
    bc = -np.inf
    for t in range(m):
        if done >= starts:
            break
        k = order[t]
        u0 = cu[k]
        v0 = cv[k]
        if _near(u0, v0, us, vs, nused, sep):
            continue
        if method == 1:
            u1, v1, c1 = three_step(fhat, target, x, y, half, u0, v0, ulo, uhi, vlo, vhi, cache, counts)
            u1, v1, c1 = hill_climb(fhat, target, x, y, half, u1, v1, ulo, uhi, vlo, vhi, cache, counts)
        else:
            u1, v1, c1 = hill_climb(fhat, target, x, y, half, u0, v0, ulo, uhi, vlo, vhi, cache, counts)
        us[nused] = u0
        vs[nused] = v0
        us[nused + 1] = u1
        vs[nused + 1] = v1
        nused += 2
        done += 1
        if c1 > bc:
            bu = u1
            bv = v1
            bc = c1
    return bu, bv, bc


@njit(cache=True)
def _search_one(fhat, target, x, y, half, ulo, uhi, vlo, vhi, n, n_iter, mu, p_min, p_max, a1, a2, sd_tol,
                tent_a, polish, boundary, sd_of, stall, vmax, method, starts, source, sep, rng, cache, counts):
    lo = np.array((ulo, vlo), dtype=np.float64)
    hi = np.array((uhi, vhi), dtype=np.float64)
    pos = np.empty((n, 2))
    vel = np.empty((n, 2))
    pbest = np.empty((n, 2))
    pfit = np.empty(n)
    fit = np.empty(n)
    iwso_init(pos, vel, lo, hi, rng, tent_a)
    g = 0
    for i in range(n):
        fit[i] = fitness(fhat, target, x, y, half, round_half_up(pos[i, 0]), round_half_up(pos[i, 1]),
                         ulo, vlo, cache, counts)
        pfit[i] = fit[i]
        pbest[i, 0] = pos[i, 0]
        pbest[i, 1] = pos[i, 1]
        if fit[i] > fit[g]:
            g = i
    # Once every position of the box has been evaluated the best of them is known:
    # iterating further cannot change the answer (small tracking boxes get here fast).
    box_size = (uhi - ulo + 1) * (vhi - vlo + 1)
    still = 0
    for k in range(1, n_iter + 1):
        if counts[0] >= box_size:
            break
        before = pfit[g]
        iwso_move_clamped(pos, vel, pbest, g, k, n_iter, lo, hi, mu, p_min, p_max, a1, a2, boundary, vmax, rng)
        for i in range(n):
            fit[i] = fitness(fhat, target, x, y, half, round_half_up(pos[i, 0]), round_half_up(pos[i, 1]),
                             ulo, vlo, cache, counts)
        g = iwso_tell(pos, fit, pbest, pfit, g)
        if sd_of == 0:
            sd = fitness_sd(fit)
        else:
            sd = fitness_sd(pfit)
        if sd < sd_tol:
            break
        if pfit[g] > before:
            still = 0
        else:
            still += 1
            if stall > 0 and still >= stall:
                break
    if polish:
        return _polish(fhat, target, x, y, half, ulo, uhi, vlo, vhi, pbest, pfit, g, method, starts, source, sep,
                       cache, counts)
    return round_half_up(pbest[g, 0]), round_half_up(pbest[g, 1]), pfit[g]


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, ulo, uhi, vlo, vhi, half, seed, n, n_iter, mu, p_min, p_max, a1, a2,
           sd_tol, tent_a, polish, boundary, sd_of, stall, vmax, method, starts, source, sep, status,
           out_u, out_v, out_c, out_evals, out_calls):
    """Search every point; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        rng = new_state(seed, i)
        # velocity clamp as a fraction of the box width (0: none)
        vm = np.inf
        if vmax > 0.0:
            vm = vmax * max(uhi[i] - ulo[i], vhi[i] - vlo[i], 1)
        u, v, c = _search_one(fhat, target, xs[i], ys[i], half, ulo[i], uhi[i], vlo[i], vhi[i], n, n_iter, mu,
                              p_min, p_max, a1, a2, sd_tol, tent_a, polish, boundary, sd_of, stall, vm, method,
                              starts, source, sep, rng, cache, counts)
        finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls)


def run(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, ulo: np.ndarray,
        uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray, seed: np.uint64,
        params: Mapping[str, Any], outputs: SearchOutputs, centre: tuple[np.ndarray, np.ndarray]) -> None:
    p = params
    _batch(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, half, seed, int(p["population"]),
           int(p["iterations"]), float(p["mu"]), float(p["p_min"]), float(p["p_max"]), float(p["a1"]),
           float(p["a2"]), float(p["sd_tol"]), float(p["tent_a"]), bool(p["polish"]), _BOUNDARY[p["boundary"]],
           _SD_OF[p["sd_of"]], int(p["stall"]), float(p["v_max"]), _POLISH[p["polish_method"]],
           int(p["polish_starts"]), _POLISH_FROM[p["polish_from"]], int(p["basin_sep"]), status, *outputs)
