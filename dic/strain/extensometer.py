"""Virtual extensometers: the length between two material points, frame after frame.

A video extensometer measures the distance between two marks on the specimen. Here
each end is a point of the reference image; in every frame it moves with the
material: its displacement is a least-squares surface of the tracked points'
displacements around it (``dic.strain.field_fit``), evaluated at the end. Two fits
(``Extensometer.end_fit``): ``LOCAL``, a quadratic over the ok points within 2.5 grid
steps (about 20; that module's notes say why a quadratic and not a plane, measured);
``BAND``, the points within 3.5 steps along the extensometer and any distance across
it, as a video extensometer's gauge-mark line across the specimen: quadratic along,
linear across, so a rotation or a strain gradient across the width reads exactly and
a neck's curvature along it too, while all the points across the width average the
noise (by the fit weights 3.7x less than the local fit on 29 points across, 2.2x on
the bench extensometer's 7-point strip, where 1.9x was measured: neighbouring subsets'
errors correlate; docs/guide/extensometer-class.md). A band end is
interpolated, never extrapolated, and read only where its local fit is possible
too (its own points not lost). A band needs points across the extensometer: the
transverse one, whose ends lie on the specimen's edges, keeps the local fit. Tracking each end with its own subset
would add a subset's full noise (~0.01 px) and its own shape-function bias at
each end. An end whose neighbourhood holds too few valid points, or points on a
line only, is lost for that frame: its readings are NaN with a reason
(``ExtensometerStatus``), never the last good value.

Per frame: the current length ``L``, engineering strain ``(L - L0) / L0`` and true
strain ``ln(L / L0)``. ``poisson_ratio`` pairs an axial and a transverse reading.
"""

import enum
import math
from dataclasses import dataclass

from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from livedic.dic.strain import field_fit
from livedic.dic.neighbours import typical_spacing

# The names of the two extensometers a tensile test places (``--gauge-length``): along the load, and across it.
AXIAL, TRANSVERSE = "axial", "transverse"
# How an end's displacement is fitted (``Extensometer.end_fit``): LOCAL, a quadratic surface over the points within
# END_REACH grid steps of it; BAND, over the band of points across the extensometer within
# field_fit.BAND_HALF_HEIGHT steps of the end along it (a gauge-mark line across the specimen: every point across
# the width averages the noise; linear across, quadratic along, see the module notes).
LOCAL, BAND = "local", "band"
END_FITS = (LOCAL, BAND)
END_REACH = field_fit.REACH
END_MIN_POINTS = field_fit.MIN_POINTS
END_MIN_SPREAD = field_fit.MIN_SPREAD
# Below this axial strain the ratio -e_trans / e_axial is noise over noise: NaN.
POISSON_MIN_AXIAL = 5e-4


class ExtensometerOffPoints(ValueError):
    """An extensometer's end has no tracked points around it (one line); ``name`` is the extensometer's."""

    def __init__(self, message: str, name: str) -> None:
        super().__init__(message)
        self.name = name


class ExtensometerStatus(enum.IntEnum):
    """Why an extensometer has no reading in a frame (0: it has one)."""
    OK = 0
    END_LOST = 1            # too few valid tracked points around one of its ends in this frame

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    ExtensometerStatus.OK: "measured",
    ExtensometerStatus.END_LOST: "an end lost its tracked points in this frame",
}


@dataclass(frozen=True)
class Extensometer:
    """A named pair of reference points (x1, y1) -> (x2, y2), px; ``end_fit``: how each end is fitted (``END_FITS``)."""
    name: str
    x1: float
    y1: float
    x2: float
    y2: float
    end_fit: str = LOCAL

    @property
    def length_px(self) -> float:
        return math.hypot(self.x2 - self.x1, self.y2 - self.y1)

    @property
    def ends(self) -> np.ndarray:
        return np.array([[self.x1, self.y1], [self.x2, self.y2]], dtype=np.float64)

    @property
    def axis(self) -> np.ndarray:
        """Unit vector from the first end to the second."""
        return (self.ends[1] - self.ends[0]) / self.length_px


@dataclass(frozen=True)
class ExtensometerReadings:
    """One frame's readings of every extensometer (arrays in the order of the definitions).

    ``length_px``, ``eng_strain``, ``true_strain`` are NaN where ``status`` is not OK. A stereo session measures
    lengths in space: ``l0_mm`` and ``length_mm`` (mm) are set and the image lengths are NaN.
    """
    names: tuple
    l0_px: np.ndarray
    length_px: np.ndarray
    eng_strain: np.ndarray
    true_strain: np.ndarray
    status: np.ndarray
    l0_mm: np.ndarray | None = None
    length_mm: np.ndarray | None = None

    @property
    def ok(self) -> np.ndarray:
        return self.status == int(ExtensometerStatus.OK)

    def reading(self, name: str) -> tuple[float, float, bool]:
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
    groups: tuple = ()                # _EndGroup per end fit used: the ends fitted alike, in one call

    @property
    def end_fits(self) -> tuple[str, ...]:
        """How each end (2E) is fitted (``END_FITS``)."""
        return tuple(e.end_fit for e in self.extensometers for _ in range(2))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.extensometers)


def place_extensometers(extensometers: Iterable[Extensometer], points: npt.ArrayLike, *,
                        step: float | None = None) -> ExtensometerSet:
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
    for e in extensometers:
        if e.length_px <= 0:
            raise ValueError(f"extensometer {e.name}: its two ends coincide (length 0)")
        if e.end_fit not in END_FITS:
            raise ValueError(f"extensometer {e.name}: end fit {e.end_fit!r} is not one of {', '.join(END_FITS)}")
    ends = np.concatenate([e.ends for e in extensometers]) if extensometers else np.empty((0, 2))
    axes = np.array([e.axis for e in extensometers for _ in range(2)], dtype=np.float64).reshape(-1, 2)
    fits = np.array([e.end_fit for e in extensometers for _ in range(2)], dtype=object)
    local = field_fit.neighbourhoods(ends, points, step)
    hoods = {LOCAL: local, BAND: field_fit.band_neighbourhoods(ends, axes, points, step)}
    members = [hoods[fit][1][hoods[fit][0][k]:hoods[fit][0][k + 1]] for k, fit in enumerate(fits)]
    start, index = _csr(members)
    x_lo, y_lo = points.min(axis=0) if len(points) else (0.0, 0.0)
    x_hi, y_hi = points.max(axis=0) if len(points) else (0.0, 0.0)
    for k, e in enumerate(extensometers):
        for end in (2 * k, 2 * k + 1):
            held = index[start[end]:start[end + 1]]
            ex, ey = ends[end]
            if len(held) < END_MIN_POINTS or not _spread_enough(points[held] - (ex, ey), step) \
                    or (fits[end] == BAND and not _around(points[held] - (ex, ey), axes[end], step)):
                raise ExtensometerOffPoints(
                    f"extensometer {e.name}: its end ({ex:g}, {ey:g}) px lies outside the tracked points "
                    f"(x {x_lo:g}..{x_hi:g}, y {y_lo:g}..{y_hi:g}); shorten it or move it into the ROI", e.name)
    local_members = [local[1][local[0][k]:local[0][k + 1]] for k in range(len(ends))]
    groups = []
    for fit in END_FITS:
        mine = np.flatnonzero(fits == fit)
        if len(mine):
            group_start, group_index = _csr([members[k] for k in mine])
            guard = _csr([local_members[k] for k in mine]) if fit == BAND else None
            groups.append(_EndGroup(mine, group_start, group_index, axes[mine], _POWERS[fit], fit == BAND, guard))
    return ExtensometerSet(extensometers=extensometers, ends=ends, start=start, index=index, step=step,
                           groups=tuple(groups))


_POWERS = {LOCAL: field_fit.QUADRATIC, BAND: field_fit.BAND}


@dataclass(frozen=True)
class _EndGroup:
    """The ends fitted one way: their indices among the 2E ends, CSR neighbourhoods, axes and surface terms."""
    ends: np.ndarray
    start: np.ndarray
    index: np.ndarray
    axes: np.ndarray
    powers: tuple
    straddle: bool
    # A band end is read only where the local fit could read it too (CSR of the local neighbourhoods): far points
    # across must not carry an end whose own points are lost (measured: with tracking failing near a neck, the
    # band read 30 % off from points still flagged ok while the local end was lost).
    guard: tuple | None


def _csr(members):
    start = np.zeros(len(members) + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(m) for m in members])
    index = np.concatenate(members).astype(np.int64) if members else np.empty(0, dtype=np.int64)
    return start, index


def _around(offsets, axis, step):
    """Points around the end within half a step on each side, along its extensometer and across it: a band fit
    would otherwise extrapolate (``field_fit.fit_at``'s ``straddle``)."""
    along, across = offsets @ axis, offsets @ np.array([-axis[1], axis[0]])
    return all(c.min() <= 0.5 * step and c.max() >= -0.5 * step for c in (along, across))


def _spread_enough(offsets, step):
    cov = np.cov(offsets.T, bias=True) if len(offsets) > 1 else np.zeros((2, 2))
    return np.linalg.eigvalsh(cov)[0] >= END_MIN_SPREAD * step * step


def end_displacements(placed: ExtensometerSet, points: np.ndarray, u: np.ndarray, v: np.ndarray, ok: np.ndarray, *,
                      point_labels: np.ndarray | None = None,
                      end_labels: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of every end (2E,) in this frame, NaN where the end is lost.

    ``point_labels`` (N,) and ``end_labels`` (2E,): regions that must not be mixed (the two sides of
    a crack): an end is fitted on the points of its own region only.
    """
    if point_labels is None:
        return _fit_ends(placed, points, u, v, ok)
    point_labels, end_labels = np.asarray(point_labels), np.asarray(end_labels)
    out_u, out_v = np.full(len(placed.ends), np.nan), np.full(len(placed.ends), np.nan)
    for label in np.unique(end_labels):
        fu, fv = _fit_ends(placed, points, u, v, np.asarray(ok, dtype=bool) & (point_labels == label))
        mine = end_labels == label
        out_u[mine], out_v[mine] = fu[mine], fv[mine]
    return out_u, out_v


def _fit_ends(placed, points, u, v, ok):
    """(u, v) of every end, each group of ends by its own fit."""
    out_u, out_v = np.full(len(placed.ends), np.nan), np.full(len(placed.ends), np.nan)
    for group in placed.groups:
        where = placed.ends[group.ends]
        fu, fv = field_fit.fit_at(where, group.start, group.index, points, u, v, ok, placed.step, axes=group.axes,
                                  powers=group.powers, straddle=group.straddle)
        if group.guard is not None:
            own, _ = field_fit.fit_at(where, *group.guard, points, u, v, ok, placed.step)
            fu, fv = np.where(np.isnan(own), np.nan, fu), np.where(np.isnan(own), np.nan, fv)
        out_u[group.ends], out_v[group.ends] = fu, fv
    return out_u, out_v


def read_extensometers(placed: ExtensometerSet, points: np.ndarray, u: np.ndarray, v: np.ndarray, ok: np.ndarray, *,
                      point_labels: np.ndarray | None = None,
                      end_labels: np.ndarray | None = None) -> ExtensometerReadings:
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
    point_labels, end_labels : arrays, optional
        Regions not to mix (``end_displacements``).

    Returns
    -------
    ExtensometerReadings
    """
    end_u, end_v = end_displacements(placed, points, u, v, ok, point_labels=point_labels, end_labels=end_labels)
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


def strain_noise(placed: ExtensometerSet, points: npt.ArrayLike, point_noise_px: float, *,
                 independent_ends: bool = False) -> np.ndarray:
    """Expected standard deviation of each extensometer's strain, from the points' displacement noise.

    Each end's displacement is a linear combination of its neighbours' (``field_fit.fit_weights``), and the
    length changes by the difference of the two ends' along the line: for independent point errors of
    ``point_noise_px`` in u and v, sigma_L = point_noise_px |w2 - w1| (a point shared by both ends counts
    once), and the strain's sigma_L / L0. Neighbouring subsets overlap and their errors correlate, so the
    fit averages less than this (measured on a rigid translation: the readings' scatter was 0.8-1.4x this
    for L0 = 12-384 px).

    ``independent_ends``: as if the two ends shared no point (an extensometer long enough): its sigma_L then
    holds at any length, so sigma_L / limit is the length that meets a strain noise limit (a short one's
    ends share points, whose errors cancel in the difference).

    Returns
    -------
    ndarray (E,)
        Strain standard deviation of each extensometer (NaN where an end cannot be fitted).
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = np.empty(len(placed.extensometers))
    for k, e in enumerate(placed.extensometers):
        total = 0.0
        weights = np.zeros(len(points))
        for end, sign in ((2 * k, -1.0), (2 * k + 1, 1.0)):
            held = placed.index[placed.start[end]:placed.start[end + 1]]
            w = field_fit.fit_weights(placed.ends[end], held, points, placed.step, axis=tuple(e.axis),
                                      powers=_POWERS[e.end_fit])
            np.add.at(weights, held, sign * w)
            total += float(np.sum(w * w))
        squares = total if independent_ends else float(np.sum(weights * weights))
        out[k] = point_noise_px * math.sqrt(squares) / e.length_px
    return out


def poisson_ratio(e_axial: npt.ArrayLike, e_transverse: npt.ArrayLike, *,
                  min_axial: float = POISSON_MIN_AXIAL) -> np.ndarray:
    """-e_transverse / e_axial; NaN where either is NaN or |e_axial| < ``min_axial`` (noise over noise)."""
    e_axial = np.asarray(e_axial, dtype=np.float64)
    e_transverse = np.asarray(e_transverse, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = -e_transverse / e_axial
    return np.where(np.abs(e_axial) >= min_axial, ratio, np.nan)
