"""The tracker's own cost per frame against the bare IC-GN kernel on the same points (issue 20, item 3).

``python -m livedic.bench.tracker_cost [--frames N] [--threads T]`` tracks the main job's frames
(the simulator ``synthetic:tensile`` 1024x1024, rendered ahead, delivered unpaced) with the tracker the
main job builds (``livedic run --gauge-length 400 --load synthetic``: its points as ``stream.points``
places them, ``TrackingConfig``'s defaults: improved-WSO seeded search on demand, IC-GN, key-frame
updates ``auto``) and prints, per frame:

* the p50 / p99 of each stage of ``KeyFrameTracker.track`` (its ``last_timings``, ``TRACKER_STAGES``),
  of "other" (the call's wall time less the stages) and of the whole call;
* the bare kernel: ``refine_prepared`` alone on the same points from the same start
  (``KeyFrameTracker.kernel_job``, taken before each ``track``, run after it on that frame's
  coefficients), and the B-spline prefilter of the same window alone;
* the ratio of the tracker's p50 to the bare kernel's p50 (the issue's goal: <= 1.5).

``--save FILE.npz`` writes every frame's result, ``--compare FILE.npz`` checks this run's results
against such a file bit for bit (exit code 1 if any differs): a change to the tracker's speed must
not change its numbers.
"""

import argparse
import sys
import time

import numpy as np

FIELDS = ("u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations")


def main_job(size=1024, frames=300, n_points=None):
    """(frame images, points) of the main job: the rendered simulated test and its points as the session places them."""
    from livedic.acquire.sources import open_source
    from livedic.stream.config import PointsConfig, TrackingConfig
    from livedic.stream.points import default_roi, place_points

    source = open_source(f"synthetic:tensile?size={size}x{size}&frames={frames}&pace=0")
    source.prepare()
    images = [frame.image for frame in source]
    source.close()
    wanted = PointsConfig() if n_points is None else PointsConfig(n_points=n_points)
    placement = place_points(images[0], wanted, subset=TrackingConfig.subset, suggested_roi=default_roi(source))
    return images, placement.points


def main_job_tracker(reference, points):
    """The ``KeyFrameTracker`` the main job's session builds on ``reference`` (``TrackingConfig``'s defaults)."""
    from livedic.stream.config import TrackingConfig
    return TrackingConfig().tracker(reference, points)


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
    from livedic.dic.tracking import TRACKER_STAGES

    def ms(values):
        values = np.asarray([v for v in values if v is not None], dtype=np.float64) / 1e6
        return (np.percentile(values, 50), np.percentile(values, 99)) if values.size else (np.nan, np.nan)

    columns = {stage: [row[stage] for row in rows] for stage in TRACKER_STAGES}
    columns["other"] = [row["total"] - sum(row[stage] for stage in TRACKER_STAGES) for row in rows]
    columns["total (track)"] = [row["total"] for row in rows]
    columns["bare prefilter"] = [row["bare_prepare"] for row in rows]
    columns["bare kernel"] = [row["bare_kernel"] for row in rows]
    say(f"{len(rows)} frames; ms per frame:       p50      p99")
    for name, values in columns.items():
        p50, p99 = ms(values)
        say(f"  {name:<28} {p50:8.3f} {p99:8.3f}")
    total, kernel = ms(columns["total (track)"])[0], ms(columns["bare kernel"])[0]
    ratio = total / kernel
    say(f"tracker / bare kernel (p50): {ratio:.2f} (goal <= 1.5)")
    return ratio


def save_results(path, results):
    arrays = {f"{i}/{name}": values for i, frame in enumerate(results) for name, values in frame.items()
              if values is not None}
    np.savez_compressed(path, **arrays)


def compare_results(path, results):
    """Frames whose results differ (bit for bit) from those saved in ``path``: a list of (frame, field)."""
    saved = np.load(path)
    differ = []
    for i, frame in enumerate(results):
        for name, values in frame.items():
            key = f"{i}/{name}"
            if values is None and key not in saved.files:
                continue
            if values is None or key not in saved.files or saved[key].dtype != np.asarray(values).dtype or \
                    saved[key].tobytes() != np.asarray(values).tobytes():
                differ.append((i, name))
    return differ


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m livedic.bench.tracker_cost", description=__doc__.split("\n")[0])
    parser.add_argument("--frames", type=int, default=300, metavar="N", help="frames of the simulated test (300)")
    parser.add_argument("--size", type=int, default=1024, metavar="PX", help="image side (1024)")
    parser.add_argument("--points", type=int, metavar="N", help="points wanted (default: the main job's)")
    parser.add_argument("--threads", type=int, default=1, metavar="T", help="numba threads (1, as livedic run)")
    parser.add_argument("--save", metavar="FILE.npz", help="write every frame's result")
    parser.add_argument("--compare", metavar="FILE.npz", help="check the results against a --save file bit for bit")
    args = parser.parse_args(argv)
    import numba
    numba.set_num_threads(args.threads)
    started = time.perf_counter()
    images, points = main_job(args.size, args.frames, args.points)
    warm = main_job_tracker(images[0], points)
    for image in images[1:4]:          # loads (or compiles) the numba kernels before the timed run
        warm.track(image)
    tracker = main_job_tracker(images[0], points)
    print(f"{len(images)} frames of {args.size}x{args.size} rendered, {tracker.n_points} points, "
          f"{args.threads} numba thread(s) ({time.perf_counter() - started:.1f} s)")
    rows, results = measure_cost(tracker, images)
    report(rows)
    if args.save:
        save_results(args.save, results)
    if args.compare:
        differ = compare_results(args.compare, results)
        print(f"results against {args.compare}: " + ("identical bit for bit" if not differ else
                                                       f"{len(differ)} differ, first: frame {differ[0]}"))
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
