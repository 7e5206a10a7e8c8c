"""Live display in Rerun: the only module of livedic that calls ``rerun`` logging.

Entity tree (paths are the constants below)::

    camera/image        the camera frame (Mono8 for display; downsampled by an integer
                        factor when larger than ``image_max_side``)
    camera/roi          the region where the points go (static outline: the ROI's rectangle or polygon,
                        the mask's or the found specimen's edge), and the exclusions in red;
                        camera/roi/label its name above it, dark on a light box
    setup/...           the set-up as ``livedic preview`` draws it (static, its own view): the reference
                        frame (setup/image), the speckle contrast per subset (setup/mig, colour-mapped,
                        with clipped pixels red), the region and exclusions, the points (weak contrast in
                        orange), P0 with its subset, the extensometers labelled with L0; setup_notes the
                        preview's figures and advice
    camera/p0           the traced point P0 at its current position
    camera/field_u      u at every ok point, drawn at its current position, colour-mapped
    camera/field_v      v, the same way
    camera/lost         hollow red squares at the points that are not ok (status other than OK), at
                        their last measured position
    camera/low_zncc     hollow yellow squares at ok points whose ZNCC is below ``low_zncc``
    legend/u, legend/v  colour bars: an image with the gradient over a white strip with the limits
                        drawn in black (text in the image reads the same in the light and dark themes)
    colour_scale/u, colour_scale/v
                        the colour limits [low, high] (px), logged when they change
    tracking            text: "lost: L of N points, low ZNCC (< T): K", logged when it changes
    p0                  P0's displacement, two series [u, v] (px), against the 'frame' and 'time'
                        timelines (and P0's position on the image, camera/p0)
    quality             [ZNCC mean, ZNCC min] over ok points and the fraction of points ok
    perf/throughput     [frames/s, kPOI/s] over the last second
    perf/latency        [latency, tracking time] (ms) per frame
    perf/drops          [frames dropped so far, queue depth]
    error               [RMS, max] error against the truth (px; synthetic sources only)

    events              text log (drops, re-found points, source errors, notes)
    summary             the final summary (text document)

  with strain (``start(strain=stage)``, the session's ``stream.strain.StrainStage``):

    camera/field_eyy    e_yy at every ok point (same discs as u and v), colour-mapped; grey where the
                        point has a displacement but no strain (too few valid points in its window)
    legend/eyy          its colour bar, in %; colour_scale/eyy its limits [low, high] (strain)
    camera/extensometers
                        the extensometers, drawn on the camera view and the e_yy view between their
                        ends' current positions, labelled "NAME 1.234 %" (engineering strain); red and
                        labelled "NAME: lost" in a frame without a reading, its lost end where last seen
    extensometers/strain/NAME
                        engineering strain (%) of each, against time; nothing is logged for a frame
                        without a reading, and a Clear at the first such frame leaves a gap in the line
    strain_xy           transverse vs axial strain (%), when the extensometers "axial" and
                        "transverse" exist (``--gauge-length``): axes, grid and tick labels
                        (strain_xy/axes, strain_xy/ticks), the curve, one segment a frame, shown up to
                        the time cursor (strain_xy/data/curve), Poisson's ratio's elastic fit so far as a
                        dark line over its range (strain_xy/data/fit; ``stream.poisson``), and the current
                        point with the two strains and, below them, that fit's value, error and frames
                        (strain_xy/now)

  with the machine's force (``start(load=stage)``, the session's ``stream.load_stage.LoadStage``):

    machine/force       the force (kN) against time; nothing logged for a frame without a force, a gap
    stress_strain       with a cross-section and an "axial" extensometer: engineering stress (MPa)
                        against axial strain (%) (stress_strain/data/curve) and the true curve up to
                        uniform elongation (stress_strain/data/true; live, while the force is within
                        0.5 % of its maximum so far: ``stream.stress.UniformElongationWatch``), drawn
                        like strain_xy, with the current strain, stress, force and true stress
                        (stress_strain/now), and a legend naming the two curves (stress_strain/legend);
                        a frame without a force or an axial strain is a gap

Related values share one entity as a multi-series ``Scalars`` (one log call
each: a scalar costs ~0.15 ms to log, about as much as an image).

Point size: each field point is a disc of radius s/sqrt(2), where s, the
typical spacing of the points, is the median over (up to 128 sampled) points of
the distance to the second-nearest distinct point. The second neighbour, not the
first, so a pair such as P0 one pixel beside a grid point does not shrink the
discs; the median ignores isolated points; duplicates are dropped first. The
discs cover a square grid of step s with no gaps, and most of an irregular point
set. The radius is capped at 1/20 of the image side.

Colour scale (the same rule for u and v, each with its own limits): with
``color_range=(lo, hi)`` (``livedic run --color-range LO,HI``) the limits are fixed. Otherwise they start at
[-0.05, +0.05] px, so the noise of the reference frame shows as one colour,
and only grow: when the 0.5th/99.5th percentile of a frame's values (ok points;
the percentiles keep a stray point from stretching the scale for the rest of
the test) leaves them, the limit that was passed moves out to the next "nice"
value (1, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 times a power of ten). They never
shrink, so a colour means the same displacement for as long as possible, and
they are not forced to be symmetric: zero sits where the 0 tick shows. Values
outside the limits take the end colours.

Strain: e_yy's colour scale follows the same rule (always automatic; ``--color-range`` is for u and v):
it starts at [-0.001, +0.001] (+-0.1 %, so strain noise of ~1e-4 is one colour) and only grows, to
nice numbers. The e_yy view's name gives the measure and the virtual strain gauge, e.g. "e_yy (%)
engineering, VSG 77 px". Rerun has no XY plot: transverse vs axial is a 2D view of a fixed plot box,
the curve logged in % under ``strain_xy/data``, whose transform maps the current axis limits onto the
box; the limits start at +-0.05 % and only grow, to 1, 2 or 5 times a power of ten, and each growth
logs one new transform (the whole curve rescales) and new axes. Logging costs about 1 ms a frame more
with strain and two extensometers (colours are packed to Rerun's 0xRRGGBBAA here, and styles that do
not change are logged once, static).

Timelines: ``frame`` (frame index) and ``time`` (seconds since the first frame,
camera clock). A default blueprint lays the views out; with strain, the four fields form a 2 x 2 grid
(camera and e_yy on top, u and v below, each over its colour bar) and the extensometer plots head the
plot column, the small plots (P0, ZNCC, throughput, latency, drops, error) two to a row below them (one
to a row, full width, without strain plots). A small plot's name says which colour is which series and it
has no legend (Rerun draws a legend over the curves); the strain and force plots keep theirs, in the top
left corner, which a tensile test's curves leave free.

Viewer modes (``--viewer``): ``spawn`` starts a local viewer bound to
127.0.0.1 (``rerun --bind 127.0.0.1 --port 9876``; one already listening there
is reused) and streams to it; with no display ($DISPLAY and $WAYLAND_DISPLAY
unset on Linux) it saves a .rrd instead and says so. ``connect URL`` streams to
a running viewer or server (default ``rerun+http://127.0.0.1:9876/proxy``).
``save FILE.rrd`` writes a file. ``none`` logs nothing. Nothing here listens on
a non-loopback interface. A background thread flushes the stream about once a
second, so a killed run's .rrd keeps what came before and the tracking loop
never waits for the disk or the network. A session runs this logger in a process of its own
(``stream.view.process``), which chooses and downsamples the camera image (``CameraImagePacing``,
``display_image``) and hands each frame over.
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

from livedic.acquire.camera.pixel_formats import FRAME_BIT_DEPTH
from livedic.dic.extensometer import end_displacements
from livedic.dic.tensile_properties import FRACTURE_DROP
from livedic.stream.load_stage import axial_strain
from livedic.stream.strain import AXIAL, TRANSVERSE

APPLICATION_ID = "livedic"
DEFAULT_PORT = 9876
# A live view draws the camera image at most this often (Hz of the frames' clock): enough to watch, and a
# 100 fps camera's images would cost the process the GIL time the tracker needs; fields go every frame.
IMAGE_MAX_HZ = 25.0
# The plots' values go out as columns this often (a few frames at once: Rerun's cost is per call).
SERIES_SEND_S = 0.1
# While results wait for the output thread the view leaves out the camera image (never the fields or the
# numbers), at most this many frames in a row: a view behind still shows the specimen a few times a second.
IMAGE_SKIP_MAX = 4
DEFAULT_CONNECT_URL = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"
VIEWER_MODES = ("spawn", "connect", "save", "none")

CAMERA = "camera"
CAMERA_IMAGE = "camera/image"
CAMERA_ROI = "camera/roi"
CAMERA_ROI_LABEL = "camera/roi/label"
SETUP = "setup"
SETUP_NOTES = "setup_notes"
CAMERA_P0 = "camera/p0"
FIELD_U = "camera/field_u"
FIELD_V = "camera/field_v"
LEGEND_U = "legend/u"
LEGEND_V = "legend/v"
LOST = "camera/lost"
LOW_ZNCC = "camera/low_zncc"
LIMITS_U = "colour_scale/u"
LIMITS_V = "colour_scale/v"
TRACKING = "tracking"
P0 = "p0"
QUALITY = "quality"
THROUGHPUT = "perf/throughput"
LATENCY = "perf/latency"
DROPS = "perf/drops"
ERROR = "error"
EVENTS = "events"
SUMMARY = "summary"
# strain (only when the session has a strain stage: ``start(strain=...)``)
FIELD_EYY = "camera/field_eyy"
EXTENSOMETER_LINES = "camera/extensometers"
LEGEND_EYY = "legend/eyy"
LIMITS_EYY = "colour_scale/eyy"
EXTENSOMETER_STRAIN = "extensometers/strain"     # one child per extensometer: extensometers/strain/NAME
STRAIN_XY = "strain_xy"
STRAIN_XY_DATA = "strain_xy/data"                # the transform from strain (%) to the plot box
STRAIN_XY_CURVE = "strain_xy/data/curve"
STRAIN_XY_NOW = "strain_xy/now"
STRAIN_XY_FIT = "strain_xy/data/fit"             # Poisson's ratio's elastic fit, over its range
STRAIN_XY_AXES = "strain_xy/axes"
STRAIN_XY_TICKS = "strain_xy/ticks"
# force and stress (only with the session's load stage: ``start(load=...)``)
FORCE = "machine/force"                          # the force (kN) against time
STRESS_STRAIN = "stress_strain"                  # the stress-strain plot, an _XYPlot like strain_xy
STRESS_STRAIN_CURVE = "stress_strain/data/curve"   # engineering stress (MPa) against axial strain (%)
STRESS_STRAIN_TRUE = "stress_strain/data/true"     # true stress against true strain, up to Ag
STRESS_STRAIN_NOW = "stress_strain/now"

TIMELINE_FRAME = "frame"
TIMELINE_TIME = "time"

MIN_COLOUR_LIMIT_PX = 0.05       # the automatic scale starts at +-this, so reference-frame noise is one colour
MIN_COLOUR_LIMIT_STRAIN = 1e-3   # e_yy's scale starts at +-0.1 %: strain noise (~1e-4) is one colour
MIN_XY_LIMIT_STRAIN = 5e-4       # the transverse-vs-axial axes start at +-0.05 %
MIN_XY_LIMIT_STRESS_MPA = 100.0  # the stress-strain plot's stress axis starts at 0-100 MPa
_NICE_MANTISSAS = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
_AXIS_MANTISSAS = (1.0, 2.0, 5.0, 10.0)   # the transverse-vs-axial axes grow in fewer, bigger steps
_LIMIT_PERCENTILES = (0.5, 99.5)
_SPACING_QUERIES = 128           # points sampled to estimate the typical spacing (once per point set)
_BAR_WIDTH = 340
_BAR_MARGIN = 10
_BAR_GRADIENT_HEIGHT = 24
_BAR_TEXT_HEIGHT = 34
_LOST_COLOUR = (230, 0, 0)
_LOW_ZNCC_COLOUR = (255, 220, 0)
_MARKER_DRAW_ORDER = 40.0        # above the field discs (Points2D default 30)
_NO_STRAIN_COLOUR = (150, 150, 150)   # an ok point without a strain (too few valid neighbours): grey
# Extensometer colours, in order of definition (axial, transverse, then the others): not red (a lost one),
# yellow (low ZNCC) or magenta (P0); lines and series share them.
_EXTENSOMETER_COLOURS = ((0, 220, 255), (70, 240, 70), (255, 150, 0), (185, 125, 255), (255, 255, 255))
_EXTENSOMETER_LOST_COLOUR = (230, 0, 0)
_BLACK = 0x000000FF              # packed opaque black
# Label sizes as fractions of the image side, for an image view ~300 px across (a quarter of a screen): Rerun
# draws a label centred under its anchor, in UI points (~7 a character, ~16 high) whatever the zoom.
_LABEL_CHARACTER = 0.024
_LABEL_HEIGHT = 0.055
_LABEL_GAP = 0.015
_EXTENSOMETER_DRAW_ORDER = 50.0  # above the lost/low-ZNCC squares and P0
_STRESS_COLOURS = ((255, 150, 0), (255, 90, 200))   # engineering, true: apart from the extensometers' colours
_FIT_COLOUR = (25, 25, 25)       # the elastic fit, drawn over the transverse-vs-axial curve on the light plot
_XY_BOX = (100.0, 25.0)          # the transverse-vs-axial plot's box (width, height) in scene units
_XY_FRAME_COLOUR = (160, 160, 160)
_XY_ZERO_COLOUR = (210, 210, 210)
_XY_GRID_COLOUR = (75, 75, 75)
_XY_MAX_TICKS = 5
_LABEL_TEXT_COLOUR = (20, 20, 20)   # labels are drawn on a light box: dark text reads best
_SERIES_STYLE = {
    P0: (["u (px)", "v (px)"], [(230, 80, 60), (60, 120, 230)]),
    QUALITY: (["ZNCC mean", "ZNCC min", "fraction ok"], [(40, 160, 90), (200, 140, 30), (120, 120, 120)]),
    THROUGHPUT: (["frames/s", "kPOI/s"], [(40, 120, 200), (230, 140, 20)]),
    LATENCY: (["latency (ms)", "tracking (ms)"], [(200, 50, 50), (80, 80, 200)]),
    DROPS: (["dropped frames", "queue depth"], [(200, 40, 40), (110, 110, 110)]),
    ERROR: (["RMS error (px)", "max error (px)"], [(130, 60, 170), (220, 120, 200)]),
    LIMITS_U: (["u low (px)", "u high (px)"], [(48, 18, 59), (122, 4, 3)]),
    LIMITS_V: (["v low (px)", "v high (px)"], [(48, 18, 59), (122, 4, 3)]),
}
# The small plots' names say which colour is which series: Rerun draws a plot's legend over the plot, where in
# a plot this small it hides the curves, so it is switched off there (the colours are _SERIES_STYLE's). Short
# enough (~30 characters) for half of the plot column.
_SMALL_PLOT_NAMES = {
    P0: "P0 (px): u red, v blue",
    QUALITY: "ZNCC: mean green, min orange, ok grey",
    THROUGHPUT: "frames/s blue, kPOI/s orange",
    LATENCY: "latency red, tracking blue (ms)",
    DROPS: "dropped red, queue depth grey",
    ERROR: "px error: RMS purple, max pink",
}
# colour bars: legend -> (the entity of its numeric limits, the unit on the bar, display factor)
_LEGENDS = {LEGEND_U: (LIMITS_U, "px", 1.0), LEGEND_V: (LIMITS_V, "px", 1.0), LEGEND_EYY: (LIMITS_EYY, "%", 100.0)}


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
                                                f"(open it later with: rerun --bind 127.0.0.1 {default_save_path})")
    return mode, None, None


def colormap_lut():
    """(256, 3) uint8 RGB 'turbo' colour map (OpenCV's table)."""
    import cv2
    ramp = np.arange(256, dtype=np.uint8).reshape(-1, 1)
    return cv2.applyColorMap(ramp, cv2.COLORMAP_TURBO)[:, 0, ::-1].copy()


def display_gray(image, pixel_format=""):
    """A camera image as 8-bit grey for display: the top 8 of its significant bits (a 10- or 12-bit camera's
    uint16 holds 0..1023 or 0..4095; Mono16 and unknown formats 16 bits)."""
    if image.dtype != np.uint8:
        shift = FRAME_BIT_DEPTH.get(pixel_format, 16) - 8
        image = (image >> shift).astype(np.uint8)
    return image


def display_scale(image_shape, max_side):
    """The integer factor the view downsamples a camera image of ``image_shape`` by: its larger side <= max_side."""
    height, width = image_shape[:2]
    scale = 1
    while max(height, width) / scale > max_side:
        scale += 1
    return scale


def display_image(image, pixel_format, scale):
    """The camera image as the view draws it: 8-bit grey (``display_gray``), 1/``scale`` of its size."""
    image = display_gray(image, pixel_format)
    if scale > 1:
        import cv2
        h, w = image.shape
        image = cv2.resize(image, (w // scale, h // scale), interpolation=cv2.INTER_AREA)
    return image


class CameraImagePacing:
    """Which frames' camera images the view draws: the costliest part of a frame's view, so a live one is
    paced (every frame's fields, markers and plots are drawn all the same).

    ``image_every``: every this many frames; ``image_max_hz``: at most this many a second of the frames' own
    clock (None: no limit); ``thin_when_behind``: while the view is behind, leave the image out, at most
    ``IMAGE_SKIP_MAX`` frames in a row. ``images_above_rate`` and ``images_left_out`` count what was left out
    by the rate and while behind (the session's summary says both).
    """

    def __init__(self, *, image_every=1, image_max_hz=None, thin_when_behind=False):
        self.image_every = max(int(image_every), 1)
        self.image_max_hz = image_max_hz
        self.thin_when_behind = bool(thin_when_behind)
        self._period_ns = int(1e9 / image_max_hz) if image_max_hz else 0
        self._last_image_ns = None               # the frame time of the last camera image drawn
        self._frames = 0
        self._left_out_in_a_row = 0
        self.images_above_rate = 0
        self.images_left_out = 0

    def due(self, timestamp_ns, behind):
        """True when this frame's image is drawn (call once per frame, in order)."""
        frame_number, self._frames = self._frames, self._frames + 1
        if self._last_image_ns is not None and timestamp_ns - self._last_image_ns < self._period_ns:
            self.images_above_rate += 1
            return False
        if frame_number % self.image_every:
            return False
        # A view behind the measurement catches up by leaving out the camera image, at most IMAGE_SKIP_MAX
        # frames in a row
        if self.thin_when_behind and behind and self._left_out_in_a_row < IMAGE_SKIP_MAX:
            self._left_out_in_a_row += 1
            self.images_left_out += 1
            return False
        self._left_out_in_a_row = 0
        self._last_image_ns = timestamp_ns
        return True


def pack_colours(rgb):
    """(N, 3) uint8 RGB -> (N,) uint32 0xRRGGBBAA, opaque: what Rerun stores, without its per-call conversion."""
    rgb = np.asarray(rgb, dtype=np.uint32).reshape(-1, 3)
    return (rgb[:, 0] << 24) | (rgb[:, 1] << 16) | (rgb[:, 2] << 8) | np.uint32(255)


def nice_ceil(value, mantissas=_NICE_MANTISSAS):
    """The smallest "nice" number (1, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 times a power of ten) >= ``value`` > 0.

    ``mantissas`` (ascending, ending with 10) replaces the nice mantissas.
    """
    exponent = np.floor(np.log10(value))
    for mantissa in mantissas:
        candidate = mantissa * 10.0 ** exponent
        if candidate >= value * (1 - 1e-9):   # 0.3 / 0.1 and friends land a rounding error above a mantissa
            return float(f"{candidate:.3g}")
    return float(f"{10.0 ** (exponent + 1):.3g}")


def grow_limits(limits, values):
    """Automatic colour limits after a frame: ``limits`` (lo < 0 < hi) widened to cover ``values``.

    The 0.5th/99.5th percentiles of the finite ``values`` are covered; an end that
    must move goes out to the next nice number. The result contains ``limits``.
    """
    lo, hi = limits
    values = values[np.isfinite(values)]
    if values.size == 0 or (values.min() >= lo and values.max() <= hi):
        return lo, hi               # inside already (the percentiles lie between min and max): most frames
    low, high = np.percentile(values, _LIMIT_PERCENTILES)
    if low < lo:
        lo = -nice_ceil(-low)
    if high > hi:
        hi = nice_ceil(high)
    return float(lo), float(hi)


def grow_to_cover(limits, value, mantissas=_AXIS_MANTISSAS):
    """``limits`` (lo <= 0 <= hi) widened to cover one finite ``value``: an end that moves goes out to the next
    1, 2 or 5 times a power of ten (``mantissas``)."""
    lo, hi = limits
    if value < lo:
        lo = -nice_ceil(-value, mantissas)
    if value > hi:
        hi = nice_ceil(value, mantissas)
    return float(lo), float(hi)


def typical_spacing(x, y):
    """Typical distance between neighbouring points (see the module notes), or None for fewer than 2 points.

    The median, over up to ``_SPACING_QUERIES`` points spread through the set, of
    the distance to the second-nearest distinct point (nearest for 2 points).
    """
    positions = np.column_stack([np.asarray(x, float), np.asarray(y, float)])
    positions = np.unique(positions[np.isfinite(positions).all(axis=1)], axis=0)
    count = len(positions)
    if count < 2:
        return None
    extent = positions.max(axis=0) - positions.min(axis=0)
    axis = int(extent[1] > extent[0])        # search along the longer side: fewer points per window
    positions = positions[np.argsort(positions[:, axis], kind="stable")]
    along = positions[:, axis]
    neighbour = min(2, count - 1)            # index 0 of the sorted distances is the query itself
    # a first window: the spacing of a grid with this many points over the bounding box
    start_window = max(np.sqrt(max(extent[0], 1.0) * max(extent[1], 1.0) / count), 1e-6)
    distances = []
    for q in np.unique(np.linspace(0, count - 1, min(count, _SPACING_QUERIES)).astype(np.int64)):
        query, window = positions[q], start_window
        while True:      # points outside the window along ``axis`` are farther than ``window``
            first = np.searchsorted(along, query[axis] - window, side="left")
            last = np.searchsorted(along, query[axis] + window, side="right")
            d2 = ((positions[first:last] - query) ** 2).sum(axis=1)
            if last - first > neighbour:
                kth = np.partition(d2, neighbour)[neighbour]
                if kth <= window * window or last - first == count:
                    distances.append(kth)
                    break
            window *= 2.0
    return float(np.sqrt(np.median(distances)))


def colour_bar_image(lut, lo, hi, unit="px", factor=1.0):
    """RGB colour bar: the gradient from ``lo`` to ``hi`` over a white strip with the limits and 0 in black.

    The limits are written times ``factor`` in ``unit`` (strain: 100 and "%"). White margins left and
    right keep the labels of two bars side by side apart.
    """
    import cv2
    bar = np.full((_BAR_GRADIENT_HEIGHT + _BAR_TEXT_HEIGHT, _BAR_WIDTH, 3), 255, dtype=np.uint8)
    first, last = _BAR_MARGIN, _BAR_WIDTH - 1 - _BAR_MARGIN          # the gradient's end columns
    columns = np.arange(last - first + 1)
    bar[:_BAR_GRADIENT_HEIGHT, first:last + 1] = lut[(columns * lut.shape[0]) // columns.size][None, :, :]
    font, font_scale, thickness = cv2.FONT_HERSHEY_SIMPLEX, 0.62, 2
    baseline_y = _BAR_GRADIENT_HEIGHT + _BAR_TEXT_HEIGHT - 7
    black = (0, 0, 0)

    def tick(x):
        cv2.line(bar, (x, _BAR_GRADIENT_HEIGHT), (x, _BAR_GRADIENT_HEIGHT + 5), black, 2)

    def text_width(text):
        return cv2.getTextSize(text, font, font_scale, thickness)[0][0]

    left, right = f"{_fmt(lo * factor)} {unit}", f"{_fmt(hi * factor)} {unit}"
    left_end, right_start = first + text_width(left), last + 1 - text_width(right)
    cv2.putText(bar, left, (first, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    cv2.putText(bar, right, (right_start, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    tick(first)
    tick(last)
    if lo < 0 < hi:
        zero_x = first + int(round((0 - lo) / (hi - lo) * (last - first)))
        tick(zero_x)
        half = text_width("0") // 2
        if left_end + 6 < zero_x - half and zero_x + half + 6 < right_start:    # only where it does not overlap
            cv2.putText(bar, "0", (zero_x - half, baseline_y), font, font_scale, black, thickness, cv2.LINE_AA)
    return bar


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


def _extensometer_colour(index):
    return _EXTENSOMETER_COLOURS[index % len(_EXTENSOMETER_COLOURS)]


def _darker(rgb, factor=0.45):
    return tuple(int(c * factor) for c in rgb)


def _label_anchors(first, second, labels, side):
    """Where each extensometer's label goes: beyond its second end, clear of the other lines' labels.

    A mostly vertical line's label sits under its end (over it, for a line drawn upwards); a mostly horizontal
    line's label starts just beyond its end and is raised above the line. So the labels of an axial and a
    transverse extensometer crossing at P0 never meet each other or P0's label (under P0), however short the
    transverse one is. ``first``, ``second``: (N, 2) ends in scene units; ``side``: the image side in them.
    """
    step = second - first
    vertical = np.abs(step[:, 1]) >= np.abs(step[:, 0])
    down, right = np.where(step[:, 1] >= 0, 1.0, -1.0), np.where(step[:, 0] >= 0, 1.0, -1.0)
    half_width = np.array([0.5 * len(label) * _LABEL_CHARACTER for label in labels])
    dx = np.where(vertical, 0.0, right * (half_width + _LABEL_GAP))
    dy = np.where(vertical, np.where(down > 0, _LABEL_GAP, -_LABEL_GAP - _LABEL_HEIGHT),
                  -_LABEL_GAP - _LABEL_HEIGHT)
    return second + side * np.column_stack([dx, dy])


def _plot_share(view):
    """A strain plot's height in the plot column: the XY plots (stress-strain, transverse vs axial) more than
    the time series, since their box keeps its aspect and their numbers and titles need the room."""
    return 3.5 if type(view).__name__ == "Spatial2DView" else 2.5


def _legend_top_left():
    """The legend of the strain and force plots: a tensile test's strains and force start at 0 and move away
    from it as time goes right, so the top left corner stays clear of the curves."""
    import rerun.blueprint as rrb
    return rrb.PlotLegend(corner=rrb.Corner2D.LeftTop, visible=True)


def _small_plot(path):
    """A small time-series view of ``path``: its name keys the colours, no legend over the curves."""
    import rerun.blueprint as rrb
    return rrb.TimeSeriesView(name=_SMALL_PLOT_NAMES[path], origin=path, plot_legend=rrb.PlotLegend(visible=False))


def _strain_view_name(strain):
    """The e_yy view's name: the measure and the virtual strain gauge, e.g. "e_yy (%) engineering, VSG 77 px"."""
    return f"e_yy (%) {strain.config.measure}, VSG {strain.vsg_px:.0f} px"


def _axial_transverse_pair(strain):
    """(index of "axial", index of "transverse") among the extensometers, or None without the pair."""
    names = [e.name for e in strain.extensometers] if strain is not None else []
    if AXIAL in names and TRANSVERSE in names:
        return names.index(AXIAL), names.index(TRANSVERSE)
    return None


def _ticks(lo, hi):
    """At most ``_XY_MAX_TICKS`` + 1 round values from ``lo`` to ``hi`` (lo <= 0 <= hi), 0 among them."""
    step = nice_ceil((hi - lo) / _XY_MAX_TICKS, (1.0, 2.0, 2.5, 5.0, 10.0))
    first = np.ceil(lo / step - 1e-9)
    return [float(f"{k * step:.6g}") + 0.0 for k in np.arange(first, np.floor(hi / step + 1e-9) + 1)]


def _tick_label(value):
    return "0" if value == 0 else f"{value:g}"


def _poisson_text(poisson):
    """Poisson's ratio's elastic fit in a few words: "Poisson 0.300 +- 0.002 (elastic fit, frames 0-45)"."""
    if poisson is None:
        return "Poisson: no fit yet"
    if not np.isfinite(poisson.value):
        return f"Poisson: n/a ({poisson.reason.value})"
    return (f"Poisson {poisson.value:.3f} +- {poisson.standard_error:.3f} "
            f"(elastic fit, frames {poisson.frames[0]}-{poisson.frames[1]})")


def _fmt(value):
    if not np.isfinite(value):
        return "n/a"
    return f"{value:+.3g}" if abs(value) < 1000 else f"{value:+.0f}"


class _RrdFile:
    """The .rrd of ``--viewer save``: Rerun's own file sink writes into a pipe, a thread here into the file.

    Rerun's file sink (``RecordingStream.save``), when its file cannot be written (a full disk), logs its
    own error lines and then hangs ``disconnect`` for good (rerun-sdk 0.41): the session would never end
    nor print its summary. Through a pipe the sink never fails; a write that fails here is one
    ``on_error(message)`` line, the file keeps the bytes written (Rerun's viewer opens such a cut
    stream up to the cut), and the rest of the stream is read and dropped. ``sink_path`` is what to
    give ``save``; ``close`` after the recording stream's ``disconnect``.
    """

    def __init__(self, path, on_error):
        self.path = path
        self.on_error = on_error
        self.error = None
        self.bytes_written = 0
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self._read_end, self._write_end = os.pipe()
        self.sink_path = f"/dev/fd/{self._write_end}"
        self._thread = threading.Thread(target=self._copy, name="livedic-rrd-writer", daemon=True)
        self._thread.start()

    def _copy(self):
        while data := os.read(self._read_end, 1 << 20):
            if self.error is not None:
                continue                  # drained, so the sink never waits on a full pipe
            try:
                view = memoryview(data)
                while view:
                    written = os.write(self._fd, view)
                    self.bytes_written += written
                    view = view[written:]
            except OSError as error:
                self.error = f"{self.path}: {error.strerror or error}"
                self.on_error(f"Rerun view file stopped: cannot write {self.error}; the session goes on, the file "
                              f"keeps its first {self.bytes_written / 1e6:.1f} MB")
        os.close(self._read_end)

    def close(self):
        """After the sink let go of the pipe: the copy ends at the pipe's end, the file is closed."""
        os.close(self._write_end)
        self._thread.join(timeout=30.0)
        os.close(self._fd)


class _XYPlot:
    """An XY plot in a 2D view (Rerun has no XY plot): a fixed box whose axes grow with the data.

    The curve is logged in data units (x, -y) under ``ROOT/data``, whose transform maps the current
    limits onto the box (``_XY_BOX``; image coordinates run down, hence -y); the limits start at
    ``x_start``/``y_start`` (lo <= 0 <= hi) and only grow, to 1, 2 or 5 times a power of ten, and each
    growth logs one new transform (the whole curve rescales: the segments already logged stay as they
    are) and new axes. One segment a frame, shown up to the time cursor (``history_override``); a
    frame without a value leaves a gap and clears the current point.

    Entities: ``ROOT/data/curve`` (and ``ROOT/data/SECOND`` for a second curve), ``ROOT/now`` (the
    current point, and the numbers above the box), ``ROOT/axes``, ``ROOT/ticks``, and with ``names`` (one
    per curve) ``ROOT/legend``: a short line in each curve's colour with its name, in the box's lower right.
    """

    def __init__(self, root, *, x_title, y_title, x_start, y_start, colours, second=None, x_title_under_zero=True,
                 mantissas=_AXIS_MANTISSAS, names=None):
        self.root = root
        self.data, self.curve, self.now = f"{root}/data", f"{root}/data/curve", f"{root}/now"
        self.axes, self.ticks = f"{root}/axes", f"{root}/ticks"
        self.second = f"{root}/data/{second}" if second else None
        self.legend, self.names = f"{root}/legend", names
        self.x_title, self.y_title = x_title, y_title
        self.x_title_under_zero = x_title_under_zero     # inside the box, under the x axis; else above the bottom
        self.mantissas = mantissas                        # the nice numbers the limits grow to
        self.colours = colours
        self.limits = {"x": tuple(x_start), "y": tuple(y_start)}
        self._axes_logged = None
        self._last = {self.curve: None, self.second: None}    # each curve's previous point, None after a gap
        self.columns = None            # a _SeriesColumns the segments go to (the logger's), else logged one by one
        self.transform = ((1.0, 1.0), (0.0, 0.0))

    def view(self, name):
        import rerun.blueprint as rrb
        history = rrb.VisibleTimeRanges([
            rrb.VisibleTimeRange(timeline, start=rrb.TimeRangeBoundary.infinite(),
                                 end=rrb.TimeRangeBoundary.cursor_relative())
            for timeline in (TIMELINE_FRAME, TIMELINE_TIME)])
        width, height = _XY_BOX
        curves = [self.curve] + ([self.second] if self.second else [])
        return rrb.Spatial2DView(name=name, origin=self.root, overrides={f"/{c}": history for c in curves},
                                 visual_bounds=rrb.VisualBounds2D(x_range=[-0.08 * width, 1.03 * width],
                                                                  y_range=[-0.4 * height, 1.2 * height]))

    def start(self, rr, rec):
        """The curves' and the current point's styles (static: logged once)."""
        rec.log(self.curve, rr.LineStrips2D.from_fields(radii=-1.5, colors=[self.colours[0]]), static=True)
        if self.second:
            rec.log(self.second, rr.LineStrips2D.from_fields(radii=-1.5, colors=[self.colours[1]]), static=True)
        rec.log(self.now, rr.Points2D.from_fields(radii=[0.0, -4.0], colors=[_LABEL_TEXT_COLOUR, (255, 255, 255)],
                                                  show_labels=True, draw_order=_MARKER_DRAW_ORDER), static=True)
        if self.names:
            self._log_legend(rr, rec)

    def _log_legend(self, rr, rec):
        """Which curve is which: a short line in each curve's colour, its name after it (low in the box, left of
        the x axis' title: a tensile test's stress stays high once it has risen), in a darker shade of the colour."""
        width, height = _XY_BOX
        rows = [0.58 * height + 0.2 * height * k for k in range(len(self.names))]
        strips = [[(0.32 * width, y), (0.38 * width, y)] for y in rows]
        # a label is drawn centred under its anchor (~1.35 box units a character, ~3 high)
        anchors = [(0.39 * width + 0.68 * len(name), y - 1.6) for name, y in zip(self.names, rows)]
        colours = self.colours[:len(self.names)]
        rec.log(self.legend, rr.LineStrips2D(strips, radii=-1.5, colors=colours, draw_order=_MARKER_DRAW_ORDER),
                static=True)
        rec.log(f"{self.legend}/names", rr.Points2D(anchors, radii=0.0, labels=list(self.names),
                                                    colors=[_darker(colour) for colour in colours], show_labels=True,
                                                    draw_order=_MARKER_DRAW_ORDER), static=True)

    def add(self, rr, rec, x, y, text, second=None):
        """This frame's point (x, y) in data units with its text; ``second``: (x, y) of the second curve or None."""
        self._grow(x, y)
        if second is not None:
            self._grow(*second)
        if self._axes_logged != self.limits:
            self._log_axes(rr, rec)
        point = (x, -y)
        self._segment(rr, rec, self.curve, point)
        if self.second:
            self._segment(rr, rec, self.second, None if second is None else (second[0], -second[1]))
        (kx, ky), (bx, by) = self.transform
        width, height = _XY_BOX
        # two labels for two points (one label alone would go to the middle of both): the numbers above the box,
        # right of its title, then the current point, unlabelled
        rec.log(self.now, rr.Points2D.from_fields(positions=[(0.68 * width, -0.3 * height),
                                                             (kx * point[0] + bx, ky * point[1] + by)],
                                                  labels=[text, ""]))

    def gap(self, rr, rec):
        """No value this frame: a gap in the curves, the current point cleared."""
        if self._last[self.curve] is not None:
            rec.log(self.now, rr.Clear(recursive=False))
        self._last = {key: None for key in self._last}

    def _segment(self, rr, rec, entity, point):
        if point is not None and self._last[entity] is not None:
            if self.columns is not None:
                self.columns.add(entity, [self._last[entity], point], kind="strip")
            else:
                rec.log(entity, rr.LineStrips2D.from_fields(strips=[[self._last[entity], point]]))
        self._last[entity] = point

    def _grow(self, x, y):
        self.limits = {"x": grow_to_cover(self.limits["x"], x, self.mantissas),
                       "y": grow_to_cover(self.limits["y"], y, self.mantissas)}

    def _log_axes(self, rr, rec):
        """The box for the current limits: frame, zero lines, grid and tick labels, and the transform."""
        width, height = _XY_BOX
        (x_lo, x_hi), (y_lo, y_hi) = self.limits["x"], self.limits["y"]
        kx, ky = width / (x_hi - x_lo), height / (y_hi - y_lo)
        bx, by = -kx * x_lo, ky * y_hi                    # box X = kx * x + bx, box Y = ky * (-y) + by
        self.transform = ((kx, ky), (bx, by))
        rec.log(self.data, rr.Transform3D(translation=[bx, by, 0.0], scale=[kx, ky, 1.0]))
        x_ticks, y_ticks = _ticks(x_lo, x_hi), _ticks(y_lo, y_hi)
        strips, colours = [], []
        for tick in x_ticks:
            x = kx * tick + bx
            strips.append([(x, 0.0), (x, height)])
            colours.append(_XY_ZERO_COLOUR if tick == 0 else _XY_GRID_COLOUR)
        for tick in y_ticks:
            y = -ky * tick + by
            strips.append([(0.0, y), (width, y)])
            colours.append(_XY_ZERO_COLOUR if tick == 0 else _XY_GRID_COLOUR)
        strips.append([(0.0, 0.0), (width, 0.0), (width, height), (0.0, height), (0.0, 0.0)])
        colours.append(_XY_FRAME_COLOUR)
        rec.log(self.axes, rr.LineStrips2D(strips, radii=-0.75, colors=colours, draw_order=0.0))
        positions = [(kx * tick + bx, height + 0.02 * height) for tick in x_ticks]
        positions += [(-0.04 * width, -ky * tick + by - 0.07 * height) for tick in y_ticks]
        labels = [_tick_label(tick) for tick in x_ticks] + [_tick_label(tick) for tick in y_ticks]
        # the axis titles: y's above the box's left side; x's inside the box at the right, under the zero line
        # (a tensile test's transverse-vs-axial curve runs down and right from 0, far from there), or just above
        # the bottom (a stress-strain curve is high up at large strains)
        x_title_y = by + 0.04 * height if self.x_title_under_zero else 0.78 * height
        positions += [(0.06 * width, -0.3 * height), (0.92 * width, x_title_y)]
        labels += [self.y_title, self.x_title]
        rec.log(self.ticks, rr.Points2D(positions, radii=0.0, labels=labels, show_labels=True,
                                        colors=[_LABEL_TEXT_COLOUR]))
        self._axes_logged = dict(self.limits)


class _SeriesColumns:
    """Every frame's scalars and plot segments, sent to Rerun as columns (``send_columns``) a few times a second.

    One ``rr.Scalars`` a series a frame (and one ``rr.LineStrips2D`` a curve a frame) cost the view most of its
    per-frame time (Rerun's Python layer builds each archetype): here a frame's values are appended to lists
    at the frame being logged (``now``), and each series goes out as one column of many frames, on the same
    timelines, the same rows a ``log`` per frame gives. A gap (``clear``) sends what waits first. Not
    thread-safe: the logging thread's alone.
    """

    def __init__(self, rr, rec):
        self.rr, self.rec = rr, rec
        self.now = (0, 0.0)            # the frame being logged: (index, seconds since the first)
        self._rows = {}                # path -> (kind, [frame], [time s], [values])
        self._last_sent = time.monotonic()

    def add(self, path, values, kind="scalars"):
        """``values`` of the series ``path`` at ``now``: scalars, or one 2-D strip (``kind="strip"``)."""
        rows = self._rows.get(path)
        if rows is None:
            rows = self._rows[path] = (kind, [], [], [])
        rows[1].append(self.now[0])
        rows[2].append(self.now[1])
        rows[3].append(values)

    def clear(self, path):
        """A gap in the series at the current time: what waits goes first."""
        self.send(path)
        self.rec.log(path, self.rr.Clear(recursive=False))

    def send_when_due(self):
        if time.monotonic() - self._last_sent >= SERIES_SEND_S:
            self.send()

    def send(self, path=None):
        rr = self.rr
        for key in [path] if path is not None else list(self._rows):
            rows = self._rows.pop(key, None)
            if not rows:
                continue
            kind, frames, seconds, values = rows
            values = np.asarray(values, dtype=np.float64)
            columns = rr.Scalars.columns(scalars=values) if kind == "scalars" else rr.LineStrips2D.columns(
                strips=values)
            rr.send_columns(key, indexes=[rr.TimeColumn(TIMELINE_FRAME, sequence=frames),
                                          rr.TimeColumn(TIMELINE_TIME, duration=seconds)],
                            columns=columns, recording=self.rec)
        if path is None:
            self._last_sent = time.monotonic()


class RerunLogger:
    """Sends a live session to Rerun (see module notes); a session sink (``stream.sinks``).

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
        Fixed colour limits (lo, hi) in px for u and v; None: the automatic scale (module notes).
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
        (``_RrdFile``).

    Raises
    ------
    ValueError
        A viewer that cannot be started or reached, or a colour range that is not two finite numbers
        with lo < hi.
    """

    name = "Rerun view"
    stage = "view"
    required = False

    def __init__(self, mode, target=None, *, recording_name="livedic session", image_max_side=512,
                 image_every=1, image_max_hz=None, flush_interval_s=1.0, color_range=None, low_zncc=0.8,
                 thin_when_behind=False,
                 on_error=None):
        if color_range is not None:
            lo, hi = (float(value) for value in color_range)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"colour range {lo:g},{hi:g}: give LO,HI with LO below HI, both finite "
                                 f"(e.g. --color-range -2,2)")
            color_range = (lo, hi)
        self.color_range = color_range
        self.low_zncc = float(low_zncc)
        self.mode = mode
        self.target = target
        self.image_max_side = int(image_max_side)
        self.image_max_hz = image_max_hz
        self.images = CameraImagePacing(image_every=image_every, image_max_hz=image_max_hz,
                                        thin_when_behind=thin_when_behind)
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
        start_limits = color_range or (-MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_PX)
        self.colour_limits = {LEGEND_U: start_limits, LEGEND_V: start_limits,   # what the bars show now
                              LEGEND_EYY: (-MIN_COLOUR_LIMIT_STRAIN, MIN_COLOUR_LIMIT_STRAIN)}
        self._limits_logged = {}
        self._radius_key = None
        self._radius = 4.0
        self._image_side = None
        self._last_u = self._last_v = None       # last ok displacement per point, to place lost markers
        self._flagged_shown = {LOST: False, LOW_ZNCC: False}
        self._tracking_text = None
        self._first_bars = {}                    # legend -> (limits, image) drawn by start()
        self._no_strain_colour = pack_colours([_NO_STRAIN_COLOUR])[0]
        self._extensometer_colours = self._lost_colour = None
        self._strain = None                      # the session's stream.strain.StrainStage, from start()
        self._end_u = self._end_v = None         # last known displacement of each extensometer end
        self._series_shown = {}                  # extensometer name -> its strain series has a value now
        self._xy_pair = None                     # (axial index, transverse index) for the transverse-vs-axial plot
        self._strain_xy = None                   # that plot (_XYPlot), from start()
        self._fit_drawn = None                   # (value, frames) of the elastic fit drawn on it
        self._load = None                        # the session's stream.load_stage.LoadStage, from start()
        self._stress_xy = None                   # the stress-strain plot (_XYPlot): with a load, A0 and "axial"
        self._force_shown = False
        self._fractured = False                  # a fracture was detected (result.fracture)
        self._broken = False                     # ... and the force fell below FRACTURE_DROP of its maximum
        self._max_force_N = -np.inf
        self.log_seconds = 0.0
        self.frames_logged = 0
        self._file = None                        # _RrdFile of mode "save"
        self.on_error = on_error
        if mode == "none":
            return
        import rerun as rr
        self.rr = rr
        self.rec = rr.RecordingStream(APPLICATION_ID)
        self.rec.send_recording_name(recording_name)
        self._lut = colormap_lut()
        self._packed_lut = pack_colours(self._lut)
        self._blueprint = None
        self._series = _SeriesColumns(rr, self.rec)

    @property
    def enabled(self):
        return self.rec is not None and not (self._file is not None and self._file.error)

    @property
    def file_error(self):
        """Why the .rrd of mode "save" stopped (a full disk), or None."""
        return self._file.error if self._file is not None else None

    def _file_failed(self, message):
        """The .rrd could not be written (full disk): told once; logging stops, the session goes on."""
        if self.on_error is not None:
            self.on_error(message)

    # ----------------------------------------------------------------- setup
    def start(self, *, image_shape, roi=None, p0_index=None, points=None, has_truth=False, title=None,
              source_settings=None, strain=None, load=None, setup=None):
        """Open the sink and log what does not change (blueprint, ROI, colour bars, series styles).

        ``setup`` is the session's ``stream.preview.SetupOverlay`` (None: the ROI's box only): the region's
        outline on the camera view and the set-up view (``log_setup``).

        ``strain`` is the session's ``stream.strain.StrainStage`` (None: no strain): with it the view
        adds e_yy, the extensometers and their plots (module notes). ``load`` is the session's
        ``stream.load_stage.LoadStage`` (None: no force): with it the force against time and, with
        a cross-section and an ``axial`` extensometer, the stress-strain curve.
        """
        if not self.enabled:
            return
        rr = self.rr
        self._strain = strain
        self._load = load
        height, width = image_shape
        self._scale = scale = display_scale(image_shape, self.image_max_side)
        self._p0 = p0_index
        blueprint = self._make_blueprint(has_truth, strain, load, setup=setup is not None)
        if self.mode == "save":
            directory = os.path.dirname(os.path.abspath(self.target))
            os.makedirs(directory, exist_ok=True)
            self._file = _RrdFile(self.target, self._file_failed)
            self.rec.save(self._file.sink_path, default_blueprint=blueprint)
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
        self._image_side = max(height, width)
        if setup is not None:
            self.log_setup(setup)
        elif roi is not None:
            self._log_roi(roi)
        # drawn now: OpenCV's first text call takes ~30 ms, which would land on the first frame
        for legend in (LEGEND_U, LEGEND_EYY) if strain is not None else (LEGEND_U,):
            _, unit, factor = _LEGENDS[legend]
            limits = self.colour_limits[legend]
            self._first_bars[legend] = (limits, colour_bar_image(self._lut, *limits, unit=unit, factor=factor))
        if strain is not None:
            self._start_strain(strain)
        if load is not None:
            rec.log(FORCE, rr.SeriesLines(names=["force (kN)"], colors=[_STRESS_COLOURS[0]], widths=[2.0]),
                    static=True)
        if self._stress_xy is not None:
            self._stress_xy.start(rr, rec)
        if self.color_range is not None:      # fixed: static; automatic: logged with the first frame
            for legend in (LEGEND_U, LEGEND_V):
                self._log_limits(legend, static=True)
        lines = [f"# {title or 'livedic session'}", "",
                 f"{len(points) if points is not None else 0} points; camera image shown at 1/{scale} scale."]
        if strain is not None:
            lines += ["", strain.describe() + "."]
        if source_settings:
            lines += ["", "| setting | value |", "|---|---|"]
            lines += [f"| {k} | {v} |" for k, v in source_settings.items()]
        rec.log(SUMMARY, rr.TextDocument("\n".join(lines), media_type=rr.MediaType.MARKDOWN), static=True)

    def log_setup(self, setup):
        """The set-up (a ``stream.preview.SetupOverlay``): the region's outline on the camera view, and the
        set-up view as ``livedic preview`` draws it (module notes). Static: logged once, at the start."""
        rr, rec = self.rr, self.rec
        preview = setup                 # the overlay carries the palette the preview draws in
        scale = float(self._scale)

        def strips(polylines):
            return [np.asarray(line, dtype=np.float64) / scale for line in polylines]

        region = strips(setup.outlines)
        excluded = strips(setup.exclusions)
        outline = rr.LineStrips2D(region + excluded, radii=-1.5, colors=[preview.REGION_COLOUR] * len(region)
                                  + [preview.EXCLUDED_COLOUR] * len(excluded))
        # Rerun puts a strip's label at its middle, where P0 and the extensometers cross: the labels are
        # points of their own, at the ends ``livedic preview`` labels
        for path in (CAMERA_ROI, f"{SETUP}/region"):
            rec.log(path, outline, static=True)
        region_label = self._roi_label(setup.placement.bounds, setup.region_label)
        rec.log(CAMERA_ROI_LABEL, region_label, static=True)
        rec.log(f"{SETUP}/region/label", region_label, static=True)
        labels = [((float(line[:, 0].max()), float(line[:, 1].min())), "excluded") for line in excluded]
        image = setup.image
        rec.log(f"{SETUP}/image", rr.Image(self._display_image(image, setup.pixel_format)), static=True)
        # at the display's scale: this runs as the first frame is tracked, every ms of it a ms of latency
        quality, step = setup.quality, self._scale
        inside = setup.placement.region[::step, ::step]
        mig = quality.mig[::step, ::step]
        top = float(np.percentile(mig[inside], 99)) if inside.any() else 1.0
        index = np.clip(mig * (255.0 / max(top, 1e-6)), 0, 255).astype(np.uint8)
        rgba = np.empty(mig.shape + (4,), dtype=np.uint8)
        rgba[..., :3] = self._lut[index]
        rgba[..., 3] = np.where(inside, 150, 0)
        rgba[quality.clipped[::step, ::step] & inside] = (*preview.CLIPPED_COLOUR, 255)
        rec.log(f"{SETUP}/mig", rr.Image(rgba), static=True)
        points = setup.placement.points / scale
        colours = np.where(setup.weak[:, None], preview.WEAK_POINT_COLOUR, preview.POINT_COLOUR).astype(np.uint8)
        rec.log(f"{SETUP}/points", rr.Points2D(points, colors=colours, radii=-1.5), static=True)
        half = setup.subset / 2.0 / scale
        p0 = points[0]
        rec.log(f"{SETUP}/p0", rr.Boxes2D(mins=[p0 - half], sizes=[[2 * half, 2 * half]], colors=[preview.P0_COLOUR],
                                          radii=-1.5), static=True)
        labels.append(((float(p0[0] - half), float(p0[1] + half)), f"P0 ({setup.subset} px subset)"))
        if setup.extensometers:
            colours = [preview.EXTENSOMETER_COLOURS[k % len(preview.EXTENSOMETER_COLOURS)]
                       for k in range(len(setup.extensometers))]
            rec.log(f"{SETUP}/extensometers",
                    rr.LineStrips2D([[(e.x1 / scale, e.y1 / scale), (e.x2 / scale, e.y2 / scale)]
                                     for e in setup.extensometers], colors=colours, radii=-2.0), static=True)
            for e, colour in zip(setup.extensometers, colours):
                # the far end along x, the upper end along y: clear of the crossing at P0
                along_y = abs(e.y2 - e.y1) >= abs(e.x2 - e.x1)
                end = min(((e.x1, e.y1), (e.x2, e.y2)), key=lambda p: p[1] if along_y else -p[0])
                labels.append(((end[0] / scale, end[1] / scale), setup.extensometer_label(e)))
        rec.log(f"{SETUP}/labels", self._label_points(labels), static=True)
        advice = setup.advice()
        notes = ["# set-up", "", *(f"- {line}" for line in setup.lines()), "",
                 "**check:**" if advice else "nothing to check: pattern, exposure and focus look fit for DIC",
                 *(f"- {line}" for line in advice)]
        rec.log(SETUP_NOTES, rr.TextDocument("\n".join(notes), media_type=rr.MediaType.MARKDOWN), static=True)

    def _label_points(self, labels):
        """Points2D that carry ``labels`` [((x, y) display px, text)]: dark text on Rerun's light label box."""
        rr = self.rr
        return rr.Points2D([xy for xy, _ in labels], labels=[text for _, text in labels],
                           colors=[_LABEL_TEXT_COLOUR] * len(labels), radii=0.0, show_labels=True,
                           draw_order=_MARKER_DRAW_ORDER + 2)

    def _roi_label(self, bounds, text):
        """``text`` above the top-left corner of ``bounds`` (x, y, w, h; image px): clear of what is inside,
        however narrow the region (labels are drawn centred under their anchor)."""
        scale = self._scale
        x, y, _, _ = bounds
        left, top = x / scale - 0.5, y / scale - 0.5
        side = self._image_side / scale
        anchor = (left + 0.5 * len(text) * _LABEL_CHARACTER * side, top - (_LABEL_HEIGHT + _LABEL_GAP) * side)
        return self._label_points([(anchor, text)])

    def _log_roi(self, roi):
        """The ROI's box (no set-up drawn), and its name above it in dark text on Rerun's light label box (the
        box's own label, in its yellow, was unreadable on speckle)."""
        rr, scale = self.rr, self._scale
        x, y, w, h = roi
        self.rec.log(CAMERA_ROI, rr.Boxes2D(mins=[[x / scale - 0.5, y / scale - 0.5]], sizes=[[w / scale, h / scale]],
                                            colors=[(255, 200, 0)]), static=True)
        self.rec.log(CAMERA_ROI_LABEL, self._roi_label(roi, "ROI"), static=True)

    def _plan_plots(self, strain, load):
        """The XY plots this session shows: transverse vs axial, stress-strain (None where it has not the data)."""
        self._xy_pair = _axial_transverse_pair(strain)
        self._strain_xy = self._stress_xy = None
        if self._xy_pair is not None:
            self._strain_xy = _XYPlot(STRAIN_XY, x_title="axial (%)", y_title="transverse (%)",
                                      x_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      y_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      colours=[_extensometer_colour(0)])
        has_axial = strain is not None and AXIAL in [e.name for e in strain.extensometers]
        if load is not None and load.area_mm2 and has_axial:
            self._stress_xy = _XYPlot(STRESS_STRAIN, x_title="axial strain (%)", y_title="stress (MPa)",
                                      x_start=(-100 * MIN_XY_LIMIT_STRAIN, 100 * MIN_XY_LIMIT_STRAIN),
                                      y_start=(0.0, MIN_XY_LIMIT_STRESS_MPA), colours=_STRESS_COLOURS,
                                      second="true", x_title_under_zero=False, mantissas=_NICE_MANTISSAS,
                                      names=("engineering", "true (to max. force)"))
        for plot in (self._strain_xy, self._stress_xy):
            if plot is not None:
                plot.columns = self._series       # their segments go out as columns with the series

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

    def _make_blueprint(self, has_truth, strain=None, load=None, *, setup=False):
        import rerun.blueprint as rrb
        self._plan_plots(strain, load)
        field = "$origin/image", "$origin/p0", f"/{LOST}", f"/{LOW_ZNCC}"
        extensometers = [f"/{EXTENSOMETER_LINES}"] if strain is not None else []
        camera = rrb.Spatial2DView(name="camera", origin=CAMERA, contents=[*field, "$origin/roi/**", *extensometers])
        if setup:      # the set-up a tab behind the camera: one click away, the live image in front
            camera = rrb.Tabs(camera, rrb.Spatial2DView(name="set-up", origin=SETUP),
                              rrb.TextDocumentView(name="set-up notes", origin=SETUP_NOTES), active_tab=0)
        image_views = [
            camera,
            rrb.Spatial2DView(name="u (px)", origin=CAMERA, contents=[*field, f"/{FIELD_U}"]),
            rrb.Spatial2DView(name="v (px)", origin=CAMERA, contents=[*field, f"/{FIELD_V}"]),
        ]
        legend_views = [
            rrb.Vertical(rrb.TextDocumentView(name="tracking", origin=TRACKING),
                         rrb.TextDocumentView(name="session", origin=SUMMARY), row_shares=[1, 2]),
            rrb.Spatial2DView(name="u colour scale (px)", origin=LEGEND_U),
            rrb.Spatial2DView(name="v colour scale (px)", origin=LEGEND_V),
        ]
        strain_plots = []
        if strain is None:
            left = rrb.Vertical(rrb.Horizontal(*image_views), rrb.Horizontal(*legend_views), row_shares=[4, 1])
        else:
            # four fields do not fit in a row: a 2 x 2 grid, each view over its colour bar, camera and e_yy on top
            eyy = rrb.Spatial2DView(name=_strain_view_name(strain), origin=CAMERA,
                                    contents=[*field, f"/{FIELD_EYY}", *extensometers])
            eyy_bar = rrb.Spatial2DView(name="e_yy colour scale (%)", origin=LEGEND_EYY)
            _, u_bar, v_bar = legend_views
            texts = rrb.Horizontal(rrb.TextDocumentView(name="tracking", origin=TRACKING),
                                   rrb.TextDocumentView(name="session", origin=SUMMARY), column_shares=[1, 2])
            cells = [(image_views[0], texts), (eyy, eyy_bar), (image_views[1], u_bar), (image_views[2], v_bar)]
            left = rrb.Grid(*(rrb.Vertical(view, under, row_shares=[5, 1]) for view, under in cells), grid_columns=2)
            strain_plots = self._strain_plots(strain)
        if self._stress_xy is not None:    # what a tensile test is run for: the first plot
            strain_plots.insert(0, self._stress_xy.view("stress-strain (MPa, %)"))
        if load is not None:
            strain_plots.append(rrb.TimeSeriesView(name="force (kN)", origin=FORCE, plot_legend=_legend_top_left()))
        small = [_small_plot(path) for path in (P0, QUALITY, THROUGHPUT, LATENCY, DROPS)]
        small += [_small_plot(ERROR)] if has_truth else []
        events = rrb.TextLogView(name="events", origin=EVENTS)
        if not strain_plots:
            plots = rrb.Vertical(*small, events)
        else:
            # The strain plots are what a test engineer watches: they take the height; the small plots go two to
            # a row below them (ZNCC, with three series to name, the wider), each still tall enough to read.
            pairs = [small[k:k + 2] for k in range(0, len(small), 2)]
            rows = [rrb.Horizontal(*pair, column_shares=([2, 3] if k == 0 else [1, 1])[:len(pair)])
                    for k, pair in enumerate(pairs)]
            plots = rrb.Vertical(*strain_plots, *rows, events,
                                 row_shares=[_plot_share(view) for view in strain_plots] + [2] * len(rows) + [1.2])
        return rrb.Blueprint(rrb.Horizontal(left, plots, column_shares=[3, 2]), collapse_panels=True)

    def _strain_plots(self, strain):
        """The extensometer strain series and the transverse-vs-axial plot (none without extensometers)."""
        import rerun.blueprint as rrb
        if not strain.extensometers:
            return []
        plots = [rrb.TimeSeriesView(name="extensometer strain (%)", origin=EXTENSOMETER_STRAIN,
                                    plot_legend=_legend_top_left())]
        if self._strain_xy is not None:
            plots.append(self._strain_xy.view("transverse vs axial strain (%)"))
        return plots

    # ----------------------------------------------------------------- per frame
    @property
    def images_above_rate(self):
        """Camera images left out by ``image_max_hz``."""
        return self.images.images_above_rate

    @property
    def images_left_out(self):
        """Frames whose camera image was left out while the view was behind."""
        return self.images.images_left_out

    def log_frame(self, result, stats, *, camera_image=None):
        """Log one ``stream.tracker_loop.FrameResult`` (a TrackerLoop sink).

        ``camera_image``: this frame's camera image as drawn (``display_image``), chosen by the caller
        (``stream.view.process``: paced and prepared in the session's process); None: chosen here, by
        ``images`` (a ``CameraImagePacing``), from ``result.frame.image``. ``stats`` is not read.
        """
        if not self.enabled:
            return
        started = time.perf_counter()
        rr, rec = self.rr, self.rec
        frame = result.frame
        m = result.measurement
        if self._t0_ns is None:
            self._t0_ns = frame.timestamp_ns
        now = self._series.now = (int(frame.index), (frame.timestamp_ns - self._t0_ns) / 1e9)
        rec.set_time(TIMELINE_FRAME, sequence=now[0])
        rec.set_time(TIMELINE_TIME, duration=now[1])
        ok = m.ok
        self._log_fields(result, m, camera_image)
        if self._strain is not None and result.extensometers is not None and len(result.extensometers.names):
            self._log_extensometer_series(result.extensometers, result.poisson)
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

    def _scalars(self, path, values):
        """This frame's values of the series ``path`` (sent with the next columns: ``_SeriesColumns``)."""
        self._series.add(path, values)

    def _log_fields(self, result, m, camera_image=None):
        """The camera image, the u, v (and e_yy) fields, the extensometer lines, the flagged points and P0's marker."""
        rr, rec, frame = self.rr, self.rec, result.frame
        if camera_image is None and frame.image is not None and self.images.due(frame.timestamp_ns,
                                                                                  result.output_backlog > 0):
            camera_image = self._display_image(frame.image, frame.pixel_format)
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
        if self._strain is not None and result.extensometers is not None and len(result.extensometers.names):
            self._log_extensometer_lines(m, result.extensometers)
        self._log_flagged(m, px, py, radius)
        p0 = self._p0
        if p0 is not None and 0 <= p0 < m.u.size:
            # a negative radius is in UI points: the same size at any zoom
            rec.log(CAMERA_P0, rr.Points2D([[px[p0], py[p0]]], labels=["P0"], radii=-4.0,
                                           colors=[(255, 0, 255) if ok[p0] else (128, 128, 128)],
                                           show_labels=True, draw_order=_MARKER_DRAW_ORDER + 1))

    def event(self, message, level="info"):
        """A line in the viewer's event log (level: info, warning or error)."""
        if not self.enabled:
            return
        rr = self.rr
        levels = {"info": rr.TextLogLevel.INFO, "warning": rr.TextLogLevel.WARN, "error": rr.TextLogLevel.ERROR}
        self.rec.log(EVENTS, rr.TextLog(message, level=levels.get(level, rr.TextLogLevel.INFO)))

    def _display_image(self, image, pixel_format):
        return display_image(image, pixel_format, self._scale)

    def _point_radius(self, m):
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

    def _colours(self, values, lo, hi):
        """(N, 3) uint8 colours of ``values`` on the scale [lo, hi] (outside: the end colours)."""
        return self._lut[self._lut_index(values, lo, hi)]

    def _lut_index(self, values, lo, hi):
        """Colour-map index of finite ``values`` on the scale [lo, hi] (outside: the ends)."""
        top = self._lut.shape[0] - 1
        return np.clip((values - lo) * (top / (hi - lo)) + 0.5, 0, top).astype(np.int64)

    def _log_limits(self, legend, static=False):
        """The colour bar image with its labels and the numeric limits, for ``legend``."""
        rr = self.rr
        lo, hi = self.colour_limits[legend]
        entity, unit, factor = _LEGENDS[legend]
        limits, bar = self._first_bars.get(legend, (None, None))
        if limits != (lo, hi):
            bar = colour_bar_image(self._lut, lo, hi, unit=unit, factor=factor)
        self.rec.log(f"{legend}/bar", rr.Image(bar), static=static)
        self.rec.log(entity, rr.Scalars([lo, hi]), static=static)
        self._limits_logged[legend] = (lo, hi)

    # ----------------------------------------------------------------- strain
    def _start_strain(self, strain):
        """Series styles and the drawing styles of the strain entities (static: logged once, not per frame)."""
        rr, rec = self.rr, self.rec
        rec.log(LIMITS_EYY, rr.SeriesLines(names=["e_yy low", "e_yy high"], colors=[(48, 18, 59), (122, 4, 3)]),
                static=True)
        count = len(strain.extensometers)
        self._end_u, self._end_v = np.zeros(2 * count), np.zeros(2 * count)
        self._extensometer_colours = pack_colours([_extensometer_colour(i) for i in range(count)])
        self._lost_colour = pack_colours([_EXTENSOMETER_LOST_COLOUR])[0]
        # label text takes its strip's colour, on Rerun's light label box: darker shades of the line colours
        self._label_colours = pack_colours([_darker(_extensometer_colour(i)) for i in range(count)])
        self._lost_label_colour = pack_colours([_darker(_EXTENSOMETER_LOST_COLOUR)])[0]
        for i, extensometer in enumerate(strain.extensometers):
            rec.log(f"{EXTENSOMETER_STRAIN}/{extensometer.name}",
                    rr.SeriesLines(names=[extensometer.name], colors=[_extensometer_colour(i)], widths=[2.0]),
                    static=True)
            self._series_shown[extensometer.name] = False
        if count:
            # label anchors (2+ extensometers), black outlines, then the coloured lines over them (module notes)
            radii = ([0.0] * count if count > 1 else []) + [-3.0] * count + [-1.5] * count
            rec.log(EXTENSOMETER_LINES, rr.LineStrips2D.from_fields(radii=radii, show_labels=True,
                                                                    draw_order=_EXTENSOMETER_DRAW_ORDER), static=True)
        if self._strain_xy is not None:
            self._strain_xy.start(rr, rec)
            rec.log(STRAIN_XY_FIT, rr.LineStrips2D.from_fields(radii=-2.5, colors=[_FIT_COLOUR],
                                                               draw_order=_MARKER_DRAW_ORDER), static=True)

    def _log_strain_field(self, strain, ok, px, py, radius):
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
        self.rec.log(FIELD_EYY, rr.Points2D(np.column_stack([px[shown], py[shown]]), radii=radius, colors=colours))

    def _log_extensometer_lines(self, m, readings):
        """The extensometers on the image, between the ends' current positions, labelled with their strain.

        One LineStrips2D: Rerun puts a strip's label at its middle, and labels only the first strips when
        there are fewer labels than strips: an invisible zero-length strip beyond each second end
        (``_label_anchors``) comes first and carries the label, so "axial" reads below its lower end and
        "transverse" beyond its right end, above the line, clear of P0 where the two cross (one extensometer
        alone is labelled at its middle). Then each line twice: black and wide, then in its colour, so it shows
        on the speckle and on any colour of the field.
        """
        rr, rec, strain = self.rr, self.rec, self._strain
        end_u, end_v = end_displacements(strain.placed, strain.points, m.u, m.v, m.ok)
        known = np.isfinite(end_u) & np.isfinite(end_v)
        np.copyto(self._end_u, end_u, where=known)     # a lost end stays where it was last seen
        np.copyto(self._end_v, end_v, where=known)
        ends = strain.placed.ends
        scale = float(self._scale)
        where = np.column_stack([(ends[:, 0] + self._end_u) / scale, (ends[:, 1] + self._end_v) / scale])
        first, second = where[0::2], where[1::2]
        ok = readings.ok
        colours = np.where(ok, self._extensometer_colours, self._lost_colour).astype(np.uint32)
        label_colours = np.where(ok, self._label_colours, self._lost_label_colour).astype(np.uint32)
        labels = [f"{name} {100 * e:.3f} %" if good else f"{name}: lost"
                  for name, e, good in zip(readings.names, readings.eng_strain, ok)]
        lines = np.stack([first, second], axis=1)
        black = np.full(len(lines), _BLACK, dtype=np.uint32)
        strips, strip_colours = [lines, lines], [black, colours]
        if len(lines) > 1:
            anchor = _label_anchors(first, second, labels, self._image_side / scale)
            strips.insert(0, np.stack([anchor, anchor], axis=1))
            strip_colours.insert(0, label_colours)
        rec.log(EXTENSOMETER_LINES, rr.LineStrips2D.from_fields(strips=np.concatenate(strips),
                                                                colors=np.concatenate(strip_colours), labels=labels))

    def _log_extensometer_series(self, readings, poisson=None):
        """Each extensometer's strain series (a gap where it has no reading) and the transverse-vs-axial plot."""
        rr, rec, ok = self.rr, self.rec, readings.ok
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

    def _log_strain_xy(self, readings, poisson):
        """This frame's point of the transverse-vs-axial plot with the two strains, and Poisson's ratio's elastic
        fit so far (``dic.poisson.ContractionRatio``, or None) as a line over its range and in the numbers."""
        self._log_elastic_fit(poisson)
        a, t = self._xy_pair
        if not (readings.ok[a] and readings.ok[t]):
            self._strain_xy.gap(self.rr, self.rec)
            return
        axial, transverse = float(readings.eng_strain[a]), float(readings.eng_strain[t])
        text = f"axial {100 * axial:.3f} %   transverse {100 * transverse:.3f} %\n" + _poisson_text(poisson)
        self._strain_xy.add(self.rr, self.rec, 100.0 * axial, 100.0 * transverse, text)

    def _log_elastic_fit(self, poisson):
        """The elastic fit's line over its axial range (in the plot's data units), when it changed; cleared when NaN."""
        drawn = None if poisson is None or not np.isfinite(poisson.value) else (poisson.value, poisson.frames)
        if drawn == self._fit_drawn:
            return
        self._fit_drawn = drawn
        if drawn is None:
            self.rec.log(STRAIN_XY_FIT, self.rr.Clear(recursive=False))
            return
        ends = [(100.0 * x, -100.0 * (poisson.intercept - poisson.value * x)) for x in poisson.axial_range]
        self.rec.log(STRAIN_XY_FIT, self.rr.LineStrips2D.from_fields(strips=[ends]))

    # ----------------------------------------------------------------- force and stress
    def _log_force(self, result):
        """The force against time (a gap where unknown) and this frame's point of the stress-strain curve."""
        rr, rec = self.rr, self.rec
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
        text = f"{100 * strain:.3f} %   {stress:.1f} MPa   F {force / 1000.0:.3f} kN"
        if true_stress is not None and np.isfinite(true_stress):
            true = (100.0 * result.true_strain, true_stress)
            text += f"   true {true_stress:.1f} MPa"
        if self._broken:
            text += "   broken"
        plot.add(rr, rec, 100.0 * strain, stress, text, second=true)

    def _last_displacement(self, m):
        """Displacement per point, the last ok one where a point is not ok now (0 before its first)."""
        ok = m.ok & np.isfinite(m.u) & np.isfinite(m.v)
        if self._last_u is None or self._last_u.shape != m.u.shape:
            self._last_u, self._last_v = np.zeros(m.u.shape), np.zeros(m.v.shape)
        np.copyto(self._last_u, m.u, where=ok)
        np.copyto(self._last_v, m.v, where=ok)
        return self._last_u, self._last_v

    def _log_flagged(self, m, px, py, radius):
        """Squares at lost and low-ZNCC points, and the counts as text (each logged only when it changes)."""
        rr, rec = self.rr, self.rec
        lost = ~m.ok
        low = m.ok & (m.zncc < self.low_zncc)
        half_size = max(0.5 * radius, 2.0)      # squares of ~0.7 spacing: neighbours stay apart
        for path, flagged, colour in ((LOST, lost, _LOST_COLOUR), (LOW_ZNCC, low, _LOW_ZNCC_COLOUR)):
            if flagged.any():
                centers = np.column_stack([px[flagged], py[flagged]])
                # half_sizes sets the number of boxes (one value would draw one box)
                rec.log(path, rr.Boxes2D(centers=centers, half_sizes=np.full(centers.shape, half_size), radii=-1.0,
                                         colors=[colour], draw_order=_MARKER_DRAW_ORDER))
                self._flagged_shown[path] = True
            elif self._flagged_shown[path]:
                rec.log(path, rr.Clear(recursive=False))
                self._flagged_shown[path] = False
        text = (f"lost: {int(lost.sum())} of {lost.size} points, "
                f"low ZNCC (< {self.low_zncc:g}): {int(low.sum())}")
        if text != self._tracking_text:
            self._tracking_text = text
            rec.log(TRACKING, rr.TextDocument(text))

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
        """Send the plots' waiting values and flush the stream (the logging thread's, once it logs no more)."""
        rec = self.rec
        if rec is not None:
            self._series.send()
            rec.flush(timeout_sec=2.0)

    def _flush_loop(self):
        while not self._closing.wait(self.flush_interval_s):
            try:
                self.rec.flush(timeout_sec=2.0)     # not the series: the logging thread sends those
            except Exception:  # noqa: BLE001 - a failed flush must not kill the thread; close() reports
                pass

    def close(self):
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
