"""The consumer side of a live session: queue -> tracker -> stages | output thread -> sinks.

One linear loop in the tracking thread: take the next frame, track it, run the measurement's
own *stages* on it (strain and extensometers, strain out, force: ``stream.pipeline.stage.Stage``),
update the statistics, and hand the result to the *output thread*, which runs the *sinks*
(recording of results, Rerun view, events, progress; a replay's CSV) in order, at their own
pace: the measurement never waits for the display or the disk. Its backlog is
``FrameResult.output_backlog``; past ``OUTPUT_BACKLOG_MAX`` results the tracking thread waits
(frames are then dropped at the frame queue, counted, never silently).

The first frame becomes the reference (``make_tracker(frame)``, or ``reference`` given before
the loop) and is reported with zero displacement. The loop ends when the queue is closed and
drained, when ``stop_event`` is set, or after ``max_frames`` results.

Statistics, on the host's monotonic clock: latency (from the frame's arrival, or its capture
when ``Frame.metadata["capture_monotonic_ns"]`` says when, the reference frame left out),
delivery delay, processing, per-stage times (``StageTimes``), fps, ok fraction over every
placed point and POI/s; their definitions: docs/guide/sessions.md ("What the summary's timings
mean").

A stage or sink that raises is switched off and its error kept in ``sink_errors`` (a broken
viewer must not stop a measurement); one marked ``required`` (a replay's CSV) ends the loop
instead, its error raised by ``run`` once the output thread has finished what it had (see
``stream.pipeline.sinks``).
"""

import collections
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numba
import numpy as np

from livedic.stream.pipeline.frame_queue import QueueClosed
from livedic.acquire.base import Frame
from livedic.stream.pipeline.frame_queue import FrameQueue
from livedic.stream.pipeline.frame_result import FrameResult, ReferenceReady, SessionStats, track_frame
from livedic.stream.pipeline.cores import OUTPUT_NICE, CoreSplit, lower_priority
from livedic.stream.pipeline.stage import Stage

# A capture time further than this before arrival is not trusted (another clock, another process).
_MAX_DELIVERY_NS = 10_000_000_000
# Results the output thread may have waiting before the tracking thread waits for it (bounded memory:
# each holds its frame's image); at 50 fps, 4 s of results.
OUTPUT_BACKLOG_MAX = 200


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

    def __init__(self, sinks: list[Callable], stats: SessionStats, *, on_required_error: Callable[[], None],
                 errors: list) -> None:
        self.sinks = sinks
        self.stats = stats
        self.on_required_error = on_required_error
        self.errors = errors
        self.error: BaseException | None = None
        self._pending: collections.deque = collections.deque()
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="livedic-output", daemon=True)
        self._thread.start()

    def put(self, result: FrameResult) -> None:
        """Queue ``result`` for the sinks; waits while ``OUTPUT_BACKLOG_MAX`` results are waiting."""
        stats = self.stats
        with self._changed:
            if len(self._pending) >= OUTPUT_BACKLOG_MAX and self.error is None:
                stats.output_waits += 1
                self._changed.wait_for(lambda: len(self._pending) < OUTPUT_BACKLOG_MAX or self.error is not None)
            self._pending.append(result)
            stats.output_backlog_max = max(stats.output_backlog_max, len(self._pending))
            self._changed.notify_all()

    def finish(self, timeout: float | None = None) -> bool:
        """Let the sinks take every result queued, then end the thread; True when it ended."""
        with self._changed:
            self._pending.append(_End)
            self._changed.notify_all()
        self._thread.join(timeout)
        return not self._thread.is_alive()

    def _run(self):
        lower_priority(OUTPUT_NICE)
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
    stages : sequence of stream.pipeline.stage.Stage
        ``stage.on_frame(result: FrameResult)`` for each frame, in order, in the tracking thread right
        after ``track``: what the result is made of (strain, force) and what must leave at once (strain
        out). The caller checks their order (``stream.pipeline.stage.check_stage_order``).
    sinks : sequence of callables
        ``sink(result: FrameResult, stats: SessionStats)`` for each frame, in order, in the output
        thread (``stream.pipeline.sinks``): recording, view, events, progress.
    stop_event : threading.Event, optional
        Set to end the loop after the current frame.
    max_frames : int, optional
        End after this many results.
    poll_s : float
        How often to look at ``stop_event`` while waiting for a frame.
    cores : stream.pipeline.cores.CoreSplit, optional
        Pinned by the tracking thread once the output thread has started, released at the end.
    between_frames : callable, optional
        Called in the tracking thread after each frame's result is handed to the output thread, before the
        next frame is taken: work the next frame needs that must not hold this one's result back (a new key
        frame's tracker: ``stream.pipeline.key_frame_builder``).
    """

    def __init__(self, queue: FrameQueue, make_tracker: Callable[[Frame], Any], *,
                 reference: ReferenceReady | None = None, stages: Sequence[Stage] = (),
                 sinks: Sequence[Callable] = (), stop_event: threading.Event | None = None,
                 max_frames: int | None = None, poll_s: float = 0.05, cores: CoreSplit | None = None,
                 between_frames: Callable[[], None] | None = None) -> None:
        self.queue = queue
        self.between_frames = between_frames
        self.cores = cores
        self.make_tracker = make_tracker
        self._ready = reference
        self.stages = list(stages)
        self.sinks = list(sinks)
        self.stop_event = stop_event or threading.Event()
        self.max_frames = max_frames
        self.poll_s = poll_s
        self.tracker: Any = None
        self.stats = SessionStats()
        self.sink_errors: list[tuple[Any, Exception]] = []
        self.reference_frame: Frame | None = None
        self.ended_by: str | None = None
        self.output: OutputThread | None = None
        self._spare_coefficients: list[Any] = []     # buffers of tracked frames' coefficients, for the next
        self._numba_threads = numba.get_num_threads()

    def coefficients_ahead(self, frame: Frame) -> Any:
        """``frame``'s IC-GN coefficients (``dic.tracking.Tracker.coefficients_ahead``), made in the calling
        thread: the acquisition thread's ``prepare``, so that the tracking thread only refines (a live
        session's prefilter is ~a third of the tracker's time: docs/guide/performance.md). None before the
        tracker exists and for methods without a window."""
        tracker = self.tracker
        if tracker is None:
            ready = self._ready
            tracker = ready.tracker if ready is not None else None
        make = getattr(tracker, "coefficients_ahead", None)
        if make is None:
            return None
        if numba.get_num_threads() != self._numba_threads:
            numba.set_num_threads(self._numba_threads)    # per thread in numba: this one's as the session's
        started = time.perf_counter_ns()
        ahead = make(frame.image, self._spare_coefficients.pop() if self._spare_coefficients else None)
        self.stats.stages.add("prepare ahead", time.perf_counter_ns() - started)
        return ahead

    def run(self) -> SessionStats:
        """Run to the end (the output thread's sinks too); returns the ``SessionStats``."""
        self.output = OutputThread(self.sinks, self.stats, on_required_error=self.stop_event.set,
                                   errors=self.sink_errors)
        if self.cores is not None:
            self.cores.pin()            # every other thread of the session has started by now
        try:
            self._track_all()
        finally:
            try:
                self.output.finish()
            finally:
                if self.cores is not None:
                    self.cores.release()
        if self.output.error is not None:
            raise self.output.error
        self.stats.dropped = self.queue.dropped
        return self.stats

    def _track(self, item):
        """``item``'s frame tracked, with the coefficients its acquisition made ahead (their buffer then reused)."""
        measurement = track_frame(self.tracker, item.frame, item.ahead)
        if item.ahead is not None:
            self._spare_coefficients.append(item.ahead.coefficients)
        return measurement

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
                self.reference_frame = replace(frame, image=frame.image.copy(), right=None if frame.right is None
                                               else replace(frame.right, image=frame.right.image.copy()))
                stats.n_points = self.tracker.n_points
            tracked = time.monotonic_ns()
            if ready is not None:
                measurement = ready.measurement
                t0 -= ready.setup_ns
            else:
                measurement = self._track(item)
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
            self._run_stages(result, stages)
            self.output.put(result)
            if self.between_frames is not None:
                self.between_frames()

    def _run_stages(self, result, stages):
        """Each stage on ``result``, in order, timed into ``stages`` (not the reference frame's); a stage that fails
        is dropped and reported later, unless it is required."""
        for stage in list(self.stages):
            started = time.perf_counter_ns()
            try:
                stage.on_frame(result)
            except Exception as error:  # noqa: BLE001 - keep measuring, report later
                if getattr(stage, "required", False):
                    raise             # the session's output itself: it cannot go on without it
                self.stages.remove(stage)
                self.sink_errors.append((stage, error))
                continue
            if result.is_reference:
                continue
            parts = getattr(stage, "last_timings", None)
            if parts:
                stages.add_all(parts)
            else:
                stages.add(_stage_name(stage), time.perf_counter_ns() - started)

    def _update(self, result):
        stats = self.stats
        m = result.measurement
        stats.frames += 1
        stats.last_done_ns = result.done_ns
        stats.dropped = result.dropped_total
        # the points this frame tried (a key frame tracker's next ones may still be being built: never waited for)
        trackable = getattr(self.tracker, "last_trackable", None)
        if trackable is None:
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


def score_against_truth(result: FrameResult, stats: SessionStats) -> None:
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
