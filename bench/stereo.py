"""``livedic bench stereo``: stereo DIC against the simulator's exact 3D truth, 2D beside it, and the live rate.

The case (issue 24, item 6): the simulated coupon (``synthetic:stereo``, 1 MP a view, a 25 degree rig 300 mm away)
stretched uniformly to 1 % axial strain (lateral -0.3 %) while it moves ``W0`` = 0.5 mm away from the cameras and
turns 1 degree about its axis; both views tracked by a live stereo session (``stereo:`` of the two views, the
simulator's exact rig as the calibration), against the truth of every material point:

* U, V, W RMSE (mm, left camera frame) over the ok points, the worst frame;
* the extensometers in space (axial ``--gauge-length`` mm and transverse) against the exact uniform strain, the
  worst error over the frames (microstrain), and the surface strain (Green-Lagrange E_yy, E_xx) RMSE at the last
  frame;
* the same extensometers of a 2D session on the left view alone (the same frames, px placed with the rig's nominal
  px/mm): the error stereo removes;
* the live rate: the same pair paced at 25 fps (pairs tracked, dropped, latency p99), and unpaced (pairs a second).

No open stereo code from PyPI is run beside it (pyALDIC-3D and pysdic were not tried yet: docs/guide/stereo.md).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from livedic.acquire.sources import open_source
from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import StrainConfig

STRAIN = 0.01                   # axial engineering strain at the last frame
LATERAL = -0.3 * STRAIN         # the simulator's uniform Poisson's ratio (acquire.simulator.coupon3d.NU_UNIFORM)
W0_MM = 0.5
ROTATION_DEG = 1.0
GAUGE_MM = 15.0
LIVE_FPS = 25.0
GOAL_FPS = 25.0


@dataclass
class _Collector:
    """A session sink keeping what the bench compares: each frame's 3D points and extensometer readings."""
    frames: list[int] = field(default_factory=list)
    displacement: list[np.ndarray] = field(default_factory=list)
    ok: list[np.ndarray] = field(default_factory=list)
    readings: list[Any] = field(default_factory=list)
    strain: Any = None

    def __call__(self, result: Any, stats: Any) -> None:
        self.frames.append(int(result.frame.index))
        points = getattr(result.measurement, "points", None)
        if points is not None:
            self.displacement.append(np.array(points.displacement))
            self.ok.append(np.array(points.ok))
        self.readings.append(result.extensometers)
        self.strain = result.strain


def _view(view: str, size: int, frames: int, *, focal: float, pace: bool, loop: int = 0) -> str:
    return (f"synthetic:stereo?view={view}&frames={frames}&size={size}x{size}&focal={focal:g}&strain={STRAIN:g}"
            f"&neck=0&w0={W0_MM:g}&roty={ROTATION_DEG:g}&fps={LIVE_FPS:g}&pace={int(pace)}"
            + (f"&loop={loop}" if loop else ""))


def _session(source: str, gauge: StrainConfig, sink: _Collector | None = None) -> Session:
    config = SessionConfig(source=source, viewer=ViewerConfig("none"), record=None, strain=gauge, static_frames=0)
    session = Session(config, sinks=[sink] if sink is not None else [])
    with session:
        session.prepare()
        session.start()
        session.run()
    return session


def _extensometer_errors(readings: list[Any], frames: list[int], last: int, names: tuple[str, ...]) -> dict[str, float]:
    """Worst |reading - exact uniform strain| per extensometer over the frames (microstrain)."""
    exact = {AXIAL: STRAIN, TRANSVERSE: LATERAL}
    worst = {name: 0.0 for name in names}
    for frame, reading in zip(frames, readings):
        if reading is None:
            continue
        tau = frame / last
        for name in names:
            i = reading.names.index(name)
            if reading.ok[i]:
                worst[name] = max(worst[name], 1e6 * abs(float(reading.eng_strain[i]) - exact[name] * tau))
    return worst


def accuracy_case(size: int, frames: int, focal: float) -> dict[str, Any]:
    """The stereo session and the 2D one on the same left frames, against the truth."""
    pair = f"stereo:{_view('left', size, frames, focal=focal, pace=False)},{_view('right', size, frames, focal=focal, pace=False)}"
    collector = _Collector()
    session = _session(pair, StrainConfig(gauge_length=GAUGE_MM), collector)
    tracker = session.loop.tracker
    with open_source(_view("left", size, frames, focal=focal, pace=False)) as left:
        scene = left.scene
        material = scene.material_at("left", 0, tracker.match.left)
        rmse = np.zeros(3)
        for frame, displacement, ok in zip(collector.frames, collector.displacement, collector.ok):
            truth = scene.truth(frame, material).displacement_mm
            error = np.sqrt(np.mean((displacement[ok] - truth[ok]) ** 2, axis=0))
            rmse = np.maximum(rmse, error)
        last_truth = scene.truth(collector.frames[-1], material).strain
    names = (AXIAL, TRANSVERSE)
    stereo_errors = _extensometer_errors(collector.readings, collector.frames, frames - 1, names)
    strain = collector.strain
    ok = strain.ok & np.all(np.isfinite(last_truth), axis=1)
    surface = {"E_yy_rmse": float(np.sqrt(np.mean((strain.eyy[ok] - last_truth[ok, 1]) ** 2))),
               "E_xx_rmse": float(np.sqrt(np.mean((strain.exx[ok] - last_truth[ok, 0]) ** 2))),
               "E_yy_mean": float(np.mean(strain.eyy[ok])), "E_yy_truth": float(np.mean(last_truth[ok, 1]))}
    # 2D: the left view alone, the extensometers placed in px at the rig's nominal scale, read in px
    from livedic.stream.stages.stereo_strain import nominal_px_per_mm
    scale = nominal_px_per_mm(tracker.calibration)
    flat = _Collector()
    _session(_view("left", size, frames, focal=focal, pace=False), StrainConfig(gauge_length=GAUGE_MM, scale=scale),
             flat)
    flat_errors = _extensometer_errors(flat.readings, flat.frames, frames - 1, names)
    summary = session.summary()
    return {"size": size, "frames": frames, "points": summary["points"], "ok_last": summary["stereo"]["last"]["ok"],
            "uvw_rmse_mm": rmse.tolist(), "extensometer_error_3d_microstrain": stereo_errors,
            "extensometer_error_2d_microstrain": flat_errors, "surface_strain": surface,
            "match_s": summary["stereo"]["match"]["match_s"]}


def live_case(size: int, frames: int, focal: float, loop: int) -> dict[str, Any]:
    """The pair paced at ``LIVE_FPS`` (drops, latency) and unpaced (pairs a second)."""
    out = {}
    for paced in (True, False):
        pair = (f"stereo:{_view('left', size, frames, focal=focal, pace=paced, loop=loop)},"
                f"{_view('right', size, frames, focal=focal, pace=paced, loop=loop)}")
        summary = _session(pair, StrainConfig(gauge_length=GAUGE_MM)).summary()
        pairing = summary["stereo"].get("pairing") or {}
        out["paced" if paced else "unpaced"] = {
            "tracked": summary["frames"], "acquired": summary["acquired"], "dropped": summary["dropped"],
            "pairs_dropped": pairing.get("pairs_dropped"), "fps": summary["fps"],
            "latency_p99_ms": summary.get("latency_p99_ms"), "tracking_p50_ms": summary["processing_p50_ms"],
            "points": summary["points"]}
    return out


def run_stereo_benchmark(*, quick: bool = False, output: str | None = None) -> int:
    """Print the tables (and write ``output`` JSON); exit code 0 (the figures are the result, the goals said)."""
    size, frames, focal = (512, 8, 4000.0) if quick else (1024, 30, 8000.0)
    started = time.perf_counter()
    accuracy = accuracy_case(size, frames, focal)
    live = live_case(size, 40 if quick else 100, focal, loop=8 if quick else 20)
    print(f"livedic bench stereo: {size}x{size} a view, {frames} frames, 25 degree rig at 300 mm (focal {focal:g} px), "
          f"{100 * STRAIN:g} % axial strain, W0 {W0_MM} mm away, {ROTATION_DEG:g} degree turn; "
          f"{accuracy['points']} points ({accuracy['ok_last']} ok in 3D at the last frame)")
    u, v, w = accuracy["uvw_rmse_mm"]
    print(f"  U, V, W RMSE (worst frame)   {1e3 * u:.2f}, {1e3 * v:.2f}, {1e3 * w:.2f} um")
    print(f"  extensometer error (worst)   in space: axial {accuracy['extensometer_error_3d_microstrain'][AXIAL]:.0f}, "
          f"transverse {accuracy['extensometer_error_3d_microstrain'][TRANSVERSE]:.0f} microstrain;  "
          f"2D (left view alone): axial {accuracy['extensometer_error_2d_microstrain'][AXIAL]:.0f}, "
          f"transverse {accuracy['extensometer_error_2d_microstrain'][TRANSVERSE]:.0f} microstrain")
    surface = accuracy["surface_strain"]
    print(f"  surface strain (last frame)  E_yy RMSE {1e6 * surface['E_yy_rmse']:.0f}, E_xx RMSE "
          f"{1e6 * surface['E_xx_rmse']:.0f} microstrain; mean E_yy {100 * surface['E_yy_mean']:.4f} % "
          f"(truth {100 * surface['E_yy_truth']:.4f} %)")
    paced, unpaced = live["paced"], live["unpaced"]
    verdict = "met" if paced["dropped"] == 0 and unpaced["fps"] >= GOAL_FPS else "NOT met"
    print(f"  live, paced at {LIVE_FPS:g} fps        {paced['tracked']} of {paced['acquired']} pairs tracked, "
          f"{paced['dropped']} dropped by the queue, {paced['pairs_dropped']} unpaired; latency p99 "
          f"{paced['latency_p99_ms']:.1f} ms; tracking p50 {paced['tracking_p50_ms']:.1f} ms a pair")
    print(f"  live, unpaced                {unpaced['fps']:.1f} pairs/s at {unpaced['points']} points "
          f"(goal >= {GOAL_FPS:g} at 2 x 1 MP, 0 mismatched pairs: {verdict})")
    print(f"  ({time.perf_counter() - started:.0f} s; no open stereo code from PyPI compared yet)")
    if output:
        with open(output, "w", encoding="utf-8") as handle:
            json.dump({"accuracy": accuracy, "live": live}, handle, indent=2)
    return 0
