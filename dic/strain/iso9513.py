"""An extensometer's class by ISO 9513:2012 from known elongations: relative bias, resolution, class met.

The classification table (ISO 9513:2012, Table 2, "Classification of extensometer systems") gives, per
class, the largest permitted

* relative error of the gauge length q_Le (%),
* resolution r, as a percentage of the reading (r / l_i) **or** in micrometres, whichever is greater,
* bias, relative q = (l_i - l_t) / l_t (%) **or** absolute l_i - l_t (um), whichever is greater,

so at small elongations the absolute limits (um) hold and at large ones the relative limits (%). The
absolute limits are lengths on the specimen: they need the scale (px/mm). Without one this module
classifies on the relative limits only and says so (``Limitation.NO_SCALE``): that is stricter than the
standard, so a class met is met; a step of zero elongation (a rigid translation) has no relative limit
at all and is not classified (``StepReason.ZERO_NEEDS_SCALE``).

Resolution of a fluctuating indication: a DIC reading fluctuates from frame to frame at a constant
elongation (image noise); as for a digital indicator whose last digit fluctuates, the resolution is
taken as half the range (max - min) of the readings held at one elongation. The bias is the mean of
those readings less the true elongation. The gauge length of a virtual extensometer is set in
software (exact in px); its error in mm is the scale's, which this module does not measure: give
``l0_relative_error`` when a calibration states it, otherwise the result says it was not assessed.

Sources: the table's values as ISO 9513:2012 Table 2 gives them; the full text was not at hand when this was
written, so the clause numbers are not cited, and the class 0.5 row was cross-checked against an extensometer
maker's description of its limits (0.5 % or 1.5 um = 3 x the 0.5 um resolution, the absolute limit holding up
to 300 um). The half-range rule for a fluctuating reading is this module's reading of the standard's rule
for an indicator that fluctuates at rest.

What zero steps alone verify: every class's absolute limits (um) are the greater ones only up to a
true elongation of bias_um / bias_relative = 300 um (resolution: 200 um), the same for all four classes;
above it the relative (%) limits hold, and an error that grows with the elongation (a wrong scale, lens
distortion, out-of-plane motion) shows only there. Static frames and rigid translations verify the zero
point (its bias and resolution against the absolute limits) and nothing of that growth, so a
classification without a non-zero step claims no class (``StepReason.NO_ELONGATION``) and states the
best class the zero point meets (``Classification.zero_point_class``).

EN 4861:2020 describes this kind of in-situ assessment of a DIC extensometer with known displacements
before a test; it is not a calibration under ISO 9513 (whose apparatus and procedure are physical).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["ClassLimits", "CLASSES", "CLASS_NAMES", "StepReason", "Limitation", "StepClass", "Classification",
           "classify_step", "classify", "class_for_gauge_length_error", "limiting_step"]

UM_PER_MM = 1000.0


@dataclass(frozen=True)
class ClassLimits:
    """One row of ISO 9513:2012 Table 2: an extensometer class's permitted errors.

    Attributes
    ----------
    name : str
        The class ("0.2", "0.5", "1", "2").
    gauge_length_relative : float
        Relative error of the gauge length, fraction (0.002 is 0.2 %).
    resolution_relative, resolution_um : float
        Resolution as a fraction of the reading, or in micrometres, whichever is greater.
    bias_relative, bias_um : float
        Bias as a fraction of the true elongation, or in micrometres, whichever is greater.
    """
    name: str
    gauge_length_relative: float
    resolution_relative: float
    resolution_um: float
    bias_relative: float
    bias_um: float


# ISO 9513:2012, Table 2, best class first.
CLASSES: tuple[ClassLimits, ...] = (
    ClassLimits("0.2", 0.002, 0.0010, 0.2, 0.002, 0.6),
    ClassLimits("0.5", 0.005, 0.0025, 0.5, 0.005, 1.5),
    ClassLimits("1", 0.010, 0.0050, 1.0, 0.010, 3.0),
    ClassLimits("2", 0.020, 0.0100, 2.0, 0.020, 6.0),
)
CLASS_NAMES: tuple[str, ...] = tuple(c.name for c in CLASSES)
MIN_READINGS = 2          # a resolution from fluctuation needs at least two readings at one elongation


class StepReason(enum.Enum):
    """Why a step has the class it has, or none."""
    CLASSIFIED = "classified"
    OUTSIDE_CLASSES = "bias or resolution beyond class 2"
    READINGS_LOST = "a reading at this elongation is missing (an extensometer end lost its points)"
    TOO_FEW_READINGS = f"fewer than {MIN_READINGS} readings: no resolution from fluctuation"
    ZERO_NEEDS_SCALE = "zero elongation has only absolute (um) limits, and no scale (px/mm) was given"
    GAUGE_LENGTH_OUTSIDE = "the gauge length's error is beyond class 2"
    NO_ELONGATION = ("no known non-zero elongation: only the zero point (bias and resolution against the absolute "
                     "um limits) was verified, not the relative limits that hold above 300 um; no class is claimed")


class Limitation(enum.Enum):
    """What the overall class does not cover (a class with limitations is stated with them)."""
    NO_SCALE = "no scale: absolute (um) limits not applied, relative limits only (stricter)"
    ZERO_STEPS_NOT_CLASSIFIED = "zero-elongation steps not classified (no scale)"
    GAUGE_LENGTH_NOT_ASSESSED = "gauge length error not assessed (set in software; its mm error is the scale's)"


@dataclass(frozen=True)
class StepClass:
    """One elongation step's verification.

    Lengths in px (``*_um``: micrometres on the specimen, NaN without a scale). ``relative_bias`` is
    bias / true (NaN at zero elongation), ``relative_resolution`` resolution / |mean reading|.
    ``best_class`` is the best class whose bias and resolution limits both hold (None: ``reason``).
    """
    true_px: float
    mean_px: float
    bias_px: float
    resolution_px: float
    relative_bias: float
    relative_resolution: float
    bias_um: float
    resolution_um: float
    max_error_px: float
    readings: int
    best_class: str | None
    reason: StepReason

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: NaN as None, the reason as its name and text."""
        out: dict[str, Any] = {}
        for name in ("true_px", "mean_px", "bias_px", "resolution_px", "relative_bias", "relative_resolution",
                     "bias_um", "resolution_um", "max_error_px"):
            value = getattr(self, name)
            out[name] = value if math.isfinite(value) else None
        out.update(readings=self.readings, best_class=self.best_class, reason=self.reason.name,
                   reason_text=self.reason.value)
        return out


@dataclass(frozen=True)
class Classification:
    """An extensometer's verification over all its steps: the class every classified step meets.

    ``met_class`` is None when any step has lost readings, too few readings or meets no class, no step
    could be classified, or no step has a non-zero elongation; ``reason`` then says why. ``zero_point_class``
    is the class the zero-elongation steps meet (None: no classified zero step). ``limitations`` say what the
    class does not cover.
    """
    l0_px: float
    l0_mm: float | None
    scale_px_per_mm: float | None
    steps: tuple[StepClass, ...]
    met_class: str | None
    reason: StepReason
    limitations: tuple[Limitation, ...] = field(default=())
    zero_point_class: str | None = None

    @property
    def elongation_verified(self) -> bool:
        """Whether any step had a known non-zero elongation (without one no class is claimed)."""
        return any(step.true_px != 0 for step in self.steps)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"l0_px": self.l0_px, "l0_mm": self.l0_mm, "scale_px_per_mm": self.scale_px_per_mm,
                "met_class": self.met_class, "reason": self.reason.name, "reason_text": self.reason.value,
                "zero_point_class": self.zero_point_class, "elongation_verified": self.elongation_verified,
                "limitations": [item.value for item in self.limitations],
                "steps": [step.as_dict() for step in self.steps]}


def _um_per_px(scale_px_per_mm: float | None) -> float:
    return UM_PER_MM / scale_px_per_mm if scale_px_per_mm else math.nan


def classify_step(true_px: float, readings_px: npt.ArrayLike, *,
                  scale_px_per_mm: float | None = None) -> StepClass:
    """Verify one known elongation from the readings held at it.

    Parameters
    ----------
    true_px : float
        The true elongation (length change of the gauge length), px; 0 for a rigid motion.
    readings_px : array (M,)
        The extensometer's elongation readings at that elongation (one per frame), px; NaN where lost.
    scale_px_per_mm : float, optional
        The scale on the specimen plane; without it the absolute (um) limits are not applied.

    Returns
    -------
    StepClass
    """
    readings = np.asarray(readings_px, dtype=np.float64).ravel()
    um_per_px = _um_per_px(scale_px_per_mm)
    finite = readings[np.isfinite(readings)]
    mean = float(finite.mean()) if finite.size else math.nan
    bias = mean - true_px
    resolution = 0.5 * float(finite.max() - finite.min()) if finite.size else math.nan
    max_error = float(np.max(np.abs(finite - true_px))) if finite.size else math.nan
    with np.errstate(invalid="ignore", divide="ignore"):
        relative_bias = bias / true_px if true_px != 0 else math.nan
        relative_resolution = resolution / abs(mean) if mean != 0 else math.nan
    if finite.size < readings.size:
        best, reason = None, StepReason.READINGS_LOST
    elif readings.size < MIN_READINGS:
        best, reason = None, StepReason.TOO_FEW_READINGS
    elif true_px == 0 and scale_px_per_mm is None:
        best, reason = None, StepReason.ZERO_NEEDS_SCALE
    else:
        best = _best_class(abs(bias), resolution, abs(true_px), abs(mean), um_per_px)
        reason = StepReason.CLASSIFIED if best is not None else StepReason.OUTSIDE_CLASSES
    return StepClass(true_px=float(true_px), mean_px=mean, bias_px=bias, resolution_px=resolution,
                     relative_bias=float(relative_bias), relative_resolution=float(relative_resolution),
                     bias_um=bias * um_per_px, resolution_um=resolution * um_per_px, max_error_px=max_error,
                     readings=int(readings.size), best_class=best, reason=reason)


def _best_class(bias: float, resolution: float, true: float, reading: float, um_per_px: float) -> str | None:
    """The best class whose limits (the greater of relative and absolute; relative only when ``um_per_px`` is
    NaN) hold ``bias`` and ``resolution`` (px)."""
    for limits in CLASSES:
        bias_limit = limits.bias_relative * true
        resolution_limit = limits.resolution_relative * reading
        if math.isfinite(um_per_px):
            bias_limit = max(bias_limit, limits.bias_um / um_per_px)
            resolution_limit = max(resolution_limit, limits.resolution_um / um_per_px)
        if bias <= bias_limit and resolution <= resolution_limit:
            return limits.name
    return None


def class_for_gauge_length_error(relative_error: float) -> str | None:
    """The best class whose gauge-length limit holds ``relative_error`` (a fraction); None beyond class 2."""
    for limits in CLASSES:
        if abs(relative_error) <= limits.gauge_length_relative:
            return limits.name
    return None


def _worst(names: Sequence[str]) -> str:
    return max(names, key=CLASS_NAMES.index)


def classify(true_px: npt.ArrayLike, readings_px: Sequence[npt.ArrayLike], l0_px: float, *,
             scale_px_per_mm: float | None = None, l0_relative_error: float | None = None) -> Classification:
    """Classify an extensometer by ISO 9513:2012 Table 2 from known elongations.

    Parameters
    ----------
    true_px : array (S,)
        The true elongation of each step, px (0: a rigid motion).
    readings_px : sequence of S arrays (M,)
        The elongation readings held at each step, px (NaN where lost).
    l0_px : float
        The gauge length, px.
    scale_px_per_mm : float, optional
        Scale on the specimen plane; without it the absolute limits cannot be applied (``Limitation.NO_SCALE``).
    l0_relative_error : float, optional
        The gauge length's relative error when known (from a calibration); it limits the class too.

    Returns
    -------
    Classification
        The class met by every classified step (the worst of theirs), or None with the first blocking reason.

    Examples
    --------
    >>> result = classify([0.0, 4.0], [[0.004, -0.004], [4.004, 4.006]], 400.0, scale_px_per_mm=10.0)
    >>> [s.best_class for s in result.steps], result.met_class
    (['0.5', '0.2'], '0.5')
    """
    true = np.asarray(true_px, dtype=np.float64).ravel()
    if len(readings_px) != true.size:
        raise ValueError(f"{true.size} true elongations but {len(readings_px)} sets of readings: one set per step")
    if not (math.isfinite(l0_px) and l0_px > 0):
        raise ValueError(f"the gauge length must be a finite number > 0 px, got {l0_px!r}")
    if scale_px_per_mm is not None and not (math.isfinite(scale_px_per_mm) and scale_px_per_mm > 0):
        raise ValueError(f"the scale must be a finite number > 0 px/mm, got {scale_px_per_mm!r}")
    steps = tuple(classify_step(float(t), r, scale_px_per_mm=scale_px_per_mm) for t, r in zip(true, readings_px))
    limitations = []
    if scale_px_per_mm is None:
        limitations.append(Limitation.NO_SCALE)
        if any(s.reason is StepReason.ZERO_NEEDS_SCALE for s in steps):
            limitations.append(Limitation.ZERO_STEPS_NOT_CLASSIFIED)
    classes = [s.best_class for s in steps if s.best_class is not None]
    if l0_relative_error is None:
        limitations.append(Limitation.GAUGE_LENGTH_NOT_ASSESSED)
    blocking = [s.reason for s in steps if s.reason not in (StepReason.CLASSIFIED, StepReason.ZERO_NEEDS_SCALE)]
    met: str | None
    reason: StepReason
    if blocking:
        met, reason = None, blocking[0]
    elif not classes:
        met, reason = None, StepReason.ZERO_NEEDS_SCALE
    else:
        met, reason = _worst(classes), StepReason.CLASSIFIED
        if l0_relative_error is not None:
            gauge = class_for_gauge_length_error(l0_relative_error)
            met, reason = ((None, StepReason.GAUGE_LENGTH_OUTSIDE) if gauge is None else (_worst([met, gauge]), reason))
    zeros = [s.best_class for s in steps if s.true_px == 0 and s.best_class is not None]
    zero_point = _worst(zeros) if zeros and len(zeros) == sum(s.true_px == 0 for s in steps) else None
    if met is not None and not any(s.true_px != 0 for s in steps):
        met, reason = None, StepReason.NO_ELONGATION
    l0_mm = l0_px / scale_px_per_mm if scale_px_per_mm else None
    return Classification(l0_px=float(l0_px), l0_mm=l0_mm, scale_px_per_mm=scale_px_per_mm, steps=steps,
                          met_class=met, reason=reason, limitations=tuple(limitations), zero_point_class=zero_point)


def limiting_step(result: Classification) -> tuple[int, str] | None:
    """The step that sets the overall class and why: ``(index, text)``; None without steps.

    The first blocking step (lost or too few readings, beyond class 2), else the step of the worst class,
    with the limit of the next better class that its bias or resolution exceeds.
    """
    for k, step in enumerate(result.steps):
        if step.reason not in (StepReason.CLASSIFIED, StepReason.ZERO_NEEDS_SCALE):
            return k, step.reason.value
    classified = [(CLASS_NAMES.index(s.best_class), k) for k, s in enumerate(result.steps) if s.best_class]
    if not classified:
        return None
    rank, k = max(classified)
    if rank == 0:
        return k, f"meets class {CLASS_NAMES[0]}, the best"
    step, better = result.steps[k], CLASSES[rank - 1]
    um_per_px = _um_per_px(result.scale_px_per_mm)
    bias_limit = better.bias_relative * abs(step.true_px)
    resolution_limit = better.resolution_relative * abs(step.mean_px)
    if math.isfinite(um_per_px):
        bias_limit = max(bias_limit, better.bias_um / um_per_px)
        resolution_limit = max(resolution_limit, better.resolution_um / um_per_px)
    def length(px: float) -> str:
        return f"{px:.4g} px" + (f" ({px * um_per_px:.3g} um)" if math.isfinite(um_per_px) else "")
    failed = [f"{name} {length(value)} > {length(limit)}" for name, value, limit in
              (("|bias|", abs(step.bias_px), bias_limit), ("resolution", step.resolution_px, resolution_limit))
              if value > limit]
    return k, f"class {step.best_class}: {' and '.join(failed)} (the class {better.name} limit)"
