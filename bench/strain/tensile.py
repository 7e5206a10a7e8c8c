"""Part b of ``livedic bench strain``: the simulated tensile test tracked as ``livedic run`` tracks it.

Strain fields in and outside the neck against the exact dV/dY, and the extensometers against ISO 9513 class 0.5.
"""

import math
import time
from dataclasses import dataclass

import numpy as np

from livedic.bench.strain.uniform import rms

ISO_ABSOLUTE = 50e-6          # ISO 9513 class 0.5: 50 microstrain ...
ISO_RELATIVE = 0.005          # ... + 0.5 % of the reading
TENSILE_GAUGE_PX = 400.0
TENSILE_WINDOWS = (3, 5, 7, 9)
TRUTH_H = 1e-3


def exact_strain_yy(truth, x, y, h=TRUTH_H):
    """dV/dY at reference points from a truth callable, by central differences of step ``h`` px."""
    return (truth(x, y + h)[1] - truth(x, y - h)[1]) / (2.0 * h)


def iso_tolerance(reading):
    return ISO_ABSOLUTE + ISO_RELATIVE * np.abs(reading)


def _field_rows(model, frame_index, truth, points, step, measurement, subset):
    from livedic.dic.strain import strain_field, strain_window
    x, y = points[:, 0], points[:, 1]
    exact = exact_strain_yy(truth, x, y)
    neck = np.abs(y - model.y_neck) < model.neck_width
    rows = []
    for window in TENSILE_WINDOWS:
        field = strain_field(strain_window(points, window=window, step=step, subset=subset),
                             measurement.u, measurement.v, measurement.ok)
        near_ends = (np.abs(y - model.gauge_top) < field.vsg_px) | (np.abs(y - model.gauge_bottom) < field.vsg_px)
        outside = ~neck & ~near_ends
        error = field.eyy - exact
        ok = field.ok
        rows.append(dict(frame=frame_index, phase=model.state(frame_index)["phase"], window=window,
                         vsg_px=field.vsg_px, neck_points=int(np.sum(ok & neck)),
                         rmse_neck=rms(error[ok & neck]), outside_points=int(np.sum(ok & outside)),
                         rmse_outside=rms(error[ok & outside]), excluded_near_ends=int(np.sum(ok & ~neck & near_ends)),
                         strain_ok=float(ok.mean()), exact_peak=float(np.max(exact[neck])) if neck.any() else float("nan"),
                         exact_outside_mean=float(np.mean(exact[outside])) if outside.any() else float("nan")))
    return rows, exact


def tensile_study(*, quick, say):
    """Part b: the simulated tensile test tracked as ``livedic run`` tracks it."""
    from livedic.dic.strain.extensometer import AXIAL

    test = _prepare_tensile(quick, say)
    extensometer_rows, field_rows, tracked_s, last = _track_tensile(test)
    say(f"  tracking: {1e3 * np.median(tracked_s):.1f} ms per frame (median), "
        f"{len(test.images) - 1} frames; exact e_yy by differences agrees with TensileModel.strain_yy within "
        f"{max(r.get('truth_check', 0.0) for r in field_rows):.1e}")
    _say_field_rows(field_rows, test.stage.windows.window, say)
    summary = _extensometer_summary(extensometer_rows, test, say)
    axial = summary.get(AXIAL)
    verdict = (f"{'MET' if axial and axial['met'] else 'NOT MET'}  target extensometer L >= 400 px within 50 microstrain "
               f"+ 0.5 % of the exact reading over the whole simulated test: axial L0 "
               f"{axial['L0_px'] if axial else float('nan'):.0f} px, max |error|/tolerance "
               f"{axial['max_ratio'] if axial else float('nan'):.2f}" + ("  [quick: 60 frames]" if quick else ""))
    return dict(uri=test.uri, points=len(test.points), step=test.step, roi=test.roi, vsg_px=test.stage.vsg_px,
                field_rows=field_rows, extensometer_rows=extensometer_rows, summary=summary, verdict=verdict,
                last=last, neck=(test.model.y_neck, test.model.neck_width),
                tracking_ms=1e3 * float(np.median(tracked_s)))


@dataclass
class _TensileTest:
    """The rendered test and what ``livedic run`` would place on it: points, P0, the strain stage."""

    uri: str
    frames: int
    images: list
    model: object
    tracking: object
    points: np.ndarray
    roi: tuple
    step: int
    stage: object


def _prepare_tensile(quick, say):
    """Render the simulated test, place the points and the strain stage as ``livedic run`` does; say how."""
    from livedic.acquire.simulator.sources import SyntheticTensileSource
    from livedic.stream.session.config import TrackingConfig
    from livedic.stream.session.p0 import choose_p0
    from livedic.stream.session.points import build_points
    from livedic.stream.stages.strain import StrainConfig

    size, frames = 1024, (60 if quick else 300)
    uri = f"synthetic:tensile?size={size}x{size}&frames={frames}&pace=0"
    source = SyntheticTensileSource(uri)
    started = time.perf_counter()
    source.prepare()
    render_s = time.perf_counter() - started
    model = source.model
    tracking = TrackingConfig()
    with source:
        images = list(source)
    first = images[0].image
    roi = tuple(int(v) for v in source.suggested_roi)
    p0 = choose_p0(first, roi, tracking.subset)
    points, roi, step = build_points(first.shape, roi=roi, step=None, n_points=1000, subset=tracking.subset,
                                     p0=p0.xy)
    stage = StrainConfig(gauge_length=TENSILE_GAUGE_PX).place(points, p0=points[0], roi=roi, step=step,
                                                              subset=tracking.subset)
    say(f"b. simulated tensile test: {uri} ({render_s:.1f} s to render), {len(points):,} points every {step} px "
        f"on the ROI {','.join(str(v) for v in roi)}, P0 ({p0.xy[0]:g}, {p0.xy[1]:g}); tracked frame to frame by "
        f"TrackingConfig().tracker ({tracking.method}); {stage.describe()}")
    say(f"  neck: |Y - {model.y_neck:g}| < {model.neck_width:g} px; outside: the rest, less the points within one "
        f"VSG of the plastic zone's ends (Y = {model.gauge_top:g} and {model.gauge_bottom:g} px, where the strain "
        f"steps from the shoulders' to the gauge's); exact e_yy = dV/dY of the frame's truth, central differences, "
        f"h = {TRUTH_H:g} px")
    return _TensileTest(uri=uri, frames=frames, images=images, model=model, tracking=tracking, points=points,
                        roi=roi, step=step, stage=stage)


def _track_tensile(test):
    """Track every frame; (extensometer rows, field rows at the end of plasticity and at the last frame,
    tracking seconds per frame, the last frame's e_yy profile)."""
    from livedic.dic.strain import strain_field, strain_window

    points, step, stage, subset = test.points, test.step, test.stage, test.tracking.subset
    plastic_end = int(math.floor(test.model.TAU_NECK * (test.frames - 1)))
    tracker = test.tracking.tracker(test.images[0].image, points)
    extensometer_rows, field_rows = [], []
    tracked_s = []
    last = None
    for frame in test.images[1:]:
        t0 = time.perf_counter()
        m = tracker.track(frame.image)
        tracked_s.append(time.perf_counter() - t0)
        _, readings = stage.compute(m.u, m.v, m.ok)
        truth = frame.metadata["truth"]
        extensometer_rows.extend(_extensometer_rows(frame, readings, stage.exact_readings(truth), stage.placed.names))
        if frame.index in (plastic_end, test.frames - 1):
            rows, exact_yy = _field_rows(test.model, frame.index, truth, points, step, m, subset)
            field_rows.extend(rows)
            check = float(np.max(np.abs(exact_yy - test.model.strain_yy(frame.index, points[:, 1]))))
            for row in rows:
                row["truth_check"] = check
            if frame.index == test.frames - 1:
                field = strain_field(strain_window(points, window=stage.windows.window, step=step, subset=subset),
                                     m.u, m.v, m.ok)
                last = dict(y=points[:, 1].copy(), eyy=field.eyy, exact=exact_yy, ok=field.ok)
    return extensometer_rows, field_rows, tracked_s, last


def _extensometer_rows(frame, readings, exact, names):
    """One row per extensometer of ``frame``: measured, exact, error, and the error over its ISO tolerance."""
    rows = []
    for k, name in enumerate(names):
        error = float(readings.eng_strain[k] - exact[k])
        tolerance = float(iso_tolerance(exact[k]))
        rows.append(dict(frame=frame.index, phase=frame.metadata["phase"], name=name,
                         L0_px=float(readings.l0_px[k]), exact=float(exact[k]),
                         measured=float(readings.eng_strain[k]), error=error, tolerance=tolerance,
                         ratio=abs(error) / tolerance if readings.ok[k] else float("nan"),
                         ok=bool(readings.ok[k])))
    return rows


def _say_field_rows(field_rows, default_window, say):
    say(f"  {'frame':>5s} {'phase':8s} {'window':>6s} {'VSG px':>6s} {'neck RMSE':>10s} {'(pts)':>6s} "
        f"{'peak exact':>10s} {'outside RMSE':>12s} {'(pts)':>6s} {'excl.':>5s} {'mean exact':>10s}")
    for r in field_rows:
        default = "  (default window)" if r["window"] == default_window else ""
        say(f"  {r['frame']:5d} {r['phase']:8s} {r['window']:6d} {r['vsg_px']:6g} {r['rmse_neck']:10.2e} "
            f"{r['neck_points']:6d} {r['exact_peak']:10.4f} {r['rmse_outside']:12.2e} {r['outside_points']:6d} "
            f"{r['excluded_near_ends']:5d} {r['exact_outside_mean']:10.4f}{default}")


def _extensometer_summary(extensometer_rows, test, say):
    """Per extensometer over the whole test: worst error over tolerance, lost frames, met or not; said, returned."""
    from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE

    names = test.stage.placed.names
    summary = {}
    say(f"  extensometers over all {len(test.images) - 1} frames, tolerance 50 microstrain + 0.5 % of the exact "
        f"reading (ISO 9513 class 0.5):")
    for name in names:
        mine = [r for r in extensometer_rows if r["name"] == name]
        lost = sum(not r["ok"] for r in mine)
        worst = max(mine, key=lambda r: (r["ratio"] if math.isfinite(r["ratio"]) else -1.0))
        max_error = max(abs(r["error"]) for r in mine if r["ok"])
        final = mine[-1]
        met = lost == 0 and worst["ratio"] <= 1.0
        applies = "target L >= 400 px" if mine[0]["L0_px"] >= 400 else "L < 400 px: outside the target, shown"
        summary[name] = dict(L0_px=mine[0]["L0_px"], max_ratio=worst["ratio"], max_error=max_error, lost_frames=lost,
                             worst_frame=worst["frame"], final_measured=final["measured"], final_exact=final["exact"],
                             met=met)
        say(f"  {name:10s} L0 {mine[0]['L0_px']:6.1f} px: max |error| {1e6 * max_error:6.1f} microstrain, "
            f"max |error|/tolerance {worst['ratio']:.2f} (frame {worst['frame']}, exact {100 * worst['exact']:.3f} %); "
            f"final {100 * final['measured']:.4f} % vs exact {100 * final['exact']:.4f} %; lost frames {lost}: "
            f"{'met' if met else 'NOT met'} ({applies})")
    if AXIAL in names and TRANSVERSE in names:
        final = {r["name"]: r for r in extensometer_rows if r["frame"] == test.frames - 1}
        measured = -final[TRANSVERSE]["measured"] / final[AXIAL]["measured"]
        exact = -final[TRANSVERSE]["exact"] / final[AXIAL]["exact"]
        say(f"  contraction ratio -e_transverse/e_axial at the last frame (plastic: not Poisson's ratio): {measured:.4f} "
            f"(exact readings {exact:.4f})")
    return summary
