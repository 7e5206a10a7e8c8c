#!/usr/bin/env python3
"""The tracker's cost per frame under several ``--interpolation``/``--prefilter`` settings, on the same frames, in
one run (interleaved, so the shared machine's drift cancels in the ratios).

The main job (``bench.tracker_cost.main_job``: ``synthetic:tensile`` 1024x1024, the session's points) is tracked
once per setting by the tracker ``TrackingConfig`` builds with it; per frame, the settings take turns for

* ``track``: ``KeyFrameTracker.track`` on the raw frame (the image pre-filter, the window's B-spline prefilter, the
  kernel, the gates: the whole cost of a frame when nothing is made ahead);
* ``ahead``: ``coefficients_ahead`` alone (what a live session moves to its acquisition thread: the pre-filter and
  the window's B-spline prefilter);
* ``kernel``: the IC-GN kernel alone on those coefficients, ``--repeats`` times (p50).

Prints each setting's p50 ms and, against the first setting, the median of the per-frame ratios:

    .venv/bin/python scripts/interpolant_ab.py --settings bspline3/none bspline5/gaussian:0.6 [--frames 40]

1 numba thread, as ``livedic run``. Settings are ``NAME/FILTER`` (``scripts/interpolation_sweep.py``'s form).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402  (after the numba thread count)

PARTS = ("track", "ahead", "kernel")


def timed(call) -> tuple[int, object]:
    started = time.perf_counter_ns()
    value = call()
    return time.perf_counter_ns() - started, value


def main() -> int:
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from interpolation_sweep import pair

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--settings", type=pair, nargs="+", required=True, help="NAME/FILTER pairs; the first is "
                                                                                  "the baseline of the ratios")
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    from livedic.bench.tracker_cost import main_job, main_job_tracker

    images, points = main_job(frames=args.frames + 1)
    trackers = []
    for interpolation, prefilter in args.settings:
        warm = main_job_tracker(images[0], points, interpolation=interpolation, prefilter=prefilter)
        for image in images[1:4]:                       # loads (or compiles) the kernels before the timed run
            warm.track(image)
        trackers.append(main_job_tracker(images[0], points, interpolation=interpolation, prefilter=prefilter))
    print(f"{args.frames} frames of {images[0].shape[1]}x{images[0].shape[0]}, {trackers[0].n_points} points, "
          f"1 numba thread; ms per frame (p50), ratio = median over frames of setting / first setting")
    ns = {(s, part): [] for s in range(len(trackers)) for part in PARTS}
    for frame, image in enumerate(images[1:]):
        order = range(len(trackers)) if frame % 2 == 0 else reversed(range(len(trackers)))
        for s in order:
            tracker = trackers[s]
            job = tracker.kernel_job()
            ahead_ns, ahead = timed(lambda: tracker.coefficients_ahead(image))
            kernel = [timed(lambda: job.run(ahead.coefficients))[0] for _ in range(args.repeats)] if job else [0]
            ns[s, "ahead"].append(ahead_ns)
            ns[s, "kernel"].append(float(np.median(kernel)))
            ns[s, "track"].append(timed(lambda: tracker.track(image))[0])
    print(f"{'setting':28s} " + " ".join(f"{part + ' ms':>9s} {'ratio':>6s}" for part in PARTS))
    for s, (interpolation, prefilter) in enumerate(args.settings):
        cells = []
        for part in PARTS:
            values, base = np.asarray(ns[s, part]) / 1e6, np.asarray(ns[0, part]) / 1e6
            cells.append(f"{np.median(values):9.3f} {np.median(values / base):6.2f}")
        print(f"{interpolation + '/' + prefilter:28s} " + " ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
