"""Virtual extensometers: the length between two material points, frame after frame.

A video extensometer measures the distance between two marks on the specimen. Here
each end is a point of the reference image; in every frame it moves with the
material: its displacement is a least-squares quadratic surface of the tracked
points' displacements around it (the ok points within ``END_REACH`` = 2.5 grid
steps, about 20), evaluated at the end. Measured on the simulated tensile test
(``livedic bench strain``): a plane over 2 steps is biased by the curvature of
the field near a neck (a transverse gauge through it read 1 % low at the last
frame), a quadratic over 2.5 steps is exact to second order and still averages
the noise of ~20 points (over 3 steps the third-order terms grow back). Tracking
each end with its own subset would add a subset's full noise (~0.01 px) and its
own shape-function bias at each end. An end whose neighbourhood holds too few
valid points, or points on a line only, is lost for that frame: its readings
are NaN with a reason (``ExtensometerStatus``), never the last good value.

Per frame: the current length ``L``, engineering strain ``(L - L0) / L0`` and true
strain ``ln(L / L0)``. ``poisson_ratio`` pairs an axial and a transverse reading.
"""

import enum
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from livedic.dic.neighbours import typical_spacing

# An end's surface is fitted over the points within this many grid steps (about 20 points).
END_REACH = 2.5
END_MIN_POINTS = 10            # 6 coefficients, with some to spare
END_MIN_SPREAD = 0.2           # smaller eigenvalue of the points' position covariance, in step^2
# Below this axial strain the ratio -e_trans / e_axial is noise over noise: NaN.
POISSON_MIN_AXIAL = 5e-4


class ExtensometerStatus(enum.IntEnum):
    """Why an extensometer has no reading in a frame (0: it has one)."""
    OK = 0
    END_LOST = 1            # too few valid tracked points around one of its ends in this frame

    @property
    def description(self):
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    ExtensometerStatus.OK: "measured",
    ExtensometerStatus.END_LOST: "an end lost its tracked points in this frame",
}


@dataclass(frozen=True)
class Extensometer:
    """A named pair of reference points (x1, y1) -> (x2, y2), px."""
    name: str
    x1: float
    y1: float
    x2: float
    y2: float

    @property
    def length_px(self):
        return math.hypot(self.x2 - self.x1, self.y2 - self.y1)

    @property
    def ends(self):
        return np.array([[self.x1, self.y1], [self.x2, self.y2]], dtype=np.float64)


@dataclass(frozen=True)
class ExtensometerReadings:
    """One frame's readings of every extensometer (arrays in the order of the definitions).

    ``length_px``, ``eng_strain``, ``true_strain`` are NaN where ``status`` is not OK.
    """
    names: tuple
    l0_px: np.ndarray
    length_px: np.ndarray
    eng_strain: np.ndarray
    true_strain: np.ndarray
    status: np.ndarray

    @property
    def ok(self):
        return self.status == int(ExtensometerStatus.OK)

    def reading(self, name):
        """(eng_strain, true_strain, ok) of the extensometer ``name``."""
        i = self.names.index(name)
        return float(self.eng_strain[i]), float(self.true_strain[i]), bool(self.ok[i])


@dataclass(frozen=True)
class ExtensometerSet:
    """Extensometers placed on a set of tracked reference points (``place_extensometers``)."""
    extensometers: tuple
    ends: np.ndarray                  # (2E, 2): start and end of each, in order
    start: np.ndarray                 # CSR: the points around end k are index[start[k]:start[k + 1]]
    index: np.ndarray
    step: float

    @property
    def names(self):
        return tuple(e.name for e in self.extensometers)


@njit(cache=True)
def _ends_near(ex, ey, x, y, reach):
    """CSR lists of the points within ``reach`` (Euclidean) of each end."""
    n_ends = ex.shape[0]
    counts = np.zeros(n_ends + 1, dtype=np.int64)
    r2 = reach * reach
    for k in range(n_ends):
        for j in range(x.shape[0]):
            if (x[j] - ex[k]) ** 2 + (y[j] - ey[k]) ** 2 <= r2:
                counts[k + 1] += 1
    for k in range(n_ends):
        counts[k + 1] += counts[k]
    index = np.empty(counts[n_ends], dtype=np.int64)
    for k in range(n_ends):
        fill = counts[k]
        for j in range(x.shape[0]):
            if (x[j] - ex[k]) ** 2 + (y[j] - ey[k]) ** 2 <= r2:
                index[fill] = j
                fill += 1
    return counts, index


def place_extensometers(extensometers, points, *, step=None):
    """Attach ``extensometers`` to the tracked reference ``points`` (N, 2).

    Raises
    ------
    ValueError
        Two extensometers share a name, one has zero length, or an end has no tracked points
        around it (it lies outside the region the points cover): one line naming it.
    """
    extensometers = tuple(extensometers)
    names = [e.name for e in extensometers]
    if len(set(names)) != len(names):
        raise ValueError(f"extensometer names must differ: {', '.join(names)}")
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if step is None:
        step = typical_spacing(points) if len(points) > 1 else 1.0
    step = float(step)
    ends = np.concatenate([e.ends for e in extensometers]) if extensometers else np.empty((0, 2))
    start, index = _ends_near(np.ascontiguousarray(ends[:, 0]), np.ascontiguousarray(ends[:, 1]),
                              np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]),
                              END_REACH * step)
    x_lo, y_lo = points.min(axis=0) if len(points) else (0.0, 0.0)
    x_hi, y_hi = points.max(axis=0) if len(points) else (0.0, 0.0)
    for k, e in enumerate(extensometers):
        if e.length_px <= 0:
            raise ValueError(f"extensometer {e.name}: its two ends coincide (length 0)")
        for end in (2 * k, 2 * k + 1):
            held = index[start[end]:start[end + 1]]
            ex, ey = ends[end]
            if len(held) < END_MIN_POINTS or not _spread_enough(points[held] - (ex, ey), step):
                raise ValueError(
                    f"extensometer {e.name}: its end ({ex:g}, {ey:g}) px lies outside the tracked points "
                    f"(x {x_lo:g}..{x_hi:g}, y {y_lo:g}..{y_hi:g}); shorten it or move it into the ROI")
    return ExtensometerSet(extensometers=extensometers, ends=ends, start=start, index=index, step=step)


def _spread_enough(offsets, step):
    cov = np.cov(offsets.T, bias=True) if len(offsets) > 1 else np.zeros((2, 2))
    return np.linalg.eigvalsh(cov)[0] >= END_MIN_SPREAD * step * step


@njit(cache=True)
def _solve_in_place(a, b):
    """Solve a x = b (small dense, partial pivoting) into b; False when a is (nearly) singular."""
    n = a.shape[0]
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(a[i, i]))
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if abs(a[pivot, col]) <= 1e-10 * scale:
            return False
        if pivot != col:
            for k in range(n):
                a[col, k], a[pivot, k] = a[pivot, k], a[col, k]
            for k in range(b.shape[1]):
                b[col, k], b[pivot, k] = b[pivot, k], b[col, k]
        for row in range(col + 1, n):
            f = a[row, col] / a[col, col]
            for k in range(col, n):
                a[row, k] -= f * a[col, k]
            for k in range(b.shape[1]):
                b[row, k] -= f * b[col, k]
    for col in range(n - 1, -1, -1):
        for k in range(b.shape[1]):
            acc = b[col, k]
            for j in range(col + 1, n):
                acc -= a[col, j] * b[j, k]
            b[col, k] = acc / a[col, col]
    return True


@njit(cache=True)
def _end_displacements(ends, start, index, x, y, u, v, valid, step, min_points, min_spread2, out_u, out_v):
    """Quadratic surface fits of u and v around each end, evaluated at the end; NaN where not possible."""
    basis = np.empty(6)
    for k in range(ends.shape[0]):
        out_u[k] = np.nan
        out_v[k] = np.nan
        count = 0
        sx = 0.0
        sy = 0.0
        for m in range(start[k], start[k + 1]):
            j = index[m]
            if valid[j]:
                count += 1
                sx += (x[j] - ends[k, 0]) / step
                sy += (y[j] - ends[k, 1]) / step
        if count < min_points:
            continue
        mx = sx / count
        my = sy / count
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        normal = np.zeros((6, 6))
        rhs = np.zeros((6, 2))
        for m in range(start[k], start[k + 1]):
            j = index[m]
            if not valid[j]:
                continue
            # Offsets in grid steps keep the 6 x 6 normal matrix well scaled.
            px = (x[j] - ends[k, 0]) / step
            py = (y[j] - ends[k, 1]) / step
            sxx += (px - mx) ** 2
            sxy += (px - mx) * (py - my)
            syy += (py - my) ** 2
            basis[0] = 1.0
            basis[1] = px
            basis[2] = py
            basis[3] = px * px
            basis[4] = px * py
            basis[5] = py * py
            for r in range(6):
                rhs[r, 0] += basis[r] * u[j]
                rhs[r, 1] += basis[r] * v[j]
                for c in range(6):
                    normal[r, c] += basis[r] * basis[c]
        half_trace = 0.5 * (sxx + syy) / count
        gap = math.sqrt((0.5 * (sxx - syy) / count) ** 2 + (sxy / count) ** 2)
        if half_trace - gap < min_spread2:
            continue
        if not _solve_in_place(normal, rhs):
            continue
        out_u[k] = rhs[0, 0]       # the surface at the end (offset 0)
        out_v[k] = rhs[0, 1]


def end_displacements(placed, points, u, v, ok):
    """(u, v) of every end (2E,) in this frame, NaN where the end is lost."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    valid = np.asarray(ok, dtype=bool) & np.isfinite(u) & np.isfinite(v)
    n_ends = placed.ends.shape[0]
    out_u, out_v = np.empty(n_ends), np.empty(n_ends)
    _end_displacements(placed.ends, placed.start, placed.index, np.ascontiguousarray(points[:, 0]),
                       np.ascontiguousarray(points[:, 1]), u, v, valid, placed.step, END_MIN_POINTS, END_MIN_SPREAD,
                       out_u, out_v)
    return out_u, out_v


def read_extensometers(placed, points, u, v, ok):
    """Every extensometer's reading in one frame.

    Parameters
    ----------
    placed : ExtensometerSet
        From ``place_extensometers`` on the same reference ``points``.
    points : array (N, 2)
        Reference positions of the tracked points, px.
    u, v : arrays (N,)
        Their displacements in this frame, px.
    ok : array (N,) of bool

    Returns
    -------
    ExtensometerReadings
    """
    end_u, end_v = end_displacements(placed, points, u, v, ok)
    ends = placed.ends
    first, second = slice(0, None, 2), slice(1, None, 2)
    l0 = np.hypot(ends[second, 0] - ends[first, 0], ends[second, 1] - ends[first, 1])
    length = np.hypot(ends[second, 0] + end_u[second] - ends[first, 0] - end_u[first],
                      ends[second, 1] + end_v[second] - ends[first, 1] - end_v[first])
    lost = ~np.isfinite(length)
    status = np.where(lost, int(ExtensometerStatus.END_LOST), int(ExtensometerStatus.OK)).astype(np.int32)
    with np.errstate(invalid="ignore", divide="ignore"):
        eng = length / l0 - 1.0
        true = np.log(length / l0)
    return ExtensometerReadings(names=placed.names, l0_px=l0, length_px=length, eng_strain=eng, true_strain=true,
                                status=status)


def poisson_ratio(e_axial, e_transverse, *, min_axial=POISSON_MIN_AXIAL):
    """-e_transverse / e_axial; NaN where either is NaN or |e_axial| < ``min_axial`` (noise over noise)."""
    e_axial = np.asarray(e_axial, dtype=np.float64)
    e_transverse = np.asarray(e_transverse, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = -e_transverse / e_axial
    return np.where(np.abs(e_axial) >= min_axial, ratio, np.nan)
