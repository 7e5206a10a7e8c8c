"""How a replay compares with the recording: ``ReplayReport`` and its ``Agreement`` (exact, within
floating-point rounding, differs, not compared), filled frame by frame by the replay's comparison sink.

The rounding tolerances and what each verdict means are in ``stream.replay.replay``'s notes.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from livedic.stream.pipeline.sinks import stereo_arrays

if TYPE_CHECKING:
    from livedic.acquire.recording.records import RecordedResults
    from livedic.dic.result import Measurement
    from livedic.stream.pipeline.frame_result import FrameResult, SessionStats


# A replay on another machine agrees within these (see ``stream.replay.replay``'s notes). Rounding
# differences of the compiled kernels moved u and v by 1.8e-6 px on the sample session (issue 8, another x86_64 CPU);
# 1e-4 px leaves room for that and is still 40x below the 8-bit rounding noise of a measurement
# (IC-GN ~4e-3 px SD).
ROUNDING_TOLERANCE_PX = 1e-4
# IC-GN forms ZNCC from per-row float32 sums (dic.subpixel.icgn), and its variance, sum g^2 - (sum g)^2 / n,
# cancels by the subset's mean^2 / var: one machine's rounding is k 2^-24 (mean^2 / var) / sqrt(side), k <= 4.4
# measured on reference frames (exact ZNCC 1: 953 subsets of the sample and of the simulated test to fracture;
# up to 2.5e-6 at mean^2 / var = 83, faded paint), and two CPUs differ by up to twice that (k <= 6.6 measured,
# 1.04e-6 on the sample). 2e-5 covers mean^2 / var up to 175 at subset 21: a grey-level SD down to 1/13 of the mean.
ROUNDING_TOLERANCE_ZNCC = 2e-5


class Agreement(enum.Enum):
    """How a replay compares with the recording (see ``stream.replay.replay``'s notes)."""
    EXACT = "exact"
    WITHIN_ROUNDING = "within floating-point rounding"
    DIFFERS = "differs"
    NOT_COMPARED = "not compared"


@dataclass
class ReplayReport:
    """What a replay did and how it compares with the recording."""
    path: str
    params: dict[str, Any]
    recorded_params: dict[str, Any]
    changed: list[tuple[str, Any, Any]]                   # (name, recorded value or None, value used)
    all_frames: bool = False
    frames: int = 0                  # frames tracked (the reference included)
    points: int = 0
    recorded_frames: int = 0         # result sets in the recording
    missing_frames: int = 0          # recorded result sets whose image is not in the file
    extra_frames: int = 0            # frames tracked without recorded results (--all-frames)
    skipped_before_reference: int = 0
    same_points: bool = False
    compared_frames: int = 0
    mismatched_frames: int = 0
    max_du: float = 0.0
    max_dv: float = 0.0
    max_dzncc: float = 0.0
    layout_differs: int = 0          # frames whose recorded points (count, x, y) differ from the replayed ones
    ok_differs: int = 0              # point-frames whose ok differs
    nan_differs: int = 0             # point-frames where one side is NaN and the other is not
    seconds: float = 0.0
    recorded_version: str = ""
    notes: list[str] = field(default_factory=list)
    truncated: bool = False          # the recording ends early (crash, kill, disk full): the reader's RecordingInfo
    strain: dict[str, Any] | None = None   # stream.stages.strain.StrainStage.summary() of the replay (extensometers)
    parallel: Any = None             # stream.replay.parallel_replay.ParallelStats on Dask (--workers, --cluster)
    force: dict[str, Any] | None = None    # stream.stages.force.LoadStage.summary() with --load
    noise_floor: dict[str, Any] | None = None   # stream.stages.noise_floor.NoiseFloorStage.summary(): static frames
    stereo: dict[str, Any] | None = None   # a stereo replay's rig (calibration_from, baseline_mm, angle_deg), pairing
    max_d_mm: float = 0.0            # stereo: the largest |difference| in X..W (mm) over the compared point-frames
    stereo_status_differs: int = 0   # stereo: point-frames whose 3D status differs

    @property
    def exact(self) -> bool:
        """Every recorded frame that could be replayed is bit-for-bit equal (u, v, zncc, ok; in stereo also X..W
        and the 3D status)."""
        return self.same_points and self.compared_frames > 0 and self.mismatched_frames == 0 \
            and self.compared_frames == self.recorded_frames - self.missing_frames

    @property
    def max_difference_px(self) -> float:
        """The largest |difference| in u or v over the compared point-frames (both finite)."""
        return max(self.max_du, self.max_dv)

    @property
    def rounding_tolerance_mm(self) -> float | None:
        """Stereo: what ``ROUNDING_TOLERANCE_PX`` in both views moves a point in space at most, in mm (None in 2D).

        A pixel is ``mm_per_px`` across at the rig's working distance, and depth is read from the views' parallax,
        1 / sin(angle) times as sensitive: the sum bounds a triangulated point's move."""
        if self.stereo is None:
            return None
        gain = 1.0 + 1.0 / np.sin(np.radians(max(float(self.stereo["angle_deg"]), 1.0)))
        return ROUNDING_TOLERANCE_PX * float(self.stereo["mm_per_px"]) * gain

    @property
    def agreement(self) -> Agreement:
        """``Agreement``: exact, within floating-point rounding, differs, or not compared."""
        if self.recorded_frames == 0 or not self.same_points or self.compared_frames == 0:
            return Agreement.NOT_COMPARED
        if self.exact:
            return Agreement.EXACT
        if (self.compared_frames == self.recorded_frames - self.missing_frames and self.layout_differs == 0
                and self.ok_differs == 0 and self.nan_differs == 0 and self.stereo_status_differs == 0
                and self.max_difference_px <= ROUNDING_TOLERANCE_PX
                and self.max_dzncc <= ROUNDING_TOLERANCE_ZNCC
                and self.max_d_mm <= (self.rounding_tolerance_mm or 0.0)):
            return Agreement.WITHIN_ROUNDING
        return Agreement.DIFFERS

    def verdict(self) -> str:
        """One line for people: equal, equal within rounding, or by how much it differs."""
        changes = ", ".join(f"{name} {'?' if old is None else old} -> {new}" for name, old, new in self.changed)
        size = f"{self.compared_frames} frames x {self.points} points"
        agreement = self.agreement
        if agreement is Agreement.NOT_COMPARED:
            if self.recorded_frames == 0:
                return "the recording holds no results to compare with"
            if not self.same_points:
                return ("the points differ from the recorded ones (point options given): not compared with the "
                        "recording")
            return "no replayed frame has recorded results: not compared with the recording"
        if agreement is Agreement.EXACT:
            if changes:
                return f"replay with changed parameters ({changes}) still equals the recording exactly: {size}"
            return f"replay matches the recording exactly: {size}"
        if agreement is Agreement.WITHIN_ROUNDING:
            within = (f"within floating-point rounding (max {self.max_difference_px:.2g} px <= "
                      f"{_short(ROUNDING_TOLERANCE_PX)} px tolerance): {size}, the same points ok; bit-exact only "
                      f"on the machine that recorded it")
            if changes:
                return f"replay with changed parameters ({changes}) agrees with the recording {within}"
            return f"replay agrees with the recording {within}" + (
                f"; in space max {self.max_d_mm:.2g} mm <= {self.rounding_tolerance_mm:.2g} mm" if self.stereo is not None
                else "")
        text = (f"replay differs from the recording on {self.mismatched_frames} of {size}: max difference "
                f"{_g(self.max_du)} px in u, {_g(self.max_dv)} px in v, {_g(self.max_dzncc)} in zncc; "
                f"ok differs at {self.ok_differs} and NaN at {self.nan_differs} point-frames")
        if self.stereo is not None:
            text += (f"; in space max {_g(self.max_d_mm)} mm in X..W, the 3D status differs at "
                     f"{self.stereo_status_differs} point-frames")
        if changes:
            return text + f" (changed parameters: {changes})"
        if self.all_frames and self.extra_frames:
            return text + (f" ({self.extra_frames} frames the live run dropped were tracked too, so later frames "
                           f"start from other seeds)")
        from livedic.acquire.recording.chunked_writer import software_version
        version = software_version()
        if self.recorded_version and self.recorded_version != version:
            return text + (f" with the recorded parameters: recorded with livedic {self.recorded_version}, "
                           f"replayed with {version}")
        return text + " with the recorded parameters"


def _short(value: float) -> str:
    """1e-4 rather than 0.0001 or 1e-04."""
    mantissa, exponent = f"{value:.0e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _g(value: float) -> str:
    return f"{value:.3g}"


def _same_bits(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    return (a.view(np.uint64) == b.view(np.uint64)) | (np.isnan(a) & np.isnan(b))


def _compare(report: ReplayReport, measurement: Measurement, recorded: RecordedResults) -> None:
    if len(recorded.u) != len(measurement.u) or not np.array_equal(recorded.x, measurement.x) \
            or not np.array_equal(recorded.y, measurement.y):
        report.compared_frames += 1
        report.mismatched_frames += 1
        report.layout_differs += 1
        return
    report.compared_frames += 1
    same = np.asarray(measurement.ok, dtype=bool) == np.asarray(recorded.ok, dtype=bool)
    report.ok_differs += int((~same).sum())
    for name in ("u", "v", "zncc"):
        a = np.asarray(getattr(measurement, name), dtype=np.float64)
        b = np.asarray(getattr(recorded, name), dtype=np.float64)
        same &= _same_bits(a, b)
        report.nan_differs += int((np.isnan(a) != np.isnan(b)).sum())
        both = np.isfinite(a) & np.isfinite(b)
        if both.any():
            attribute = {"u": "max_du", "v": "max_dv", "zncc": "max_dzncc"}[name]
            setattr(report, attribute, max(getattr(report, attribute), float(np.max(np.abs(a[both] - b[both])))))
    same &= _compare_stereo(report, measurement, recorded)
    if not same.all():
        report.mismatched_frames += 1


def _compare_stereo(report: ReplayReport, measurement: Measurement, recorded: RecordedResults) -> np.ndarray | bool:
    """A stereo frame's 3D points and status against the recorded ones (True for a 2D frame): per point, bit-equal."""
    replayed, in_file = stereo_arrays(measurement), getattr(recorded, "stereo", None)
    if not replayed and not in_file:
        return True
    if not replayed or not in_file:                  # one side stereo, the other not: nothing agrees
        report.stereo_status_differs += len(measurement.u)
        return False
    status_same = np.asarray(replayed["stereo_status"]) == np.asarray(in_file["stereo_status"])
    report.stereo_status_differs += int((~status_same).sum())
    same = status_same
    for name in ("x_mm", "y_mm", "z_mm", "u_mm", "v_mm", "w_mm"):
        a = np.asarray(replayed[name], dtype=np.float64)
        b = np.asarray(in_file[name], dtype=np.float64)
        same = same & _same_bits(a, b)
        report.nan_differs += int((np.isnan(a) != np.isnan(b)).sum())
        both = np.isfinite(a) & np.isfinite(b)
        if both.any():
            report.max_d_mm = max(report.max_d_mm, float(np.max(np.abs(a[both] - b[both]))))
    return same


class _Comparison:
    """The replay's sink that compares each tracked frame with its recorded results (fills the report)."""
    name = "comparison"
    required = True

    def __init__(self, report: ReplayReport, recorded: dict[tuple[int, int], RecordedResults],
                 recorded_xy: np.ndarray | None) -> None:
        self.report = report
        self.recorded = recorded
        self.recorded_xy = recorded_xy
        self.seen: set[tuple[int, int]] = set()

    def __call__(self, result: FrameResult, stats: SessionStats) -> None:
        report = self.report
        m = cast("Measurement", result.measurement)
        if result.is_reference:
            recorded_xy = self.recorded_xy
            report.points = stats.n_points
            report.same_points = recorded_xy is not None and recorded_xy.shape == (stats.n_points, 2) \
                and np.array_equal(recorded_xy[:, 0], m.x) and np.array_equal(recorded_xy[:, 1], m.y)
        report.frames += 1
        frame: Any = result.frame
        key = (int(frame.index), int(frame.timestamp_ns))
        match = self.recorded.get(key)
        if match is not None and key not in self.seen:
            self.seen.add(key)
            if report.same_points:
                _compare(report, m, match)
        else:
            report.extra_frames += 1
