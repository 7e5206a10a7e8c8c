"""``livedic export``'s pictures of the fields: maps (PNG), an overlay video (MP4) and VTK for ParaView.

What ``livedic export FILE.mcap -o DIR`` writes besides its CSV files (``stream.export.export``):

``maps/Q/Q_FFFFFF.png`` (``--maps``: any of ``u,v,exx,eyy,exy``, default all; ``none``)
    Quantity Q of frame F colour-mapped over that frame's camera image, for every ``--every``-th
    frame with results (default 10; the reference frame and the last frame always). The camera
    image is at full resolution at the bottom left of the picture, the title (quantity, frame,
    time since the reference frame) above it, the colour bar (quantity and unit) at the right.
``overlay_Q.mp4`` (``--video Q``, default ``eyy``; ``none``)
    The same picture of Q for every frame with results, at ``--video-fps`` (default 10) frames a
    second: MPEG-4 Part 2 (fourcc ``mp4v``) in an MP4 container, the codec the pip OpenCV wheel
    writes (it has no H.264 encoder). VLC, mpv, QuickTime, Windows' player and PowerPoint play it;
    web browsers do not.
``vtk/frame_FFFFFF.vtu`` and ``fields.pvd`` (``--vtk``, default; ``--no-vtk``)
    Every frame with results as a VTK unstructured grid (meshio): the points at their reference
    positions (x, y, 0 in image px: x right, y down), point data ``u, v, exx, eyy, exy, zncc, ok,
    status, point_id`` (the values of ``fields.csv``, bit for bit) and ``displacement`` (u, v, 0;
    ParaView's "Warp By Vector" shows the deformed shape), and a triangulated surface. ``fields.pvd``
    lists the files with each frame's time (s since the reference frame), so ParaView plays them as
    a time series.

How a map is drawn (as VIC, ARAMIS or Ncorr draw a contour overlay): the reference points are
triangulated once (Delaunay, ``matplotlib.tri``), leaving out triangles with an edge longer than
``LONG_EDGE`` grid steps (they would bridge a gap in the grid: a mask, the image edge). In each
frame the triangles move with their corners to the deformed positions (x + u, y + v) and the
value is interpolated linearly over each one (the field is exact where it is affine). A triangle
is left out where a corner is not ok or has no value (NaN: a point not tracked, no strain), and
where its corners fold over (a wrong point): there the camera image shows, never a colour.

Colours: matplotlib's ``turbo`` (the live view's map), one fixed range per quantity for the whole
sequence, so a colour means the same value in every frame: ``--map-range Q=LO,HI`` (the unit of
the colour bar), or automatic, by the live view's rule over all the frames (``stream.view.colour_scale.
grow_limits``: the 0.5th/99.5th percentiles of each frame's values, the ends moving out to round
numbers, from +-0.05 px or +-0.1 % strain). Values beyond the range take the end colours.
Displacements in px, or mm with ``--scale``; strain in % (``--strain-unit microstrain``).

Every file is written whole or not at all (``acquire.atomic_file``): an export stopped halfway
leaves the pictures finished so far, each complete, and no video or ``.pvd``.
"""

import argparse
import os
import re
import xml.etree.ElementTree as ElementTree
from dataclasses import dataclass, field

import numpy as np

from livedic.acquire.atomic_file import AtomicFile
from livedic.stream.view.camera_image import display_gray
from livedic.stream.view.colour_scale import MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_STRAIN, grow_limits

QUANTITIES = ("u", "v", "exx", "eyy", "exy")
DEFAULT_EVERY = 10          # maps of 1 frame in 10: a map costs ~0.1 s and ~0.7 MB at 1 MP (docs/guide/export.md)
DEFAULT_VIDEO = "eyy"
DEFAULT_VIDEO_FPS = 10.0
DEFAULT_OPACITY = 1.0       # the field opaque: its colours read true against the colour bar
STRAIN_UNITS = {"%": 100.0, "microstrain": 1e6}
DEFAULT_STRAIN_UNIT = "%"
COLOUR_MAP = "turbo"
LONG_EDGE = 1.5             # x the grid step: a grid cell's diagonal is 1.41 steps
MAPS_FOLDER = "maps"
VTK_FOLDER = "vtk"
PVD_FILE = "fields.pvd"
VIDEO_FOURCC = "mp4v"
VIDEO_SUFFIX = ".mp4"
_MAP_NAME = re.compile(r"^(u|v|exx|eyy|exy)_\d+\.png$")
_VTU_NAME = re.compile(r"^frame_\d+\.vtu$")
_SUBPIXEL_BITS = 4          # triangle corners drawn to 1/16 px
MIN_PANEL_HEIGHT = 240      # px: the colour bar's height at least, below an image smaller than that
PNG_COMPRESSION = 3         # zlib level: half the size of OpenCV's default for +40 ms a 1 MP map


def video_name(quantity):
    return f"overlay_{quantity}{VIDEO_SUFFIX}"


def map_name(quantity, frame_index):
    return os.path.join(MAPS_FOLDER, quantity, f"{quantity}_{int(frame_index):06d}.png")


def vtu_name(frame_index):
    return os.path.join(VTK_FOLDER, f"frame_{int(frame_index):06d}.vtu")


# ----------------------------------------------------------------------------- options

def add_field_arguments(parser):
    """Add ``--maps --every --video --video-fps --vtk --map-range --map-opacity --strain-unit`` to ``parser``."""
    group = parser.add_argument_group("maps, video and VTK (the fields as pictures; --maps none --video none "
                                      "--no-vtk for the CSV files only)")
    group.add_argument("--maps", default=",".join(QUANTITIES), metavar="Q[,Q...]|none",
                       help=f"quantities drawn as PNG maps over the camera image, into DIR/{MAPS_FOLDER}/Q/: any of "
                            f"{','.join(QUANTITIES)} (default all), or none")
    group.add_argument("--every", type=int, default=DEFAULT_EVERY, metavar="N",
                       help=f"maps of every N-th frame with results (default {DEFAULT_EVERY}; the reference and the "
                            f"last frame always); the video and VTK have every frame")
    group.add_argument("--video", default=DEFAULT_VIDEO, metavar="Q|none",
                       help=f"the overlay video DIR/{video_name('Q')} of quantity Q over every frame (MPEG-4, "
                            f"{VIDEO_FOURCC}; default {DEFAULT_VIDEO}), or none")
    group.add_argument("--video-fps", type=float, default=DEFAULT_VIDEO_FPS, metavar="F",
                       help=f"frames a second of the video (default {DEFAULT_VIDEO_FPS:g})")
    group.add_argument("--vtk", action=argparse.BooleanOptionalAction, default=True,
                       help=f"the fields as VTK for ParaView: DIR/{VTK_FOLDER}/frame_F.vtu per frame and "
                            f"DIR/{PVD_FILE}, the time series (default; --no-vtk: none)")
    group.add_argument("--map-range", action="append", metavar="Q=LO,HI",
                       help="fixed colour range of quantity Q, in the unit of its colour bar (px, mm with --scale, "
                            "%% or microstrain), e.g. eyy=0,20 (repeatable; default: automatic, one range for the "
                            "whole sequence)")
    group.add_argument("--map-opacity", type=float, default=DEFAULT_OPACITY, metavar="A",
                       help=f"opacity of the field over the camera image, 0..1 (default {DEFAULT_OPACITY:g})")
    group.add_argument("--strain-unit", choices=tuple(STRAIN_UNITS), default=DEFAULT_STRAIN_UNIT,
                       help=f"unit of strain on the maps (default {DEFAULT_STRAIN_UNIT.replace('%', '%%')}); the CSV "
                            f"and VTK files "
                            f"hold plain numbers")
    return parser


@dataclass(frozen=True)
class FieldOptions:
    """What ``livedic export`` draws and writes of the fields (see the module notes)."""
    maps: tuple = QUANTITIES
    every: int = DEFAULT_EVERY
    video: str = DEFAULT_VIDEO          # "" for none
    video_fps: float = DEFAULT_VIDEO_FPS
    vtk: bool = True
    ranges: dict = field(default_factory=dict)     # quantity -> (lo, hi), display unit
    strain_unit: str = DEFAULT_STRAIN_UNIT
    opacity: float = DEFAULT_OPACITY

    @classmethod
    def from_args(cls, args):
        """The options of parsed ``args``; ValueError (one line) for a bad one."""
        maps = _quantity_list(args.maps, "--maps")
        video = "" if str(args.video).strip().lower() == "none" else str(args.video).strip()
        if video and video not in QUANTITIES:
            raise ValueError(f"--video {args.video!r}: give one of {', '.join(QUANTITIES)}, or none")
        if args.every < 1:
            raise ValueError(f"--every {args.every}: give a whole number of frames >= 1 (1: every frame)")
        if not (np.isfinite(args.video_fps) and 0 < args.video_fps <= 1000):
            raise ValueError(f"--video-fps {args.video_fps:g}: give frames a second between 0 and 1000, e.g. 10")
        if not (0.0 < args.map_opacity <= 1.0):
            raise ValueError(f"--map-opacity {args.map_opacity:g}: give a number in (0, 1], e.g. 1 (opaque) or 0.7")
        ranges = dict(_parse_range(text) for text in args.map_range or ())
        return cls(maps=maps, every=int(args.every), video=video, video_fps=float(args.video_fps), vtk=bool(args.vtk),
                   ranges=ranges, strain_unit=args.strain_unit, opacity=float(args.map_opacity))

    @property
    def wanted(self):
        return bool(self.maps or self.video or self.vtk)

    @property
    def coloured(self):
        """The quantities drawn (maps and video), in ``QUANTITIES`` order."""
        return tuple(q for q in QUANTITIES if q in self.maps or q == self.video)

    def outputs(self):
        """What this export writes into DIR besides the CSV files (top-level names)."""
        names = [MAPS_FOLDER] if self.maps else []
        names += [video_name(self.video)] if self.video else []
        names += [VTK_FOLDER, PVD_FILE] if self.vtk else []
        return names

    def existing(self, directory):
        """The outputs of this export that ``directory`` already holds (names for a message)."""
        found = []
        for quantity in self.maps:
            folder = os.path.join(directory, MAPS_FOLDER, quantity)
            if os.path.isdir(folder) and any(_MAP_NAME.match(name) for name in os.listdir(folder)):
                found.append(f"{MAPS_FOLDER}/{quantity}/")
        if self.video and os.path.lexists(os.path.join(directory, video_name(self.video))):
            found.append(video_name(self.video))
        if self.vtk:
            folder = os.path.join(directory, VTK_FOLDER)
            if os.path.isdir(folder) and any(_VTU_NAME.match(name) for name in os.listdir(folder)):
                found.append(f"{VTK_FOLDER}/")
            if os.path.lexists(os.path.join(directory, PVD_FILE)):
                found.append(PVD_FILE)
        return found


NO_FIELDS = FieldOptions(maps=(), video="", vtk=False)     # the CSV files only


def _quantity_list(text, option):
    text = str(text).strip()
    if text.lower() == "none":
        return ()
    if text.lower() == "all":
        return QUANTITIES
    names = [name.strip() for name in text.split(",") if name.strip()]
    bad = [name for name in names if name not in QUANTITIES]
    if bad or not names:
        raise ValueError(f"{option} {text!r}: give quantities from {','.join(QUANTITIES)} separated by commas "
                         f"(e.g. eyy or u,v,eyy), all, or none")
    return tuple(q for q in QUANTITIES if q in names)


def _parse_range(text):
    name, _, values = str(text).partition("=")
    name = name.strip()
    try:
        lo, hi = (float(value) for value in values.split(","))
    except ValueError:
        lo = hi = float("nan")
    if name not in QUANTITIES or not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"--map-range {text!r}: give Q=LO,HI with Q one of {', '.join(QUANTITIES)} and LO < HI in "
                         f"the colour bar's unit, e.g. eyy=0,20 (%) or u=-2,2 (px)")
    return name, (lo, hi)


# ----------------------------------------------------------------------------- quantities and colour ranges

@dataclass(frozen=True)
class Quantity:
    """How a quantity is shown: ``factor`` x the recorded value, in ``unit``."""
    name: str          # the CSV column
    symbol: str        # u, v, e_xx ...
    meaning: str
    unit: str
    factor: float
    start: float       # the automatic range starts at +-start (display unit)

    @property
    def label(self):
        return f"{self.symbol} ({self.unit})"


def quantities(scale=None, strain_unit=DEFAULT_STRAIN_UNIT, measure="engineering", vsg_px=None):
    """name -> ``Quantity``: displacements in px (mm with ``scale`` px/mm), strain in ``strain_unit``."""
    length_unit, length_factor = ("mm", 1.0 / scale) if scale else ("px", 1.0)
    strain_factor = STRAIN_UNITS[strain_unit]
    gauge = f", VSG {vsg_px:.0f} px" if vsg_px else ""
    shown = {"u": ("u", "horizontal displacement"), "v": ("v", "vertical displacement"),
             "exx": ("e_xx", f"{measure} strain along x{gauge}"), "eyy": ("e_yy", f"{measure} strain along y{gauge}"),
             "exy": ("e_xy", f"{measure} shear strain (tensor){gauge}")}
    out = {}
    for name, (symbol, meaning) in shown.items():
        strain = name.startswith("e")
        factor = strain_factor if strain else length_factor
        start = (MIN_COLOUR_LIMIT_STRAIN if strain else MIN_COLOUR_LIMIT_PX) * factor
        out[name] = Quantity(name, symbol, meaning, strain_unit if strain else length_unit, factor, start)
    return out


class ColourRanges:
    """One colour range per quantity for the whole sequence: the fixed ones, the others grown frame by frame."""

    def __init__(self, shown, fixed=None, names=QUANTITIES):
        self.shown = shown
        self.fixed = dict(fixed or {})
        self.limits = {q: self.fixed.get(q, (-shown[q].start, shown[q].start)) for q in names}

    def add(self, values, ok):
        """Take one frame's ``values`` (quantity -> recorded values of the points) of the ``ok`` points."""
        for name, limits in self.limits.items():
            if name not in self.fixed:
                self.limits[name] = grow_limits(limits, self.shown[name].factor * np.asarray(values[name])[ok])


# ----------------------------------------------------------------------------- the surface

@dataclass(frozen=True)
class SurfaceMesh:
    """Triangles over the reference points: Delaunay, without the ones that bridge a gap in the grid."""
    triangles: np.ndarray        # (T, 3) int32 point indices

    @classmethod
    def over(cls, x, y, step):
        """The mesh of the points (x, y) on a grid of ``step`` px (no triangles for fewer than 3 in a plane)."""
        import matplotlib.tri as mtri
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        try:
            triangles = mtri.Triangulation(x, y).triangles.astype(np.int32)
        except (ValueError, RuntimeError):      # fewer than 3 points, or all on a line
            triangles = np.empty((0, 3), dtype=np.int32)
        corners = np.stack([x[triangles], y[triangles]], axis=-1)
        edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=-1).max(axis=1) if len(triangles) else []
        return cls(triangles[np.asarray(edges) <= LONG_EDGE * float(step)])

    def where(self, valid):
        """The triangles whose three corners are ``valid`` (N,) bool."""
        return self.triangles[np.asarray(valid, dtype=bool)[self.triangles].all(axis=1)]


def _twice_area(x, y, triangles):
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return (x[b] - x[a]) * (y[c] - y[a]) - (x[c] - x[a]) * (y[b] - y[a])


class PixelWeights:
    """Which moved triangle covers each pixel of a frame, and the pixel's barycentric weights in it.

    Triangles are filled into an index image (OpenCV, corners to 1/16 px) rather than searched:
    a deformed mesh can fold where a point is wrong, which a triangle finder refuses, and one fill
    serves every quantity of the frame. A pixel's value is the weighted sum of its triangle's
    corner values, NaN where a corner has none.
    """

    def __init__(self, shape, x, y, triangles, reference_area):
        import cv2
        self.shape = tuple(shape[:2])
        area = _twice_area(x, y, triangles)
        # A triangle that flipped or collapsed is a wrong point, not a deformation: left out.
        keep = (area * np.sign(reference_area) > 1e-9) & np.isfinite(area)
        triangles = triangles[keep]
        index = np.full(self.shape, -1, dtype=np.int32)
        corners = np.round(np.stack([x[triangles], y[triangles]], axis=-1) * (1 << _SUBPIXEL_BITS)).astype(np.int32)
        for k, polygon in enumerate(corners):
            cv2.fillConvexPoly(index, polygon, k, lineType=cv2.LINE_8, shift=_SUBPIXEL_BITS)
        rows, cols = np.nonzero(index >= 0)
        which = triangles[index[rows, cols]]
        x0, y0 = x[which[:, 0]], y[which[:, 0]]
        dx1, dy1 = x[which[:, 1]] - x0, y[which[:, 1]] - y0
        dx2, dy2 = x[which[:, 2]] - x0, y[which[:, 2]] - y0
        det = dx1 * dy2 - dx2 * dy1
        px, py = cols - x0, rows - y0
        w1 = (px * dy2 - dx2 * py) / det
        w2 = (dx1 * py - px * dy1) / det
        self.rows, self.cols, self.corners = rows, cols, which
        self.weights = np.stack([1.0 - w1 - w2, w1, w2], axis=1)

    def sample(self, values):
        """(H, W) float64 image of the vertex ``values`` (N,), NaN where no triangle covers a pixel."""
        out = np.full(self.shape, np.nan)
        out[self.rows, self.cols] = np.einsum("ij,ij->i", np.asarray(values, dtype=np.float64)[self.corners],
                                              self.weights)
        return out


# ----------------------------------------------------------------------------- pictures

def overlay(gray, values, limits, opacity=DEFAULT_OPACITY):
    """(H, W, 3) BGR: ``values`` (H, W; display unit, NaN: none) coloured on ``limits`` over the ``gray`` image."""
    import cv2
    from matplotlib import colormaps
    from matplotlib.colors import Normalize
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    painted = np.isfinite(values)
    colours = colormaps[COLOUR_MAP](Normalize(*limits)(values[painted]), bytes=True)[:, 2::-1]
    if opacity >= 1.0:
        out[painted] = colours
    else:
        out[painted] = np.round(opacity * colours + (1.0 - opacity) * out[painted]).astype(np.uint8)
    return out


class MapLayout:
    """The picture around a map: the camera image at the bottom left, a title above, the colour bar at the right.

    Sizes follow the image height, so the text stays legible on any camera; the picture's width and
    height are even (what video encoders need). Text is drawn by matplotlib, as little as it can be:
    the colour bar and the title's quantity and note once per quantity, the frame and time once per
    frame (shared by its quantities).
    """

    def __init__(self, image_shape, title_note=""):
        self.height, self.width = (int(n) for n in image_shape[:2])
        self.panel_height = max(self.height, MIN_PANEL_HEIGHT)      # a small image: the bar still fits beside it
        self.font_px = float(np.clip(self.height / 55.0, 11.0, 30.0))
        self.title_height = int(round(3.4 * self.font_px))
        self.line_height = self.title_height // 2
        self.bar_width = int(round(9.0 * self.font_px))
        self.total_width = self.width + self.bar_width + (self.width + self.bar_width) % 2
        self.total_height = self.panel_height + self.title_height + (self.panel_height + self.title_height) % 2
        self.title_note = title_note
        self.margin = int(round(0.5 * self.font_px))
        self.frame_text_left = self.margin + int(round(4.5 * self.font_px))   # after the widest symbol, "e_xy"
        self._bars = {}
        self._headings = {}
        self._frame_text = (None, None)

    def picture(self, coloured, quantity, limits, frame_index, time_s):
        """The whole picture (H, W, 3 BGR) of one map: ``coloured`` from ``overlay``."""
        picture = np.full((self.total_height, self.total_width, 3), 255, dtype=np.uint8)
        top = self.total_height - self.panel_height
        picture[:top] = self._heading(quantity, top)
        picture[:self.line_height, self.frame_text_left:] = self._frame_line(frame_index, time_s)
        picture[self.total_height - self.height:, :self.width] = coloured
        picture[top:, self.width:self.width + self.bar_width] = self._bar(quantity, limits)
        return picture

    def _figure(self, width, height):
        from matplotlib.figure import Figure
        return Figure(figsize=(width / 100.0, height / 100.0), dpi=100, facecolor="white")

    def _text(self, width, height, lines):
        """A white strip of ``lines``: (text, x px, y from the top 0..1, size in font_px, bold), each shrunk to fit."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        figure = self._figure(width, height)
        renderer = FigureCanvasAgg(figure).get_renderer()
        for text, x, y, size, bold in lines:
            label = figure.text(x / width, 1.0 - y, text, ha="left", va="center", fontsize=0.72 * size * self.font_px,
                                weight="bold" if bold else "normal", color="black" if bold else "0.3")
            room = width - x - self.margin
            extent = label.get_window_extent(renderer).width
            if extent > room:
                label.set_fontsize(label.get_fontsize() * room / extent)
        return _rendered(figure)

    def _heading(self, quantity, height):
        """The title strip of ``quantity`` without the frame: its symbol (bold) over a note (meaning, recording)."""
        if quantity not in self._headings:
            note = f"{quantity.meaning}; {self.title_note}" if self.title_note else quantity.meaning
            self._headings[quantity] = self._text(self.total_width, height, [
                (quantity.symbol, self.margin, 0.25, 1.0, True), (note, self.margin, 0.72, 0.8, False)])
        return self._headings[quantity]

    def _frame_line(self, frame_index, time_s):
        """"frame N   t = T s" (bold), drawn once per frame."""
        key = (int(frame_index), float(time_s))
        if self._frame_text[0] != key:
            text = f"frame {int(frame_index)}   t = {time_s:.3f} s"
            strip = self._text(self.total_width - self.frame_text_left, self.line_height, [(text, 0, 0.5, 1.0, True)])
            self._frame_text = (key, strip)
        return self._frame_text[1]

    def _bar(self, quantity, limits):
        key = (quantity, tuple(limits))
        if key not in self._bars:
            from matplotlib import colormaps
            from matplotlib.cm import ScalarMappable
            from matplotlib.colors import Normalize
            figure = self._figure(self.bar_width, self.panel_height)
            points = self.font_px * 0.72
            margin = 1.5 * self.font_px / self.panel_height
            axes = figure.add_axes((0.12, 3 * margin, 1.8 * self.font_px / self.bar_width, 1 - 5 * margin))
            bar = figure.colorbar(ScalarMappable(Normalize(*limits), colormaps[COLOUR_MAP]), cax=axes,
                                  extend="both")
            bar.ax.tick_params(labelsize=points)
            bar.set_label(quantity.label, fontsize=points)
            figure.text(0.5, margin, "no colour: no value", ha="center", va="center", fontsize=0.75 * points,
                        color="0.3")
            self._bars[key] = _rendered(figure)
        return self._bars[key]


def _rendered(figure):
    """A matplotlib figure as a BGR array of its pixel size."""
    import cv2
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return cv2.cvtColor(np.asarray(canvas.buffer_rgba()), cv2.COLOR_RGBA2BGR)


def encode_png(picture):
    import cv2
    ok, data = cv2.imencode(".png", picture, [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION])
    if not ok:
        raise RuntimeError("OpenCV could not encode a PNG")
    return data.tobytes()


# ----------------------------------------------------------------------------- VTK

def vtu_mesh(x, y, values, triangles):
    """A ``meshio.Mesh`` of one frame: points at (x, y, 0), ``values`` (name -> (N,) array) as point data."""
    import meshio
    points = np.column_stack([x, y, np.zeros_like(x)]).astype(np.float64)
    point_data = {name: np.ascontiguousarray(array) for name, array in values.items()}
    point_data["displacement"] = np.column_stack([values["u"], values["v"], np.zeros_like(values["u"])])
    return meshio.Mesh(points, [("triangle", np.asarray(triangles, dtype=np.int64).reshape(-1, 3))],
                       point_data=point_data)


def pvd_text(entries):
    """A ParaView collection (``.pvd``) of (time_s, relative file name) entries: a time series."""
    root = ElementTree.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ElementTree.SubElement(root, "Collection")
    for time_s, name in entries:
        ElementTree.SubElement(collection, "DataSet", timestep=repr(float(time_s)), group="", part="0",
                               file=name.replace(os.sep, "/"))
    ElementTree.indent(root)
    return '<?xml version="1.0"?>\n' + ElementTree.tostring(root, encoding="unicode") + "\n"


# ----------------------------------------------------------------------------- the writer

class RecordedImages:
    """The camera images of a recording, in order, looked up by the time of each frame with results.

    One pass over ``/camera/image`` (``acquire.recording.source.McapSource``, truncated files too): frames
    without results (dropped by a tracker that fell behind) are passed over, and a result whose
    frame's image is not in the file gets None.
    """

    def __init__(self, path):
        from livedic.acquire.recording.source import McapSource
        self._frames = iter(McapSource(path))
        self._next = None

    def at(self, timestamp_ns):
        """The ``acquire.base.Frame`` logged at ``timestamp_ns``, or None."""
        while True:
            if self._next is None:
                self._next = next(self._frames, None)
                if self._next is None:
                    return None
            if self._next.timestamp_ns > timestamp_ns:
                return None
            frame, self._next = self._next, None
            if frame.timestamp_ns == timestamp_ns:
                return frame


@dataclass
class FieldReport:
    """What ``FieldWriter`` has written (complete files only), for the command's last line and session.json."""
    maps: int = 0
    vtu: int = 0
    video_frames: int = 0
    video: str = ""
    pvd: str = ""
    frames: int = 0                   # frames gone through
    no_image: int = 0                 # frames with results but no camera image: no map, no video frame
    other_points: int = 0             # frames tracking other points than the reference's: left out

    def written(self, options):
        """The outputs complete so far, as words."""
        parts = []
        if options.maps:
            parts.append(f"{self.maps} map{'s' if self.maps != 1 else ''}")
        if self.video:
            parts.append(f"{os.path.basename(self.video)} ({self.video_frames} frames)")
        if options.vtk:
            parts.append(f"{self.vtu} .vtu file{'s' if self.vtu != 1 else ''}"
                         + (f" and {PVD_FILE}" if self.pvd else ""))
        return ", ".join(parts)


class FieldWriter:
    """Draws and writes the maps, the video and the VTK files of a recording, one frame with results at a time.

    Parameters
    ----------
    directory : str
        The export folder (exists).
    options : FieldOptions
    shown : dict
        Quantity name -> ``Quantity``.
    limits : dict
        Quantity name -> (lo, hi), display unit (``ColourRanges.limits``).
    reference : (x, y) arrays
        The reference points (the first frame's), which the surface is built on.
    step : float
        Their grid step, px.
    frames : int
        Frames with results in the recording (the last one always gets maps).
    title_note : str
        Said at the right of every title (the recording, the strain measure).
    """

    def __init__(self, directory, options, shown, limits, reference, step, frames, title_note=""):
        self.directory = directory
        self.options = options
        self.shown = shown
        self.limits = limits
        self.x0, self.y0 = (np.asarray(a, dtype=np.float64) for a in reference)
        self.mesh = SurfaceMesh.over(self.x0, self.y0, step)
        self.reference_area = _twice_area(self.x0, self.y0, self.mesh.triangles)
        self.frames = int(frames)
        self.title_note = title_note
        self.report = FieldReport()
        self._layout = None
        self._video = None
        self._video_file = None
        self._pvd = []

    # -- per frame

    def wants_image(self, position):
        """Whether the ``position``-th frame with results (0 = reference) is drawn (maps or video)."""
        return bool(self.options.video) or bool(self._maps_of(position))

    def _maps_of(self, position):
        every = self.options.every
        if position % every == 0 or position == self.frames - 1:
            return self.options.maps
        return ()

    def add(self, position, frame_index, time_s, values, ok, image=None, pixel_format=""):
        """Write what frame ``position`` gets: ``values`` maps name -> (N,) array of every ``fields.csv`` column
        this writer uses (``u v exx eyy exy zncc`` and, when recorded, ``status``, ``point_id``); ``image`` is the
        camera image (None: none recorded, no map or video frame)."""
        ok = np.asarray(ok, dtype=bool)
        drawn = tuple(q for q in QUANTITIES if q in self._maps_of(position) or q == self.options.video)
        if drawn and image is None:
            self.report.no_image += 1
        elif drawn:
            self._draw(position, frame_index, time_s, values, ok, image, pixel_format, drawn)
        if self.options.vtk:
            self._write_vtu(frame_index, time_s, values, ok)
        self.report.frames += 1

    def _draw(self, position, frame_index, time_s, values, ok, image, pixel_format, drawn):
        gray = display_gray(np.asarray(image), pixel_format)     # as the live view shows it
        if self._layout is None:
            self._layout = MapLayout(gray.shape, self.title_note)
        u, v = np.asarray(values["u"], dtype=np.float64), np.asarray(values["v"], dtype=np.float64)
        valid = ok & np.isfinite(u) & np.isfinite(v)
        keep = valid[self.mesh.triangles].all(axis=1)
        weights = PixelWeights(gray.shape, self.x0 + u, self.y0 + v, self.mesh.triangles[keep],
                               self.reference_area[keep])
        for name in drawn:
            quantity = self.shown[name]
            shown_values = np.where(valid, quantity.factor * np.asarray(values[name], dtype=np.float64), np.nan)
            coloured = overlay(gray, weights.sample(shown_values), self.limits[name], self.options.opacity)
            picture = self._layout.picture(coloured, quantity, self.limits[name], frame_index, time_s)
            if name in self._maps_of(position):
                self._write_map(name, frame_index, picture)
            if name == self.options.video:
                self._video_frame(picture)

    def _write_map(self, name, frame_index, picture):
        path = os.path.join(self.directory, map_name(name, frame_index))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with AtomicFile(path, binary=True) as out:
            out.write(encode_png(picture))
            out.commit()
        self.report.maps += 1

    def _video_frame(self, picture):
        import cv2
        if self._video is None:
            self._video_file = AtomicFile(os.path.join(self.directory, video_name(self.options.video)), binary=True,
                                          suffix=VIDEO_SUFFIX)
            height, width = picture.shape[:2]
            self._video = cv2.VideoWriter(self._video_file.tmp, cv2.VideoWriter_fourcc(*VIDEO_FOURCC),
                                          self.options.video_fps, (width, height))
            if not self._video.isOpened():
                self.discard()
                raise RuntimeError(f"OpenCV cannot write {VIDEO_FOURCC} video here: use --video none")
        self._video.write(picture)
        self.report.video_frames += 1

    def _write_vtu(self, frame_index, time_s, values, ok):
        import meshio
        name = vtu_name(frame_index)
        path = os.path.join(self.directory, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        data = {key: np.asarray(values[key]) for key in ("u", "v", "exx", "eyy", "exy", "zncc")}
        data["ok"] = ok.astype(np.uint8)
        for key in ("status", "point_id"):
            if values.get(key) is not None:
                data[key] = np.asarray(values[key])
        with AtomicFile(path, binary=True) as out:
            # meshio writes by path (it opens the file itself): the temporary one, renamed when complete.
            meshio.write(out.tmp, vtu_mesh(self.x0, self.y0, data, self.mesh.where(ok)), file_format="vtu")
            out.commit()
        self._pvd.append((time_s, name))
        self.report.vtu += 1

    # -- the end

    def finish(self):
        """Close the video and write the ``.pvd`` (after the last frame)."""
        if self._video is not None:
            self._video.release()
            self._video = None
            self._video_file.commit()
            self.report.video = self._video_file.path
        if self.options.vtk:
            path = os.path.join(self.directory, PVD_FILE)
            with AtomicFile(path) as out:
                out.write(pvd_text(self._pvd))
                out.commit()
            self.report.pvd = path

    def discard(self):
        """Give up (an error or a stop): the unfinished video is removed; finished files stay."""
        if self._video is not None:
            self._video.release()
            self._video = None
        if self._video_file is not None and self._video_file.tmp is not None:
            self._video_file.discard()


def remove_stale(directory, options):
    """Remove the maps and ``.vtu`` files of an earlier export that this one replaces (``--overwrite``), so the
    folder holds one export's pictures only; other files are never touched."""
    folders = [(os.path.join(directory, MAPS_FOLDER, q), _MAP_NAME) for q in options.maps]
    folders += [(os.path.join(directory, VTK_FOLDER), _VTU_NAME)] if options.vtk else []
    for folder, pattern in folders:
        if os.path.isdir(folder):
            for name in os.listdir(folder):
                if pattern.match(name):
                    os.unlink(os.path.join(folder, name))
