"""The consumer side of a live session: queue -> tracker -> stages | output thread -> sinks.

One linear loop (the Rerun examples' shape) in the tracking thread: take the
next frame, track it, run the measurement's own *stages* on it (strain and
extensometers, strain out to the controller, force: what the result is made
of and what must leave at once), update the statistics, and hand the result
to the *output thread*, which runs the *sinks* (recording of results, Rerun
view, events, progress; a replay's CSV) in order, at their own pace: the
measurement never waits for the display or the disk. The output thread's
backlog (results waiting for it) is ``FrameResult.output_backlog`` (a view in
the session's process leaves the camera image out while it is behind:
``stream.view.logger``; a live session's view runs in a process of its own,
``stream.view.process``, and paces itself on its own backlog), and past ``OUTPUT_BACKLOG_MAX`` results the tracking thread waits for it (frames
are then dropped at the frame queue, counted, never silently).

The first frame becomes the reference: the tracker is built from it
(``make_tracker(frame)``, or before the loop: ``reference``) and it is reported
with zero displacement. The loop ends when the queue is closed and drained (source
finished, failed or stopped), when ``stop_event`` is set, or after
``max_frames`` results.

Timing, all on the host's monotonic clock:

* **latency** = results ready - frame arrival in the acquisition thread
  (queue wait + tracking), per frame; when the source says when it captured the
  frame on this clock (``Frame.metadata["capture_monotonic_ns"]``, the paced
  simulator does) latency counts from that capture instead, so a delivery held
  up by the tracker (numba kernels hold the GIL, and the acquisition thread
  needs it to hand a frame over) is not hidden; that hold-up is reported as
  ``delivery delay``. The reference frame is left out of the latency statistics
  (it pays for building the tracker) and its setup time is reported on its own;
* **processing** = time inside ``Tracker.track``;
* **stage times** = per frame, each tracker stage (``tracker.last_timings``:
  preparing the frame, the IC-GN kernel, searches, gates, reference updates),
  each stage (``stage.last_timings`` where it splits its own time, e.g. strain
  and extensometers) and each sink, in ``StageTimes`` (p50/p99 in the summary);
* **fps** = frames tracked / (last result - first arrival);
* **ok fraction** = ok points / every placed point, over all frames: a point that could never be
  tracked (no texture in its reference subset, subset off the image) counts as not ok; the
  summary also gives those never-trackable points and the points lost later (trackable in the
  reference, not ok in the last frame), each by ``dic.Status``;
* **POI/s** = points tracked per second of that same wall time.

A stage or sink that raises is switched off and its error kept in
``sink_errors`` (a broken viewer must not stop a measurement); the caller
decides what to do. One marked ``required`` (its ``required`` attribute is
true: a replay's CSV) ends the loop instead, its error raised by ``run`` once
the output thread has finished what it had (see ``stream.pipeline.sinks``).
"""

import collections
import os
import sys
import threading
import time
from array import array
from dataclasses import dataclass, field, replace

import numpy as np

from livedic.dic.status import Status
from livedic.stream.pipeline.frame_queue import QueueClosed

# A capture time further than this before arrival is not trusted (another clock, another process).
_MAX_DELIVERY_NS = 10_000_000_000
# The output thread's niceness (Linux, per thread): when the cores are busy the scheduler gives the tracking
# thread (and numba's workers) the CPU first; the outputs catch up in the gaps.
OUTPUT_NICE = 10
# Results the output thread may have waiting before the tracking thread waits for it (bounded memory:
# each holds its frame's image); at 50 fps, 4 s of results.
OUTPUT_BACKLOG_MAX = 200


class StageTimes:
    """Per-frame durations of named stages (packed 64-bit ns), for their percentiles.

    Each stage has its own series (a stage that did not run in a frame adds nothing
    for it). One writer per stage name: the tracking thread writes the tracker's and
    the stages', the output thread the sinks'.
    """

    def __init__(self):
        self._times = {}

    def add(self, stage, ns):
        series = self._times.get(stage)
        if series is None:
            series = self._times[stage] = array("q")
        series.append(int(ns))

    def add_all(self, timings):
        for stage, ns in timings.items():
            self.add(stage, ns)

    def summary(self):
        """``{stage: {"frames", "p50_ms", "p99_ms", "mean_ms", "max_ms"}}`` in the order stages first ran."""
        out = {}
        for stage, series in list(self._times.items()):
            values = np.array(series[:], dtype=np.int64) / 1e6     # a slice: a copy, not an export
            if values.size:
                out[stage] = {"frames": int(values.size), "p50_ms": float(np.percentile(values, 50)),
                              "p99_ms": float(np.percentile(values, 99)), "mean_ms": float(values.mean()),
                              "max_ms": float(values.max())}
        return out


def _lower_priority(nice):
    """Raise the calling thread's niceness by ``nice`` where the system allows it per thread (Linux); else nothing."""
    if not sys.platform.startswith("linux"):
        return
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + nice)
    except OSError:
        pass


def _percentile_ms(series, percentile):
    """Percentile (ms) of a packed ns series another thread may be appending to (NaN when empty)."""
    if not series:
        return float("nan")
    return float(np.percentile(np.array(series[:], np.int64), percentile)) / 1e6


@dataclass
class FrameResult:
    """What the loop hands to sinks for one frame."""
    frame: object                 # acquire.base.Frame
    arrival_ns: int               # time.monotonic_ns() when acquisition got it
    done_ns: int                  # results ready
    processing_ns: int            # inside Tracker.track
    measurement: object           # dic.result.Measurement
    is_reference: bool
    frames_done: int              # results so far, this one included
    dropped_total: int            # frames the queue has dropped so far
    dropped_since_last: int       # ... since the previous result
    queue_depth: int              # frames waiting after this one was taken
    refind_attempts: int = 0
    refound: int = 0
    error_rms_px: float = float("nan")   # against the truth (synthetic sources), ok points
    error_max_px: float = float("nan")
    capture_ns: int = None        # capture time on the monotonic clock, when the source gives it
    reference_update: object = None   # dic.tracking.key_frames.ReferenceUpdate when this frame became the reference
    fracture: object = None       # dic.tensile.fracture.Fracture when one was detected in this frame
    strain: object = None         # dic.strain.StrainField, set by the strain stage (stream.stages.strain) when it runs
    force_N: float = None         # the machine's force at this frame (stream.stages.force), NaN when unknown
    stress_MPa: float = None      # ... and the engineering stress
    true_strain: float = None     # ln(1 + e) of the axial extensometer while the elongation may be uniform, else NaN
    true_stress_MPa: float = None  # ... and the true stress F / A0 (1 + e) (stream.stages.stress.UniformElongationWatch)
    extensometers: object = None  # dic.strain.extensometer.ExtensometerReadings, idem
    poisson: object = None        # dic.tensile.poisson.ContractionRatio: Poisson's ratio fitted so far (stream.stages.contraction)
    output_backlog: int = 0       # results waiting for the output thread behind this one (set as sinks get it)

    @property
    def origin_ns(self):
        """Where latency starts: capture when known (and earlier than arrival), else arrival."""
        if self.capture_ns is None:
            return self.arrival_ns
        return min(self.capture_ns, self.arrival_ns)

    @property
    def latency_ns(self):
        return self.done_ns - self.origin_ns

    @property
    def delivery_delay_ns(self):
        """Arrival in the acquisition thread - capture (None when the source gives no capture time)."""
        return None if self.capture_ns is None else self.arrival_ns - self.capture_ns


@dataclass
class SessionStats:
    """Running statistics of a session (see module notes for definitions)."""
    n_points: int = 0
    frames: int = 0
    dropped: int = 0
    first_arrival_ns: int = None
    last_done_ns: int = None
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
    trackable_at_reference: np.ndarray = None   # (N,) bool: trackable when the reference was set
    reference_status: np.ndarray = None         # (N,) the reference frame's statuses (why not trackable)
    last_status: np.ndarray = None              # (N,) the last frame's statuses

    @property
    def elapsed_s(self):
        if self.first_arrival_ns is None or self.last_done_ns is None:
            return 0.0
        return (self.last_done_ns - self.first_arrival_ns) / 1e9

    @property
    def fps(self):
        elapsed = self.elapsed_s
        return (self.frames - 1) / elapsed if elapsed > 0 and self.frames > 1 else float("nan")

    @property
    def poi_per_s(self):
        elapsed = self.elapsed_s
        return self.points_tracked / elapsed if elapsed > 0 else float("nan")

    def latency_ms(self, percentile):
        return _percentile_ms(self.latencies_ns, percentile)

    def delivery_delay_ms(self, percentile):
        return _percentile_ms(self.delivery_delays_ns, percentile)

    def processing_ms(self, percentile):
        return _percentile_ms(self.processing_ns, percentile)

    @property
    def error_rms_px(self):
        return float(np.sqrt(self.error_sq_sum / self.error_count)) if self.error_count else float("nan")

    @property
    def ok_fraction(self):
        """Ok points over every placed point (the never-trackable count as not ok)."""
        return self.points_ok / self.points_placed if self.points_placed else float("nan")

    @property
    def ok_fraction_of_trackable(self):
        """Ok points over the points the tracker could track."""
        return self.points_ok / self.points_tracked if self.points_tracked else float("nan")

    def point_losses(self):
        """``{"points_never_trackable": {"count", "by_status"}, "points_lost_later": {...}}`` (status names).

        Never trackable: not trackable in the reference frame. Lost later: trackable there, not ok
        in the last frame."""
        def counted(statuses):
            codes, counts = np.unique(np.asarray(statuses, dtype=np.int64), return_counts=True)
            return {"count": int(counts.sum()),
                    "by_status": {Status(int(code)).name: int(n) for code, n in zip(codes, counts)}}
        if self.trackable_at_reference is None:
            return {"points_never_trackable": counted([]), "points_lost_later": counted([])}
        never = ~self.trackable_at_reference
        lost = self.trackable_at_reference & (self.last_status != int(Status.OK))
        return {"points_never_trackable": counted(self.reference_status[never]),
                "points_lost_later": counted(self.last_status[lost])}

    def summary(self):
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
    tracker: object
    measurement: object
    setup_ns: int                 # building the tracker and tracking the reference


def reference_ready(make_tracker, frame):
    """Build the tracker on ``frame`` and track it: a ``ReferenceReady``."""
    started = time.monotonic_ns()
    tracker = make_tracker(frame)
    measurement = tracker.track(frame.image)
    return ReferenceReady(tracker, measurement, time.monotonic_ns() - started)


def _stage_name(stage):
    """A stage's or sink's row in the stage times: its ``stage`` label, else its ``name``."""
    return getattr(stage, "stage", None) or getattr(stage, "name", None) or type(stage).__name__


class _End:
    """The output thread's last item."""


class OutputThread:
    """Runs the sinks on each result, in order, in a thread of their own (see module notes).

    ``put`` never blocks below ``OUTPUT_BACKLOG_MAX`` waiting results; ``finish`` waits for the
    last one. A required sink's error stops the sinks (``error``) and calls ``on_required_error``.
    """

    def __init__(self, sinks, stats, *, on_required_error, errors):
        self.sinks = sinks
        self.stats = stats
        self.on_required_error = on_required_error
        self.errors = errors
        self.error = None
        self._pending = collections.deque()
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="livedic-output", daemon=True)
        self._thread.start()

    def put(self, result):
        """Queue ``result`` for the sinks; waits while ``OUTPUT_BACKLOG_MAX`` results are waiting."""
        stats = self.stats
        with self._changed:
            if len(self._pending) >= OUTPUT_BACKLOG_MAX and self.error is None:
                stats.output_waits += 1
                self._changed.wait_for(lambda: len(self._pending) < OUTPUT_BACKLOG_MAX or self.error is not None)
            self._pending.append(result)
            stats.output_backlog_max = max(stats.output_backlog_max, len(self._pending))
            self._changed.notify_all()

    def finish(self, timeout=None):
        """Let the sinks take every result queued, then end the thread; True when it ended."""
        with self._changed:
            self._pending.append(_End)
            self._changed.notify_all()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _run(self):
        _lower_priority(OUTPUT_NICE)
        stages = self.stats.stages
        while True:
            with self._changed:
                self._changed.wait_for(lambda: self._pending)
                result = self._pending.popleft()
                backlog = len(self._pending) - (self._pending[-1] is _End if self._pending else 0)
                self._changed.notify_all()
            if result is _End:
                return
            if self.error is not None:
                continue                  # a required sink failed: the rest is not wanted
            result.output_backlog = backlog
            score_against_truth(result, self.stats)
            for sink in list(self.sinks):
                started = time.perf_counter_ns()
                try:
                    sink(result, self.stats)
                except BaseException as error:  # noqa: BLE001 - keep measuring, report later
                    self.sinks.remove(sink)
                    if getattr(sink, "required", False) or not isinstance(error, Exception):
                        # the session's output itself (or an interrupt): the session ends, run() raises it
                        self.error = error
                        self.on_required_error()
                        break
                    self.errors.append((sink, error))
                    continue
                stages.add(_stage_name(sink), time.perf_counter_ns() - started)


class TrackerLoop:
    """Consume ``queue`` until it ends; see module notes.

    Parameters
    ----------
    queue : FrameQueue
        Holds ``stream.pipeline.acquisition.QueuedFrame`` items.
    make_tracker : callable
        ``make_tracker(first_frame) -> dic.tracking.Tracker`` (built on the reference).
    reference : ReferenceReady, optional
        The tracker already built on the first frame the queue will give, and that frame tracked
        (before acquisition started: the frames after it do not queue up behind its set-up);
        ``make_tracker`` is not called.
    stages : sequence of callables
        ``stage(result: FrameResult, stats: SessionStats)`` for each frame, in order, in the tracking
        thread right after ``track``: what the result is made of (strain, force) and what must leave at
        once (strain out).
    sinks : sequence of callables
        ``sink(result: FrameResult, stats: SessionStats)`` for each frame, in order, in the output
        thread (``stream.pipeline.sinks``): recording, view, events, progress.
    stop_event : threading.Event, optional
        Set to end the loop after the current frame.
    max_frames : int, optional
        End after this many results.
    poll_s : float
        How often to look at ``stop_event`` while waiting for a frame.
    """

    def __init__(self, queue, make_tracker, *, reference=None, stages=(), sinks=(), stop_event=None,
                 max_frames=None, poll_s=0.05):
        self.queue = queue
        self.make_tracker = make_tracker
        self._ready = reference
        self.stages = list(stages)
        self.sinks = list(sinks)
        self.stop_event = stop_event or threading.Event()
        self.max_frames = max_frames
        self.poll_s = poll_s
        self.tracker = None
        self.stats = SessionStats()
        self.sink_errors = []
        self.reference_frame = None
        self.ended_by = None
        self.output = None

    def run(self):
        """Run to the end (the output thread's sinks too); returns the ``SessionStats``."""
        self.output = OutputThread(self.sinks, self.stats, on_required_error=self.stop_event.set,
                                   errors=self.sink_errors)
        try:
            self._track_all()
        finally:
            self.output.finish()
        if self.output.error is not None:
            raise self.output.error
        self.stats.dropped = self.queue.dropped
        return self.stats

    def _track_all(self):
        last_dropped = 0
        stages = self.stats.stages
        while True:
            if self.stop_event.is_set():
                self.ended_by = "stop" if self.output.error is None else "output"
                break
            if self.max_frames is not None and self.stats.frames >= self.max_frames:
                self.ended_by = "limit"
                break
            try:
                item = self.queue.get(timeout=self.poll_s)
            except QueueClosed:
                self.ended_by = "source"
                break
            if item is None:
                continue
            frame = item.frame
            stats = self.stats
            if stats.first_arrival_ns is None:
                stats.first_arrival_ns = item.arrival_ns
            is_reference = self.tracker is None
            t0 = time.monotonic_ns()
            ready = None
            if is_reference:
                ready, self._ready = self._ready, None
                self.tracker = ready.tracker if ready is not None else self.make_tracker(frame)
                # A copy: a camera frame's image is a buffer lent by the camera's pool, and the
                # reference is kept for the whole session.
                self.reference_frame = replace(frame, image=frame.image.copy())
                stats.n_points = self.tracker.n_points
            tracked = time.monotonic_ns()
            if ready is not None:
                measurement = ready.measurement
                t0 -= ready.setup_ns
            else:
                measurement = self.tracker.track(frame.image)
            done = time.monotonic_ns()
            if is_reference:
                stats.setup_ns = done - t0
            timings = getattr(self.tracker, "last_timings", None)
            dropped = self.queue.dropped
            capture = frame.metadata.get("capture_monotonic_ns") if isinstance(frame.metadata, dict) else None
            if capture is not None and not 0 <= item.arrival_ns - int(capture) < _MAX_DELIVERY_NS:
                capture = None    # not from this process's clock (e.g. copied from a recording)
            result = FrameResult(frame=frame, arrival_ns=item.arrival_ns, done_ns=done, processing_ns=done - t0,
                                 measurement=measurement, is_reference=is_reference, frames_done=stats.frames + 1,
                                 dropped_total=dropped, dropped_since_last=dropped - last_dropped,
                                 queue_depth=len(self.queue),
                                 refind_attempts=self.tracker.last_refind_attempts,
                                 refound=int(self.tracker.last_refound.sum()),
                                 capture_ns=int(capture) if capture is not None else None,
                                 reference_update=getattr(self.tracker, "last_update", None),
                                 fracture=getattr(self.tracker, "last_fracture", None))
            last_dropped = dropped
            self._update(result)
            if not is_reference:
                stages.add("tracker", done - tracked)
                if timings is not None:
                    stages.add_all(timings)
            for stage in list(self.stages):
                started = time.perf_counter_ns()
                try:
                    stage(result, stats)
                except Exception as error:  # noqa: BLE001 - keep measuring, report later
                    if getattr(stage, "required", False):
                        raise             # the session's output itself: it cannot go on without it
                    self.stages.remove(stage)
                    self.sink_errors.append((stage, error))
                    continue
                if is_reference:
                    continue
                parts = getattr(stage, "last_timings", None)
                if parts:
                    stages.add_all(parts)
                else:
                    stages.add(_stage_name(stage), time.perf_counter_ns() - started)
            self.output.put(result)

    def _update(self, result):
        stats = self.stats
        m = result.measurement
        stats.frames += 1
        stats.last_done_ns = result.done_ns
        stats.dropped = result.dropped_total
        trackable = self.tracker.trackable
        if result.is_reference:
            stats.trackable_at_reference = np.array(trackable, dtype=bool)
            stats.reference_status = np.array(m.status, dtype=np.int64)
        stats.last_status = m.status
        stats.points_placed += int(m.ok.size)
        stats.points_tracked += int(trackable.sum())
        stats.points_ok += int(m.ok.sum())
        stats.refound += result.refound
        if not result.is_reference:
            stats.latencies_ns.append(result.latency_ns)
            stats.processing_ns.append(result.processing_ns)
            if result.capture_ns is not None:
                stats.delivery_delays_ns.append(result.delivery_delay_ns)
                stats.latency_from = "capture"


def score_against_truth(result, stats):
    """The result's error against the source's truth (the simulator's exact motion), into ``result`` and ``stats``.

    The first sink of the output thread (the truth is the simulator's, not part of the measurement):
    ``result.error_rms_px``/``error_max_px`` over the ok points, and the session's running sums.
    """
    m = result.measurement
    truth = result.frame.metadata.get("truth") if isinstance(result.frame.metadata, dict) else None
    if not (callable(truth) and m.ok.any()):   # a replayed recording holds only its text form
        return
    tu, tv = truth(m.x[m.ok], m.y[m.ok])
    err = np.hypot(m.u[m.ok] - tu, m.v[m.ok] - tv)
    result.error_rms_px = float(np.sqrt(np.mean(err * err)))
    result.error_max_px = float(err.max())
    if not result.is_reference:
        stats.truth_frames += 1
        stats.error_sq_sum += float(np.sum(err * err))
        stats.error_count += int(err.size)
        if not stats.error_max >= result.error_max_px:
            stats.error_max = result.error_max_px
