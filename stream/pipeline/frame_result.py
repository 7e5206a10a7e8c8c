"""What the live pipeline hands on for each frame and keeps for the session: ``FrameResult``, ``SessionStats``.

``StageTimes`` holds each stage's per-frame durations; ``ReferenceReady`` is the reference frame's tracker and
result made before the loop starts (``reference_ready``). The timings are defined in ``stream.pipeline.tracker_loop``.
"""

import time
from array import array
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from livedic.acquire.base import Frame
from livedic.dic.result import Measurement
from livedic.dic.status import Status


class StageTimes:
    """Per-frame durations of named stages (packed 64-bit ns), for their percentiles.

    Each stage has its own series (a stage that did not run in a frame adds nothing
    for it). One writer per stage name: the tracking thread writes the tracker's and
    the stages', the output thread the sinks'.
    """

    def __init__(self) -> None:
        self._times: dict[str, array] = {}

    def add(self, stage: str, ns: int) -> None:
        series = self._times.get(stage)
        if series is None:
            series = self._times[stage] = array("q")
        series.append(int(ns))

    def add_all(self, timings: Mapping[str, int]) -> None:
        for stage, ns in timings.items():
            self.add(stage, ns)

    def summary(self) -> dict[str, dict[str, float]]:
        """``{stage: {"frames", "p50_ms", "p99_ms", "mean_ms", "max_ms"}}`` in the order stages first ran."""
        out = {}
        for stage, series in list(self._times.items()):
            values = np.array(series[:], dtype=np.int64) / 1e6     # a slice: a copy, not an export
            if values.size:
                out[stage] = {"frames": int(values.size), "p50_ms": float(np.percentile(values, 50)),
                              "p99_ms": float(np.percentile(values, 99)), "mean_ms": float(values.mean()),
                              "max_ms": float(values.max())}
        return out


def _percentile_ms(series, percentile):
    """Percentile (ms) of a packed ns series another thread may be appending to (NaN when empty)."""
    if not series:
        return float("nan")
    return float(np.percentile(np.array(series[:], np.int64), percentile)) / 1e6


@dataclass
class FrameResult:
    """What the loop hands to sinks for one frame."""
    frame: Frame
    arrival_ns: int               # time.monotonic_ns() when acquisition got it
    done_ns: int                  # results ready
    processing_ns: int            # inside Tracker.track
    measurement: Measurement
    is_reference: bool
    frames_done: int              # results so far, this one included
    dropped_total: int            # frames the queue has dropped so far
    dropped_since_last: int       # ... since the previous result
    queue_depth: int              # frames waiting after this one was taken
    refind_attempts: int = 0
    refound: int = 0
    error_rms_px: float = float("nan")   # against the truth (synthetic sources), ok points
    error_max_px: float = float("nan")
    capture_ns: int | None = None     # capture time on the monotonic clock, when the source gives it
    reference_update: Any = None      # dic.key_frames.ReferenceUpdate when this frame became the reference
    fracture: Any = None              # dic.fracture.Fracture when one was detected in this frame
    strain: Any = None                # dic.strain.StrainField, set by the strain stage (stream.stages.strain)
    force_N: float | None = None      # the machine's force at this frame (stream.stages.force), NaN when unknown
    stress_MPa: float | None = None   # ... and the engineering stress
    # ln(1 + e) of the axial extensometer while the elongation may be uniform, else NaN, and the true stress
    # F / A0 (1 + e) (stream.stages.stress.UniformElongationWatch)
    true_strain: float | None = None
    true_stress_MPa: float | None = None
    extensometers: Any = None         # dic.extensometer.ExtensometerReadings, set by the strain stage
    poisson: Any = None               # dic.poisson.ContractionRatio: Poisson's ratio so far (stream.stages.contraction)
    noise_floor: Any = None           # list of dic.noise_floor.NoiseFloor on the last static frame (stages.noise_floor)
    output_backlog: int = 0       # results waiting for the output thread behind this one (set as sinks get it)

    # The tracker's fields are set by ``TrackerLoop`` (``TRACKER_FIELDS``); the rest by the stage that ``provides``
    # it (``stream.pipeline.stage``) or by the output thread (the truth's error, the backlog, Poisson's ratio).

    @property
    def origin_ns(self) -> int:
        """Where latency starts: capture when known (and earlier than arrival), else arrival."""
        if self.capture_ns is None:
            return self.arrival_ns
        return min(self.capture_ns, self.arrival_ns)

    @property
    def latency_ns(self) -> int:
        return self.done_ns - self.origin_ns

    @property
    def delivery_delay_ns(self) -> int | None:
        """Arrival in the acquisition thread - capture (None when the source gives no capture time)."""
        return None if self.capture_ns is None else self.arrival_ns - self.capture_ns


RESULT_FIELDS = frozenset(f.name for f in fields(FrameResult))
# What ``TrackerLoop`` sets when it makes a frame's result: what the first stage may read.
TRACKER_FIELDS = ("frame", "arrival_ns", "done_ns", "processing_ns", "measurement", "is_reference", "frames_done",
                  "dropped_total", "dropped_since_last", "queue_depth", "refind_attempts", "refound", "capture_ns",
                  "reference_update", "fracture")


@dataclass
class SessionStats:
    """Running statistics of a session (the definitions: ``stream.pipeline.tracker_loop``'s notes)."""
    n_points: int = 0
    frames: int = 0
    dropped: int = 0
    first_arrival_ns: int | None = None
    last_done_ns: int | None = None
    setup_ns: int = 0
    points_placed: int = 0        # every point, every frame
    points_tracked: int = 0       # the trackable ones
    points_ok: int = 0
    refound: int = 0
    # Per tracked frame, as packed 64-bit integers (8 bytes each, not a Python int object and
    # a list slot): a long session keeps these for its percentiles.
    latencies_ns: array = field(default_factory=lambda: array("q"))
    processing_ns: array = field(default_factory=lambda: array("q"))
    delivery_delays_ns: array = field(default_factory=lambda: array("q"))
    latency_from: str = "arrival"
    error_sq_sum: float = 0.0
    error_count: int = 0
    error_max: float = float("nan")
    truth_frames: int = 0
    stages: StageTimes = field(default_factory=StageTimes)   # per-frame time of each stage and sink
    output_backlog_max: int = 0                  # the most results that waited for the output thread
    output_waits: int = 0                        # times the tracking thread waited for it (backlog full)
    trackable_at_reference: np.ndarray | None = None   # (N,) bool: trackable when the reference was set
    reference_status: np.ndarray | None = None        # (N,) the reference frame's statuses (why not trackable)
    last_status: np.ndarray | None = None             # (N,) the last frame's statuses

    @property
    def elapsed_s(self) -> float:
        if self.first_arrival_ns is None or self.last_done_ns is None:
            return 0.0
        return (self.last_done_ns - self.first_arrival_ns) / 1e9

    @property
    def fps(self) -> float:
        elapsed = self.elapsed_s
        return (self.frames - 1) / elapsed if elapsed > 0 and self.frames > 1 else float("nan")

    @property
    def poi_per_s(self) -> float:
        elapsed = self.elapsed_s
        return self.points_tracked / elapsed if elapsed > 0 else float("nan")

    def latency_ms(self, percentile: float) -> float:
        return _percentile_ms(self.latencies_ns, percentile)

    def delivery_delay_ms(self, percentile: float) -> float:
        return _percentile_ms(self.delivery_delays_ns, percentile)

    def processing_ms(self, percentile: float) -> float:
        return _percentile_ms(self.processing_ns, percentile)

    @property
    def error_rms_px(self) -> float:
        return float(np.sqrt(self.error_sq_sum / self.error_count)) if self.error_count else float("nan")

    @property
    def ok_fraction(self) -> float:
        """Ok points over every placed point (the never-trackable count as not ok)."""
        return self.points_ok / self.points_placed if self.points_placed else float("nan")

    @property
    def ok_fraction_of_trackable(self) -> float:
        """Ok points over the points the tracker could track."""
        return self.points_ok / self.points_tracked if self.points_tracked else float("nan")

    def point_losses(self) -> dict[str, dict[str, Any]]:
        """``{"points_never_trackable": {"count", "by_status"}, "points_lost_later": {...}}`` (status names).

        Never trackable: not trackable in the reference frame. Lost later: trackable there, not ok
        in the last frame."""
        def counted(statuses):
            codes, counts = np.unique(np.asarray(statuses, dtype=np.int64), return_counts=True)
            return {"count": int(counts.sum()),
                    "by_status": {Status(int(code)).name: int(n) for code, n in zip(codes, counts)}}
        if self.trackable_at_reference is None or self.reference_status is None or self.last_status is None:
            return {"points_never_trackable": counted([]), "points_lost_later": counted([])}
        never = ~self.trackable_at_reference
        lost = self.trackable_at_reference & (self.last_status != int(Status.OK))
        return {"points_never_trackable": counted(self.reference_status[never]),
                "points_lost_later": counted(self.last_status[lost])}

    def summary(self) -> dict[str, Any]:
        """Plain dict of the headline numbers (JSON-friendly)."""
        return {
            "frames": self.frames, "points": self.n_points, "elapsed_s": self.elapsed_s, "fps": self.fps,
            "poi_per_s": self.poi_per_s, "latency_p50_ms": self.latency_ms(50), "latency_p99_ms": self.latency_ms(99),
            "latency_max_ms": self.latency_ms(100), "processing_p50_ms": self.processing_ms(50),
            "processing_p99_ms": self.processing_ms(99), "latency_from": self.latency_from,
            "delivery_delay_p99_ms": self.delivery_delay_ms(99) if self.delivery_delays_ns else None,
            "setup_ms": self.setup_ns / 1e6, "dropped": self.dropped,
            "ok_fraction": self.ok_fraction, "ok_fraction_of_trackable": self.ok_fraction_of_trackable,
            **self.point_losses(), "refound": self.refound,
            "error_rms_px": self.error_rms_px if self.truth_frames else None,
            "error_max_px": self.error_max if self.truth_frames else None,
            "stages": self.stages.summary(), "output_backlog_max": self.output_backlog_max,
            "output_waits": self.output_waits,
        }


@dataclass
class ReferenceReady:
    """The reference frame's tracker and result, made before the session's clock started (``TrackerLoop``)."""
    tracker: Any
    measurement: Measurement
    setup_ns: int                 # building the tracker and tracking the reference


def track_frame(tracker: Any, frame: Frame, ahead: Any = None) -> Measurement:
    """``frame`` tracked: one camera's image (with its coefficients made ``ahead``), or a stereo pair's two images
    (``frame.right``: a ``dic.stereo.StereoTracker``)."""
    if frame.right is not None:
        return tracker.track(frame.image, frame.right.image)
    return tracker.track(frame.image) if ahead is None else tracker.track(frame.image, ahead=ahead)


def reference_ready(make_tracker: Callable[[Frame], Any], frame: Frame) -> ReferenceReady:
    """Build the tracker on ``frame`` and track it: a ``ReferenceReady``."""
    started = time.monotonic_ns()
    tracker = make_tracker(frame)
    measurement = track_frame(tracker, frame)
    return ReferenceReady(tracker, measurement, time.monotonic_ns() - started)
