"""``livedic bench paper``: reproduce the improved-WSO paper's figures, plus noise.

Paper: LI Jun, LEI Zongyu et al., "DIC displacement measurement method based on
the improved white shark optimizer", *Laser Technology* 49(3):368 (2025),
DOI 10.7510/jgjs.issn.1001-3806.2025.03.008 (text: shared/seed/improved-wso-dic-paper.md).

What is reproduced, on Zhou-Goodson simulated speckle (256 x 256 px, 1000
speckles, R = 4 px, 8-bit; deformed images are exact, the simulator moves the
speckle centres), subset 21 x 21 px:

* Fig 9  integer-search success rate vs displacement 1..10 px (integer
  shifts of that magnitude in eight compass directions), coarse-fine / PSO /
  WSO / improved WSO, scored against the exhaustive-search argmax over the
  same +-10 px box;
* Fig 10 time and ZNCC evaluations per point of those searches, same run;
* Fig 11 mean error and SD of u vs sub-pixel translation (s, 0), s = 0.05..1 px,
  for surface fit, gradient, Newton-Raphson, improved surface fit, IC-GN and
  IC-GN2 (IC-GN with the 2nd-order shape function, not in the paper), all
  started from the same exhaustive integer argmax;
* Table 1 time of each sub-pixel method on the Fig 11 job: the sub-pixel stage
  alone, and the whole ``dic.measure`` call (improved-WSO search + method);
* Fig 7  improved surface fit error vs fitting distance 0.2..2 px at 0.2, 0.8 px;
* Fig 12 u field at 0.5 px per method;
* noisy variants (Gaussian noise sigma = 2 grey levels on both images,
  independent), which the paper left out, and the accuracy checks of the issue.

Outputs in the results folder: ``figNN_*.png``, a CSV beside each figure,
``results.json`` (every number) and ``report.md``.
"""

import dataclasses
import os
import platform
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

import livedic.bench.paper.figures as figures
import livedic.bench.paper.report as report
import livedic.bench.paper.runs as runs
from livedic.bench.paper.runs import LABELS, SUBPIXELS
from livedic.bench.patterns import GENERATORS


def _steps(start, stop, step):
    count = int(round((stop - start) / step)) + 1
    return tuple(round(start + i * step, 6) for i in range(count))


@dataclass(frozen=True)
class PaperConfig:
    """Everything that sets the size of the benchmark; ``full()``, ``quick()``, ``tiny()``."""

    name: str = "full"
    image_size: int = 256
    n_speckles: int = 1000
    speckle_radius: float = 4.0
    subset: int = 21
    search_radius: int = 10        # the smallest box that holds the largest shift (10 px); the paper states none
    noise_sigma: float = 2.0
    bit_depth: object = 8          # 8: the noise-free 8-bit images; None: exact float on the 8-bit scale
    seed: int = 0
    # Figs 9/10: integer shifts of magnitude d (compass directions) of int_patterns patterns, points every int_step px.
    int_displacements: tuple = tuple(range(1, 11))
    int_patterns: int = 10
    int_step: int = 17
    # Figs 11/7 and Table 1: translations (s, 0) of sub_patterns patterns, points every sub_step px.
    sub_displacements: tuple = _steps(0.05, 1.0, 0.05)
    sub_patterns: int = 3
    sub_step: int = 8
    start_radius: int = 2          # exhaustive integer search radius that gives every method its start
    timing_repeats: int = 3        # sub-pixel stage: best of this many runs per image pair (noise-free)
    measure_every: int = 2         # Table 1 whole-measure timing: every n-th displacement of the sweep
    fit_spacings: tuple = _steps(0.2, 2.0, 0.2)
    fit_displacements: tuple = (0.2, 0.8)
    field_displacement: float = 0.5
    field_step: int = 4
    # Radius study (not in the paper): every search at these radii on six pattern generators.
    radius_study: tuple = (10, 16, 24, 32, 48)
    radius_size: int = 512
    radius_step: int = 7
    radius_generators: tuple = GENERATORS

    @classmethod
    def full(cls):
        return cls()

    @classmethod
    def quick(cls):
        """Every figure and check with about a tenth of the points and coarser sweeps (CI, docs/guide/performance.md)."""
        return cls(name="quick", int_patterns=1, int_step=17, int_displacements=tuple(range(1, 11)),
                   sub_displacements=_steps(0.1, 1.0, 0.1), sub_patterns=1, sub_step=16, timing_repeats=1,
                   measure_every=3, fit_spacings=_steps(0.2, 2.0, 0.6), field_step=8, radius_size=384,
                   radius_step=16, radius_generators=("simulator R=4", "sparse dots"))

    @classmethod
    def tiny(cls):
        """Plumbing check for the tests: every figure and check, a few dozen points each."""
        return cls(name="tiny", int_patterns=1, int_step=51, int_displacements=(1, 4, 7, 10),
                   sub_displacements=(0.2, 0.5, 0.8), sub_patterns=1, sub_step=24, timing_repeats=1,
                   measure_every=3, fit_spacings=(0.2, 1.0, 2.0), field_step=24, radius_study=(10, 32),
                   radius_size=256, radius_step=40, radius_generators=("simulator R=4", "fft-filtered noise"))


def run_paper_benchmark(output_dir, quick=False, *, config=None, log=None):
    """Run every experiment, write figures, CSV/JSON and ``report.md`` into ``output_dir``.

    Parameters
    ----------
    output_dir : str or path
        Results folder (created).
    quick : bool
        ``PaperConfig.quick()`` instead of ``PaperConfig.full()``.
    config : PaperConfig, optional
        Overrides ``quick`` (the tests use ``PaperConfig.tiny()``).
    log : callable, optional
        Progress sink, one line per call (default: print to stdout, flushed).

    Returns
    -------
    int
        0 when every stage ran; 1 when a stage raised (its error is in the
        report and on the console; the other stages still ran). Accuracy checks
        that FAIL are reported in ``report.md``, not in the exit code.
    """
    cfg = config or (PaperConfig.quick() if quick else PaperConfig.full())
    log = log or _print
    os.makedirs(output_dir, exist_ok=True)
    began = time.perf_counter()
    log(f"livedic bench paper ({cfg.name}): results in {output_dir}")
    results = dict(config=_config_dict(cfg), machine=machine_info(), stages={}, errors={})
    stage = _Stages(results, log)
    images = runs.Images(cfg)
    _warm_up(stage, cfg, log)
    _integer_searches(stage, cfg, images, log)
    _radius_study(stage, cfg, log)
    _subpixel_methods(stage, cfg, images, log)
    _measure_timing(stage, cfg, images, log)
    _fields(stage, cfg, images, log)

    log("[figures and report]")
    written = stage("figures", figures.draw_all, results, cfg, output_dir)
    results["figures"] = written or {}
    results["stages"]["total"] = round(time.perf_counter() - began, 2)
    checks = stage("report", report.write_all, results, cfg, output_dir)
    for line in checks or []:
        log(line)
    log(f"done in {time.perf_counter() - began:.0f} s: {os.path.join(output_dir, 'report.md')}")
    if results["errors"]:
        log(f"{len(results['errors'])} stage(s) failed: {', '.join(results['errors'])}")
        return 1
    return 0


class _Stages:
    """Runs one stage at a time into ``results``: timed; an error is logged and recorded, and the others go on."""

    def __init__(self, results, log):
        self.results = results
        self.log = log

    def __call__(self, name, function, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            value = function(*args, **kwargs)
        except Exception as error:  # noqa: BLE001 - reported, the other stages go on
            import traceback
            self.results["errors"][name] = f"{type(error).__name__}: {error}"
            self.log(f"[{name}] FAILED: {type(error).__name__}: {error}")
            self.log("".join(traceback.format_exception(error)).rstrip())
            value = None
        self.results["stages"][name] = round(time.perf_counter() - t0, 2)
        return value

    def keep(self, name, key, function, *args, **kwargs):
        """Run the stage, record the methods that failed in it, keep its value (if any) as ``results[key]``."""
        value = self(name, function, *args, **kwargs)
        for method, error in (value or {}).get("failed_methods", {}).items():
            self.results["errors"][f"{name}: {method}"] = error
        if value is not None:
            self.results[key] = value
        return value


def _sigmas(cfg):
    return (0.0, cfg.noise_sigma)


def _warm_up(stage, cfg, log):
    warm = stage("warm-up", runs.warm_up, cfg, log)
    for method, error in (warm or {}).get("failed", {}).items():
        stage.results["errors"][f"warm-up: {method}"] = error
    stage.results["warm_up_s"] = (warm or {}).get("seconds", {})


def _integer_searches(stage, cfg, images, log):
    for sigma in _sigmas(cfg):
        tag = _noise_tag(sigma)
        log(f"[fig 9/10] integer searches, {tag}")
        value = stage.keep(f"integer {tag}", f"integer_{_key(sigma)}", runs.run_integer, cfg, images, sigma, log)
        if value is not None:
            value["cost"] = runs.cost_summary(value["rows"])
            _log_cost(log, value["cost"])


def _radius_study(stage, cfg, log):
    log(f"[radius study] every search at radii {', '.join(map(str, cfg.radius_study))} px, "
        f"{len(cfg.radius_generators)} pattern generators, noise-free and sigma = {cfg.noise_sigma:g}")
    value = stage.keep("radius study", "radius", runs.run_radius, cfg, log)
    if value is not None:
        value["summary"] = runs.radius_summary(value["rows"])
        for row in value["summary"]:
            log(f"  r = {row['radius']:>2} {runs.RADIUS_LABELS[row['method']]:<28} success {row['success_pct']:7.3f} % "
                f"({row['misses']} misses in {row['n']})  {row['evaluations']:7.1f} evaluations  "
                f"{row['us_per_point']:7.1f} us/pt")


def _subpixel_methods(stage, cfg, images, log):
    for sigma in _sigmas(cfg):
        tag = _noise_tag(sigma)
        repeats = cfg.timing_repeats if sigma == 0 else 1
        log(f"[fig 11/7, table 1] sub-pixel methods, {tag}"
            + (f" (sub-pixel stage timed, best of {repeats})" if sigma == 0 else ""))
        value = stage.keep(f"subpixel {tag}", f"subpixel_{_key(sigma)}", runs.run_subpixel, cfg, images, sigma, log,
                           repeats=repeats)
        if value is not None:
            _log_subpixel(log, value)

    if cfg.bit_depth is not None:
        log("[fig 11 check] sub-pixel methods on exact (unrounded) images, noise-free")
        exact = dataclasses.replace(cfg, bit_depth=None)
        stage.keep("subpixel exact", "subpixel_exact", runs.run_subpixel, exact, runs.Images(exact), 0.0, log,
                   repeats=1)


def _measure_timing(stage, cfg, images, log):
    log("[table 1] whole measure() calls (improved-WSO search + each sub-pixel method), noise-free")
    value = stage.keep("measure timing", "measure_timing", runs.run_measure_timing, cfg, images, log)
    if value is not None:
        nr = value["methods"].get("newton-raphson", {}).get("time_s", float("nan"))
        for method, entry in value["methods"].items():
            log(f"  {LABELS[method]:<22} {entry['time_s']:7.2f} s  ({100 * entry['time_s'] / nr:5.1f} % of N-R)")


def _fields(stage, cfg, images, log):
    for sigma in _sigmas(cfg):
        tag = _noise_tag(sigma)
        log(f"[fig 12] u field at {cfg.field_displacement} px, {tag}")
        stage.keep(f"field {tag}", f"field_{_key(sigma)}", runs.run_field, cfg, images, sigma, log)


def _print(line):
    print(line, flush=True)


def _key(sigma):
    return "clean" if sigma == 0 else "noisy"


def _noise_tag(sigma):
    return "noise-free" if sigma == 0 else f"noise sigma = {sigma:g} grey levels"


def _config_dict(cfg):
    return asdict(cfg)


def _log_cost(log, cost):
    for method, entry in cost.items():
        ratios = "  ".join(f"{entry[f'time_vs_{b}']:.2f}x {LABELS[b]}" for b in ("pso", "coarse-fine")
                           if f"time_vs_{b}" in entry)
        log(f"  {LABELS[method]:<16} success {entry['success_pct']:6.2f} %  {entry['time_ms_per_point']:7.3f} ms/pt  "
            f"{entry['evaluations']:6.1f} distinct / {entry['calls']:6.1f} calls per pt  time {ratios}")


def _log_subpixel(log, value):
    for method in SUBPIXELS:
        rows = [r for r in value["rows"] if r["method"] == method and r["n"]]
        if not rows:
            log(f"  {LABELS[method]:<22} no result")
            continue
        bias = max(abs(r["mean_u"]) for r in rows)
        sd = max(r["sd_u"] for r in rows)
        failed = sum(r["failed"] for r in rows)
        log(f"  {LABELS[method]:<22} max |mean error| {bias:.4f} px  max SD {sd:.4f} px  failed {failed}  "
            f"stage {value['stage_us_per_point'].get(method, float('nan')):8.1f} us/pt")
    if "icgn_noise" in value:
        check = value["icgn_noise"]
        log(f"  IC-GN SD {check['measured_sd']:.4f} px vs predicted {check['predicted_sd']:.4f} px "
            f"(ratio {check['ratio']:.3f})")


def machine_info():
    import numba
    return dict(cpu_count=os.cpu_count(), python=platform.python_version(), numba=numba.__version__,
                numpy=np.__version__, platform=platform.platform(), processor=platform.processor() or platform.machine(),
                numba_threads=numba.get_num_threads(), date=time.strftime("%Y-%m-%d %H:%M:%S %Z"),
                argv=" ".join(sys.argv[:1] + [a for a in sys.argv[1:]]))


__all__ = ["PaperConfig", "run_paper_benchmark"]
