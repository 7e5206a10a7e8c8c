"""Integer-pixel search: find, per point, the integer displacement maximising ZNCC.

Methods (``SEARCH_METHODS``), one module each:

* ``"exhaustive"`` -- every position of the box (:mod:`dic.search.exhaustive`); the truth.
* ``"fft-cc"`` -- the same ZNCC map as exhaustive, computed by FFT (:mod:`dic.search.fft_cc`).
* ``"coarse-fine"`` -- lattice of step ``step`` then the full fine window (:mod:`dic.search.coarse_fine`).
* ``"pso"`` -- inertia-weight particle swarm (:mod:`dic.search.pso`).
* ``"wso"`` -- original White Shark Optimizer, ``variant="code"|"paper"`` (:mod:`dic.search.wso`).
* ``"improved-wso"`` -- the paper's improved WSO plus neighbour hill climb (:mod:`dic.search.improved_wso`).

Every search reports per point ``evaluations`` (distinct positions whose ZNCC
was computed: each point caches its box) and ``calls`` (fitness calls, repeats
included). The stochastic ones draw from a per-point SplitMix64 stream seeded
with ``(seed, point index)``, so results do not depend on the number of threads.

Measured success, evaluations and time of all of them: ``livedic bench paper``
(Figs 9/10 at radius 10 and a radius study up to 48 px; tables in
:mod:`dic.search.improved_wso`). In short, the improved WSO, run on an image
pyramid (:mod:`dic.search.pyramid`), finds the exhaustive optimum in every
search at radius 10-48 on six pattern generators with 62-174 distinct
evaluations a point; coarse-fine step 3 needs 73-1,113 and misses 0.02-0.4 %,
PSO and the original WSO fall to 41 % and 16 % at radius 48. ``"fft-cc"``
gives the exhaustive answer in 3.5-8.4x less time than ``"exhaustive"`` at
radius 10-48. For a seeded search with a small radius (tracking), ``"exhaustive"`` is
the cheapest: at radius 2 it costs 25 evaluations.
"""

from collections.abc import Mapping
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.dic.correlation import DEFAULT_SUBSET
from livedic.dic.result import IntegerSearchResult
from livedic.dic.search import coarse_fine, exhaustive, fft_cc, improved_wso, pso, wso
from livedic.dic.method_options import resolve_options, seed_to_uint
from livedic.dic.search._common import new_outputs, search_boxes
from livedic.dic.search.pyramid import levels_for, pyramid_search
from livedic.dic.validation import as_guess, as_image, as_points, check_radius, check_same_shape, check_subset

# Search method -> its module (DEFAULTS, CHECKS and the kernel).
_MODULES = {
    "exhaustive": exhaustive,
    "fft-cc": fft_cc,
    "coarse-fine": coarse_fine,
    "pso": pso,
    "wso": wso,
    "improved-wso": improved_wso,
}
# The integer searches; ``dic.measure.SEARCH_METHODS`` adds "none" (no search: start from the guess).
SEARCH_METHODS = tuple(_MODULES)
# No integer search: the sub-pixel method starts from the guess (``dic.measure``, ``dic.tracking``).
NO_SEARCH = "none"
# The integer search, and its box's half-side (px), that measure, track and the commands use unless told otherwise.
DEFAULT_SEARCH = "improved-wso"
DEFAULT_RADIUS = 16


@dataclass(frozen=True)
class SearchMethod:
    """An integer search as measure and tracking ask of it (they never compare its name).

    ``module`` holds its ``DEFAULTS``, ``CHECKS`` and kernel; None for ``"none"``, no search.
    """
    name: str
    module: ModuleType | None

    @property
    def searches(self) -> bool:
        """It searches (``"none"`` does not: the sub-pixel method starts from the guess)."""
        return self.module is not None

    @property
    def swarm(self) -> bool:
        """A population search (a swarm of candidates over iterations): a seeded search sizes it down."""
        return self.module is not None and "population" in self.module.DEFAULTS

    def __reduce__(self) -> tuple:
        return search_method, (self.name,)        # pickled by name (replay --workers), not with its module


SEARCHES: dict[str, SearchMethod] = {**{name: SearchMethod(name, module) for name, module in _MODULES.items()},
                                     NO_SEARCH: SearchMethod(NO_SEARCH, None)}


def search_method(name: str) -> SearchMethod:
    """The search called ``name`` (``"none"`` included); ValueError (one line) naming the choices otherwise."""
    try:
        return SEARCHES[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown search method {name!r}: choose one of {', '.join(SEARCHES)}") from None


def method_options(method: str) -> dict[str, Any]:
    """Default options of a search method (a copy), e.g. ``method_options("pso")["population"]``."""
    _check_method(method)
    return dict(_MODULES[method].DEFAULTS)


def _check_method(method: str) -> None:
    if method not in _MODULES:
        raise ValueError(f"unknown search method {method!r}: choose one of {', '.join(SEARCH_METHODS)}")


def search_points(reference: np.ndarray, deformed: np.ndarray, xs: np.ndarray, ys: np.ndarray, guess_u: np.ndarray,
                  guess_v: np.ndarray, half: int, radius: int, method: str, *, seed: int = 0, margin: int = 0,
                  options: Mapping[str, Any] | None = None) -> IntegerSearchResult:
    """Integer search for already validated inputs (the kernel entry used by ``dic.measure``).

    Parameters
    ----------
    reference, deformed : ndarray of float32, shape (H, W)
        C-contiguous images of equal size.
    xs, ys : ndarray of int64, shape (N,)
        Snapped point positions.
    guess_u, guess_v : ndarray of float64, shape (N,)
        Initial guess; the box is ``round(guess) +- radius``. NaN -> ``Status.BAD_GUESS``.
    half : int
        Subset half-width.
    radius : int
        Search radius, pixels.
    method : str
        One of ``SEARCH_METHODS``.
    seed : int
        Seed of the stochastic methods.
    margin : int
        Extra pixels the target subset must keep from the image edge (room for the
        interpolation of a later sub-pixel stage); the box is clipped accordingly.
    options : dict, optional
        Method parameters (see ``method_options(method)``).

    Returns
    -------
    IntegerSearchResult
        u, v are 0 and zncc NaN where status is not OK.

    Raises
    ------
    ValueError
        Unknown method or option, or a bad option value.

    Notes
    -----
    Status precedence: OUTSIDE_REFERENCE, FLAT_REFERENCE, BAD_GUESS,
    OUTSIDE_TARGET (box empty once clipped to the image), FLAT_TARGET (the best
    match has no texture).
    """
    _check_method(method)
    module = _MODULES[method]
    params = resolve_options(method, options, module.DEFAULTS, module.CHECKS)
    stream_seed = seed_to_uint(seed)
    xs = np.ascontiguousarray(xs, dtype=np.int64)
    ys = np.ascontiguousarray(ys, dtype=np.int64)
    guess_u = np.asarray(guess_u, dtype=np.float64)
    guess_v = np.asarray(guess_v, dtype=np.float64)
    ulo, uhi, vlo, vhi, cu, cv, status = search_boxes(deformed.shape, xs, ys, guess_u, guess_v, int(half),
                                                      int(radius), int(margin))
    outputs = new_outputs(xs.shape[0])
    levels = levels_for(int(radius), params["top_radius"], int(half), deformed.shape) if params.get("pyramid") else 0
    if xs.shape[0] and levels:
        pyramid_search(module, reference, deformed, xs, ys, ulo, uhi, vlo, vhi, int(half), status, stream_seed, params,
                       outputs, (cu, cv), levels=levels, top_radius=params["top_radius"])
    elif xs.shape[0]:
        module.run(reference, deformed, xs, ys, ulo, uhi, vlo, vhi, int(half), status, stream_seed, params, outputs,
                   (cu, cv))
    u, v, zncc, evaluations, calls = outputs
    return IntegerSearchResult(xs=xs, ys=ys, u=u, v=v, zncc=zncc, status=status, evaluations=evaluations,
                               calls=calls)


def integer_search(reference: np.ndarray, deformed: np.ndarray, points: npt.ArrayLike, *, method: str = DEFAULT_SEARCH,
                   subset: int = DEFAULT_SUBSET, radius: int = DEFAULT_RADIUS, guess: npt.ArrayLike | None = None,
                   seed: int = 0, **options: Any) -> IntegerSearchResult:
    """Integer-pixel displacement of each point: the ZNCC maximum in a box around the guess.

    Parameters
    ----------
    reference, deformed : ndarray, shape (H, W)
        Grey images (any integer or float dtype) of equal size.
    points : array_like, shape (N, 2)
        (x, y) pixel positions in the reference, snapped to the nearest pixel.
    method : str
        One of ``SEARCH_METHODS``; default the paper's ``"improved-wso"``.
    subset : int
        Odd subset side, pixels.
    radius : int
        The box is ``round(guess) +- radius`` (clipped to the image).
    guess : array_like, shape (2,) or (N, 2), optional
        Initial (u, v); zero if omitted. NaN rows get ``Status.BAD_GUESS``.
    seed : int
        Seed of the stochastic methods (same seed, same result, any thread count).
    **options
        Method parameters, e.g. ``population=30`` (see ``method_options``).

    Returns
    -------
    IntegerSearchResult
        ``u, v`` (int64), ``zncc``, ``status``, ``evaluations`` (distinct ZNCC
        positions) and ``calls`` (fitness calls) per point.

    Raises
    ------
    ValueError
        Bad images, points, subset, radius, guess, method or option.

    Examples
    --------
    >>> from livedic.dic.speckle import SpecklePattern, render
    >>> pattern = SpecklePattern((128, 128), n_speckles=250, seed=1)
    >>> ref, dfm = render(pattern), render(pattern, (3, -2))
    >>> r = integer_search(ref, dfm, [(64, 64)], radius=8)
    >>> int(r.u[0]), int(r.v[0]), int(r.status[0])
    (3, -2, 0)
    """
    _check_method(method)
    reference = as_image(reference, "reference")
    deformed = as_image(deformed, "deformed")
    check_same_shape(reference, deformed)
    half = check_subset(subset, reference.shape)
    radius = check_radius(radius)
    xy = as_points(points)
    start = as_guess(guess, xy.shape[0])
    from livedic.dic.correlation import snap_points
    xs, ys = snap_points(xy)
    return search_points(reference, deformed, xs, ys, np.ascontiguousarray(start[:, 0]),
                         np.ascontiguousarray(start[:, 1]), half, radius, method, seed=seed, options=options)
