"""The measurements behind ``livedic bench paper``: image pairs, runs and raw numbers.

Nothing here plots or writes files; every function returns plain dicts/lists of
numbers that ``bench.paper.figures`` draws and ``bench.paper.report`` writes.
Everything is seeded: the same configuration gives the same numbers (timings aside).
"""

import importlib
import time
import zlib

import numpy as np

# Integer searches compared in Figs 9/10, in the paper's order; "exhaustive" is the reference.
SEARCHES = ("coarse-fine", "pso", "wso", "improved-wso")
REFERENCE_SEARCH = "exhaustive"
# Sub-pixel methods compared in Figs 11/12 and Table 1.
QUANTISATION_SD = 1.0 / np.sqrt(12.0)
SUBPIXELS = ("surface-fit", "gradient", "newton-raphson", "improved-surface-fit", "icgn", "icgn2")
SUBPIXEL_MODULES = {
    "surface-fit": "livedic.dic.subpixel.surface_fit",
    "gradient": "livedic.dic.subpixel.gradient_method",
    "newton-raphson": "livedic.dic.subpixel.newton_raphson",
    "improved-surface-fit": "livedic.dic.subpixel.improved_surface_fit",
    "icgn": "livedic.dic.subpixel.icgn",
    "icgn2": "livedic.dic.subpixel.icgn2",
}
LABELS = {
    "exhaustive": "exhaustive",
    "coarse-fine": "coarse-fine",
    "pso": "PSO",
    "wso": "WSO (original)",
    "improved-wso": "improved WSO",
    "surface-fit": "surface fit",
    "gradient": "gradient",
    "newton-raphson": "Newton-Raphson",
    "improved-surface-fit": "improved surface fit",
    "icgn": "IC-GN",
    "icgn2": "IC-GN2",
}


def subpixel_module(name):
    return importlib.import_module(SUBPIXEL_MODULES[name])


def noise_seed(*key):
    """A stable 31-bit seed for a tuple key (the same on every machine and run)."""
    return zlib.crc32(repr(key).encode()) & 0x7FFFFFFF


def grid_points(lo, hi, step):
    """(N, 2) float (x, y) points every ``step`` px over [lo, hi]^2, centred in that span."""
    span = hi - lo
    count = span // step + 1
    start = lo + (span - (count - 1) * step) // 2
    axis = start + step * np.arange(count)
    xs, ys = np.meshgrid(axis, axis)
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64)


class Images:
    """Speckle patterns and rendered image pairs of one configuration (cached)."""

    def __init__(self, cfg):
        self.cfg = cfg
        self._patterns = {}
        self._clean = {}

    def pattern(self, index):
        if index not in self._patterns:
            from livedic.dic.speckle import SpecklePattern
            size = self.cfg.image_size
            self._patterns[index] = SpecklePattern((size, size), n_speckles=self.cfg.n_speckles,
                                                   radius=self.cfg.speckle_radius, seed=self.cfg.seed + index)
        return self._patterns[index]

    def render(self, index, displacement, sigma, key):
        """One image of pattern ``index`` in 8-bit grey levels; ``key`` seeds its noise (unused when sigma == 0).

        ``cfg.bit_depth`` None: exact float intensities on the 8-bit grey scale
        (the pattern's single factor, brightest reference pixel at 80 % of 255),
        noise added unrounded; 8/12/16: the simulator's rounded integer images.
        """
        from livedic.dic.speckle import render
        pattern = self.pattern(index)
        cache_key = (index, displacement)
        if sigma == 0 and cache_key in self._clean:
            return self._clean[cache_key]
        seed = noise_seed(self.cfg.seed, *key) if sigma else 0
        if self.cfg.bit_depth is None:
            scale = pattern.grey_scale(8)
            image = render(pattern, displacement, bit_depth=None, noise_sigma=sigma / scale, noise_seed=seed) * scale
        else:
            image = render(pattern, displacement, bit_depth=self.cfg.bit_depth, noise_sigma=sigma, noise_seed=seed)
        if sigma == 0:
            self._clean[cache_key] = image
        return image

    def pair(self, index, displacement, sigma, key):
        """(reference, deformed) with independent noise on each image."""
        reference = self.render(index, None, sigma, key + ("reference",))
        deformed = self.render(index, tuple(float(c) for c in displacement), sigma, key + ("deformed",))
        return reference, deformed

    def forget_clean(self):
        """Drop cached noise-free deformed images (references are kept)."""
        for key in [key for key in self._clean if key[1] is not None]:
            del self._clean[key]


def _timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


class Guard:
    """Runs method calls; a method that raises is recorded once and skipped from then on.

    A missing or broken method must not stop the other methods' measurements:
    its error goes to the report instead.
    """

    def __init__(self, log=None):
        self.failed = {}
        self.log = log

    def ok(self, name):
        return name not in self.failed

    def call(self, name, function, /, *args, **kwargs):
        """``(result, seconds)``, or ``(None, nan)`` if method ``name`` failed now or before."""
        if name in self.failed:
            return None, float("nan")
        try:
            return _timed(function, *args, **kwargs)
        except Exception as error:  # noqa: BLE001 - recorded and reported
            self.failed[name] = f"{type(error).__name__}: {error}"
            if self.log:
                self.log(f"  {LABELS.get(name, name)} FAILED, skipped from now on: {self.failed[name]}")
            return None, float("nan")


def _rotated(items, shift):
    shift %= len(items)
    return tuple(items[shift:]) + tuple(items[:shift])


def as_float_image(image):
    return np.ascontiguousarray(image, dtype=np.float32)


# --------------------------------------------------------------------------- warm-up


def warm_up(cfg, log):
    """Compile every numba kernel the timed runs use, on a small pair, so compile time is not timed.

    Returns {method: error} for the methods that raised (they are skipped by the runs too).
    """
    from livedic.dic import measure
    from livedic.dic.search import integer_search
    from livedic.dic.speckle import SpecklePattern, render

    start = time.perf_counter()
    pattern = SpecklePattern((96, 96), n_speckles=150, radius=cfg.speckle_radius, seed=12345)
    reference = render(pattern, bit_depth=8)
    deformed = render(pattern, (1.3, 0.7), bit_depth=8)
    noisy = render(pattern, (1.3, 0.7), bit_depth=8, noise_sigma=1.0, noise_seed=1)
    points = grid_points(40, 56, 8)
    guard = Guard(log)
    seconds = {}
    for method in (REFERENCE_SEARCH,) + SEARCHES:
        t0 = time.perf_counter()
        for deformed_image in (deformed, noisy):
            guard.call(method, integer_search, reference, deformed_image, points, method=method, subset=cfg.subset,
                       radius=4, seed=cfg.seed)
        seconds[method] = time.perf_counter() - t0
    start_search = integer_search(reference, deformed, points, method=REFERENCE_SEARCH, subset=cfg.subset, radius=2)
    ref32, def32 = as_float_image(reference), as_float_image(deformed)
    half = cfg.subset // 2
    for name in SUBPIXELS:
        t0 = time.perf_counter()
        guard.call(name, lambda: _refine(subpixel_module(name), ref32, def32, start_search, half))
        guard.call(name, measure, reference, deformed, points, subset=cfg.subset, search="improved-wso",
                   subpixel=name, radius=4, seed=cfg.seed)
        if name == "improved-surface-fit":
            guard.call(name, lambda: _refine(subpixel_module(name), ref32, def32, start_search, half, spacing=0.4))
        seconds[name] = time.perf_counter() - t0
    total = time.perf_counter() - start
    log(f"warm-up (numba compilation or cache load, not timed): {total:.1f} s: "
        + ", ".join(f"{LABELS[m]} {t:.1f}" for m, t in seconds.items()))
    return dict(failed=guard.failed, seconds=seconds, total_s=total)


def _refine(module, ref32, def32, start, half, **options):
    return module.refine(ref32, def32, start.xs.astype(np.int64), start.ys.astype(np.int64),
                         start.u.astype(np.float64), start.v.astype(np.float64),
                         start.status.copy(), half, **options)


# --------------------------------------------------------------------------- Figs 9 and 10


def integer_points(cfg):
    """Fig 9 points: a grid where the whole +-radius search box stays inside the image."""
    half = cfg.subset // 2
    lo = half + cfg.search_radius
    hi = cfg.image_size - 1 - half - cfg.search_radius
    return grid_points(lo, hi, cfg.int_step)


_COMPASS = ((1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1))


def compass_shift(d, index):
    """Integer (u, v) of length about ``d`` in the ``index``-th of eight compass directions.

    Axis directions give (+-d, 0) or (0, +-d); diagonals (+-r, +-r) with r = round(d / sqrt 2).
    """
    cx, cy = _COMPASS[index % len(_COMPASS)]
    step = d if cx == 0 or cy == 0 else max(1, int(round(d / np.sqrt(2.0))))
    return float(cx * step), float(cy * step)


def run_integer(cfg, images, sigma, log):
    """Success rate, time and evaluations of every integer search, per displacement.

    Each displacement magnitude d in ``cfg.int_displacements`` translates each of
    ``cfg.int_patterns`` patterns by an integer shift of about that length in one
    of eight compass directions (``compass_shift``), so every true shift lies
    inside the +-radius box whatever its direction; points on ``integer_points``.
    Returns {"rows": [per (method, d) dict], "points_per_pair": n}.
    """
    from livedic.dic.search import integer_search

    points = integer_points(cfg)
    methods = (REFERENCE_SEARCH,) + SEARCHES
    guard = Guard(log)
    totals = {}
    for k, d in enumerate(cfg.int_displacements):
        t0 = time.perf_counter()
        for p in range(cfg.int_patterns):
            du, dv = compass_shift(d, p)
            reference, deformed = images.pair(p, (du, dv), sigma, ("int", p, d))
            seed = cfg.seed + 1000 * p + k
            kwargs = dict(subset=cfg.subset, radius=cfg.search_radius, seed=seed)
            results = {}
            for method in _rotated(methods, k + p):
                res, elapsed = guard.call(method, integer_search, reference, deformed, points, method=method, **kwargs)
                if res is None:
                    continue
                results[method] = res
                acc = totals.setdefault((method, d), dict(n=0, success=0, truth=0, failed=0, time_s=0.0,
                                                          evaluations=0, calls=0))
                acc["time_s"] += elapsed
            if REFERENCE_SEARCH not in results:
                raise RuntimeError(f"the exhaustive search failed ({guard.failed[REFERENCE_SEARCH]}): "
                                   "nothing to score the other searches against")
            ex = results[REFERENCE_SEARCH]
            valid = ex.status == 0
            for method, res in results.items():
                acc = totals[(method, d)]
                ok = valid & (res.status == 0)
                acc["n"] += int(valid.sum())
                acc["failed"] += int((valid & (res.status != 0)).sum())
                acc["success"] += int((ok & (res.u == ex.u) & (res.v == ex.v)).sum())
                acc["truth"] += int((ok & (np.abs(res.u - du) <= 0.5) & (np.abs(res.v - dv) <= 0.5)).sum())
                acc["evaluations"] += int(res.evaluations[valid].sum())
                acc["calls"] += int(res.calls[valid].sum())
        images.forget_clean()
        done = totals.get(("improved-wso", d))
        note = (f"improved WSO success {100.0 * done['success'] / max(done['n'], 1):.1f} %" if done
                else "improved WSO failed")
        log(f"  d = {d:>2} px: {totals[(REFERENCE_SEARCH, d)]['n']} points, {note} ({time.perf_counter() - t0:.1f} s)")
    rows = []
    for (method, d), acc in totals.items():
        n = max(acc["n"], 1)
        rows.append(dict(sigma=sigma, method=method, displacement=d, n=acc["n"], failed=acc["failed"],
                         success_pct=100.0 * acc["success"] / n, truth_pct=100.0 * acc["truth"] / n,
                         evaluations=acc["evaluations"] / n, calls=acc["calls"] / n,
                         time_s=acc["time_s"], time_ms_per_point=1000.0 * acc["time_s"] / n))
    rows.sort(key=lambda r: (methods.index(r["method"]), r["displacement"]))
    return dict(rows=rows, points_per_pair=int(points.shape[0]), failed_methods=guard.failed)


def cost_summary(rows):
    """Fig 10: per method, mean time and evaluations per point over all displacements, and ratios."""
    out = {}
    for method in (REFERENCE_SEARCH,) + SEARCHES:
        mine = [r for r in rows if r["method"] == method]
        n = sum(r["n"] for r in mine)
        if not n:
            continue
        out[method] = dict(
            n=n,
            time_s=sum(r["time_s"] for r in mine),
            time_ms_per_point=1000.0 * sum(r["time_s"] for r in mine) / n,
            evaluations=sum(r["evaluations"] * r["n"] for r in mine) / n,
            calls=sum(r["calls"] * r["n"] for r in mine) / n,
            success_pct=sum(r["success_pct"] * r["n"] for r in mine) / n,
        )
    for method, entry in out.items():
        for base in ("pso", "coarse-fine"):
            if base in out:
                entry[f"time_vs_{base}"] = entry["time_ms_per_point"] / out[base]["time_ms_per_point"]
                entry[f"evaluations_vs_{base}"] = entry["evaluations"] / out[base]["evaluations"]
    return out


# --------------------------------------------------------------------------- Figs 11, 7, 12 and Table 1


def subpixel_points(cfg, step):
    """Sub-pixel points: a grid keeping subset + start box + interpolation margin inside the image."""
    half = cfg.subset // 2
    reach = half + cfg.start_radius + 4
    return grid_points(reach, cfg.image_size - 2 - reach, step)


def icgn_noise_prediction(reference, points, half, sigma):
    """Predicted noise SD of u per point, two ways, from the noise-free reference's gradients.

    * ``translation``: sqrt(2) sigma / sqrt(sum over the subset of f_x^2), the
      classic formula for a translation-only (zero-order) estimate;
    * ``first_order``: sqrt(2 sigma^2 [H^-1]_uu) with H the 6x6 Gauss-Newton
      Hessian of the first-order shape function (what IC-GN estimates), which
      adds the variance lost to the four displacement-gradient parameters.

    Gradients are central differences; sqrt(2) (and 2) are for independent
    noise of equal sigma on both images.
    """
    image = np.asarray(reference, dtype=np.float64)
    gy, gx = np.gradient(image)
    d = np.arange(-half, half + 1, dtype=np.float64)
    dx, dy = np.meshgrid(d, d)
    translation = np.empty(points.shape[0])
    first_order = np.empty(points.shape[0])
    for i, (x, y) in enumerate(points.astype(np.int64)):
        window = (slice(y - half, y + half + 1), slice(x - half, x + half + 1))
        fx, fy = gx[window], gy[window]
        translation[i] = np.sqrt(2.0) * sigma / np.sqrt(np.sum(fx * fx))
        jac = np.stack([fx, fx * dx, fx * dy, fy, fy * dx, fy * dy]).reshape(6, -1)
        hessian = jac @ jac.T
        first_order[i] = np.sqrt(2.0 * sigma ** 2 * np.linalg.inv(hessian)[0, 0])
    return translation, first_order


def _error_stats(errors_u, errors_v, n_total):
    eu = np.asarray(errors_u, dtype=np.float64)
    ev = np.asarray(errors_v, dtype=np.float64)
    n = int(eu.size)
    if n == 0:
        nan = float("nan")
        return dict(n=0, failed=n_total, mean_u=nan, sd_u=nan, rmse_u=nan, max_abs_u=nan, mean_v=nan, sd_v=nan)
    return dict(n=n, failed=int(n_total - n), mean_u=float(eu.mean()), sd_u=float(eu.std(ddof=1)) if n > 1 else 0.0,
                rmse_u=float(np.sqrt(np.mean(eu ** 2))), max_abs_u=float(np.max(np.abs(eu))),
                mean_v=float(ev.mean()), sd_v=float(ev.std(ddof=1)) if n > 1 else 0.0)


def run_subpixel(cfg, images, sigma, log, *, repeats=1):
    """Figs 11 and 7 and the sub-pixel-stage times of Table 1 at one noise level.

    Each displacement s is the translation (s, 0) along x of ``cfg.sub_patterns``
    patterns. The integer start of every method is the exhaustive-search argmax
    within ``cfg.start_radius`` px (the same start for all methods); then each
    method's ``refine`` runs alone and is timed (best of ``repeats`` per pair).
    """
    from livedic.dic.search import integer_search

    points = subpixel_points(cfg, cfg.sub_step)
    half = cfg.subset // 2
    guard = Guard(log)
    errors = {(m, s): ([], [], 0) for m in SUBPIXELS for s in cfg.sub_displacements}
    per_point = {}
    times = {m: 0.0 for m in SUBPIXELS}
    n_refined = 0
    fit = {}
    fit_targets = [s for s in cfg.sub_displacements if any(abs(s - t) < 1e-9 for t in cfg.fit_displacements)]
    predictions = {}
    # Noise-free integer images still carry rounding noise: uniform, SD 1/sqrt(12) grey level per image.
    prediction_sigma = sigma if sigma > 0 else (QUANTISATION_SD if cfg.bit_depth is not None else 0.0)
    t_all = time.perf_counter()
    for k, s in enumerate(cfg.sub_displacements):
        for p in range(cfg.sub_patterns):
            reference, deformed = images.pair(p, (s, 0.0), sigma, ("sub", p, round(s, 6)))
            start = integer_search(reference, deformed, points, method=REFERENCE_SEARCH, subset=cfg.subset,
                                   radius=cfg.start_radius)
            ref32, def32 = as_float_image(reference), as_float_image(deformed)
            if prediction_sigma > 0 and p not in predictions:
                clean = images.render(p, None, 0.0, ())
                predictions[p] = icgn_noise_prediction(clean, points, half, prediction_sigma)
            best = {m: np.inf for m in SUBPIXELS}
            out = {}
            for r in range(repeats):
                for method in _rotated(SUBPIXELS, k + p + r):
                    res, elapsed = guard.call(method, lambda: _refine(subpixel_module(method), ref32, def32,
                                                                       start, half))
                    if res is not None:
                        best[method] = min(best[method], elapsed)
                        out[method] = res
            n_refined += points.shape[0]
            for method, res in out.items():
                times[method] += best[method]
                ok = res.status == 0
                eu, ev, nt = errors[(method, s)]
                eu.append(res.u[ok] - s)
                ev.append(res.v[ok] - 0.0)
                errors[(method, s)] = (eu, ev, nt + ok.size)
                if method == "icgn":
                    err = np.where(ok, res.u - s, np.nan)
                    per_point.setdefault(s, []).append(err)
            if s in fit_targets:
                _fitting_distances(guard, ref32, def32, start, half, s, cfg.fit_spacings, fit)
        if (k + 1) % max(1, len(cfg.sub_displacements) // 5) == 0 or k + 1 == len(cfg.sub_displacements):
            log(f"  s = {s:.2f} px done ({k + 1}/{len(cfg.sub_displacements)}, {time.perf_counter() - t_all:.1f} s)")
    images.forget_clean()

    rows, fit_rows = _subpixel_rows(errors, fit, sigma)
    times = {m: t for m, t in times.items() if guard.ok(m)}
    result = dict(rows=rows, fit_rows=fit_rows, points_per_pair=int(points.shape[0]), n_refined=n_refined,
                  stage_time_s=times, stage_us_per_point={m: 1e6 * t / max(n_refined, 1) for m, t in times.items()},
                  failed_methods=guard.failed)
    if predictions and per_point:
        result["icgn_noise"] = _noise_check(cfg, per_point, predictions, prediction_sigma)
    return result



def _fitting_distances(guard, ref32, def32, start, half, s, spacings, fit):
    """Fig 7: the improved surface fit at each fitting distance h for displacement ``s``, errors added to ``fit``."""
    for h in spacings:
        res, _ = guard.call("improved-surface-fit", lambda: _refine(
            subpixel_module("improved-surface-fit"), ref32, def32, start, half, spacing=float(h)))
        if res is None:
            break
        ok = res.status == 0
        key = (round(s, 6), round(float(h), 6))
        eu, ev, nt = fit.get(key, ([], [], 0))
        eu.append(res.u[ok] - s)
        ev.append(res.v[ok])
        fit[key] = (eu, ev, nt + ok.size)


def _subpixel_rows(errors, fit, sigma):
    """The error statistics per (method, s) for Fig 11 and per (s, h) for Fig 7, as rows."""
    rows = []
    for (method, s), (eu, ev, nt) in errors.items():
        if not nt:
            continue
        stats = _error_stats(np.concatenate(eu) if eu else [], np.concatenate(ev) if ev else [], nt)
        rows.append(dict(sigma=sigma, method=method, displacement=round(s, 6), **stats))
    rows.sort(key=lambda r: (SUBPIXELS.index(r["method"]), r["displacement"]))
    fit_rows = []
    for (s, h), (eu, ev, nt) in sorted(fit.items()):
        stats = _error_stats(np.concatenate(eu), np.concatenate(ev), nt)
        fit_rows.append(dict(sigma=sigma, displacement=s, spacing=h, **stats))
    return rows, fit_rows

def _noise_check(cfg, per_point, predictions, sigma):
    """Measured IC-GN SD of u per displacement vs the prediction pooled over the same points."""
    pred_u = np.concatenate([predictions[p][0] for p in range(cfg.sub_patterns)])
    pred_first = np.concatenate([predictions[p][1] for p in range(cfg.sub_patterns)])
    rows = []
    for s, parts in sorted(per_point.items()):
        err = np.concatenate(parts)
        ok = np.isfinite(err)
        measured = float(np.std(err[ok], ddof=1))
        predicted = float(np.sqrt(np.mean(pred_u[ok] ** 2)))
        first = float(np.sqrt(np.mean(pred_first[ok] ** 2)))
        rows.append(dict(displacement=round(s, 6), measured_sd=measured, predicted_sd=predicted,
                         ratio=measured / predicted, predicted_first_order_sd=first,
                         ratio_first_order=measured / first, n=int(ok.sum()), failed=int((~ok).sum())))
    measured_all = float(np.sqrt(np.mean([r["measured_sd"] ** 2 for r in rows])))
    predicted_all = float(np.sqrt(np.mean([r["predicted_sd"] ** 2 for r in rows])))
    first_all = float(np.sqrt(np.mean([r["predicted_first_order_sd"] ** 2 for r in rows])))
    return dict(sigma=sigma, rows=rows, measured_sd=measured_all, predicted_sd=predicted_all,
                ratio=measured_all / predicted_all, predicted_first_order_sd=first_all,
                ratio_first_order=measured_all / first_all,
                predicted_sd_per_point_range=(float(pred_u.min()), float(pred_u.max())))


def run_field(cfg, images, sigma, log=None):
    """Fig 12: u over a dense grid of points at the translation (0.5, 0) px, per method."""
    from livedic.dic.search import integer_search

    s = cfg.field_displacement
    points = subpixel_points(cfg, cfg.field_step)
    half = cfg.subset // 2
    reference, deformed = images.pair(0, (s, 0.0), sigma, ("field", 0, s))
    start = integer_search(reference, deformed, points, method=REFERENCE_SEARCH, subset=cfg.subset,
                           radius=cfg.start_radius)
    ref32, def32 = as_float_image(reference), as_float_image(deformed)
    fields = {}
    guard = Guard(log)
    for method in SUBPIXELS:
        res, _ = guard.call(method, lambda: _refine(subpixel_module(method), ref32, def32, start, half))
        if res is not None:
            fields[method] = np.where(res.status == 0, res.u, np.nan)
    axis = np.unique(points[:, 0])
    images.forget_clean()
    return dict(sigma=sigma, displacement=s, axis=axis, points=points, u=fields, failed_methods=guard.failed)


def run_measure_timing(cfg, images, log):
    """Table 1, whole pipeline: ``dic.measure`` (improved-WSO search + each sub-pixel method), noise-free.

    Same pairs and points as the noise-free Fig 11 sweep (every
    ``cfg.measure_every``-th displacement), search radius ``cfg.search_radius``.
    """
    from livedic.dic import measure

    points = subpixel_points(cfg, cfg.sub_step)
    displacements = cfg.sub_displacements[::cfg.measure_every]
    times = {m: 0.0 for m in SUBPIXELS}
    errors = {m: [] for m in SUBPIXELS}
    failed = {m: 0 for m in SUBPIXELS}
    guard = Guard(log)
    n = 0
    for k, s in enumerate(displacements):
        for p in range(cfg.sub_patterns):
            reference, deformed = images.pair(p, (s, 0.0), 0.0, ("sub", p, round(s, 6)))
            n += points.shape[0]
            for method in _rotated(SUBPIXELS, k + p):
                res, elapsed = guard.call(method, measure, reference, deformed, points, subset=cfg.subset,
                                          search="improved-wso", subpixel=method, radius=cfg.search_radius,
                                          seed=cfg.seed + k)
                if res is None:
                    continue
                times[method] += elapsed
                errors[method].append(res.u[res.ok] - s)
                failed[method] += int((~res.ok).sum())
    images.forget_clean()
    out = {}
    for method in SUBPIXELS:
        if not guard.ok(method):
            continue
        err = np.concatenate(errors[method]) if errors[method] else np.array([])
        out[method] = dict(time_s=times[method], us_per_point=1e6 * times[method] / max(n, 1), failed=failed[method],
                           rmse_u=float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan"),
                           max_abs_u=float(np.max(np.abs(err))) if err.size else float("nan"))
    return dict(methods=out, n_points=n, displacements=[round(s, 6) for s in displacements],
                failed_methods=guard.failed)


# --------------------------------------------------------------------------- radius study (beyond the paper)

# Every search, plus the improved WSO as the paper describes it (no pyramid), at growing radii.
RADIUS_SEARCHES = ("exhaustive", "fft-cc", "coarse-fine", "pso", "wso", "improved-wso", "improved-wso (paper)")
# The exhaustive search costs (2r + 1)^2 subset correlations a point: timed on this many points only.
EXHAUSTIVE_SAMPLE = 64
RADIUS_LABELS = {"exhaustive": "exhaustive", "fft-cc": "FFT-CC", "coarse-fine": "coarse-fine", "pso": "PSO",
                 "wso": "WSO (original)", "improved-wso": "improved WSO (pyramid)",
                 "improved-wso (paper)": "improved WSO (paper literal)"}


def run_radius(cfg, log):
    """Success, evaluations and time of every integer search at radii ``cfg.radius_study`` (module notes).

    Per generator, radius and noise level: one image pair of ``cfg.radius_size``
    px shifted by a random direction and a magnitude of 0.2..0.9 x the radius,
    points every ``cfg.radius_step`` px where the whole box fits. Success = the
    integer of the exhaustive search over the same box (computed by FFT-CC, which
    ``tests/dic/search/test_search.py`` shows identical), counted over the points where
    that integer is the true shift rounded (a dot-free subset of a sparse pattern
    has no right answer to find).
    """
    from livedic.bench import patterns
    from livedic.dic.search import integer_search
    from livedic.dic.search.improved_wso import PAPER_LITERAL

    rows = []
    guard = Guard(log)
    for radius in cfg.radius_study:
        t0 = time.perf_counter()
        for g, generator in enumerate(cfg.radius_generators):
            for sigma in (0.0, cfg.noise_sigma):
                rng = np.random.default_rng(noise_seed("radius", radius, g, sigma))
                angle = rng.uniform(0.0, 2.0 * np.pi)
                magnitude = radius * rng.uniform(0.2, 0.9)
                shift = (round(magnitude * np.cos(angle), 3), round(magnitude * np.sin(angle), 3))
                reference, deformed = patterns.pair(generator, (cfg.radius_size,) * 2, shift, noise_sigma=sigma,
                                                    seed=cfg.seed + g)
                half = cfg.subset // 2
                points = grid_points(half + radius + 4, cfg.radius_size - 1 - half - radius - 4, cfg.radius_step)
                kwargs = dict(subset=cfg.subset, radius=radius, seed=cfg.seed + radius)
                truth, _ = guard.call("fft-cc", integer_search, reference, deformed, points, method="fft-cc",
                                      **kwargs)
                if truth is None:
                    continue
                # the true peak is one of the integers next to the shift (which, noise decides near .5)
                real = (truth.status == 0) & (np.abs(truth.u - shift[0]) < 1.0) & (np.abs(truth.v - shift[1]) < 1.0)
                for method in RADIUS_SEARCHES:
                    options = PAPER_LITERAL if method == "improved-wso (paper)" else {}
                    name = method.split(" ")[0]
                    take = (slice(None, None, max(len(points) // EXHAUSTIVE_SAMPLE, 1)) if method == "exhaustive"
                            else slice(None))
                    found, elapsed = guard.call(method, integer_search, reference, deformed, points[take],
                                                method=name, **kwargs, **options)
                    if found is None:
                        continue
                    sel = real[take]
                    hit = sel & (found.status == 0) & (found.u == truth.u[take]) & (found.v == truth.v[take])
                    n = int(sel.sum())
                    rows.append(dict(radius=radius, generator=generator, sigma=sigma, method=method, n=n,
                                     success_pct=100.0 * hit.sum() / max(n, 1), misses=int(n - hit.sum()),
                                     evaluations=float(found.evaluations[sel].mean()) if n else float("nan"),
                                     us_per_point=1e6 * elapsed / len(points[take]), shift_u=shift[0],
                                     shift_v=shift[1]))
        iwso = [r for r in rows if r["radius"] == radius and r["method"] == "improved-wso"]
        worst = min((r["success_pct"] for r in iwso), default=float("nan"))
        log(f"  radius {radius:>2}: {len(cfg.radius_generators)} generators x 2 noise levels, improved WSO lowest "
            f"success {worst:.2f} % ({time.perf_counter() - t0:.1f} s)")
    return dict(rows=rows, failed_methods=guard.failed)


def radius_summary(rows):
    """Per (radius, method): searches, misses, success %, mean evaluations and time over generators and noise."""
    out = []
    for radius in sorted({r["radius"] for r in rows}):
        for method in RADIUS_SEARCHES:
            mine = [r for r in rows if r["radius"] == radius and r["method"] == method]
            n = sum(r["n"] for r in mine)
            if not n:
                continue
            out.append(dict(radius=radius, method=method, n=n, misses=sum(r["misses"] for r in mine),
                            success_pct=100.0 * (n - sum(r["misses"] for r in mine)) / n,
                            lowest_pct=min(r["success_pct"] for r in mine),
                            evaluations=sum(r["evaluations"] * r["n"] for r in mine) / n,
                            us_per_point=float(np.mean([r["us_per_point"] for r in mine]))))
    return out
