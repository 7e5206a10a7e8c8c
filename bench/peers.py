"""``livedic bench peers``: livedic's random error against open DIC codes, on images livedic did not make.

Issue 23 asks for an RMSE at or below ``TARGET_RATIO`` (0.9) x the best open peer's on simulated rigid
sub-pixel shifts from pattern generators other than livedic's simulator, 8 and 12 bit, image noise sigma 2
grey levels. This module renders those cases, measures them with livedic in several interpolation /
pre-filter settings and, in the same run, with the peers where they are installed:

* **SUN-DIC** (PyPI ``sun-dic``): ``--sundic-python`` names the Python of the separate environment where it is
  installed; ``bench/peer_sundic_runner.py`` runs it there (IC-GN, affine, its defaults; docstring there).
* **OpenCorr** (github vincentjzy/OpenCorr): ``--opencorr-bin`` names a build of its FFT-CC + IC-GN (first
  order, bicubic B-spline) example that reads images at full bit depth (the guide, docs/guide/measure.md, has
  the driver and the build lines): ``BIN REF TAR POIS.csv OUT.csv SUBSET_RADIUS``, writing
  ``x,y,u,v,zncc,...``; OpenCorr marks a failed point with ZNCC < 0.

A peer not given is reported "not installed"; one that fails is reported with its own last error line; the
livedic rows are measured either way.

**Cases** (``cases``): every case is a rigid shift, the same for every point, so the truth is exact:

* ``fft-filtered noise`` (``bench.patterns.fft_blurred``): band-limited, the shift applied as a Fourier phase
  ramp, exact for any sub-pixel value;
* ``gaussian dots`` (``bench.patterns.sparse_dots``, 12 per 21 x 21 px): isotropic Gaussian dots sampled at
  their shifted centres, exact; where dots overlap the generator saturates (250 grey levels), so the sampled
  image is not band-limited: a pattern-induced error of about 0.003 px that no interpolant or pre-filter
  removes (an overexposed speckle; the quick run leaves it out);

each linearly scaled so the reference spans ``GREY_RANGE`` (a dark floor of 20 grey levels, as a camera's
offset, so no pixel clips at 0), then quantised to 8 bit, or to 12 bit (x 4095/255, in a 16-bit container),
with independent Gaussian noise of ``NOISE_SIGMA_8BIT`` grey levels in 8-bit units (x 4095/255 at 12 bit) on
each image. Shifts ``SHIFTS`` (u, v px; quick: ``QUICK_SHIFTS``), ``IMAGE_SIZE`` square images (quick
``QUICK_SIZE``), a grid every ``GRID_STEP`` px at least ``MARGIN`` px in, subset ``SUBSET`` for every code.

**Numbers**: per case and code, over every point the code reports ok, pooled over the case's shifts: the
RMSE of u - truth and of v - truth and ``rmse = sqrt((RMSE_u^2 + RMSE_v^2) / 2)``, the ok count; livedic's
``rmse`` over the best peer's (the smallest ``rmse`` among the peers that ran) is the ratio; a setting meets
the target when its ratio is at most ``TARGET_RATIO`` in every case. Exit code 1 when peers ran and no
setting meets it, else 0. Each case also shows the first-order noise prediction (``predicted_rmse``): the
RMSE an unbiased IC-GN reaches on that pattern, subset and noise, the floor no setting goes below.
"""

from __future__ import annotations

import enum
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from livedic.bench.patterns import fft_blurred, sparse_dots

SUBSET = 21
GRID_STEP = 10
MARGIN = 20                        # px from the image edge to the first grid point
IMAGE_SIZE = 512
QUICK_SIZE = 256
SHIFTS = ((0.1, 0.5), (0.3, 0.7), (0.5, 0.9), (0.7, 0.1), (0.9, 0.3))
QUICK_SHIFTS = ((0.3, 0.7),)
NOISE_SIGMA_8BIT = 2.0             # grey levels in 8-bit units, issue 23
GREY_RANGE = (20.0, 235.0)         # the reference's darkest and brightest grey level before noise (8-bit units)
BIT_DEPTHS = (8, 12)
GENERATORS = ("fft-filtered noise", "gaussian dots")
QUICK_GENERATORS = ("fft-filtered noise",)
SETTINGS = (("bspline3", "none"), ("bspline3", "gaussian:0.8"), ("bspline5", "none"), ("bspline5", "gaussian:0.6"))
TARGET_RATIO = 0.9
PEER_TIMEOUT_S = 600               # one peer on one image pair
SUNDIC_RUNNER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "peer_sundic_runner.py")


class PeerStatus(enum.Enum):
    """Whether a code's numbers exist."""
    MEASURED = "measured"
    NOT_INSTALLED = "not installed"
    FAILED = "failed"


@dataclass(frozen=True)
class Case:
    """One simulated case: a generator at a bit depth, over ``shifts`` (u, v px)."""
    generator: str
    bits: int
    shifts: tuple[tuple[float, float], ...]
    size: int

    @property
    def name(self) -> str:
        return f"{self.generator}, {self.bits} bit"


@dataclass
class Score:
    """A code's errors on one case (module notes), pooled over the case's shifts."""
    code: str
    status: PeerStatus = PeerStatus.MEASURED
    ok: int = 0
    points: int = 0
    rmse_u: float = math.nan
    rmse_v: float = math.nan
    rmse: float = math.nan
    reason: str = ""
    seconds: float = 0.0


@dataclass
class CaseResult:
    """Every code's score on one case and livedic's ratio to the best peer."""
    case: Case
    livedic: list[Score] = field(default_factory=list)
    peers: list[Score] = field(default_factory=list)
    predicted_rmse: float = math.nan

    def best_peer(self) -> Score | None:
        measured = [s for s in self.peers if s.status is PeerStatus.MEASURED and math.isfinite(s.rmse)]
        return min(measured, key=lambda s: s.rmse) if measured else None

    def ratio(self, score: Score) -> float:
        best = self.best_peer()
        return score.rmse / best.rmse if best is not None and best.rmse > 0 else math.nan


# ----------------------------------------------------------------------------- the cases

def cases(quick: bool = False) -> list[Case]:
    """The benchmark's cases (module notes)."""
    generators, shifts, size = ((QUICK_GENERATORS, QUICK_SHIFTS, QUICK_SIZE) if quick
                                else (GENERATORS, SHIFTS, IMAGE_SIZE))
    return [Case(generator, bits, tuple(shifts), size) for generator in generators for bits in BIT_DEPTHS]


def render_clean(generator: str, size: int, shift: tuple[float, float], seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free (reference, shifted) float images of ``generator``, 8-bit grey scale, spanning ``GREY_RANGE``.

    The reference's minimum and maximum map to ``GREY_RANGE``; the same linear map on the shifted image keeps
    the shift exact.
    """
    if generator == "fft-filtered noise":
        reference, deformed = fft_blurred((size, size), shift, seed=seed)
    elif generator == "gaussian dots":
        reference, deformed = sparse_dots((size, size), shift, dots_per_subset=12.0, seed=seed)
    else:
        raise ValueError(f"unknown generator {generator!r}: one of {', '.join(GENERATORS)}")
    lo, hi = float(reference.min()), float(reference.max())
    scale = (GREY_RANGE[1] - GREY_RANGE[0]) / (hi - lo)
    return GREY_RANGE[0] + (reference - lo) * scale, GREY_RANGE[0] + (deformed - lo) * scale


def quantise(image: np.ndarray, bits: int, noise_sigma_8bit: float, seed: int) -> np.ndarray:
    """``image`` (8-bit grey scale) at ``bits`` (8: uint8; 12: uint16 holding 0..4095) with Gaussian noise of
    ``noise_sigma_8bit`` 8-bit grey levels (scaled with the image), rounded and clipped."""
    top = 2 ** bits - 1
    scale = top / 255.0
    rng = np.random.default_rng(seed)
    noisy = image * scale + (rng.normal(0.0, noise_sigma_8bit * scale, image.shape) if noise_sigma_8bit > 0 else 0.0)
    return np.clip(np.floor(noisy + 0.5), 0, top).astype(np.uint8 if bits <= 8 else np.uint16)


def render_pair(case: Case, shift: tuple[float, float], index: int,
                noise_sigma_8bit: float = NOISE_SIGMA_8BIT) -> tuple[np.ndarray, np.ndarray]:
    """The (reference, deformed) integer images of ``case`` at ``shift``; ``index`` seeds pattern and noise."""
    reference, deformed = render_clean(case.generator, case.size, shift, seed=index)
    return (quantise(reference, case.bits, noise_sigma_8bit, 2 * index + 1),
            quantise(deformed, case.bits, noise_sigma_8bit, 2 * index + 2))


def grid(size: int) -> np.ndarray:
    """(x, y) grid points, shape (N, 2): every ``GRID_STEP`` px from ``MARGIN`` to ``size - MARGIN``."""
    ticks = np.arange(MARGIN, size - MARGIN + 1, GRID_STEP, dtype=float)
    xs, ys = np.meshgrid(ticks, ticks)
    return np.column_stack([xs.ravel(), ys.ravel()])


# ----------------------------------------------------------------------------- the arithmetic

def score(code: str, errors_u: Sequence[np.ndarray], errors_v: Sequence[np.ndarray], ok: Sequence[np.ndarray],
          seconds: float = 0.0) -> Score:
    """RMSE of u and v errors over the ok points of every pair, pooled (module notes)."""
    du = np.concatenate([np.asarray(e, float)[k] for e, k in zip(errors_u, ok)])
    dv = np.concatenate([np.asarray(e, float)[k] for e, k in zip(errors_v, ok)])
    points = int(sum(np.asarray(k).size for k in ok))
    if du.size == 0:
        return Score(code, PeerStatus.FAILED, 0, points, reason="no point ok", seconds=seconds)
    rmse_u, rmse_v = float(np.sqrt(np.mean(du ** 2))), float(np.sqrt(np.mean(dv ** 2)))
    return Score(code, PeerStatus.MEASURED, int(du.size), points, rmse_u, rmse_v,
                 float(np.sqrt(0.5 * (rmse_u ** 2 + rmse_v ** 2))), seconds=seconds)


def predicted_rmse(case: Case, noise_sigma_8bit: float = NOISE_SIGMA_8BIT) -> float:
    """The first-order noise prediction of the case's RMSE (``bench.accuracy.predicted_noise``), px.

    ``sqrt(2 sigma^2 [H^-1])`` for u (on the transposed image) and v at every grid point of every shift's
    noise-free reference, first-order shape function, combined as ``rmse``; sigma includes the rounding
    (1/12 level^2 at the case's depth). What an unbiased IC-GN reaches on this subset and noise: the floor
    the RMSE of every code approaches when the interpolation bias is gone.
    """
    from livedic.bench.accuracy import predicted_noise

    points = grid(case.size).astype(int)
    scale = (2 ** case.bits - 1) / 255.0
    sigma = math.sqrt(noise_sigma_8bit ** 2 + 1.0 / 12.0 / scale ** 2)
    squares = []
    for index, shift in enumerate(case.shifts):
        reference, _ = render_clean(case.generator, case.size, shift, seed=index)
        for image, xs, ys in ((reference, points[:, 0], points[:, 1]), (reference.T, points[:, 1], points[:, 0])):
            squares.append(predicted_noise(image, xs, ys, SUBSET, 1, sigma) ** 2)
    return float(np.sqrt(np.mean(np.concatenate(squares))))


# ----------------------------------------------------------------------------- the codes

def livedic_code(interpolation: str, prefilter: str) -> str:
    return f"livedic {interpolation}/{prefilter}"


def _measure_livedic(pairs, points, interpolation, prefilter) -> Score:
    from livedic.dic import measure

    started = time.perf_counter()
    errors_u, errors_v, ok = [], [], []
    for (reference, deformed), (u, v) in pairs:
        m = measure(reference, deformed, points, subset=SUBSET, subpixel="icgn", interpolation=interpolation,
                    prefilter=prefilter)
        errors_u.append(m.u - u)
        errors_v.append(m.v - v)
        ok.append(m.ok & np.isfinite(m.u) & np.isfinite(m.v))
    return score(livedic_code(interpolation, prefilter), errors_u, errors_v, ok, time.perf_counter() - started)


def _run(command: list[str]) -> str | None:
    """Run a peer; None on success, else its last stderr line (or why it did not run)."""
    try:
        run = subprocess.run(command, capture_output=True, text=True, timeout=PEER_TIMEOUT_S)
    except OSError as error:
        return f"cannot run {command[0]}: {error.strerror}"
    except subprocess.TimeoutExpired:
        return f"no answer within {PEER_TIMEOUT_S} s"
    if run.returncode != 0:
        lines = [line for line in (run.stderr or run.stdout).splitlines() if line.strip()]
        return f"exit code {run.returncode}: {lines[-1] if lines else 'no message'}"
    return None


def _read_table(path: str) -> dict[str, np.ndarray]:
    table = np.genfromtxt(path, delimiter=",", names=True, dtype=float, ndmin=1)
    return {name: np.atleast_1d(table[name]) for name in table.dtype.names}


def _on_grid(table: dict[str, np.ndarray], points: np.ndarray, valid: np.ndarray):
    """The peer's u, v and validity at ``points`` (rows matched by position; a point it left out is not ok)."""
    index = {(int(round(x)), int(round(y))): i for i, (x, y) in enumerate(zip(table["x"], table["y"]))}
    u = np.full(len(points), np.nan)
    v = np.full(len(points), np.nan)
    ok = np.zeros(len(points), dtype=bool)
    for j, (x, y) in enumerate(points):
        i = index.get((int(round(x)), int(round(y))))
        if i is not None:
            u[j], v[j], ok[j] = table["u"][i], table["v"][i], valid[i]
    return u, v, ok & np.isfinite(u) & np.isfinite(v)


def _measure_peer(code, files, points, work, command_for, validity) -> Score:
    """Run one peer over every pair of a case (``command_for(ref, def, pois, out)`` its command line)."""
    started = time.perf_counter()
    pois = os.path.join(work, "pois.csv")
    np.savetxt(pois, points, fmt="%d", delimiter=",")
    errors_u, errors_v, ok = [], [], []
    for (reference, deformed), (u_true, v_true) in files:
        out = os.path.join(work, "peer.csv")
        if os.path.exists(out):
            os.remove(out)
        failure = _run(command_for(reference, deformed, pois, out))
        if failure is None and not os.path.isfile(out):
            failure = "wrote no result"
        if failure is not None:
            return Score(code, PeerStatus.FAILED, reason=failure, seconds=time.perf_counter() - started)
        try:
            table = _read_table(out)
            u, v, valid = _on_grid(table, points, validity(table))
        except (ValueError, KeyError, TypeError) as error:
            return Score(code, PeerStatus.FAILED, reason=f"unreadable result: {error}",
                         seconds=time.perf_counter() - started)
        errors_u.append(u - u_true)
        errors_v.append(v - v_true)
        ok.append(valid)
    return score(code, errors_u, errors_v, ok, time.perf_counter() - started)


SUNDIC = "SUN-DIC IC-GN affine"
OPENCORR = "OpenCorr IC-GN1 bicubic B-spline"


def _sundic_command(python, points):
    lo, hi = int(points.min()), int(points.max())
    return lambda ref, tar, pois, out: [python, SUNDIC_RUNNER, ref, tar, out, str(SUBSET), str(GRID_STEP),
                                        str(lo), str(lo), str(hi), str(hi)]


def _opencorr_command(binary):
    return lambda ref, tar, pois, out: [binary, ref, tar, pois, out, str(SUBSET // 2)]


def _peers(case_files, points, work, sundic_python, opencorr_bin) -> list[Score]:
    scores = []
    for code, location, command, validity in (
            (SUNDIC, sundic_python, lambda: _sundic_command(sundic_python, points), lambda t: t["cznssd"] < 1e5),
            (OPENCORR, opencorr_bin, lambda: _opencorr_command(opencorr_bin), lambda t: t["zncc"] >= 0)):
        if location is None:
            scores.append(Score(code, PeerStatus.NOT_INSTALLED))
        else:
            scores.append(_measure_peer(code, case_files, points, work, command(), validity))
    return scores


def check_peer_location(option: str, path: str) -> None:
    """ValueError (one line) unless ``path`` is an executable file, as ``--sundic-python`` / ``--opencorr-bin``."""
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        raise ValueError(f"{option} {path} is not an executable file: give its full path, or leave the option out "
                         "to report that peer as not installed")


def check_sundic_python(path: str) -> None:
    """ValueError (one line) unless ``path`` is a Python that imports ``sundic``."""
    check_peer_location("--sundic-python", path)
    if _run([path, "-c", "import sundic.sundic"]) is not None:
        raise ValueError(f"--sundic-python {path} cannot import sundic: give the python of the environment where "
                         "sun-dic is installed (pip install sun-dic)")


# ----------------------------------------------------------------------------- the run

def _write_image(path: str, image: np.ndarray) -> str:
    import cv2
    if not cv2.imwrite(path, image):
        raise OSError(f"cannot write {path}")
    return path


def run_case(case: Case, *, settings: Sequence[tuple[str, str]] = SETTINGS, sundic_python: str | None = None, opencorr_bin: str | None = None,
             noise_sigma_8bit: float = NOISE_SIGMA_8BIT) -> CaseResult:
    """Every livedic setting and every peer on ``case``."""
    points = grid(case.size)
    pairs = [(render_pair(case, shift, index, noise_sigma_8bit), shift) for index, shift in enumerate(case.shifts)]
    result = CaseResult(case, predicted_rmse=predicted_rmse(case, noise_sigma_8bit))
    result.livedic = [_measure_livedic(pairs, points, interpolation, prefilter)
                      for interpolation, prefilter in settings]
    with tempfile.TemporaryDirectory(prefix="livedic-peers-") as work:
        files = [((_write_image(os.path.join(work, f"ref{i}.png"), a), _write_image(os.path.join(work, f"def{i}.png"), b)),
                  shift) for i, ((a, b), shift) in enumerate(pairs)]
        result.peers = _peers(files, points, work, sundic_python, opencorr_bin)
    return result


def _number(value: float, width: int = 8, digits: int = 4) -> str:
    return f"{value:{width}.{digits}f}" if math.isfinite(value) else f"{'n/a':>{width}s}"


def _row(result: CaseResult, score_: Score, is_livedic: bool) -> str:
    head = f"  {score_.code:34s}"
    if score_.status is not PeerStatus.MEASURED:
        return f"{head} {score_.status.value}" + (f": {score_.reason}" if score_.reason else "")
    ratio = result.ratio(score_) if is_livedic else math.nan
    verdict = ("" if not math.isfinite(ratio) else "  meets 0.9x" if ratio <= TARGET_RATIO else "  above 0.9x")
    return (f"{head} {f'{score_.ok}/{score_.points}':>11s} {_number(score_.rmse_u)} {_number(score_.rmse_v)} "
            f"{_number(score_.rmse)} {_number(ratio, 7, 2) if is_livedic else ' ' * 7}{verdict}")


def report_case(result: CaseResult, log: Callable[[str], None]) -> None:
    """The case's table."""
    case = result.case
    log(f"{case.name}: {len(case.shifts)} shift(s), {case.size}x{case.size} px; first-order noise prediction "
        f"(an unbiased IC-GN's RMSE) {_number(result.predicted_rmse, 0)} px")
    log(f"  {'code':34s} {'ok':>11s} {'RMSE u':>8s} {'RMSE v':>8s} {'RMSE':>8s} {'/ best':>7s}")
    for s in result.livedic:
        log(_row(result, s, True))
    for s in result.peers:
        log(_row(result, s, False))


def verdicts(results: Sequence[CaseResult]) -> dict[str, float]:
    """Per livedic setting, its worst ratio to the best peer over the cases (NaN where no peer ran)."""
    worst: dict[str, float] = {}
    for result in results:
        for s in result.livedic:
            ratio = result.ratio(s)
            worst[s.code] = max(worst.get(s.code, -math.inf), ratio) if math.isfinite(ratio) else math.nan
    return worst


def run_peers_benchmark(*, quick: bool = False, output: str | None = None, sundic_python: str | None = None,
                        opencorr_bin: str | None = None, log: Callable[[str], None] = print) -> int:
    """Every case (module notes): print the tables and the verdict, write ``output`` (JSON); the exit code."""
    import platform

    started = time.perf_counter()
    log(f"livedic bench peers: {os.cpu_count()} CPU cores, {platform.machine()}" + (" (quick)" if quick else ""))
    log(f"rigid sub-pixel shifts, subset {SUBSET}, grid every {GRID_STEP} px, image noise sigma "
        f"{NOISE_SIGMA_8BIT:g} grey levels (8-bit units, scaled at 12 bit); livedic icgn; RMSE over each code's ok "
        f"points, px; RMSE = sqrt((u^2 + v^2) / 2); / best = livedic RMSE / the best peer's")
    results = []
    for case in cases(quick):
        result = run_case(case, sundic_python=sundic_python, opencorr_bin=opencorr_bin)
        log("")
        report_case(result, log)
        results.append(result)
    worst = verdicts(results)
    log("")
    peers_ran = any(r.best_peer() is not None for r in results)
    meeting = [code for code, ratio in worst.items() if math.isfinite(ratio) and ratio <= TARGET_RATIO]
    if not peers_ran:
        log("no verdict: no peer was measured (give --sundic-python and/or --opencorr-bin)")
    else:
        for code, ratio in worst.items():
            log(f"  {code:34s} worst ratio {_number(ratio, 5, 2)}  "
                f"{'PASS' if code in meeting else 'FAIL'} (target <= {TARGET_RATIO:g}x the best peer in every case)")
        log(f"{'PASS' if meeting else 'FAIL'}: {', '.join(meeting) if meeting else 'no livedic setting'} "
            f"at or below {TARGET_RATIO:g}x the best peer in every case")
    log(f"{time.perf_counter() - started:.0f} s")
    if output is not None:
        from livedic.stream.output.files import json_text, write_text_atomic
        write_text_atomic(output, json_text(_report(results, worst, quick, sundic_python, opencorr_bin)))
        log(f"written: {output}")
    return 1 if peers_ran and not meeting else 0


def _report(results, worst, quick, sundic_python, opencorr_bin):
    def plain(s: Score, result: CaseResult | None = None):
        entry = asdict(s)
        entry["status"] = s.status.value
        if result is not None:
            entry["ratio_to_best_peer"] = result.ratio(s)
        return entry
    return {"kind": "livedic bench peers", "quick": quick, "subset": SUBSET, "grid_px": GRID_STEP,
            "noise_sigma_8bit": NOISE_SIGMA_8BIT, "target_ratio": TARGET_RATIO, "python": sys.version.split()[0],
            "peers": {"sundic_python": sundic_python, "opencorr_bin": opencorr_bin},
            "cases": [{"generator": r.case.generator, "bits": r.case.bits, "size": r.case.size,
                       "shifts": [list(s) for s in r.case.shifts], "predicted_rmse": r.predicted_rmse,
                       "livedic": [plain(s, r) for s in r.livedic], "peers": [plain(s) for s in r.peers]}
                      for r in results],
            "worst_ratio": worst}
