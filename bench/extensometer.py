"""``livedic bench extensometer``: the virtual extensometer's class by ISO 9513 from known elongations.

Known motions are rendered exactly (``dic.speckle.render`` of ``dic.speckle.affine``: no image is
interpolated) on a vertical speckle strip just tall enough for the longest gauge length: rigid
translations (zero elongation) and uniform stretches along y (engineering strain e, lateral -0.3 e,
about the strip's centre), each held ``frames_per_step`` frames with independent Gaussian noise, in
increasing order. Between two steps the motion ramps over frames that move no point more than
``MAX_RAMP_PX`` (tracked, not counted), as a live test's load ramps. The frames are tracked as
``livedic run`` tracks (``TrackingConfig().tracker``: KeyFrameTracker, IC-GN, default subset,
reference updates) on points every ``STEP`` px (the spacing ``livedic run`` gives the default simulated
test's ~1,000 points), and every gauge length's axial extensometer, centred on the strip, is read by
``dic.strain.extensometer.read_extensometers`` as the strain stage reads it (its end fit: ``end_fit``,
``livedic run``'s default for the axial unless given). Its elongation readings
(length - L0) against the exact elongation e L0 give, per step, the bias and the resolution (half the
range of the held readings), classified by ``dic.strain.iso9513.classify`` (ISO 9513:2012 Table 2).

The steps are an in-situ assessment in the sense of EN 4861:2020 (known displacements, test
conditions), not an ISO 9513 calibration with a physical apparatus. The images are ideal (exact
speckle, Gaussian noise, no lens distortion, no out-of-plane motion): the class is the upper bound of
what the software achieves; a user's own frames say what the setup achieves.
"""

from __future__ import annotations

import math
import os
import platform
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Any, Callable, Sequence

import numpy as np

from livedic.acquire.simulator.options import DEFAULT_SCALE_PX_PER_MM

DEFAULT_GAUGE_LENGTHS = (100.0, 200.0, 400.0, 600.0)
# Engineering strains of the stretch steps: the small strains where E and Rp0.2 are read, up to the default
# simulated test's (5 % uniform plastic strain, more inside the neck).
DEFAULT_STRAINS = (0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.10)
# Rigid translations (u, v) px: zero elongation, at rest, sub-pixel and over pixels.
ZERO_TRANSLATIONS = ((0.0, 0.0), (0.37, -0.21), (2.6, 1.4))
DEFAULT_FRAMES_PER_STEP = 10
DEFAULT_NOISE = 1.0           # grey levels of an 8-bit image (scaled to the bit depth)
BIT_DEPTHS = (8, 12)
LATERAL = -0.3                # lateral strain per axial strain (elastic Poisson's ratio)
STEP = 14                     # point spacing, px (what livedic run gives the default test's ~1,000 points)
MAX_RAMP_PX = 1.0             # largest motion of any point between two ramp frames
SPECKLE_DENSITY = 1000 / 256 ** 2
SPECKLE_RADIUS = 3.0
FILL = (20.0, 220.0)          # 8-bit grey range of the exact pattern (as bench strain)


def default_test_width() -> float:
    """The default simulated test's gauge width, px (``acquire.simulator``): the band of points an axial
    extensometer's band ends are fitted over in the main job, so the default strip is as wide."""
    from livedic.acquire.simulator.model import TensileModel
    from livedic.acquire.simulator.options import TENSILE_DEFAULTS
    return 2.0 * TensileModel(TENSILE_DEFAULTS["size"], 2).gauge_half


@dataclass(frozen=True)
class Step:
    """One held state: a uniform axial strain about the centre plus a translation (px)."""
    label: str
    strain: float
    translation: tuple[float, float]


def default_steps(strains: Sequence[float] = DEFAULT_STRAINS) -> tuple[Step, ...]:
    """The zero steps (``ZERO_TRANSLATIONS``) then one step per strain, increasing."""
    zeros = tuple(Step(f"rigid {u:g},{v:g} px", 0.0, (u, v)) for u, v in ZERO_TRANSLATIONS)
    return zeros + tuple(Step(f"{100 * e:g} %", float(e), (0.0, 0.0)) for e in sorted(strains))


def _strip(gauge_lengths, steps, subset, width):
    """(image shape, centre (cx, cy), reference points) for the longest gauge length at the largest motion:
    the points reach one fit neighbourhood past the longest extensometer's ends and fill ``width`` px across
    (their subsets inside it, as on a specimen); the image holds their subsets and a re-find search around them."""
    from livedic.dic.search import DEFAULT_RADIUS
    from livedic.dic.strain.extensometer import END_REACH
    longest, largest = max(gauge_lengths), max([0.0, *(s.strain for s in steps)])
    reach = 0.5 * longest + (END_REACH + 1) * STEP
    moved = reach * (1 + largest) + max([0.0, *(abs(t) for s in steps for t in s.translation)])
    margin = subset // 2 + DEFAULT_RADIUS + 4
    half_height = int(math.ceil(moved + margin))
    columns = max(1, int((0.5 * width - subset // 2) // STEP))     # point columns either side of the centre
    half_width = int(math.ceil((columns * STEP) * (1 + abs(LATERAL) * largest) + margin + 3))
    shape = (2 * half_height + 1, 2 * half_width + 1)
    centre = (float(half_width), float(half_height))
    rows = np.arange(-math.floor(reach / STEP), math.floor(reach / STEP) + 1) * STEP + centre[1]
    cols = np.arange(-columns, columns + 1) * STEP + centre[0]
    xx, yy = np.meshgrid(cols, rows)
    return shape, centre, np.column_stack([xx.ravel(), yy.ravel()]).astype(np.float64)


class _Frames:
    """Exact images of one speckle pattern, quantised with independent noise per frame."""

    def __init__(self, shape, centre, *, bit, noise, seed):
        from livedic.dic.speckle import SpecklePattern, render
        self.pattern = SpecklePattern(shape, density=SPECKLE_DENSITY, radius=SPECKLE_RADIUS, seed=seed)
        self.centre = centre
        self.full = (1 << bit) - 1
        self.dtype = np.uint8 if bit == 8 else np.uint16
        self.noise = noise * self.full / 255.0
        reference = render(self.pattern, bit_depth=None)
        self.gain = (FILL[1] - FILL[0]) / np.percentile(reference, 99.5) * self.full / 255.0
        self.offset = FILL[0] * self.full / 255.0
        self.rng = np.random.default_rng(seed + 1)

    def exact(self, strain, translation):
        from livedic.dic.speckle import affine, render
        field = affine(translation[0], translation[1], ux=LATERAL * strain, vy=strain, centre=self.centre)
        return self.offset + self.gain * render(self.pattern, field, bit_depth=None)

    def noisy(self, exact):
        image = exact + self.rng.normal(0.0, self.noise, exact.shape) if self.noise > 0 else exact
        return np.clip(np.floor(image + 0.5), 0, self.full).astype(self.dtype)


def _ramp(previous, step, points, centre):
    """Intermediate (strain, translation) states from ``previous`` to ``step``, none moving a point > MAX_RAMP_PX."""
    arm = np.max(np.abs(points - np.asarray(centre)), axis=0)
    d_strain = step.strain - previous.strain
    d_u = abs(step.translation[0] - previous.translation[0]) + abs(LATERAL * d_strain) * arm[0]
    d_v = abs(step.translation[1] - previous.translation[1]) + abs(d_strain) * arm[1]
    count = int(math.ceil(math.hypot(d_u, d_v) / MAX_RAMP_PX))
    states = []
    for k in range(1, count):
        f = k / count
        states.append((previous.strain + f * d_strain,
                       tuple(a + f * (b - a) for a, b in zip(previous.translation, step.translation))))
    return states


def _axial_extensometers(names, gauge_lengths, centre, points, end_fit):
    """The axial extensometers of the gauge lengths, centred on the strip, placed on its points."""
    from livedic.dic.strain.extensometer import Extensometer, place_extensometers
    return place_extensometers([Extensometer(name, centre[0], centre[1] - 0.5 * length, centre[0],
                                             centre[1] + 0.5 * length, end_fit)
                                for name, length in zip(names, gauge_lengths)], points, step=STEP)


def run_extensometer_bench(*, gauge_lengths: Sequence[float] = DEFAULT_GAUGE_LENGTHS,
                           steps: Sequence[Step] | None = None, frames_per_step: int = DEFAULT_FRAMES_PER_STEP,
                           noise: float = DEFAULT_NOISE, bit: int = 8,
                           scale_px_per_mm: float | None = DEFAULT_SCALE_PX_PER_MM, seed: int = 0,
                           end_fit: str | None = None, width: float | None = None, subpixel: str | None = None,
                           say: Callable[[str], None] = print) -> dict[str, Any]:
    """Render, track and classify; print the table per gauge length; return the JSON-ready result.

    ``width``: the specimen's width, px, the points fill across (None: ``default_test_width``, the main job's);
    ``subpixel``: the tracker's sub-pixel method (None: ``TrackingConfig``'s default, ``livedic run``'s).
    ``end_fit``: how the extensometers' ends are fitted (``dic.strain.extensometer.END_FITS``; None: the axial
    extensometer's default, ``stream.stages.strain.DEFAULT_AXIAL_END_FIT``). ``seed``: the speckle and the noise.

    Returns
    -------
    dict
        ``settings``, ``date``, ``environment``, ``gauge_lengths`` (one entry per L0: ``l0_px``, ``l0_mm``,
        ``met_class``, ``reason``, ``limitations``, ``steps`` with ``label``, ``strain`` and ``readings_px`` beside
        ``dic.strain.iso9513.StepClass.as_dict``), ``lost_points`` (points not ok, summed over counted frames),
        ``seconds``.
    """
    from livedic.dic.strain.extensometer import AXIAL, read_extensometers
    from livedic.stream.session.config import TrackingConfig
    from livedic.stream.stages.strain import DEFAULT_AXIAL_END_FIT

    end_fit = end_fit or DEFAULT_AXIAL_END_FIT
    started = time.perf_counter()
    steps = tuple(steps) if steps is not None else default_steps()
    tracking = TrackingConfig() if subpixel is None else TrackingConfig(subpixel=subpixel)
    width = default_test_width() if width is None else float(width)
    shape, centre, points = _strip(gauge_lengths, steps, tracking.subset, width)
    frames = _Frames(shape, centre, bit=bit, noise=noise, seed=seed)
    names = tuple(f"{AXIAL}_{length:g}" for length in gauge_lengths)
    placed = _axial_extensometers(names, gauge_lengths, centre, points, end_fit)
    tracker = tracking.tracker(frames.noisy(frames.exact(0.0, (0.0, 0.0))), points)
    scale = f"{scale_px_per_mm:g} px/mm" if scale_px_per_mm else "none (relative limits only)"
    say(f"livedic bench extensometer: {shape[1]}x{shape[0]} px strip ({width:g} px specimen width), {len(points)} "
        f"points every {STEP} px, subset {tracking.subset}, {tracking.search}+{tracking.subpixel}, reference update "
        f"{tracking.reference_update}; {bit}-bit, noise {noise:g} grey levels (8-bit scale), {frames_per_step} "
        f"frames per step; {end_fit} ends; seed {seed}; scale {scale}")
    readings = {name: [] for name in names}
    lost_points = 0
    tracked = 0
    previous = Step("reference", 0.0, (0.0, 0.0))
    for step in steps:
        for strain, translation in _ramp(previous, step, points, centre):
            tracker.track(frames.noisy(frames.exact(strain, translation)))
            tracked += 1
        exact = frames.exact(step.strain, step.translation)
        held = {name: [] for name in names}
        for _ in range(frames_per_step):
            m = tracker.track(frames.noisy(exact))
            tracked += 1
            lost_points += int(np.count_nonzero(~m.ok))
            frame = read_extensometers(placed, points, m.u, m.v, m.ok)
            for k, name in enumerate(names):
                held[name].append(float(frame.length_px[k] - frame.l0_px[k]))
        for name in names:
            readings[name].append(np.asarray(held[name]))
        previous = step
    results = [_classified(steps, readings[name], length, scale_px_per_mm) for name, length in
               zip(names, gauge_lengths)]
    from livedic.stream.export.report_verification import verification_table_lines
    for entry in results:
        for line in verification_table_lines(entry):
            say(line)
    seconds = time.perf_counter() - started
    say(f"{tracked} frames tracked ({len(steps)} steps x {frames_per_step} counted, the rest ramps); points not ok "
        f"in counted frames: {lost_points}; {seconds:.0f} s")
    say(_verdict(results))
    return {"settings": {"gauge_lengths_px": list(gauge_lengths), "steps": [s.label for s in steps],
                         "strains": [s.strain for s in steps], "frames_per_step": frames_per_step, "noise": noise,
                         "bit_depth": bit, "scale_px_per_mm": scale_px_per_mm, "subset": tracking.subset,
                         "step_px": STEP, "specimen_width_px": width, "search": tracking.search, "subpixel": tracking.subpixel,
                         "reference_update": tracking.reference_update, "image": [shape[1], shape[0]],
                         "seed": seed, "end_fit": end_fit},
            "date": datetime.now(timezone.utc).isoformat(),
            "environment": {"cpu_count": os.cpu_count(), "machine": platform.machine()},
            "standard": "ISO 9513:2012 Table 2; in-situ known displacements as EN 4861:2020",
            "gauge_lengths": results, "lost_points": lost_points, "seconds": seconds, "verdict": _verdict(results)}


def _classified(steps: Sequence[Step], readings: Sequence[np.ndarray], length: float,
                scale_px_per_mm: float | None) -> dict[str, Any]:
    """One gauge length's ISO 9513 verdict (JSON-ready), each step with its label, strain and readings."""
    from livedic.stream.export.report_verification import classified_entry
    return classified_entry([s.strain * length for s in steps], readings, length, scale_px_per_mm,
                            labels=[s.label for s in steps])


TARGET_L0_PX = 400.0
TARGET_CLASS = "0.5"


def _verdict(results):
    """The issue's target: class 0.5 (or better) at every L0 >= 400 px."""
    from livedic.dic.strain.iso9513 import CLASS_NAMES
    judged = [r for r in results if r["l0_px"] >= TARGET_L0_PX]
    if not judged:
        return f"(no gauge length >= {TARGET_L0_PX:g} px: the class {TARGET_CLASS} target is not judged)"
    met = all(r["met_class"] is not None and CLASS_NAMES.index(r["met_class"]) <= CLASS_NAMES.index(TARGET_CLASS)
              for r in judged)
    classes = ", ".join(f"L0 {r['l0_px']:g} px: {r['met_class'] or 'none'}" for r in judged)
    return f"{'MET' if met else 'NOT MET'}  target ISO 9513 class {TARGET_CLASS} at L0 >= {TARGET_L0_PX:g} px ({classes})"
