"""A tracking session: source -> queue -> tracker -> sinks, with one lifecycle.

Wiring (one producer thread, one consumer loop)::

    source --(acquisition thread)--> FrameQueue --(calling thread)--> Tracker --> sinks: recorder results,
                    |                 (drops counted)                              Rerun view, P0 check,
                    \\--> recorder frames (every frame, dropped or not)             progress, more ...

``livedic run``, ``livedic replay``, ``livedic bench live`` and ``bench soak``
all run this one object, so the benchmarks measure what a user gets. Its
lifecycle::

    session = Session(config)     # a SessionConfig (stream.session.config): nothing is opened yet
    session.prepare()             # outputs checked, source opened, kernels compiled, the simulated test
                                  # rendered, the first frame read, the points and P0 placed on it and
                                  # checked, then the recording and the view opened
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

Sinks (``stream.pipeline.sinks``): the recording of results, the Rerun view, the P0
check and the progress line are built in; ``Session(config, sinks=[...])``
adds more (a replay's comparison and CSV, the soak's memory monitor; strain,
extensometers or load channels later).
"""

import dataclasses
import enum
import os
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np

from livedic.acquire import sources
from livedic.dic import DEFAULT_SUBSET, bspline
from livedic.dic.strain import field_fit
from livedic.acquire.base import SourceError
from livedic.stream.pipeline.acquisition import AcquisitionThread, Reconnect
from livedic.stream.session.config import VIEWER_NONE
from livedic.stream.pipeline.frame_queue import BLOCK, DROP_NEWEST, DROP_OLDEST, FrameQueue
from livedic.stream.stages.contraction import ContractionWatch, has_pair
from livedic.stream.session.points import PlacedBy, check_point_count, default_roi, place_points, read_points_csv
from livedic.stream.session.preview import setup_overlay
from livedic.stream.pipeline.progress import ProgressBar
from livedic.stream.pipeline.sinks import (BitDepthWatch, FractureWatch, P0Watch, ProgressLine, RecordResults,
                                  ReferenceUpdates)
from livedic.dic.strain.extensometer import AXIAL
from livedic.stream.stages.strain import StrainConfig
from livedic.stream.pipeline.frame_result import reference_ready
from livedic.stream.pipeline.stage import Reference, Stage, check_stage_order
from livedic.stream.pipeline.tracker_loop import TrackerLoop
from livedic.stream.session.summary import format_summary


# How long a thread that wants the GIL waits before it asks the holder to give it up (Python's default: 5 ms).
GIL_SWITCH_INTERVAL_S = 0.0005


class Phase(enum.Enum):
    """Where a session stands; the value says it in words ("stopped while ...")."""
    CREATED = "setting up"
    CHECKING = "checking the outputs"
    OPENING_SOURCE = "opening the source"
    COMPILING = "compiling the tracking kernels"
    RENDERING = "rendering the simulated test"
    FIRST_FRAME = "waiting for the first frame"
    CHECKING_POINTS = "checking the points"
    OPENING_OUTPUTS = "opening the outputs"
    READY = "starting the session"
    RUNNING = "running"
    FINISHED = "finished"
    CLOSED = "closed"


# Phases in which this session's recording may exist without a session in it.
_RECORDING_OPENED = (Phase.OPENING_OUTPUTS, Phase.READY)


class NoFrame(SourceError):
    """The source ended before its first frame."""


class FirstFrameAhead:
    """A source whose first frame has been read already; iterating yields it, then the rest.

    The first frame gives the image size, so the points (ROI, P0, a points file,
    their number) are checked and P0 is placed before any output is opened: bad
    input leaves no file behind.

    Raises
    ------
    NoFrame
        The source ends before its first frame.
    SourceError
        It fails before its first frame.
    """

    def __init__(self, source, uri):
        self.source = source
        self._frames = iter(source)
        try:
            self.frame = next(self._frames)
        except StopIteration:
            raise NoFrame(f"{uri} delivered no frame") from None

    def __iter__(self):
        yield self.frame
        yield from self._frames

    @property
    def settings(self):
        return self.source.settings

    def close(self):
        self.source.close()


def warm_up(tracking):
    """Compile every numba kernel the tracker may use before the camera starts (cached: ~0.5 s later).

    A kernel first met mid-session compiles there (several seconds for the parallel
    ones, on a fresh installation): the frames queue up and are dropped. So the
    warm-up takes each path once: plain tracking, a seeded search, points lost while
    their neighbours are fine (solved again from the neighbours), and a jump no
    neighbour explains (the wide re-find and its fallback).
    """
    import cv2
    rng = np.random.default_rng(0)
    image = cv2.GaussianBlur(rng.uniform(0, 255, (128, 128)).astype(np.float32), (0, 0), 2.0)
    axis = np.arange(40.0, 89.0, 12.0)
    points = [(x, y) for y in axis for x in axis]
    # reference updates every 2 frames: the update and the composition back to frame 0 are taken too
    tracker = tracking.tracker(image, points, subset=min(tracking.subset, 31), refind_radius=8,
                               reference_update="every:2")
    shifted = np.roll(image, (1, 2), axis=(0, 1))
    partly = shifted.copy()
    partly[:, :60] = np.roll(image, (3, 4), axis=(0, 1))[:, :60]        # the left points jump by ~2 px
    tracker.track(image)
    tracker.track(shifted)
    tracker.track(partly)
    tracker.track(np.roll(image, (9, -7), axis=(0, 1)))                 # every point far off: wide re-find
    stage = StrainConfig(gauge_length=24.0).place(np.asarray(points, dtype=np.float64), p0=(64.0, 64.0),
                                                  roi=(40, 40, 49, 49), step=12.0, subset=DEFAULT_SUBSET)
    m = tracker.track(shifted)
    stage.compute(m.u, m.v, m.ok)
    field_fit.displacement_at(np.array([[64.0, 64.0]]), np.asarray(points, dtype=np.float64), m.u, m.v, m.ok, 12.0)
    # The prefilter reads a camera's 8- or 16-bit frame as it is, contiguous or a view of a larger buffer:
    # one kernel signature each, compiled here, not on the first frames
    for dtype in (np.uint8, np.uint16):
        frame = np.zeros((16, 16), dtype=dtype)
        for image in (frame, frame[:, :12]):
            bspline.prefilter(image)


def check_viewer_reachable(url, timeout_s=1.0):
    """ValueError (one line) unless something accepts TCP connections at ``url``'s host and port.

    ``--viewer connect URL`` with no viewer there would otherwise run the whole session
    while the Rerun SDK retries in the background, and end with a flush timeout.
    """
    import socket
    from urllib.parse import urlsplit

    from livedic.stream.view.viewer import DEFAULT_PORT
    try:
        parts = urlsplit(url)
        host = parts.hostname or "127.0.0.1"
        port = parts.port or (443 if parts.scheme.endswith("https") else DEFAULT_PORT)
    except ValueError as error:
        raise ValueError(f"--viewer connect {url}: not a valid URL ({error})") from None
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as error:
        reason = "connection refused" if isinstance(error, ConnectionRefusedError) else \
            (error.strerror or type(error).__name__)
        raise ValueError(f"--viewer connect {url}: no Rerun viewer is listening at {host}:{port} ({reason}); "
                         f"start one (rerun --bind 127.0.0.1 --port {port}), or use --viewer spawn, "
                         f"--viewer save FILE.rrd or --viewer none") from None


def is_live(source):
    """Whether frames come at a real clock's pace (``FrameSource.live``; a source without it is a file)."""
    return bool(getattr(source, "live", False))


def drop_policy(choice, source):
    """Queue policy: as chosen, or (auto) drop the oldest for live sources and block for files."""
    if choice != "auto":
        return {"oldest": DROP_OLDEST, "newest": DROP_NEWEST, "block": BLOCK}[choice]
    return DROP_OLDEST if is_live(source) else BLOCK


# Per-process keys that mean nothing in a recording (the host's monotonic clock).
_VOLATILE_METADATA = ("capture_monotonic_ns",)


def for_recording(frame):
    """``frame`` without the per-process metadata keys (same image, no copy)."""
    metadata = frame.metadata
    if not isinstance(metadata, dict) or not any(key in metadata for key in _VOLATILE_METADATA):
        return frame
    kept = {k: v for k, v in metadata.items() if k not in _VOLATILE_METADATA}
    return dataclasses.replace(frame, metadata=kept)


# Seconds without the first frame before the session says it is waiting for it.
FIRST_FRAME_NOTE_S = 3.0


def lost_upstream(acquisition):
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


def _needs_the_camera(load):
    """``--load synthetic`` reads the session's simulated camera: it opens after the source."""
    return load is not None and str(load).strip().lower() == "synthetic"


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

    def __init__(self, config, *, source=None, points=None, sinks=(), say=None, tracker_factory=None):
        self.config = config
        self._tracker_factory = tracker_factory if tracker_factory is not None else config.tracking.tracker
        self.phase = Phase.CREATED
        self._given_source = source
        self._given_points = points
        self._extra_sinks = list(sinks)
        self._say = say
        self.source = None
        self.recorder = None
        self.viewer = None
        self._view_child = None                 # the view's process, started before the outputs open
        self.queue = None
        self.acquisition = None
        self.loop = None
        self.bar = None
        self.progress = None
        self.points = None
        self.p0 = None
        self.placement = None
        self._setup = None                      # the set-up drawn in the view (stream.session.preview.SetupOverlay)
        self.strain = None
        self.poisson = None
        self.load = None
        self.load_stage = None
        self.publishers = []
        self.reference_updates = None
        self.fractures = None
        self.reference = None
        self.total_frames = config.frames
        self.render_seconds = None
        self.stopped_by = None
        self.sink_errors = []
        self.drop_policy = None
        self._ahead = None
        self._roi = None                       # the ROI asked for (given or the source's), None: whole image
        self._step = None
        self._given_xy = None
        self._settings = {}
        self._source_options = {}
        self._stop_requested = False
        self._previous_threads = None
        self._previous_switch_interval = None
        self._record_path_was_free = False
        self._summary = None
        self._summary_text = None

    # ----------------------------------------------------------------- messages

    def say(self, message):
        """One message for the user (``livedic: message`` on stderr, clear of the progress line)."""
        if self._say is not None:
            self._say(message)
            return
        if self.config.show_progress:
            sys.stderr.write("\r\033[K")
        print(f"livedic: {message}", file=sys.stderr, flush=True)

    def event(self, kind, message, level="info", *, tell=True):
        """An event: said (``tell``; "warning: " unless info), shown in the view and recorded as ``kind``."""
        if tell:
            self.say(("warning: " if level != "info" else "") + message)
        if self.viewer is not None:
            self.viewer.event(message, level=level)
        if self.recorder is not None:
            self.recorder.write_event(kind, message, level=level)

    # ----------------------------------------------------------------- lifecycle

    def prepare(self):
        """Everything before the session: see the module notes. Raises on bad input; nothing is left behind."""
        config = self.config
        import numba
        self._previous_threads = numba.get_num_threads()
        numba.set_num_threads(config.threads)
        # The tracking thread takes the GIL back from the output thread within this when it needs it
        # (between its kernels), instead of Python's default 5 ms: docs/guide/performance.md.
        self._previous_switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)

        self.phase = Phase.CHECKING
        if self._given_points is None:
            self._given_xy = config.points.xy
            if self._given_xy is None and config.points.points_file:
                self._given_xy = read_points_csv(config.points.points_file)
        self._check_outputs()
        if config.viewer.mode == "connect":
            check_viewer_reachable(config.viewer.target)
        self._record_path_was_free = bool(config.record) and not os.path.exists(config.record)

        if not _needs_the_camera(config.load):
            self._open_load()           # a bad --load URI or file: one line now, not after the source's set-up
        self.phase = Phase.OPENING_SOURCE
        scheme = config.scheme
        if scheme == "synthetic" and config.frames is not None and "frames=" not in config.source:
            self._source_options["frames"] = max(config.frames, 2)
        if self._given_source is not None:
            self.source = self._given_source
        else:
            self.source = sources.open_source(config.source, **self._source_options)
        self.phase = Phase.COMPILING
        if config.warm_up:
            warm_up(config.tracking)
        # Imported now (~0.5 s together), not between the first frame and the next: frames that come
        # meanwhile queue up and a paced source delivers them late, in a burst. The view's process imports
        # its own (~2 s) while the source renders or the camera opens.
        if config.viewer.mode != VIEWER_NONE:
            from livedic.stream.view.process import ViewChild
            self._view_child = ViewChild()
        if config.record:
            try:
                import livedic.acquire.recording.writer  # noqa: F401
            except ImportError:
                pass                    # _open_recorder says so
        if config.publish:
            from livedic.stream.publish import preload
            preload(config.publish_targets)     # pymodbus's import (0.1-0.3 s) would land between the first frames
        frames = getattr(self.source, "frames", None)
        if frames and isinstance(frames, int):
            self.total_frames = min(self.total_frames, frames) if self.total_frames else frames
        if hasattr(self.source, "prepare"):
            self.phase = Phase.RENDERING
            self._render()
        self.drop_policy = drop_policy(config.drop, self.source)

        # The first frame: its size checks the points before any output exists.
        self.phase = Phase.FIRST_FRAME
        # a triggered camera waits for its trigger without a limit: say so rather than sit silent
        waiting = threading.Timer(FIRST_FRAME_NOTE_S, self.say, [
            f"waiting for the first frame from {config.source} ({FIRST_FRAME_NOTE_S:g} s so far; a triggered camera "
            f"waits for its trigger; Ctrl-C to stop)"])
        waiting.daemon = True
        waiting.start()
        try:
            self._ahead = FirstFrameAhead(self.source, config.source)
        finally:
            waiting.cancel()
        self.phase = Phase.CHECKING_POINTS
        self._place_points(self._ahead.frame)

        if self.load is None:
            self._open_load()           # the simulator's own force law needs the simulator
        self._open_publishers()
        check_stage_order(self.stages)      # a stage reading what no earlier stage made: a bug, said before outputs
        self.phase = Phase.OPENING_OUTPUTS
        self._open_outputs(scheme)
        self.phase = Phase.READY

    def start(self):
        """Start acquisition (after ``prepare``)."""
        config = self.config
        self.queue = FrameQueue(config.queue, self.drop_policy)
        recorder = self.recorder
        on_frame = None
        if recorder is not None:
            def on_frame(item):          # in the acquisition thread: every frame, tracked or dropped
                started = time.perf_counter_ns()
                recorder.write_frame(for_recording(item.frame))
                self.loop.stats.stages.add("record frame", time.perf_counter_ns() - started)
        reconnect = None
        if config.reconnect:
            reconnect = Reconnect(reopen=lambda: sources.open_source(config.source, **self._source_options),
                                  retry_s=1.0, timeout_s=config.reconnect_timeout, on_event=self._source_event)
        self.acquisition = AcquisitionThread(self._ahead, self.queue, max_frames=config.frames, on_frame=on_frame,
                                             reconnect=reconnect)
        self.bar = ProgressBar(self.total_frames, enabled=config.show_progress)
        # The outputs, in the output thread at their own pace: Poisson's ratio (for the view), recording,
        # view, events, progress.
        sinks = []
        if has_pair(self.strain):
            self.poisson = ContractionWatch()       # after the load stage: the force picks the elastic range
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
                                                                                          self._ahead.frame),
                                stages=self.stages, sinks=sinks)
        self.phase = Phase.RUNNING
        if self._stop_requested:
            self.acquisition.stop()
        discard = getattr(self.source, "discard_buffered", None)
        if discard is not None:
            discard()           # a camera's frames sent while the session was prepared: stale (AravisSource)
        self.acquisition.start()

    def run(self):
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
            for publisher in self.publishers:
                self._close_quietly(publisher.finish, publisher.name)
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

    def execute(self):
        """``prepare``, ``start`` and ``run``; returns ``summary()`` (close the session afterwards)."""
        self.prepare()
        self.start()
        self.run()
        return self.summary()

    def stop(self, reason=None):
        """Stop acquisition (any thread; a signal handler): ``run`` then tracks what is queued and returns."""
        if reason is not None:
            self.stopped_by = reason
        self._stop_requested = True
        if self.acquisition is not None:
            self.acquisition.stop()

    def close(self):
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
        if self.load is not None:
            load, self.load = self.load, None
            self._close_quietly(load.close, "force source")
        if self.recorder is not None and not self.recorder.closed:
            self.recorder.close()
        if self.viewer is not None:
            viewer, self.viewer = self.viewer, None
            self._close_quietly(viewer.close, "Rerun stream")
        if self._view_child is not None:        # started, never used: the session ended before its outputs
            child, self._view_child = self._view_child, None
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

    def abandon(self):
        """Before ``start``: close what is open and remove the recording this session had just created."""
        remove = self.phase in _RECORDING_OPENED and self._record_path_was_free
        if self.recorder is not None:
            self._close_quietly(self.recorder.close, "recording")
        self.close()
        if remove:
            _remove_quietly(self.config.record)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # ----------------------------------------------------------------- results

    @property
    def stages(self) -> list[Stage]:
        """The measurement's stages in the order they run (the tracking thread): strain, strain out as soon as it
        exists, then force (a live force stream's stage may wait for its next sample). From ``prepare``."""
        return [stage for stage in (self.strain, *self.publishers, self.load_stage) if stage is not None]

    @property
    def stats(self):
        """The running ``SessionStats`` (from ``start``)."""
        return self.loop.stats if self.loop is not None else None

    @property
    def source_error(self):
        """Why acquisition stopped early (``SourceError``), or None."""
        return self.acquisition.error if self.acquisition is not None else None

    def summary(self):
        """The session's numbers (a dict; NaN where a number is missing), after ``run``."""
        return self._summary

    def summary_text(self):
        """The end-of-run text (a few aligned lines), after ``run``."""
        return self._summary_text

    # ----------------------------------------------------------------- stages

    def _check_outputs(self):
        """``OutputError`` (one line) for an output that cannot be written, before anything starts."""
        from livedic.stream.output.files import check_output_file
        config = self.config
        if config.record:
            check_output_file(config.record, "--record" if config.record_named else
                              "recording (--record FILE.mcap or --no-record to change)", create_folders=True)
        if config.viewer.mode == "save":
            check_output_file(config.viewer.target, "--viewer save", create_folders=True)
        if config.summary_json:
            check_output_file(config.summary_json, "--summary-json")

    def _render(self):
        """Render the simulated test ahead, with a progress line; says how long it took."""
        source = self.source
        rendered = getattr(source, "rendered_frames", source.frames)
        bar = ProgressBar(rendered, enabled=self.config.show_progress)
        started = time.perf_counter()
        try:
            source.prepare(progress=lambda done, n: bar.update(done, "rendering the simulated test"))
        finally:
            bar.close()
        self.render_seconds = time.perf_counter() - started
        cycling = f", cycled to make {source.frames}" if rendered != source.frames else ""
        pacing = f"delivery paced at {source.fps:g} fps" if source.options.get("pace", True) else "delivery unpaced"
        self.say(f"simulator: {rendered} frames rendered ahead in {self.render_seconds:.1f} s{cycling}; {pacing}")

    def _place_points(self, first):
        """The points on the first frame (P0 first), checked: inside the image, not too many."""
        config = self.config
        if self._given_points is not None:
            points = self._given_points(first.image) if callable(self._given_points) else self._given_points
            self.points = np.asarray(points, dtype=np.float64)
            self._place_strain(first.image.shape)
            return
        wanted = config.points
        if self._given_xy is not None and wanted.xy is None:
            wanted = dataclasses.replace(wanted, xy=self._given_xy)
        suggested = default_roi(self.source) if wanted.xy is None else None
        self.placement = place_points(first.image, wanted, subset=config.tracking.subset, suggested_roi=suggested)
        check_point_count(len(self.placement.points), wanted.max_points, how=wanted.how(self.placement.step),
                          frames=self.total_frames, recording=config.record is not None)
        self.p0 = self.placement.p0
        self.points = self.placement.points
        self._step = self.placement.step
        whole = self.placement.placed_by in (PlacedBy.POINTS, PlacedBy.WHOLE_IMAGE)
        self._roi = None if whole else self.placement.bounds
        self._place_strain(first.image.shape)
        # the set-up as livedic preview draws it: its advice said now, the overlay in the view
        self._setup = setup_overlay(first.image, self.placement, self.strain, subset=config.tracking.subset,
                                    scale=config.strain.scale, source=config.source,
                                    bit_depth=(first.metadata or {}).get("bit_depth"),
                                    pixel_format=first.pixel_format)

    def _open_load(self):
        """The machine's force source (``--load``), checked before any output opens (one line if bad).

        Opened before the frame source, except ``synthetic`` (the simulator's law needs the simulator).
        """
        config = self.config
        if config.load is None:
            return
        from livedic.stream.stages.force import LoadStage, open_session_load
        self.load = open_session_load(config.load, offset_s=config.load_offset, camera=self.source)
        area = config.area_mm2
        if area is None:
            area = (getattr(self.load, "specimen", None) or {}).get("A0_mm2")
        self.load_stage = LoadStage(self.load, area, lambda kind, message, level: self.event(
            kind, message, level, tell=level != "info"))

    def _open_publishers(self):
        """The ``--publish`` outlets (sockets, Modbus servers listening), before any output opens.

        ValueError (one line) when one cannot open (a host that does not resolve, a port in use):
        nothing is recorded then.
        """
        config = self.config
        if not config.publish:
            return
        from livedic.stream.publish import open_publishers
        names = [e.name for e in self.strain.extensometers] if self.strain is not None else []
        self.publishers = open_publishers(config.publish_targets, names, lambda kind, message, level: self.event(
            kind, message, level, tell=level != "info"))
        for publisher in self.publishers:
            self.say(publisher.outlet.note())

    def _place_strain(self, shape):
        """The strain stage on the points as the tracker uses them (pixel centres); ValueError for an
        extensometer end off the points, before any output opens."""
        from livedic.dic.correlation import snap_points
        xs, ys = snap_points(self.points)
        used = np.column_stack([xs, ys]).astype(np.float64)
        if self._roi is not None:
            roi = self._roi
        elif len(used):
            lo, hi = used.min(axis=0), used.max(axis=0)
            roi = (lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
        else:
            roi = (0, 0, shape[1], shape[0])
        self.strain = self.config.strain.place(used, p0=used[0], roi=roi, step=self._step,
                                               subset=self.config.tracking.subset)

    def _metadata(self):
        """The session metadata the recording starts with."""
        config = self.config
        wanted = config.points
        p0 = self.p0.xy if self.p0 is not None else tuple(self.points[0])
        metadata = {
            "command": config.command, "source_uri": config.source, "source_settings": self._settings,
            "roi": list(self._roi) if self._roi else "full image", "step": wanted.step, "grid_step": self._step,
            "region": self.placement.as_metadata() if self.placement is not None else None,
            "n_points_wanted": wanted.n_points, "points_file": wanted.points_file, "p0": list(p0),
            "p0_choice": self.p0.describe() if self.p0 is not None else "given with the points",
            **config.tracking.as_dict(),
            "queue_size": config.queue, "drop_policy": self.drop_policy, "point_ids": "P0 is point 0",
            "threads": config.threads, "reconnect": config.reconnect, "reconnect_timeout_s": config.reconnect_timeout,
            **config.strain.as_metadata(),
            "vsg_px": None, "extensometers": [],            # the strain stage's (its metadata below)
            "load": config.load, "load_offset_s": config.load_offset, "area_mm2": config.area_mm2,
            "publish": list(config.publish or ()),          # where the strain went (--publish)
        }
        for stage in self.stages:
            metadata.update(stage.metadata())               # a key named above keeps its place
        return metadata

    def _open_outputs(self, scheme):
        from livedic.stream.view.camera_image import IMAGE_MAX_HZ
        from livedic.stream.view.logger import RerunLogger
        from livedic.stream.view.process import ViewProcess
        config = self.config
        self._settings = _safe_settings(self.source)
        if config.record:
            # The simulator's clock starts at 0 ns; cameras keep the recorder's default (Unix time).
            self.recorder = self._open_recorder(config.record, self._metadata(),
                                                start_time_ns=0 if scheme == "synthetic" else None)
        if config.viewer.note:
            self.say(config.viewer.note)
        # the view logs in a process of its own: its Python never holds the GIL the tracking thread needs
        options = dict(recording_name=config.name, image_max_side=config.image_max_side,
                       color_range=config.color_range, low_zncc=config.tracking.refind_zncc,
                       thin_when_behind=self.drop_policy != BLOCK,
                       image_max_hz=IMAGE_MAX_HZ if self.drop_policy != BLOCK else None,
                       on_error=lambda message: self.event("viewer_file_stopped", message, "warning"))
        if self._view_child is None:
            self.viewer = RerunLogger(config.viewer.mode, config.viewer.target, **options)
        else:
            child, self._view_child = self._view_child, None
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
        return Recorder(path, metadata, start_time_ns=start_time_ns, on_error=recording_stopped)

    def _make_tracker(self, frame):
        """The tracker on the reference frame (the first tracked), the stages set up on it; tells the view and the
        recording."""
        config = self.config
        tracker = self._tracker_factory(frame.image, self.points)
        roi_used = self._roi if self._roi is not None else (0, 0, frame.image.shape[1], frame.image.shape[0])
        self.reference = Reference(frame_index=frame.index, points=self.points, roi=tuple(int(v) for v in roi_used),
                                   step=self._step, shape=frame.image.shape, timestamp_ns=frame.timestamp_ns)
        for stage in self.stages:
            stage.on_reference(self.reference)
        if self.p0 is None:
            return tracker                      # given points: the caller's session (a replay) says what they are
        wanted = config.points
        placed = self.placement.describe()
        if self._given_xy is not None:
            placed += f" from {wanted.points_file or 'the given points'}"
        note = f"reference frame {frame.index}: {placed}; {self.p0.describe()}"
        has_truth = callable((frame.metadata or {}).get("truth"))
        if self.viewer is not None:
            self.viewer.start(image_shape=frame.image.shape, roi=self.reference.roi, p0_index=0, points=self.points,
                              has_truth=has_truth, title=f"livedic run: {config.source}",
                              source_settings=self._settings, strain=self.strain, load=self.load_stage,
                              setup=self._setup)
        # an automatic choice is said: the user did not say where the points go
        self.event("note", note, tell=self.placement is not None and self.placement.placed_by is PlacedBy.SPECIMEN)
        for line in self._setup.checks() if self._setup is not None else ():
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
            render_s=round(self.render_seconds, 3) if self.render_seconds is not None else None,
            strain=({**self.strain.summary(), **(self.poisson.summary() if self.poisson is not None else {})}
                    if self.strain is not None else None),
            force=self.load_stage.summary() if self.load_stage is not None else None,
            publish=[publisher.summary() for publisher in self.publishers] or None,
            reference_update=config.tracking.reference_update,
            **(self.reference_updates.summary() if self.reference_updates is not None else {}),
            **(self.fractures.summary() if self.fractures is not None else {}))
        return summary

    def _close_quietly(self, close, what):
        """``close()``; a failure is one warning line (the session's outcome and summary still go out)."""
        try:
            close()
        except Exception as error:  # noqa: BLE001 - closing a display or a source must not hide the summary
            self.say(f"warning: closing the {what} failed: {type(error).__name__}: {error}")
