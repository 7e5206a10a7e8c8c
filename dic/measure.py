"""``measure``: integer-pixel search followed by sub-pixel refinement, for many points."""

import importlib

import numpy as np

from dic.correlation import snap_points
from dic.result import Measurement
from dic.status import Status
from dic.validation import as_guess, as_image, as_points, check_radius, check_same_shape, check_subset

SEARCH_METHODS = ("exhaustive", "fft-cc", "coarse-fine", "pso", "wso", "improved-wso", "none")

# Sub-pixel method -> (module, extra pixels its interpolation/fit needs beyond the subset).
_SUBPIXEL = {
    "none": (None, 0),
    "surface-fit": ("dic.subpixel.surface_fit", 1),
    "gradient": ("dic.subpixel.gradient_method", 2),
    "newton-raphson": ("dic.subpixel.newton_raphson", 3),
    "improved-surface-fit": ("dic.subpixel.improved_surface_fit", 3),
    "icgn": ("dic.subpixel.icgn", 3),
}
SUBPIXEL_METHODS = tuple(_SUBPIXEL)
# Sub-pixel methods that run a stochastic optimiser and so take the seed.
_SEEDED_SUBPIXEL = ("surface-fit", "improved-surface-fit")


def measure(reference, deformed, points, *, subset=21, search="improved-wso",
            subpixel="improved-surface-fit", radius=16, guess=None, seed=0,
            search_options=None, subpixel_options=None):
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
        Integer search radius around the guess, pixels.
    guess : array_like, shape (2,) or (N, 2), optional
        Initial (u, v) per point (e.g. the previous frame's result); zero if omitted.
        Rows with NaN are flagged ``Status.BAD_GUESS``.
    seed : int
        Seed of the stochastic searches (PSO, WSO); the same seed gives the same result.
    search_options, subpixel_options : dict, optional
        Method parameters passed through (see each method's module).

    Returns
    -------
    Measurement
        ``x, y, u, v, zncc, ok, status`` per point, plus ``ux, uy, vx, vy`` for
        first-order methods (``newton-raphson``, ``icgn``), ``iterations`` for
        iterative ones and ``evaluations`` (ZNCC evaluations of the search).
        Content at (x, y) in the reference is found at (x + u, y + v) in the
        deformed image; u is along x (columns), v along y (rows).

    Raises
    ------
    ValueError
        Images of different size or not 2-D, bad subset, radius, points, guess
        or method name; the message says what to change.

    Examples
    --------
    >>> from dic.speckle import SpecklePattern, render
    >>> pattern = SpecklePattern((128, 128), n_speckles=250, seed=1)
    >>> ref, dfm = render(pattern), render(pattern, (2.3, -1.4))
    >>> m = measure(ref, dfm, [(64, 64)], subpixel="icgn")
    >>> round(float(m.u[0]), 2), round(float(m.v[0]), 2), bool(m.ok[0])
    (2.3, -1.4, True)
    """
    if search not in SEARCH_METHODS:
        raise ValueError(f"unknown search method {search!r}: choose one of {', '.join(SEARCH_METHODS)}")
    if subpixel not in _SUBPIXEL:
        raise ValueError(f"unknown sub-pixel method {subpixel!r}: choose one of {', '.join(SUBPIXEL_METHODS)}")
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    half = check_subset(subset, reference.shape)
    radius = check_radius(radius)
    xy = as_points(points)
    start = as_guess(guess, xy.shape[0])
    xs, ys = snap_points(xy)
    module_name, margin = _SUBPIXEL[subpixel]

    if search == "none":
        u0 = start[:, 0].copy()
        v0 = start[:, 1].copy()
        status = _start_status(reference.shape, xs, ys, u0, v0, half, margin)
        zncc = np.full(xs.shape[0], np.nan)
        evaluations = None
        if subpixel in ("surface-fit", "improved-surface-fit", "gradient", "none"):
            # These methods work around an integer peak.
            u0, v0 = np.floor(u0 + 0.5), np.floor(v0 + 0.5)
    else:
        from dic.search import search_points
        found = search_points(reference, deformed, xs, ys, start[:, 0], start[:, 1], half, radius,
                              search, seed=seed, margin=margin, options=search_options)
        u0 = found.u.astype(np.float64)
        v0 = found.v.astype(np.float64)
        status = found.status.copy()
        zncc = found.zncc
        evaluations = found.evaluations

    if module_name is None:
        ok_mask = status == Status.OK
        if search == "none":
            from dic.correlation import _zncc_batch
            zncc = np.full(xs.shape[0], np.nan)
            st = np.zeros(xs.shape[0], dtype=np.int8)
            _zncc_batch(reference, deformed, xs, ys, np.where(ok_mask, u0, 0).astype(np.int64),
                        np.where(ok_mask, v0, 0).astype(np.int64), half, zncc, st)
            status = np.where(ok_mask, st, status).astype(np.int8)
            ok_mask = status == Status.OK
        u = np.where(ok_mask, u0, np.nan)
        v = np.where(ok_mask, v0, np.nan)
        return Measurement(x=xs.astype(np.float64), y=ys.astype(np.float64), u=u, v=v,
                           zncc=np.where(ok_mask, zncc, np.nan), ok=ok_mask, status=status,
                           evaluations=evaluations)

    method = importlib.import_module(module_name)
    options = dict(subpixel_options or {})
    if subpixel in _SEEDED_SUBPIXEL:
        options.setdefault("seed", seed)
    refined = method.refine(reference, deformed, xs, ys, u0, v0, status, half, **options)
    ok_mask = refined.status == Status.OK
    return Measurement(x=xs.astype(np.float64), y=ys.astype(np.float64), u=refined.u, v=refined.v,
                       zncc=refined.zncc, ok=ok_mask, status=refined.status,
                       ux=refined.ux, uy=refined.uy, vx=refined.vx, vy=refined.vy,
                       iterations=refined.iterations, evaluations=evaluations)


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
