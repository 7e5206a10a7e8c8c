"""The yield phenomenon of an engineering stress-strain curve, read as ISO 6892-1:2019 reads it.

Input: the frames with both a strain and a stress (``dic.tensile.properties`` passes them), the
elastic modulus and the toe correction. Output: a ``YieldAnalysis``, data only: the curve's
``CurveShape`` and the frames where the yield phenomenon starts, where its transient ends and
where uniform work hardening starts (or where the force starts to fall when none follows).

How the shape is read, robust to the force noise of a class 0.5/1 load cell (~0.1-0.3 % per
reading) and the strain noise of a DIC extensometer (1e-5..1e-4): the stress and strain are
smoothed by a running mean over ``SMOOTH_FRAMES`` frames (one noisy reading is no yield point),
and every band below widens to ``NOISE_SIGMAS`` standard deviations of that mean when the force is
noisier (the noise measured from the curve's second differences, ``stress_noise``); then

* **upper yield point** (``UPPER_YIELD_POINT``): the smoothed force falls more than ``DROP``
  (1 %) below its running maximum while the plastic strain is still below
  ``UPPER_YIELD_MAX_PLASTIC`` (0.5 %), and the stress then holds a plateau at least
  ``MIN_YIELD_EXTENSION`` long or work hardening follows at once (a falling branch to fracture,
  a brittle curve, is neither);
  ReH is that maximum, "the maximum stress prior to the first decrease in force" (3.10.2.1);
* **yield plateau** (``PLATEAU``): no such drop, but from the yield onset (plastic strain above
  ``YIELD_ONSET``) the smoothed stress rises less than ``HARDENING_RISE`` (0.5 %) above its
  level (its median) over at least ``MIN_YIELD_EXTENSION`` (0.5 %) of strain: plastic deformation
  "without any increase in the force" (3.10.2);
* **continuous yielding** (``CONTINUOUS``): neither.

The plateau ends at the start of uniform work hardening, by the construction of ISO 6892-1
Figure 7: the intersection of a horizontal line through the last local minimum of the plateau
(here the median of its last third: a minimum of noisy readings lies below the plateau) with a
regression line through the work-hardening range right after it; where no work
hardening follows (the force falls from the plateau into necking), the plateau ends at its last
frame whose smoothed stress is within ``HARDENING_RISE`` of the plateau's level.

Clauses cited (ISO 6892-1:2019): 3.10.2 yield strength, 3.10.2.1 ReH, 3.10.2.2 ReL, 3.6.3 Ae,
3.9.2 Fm for discontinuous yielding (Note 1: undefined without work hardening), Figures 2 and 7.
These numbers are cited from memory, not checked against the standard's text (none was at hand:
docs/guide/tensile-test.md, "Sources and clause numbers").
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

SMOOTH_FRAMES = 5              # running mean for the shape decisions (odd)
DROP = 0.01                    # a force decrease larger than this share is a drop (noise of class 1 is ~0.3 %)
UPPER_YIELD_MAX_PLASTIC = 0.005  # an upper yield point lies at the very start of plastic flow
YIELD_ONSET = 0.0005           # plastic strain that starts the yield phenomenon (5x the DIC noise of 1e-4)
HARDENING_RISE = 0.005         # a rise above the plateau's level (median) larger than this share is work hardening
MIN_YIELD_EXTENSION = 0.005    # shortest plateau (strain) read as discontinuous yielding
TRANSIENT_EXTENSION = 0.001    # strain after the drop at ReH ignored for ReL: the initial transient (3.10.2.2)
HARDENING_FIT_EXTENSION = 0.01  # strain of the work-hardening range fitted for the end of Ae (Figure 7)
NOISE_SIGMAS = 5.0             # a rise or fall is real beyond this many SDs of the smoothed stress's noise


class CurveShape(enum.Enum):
    """How the material yields (ISO 6892-1:2019 Figures 2 and 7)."""
    CONTINUOUS = "continuous yielding"
    PLATEAU = "discontinuous yielding: a yield plateau without a force drop"
    UPPER_YIELD_POINT = "discontinuous yielding: upper yield point and force drop, then a (Lueders) plateau"
    UNDETERMINED = "too few frames past the elastic range to tell"


@dataclass(frozen=True)
class YieldAnalysis:
    """Where the yield phenomenon lies, as indices into the arrays given (-1: none).

    Attributes
    ----------
    shape : CurveShape
    start : int
        Start of discontinuous yielding: the frame of ReH (upper yield point) or the first frame
        of the plateau.
    start_strain : float
        Strain where it starts: at ReH, or where the elastic line reaches the plateau's stress.
    upper : int
        The frame of ReH: the largest stress before the first decrease in force.
    lowest_from : int
        First frame searched for ReL (after the initial transient).
    end : int
        Last frame of the plateau (before work hardening or the fall into necking).
    end_strain : float
        Strain at the end of the yield point extension (Figure 7 intersection); NaN when none.
    hardening : bool
        Whether uniform work hardening follows the plateau.
    hardening_from : int
        First frame of work hardening (-1 without).
    """
    shape: CurveShape
    start: int = -1
    start_strain: float = float("nan")
    upper: int = -1
    lowest_from: int = -1
    end: int = -1
    end_strain: float = float("nan")
    hardening: bool = False
    hardening_from: int = -1


def smooth(values: np.ndarray, frames: int = SMOOTH_FRAMES) -> np.ndarray:
    """Centred running mean over ``frames`` values (fewer at the ends)."""
    kernel = np.ones(frames)
    total = np.convolve(values, kernel, mode="same")
    count = np.convolve(np.ones_like(values), kernel, mode="same")
    return total / count


def stress_noise(stress: np.ndarray) -> float:
    """Standard deviation of one stress reading's noise (MPa), from the median absolute second difference.

    A second difference of independent noise has SD sqrt(6) sigma; the median ignores the few large
    ones at the curve's kinks and drops, and the smooth curve's own curvature adds almost nothing.
    """
    if stress.size < 3:
        return 0.0
    return float(1.4826 * np.median(np.abs(np.diff(stress, 2))) / np.sqrt(6.0))


def analyse_yielding(strain: np.ndarray, stress: np.ndarray, E_MPa: float, toe: float) -> YieldAnalysis:
    """Shape of the curve and the frames of its yield phenomenon.

    Parameters
    ----------
    strain, stress : ndarray (n,)
        Engineering strain (-) and stress (MPa), all finite, in test order.
    E_MPa : float
        Elastic modulus (MPa), finite and > 0.
    toe : float
        Strain where the elastic line crosses zero stress.

    Returns
    -------
    YieldAnalysis
    """
    if strain.size < 3 * SMOOTH_FRAMES:
        return YieldAnalysis(CurveShape.UNDETERMINED)
    s = smooth(stress)
    e = smooth(strain)
    plastic = e - s / E_MPa - toe
    onset_at = np.flatnonzero(plastic > YIELD_ONSET)
    if onset_at.size == 0:
        return YieldAnalysis(CurveShape.UNDETERMINED)
    band = NOISE_SIGMAS * stress_noise(stress) / np.sqrt(SMOOTH_FRAMES)     # MPa, on the smoothed stress
    running_max = np.maximum.accumulate(s)
    dropped = np.flatnonzero(s < np.minimum((1.0 - DROP) * running_max, running_max - band))
    if dropped.size:
        first_drop = int(dropped[0])
        upper = int(np.argmax(stress[:first_drop + 1]))     # raw: the peak is a real, narrow feature
        # the drop itself comes at the start of plastic flow: a later one is necking, a noisy spike no peak
        if plastic[first_drop] < UPPER_YIELD_MAX_PLASTIC:
            after = np.flatnonzero(strain >= strain[first_drop] + TRANSIENT_EXTENSION)
            if after.size:
                found = _plateau(strain, s, int(after[0]), band, min_extension=0.0)
                # a plateau, or work hardening right after the drop: a fall to fracture is no yield point
                if found is not None and (found[2] or strain[found[0]] - strain[after[0]] >= MIN_YIELD_EXTENSION):
                    return YieldAnalysis(CurveShape.UPPER_YIELD_POINT, upper, float(strain[upper]), upper,
                                         int(after[0]), *found)
    onset = int(onset_at[0])
    # The running mean reaches back over the kink into the elastic line: judge the plateau past its reach.
    first = min(onset + SMOOTH_FRAMES, s.size - 1)
    found = _plateau(strain, s, first, band)
    if found is not None:
        highest = first + int(np.argmax(s[first:found[0] + 1]))
        # the elastic line's strain at the plateau's stress: the yield point, free of the strain's noise
        start_strain = float(s[first] / E_MPa + toe)
        return YieldAnalysis(CurveShape.PLATEAU, onset, start_strain, highest, first, *found)
    return YieldAnalysis(CurveShape.CONTINUOUS)


def _plateau(strain: np.ndarray, s: np.ndarray, first: int, band: float,
             min_extension: float = MIN_YIELD_EXTENSION) -> tuple[int, float, bool, int] | None:
    """The plateau from frame ``first`` on: (end frame, end strain, hardening, hardening frame), or None.

    The plateau holds while the smoothed stress ``s`` stays within ``HARDENING_RISE`` above and
    ``DROP`` below its level (or ``band`` MPa either way, where that is wider) (the median so far: a running minimum would creep down with the
    noise and read noise as hardening); it ends where ``SMOOTH_FRAMES`` frames in a row leave
    that band, and must span ``min_extension`` of strain from ``first`` on. A rise ends it
    with work hardening, a fall without.
    """
    end = first
    beyond = -1
    hardening = False
    for i in range(first + 1, s.size):
        level = float(np.median(s[first:end + 1]))
        run = s[i:i + SMOOTH_FRAMES]
        if np.all(run > level + max(HARDENING_RISE * level, band)):
            beyond, hardening = i, True
            break
        if np.all(run < level - max(DROP * level, band)):
            beyond = i
            break
        end = i
    if strain[end] - strain[first] < min_extension:       # from ``first``: no skipped frame counts
        return None
    if beyond < 0:
        return end, float(strain[end]), False, -1
    if not hardening:
        # the force's fall into necking can start with a vertical tangent (the neck strains outside the plateau's
        # law): no line to fit; the plateau ends at its last frame within HARDENING_RISE of its level
        level = float(np.median(s[first:end + 1]))
        held = first + np.flatnonzero(s[first:beyond] >= level - max(HARDENING_RISE * level, band))
        return int(held[-1]), float(strain[held[-1]]), False, -1
    return end, _plateau_end_strain(strain, s, first, end, beyond), True, beyond


def _plateau_end_strain(strain: np.ndarray, s: np.ndarray, first: int, end: int, beyond: int) -> float:
    """Strain where a regression line of the work-hardening range meets the plateau's horizontal line.

    ISO 6892-1:2019 Figure 7: the horizontal line goes through the plateau's last local minimum
    (here the median of its last third: a minimum of noisy readings lies below the plateau); the line is fitted over
    ``HARDENING_FIT_EXTENSION`` of strain from the first hardening frame, up to the maximum stress.
    Falls back to the strain of that first frame when the fit does not cross the plateau.
    """
    tail = slice(end - (end - first) // 3, end + 1)
    level = float(np.median(s[tail]))
    stop = beyond + int(np.argmax(s[beyond:]))
    window = np.flatnonzero(strain[beyond:stop + 1] <= strain[beyond] + HARDENING_FIT_EXTENSION)
    fit = beyond + window
    if fit.size >= 3 and np.ptp(strain[fit]) > 0:
        slope, intercept = np.polyfit(strain[fit], s[fit], 1)
        if slope > 0:
            crossing = (level - intercept) / slope
            if strain[first] <= crossing <= strain[beyond]:
                return float(crossing)
    return float(strain[beyond])
