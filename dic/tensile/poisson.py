"""Poisson's ratio over the elastic range, and the plastic contraction ratio, from two extensometers.

Input: per frame, the engineering strain of an axial and of a transverse extensometer (NaN
where either has no reading: the frame is skipped), optionally the force (or stress: any unit,
only shares of it are used), and the frames' numbers for the labels.

Poisson's ratio (ASTM E132) is minus the slope of a least-squares line of transverse on axial
strain, **with an intercept**, over the elastic range:

* with a force: below the proportional limit, the initial linear part of force against axial
  strain;
* without a force, or when that gives no ratio (said in ``method``): the initial linear part of
  transverse against axial strain.

The initial linear part (``linear_part``) runs from the first frame to where the curve departs
from its line (``DEPARTURE_FRAMES``, ``DEPARTURE_SIGMAS``) or to a ``bend``. The noise is measured
on the series (``series_noise``). A range spanning less than ``MIN_SPAN_NOISE`` x the axial noise,
holding fewer than ``MIN_FRAMES`` frames, or that is no line (``LINEARITY_SIGMAS``, sign runs)
gives NaN with a ``Reason``, never a ratio of noise over noise.

The plastic contraction ratio (never called Poisson's ratio) is the same slope over the plastic
range: with a force, from the proof point (0.2 % plastic strain) to the end of uniform elongation
(``stream.stages.stress``'s rule); without, the linear part that follows the elastic range.
Why each choice: docs/guide/strain.md ("How Poisson's ratio is fitted").
"""

import dataclasses
import enum
import math
from dataclasses import dataclass

from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.dic.tensile.properties import MIN_POINTS, NECKING_DROP, PROOF_OFFSET, fit_line, tensile_properties

MIN_FRAMES = MIN_POINTS          # fewest frames in a fitted range (as for E)
MIN_SPAN_NOISE = 10.0            # the range's axial strain span, in axial noise standard deviations
DEPARTURE_SIGMAS = 3.0           # a frame departs from the line beyond this many prediction sigmas ...
DEPARTURE_FRAMES = 3             # ... and so do the next ones, on the same side
LINE_FRAMES = 3                  # the departure test starts on a line through this many frames (its uncertainty
                                 # is in the test's sigma), so a short elastic part is seen
LINEARITY_SIGMAS = 3.0           # an elastic range scattering more than this x the noise about its line is no line,
RUNS_Z = 3.0                     # ... nor one whose residuals' signs change too seldom (runs test, z < -3) ...
RUNS_MIN_FRAMES = 10             # ... over at least this many frames
BEND_F = 10.0                    # two lines fit a range better than one beyond this F (``bend``)
NOISE_WINDOW = 4                 # series_noise: values per third difference
NOISE_FLOOR = 1e-6               # the departure tests' floor in data without noise (exact), a share of the values

_NAN = float("nan")


class Basis(enum.Enum):
    """Where the fitted range comes from."""
    FORCE = "below the proportional limit (the initial linear part of force against axial strain)"
    LINEAR_PART = "the initial linear part of transverse against axial strain"
    PLASTIC = "the plastic range"
    NONE = "no range"


class Reason(enum.Enum):
    """Why a ratio is NaN."""
    NO_PAIR = "no axial and transverse extensometer pair"
    TOO_FEW_FRAMES = "too few frames with both strains in the range"
    BELOW_NOISE = "the range's axial strain span is within 10 x the axial extensometer's noise"
    NO_ELASTIC_RANGE = "no elastic range to start from"
    NO_PLASTIC_RANGE = "no frame after the elastic range (the whole test looks elastic)"
    NOT_LINEAR = ("the range's frames do not lie on one line (their scatter about it is over 3 x the strains' "
                  "noise, or its signs run in long stretches): too few frames before the curve bends to tell "
                  "the elastic part")


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
    linear_to_end : bool
        The linear part never ended: every frame is in the range (nothing told elastic from plastic).
    """
    value: float
    standard_error: float
    n_frames: int
    frames: tuple
    axial_range: tuple
    axial_noise: float
    basis: Basis
    method: str
    reason: Reason | None = None
    elastic: bool = True
    intercept: float = _NAN
    linear_to_end: bool = False

    @property
    def label(self) -> str:
        """"Poisson's ratio (elastic, frames a-b, axial strain x-y %)" or the plastic ratio's label."""
        parts = ["elastic"] if self.elastic else []
        if self.frames[0] >= 0:
            lo, hi = (_percent(v) for v in self.axial_range)
            parts += [f"frames {self.frames[0]}-{self.frames[1]}", f"axial strain {lo}-{hi} %"]
        name = "Poisson's ratio" if self.elastic else "plastic contraction ratio"
        return f"{name} ({', '.join(parts)})" if parts else name

    def as_dict(self) -> dict[str, Any]:
        """A JSON-ready object: value, stderr, label, range, basis, method, reason (NaN stays NaN)."""
        return {"value": float(self.value), "stderr": float(self.standard_error), "label": self.label,
                "n_frames": int(self.n_frames), "frames": [int(f) for f in self.frames],
                "axial_strain_range": [float(v) for v in self.axial_range], "axial_noise": float(self.axial_noise),
                "basis": self.basis.name.lower(), "linear_to_end": self.linear_to_end, "method": self.method,
                "reason": None if self.reason is None else self.reason.value}


def _percent(strain):
    """A strain in % to 4 decimals, trailing zeros dropped: 0.0449, 0.4, 5.96, 0."""
    text = f"{100.0 * strain:.4f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def series_noise(values: npt.ArrayLike, positions: npt.ArrayLike | None = None) -> float:
    """Noise (standard deviation) of a series smooth in ``positions`` (frame numbers; default 0, 1, 2 ...).

    The third divided difference of each four consecutive values (at their positions: frames the queue
    dropped leave gaps) cancels any quadratic, so a test's smooth schedule (a ramp, a neck growing with
    the square of time) leaves only the noise: sum c_j v_j with c_j = 1 / prod_k (x_j - x_k), divided by
    sqrt(sum c_j^2), has the noise's standard deviation. 1.4826 x its median absolute deviation is
    sigma; the median ignores the few windows over a kink (yield, the neck's start). NaN with fewer
    than 4 values.
    """
    series = np.asarray(values, dtype=np.float64)
    at = np.arange(series.size, dtype=np.float64) if positions is None else np.asarray(positions, dtype=np.float64)
    keep = np.isfinite(series)
    series, at = series[keep], at[keep]
    if series.size < NOISE_WINDOW:
        return _NAN
    windows = np.lib.stride_tricks.sliding_window_view(at, NOISE_WINDOW)
    gaps = windows[:, :, None] - windows[:, None, :]
    np.einsum("wii->wi", gaps)[:] = 1.0
    weights = 1.0 / np.prod(gaps, axis=2)
    weights /= np.sqrt(np.sum(weights * weights, axis=1, keepdims=True))
    off = np.sum(weights * np.lib.stride_tricks.sliding_window_view(series, NOISE_WINDOW), axis=1)
    return float(1.4826 * np.median(np.abs(off - np.median(off))))


def linear_part(x: npt.ArrayLike, y: npt.ArrayLike, *, x_noise: float, y_noise: float,
                min_frames: int = LINE_FRAMES) -> tuple[int, bool]:
    """Frames (count from the first) of the initial linear part of ``y`` against ``x``.

    Parameters
    ----------
    x, y : arrays (n,)
        Finite values in frame order: axial and transverse strain, or axial strain and force.
    x_noise, y_noise : float
        Their noise (standard deviations).

    Returns
    -------
    (int, bool)
        How many frames from the first are on the initial line, and whether a departure was seen
        (False: all ``n``). The test starts once ``min_frames`` frames span ``MIN_SPAN_NOISE`` x the
        x noise (before that the line is not known well enough to depart from); the prediction's
        sigma holds the line's own uncertainty (the leverage of each frame ahead).
    """
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    n, m = x.size, DEPARTURE_FRAMES
    span = np.fmax.accumulate(x) - np.fmin.accumulate(x) if n else x
    known = np.flatnonzero((np.arange(1, n + 1) >= min_frames) & (span >= MIN_SPAN_NOISE * x_noise))
    if not known.size or known[0] + 1 + m > n:
        return n, False
    # the line fitted on frames [0, k), for every k, from running sums
    k = np.arange(known[0] + 1, n - m + 1)
    count = k.astype(np.float64)
    sx, sy = np.cumsum(x)[k - 1], np.cumsum(y)[k - 1]
    sxx, sxy = np.cumsum(x * x)[k - 1], np.cumsum(x * y)[k - 1]
    spread = np.maximum(sxx - sx * sx / count, 1e-300)
    slope = (sxy - sx * sy / count) / spread
    intercept = (sy - slope * sx) / count
    ahead = k[:, None] + np.arange(m)[None, :]                  # the next m frames after each prefix
    residual = y[ahead] - slope[:, None] * x[ahead] - intercept[:, None]
    leverage = 1.0 + 1.0 / count[:, None] + (x[ahead] - (sx / count)[:, None]) ** 2 / spread[:, None]
    sigma = np.sqrt((y_noise ** 2 + (slope ** 2)[:, None] * x_noise ** 2) * leverage)
    off = np.abs(residual) > np.maximum(DEPARTURE_SIGMAS * sigma, _floor(y))
    one_side = np.all(residual > 0, axis=1) | np.all(residual < 0, axis=1)
    departed = np.flatnonzero(np.all(off, axis=1) & one_side)
    if not departed.size:
        return n, False
    return int(k[departed[0]]), True


def _floor(y):
    """The smallest departure that counts in data without noise (exact): a share of the values' size."""
    return NOISE_FLOOR * max(float(np.max(np.abs(y))) if np.size(y) else 0.0, 1e-300)


def _sse(count, sa, st, saa, stt, sat):
    """Residual sum of squares of least-squares lines from their points' sums (vectorised)."""
    sxx = saa - sa * sa / count
    sxy = sat - sa * st / count
    syy = stt - st * st / count
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(sxx > 0, syy - sxy * sxy / sxx, syy)


def bend(axial: np.ndarray, transverse: np.ndarray) -> int | None:
    """Where the frames split best into two lines (transverse, or force, on axial strain) when two fit
    significantly better than one, else None.

    For every split with ``LINE_FRAMES`` frames or more on each side, F = ((SSE_1 - SSE_2) / 2) /
    (SSE_2 / (n - 4)) compares one line (SSE_1) with one on each side (SSE_2); the best split counts
    when F > ``BEND_F``. Measured on noisy straight lines of 20 to 300 frames: 1 false bend in 100 (it only
    shortens the range); a 4-frame elastic part before 16 plastic frames, both strains under 130
    microstrain of noise: found 92 times in 100. The noise is the fits' own (no estimate needed); exact
    data (SSE_1 ~ 0) has no bend to find.
    """
    a, t = np.asarray(axial, dtype=np.float64), np.asarray(transverse, dtype=np.float64)
    n = a.size
    if n < 2 * LINE_FRAMES + 1:
        return None
    sums = [np.concatenate([[0.0], np.cumsum(v)]) for v in (a, t, a * a, t * t, a * t)]
    whole = float(_sse(n, *(s[n] for s in sums)))
    if not whole > _floor(t) ** 2 * n:
        return None
    split = np.arange(LINE_FRAMES, n - LINE_FRAMES + 1)
    two = _sse(split, *(s[split] for s in sums)) + _sse(n - split, *(s[n] - s[split] for s in sums))
    with np.errstate(invalid="ignore", divide="ignore"):
        f = ((whole - two) / 2.0) / (np.maximum(two, 0.0) / (n - 4))
    best = int(np.nanargmax(np.where(np.isfinite(f), f, -np.inf)))
    return int(split[best]) if f[best] > BEND_F else None


def _ratio(a, t, frames, used, *, noise, transverse_noise, basis, method, elastic, min_frames):
    """The ratio fitted over the frames ``used`` (indices into a, t, frames); an elastic range must be one line."""
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
    slope, intercept, error = fit_line(a[used], t[used]) if reason is None else (_NAN, _NAN, _NAN)
    scatter = _NAN
    if reason is None and n > 2:
        residual = t[used] - slope * a[used] - intercept
        scatter = math.sqrt(float(np.sum(residual * residual)) / (n - 2))
        expected = math.sqrt(transverse_noise ** 2 + slope ** 2 * noise ** 2)
        if elastic and scatter > _floor(t[used]) and (scatter > LINEARITY_SIGMAS * expected or
                                                      _too_few_runs(residual)):
            reason = Reason.NOT_LINEAR
    method = (f"{method}; minus the slope of a least-squares line of transverse on axial strain, with an "
              f"intercept, over {n} frames ({ends[0]}-{ends[1]}), axial strain {_percent(lo)}-{_percent(hi)} % "
              f"(axial noise {1e6 * noise:.1f}, transverse {1e6 * transverse_noise:.1f} microstrain"
              + (f"; scatter about the line {1e6 * scatter:.1f} microstrain" if math.isfinite(scatter) else "") + ")")
    return ContractionRatio(-slope if reason is None else _NAN, error, n, ends, (lo, hi), noise, basis, method,
                            reason, elastic, intercept)


def _too_few_runs(residual):
    """Whether the residuals' signs change too seldom for noise about a line (Wald-Wolfowitz runs test, z below
    -RUNS_Z): a curve through a straight fit leaves long runs on each side, whatever the noise estimate says."""
    signs = residual[residual != 0] > 0
    n, ups = signs.size, int(signs.sum())
    downs = n - ups
    if n < RUNS_MIN_FRAMES or ups == 0 or downs == 0:
        return False
    runs = 1 + int(np.count_nonzero(signs[1:] != signs[:-1]))
    mean = 2.0 * ups * downs / n + 1.0
    variance = 2.0 * ups * downs * (2.0 * ups * downs - n) / (n * n * (n - 1.0))
    return variance > 0 and (runs - mean) / math.sqrt(variance) < -RUNS_Z


def _empty(noise, basis, method, reason, elastic):
    return ContractionRatio(_NAN, _NAN, 0, (-1, -1), (_NAN, _NAN), noise, basis, method, reason, elastic)


def _uniform_plastic_frames(axial, force, E):
    """Indices of the frames past the proof point (plastic strain >= 0.2 %, from the force and E) up to the end
    of uniform elongation: the last frame before the force first falls by ``NECKING_DROP`` below its maximum
    after the maximum (a plateau is uniform too; the neck lowers the force)."""
    frames = np.flatnonzero(np.isfinite(axial) & np.isfinite(force))
    if not frames.size:
        return frames
    peak = int(np.argmax(force[frames]))
    fallen = np.flatnonzero(force[frames[peak:]] < (1.0 - NECKING_DROP) * force[frames[peak]])
    frames = frames[:peak + fallen[0]] if fallen.size else frames
    plastic = axial[frames] - force[frames] / (1000.0 * E.value) - E.strain_at_zero_stress
    return frames[plastic >= PROOF_OFFSET]


def without_pair() -> tuple[ContractionRatio, ContractionRatio]:
    """(Poisson's ratio, plastic contraction ratio), both NaN with ``Reason.NO_PAIR``."""
    return (_empty(_NAN, Basis.NONE, "", Reason.NO_PAIR, True), _empty(_NAN, Basis.NONE, "", Reason.NO_PAIR, False))


def contraction_ratios(axial: npt.ArrayLike, transverse: npt.ArrayLike, *, force: npt.ArrayLike | None = None,
                       frames: npt.ArrayLike | None = None,
                       min_frames: int = MIN_FRAMES) -> tuple[ContractionRatio, ContractionRatio]:
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
    noise = series_noise(a[valid], frames[valid])
    fit = dict(noise=noise, transverse_noise=series_noise(t[valid], frames[valid]), min_frames=min_frames)
    if valid.size < max(min_frames, 3):
        method = f"{valid.size} frames with both strains"
        return (_empty(noise, Basis.NONE, method, Reason.TOO_FEW_FRAMES, True),
                _empty(noise, Basis.NONE, method, Reason.NO_ELASTIC_RANGE, False))
    note = ""
    f = None if force is None else np.asarray(force, dtype=np.float64).ravel()
    if f is not None and np.isfinite(f).any():
        both = valid[np.isfinite(f[valid])]
        # below the proportional limit: the initial linear part of force against axial strain
        count, _, words = _linear_range(a[both], f[both], noise, series_noise(f[both], frames[both]),
                                        "force against axial strain")
        nu = _ratio(a, t, frames, both[:count], basis=Basis.FORCE,
                    method="elastic range, below the proportional limit: " + words, elastic=True, **fit)
        if nu.reason is None:
            E = tensile_properties(np.where(np.isfinite(t), a, np.nan), f, min_points=min_frames).E_GPa
            plastic_method = ("plastic range: from 0.2 % plastic strain to the end of uniform elongation (force "
                              "within 0.5 % of its maximum)")
            plastic_used = _uniform_plastic_frames(np.where(np.isfinite(t), a, np.nan), f, E) \
                if E.reason is None else valid[:0]
            return nu, _plastic(a, t, frames, plastic_used, plastic_method, fit)
        note = f"the force's linear part gives no ratio ({nu.reason.value}); "
    count, departed, words = _linear_range(a[valid], t[valid], noise, fit["transverse_noise"],
                                           "transverse against axial strain")
    nu = _ratio(a, t, frames, valid[:count], basis=Basis.LINEAR_PART, method=note + "elastic range: " + words,
                elastic=True, **fit)
    nu = dataclasses.replace(nu, linear_to_end=not departed)
    # without a force to see the neck by, the uniform plastic flow is the next line (the neck bends it)
    rest = valid[count:] if departed else valid[:0]
    if rest.size:
        uniform, _, _ = _linear_range(a[rest], t[rest], noise, fit["transverse_noise"], "")
        rest = rest[:uniform]
    return nu, _plastic(a, t, frames, rest, "plastic range: the linear part of transverse against axial strain "
                                            "after the elastic range (the neck, if any, bends it)", fit)


def _linear_range(x, y, x_noise, y_noise, what):
    """(frames from the first on the initial line of ``y`` against ``x``, whether it ended, the method's words)."""
    count, departed = linear_part(x, y, x_noise=x_noise, y_noise=y_noise)
    # A short elastic part (too few frames to know its line before the curve bends) is not seen departing:
    # the frames found still hold a bend, which two lines fit significantly better than one.
    bent = False
    while (split := bend(x[:count], y[:count])) is not None:
        count, departed, bent = split, True, True
    if not departed:
        return count, False, f"{what} never departs from its initial line: every frame"
    return count, True, (f"the initial linear part of {what}, up to where it departs from the line by > "
                         f"{DEPARTURE_SIGMAS:g} sigma for {DEPARTURE_FRAMES} frames"
                         + (", and where two lines fit it better than one" if bent else ""))


def _plastic(a, t, frames, used, method, fit):
    """The plastic contraction ratio over ``used`` (NaN with NO_PLASTIC_RANGE when empty)."""
    if not used.size:
        return _empty(fit["noise"], Basis.PLASTIC, method, Reason.NO_PLASTIC_RANGE, False)
    return _ratio(a, t, frames, used, basis=Basis.PLASTIC, method=method, elastic=False, **fit)
