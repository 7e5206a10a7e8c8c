"""``Tracker``: points tracked frame to frame against a fixed reference (the package docstring says how)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from livedic.dic import quality
from livedic.dic.bspline import INTERPOLATION_MARGIN, BSplineCoefficients
from livedic.dic.correlation import DEFAULT_SUBSET, _reference_status_batch, snap_points
from livedic.dic.image_filter import DEFAULT_PREFILTER, Prefilter
from livedic.dic.interpolation import DEFAULT_INTERPOLATION, Interpolation
from livedic.dic.measure import measure
from livedic.dic.neighbours import neighbour_graph
from livedic.dic.quality import Gates
from livedic.dic.result import Measurement
from livedic.dic.search import (DEFAULT_RADIUS, DEFAULT_SEARCH, NO_SEARCH, SEARCH_METHODS as _INTEGER_SEARCHES,
                                search_method, search_points)
from livedic.dic.status import Status
from livedic.dic.subpixel.icgn import prepare_reference
from livedic.dic.subpixel.icgn2 import SECOND_ORDER
from livedic.dic.subpixel.method import subpixel_method
from livedic.dic.validation import as_image, as_points, check_radius, check_subset, checked_image
from livedic.dic.tracking.kernel_job import KernelJob, WindowCoefficients, window_coefficients
from livedic.dic.tracking.refind import RefindSteps
from livedic.dic.tracking.results import _SHAPE, _Curved, _gradients_of, _median_test_inputs, _same_bits, _take

# IC-GN iteration cap used for tracking (dic.subpixel.icgn's own default is 10): measured here, a
# few subsets of the tensile sequence need 16-40 iterations from the exact displacement with zero
# gradients; with 10 they are reported NOT_CONVERGED frame after frame.
ICGN_MAX_ITERATIONS = 50
# Longest wait (frames) before a point the wide search could not recover is searched again.
REFIND_MAX_WAIT = 32
# Points whose ZNCC falls below this are re-found (``Tracker``'s ``refind_zncc``, the view's low-ZNCC colour).
REFIND_ZNCC = 0.8
# Seeded-search options for the swarm methods (see Tracker).
SEED_SWARM = {"population": 6, "iterations": 8}
# IC-GN reads each frame on a window around the points: displacement room it starts with (px) and the
# extra border that keeps the B-spline prefilter's edge effects away, per degree (cubic pole 2 - sqrt(3):
# 0.27^12 < 1e-6; the quintic's larger pole 0.43 needs 19 px for the same, the septic's 0.54 25 px).
_WINDOW_ALLOWANCE = 48
_FILTER_GUARD = {3: 12, 5: 19, 7: 25}

# The stages of ``track`` that ``last_timings`` times (``StageTimes``), in the order a frame passes them:
# prepare = the new frame made ready to sample (the image pre-filter if any, grey float32, the B-spline prefilter
# of the IC-GN window);
# kernel = the sub-pixel method on every trackable point from its start (for methods that always search,
# the seeded search too); seeded_search = the on-demand seeded search of the doubtful points and their
# re-refinement; refind = the re-finding of weak points (from neighbours, from seeds, the wide search);
# gates = the tests that decide which points are doubtful, outliers or ok (ZNCC, gradient jumps, the
# median test, the quality gates); reference_update = ``dic.tracking.key_frames``' composition to the first frame,
# fracture check, update policy and any move of the reference (0 for a plain ``Tracker``).
TRACKER_STAGES = ("prepare", "kernel", "seeded_search", "refind", "gates", "reference_update")


class StageTimes:
    """Nanoseconds spent per stage (``TRACKER_STAGES``) of one call, each stage's spans added up.

    ``with times.stage("kernel"): ...`` adds the block's duration to ``times.ns["kernel"]``; spans
    must not nest (a nested one would be counted twice).
    """
    __slots__ = ("ns", "_stage", "_started")

    def __init__(self) -> None:
        self.ns = dict.fromkeys(TRACKER_STAGES, 0)
        self._stage: str | None = None
        self._started = 0

    def stage(self, name: str) -> StageTimes:
        self._stage = name
        return self

    def __enter__(self):
        self._started = time.perf_counter_ns()
        return self

    def __exit__(self, *exc):
        self.ns[self._stage] += time.perf_counter_ns() - self._started
        return False


class Tracker(RefindSteps):
    """Track points of a reference image through later frames.

    Parameters
    ----------
    reference_image : ndarray, shape (H, W)
        The reference frame (any integer or float grey dtype).
    points : array_like, shape (N, 2)
        (x, y) positions in the reference, snapped to pixel centres.
    subset : int
        Odd subset side, pixels.
    search : str
        Integer search seeded by the previous result (``dic.SEARCH_METHODS``),
        or ``"none"`` to start the sub-pixel method straight from it. With
        ``"icgn"``, ``"icgn2"`` and ``"newton-raphson"`` it runs only for doubtful points
        (see the module notes).
    subpixel : str
        Sub-pixel method (``dic.SUBPIXEL_METHODS``); ``"icgn"`` and ``"icgn2"``
        use the prepared-reference fast path.
    seed_radius : int
        Search radius around the previous displacement, pixels (2 covers 1.5 px of
        motion between frames; measured on 1,000 points, searching every point, the
        seeded improved WSO costs ~9 ms at radius 1, ~14 ms at 2 and ~25 ms at 3 on a
        shared 2-core machine).
    refind_radius : int
        Search radius for re-finding lost points, pixels.
    refind_zncc : float
        Re-find points whose ZNCC is below this.
    refind_drop : float
        Also re-find points whose ZNCC fell by more than this since the previous frame.
    refind_gradient : float
        First-order methods: also re-find points whose displacement gradients (ux, uy,
        vx, vy) changed by more than this since the previous frame. IC-GN can settle on
        a strongly squeezed warp of a wrong region with a ZNCC near 0.9; a material
        does not change its strain by 0.1 between two frames.
    refind_search : str, optional
        Search method for re-finding (default: ``search``, or ``"improved-wso"`` when
        ``search`` is ``"none"``).
    refind_fallback : str or None
        Search tried next for points the re-find search left weak (default
        ``"exhaustive"``: certain, and only run for the few points left; the
        swarm searches miss a sharp speckle peak in a 33 x 33 box a few % of the time).
    seed : int
        Seed of the stochastic searches.
    search_options : dict, optional
        Options of the search method for re-finding (see ``dic.search.method_options``).
    seed_search_options : dict, optional
        Options of the seeded (small-box) search. Default for the swarm searches
        (improved-wso, wso, pso): ``SEED_SWARM`` = population 6, 8 iterations, as a
        box of (2 * seed_radius + 1)^2 positions needs no 20 x 50 swarm (the
        improved WSO's hill-climb polish still ends on a ZNCC maximum); otherwise
        ``search_options``.
    subpixel_options : dict, optional
        Options of the sub-pixel method; for ``"icgn"`` and ``"icgn2"`` the default
        cap is ``max_iterations=ICGN_MAX_ITERATIONS`` (50): a few subsets need far
        more than IC-GN's own default of 10. ``"icgn2"`` also takes ``vif_max``
        (``dic.subpixel.icgn2.prepare_from``).
    gates : dic.quality.Gates
        Quality gates applied to every frame's result, as in ``dic.measure``:
        a point is ok only if it passes them (``POOR_TEXTURE`` points are never
        tracked; ``OUTLIER`` points are re-found first, and flagged if they
        still disagree with their neighbours).
    prefilter : str or dic.image_filter.Prefilter
        Image pre-filter applied to the reference and, once, to every frame ``track`` is given, before
        anything reads them: ``"none"`` (default) or ``"gaussian:SIGMA"`` (``dic.image_filter``).
    interpolation : str or dic.interpolation.Interpolation
        The B-spline IC-GN samples each frame with: ``"bspline3"`` (default), ``"bspline5"`` or ``"bspline7"``
        (``icgn`` only; ``dic.interpolation``).

    Attributes
    ----------
    x, y : ndarray of float64, shape (N,)
        Snapped point positions.
    frames_tracked : int
    last_refound : ndarray of bool, shape (N,)
        Points re-found by the wide search in the last ``track`` call.
    last_refind_attempts : int
        Points that the wide search was run for in the last call.
    last_seed_searches : int
        Points that the seeded search was run for in the last call (all trackable points
        for the surface-fit methods; only doubtful ones for IC-GN and Newton-Raphson).
    last_second_order : dict of str -> ndarray of float64, shape (N,), or None
        ``"icgn2"``: the second-order terms of the last frame (``dic.subpixel.icgn2.SECOND_ORDER``:
        uxx, uxy, uyy, vxx, vxy, vyy), NaN where not ok or refined below order 2; None otherwise.
    last_timings : dict of str -> int
        Nanoseconds per stage of the last ``track`` call, every key of ``TRACKER_STAGES`` (0 before
        the first call and for a stage that did not run); their sum is at most the call's wall time.

    Raises
    ------
    ValueError
        Bad image, points, subset, radii, threshold or method name.

    Examples
    --------
    >>> from livedic.dic.speckle import SpecklePattern, render
    >>> pattern = SpecklePattern((128, 128), n_speckles=250, seed=1)
    >>> tracker = Tracker(render(pattern), [(64, 64)], subpixel="icgn")
    >>> m = tracker.track(render(pattern, (0.4, -0.3)))
    >>> round(float(m.u[0]), 2), round(float(m.v[0]), 2)
    (0.4, -0.3)
    """

    def __init__(self, reference_image: np.ndarray, points: np.ndarray, *, subset: int = DEFAULT_SUBSET,
                 search: str = DEFAULT_SEARCH, subpixel: str = "icgn", seed_radius: int = 2,
                 refind_radius: int = DEFAULT_RADIUS, refind_zncc: float = REFIND_ZNCC, refind_drop: float = 0.05,
                 refind_gradient: float = 0.1, refind_search: str | None = None,
                 refind_fallback: str | None = "exhaustive", seed: int = 0, search_options: dict | None = None,
                 seed_search_options: dict | None = None, subpixel_options: dict | None = None,
                 gates: Gates = Gates(), prefilter: str | Prefilter = DEFAULT_PREFILTER,
                 interpolation: str | Interpolation = DEFAULT_INTERPOLATION):
        self.searching = search_method(search)
        self.method = subpixel_method(subpixel)
        self.interpolation = self.method.checked_interpolation(interpolation)
        if refind_search is None:
            refind_search = search if self.searching.searches else DEFAULT_SEARCH
        if refind_search not in _INTEGER_SEARCHES:
            raise ValueError(f"re-find search must be one of {', '.join(_INTEGER_SEARCHES)}, "
                             f"got {refind_search!r}")
        self.prefilter = Prefilter.parse(prefilter)
        self.reference = as_image(self.prefilter.apply(checked_image(reference_image, "reference")), "reference")
        self.half = check_subset(subset, self.reference.shape)
        self.subset = int(subset)
        self.seed_radius = check_radius(seed_radius)
        self.refind_radius = check_radius(refind_radius)
        for name, value in (("refind_zncc", refind_zncc), ("refind_drop", refind_drop),
                            ("refind_gradient", refind_gradient)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not -1.0 <= value <= 2.0:
                raise ValueError(f"{name} must be a number between -1 and 2 (ZNCC units), got {value!r}")
        self.refind_zncc = float(refind_zncc)
        self.refind_drop = float(refind_drop)
        self.refind_gradient = float(refind_gradient)
        self.search = search
        self.subpixel = subpixel
        self.refind_search = refind_search
        if refind_fallback is not None and refind_fallback not in _INTEGER_SEARCHES:
            raise ValueError(f"re-find fallback must be None or a search method, got {refind_fallback!r}")
        self.refind_fallback = refind_fallback if refind_fallback != refind_search else None
        self.seed = int(seed)
        self.search_options = search_options
        if seed_search_options is None:
            seed_search_options = dict(SEED_SWARM) if self.searching.swarm else search_options
        self.seed_search_options = seed_search_options
        self.subpixel_options = dict(subpixel_options or {})
        self._reference_options = self.method.pop_reference_options(self.subpixel_options)
        if self.method.prepared:
            self.subpixel_options.setdefault("max_iterations", ICGN_MAX_ITERATIONS)
        if not isinstance(gates, Gates):
            raise ValueError(f"gates must be a dic.quality.Gates, got {gates!r}")
        self.gates = gates
        xy = as_points(points)
        self._xs, self._ys = snap_points(xy)
        self.x = self._xs.astype(np.float64)
        self.y = self._ys.astype(np.float64)
        n = self._xs.shape[0]
        # a second-order method also starts each point from its previous second-order terms
        self._shape_terms = _SHAPE + self.method.shape_terms
        self._prev = {name: np.zeros(n) for name in ("u", "v") + self._shape_terms}
        self._prev_zncc = np.full(n, np.nan)
        self._good_u = np.zeros(n)
        self._good_v = np.zeros(n)
        self._good_grad = {name: np.zeros(n) for name in ("ux", "uy", "vx", "vy")}
        self._ever_good = np.zeros(n, dtype=bool)
        self._refind_wait = np.zeros(n, dtype=np.int64)    # frames to skip before the next wide search
        self._refind_skip = np.zeros(n, dtype=np.int64)
        self._ref_status = self._reference_status()
        self._prep: Any = None          # the method's prepared reference data (IC-GN), on the window
        self._window: tuple[int, int, int, int] | None = None
        self._allowance = 0
        self._graph = neighbour_graph(np.column_stack([self.x, self.y]))
        if self.method.prepared:
            self._prepare_window(_WINDOW_ALLOWANCE)
            prepared_status = self._first_order_prep().status      # the same points: either order's
            self._ref_status = np.where(self._ref_status != Status.OK, self._ref_status,
                                        prepared_status).astype(np.int8)
            texture = quality.texture(self._first_order_prep())
        else:
            texture = quality.texture(prepare_reference(self.reference, self._xs, self._ys, self.half))
        poor = texture.poor(gates) & (self._ref_status == Status.OK)
        self._ref_status[poor] = Status.POOR_TEXTURE
        # first-order methods fit a translation where one or two speckles cannot pin a 6-parameter warp
        self._order = np.where(texture.translation_only(gates), 0, max(self.method.shape_order, 1))
        self.trackable = self._ref_status == Status.OK
        self.frames_tracked = 0
        self.last_refound = np.zeros(self.n_points, dtype=bool)
        self.last_refind_attempts = 0
        self.last_seed_searches = 0
        self.last_second_order: dict[str, np.ndarray] | None = None
        self.last_timings = StageTimes().ns
        self._tested: Any = None
        self._spare: Any = None     # the IC-GN window's coefficients buffer, reused frame after frame

    def __getstate__(self):
        # a copy or a pickle (replay --workers) leaves the coefficients buffer behind: it is scratch
        state = self.__dict__.copy()
        state["_spare"] = None
        return state

    # ------------------------------------------------------------------ IC-GN window
    def _prepare_window(self, allowance):
        """Prepare IC-GN on the window holding every subset displaced by up to ``allowance`` px.

        The window (rows y0:y1, columns x0:x1) is the points' bounding box grown by
        the subset half-width, the interpolation margin, a guard for the B-spline
        prefilter's edge effects and ``allowance``; each frame is prefiltered on
        this window only, not on the whole image.
        """
        height, width = self.reference.shape
        reach = self.half + INTERPOLATION_MARGIN + _FILTER_GUARD[self.interpolation.degree] + int(allowance)
        x0 = max(int(self._xs.min()) - reach, 0)
        y0 = max(int(self._ys.min()) - reach, 0)
        x1 = min(int(self._xs.max()) + reach + 1, width)
        y1 = min(int(self._ys.max()) + reach + 1, height)
        if self._prep is not None and self._same_subsets((y0, y1, x0, x1)):
            # a larger window: the prepared subsets stay as they are (bit for bit), only their positions move
            old_y0, _, old_x0, _ = self._window
            self._prep = self.method.moved_data(self._prep, old_x0 - x0, old_y0 - y0, (y1 - y0, x1 - x0))
        else:
            window = np.ascontiguousarray(self.reference[y0:y1, x0:x1])
            self._prep = self.method.reference_data(prepare_reference(window, self._xs - x0, self._ys - y0,
                                                                      self.half), **self._reference_options)
        self._window = (y0, y1, x0, x1)
        self._allowance = int(allowance)
        self._window_full = (y0, x0) == (0, 0) and (y1, x1) == (height, width)

    def _same_subsets(self, window):
        """Whether ``icgn.prepare_reference`` computes every point's subset the same way in ``window`` as in the
        current one: the point clear of both windows' edges by the gradient stencil's reach (the same pixels are
        read), or as far from each edge in both (near an image edge both share)."""
        def rooms(bounds):
            y0, y1, x0, x1 = bounds
            return np.column_stack([self._xs - x0, x1 - 1 - self._xs, self._ys - y0, y1 - 1 - self._ys])
        new, now = rooms(window), rooms(self._window)
        clear = (new.min(axis=1) >= self.half + 2) & (now.min(axis=1) >= self.half + 2)
        return bool(np.all(clear | np.all(new == now, axis=1)))

    def _ensure_window(self, displacement):
        """Grow the IC-GN window (re-preparing the reference) if points may move ``displacement`` px."""
        if self._prep is None or self._window_full or not np.isfinite(displacement):
            return False
        if displacement <= self._allowance:
            return False
        self._prepare_window(max(2 * self._allowance, int(np.ceil(displacement)) + _WINDOW_ALLOWANCE))
        return True

    def _first_order_prep(self):
        """The first-order IC-GN reference data (a second-order method's extend them)."""
        return self.method.first_order_data(self._prep)

    def coefficients_ahead(self, image: np.ndarray, out: BSplineCoefficients | None = None
                           ) -> WindowCoefficients | None:
        """``image``'s IC-GN coefficients on the window as it stands, for ``track(image, ahead=...)``.

        Safe to call from another thread while ``track`` runs on an earlier frame: a live session
        prefilters each new frame in its acquisition thread, so the tracking thread only refines.
        ``track`` computes them again if its window has grown meanwhile. None for methods without
        a window. ``out``: a buffer of an earlier frame's to overwrite.
        """
        window = self._window
        if window is None or not self.trackable.any():      # nothing to refine: ``track`` makes none either
            return None
        filtered = self.prefilter.apply(checked_image(image, "frame"))     # as ``track`` filters it
        return WindowCoefficients(window, window_coefficients(filtered, window, out, self.interpolation.degree),
                                  filtered if self.prefilter.active else None)

    def _filtered(self, image: np.ndarray, ahead: WindowCoefficients | None) -> np.ndarray:
        """``image`` after the pre-filter: the one ``coefficients_ahead`` made when it came with ``ahead``."""
        checked = checked_image(image, "frame")
        if ahead is not None and ahead.filtered is not None and ahead.filtered.shape == checked.shape:
            return ahead.filtered
        return self.prefilter.apply(checked)

    @property
    def window(self) -> tuple[int, int, int, int] | None:
        """(y0, y1, x0, x1): the part of each frame IC-GN reads, or None (other methods read all)."""
        return self._window

    @property
    def n_points(self) -> int:
        return self._xs.shape[0]

    def _reference_status(self):
        """OUTSIDE_REFERENCE / FLAT_REFERENCE per point: the status of the ZNCC of the reference with itself."""
        status = np.empty(self._xs.shape[0], dtype=np.int8)
        _reference_status_batch(self.reference, self._xs, self._ys, self.half, status)
        return status

    # ------------------------------------------------------------------ guesses
    def _start(self):
        """Start displacement per point: previous result, else last good one, else nearest good neighbour's."""
        u = self._prev["u"].copy()
        v = self._prev["v"].copy()
        missing = ~np.isfinite(u) | ~np.isfinite(v)
        if missing.any():
            u[missing] = self._good_u[missing]
            v[missing] = self._good_v[missing]
            never = missing & ~self._ever_good
            if never.any():
                nu, nv = self._neighbour_guess(np.flatnonzero(never))
                u[never], v[never] = nu, nv
        return u, v

    def _frame_start(self):
        """The trackable points and every point's start (``_start``), the IC-GN window grown to hold them."""
        idx = np.flatnonzero(self.trackable)
        start_u, start_v = self._start()
        if idx.size:
            reach = max(self.seed_radius, self.refind_radius) + 2
            self._ensure_window(float(np.max(np.maximum(np.abs(start_u[idx]), np.abs(start_v[idx])))) + reach)
        return idx, start_u, start_v

    def _neighbour_guess(self, idx):
        """Displacement of the nearest point that has a good result (zeros if none)."""
        good = np.flatnonzero(self._ever_good & np.isfinite(self._prev["u"]))
        if good.size == 0:
            good = np.flatnonzero(self._ever_good)
        if good.size == 0:
            return np.zeros(idx.size), np.zeros(idx.size)
        nu = np.empty(idx.size)
        nv = np.empty(idx.size)
        gx, gy = self.x[good], self.y[good]
        for start in range(0, idx.size, 256):
            chunk = idx[start:start + 256]
            d2 = (self.x[chunk, None] - gx[None, :]) ** 2 + (self.y[chunk, None] - gy[None, :]) ** 2
            nearest = good[np.argmin(d2, axis=1)]
            nu[start:start + chunk.size] = self._good_u[nearest]
            nv[start:start + chunk.size] = self._good_v[nearest]
        return nu, nv

    def _gradients(self):
        """Start shape terms per point (gradients, and icgn2's second-order terms): previous ones, else 0."""
        grads = {}
        for name in self._shape_terms:
            g = self._prev[name]
            grads[name] = np.where(np.isfinite(g), g, 0.0)
        return grads

    # ------------------------------------------------------------------ measuring
    def _measure(self, target, idx, start_u, start_v, search, radius, grads, options):
        """Measure points ``idx`` from (start_u, start_v): search (unless "none") then sub-pixel."""
        if self._prep is not None:
            return self._measure_icgn(target, idx, start_u, start_v, search, radius, grads, options)
        points = np.column_stack([self.x[idx], self.y[idx]])
        guess = np.column_stack([start_u, start_v])
        return measure(self.reference, target.grey, points, subset=self.subset, search=search,
                       subpixel=self.subpixel, radius=radius, guess=guess, seed=self.seed,
                       search_options=options, subpixel_options=self.subpixel_options or None, gates=None,
                       interpolation=self.interpolation)

    def _measure_icgn(self, target, idx, start_u, start_v, search, radius, grads, options):
        """IC-GN on the prepared reference for the points ``idx`` only (after the seeded search, if any)."""
        status = None
        evaluations = None
        u0, v0 = start_u, start_v
        if search_method(search).searches:
            found = search_points(self.reference, target.grey, self._xs[idx], self._ys[idx], start_u, start_v,
                                  self.half, radius, search, seed=self.seed, margin=INTERPOLATION_MARGIN,
                                  options=options)
            ok = found.status == Status.OK
            # Where the search confirms the start's integer pixel, keep the start's fraction.
            same = ok & (found.u == np.floor(start_u + 0.5)) & (found.v == np.floor(start_v + 0.5))
            u0 = np.where(same, start_u, found.u)
            v0 = np.where(same, start_v, found.v)
            status = found.status
            evaluations = found.evaluations
            if ok.any():
                self._ensure_window(float(np.max(np.maximum(np.abs(found.u[ok]), np.abs(found.v[ok])))) + 2)
        result = self._kernel_job(idx, u0, v0, grads, status).run(self._target_coefficients())
        return self._measurement(idx, result, evaluations)

    def _kernel_job(self, idx, u0, v0, grads, status=None):
        """The prepared IC-GN run for the points ``idx`` from (u0, v0) and the shape terms ``grads``."""
        starts = tuple(f"{name}0" for name in self._shape_terms)
        options = {k: v for k, v in self.subpixel_options.items() if k not in starts}
        order = options.pop("order", self._order)
        if np.ndim(order) > 0:
            order = np.asarray(order)[idx]
        return KernelJob(self.method, self._prep, self._window, idx, u0, v0, grads, order, options, status,
                         self.interpolation.degree)

    def kernel_job(self) -> KernelJob | None:
        """The kernel stage of the next ``track`` on its own: a ``KernelJob``, or None (no IC-GN, no point).

        For timing the bare kernel against the tracker on the same points from the same start
        (``livedic.bench.tracker_cost``): ``job.run(job.coefficients(frame))`` is what the next
        ``track(frame)`` runs in its ``kernel`` stage. Calling it changes nothing the next ``track``
        would not (it may grow the IC-GN window as that ``track`` will).
        """
        if self._prep is None:
            return None
        idx, start_u, start_v = self._frame_start()
        if idx.size == 0:
            return None
        grads = self._gradients()
        return self._kernel_job(idx, start_u[idx], start_v[idx], {k: g[idx] for k, g in grads.items()})

    def _measurement(self, idx, result, evaluations=None):
        """The points ``idx``'s rows of a tracker result from a sub-pixel result (icgn2: with its 2nd-order terms)."""
        fields = dict(x=self.x[idx], y=self.y[idx], u=result.u, v=result.v, zncc=result.zncc,
                      ok=result.status == Status.OK, status=result.status, ux=result.ux, uy=result.uy,
                      vx=result.vx, vy=result.vy, iterations=result.iterations, evaluations=evaluations)
        if self.method.shape_terms:
            return _Curved(**fields, **{name: getattr(result, name) for name in SECOND_ORDER})
        return Measurement(**fields)

    def track(self, image: np.ndarray, *, ahead: WindowCoefficients | None = None) -> Measurement:
        """Displacement of every point from the reference to ``image``.

        Parameters
        ----------
        image : ndarray, shape (H, W)
            The new frame, same size as the reference.
        ahead : WindowCoefficients, optional
            ``image``'s coefficients from ``coefficients_ahead`` (used where the window is still theirs).

        Returns
        -------
        Measurement
            Per point: ``x, y`` (reference), ``u, v``, ``zncc``, ``ok``, ``status``,
            and ``ux, uy, vx, vy`` / ``iterations`` for first-order methods.

        Raises
        ------
        ValueError
            An image of another size or not 2-D grey.
        """
        times = StageTimes()
        with times.stage("prepare"):
            target = _Frame(self._filtered(image, ahead))
        if target.raw.shape != self.reference.shape:
            raise ValueError(f"frame is {target.raw.shape[1]}x{target.raw.shape[0]} but the reference is "
                             f"{self.reference.shape[1]}x{self.reference.shape[0]}: frames must keep the size")
        self._target = target
        self._coeffs = ahead
        idx, start_u, start_v = self._frame_start()
        if idx.size:
            with times.stage("prepare"):
                if self._prep is not None:
                    self._target_coefficients()
                else:
                    target.grey                 # the methods without IC-GN's window read the whole frame
        grads = self._gradients()
        on_demand = self.searching.searches and self.method.first_order
        self.last_seed_searches = 0
        result = None
        if idx.size:
            with times.stage("kernel"):
                first = self._measure(target, idx, start_u[idx], start_v[idx], NO_SEARCH if on_demand else self.search,
                                      self.seed_radius, {k: g[idx] for k, g in grads.items()},
                                      self.seed_search_options)
            if self._prep is not None and idx.size == self.n_points and first.evaluations is None:
                result = first                  # IC-GN measured every point: its fields are the frame's result's
            else:
                result = self._empty_result()
                self._scatter(result, idx, first)
            self.last_seed_searches = int(idx.size) if self.searching.searches and not on_demand else 0
        if result is None:
            result = self._empty_result()
        weak = self._search_doubtful(target, result, start_u, start_v, grads, times) if on_demand else None
        # Re-find the points that failed, lost correlation or disagree with their neighbours; not those
        # at the image's edge, whose material is leaving the view (_at_the_edge).
        with times.stage("gates"):
            weak = (self._weak(result) if weak is None else weak) | self._outliers(result)
        with times.stage("refind"):
            retry = self._refind_weak(target, result, weak, start_u, start_v, grads)
        with times.stage("gates"):
            self._gate(result)
        # Back off on points the wide search could not recover; reset on the others.
        recovered = self.last_refound | (result.ok & ~weak)
        self._refind_wait[recovered] = 0
        if retry.size:
            self._refind_wait[retry] = np.clip(2 * self._refind_wait[retry], 1, REFIND_MAX_WAIT)
            self._refind_skip[retry] = self._refind_wait[retry]
        self._remember(result)
        self.frames_tracked += 1
        self._target = None         # type: ignore[assignment]  # only inside track: its frame
        self._coeffs = None
        self.last_timings = times.ns
        if isinstance(result, _Curved):
            self.last_second_order = {name: getattr(result, name) for name in SECOND_ORDER}
            result = _take(result, slice(None), Measurement)
        return result

    def _search_doubtful(self, target, result, start_u, start_v, grads, times):
        """The on-demand seeded search of the points IC-GN from its start left doubtful (``result`` updated);
        returns the weak mask when nothing was searched (else None: the result is to be judged again)."""
        with times.stage("gates"):
            weak = self._weak(result)
            doubtful = np.flatnonzero(weak)
        if not doubtful.size:
            return weak
        self.last_seed_searches = int(doubtful.size)
        with times.stage("seeded_search"):
            again = self._measure(target, doubtful, start_u[doubtful], start_v[doubtful], self.search,
                                  self.seed_radius, {k: g[doubtful] for k, g in grads.items()},
                                  self.seed_search_options)
            self._keep_better(result, doubtful, again)
        return None

    def resume(self, previous: Measurement | None, *, last_good: dict[str, np.ndarray] | None = None) -> None:
        """Start the next ``track`` from a known earlier result, as if the frames before had been tracked here.

        ``track`` starts each frame from what it keeps of the frames before: the previous
        result (displacement, gradients, ZNCC) and each point's last ok result. Offline,
        where a recording holds what the tracker measured in every frame, setting that
        state from the recording lets any frame be measured on its own, in any order and
        on any machine (``livedic replay --workers``), by this same ``track``; with the
        recorded result of the frame tracked just before, IC-GN starts where the live
        tracker started.

        Parameters
        ----------
        previous : dic.result.Measurement or None
            The result of the frame tracked before (``u, v, zncc, ok`` and, for first-order
            methods, ``ux, uy, vx, vy``; shape (N,) in this tracker's point order). None: no
            frame before (the state of a new tracker, as for the reference frame).
        last_good : dict of str -> ndarray (N,), optional
            Each point's last ok result up to that frame: ``u, v`` and ``ux, uy, vx, vy``
            (0 where never ok, as ``track`` keeps them) and ``ever`` (bool: ok in some frame).
            Default: ``previous``'s own where ok, 0 elsewhere (no point lost before it).

        Not restored: the back-off of the wide re-find search (a point lost for several
        frames is searched for at once, not after waiting ``REFIND_MAX_WAIT`` frames), the
        IC-GN window (it grows as ``track`` needs it) and icgn2's second-order start terms
        (0: they are not part of a ``Measurement``; icgn2 refines them from there).

        Raises
        ------
        ValueError
            ``previous`` or ``last_good`` of another number of points.
        """
        n = self.n_points
        zeros = np.zeros(n)
        self._refind_wait = np.zeros(n, dtype=np.int64)
        self._refind_skip = np.zeros(n, dtype=np.int64)
        if previous is None:
            self._prev = {name: zeros.copy() for name in ("u", "v") + self._shape_terms}
            self._prev_zncc = np.full(n, np.nan)
            self._good_u, self._good_v = zeros.copy(), zeros.copy()
            self._good_grad = {name: zeros.copy() for name in _SHAPE}
            self._ever_good = np.zeros(n, dtype=bool)
            return
        ok = np.asarray(previous.ok, dtype=bool)
        if ok.shape != (n,):
            raise ValueError(f"resume: the earlier result has {ok.size} points, the tracker {n}")
        nan = np.full(n, np.nan)

        def where_ok(values, otherwise):
            return otherwise.copy() if values is None else np.where(ok, np.asarray(values, dtype=np.float64),
                                                                     otherwise)

        self._prev = {name: where_ok(getattr(previous, name, None), nan) for name in ("u", "v") + _SHAPE}
        for name in self._shape_terms[len(_SHAPE):]:
            self._prev[name] = zeros.copy()
        if previous.ux is None:
            for name in _SHAPE:
                self._prev[name] = zeros.copy()
        self._prev_zncc = where_ok(previous.zncc, nan)
        if last_good is None:
            last_good = {name: where_ok(getattr(previous, name, None), zeros) for name in ("u", "v") + _SHAPE}
            last_good["ever"] = ok
        for name in ("u", "v", "ever") + _SHAPE:
            if np.shape(last_good[name]) != (n,):
                raise ValueError(f"resume: last_good[{name!r}] is not one value per point ({n})")
        self._good_u = np.array(last_good["u"], dtype=np.float64)
        self._good_v = np.array(last_good["v"], dtype=np.float64)
        self._good_grad = {name: np.array(last_good[name], dtype=np.float64) for name in _SHAPE}
        self._ever_good = np.array(last_good["ever"], dtype=bool)

    def carry(self, fields: dict[str, np.ndarray]) -> None:
        """Start the next frame from ``fields`` instead of the displacements the frame just tracked gave.

        ``fields``: that frame's ``u, v, ok`` and, for first-order methods, ``ux, uy, vx, vy`` (N,), the same
        points ok and the same numbers up to rounding. ``dic.tracking.key_frames`` gives them as ``resume`` rebuilds them
        from a recording (through the composition to the first frame and back), so that a resumed frame starts
        where the sequence started it, bit for bit. icgn2's second-order start terms stay as tracked.
        """
        ok = np.asarray(fields["ok"], dtype=bool)
        for name in ("u", "v") + _SHAPE:
            values = fields.get(name)
            if values is not None:
                self._prev[name] = np.where(ok, values, np.nan)
        self._good_u = np.where(ok, fields["u"], self._good_u)
        self._good_v = np.where(ok, fields["v"], self._good_v)
        for name in _SHAPE:
            if fields.get(name) is not None:
                self._good_grad[name] = np.where(ok, fields[name], self._good_grad[name])

    def _gate(self, result):
        """The quality gates on the frame's result (in place): LOW_CORRELATION, OUTLIER; NaN where not ok."""
        known = None
        if self._tested is not None:
            inputs, flagged = self._tested
            if all(_same_bits(a, b) for a, b in zip(inputs[1:], _median_test_inputs(result)[1:])):
                known = (inputs[0], flagged)       # the same u, v and gradients: the same test over the same ok
        self._tested = None
        status = quality.gate_status(result.status, result.zncc, self.x, self.y, result.u, result.v, self._graph,
                                     self.gates, gradients=_gradients_of(result), known_outliers=known)
        result.status[:] = status
        result.ok[:] = status == Status.OK
        bad = ~result.ok
        for name in ("u", "v") + self._shape_terms:
            values = getattr(result, name)
            if values is not None:
                values[bad] = np.nan

    def _target_coefficients(self):
        """B-spline coefficients of the current frame on the IC-GN window (computed once per window)."""
        if self._coeffs is None or self._coeffs.window != self._window:
            # the previous frame's buffer is reused (no fresh pages to fault in every frame)
            self._spare = window_coefficients(self._target.raw, self._window, out=self._spare,
                                              degree=self.interpolation.degree)
            self._coeffs = WindowCoefficients(self._window, self._spare)
        return self._coeffs.coefficients

    def _empty_result(self):
        n = self.n_points
        nan = np.full(n, np.nan)
        first_order = self.method.first_order
        fields = dict(x=self.x.copy(), y=self.y.copy(), u=nan.copy(), v=nan.copy(), zncc=nan.copy(),
                      ok=np.zeros(n, dtype=bool), status=self._ref_status.copy(),
                      ux=nan.copy() if first_order else None, uy=nan.copy() if first_order else None,
                      vx=nan.copy() if first_order else None, vy=nan.copy() if first_order else None,
                      iterations=np.zeros(n, dtype=np.int64) if first_order else None)
        if self.method.shape_terms:
            return _Curved(**fields, **{name: nan.copy() for name in SECOND_ORDER})
        return Measurement(**fields)

    @staticmethod
    def _scatter(result, idx, part):
        for name in ("u", "v", "zncc", "ok", "status"):
            getattr(result, name)[idx] = getattr(part, name)
        for name in ("ux", "uy", "vx", "vy", "iterations") + SECOND_ORDER:
            target = getattr(result, name, None)
            values = getattr(part, name, None)
            if target is not None and values is not None:
                target[idx] = values

    def _remember(self, result):
        ok = result.ok
        self._prev["u"] = np.where(ok, result.u, np.nan)
        self._prev["v"] = np.where(ok, result.v, np.nan)
        for name in self._shape_terms:
            values = getattr(result, name)
            self._prev[name] = np.where(ok, values, np.nan) if values is not None else np.zeros(self.n_points)
        self._prev_zncc = np.where(ok, result.zncc, np.nan)
        self._good_u = np.where(ok, result.u, self._good_u)
        self._good_v = np.where(ok, result.v, self._good_v)
        for name in ("ux", "uy", "vx", "vy"):
            values = getattr(result, name)
            if values is not None:
                self._good_grad[name] = np.where(ok, values, self._good_grad[name])
        self._ever_good |= ok


class _Frame:
    """The frame ``track`` measures: as given (``raw``; IC-GN prefilters its window of it) and, made
    when a search first needs it, as the float32 image the searches read (``grey``)."""
    __slots__ = ("raw", "_grey")

    def __init__(self, raw: np.ndarray):
        self.raw = raw
        self._grey: np.ndarray | None = None

    @property
    def grey(self) -> np.ndarray:
        if self._grey is None:
            self._grey = as_image(self.raw, "frame")
        return self._grey
