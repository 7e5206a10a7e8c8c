"""``livedic bench accuracy``: spatial resolution and noise as the DIC Challenge 2.0 judges them, and bias.

Two parts, each a plain-text table (``-o`` also writes them as JSON):

**Star 1 and Star 2** (DIC Challenge 2.0, Reu et al., Exp. Mech. 2022; ``dicc2_star`` under ``--data``).
The images carry a vertical displacement ``v = A cos(2 pi (y - 250) / p(x))``, A = 0.5 px, whose period
grows along x, ``p(x) = 10 + 140 (x + 1) / 2000`` px (the set's ``star_truth.py``). On the centre row
(y = 250) the true v is +A at every column, so what a code reads there, against the period, is its
attenuation curve. Per case (subset, sub-pixel method) ``dic.measure`` reads v at every ``step`` px along the
centre row and this module reports:

* the **spatial resolution**: on Star 1 (noise-free), the period at which the amplitude error ``|A - v| / A``
  (smoothed by a running mean over ``SMOOTH_POINTS`` points along the row) last reaches 10 %, scanning from the
  largest period down, interpolated linearly between the two points around the crossing
  (``resolution_period``); a status says when the error stays below 10 % everywhere or exceeds it everywhere.
  The same read on Star 2 is printed too: there the noise moves the last crossing outwards;
* the **noise**: on Star 2, the SD of ``v - truth`` on the centre row where the period is at least
  ``NOISE_MIN_PERIOD`` px (the large-period region, where the attenuation changes slowly);
* ``noise 2-D``: the SD of ``v(Star 2) - v(Star 1)`` over a 2-D grid of the same region: the two stars share
  the pattern and the motion (Star 2 = Star 1 plus noise), so this removes every bias and keeps the noise
  only, on many more independent subsets;
* the **metrological efficiency indicator** (MEI): Star 1's resolution x Star 2's noise, px^2; smaller is
  better; "MEI 2" is Star 2's own resolution x its noise: both read on the noisy images, the fair product for a
  method whose order adapts to the noise (``icgn2``'s curvature test keeps the first order where the noise hides
  the curvature, so its Star 1 resolution is not what it delivers on noisy images);
* the **first-order noise prediction** ``sqrt(2 sigma^2 [H^-1]_vv)`` (noise sigma in both images): H is the
  Gauss-Newton matrix of the subset's shape function (first order for ``icgn``, second for ``icgn2``) plus
  the grey-level offset and scale that ZNCC is blind to, built from the noise-free reference's gradients;
  sigma is the SD of the noisy minus the noise-free reference (the same pattern). RMS over the
  noise-region points of the row.

**Sample 3** (DIC Challenge 1.0, rigid shifts 0-1 px, ``dicc1_sample3_translation``): per shift, the mean
bias of u and v over every ok point of the grid (step 10, subset 21, icgn) and their SD, the worst |mean bias|
against issue 23's target (``BIAS_TARGET`` = 0.001 px): PASS or FAIL. Exit code 0 on PASS, 1 on FAIL.

The arithmetic (``amplitude_error``, ``resolution_period``, ``noise_sd``, ``shift_bias``, ``worst_bias``)
is separate from the reading of the data sets, so the tests check it on analytic fields.
"""

from __future__ import annotations

import enum
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from livedic.bench.validate import STARS, read_star_pair, sample3_frames, sample3_grid

AMPLITUDE = 0.5            # px, the Stars' v on the centre row
CENTRE_ROW = 250           # the Stars' centre row (0-based), where v = +A
STAR_WIDTH = 2000
LIMIT = 0.10               # the amplitude error that defines the spatial resolution
NOISE_MIN_PERIOD = 130.0   # px: the large-period region (x >= 1713 of 2000)
SMOOTH_POINTS = 15         # running mean of the amplitude error along the row (15 px at step 1)
SUBSETS = (15, 21, 31)
SUBPIXELS = ("icgn", "icgn2")
LINE_STEP = 1              # px between points along the centre row
GRID_STEP_2D = 5           # px, the 2-D grid of the bias-free noise
BIAS_TARGET = 0.001        # px, issue 23's worst |mean bias| on Sample 3
SAMPLE3_SUBSET = 21
SAMPLE3_SUBPIXEL = "icgn"


def star_period(x: np.ndarray | float) -> np.ndarray:
    """The Stars 1-2 period law p(x) = 10 + 140 (x + 1) / 2000 px (0-based column x)."""
    return 10.0 + 140.0 * (np.asarray(x, dtype=float) + 1.0) / STAR_WIDTH


def star_v(x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
    """The Stars' true v at (x, y): A cos(2 pi (y - 250) / p(x)), px (+v downwards)."""
    return AMPLITUDE * np.cos(2.0 * np.pi * (np.asarray(y, dtype=float) - CENTRE_ROW) / star_period(x))


# ----------------------------------------------------------------------------- the arithmetic

class CrossingStatus(enum.Enum):
    """Whether the amplitude error crosses the limit inside the periods measured."""
    FOUND = "found"
    BELOW_RANGE = "below_range"      # error under the limit at every period: resolution finer than measured
    ABOVE_RANGE = "above_range"      # error at or over the limit even at the largest period
    NO_DATA = "no_data"              # no ok point

    @property
    def description(self) -> str:
        return _CROSSING_TEXT[self]


_CROSSING_TEXT = {
    CrossingStatus.FOUND: "crossing found",
    CrossingStatus.BELOW_RANGE: "error below the limit at every period measured",
    CrossingStatus.ABOVE_RANGE: "error at or above the limit even at the largest period",
    CrossingStatus.NO_DATA: "no ok point on the line",
}


@dataclass(frozen=True)
class Crossing:
    """The period (px) where the amplitude error reaches the limit; NaN unless ``status`` is FOUND."""
    period: float
    status: CrossingStatus


def amplitude_error(v: np.ndarray, amplitude: float = AMPLITUDE) -> np.ndarray:
    """``|A - v| / A`` for v read where the true value is +A (NaN stays NaN)."""
    return np.abs(amplitude - np.asarray(v, dtype=float)) / amplitude


def running_mean(values: np.ndarray, points: int) -> np.ndarray:
    """Mean of the finite values among ``points`` neighbours centred on each one (NaN where none)."""
    values = np.asarray(values, dtype=float)
    if points <= 1:
        return values.copy()
    finite = np.isfinite(values)
    kernel = np.ones(points)
    total = np.convolve(np.where(finite, values, 0.0), kernel, mode="same")
    count = np.convolve(finite.astype(float), kernel, mode="same")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


def resolution_period(periods: np.ndarray, error: np.ndarray, limit: float = LIMIT) -> Crossing:
    """The largest period at which ``error`` reaches ``limit``, interpolated (see the module notes).

    Parameters
    ----------
    periods : ndarray (N,)
        Increasing periods, px.
    error : ndarray (N,)
        Amplitude error at each period (fraction); NaN where not measured (skipped).
    limit : float
        The error that defines the resolution (0.10 in the DIC Challenge 2.0).
    """
    periods = np.asarray(periods, dtype=float)
    error = np.asarray(error, dtype=float)
    finite = np.isfinite(error)
    if not finite.any():
        return Crossing(math.nan, CrossingStatus.NO_DATA)
    p, e = periods[finite], error[finite]
    over = np.flatnonzero(e >= limit)
    if over.size == 0:
        return Crossing(math.nan, CrossingStatus.BELOW_RANGE)
    last = over[-1]
    if last == e.size - 1:
        return Crossing(math.nan, CrossingStatus.ABOVE_RANGE)
    # e[last] >= limit > e[last + 1]
    fraction = (e[last] - limit) / (e[last] - e[last + 1])
    return Crossing(float(p[last] + fraction * (p[last + 1] - p[last])), CrossingStatus.FOUND)


def noise_sd(residual: np.ndarray) -> float:
    """SD (ddof 1) of the finite values of ``residual``; NaN with fewer than two."""
    values = np.asarray(residual, dtype=float)
    values = values[np.isfinite(values)]
    return float(np.std(values, ddof=1)) if values.size >= 2 else math.nan


def efficiency_indicator(resolution: float, noise: float) -> float:
    """The metrological efficiency indicator: spatial resolution (px) x noise (px), px^2 (NaN if either is)."""
    return float(resolution * noise)


def predicted_noise(reference: np.ndarray, xs: np.ndarray, ys: np.ndarray, subset: int, order: int,
                    sigma: float) -> np.ndarray:
    """First-order SD of v per point, ``sqrt(2 sigma^2 [H^-1]_vv)``, px (see the module notes).

    Parameters
    ----------
    reference : ndarray (H, W)
        Noise-free reference image (grey levels).
    xs, ys : ndarray (N,)
        Integer subset centres.
    subset : int
        Odd subset side, px.
    order : int
        Shape function order, 1 (u, v and their 4 gradients) or 2 (also the 6 second derivatives).
    sigma : float
        Image noise SD in each of the two images, grey levels.
    """
    from livedic.dic.gradient import gradient_4th

    image = np.asarray(reference, dtype=np.float64)
    gx, gy = gradient_4th(image)
    half = subset // 2
    dy, dx = (a.ravel().astype(float) for a in np.mgrid[-half:half + 1, -half:half + 1])
    rows = np.asarray(ys, dtype=int)[:, None] + dy.astype(int)[None, :]
    cols = np.asarray(xs, dtype=int)[:, None] + dx.astype(int)[None, :]
    fx, fy, f = gx[rows, cols], gy[rows, cols], image[rows, cols]
    terms = [np.ones_like(dx), dx, dy]
    if order == 2:
        terms += [0.5 * dx * dx, dx * dy, 0.5 * dy * dy]
    columns = [fx * t for t in terms] + [fy * t for t in terms]
    columns += [f - f.mean(axis=1, keepdims=True), np.ones_like(f)]   # grey-level scale and offset
    jacobian = np.stack(columns, axis=2)                               # (N, pixels, params)
    hessian = np.einsum("npi,npj->nij", jacobian, jacobian)
    v_index = len(terms)                                                # v is the first of the y terms
    variance = np.linalg.inv(hessian)[:, v_index, v_index]
    return np.sqrt(2.0 * sigma * sigma * variance)


@dataclass(frozen=True)
class ShiftBias:
    """One rigid shift's bias over the ok points: mean and SD of (measured - truth), px."""
    true_u: float
    true_v: float
    points: int
    ok: int
    bias_u: float
    bias_v: float
    sd_u: float
    sd_v: float


def shift_bias(u: np.ndarray, v: np.ndarray, ok: np.ndarray, true_u: float, true_v: float) -> ShiftBias:
    """Mean and SD of u - true_u and v - true_v over the ok points (NaN where fewer than two)."""
    ok = np.asarray(ok, dtype=bool) & np.isfinite(u) & np.isfinite(v)
    du, dv = np.asarray(u)[ok] - true_u, np.asarray(v)[ok] - true_v
    mean = (lambda a: float(a.mean()) if a.size else math.nan)
    return ShiftBias(float(true_u), float(true_v), int(np.size(ok)), int(ok.sum()), mean(du), mean(dv),
                     noise_sd(du), noise_sd(dv))


def worst_bias(rows: Sequence[ShiftBias]) -> float:
    """The largest |mean bias| of u or v over the shifts (NaN if any shift had no ok point)."""
    values = [abs(value) for row in rows for value in (row.bias_u, row.bias_v)]
    return max(values) if values and all(math.isfinite(v) for v in values) else math.nan


def sampling(subpixel: str, interpolation: str | None, prefilter: str | None) -> tuple[str, str]:
    """(interpolation, prefilter) a case runs with: as given, else what ``livedic measure`` defaults to for
    ``subpixel`` (``stream.session.config.measure_defaults``)."""
    from livedic.stream.session.config import measure_defaults
    return measure_defaults(subpixel, interpolation, prefilter)


# ----------------------------------------------------------------------------- the Stars

@dataclass(frozen=True)
class StarCase:
    """One subset x method on the Stars: resolution, noise, their product, the prediction (px, px^2).

    ``resolution_px``: Star 1's (noise-free) crossing, the Challenge's spatial resolution;
    ``resolution_noisy_px``: the same read on Star 2, where the noise moves the last crossing.
    ``noise_px``: SD of v - truth on Star 2's centre row (large periods); ``noise_2d_px``: SD of
    v(Star 2) - v(Star 1) on the 2-D grid there; ``pattern_sd_px``: SD of v - truth on Star 1's row
    (no image noise: the pattern-induced scatter). ``mei_px2`` = ``resolution_px`` x ``noise_px``;
    ``mei_noisy_px2`` = ``resolution_noisy_px`` x ``noise_px``.
    ``interpolation``, ``prefilter``: what the case sampled with (``dic.interpolation``, ``dic.image_filter``).
    """
    subset: int
    subpixel: str
    points: int
    ok_star1: int
    ok_star2: int
    resolution_px: float
    resolution_status: CrossingStatus
    resolution_noisy_px: float
    resolution_noisy_status: CrossingStatus
    noise_px: float
    noise_2d_px: float
    pattern_sd_px: float
    mei_px2: float
    predicted_noise_px: float
    noise_sigma_grey: float
    interpolation: str
    prefilter: str

    @property
    def mei_noisy_px2(self) -> float:
        """Star 2's own resolution x its noise (module notes)."""
        return efficiency_indicator(self.resolution_noisy_px, self.noise_px)


@dataclass(frozen=True)
class _LineReading:
    """v read on a Star's centre row: the crossing, the residual SD where the period is large, the points."""
    crossing: Crossing
    residual_sd: float
    ok: int
    points: int
    xs: np.ndarray
    ys: np.ndarray


def _centre_line(step: int, subset: int) -> np.ndarray:
    margin = subset // 2 + 4
    xs = np.arange(margin, STAR_WIDTH - margin, step, dtype=float)
    return np.column_stack([xs, np.full(xs.size, float(CENTRE_ROW))])


def _noise_grid(subset: int, height: int) -> np.ndarray:
    margin = subset // 2 + 4
    first = math.ceil(STAR_WIDTH * (NOISE_MIN_PERIOD - 10.0) / 140.0 - 1.0)
    xs = np.arange(first, STAR_WIDTH - margin, GRID_STEP_2D, dtype=float)
    ys = np.arange(margin, height - margin, GRID_STEP_2D, dtype=float)
    return np.column_stack([a.ravel() for a in np.meshgrid(xs, ys)])


def _read_line(images, subset, subpixel, step, interpolation: str, prefilter: str) -> _LineReading:
    from livedic.dic import measure

    m = measure(*images, _centre_line(step, subset), subset=subset, subpixel=subpixel, interpolation=interpolation,
                prefilter=prefilter)
    periods = star_period(m.x)
    crossing = resolution_period(periods, running_mean(amplitude_error(m.v), max(1, SMOOTH_POINTS // step)))
    region = periods >= NOISE_MIN_PERIOD
    return _LineReading(crossing, noise_sd((m.v - star_v(m.x, m.y))[region]), int(m.ok.sum()), int(m.ok.size),
                        m.x[region], m.y[region])


def _star_case(images, subset, subpixel, step, sigma, interpolation: str | None, prefilter: str | None) -> StarCase:
    """Measure one subset x method on both Stars (module notes); None: ``measure``'s default for the method."""
    from livedic.dic import measure

    interpolation, prefilter = sampling(subpixel, interpolation, prefilter)

    clean, noisy = (_read_line(images[name], subset, subpixel, step, interpolation, prefilter)
                    for name in ("Star 1", "Star 2"))
    grid = _noise_grid(subset, images["Star 1"][0].shape[0])
    grid_v = [measure(*images[name], grid, subset=subset, subpixel=subpixel, interpolation=interpolation,
                      prefilter=prefilter).v
              for name in ("Star 1", "Star 2")]
    per_point = predicted_noise(images["Star 1"][0], noisy.xs, noisy.ys, subset, 2 if subpixel == "icgn2" else 1,
                                sigma)
    return StarCase(subset, subpixel, clean.points, clean.ok, noisy.ok, clean.crossing.period, clean.crossing.status,
                    noisy.crossing.period, noisy.crossing.status, noisy.residual_sd,
                    noise_sd(grid_v[1] - grid_v[0]), clean.residual_sd,
                    efficiency_indicator(clean.crossing.period, noisy.residual_sd),
                    float(np.sqrt(np.mean(per_point ** 2))), sigma, interpolation, prefilter)


def _star_header(log):
    header = (f"{'subset':>6s} {'method':7s} {'ok 1 / 2':>11s} {'resolution':>10s} {'on Star 2':>10s} "
              f"{'noise':>7s} {'noise 2-D':>9s} {'predicted':>9s} {'MEI px^2':>8s} {'MEI 2':>7s} {'Star 1 SD':>9s}  "
              "sampled with")
    log(header)
    log("-" * len(header))


def _period_text(period: float, status: CrossingStatus) -> str:
    return f"{period:10.1f}" if status is CrossingStatus.FOUND else f"{status.value:>10s}"


def _star_row(case: StarCase) -> str:
    number = (lambda value, width=7: f"{value:{width}.4f}" if math.isfinite(value) else f"{'n/a':>{width}s}")
    return (f"{case.subset:6d} {case.subpixel:7s} {f'{case.ok_star1}/{case.ok_star2}':>11s} "
            f"{_period_text(case.resolution_px, case.resolution_status)} "
            f"{_period_text(case.resolution_noisy_px, case.resolution_noisy_status)} {number(case.noise_px)} "
            f"{number(case.noise_2d_px, 9)} {number(case.predicted_noise_px, 9)} {number(case.mei_px2, 8)} "
            f"{number(case.mei_noisy_px2)} {number(case.pattern_sd_px, 9)}  {case.interpolation}, {case.prefilter}")


def run_stars(data: str, subsets: Sequence[int], subpixels: Sequence[str], step: int,
              log: Callable[[str], None], interpolation: str | None = None,
              prefilter: str | None = None) -> list[StarCase]:
    """Every subset x method case on the Stars (module notes), printed as a table; returns the cases. The
    predicted noise is the unfiltered images' (the first-order formula knows no pre-filter)."""
    images = {name: read_star_pair(data, name) for name in STARS}
    # Star 2 is Star 1 plus noise: their difference is the noise of one image
    sigma = noise_sd(images["Star 2"][0].astype(float) - images["Star 1"][0].astype(float))
    log(f"image noise sigma {sigma:.3f} grey levels (Star 2 - Star 1 reference); px unless said")
    _star_header(log)
    cases = []
    for subset in subsets:
        for subpixel in subpixels:
            case = _star_case(images, subset, subpixel, step, sigma, interpolation, prefilter)
            log(_star_row(case))
            cases.append(case)
    return cases


# ----------------------------------------------------------------------------- Sample 3

def run_sample3(data: str, log: Callable[[str], None], interpolation: str | None = None,
                prefilter: str | None = None) -> list[ShiftBias]:
    """Sample 3's bias table (subset 21, grid 10, icgn, ``interpolation``, ``prefilter``; None: ``measure``'s
    defaults), printed; returns one row per shift."""
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.dic import measure

    interpolation, prefilter = sampling(SAMPLE3_SUBPIXEL, interpolation, prefilter)
    log(f"interpolation {interpolation}, pre-filter {prefilter}")
    reference, frames = sample3_frames(data)
    points = sample3_grid()
    header = (f"{'shift u,v px':>13s} {'ok':>9s} {'bias u px':>10s} {'bias v px':>10s} {'SD u px':>8s} "
              f"{'SD v px':>8s}")
    log(header)
    log("-" * len(header))
    rows = []
    for path, (true_u, true_v) in frames:
        m = measure(reference, read_grey_image(path)[0], points, subset=SAMPLE3_SUBSET, subpixel=SAMPLE3_SUBPIXEL,
                    interpolation=interpolation, prefilter=prefilter)
        row = shift_bias(m.u, m.v, m.ok, true_u, true_v)
        log(f"{f'{true_u:.1f},{true_v:.1f}':>13s} {f'{row.ok}/{row.points}':>9s} {row.bias_u:+10.4f} "
            f"{row.bias_v:+10.4f} {row.sd_u:8.4f} {row.sd_v:8.4f}")
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------- the command

def check_data(data: str) -> None:
    """ValueError (one line) unless ``data`` holds the two DIC Challenge sets this benchmark reads."""
    missing = [d for d in ("dicc2_star", "dicc1_sample3_translation") if not os.path.isdir(os.path.join(data, d))]
    if missing:
        raise ValueError(f"--data {data} lacks {', '.join(missing)}: give the folder holding the DIC Challenge "
                         "sets (e.g. ../shared/datasets)")


def run_accuracy_benchmark(*, data: str, quick: bool = False, output: str | None = None,
                           log: Callable[[str], None] = print, interpolation: str | None = None,
                           prefilter: str | None = None) -> int:
    """Both parts (module notes): print the tables, write ``output`` (JSON) if given; 0 on PASS, 1 on FAIL.
    ``interpolation`` (``--interpolation``): the methods that cannot sample with it are left out; ``prefilter``
    (``--prefilter``) filters every image read; None: each method with ``livedic measure``'s default
    (``sampling``)."""
    import platform

    from livedic.dic.subpixel.method import subpixel_method

    check_data(data)
    subsets, subpixels = ((SAMPLE3_SUBSET,), ("icgn",)) if quick else (SUBSETS, SUBPIXELS)
    subpixels = tuple(name for name in subpixels
                      if interpolation is None or interpolation in subpixel_method(name).interpolations)
    step = 2 * LINE_STEP if quick else LINE_STEP
    started = time.perf_counter()
    chosen = (lambda value: "measure's default" if value is None else value)
    log(f"livedic bench accuracy: {os.cpu_count()} CPU cores, {platform.machine()}, interpolation "
        f"{chosen(interpolation)}, pre-filter {chosen(prefilter)}" + (" (quick)" if quick else ""))
    log("")
    log(f"DIC Challenge 2.0 Stars: v on the centre row every {step} px. resolution: period where |A - v|/A "
        f"reaches {100 * LIMIT:g} % on Star 1 (noise-free; {SMOOTH_POINTS} px running mean), 'on Star 2' the same "
        f"on the noisy pair; noise: SD(v - truth) on Star 2's row where p >= {NOISE_MIN_PERIOD:g} px; noise 2-D: "
        f"SD(v Star 2 - v Star 1) on a {GRID_STEP_2D} px grid there; predicted: sqrt(2 sigma^2 [H^-1]_vv); "
        "MEI = resolution x noise, MEI 2 = resolution on Star 2 x noise; Star 1 SD: SD(v - truth) on Star 1's row there (pattern-induced); sampled with: "
        "interpolation, pre-filter")
    stars = run_stars(data, subsets, subpixels, step, log, interpolation, prefilter)
    log("")
    log(f"DIC Challenge 1.0 Sample 3: every grid point (step 10), subset {SAMPLE3_SUBSET}, {SAMPLE3_SUBPIXEL}; "
        "bias = mean of (measured - truth) over the ok points")
    shifts = run_sample3(data, log, interpolation, prefilter)
    worst = worst_bias(shifts)
    passed = math.isfinite(worst) and worst <= BIAS_TARGET
    log("")
    log(f"{'PASS' if passed else 'FAIL'}: Sample 3 worst |mean bias| {worst:.4f} px "
        f"({'<=' if passed else 'above'} the target {BIAS_TARGET} px); largest SD "
        f"{max(max(r.sd_u, r.sd_v) for r in shifts):.4f} px")
    log(f"{time.perf_counter() - started:.0f} s")
    if output is not None:
        from livedic.stream.output.files import json_text, write_text_atomic
        write_text_atomic(output, json_text(_report(stars, shifts, worst, passed, quick, step, interpolation,
                                                    prefilter)))
        log(f"written: {output}")
    return 0 if passed else 1


def _report(stars, shifts, worst, passed, quick, step, interpolation, prefilter):
    def plain(case):
        entry = asdict(case)
        entry["resolution_status"] = case.resolution_status.value
        entry["resolution_noisy_status"] = case.resolution_noisy_status.value
        entry["mei_noisy_px2"] = case.mei_noisy_px2
        return entry
    return {"kind": "livedic bench accuracy", "quick": quick, "interpolation": interpolation, "prefilter": prefilter,
            "stars": {"amplitude_px": AMPLITUDE, "centre_row": CENTRE_ROW, "limit": LIMIT, "line_step_px": step,
                      "smooth_points": SMOOTH_POINTS, "noise_min_period_px": NOISE_MIN_PERIOD,
                      "cases": [plain(case) for case in stars]},
            "sample3": {"subset": SAMPLE3_SUBSET, "subpixel": SAMPLE3_SUBPIXEL, "grid_px": 10,
                        **dict(zip(("interpolation", "prefilter"), sampling(SAMPLE3_SUBPIXEL, interpolation, prefilter))),
                        "target_px": BIAS_TARGET, "worst_bias_px": worst, "passed": passed,
                        "shifts": [asdict(row) for row in shifts]}}
