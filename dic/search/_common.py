"""Plumbing shared by the integer-pixel searches.

* ``search_boxes``: the integer box each point may search, and the status of
  points that cannot be searched at all (vectorised, Python side).
* ``begin_point`` / ``finish_point``: per-point prologue and epilogue used inside
  every method's ``prange`` kernel (reference subset, flat checks, outputs).
* ``fitness``: ZNCC at an integer displacement through a per-point cache, so each
  method can report distinct evaluations and total calls.
* ``hill_climb``: 8-neighbour ascent on the integer grid (the improved WSO's
  "three-step search" polish and the pyramid's refinement).

Options are checked by ``dic.method_options``; status codes are ``dic.status``'s.

Positions are absolute integer displacements (u, v); the search box of a point
is ``[ulo, uhi] x [vlo, vhi]`` and its cache is a (vhi-vlo+1, uhi-ulo+1) array
holding NaN where a position has not been evaluated.
"""

import numpy as np
from numba import njit

from livedic.dic.correlation import prepare_reference_subset, zncc_at_integer
from livedic.dic.status import BAD_GUESS, FLAT_REFERENCE, FLAT_TARGET, OK, OUTSIDE_REFERENCE, OUTSIDE_TARGET

# A guess beyond this many pixels is treated as "far outside", before it is cast
# to int64 (avoids overflow on absurd guesses such as 1e300).
_FAR = 1 << 40

SearchOutputs = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
"""A search kernel's outputs per point: u, v (int64), zncc (float64), evaluations, calls (int64)."""


def search_boxes(shape: tuple[int, ...], xs: np.ndarray, ys: np.ndarray, guess_u: np.ndarray, guess_v: np.ndarray,
                 half: int, radius: int, margin: int) -> tuple[np.ndarray, ...]:
    """Integer search box per point and the status of points that cannot be searched.

    Parameters
    ----------
    shape : (H, W)
        Image shape (reference and deformed are the same size).
    xs, ys : ndarray of int64, shape (N,)
        Snapped point positions.
    guess_u, guess_v : ndarray of float64, shape (N,)
        Initial guess; NaN/inf rows get ``Status.BAD_GUESS``.
    half, radius, margin : int
        Subset half-width, search radius around ``round(guess)``, extra pixels the
        target subset must keep from the image edge (for later interpolation).

    Returns
    -------
    ulo, uhi, vlo, vhi : ndarray of int64, shape (N,)
        Inclusive box bounds (absolute displacements).
    cu, cv : ndarray of int64, shape (N,)
        The rounded guess (0 where it is not finite).
    status : ndarray of int8, shape (N,)
        ``OUTSIDE_REFERENCE`` > ``BAD_GUESS`` > ``OUTSIDE_TARGET`` (empty box) > OK.
        The kernels later add ``FLAT_REFERENCE`` (which outranks ``BAD_GUESS``)
        and ``FLAT_TARGET``.
    """
    height, width = shape
    xs = np.asarray(xs, dtype=np.int64)
    ys = np.asarray(ys, dtype=np.int64)
    gu = np.asarray(guess_u, dtype=np.float64)
    gv = np.asarray(guess_v, dtype=np.float64)
    finite = np.isfinite(gu) & np.isfinite(gv)
    cu = np.floor(np.clip(np.where(finite, gu, 0.0), -_FAR, _FAR) + 0.5).astype(np.int64)
    cv = np.floor(np.clip(np.where(finite, gv, 0.0), -_FAR, _FAR) + 0.5).astype(np.int64)
    reach = half + margin
    ulo = np.maximum(cu - radius, reach - xs)
    uhi = np.minimum(cu + radius, width - 1 - reach - xs)
    vlo = np.maximum(cv - radius, reach - ys)
    vhi = np.minimum(cv + radius, height - 1 - reach - ys)
    status = np.zeros(xs.shape[0], dtype=np.int8)
    status[(ulo > uhi) | (vlo > vhi)] = OUTSIDE_TARGET
    status[~finite] = BAD_GUESS
    inside_ref = (xs - half >= 0) & (ys - half >= 0) & (xs + half < width) & (ys + half < height)
    status[~inside_ref] = OUTSIDE_REFERENCE
    # Empty or unusable boxes become a harmless 1x1 box so kernels can allocate.
    bad = status != OK
    ulo[bad] = 0
    uhi[bad] = 0
    vlo[bad] = 0
    vhi[bad] = 0
    return ulo, uhi, vlo, vhi, cu, cv, status


@njit(cache=True)
def begin_point(reference, x, y, half, fhat, status, i):
    """Prepare the reference subset of point ``i``; True if it should be searched.

    Writes ``FLAT_REFERENCE`` into ``status[i]`` for a textureless subset (this
    outranks a bad guess or an empty box: the point is unmeasurable either way).
    """
    if status[i] == OUTSIDE_REFERENCE:
        return False
    if prepare_reference_subset(reference, x, y, half, fhat) == 0.0:
        status[i] = FLAT_REFERENCE
        return False
    return status[i] == OK


@njit(cache=True)
def new_cache(ulo, uhi, vlo, vhi):
    """Evaluation cache for a box: NaN = not evaluated yet."""
    return np.full((vhi - vlo + 1, uhi - ulo + 1), np.nan)


@njit(cache=True)
def fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts):
    """ZNCC at integer (u, v) (inside the box), cached; counts[0] distinct, counts[1] calls."""
    counts[1] += 1
    c = cache[v - vlo, u - ulo]
    if np.isnan(c):
        c = zncc_at_integer(fhat, target, x, y, half, u, v)
        cache[v - vlo, u - ulo] = c
        counts[0] += 1
    return c


@njit(cache=True)
def hill_climb(fhat, target, x, y, half, u, v, ulo, uhi, vlo, vhi, cache, counts):
    """8-neighbour ascent from (u, v) inside the box; returns the local maximum (u, v, zncc).

    Each step evaluates the in-box neighbours of the centre and moves to the best
    one if it beats the centre (ties keep the centre); it stops when the centre is
    the best of its neighbourhood. ZNCC rises strictly at each move, so it ends.
    """
    best = fitness(fhat, target, x, y, half, u, v, ulo, vlo, cache, counts)
    for _ in range((uhi - ulo + 1) * (vhi - vlo + 1)):
        bu = u
        bv = v
        bc = best
        for dv in range(-1, 2):
            nv = v + dv
            if nv < vlo or nv > vhi:
                continue
            for du in range(-1, 2):
                nu = u + du
                if (du == 0 and dv == 0) or nu < ulo or nu > uhi:
                    continue
                c = fitness(fhat, target, x, y, half, nu, nv, ulo, vlo, cache, counts)
                if c > bc:
                    bu = nu
                    bv = nv
                    bc = c
        if bu == u and bv == v:
            break
        u = bu
        v = bv
        best = bc
    return u, v, best


@njit(cache=True)
def finish_point(i, u, v, c, counts, status, out_u, out_v, out_c, out_evals, out_calls):
    """Write one point's result; a best match on a flat target (ZNCC -1) is ``FLAT_TARGET``."""
    out_evals[i] = counts[0]
    out_calls[i] = counts[1]
    if c == -1.0:
        status[i] = FLAT_TARGET
        return
    out_u[i] = u
    out_v[i] = v
    out_c[i] = c


def new_outputs(n: int) -> SearchOutputs:
    """Output arrays of a search kernel: u, v, zncc, evaluations, calls."""
    return (np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64), np.full(n, np.nan),
            np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64))
