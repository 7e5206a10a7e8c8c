"""``livedic bench speed``: points per second per method on one large image pair.

Setup: a 1024x1024 8-bit speckle image (paper density: 1000 speckles per
256x256, radius 4 px), 10,000 points on a grid, subset 21. The deformation is
a rigid shift plus a small homogeneous strain, rendered exactly. Two jobs:

* seeded: every point gets a guess within 2 px of its true displacement (what
  a tracker has from the previous frame); searches use radius 2;
* unseeded: guess (0, 0), search radius 16.

Each method is timed after a warm-up call (numba compilation excluded), best of
``repeat`` runs. OpenCV's pyramidal Lucas-Kanade (21x21 window, no pyramid,
seeded with the same guess) runs on the same points as the familiar baseline.
Peak memory is the process's peak resident set during each method (VmHWM,
reset before each method through /proc/self/clear_refs where the kernel allows).
"""

import os
import platform
import time

import numpy as np

SEEDED_OFFSET_PX = 2.0
UNSEEDED_RADIUS = 16


def make_job(size=1024, n_points=10_000, subset=21, seed=0, shift=(5.3, -7.6)):
    """Reference, deformed, points, true (u, v) per point and the field parameters."""
    from dic.speckle import SpecklePattern, affine, render

    centre = ((size - 1) / 2.0, (size - 1) / 2.0)
    field = dict(u=shift[0], v=shift[1], ux=0.002, uy=0.0005, vx=-0.0005, vy=0.003)
    pattern = SpecklePattern((size, size), n_speckles=int(round(1000 * size * size / 256 ** 2)), radius=4.0, seed=seed)
    displacement = affine(**field, centre=centre)
    reference = render(pattern, bit_depth=8)
    deformed = render(pattern, displacement, bit_depth=8)
    half = subset // 2
    margin = half + UNSEEDED_RADIUS + 12
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
    good = ok & np.isfinite(u) & np.isfinite(v)
    if not np.any(good):
        return float("nan"), 0.0
    du = u[good] - truth[good, 0]
    dv = v[good] - truth[good, 1]
    return float(np.sqrt(np.mean(du * du + dv * dv))), float(good.mean())


def _lucas_kanade(reference, deformed, points, guess):
    import cv2

    ref8 = reference if reference.dtype == np.uint8 else cv2.normalize(reference, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    def8 = deformed if deformed.dtype == np.uint8 else cv2.normalize(deformed, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    p0 = points.astype(np.float32).reshape(-1, 1, 2)
    p1 = (points + guess).astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.001)

    def run():
        moved, found, _err = cv2.calcOpticalFlowPyrLK(ref8, def8, p0, p1.copy(), winSize=(21, 21), maxLevel=0,
                                                      criteria=criteria, flags=cv2.OPTFLOW_USE_INITIAL_FLOW)
        displacement = moved.reshape(-1, 2) - points
        return displacement[:, 0], displacement[:, 1], found.ravel().astype(bool)
    return run


def _cases(quick):
    """(label, job, search, subpixel, radius, extra) rows, in print order."""
    seeded = [
        ("icgn (from guess)", "seeded", "none", "icgn", 0),
        ("improved-wso r2 + icgn", "seeded", "improved-wso", "icgn", 2),
        ("improved-wso r2 + improved-surface-fit", "seeded", "improved-wso", "improved-surface-fit", 2),
        ("exhaustive r2 + improved-surface-fit", "seeded", "exhaustive", "improved-surface-fit", 2),
        ("improved-wso r2 + surface-fit", "seeded", "improved-wso", "surface-fit", 2),
        ("improved-wso r2 + gradient", "seeded", "improved-wso", "gradient", 2),
        ("improved-wso r2 + newton-raphson", "seeded", "improved-wso", "newton-raphson", 2),
    ]
    unseeded = [
        ("improved-wso r16 + improved-surface-fit", "unseeded", "improved-wso", "improved-surface-fit", UNSEEDED_RADIUS),
        ("improved-wso r16 + icgn", "unseeded", "improved-wso", "icgn", UNSEEDED_RADIUS),
        ("pso r16 + icgn", "unseeded", "pso", "icgn", UNSEEDED_RADIUS),
        ("coarse-fine r16 + icgn", "unseeded", "coarse-fine", "icgn", UNSEEDED_RADIUS),
    ]
    if quick:
        return seeded[:3] + unseeded[:1]
    return seeded + unseeded


def run_speed_benchmark(*, n_points=10_000, size=1024, repeat=3, quick=False, subset=21, seed=0):
    """Print POI/s, RMSE and peak memory per method; return 0."""
    import numba

    from dic import measure
    from dic.subpixel import icgn

    if quick:
        n_points, size, repeat = min(n_points, 2_000), min(size, 512), 1
    print(f"livedic bench speed: {size}x{size} 8-bit speckle, {n_points} points, subset {subset}, "
          f"{os.cpu_count()} CPU cores, numba {numba.__version__} ({numba.config.THREADING_LAYER} threading), "
          f"{platform.machine()}")
    started = time.perf_counter()
    reference, deformed, points, truth = make_job(size=size, n_points=n_points, subset=subset, seed=seed)
    print(f"images rendered in {time.perf_counter() - started:.1f} s")
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, len(points))
    offset = SEEDED_OFFSET_PX * np.sqrt(rng.uniform(0, 1, len(points)))
    seeded_guess = truth + np.column_stack([offset * np.cos(angle), offset * np.sin(angle)])
    guesses = {"seeded": seeded_guess, "unseeded": np.zeros_like(truth)}

    rows = []
    header = f"{'method':44s} {'job':9s} {'POI/s':>10s} {'time s':>8s} {'RMSE px':>9s} {'ok %':>6s} {'peak MB':>8s}"
    print(header)
    print("-" * len(header))

    def report(label, job, seconds, rmse, ok_fraction, peak):
        rate = len(points) / seconds
        rows.append(dict(method=label, job=job, poi_per_s=rate, seconds=seconds, rmse=rmse, ok=ok_fraction, peak_mb=peak))
        print(f"{label:44s} {job:9s} {rate:10.0f} {seconds:8.3f} {rmse:9.4f} {100 * ok_fraction:6.1f} {peak:8.0f}", flush=True)

    lk_seconds, (lk_u, lk_v, lk_ok), lk_peak = _time_best(
        _lucas_kanade(reference, deformed, points, seeded_guess), repeat)
    report("opencv calcOpticalFlowPyrLK 21x21 L0", "seeded", lk_seconds, *_errors(lk_u, lk_v, lk_ok, truth), lk_peak)

    half = subset // 2
    xs = points[:, 0].astype(np.int64)
    ys = points[:, 1].astype(np.int64)
    ref32 = np.ascontiguousarray(reference, dtype=np.float32)
    def32 = np.ascontiguousarray(deformed, dtype=np.float32)
    prepared = icgn.prepare_reference(ref32, xs, ys, half)

    def live_icgn():
        coefficients = icgn.prepare_target(def32)
        return icgn.refine_prepared(prepared, coefficients, seeded_guess[:, 0].copy(), seeded_guess[:, 1].copy())
    seconds, result, peak = _time_best(live_icgn, repeat)
    report("icgn live (reference prepared once)", "seeded", seconds,
           *_errors(result.u, result.v, result.status == 0, truth), peak)

    for label, job, search, subpixel, radius in _cases(quick):
        guess = guesses[job]
        def call(search=search, subpixel=subpixel, radius=radius, guess=guess):
            return measure(reference, deformed, points, subset=subset, search=search, subpixel=subpixel,
                           radius=radius, guess=guess, seed=seed)
        seconds, result, peak = _time_best(call, repeat)
        report(label, job, seconds, *_errors(result.u, result.v, result.ok, truth), peak)

    by_name = {row["method"]: row for row in rows}
    lk = by_name["opencv calcOpticalFlowPyrLK 21x21 L0"]
    print()
    print("throughput relative to OpenCV Lucas-Kanade on the same points (same run):")
    for row in rows[1:]:
        print(f"  {row['method']:44s} {row['poi_per_s'] / lk['poi_per_s']:6.2f} x   RMSE {row['rmse']:.4f} px vs LK {lk['rmse']:.4f} px")
    improved = by_name.get("improved-wso r2 + improved-surface-fit")
    newton = by_name.get("improved-wso r2 + newton-raphson")
    if improved and newton:
        print(f"time ratio improved-surface-fit / newton-raphson (seeded, same run): "
              f"{100 * improved['seconds'] / newton['seconds']:.1f} % (paper: 3.5 %)")
    print(f"total {time.perf_counter() - started:.0f} s")
    return 0
