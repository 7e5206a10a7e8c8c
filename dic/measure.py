"""``measure``: integer-pixel search followed by sub-pixel refinement, for many points."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from livedic.dic import quality
from livedic.dic.bspline import INTERPOLATION_MARGIN
from livedic.dic.correlation import DEFAULT_SUBSET, _zncc_batch, snap_points
from livedic.dic.image_filter import DEFAULT_PREFILTER, Prefilter
from livedic.dic.interpolation import DEFAULT_INTERPOLATION, Interpolation
from livedic.dic.neighbours import neighbour_graph
from livedic.dic.quality import Gates
from livedic.dic.reliability_guided import ICGN_OPTIONS, guided_icgn
from livedic.dic.result import Measurement, SubpixelResult
from livedic.dic.search import (DEFAULT_RADIUS, DEFAULT_SEARCH, NO_SEARCH, SEARCH_METHODS as _INTEGER_SEARCHES,
                                SearchMethod, search_method, search_points)
from livedic.dic.status import Status
from livedic.dic.subpixel import icgn
from livedic.dic.subpixel.method import SUBPIXEL_METHODS, SubpixelMethod, subpixel_method
from livedic.dic.validation import as_guess, as_image, as_points, check_radius, check_same_shape, check_subset

# The integer searches, and "none": start the sub-pixel method from the guess.
SEARCH_METHODS = _INTEGER_SEARCHES + (NO_SEARCH,)



def measure(reference: np.ndarray, deformed: np.ndarray, points: ArrayLike, *, subset: int = DEFAULT_SUBSET,
            search: str = DEFAULT_SEARCH, subpixel: str = "improved-surface-fit", radius: int = DEFAULT_RADIUS,
            guess: ArrayLike | None = None, seed: int = 0, search_options: dict | None = None,
            subpixel_options: dict | None = None, guided: bool = True, gates: Gates | None = Gates(),
            prefilter: str | Prefilter | None = DEFAULT_PREFILTER,
            interpolation: str | Interpolation | None = DEFAULT_INTERPOLATION) -> Measurement:
    """Displacement of each point from ``reference`` to ``deformed``.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images (any integer or float dtype) of equal size.
    points : array_like, shape (N, 2)
        (x, y) pixel positions in the reference; snapped to the nearest pixel centre.
    subset : int
        Odd side of the square subset, pixels.
    search : str
        Integer-pixel search: one of ``SEARCH_METHODS``. ``"none"`` skips the
        search and starts the sub-pixel method from ``guess``.
    subpixel : str
        Sub-pixel method: one of ``SUBPIXEL_METHODS``.
    radius : int
        Integer search radius (around the guess, or around 0 without one), pixels.
    guess : array_like, shape (2,) or (N, 2), optional
        Initial (u, v) per point (e.g. the previous frame's result). Rows with NaN
        are flagged ``Status.BAD_GUESS``. Without a guess the measurement is
        reliability-guided (``guided``).
    seed : int
        Seed of the stochastic searches (PSO, WSO); the same seed gives the same result.
    search_options, subpixel_options : dict, optional
        Method parameters passed through (see each method's module).
    guided : bool
        Without a guess: measure a few seeds over the full radius and propagate
        to neighbours (``dic.reliability_guided``), instead of searching every
        point over the full radius (``False``). Ignored with a guess or
        ``search="none"``.
    gates : dic.quality.Gates or None
        Quality gates (``dic.quality``): a point is ok only if it passes them.
        None returns the solver's own status (for callers that gate themselves).
    prefilter : str or dic.image_filter.Prefilter or None
        Image pre-filter applied to both images before anything reads them: ``"none"`` (default; None too) or
        ``"gaussian:SIGMA"`` (``dic.image_filter``).
    interpolation : str or dic.interpolation.Interpolation or None
        The B-spline IC-GN samples the deformed image with: ``"bspline3"`` (default; None too), ``"bspline5"``
        or ``"bspline7"`` (``icgn`` only; ``dic.interpolation``).

    Returns
    -------
    Measurement
        ``x, y, u, v, zncc, ok, status`` per point, plus ``ux, uy, vx, vy`` for
        first- and second-order methods (``newton-raphson``, ``icgn``, ``icgn2``; NaN where the subset
        was too poorly textured for a first-order warp and a translation was
        fitted), ``iterations`` for iterative ones and ``evaluations`` (ZNCC
        evaluations of the search). Content at (x, y) in the reference is found
        at (x + u, y + v) in the deformed image; u is along x (columns), v along
        y (rows). ``u, v`` (and gradients) are NaN where ``ok`` is False; ``zncc``
        keeps the value that was judged.

    Raises
    ------
    ValueError
        Images of different size or not 2-D, bad subset, radius, points, guess,
        method name, pre-filter or interpolation; the message says what to change.

    Examples
    --------
    >>> from livedic.dic.speckle import SpecklePattern, render
    >>> pattern = SpecklePattern((128, 128), n_speckles=250, seed=1)
    >>> ref, dfm = render(pattern), render(pattern, (2.3, -1.4))
    >>> m = measure(ref, dfm, [(64, 64)], subpixel="icgn")
    >>> round(float(m.u[0]), 2), round(float(m.v[0]), 2), bool(m.ok[0])
    (2.3, -1.4, True)
    """
    searching = search_method(search)
    method = subpixel_method(subpixel)
    if gates is not None and not isinstance(gates, Gates):
        raise ValueError(f"gates must be a dic.quality.Gates or None, got {gates!r}")
    degree = method.checked_interpolation(interpolation).degree
    filtering = Prefilter.parse(prefilter)
    reference = filtering.apply(as_image(reference, "reference"))
    deformed = filtering.apply(as_image(deformed, "deformed"))
    check_same_shape(reference, deformed)
    half = check_subset(subset, reference.shape)
    radius = check_radius(radius)
    xy = as_points(points)
    xs, ys = snap_points(xy)
    icgn_options = dict(subpixel_options or {}) if method.prepared else {}
    # IC-GN's reference data also give the texture gates (dic.quality.texture)
    prep = icgn.prepare_reference(reference, xs, ys, half, hessian=icgn_options.pop("hessian", "projected"))
    texture = quality.texture(prep)
    thresholds = gates or Gates()
    prep = method.reference_data(prep, **method.pop_reference_options(icgn_options))
    translation_only = texture.translation_only(thresholds) if method.first_order else None
    guided = guess is None and guided and searching.searches and xs.shape[0] > 0
    # neighbours serve the propagation and the median test only (a tracker that gates itself needs neither)
    graph = neighbour_graph(np.column_stack([xs, ys]).astype(np.float64)) if guided or gates is not None else None
    if guided:
        poor = texture.poor(thresholds)
        raw = _guided(reference, deformed, prep, searching, method, radius, seed, search_options, subpixel_options,
                      icgn_options, thresholds, texture, poor, translation_only, graph, degree=degree)
    else:
        start = as_guess(guess, xs.shape[0])
        raw = _solve(reference, deformed, prep, start, searching, method, radius, seed, search_options,
                     subpixel_options, icgn_options, translation_only, degree=degree)
    status = raw.status
    if gates is not None:
        gradients = None if raw.ux is None else (raw.ux, raw.uy, raw.vx, raw.vy)
        status = quality.gate_status(status, raw.zncc, xs, ys, raw.u, raw.v, graph, gates, gradients=gradients,
                                     poor_texture=texture.poor(gates))
    return _finish(xs, ys, raw, status, translation_only)


def _finish(xs, ys, raw, status, translation_only):
    """The Measurement: NaN displacements (and gradients) wherever the status is not OK."""
    ok = status == Status.OK

    def masked(values, also=None):
        if values is None:
            return None
        bad = ~ok if also is None else ~ok | also
        return np.where(bad, np.nan, values)

    grads = {name: masked(getattr(raw, name), translation_only) for name in ("ux", "uy", "vx", "vy")}
    return Measurement(x=xs.astype(np.float64), y=ys.astype(np.float64), u=masked(raw.u), v=masked(raw.v),
                       zncc=raw.zncc, ok=ok, status=status, iterations=raw.iterations,
                       evaluations=raw.evaluations, **grads)


def _solve(reference, deformed, prep, start, search: SearchMethod, method: SubpixelMethod, radius, seed, search_options,
           subpixel_options, icgn_options, translation_only, *, degree=3):
    """Search around ``start`` (unless ``search`` does not search), then the sub-pixel method; no gates.
    ``degree``: of the B-spline prepared methods sample the deformed image with."""
    first = method.first_order_data(prep)
    xs, ys, half = first.xs, first.ys, first.half
    margin = method.margin
    if not search.searches:
        u0 = start[:, 0].copy()
        v0 = start[:, 1].copy()
        status = _start_status(reference.shape, xs, ys, u0, v0, half, margin)
        zncc = np.full(xs.shape[0], np.nan)
        evaluations = None
        if not method.first_order:
            # These methods work around an integer peak.
            u0, v0 = np.floor(u0 + 0.5), np.floor(v0 + 0.5)
    else:
        found = search_points(reference, deformed, xs, ys, start[:, 0], start[:, 1], half, radius,
                              search.name, seed=seed, margin=margin, options=search_options)
        u0 = found.u.astype(np.float64)
        v0 = found.v.astype(np.float64)
        status = found.status.copy()
        zncc = found.zncc
        evaluations = found.evaluations
    return _refine(reference, deformed, prep, u0, v0, status, zncc, evaluations, not search.searches, method, seed,
                   subpixel_options, icgn_options, translation_only, degree=degree)


def _refine(reference, deformed, prep, u0, v0, status, zncc, evaluations, from_guess, method: SubpixelMethod, seed,
            subpixel_options, icgn_options, translation_only, gradients=None, degree=3):
    """The sub-pixel stage from integer (or float) starts; first-order methods fit a translation where told."""
    first = method.first_order_data(prep)
    xs, ys, half = first.xs, first.ys, first.half
    if method.module is None:
        ok_mask = status == Status.OK
        if from_guess:
            zncc = np.full(xs.shape[0], np.nan)
            st = np.zeros(xs.shape[0], dtype=np.int8)
            _zncc_batch(reference, deformed, xs, ys, np.where(ok_mask, u0, 0).astype(np.int64),
                        np.where(ok_mask, v0, 0).astype(np.int64), half, zncc, st)
            status = np.where(ok_mask, st, status).astype(np.int8)
            ok_mask = status == Status.OK
        return SubpixelResult(u=np.where(ok_mask, u0, np.nan), v=np.where(ok_mask, v0, np.nan),
                              zncc=np.where(ok_mask, zncc, np.nan), status=status, evaluations=evaluations)
    options = dict(icgn_options) if method.prepared else dict(subpixel_options or {})
    if method.seeded:
        options.setdefault("seed", seed)
    if gradients is not None:
        for name, values in gradients.items():
            options.setdefault(f"{name}0", values)
    # first-order methods: a rigid shift where the texture cannot pin an affine warp
    split = translation_only is not None and translation_only.any() and options.get("order", 1) != 0
    if method.prepared:
        if split:
            # per-point shape function
            options["order"] = np.where(translation_only, 0, options.get("order", method.shape_order))
        refined = method.refine_prepared(prep, icgn.prepare_target(deformed, degree=degree), u0, v0, status=status,
                                         **options)
    elif split:
        refined = _refine_by_order(method.module, reference, deformed, xs, ys, u0, v0, status, half, options,
                                   translation_only)
    else:
        refined = method.module.refine(reference, deformed, xs, ys, u0, v0, status, half, **options)
    refined.evaluations = evaluations
    return refined


def _refine_by_order(method, reference, deformed, xs, ys, u0, v0, status, half, options, translation_only):
    """``method.refine`` affine on the points where ``translation_only`` is False, rigid shift on the others.

    One call per shape function, each on its own points (start gradients, given
    one per point, follow them); the two results are merged, gradients NaN at
    the shift points.
    """
    n = xs.shape[0]
    merged = SubpixelResult(u=np.full(n, np.nan), v=np.full(n, np.nan), zncc=np.full(n, np.nan),
                            status=np.empty(n, dtype=np.int8), ux=np.full(n, np.nan), uy=np.full(n, np.nan),
                            vx=np.full(n, np.nan), vy=np.full(n, np.nan), iterations=np.zeros(n, dtype=np.int64))
    for points, order in ((np.flatnonzero(~translation_only), {}), (np.flatnonzero(translation_only), {"order": 0})):
        if points.size == 0:
            continue
        part_options = {name: np.broadcast_to(value, (n,))[points] if name in _START_GRADIENTS and value is not None
                        else value for name, value in options.items()}
        part = method.refine(reference, deformed, xs[points], ys[points], u0[points], v0[points], status[points],
                             half, **{**part_options, **order})
        for name in ("u", "v", "zncc", "status", "iterations", "ux", "uy", "vx", "vy"):
            values = getattr(part, name)
            if values is not None:
                getattr(merged, name)[points] = values
    return merged


_START_GRADIENTS = ("ux0", "uy0", "vx0", "vy0")


def _guided(reference, deformed, prep, search: SearchMethod, method: SubpixelMethod, radius, seed, search_options, subpixel_options,
            icgn_options, gates, texture, poor, translation_only, graph, *, degree=3):
    """Reliability-guided measurement (``dic.reliability_guided``), then the chosen sub-pixel method."""
    first = method.first_order_data(prep)
    xs, ys, half = first.xs, first.ys, first.half
    coeffs = icgn.prepare_target(deformed, degree=degree)
    options = dict(icgn_options)
    # the propagation is first-order IC-GN (icgn2 refines every point from its result below)
    order = np.where(texture.translation_only(gates), 0, np.minimum(options.pop("order", 1), 1))

    def full_search(idx):
        zero = np.zeros(idx.size)
        found = search_points(reference, deformed, xs[idx], ys[idx], zero, zero, half, radius, search.name, seed=seed,
                              margin=INTERPOLATION_MARGIN, options=search_options)
        return found.u, found.v, found.status, found.evaluations

    def outliers(params, ok):
        flagged, _ = quality.median_test(xs, ys, params[:, 0], params[:, 3], ok, graph,
                                         gradients=(params[:, 1], params[:, 2], params[:, 4], params[:, 5]),
                                         epsilon=gates.outlier_epsilon, threshold=gates.outlier_threshold)
        return flagged

    params, status, zncc, iterations, evaluations = guided_icgn(
        first, coeffs, full_search, graph, order=order, accept=gates.min_zncc, energy=texture.energy,
        active=~poor, options={k: v for k, v in options.items() if k in ICGN_OPTIONS}, repair=outliers)
    if method.final_after_guidance:
        return SubpixelResult(u=params[:, 0], v=params[:, 3], zncc=zncc, status=status, ux=params[:, 1],
                              uy=params[:, 2], vx=params[:, 4], vy=params[:, 5], iterations=iterations,
                              evaluations=evaluations)
    # other methods refine from the guided integer position (and gradients, for Newton-Raphson)
    ok = status == Status.OK
    u0 = np.where(ok, np.floor(params[:, 0] + 0.5), 0.0)
    v0 = np.where(ok, np.floor(params[:, 3] + 0.5), 0.0)
    gradients = None
    if method.first_order:
        u0, v0 = np.where(ok, params[:, 0], 0.0), np.where(ok, params[:, 3], 0.0)
        gradients = {name: np.where(ok, params[:, c], 0.0) for name, c in (("ux", 1), ("uy", 2), ("vx", 4), ("vy", 5))}
    return _refine(reference, deformed, prep, u0, v0, status.copy(), np.where(ok, zncc, np.nan), evaluations,
                   method.module is None, method, seed, subpixel_options, icgn_options, translation_only,
                   gradients=gradients, degree=degree)


def _start_status(shape, xs, ys, u0, v0, half, margin):
    """Status of each point before refinement when there is no search: where it starts."""
    height, width = shape
    status = np.zeros(xs.shape[0], dtype=np.int8)
    inside_ref = (xs - half >= 0) & (ys - half >= 0) & (xs + half < width) & (ys + half < height)
    finite = np.isfinite(u0) & np.isfinite(v0)
    reach = half + margin
    tx = np.where(finite, np.floor(np.nan_to_num(xs + u0) + 0.5), 0)
    ty = np.where(finite, np.floor(np.nan_to_num(ys + v0) + 0.5), 0)
    inside_tar = (tx - reach >= 0) & (ty - reach >= 0) & (tx + reach < width) & (ty + reach < height)
    status[~inside_tar] = Status.OUTSIDE_TARGET
    status[~finite] = Status.BAD_GUESS
    status[~inside_ref] = Status.OUTSIDE_REFERENCE
    return status


__all__ = ["measure", "SEARCH_METHODS", "SUBPIXEL_METHODS"]
