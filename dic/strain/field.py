"""Strain fields from measured displacements: pointwise least squares (Pan et al. 2009).

Displacements measured by subsets are noisy at the 0.01 px level; differentiating
them point to point would turn that into strain noise of 1e-3 and more. The
pointwise least-squares method fits a plane to u and to v over a square window of
(2m+1) x (2m+1) grid points around each point, over the *valid* (ok) points only,
and takes the plane's slopes as the displacement gradients ux, uy, vx, vy there.
The window is fixed in the reference image (Lagrangian): its neighbourhoods are
found once (``strain_window``) and each frame costs one pass over them
(``strain_field``).

The spatial resolution of the result is the virtual strain gauge (iDICs Good
Practices Guide, 2018): ``VSG = (window - 1) * step + subset`` pixels, with
``window`` = 2m + 1 points a side. A bigger window averages more noise away and
sees less detail.

Strain measures (``MEASURES``), from the deformation gradient F = I + grad u::

    engineering   small strain, eps = (grad u + grad u^T) / 2
    green         Green-Lagrange, E = (F^T F - I) / 2
    true          logarithmic (Hencky), ln U = ln(F^T F) / 2, through the eigen-decomposition
                  of C = F^T F (not the log of each component)

Shear is the tensor component (exy = gamma_xy / 2). A rigid rotation gives zero
green and true strain at any angle; the engineering measure shows
cos(theta) - 1 there, as small-strain theory does. Principal strains are the
eigenvalues of the chosen tensor (e1 >= e2) and the angle of e1 from the x axis.

Nothing is invented where the data are missing: a point whose own displacement is
not ok, or whose window has too few valid points, or valid points that do not
spread in both directions (a row along a crack), gets NaN strains and a
``StrainStatus`` saying why, never 0.
"""

import enum
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from livedic.dic.correlation import DEFAULT_SUBSET
from livedic.dic.neighbours import typical_spacing

MEASURES = ("engineering", "green", "true")
DEFAULT_MEASURE = "engineering"
DEFAULT_WINDOW = 5
# A window needs this share of the points it holds in the reference, and at least
# MIN_POINTS of them: with fewer the plane is a guess (3 points fit any plane exactly).
MIN_VALID_FRACTION = 0.5
MIN_POINTS = 6
# The valid points must spread in both directions: the smaller eigenvalue of their
# position covariance at least this times step^2 (two rows have 0.25, a 3x3 corner block 2/3).
MIN_SPREAD = 0.2


class StrainStatus(enum.IntEnum):
    """Why a point has no strain (0: it has one)."""
    OK = 0
    POINT_NOT_OK = 1        # the point's own displacement is not ok
    TOO_FEW_POINTS = 2      # too few valid points in its window
    ONE_DIRECTION = 3       # the valid points lie (nearly) on a line: no gradient across it

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    StrainStatus.OK: "strain measured",
    StrainStatus.POINT_NOT_OK: "the point's displacement is not ok",
    StrainStatus.TOO_FEW_POINTS: "too few valid points in the strain window",
    StrainStatus.ONE_DIRECTION: "the valid points of the strain window lie along a line",
}
_OK = int(StrainStatus.OK)
_POINT_NOT_OK = int(StrainStatus.POINT_NOT_OK)
_TOO_FEW_POINTS = int(StrainStatus.TOO_FEW_POINTS)
_ONE_DIRECTION = int(StrainStatus.ONE_DIRECTION)


def virtual_strain_gauge(window: int, step: float, subset: int) -> float:
    """VSG in pixels: ``(window - 1) * step + subset`` (iDICs Good Practices Guide)."""
    return (int(window) - 1) * float(step) + int(subset)


@dataclass(frozen=True)
class StrainWindow:
    """Each point's neighbourhood for the plane fits, found once on the reference points.

    The window of point ``i`` is ``index[start[i]:start[i + 1]]`` (itself included);
    ``dx``, ``dy`` are those points' reference offsets from point ``i`` in px.

    Attributes
    ----------
    window : int
        Points a side of the square window (odd).
    step : float
        Grid spacing, px.
    subset : int
        Subset side, px (for the VSG).
    vsg_px : float
        Virtual strain gauge, px.
    """
    start: np.ndarray
    index: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    window: int
    step: float
    subset: int

    @property
    def vsg_px(self) -> float:
        return virtual_strain_gauge(self.window, self.step, self.subset)

    @property
    def n_points(self) -> int:
        return self.start.shape[0] - 1


@njit(cache=True)
def _square_neighbourhoods(x, y, reach):
    """CSR lists of the points within ``reach`` of each point in x and in y (a square), found by rows."""
    n = x.shape[0]
    order = np.argsort(y)
    ys = y[order]
    counts = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        lo = np.searchsorted(ys, y[i] - reach, side="left")
        hi = np.searchsorted(ys, y[i] + reach, side="right")
        for k in range(lo, hi):
            if abs(x[order[k]] - x[i]) <= reach:
                counts[i + 1] += 1
    for i in range(n):
        counts[i + 1] += counts[i]
    index = np.empty(counts[n], dtype=np.int64)
    for i in range(n):
        lo = np.searchsorted(ys, y[i] - reach, side="left")
        hi = np.searchsorted(ys, y[i] + reach, side="right")
        fill = counts[i]
        for k in range(lo, hi):
            j = order[k]
            if abs(x[j] - x[i]) <= reach:
                index[fill] = j
                fill += 1
    return counts, index


def strain_window(points: npt.ArrayLike, *, window: int = DEFAULT_WINDOW, step: float | None = None,
                  subset: int = DEFAULT_SUBSET) -> StrainWindow:
    """The neighbourhoods of the plane fits for ``points`` (N, 2) in the reference image.

    Parameters
    ----------
    points : array (N, 2)
        Reference positions (x, y), px: a grid (any extra point such as P0 is fine) or scattered.
    window : int
        Odd number of grid points a side of the square window, >= 3.
    step : float, optional
        Grid spacing in px; default: the points' typical spacing.
    subset : int
        Subset side in px, for the VSG only.

    Returns
    -------
    StrainWindow
    """
    window = int(window)
    if window < 3 or window % 2 == 0:
        raise ValueError(f"strain window must be an odd number of points >= 3, got {window}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if step is None:
        step = typical_spacing(points) if len(points) > 1 else 1.0
    step = float(step)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"grid step must be a positive number of pixels, got {step}")
    x = np.ascontiguousarray(points[:, 0])
    y = np.ascontiguousarray(points[:, 1])
    # Half a step of slack: a grid point's window is exactly its (2m+1)^2 block even when
    # P0 or rounding puts it a fraction of a pixel off.
    reach = (window // 2 + 0.5) * step
    start, index = _square_neighbourhoods(x, y, reach)
    centre = np.repeat(np.arange(len(x)), np.diff(start))
    return StrainWindow(start=start, index=index, dx=x[index] - x[centre], dy=y[index] - y[centre],
                        window=window, step=step, subset=int(subset))


@njit(cache=True)
def _plane_slopes(start, index, dx, dy, u, v, valid, min_fraction, min_points, min_spread2,
                  ux, uy, vx, vy, status):
    """Least-squares plane slopes of u and v over each window's valid points (see the module notes)."""
    n = start.shape[0] - 1
    for i in range(n):
        ux[i] = np.nan
        uy[i] = np.nan
        vx[i] = np.nan
        vy[i] = np.nan
        if not valid[i]:
            status[i] = _POINT_NOT_OK
            continue
        held = start[i + 1] - start[i]
        count = 0
        sx = 0.0
        sy = 0.0
        su = 0.0
        sv = 0.0
        for k in range(start[i], start[i + 1]):
            j = index[k]
            if valid[j]:
                count += 1
                sx += dx[k]
                sy += dy[k]
                su += u[j]
                sv += v[j]
        if count < min_points or count < min_fraction * held:
            status[i] = _TOO_FEW_POINTS
            continue
        mx = sx / count
        my = sy / count
        mu = su / count
        mv = sv / count
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        sxu = 0.0
        syu = 0.0
        sxv = 0.0
        syv = 0.0
        for k in range(start[i], start[i + 1]):
            j = index[k]
            if valid[j]:
                px = dx[k] - mx
                py = dy[k] - my
                du = u[j] - mu
                dv = v[j] - mv
                sxx += px * px
                sxy += px * py
                syy += py * py
                sxu += px * du
                syu += py * du
                sxv += px * dv
                syv += py * dv
        # Smaller eigenvalue of the position covariance: the spread across the thinnest direction.
        half_trace = 0.5 * (sxx + syy) / count
        gap = math.sqrt((0.5 * (sxx - syy) / count) ** 2 + (sxy / count) ** 2)
        if half_trace - gap < min_spread2:
            status[i] = _ONE_DIRECTION
            continue
        det = sxx * syy - sxy * sxy
        ux[i] = (syy * sxu - sxy * syu) / det
        uy[i] = (sxx * syu - sxy * sxu) / det
        vx[i] = (syy * sxv - sxy * syv) / det
        vy[i] = (sxx * syv - sxy * sxv) / det
        status[i] = _OK


def displacement_gradients(neighbourhoods: StrainWindow, u: npt.ArrayLike, v: npt.ArrayLike,
                           ok: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ux, uy, vx, vy at each point by pointwise least squares, and a ``StrainStatus`` code per point.

    Parameters
    ----------
    neighbourhoods : StrainWindow
    u, v : array (N,)
        Displacements of the window's points, px (NaN where not measured).
    ok : array (N,) of bool
        Which displacements are valid.

    Returns
    -------
    ux, uy, vx, vy : arrays (N,), NaN where the status is not OK
    status : array (N,) of int32
    """
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    n = neighbourhoods.n_points
    if u.shape != (n,) or v.shape != (n,) or np.shape(ok) != (n,):
        raise ValueError(f"strain window holds {n} points; got u {u.shape}, v {v.shape}, ok {np.shape(ok)}")
    valid = np.asarray(ok, dtype=bool) & np.isfinite(u) & np.isfinite(v)
    ux, uy, vx, vy = (np.empty(n) for _ in range(4))
    status = np.empty(n, dtype=np.int32)
    step = neighbourhoods.step
    _plane_slopes(neighbourhoods.start, neighbourhoods.index, neighbourhoods.dx, neighbourhoods.dy, u, v, valid,
                  MIN_VALID_FRACTION, MIN_POINTS, MIN_SPREAD * step * step, ux, uy, vx, vy, status)
    return ux, uy, vx, vy, status


def strain_tensor(ux: np.ndarray, uy: np.ndarray, vx: np.ndarray, vy: np.ndarray,
                  measure: str = DEFAULT_MEASURE) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(exx, eyy, exy) of the chosen measure (``MEASURES``) from the displacement gradients.

    ``exy`` is the tensor shear component. NaN gradients give NaN strains.
    """
    ux, uy, vx, vy = (np.asarray(a, dtype=np.float64) for a in (ux, uy, vx, vy))
    if measure == "engineering":
        return ux, vy, 0.5 * (uy + vx)
    # C = F^T F with F = [[1 + ux, uy], [vx, 1 + vy]]
    cxx = (1.0 + ux) ** 2 + vx ** 2
    cyy = uy ** 2 + (1.0 + vy) ** 2
    cxy = (1.0 + ux) * uy + vx * (1.0 + vy)
    if measure == "green":
        return 0.5 * (cxx - 1.0), 0.5 * (cyy - 1.0), 0.5 * cxy
    if measure == "true":
        return _half_log_symmetric(cxx, cyy, cxy)
    raise ValueError(f"unknown strain measure {measure!r}: choose one of {', '.join(MEASURES)}")


def _symmetric_eigen(axx, ayy, axy):
    """Eigenvalues (l1 >= l2) of the 2x2 symmetric [[axx, axy], [axy, ayy]] and the angle of l1's vector."""
    mean = 0.5 * (axx + ayy)
    radius = np.hypot(0.5 * (axx - ayy), axy)
    angle = 0.5 * np.arctan2(2.0 * axy, axx - ayy)
    return mean + radius, mean - radius, angle


def _half_log_symmetric(cxx, cyy, cxy):
    """ln(C) / 2 for the symmetric positive 2x2 C, by its eigen-decomposition (Hencky strain)."""
    l1, l2, angle = _symmetric_eigen(cxx, cyy, cxy)
    with np.errstate(invalid="ignore", divide="ignore"):
        h1 = 0.5 * np.log(l1)
        h2 = 0.5 * np.log(l2)
    c, s = np.cos(angle), np.sin(angle)
    return h1 * c * c + h2 * s * s, h1 * s * s + h2 * c * c, (h1 - h2) * c * s


def principal_strains(exx: npt.ArrayLike, eyy: npt.ArrayLike,
                      exy: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Principal strains e1 >= e2 of the tensor (exx, eyy, exy) and the angle of e1 from x, radians."""
    return _symmetric_eigen(np.asarray(exx, dtype=np.float64), np.asarray(eyy, dtype=np.float64),
                            np.asarray(exy, dtype=np.float64))


@dataclass(frozen=True)
class StrainField:
    """Strain at each point of one frame (NaN where ``status`` is not OK).

    Attributes
    ----------
    exx, eyy, exy : arrays (N,)
        The tensor of ``measure`` in image axes (x columns, y rows); exy the tensor shear.
    e1, e2, angle : arrays (N,)
        Principal strains (e1 >= e2) and the direction of e1 from the x axis, radians.
    ux, uy, vx, vy : arrays (N,)
        The fitted displacement gradients.
    status : array (N,) of int32
        ``StrainStatus`` codes.
    measure : str
    vsg_px : float
        Virtual strain gauge, px.
    """
    exx: np.ndarray
    eyy: np.ndarray
    exy: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    angle: np.ndarray
    ux: np.ndarray
    uy: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    status: np.ndarray
    measure: str
    vsg_px: float

    @property
    def ok(self) -> np.ndarray:
        return self.status == _OK


def strain_field(neighbourhoods: StrainWindow, u: npt.ArrayLike, v: npt.ArrayLike, ok: npt.ArrayLike, *,
                 measure: str = DEFAULT_MEASURE, labels: npt.ArrayLike | None = None) -> StrainField:
    """The strain field of one frame: plane fits over ``neighbourhoods``, then the chosen measure.

    Parameters
    ----------
    neighbourhoods : StrainWindow
        From ``strain_window`` on the reference points.
    u, v : arrays (N,)
        Displacements from the reference, px.
    ok : array (N,) of bool
    measure : str
        One of ``MEASURES``.
    labels : array (N,) of int, optional
        Regions that must not be mixed (the two sides of a crack, ``dic.tensile.fracture``): a point's window
        uses the points of its own region only.

    Returns
    -------
    StrainField
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown strain measure {measure!r}: choose one of {', '.join(MEASURES)}")
    if labels is None:
        ux, uy, vx, vy, status = displacement_gradients(neighbourhoods, u, v, ok)
    else:
        labels = np.asarray(labels)
        ok = np.asarray(ok, dtype=bool)
        ux, uy, vx, vy = (np.full(labels.shape, np.nan) for _ in range(4))
        status = np.full(labels.shape, _POINT_NOT_OK, dtype=np.int32)
        for label in np.unique(labels):
            mine = labels == label
            part = displacement_gradients(neighbourhoods, u, v, ok & mine)
            for out, values in zip((ux, uy, vx, vy, status), part):
                out[mine] = values[mine]
    exx, eyy, exy = strain_tensor(ux, uy, vx, vy, measure)
    e1, e2, angle = principal_strains(exx, eyy, exy)
    return StrainField(exx=exx, eyy=eyy, exy=exy, e1=e1, e2=e2, angle=angle, ux=ux, uy=uy, vx=vx, vy=vy,
                       status=status, measure=measure, vsg_px=neighbourhoods.vsg_px)
