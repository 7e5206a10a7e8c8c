"""Original White Shark Optimizer (Braik et al. 2022) as an integer search.

M. Braik, A. Hammouri, J. Atwan, M. A. Al-Betar, M. A. Awadallah, "White Shark
Optimizer: A novel bio-inspired meta-heuristic algorithm for global optimization
problems", Knowledge-Based Systems 243 (2022) 108457, DOI 10.1016/j.knosys.2022.108457.
The paper's Fig. 9/10 baseline. Constants and semantics follow
``shared/design/algorithms.md`` section 1 (the authors' MATLAB ``WSO.m`` v1.0 as
copied in VG-TechCenter/Optimizers @41a0703):

``variant="code"`` (default) -- what ``WSO.m`` does:
  tau = 4.11 (mu = 0.71881); velocity ``v = mu v + w_r (wbest[nu_i] - w)`` with
  ``w_r = |2 r_a - (r_b + r_c)| / U(1, 3)`` (p1, p2 computed but unused, no gbest
  term); with probability ``mv`` a shark is only clamped to the violated bounds
  (an in-range shark stays put), else ``w <- w + v / f`` with the constant
  f = 0.899268 and the *fresh* velocity; fishing school per shark *and*
  dimension with ``rand < Ss``: shark 1 jumps near gbest, shark i >= 2 becomes
  ``((gbest_j + r D sgn(r - 0.5)) + w_{i-1,j}) / 2 * rand``; positions are not
  clipped and a shark outside the box is not evaluated (keeps its stale fitness).
``variant="paper"`` -- the paper's equations:
  tau = 4.125 (mu = 0.70346); ``v = mu [v + p1 (gbest - w) c1 + p2 (wbest[nu_i] - w) c2]``
  with c1, c2 ~ U(0, 1) per dimension; the move uses the velocity just computed,
  as the reference code does (D8: Eq. 3 literally writes ``w_k + v_k / f``; read
  as a one-iteration lag it makes the swarm oscillate into the walls -- measured
  24 % success against 91 % with the fresh velocity, radius 16, subset 21 -- so we
  take v_k as notation for the current velocity); fishing school per shark with ``r3 < Ss``:
  ``w' = gbest + r1 D sgn(r2 - 0.5)``, ``w <- (w + w') / (2 rand)``; positions
  are then clipped to the box (D7) and every shark is evaluated.
``fix_gbest=True`` (default, both variants): when a shark beats the best fitness,
  gbest becomes *that shark's* best position. ``fix_gbest=False`` reproduces the
  reference code's bug exactly: gbest becomes the personal best of the shark that
  was best at initialisation (``index`` is never updated), so the search follows a
  stale leader and the returned position can disagree with the best fitness seen.
  The returned position is gbest (as ``WSO.m`` returns it) with its own ZNCC.

Both: ``mv = 1 / (6.25 + exp((K/2 - k) / 100))``, ``Ss = |1 - exp(-0.0005 k / K)|``,
p_min = 0.5, p_max = 1.5, f_min = 0.07, f_max = 0.75; positions are continuous
displacements relative to the rounded guess (the code variant's ``* rand`` pulls
towards that origin), fitness ZNCC at ``floor(w + 0.5)`` (maximised, i.e. the
reference code's minimisation of -ZNCC). Defaults n = 20, K = 50.
"""

from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit, prange

from livedic.dic._random import new_state, uniform
from livedic.dic.correlation import round_half_up
from livedic.dic.method_options import is_bool, is_int_at_least
from livedic.dic.search._common import SearchOutputs, begin_point, finish_point, fitness, new_cache

DEFAULTS = {"population": 20, "iterations": 50, "variant": "code", "fix_gbest": True}
CHECKS = {
    "population": (is_int_at_least(1), "an integer >= 1"),
    "iterations": (is_int_at_least(0), "an integer >= 0"),
    "variant": (lambda v: v in ("code", "paper"), "'code' or 'paper'"),
    "fix_gbest": (is_bool, "True or False"),
}

F_MAX = 0.75
F_MIN = 0.07
P_MIN = 0.5
P_MAX = 1.5
A0 = 6.25
A1 = 100.0
A2 = 0.0005
TAU_CODE = 4.11
TAU_PAPER = 4.125


def constriction(tau: float) -> float:
    """mu = 2 / |2 - tau - sqrt(tau^2 - 4 tau)| (Clerc-Kennedy form)."""
    return 2.0 / abs(2.0 - tau - np.sqrt(tau * tau - 4.0 * tau))


@njit(cache=True)
def _sign(x):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0


@njit(cache=True)
def _eval(fhat, target, x, y, half, pos, i, cu, cv, ulo, vlo, cache, counts):
    return fitness(fhat, target, x, y, half, cu + round_half_up(pos[i, 0]), cv + round_half_up(pos[i, 1]),
                   ulo, vlo, cache, counts)


@njit(cache=True)
def _search_one(fhat, target, x, y, half, cu, cv, ulo, uhi, vlo, vhi, n, n_iter, paper, fix_gbest, mu,
                rng, cache, counts):
    # bounds relative to the centre (rounded guess)
    lo = np.array((ulo - cu, vlo - cv), dtype=np.float64)
    hi = np.array((uhi - cu, vhi - cv), dtype=np.float64)
    f = F_MIN + (F_MAX - F_MIN) / (F_MAX + F_MIN)
    pos = np.empty((n, 2))
    vel = np.zeros((n, 2))
    wbest = np.empty((n, 2))
    fit = np.empty(n)        # personal best fitness ("fitness" in WSO.m), maximised
    gbest = np.empty(2)
    nu = np.empty(n, dtype=np.int64)
    for i in range(n):
        for d in range(2):
            pos[i, d] = lo[d] + uniform(rng) * (hi[d] - lo[d])
            wbest[i, d] = pos[i, d]
        fit[i] = _eval(fhat, target, x, y, half, pos, i, cu, cv, ulo, vlo, cache, counts)
    index = 0
    for i in range(1, n):
        if fit[i] > fit[index]:
            index = i
    gfit = fit[index]
    gbest[0] = wbest[index, 0]
    gbest[1] = wbest[index, 1]
    gbest_fit = gfit         # ZNCC at the returned gbest position

    for ite in range(1, n_iter + 1):
        mv = 1.0 / (A0 + np.exp((n_iter / 2.0 - ite) / A1))
        s_s = abs(1.0 - np.exp(-A2 * ite / n_iter))
        e = np.exp(-(4.0 * ite / n_iter) ** 2)
        p1 = P_MAX + (P_MAX - P_MIN) * e
        p2 = P_MIN + (P_MAX - P_MIN) * e
        for i in range(n):
            nu[i] = min(np.int64(n * uniform(rng)), n - 1)
        # velocity
        for i in range(n):
            j = nu[i]
            if paper:
                for d in range(2):
                    c1 = uniform(rng)
                    c2 = uniform(rng)
                    vel[i, d] = mu * (vel[i, d] + p1 * (gbest[d] - pos[i, d]) * c1
                                      + p2 * (wbest[j, d] - pos[i, d]) * c2)
            else:
                rr = 1.0 + uniform(rng) * 2.0
                ra = uniform(rng)
                rb = uniform(rng)
                rc = uniform(rng)
                wr = abs((2.0 * ra - (rb + rc)) / rr)
                for d in range(2):
                    vel[i, d] = mu * vel[i, d] + wr * (wbest[j, d] - pos[i, d])
        # movement towards the prey
        for i in range(n):
            if uniform(rng) < mv:
                for d in range(2):
                    if pos[i, d] > hi[d]:
                        pos[i, d] = hi[d]
                    elif pos[i, d] < lo[d]:
                        pos[i, d] = lo[d]
            else:
                for d in range(2):
                    pos[i, d] += vel[i, d] / f
        # fishing school
        if paper:
            for i in range(n):
                if uniform(rng) < s_s:
                    den = max(2.0 * uniform(rng), 1e-300)  # may blow up: clipped below
                    for d in range(2):
                        dist = abs(uniform(rng) * (gbest[d] - pos[i, d]))
                        r1 = uniform(rng)
                        wp = gbest[d] + r1 * dist * _sign(uniform(rng) - 0.5)
                        pos[i, d] = (pos[i, d] + wp) / den
        else:
            for i in range(n):
                for d in range(2):
                    if uniform(rng) < s_s:
                        dist = abs(uniform(rng) * (gbest[d] - pos[i, d]))
                        r1 = uniform(rng)
                        wp = gbest[d] + r1 * dist * _sign(uniform(rng) - 0.5)
                        if i == 0:
                            pos[i, d] = wp
                        else:
                            pos[i, d] = (wp + pos[i - 1, d]) / 2.0 * uniform(rng)
        if paper:
            for i in range(n):
                for d in range(2):
                    pos[i, d] = min(max(pos[i, d], lo[d]), hi[d])
        # evaluation, personal and global bests
        for i in range(n):
            inside = True
            for d in range(2):
                if not (pos[i, d] >= lo[d] and pos[i, d] <= hi[d]):
                    inside = False
            if not inside:
                continue
            c = _eval(fhat, target, x, y, half, pos, i, cu, cv, ulo, vlo, cache, counts)
            if c > fit[i]:
                wbest[i, 0] = pos[i, 0]
                wbest[i, 1] = pos[i, 1]
                fit[i] = c
            if fit[i] > gfit:
                gfit = fit[i]
                src = i if fix_gbest else index
                gbest[0] = wbest[src, 0]
                gbest[1] = wbest[src, 1]
                gbest_fit = fit[src]
    return cu + round_half_up(gbest[0]), cv + round_half_up(gbest[1]), gbest_fit


@njit(cache=True, parallel=True, nogil=True)
def _batch(reference, target, xs, ys, ulo, uhi, vlo, vhi, cus, cvs, half, seed, n, n_iter, paper, fix_gbest,
           mu, status, out_u, out_v, out_c, out_evals, out_calls):
    """Search every point; arrays (N,), status updated in place."""
    side = 2 * half + 1
    for i in prange(xs.shape[0]):
        fhat = np.empty(side * side)
        if not begin_point(reference, xs[i], ys[i], half, fhat, status, i):
            continue
        cache = new_cache(ulo[i], uhi[i], vlo[i], vhi[i])
        counts = np.zeros(2, dtype=np.int64)
        rng = new_state(seed, i)
        cu = min(max(cus[i], ulo[i]), uhi[i])
        cv = min(max(cvs[i], vlo[i]), vhi[i])
        u, v, c = _search_one(fhat, target, xs[i], ys[i], half, cu, cv, ulo[i], uhi[i], vlo[i], vhi[i], n, n_iter,
                              paper, fix_gbest, mu, rng, cache, counts)
        finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls)


def run(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, ulo: np.ndarray,
        uhi: np.ndarray, vlo: np.ndarray, vhi: np.ndarray, half: int, status: np.ndarray, seed: np.uint64,
        params: Mapping[str, Any], outputs: SearchOutputs, centre: tuple[np.ndarray, np.ndarray]) -> None:
    paper = params["variant"] == "paper"
    mu = constriction(TAU_PAPER if paper else TAU_CODE)
    _batch(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, centre[0], centre[1], half, seed,
           int(params["population"]), int(params["iterations"]), paper, bool(params["fix_gbest"]), mu,
           status, *outputs)
