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
   Eq. 8 writes it) of the current population's fitness is below ``sd_tol``
   (0.001), or after K iterations. Checked after each iteration's evaluation.
5. **Polish** -- the paper's "three-step search" (section 2.4, Fig. 4). What the
   paper describes is *not* Koga's three-step search (steps 4, 2, 1) but an
   8-neighbour hill climb (block-based gradient descent, BBGDS-like): from the
   rounded gbest evaluate the 8 neighbours, move to the best while it beats the
   centre, stop when the centre is best. It turns "near the peak" into "on the
   peak"; with it the returned position is always a local maximum.

Population size and K are not stated in the paper; the defaults n = 20, K = 50
were chosen by measurement. Paper setting (256 x 256 speckle, 1000 speckles,
R = 4, noise free, 8 bit), radius 16, shifts 1..10 px (10 along x, 10 in random
directions), 500 points each, success = same integer as the exhaustive search,
CPU time per point (2 threads, shared machine), same run:

=================  ========  =======  ========  ===========  =========
method             success   evals    calls     us / point   (subset)
=================  ========  =======  ========  ===========  =========
exhaustive         100 %     1089     1089      612          21
coarse-fine s=3    100 %     145      146       89           21
PSO                97.6 %    176      1020      147          21
WSO (code, fixed)  99.62 %   265      978       227          21
WSO (gbest bug)    7.7 %     265      978       232          21
WSO (paper form)   90.6 %    267      1020      220          21
improved WSO       99.65 %   272      975       196          21
 ... boundary clip 92.1 %    309      1002      216          21
 ... reflect       99.85 %   396      1028      267          21
 ... n=40, K=30    99.86 %   346      1249      245          21
improved WSO       99.99 %   264      969       328          31
WSO (code, fixed)  99.92 %   250      985       344          31
PSO                99.33 %   170      1020      227          31
coarse-fine s=3    100 %     145      146       157          31
=================  ========  =======  ========  ===========  =========

So the improved WSO is the most reliable of the swarms, but on this landscape
(subset side lobes up to ZNCC ~0.85 with 21 px subsets) it does not reach the
paper's 100 %, and it needs more distinct evaluations than coarse-fine at
step 3 (an exact cover of a peak whose half-width exceeds 2 px) and about as
many as the original WSO; it is cheaper than the WSO only at radius >= 24 and
than coarse-fine at radius >= 30, where its success drops to 94-98 %. The
adaptive stop rarely fires before K: the population only aggregates in the
last ~10 % of the schedule, since p1, p2 and K_t are functions of k / K.

The swarm update is written ask/tell style (``iwso_init``, ``iwso_move``,
``iwso_tell``, ``fitness_sd``) so the same code also searches the 0.2 px lattice
of the improved surface fit (``dic.subpixel.improved_surface_fit``).
"""

import numpy as np
from numba import njit, prange

from dic._random import uniform, new_state
from dic.search._common import (begin_point, finish_point, fitness, hill_climb, is_bool, is_int_at_least,
                                is_real_in, new_cache, round_half_up)

DEFAULTS = {"population": 20, "iterations": 50, "mu": 0.7, "p_min": 0.5, "p_max": 1.5,
            "a1": 6.25, "a2": 5.0, "sd_tol": 1e-3, "tent_a": 0.5, "polish": True,
            "boundary": "random"}
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
}
_BOUNDARY = {"clip": 0, "reflect": 1, "random": 2}


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
    e = np.exp(-(4.0 * k / n_iter) ** 2)
    p1 = p_max + (p_max - p_min) * e
    p2 = p_min + (p_max - p_min) * e
    kt = 10.0 / (a1 + np.exp(a2 * (2.0 * k / n_iter - 1.0))) + 0.5
    for i in range(pos.shape[0]):
        for d in range(2):
            c1 = uniform(rng)
            c2 = uniform(rng)
            vd = mu * (vel[i, d] + p1 * (pbest[g, d] - pos[i, d]) * c1 + p2 * (pbest[i, d] - pos[i, d]) * c2)
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
def _search_one(fhat, target, x, y, half, ulo, uhi, vlo, vhi, n, n_iter, mu, p_min, p_max, a1, a2, sd_tol,
                tent_a, polish, boundary, rng, cache, counts):
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
    for k in range(1, n_iter + 1):
        iwso_move(pos, vel, pbest, g, k, n_iter, lo, hi, mu, p_min, p_max, a1, a2, boundary, rng)
        for i in range(n):
            fit[i] = fitness(fhat, target, x, y, half, round_half_up(pos[i, 0]), round_half_up(pos[i, 1]),
                             ulo, vlo, cache, counts)
        g = iwso_tell(pos, fit, pbest, pfit, g)
        if fitness_sd(fit) < sd_tol:
            break
    u = round_half_up(pbest[g, 0])
    v = round_half_up(pbest[g, 1])
    c = pfit[g]
    if polish:
        u, v, c = hill_climb(fhat, target, x, y, half, u, v, ulo, uhi, vlo, vhi, cache, counts)
    return u, v, c


@njit(parallel=True, cache=True)
def _batch(reference, target, xs, ys, ulo, uhi, vlo, vhi, half, seed, n, n_iter, mu, p_min, p_max, a1, a2,
           sd_tol, tent_a, polish, boundary, status, out_u, out_v, out_c, out_evals, out_calls):
    """Search every point; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        rng = new_state(seed, i)
        u, v, c = _search_one(fhat, target, xs[i], ys[i], half, ulo[i], uhi[i], vlo[i], vhi[i], n, n_iter, mu,
                              p_min, p_max, a1, a2, sd_tol, tent_a, polish, boundary, rng, cache, counts)
        finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls)


def run(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, half, status, seed, params, outputs, centre):
    p = params
    _batch(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, half, seed, int(p["population"]),
           int(p["iterations"]), float(p["mu"]), float(p["p_min"]), float(p["p_max"]), float(p["a1"]),
           float(p["a2"]), float(p["sd_tol"]), float(p["tent_a"]), bool(p["polish"]), _BOUNDARY[p["boundary"]],
           status, *outputs)
