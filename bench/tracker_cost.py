"""``livedic bench tracker``: the tracker's own cost per frame against the bare IC-GN kernel (issue 20, item 3).

It tracks the main job's frames (the simulator ``synthetic:tensile`` 1024x1024, rendered ahead,
delivered unpaced) with the tracker the main job builds (``livedic run --gauge-length 400 --load
synthetic``: its points as ``stream.session.points`` places them, ``TrackingConfig``'s defaults: improved-WSO
seeded search on demand, IC-GN, key-frame updates ``auto``; 1 numba thread as ``livedic run``) and
prints per frame:

* the p50 / p99 of each stage of ``KeyFrameTracker.track`` (``last_timings``, ``dic.TRACKER_STAGES``),
  of "other" (the call's wall time less its stages) and of the whole call;
* the bare kernel: ``refine_prepared`` alone on the same points from the same start
  (``KeyFrameTracker.kernel_job``, taken before each ``track``, run after it on that frame), and the
  prefilter of the same window alone;
* the tracker's p50 over the bare kernel's p50 (the issue's goal: <= 1.5).

``--save FILE.npz`` keeps every frame's result and ``--compare FILE.npz`` checks a run against such a
file bit for bit (exit code 1 if anything differs): a change to the tracker's speed must not change
its numbers. ``--stacks FILE`` reads a py-spy profile (``py-spy record --format raw``) of any livedic
run and prints where the samples inside ``KeyFrameTracker.track`` end (docs/guide/performance.md).
"""

import collections
import re
import time

import numpy as np

FIELDS = ("u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations")
MAIN_JOB_SIZE = 1024
GOAL_RATIO = 1.5


def main_job(size=MAIN_JOB_SIZE, frames=300, n_points=None):
    """(frame images, points) of the main job: the rendered simulated test and its points as the session places them."""
    from livedic.acquire.sources import open_source
    from livedic.stream.session.config import PointsConfig, TrackingConfig
    from livedic.stream.session.points import default_roi, place_points

    source = open_source(f"synthetic:tensile?size={size}x{size}&frames={frames}&pace=0")
    source.prepare()
    images = [frame.image for frame in source]
    source.close()
    wanted = PointsConfig() if n_points is None else PointsConfig(n_points=n_points)
    placement = place_points(images[0], wanted, subset=TrackingConfig.subset, suggested_roi=default_roi(source))
    return images, placement.points


def main_job_tracker(reference, points, **settings):
    """The ``KeyFrameTracker`` the main job's session builds on ``reference`` (``TrackingConfig``'s defaults, but
    ``settings``)."""
    from livedic.stream.session.config import TrackingConfig
    return TrackingConfig(**settings).tracker(reference, points)


def measure_cost(tracker, images):
    """Track ``images`` (after the reference) and time each frame; returns (rows, results).

    rows: one dict per frame: the stages' ns, ``total`` (the call), ``bare_kernel`` and ``bare_prepare``
    (the kernel stage and the window's prefilter run alone on the same frame; None without IC-GN).
    """
    rows, results = [], []
    spare = None                        # the bare prefilter reuses its buffer, as the tracker does
    for image in images[1:]:
        job = tracker.kernel_job()
        started = time.perf_counter_ns()
        result = tracker.track(image)
        total = time.perf_counter_ns() - started
        row = dict(tracker.last_timings, total=total, bare_kernel=None, bare_prepare=None)
        if job is not None:
            started = time.perf_counter_ns()
            spare = job.coefficients(image, spare)
            row["bare_prepare"] = time.perf_counter_ns() - started
            started = time.perf_counter_ns()
            job.run(spare)
            row["bare_kernel"] = time.perf_counter_ns() - started
        rows.append(row)
        results.append({name: getattr(result, name) for name in FIELDS})
    return rows, results


def report(rows, say=print):
    """Print the per-stage table and the tracker / kernel ratio; returns the ratio of the p50s."""
    from livedic.dic import TRACKER_STAGES

    def ms(values):
        values = np.asarray([v for v in values if v is not None], dtype=np.float64) / 1e6
        return (np.percentile(values, 50), np.percentile(values, 99)) if values.size else (np.nan, np.nan)

    columns = {stage: [row[stage] for row in rows] for stage in TRACKER_STAGES}
    columns["other"] = [row["total"] - sum(row[stage] for stage in TRACKER_STAGES) for row in rows]
    columns["total (track)"] = [row["total"] for row in rows]
    columns["bare prefilter"] = [row["bare_prepare"] for row in rows]
    columns["bare kernel"] = [row["bare_kernel"] for row in rows]
    say(f"{len(rows)} frames; ms per frame:        p50      p99")
    for name, values in columns.items():
        p50, p99 = ms(values)
        say(f"  {name:<28} {p50:8.3f} {p99:8.3f}")
    ratio = ms(columns["total (track)"])[0] / ms(columns["bare kernel"])[0]
    say(f"tracker / bare kernel (p50): {ratio:.2f} (goal <= {GOAL_RATIO:g})")
    return ratio


def save_results(path, results):
    """Every frame's result fields into ``path`` (.npz), as ``compare_results`` reads them."""
    arrays = {f"{i}/{name}": values for i, frame in enumerate(results) for name, values in frame.items()
              if values is not None}
    np.savez_compressed(path, **arrays)


def compare_results(path, results):
    """The (frame, field) pairs whose values differ, bit for bit, from those ``save_results`` wrote to ``path``."""
    saved = np.load(path)
    keys = {f"{i}/{name}" for i, frame in enumerate(results) for name, values in frame.items() if values is not None}
    differ = [key for key in sorted(set(saved.files) ^ keys)]
    for key in sorted(keys & set(saved.files)):
        i, name = key.split("/")
        values = np.asarray(results[int(i)][name])
        if saved[key].dtype != values.dtype or saved[key].tobytes() != values.tobytes():
            differ.append(key)
    return differ


def stack_summary(path, say=print, most=12):
    """Where the samples of a py-spy raw profile (``py-spy record --format raw``) inside ``KeyFrameTracker.track``
    end: per function (the innermost Python frame; numba kernels count in the function that called them)."""
    leaves, total = collections.Counter(), 0
    with open(path) as handle:
        for line in handle:
            stack, _, count = line.rstrip().rpartition(" ")
            frames = stack.split(";")
            if not count.isdigit() or any(f.startswith("warm_up ") for f in frames) or \
                    not any(f.startswith("KeyFrameTracker.track ") for f in frames):
                continue
            total += int(count)
            leaves[re.sub(r":\d+\)$", ")", frames[-1])] += int(count)
    if not total:
        say(f"{path}: no samples inside KeyFrameTracker.track")
        return
    say(f"{total} samples inside KeyFrameTracker.track; where they end:")
    for name, count in leaves.most_common(most):
        say(f"  {100.0 * count / total:5.1f} %  {name}")


def run_tracker_benchmark(*, frames=300, size=MAIN_JOB_SIZE, n_points=None, threads=1, save=None, compare=None,
                          say=print, interpolation="bspline3"):
    """``livedic bench tracker``; returns the exit code (1: ``compare`` found a difference). ``interpolation``:
    ``TrackingConfig``'s (``--interpolation``)."""
    import numba
    numba.set_num_threads(threads)
    started = time.perf_counter()
    images, points = main_job(size, frames, n_points)
    warm = main_job_tracker(images[0], points, interpolation=interpolation)
    for image in images[1:4]:          # loads (or compiles) the numba kernels before the timed run
        warm.track(image)
    tracker = main_job_tracker(images[0], points, interpolation=interpolation)
    say(f"{len(images)} frames of {size}x{size} rendered, {tracker.n_points} points, {threads} numba thread(s), "
        f"interpolation {interpolation} "
        f"({time.perf_counter() - started:.1f} s)")
    rows, results = measure_cost(tracker, images)
    report(rows, say)
    if save:
        save_results(save, results)
    if compare:
        differ = compare_results(compare, results)
        say(f"results against {compare}: " + ("identical bit for bit" if not differ else
                                               f"{len(differ)} differ, first: {differ[0]}"))
        return 1 if differ else 0
    return 0
