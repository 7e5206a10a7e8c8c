"""Live display in Rerun: the only module of livedic that calls ``rerun`` logging.

Entity tree (paths are the constants below)::

    camera/image        the camera frame (Mono8 for display; downsampled by an integer
                        factor when larger than ``image_max_side``)
    camera/roi          the region of interest (static box)
    camera/p0           the traced point P0 at its current position
    camera/field_u      u at every point, drawn at its current position, colour-mapped
    camera/field_v      v, the same way
    legend/u, legend/v  colour bars: a static gradient image plus per-frame end labels (px)
    p0                  P0's displacement, two series [u, v] (px), against the 'frame' and 'time'
                        timelines (and P0's position on the image, camera/p0)
    quality             [ZNCC mean, ZNCC min] over ok points and the fraction of points ok
    perf/throughput     [frames/s, kPOI/s] over the last second
    perf/latency        [latency, tracking time] (ms) per frame
    perf/drops          [frames dropped so far, queue depth]
    error               [RMS, max] error against the truth (px; synthetic sources only)

Related values share one entity as a multi-series ``Scalars`` (one log call
each: a scalar costs ~0.15 ms to log, about as much as an image).
    events              text log (drops, re-found points, source errors, notes)
    summary             the final summary (text document)

Timelines: ``frame`` (frame index) and ``time`` (seconds since the first frame,
camera clock). A default blueprint lays the views out.

Viewer modes (``--viewer``): ``spawn`` starts a local viewer bound to
127.0.0.1 (``rerun --bind 127.0.0.1 --port 9876``; one already listening there
is reused) and streams to it; with no display ($DISPLAY and $WAYLAND_DISPLAY
unset on Linux) it saves a .rrd instead and says so. ``connect URL`` streams to
a running viewer or server (default ``rerun+http://127.0.0.1:9876/proxy``).
``save FILE.rrd`` writes a file. ``none`` logs nothing. Nothing here listens on
a non-loopback interface. A background thread flushes the stream about once a
second, so a killed run's .rrd keeps what came before and the tracking loop
never waits for the disk or the network.
"""

import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections import deque

import numpy as np

APPLICATION_ID = "livedic"
DEFAULT_PORT = 9876
DEFAULT_CONNECT_URL = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"
VIEWER_MODES = ("spawn", "connect", "save", "none")

CAMERA = "camera"
CAMERA_IMAGE = "camera/image"
CAMERA_ROI = "camera/roi"
CAMERA_P0 = "camera/p0"
FIELD_U = "camera/field_u"
FIELD_V = "camera/field_v"
LEGEND_U = "legend/u"
LEGEND_V = "legend/v"
P0 = "p0"
QUALITY = "quality"
THROUGHPUT = "perf/throughput"
LATENCY = "perf/latency"
DROPS = "perf/drops"
ERROR = "error"
EVENTS = "events"
SUMMARY = "summary"

TIMELINE_FRAME = "frame"
TIMELINE_TIME = "time"

_BAR_WIDTH = 256
_BAR_HEIGHT = 20
_SERIES_STYLE = {
    P0: (["u (px)", "v (px)"], [(230, 80, 60), (60, 120, 230)]),
    QUALITY: (["ZNCC mean", "ZNCC min", "fraction ok"], [(40, 160, 90), (200, 140, 30), (120, 120, 120)]),
    THROUGHPUT: (["frames/s", "kPOI/s"], [(40, 120, 200), (200, 90, 40)]),
    LATENCY: (["latency (ms)", "tracking (ms)"], [(200, 50, 50), (80, 80, 200)]),
    DROPS: (["dropped frames", "queue depth"], [(200, 40, 40), (110, 110, 110)]),
    ERROR: (["RMS error (px)", "max error (px)"], [(130, 60, 170), (220, 120, 200)]),
}


def has_display():
    """True unless on Linux/BSD with neither $DISPLAY nor $WAYLAND_DISPLAY set."""
    if sys.platform.startswith(("win", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def parse_viewer(values, default_save_path):
    """``--viewer`` words -> (mode, argument, note).

    ``["spawn"]``, ``["connect"]``, ``["connect", URL]``, ``["save", FILE]``,
    ``["save"]`` (to ``default_save_path``) or ``["none"]``. "spawn" without a
    display becomes ("save", default_save_path) with a note saying so.

    Raises
    ------
    ValueError
        Unknown mode, missing or extra argument, or a bad URL.
    """
    if not values:
        values = ["spawn"]
    if isinstance(values, str):
        values = values.split()
    mode, args = values[0], list(values[1:])
    usage = "use --viewer spawn | connect [URL] | save FILE.rrd | none"
    if mode not in VIEWER_MODES:
        raise ValueError(f"unknown viewer mode {mode!r}: {usage}")
    if len(args) > 1 or (mode in ("spawn", "none") and args):
        raise ValueError(f"--viewer {' '.join(values)}: too many arguments; {usage}")
    if mode == "connect":
        url = args[0] if args else DEFAULT_CONNECT_URL
        if not url.startswith(("rerun://", "rerun+http://", "rerun+https://")):
            raise ValueError(f"viewer URL {url!r} must start with rerun://, rerun+http:// or rerun+https:// "
                             f"(e.g. {DEFAULT_CONNECT_URL})")
        return "connect", url, None
    if mode == "save":
        path = args[0] if args else str(default_save_path)
        if not str(path).endswith(".rrd"):
            raise ValueError(f"Rerun file {path!r} must end in .rrd")
        return "save", path, None
    if mode == "spawn" and not has_display():
        return "save", str(default_save_path), (f"no display ($DISPLAY and $WAYLAND_DISPLAY are unset): "
                                                f"saving the Rerun stream to {default_save_path} instead "
                                                f"(open it later with: rerun {default_save_path})")
    return mode, None, None


def colormap_lut():
    """(256, 3) uint8 RGB 'turbo' colour map (OpenCV's table)."""
    import cv2
    ramp = np.arange(256, dtype=np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)[:, 0, ::-1].copy()


def _port_open(host, port, timeout=0.2):
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def _viewer_command(port):
    exe = os.path.join(os.path.dirname(sys.executable), "rerun")
    if not os.path.exists(exe):
        exe = shutil.which("rerun")
    if exe is None:
        raise ValueError("cannot spawn a viewer: the 'rerun' program is not installed (pip install rerun-sdk), "
                         "or use --viewer save FILE.rrd")
    return [exe, "--bind", "127.0.0.1", "--port", str(port)]


def _fmt(value):
    if not np.isfinite(value):
        return "n/a"
    return f"{value:+.3g}" if abs(value) < 1000 else f"{value:+.0f}"


class RerunLogger:
    """Sends a live session to Rerun (see module notes).

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
    flush_interval_s : float
        Seconds between flushes of the stream (done by a background thread).

    Raises
    ------
    ValueError
        A viewer that cannot be started or reached.
    """

    def __init__(self, mode, target=None, *, recording_name="livedic session", image_max_side=512,
                 image_every=1, flush_interval_s=1.0):
        self.mode = mode
        self.target = target
        self.image_max_side = int(image_max_side)
        self.image_every = max(int(image_every), 1)
        self.flush_interval_s = flush_interval_s
        self.rec = None
        self.viewer_process = None
        self._flusher = None
        self._closing = threading.Event()
        self._scale = 1
        self._lut = None
        self._done_times = deque()
        self._t0_ns = None
        self._p0 = None
        self._tick_labels = {}
        self.log_seconds = 0.0
        self.frames_logged = 0
        if mode == "none":
            return
        import rerun as rr
        self.rr = rr
        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.rec.send_recording_name(recording_name)
        self._lut = colormap_lut()
        self._blueprint = None

    @property
    def enabled(self):
        return self.rec is not None

    # ----------------------------------------------------------------- setup
    def start(self, *, image_shape, roi=None, p0_index=None, points=None, has_truth=False, title=None,
              source_settings=None):
        """Open the sink and log what does not change (blueprint, ROI, colour bars, series styles)."""
        if not self.enabled:
            return
        rr = self.rr
        height, width = image_shape
        scale = 1
        while max(height, width) / scale > self.image_max_side:
            scale += 1
        self._scale = scale
        self._p0 = p0_index
        blueprint = self._make_blueprint(has_truth)
        if self.mode == "save":
            directory = os.path.dirname(os.path.abspath(self.target))
            os.makedirs(directory, exist_ok=True)
            self.rec.save(self.target, default_blueprint=blueprint)
        elif self.mode == "connect":
            self.rec.connect_grpc(self.target, default_blueprint=blueprint)
        elif self.mode == "spawn":
            self._spawn_viewer()
            self.rec.connect_grpc(f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy", default_blueprint=blueprint)
        rec = self.rec
        self._flusher = threading.Thread(target=self._flush_loop, name="livedic-rerun-flush", daemon=True)
        self._flusher.start()
        for path, (names, colours) in _SERIES_STYLE.items():
            if path == ERROR and not has_truth:
                continue
            rec.log(path, rr.SeriesLines(names=names, colors=colours), static=True)
        if roi is not None:
            x, y, w, h = roi
            rec.log(CAMERA_ROI, rr.Boxes2D(mins=[[x / scale - 0.5, y / scale - 0.5]], sizes=[[w / scale, h / scale]],
                                           colors=[(255, 200, 0)], labels=["ROI"]), static=True)
        bar = np.repeat(self._lut[None, :, :], _BAR_HEIGHT, axis=0)
        for legend in (LEGEND_U, LEGEND_V):
            rec.log(f"{legend}/bar", rr.Image(bar), static=True)
        lines = [f"# {title or 'livedic session'}", "",
                 f"{len(points) if points is not None else 0} points; camera image shown at 1/{scale} scale."]
        if source_settings:
            lines += ["", "| setting | value |", "|---|---|"]
            lines += [f"| {k} | {v} |" for k, v in source_settings.items()]
        rec.log(SUMMARY, rr.TextDocument("\n".join(lines), media_type=rr.MediaType.MARKDOWN), static=True)

    def _spawn_viewer(self):
        if _port_open("127.0.0.1", DEFAULT_PORT):
            return  # a viewer (or proxy) already listens on loopback: reuse it
        command = _viewer_command(DEFAULT_PORT)
        try:
            self.viewer_process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                                   stderr=subprocess.DEVNULL, start_new_session=True)
        except OSError as error:
            raise ValueError(f"cannot start the Rerun viewer ({command[0]}): {error}; "
                             "use --viewer save FILE.rrd instead") from None
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            if _port_open("127.0.0.1", DEFAULT_PORT):
                return
            if self.viewer_process.poll() is not None:
                raise ValueError(f"the Rerun viewer exited at start (code {self.viewer_process.returncode}); "
                                 "use --viewer save FILE.rrd instead")
            time.sleep(0.1)
        raise ValueError(f"the Rerun viewer did not start listening on 127.0.0.1:{DEFAULT_PORT} within 10 s; "
                         "use --viewer save FILE.rrd instead")

    def _make_blueprint(self, has_truth):
        import rerun.blueprint as rrb
        field = "$origin/image", "$origin/p0"
        images = rrb.Horizontal(
            rrb.Spatial2DView(name="camera", origin=CAMERA, contents=[*field, "$origin/roi"]),
            rrb.Spatial2DView(name="u (px)", origin=CAMERA, contents=[*field, f"/{FIELD_U}"]),
            rrb.Spatial2DView(name="v (px)", origin=CAMERA, contents=[*field, f"/{FIELD_V}"]),
        )
        legends = rrb.Horizontal(
            rrb.TextDocumentView(name="session", origin=SUMMARY),
            rrb.Spatial2DView(name="u colour scale (px)", origin=LEGEND_U),
            rrb.Spatial2DView(name="v colour scale (px)", origin=LEGEND_V),
        )
        plots = [
            rrb.TimeSeriesView(name="P0 displacement (px)", origin=P0),
            rrb.TimeSeriesView(name="ZNCC quality", origin=QUALITY),
            rrb.TimeSeriesView(name="throughput", origin=THROUGHPUT),
            rrb.TimeSeriesView(name="latency (ms)", origin=LATENCY),
            rrb.TimeSeriesView(name="drops", origin=DROPS),
        ]
        if has_truth:
            plots.append(rrb.TimeSeriesView(name="error vs truth (px)", origin=ERROR))
        plots.append(rrb.TextLogView(name="events", origin=EVENTS))
        return rrb.Blueprint(
            rrb.Horizontal(
                rrb.Vertical(images, legends, row_shares=[4, 1]),
                rrb.Vertical(*plots),
                column_shares=[3, 2]),
            collapse_panels=True)

    # ----------------------------------------------------------------- per frame
    def log_frame(self, result, stats):
        """Log one ``stream.tracker_loop.FrameResult`` (a TrackerLoop sink)."""
        if not self.enabled:
            return
        started = time.perf_counter()
        rr, rec = self.rr, self.rec
        frame = result.frame
        m = result.measurement
        if self._t0_ns is None:
            self._t0_ns = frame.timestamp_ns
        rec.set_time(TIMELINE_FRAME, sequence=int(frame.index))
        rec.set_time(TIMELINE_TIME, duration=(frame.timestamp_ns - self._t0_ns) / 1e9)
        if self.frames_logged % self.image_every == 0:
            rec.log(CAMERA_IMAGE, rr.Image(self._display_image(frame.image, frame.pixel_format)))
        ok = m.ok
        scale = float(self._scale)
        px = (m.x + np.where(ok, m.u, 0.0)) / scale
        py = (m.y + np.where(ok, m.v, 0.0)) / scale
        radius = self._point_radius(m) / scale
        for path, legend, values in ((FIELD_U, LEGEND_U, m.u), (FIELD_V, LEGEND_V, m.v)):
            good = ok & np.isfinite(values)
            colours, lo, hi = self._colours(values, good)
            rec.log(path, rr.Points2D(np.column_stack([px[good], py[good]]), colors=colours, radii=radius))
            labels = [f"{_fmt(lo)} px", _fmt(0.5 * (lo + hi)), f"{_fmt(hi)} px"]
            if labels != self._tick_labels.get(legend):      # 3 significant digits: changes now and then
                self._tick_labels[legend] = labels
                rec.log(f"{legend}/ticks", rr.Points2D(
                    [[0, _BAR_HEIGHT + 2], [_BAR_WIDTH / 2, _BAR_HEIGHT + 2], [_BAR_WIDTH - 1, _BAR_HEIGHT + 2]],
                    labels=labels, radii=0.5, colors=[(255, 255, 255)], show_labels=True))
        p0 = self._p0
        if p0 is not None and 0 <= p0 < m.u.size:
            if ok[p0]:
                rec.log(P0, rr.Scalars([float(m.u[p0]), float(m.v[p0])]))
            rec.log(CAMERA_P0, rr.Points2D([[px[p0], py[p0]]], labels=["P0"], radii=max(3.0, 2 * radius),
                                           colors=[(255, 0, 255) if ok[p0] else (128, 128, 128)],
                                           show_labels=True))
        nan = float("nan")
        zncc_ok = m.zncc[ok]
        rec.log(QUALITY, rr.Scalars([float(np.mean(zncc_ok)) if zncc_ok.size else nan,
                                     float(np.min(zncc_ok)) if zncc_ok.size else nan,
                                     float(ok.mean()) if ok.size else 0.0]))
        fps, poi = self._rates(result, m)
        if np.isfinite(fps):
            rec.log(THROUGHPUT, rr.Scalars([fps, poi / 1000.0]))
        if not result.is_reference:
            rec.log(LATENCY, rr.Scalars([result.latency_ns / 1e6, result.processing_ns / 1e6]))
        rec.log(DROPS, rr.Scalars([float(result.dropped_total), float(result.queue_depth)]))
        if np.isfinite(result.error_rms_px):
            rec.log(ERROR, rr.Scalars([result.error_rms_px, result.error_max_px]))
        if result.dropped_since_last:
            self.event(f"{result.dropped_since_last} frame(s) dropped before frame {frame.index} "
                       f"(total {result.dropped_total})", level="warning")
        if result.refound:
            self.event(f"frame {frame.index}: {result.refound} point(s) re-found by the wide search")
        self.frames_logged += 1
        self.log_seconds += time.perf_counter() - started

    __call__ = log_frame

    def event(self, message, level="info"):
        """A line in the viewer's event log (level: info, warning or error)."""
        if not self.enabled:
            return
        rr = self.rr
        levels = {"info": rr.TextLogLevel.INFO, "warning": rr.TextLogLevel.WARN, "error": rr.TextLogLevel.ERROR}
        self.rec.log(EVENTS, rr.TextLog(message, level=levels.get(level, rr.TextLogLevel.INFO)))

    def _display_image(self, image, pixel_format):
        if image.dtype != np.uint8:
            shift = 4 if pixel_format == "Mono12" else 8
            image = (image >> shift).astype(np.uint8)
        if self._scale > 1:
            import cv2
            h, w = image.shape
            image = cv2.resize(image, (w // self._scale, h // self._scale), interpolation=cv2.INTER_AREA)
        return image

    @staticmethod
    def _point_radius(m):
        """Half the typical spacing between points, so the coloured dots tile the field."""
        if m.x.size < 2:
            return 4.0
        xs = np.unique(m.x)
        ys = np.unique(m.y)
        steps = [np.min(np.diff(a)) for a in (xs, ys) if a.size > 1]
        return 0.5 * float(min(steps)) if steps else 4.0

    def _colours(self, values, good):
        if not good.any():
            return np.zeros((0, 3), dtype=np.uint8), float("nan"), float("nan")
        v = values[good]
        lo, hi = float(v.min()), float(v.max())
        span = hi - lo if hi > lo else 1.0
        index = np.clip(((v - lo) / span * 255.0).astype(np.int64), 0, 255)
        return self._lut[index], lo, hi

    def _rates(self, result, m):
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
    def log_summary(self, text):
        """Replace the summary document with ``text`` (markdown)."""
        if not self.enabled:
            return
        rr = self.rr
        self.rec.log(SUMMARY, rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)

    def flush(self):
        rec = self.rec
        if rec is not None:
            rec.flush(timeout_sec=2.0)

    def _flush_loop(self):
        while not self._closing.wait(self.flush_interval_s):
            try:
                self.flush()
            except Exception:  # noqa: BLE001 - a failed flush must not kill the thread; close() reports
                pass

    def close(self):
        """Flush and close the sink (the spawned viewer keeps running)."""
        if not self.enabled:
            return
        self._closing.set()
        if self._flusher is not None:
            self._flusher.join(timeout=5.0)
        try:
            self.rec.flush(timeout_sec=5.0)
        finally:
            self.rec.disconnect()
            self.rec = None
