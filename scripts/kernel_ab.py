#!/usr/bin/env python3
"""The IC-GN kernel of this checkout against the one of an earlier commit, on the main job's frames, in one run.

Both kernels refine the same points of the same frames from the same start, in turn (pairs, so the machine's
drift cancels); prints per frame the p50 ms of each, the new/old ratio per pair and the largest difference in
u. For changes to ``dic/subpixel/icgn.py`` (docs/guide/performance.md, "The IC-GN kernel's rows"):

    .venv/bin/python scripts/kernel_ab.py --baseline 6f870f3 [--frames 20 100 150 200 280] [--repeats 25]

Runs with 1 numba thread, as ``livedic run``. Needs git (the baseline is read with ``git show``).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
import types

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402  (after the numba thread count)


def baseline_module(revision: str) -> types.ModuleType:
    """``dic/subpixel/icgn.py`` as it was at ``revision``, imported beside today's (its imports are today's)."""
    source = subprocess.run(["git", "show", f"{revision}:dic/subpixel/icgn.py"], check=True, capture_output=True,
                            text=True).stdout
    folder = tempfile.mkdtemp(prefix="icgn-baseline-")
    path = os.path.join(folder, "icgn_baseline.py")
    with open(path, "w") as file:
        file.write(source)
    spec = importlib.util.spec_from_file_location("icgn_baseline", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--baseline", required=True, help="the commit whose kernel is the baseline")
    parser.add_argument("--frames", type=int, nargs="+", default=[20, 100, 150, 200, 280])
    parser.add_argument("--repeats", type=int, default=25)
    args = parser.parse_args()
    from livedic.bench.tracker_cost import main_job, main_job_tracker

    old = baseline_module(args.baseline)
    images, points = main_job(frames=max(args.frames) + 1)
    tracker = main_job_tracker(images[0], points)
    for index in range(1, max(args.frames) + 1):
        if index in args.frames:
            job = tracker.kernel_job()
            y0, y1, x0, x1 = job.window
            window = np.ascontiguousarray(tracker._inner.reference[y0:y1, x0:x1])
            prep = old.prepare_reference(window, job.prep.xs, job.prep.ys, job.prep.half)
            old_job = dataclasses.replace(job, method=types.SimpleNamespace(refine_prepared=old.refine_prepared),
                                          prep=prep)
            coefficients = job.coefficients(images[index])
            new_result, old_result = job.run(coefficients), old_job.run(coefficients)     # compiled, and compared
            times: dict[str, list[int]] = {"new": [], "old": []}
            for _ in range(args.repeats):
                for name, one in (("new", job), ("old", old_job)):
                    started = time.perf_counter_ns()
                    one.run(coefficients)
                    times[name].append(time.perf_counter_ns() - started)
            new_ms, old_ms = np.array(times["new"]) / 1e6, np.array(times["old"]) / 1e6
            both = (new_result.status == 0) & (old_result.status == 0)
            print(f"frame {index}: {args.baseline} p50 {np.median(old_ms):.3f} ms, this checkout p50 "
                  f"{np.median(new_ms):.3f} ms, ratio (pairs, p50) {np.median(new_ms / old_ms):.3f}; max |du| "
                  f"{np.max(np.abs(new_result.u[both] - old_result.u[both])):.1e} px; mean iterations "
                  f"{old_result.iterations.mean():.3f} -> {new_result.iterations.mean():.3f}", flush=True)
        tracker.track(images[index])


if __name__ == "__main__":
    sys.exit(main())
