"""Tensile properties from an engineering stress-strain curve, by the methods of ISO 6892-1.

Input: per frame, the engineering strain (dimensionless, e.g. the ``axial`` extensometer)
and the engineering stress (MPa). A frame with either value not finite has no reading and
is skipped: the properties are computed from the frames that have one, and where a value
lies between two frames (Rp0.2) it is interpolated between the valid frames either side,
which the result names. Frames are reported by their index in the input arrays.

What is computed, and how (each result carries this as its ``method`` text):

* **E** (GPa): least-squares line of stress on strain over a stress range of the loading
  branch (the frames before the curve first rises above the range). The default range is
  10 % to 40 % of Rp0.2 when Rp0.2 is known, else of the maximum stress (ISO 6892-1:2019
  Annex G fits the elastic line well below the proportional limit; 40 % of Rm is below it
  for the usual metals, and ``tensile_properties`` refits once Rp0.2 is known). The line's
  strain at zero stress (``strain_at_zero_stress``) is the toe correction: seating and a
  zero offset of the extensometer move the curve, not the properties.
* **Rp0.2** (MPa): the curve's first crossing of the line parallel to the elastic line,
  offset by 0.2 % strain; linear interpolation between the bracketing frames.
* **Rm** (MPa): the maximum engineering stress (at maximum force), the first frame with it.
* **Ag** (%): plastic extension at maximum force, (strain - Rm / E) x 100; **Agt** the
  total, strain x 100 (both toe-corrected). The strain is that of the frame of Rm, or on a
  plateau at maximum force (a flat top) the middle of the plateau, as ISO 6892-1 reads it
  (``dic.tensile.flat_top``; ``UniformElongation.rule`` says which). ISO's polynomial fit
  near the maximum is not done.
* **A** (%): plastic elongation at fracture, (strain - stress / E) x 100 at the last frame
  before the stress first falls below ``FRACTURE_DROP`` (10 %) of Rm after Rm: ISO 6892-1
  defines fracture by the force drop; the elastic recovery stress / E is removed, as the
  broken specimen springs back.

ASTM E8/E8M reads yield strength by the same 0.2 % offset line and tensile strength as the
maximum force over the original area, so the numbers serve both; its elongation after
fracture is measured on the gauge marks after the test, which the plastic strain at the
force drop approximates as ISO 6892-1 does with an extensometer.

A property that cannot be computed is NaN with a ``Reason`` (data, not text).

Clause numbers cited here (3.9.2, 3.10.2.x, 3.6.3) are from memory, not checked against the standard's
text; Annex G (E) is confirmed for the 2016 edition (docs/guide/tensile-test.md, "Sources and clause
numbers").
"""

import enum
from dataclasses import dataclass

from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.dic.tensile.flat_top import AgRule, FlatTop, flat_top
from livedic.dic.tensile.yielding import SMOOTH_FRAMES, CurveShape, YieldAnalysis, analyse_yielding, smooth

DEFAULT_RANGE = (0.10, 0.40)   # share of Rp0.2 (or of the maximum stress) fitted for E
MIN_POINTS = 5                 # fewest frames in the range to fit E
PROOF_OFFSET = 0.002           # 0.2 % strain
FRACTURE_DROP = 0.10           # fracture: stress below this share of Rm, after Rm
# Uniform elongation is over once the force falls this fraction below its (running) maximum. Load cells of class
# 0.5 or better stay well inside it while the force still climbs or holds (their noise is ~0.1 %).
NECKING_DROP = 0.005

_NAN = float("nan")


class Reason(enum.Enum):
    """Why a property is NaN."""
    NO_DATA = "no frame with both strain and stress"
    TOO_FEW_POINTS = "too few frames in the stress range of the elastic fit"
    NOT_POSITIVE = "the elastic fit's slope is not positive"
    NO_MODULUS = "needs E, which is NaN"
    NEVER_CROSSED = "the curve does not cross the offset line before maximum force"
    NO_FRACTURE = "the stress never falls below the fracture share of Rm after Rm"
    FORCE_MISSING_AT_MAXIMUM = ("the force is missing right next to the maximum (frames with strain but no force): "
                                "the true maximum may lie there")
    NO_YIELD_PHENOMENON = "continuous yielding: no yield phenomenon (ISO 6892-1 reads Rp0.2 instead)"
    NO_WORK_HARDENING = ("discontinuous yielding with no work hardening after it: ISO 6892-1:2019 3.9.2 Note 1 "
                         "leaves the maximum force Fm undefined, and with it Rm, Ag and Agt (ReH, ReL hold)")
    SHAPE_UNDETERMINED = "too few frames past the elastic range to read how the material yields"
    STILL_RISING = ("the force was highest at the last frame with a force: the test ended before the maximum force, "
                    "so Rm, Ag and Agt are not known")


@dataclass(frozen=True)
class Modulus:
    """The elastic modulus fitted over a stress range.

    Attributes
    ----------
    value : float
        E in GPa (NaN with ``reason`` when it cannot be fitted).
    standard_error : float
        Standard error of the fitted slope, GPa.
    n_points : int
        Frames in the fit.
    stress_range_MPa : (float, float)
        The fitted stress range.
    strain_at_zero_stress : float
        Where the fitted line crosses zero stress (toe correction); 0 when NaN.
    method : str
    reason : Reason or None
    basis : str
        Where the stress range comes from ("10% to 40% of Rp0.2", ...).
    """
    value: float
    standard_error: float
    n_points: int
    stress_range_MPa: tuple
    strain_at_zero_stress: float
    method: str
    reason: Reason | None = None
    basis: str = ""


@dataclass(frozen=True)
class ProofStrength:
    """Rp (MPa) and the two frames it was interpolated between (-1 when NaN)."""
    value: float
    frames: tuple
    method: str
    reason: Reason | None = None


@dataclass(frozen=True)
class TensileStrength:
    """Rm (MPa), the frame of the maximum and the strain there (-1 and NaN when NaN)."""
    value: float
    frame: int
    strain: float
    method: str
    reason: Reason | None = None


@dataclass(frozen=True)
class UniformElongation:
    """Ag (%, plastic) and Agt (%, total) at maximum force; ``rule`` says where they were read (at the frame
    of Rm, or at the middle of a plateau at maximum force: ``top`` holds the plateau)."""
    value: float
    total: float
    method: str
    reason: Reason | None = None
    rule: AgRule = AgRule.AT_MAXIMUM
    top: FlatTop | None = None


@dataclass(frozen=True)
class ElongationAfterFracture:
    """A (%) and the frame taken as the last before fracture (-1 when NaN)."""
    value: float
    frame: int
    method: str
    reason: Reason | None = None


@dataclass(frozen=True)
class YieldStrength:
    """ReH or ReL (MPa) and the frame it was read at (-1 when NaN)."""
    value: float
    frame: int
    method: str
    reason: Reason | None = None


@dataclass(frozen=True)
class YieldPointExtension:
    """Ae (%, of the extensometer gauge length), its first and last frames ((-1, -1) when NaN) and the strains
    where it starts and ends (NaN when NaN)."""
    value: float
    frames: tuple
    method: str
    reason: Reason | None = None
    strains: tuple = (_NAN, _NAN)


PROPERTY_NAMES = ("E_GPa", "Rp02_MPa", "Rm_MPa", "Ag_percent", "A_percent", "ReH_MPa", "ReL_MPa", "Ae_percent")


@dataclass(frozen=True)
class TensileProperties:
    """The properties of one test; the field names are the report's JSON keys.

    ``curve_shape`` says how the material yields (``dic.tensile.yielding.CurveShape``); ReH, ReL
    and Ae are NaN with ``Reason.NO_YIELD_PHENOMENON`` on continuous yielding.
    """
    E_GPa: Modulus
    Rp02_MPa: ProofStrength
    Rm_MPa: TensileStrength
    Ag_percent: UniformElongation
    A_percent: ElongationAfterFracture
    ReH_MPa: YieldStrength = YieldStrength(_NAN, -1, "not read", Reason.SHAPE_UNDETERMINED)
    ReL_MPa: YieldStrength = YieldStrength(_NAN, -1, "not read", Reason.SHAPE_UNDETERMINED)
    Ae_percent: YieldPointExtension = YieldPointExtension(_NAN, (-1, -1), "not read", Reason.SHAPE_UNDETERMINED)
    curve_shape: CurveShape = CurveShape.UNDETERMINED

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """``{"E_GPa": {"value": float, "method": str, "reason": str or None}, ...}`` (NaN stays NaN), one entry
        per ``PROPERTY_NAMES``."""
        out: dict[str, dict[str, Any]] = {}
        for name in PROPERTY_NAMES:
            prop = getattr(self, name)
            out[name] = {"value": float(prop.value), "method": prop.method,
                         "reason": None if prop.reason is None else prop.reason.value}
        return out


def _valid(strain: npt.ArrayLike, stress: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The input as float arrays, and the indices of the frames with both values finite."""
    strain = np.asarray(strain, dtype=np.float64)
    stress = np.asarray(stress, dtype=np.float64)
    if strain.shape != stress.shape or strain.ndim != 1:
        raise ValueError(f"strain and stress must be 1-D arrays of one length, got shapes "
                         f"{strain.shape} and {stress.shape}")
    frames = np.flatnonzero(np.isfinite(strain) & np.isfinite(stress))
    return strain, stress, frames


def fit_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least squares y = a x + b: slope, intercept, standard error of the slope (NaN if x is constant)."""
    if np.ptp(x) == 0:
        return _NAN, _NAN, _NAN
    x_mean, y_mean = x.mean(), y.mean()
    sxx = np.sum((x - x_mean) ** 2)
    slope = np.sum((x - x_mean) * (y - y_mean)) / sxx
    intercept = y_mean - slope * x_mean
    residuals = y - (slope * x + intercept)
    error = np.sqrt(np.sum(residuals ** 2) / (x.size - 2) / sxx)
    return slope, intercept, error


def _plastic_strain(strain, stress, E_GPa, strain_at_zero_stress):
    """Strain less the elastic part and the toe: what stays after unloading."""
    return strain - stress / (E_GPa * 1000.0) - strain_at_zero_stress


def modulus(strain: npt.ArrayLike, stress: npt.ArrayLike, *, stress_range: tuple[float, float] | None = None,
            rp02_MPa: float | None = None, min_points: int = MIN_POINTS) -> Modulus:
    """Elastic modulus E by a least-squares line over a stress range of the loading branch.

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    stress_range : (float, float), optional
        The stress range (MPa) to fit. Default: 10 % to 40 % of ``rp02_MPa`` when it is
        given and finite, else of the maximum stress.
    rp02_MPa : float, optional
        Rp0.2, for the default range.
    min_points : int
        Fewest frames in the range; fewer gives NaN with ``Reason.TOO_FEW_POINTS``.

    Returns
    -------
    Modulus
        E (GPa) with its standard error, the frames fitted and the range. The loading
        branch is the frames before the stress first exceeds the range's upper end, so
        an unloading or the falling branch after Rm is never fitted.
    """
    strain, stress, frames = _valid(strain, stress)
    if frames.size == 0:
        return Modulus(_NAN, _NAN, 0, (_NAN, _NAN), 0.0, "no fit", Reason.NO_DATA)
    lo_share, hi_share = DEFAULT_RANGE
    if stress_range is not None:
        low, high = (float(v) for v in stress_range)
        basis = "the stated range"
    elif rp02_MPa is not None and np.isfinite(rp02_MPa):
        low, high = lo_share * rp02_MPa, hi_share * rp02_MPa
        basis = f"{lo_share:.0%} to {hi_share:.0%} of Rp0.2"
    else:
        peak = stress[frames].max()
        low, high = lo_share * peak, hi_share * peak
        basis = f"{lo_share:.0%} to {hi_share:.0%} of the maximum stress"
    inside = elastic_fit_frames(strain, stress, low, high)
    n = int(inside.size)
    method = (f"least-squares line of stress on strain over {low:.1f} to {high:.1f} MPa "
              f"({basis}) of the loading branch, {n} frames")
    if n < max(min_points, 3):
        return Modulus(_NAN, _NAN, n, (float(low), float(high)), 0.0, method, Reason.TOO_FEW_POINTS, basis)
    slope, intercept, error = fit_line(strain[inside], stress[inside])
    if not slope > 0:
        return Modulus(_NAN, _NAN, n, (float(low), float(high)), 0.0, method, Reason.NOT_POSITIVE, basis)
    return Modulus(float(slope / 1000.0), float(error / 1000.0), n, (float(low), float(high)),
                   float(-intercept / slope), method, basis=basis)


def elastic_fit_frames(strain: npt.ArrayLike, stress: npt.ArrayLike, low: float, high: float) -> np.ndarray:
    """Indices of the frames the elastic fit uses: stress within [low, high] on the loading branch.

    The loading branch is the frames (with both values finite) before the stress first exceeds
    ``high``, so an unloading or the falling branch after Rm is never among them.
    """
    strain, stress, frames = _valid(strain, stress)
    s = stress[frames]
    above = np.flatnonzero(s > high)
    branch = frames[:above[0] if above.size else s.size]
    return branch[(stress[branch] >= low) & (stress[branch] <= high)]


def proof_strength(strain: npt.ArrayLike, stress: npt.ArrayLike, E_GPa: float, offset: float = PROOF_OFFSET, *,
                   strain_at_zero_stress: float = 0.0, through_frame: int = -1) -> ProofStrength:
    """Proof strength Rp (Rp0.2 by default) by the offset line.

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    E_GPa : float
        The elastic modulus (slope of the offset line).
    offset : float
        The offset, as strain (0.002 = 0.2 %).
    strain_at_zero_stress : float
        Where the elastic line crosses zero stress (``Modulus.strain_at_zero_stress``).
    through_frame : int
        Search at least up to this frame (index in the input): the end of a yield plateau,
        whose first frame can hold the maximum force. -1: up to maximum force only.

    Returns
    -------
    ProofStrength
        The stress where the curve first crosses the line
        stress = E (strain - strain_at_zero_stress - offset), linearly interpolated between
        the last valid frame above the line and the first at or below it. Only the frames
        up to maximum force (or ``through_frame``) are searched: a fall of the force at
        fracture is no crossing.
    """
    method = (f"first crossing of the curve with the elastic line offset by {offset:.1%} strain "
              f"up to {'the end of the yield plateau' if through_frame >= 0 else 'maximum force'}, "
              "linear interpolation between the bracketing frames")
    if through_frame >= 0:
        method += ("; on a yield plateau the line meets the plateau, so this is the plateau's stress "
                   "(ISO 6892-1 reads ReH and ReL there; Rp0.2 is given for comparison)")
    strain, stress, frames = _valid(strain, stress)
    if not np.isfinite(E_GPa):
        return ProofStrength(_NAN, (-1, -1), method, Reason.NO_MODULUS)
    if frames.size == 0:
        return ProofStrength(_NAN, (-1, -1), method, Reason.NO_DATA)
    last = max(int(np.argmax(stress[frames])), int(np.searchsorted(frames, through_frame)))
    frames = frames[:last + 1]
    s, e = stress[frames], strain[frames]
    # stress above the offset line; > 0 on the elastic part (E * offset), falls through 0 at Rp
    above = s - E_GPa * 1000.0 * (e - strain_at_zero_stress - offset)
    crossed = np.flatnonzero((above[:-1] > 0) & (above[1:] <= 0))
    if crossed.size == 0:
        return ProofStrength(_NAN, (-1, -1), method, Reason.NEVER_CROSSED)
    i = crossed[0]
    t = above[i] / (above[i] - above[i + 1])
    value = s[i] + t * (s[i + 1] - s[i])
    return ProofStrength(float(value), (int(frames[i]), int(frames[i + 1])), method)


def tensile_strength(strain: npt.ArrayLike, stress: npt.ArrayLike, *, from_frame: int = 0) -> TensileStrength:
    """Tensile strength Rm: the maximum engineering stress.

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    from_frame : int
        First frame searched: the start of work hardening after discontinuous yielding, as
        ISO 6892-1:2019 3.9.2 takes Fm after it (an upper yield point can be higher).

    Returns
    -------
    TensileStrength
        Rm (MPa), the first frame with it and the strain there. After fracture the force
        is ~0, so the maximum is the one before fracture. NaN with ``FORCE_MISSING_AT_MAXIMUM``
        when the frame just before or after the maximum (among the frames with a strain) has
        no stress: a force stream that stopped, or stalled, while the force still rose could
        have its true maximum there, and the largest value seen is not Rm; NaN with ``STILL_RISING`` when the
        maximum is the last frame with a stress (a test stopped while the force rose).
    """
    method = "maximum engineering stress (maximum force), first frame with it"
    if from_frame > 0:
        method += " after the start of work hardening (ISO 6892-1:2019 3.9.2: Fm follows discontinuous yielding)"
    strain, stress, frames = _valid(strain, stress)
    frames = frames[frames >= from_frame]
    if frames.size == 0:
        return TensileStrength(_NAN, -1, _NAN, method, Reason.NO_DATA)
    frame = int(frames[np.argmax(stress[frames])])
    strained = np.flatnonzero(np.isfinite(strain))
    at = int(np.searchsorted(strained, frame))
    beside = strained[max(at - 1, 0):at + 2]
    if not np.isfinite(stress[beside]).all():
        return TensileStrength(_NAN, -1, _NAN, method, Reason.FORCE_MISSING_AT_MAXIMUM)
    if frame == frames[-1]:
        return TensileStrength(_NAN, -1, _NAN, method, Reason.STILL_RISING)
    return TensileStrength(float(stress[frame]), frame, float(strain[frame]), method)


def uniform_elongation(Rm: TensileStrength, E_GPa: float, *, strain_at_zero_stress: float = 0.0,
                       top: FlatTop | None = None) -> UniformElongation:
    """Ag and Agt: plastic and total extension at maximum force, percent.

    Parameters
    ----------
    Rm : TensileStrength
    E_GPa : float
    strain_at_zero_stress : float
        Toe correction (``Modulus.strain_at_zero_stress``).
    top : FlatTop, optional
        The curve's top (``top_of_curve``); None: read at the frame of Rm.

    Returns
    -------
    UniformElongation
        Ag = (strain - Rm / E - toe) x 100 (ISO 6892-1 Ag, the plastic part) and
        Agt = (strain - toe) x 100, the strain that of Rm's frame, or the middle of the plateau
        at maximum force when ``top`` found one (``rule``).
    """
    rule = AgRule.AT_MAXIMUM if top is None else top.rule
    where = rule.value if top is None else top.describe()
    method = (f"plastic extension at maximum force, (strain - Rm/E) x 100, toe-corrected, total = strain x 100; "
              f"read {where}")
    if Rm.reason is not None:
        return UniformElongation(_NAN, _NAN, method, Rm.reason, rule, top)
    strain = Rm.strain if top is None else top.strain
    total = 100.0 * (strain - strain_at_zero_stress)
    if not np.isfinite(E_GPa):
        return UniformElongation(_NAN, total, method, Reason.NO_MODULUS, rule, top)
    plastic = 100.0 * _plastic_strain(strain, Rm.value, E_GPa, strain_at_zero_stress)
    return UniformElongation(float(plastic), float(total), method, rule=rule, top=top)


def top_of_curve(strain: npt.ArrayLike, stress: npt.ArrayLike, Rm: TensileStrength, *,
                 from_frame: int = 0) -> FlatTop | None:
    """The curve's top as Ag reads it (``dic.tensile.flat_top.flat_top``) over the frames from ``from_frame``
    (the start of work hardening after discontinuous yielding); None when Rm is NaN."""
    if Rm.reason is not None:
        return None
    strain, stress, frames = _valid(strain, stress)
    return flat_top(strain, stress, frames[frames >= from_frame], Rm.frame, Rm.strain)


def fracture_frame(strain: npt.ArrayLike, stress: npt.ArrayLike, *, drop: float = FRACTURE_DROP) -> int:
    """The first frame whose stress falls below ``drop`` x Rm after the frame of Rm (-1: none).

    Only frames with both a strain and a stress count. The frames from this one on are the
    broken specimen's: the stress-strain curve ends here.
    """
    _, stress, frames = _valid(strain, stress)
    if frames.size == 0:
        return -1
    s = stress[frames]
    peak = int(np.argmax(s))
    fallen = np.flatnonzero(s[peak:] < drop * s[peak])
    return int(frames[peak + fallen[0]]) if fallen.size else -1


def elongation_after_fracture(strain: npt.ArrayLike, stress: npt.ArrayLike, E_GPa: float, *,
                              drop: float = FRACTURE_DROP,
                              strain_at_zero_stress: float = 0.0) -> ElongationAfterFracture:
    """A: plastic elongation at fracture, percent.

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    E_GPa : float
    drop : float
        Fracture is where the stress first falls below ``drop`` x Rm after the frame of Rm.
    strain_at_zero_stress : float
        Toe correction (``Modulus.strain_at_zero_stress``).

    Returns
    -------
    ElongationAfterFracture
        (strain - stress / E - toe) x 100 at the last valid frame before that fall: the
        elongation the broken specimen keeps once its elastic strain has recovered.
    """
    method = (f"plastic strain x 100 at the last frame before the stress falls below "
              f"{drop:.0%} of Rm after Rm (fracture), elastic recovery stress/E removed")
    strain, stress, frames = _valid(strain, stress)
    if not np.isfinite(E_GPa):
        return ElongationAfterFracture(_NAN, -1, method, Reason.NO_MODULUS)
    if frames.size == 0:
        return ElongationAfterFracture(_NAN, -1, method, Reason.NO_DATA)
    broken = fracture_frame(strain, stress, drop=drop)
    if broken < 0:
        return ElongationAfterFracture(_NAN, -1, method, Reason.NO_FRACTURE)
    frame = int(frames[np.searchsorted(frames, broken) - 1])
    plastic = 100.0 * _plastic_strain(strain[frame], stress[frame], E_GPa, strain_at_zero_stress)
    return ElongationAfterFracture(float(plastic), frame, method)


def yield_analysis(strain: npt.ArrayLike, stress: npt.ArrayLike, E: Modulus) -> tuple[YieldAnalysis, np.ndarray]:
    """``dic.tensile.yielding.analyse_yielding`` of the valid frames; its indices mapped to input frames.

    Returns the analysis (frames as indices of the input arrays) and the valid frames.
    """
    strain, stress, frames = _valid(strain, stress)
    if not np.isfinite(E.value) or frames.size == 0:
        return YieldAnalysis(CurveShape.UNDETERMINED), frames
    found = analyse_yielding(strain[frames], stress[frames], E.value * 1000.0, E.strain_at_zero_stress)

    def frame(i: int) -> int:
        return int(frames[i]) if i >= 0 else -1
    mapped = YieldAnalysis(found.shape, frame(found.start), found.start_strain, frame(found.upper),
                           frame(found.lowest_from),
                           frame(found.end), found.end_strain, found.hardening, frame(found.hardening_from))
    return mapped, frames


def yield_strengths(strain: npt.ArrayLike, stress: npt.ArrayLike,
                    found: YieldAnalysis) -> tuple[YieldStrength, YieldStrength, YieldPointExtension]:
    """ReH, ReL and Ae of a curve with a yield phenomenon (ISO 6892-1:2019 3.10.2.1, 3.10.2.2, 3.6.3).

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    found : YieldAnalysis
        From ``yield_analysis`` (frames as input indices).

    Returns
    -------
    (YieldStrength, YieldStrength, YieldPointExtension)
        NaN with ``NO_YIELD_PHENOMENON`` on continuous yielding, ``SHAPE_UNDETERMINED`` when
        the shape could not be read.
    """
    strain, stress, frames = _valid(strain, stress)
    if found.shape in (CurveShape.CONTINUOUS, CurveShape.UNDETERMINED):
        reason = (Reason.NO_YIELD_PHENOMENON if found.shape is CurveShape.CONTINUOUS
                  else Reason.SHAPE_UNDETERMINED)
        return (YieldStrength(_NAN, -1, "upper yield strength", reason),
                YieldStrength(_NAN, -1, "lower yield strength", reason),
                YieldPointExtension(_NAN, (-1, -1), "yield point extension", reason))
    smoothed = np.full(stress.shape, _NAN)
    smoothed[frames] = smooth(stress[frames])
    # up to where Ae ends: past it the running mean takes in the first frames of hardening or of the fall
    plateau = frames[(frames >= found.lowest_from) & (frames <= found.end) & (strain[frames] <= found.end_strain)]
    plateau = plateau[:max(plateau.size - SMOOTH_FRAMES, 1)]
    low = int(plateau[np.argmin(smoothed[plateau])])
    if found.shape is CurveShape.UPPER_YIELD_POINT:
        upper = YieldStrength(float(stress[found.upper]), found.upper,
                              "highest stress before the first decrease in force (ISO 6892-1:2019 3.10.2.1)")
        transient = "ignoring the initial transient (the first 0.1 % strain after the drop, 3.10.2.2)"
    else:
        high = int(plateau[np.argmax(smoothed[plateau])])
        upper = YieldStrength(float(smoothed[high]), high,
                              "no force drop at yield: the highest stress of the yield plateau (3.10.2.1: "
                              "no decrease in force precedes it), running mean over 5 frames")
        transient = "no upper yield point, so no transient"
    lower = YieldStrength(float(smoothed[low]), low,
                          f"lowest stress during plastic yielding, {transient}, running mean over 5 frames "
                          "(ISO 6892-1:2019 3.10.2.2)")
    if found.hardening:
        end_rule = ("the start of uniform work hardening: a horizontal line through the plateau's last local "
                    "minimum meets a regression line through the work-hardening range (Figure 7)")
    else:
        end_rule = "the end of the plateau, where the force starts to fall (no work hardening follows)"
    method = (f"extension x 100 from the start of discontinuous yielding (ReH or the plateau's start) to {end_rule} "
              "(ISO 6892-1:2019 3.6.3)")
    extension = YieldPointExtension(float(100.0 * (found.end_strain - found.start_strain)), (found.start, found.end),
                                    method, strains=(found.start_strain, found.end_strain))
    return upper, lower, extension


def tensile_properties(strain: npt.ArrayLike, stress: npt.ArrayLike, *, stress_range: tuple[float, float] | None = None,
                       offset: float = PROOF_OFFSET, drop: float = FRACTURE_DROP,
                       min_points: int = MIN_POINTS) -> TensileProperties:
    """E, Rp0.2, Rm, Ag, A, and on a yield phenomenon ReH, ReL and Ae, of one test.

    Parameters
    ----------
    strain, stress : array_like (n,)
        Engineering strain (-) and stress (MPa) per frame; NaN frames are skipped.
    stress_range : (float, float), optional
        Stress range (MPa) for E. Default: E is fitted over 10 % to 40 % of the maximum
        stress, Rp0.2 found with it, then E refitted over 10 % to 40 % of that Rp0.2 (kept
        when it has ``min_points`` frames) and Rp0.2 found again with the refit.
    offset : float
        Proof strain (0.002: Rp0.2).
    drop : float
        Fracture's force drop, as share of Rm (``elongation_after_fracture``).
    min_points : int
        Fewest frames for the fit of E.

    Returns
    -------
    TensileProperties
        On discontinuous yielding Rp0.2 is the offset line's crossing with the plateau, Rm the
        maximum after the start of work hardening, and Rm, Ag, Agt are NaN with
        ``NO_WORK_HARDENING`` when none follows (ISO 6892-1:2019 3.9.2 Note 1).
    """
    E = modulus(strain, stress, stress_range=stress_range, min_points=min_points)
    found, _ = yield_analysis(strain, stress, E)
    rp = proof_strength(strain, stress, E.value, offset, strain_at_zero_stress=E.strain_at_zero_stress,
                        through_frame=found.end)
    if stress_range is None and rp.reason is None:
        refit = modulus(strain, stress, rp02_MPa=rp.value, min_points=min_points)
        if refit.reason is None:
            E = refit
            found, _ = yield_analysis(strain, stress, E)
            rp = proof_strength(strain, stress, E.value, offset,
                                strain_at_zero_stress=E.strain_at_zero_stress, through_frame=found.end)
    ReH, ReL, Ae = yield_strengths(strain, stress, found)
    from_frame = found.hardening_from if found.hardening else 0
    if found.shape in (CurveShape.CONTINUOUS, CurveShape.UNDETERMINED):
        Rm = tensile_strength(strain, stress)
    elif found.hardening:
        Rm = tensile_strength(strain, stress, from_frame=from_frame)
    else:
        Rm = TensileStrength(_NAN, -1, _NAN, "maximum force after the start of work hardening (ISO 6892-1:2019 "
                             "3.9.2)", Reason.NO_WORK_HARDENING)
    Ag = uniform_elongation(Rm, E.value, strain_at_zero_stress=E.strain_at_zero_stress,
                            top=top_of_curve(strain, stress, Rm, from_frame=from_frame))
    A = elongation_after_fracture(strain, stress, E.value, drop=drop,
                                  strain_at_zero_stress=E.strain_at_zero_stress)
    return TensileProperties(E, rp, Rm, Ag, A, ReH, ReL, Ae, found.shape)
