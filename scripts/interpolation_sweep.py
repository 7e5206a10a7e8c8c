#!/usr/bin/env python3
"""Interpolant x pre-filter sweep on images livedic did not make: the numbers behind the default (issue 23).

For each (``--interpolation``, ``--prefilter``) pair, DIC Challenge 1.0 Sample 3 (all 11 shifts, grid 10, subset
21, icgn: ``bench.accuracy.run_sample3``) gives

* ``worst |bias| u, v``: the largest |mean of (measured - truth)| over the shifts, per component;
* ``mean SD u, v``: ``bench accuracy``'s SD (per shift, the SD with ddof 1 of measured - truth over the ok points
  of the grid), averaged over the 11 shifts;
* ``SD 0/1`` and ``SD .5``: the same SD (u and v pooled, RMS) at the integer shifts 0.0 and 1.0, where the
  interpolant makes no bias (the SD there is the images' noise), and at 0.4-0.6, where the interpolation bias
  is largest; ``bias share``: the part of the variance at 0.4-0.6 the noise does not explain,
  ``1 - SD0/1^2 / SD.5^2``: how much of the per-point SD is the bias's dependence on the local pattern.

then, for the ``--finalists``, Star 1/2 of the DIC Challenge 2.0 (subset 21, icgn: ``bench.accuracy.run_stars``):
the period at 10 % amplitude error, Star 2's noise and their product (MEI).

    .venv/bin/python scripts/interpolation_sweep.py --data ../shared/datasets [--finalists bspline3/none ...]
        [--step 2] [--only-finalists] [--pairs bspline7/none ...] [-o sweep.json]

A pair is ``NAME/FILTER`` (``bspline5/gaussian:0.5``). Runs on 1 numba thread unless NUMBA_NUM_THREADS says.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402  (after the numba thread count)

SWEEP = ([("bspline3", f) for f in ("none", "gaussian:0.5", "gaussian:0.6", "gaussian:0.7", "gaussian:0.8",
                                     "gaussian:1")]
         + [("bspline5", f) for f in ("none", "gaussian:0.3", "gaussian:0.4", "gaussian:0.5", "gaussian:0.6")]
         + [("bspline7", f) for f in ("none", "gaussian:0.3", "gaussian:0.4", "gaussian:0.45", "gaussian:0.47",
                                     "gaussian:0.5")])
INTEGER_SHIFTS = (0.0, 1.0)
MIDDLE_SHIFTS = (0.4, 0.5, 0.6)


@dataclass(frozen=True)
class SweepRow:
    """One pair's Sample 3 summary (module notes), px."""
    interpolation: str
    prefilter: str
    worst_u: float
    worst_v: float
    mean_sd_u: float
    mean_sd_v: float
    sd_integer: float
    sd_middle: float
    bias_share: float
    ok_min: int
    points: int


def pooled_sd(rows, shifts) -> float:
    """RMS of the u and v SDs over the rows whose true shift is in ``shifts``."""
    values = [sd for row in rows if any(math.isclose(row.true_u, s) for s in shifts) for sd in (row.sd_u, row.sd_v)]
    return float(np.sqrt(np.mean(np.square(values))))


def summarise(interpolation: str, prefilter: str, rows) -> SweepRow:
    integer, middle = pooled_sd(rows, INTEGER_SHIFTS), pooled_sd(rows, MIDDLE_SHIFTS)
    return SweepRow(interpolation, prefilter, max(abs(r.bias_u) for r in rows), max(abs(r.bias_v) for r in rows),
                    float(np.mean([r.sd_u for r in rows])), float(np.mean([r.sd_v for r in rows])), integer, middle,
                    1.0 - integer ** 2 / middle ** 2, min(r.ok for r in rows), rows[0].points)


def pair(text: str) -> tuple[str, str]:
    from livedic.dic.image_filter import Prefilter
    from livedic.dic.interpolation import Interpolation
    name, slash, filtering = text.partition("/")
    if not slash:
        raise argparse.ArgumentTypeError(f"{text!r}: give NAME/FILTER, e.g. bspline5/gaussian:0.5")
    try:
        return str(Interpolation.parse(name)), str(Prefilter.parse(filtering))
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", required=True, help="folder with dicc1_sample3_translation and dicc2_star")
    parser.add_argument("--finalists", type=pair, nargs="*", default=[],
                        help="NAME/FILTER pairs also run on the Stars (e.g. bspline3/none bspline5/gaussian:0.5)")
    parser.add_argument("--only-finalists", action="store_true", help="Sample 3 for the finalists only")
    parser.add_argument("--pairs", type=pair, nargs="+", help="NAME/FILTER pairs run on Sample 3 instead of the sweep")
    parser.add_argument("--step", type=int, default=2, help="px between points on the Stars' centre row (default 2)")
    parser.add_argument("-o", "--output", help="also write the numbers as JSON")
    args = parser.parse_args()
    from livedic.bench.accuracy import check_data, run_sample3, run_stars
    try:
        check_data(args.data)
    except ValueError as error:
        print(f"interpolation_sweep: {error}", file=sys.stderr)
        return 2

    quiet = (lambda line: None)
    sample3 = args.pairs if args.pairs else SWEEP
    pairs = list(dict.fromkeys(args.finalists if args.only_finalists else sample3 + args.finalists))
    header = (f"{'interpolation':13s} {'prefilter':13s} {'worst u':>8s} {'worst v':>8s} {'mean SD u':>9s} "
              f"{'mean SD v':>9s} {'SD 0/1':>7s} {'SD .5':>7s} {'bias share':>10s} {'ok':>9s}")
    print("DIC Challenge 1.0 Sample 3, grid 10, subset 21, icgn; px (module notes)")
    print(header)
    print("-" * len(header))
    sweep = []
    for interpolation, prefilter in pairs:
        started = time.perf_counter()
        row = summarise(interpolation, prefilter, run_sample3(args.data, quiet, interpolation, prefilter))
        sweep.append(row)
        print(f"{interpolation:13s} {prefilter:13s} {row.worst_u:8.5f} {row.worst_v:8.5f} {row.mean_sd_u:9.5f} "
              f"{row.mean_sd_v:9.5f} {row.sd_integer:7.5f} {row.sd_middle:7.5f} {row.bias_share:10.2f} "
              f"{f'{row.ok_min}/{row.points}':>9s}  ({time.perf_counter() - started:.0f} s)", flush=True)
    stars = {}
    for interpolation, prefilter in args.finalists:
        print(f"\nStars (subset 21, icgn, every {args.step} px): {interpolation} {prefilter}")
        cases = run_stars(args.data, (21,), ("icgn",), args.step, lambda line: print(line, flush=True),
                          interpolation, prefilter)
        stars[f"{interpolation}/{prefilter}"] = [
            {k: (v.value if hasattr(v, "value") else v) for k, v in asdict(case).items()} for case in cases]
    if args.output:
        with open(args.output, "w") as file:
            json.dump({"sample3": [asdict(row) for row in sweep], "stars": stars}, file, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
