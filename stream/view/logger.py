"""``RerunLogger``: the session sink that draws each frame in Rerun, the only caller of ``rerun`` logging.

What it draws (the entity tree, the colour rules, the point sizes, the layout and the viewer modes) is
described in docs/guide/live-view.md. ``start`` opens the viewer or file (``viewer``) with the layout
(``blueprint``) and logs what does not change; each call logs one ``stream.pipeline.frame_result.FrameResult``;
``close`` flushes and ends the stream. One logging thread; a background thread only flushes. A live session
runs the logger in a process of its own (``process``).
"""

from __future__ import annotations

import os
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from livedic.dic.strain.extensometer import AXIAL
from livedic.dic.tensile.properties import FRACTURE_DROP
from livedic.dic.tracking.tracker import REFIND_ZNCC
from livedic.stream.stages.force import axial_strain
from livedic.stream.view.blueprint import axial_transverse_pair, make_blueprint
from livedic.stream.view.camera_image import CameraImagePacing, display_image, display_scale
from livedic.stream.view.colour_bar import LEGENDS, colour_bar_image
from livedic.stream.view.colour_scale import (
    MIN_COLOUR_LIMIT_MM, MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_STRAIN, NICE_MANTISSAS, colormap_lut, grow_limits, pack_colours,
    typical_spacing)
from livedic.stream.view.entities import (
    BLACK, CAMERA_IMAGE, CAMERA_P0, CAMERA_ROI, CAMERA_ROI_LABEL, DROPS, ERROR, EVENTS, EXTENSOMETER_DRAW_ORDER,
    EXTENSOMETER_LINES, EXTENSOMETER_LOST_COLOUR, EXTENSOMETER_STRAIN, FIELD_EYY, FIELD_U, FIELD_V, FIT_COLOUR, FORCE,
    LABEL_CHARACTER, LABEL_GAP, LABEL_HEIGHT, LATENCY, LEGEND_EYY, LEGEND_U, LEGEND_V, LEGEND_W, LIMITS_EYY, LOST, LOST_COLOUR,
    LOW_ZNCC, LOW_ZNCC_COLOUR, MARKER_DRAW_ORDER, NO_STRAIN_COLOUR, P0, QUALITY, SERIES_STYLE, STRAIN_XY, STRAIN_XY_FIT,
    STRESS_COLOURS, STRESS_STRAIN, SUMMARY, THROUGHPUT, TIMELINE_FRAME, TIMELINE_TIME, TRACKING, darker,
    extensometer_colour)
from livedic.stream.view.setup_view import SetupOverlay, SetupView
from livedic.stream.view.stereo_view import StereoView
from livedic.stream.view.viewer import APPLICATION_ID, DEFAULT_PORT, RrdFile, spawn_viewer
from livedic.stream.view.xy_plot import MIN_XY_LIMIT_STRAIN, MIN_XY_LIMIT_STRESS_MPA, SeriesColumns, XYPlot

if TYPE_CHECKING:
    import rerun as rerun_sdk
    import rerun.blueprint as rrb

    from livedic.acquire.base import Frame
    from livedic.dic.result import Measurement
    from livedic.dic.stereo import StereoMeasurement
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.dic.tensile.poisson import ContractionRatio
    from livedic.stream.pipeline.frame_result import FrameResult, SessionStats
    from livedic.stream.stages.force import LoadStage
    from livedic.stream.stages.strain import StrainStage

Limits = tuple[float, float]


def _label_anchors(first: np.ndarray, second: np.ndarray, labels: Sequence[str], side: float) -> np.ndarray:
    """Where each extensometer's label goes: beyond its second end, clear of the other lines' labels.

    A mostly vertical line's label sits under its end (over it, for a line drawn upwards); a mostly horizontal
    line's label starts just beyond its end and is raised above the line. So the labels of an axial and a
    transverse extensometer crossing at P0 never meet each other or P0's label (under P0), however short the
    transverse one is. ``first``, ``second``: (N, 2) ends in scene units; ``side``: the image side in them.
    """
    step = second - first
    vertical = np.abs(step[:, 1]) >= np.abs(step[:, 0])
    down, right = np.where(step[:, 1] >= 0, 1.0, -1.0), np.where(step[:, 0] >= 0, 1.0, -1.0)
    half_width = np.array([0.5 * len(label) * LABEL_CHARACTER for label in labels])
    dx = np.where(vertical, 0.0, right * (half_width + LABEL_GAP))
    dy = np.where(vertical, np.where(down > 0, LABEL_GAP, -LABEL_GAP - LABEL_HEIGHT),
                  -LABEL_GAP - LABEL_HEIGHT)
    return second + side * np.column_stack([dx, dy])


def _poisson_text(poisson: ContractionRatio | None) -> str:
    """Poisson's ratio's elastic fit in a few words: "Poisson 0.300 +- 0.002 (elastic fit, frames 0-45)"."""
    if poisson is None:
        return "Poisson: no fit yet"
    if not np.isfinite(poisson.value):
        return f"Poisson: n/a ({poisson.reason.value if poisson.reason is not None else 'no fit'})"
    return (f"Poisson {poisson.value:.3f} +- {poisson.standard_error:.3f} "
            f"(elastic fit, frames {poisson.frames[0]}-{poisson.frames[1]})")


class RerunLogger:
    """Sends a live session to Rerun (docs/guide/live-view.md); a session sink (``stream.pipeline.sinks``).

    Parameters
    ----------
    mode : str
        "spawn", "connect", "save" or "none" (from ``parse_viewer``).
    target : str or None
        URL for "connect", file path for "save".
    recording_name : str
        Shown in the viewer's recording list.
    image_max_side : int
        The camera image is downsampled by an integer factor until its larger side is at most this.
    image_every : int
        Log the camera image every this many frames (fields and scalars are logged every frame).
    image_max_hz : float or None
        A live session: the camera image at most this many times a second of the frames' own clock
        (``IMAGE_MAX_HZ``; a 100 fps camera is drawn at 25); fields, markers and plots every frame.
        None: every frame's image (files, replays).
    flush_interval_s : float
        Seconds between flushes of the stream (done by a background thread).
    color_range : (float, float) or None
        Fixed colour limits (lo, hi) in px for u and v; None: the automatic scale (docs/guide/live-view.md).
    low_zncc : float
        Ok points whose ZNCC is below this are counted and marked as "low ZNCC" (default: the
        tracker's default ``refind_zncc``).
    thin_when_behind : bool
        A live session: while results wait for the session's output thread behind this one
        (``FrameResult.output_backlog``), leave out the camera image (at most ``IMAGE_SKIP_MAX``
        frames in a row), the costliest part of a frame's view; every frame's fields, markers and
        plots are drawn. Off: every frame's image too (files, replays).
    on_error : callable, optional
        ``on_error(message)`` once when the .rrd of mode "save" cannot be written (a full disk): one
        line, from the file's writer thread; logging stops there, the file keeps what was written
        (``RrdFile``).

    Raises
    ------
    ValueError
        A viewer that cannot be started or reached, or a colour range that is not two finite numbers
        with lo < hi.
    """

    name = "Rerun view"
    stage = "view"
    required = False

    def __init__(self, mode: str, target: str | None = None, *, recording_name: str = "livedic session",
                 image_max_side: int = 512, image_every: int = 1, image_max_hz: float | None = None,
                 flush_interval_s: float = 1.0, color_range: Sequence[float] | None = None,
                 low_zncc: float = REFIND_ZNCC, thin_when_behind: bool = False,
                 on_error: Callable[[str], None] | None = None) -> None:
        if color_range is not None:
            lo, hi = (float(value) for value in color_range)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"colour range {lo:g},{hi:g}: give LO,HI with LO below HI, both finite "
                                 f"(e.g. --color-range -2,2)")
        self.color_range: Limits | None = (lo, hi) if color_range is not None else None
        self.low_zncc = float(low_zncc)
        self.mode = mode
        self.target = target
        self.image_max_side = int(image_max_side)
        self.image_max_hz = image_max_hz
        self.images = CameraImagePacing(image_every=image_every, image_max_hz=image_max_hz,
                                        thin_when_behind=thin_when_behind)
        self.flush_interval_s = flush_interval_s
        self.rec: rerun_sdk.RecordingStream | None = None
        self.viewer_process: subprocess.Popen[bytes] | None = None
        self._flusher: threading.Thread | None = None
        self._closing = threading.Event()
        self._scale = 1
        self._lut = np.zeros((0, 3), dtype=np.uint8)    # the colour map (mode "none" draws nothing)
        self._done_times: deque[tuple[int, int]] = deque()
        self._t0_ns: int | None = None
        self._p0: int | None = None
        start_limits = self.color_range or (-MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_PX)
        self.colour_limits: dict[str, Limits] = {LEGEND_U: start_limits, LEGEND_V: start_limits,   # what the bars show
                                                 LEGEND_EYY: (-MIN_COLOUR_LIMIT_STRAIN, MIN_COLOUR_LIMIT_STRAIN),
                                                 LEGEND_W: (-MIN_COLOUR_LIMIT_MM, MIN_COLOUR_LIMIT_MM)}
        self._limits_logged: dict[str, Limits] = {}
        self._radius_key: tuple[Any, ...] | None = None
        self._radius = 4.0
        self._image_side = 0                    # the camera image's larger side (px), from start()
        # the last ok displacement per point, to place lost markers
        self._last_u: np.ndarray | None = None
        self._last_v: np.ndarray | None = None
        self._flagged_shown = {LOST: False, LOW_ZNCC: False}
        self._tracking_text: str | None = None
        self._first_bars: dict[str, tuple[Limits, np.ndarray]] = {}  # legend -> (limits, image) drawn by start()
        self._no_strain_colour = pack_colours([NO_STRAIN_COLOUR])[0]
        self._extensometer_colours = self._label_colours = np.zeros(0, dtype=np.uint32)   # from _start_strain
        self._lost_colour = self._lost_label_colour = np.uint32(0)
        self._strain: StrainStage | None = None  # the session's stream.stages.strain.StrainStage, from start()
        self._stereo: StereoView | None = None   # a stereo session's right camera and 3D panels, from start()
        self._end_u = self._end_v = np.zeros(0)  # last known displacement of each extensometer end
        self._series_shown: dict[str, bool] = {}  # extensometer name -> its strain series has a value now
        self._xy_pair: tuple[int, int] | None = None  # (axial index, transverse index) for the transverse-vs-axial plot
        self._strain_xy: XYPlot | None = None                  # that plot (XYPlot), from start()
        self._fit_drawn: tuple[float, Any] | None = None  # (value, frames) of the elastic fit drawn on it
        self._load: LoadStage | None = None  # the session's stream.stages.force.LoadStage, from start()
        self._stress_xy: XYPlot | None = None  # the stress-strain plot (XYPlot): with a load, A0 and "axial"
        self._force_shown = False
        self._fractured = False                  # a fracture was detected (result.fracture)
        self._broken = False                     # ... and the force fell below FRACTURE_DROP of its maximum
        self._max_force_N = -np.inf
        self.log_seconds = 0.0
        self.frames_logged = 0
        self._file: RrdFile | None = None                       # RrdFile of mode "save"
        self.on_error = on_error
        if mode == "none":
            return
        import rerun as rr
        self.rr: ModuleType = rr
        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.rec.send_recording_name(recording_name)
        self._lut = colormap_lut()
        self._packed_lut = pack_colours(self._lut)
        self._series = SeriesColumns(rr, self.rec)

    @property
    def enabled(self) -> bool:
        return self.rec is not None and not (self._file is not None and self._file.error)

    @property
    def _stream(self) -> rerun_sdk.RecordingStream:
        """The open stream: what draws runs only while ``enabled``."""
        assert self.rec is not None
        return self.rec

    @property
    def file_error(self) -> str | None:
        """Why the .rrd of mode "save" stopped (a full disk), or None."""
        return self._file.error if self._file is not None else None

    def _file_failed(self, message: str) -> None:
        """The .rrd could not be written (full disk): told once; logging stops, the session goes on."""
        if self.on_error is not None:
            self.on_error(message)

    # ----------------------------------------------------------------- setup
    def start(self, *, image_shape: tuple[int, int], roi: Sequence[float] | None = None, p0_index: int | None = None,
              points: np.ndarray | None = None, has_truth: bool = False, title: str | None = None,
              source_settings: Mapping[str, object] | None = None, strain: StrainStage | None = None,
              load: LoadStage | None = None, setup: SetupOverlay | None = None, stereo: bool = False) -> None:
        """Open the sink and log what does not change (blueprint, ROI, colour bars, series styles).

        ``setup`` is the session's ``stream.session.preview.SetupOverlay`` (None: the ROI's box only): the region's
        outline on the camera view and the set-up view (``log_setup``).

        ``strain`` is the session's ``stream.stages.strain.StrainStage`` (None: no strain): with it the view
        adds e_yy, the extensometers and their plots (docs/guide/live-view.md). ``load`` is the session's
        ``stream.stages.force.LoadStage`` (None: no force): with it the force against time and, with
        a cross-section and an ``axial`` extensometer, the stress-strain curve. ``stereo``: a stereo session
        (each result's measurement a ``dic.stereo.StereoMeasurement``): the right camera and the 3D points too.
        """
        if not self.enabled:
            return
        self._strain = strain
        self._load = load
        height, width = image_shape
        self._scale = display_scale(image_shape, self.image_max_side)
        self._p0 = p0_index
        self._open_stream(self._make_blueprint(has_truth, strain, load, setup=setup is not None, stereo=stereo))
        self._log_series_styles(has_truth)
        self._image_side = max(height, width)
        if setup is not None:
            self.log_setup(setup)
        elif roi is not None:
            self._log_roi(roi)
        self._draw_first_bars(strain, stereo)
        if strain is not None:
            self._start_strain(strain)
        if stereo:
            self._stereo = StereoView(self.rr, self._stream, self._legend_colours, self._scale, self._no_strain_colour)
            self._stereo.start()
        self._start_force(load)
        if self.color_range is not None:      # fixed: static; automatic: logged with the first frame
            for legend in (LEGEND_U, LEGEND_V):
                self._log_limits(legend, static=True)
        self._log_session_text(title, points, strain, source_settings)

    def _open_stream(self, blueprint: rrb.Blueprint) -> None:
        """Start the stream to the mode's destination with ``blueprint``, and the thread that flushes it."""
        if self.mode == "save":
            assert self.target is not None       # parse_viewer gives "save" its file
            directory = os.path.dirname(os.path.abspath(self.target))
            os.makedirs(directory, exist_ok=True)
            self._file = RrdFile(self.target, self._file_failed)
            self._stream.save(self._file.sink_path, default_blueprint=blueprint)
        elif self.mode == "connect":
            self._stream.connect_grpc(self.target, default_blueprint=blueprint)
        elif self.mode == "spawn":
            self.viewer_process = spawn_viewer()
            self._stream.connect_grpc(f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy", default_blueprint=blueprint)
        self._flusher = threading.Thread(target=self._flush_loop, name="livedic-rerun-flush", daemon=True)
        self._flusher.start()

    def _log_series_styles(self, has_truth: bool) -> None:
        """The small plots' series names and colours (static; the error plot only with a truth)."""
        for path, (names, colours) in SERIES_STYLE.items():
            if path == ERROR and not has_truth:
                continue
            self._stream.log(path, self.rr.SeriesLines(names=names, colors=colours), static=True)

    def _draw_first_bars(self, strain: StrainStage | None, stereo: bool = False) -> None:
        """The colour bars at their start limits, drawn now: OpenCV's first text call takes ~30 ms, which would
        land on the first frame."""
        legends = [LEGEND_U] + ([LEGEND_EYY] if strain is not None else []) + ([LEGEND_W] if stereo else [])
        for legend in legends:
            _, unit, factor = LEGENDS[legend]
            limits = self.colour_limits[legend]
            self._first_bars[legend] = (limits, colour_bar_image(self._lut, *limits, unit=unit, factor=factor))

    def _start_force(self, load: LoadStage | None) -> None:
        """The force series' style (with a load) and the stress-strain plot's (when this session shows it)."""
        rr, rec = self.rr, self._stream
        if load is not None:
            rec.log(FORCE, rr.SeriesLines(names=["force (kN)"], colors=[STRESS_COLOURS[0]], widths=[2.0]),
                    static=True)
        if self._stress_xy is not None:
            self._stress_xy.start(rr, rec)

    def _log_session_text(self, title: str | None, points: np.ndarray | None, strain: StrainStage | None,
                          source_settings: Mapping[str, object] | None) -> None:
        """The session document: title, points and display scale, the strain settings, the source's settings.
        ``log_summary`` replaces it at the end."""
        rr = self.rr
        lines = [f"# {title or 'livedic session'}", "",
                 f"{len(points) if points is not None else 0} points; camera image shown at 1/{self._scale} scale."]
        if strain is not None:
            lines += ["", strain.describe() + "."]
        if source_settings:
            lines += ["", "| setting | value |", "|---|---|"]
            lines += [f"| {k} | {v} |" for k, v in source_settings.items()]
        self._stream.log(SUMMARY, rr.TextDocument("\n".join(lines), media_type=rr.MediaType.MARKDOWN), static=True)

    def log_setup(self, setup: SetupOverlay) -> None:
        """The set-up (a ``stream.session.preview.SetupOverlay``): the region's outline on the camera view, and the
        set-up view as ``livedic preview`` draws it (``setup_view``). Static: logged once, at the start."""
        self._setup_view().log(setup)

    def _setup_view(self) -> SetupView:
        return SetupView(self.rr, self._stream, self._scale, self._lut, self._image_side)

    def _log_roi(self, roi: Sequence[float]) -> None:
        """The ROI's box (no set-up drawn), and its name above it in dark text on Rerun's light label box (the
        box's own label, in its yellow, was unreadable on speckle)."""
        rr, scale = self.rr, self._scale
        x, y, w, h = roi
        self._stream.log(CAMERA_ROI, rr.Boxes2D(mins=[[x / scale - 0.5, y / scale - 0.5]],
                                                sizes=[[w / scale, h / scale]], colors=[(255, 200, 0)]), static=True)
        self._stream.log(CAMERA_ROI_LABEL, self._setup_view().roi_label(roi, "ROI"), static=True)

    def _plan_plots(self, strain: StrainStage | None, load: LoadStage | None) -> None:
        """The XY plots this session shows: transverse vs axial, stress-strain (None where it has not the data)."""
        self._xy_pair = axial_transverse_pair(strain)
        self._strain_xy = self._stress_xy = None
        if self._xy_pair is not None:
            self._strain_xy = XYPlot(STRAIN_XY, x_title="axial (%)", y_title="transverse (%)",
                                      x_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      y_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      colours=[extensometer_colour(0)])
        has_axial = strain is not None and AXIAL in [e.name for e in strain.extensometers]
        if load is not None and load.area_mm2 and has_axial:
            self._stress_xy = XYPlot(STRESS_STRAIN, x_title="axial strain (%)", y_title="stress (MPa)",
                                      x_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      y_start=(0.0, MIN_XY_LIMIT_STRESS_MPA), colours=STRESS_COLOURS,
                                      second="true", x_title_under_zero=False, mantissas=NICE_MANTISSAS,
                                      names=("engineering", "true (to max. force)"))
        for plot in (self._strain_xy, self._stress_xy):
            if plot is not None:
                plot.columns = self._series       # their segments go out as columns with the series

    def _make_blueprint(self, has_truth: bool, strain: StrainStage | None = None, load: LoadStage | None = None, *,
                        setup: bool = False, stereo: bool = False) -> rrb.Blueprint:
        """The session's layout (``blueprint.make_blueprint``), with the XY plots this session shows."""
        self._plan_plots(strain, load)
        return make_blueprint(has_truth, strain, load, setup=setup, strain_xy=self._strain_xy,
                              stress_xy=self._stress_xy, stereo=stereo)

    # ----------------------------------------------------------------- per frame
    def log_frame(self, result: FrameResult, stats: SessionStats | None, *,
                  camera_image: np.ndarray | None = None, right_image: np.ndarray | None = None) -> None:
        """Log one ``stream.pipeline.frame_result.FrameResult`` (a TrackerLoop sink).

        ``camera_image``: this frame's camera image as drawn (``display_image``), chosen by the caller
        (``stream.view.process``: paced and prepared in the session's process); None: chosen here, by
        ``images`` (a ``CameraImagePacing``), from ``result.frame.image``. ``right_image``: a stereo pair's right
        image as drawn, given with ``camera_image`` (None with it: chosen here with the left one, from
        ``result.frame.right``). ``stats`` is not read.
        """
        if not self.enabled:
            return
        started = time.perf_counter()
        rr, rec = self.rr, self._stream
        # (FrameResult's fields are untyped: what they hold)
        frame = cast("Frame", result.frame)
        m = cast("Measurement", result.measurement)
        readings = cast("ExtensometerReadings | None", result.extensometers)
        if self._t0_ns is None:
            self._t0_ns = frame.timestamp_ns
        now = self._series.now = (int(frame.index), (frame.timestamp_ns - self._t0_ns) / 1e9)
        rec.set_time(TIMELINE_FRAME, sequence=now[0])
        rec.set_time(TIMELINE_TIME, duration=now[1])
        ok = m.ok
        right_image = self._log_fields(result, m, camera_image, right_image)
        if self._stereo is not None:
            self._stereo.log(cast("StereoMeasurement", m), result.strain, right_image)
        if self._strain is not None and readings is not None and len(readings.names):
            self._log_extensometer_series(readings, cast("ContractionRatio | None", result.poisson))
        if self._load is not None:
            self._log_force(result)
        p0 = self._p0
        if p0 is not None and 0 <= p0 < m.u.size and ok[p0]:
            self._scalars(P0, [float(m.u[p0]), float(m.v[p0])])
        nan = float("nan")
        zncc_ok = m.zncc[ok]
        self._scalars(QUALITY, [float(np.mean(zncc_ok)) if zncc_ok.size else nan,
                                float(np.min(zncc_ok)) if zncc_ok.size else nan, float(ok.mean()) if ok.size else 0.0])
        fps, poi = self._rates(result, m)
        if np.isfinite(fps):
            self._scalars(THROUGHPUT, [fps, poi / 1000.0])
        if not result.is_reference:
            self._scalars(LATENCY, [result.latency_ns / 1e6, result.processing_ns / 1e6])
        self._scalars(DROPS, [float(result.dropped_total), float(result.queue_depth)])
        if np.isfinite(result.error_rms_px):
            self._scalars(ERROR, [result.error_rms_px, result.error_max_px])
        self._series.send_when_due()
        if result.dropped_since_last:
            self.event(f"{result.dropped_since_last} frame(s) dropped before frame {frame.index} "
                       f"(total {result.dropped_total})", level="warning")
        if result.refound:
            self.event(f"frame {frame.index}: {result.refound} point(s) re-found by the wide search")
        self.frames_logged += 1
        self.log_seconds += time.perf_counter() - started

    __call__ = log_frame

    def _scalars(self, path: str, values: Any) -> None:
        """This frame's values of the series ``path`` (sent with the next columns: ``SeriesColumns``)."""
        self._series.add(path, values)

    def _log_fields(self, result: FrameResult, m: Measurement, camera_image: np.ndarray | None = None,
                    right_image: np.ndarray | None = None) -> np.ndarray | None:
        """The camera image, the u, v (and e_yy) fields, the extensometer lines, the flagged points and P0's marker;
        returns the right image to draw (a stereo pair's, when its left one is drawn), or None."""
        rr, rec, frame = self.rr, self._stream, cast("Frame", result.frame)
        readings = cast("ExtensometerReadings | None", result.extensometers)
        if camera_image is None and frame.image is not None and self.images.due(frame.timestamp_ns,
                                                                                  result.output_backlog > 0):
            camera_image = self._display_image(frame.image, frame.pixel_format)
            right = frame.right
            if right is not None and right.image is not None:
                right_image = self._display_image(right.image, right.pixel_format)
        if camera_image is not None:
            rec.log(CAMERA_IMAGE, rr.Image(camera_image))
        ok = m.ok
        scale = float(self._scale)
        last_u, last_v = self._last_displacement(m)
        px = (m.x + last_u) / scale
        py = (m.y + last_v) / scale
        radius = self._point_radius(m) / scale
        for path, legend, values in ((FIELD_U, LEGEND_U, m.u), (FIELD_V, LEGEND_V, m.v)):
            good = ok & np.isfinite(values)
            if self.color_range is None:
                self.colour_limits[legend] = grow_limits(self.colour_limits[legend], values[good])
            if self._limits_logged.get(legend) != self.colour_limits[legend]:
                self._log_limits(legend)
            rec.log(path, rr.Points2D(np.column_stack([px[good], py[good]]), radii=radius,
                                      colors=self._packed_lut[self._lut_index(values[good],
                                                                              *self.colour_limits[legend])]))
        if self._strain is not None and result.strain is not None:
            self._log_strain_field(result.strain, ok, px, py, radius)
        if self._strain is not None and readings is not None and len(readings.names):
            self._log_extensometer_lines(m, readings)
        self._log_flagged(m, px, py, radius)
        p0 = self._p0
        if p0 is not None and 0 <= p0 < m.u.size:
            # a negative radius is in UI points: the same size at any zoom
            rec.log(CAMERA_P0, rr.Points2D([[px[p0], py[p0]]], labels=["P0"], radii=-4.0,
                                           colors=[(255, 0, 255) if ok[p0] else (128, 128, 128)],
                                           show_labels=True, draw_order=MARKER_DRAW_ORDER + 1))
        return right_image

    def event(self, message: str, level: str = "info") -> None:
        """A line in the viewer's event log (level: info, warning or error)."""
        if not self.enabled:
            return
        rr = self.rr
        levels = {"info": rr.TextLogLevel.INFO, "warning": rr.TextLogLevel.WARN, "error": rr.TextLogLevel.ERROR}
        self._stream.log(EVENTS, rr.TextLog(message, level=levels.get(level, rr.TextLogLevel.INFO)))

    def _display_image(self, image: np.ndarray, pixel_format: str) -> np.ndarray:
        return display_image(image, pixel_format, self._scale)

    def _point_radius(self, m: Measurement) -> float:
        """Disc radius (image px) so the coloured discs cover the field: the typical spacing / sqrt(2).

        Computed once per point set (the points' reference positions do not change).
        """
        key = (m.x.size, float(m.x[0]), float(m.y[0]), float(m.x[-1]), float(m.y[-1])) if m.x.size else None
        if key != self._radius_key:
            spacing = typical_spacing(m.x, m.y)
            radius = 4.0 * self._scale if spacing is None else spacing / np.sqrt(2.0)
            if self._image_side:
                radius = min(radius, self._image_side / 20.0)
            self._radius_key, self._radius = key, max(radius, 0.5 * self._scale)   # >= 1 display px across
        return self._radius

    def _legend_colours(self, legend: str, values: np.ndarray) -> np.ndarray:
        """Packed colours of finite ``values`` on ``legend``'s automatic scale, grown to cover them (its bar and
        limits logged when they change)."""
        self.colour_limits[legend] = grow_limits(self.colour_limits[legend], values)
        if self._limits_logged.get(legend) != self.colour_limits[legend]:
            self._log_limits(legend)
        return self._packed_lut[self._lut_index(values, *self.colour_limits[legend])]

    def _colours(self, values: np.ndarray, lo: float, hi: float) -> np.ndarray:
        """(N, 3) uint8 colours of ``values`` on the scale [lo, hi] (outside: the end colours)."""
        return self._lut[self._lut_index(values, lo, hi)]

    def _lut_index(self, values: np.ndarray, lo: float, hi: float) -> np.ndarray:
        """Colour-map index of finite ``values`` on the scale [lo, hi] (outside: the ends)."""
        top = self._lut.shape[0] - 1
        return np.clip((values - lo) * (top / (hi - lo)) + 0.5, 0, top).astype(np.int64)

    def _log_limits(self, legend: str, static: bool = False) -> None:
        """The colour bar image with its labels and the numeric limits, for ``legend``."""
        rr = self.rr
        lo, hi = self.colour_limits[legend]
        entity, unit, factor = LEGENDS[legend]
        first = self._first_bars.get(legend)
        if first is not None and first[0] == (lo, hi):
            bar = first[1]
        else:
            bar = colour_bar_image(self._lut, lo, hi, unit=unit, factor=factor)
        self._stream.log(f"{legend}/bar", rr.Image(bar), static=static)
        self._stream.log(entity, rr.Scalars([lo, hi]), static=static)
        self._limits_logged[legend] = (lo, hi)

    # ----------------------------------------------------------------- strain
    def _start_strain(self, strain: StrainStage) -> None:
        """Series styles and the drawing styles of the strain entities (static: logged once, not per frame)."""
        rr, rec = self.rr, self._stream
        rec.log(LIMITS_EYY, rr.SeriesLines(names=["e_yy low", "e_yy high"], colors=[(48, 18, 59), (122, 4, 3)]),
                static=True)
        count = len(strain.extensometers)
        self._end_u, self._end_v = np.zeros(2 * count), np.zeros(2 * count)
        self._extensometer_colours = pack_colours([extensometer_colour(i) for i in range(count)])
        self._lost_colour = pack_colours([EXTENSOMETER_LOST_COLOUR])[0]
        # label text takes its strip's colour, on Rerun's light label box: darker shades of the line colours
        self._label_colours = pack_colours([darker(extensometer_colour(i)) for i in range(count)])
        self._lost_label_colour = pack_colours([darker(EXTENSOMETER_LOST_COLOUR)])[0]
        for i, extensometer in enumerate(strain.extensometers):
            rec.log(f"{EXTENSOMETER_STRAIN}/{extensometer.name}",
                    rr.SeriesLines(names=[extensometer.name], colors=[extensometer_colour(i)], widths=[2.0]),
                    static=True)
            self._series_shown[extensometer.name] = False
        if count:
            # label anchors (2+ extensometers), black outlines, then the coloured lines over them
            # (docs/guide/live-view.md)
            radii = ([0.0] * count if count > 1 else []) + [-3.0] * count + [-1.5] * count
            rec.log(EXTENSOMETER_LINES, rr.LineStrips2D.from_fields(radii=radii, show_labels=True,
                                                                    draw_order=EXTENSOMETER_DRAW_ORDER), static=True)
        if self._strain_xy is not None:
            self._strain_xy.start(rr, rec)
            rec.log(STRAIN_XY_FIT, rr.LineStrips2D.from_fields(radii=-2.5, colors=[FIT_COLOUR],
                                                               draw_order=MARKER_DRAW_ORDER), static=True)

    def _log_strain_field(self, strain: Any, ok: np.ndarray, px: np.ndarray, py: np.ndarray, radius: float) -> None:
        """e_yy at every point drawn (ok displacement): colour-mapped where it has a strain, grey where not."""
        rr = self.rr
        values = strain.eyy
        has_strain = strain.ok & np.isfinite(values)
        legend = LEGEND_EYY
        self.colour_limits[legend] = grow_limits(self.colour_limits[legend], values[has_strain])
        if self._limits_logged.get(legend) != self.colour_limits[legend]:
            self._log_limits(legend)
        shown = ok
        colours = self._packed_lut[self._lut_index(np.where(has_strain[shown], values[shown], 0.0),
                                                   *self.colour_limits[legend])]
        colours[~has_strain[shown]] = self._no_strain_colour
        self._stream.log(FIELD_EYY, rr.Points2D(np.column_stack([px[shown], py[shown]]), radii=radius, colors=colours))

    def _log_extensometer_lines(self, m: Measurement, readings: ExtensometerReadings) -> None:
        """The extensometers on the image, between the ends' current positions, labelled with their strain.

        One LineStrips2D: Rerun puts a strip's label at its middle, and labels only the first strips when
        there are fewer labels than strips: an invisible zero-length strip beyond each second end
        (``_label_anchors``) comes first and carries the label, so "axial" reads below its lower end and
        "transverse" beyond its right end, above the line, clear of P0 where the two cross (one extensometer
        alone is labelled at its middle). Then each line twice: black and wide, then in its colour, so it shows
        on the speckle and on any colour of the field.
        """
        rr, rec, strain = self.rr, self._stream, self._strain
        assert strain is not None         # the caller draws extensometers of a strain session only
        ends = strain.image_ends                         # undistorted ends back on the camera's image
        moved = strain.end_positions(m.u, m.v, m.ok)
        end_u, end_v = moved[:, 0] - ends[:, 0], moved[:, 1] - ends[:, 1]
        known = np.isfinite(end_u) & np.isfinite(end_v)
        np.copyto(self._end_u, end_u, where=known)     # a lost end stays where it was last seen
        np.copyto(self._end_v, end_v, where=known)
        scale = float(self._scale)
        where = np.column_stack([(ends[:, 0] + self._end_u) / scale, (ends[:, 1] + self._end_v) / scale])
        first, second = where[0::2], where[1::2]
        ok = readings.ok
        colours = np.where(ok, self._extensometer_colours, self._lost_colour).astype(np.uint32)
        label_colours = np.where(ok, self._label_colours, self._lost_label_colour).astype(np.uint32)
        labels = [f"{name} {100 * e:.3f} %" if good else f"{name}: lost"
                  for name, e, good in zip(readings.names, readings.eng_strain, ok)]
        lines = np.stack([first, second], axis=1)
        black = np.full(len(lines), BLACK, dtype=np.uint32)
        strips, strip_colours = [lines, lines], [black, colours]
        if len(lines) > 1:
            anchor = _label_anchors(first, second, labels, self._image_side / scale)
            strips.insert(0, np.stack([anchor, anchor], axis=1))
            strip_colours.insert(0, label_colours)
        rec.log(EXTENSOMETER_LINES, rr.LineStrips2D.from_fields(strips=np.concatenate(strips),
                                                                colors=np.concatenate(strip_colours), labels=labels))

    def _log_extensometer_series(self, readings: ExtensometerReadings, poisson: ContractionRatio | None = None) -> None:
        """Each extensometer's strain series (a gap where it has no reading) and the transverse-vs-axial plot."""
        rr, rec, ok = self.rr, self._stream, readings.ok
        for name, e, good in zip(readings.names, readings.eng_strain, ok):
            path = f"{EXTENSOMETER_STRAIN}/{name}"
            if good:
                self._scalars(path, 100.0 * float(e))
                self._series_shown[name] = True
            elif self._series_shown.get(name):
                self._series.clear(path)                    # a gap in the line, never the last value
                self._series_shown[name] = False
        if self._xy_pair is not None:
            self._log_strain_xy(readings, poisson)

    def _log_strain_xy(self, readings: ExtensometerReadings, poisson: ContractionRatio | None) -> None:
        """This frame's point of the transverse-vs-axial plot with the two strains, and Poisson's ratio's elastic
        fit so far (``dic.tensile.poisson.ContractionRatio``, or None) as a line over its range and in the numbers."""
        self._log_elastic_fit(poisson)
        plot, pair = self._strain_xy, self._xy_pair
        assert plot is not None and pair is not None       # planned together (_plan_plots)
        a, t = pair
        if not (readings.ok[a] and readings.ok[t]):
            plot.gap(self.rr, self._stream)
            return
        axial, transverse = float(readings.eng_strain[a]), float(readings.eng_strain[t])
        text = f"axial {100 * axial:.3f} %   transverse {100 * transverse:.3f} %\n" + _poisson_text(poisson)
        plot.add(self.rr, self._stream, 100.0 * axial, 100.0 * transverse, text)

    def _log_elastic_fit(self, poisson: ContractionRatio | None) -> None:
        """The elastic fit's line over its axial range (in the plot's data units), when it changed; cleared when NaN."""
        drawn = None if poisson is None or not np.isfinite(poisson.value) else (poisson.value, poisson.frames)
        if drawn == self._fit_drawn:
            return
        self._fit_drawn = drawn
        if poisson is None or drawn is None:
            self._stream.log(STRAIN_XY_FIT, self.rr.Clear(recursive=False))
            return
        ends = [(100.0 * x, -100.0 * (poisson.intercept - poisson.value * x)) for x in poisson.axial_range]
        self._stream.log(STRAIN_XY_FIT, self.rr.LineStrips2D.from_fields(strips=[ends]))

    # ----------------------------------------------------------------- force and stress
    def _log_force(self, result: FrameResult) -> None:
        """The force against time (a gap where unknown) and this frame's point of the stress-strain curve."""
        rr, rec = self.rr, self._stream
        force = result.force_N
        if force is not None and np.isfinite(force):
            self._scalars(FORCE, force / 1000.0)
            self._force_shown = True
        elif self._force_shown:
            self._series.clear(FORCE)                        # a gap in the line, never the last value
            self._force_shown = False
        plot = self._stress_xy
        if plot is None or self._broken:
            return
        # The broken specimen's frames are not on the curve (a machine stops there; the simulator goes on
        # pulling the halves apart): the curve ends with the force's fall, at the first frame, after a fracture
        # was detected, below FRACTURE_DROP of the maximum force (the report's rule for A).
        self._fractured |= result.fracture is not None
        if force is not None and np.isfinite(force):
            self._max_force_N = max(self._max_force_N, force)
            self._broken = self._fractured and force < FRACTURE_DROP * self._max_force_N
        stress, strain = result.stress_MPa, axial_strain(result)
        if stress is None or not (np.isfinite(stress) and np.isfinite(strain)):
            plot.gap(rr, rec)
            return
        true_stress = result.true_stress_MPa
        true = None
        text = f"{100 * strain:.3f} %   {stress:.1f} MPa"
        if force is not None:
            text += f"   F {force / 1000.0:.3f} kN"
        if true_stress is not None and np.isfinite(true_stress) and result.true_strain is not None:
            true = (100.0 * result.true_strain, true_stress)
            text += f"   true {true_stress:.1f} MPa"
        if self._broken:
            text += "   broken"
        plot.add(rr, rec, 100.0 * strain, stress, text, second=true)

    def _last_displacement(self, m: Measurement) -> tuple[np.ndarray, np.ndarray]:
        """Displacement per point, the last ok one where a point is not ok now (0 before its first)."""
        ok = m.ok & np.isfinite(m.u) & np.isfinite(m.v)
        if self._last_u is None or self._last_v is None or self._last_u.shape != m.u.shape:
            self._last_u, self._last_v = np.zeros(m.u.shape), np.zeros(m.v.shape)
        np.copyto(self._last_u, m.u, where=ok)
        np.copyto(self._last_v, m.v, where=ok)
        return self._last_u, self._last_v

    def _log_flagged(self, m: Measurement, px: np.ndarray, py: np.ndarray, radius: float) -> None:
        """Squares at lost and low-ZNCC points, and the counts as text (each logged only when it changes)."""
        rr, rec = self.rr, self._stream
        lost = ~m.ok
        low = m.ok & (m.zncc < self.low_zncc)
        half_size = max(0.5 * radius, 2.0)      # squares of ~0.7 spacing: neighbours stay apart
        for path, flagged, colour in ((LOST, lost, LOST_COLOUR), (LOW_ZNCC, low, LOW_ZNCC_COLOUR)):
            if flagged.any():
                centers = np.column_stack([px[flagged], py[flagged]])
                # half_sizes sets the number of boxes (one value would draw one box)
                rec.log(path, rr.Boxes2D(centers=centers, half_sizes=np.full(centers.shape, half_size), radii=-1.0,
                                         colors=[colour], draw_order=MARKER_DRAW_ORDER))
                self._flagged_shown[path] = True
            elif self._flagged_shown[path]:
                rec.log(path, rr.Clear(recursive=False))
                self._flagged_shown[path] = False
        text = (f"lost: {int(lost.sum())} of {lost.size} points, "
                f"low ZNCC (< {self.low_zncc:g}): {int(low.sum())}")
        if text != self._tracking_text:
            self._tracking_text = text
            rec.log(TRACKING, rr.TextDocument(text))

    def _rates(self, result: FrameResult, m: Measurement) -> tuple[float, float]:
        """Frame rate and POI/s over the last second of results."""
        self._done_times.append((result.done_ns, int(m.ok.size)))
        while len(self._done_times) > 2 and result.done_ns - self._done_times[0][0] > 1_000_000_000:
            self._done_times.popleft()
        if len(self._done_times) < 2:
            return float("nan"), float("nan")
        span = (self._done_times[-1][0] - self._done_times[0][0]) / 1e9
        if span <= 0:
            return float("nan"), float("nan")
        frames = len(self._done_times) - 1
        points = sum(n for _, n in list(self._done_times)[1:])
        return frames / span, points / span

    # ----------------------------------------------------------------- end
    def log_summary(self, text: str) -> None:
        """Replace the summary document with ``text`` (markdown)."""
        if not self.enabled:
            return
        rr = self.rr
        self._stream.log(SUMMARY, rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)

    def flush(self) -> None:
        """Send the plots' waiting values and flush the stream (the logging thread's, once it logs no more)."""
        rec = self.rec
        if rec is not None:
            self._series.send()
            rec.flush(timeout_sec=2.0)

    def _flush_loop(self) -> None:
        while not self._closing.wait(self.flush_interval_s):
            try:
                self._stream.flush(timeout_sec=2.0)     # not the series: the logging thread sends those
            except Exception:  # noqa: BLE001 - a failed flush must not kill the thread; close() reports
                pass

    def close(self) -> None:
        """Flush and close the sink (the spawned viewer keeps running)."""
        if self.rec is None:
            return
        self._closing.set()
        if self._flusher is not None:
            self._flusher.join(timeout=5.0)
        try:
            self._series.send()
            self.rec.flush(timeout_sec=5.0)
        finally:
            self.rec.disconnect()
            self.rec = None
            if self._file is not None:
                self._file.close()
