"""``livedic bench validate``: is every point marked ok right, on images livedic did not make?

A metrology tool must never present a wrong number as a measurement. This
benchmark counts, for ``dic.measure`` as a user runs it, the points that are
**ok but more than 0.5 px from the truth** ("wrong ok"); the target is 0 in
every row. It also prints how many points were measured (ok) and their RMS
error, so a method cannot pass by flagging everything.

Cases (each with the defaults, ``--search`` each of the integer searches, and
``--subpixel icgn``, with the interpolant and pre-filter ``livedic measure`` gives them by default):

* **synthetic**, made here: shifts up to 30 px at radius 32 on four pattern
  generators, three of them not livedic's simulator (``bench.patterns``:
  FFT-filtered random noise, sparse dots, hard discs), noise sigma = 2;
* **low contrast** (the choice of ``dic.quality.MIN_ZNCC``): speckle squeezed
  into 50 grey levels with noise sigma = 3; prints the lowest ZNCC of a correct
  point, which the default ZNCC gate must stay below;
* **DIC Challenge** images from ``--data DIR`` (the folder of
  ``dicc1_sample3_translation``, ``dicc1_sample12_oht_cfrp``, ``dicc2_star``):
  Sample 3 (rigid shifts 0-1 px, every grid point at step 10), Sample 12 (real
  open-hole CFRP test, frames 1-11 at DICe's 230 points; DICe's result is the
  reference, not truth: "wrong" is more than 0.5 px from it), Star 1 and 2
  (sinusoidal v of amplitude 0.5 px: "wrong" is more than 0.5 px from any value
  the true field takes, |u| or |v| - 0.5 beyond 0.5 px), centre line and every
  5 px.

Exit code 0 when no row has a wrong-ok point, 1 otherwise.
"""

import glob
import os
import time

import numpy as np

from livedic.bench import patterns

SYNTHETIC_SHIFTS = ((17.4, -9.2), (0.37, -0.81), (-26.3, 14.1), (29.1, 21.7))
RADIUS = 32
SIZE = 384


def _grid(lo, hi, step):
    axis = np.arange(lo, hi + 1, step, dtype=float)
    return np.column_stack([a.ravel() for a in np.meshgrid(axis, axis)])


# The DIC Challenge 2.0 Star pairs in --data's dicc2_star: name -> (sub-folder, file tag).
STARS = {"Star 1": ("star1_noisefree", "NoiseFree"), "Star 2": ("star2_noisy", "Noisy")}


def read_star_pair(data: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The reference and deformed image of Star ``name`` ("Star 1" or "Star 2") under ``data``."""
    from livedic.acquire.files.image_file import read_grey_image

    sub, tag = STARS[name]
    folder = os.path.join(data, "dicc2_star", sub)
    return tuple(read_grey_image(os.path.join(folder, f"DIC_Challenge_Wave_{kind}_{tag}.tif"))[0]
                 for kind in ("Reference", "Deformed"))


def sample3_frames(data: str) -> tuple[np.ndarray, list[tuple[str, tuple[float, float]]]]:
    """DIC Challenge 1.0 Sample 3 under ``data``: the reference image and each frame's (path, (u, v) truth).

    Frame k (Sample3-00k) is the pattern shifted by 0.1 k px in x and in y (the set's ground_truth.csv).
    """
    from livedic.acquire.files.image_file import read_grey_image

    folder = os.path.join(data, "dicc1_sample3_translation", "images")
    reference = read_grey_image(os.path.join(folder, "Sample3 Reference.tif"))[0]
    frames = sorted(glob.glob(os.path.join(folder, "Sample3-0*.tif")))
    return reference, [(path, (round(0.1 * k, 10), round(0.1 * k, 10))) for k, path in enumerate(frames)]


def sample3_grid() -> np.ndarray:
    """Every grid point at step 10 px of the 512 x 512 Sample 3 images, (N, 2) as (x, y)."""
    return _grid(10, 501, 10)


def _methods(quick):
    from livedic.dic.measure import SEARCH_METHODS
    searches = [s for s in SEARCH_METHODS if s != "none"]
    if quick:
        searches = ["improved-wso", "pso"]
    rows = [("defaults (improved-wso + improved-surface-fit)", dict())]
    rows += [(f"--search {s} --subpixel icgn", dict(search=s, subpixel="icgn")) for s in searches]
    return [(label, _as_measure_runs(options)) for label, options in rows]


def _as_measure_runs(options):
    """``options`` with the interpolant and pre-filter ``livedic measure`` adds to them by default, so that each
    row is what its command line measures."""
    from livedic.stream.session.config import MeasureConfig
    config = MeasureConfig(**options)
    return dict(options, interpolation=config.interpolation, prefilter=config.prefilter)


class _Table:
    def __init__(self, log):
        self.log = log
        self.rows = []
        header = f"{'case':44s} {'method':48s} {'points':>7s} {'ok %':>6s} {'wrong ok':>8s} {'RMSE ok px':>10s}"
        log(header)
        log("-" * len(header))

    def add(self, case, method, error, ok):
        good = ok & np.isfinite(error)
        wrong = int(np.sum(good & (error > 0.5)))
        rmse = float(np.sqrt(np.mean(error[good] ** 2))) if good.any() else float("nan")
        self.rows.append(dict(case=case, method=method, points=int(ok.size), ok=int(ok.sum()), wrong_ok=wrong,
                              rmse=rmse))
        self.log(f"{case:44s} {method:48s} {ok.size:7d} {100 * ok.mean():6.1f} {wrong:8d} {rmse:10.4f}")


def _synthetic(table, quick):
    from livedic.dic import measure

    generators = ("simulator R=4", "fft-filtered noise", "sparse dots", "hard discs R=3")
    shifts = SYNTHETIC_SHIFTS[:2] if quick else SYNTHETIC_SHIFTS
    points = _grid(40, SIZE - 41, 16 if quick else 12)
    for g, generator in enumerate(generators):
        for shift in shifts:
            ref, dfm = patterns.pair(generator, (SIZE, SIZE), shift, noise_sigma=2.0, seed=10 + g)
            for label, options in _methods(quick):
                m = measure(ref, dfm, points, radius=RADIUS, **options)
                error = np.hypot(m.u - shift[0], m.v - shift[1])
                table.add(f"{generator}, shift ({shift[0]:g}, {shift[1]:g}), r {RADIUS}", label, error, m.ok)


def low_contrast_floor(log, quick=False):
    """Lowest ZNCC of a correct (within 0.5 px) point on 50-grey-level, sigma-3 pairs (ZNCC gate off)."""
    from livedic.dic import measure
    from livedic.dic.quality import Gates

    lowest = 1.0
    points = _grid(40, SIZE - 41, 16 if quick else 8)
    for g, generator in enumerate(("simulator R=4", "fft-filtered noise")):
        shift = (5.37, -3.81)
        ref, dfm = patterns.pair(generator, (SIZE, SIZE), shift, noise_sigma=3.0, seed=30 + g, contrast=50.0)
        m = measure(ref, dfm, points, subpixel="icgn", radius=8, gates=Gates(min_zncc=-1.0))
        error = np.hypot(m.u - shift[0], m.v - shift[1])
        right = m.ok & (error <= 0.5)
        value = float(np.min(m.zncc[right])) if right.any() else float("nan")
        log(f"  {generator}: {right.sum()} correct points of {len(points)}, lowest ZNCC of a correct point {value:.3f}")
        lowest = min(lowest, value)
    return lowest


def _sample3(table, data, methods):
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.dic import measure

    reference, frames = sample3_frames(data)
    points = sample3_grid()
    for label, options in methods:
        errors, oks = [], []
        for path, (true_u, true_v) in frames:
            m = measure(reference, read_grey_image(path)[0], points, **options)
            errors.append(np.hypot(m.u - true_u, m.v - true_v))
            oks.append(m.ok)
        table.add(f"Sample 3, {len(frames)} frames, every point (grid 10)", label, np.concatenate(errors),
                  np.concatenate(oks))


def _sample12(table, data, methods):
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.dic import measure

    folder = os.path.join(data, "dicc1_sample12_oht_cfrp")
    images = sorted(glob.glob(os.path.join(folder, "images", "oht_cfrp_*.tiff")))
    reference = read_grey_image(images[0])[0]
    for label, options in methods:
        errors, oks = [], []
        for k in range(1, len(images)):
            gold = np.loadtxt(os.path.join(folder, "dice_gold", f"DICe_solution_{k:02d}.txt"), delimiter=",",
                              skiprows=21)
            m = measure(reference, read_grey_image(images[k])[0], gold[:, :2], **options)
            errors.append(np.hypot(m.u - gold[:, 2], m.v - gold[:, 3]))
            oks.append(m.ok)
        table.add("Sample 12 (real CFRP), frames 1-11, DICe points", label, np.concatenate(errors),
                  np.concatenate(oks))


def _stars(table, data, methods):
    from livedic.dic import measure

    for name in STARS:
        ref, dfm = read_star_pair(data, name)
        height, width = ref.shape
        centre = np.column_stack([np.arange(15, width - 15, 5.0), np.full(len(range(15, width - 15, 5)), 250.0)])
        every = np.column_stack([a.ravel() for a in np.meshgrid(np.arange(10, width - 10, 5.0),
                                                                np.arange(10, height - 10, 5.0))])
        for label, options in methods:
            for where, points in (("centre line", centre), ("every 5 px", every)):
                m = measure(ref, dfm, points, **options)
                # distance to the set of true values {(0, v): |v| <= 0.5}
                error = np.hypot(m.u, np.maximum(np.abs(m.v) - 0.5, 0.0))
                table.add(f"{name}, {where}", label, error, m.ok)


def run_validate_benchmark(*, data=None, quick=False, log=print):
    """Print the wrong-ok table (module notes); return 0 when no row has a wrong-ok point, else 1."""
    import numba
    import platform

    from livedic.dic.quality import MIN_ZNCC

    started = time.perf_counter()
    log(f"livedic bench validate: {os.cpu_count()} CPU cores, numba {numba.__version__}, {platform.machine()}"
        + (" (quick)" if quick else ""))
    log("")
    log(f"low-contrast pairs (50 grey levels, noise sigma 3): the ZNCC gate's default is {MIN_ZNCC}")
    floor = low_contrast_floor(log, quick)
    log(f"  -> default min ZNCC {MIN_ZNCC} {'is below' if MIN_ZNCC < floor else 'is NOT below'} every correct "
        f"point ({floor:.3f})")
    log("")
    table = _Table(log)
    _synthetic(table, quick)
    if data:
        missing = [d for d in ("dicc1_sample3_translation", "dicc1_sample12_oht_cfrp", "dicc2_star")
                   if not os.path.isdir(os.path.join(data, d))]
        if missing:
            raise ValueError(f"--data {data} lacks {', '.join(missing)}: give the folder holding the DIC Challenge "
                             "sets (e.g. ../shared/datasets)")
        methods = _methods(quick)
        _sample3(table, data, methods)
        _sample12(table, data, methods)
        _stars(table, data, methods)
    else:
        log("(no --data: the DIC Challenge cases are skipped)")
    bad = [r for r in table.rows if r["wrong_ok"]]
    log("")
    log(f"{len(table.rows)} rows, {sum(r['points'] for r in table.rows)} point measurements, "
        f"{sum(r['wrong_ok'] for r in table.rows)} wrong but ok; {time.perf_counter() - started:.0f} s")
    if bad:
        log("FAIL: wrong points reported as ok in: " + "; ".join(f"{r['case']} / {r['method']}" for r in bad))
        return 1
    log("PASS: no point more than 0.5 px off is reported ok")
    return 0
