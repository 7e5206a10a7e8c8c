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

With ``--peer-python PATH`` (the Python of a separate environment where PyPI's ``al-dic-3d`` is installed), pyALDIC-3D
runs on the same rendered reference and last pairs, the same calibration, subset and points
(``bench/peer_aldic3d_runner.py``): its U, V, W RMSE at the last frame beside livedic's at the same frame and points.
Without it the peer is "not installed"; a peer that fails is reported with its own last error line.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from livedic.acquire.sources import open_source
from livedic.bench.peers import PeerStatus, _run, check_peer_location
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
ALDIC3D = "pyALDIC-3D"
ALDIC3D_RUNNER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "peer_aldic3d_runner.py")


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


@dataclass
class CodeResult:
    """One stereo code's U, V, W RMSE (mm, left camera frame) against the truth at one frame, over its ok points."""
    code: str
    status: PeerStatus = PeerStatus.MEASURED
    ok: int = 0
    points: int = 0
    uvw_rmse_mm: list[float] | None = None
    reason: str = ""
    seconds: float = 0.0


def score_uvw(code: str, displacement: np.ndarray, ok: np.ndarray, truth: np.ndarray, seconds: float = 0.0
              ) -> CodeResult:
    """``code``'s RMSE over the points it reports ok with a finite result where the truth exists."""
    good = np.asarray(ok, dtype=bool) & np.all(np.isfinite(displacement), axis=1) & np.all(np.isfinite(truth), axis=1)
    if not np.any(good):
        return CodeResult(code, PeerStatus.FAILED, 0, len(truth), reason="no point ok", seconds=seconds)
    rmse = np.sqrt(np.mean((displacement[good] - truth[good]) ** 2, axis=0))
    return CodeResult(code, PeerStatus.MEASURED, int(np.count_nonzero(good)), len(truth), rmse.tolist(),
                      seconds=seconds)


def check_peer_python(path: str) -> None:
    """ValueError (one line) unless ``path`` is a Python that imports pyALDIC-3D's pipeline (``--peer-python``)."""
    check_peer_location("--peer-python", path)
    if _run([path, "-c", "import al_dic_3d.runner, scipy.interpolate"]) is not None:
        raise ValueError(f"--peer-python {path} cannot import al_dic_3d: give the python of the environment where "
                         "pyALDIC-3D is installed (pip install al-dic-3d)")


def grid_step(points: np.ndarray) -> int:
    """The spacing (px) of a set of points: the median distance from a point to its nearest neighbour (sampled)."""
    points = np.asarray(points, dtype=np.float64)
    if len(points) < 2:
        return 1
    sample = points[:: max(1, len(points) // 200)]
    distance = np.linalg.norm(sample[:, None, :] - points[None, :, :], axis=2)
    distance[distance == 0] = np.inf
    return max(1, int(round(float(np.median(distance.min(axis=1))))))


class PeerFailure(Exception):
    """The peer did not run or gave no usable table; the message (one line) says why."""


def run_aldic3d(python: str, images: list[np.ndarray], calibration: dict[str, Any], points: np.ndarray, subset: int,
                step: int) -> np.ndarray:
    """pyALDIC-3D (``bench/peer_aldic3d_runner.py`` under ``python``) on [left0, right0, left1, right1]: its 3D
    displacement (N, 3) mm of the second pair at ``points`` (left reference px), NaN where it has none;
    ``PeerFailure`` when it fails."""
    import cv2
    with tempfile.TemporaryDirectory(prefix="livedic-stereo-peer-") as work:
        calibration_path = os.path.join(work, "calibration.json")
        with open(calibration_path, "w", encoding="utf-8") as handle:
            json.dump(calibration, handle)
        points_path = os.path.join(work, "points.csv")
        np.savetxt(points_path, points, delimiter=",", header="x,y", comments="")
        paths = []
        for index, image in enumerate(images):
            paths.append(os.path.join(work, f"{index // 2}_{'left' if index % 2 == 0 else 'right'}.png"))
            if not cv2.imwrite(paths[-1], image):
                raise OSError(f"cannot write {paths[-1]}")
        out = os.path.join(work, "peer.csv")
        failure = _run([python, ALDIC3D_RUNNER, calibration_path, points_path, out, str(subset), str(step), *paths])
        if failure is None and not os.path.isfile(out):
            failure = "wrote no result"
        if failure is not None:
            raise PeerFailure(failure)
        try:
            table = np.genfromtxt(out, delimiter=",", names=True, dtype=float, ndmin=1)
            rows = table[table["frame"] == 1]
            if len(rows) != len(points) or not np.allclose(np.column_stack([rows["x"], rows["y"]]), points):
                raise ValueError(f"{len(rows)} rows for {len(points)} points, or not in their order")
            return np.column_stack([rows["U"], rows["V"], rows["W"]])
        except (ValueError, KeyError, TypeError, IndexError) as error:
            raise PeerFailure(f"unreadable result: {error}") from None


def accuracy_case(size: int, frames: int, focal: float, peer_python: str | None = None) -> dict[str, Any]:
    """The stereo session and the 2D one on the same left frames, against the truth; with ``peer_python``,
    pyALDIC-3D on the reference and last pairs too."""
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
        peer = _peer_comparison(peer_python, scene, left.settings["stereo"]["calibration"], collector,
                                np.asarray(tracker.match.left, dtype=np.float64),
                                scene.truth(collector.frames[-1], material).displacement_mm,
                                session.config.tracking.subset)
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
            "match_s": summary["stereo"]["match"]["match_s"], "peer": peer}




def _peer_comparison(peer_python: str | None, scene: Any, calibration: dict[str, Any], collector: _Collector,
                     points: np.ndarray, truth: np.ndarray, subset: int) -> dict[str, Any]:
    """livedic and pyALDIC-3D at the last frame, the same points and truth (``truth``: that frame's, (N, 3) mm): each
    over the points it reports ok (``codes``), and both over the points both report ok (``common``)."""
    frame = collector.frames[-1]
    ours, our_ok = collector.displacement[-1], collector.ok[-1]
    codes = [score_uvw("livedic", ours, our_ok, truth)]
    common: list[CodeResult] = []
    if peer_python is None:
        codes.append(CodeResult(ALDIC3D, PeerStatus.NOT_INSTALLED, points=len(points)))
    else:
        images = [scene.render_view(view, f) for f in (0, frame) for view in ("left", "right")]
        started = time.perf_counter()
        try:
            theirs = run_aldic3d(peer_python, images, calibration, points, subset, grid_step(points))
        except PeerFailure as failure:
            codes.append(CodeResult(ALDIC3D, PeerStatus.FAILED, reason=str(failure),
                                    seconds=time.perf_counter() - started))
        else:
            their_ok = np.all(np.isfinite(theirs), axis=1)
            codes.append(score_uvw(ALDIC3D, theirs, their_ok, truth, time.perf_counter() - started))
            common = [score_uvw("livedic", ours, our_ok & their_ok, truth),
                      score_uvw(ALDIC3D, theirs, our_ok & their_ok, truth)]
    return {"frame": frame, "codes": [_as_dict(code) for code in codes], "common": [_as_dict(code) for code in common]}


def _as_dict(code: CodeResult) -> dict[str, Any]:
    return {**asdict(code), "status": code.status.value}


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


def peer_lines(peer: dict[str, Any]) -> list[str]:
    """The comparison's lines: each code's U, V, W RMSE at the last frame, or why it has none."""
    lines = []
    for code in peer["codes"]:
        head = f"  {code['code'] + ',':<12} frame {peer['frame']}"
        if code["status"] == PeerStatus.MEASURED.value:
            u, v, w = (1e3 * value for value in code["uvw_rmse_mm"])
            lines.append(f"{head}  U, V, W RMSE {u:.2f}, {v:.2f}, {w:.2f} um over {code['ok']} of {code['points']} "
                         f"points" + (f" ({code['seconds']:.0f} s)" if code["code"] != "livedic" else ""))
        elif code["status"] == PeerStatus.NOT_INSTALLED.value:
            lines.append(f"{head}  not installed (--peer-python: the python where al-dic-3d is installed)")
        else:
            lines.append(f"{head}  failed: {code['reason']}")
    if peer.get("common") and all(code["status"] == PeerStatus.MEASURED.value for code in peer["common"]):
        rmse = "; ".join(f"{code['code']} " + ", ".join(f"{1e3 * value:.2f}" for value in code["uvw_rmse_mm"])
                         for code in peer["common"])
        lines.append(f"  on the {peer['common'][0]['ok']} points both report ok: U, V, W RMSE {rmse} um")
    return lines


def run_stereo_benchmark(*, quick: bool = False, output: str | None = None, peer_python: str | None = None) -> int:
    """Print the tables (and write ``output`` JSON); exit code 0 (the figures are the result, the goals said)."""
    size, frames, focal = (512, 8, 4000.0) if quick else (1024, 30, 8000.0)
    started = time.perf_counter()
    accuracy = accuracy_case(size, frames, focal, peer_python)
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
    print("  beside an open stereo code (PyPI al-dic-3d), the same rendered reference and last pairs, calibration, "
          "subset and points:")
    for line in peer_lines(accuracy["peer"]):
        print(line)
    print(f"  ({time.perf_counter() - started:.0f} s)")
    if output:
        with open(output, "w", encoding="utf-8") as handle:
            json.dump({"accuracy": accuracy, "live": live}, handle, indent=2)
    return 0
