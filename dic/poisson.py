"""Poisson's ratio over the elastic range, and the plastic contraction ratio, from two extensometers.

Input: per frame, the engineering strain of an axial and of a transverse extensometer (NaN
where either has no reading: the frame is skipped), optionally the force (or stress: any unit,
only shares of it are used), and the frames' numbers for the labels.

Poisson's ratio (ASTM E132: fitted over the elastic range) is minus the slope of a least-squares
line of transverse on axial strain, **with an intercept**: DIC measures both strains from one
reference image, whose own noise (and a preload or seating before it) is a constant offset in
every later reading of each extensometer; a line through the origin would turn that offset into
slope, an intercept takes it out (as E132's ratio of the two strain-load slopes does). The
elastic range is:

* with a force: the frames of the elastic modulus fit (``dic.tensile_properties``: 10 % to 40 %
  of Rp0.2 on the loading branch, ISO 6892-1 Annex G), so nu and E come from the same frames;
* without a force, or when E cannot be fitted: the initial linear part of transverse against
  axial strain, from the first frame to where the curve departs from the line fitted so far: the
  first frame whose next ``DEPARTURE_FRAMES`` frames all lie more than ``DEPARTURE_SIGMAS``
  standard deviations of the prediction off that line, on one side (the sigma from both strains'
  noise, the line's own uncertainty included). No departure: every frame is elastic.

The strains' noise is measured on the series itself (the median absolute second difference,
``series_noise``). A range whose axial strain spans less than ``MIN_SPAN_NOISE`` times the axial
noise, or that holds fewer than ``MIN_FRAMES`` frames, gives NaN with a ``Reason``: the ratio
would be noise over noise. Least squares of y on x underestimates the slope by the share of x's
variance that is noise (regression dilution): at the minimum span it is below 1 %.

The plastic contraction ratio (never called Poisson's ratio: plastic flow keeps the volume, 0.5
for metals) is the same slope over the frames after the elastic range: up to maximum force with
a force (uniform elongation), else up to the largest axial strain.
"""

import enum
import math
from dataclasses import dataclass

import numpy as np

from livedic.dic.tensile_properties import MIN_POINTS, elastic_fit_frames, tensile_properties

MIN_FRAMES = MIN_POINTS          # fewest frames in a fitted range (as for E)
MIN_SPAN_NOISE = 10.0            # the range's axial strain span, in axial noise standard deviations
DEPARTURE_SIGMAS = 3.0           # a frame departs from the line beyond this many prediction sigmas ...
DEPARTURE_FRAMES = 3             # ... and so do the next ones, on the same side
NOISE_FLOOR = 1e-7               # strain: the departure test's floor when the series has no noise (exact data)

_NAN = float("nan")


class Basis(enum.Enum):
    """Where the fitted range comes from."""
    FORCE = "the frames of the elastic modulus fit (force)"
    LINEAR_PART = "the initial linear part of transverse against axial strain"
    PLASTIC = "the frames after the elastic range"
    NONE = "no range"


class Reason(enum.Enum):
    """Why a ratio is NaN."""
    NO_PAIR = "no axial and transverse extensometer pair"
    TOO_FEW_FRAMES = "too few frames with both strains in the range"
    BELOW_NOISE = "the range's axial strain span is within 10 x the axial extensometer's noise"
    NO_ELASTIC_RANGE = "no elastic range to start from"
    NO_PLASTIC_RANGE = "no frame after the elastic range (the whole test looks elastic)"


@dataclass(frozen=True)
class ContractionRatio:
    """-d e_transverse / d e_axial over a range of frames.

    Attributes
    ----------
    value, standard_error : float
        The ratio and the standard error of the fitted slope (NaN with ``reason``).
    n_frames : int
        Frames in the fit.
    frames : (int, int)
        First and last frame of the range (frame numbers as given; -1 without a range).
    axial_range : (float, float)
        Smallest and largest axial strain in the range (NaN without a range).
    axial_noise : float
        The axial strain's noise (standard deviation of one reading) measured on the series.
    basis : Basis
    method : str
    reason : Reason or None
    elastic : bool
        Poisson's ratio (True) or the plastic contraction ratio.
    intercept : float
        The fitted line's transverse strain at zero axial strain (to draw it).
    """
    value: float
    standard_error: float
    n_frames: int
    frames: tuple
    axial_range: tuple
    axial_noise: float
    basis: Basis
    method: str
    reason: Reason = None
    elastic: bool = True
    intercept: float = _NAN

    @property
    def label(self):
        """"Poisson's ratio (elastic, frames a-b, axial strain x-y %)" or the plastic ratio's label."""
        parts = ["elastic"] if self.elastic else []
        if self.frames[0] >= 0:
            lo, hi = (100.0 * v for v in self.axial_range)
            parts += [f"frames {self.frames[0]}-{self.frames[1]}", f"axial strain {lo:.3g}-{hi:.3g} %"]
        name = "Poisson's ratio" if self.elastic else "plastic contraction ratio"
        return f"{name} ({', '.join(parts)})" if parts else name

    def as_dict(self):
        """A JSON-ready object: value, stderr, label, range, basis, method, reason (NaN stays NaN)."""
        return {"value": float(self.value), "stderr": float(self.standard_error), "label": self.label,
                "n_frames": int(self.n_frames), "frames": [int(f) for f in self.frames],
                "axial_strain_range": [float(v) for v in self.axial_range], "axial_noise": float(self.axial_noise),
                "basis": self.basis.name.lower(), "method": self.method,
                "reason": None if self.reason is None else self.reason.value}


def series_noise(values):
    """Noise (standard deviation) of a smooth series: 1.4826 x the median absolute second difference / sqrt(6).

    A second difference cancels a straight line and leaves 6 sigma^2 of white noise; the median
    ignores the few frames where the curve bends (yield, a kink). NaN with fewer than 3 values.
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size < 3:
        return _NAN
    second = np.diff(values, 2)
    return float(1.4826 * np.median(np.abs(second - np.median(second))) / math.sqrt(6.0))


def _fit_line(x, y):
    """Least squares y = a x + b: slope, intercept, standard error of the slope (NaN if x is constant)."""
    sxx = np.sum((x - x.mean()) ** 2)
    if not sxx > 0:
        return _NAN, _NAN, _NAN
    slope = np.sum((x - x.mean()) * (y - y.mean())) / sxx
    intercept = y.mean() - slope * x.mean()
    dof = x.size - 2
    error = math.sqrt(np.sum((y - slope * x - intercept) ** 2) / dof / sxx) if dof > 0 else _NAN
    return float(slope), float(intercept), float(error)


def linear_part(axial, transverse, *, axial_noise, transverse_noise, min_frames=MIN_FRAMES):
    """Frames (count from the first) of the initial linear part of ``transverse`` against ``axial``.

    Parameters
    ----------
    axial, transverse : arrays (n,)
        Finite strains, in frame order.
    axial_noise, transverse_noise : float
        Their noise (standard deviations).

    Returns
    -------
    (int, bool)
        How many frames from the first are on the initial line, and whether a departure was seen
        (False: all ``n``). The test starts once ``min_frames`` frames span ``MIN_SPAN_NOISE`` x the
        axial noise (before that the line is not known well enough to depart from).
    """
    a, t = np.asarray(axial, dtype=np.float64), np.asarray(transverse, dtype=np.float64)
    n, m = a.size, DEPARTURE_FRAMES
    span = np.fmax.accumulate(a) - np.fmin.accumulate(a) if n else a
    known = np.flatnonzero((np.arange(1, n + 1) >= min_frames) & (span >= MIN_SPAN_NOISE * axial_noise))
    if not known.size or known[0] + 1 + m > n:
        return n, False
    # the line fitted on frames [0, k), for every k, from running sums
    k = np.arange(known[0] + 1, n - m + 1)
    count = k.astype(np.float64)
    sa, st = np.cumsum(a)[k - 1], np.cumsum(t)[k - 1]
    saa, sat = np.cumsum(a * a)[k - 1], np.cumsum(a * t)[k - 1]
    sxx = np.maximum(saa - sa * sa / count, 1e-300)
    slope = (sat - sa * st / count) / sxx
    intercept = (st - slope * sa) / count
    ahead = k[:, None] + np.arange(m)[None, :]                  # the next m frames after each prefix
    residual = t[ahead] - slope[:, None] * a[ahead] - intercept[:, None]
    leverage = 1.0 + 1.0 / count[:, None] + (a[ahead] - (sa / count)[:, None]) ** 2 / sxx[:, None]
    sigma = np.sqrt((transverse_noise ** 2 + (slope ** 2)[:, None] * axial_noise ** 2) * leverage)
    off = np.abs(residual) > np.maximum(DEPARTURE_SIGMAS * sigma, NOISE_FLOOR)
    one_side = np.all(residual > 0, axis=1) | np.all(residual < 0, axis=1)
    departed = np.flatnonzero(np.all(off, axis=1) & one_side)
    if not departed.size:
        return n, False
    return int(k[departed[0]]), True


def _ratio(a, t, frames, used, *, noise, basis, method, elastic, min_frames):
    """The ratio fitted over the frames ``used`` (indices into a, t, frames)."""
    n = int(used.size)
    if n == 0:
        return _empty(noise, basis, method, Reason.TOO_FEW_FRAMES, elastic)
    ends = (int(frames[used[0]]), int(frames[used[-1]]))
    lo, hi = float(a[used].min()), float(a[used].max())
    reason = None
    if n < min_frames:
        reason = Reason.TOO_FEW_FRAMES
    elif not hi - lo >= MIN_SPAN_NOISE * noise:
        reason = Reason.BELOW_NOISE
    slope, intercept, error = _fit_line(a[used], t[used]) if reason is None else (_NAN, _NAN, _NAN)
    method = (f"{method}; minus the slope of a least-squares line of transverse on axial strain, with an "
              f"intercept, over {n} frames ({ends[0]}-{ends[1]}), axial strain {100 * lo:.3g}-{100 * hi:.3g} % "
              f"(axial noise {1e6 * noise:.1f} microstrain)")
    return ContractionRatio(-slope if reason is None else _NAN, error, n, ends, (lo, hi), noise, basis, method,
                            reason, elastic, intercept)


def _empty(noise, basis, method, reason, elastic):
    return ContractionRatio(_NAN, _NAN, 0, (-1, -1), (_NAN, _NAN), noise, basis, method, reason, elastic)


def contraction_ratios(axial, transverse, *, force=None, frames=None, min_frames=MIN_FRAMES):
    """Poisson's ratio over the elastic range and the plastic contraction ratio (see the module notes).

    Parameters
    ----------
    axial, transverse : array_like (n,)
        Engineering strains per frame, NaN where there is no reading.
    force : array_like (n,), optional
        Force or stress per frame (NaN where unknown); None or no finite value: no force.
    frames : array_like (n,) of int, optional
        The frames' numbers for the labels (default 0..n-1).
    min_frames : int
        Fewest frames in a fitted range.

    Returns
    -------
    (ContractionRatio, ContractionRatio)
        Poisson's ratio (elastic) and the plastic contraction ratio.
    """
    a = np.asarray(axial, dtype=np.float64).ravel()
    t = np.asarray(transverse, dtype=np.float64).ravel()
    if a.shape != t.shape:
        raise ValueError(f"axial and transverse strains must have one length, got {a.size} and {t.size}")
    frames = np.arange(a.size) if frames is None else np.asarray(frames, dtype=np.int64).ravel()
    valid = np.flatnonzero(np.isfinite(a) & np.isfinite(t))
    noise = series_noise(a[valid])
    if valid.size < max(min_frames, 3):
        method = f"{valid.size} frames with both strains"
        return (_empty(noise, Basis.NONE, method, Reason.TOO_FEW_FRAMES, True),
                _empty(noise, Basis.NONE, method, Reason.NO_ELASTIC_RANGE, False))
    elastic_used, plastic_used, basis, method = None, None, None, ""
    f = None if force is None else np.asarray(force, dtype=np.float64).ravel()
    if f is not None and np.isfinite(f).any():
        paired = np.where(np.isfinite(t), a, np.nan)          # the frames with both strains
        props = tensile_properties(paired, f, min_points=min_frames)
        E = props.E_GPa
        if E.reason is None:
            elastic_used = elastic_fit_frames(paired, f, *E.stress_range_MPa)
            basis = Basis.FORCE
            method = f"elastic range: the frames of the E fit ({E.basis} of the force on the loading branch)"
            top = props.Rm_MPa.frame if props.Rm_MPa.reason is None else int(valid[-1])
            start = elastic_used[-1] + 1 if elastic_used.size else valid[0]
            if props.Rp02_MPa.reason is None:
                start = props.Rp02_MPa.frames[1]
            plastic_used = valid[(valid >= start) & (valid <= top)]
        else:
            method = f"no elastic range from the force (E: {E.reason.value}); "
    if elastic_used is None:
        t_noise = series_noise(t[valid])
        count, departed = linear_part(a[valid], t[valid], axial_noise=noise, transverse_noise=t_noise,
                                      min_frames=min_frames)
        elastic_used = valid[:count]
        basis = Basis.LINEAR_PART
        method += ("elastic range: the initial linear part of transverse against axial strain, up to where it "
                   f"departs from the line by > {DEPARTURE_SIGMAS:g} sigma for {DEPARTURE_FRAMES} frames"
                   if departed else
                   "elastic range: transverse against axial strain never departs from its initial line: every frame")
        top = valid[count:][np.argmax(a[valid[count:]])] if departed else -1
        plastic_used = valid[count:][valid[count:] <= top] if departed else valid[:0]
    nu = _ratio(a, t, frames, elastic_used, noise=noise, basis=basis, method=method, elastic=True,
                min_frames=min_frames)
    plastic_method = "plastic range: after the elastic range, up to maximum force" if basis is Basis.FORCE else \
        "plastic range: after the elastic range, up to the largest axial strain"
    if not plastic_used.size:
        plastic = _empty(noise, Basis.PLASTIC, plastic_method, Reason.NO_PLASTIC_RANGE, False)
    else:
        plastic = _ratio(a, t, frames, plastic_used, noise=noise, basis=Basis.PLASTIC, method=plastic_method,
                         elastic=False, min_frames=min_frames)
    return nu, plastic
