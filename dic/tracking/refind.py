"""The re-find of weak points, a part of ``Tracker``: where a point's correlation falls or its result jumps,
it is found again from its neighbours (reliability-guided propagation), from a few searched seeds, or by a
wide search, with a back-off for points that stay lost (the package docstring says when each runs)."""

import numpy as np

from livedic.dic import quality
from livedic.dic.bspline import INTERPOLATION_MARGIN
from livedic.dic.reliability_guided import propagate
from livedic.dic.result import Measurement
from livedic.dic.status import Status
from livedic.dic.tracking.results import _gradients_of, _median_test_inputs, _take

# With at least twice this many points to re-find in one frame, the wide search runs for this many
# (spread over them) and IC-GN carries their result to the rest: measured after the fracture of the
# simulated test with frames dropped (the upper half jumping 4-10 px), ~500 wide searches took the
# frame to 133 ms and more frames were dropped.
REFIND_SEEDS = 16


class RefindSteps:
    """``Tracker``'s re-find steps (a mixin: they read and update the tracker's own state)."""

    def _refind_weak(self, target, result, weak, start_u, start_v, grads):
        """Re-find the ``weak`` points (in place in ``weak`` and ``result``), but not those whose material
        left the view (``_at_the_edge``) nor those waiting out their back-off; returns the points still lost."""
        if not weak.any():
            self.last_refound = np.zeros(self.n_points, dtype=bool)
            self.last_refind_attempts = 0
            return np.flatnonzero(weak)
        gone = weak & self._at_the_edge(start_u, start_v)
        stale = np.flatnonzero(weak & ~gone & ~np.isfinite(self._prev["u"]))
        if stale.size:
            # lost before this frame: its own last result is where it was, not where its material went;
            # its nearest tracked neighbour's motion says whether that has left the view
            nu, nv = self._neighbour_guess(stale)
            gone[stale] = self._at_the_edge(nu, nv, stale)
        if gone.any():
            result.ok[gone] = False
            result.status[gone] = Status.OUTSIDE_TARGET
            weak &= ~gone
        waiting = weak & (self._refind_skip > 0)
        self._refind_skip[waiting] -= 1
        weak &= ~waiting
        retry = np.flatnonzero(weak)
        self.last_refound = np.zeros(self.n_points, dtype=bool)
        self.last_refind_attempts = int(retry.size)
        if retry.size and self._prep is not None:
            retry = self._from_neighbours(result, retry, weak)
        if retry.size >= 2 * REFIND_SEEDS and self._prep is not None:
            retry = self._refind_from_seeds(target, result, retry, weak, grads)
        for method in (self.refind_search, self.refind_fallback):
            if retry.size == 0 or method is None:
                break
            self._refind(target, result, retry, method, grads)
            with np.errstate(invalid="ignore"):
                still = ~result.ok[retry] | (result.zncc[retry] < self.refind_zncc)
            retry = retry[still]
        return retry

    def _at_the_edge(self, start_u, start_v, points=None):
        """Points (all, or the indices ``points``) whose start (previous result) puts their subset at the image's edge.

        A doubtful result there (failed, low or falling ZNCC) is taken as the material leaving the
        field of view (the top of a coupon pulled out of the picture): it is not searched for elsewhere,
        where only something else can be found. Measured on the simulated test to fracture: the
        wide search "found" such points 20-60 px off at ZNCC 0.5-0.95, and they passed as ok.
        """
        height, width = self.reference.shape
        edge = self.half + INTERPOLATION_MARGIN + self.seed_radius + 1
        index = slice(None) if points is None else points
        with np.errstate(invalid="ignore"):
            x = self.x[index] + start_u
            y = self.y[index] + start_v
            return (x < edge) | (y < edge) | (x > width - 1 - edge) | (y > height - 1 - edge)

    def _outliers(self, result):
        """Ok points that fail the normalised median test against their ok neighbours.

        Kept with a copy of what it tested (``_tested``): ``_gate`` runs the same test at the end of the
        frame and, when re-finding changed nothing, takes this answer instead of computing it again.
        """
        flagged, _ = quality.median_test(self.x, self.y, result.u, result.v, result.ok, self._graph,
                                         gradients=_gradients_of(result), epsilon=self.gates.outlier_epsilon,
                                         threshold=self.gates.outlier_threshold)
        self._tested = (_median_test_inputs(result, copy=True), flagged)
        return flagged.copy()

    def _refind_from_seeds(self, target, result, retry, weak, grads):
        """Many points to re-find at once (a whole region jumped: a grip slip, the half of a broken coupon):
        the wide search for ``REFIND_SEEDS`` of them spread over the list, then IC-GN from those to the
        rest (``_from_neighbours``), as the reliability-guided measurement does; returns the points left."""
        seeds = retry[np.linspace(0, retry.size - 1, REFIND_SEEDS).astype(np.int64)]
        self._refind(target, result, seeds, self.refind_search, grads)
        with np.errstate(invalid="ignore"):
            found = seeds[result.ok[seeds] & (result.zncc[seeds] >= self.refind_zncc)]
        if found.size == 0:
            return retry
        weak = weak.copy()
        weak[found] = False
        rest = retry[~np.isin(retry, found)]
        return self._from_neighbours(result, rest, weak) if rest.size else rest

    def _from_neighbours(self, result, retry, weak):
        """IC-GN for the points ``retry`` from their best neighbour measured in this frame
        (``dic.reliability_guided.propagate``); returns the points still to search."""
        solved = result.ok & ~weak
        if not solved.any():
            return retry
        pending = np.zeros(self.n_points, dtype=bool)
        pending[retry] = True
        params = np.column_stack([result.u, result.ux, result.uy, result.v, result.vx, result.vy])
        params = np.where(np.isfinite(params), params, 0.0)
        options = {k: v for k, v in self.subpixel_options.items() if k in ("max_iterations", "tolerance")}
        accepted, params, status, zncc, iterations = propagate(
            self._first_order_prep(), self._target_coefficients(), self._graph, order=np.minimum(self._order, 1),
            accept=max(self.gates.min_zncc, self.refind_zncc), params=params, zncc=result.zncc, solved=solved,
            pending=pending, options=options)
        idx = np.flatnonzero(accepted)
        if idx.size:
            p = params[idx]
            if self.method.shape_order > 1:
                # the first-order warp from the neighbour starts a second-order method (no second-order terms: its
                # first-order stage confirms the propagated result, then the 2nd-order iteration runs)
                again = self.method.refine_prepared(self._prep, self._target_coefficients(), p[:, 0], p[:, 3],
                                                    ux0=p[:, 1], uy0=p[:, 2], vx0=p[:, 4], vy0=p[:, 5], points=idx,
                                                    order=self._order[idx], **options)
                again.iterations += iterations[idx]
                found = self._measurement(idx, again)
            else:
                translation = self._order[idx] == 0
                grads = {name: np.where(translation, np.nan, p[:, c]) for name, c in (("ux", 1), ("uy", 2),
                                                                                      ("vx", 4), ("vy", 5))}
                found = Measurement(x=self.x[idx], y=self.y[idx], u=p[:, 0], v=p[:, 3], zncc=zncc[idx],
                                    ok=np.ones(idx.size, dtype=bool), status=status[idx], iterations=iterations[idx],
                                    **grads)
            self.last_refound[idx[self._keep_better(result, idx, found)]] = True
        with np.errstate(invalid="ignore"):
            still = ~result.ok[retry] | (result.zncc[retry] < self.refind_zncc)
        return retry[still]

    def _weak(self, result):
        """Trackable points that failed, correlate below ``refind_zncc``, lost ZNCC or jumped in gradient."""
        zncc = result.zncc
        prev = self._prev_zncc
        with np.errstate(invalid="ignore"):
            weak = ~result.ok | (zncc < self.refind_zncc) | (np.isfinite(prev) & (zncc < prev - self.refind_drop))
        weak |= self._gradient_jump(result)
        return weak & self.trackable

    def _keep_better(self, result, idx, again):
        """Put the rows of ``again`` (points ``idx``) into ``result`` where they correlate better; their mask."""
        old = np.where(result.ok[idx], result.zncc[idx], -np.inf)
        better = again.ok & (np.nan_to_num(again.zncc, nan=-np.inf) > old)
        if better.any():
            self._scatter(result, idx[better], _take(again, better))
        return better

    def _gradient_jump(self, result):
        """Points whose displacement gradients moved more than ``refind_gradient`` since their last good frame."""
        jump = np.zeros(self.n_points, dtype=bool)
        if result.ux is None:
            return jump
        for name in ("ux", "uy", "vx", "vy"):
            now = getattr(result, name)
            before = self._good_grad[name]
            jump |= np.isfinite(now) & (np.abs(now - before) > self.refind_gradient)
        return jump & self._ever_good

    def _refind(self, target, result, retry, method, grads):
        """Wide search + sub-pixel for points ``retry``; keep what correlates better."""
        ru, rv = self._refind_start(retry)
        options = self.search_options if method == self.refind_search else None
        again = self._measure(target, retry, ru, rv, method, self.refind_radius,
                              {k: np.zeros(retry.size) for k in grads}, options)
        self.last_refound[retry[self._keep_better(result, retry, again)]] = True

    def _refind_start(self, retry):
        u = np.where(self._ever_good[retry], self._good_u[retry], np.nan)
        v = np.where(self._ever_good[retry], self._good_v[retry], np.nan)
        missing = ~np.isfinite(u)
        if missing.any():
            nu, nv = self._neighbour_guess(retry[missing])
            u[missing], v[missing] = nu, nv
        return u, v
