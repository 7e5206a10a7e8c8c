"""``livedic bench speed``: points per second per method on one large image pair.

Setup: a 1024x1024 8-bit speckle image (paper density: 1000 speckles per
256x256, radius 4 px), points on a grid, subset 21. The deformation is a rigid
shift plus a small homogeneous strain, rendered exactly. Two jobs, each with
its own OpenCV baseline measured in the same run:

* seeded (10,000 points, shift (5.3, -7.6)): every point gets a guess within
  2 px of its true displacement (what a tracker has from the previous frame);
  searches use radius 2. Baseline: ``calcOpticalFlowPyrLK`` (21x21, no
  pyramid) from the same guess.
* unseeded (8,281 points, shift (17.3, -9.6) px, no guess): ``dic.measure`` as
  a user calls it, reliability-guided (a few seeds searched over radius 24,
  then propagation), and the same with every point searched (``guided=False``).
  Baseline: ``calcOpticalFlowPyrLK`` (21x21) with a 3-level pyramid
  (``maxLevel=3``), the usual way to reach a large motion without a guess.

``icgn2`` (IC-GN with the 2nd-order shape function) runs on the same jobs:
they are affine, so it can only add noise there (its RMSE against IC-GN's is
the cost of six more parameters per subset); its gain is on curved fields.

Each method is timed after a warm-up call (numba compilation excluded), best of
``repeat`` runs. "wrong ok" counts points more than 0.5 px off that the method
reports as valid.
Peak memory is the process's peak resident set during each method (VmHWM,
reset before each method through /proc/self/clear_refs where the kernel allows).
"""

import os
import platform
import time

import numpy as np

from livedic.dic import DEFAULT_SUBSET

SEEDED_OFFSET_PX = 2.0
UNSEEDED_SHIFT = (17.3, -9.6)
UNSEEDED_POINTS = 8281
UNSEEDED_RADIUS = 24


def make_job(size=1024, n_points=10_000, subset=DEFAULT_SUBSET, seed=0, shift=(5.3, -7.6)):
    """Reference, deformed, points, true (u, v) per point and the field parameters."""
    from livedic.dic.speckle import SpecklePattern, affine, render

    centre = ((size - 1) / 2.0, (size - 1) / 2.0)
    field = dict(u=shift[0], v=shift[1], ux=0.002, uy=0.0005, vx=-0.0005, vy=0.003)
    pattern = SpecklePattern((size, size), n_speckles=int(round(1000 * size * size / 256 ** 2)), radius=4.0, seed=seed)
    displacement = affine(**field, centre=centre)
    reference = render(pattern, bit_depth=8)
    deformed = render(pattern, displacement, bit_depth=8)
    half = subset // 2
    margin = half + int(np.ceil(max(abs(shift[0]), abs(shift[1])))) + 12
    side = int(np.ceil(np.sqrt(n_points)))
    axis = np.linspace(margin, size - 1 - margin, side).round()
    xs, ys = np.meshgrid(axis, axis)
    points = np.column_stack([xs.ravel(), ys.ravel()])[:n_points]
    truth = np.column_stack(displacement(points[:, 0], points[:, 1]))
    return reference, deformed, points, truth


def _peak_rss_reset():
    try:
        with open("/proc/self/clear_refs", "w") as handle:
            handle.write("5")
        return True
    except OSError:
        return False


def _peak_rss_mb():
    try:
        with open("/proc/self/status") as handle:
            for line in handle:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def _time_best(function, repeat):
    function()  # warm-up: compilation and first-touch allocation are not timed
    reset_ok = _peak_rss_reset()
    best = float("inf")
    result = None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        best = min(best, time.perf_counter() - start)
    return best, result, (_peak_rss_mb() if reset_ok else float("nan"))


def _errors(u, v, ok, truth):
    """RMSE of the valid points, the valid fraction, and how many valid points are more than 0.5 px off."""
    good = ok & np.isfinite(u) & np.isfinite(v)
    if not np.any(good):
        return float("nan"), 0.0, 0
    du = u[good] - truth[good, 0]
    dv = v[good] - truth[good, 1]
    error = np.sqrt(du * du + dv * dv)
    return float(np.sqrt(np.mean(error * error))), float(good.mean()), int(np.sum(error > 0.5))


def _lucas_kanade(reference, deformed, points, guess, levels=0):
    import cv2

    ref8 = reference if reference.dtype == np.uint8 else cv2.normalize(reference, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    def8 = deformed if deformed.dtype == np.uint8 else cv2.normalize(deformed, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    p0 = points.astype(np.float32).reshape(-1, 1, 2)
    p1 = None if guess is None else (points + guess).astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.001)
    flags = 0 if guess is None else cv2.OPTFLOW_USE_INITIAL_FLOW

    def run():
        moved, found, _err = cv2.calcOpticalFlowPyrLK(ref8, def8, p0, None if p1 is None else p1.copy(),
                                                      winSize=(21, 21), maxLevel=levels, criteria=criteria,
                                                      flags=flags)
        displacement = moved.reshape(-1, 2) - points
        return displacement[:, 0], displacement[:, 1], found.ravel().astype(bool)
    return run


def _cases(quick):
    """(label, search, subpixel, radius, guided) rows per job, in print order."""
    seeded = [
        ("icgn (from guess)", "none", "icgn", 0, False),
        ("improved-wso r2 + icgn", "improved-wso", "icgn", 2, False),
        ("icgn2 (from guess)", "none", "icgn2", 0, False),
        ("improved-wso r2 + icgn2", "improved-wso", "icgn2", 2, False),
        ("improved-wso r2 + improved-surface-fit", "improved-wso", "improved-surface-fit", 2, False),
        ("exhaustive r2 + improved-surface-fit", "exhaustive", "improved-surface-fit", 2, False),
        ("improved-wso r2 + surface-fit", "improved-wso", "surface-fit", 2, False),
        ("improved-wso r2 + gradient", "improved-wso", "gradient", 2, False),
        ("improved-wso r2 + newton-raphson", "improved-wso", "newton-raphson", 2, False),
    ]
    unseeded = [
        ("measure: improved-wso + icgn (guided)", "improved-wso", "icgn", UNSEEDED_RADIUS, True),
        ("measure: improved-wso + icgn2 (guided)", "improved-wso", "icgn2", UNSEEDED_RADIUS, True),
        ("measure: fft-cc + icgn (guided)", "fft-cc", "icgn", UNSEEDED_RADIUS, True),
        ("measure: improved-wso + improved-surface-fit", "improved-wso", "improved-surface-fit", UNSEEDED_RADIUS,
         True),
        ("improved-wso r24 + icgn, every point searched", "improved-wso", "icgn", UNSEEDED_RADIUS, False),
        ("coarse-fine r24 + icgn, every point searched", "coarse-fine", "icgn", UNSEEDED_RADIUS, False),
    ]
    if quick:
        return seeded[:5], unseeded[:2]
    return seeded, unseeded


def run_speed_benchmark(*, n_points=10_000, size=1024, repeat=3, quick=False, subset=DEFAULT_SUBSET, seed=0):
    """Print POI/s, RMSE, wrong-but-ok points and peak memory per method, with ratios to OpenCV; return 0."""
    import numba

    from livedic.dic import measure
    from livedic.dic.subpixel import icgn, icgn2

    unseeded_points = UNSEEDED_POINTS
    if quick:
        n_points, size, repeat, unseeded_points = min(n_points, 2_000), min(size, 512), 1, 2_025
    print(f"livedic bench speed: {size}x{size} 8-bit speckle, subset {subset}, "
          f"{os.cpu_count()} CPU cores, numba {numba.__version__} ({numba.config.THREADING_LAYER} threading), "
          f"{platform.machine()}")
    started = time.perf_counter()
    seeded_cases, unseeded_cases = _cases(quick)
    header = (f"{'method':46s} {'POI/s':>10s} {'time s':>8s} {'RMSE px':>9s} {'ok %':>6s} {'wrong ok':>8s} "
              f"{'peak MB':>8s}")
    summaries = []

    def run_job(title, reference, deformed, points, truth, baseline_label, baseline, rows):
        print()
        print(f"{title}: {len(points)} points")
        print(header)
        print("-" * len(header))
        results = []

        def report(label, seconds, result_errors, peak):
            rmse, ok_fraction, wrong = result_errors
            rate = len(points) / seconds
            results.append(dict(method=label, poi_per_s=rate, seconds=seconds, rmse=rmse, ok=ok_fraction,
                                wrong_ok=wrong, peak_mb=peak))
            print(f"{label:46s} {rate:10.0f} {seconds:8.3f} {rmse:9.4f} {100 * ok_fraction:6.1f} {wrong:8d} "
                  f"{peak:8.0f}", flush=True)

        seconds, (u, v, ok), peak = _time_best(baseline, repeat)
        report(baseline_label, seconds, _errors(u, v, ok, truth), peak)
        for label, call in rows:
            seconds, result, peak = _time_best(call, repeat)
            report(label, seconds, _errors(result.u, result.v, result.ok, truth), peak)
        base = results[0]
        print(f"relative to {base['method']} (same run):")
        for row in results[1:]:
            print(f"  {row['method']:46s} {row['poi_per_s'] / base['poi_per_s']:6.2f} x throughput   "
                  f"RMSE {row['rmse'] / base['rmse']:5.2f} x ({row['rmse']:.4f} vs {base['rmse']:.4f} px)")
        summaries.append((title, results))
        return results

    # --- seeded
    reference, deformed, points, truth = make_job(size=size, n_points=n_points, subset=subset, seed=seed)
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, len(points))
    offset = SEEDED_OFFSET_PX * np.sqrt(rng.uniform(0, 1, len(points)))
    guess = truth + np.column_stack([offset * np.cos(angle), offset * np.sin(angle)])
    half = subset // 2
    xs = points[:, 0].astype(np.int64)
    ys = points[:, 1].astype(np.int64)
    ref32 = np.ascontiguousarray(reference, dtype=np.float32)
    def32 = np.ascontiguousarray(deformed, dtype=np.float32)
    prepared = icgn.prepare_reference(ref32, xs, ys, half)
    prepared2 = icgn2.prepare_from(prepared)

    def live_icgn():
        coefficients = icgn.prepare_target(def32)
        return icgn.refine_prepared(prepared, coefficients, guess[:, 0].copy(), guess[:, 1].copy())

    def live_icgn2():
        coefficients = icgn2.prepare_target(def32)
        return icgn2.refine_prepared(prepared2, coefficients, guess[:, 0].copy(), guess[:, 1].copy())

    def seeded_call(search, subpixel, radius):
        return lambda: measure(reference, deformed, points, subset=subset, search=search, subpixel=subpixel,
                               radius=radius, guess=guess, seed=seed)

    live = [("icgn live (reference prepared once)", lambda: _Ok(live_icgn())),
            ("icgn2 live (reference prepared once)", lambda: _Ok(live_icgn2()))]
    seeded = run_job("seeded (guess within 2 px), shift (5.3, -7.6) px", reference, deformed, points, truth,
                     "opencv calcOpticalFlowPyrLK 21x21 L0", _lucas_kanade(reference, deformed, points, guess),
                     live + [(label, seeded_call(search, subpixel, radius))
                               for label, search, subpixel, radius, _ in seeded_cases])
    # --- unseeded
    reference, deformed, points, truth = make_job(size=size, n_points=unseeded_points, subset=subset, seed=seed,
                                                  shift=UNSEEDED_SHIFT)

    def unseeded_call(search, subpixel, radius, guided):
        return lambda: measure(reference, deformed, points, subset=subset, search=search, subpixel=subpixel,
                               radius=radius, seed=seed, guided=guided)

    run_job(f"unseeded (no guess), shift {UNSEEDED_SHIFT} px", reference, deformed, points, truth,
            "opencv calcOpticalFlowPyrLK 21x21 L3 (pyramid)",
            _lucas_kanade(reference, deformed, points, None, levels=3),
            [(label, unseeded_call(search, subpixel, radius, guided))
             for label, search, subpixel, radius, guided in unseeded_cases])
    by_name = {row["method"]: row for row in seeded}
    improved = by_name.get("improved-wso r2 + improved-surface-fit")
    newton = by_name.get("improved-wso r2 + newton-raphson")
    if improved and newton:
        print(f"time ratio improved-surface-fit / newton-raphson (seeded, same run): "
              f"{100 * improved['seconds'] / newton['seconds']:.1f} % (paper: 3.5 %)")
    print(f"total {time.perf_counter() - started:.0f} s")
    return 0


class _Ok:
    """A SubpixelResult seen as a Measurement (``ok`` from its status)."""

    def __init__(self, result):
        self.u, self.v = result.u, result.v
        self.ok = result.status == 0
