"""A session's preparation: the outputs checked, the sources opened, the first frame read, the points placed.

``Preparation(config, ...).run()`` does, in order, what must hold before any output exists: the outputs
writable, a ``--viewer connect`` reachable, the force source (``--load``) and the frame source opened, the
tracking kernels compiled, the simulated test rendered, the first frame read (``FirstFrameAhead``), the points
and P0 placed on it and checked, the strain stage placed on them, the ``--publish`` outlets opened, and the
order of the stages checked. Bad input raises (``ValueError``, ``SourceError``: one line); what was opened stays
in its attributes for the session to close. ``stream.session.session.Session.prepare`` runs it, then opens the
recording and the view.
"""

import dataclasses
import enum
import os
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from livedic.acquire import sources
from livedic.acquire.base import SourceError
from livedic.dic import DEFAULT_SUBSET, bspline
from livedic.dic.strain import field_fit
from livedic.stream.session.stereo import STEREO_KEY, stereo_calibration
from livedic.stream.stages.stereo_strain import StereoStrainStage, stereo_strain_config
from livedic.stream.pipeline.frame_queue import BLOCK, DROP_NEWEST, DROP_OLDEST
from livedic.stream.pipeline.progress import ProgressBar
from livedic.stream.pipeline.stage import Stage, check_stage_order
from livedic.stream.session.config import CAMERA_SCHEMES, VIEWER_NONE
from livedic.stream.session.points import PlacedBy, check_point_count, default_roi, place_points, read_points_csv
from livedic.stream.session.preview import setup_overlay
from livedic.stream.stages.noise_floor import NoiseFloorStage
from livedic.stream.stages.strain import StrainConfig


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


# Seconds without the first frame before the session says it is waiting for it.
FIRST_FRAME_NOTE_S = 3.0


def _needs_the_camera(load):
    """``--load synthetic`` reads the session's simulated camera: it opens after the source."""
    return load is not None and str(load).strip().lower() == "synthetic"


class Preparation:
    """Everything before a session starts (see the module notes); ``run`` does it, raising on bad input.

    Parameters
    ----------
    config : stream.session.config.SessionConfig
    source : FrameSource, optional
        An opened source to use instead of opening ``config.source``.
    points : ndarray (N, 2) or callable, optional
        Track exactly these points (P0 first), or ``points(reference_image)``'s.
    say : callable
        ``say(message)``: a message for the user.
    event : callable
        ``event(kind, message, level, tell=...)``: the session's event (said, shown, recorded).

    Attributes
    ----------
    phase : Phase
        How far it got (a stop while preparing says where).
    source, load : the opened frame and force sources (None until opened)
    ahead : FirstFrameAhead
        The source with its first frame read.
    points, p0, placement, roi, step, given_xy, setup
        The points (P0 first), where P0 is and why, how they were placed, the region asked for (None: the
        whole image), the grid step, the points given by ``--points``, the set-up overlay for the view.
    strain, noise_floor, load_stage, publishers
        The stages (``stages``: in the order they run).
    static_frames : int
        Frames after the reference measured for the noise floor (``SessionConfig.static_frames_wanted``, or the
        simulator's own ``static=``).
    max_frames : int or None
        Frames the session takes at most: ``--frames``, plus the static frames for the simulator (whose
        ``--frames`` is the test's length).
    total_frames, render_seconds, drop_policy, source_options, view_child, record_path_was_free
    """

    def __init__(self, config: Any, *, source: Any = None, points: Any = None, say: Callable[[str], None],
                 event: Callable[..., None]) -> None:
        self.config = config
        self._given_source = source
        self._given_points = points
        self._say = say
        self._event = event
        self.phase = Phase.CREATED
        self.source: Any = None
        self.ahead: Any = None                 # FirstFrameAhead, from run
        self.points: Any = None                # ndarray (N, 2), P0 first
        self.p0: Any = None
        self.placement: Any = None
        self.roi: tuple | None = None          # the ROI asked for (given or the source's), None: whole image
        self.step: Any = None
        self.given_xy: Any = None
        self.setup: Any = None                 # the set-up drawn in the view (stream.session.preview.SetupOverlay)
        self.strain: Any = None
        self.noise_floor: Any = None
        self.static_frames = 0
        self.max_frames: int | None = config.frames
        self.load: Any = None
        self.load_stage: Any = None
        self.publishers: list = []
        self.total_frames: int | None = config.frames
        self.render_seconds: float | None = None
        self.drop_policy: str | None = None
        self.source_options: dict[str, Any] = {}
        self.view_child: Any = None            # the view's process, started before the outputs open
        self.record_path_was_free = False
        self.stereo: Any = None                # a stereo source's rig: StereoCalibration (None: one camera)
        self.stereo_calibration_from: str | None = None

    @property
    def stages(self) -> list[Stage]:
        """The measurement's stages in the order they run (the tracking thread): strain, strain out as soon as it
        exists, then force (a live force stream's stage may wait for its next sample)."""
        return [stage for stage in (self.strain, self.noise_floor, *self.publishers, self.load_stage)
                if stage is not None]

    def run(self) -> None:
        """Check, open, read and place (see the module notes). Raises on bad input."""
        config = self.config
        self.phase = Phase.CHECKING
        if self._given_points is None:
            self.given_xy = config.points.xy
            if self.given_xy is None and config.points.points_file:
                self.given_xy = read_points_csv(config.points.points_file)
        self._check_outputs()
        if config.viewer.mode == "connect":
            check_viewer_reachable(config.viewer.target)
        self.record_path_was_free = bool(config.record) and not os.path.exists(config.record)

        if not _needs_the_camera(config.load):
            self._open_load()           # a bad --load URI or file: one line now, not after the source's set-up
        self.phase = Phase.OPENING_SOURCE
        if config.scheme == "synthetic" and config.frames is not None and "frames=" not in config.source:
            self.source_options["frames"] = max(config.frames, 2)
        self.static_frames = config.static_frames_wanted
        if config.scheme in ("synthetic", "stereo") and "static=" not in config.source:
            self.source_options["static"] = self.static_frames     # a stereo pair's simulated views render them
        if self._given_source is not None:
            self.source = self._given_source
        else:
            self.source = sources.open_source(config.source, **self.source_options)
        if getattr(self.source, "stereo", False):
            if config.strain.calibration is not None:
                raise ValueError("--calibration holds one camera's calibration but the source is stereo: calibrate "
                                 "the rig from target pairs (livedic calibrate --left ... --right ...) and give that")
            self.stereo, self.stereo_calibration_from = stereo_calibration(config.rig, dict(self.source.settings or {}))
        elif config.rig is not None:
            raise ValueError("--calibration holds a stereo rig's calibration (two cameras) but the source is one "
                             "camera: give a stereo source (--source stereo:LEFT,RIGHT) or that camera's own "
                             "calibration")
        self._count_static_frames()
        self.phase = Phase.COMPILING
        if config.warm_up:
            warm_up(config.tracking)
        self._preload()
        frames = getattr(self.source, "frames", None)
        if frames and isinstance(frames, int):
            self.total_frames = min(self.total_frames, frames) if self.total_frames else frames
        if hasattr(self.source, "prepare"):
            self.phase = Phase.RENDERING
            self._render()
        self.drop_policy = drop_policy(config.drop, self.source)

        # The first frame: its size checks the points before any output exists.
        self.phase = Phase.FIRST_FRAME
        self.ahead = self._first_frame()
        self.phase = Phase.CHECKING_POINTS
        self._place_points(self.ahead.frame)

        if self.load is None:
            self._open_load()           # the simulator's own force law needs the simulator
        self._open_publishers()
        check_stage_order(self.stages)  # a stage reading what no earlier stage made: a bug, said before outputs

    def _count_static_frames(self):
        """The static frames the source gives (the simulator's ``static=``) or the user holds still (said)."""
        config = self.config
        simulated = getattr(self.source, "static", None)
        if isinstance(simulated, int):
            self.static_frames = simulated
            if config.frames is not None:
                self.max_frames = config.frames + simulated      # --frames is the test's length
        elif self.static_frames and _films(config.source):
            pairs = "pairs" if getattr(self.source, "stereo", False) else "frames"
            self._say(f"hold the specimen still: taking {self.static_frames} static {pairs} after the reference "
                      f"for the noise floor (--static-frames 0: none)")

    def _preload(self):
        """Imported now (~0.5 s together), not between the first frame and the next: frames that come meanwhile
        queue up and a paced source delivers them late, in a burst. The view's process imports its own (~2 s)
        while the source renders or the camera opens."""
        config = self.config
        if config.viewer.mode != VIEWER_NONE:
            from livedic.stream.view.process import ViewChild
            self.view_child = ViewChild()
        if config.record:
            try:
                import livedic.acquire.recording.writer  # noqa: F401
            except ImportError:
                pass                    # the session's recorder says so
        if config.publish:
            from livedic.stream.publish import preload
            preload(config.publish_targets)     # pymodbus's import (0.1-0.3 s) would land between the first frames

    def _first_frame(self):
        """The source with its first frame read; a triggered camera waits for its trigger without a limit: said."""
        config = self.config
        waiting = threading.Timer(FIRST_FRAME_NOTE_S, self._say, [
            f"waiting for the first frame from {config.source} ({FIRST_FRAME_NOTE_S:g} s so far; a triggered camera "
            f"waits for its trigger; Ctrl-C to stop)"])
        waiting.daemon = True
        waiting.start()
        try:
            return FirstFrameAhead(self.source, config.source)
        finally:
            waiting.cancel()

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
        test_frames = getattr(source, "test_frames", source.frames)
        static = getattr(source, "static", 0) or 0
        bar = ProgressBar(rendered + static, enabled=self.config.show_progress)
        started = time.perf_counter()
        try:
            source.prepare(progress=lambda done, n: bar.update(done, "rendering the simulated test"))
        finally:
            bar.close()
        self.render_seconds = time.perf_counter() - started
        cycling = f", cycled to make {test_frames}" if rendered != test_frames else ""
        still = f" after {static} static frames (the noise floor)" if static else ""
        pacing = f"delivery paced at {source.fps:g} fps" if source.options.get("pace", True) else "delivery unpaced"
        self._say(f"simulator: {rendered} frames of the test rendered ahead{still} in {self.render_seconds:.1f} s"
                  f"{cycling}; {pacing}")

    def _place_points(self, first):
        """The points on the first frame (P0 first), checked: inside the image, not too many."""
        config = self.config
        if self._given_points is not None:
            points = self._given_points(first.image) if callable(self._given_points) else self._given_points
            self.points = np.asarray(points, dtype=np.float64)
            self._place_strain(first.image.shape)
            return
        wanted = config.points
        if self.given_xy is not None and wanted.xy is None:
            wanted = dataclasses.replace(wanted, xy=self.given_xy)
        suggested = default_roi(self.source) if wanted.xy is None else None
        self.placement = place_points(first.image, wanted, subset=config.tracking.subset, suggested_roi=suggested)
        check_point_count(len(self.placement.points), wanted.max_points, how=wanted.how(self.placement.step),
                          frames=self.total_frames, recording=config.record is not None)
        self.p0 = self.placement.p0
        self.points = self.placement.points
        self.step = self.placement.step
        whole = self.placement.placed_by in (PlacedBy.POINTS, PlacedBy.WHOLE_IMAGE)
        self.roi = None if whole else self.placement.bounds
        self._place_strain(first.image.shape)
        # the set-up as livedic preview draws it: its advice said now, the overlay in the view
        self.setup = setup_overlay(first.image, self.placement, self.strain, subset=config.tracking.subset,
                                    scale=config.strain.px_per_mm, source=config.source,
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
        self.load_stage = LoadStage(self.load, area, lambda kind, message, level: self._event(
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
        self.publishers = open_publishers(config.publish_targets, names, lambda kind, message, level: self._event(
            kind, message, level, tell=level != "info"))
        for publisher in self.publishers:
            self._say(publisher.outlet.note())

    def _place_strain(self, shape):
        """The strain stage on the points as the tracker uses them (pixel centres); ValueError for an
        extensometer end off the points, before any output opens."""
        from livedic.dic.correlation import snap_points
        xs, ys = snap_points(self.points)
        used = np.column_stack([xs, ys]).astype(np.float64)
        if self.roi is not None:
            roi = self.roi
        elif len(used):
            lo, hi = used.min(axis=0), used.max(axis=0)
            roi = (lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
        else:
            roi = (0, 0, shape[1], shape[0])
        if self.stereo is not None:        # strain on the surface and extensometers in space (placed as in 2D)
            strain = stereo_strain_config(self.config.strain, self.stereo)
            self.strain = StereoStrainStage.of(strain.place(used, p0=used[0], roi=roi, step=self.step,
                                                            subset=self.config.tracking.subset))
        else:
            self.strain = self.config.strain.place(used, p0=used[0], roi=roi, step=self.step,
                                                   subset=self.config.tracking.subset, image_size=(shape[1], shape[0]))
        if self.static_frames:
            # stereo: U, V, W in mm from the 3D points (the rig's nominal px/mm only places the extensometers)
            stereo = self.stereo is not None
            self.noise_floor = NoiseFloorStage(self.static_frames, None if stereo else self.config.strain.px_per_mm,
                                               stereo=stereo)

    def _frame_size(self) -> list[int] | None:
        """[W, H] of the first frame (the report's image size), None before it was read."""
        if self.ahead is None:
            return None
        height, width = self.ahead.frame.image.shape[:2]
        return [int(width), int(height)]

    def metadata(self, source_settings: dict) -> dict[str, Any]:
        """The session metadata the recording starts with (``source_settings``: the opened source's)."""
        config = self.config
        wanted = config.points
        p0 = self.p0.xy if self.p0 is not None else tuple(self.points[0])
        # a stereo session's strain is measured on the specimen's surface: its settings as the stage uses them
        strain = config.strain if self.stereo is None else stereo_strain_config(config.strain, self.stereo)
        metadata = {
            "command": config.command, "source_uri": config.source, "source_settings": source_settings,
            "frame_size": self._frame_size(),
            "roi": list(self.roi) if self.roi else "full image", "step": wanted.step, "grid_step": self.step,
            "region": self.placement.as_metadata() if self.placement is not None else None,
            "n_points_wanted": wanted.n_points, "points_file": wanted.points_file, "p0": list(p0),
            "p0_choice": self.p0.describe() if self.p0 is not None else "given with the points",
            **config.tracking.as_dict(),
            "queue_size": config.queue, "drop_policy": self.drop_policy, "point_ids": "P0 is point 0",
            "threads": config.threads, "reconnect": config.reconnect, "reconnect_timeout_s": config.reconnect_timeout,
            **strain.as_metadata(),
            "vsg_px": None, "extensometers": [],            # the strain stage's (its metadata below)
            "load": config.load, "load_offset_s": config.load_offset, "area_mm2": config.area_mm2,
            "publish": list(config.publish or ()),          # where the strain went (--publish)
        }
        if self.stereo is not None:
            metadata[STEREO_KEY] = {"calibration": self.stereo.to_dict(), "calibration_from": self.stereo_calibration_from}
            metadata["calibration"] = None                  # the 2D one's key: the rig's is above
        for stage in self.stages:
            metadata.update(stage.metadata())               # a key named above keeps its place
        return metadata


def _films(uri: str) -> bool:
    """Whether the source is a camera, or a stereo pair of cameras (a user must hold the specimen still)."""
    from livedic.acquire.sources import parse_scheme, parse_stereo_uri
    scheme = parse_scheme(uri)
    if scheme == "stereo":
        return all(parse_scheme(view) in CAMERA_SCHEMES for view in parse_stereo_uri(uri)[:2])
    return scheme in CAMERA_SCHEMES
