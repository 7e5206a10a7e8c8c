"""Incremental correlation with key frames: the reference follows the test, results stay Lagrangian.

``KeyFrameTracker`` switches its reference to a recent frame (a *key frame*) when
``UpdatePolicy`` says so, and composes the displacements back to the first frame::

    u_0->k(X) = u_0->r(X) + u_r->k(x_r),        x_r = X + u_0->r(X)

so every result is the displacement of a material point X of frame 0 (Lagrangian, as without
updates); the gradients compose as deformation gradients, F_0->k = (I + G) F_0->r.

When (``UpdatePolicy``, ``--reference-update``)::

    never     frame 0 stays the reference (the results equal ``dic.Tracker``'s bit for bit)
    every:N   the reference moves to every N-th frame tracked
    auto      (default) the reference moves to the frame just tracked when, in it,
              the 5th percentile of the ok points' ZNCC fell below AUTO_ZNCC, or the
              strain since the key frame passed AUTO_STRAIN, and at least AUTO_OK of its
              tracked points still in view are ok (else the move waits).

Only trustworthy results are carried into a new reference (ok, ZNCC at least the tracker's
``refind_zncc``, no failed point within a subset's width); the others are measured there
from frame 0 and, unless that confirms them, reported ``NOT_IN_KEY_FRAME`` until a later
update does.

How the composition is done, what an update costs and adds to the error, why only trusted
points are carried, and the measurements: docs/guide/large-deformation.md ("How key frames work").
"""

from __future__ import annotations

import time
from concurrent.futures import Executor, Future
from typing import Any

import numpy as np

from livedic.dic.strain import field_fit
from livedic.dic.tensile.fracture import detect_fracture
from livedic.dic.image_filter import DEFAULT_PREFILTER, Prefilter
from livedic.dic.neighbours import typical_spacing
from livedic.dic.result import Measurement
from livedic.dic.status import Status
from livedic.dic.measure import measure
from livedic.dic.tracking.results import _SHAPE
from livedic.dic.tracking.tracker import _FILTER_GUARD, ICGN_MAX_ITERATIONS, StageTimes, Tracker
from livedic.dic.tracking.update_policy import ReferenceUpdate, UpdatePolicy
from livedic.dic.bspline import BSplineCoefficients
from livedic.dic.tracking.kernel_job import KernelJob, WindowCoefficients


class KeyFrameTracker:
    """``dic.Tracker`` with reference updates (module notes); results are displacements from frame 0.

    Parameters
    ----------
    reference_image : ndarray (H, W)
        The first frame.
    points : array_like (N, 2)
        (x, y) positions in it (snapped to pixel centres, as ``Tracker`` does).
    reference_update : str or UpdatePolicy
        ``"auto"`` (default), ``"never"`` or ``"every:N"``.
    prefilter : str or dic.image_filter.Prefilter
        Image pre-filter (``Tracker``'s): applied here once to the first frame and to every frame tracked, so
        the key frames, the inner trackers and the re-measurements from the first frame all see filtered images.
    **tracker_options
        Passed to every ``Tracker`` (subset, search, subpixel, radii, gates ...).

    Attributes
    ----------
    x, y : ndarray (N,)
        The material points (positions in the first frame).
    updates : list of ReferenceUpdate
    last_update : ReferenceUpdate or None
        Set when the frame just tracked became the reference.
    fractures : list of dic.tensile.fracture.Fracture
    last_fracture : dic.tensile.fracture.Fracture or None
        Set when a fracture was detected in the frame just tracked (``dic.tensile.fracture``; its points
        across the crack are ``SEPARATED`` from that frame on). ``detect_fractures=False`` turns it off.
    key_frame : int
        The tracked frame that is the reference now (0: the first).
    last_trackable : ndarray of bool (N,)
        The points the frame just tracked tried to measure (``trackable`` as that frame began: a move of the
        reference after it may change ``trackable`` for the next).
    last_timings : dict of str -> int
        Nanoseconds per stage (``TRACKER_STAGES``) of the last ``track`` call: the inner tracker's
        stages (``Tracker.last_timings``) and ``reference_update``, the composition to the first frame,
        the fracture check, the update policy and any move of the reference.
    """

    def __init__(self, reference_image: np.ndarray, points: np.ndarray, *, reference_update: str = "auto",
                 detect_fractures: bool = True, prefilter: str | Prefilter = DEFAULT_PREFILTER,
                 **tracker_options: Any):
        self.policy = UpdatePolicy.parse(reference_update)
        self.detect_fractures = bool(detect_fractures)
        self.prefilter = Prefilter.parse(prefilter)
        self._options = tracker_options            # the inner trackers get filtered images: no pre-filter of theirs
        self._executor: Executor | None = None        # ``build_on``
        # the key frame's Tracker, or the Future of the one being built (``_inner`` waits for it); only the
        # tracking thread replaces it, other threads (``coefficients_ahead``) only read it
        self._slot: Tracker | Future = Tracker(self.prefilter.apply(reference_image), points, **tracker_options)
        self._token = object()                  # ``state``: a new one with every new inner tracker
        self._first = self._inner.reference            # points lost at a key frame are re-measured from it
        self.x, self.y = self._inner.x.copy(), self._inner.y.copy()
        n = self.x.size
        self._step = typical_spacing(np.column_stack([self.x, self.y])) if n > 1 else 1.0
        self._members = np.arange(n)            # outer index of each inner point
        self._u0 = np.zeros(n)                  # u_0->r, v_0->r at the key frame
        self._v0 = np.zeros(n)
        self._f0 = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()   # F_0->r
        self._f0_inv = None                     # its inverse at the inner points (_f0_inverse)
        self._offset = np.zeros((n, 2))         # x_r - p_r of the inner points
        self._status = np.full(n, -1, dtype=np.int8)   # outer status for points not in the inner tracker
        self.key_frame = 0
        self.frames_tracked = 0
        self._since_key = 0
        self.updates: list[ReferenceUpdate] = []
        self.last_update: ReferenceUpdate | None = None
        self.fractures: list[Any] = []
        self.last_fracture = None
        self._previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None   # the last result (fracture test)
        self.last_timings = StageTimes().ns
        self.last_trackable = self.trackable
        self._last_refound = np.zeros(n, dtype=bool)
        self._last_searches = (0, 0)            # the last frame's re-find attempts and seeded searches

    def build_on(self, executor: Executor | None) -> None:
        """Submit the next key frames' trackers' builds to ``executor`` (None: build them in the call that moves
        the reference).

        The frame that moves the reference then returns once the points are placed in the new key frame; the
        next call waits for the build only if it is not done (a live session's tracking loop runs it between the
        two frames: ``stream.pipeline.key_frame_builder``). ``coefficients_ahead``, called from another thread,
        never waits for it: None until it is done. The results are the same either way: the same tracker, built
        from the same data.
        """
        self._executor = executor

    @property
    def _inner(self) -> Tracker:
        """The current key frame's Tracker (waits for it if it is being built)."""
        slot = self._slot
        return slot.result() if isinstance(slot, Future) else slot

    def __getstate__(self):
        # a copy or a pickle (replay --workers) holds the built tracker, never a build in progress or the executor
        state = self.__dict__.copy()
        state["_slot"] = self._inner
        state["_executor"] = None
        return state

    # the Tracker interface the session uses
    @property
    def n_points(self) -> int:
        return self.x.size

    @property
    def trackable(self) -> np.ndarray:
        mask = np.zeros(self.n_points, dtype=bool)
        mask[self._members] = self._inner.trackable
        return mask

    @property
    def last_refound(self) -> np.ndarray:
        return self._last_refound

    @property
    def last_refind_attempts(self) -> int:
        return self._last_searches[0]

    @property
    def last_seed_searches(self) -> int:
        return self._last_searches[1]

    @property
    def window(self) -> tuple[int, int, int, int] | None:
        return self._inner.window

    def kernel_job(self) -> KernelJob | None:
        """``Tracker.kernel_job`` of the current key frame's tracker (displacements from the key frame)."""
        return self._inner.kernel_job()

    def coefficients_ahead(self, image: np.ndarray, out: BSplineCoefficients | None = None
                           ) -> WindowCoefficients | None:
        """``Tracker.coefficients_ahead`` on the current key frame's window (any thread), of the image
        pre-filtered as ``track`` filters it; None, at once, while the key frame's tracker is being built
        (``build_on``): the caller (a camera's acquisition thread) never waits for a build, ``track`` makes them."""
        slot = self._slot
        if isinstance(slot, Future) and not slot.done():
            return None
        if not self.prefilter.active:
            return self._inner.coefficients_ahead(image, out)
        filtered = self.prefilter.apply(image)
        ahead = self._inner.coefficients_ahead(filtered, out)
        return None if ahead is None else ahead._replace(filtered=filtered)

    def track(self, image: np.ndarray, *, ahead: WindowCoefficients | None = None) -> Measurement:
        """Displacement of every material point from the first frame to ``image`` (a ``Measurement``);
        ``ahead``: ``image``'s coefficients from ``coefficients_ahead``."""
        if isinstance(self._slot, Future):
            self._slot = self._slot.result()        # the key frame's tracker built meanwhile
        tracker = self._inner
        self.last_trackable = self.trackable
        times = StageTimes()
        with times.stage("prepare"):
            image = ahead.filtered if ahead is not None and ahead.filtered is not None else self.prefilter.apply(image)
        filtering = times.ns["prepare"]
        inner = tracker.track(image, ahead=ahead)
        self._last_refound = np.zeros(self.n_points, dtype=bool)
        self._last_refound[self._members] = tracker.last_refound
        self._last_searches = (tracker.last_refind_attempts, tracker.last_seed_searches)
        times.ns.update(tracker.last_timings)
        times.ns["prepare"] += filtering
        with times.stage("reference_update"):
            self.frames_tracked += 1
            self._since_key += 1
            self.last_update = None
            self.last_fracture = None
            composed = not (self.key_frame == 0 and self._members.size == self.n_points)
            result = self._compose(inner) if composed else inner
            if self.detect_fractures and self._previous is not None:
                self._check_fracture(result)
            if self.last_fracture is None:
                reason = self.policy.reason(self._since_key, inner, self._inner.trackable)
                if reason is not None:
                    self._move_reference(image, result, reason)
            # The next frame starts from this result as resume() maps it back onto the key frame (rounded by
            # the round trip): a frame resumed from the recording (replay --workers) then starts bit for bit
            # where this one does. A start 1 ulp away can flip the last bit of an IC-GN float32 row sum: ~1e-7
            # px in the result.
            if composed and self._slot is tracker:
                tracker.carry(self._key_frame_view({name: getattr(result, name)
                                                    for name in ("u", "v", "ok") + _SHAPE}))
            self._previous = (result.ok.copy(), result.u.copy(), result.v.copy())
        self.last_timings = times.ns
        return result

    def _check_fracture(self, result):
        """``dic.tensile.fracture``: a band lost at once with a jump across it stops the points across the crack."""
        ok_before, u_before, v_before = self._previous
        fracture = detect_fracture(self.x, self.y, ok_before, result.ok, u_before, v_before, result.u, result.v,
                                   step=self._step, subset=self._inner.subset, trackable=self.trackable)
        if fracture is None:
            return
        same = any(_same_crack(fracture, earlier, 2.0 * self._inner.subset) for earlier in self.fractures)
        self.stop_tracking(fracture.separated)
        separated = fracture.separated
        result.ok[separated] = False
        result.status[separated] = int(Status.SEPARATED)
        for name in ("u", "v", "zncc", "ux", "uy", "vx", "vy"):
            values = getattr(result, name)
            if values is not None:
                values[separated] = np.nan
        if same:
            return                      # the crack widening (its faces pull more subsets across): not news
        self.last_fracture = fracture
        self.fractures.append(fracture)

    def stop_tracking(self, mask: np.ndarray, status: int = Status.SEPARATED) -> None:
        """Stop tracking the points ``mask`` (N,) from the next frame on (a fracture): reported with ``status``.

        The current key frame stays the reference; its tracker is rebuilt without those points.
        """
        mask = np.asarray(mask, dtype=bool)
        keep = ~mask[self._members]
        if keep.all():
            return
        self._status[self._members[~keep]] = int(status)
        pixels = np.column_stack([self._inner.x, self._inner.y])
        self._rebuild(self._inner.reference, self._members[keep], pixels[keep], self._offset[keep])

    # ------------------------------------------------------------------ composition
    def _compose(self, inner):
        """The inner result (displacement key frame -> this frame at p_r) as displacement from frame 0 at X."""
        n = self.n_points
        nan = np.full(n, np.nan)
        status = np.where(self._status >= 0, self._status, int(Status.NOT_IN_KEY_FRAME)).astype(inner.status.dtype)
        out = Measurement(x=self.x.copy(), y=self.y.copy(), u=nan.copy(), v=nan.copy(), zncc=nan.copy(),
                          ok=np.zeros(n, dtype=bool), status=status,
                          ux=None if inner.ux is None else nan.copy(), uy=None if inner.uy is None else nan.copy(),
                          vx=None if inner.vx is None else nan.copy(), vy=None if inner.vy is None else nan.copy(),
                          iterations=None if inner.iterations is None else np.zeros(n, dtype=inner.iterations.dtype))
        members = self._members
        du, dv = inner.u, inner.v
        if inner.ux is not None:
            g = (inner.ux, inner.uy, inner.vx, inner.vy)
            cu, cv = _times_vector(_where_known(g), self._offset)
            du = du + cu
            dv = dv + cv
            f = _times(_plus_identity(g), self._f0_of_members())
            out.ux[members], out.uy[members] = f[0] - 1.0, f[1]
            out.vx[members], out.vy[members] = f[2], f[3] - 1.0
        out.u[members] = self._u0[members] + du
        out.v[members] = self._v0[members] + dv
        out.zncc[members] = inner.zncc
        out.ok[members] = inner.ok
        out.status[members] = inner.status
        if out.iterations is not None and inner.iterations is not None:
            out.iterations[members] = inner.iterations
        return out

    # ------------------------------------------------------------------ updates
    def _move_reference(self, image, result, reason):
        """Make ``image`` (whose result from frame 0 is ``result``) the reference; records a ReferenceUpdate.

        The points followed so far, and those lost at an earlier update (``NOT_IN_KEY_FRAME``: they come
        back once trusted points surround them again), are placed in the new reference: by their own
        result where it is trusted, else by the quadratic fit of the trusted points around them.
        """
        started = time.perf_counter()
        was_lost = np.flatnonzero(np.isin(self._status, (int(Status.NOT_IN_KEY_FRAME), int(Status.OUTSIDE_TARGET))))
        candidates = np.union1d(self._members, was_lost)
        near_failures = self._near_failures(result)
        trusted = self._trusted(result, near_failures)
        own = trusted[candidates]
        u = np.where(own, result.u[candidates], np.nan)
        v = np.where(own, result.v[candidates], np.nan)
        grad = np.full((candidates.size, 4), np.nan)
        if result.ux is not None:
            grad[own] = np.column_stack([result.ux, result.uy, result.vx, result.vy])[candidates[own]]
        # Not trusted here: re-measured from frame 0 where nothing else failed around them (their own failure
        # aside), else left out until a later key frame (their subset here may show something else).
        own_failure = (~result.ok[candidates] & self.trackable[candidates] &
                       (result.status[candidates] != int(Status.OUTSIDE_TARGET))).astype(np.int64)
        others = np.flatnonzero(~own & (near_failures[candidates] - own_failure == 0))
        if others.size:
            u[others], v[others], grad[others] = self._place_from_first_frame(image, candidates[others], result,
                                                                              trusted)
        placed = np.isfinite(u) & np.isfinite(v)
        members = candidates[placed]
        # not placed: out of view if its material had left the image in this frame, else not in the key frame
        gone = result.status[candidates] == int(Status.OUTSIDE_TARGET)
        self._status[candidates[~placed]] = np.where(gone[~placed], int(Status.OUTSIDE_TARGET),
                                                     int(Status.NOT_IN_KEY_FRAME))
        self._status[members] = -1
        f = np.broadcast_to(np.eye(2), (members.size, 2, 2)).copy()
        g = grad[placed]
        known = np.all(np.isfinite(g), axis=1)
        f[known] += g[known].reshape(-1, 2, 2)
        # translation-only points (no gradients): the previous key frame's are the best known
        f[~known] = self._f0[members[~known]]
        self._u0[members], self._v0[members] = u[placed], v[placed]
        self._f0[members] = f
        where = np.column_stack([self.x[members] + u[placed], self.y[members] + v[placed]])
        snapped = np.floor(where + 0.5)
        self._rebuild(np.array(image, copy=True), members, snapped, where - snapped, elsewhere=True)
        self.key_frame = self.frames_tracked - 1
        self._since_key = 0
        self.last_update = ReferenceUpdate(frame=self.key_frame, reason=reason, carried=int((placed & own).sum()),
                                           estimated=int((placed & ~own).sum()), lost=int((~placed).sum()),
                                           seconds=time.perf_counter() - started)
        self.updates.append(self.last_update)

    def _place_from_first_frame(self, image, idx, result, trusted):
        """(u, v, gradients) of the points ``idx`` in ``image``, measured from the first frame, or NaN.

        Their own result in this frame is not trusted (module notes), so their subset here may show
        something else (an occlusion, a flake). The quadratic fit of the trusted points around
        (within 2.5 grid steps, else 5: the rim of a hole) gives where they should be; IC-GN from the
        first frame, started there, confirms it only if the subset here shows the same material
        (ZNCC >= the tracker's ``refind_zncc``): then its result is the placement.
        """
        n = idx.size
        u, v, grad = np.full(n, np.nan), np.full(n, np.nan), np.full((n, 4), np.nan)
        points = np.column_stack([self.x, self.y])
        for reach in (field_fit.REACH, 2 * field_fit.REACH):
            todo = np.flatnonzero(~np.isfinite(u))
            if todo.size == 0:
                break
            where = points[idx[todo]]
            start, index = field_fit.neighbourhoods(where, points, self._step, reach)
            u[todo], v[todo] = field_fit.fit_at(where, start, index, points, result.u, result.v, trusted, self._step)
            if result.ux is not None:
                for pair, (a, b) in enumerate((("ux", "uy"), ("vx", "vy"))):
                    grad[todo, 2 * pair], grad[todo, 2 * pair + 1] = field_fit.fit_at(
                        where, start, index, points, getattr(result, a), getattr(result, b), trusted, self._step)
        guessed = np.flatnonzero(np.isfinite(u) & np.isfinite(v))
        out_u, out_v, out_grad = np.full(n, np.nan), np.full(n, np.nan), np.full((n, 4), np.nan)
        if guessed.size == 0:
            return out_u, out_v, out_grad
        start_grad = np.where(np.isfinite(grad[guessed]), grad[guessed], 0.0)
        subpixel = self._inner.method.name if self._inner.method.prepared else "icgn"
        first, now, at, shift = _crops(self._first, image, points[idx[guessed]],
                                       np.column_stack([u[guessed], v[guessed]]), self._inner.subset,
                                       self._inner.interpolation.degree)
        m = measure(first, now, at, subset=self._inner.subset, search="none", subpixel=subpixel,
                    interpolation=self._inner.interpolation,
                    guess=np.column_stack([u[guessed] - shift[0], v[guessed] - shift[1]]), gates=None,
                    subpixel_options={"ux0": start_grad[:, 0], "uy0": start_grad[:, 1], "vx0": start_grad[:, 2],
                                      "vy0": start_grad[:, 3], "max_iterations": ICGN_MAX_ITERATIONS})
        m.u[:] += shift[0]
        m.v[:] += shift[1]
        with np.errstate(invalid="ignore"):
            confirmed = m.ok & (m.zncc >= max(self._inner.refind_zncc, self._inner.gates.min_zncc))
        keep = guessed[confirmed]
        out_u[keep], out_v[keep] = m.u[confirmed], m.v[confirmed]
        if m.ux is not None:
            out_grad[keep] = np.column_stack([m.ux, m.uy, m.vx, m.vy])[confirmed]
        return out_u, out_v, out_grad

    def _near_failures(self, result):
        """How many failed (tracked, not ok) points lie within a subset's width of each point (itself included).

        A point whose material left the image (OUTSIDE_TARGET) is no failure around it: the subsets beside
        it are whole and in view, nothing covers them.
        """
        count = np.zeros(self.n_points, dtype=np.int64)
        reach = float(self._inner.subset)
        failed = ~result.ok & self.trackable & (result.status != int(Status.OUTSIDE_TARGET))
        for i in np.flatnonzero(failed):
            count += (np.abs(self.x - self.x[i]) < reach) & (np.abs(self.y - self.y[i]) < reach)
        return count

    def _trusted(self, result, near_failures):
        """Points whose own result in this frame may be carried into it as a key frame (module notes)."""
        with np.errstate(invalid="ignore"):
            return result.ok & (result.zncc >= self._inner.refind_zncc) & (near_failures == 0)

    def resume(self, previous: Measurement | None, *, last_good: dict[str, np.ndarray] | None = None, frames_tracked: int,
               frames_since_key: int, frames_since_rebuild: int) -> None:
        """``Tracker.resume`` for key frames: the next ``track`` starts as it would in sequence.

        For ``livedic replay --workers``, which measures frames apart and follows reference updates and
        fractures. The tracker must be a copy of the tracker as it was right after the frame that built its current
        inner tracker (a new tracker; the last key frame or fracture): only the per-frame state changes
        between then and any later frame of the same key frame, and this sets it. ``previous`` (a
        ``Measurement`` as ``track`` returned it: displacements from the first frame) is the result of
        the frame tracked just before; ``last_good`` (``last_good_after`` over the frames tracked since
        the inner tracker was built, on those results) each point's last ok one. They are mapped onto the
        inner tracker's points as displacements from the key frame, the inverse of the composition
        (u_0->k = u_0->r + u_r->k(p_r) + G (x_r - p_r), F_0->k = (I + G) F_0->r).

        Parameters
        ----------
        frames_tracked : int
            Frames tracked before the next one (its ``frames_tracked`` then).
        frames_since_key : int
            Of those, since the current key frame (the update policy counts them; 0 right after a move).
        frames_since_rebuild : int
            Of those, since the inner tracker was built (at a key frame or a fracture): 0 = it is new, as it
            is then in sequence, and ``previous`` only feeds the fracture test.
        """
        self.frames_tracked = int(frames_tracked)
        self._since_key = int(frames_since_key)
        self.last_update = self.last_fracture = None
        self._previous = None if previous is None else (np.asarray(previous.ok, dtype=bool).copy(),
                                                            np.asarray(previous.u, dtype=np.float64).copy(),
                                                            np.asarray(previous.v, dtype=np.float64).copy())
        inner = self._inner
        if previous is None or frames_since_rebuild == 0:
            inner.resume(None)
            return
        mapped = self._key_frame_view({name: getattr(previous, name)
                                       for name in ("u", "v", "zncc", "ok") + _SHAPE})
        empty = np.zeros(0)
        start = Measurement(x=empty, y=empty, status=np.zeros(0, dtype=np.int8), **mapped)
        good = None
        if last_good is not None:
            good = self._key_frame_view(dict(last_good))
            ever = np.asarray(good["ever"], dtype=bool)
            good = {name: (np.zeros(ever.size) if good.get(name) is None else np.where(ever, good[name], 0.0))
                    for name in ("u", "v") + _SHAPE} | {"ever": ever}
        inner.resume(start, last_good=good)

    @property
    def state(self) -> object:
        """An opaque token of the key-frame state (compare with ``is``): it changes whenever ``track``
        rebuilds the inner tracker: a reference move, a fracture, or a known crack widening (which stops
        tracking more points without a new ``last_fracture``)."""
        return self._token

    def _key_frame_view(self, fields):
        """``fields`` of an outer result (``u, v`` and ``ux, uy, vx, vy`` from the first frame at X; ``zncc, ok``,
        ``ever`` as they are) on the inner tracker's points, from its key frame at p_r: ``_compose`` inverted."""
        members = self._members
        if self.key_frame == 0 and members.size == self.n_points:
            return {name: (None if value is None else np.asarray(value)) for name, value in fields.items()}
        out = {name: (None if value is None else np.asarray(value)[members]) for name, value in fields.items()}
        u = out["u"].astype(np.float64) - self._u0[members]
        v = out["v"].astype(np.float64) - self._v0[members]
        if out.get("ux") is not None:
            f = (1.0 + out["ux"], out["uy"], out["vx"], 1.0 + out["vy"])
            g = _times(f, self._f0_inverse())
            g = (g[0] - 1.0, g[1] - 0.0, g[2] - 0.0, g[3] - 1.0)        # - I, as np.eye(2) subtracted it
            cu, cv = _times_vector(_where_known(g), self._offset)
            u, v = u - cu, v - cv
            out["ux"], out["uy"], out["vx"], out["vy"] = g
        out["u"], out["v"] = u, v
        return out

    def _f0_of_members(self):
        """F_0->r of the inner points as (F11, F12, F21, F22)."""
        f0 = self._f0[self._members]
        return f0[:, 0, 0], f0[:, 0, 1], f0[:, 1, 0], f0[:, 1, 1]

    def _f0_inverse(self):
        """(F_0->r)^-1 of the inner points as (11, 12, 21, 22), computed once per inner tracker (F_0->r and the
        points change only when it is rebuilt)."""
        if self._f0_inv is None:
            inverse = np.linalg.inv(self._f0[self._members])
            self._f0_inv = (inverse[:, 0, 0], inverse[:, 0, 1], inverse[:, 1, 0], inverse[:, 1, 1])
        return self._f0_inv

    def _rebuild(self, key_image, members, positions, offset, *, elsewhere=False):
        """A new inner Tracker on ``key_image`` for the outer points ``members`` at pixel ``positions``; built on
        the executor (``build_on``) when ``elsewhere`` and there is one."""
        if elsewhere and self._executor is not None:
            self._slot = self._executor.submit(Tracker, key_image, positions, **self._options)
        else:
            self._slot = Tracker(key_image, positions, **self._options)
        self._token = object()
        self._members = np.asarray(members)
        self._offset = np.asarray(offset, dtype=np.float64).reshape(-1, 2)
        self._f0_inv = None


# 2 x 2 matrices per point as 4 arrays (11, 12, 21, 22). The products add their terms as np.einsum did
# (from 0: 0 + a b + c d, which makes a -0 result +0), so that results stay those of the einsum version.

def _times(a, b):
    """The matrix products a b."""
    a11, a12, a21, a22 = a
    b11, b12, b21, b22 = b
    return ((0.0 + a11 * b11) + a12 * b21, (0.0 + a11 * b12) + a12 * b22,
            (0.0 + a21 * b11) + a22 * b21, (0.0 + a21 * b12) + a22 * b22)


def _times_vector(a, x):
    """The products a x with the vectors x (N, 2), as (first, second) components."""
    a11, a12, a21, a22 = a
    return (0.0 + a11 * x[:, 0]) + a12 * x[:, 1], (0.0 + a21 * x[:, 0]) + a22 * x[:, 1]


def _plus_identity(g):
    """I + g (np.eye(2) + g: 0 + g off the diagonal)."""
    return 1.0 + g[0], 0.0 + g[1], 0.0 + g[2], 1.0 + g[3]


def _where_known(g):
    """g where all four terms are finite, else 0."""
    known = np.isfinite(g[0]) & np.isfinite(g[1]) & np.isfinite(g[2]) & np.isfinite(g[3])
    return tuple(np.where(known, term, 0.0) for term in g)


def _same_crack(new, old, distance):
    """Whether ``new`` lies along the crack of ``old`` (within ``distance`` px of its line, within 20 degrees)."""
    normal = np.array([-old.direction[1], old.direction[0]])
    offset = abs(float((np.asarray(new.centre) - np.asarray(old.centre)) @ normal))
    parallel = abs(float(np.dot(new.direction, old.direction))) >= np.cos(np.radians(20.0))
    return offset <= distance and parallel


def _crops(first, image, points, displacement, subset, degree):
    """Same-size crops of ``first`` around ``points`` and of ``image`` around ``points + displacement``.

    Returns (first crop, image crop, points in the first crop, (dx, dy)): a displacement measured
    between the crops plus (dx, dy) is the displacement between the full images. IC-GN's prefilter
    then runs on the few points' neighbourhood, not on the whole frame.
    """
    margin = subset + 4 + _FILTER_GUARD[degree]    # subset, interpolation margin and prefilter guard
    lo = np.floor(points.min(axis=0)) - margin
    hi = np.ceil(points.max(axis=0)) + margin
    moved = points + displacement
    lo_b = np.floor(moved.min(axis=0)) - margin
    hi_b = np.ceil(moved.max(axis=0)) + margin
    size = np.maximum(hi - lo, hi_b - lo_b).astype(int) + 1
    height, width = first.shape
    origin_a = np.clip(lo.astype(int), 0, [width - 1, height - 1])
    origin_b = np.clip(lo_b.astype(int), 0, [width - 1, height - 1])
    size = np.minimum(size, [width - max(origin_a[0], origin_b[0]), height - max(origin_a[1], origin_b[1])])
    (xa, ya), (xb, yb), (w, h) = origin_a, origin_b, size
    crop_a = np.ascontiguousarray(first[ya:ya + h, xa:xa + w])
    crop_b = np.ascontiguousarray(image[yb:yb + h, xb:xb + w])
    return crop_a, crop_b, points - (xa, ya), (float(xb - xa), float(yb - ya))
