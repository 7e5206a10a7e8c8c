"""A tracking session: source -> queue -> tracker -> sinks, with one lifecycle.

Wiring (one producer thread, one consumer loop)::

    source --(acquisition thread)--> FrameQueue --(calling thread)--> Tracker --> sinks: recorder results,
                    |                 (drops counted)                              Rerun view, P0 check,
                    \\--> recorder frames (every frame, dropped or not)             progress, more ...

``livedic run``, ``livedic replay``, ``livedic bench live`` and ``bench soak``
all run this one object, so the benchmarks measure what a user gets. Its
lifecycle::

    session = Session(config)     # a SessionConfig (stream.session.config): nothing is opened yet
    session.prepare()             # its Preparation (stream.session.preparation): outputs checked, source
                                  # opened, kernels compiled, the simulated test rendered, the first frame
                                  # read, the points and P0 placed on it and checked, the stages' order
                                  # checked; then the recording and the view opened
    session.start()               # the acquisition thread starts
    session.run()                 # tracks until the source ends or fails, or stop() is called
    session.stop(reason)          # from any thread or a signal handler: run() then tracks what is queued
    session.summary()             # the numbers (dict, as --summary-json writes them); summary_text()
    session.close()               # recording, view and source closed (``with Session(...)`` does it)

Bad input raises from ``prepare`` (``ValueError``, ``SourceError``, one line)
before any output exists; ``abandon`` (a stop before the session started)
closes what was opened and removes the recording it had just created. Where
the session stands is ``phase`` (a ``Phase``); how it went is data: ``stats``,
``acquisition`` (frames, losses, ``error``), ``recorder``, ``sink_errors``,
``stopped_by``, ``render_seconds``.

Stages (``stream.pipeline.stage.Stage``, in the tracking thread): strain, strain out, force;
their summary lines and recording metadata are their own. Sinks (``stream.pipeline.sinks``, in
the output thread): the recording of results, the Rerun view, the P0 check and the progress line
are built in; ``Session(config, sinks=[...])`` adds more (a replay's comparison and CSV, the
soak's memory monitor). ``Session(config, tracker_factory=...)`` tracks with another tracker (a
replay on a cluster).
"""

import dataclasses
import os
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, Literal

from livedic.acquire import sources
from livedic.acquire.base import Frame
from livedic.dic.strain.extensometer import AXIAL
from livedic.stream.pipeline.acquisition import AcquisitionThread, Reconnect
from livedic.stream.pipeline.cores import CoreSplit, core_split
from livedic.stream.pipeline.frame_recording import FrameRecording
from livedic.stream.pipeline.frame_queue import BLOCK, FrameQueue
from livedic.stream.pipeline.frame_result import SessionStats, reference_ready
from livedic.stream.pipeline.key_frame_builder import KeyFrameBuilder
from livedic.stream.pipeline.progress import ProgressBar
from livedic.stream.pipeline.sinks import (BitDepthWatch, FractureWatch, P0Watch, ProgressLine, RecordResults,
                                           ReferenceUpdates)
from livedic.stream.pipeline.stage import Reference, Stage
from livedic.stream.pipeline.tracker_loop import TrackerLoop
from livedic.stream.session.points import PlacedBy
# the preparation's names, imported from here by the callers of the session
from livedic.stream.session.preparation import (FIRST_FRAME_NOTE_S, FirstFrameAhead, NoFrame, Phase, Preparation,
                                                check_viewer_reachable, drop_policy, is_live, warm_up)
from livedic.stream.session.stereo import describe_match, last_frame_numbers, make_stereo_tracker, match_summary
from livedic.stream.session.summary import format_summary
from livedic.stream.stages.contraction import ContractionWatch, has_pair

__all__ = ["Session", "Phase", "NoFrame", "FirstFrameAhead", "FIRST_FRAME_NOTE_S", "GIL_SWITCH_INTERVAL_S",
           "check_viewer_reachable", "drop_policy", "is_live", "warm_up", "for_recording", "lost_upstream"]


# How long a thread that wants the GIL waits before it asks the holder to give it up (Python's default: 5 ms).
GIL_SWITCH_INTERVAL_S = 0.0005


# Phases in which this session's recording may exist without a session in it.
_RECORDING_OPENED = (Phase.OPENING_OUTPUTS, Phase.READY)


# Per-process keys that mean nothing in a recording (the host's monotonic clock).
_VOLATILE_METADATA = ("capture_monotonic_ns",)


def for_recording(frame: Frame) -> Frame:
    """``frame`` without the per-process metadata keys (same image, no copy)."""
    metadata = frame.metadata
    if not isinstance(metadata, dict) or not any(key in metadata for key in _VOLATILE_METADATA):
        return frame
    kept = {k: v for k, v in metadata.items() if k not in _VOLATILE_METADATA}
    return dataclasses.replace(frame, metadata=kept)


def lost_upstream(acquisition: Any) -> int:
    """Frames the source skipped (gaps in its frame indices) once the session had started, not counting queue
    drops, nor the frames a camera sent while the session was being prepared (``skipped_before_start``)."""
    if acquisition.first_index is None:
        return 0
    span = acquisition.last_index - acquisition.first_index + 1
    return max(0, span - acquisition.frames - acquisition.skipped_before_start)


def _safe_settings(source):
    try:
        settings = dict(source.settings)
    except Exception as error:  # noqa: BLE001 - settings are informative only
        settings = {"settings_error": f"{type(error).__name__}: {error}"}
    return settings


def _remove_quietly(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def _prepared(name: str, doc: str) -> Any:
    """A ``Session`` attribute that is its ``Preparation``'s (read and replaced there)."""
    return property(lambda self: getattr(self.preparation, name),
                    lambda self, value: setattr(self.preparation, name, value), doc=doc)


class Session:
    """One tracking session (see the module notes for the lifecycle).

    Parameters
    ----------
    config : stream.session.config.SessionConfig
        Validated settings.
    source : FrameSource, optional
        An opened source to use instead of opening ``config.source`` (a replay's
        selected frames, the soak's counted simulator); ``config.source`` still names it.
    points : ndarray (N, 2) or callable, optional
        Track exactly these points (P0 first), or ``points(reference_image)``'s, instead of
        ``config.points``' grid and P0 (a replay of the recorded points).
    sinks : sequence of callables, optional
        More sinks, called after the built-in ones (``stream.pipeline.sinks``).
    tracker_factory : callable, optional
        ``tracker_factory(reference_image, points) -> tracker`` builds what tracks the frames (default
        ``config.tracking.tracker``: a ``dic.tracking`` tracker); a replay on a cluster gives its own.
    say : callable, optional
        ``say(message)`` receives the session's messages; default: a ``livedic: `` line on stderr.

    Attributes
    ----------
    phase : Phase
    preparation : stream.session.preparation.Preparation
        What ``prepare`` checked, opened and placed; ``source``, ``points``, ``p0``, ``placement``, ``strain``,
        ``load``, ``load_stage``, ``publishers``, ``total_frames``, ``render_seconds`` and ``drop_policy`` are its.
    stages : list of stream.pipeline.stage.Stage
        The measurement's stages, in the order they run.
    source : FrameSource or None
        The opened source (the session closes it).
    recorder : acquire.recording.writer.Recorder or None
    viewer : stream.view.logger.RerunLogger or None
    queue : FrameQueue, acquisition : AcquisitionThread, loop : TrackerLoop
        The pipeline, from ``start``.
    points : ndarray (N, 2)
        The points (P0 first), from ``prepare``.
    p0 : stream.session.p0.P0Choice or None
        Where P0 is and why (None when ``points`` were given).
    strain : stream.stages.strain.StrainStage or None
        The strain and extensometer stage on the points, from ``prepare``.
    poisson : stream.stages.contraction.ContractionWatch or None
        Poisson's ratio over the elastic range, with the ``axial``/``transverse`` pair, from ``start``.
    publishers : list of stream.publish.PublishStage
        The ``--publish`` outlets, opened in ``prepare`` (before any output), closed by ``close``.
    reference : stream.pipeline.stage.Reference or None
        The reference frame's points, once the tracker is built on it.
    total_frames : int or None
        Frames the session expects (``config.frames`` or the source's length).
    render_seconds : float or None
        Time spent rendering the simulated test ahead (before the session; not measured).
    stopped_by : str or None
        Why ``stop`` was called (a signal name, ...).
    sink_errors : list of (name, exception)
        Sinks switched off during the session.
    """

    def __init__(self, config: Any, *, source: Any = None, points: Any = None, sinks: Sequence[Callable] = (),
                 say: Callable[[str], None] | None = None, tracker_factory: Callable[..., Any] | None = None) -> None:
        self.config = config
        self._tracker_factory = tracker_factory if tracker_factory is not None else config.tracking.tracker
        self._phase: Phase | None = None        # None: the preparation's
        self._extra_sinks = list(sinks)
        self._say = say
        self.preparation = Preparation(config, source=source, points=points, say=self.say, event=self.event)
        self.recorder: Any = None
        self.viewer: Any = None
        self.queue: Any = None                  # FrameQueue, from start
        self.acquisition: Any = None
        self.loop: Any = None                   # TrackerLoop, from start
        self.cores: CoreSplit | None = None     # where the tracking thread ran (--cores split), from start
        self.frame_recording: FrameRecording | None = None     # writes the camera frames, from start
        self.key_frames: KeyFrameBuilder | None = None          # builds new key frames' trackers, from start
        self.bar: Any = None
        self.progress: Any = None
        self.poisson: ContractionWatch | None = None
        self.reference_updates: Any = None
        self.fractures: Any = None
        self.reference: Reference | None = None
        self.stopped_by: str | None = None
        self.sink_errors: list = []
        self._settings: dict = {}
        self._stop_requested = False
        self._previous_threads: int | None = None
        self._previous_switch_interval: float | None = None
        self._summary: dict | None = None
        self._summary_text: str | None = None
        self._stereo: dict | None = None        # a stereo session's rig and reference match, for the summary

    # what the preparation opened, read and placed (stream.session.preparation.Preparation)
    source = _prepared("source", "The opened frame source (the session closes it).")
    points = _prepared("points", "The points (P0 first), from ``prepare``.")
    p0 = _prepared("p0", "Where P0 is and why (None when ``points`` were given).")
    placement = _prepared("placement", "How the points were placed (``stream.session.points``).")
    strain = _prepared("strain", "The strain and extensometer stage on the points.")
    load = _prepared("load", "The opened force source (``--load``).")
    load_stage = _prepared("load_stage", "The force stage.")
    publishers = _prepared("publishers", "The ``--publish`` stages.")
    total_frames = _prepared("total_frames", "Frames the session expects.")
    render_seconds = _prepared("render_seconds", "Time spent rendering the simulated test ahead.")
    drop_policy = _prepared("drop_policy", "The queue's policy.")

    @property
    def phase(self) -> Phase:
        """Where the session stands (while preparing: how far its preparation got)."""
        return self._phase if self._phase is not None else self.preparation.phase

    @phase.setter
    def phase(self, value: Phase) -> None:
        self._phase = value

    # ----------------------------------------------------------------- messages

    def say(self, message: str) -> None:
        """One message for the user (``livedic: message`` on stderr, clear of the progress line)."""
        if self._say is not None:
            self._say(message)
            return
        if self.config.show_progress:
            sys.stderr.write("\r\033[K")
        print(f"livedic: {message}", file=sys.stderr, flush=True)

    def event(self, kind: str, message: str, level: str = "info", *, tell: bool = True) -> None:
        """An event: said (``tell``; "warning: " unless info), shown in the view and recorded as ``kind``."""
        if tell:
            self.say(("warning: " if level != "info" else "") + message)
        if self.viewer is not None:
            self.viewer.event(message, level=level)
        if self.recorder is not None:
            self.recorder.write_event(kind, message, level=level)

    # ----------------------------------------------------------------- lifecycle

    def prepare(self) -> None:
        """Everything before the session: see the module notes. Raises on bad input; nothing is left behind."""
        config = self.config
        import numba
        self._previous_threads = numba.get_num_threads()
        numba.set_num_threads(config.threads)
        # The tracking thread takes the GIL back from the output thread within this when it needs it
        # (between its kernels), instead of Python's default 5 ms: docs/guide/performance.md.
        self._previous_switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
        self.preparation.run()
        self.phase = Phase.OPENING_OUTPUTS
        self._open_outputs(config.scheme)
        self.phase = Phase.READY

    def start(self) -> None:
        """Start acquisition (after ``prepare``)."""
        config = self.config
        self.queue = FrameQueue(config.queue, self.drop_policy)
        key_frames = self.key_frames = KeyFrameBuilder()
        recorder = self.recorder
        on_frame = None
        if recorder is not None:
            def write_frame(item):       # every frame, tracked or dropped, in order, behind the acquisition thread
                started = time.perf_counter_ns()
                recorder.write_frame(for_recording(item.frame))
                if item.frame.right is not None:
                    recorder.write_frame(for_recording(item.frame.right), view="right")
                self.loop.stats.stages.add("record frame", time.perf_counter_ns() - started)
            on_frame = self.frame_recording = FrameRecording(write_frame)
        reconnect = None
        if config.reconnect:
            options = self.preparation.source_options
            reconnect = Reconnect(reopen=lambda: sources.open_source(config.source, **options),
                                  retry_s=1.0, timeout_s=config.reconnect_timeout, on_event=self._source_event)
        self.acquisition = AcquisitionThread(self.preparation.ahead, self.queue, max_frames=self.preparation.max_frames,
                                             on_frame=on_frame, reconnect=reconnect)
        self.bar = ProgressBar(self.total_frames, enabled=config.show_progress)
        # The outputs, in the output thread at their own pace: Poisson's ratio (for the view), recording,
        # view, events, progress.
        sinks: list[Callable] = []
        if has_pair(self.strain):
            # after the load stage: the force picks the elastic range; the static frames are no part of the test
            self.poisson = ContractionWatch(self.preparation.static_frames)
            self.strain.contraction = self.poisson  # its ratio is summarised with the strain
            sinks.append(self.poisson)
        if recorder is not None:
            sinks.append(RecordResults(recorder, config.tracking.method,
                                       strain_window=self.strain.windows.window if self.strain is not None else None,
                                       load_source=config.load))
        if self.viewer is not None and self.viewer.enabled:
            sinks.append(self.viewer)
        self.reference_updates = ReferenceUpdates(lambda kind, message, level: self.event(kind, message, level,
                                                                                         tell=level != "info"))
        sinks.append(self.reference_updates)
        self.fractures = FractureWatch(self.event)
        sinks.append(self.fractures)
        if self.p0 is not None:
            sinks.append(P0Watch(config.tracking.refind_zncc, self.event))
        sinks.append(BitDepthWatch(self.event))
        self.progress = ProgressLine(self.bar, self.acquisition)
        sinks.append(self.progress)
        sinks.extend(self._extra_sinks)
        # The tracker built on the reference (the first frame, read by prepare) and the reference tracked before
        # the acquisition thread starts: the next frames do not queue up behind that set-up (~70 ms at 1 MP).
        self.loop = TrackerLoop(self.queue, self._make_tracker, reference=reference_ready(self._make_tracker,
                                                                                          self.preparation.ahead.frame),
                                stages=self.stages, sinks=sinks, cores=self._core_split(),
                                between_frames=key_frames.run_pending)
        # Each new frame is prefiltered in the acquisition thread while the tracker refines the one before.
        self.acquisition.prepare = self.loop.coefficients_ahead
        self.phase = Phase.RUNNING
        if self._stop_requested:
            self.acquisition.stop()
        discard = getattr(self.source, "discard_buffered", None)
        if discard is not None:
            discard()           # a camera's frames sent while the session was prepared: stale (AravisSource)
        self.acquisition.start()

    def _core_split(self) -> CoreSplit | None:
        """Where the tracking thread and the rest run while it tracks (``--cores``: stream.pipeline.cores)."""
        if self.config.cores != "split":
            return None
        view_pid = getattr(self.viewer, "pid", None) if self.viewer is not None else None
        self.cores = core_split(self.config.threads, [view_pid] if view_pid is not None else [])
        return self.cores

    def run(self) -> SessionStats:
        """Track until the source ends or fails, or ``stop`` is called; returns the ``SessionStats``.

        A sink marked ``required`` that fails ends the session: its error is raised
        (after acquisition has stopped). A source failure is not raised: it is
        ``acquisition.error`` (the summary reports it, the caller decides).
        """
        try:
            self.loop.run()
        finally:
            self.acquisition.stop()
            self.queue.close()          # frees a put blocked on a full queue ("block" policy)
            self.acquisition.join(timeout=10.0)
            if self.frame_recording is not None:    # every frame acquired is in the recording before it closes
                self._close_quietly(self.frame_recording.close, "frame recording")
            for publisher in self.publishers:
                self._close_quietly(publisher.finish, publisher.name)
            self._close_key_frames()
        self.progress.finish()
        self._report_end()
        self.phase = Phase.FINISHED
        if self.viewer is not None and self.viewer.enabled:
            try:
                self.viewer.flush()             # a .rrd that cannot be written is known to the summary
            except Exception:  # noqa: BLE001 - a slow flush: close() flushes again and reports
                pass
        self._summary = self._make_summary()
        # the measurement's stages' lines first (strain, force), then the outlets' (strain out: they provide nothing)
        reported = sorted(self.stages, key=lambda stage: not stage.provides)
        self._summary_text = format_summary(self._summary, self.reference, self.recorder,
                                            [line for stage in reported for line in stage.summary_lines()])
        if self.viewer is not None:
            try:
                self.viewer.log_summary("```\n" + self._summary_text + "\n```")
            except Exception as error:  # noqa: BLE001 - the viewer is a display: the summary still goes out
                self.say(f"warning: the Rerun viewer did not take the summary: {type(error).__name__}: {error}")
        return self.loop.stats

    def execute(self) -> dict | None:
        """``prepare``, ``start`` and ``run``; returns ``summary()`` (close the session afterwards)."""
        self.prepare()
        self.start()
        self.run()
        return self.summary()

    def stop(self, reason: str | None = None) -> None:
        """Stop acquisition (any thread; a signal handler): ``run`` then tracks what is queued and returns."""
        if reason is not None:
            self.stopped_by = reason
        self._stop_requested = True
        if self.acquisition is not None:
            self.acquisition.stop()

    def close(self) -> None:
        """Close the source, the recording and the view (what is open); restore numba's threads. Idempotent.

        ``acquisition`` stays for the caller to read (its frames, losses, error).
        """
        acquisition = self.acquisition
        if acquisition is not None and acquisition.ident is not None:
            if acquisition.is_alive():
                acquisition.stop()
                acquisition.join(timeout=10.0)    # the thread closes the source as it ends
        elif self.source is not None:
            self._close_quietly(self.source.close, "frame source")
        self.source = None
        if self.frame_recording is not None:      # before the recorder: the frames still waiting are written
            self._close_quietly(self.frame_recording.close, "frame recording")
        self._close_key_frames()
        if self.load is not None:
            load, self.load = self.load, None
            self._close_quietly(load.close, "force source")
        if self.recorder is not None and not self.recorder.closed:
            self.recorder.close()
        if self.viewer is not None:
            viewer, self.viewer = self.viewer, None
            self._close_quietly(viewer.close, "Rerun stream")
        if self.preparation.view_child is not None:    # started, never used: the session ended before its outputs
            child, self.preparation.view_child = self.preparation.view_child, None
            self._close_quietly(child.close, "Rerun view process")
        # Last: a Modbus server answers "ended" for a short linger first, and a second Ctrl-C during it must
        # not leave the recording unfinished.
        publishers, self.publishers = self.publishers, []
        for publisher in publishers:
            self._close_quietly(publisher.close, publisher.name)
        if self._previous_threads is not None:
            import numba
            numba.set_num_threads(self._previous_threads)
            self._previous_threads = None
        if self._previous_switch_interval is not None:
            sys.setswitchinterval(self._previous_switch_interval)
            self._previous_switch_interval = None
        self.phase = Phase.CLOSED

    def _close_key_frames(self) -> None:
        if self.key_frames is not None:
            builder, self.key_frames = self.key_frames, None
            self._close_quietly(builder.close, "key frame builder")

    def abandon(self) -> None:
        """Before ``start``: close what is open and remove the recording this session had just created."""
        remove = self.phase in _RECORDING_OPENED and self.preparation.record_path_was_free
        if self.recorder is not None:
            self._close_quietly(self.recorder.close, "recording")
        self.close()
        if remove:
            _remove_quietly(self.config.record)

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close()
        return False

    # ----------------------------------------------------------------- results

    @property
    def stages(self) -> list[Stage]:
        """The measurement's stages in the order they run (``Preparation.stages``), from ``prepare``."""
        return self.preparation.stages

    @property
    def stats(self) -> SessionStats | None:
        """The running ``SessionStats`` (from ``start``)."""
        return self.loop.stats if self.loop is not None else None

    @property
    def source_error(self) -> Exception | None:
        """Why acquisition stopped early (``SourceError``), or None."""
        return self.acquisition.error if self.acquisition is not None else None

    def summary(self) -> dict | None:
        """The session's numbers (a dict; NaN where a number is missing), after ``run``."""
        return self._summary

    def summary_text(self) -> str | None:
        """The end-of-run text (a few aligned lines), after ``run``."""
        return self._summary_text

    # ----------------------------------------------------------------- stages

    def _open_outputs(self, scheme):
        from livedic.stream.view.camera_image import IMAGE_MAX_HZ
        from livedic.stream.view.logger import RerunLogger
        from livedic.stream.view.process import ViewProcess
        config = self.config
        self._settings = _safe_settings(self.source)
        if config.record:
            # The simulator's clock starts at 0 ns; cameras keep the recorder's default (Unix time).
            self.recorder = self._open_recorder(config.record, self.preparation.metadata(self._settings),
                                                start_time_ns=0 if scheme == "synthetic" else None)
        if config.viewer.note:
            self.say(config.viewer.note)
        # the view logs in a process of its own: its Python never holds the GIL the tracking thread needs
        options = dict(recording_name=config.name, image_max_side=config.image_max_side,
                       color_range=config.color_range, low_zncc=config.tracking.refind_zncc,
                       thin_when_behind=self.drop_policy != BLOCK,
                       image_max_hz=IMAGE_MAX_HZ if self.drop_policy != BLOCK else None,
                       on_error=lambda message: self.event("viewer_file_stopped", message, "warning"))
        if self.preparation.view_child is None:
            self.viewer = RerunLogger(config.viewer.mode, config.viewer.target, **options)
        else:
            child, self.preparation.view_child = self.preparation.view_child, None
            self.viewer = ViewProcess(config.viewer.mode, config.viewer.target, child=child, **options)

    def _open_recorder(self, path, metadata, *, start_time_ns=None):
        try:
            from livedic.acquire.recording.writer import Recorder
        except ImportError as error:
            self.say(f"warning: not recording ({error}); use --no-record to silence this")
            return None

        def recording_stopped(message):
            self.say(f"warning: {message}")        # the recorder's message starts "recording stopped: ..."
            if self.viewer is not None:
                self.viewer.event(message, level="error")

        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        return Recorder(path, metadata, start_time_ns=start_time_ns, on_error=recording_stopped,
                        stereo=self.preparation.stereo is not None)

    def _make_tracker(self, frame: Frame) -> Any:
        """The tracker on the reference frame (the first tracked), the stages set up on it; tells the view and the
        recording."""
        config = self.config
        prepared = self.preparation
        if prepared.stereo is not None:
            tracker, seconds = make_stereo_tracker(prepared.stereo, frame, self.points, config.tracking)
            self._stereo = {"match": match_summary(tracker, seconds), "calibration_from": prepared.stereo_calibration_from}
            self.event("note", describe_match(self._stereo["match"]), tell=True)
        else:
            tracker = self._tracker_factory(frame.image, self.points)
        if self.key_frames is not None:
            self.key_frames.attach(tracker)
        roi_used = prepared.roi if prepared.roi is not None else (0, 0, frame.image.shape[1], frame.image.shape[0])
        self.reference = Reference(frame_index=frame.index, points=self.points, roi=tuple(int(v) for v in roi_used),
                                   step=prepared.step, shape=frame.image.shape, timestamp_ns=frame.timestamp_ns)
        for stage in self.stages:
            stage.on_reference(self.reference)
        if self.p0 is None:
            return tracker                      # given points: the caller's session (a replay) says what they are
        wanted = config.points
        placed = self.placement.describe()
        if prepared.given_xy is not None:
            placed += f" from {wanted.points_file or 'the given points'}"
        note = f"reference frame {frame.index}: {placed}; {self.p0.describe()}"
        has_truth = callable((frame.metadata or {}).get("truth"))
        if self.viewer is not None:
            self.viewer.start(image_shape=frame.image.shape, roi=self.reference.roi, p0_index=0, points=self.points,
                              has_truth=has_truth, title=f"livedic run: {config.source}",
                              source_settings=self._settings, strain=self.strain, load=self.load_stage,
                              setup=prepared.setup, stereo=prepared.stereo is not None)
        # an automatic choice is said: the user did not say where the points go
        self.event("note", note, tell=self.placement is not None and self.placement.placed_by is PlacedBy.SPECIMEN)
        for line in prepared.setup.checks() if prepared.setup is not None else ():
            self.event("note", f"set-up: {line}", tell=True)
        if self.strain is not None:
            self.event("note", self.strain.describe(), tell=bool(self.strain.extensometers))
            for warning in self.strain.noise_warnings():
                self.event("extensometer_noise", warning, "warning")
        names = [e.name for e in self.strain.extensometers] if self.strain is not None else []
        if self.load_stage is not None and AXIAL not in names:
            self.event("note", "force without an axial extensometer: force and stress are recorded, but the "
                               "stress-strain curve and livedic report need one (--gauge-length L)", tell=True)
        warning = self.p0.warning()
        if warning:
            self.event("p0_weak", warning, "warning")
        return tracker

    def _source_event(self, kind, message, level):
        """A lost camera, waited for and back (``Reconnect.on_event``; from the acquisition thread)."""
        self.event(kind, message, level)

    def _report_end(self):
        """Say what went wrong during the session, and record it."""
        recorder = self.recorder
        for sink, error in self.loop.sink_errors:
            name = "Rerun display" if sink is self.viewer else getattr(sink, "name", type(sink).__name__)
            self.sink_errors.append((name, error))
            self.say(f"warning: {name} stopped during the session: {type(error).__name__}: {error}")
            if recorder is not None and not isinstance(sink, RecordResults):
                recorder.write_event("note", f"{name} stopped: {error}", level="warning")
        if self.stopped_by:
            self.say(f"stopped on {self.stopped_by}; the recording is closed properly")
            if recorder is not None:
                recorder.write_event("note", f"session stopped on {self.stopped_by}")
        error = self.acquisition.error
        if error is not None:
            if recorder is not None:
                recorder.write_event("camera_lost", str(error), level="error")
            if self.viewer is not None:
                self.viewer.event(f"source failed: {error}", level="error")

    def _make_summary(self):
        config = self.config
        acquisition = self.acquisition
        viewer = self.viewer
        reference = self.reference
        summary = self.loop.stats.summary()
        summary["stages"].update(getattr(viewer, "stages", None) or {})     # the view's own process
        live = is_live(self.source)
        if not live:
            # frames taken as fast as the tracker takes them: no clock to be late against, no latency
            summary.update(latency_p50_ms=None, latency_p99_ms=None, latency_max_ms=None, latency_from=None)
        summary.update(
            source=config.source, live=live, method=config.tracking.method, acquired=acquisition.frames,
            prefilter=config.tracking.prefilter, interpolation=config.tracking.interpolation,
            lost_upstream=lost_upstream(acquisition), skipped_before_start=acquisition.skipped_before_start,
            stopped_by=self.stopped_by,
            source_losses=list(acquisition.losses), reconnects=acquisition.reconnects,
            outage_s=round(acquisition.outage_s, 3),
            source_error=str(acquisition.error) if acquisition.error is not None else None,
            recording=config.record if self.recorder is not None else None,
            rerun=config.viewer.describe(), rerun_error=viewer.file_error if viewer is not None else None,
            points_shape=list(reference.shape) if reference else [],
            roi=list(reference.roi) if reference else None,
            step=reference.step if reference else None,
            p0=list(self.p0.xy) if self.p0 is not None else None,
            p0_choice=self.p0.reason.name if self.p0 is not None else None,
            p0_weak=self.p0.weak if self.p0 is not None else None,
            viewer_log_ms_per_frame=(1e3 * viewer.log_seconds / viewer.frames_logged
                                     if viewer is not None and viewer.frames_logged else None),
            viewer_images_left_out=viewer.images.images_left_out if viewer is not None else None,
            viewer_image_max_hz=viewer.image_max_hz if viewer is not None else None,
            viewer_images_above_rate=viewer.images.images_above_rate if viewer is not None else None,
            viewer_process=getattr(viewer, "frames_left_out", None) is not None,
            viewer_frames_left_out=getattr(viewer, "frames_left_out", None),
            cores=self.cores.describe() if self.cores is not None else None,
            render_s=round(self.render_seconds, 3) if self.render_seconds is not None else None,
            strain=({**self.strain.summary(), **(self.poisson.summary() if self.poisson is not None else {})}
                    if self.strain is not None else None),
            force=self.load_stage.summary() if self.load_stage is not None else None,
            noise_floor=self.preparation.noise_floor.summary() if self.preparation.noise_floor is not None else None,
            publish=[publisher.summary() for publisher in self.publishers] or None,
            reference_update=config.tracking.reference_update,
            **(self.reference_updates.summary() if self.reference_updates is not None else {}),
            **(self.fractures.summary() if self.fractures is not None else {}))
        if self._stereo is not None:
            last = getattr(self.loop.tracker, "last_points", None)
            summary["stereo"] = {**self._stereo, "last": last_frame_numbers(last) if last is not None else None,
                                 "pairing": _safe_settings(self.source).get("pairing")}   # counted to the end
        return summary

    def _close_quietly(self, close, what):
        """``close()``; a failure is one warning line (the session's outcome and summary still go out)."""
        try:
            close()
        except Exception as error:  # noqa: BLE001 - closing a display or a source must not hide the summary
            self.say(f"warning: closing the {what} failed: {type(error).__name__}: {error}")
