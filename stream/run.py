"""``livedic run``: acquire, track, record and display a live session.

Wiring (one producer thread, one consumer loop)::

    source --(acquisition thread)--> FrameQueue --(main thread)--> Tracker --> recorder results
                    |                 (drops counted)                    \\--> Rerun logger
                    \\--> recorder frames (every frame, dropped or not)    \\--> progress bar

With no options it runs the simulated tensile test (``synthetic:tensile``),
tracks about 1,000 points over the gauge section, records into
``recordings/session-YYYYmmdd-HHMMSS.mcap``, shows the session in Rerun (or
saves a .rrd next to the recording when there is no display), and prints a
summary: frames, fps, POI/s, latency p50/p99, drops and, for synthetic
sources, the error against the exact displacement.

Ctrl-C (SIGINT) or SIGTERM stops acquisition, tracks what is already queued,
and closes the recording properly. A camera lost mid-run ends the session
(recording closed, summary, ``SourceLost``) or, with ``--reconnect``, is
reopened until it is back while the session, its reference and its recording
stay open (``stream.acquisition.Reconnect``).

The lead wires it into ``stream.cli``::

    run = commands.add_parser("run", help="live tracking of a camera or the simulated tensile test")
    add_run_arguments(run)
    run.set_defaults(handler=run_session)
"""

import enum
import math
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from datetime import datetime

import numpy as np

from livedic.dic.quality import MIN_ZNCC, Gates

DEFAULT_SOURCE = "synthetic:tensile"
DEFAULT_POINTS = 1000
# Points a live session tracks at most unless --max-points says otherwise: 20,000 points take ~140 MB in
# the tracker and ~0.15 s a frame on one core (IC-GN, 1 MP), a few frames a second; --step 1 on 1 MP
# (198,120 points) took 2.8 GB, dropped half the frames and lost a fifth of the points (issue 8).
DEFAULT_MAX_POINTS = 20_000
RECORDINGS_DIR = "recordings"


def add_run_arguments(parser):
    """Add the ``livedic run`` options to an ``argparse`` (sub)parser."""
    from livedic.dic.measure import SEARCH_METHODS, SUBPIXEL_METHODS
    parser.add_argument("--source", default=DEFAULT_SOURCE, metavar="URI",
                        help="frame source (default synthetic:tensile): synthetic:[tensile|translate][?opts], "
                             "aravis:[ID], v4l2:/dev/videoN, video:FILE, images:GLOB, mcap:FILE")
    parser.add_argument("--frames", type=int, metavar="N",
                        help="stop after N frames (synthetic: also the length of the test; default 300)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--roi", metavar="X,Y,W,H",
                       help="region of interest for the point grid (default: the specimen gauge section for "
                            "synthetic:tensile, else the whole image)")
    where.add_argument("--points", metavar="FILE.csv",
                       help="track these points (CSV with header x,y) instead of a grid")
    parser.add_argument("--step", type=int, metavar="S",
                        help="grid step in pixels (default: about --n-points points over the ROI)")
    parser.add_argument("--n-points", type=int, default=DEFAULT_POINTS, metavar="N",
                        help=f"points wanted when --step is not given (default {DEFAULT_POINTS})")
    parser.add_argument("--p0", metavar="X,Y",
                        help="the traced point P0 (default: the best-textured point near the ROI centre, never on a "
                             "hole or background; a given P0 on weak texture is warned about)")
    parser.add_argument("--max-points", type=int, default=DEFAULT_MAX_POINTS, metavar="N",
                        help=f"refuse to start with more than N points (default {DEFAULT_MAX_POINTS:,}: about "
                             f"{DEFAULT_MAX_POINTS * 7 // 1000} MB of tracker memory and a few frames a second on one "
                             "core); raise it for slow tests on a big machine")
    parser.add_argument("--subset", type=int, default=21, metavar="N", help="odd subset side, pixels (default 21)")
    parser.add_argument("--search", default="improved-wso", metavar="NAME",
                        help=f"integer search seeded by the previous frame: {', '.join(SEARCH_METHODS)} "
                             "(default improved-wso; with icgn or newton-raphson it runs only for the points the "
                             "sub-pixel method, started from the previous result, leaves doubtful; none = never)")
    parser.add_argument("--subpixel", default="icgn", metavar="NAME",
                        help=f"sub-pixel method: {', '.join(SUBPIXEL_METHODS)} (default icgn)")
    parser.add_argument("--seed-radius", type=int, default=2, metavar="R",
                        help="search radius around the previous result, pixels (default 2: covers 1.5 px of "
                             "motion between two frames; faster motion is caught by the re-find search)")
    parser.add_argument("--refind-radius", type=int, default=16, metavar="R",
                        help="search radius for re-finding lost points, pixels (default 16)")
    parser.add_argument("--refind-zncc", type=float, default=0.8, metavar="Z",
                        help="re-find points whose ZNCC falls below Z (default 0.8)")
    parser.add_argument("--min-zncc", type=float, default=MIN_ZNCC, metavar="Z",
                        help=f"a point is ok only if its ZNCC is at least Z (default {MIN_ZNCC}); the other quality "
                             "gates (texture, neighbours, border) always apply")
    parser.add_argument("--seed", type=int, default=0, help="seed of the stochastic searches (default 0)")
    record = parser.add_mutually_exclusive_group()
    record.add_argument("--record", metavar="FILE.mcap",
                        help=f"recording file (default {RECORDINGS_DIR}/session-YYYYmmdd-HHMMSS.mcap)")
    record.add_argument("--no-record", action="store_true", help="do not record")
    parser.add_argument("--viewer", nargs="+", default=["spawn"], metavar="MODE",
                        help="spawn | connect [URL] | save FILE.rrd | none (default spawn; without a display "
                             "the stream is saved next to the recording)")
    parser.add_argument("--queue", type=int, default=4, metavar="N", help="frames the queue holds (default 4)")
    parser.add_argument("--drop", choices=("auto", "oldest", "newest", "block"), default="auto",
                        help="when the queue is full: drop the oldest queued frame, drop the newest, or block "
                             "(wait; for files only). Default auto: oldest for cameras and paced sources, "
                             "block for recordings, files and the unpaced simulator")
    parser.add_argument("--color-range", metavar="LO,HI",
                        help="fixed colour limits of the u and v fields in the viewer, px (e.g. -2,2). Default: "
                             "automatic, starting at -0.05,0.05 and only growing, to round numbers, to cover the "
                             "0.5-99.5 percentiles of the ok points")
    parser.add_argument("--image-max-side", type=int, default=512, metavar="PX",
                        help="camera image shown in Rerun downsampled to at most PX pixels a side (default 512)")
    parser.add_argument("--progress", choices=("auto", "on", "off"), default="auto",
                        help="progress bar on stderr (default auto: when stderr is a terminal)")
    parser.add_argument("--threads", type=int, default=1, metavar="N",
                        help="numba threads for rendering and tracking (default 1: the other core serves "
                             "acquisition, recording and display, and parallel regions stall when cores are shared)")
    parser.add_argument("--summary-json", metavar="FILE.json", help="also write the summary as JSON")
    parser.add_argument("--reconnect", action="store_true",
                        help="cameras (aravis:, v4l2:): when the camera is lost, keep the session and the recording "
                             "open and reopen it every second until it is back (or Ctrl-C); the session then goes on "
                             "with the same reference and points")
    parser.add_argument("--reconnect-timeout", type=float, metavar="S",
                        help="with --reconnect: give up after S seconds without the camera (default: wait until "
                             "stopped)")
    return parser


# ----------------------------------------------------------------------------- argument helpers

def _ints(text, count, what, example):
    try:
        values = [int(round(float(part))) for part in str(text).split(",")]
    except ValueError:
        values = []
    if len(values) != count:
        raise ValueError(f"{what} must be {count} comma-separated numbers, e.g. {example}; got {text!r}")
    return values


def _floats(text, count, what, example):
    try:
        values = [float(part) for part in str(text).split(",")]
    except ValueError:
        values = []
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} must be {count} comma-separated numbers, e.g. {example}; got {text!r}")
    return values


def parse_color_range(text):
    """``--color-range`` "LO,HI" -> (lo, hi) in px, or None when not given.

    Raises
    ------
    ValueError
        Not two finite comma-separated numbers, or LO not below HI.
    """
    if text is None:
        return None
    lo, hi = _floats(text, 2, "--color-range", "-2,2")
    if not lo < hi:
        raise ValueError(f"--color-range {text}: LO must be below HI, e.g. -2,2")
    return lo, hi


def _check_args(args):
    from livedic.dic.measure import SEARCH_METHODS, SUBPIXEL_METHODS
    if args.frames is not None and args.frames < 1:
        raise ValueError(f"--frames must be >= 1, got {args.frames}")
    if args.subset < 3 or args.subset % 2 == 0:
        raise ValueError(f"--subset must be an odd integer >= 3, got {args.subset}")
    if args.search not in SEARCH_METHODS:
        raise ValueError(f"unknown search method {args.search!r}: choose one of {', '.join(SEARCH_METHODS)}")
    if args.subpixel not in SUBPIXEL_METHODS:
        raise ValueError(f"unknown sub-pixel method {args.subpixel!r}: choose one of {', '.join(SUBPIXEL_METHODS)}")
    if args.subpixel == "none":
        raise ValueError("--subpixel none gives integer displacements only: choose a sub-pixel method (e.g. icgn)")
    if args.step is not None and args.step < 1:
        raise ValueError(f"--step must be a positive number of pixels, got {args.step}")
    if args.n_points < 1:
        raise ValueError(f"--n-points must be >= 1, got {args.n_points}")
    if args.max_points < 1:
        raise ValueError(f"--max-points must be >= 1, got {args.max_points}")
    for name in ("seed_radius", "refind_radius"):
        if getattr(args, name) < 0:
            raise ValueError(f"--{name.replace('_', '-')} must be >= 0")
    if not -1.0 <= args.refind_zncc <= 1.0:
        raise ValueError(f"--refind-zncc must be between -1 and 1, got {args.refind_zncc}")
    if not -1.0 <= args.min_zncc <= 1.0:
        raise ValueError(f"--min-zncc must be between -1 and 1, got {args.min_zncc}")
    import numba
    if not 1 <= args.threads <= numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"--threads must be between 1 and {numba.config.NUMBA_NUM_THREADS}, got {args.threads}")
    if args.queue < 1:
        raise ValueError(f"--queue must be >= 1 frame, got {args.queue}")
    if args.image_max_side < 16:
        raise ValueError(f"--image-max-side must be >= 16 pixels, got {args.image_max_side}")
    if args.record is not None and not args.record.endswith(".mcap"):
        raise ValueError(f"--record file {args.record!r} must end in .mcap")
    if args.record is not None and os.path.exists(args.record):
        raise ValueError(f"--record file {args.record} exists: choose a new name (recordings are never overwritten)")
    roi = _ints(args.roi, 4, "--roi", "100,50,400,800") if args.roi else None
    if roi is not None and (roi[2] <= 0 or roi[3] <= 0):
        raise ValueError(f"--roi width and height must be positive, got {args.roi!r}")
    p0 = _floats(args.p0, 2, "--p0", "512,400") if args.p0 else None
    parse_color_range(getattr(args, "color_range", None))
    if args.reconnect_timeout is not None:
        if not args.reconnect:
            raise ValueError("--reconnect-timeout needs --reconnect")
        if not (math.isfinite(args.reconnect_timeout) and args.reconnect_timeout > 0):
            raise ValueError(f"--reconnect-timeout must be a positive number of seconds, got {args.reconnect_timeout}")
    return roi, p0


def _session_stem():
    return os.path.join(RECORDINGS_DIR, "session-" + datetime.now().strftime("%Y%m%d-%H%M%S"))


def _unique(path):
    """``path`` or ``path`` with -2, -3 ... before the extension if it exists."""
    if not os.path.exists(path):
        return path
    stem, ext = os.path.splitext(path)
    k = 2
    while os.path.exists(f"{stem}-{k}{ext}"):
        k += 1
    return f"{stem}-{k}{ext}"


# ----------------------------------------------------------------------------- progress bar

class ProgressBar:
    """One line on stderr, redrawn at most ``hz`` times a second; silent when disabled."""

    def __init__(self, total=None, *, enabled=True, stream=None, hz=8.0, width=24):
        self.total = total
        self.enabled = enabled
        self.stream = stream or sys.stderr
        self.period = 1.0 / hz
        self.width = width
        self._last = 0.0
        self._shown = False
        self.last_text = ""

    def update(self, done, text="", force=False):
        if not self.enabled:
            return
        self.last_text = text
        now = time.monotonic()
        if not force and now - self._last < self.period:
            return
        self._last = now
        if self.total:
            filled = int(self.width * min(done / self.total, 1.0))
            bar = f"[{'#' * filled}{'.' * (self.width - filled)}] {done}/{self.total}"
        else:
            bar = f"{done}"
        self.stream.write(f"\r{bar} {text}\033[K")
        self.stream.flush()
        self._shown = True

    def close(self):
        if self.enabled and self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False


# ----------------------------------------------------------------------------- points

def _read_points(path):
    from livedic.stream.cli import read_points_csv
    return read_points_csv(path)


def build_points(shape, *, roi, step, n_points, subset, p0=None, points=None):
    """Tracked points with P0 first: ``(points (N, 2), roi used, step used)``.

    P0 is ``p0`` or the ROI centre, snapped to a pixel; a grid point on the same
    pixel is not repeated.
    """
    from livedic.dic.tracking import grid_in_roi, step_for_count
    height, width = shape
    if roi is None:
        roi = (0, 0, width, height)
    x, y, w, h = roi
    if x < 0 or y < 0 or x + w > width or y + h > height:
        raise ValueError(f"ROI {x},{y},{w},{h} extends beyond the {width}x{height} image: "
                         f"give X,Y,W,H with X+W <= {width} and Y+H <= {height}")
    if points is not None:
        xy = np.asarray(points, dtype=np.float64)
        outside = (xy[:, 0] < 0) | (xy[:, 1] < 0) | (xy[:, 0] > width - 1) | (xy[:, 1] > height - 1)
        if outside.any():
            bad = xy[np.argmax(outside)]
            raise ValueError(f"{int(outside.sum())} of the given points lie outside the {width}x{height} image "
                             f"(first: {bad[0]:g},{bad[1]:g}): keep 0 <= x <= {width - 1} and 0 <= y <= {height - 1}")
    if points is None:
        if step is None:
            step = step_for_count(roi, n_points, subset)
        grid = grid_in_roi(shape, roi, step, subset)
    else:
        grid = np.asarray(points, dtype=np.float64)
    if p0 is None:
        p0 = (x + (w - 1) / 2.0, y + (h - 1) / 2.0)
    p0 = np.floor(np.asarray(p0, dtype=np.float64) + 0.5)
    if not (0 <= p0[0] < width and 0 <= p0[1] < height):
        raise ValueError(f"P0 ({p0[0]:g}, {p0[1]:g}) is outside the {width}x{height} image")
    same = np.all(np.floor(grid + 0.5) == p0[None, :], axis=1)
    grid = grid[~same]
    return np.vstack([p0[None, :], grid]), tuple(int(v) for v in roi), step


# ----------------------------------------------------------------------------- P0 on the specimen

# Texture is the gradient energy |grad I|^2 (grey levels^2/px^2): its sum over a subset (SSSIG) sets the
# noise of a DIC measurement there. "Local" texture is its mean over 9x9 px, about a speckle and its gap.
_LOCAL_WINDOW = 9
# A pixel is flat where its local texture is below this share of the ROI's 75th percentile: a hole, the
# background or a saturated patch (Sample 12's hole: 0.3 % of it), not the gaps between speckles.
P0_FLAT_LEVEL = 0.02
# A P0 subset is weak when more than this share of it is flat, or when its texture (mean over the subset)
# is below P0_WEAK_TEXTURE times the ROI's median: its trace may follow a hole, an edge or background.
P0_FLAT_SHARE = 0.25
P0_WEAK_TEXTURE = 0.25


class P0Reason(enum.Enum):
    """How P0 was chosen."""
    BEST_NEAR_CENTRE = "best-textured point near the ROI centre"
    MOVED_OFF_WEAK_CENTRE = "the ROI centre has no specimen texture: best-textured point nearest to it"
    NO_TEXTURE = "no textured subset in the ROI: the ROI centre"
    GIVEN = "given with --p0"


@dataclass(frozen=True)
class P0Choice:
    """Where P0 is and why (see ``choose_p0``).

    xy : (x, y) pixel centre of P0
    reason : P0Reason
    relative_texture : P0's subset texture over the ROI's median subset texture (NaN: no texture at all)
    flat_share : share of P0's subset that is flat (hole, background, saturation)
    centre : the ROI centre, pixel
    centre_weak : whether the ROI centre's subset is weak
    radius : the search radius around the centre that found P0 (px; 0 when given)
    """
    xy: tuple
    reason: P0Reason
    relative_texture: float
    flat_share: float
    centre: tuple
    centre_weak: bool
    radius: int = 0

    @property
    def weak(self):
        """P0's subset is partly flat or has little texture: its trace may be wrong."""
        return self.flat_share > P0_FLAT_SHARE or not (self.relative_texture >= P0_WEAK_TEXTURE)

    def _quality(self):
        texture = "n/a" if not math.isfinite(self.relative_texture) else f"{self.relative_texture:.2f}x"
        return f"texture {texture} the ROI's median, {100 * self.flat_share:.0f} % of its subset flat"

    def describe(self):
        """Which point, and why, for the session's note."""
        x, y = self.xy
        cx, cy = self.centre
        if self.reason is P0Reason.GIVEN:
            return f"P0 = point 0 at ({x:g}, {y:g}), given with --p0 ({self._quality()})"
        if self.reason is P0Reason.NO_TEXTURE:
            return (f"P0 = point 0 at the ROI centre ({x:g}, {y:g}): the ROI has no textured subset (a blank or "
                    f"out-of-focus image?)")
        if self.reason is P0Reason.MOVED_OFF_WEAK_CENTRE:
            return (f"P0 = point 0 at ({x:g}, {y:g}): the ROI centre ({cx:g}, {cy:g}) is not on specimen texture "
                    f"(a hole, an edge or background), so P0 is the best-textured point within {self.radius} px "
                    f"of it ({self._quality()})")
        return (f"P0 = point 0 at ({x:g}, {y:g}), the best-textured point within {self.radius} px of the ROI "
                f"centre ({cx:g}, {cy:g}) ({self._quality()})")

    def warning(self):
        """A line for the user when P0 is weak, else None."""
        if not self.weak:
            return None
        x, y = self.xy
        if self.reason is P0Reason.GIVEN:
            return (f"P0 ({x:g}, {y:g}) given with --p0 is on weak texture ({self._quality()}): its trace may be "
                    f"wrong; leave out --p0 to let livedic choose a point on the speckle")
        return f"P0 ({x:g}, {y:g}) is on weak texture ({self._quality()}): its trace may be wrong"


def _texture_maps(image, roi, subset):
    """Maps over ``roi`` grown by a subset, indexed [row - y0, column - x0]: (floor, texture, flat, x0, y0).

    floor: the weakest local texture in and around each subset; texture: mean |grad I|^2 over each
    subset; flat: share of each subset that is flat.
    """
    import cv2
    height, width = image.shape
    x, y, w, h = roi
    grow = int(subset)
    x0, y0 = max(x - grow, 0), max(y - grow, 0)
    x1, y1 = min(x + w + grow, width), min(y + h + grow, height)
    crop = np.ascontiguousarray(image[y0:y1, x0:x1], dtype=np.float32)
    gx = cv2.Sobel(crop, cv2.CV_32F, 1, 0, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    gy = cv2.Sobel(crop, cv2.CV_32F, 0, 1, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    energy = gx * gx + gy * gy
    local = cv2.boxFilter(energy, -1, (_LOCAL_WINDOW, _LOCAL_WINDOW), borderType=cv2.BORDER_REPLICATE)
    inner = local[y - y0:y - y0 + h, x - x0:x - x0 + w]
    level = float(np.percentile(inner[::2, ::2], 75)) if inner.size else 0.0
    size = (int(subset), int(subset))
    flat = cv2.boxFilter((local <= P0_FLAT_LEVEL * level).astype(np.float32), -1, size,
                         borderType=cv2.BORDER_REPLICATE)
    # The weakest local texture around each subset, grown by the local window: the 9x9 means just inside a
    # hole still see its edge (strong), so only the grown window reaches the flat inside of a hole the
    # subset touches.
    grown = int(subset) + _LOCAL_WINDOW - 1
    floor = cv2.erode(local, np.ones((grown, grown), np.uint8), borderType=cv2.BORDER_REPLICATE)
    texture = cv2.boxFilter(energy, -1, size, borderType=cv2.BORDER_REPLICATE)
    return floor, texture, flat, x0, y0


def choose_p0(image, roi, subset, p0=None):
    """P0 on the specimen: the best-textured point near the ROI centre, or the given ``p0`` assessed.

    Without ``p0``: among the pixel centres within a radius of the ROI centre whose
    subset fits in the image, the one whose subset is textured best throughout (the
    largest minimum of the 9x9-px mean |grad I|^2 within the subset; a subset that
    touches a hole, the specimen's edge or background has ~0 there); the radius starts
    at one subset and doubles until a subset with at least ``P0_WEAK_TEXTURE`` times
    the ROI's median of that is found. The ROI centre is often on a hole or on
    background (an open-hole specimen, a wide ROI): those are never chosen. With
    ``p0`` the point is kept and only assessed (``P0Choice.weak``).

    Parameters
    ----------
    image : ndarray (H, W)
        The reference frame.
    roi : tuple (x, y, w, h) or None
        None: the whole image.
    subset : int
        Odd subset side, pixels.
    p0 : (x, y), optional
        A given P0 (snapped to a pixel centre).

    Returns
    -------
    P0Choice
    """
    height, width = image.shape
    x, y, w, h = roi if roi is not None else (0, 0, width, height)
    half = int(subset) // 2
    centre = (float(np.floor(x + (w - 1) / 2.0 + 0.5)), float(np.floor(y + (h - 1) / 2.0 + 0.5)))
    floor, texture, flat, x0, y0 = _texture_maps(image, (x, y, w, h), subset)
    rows, cols = floor.shape
    # Candidates: pixel centres of the ROI whose subset lies inside the image.
    cx_lo, cx_hi = max(x, half), min(x + w - 1, width - 1 - half)
    cy_lo, cy_hi = max(y, half), min(y + h - 1, height - 1 - half)
    inside = np.zeros(floor.shape, dtype=bool)
    if cx_lo <= cx_hi and cy_lo <= cy_hi:
        inside[cy_lo - y0:cy_hi - y0 + 1, cx_lo - x0:cx_hi - x0 + 1] = True
    typical_texture = float(np.median(texture[inside][::3])) if inside.any() else 0.0
    typical_floor = float(np.median(floor[inside][::3])) if inside.any() else 0.0

    def assess(xy):
        col, row = int(xy[0]) - x0, int(xy[1]) - y0
        if not (0 <= row < rows and 0 <= col < cols) or typical_texture <= 0:
            return float("nan"), 1.0
        return float(texture[row, col]) / typical_texture, float(flat[row, col])

    def weak(xy):
        relative, flat_share = assess(xy)
        return flat_share > P0_FLAT_SHARE or not (relative >= P0_WEAK_TEXTURE)

    centre_weak = weak(centre)
    if p0 is not None:
        xy = (float(np.floor(p0[0] + 0.5)), float(np.floor(p0[1] + 0.5)))
        return P0Choice(xy, P0Reason.GIVEN, *assess(xy), centre, centre_weak)
    if not inside.any() or typical_floor <= 0:
        return P0Choice(centre, P0Reason.NO_TEXTURE, *assess(centre), centre, centre_weak)
    row_index, col_index = np.nonzero(inside)
    distance2 = (col_index + x0 - centre[0]) ** 2 + (row_index + y0 - centre[1]) ** 2
    scores = floor[row_index, col_index]
    radius = max(int(subset), 1)
    limit = np.sqrt(float(distance2.max()))
    while True:
        near = np.flatnonzero(distance2 <= radius * radius)
        if near.size and (scores[near].max() >= P0_WEAK_TEXTURE * typical_floor or radius >= limit):
            break
        radius *= 2
    best = near[int(np.argmax(scores[near]))]        # the first of equals in row-major order: deterministic
    xy = (float(col_index[best] + x0), float(row_index[best] + y0))
    reason = P0Reason.MOVED_OFF_WEAK_CENTRE if centre_weak else P0Reason.BEST_NEAR_CENTRE
    return P0Choice(xy, reason, *assess(xy), centre, centre_weak, radius)


# ----------------------------------------------------------------------------- the session

def _warm_up(args):
    """Compile the numba kernels on a tiny image before the camera starts (cached: ~0.5 s later)."""
    from livedic.dic.tracking import Tracker
    rng = np.random.default_rng(0)
    import cv2
    image = cv2.GaussianBlur(rng.uniform(0, 255, (96, 96)).astype(np.float32), (0, 0), 2.0)
    shifted = np.roll(image, (1, 2), axis=(0, 1))
    tracker = Tracker(image, [(48.0, 48.0), (40.0, 52.0)], subset=min(args.subset, 31), search=args.search,
                      subpixel=args.subpixel, seed_radius=args.seed_radius, refind_radius=8,
                      refind_zncc=args.refind_zncc, seed=args.seed, gates=Gates(min_zncc=args.min_zncc))
    tracker.track(image)
    tracker.track(shifted)
    tracker.track(np.roll(image, (9, -7), axis=(0, 1)))   # exercises the re-find path


class _StoppedBeforeStart(Exception):
    """A stop signal arrived before the session started (nothing was recorded)."""

    def __init__(self, signal_name):
        super().__init__(signal_name)
        self.signal_name = signal_name


class _Interrupt:
    """SIGINT/SIGTERM over the whole of ``livedic run`` (installed only in the main thread).

    Before the session starts (opening the source, compiling the kernels, rendering the
    simulated test, waiting for the first frame, opening the outputs) a signal ends the
    run at once: the handler raises ``_StoppedBeforeStart``. Once ``session_started``
    is called it is a stop request instead (``on_signal``): acquisition stops, the
    queued frames are tracked and the recording is closed properly. A second Ctrl-C
    gives up at once (``KeyboardInterrupt``).
    """

    def __init__(self):
        self.on_signal = None
        self.received = None
        self._previous = {}

    def session_started(self, on_signal):
        self.on_signal = on_signal

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, _frame):
        name = signal.Signals(signum).name
        if self.on_signal is None:
            self.received = name
            raise _StoppedBeforeStart(name)
        if self.received is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt   # a second Ctrl-C: give up on the clean stop
        self.received = name
        self.on_signal()

    def __exit__(self, *exc):
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        return False


class _FirstFrameAhead:
    """A source whose first frame has been read already; iterating yields it, then the rest.

    The first frame gives the image size, so the points (``--roi``, ``--p0``, ``--points``,
    their number) are checked and P0 is placed before any output is opened: bad input
    leaves no file behind.

    Raises
    ------
    SourceError
        The source ends (or fails) before its first frame.
    """

    def __init__(self, source, uri):
        from livedic.acquire.base import SourceError
        self.source = source
        self._frames = iter(source)
        try:
            self.frame = next(self._frames)
        except StopIteration:
            raise SourceError(f"{uri} delivered no frame") from None

    def __iter__(self):
        yield self.frame
        yield from self._frames

    @property
    def settings(self):
        return self.source.settings

    def close(self):
        self.source.close()


def _check_outputs(args, record_path, viewer_mode, viewer_target):
    """``OutputError`` (one line) for an output that cannot be written, before anything starts."""
    from livedic.stream.csv_output import check_output_file
    if record_path:
        check_output_file(record_path, "--record" if args.record else "recording (--record FILE.mcap or "
                          "--no-record to change)", create_folders=True)
    if viewer_mode == "save":
        check_output_file(viewer_target, "--viewer save", create_folders=True)
    if args.summary_json:
        check_output_file(args.summary_json, "--summary-json")


def check_viewer_reachable(url, timeout_s=1.0):
    """ValueError (one line) unless something accepts TCP connections at ``url``'s host and port.

    ``--viewer connect URL`` with no viewer there would otherwise run the whole session
    while the Rerun SDK retries in the background, and end with a flush timeout.
    """
    import socket
    from urllib.parse import urlsplit

    from livedic.stream.rerun_log import DEFAULT_PORT
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


# Tracker memory per point, measured with IC-GN and the seeded search on 1 MP: 5,184 points 31 MB,
# 40,401 points 280 MB (reference subset, gradients, Hessian and per-point state): ~7 KB.
_TRACKER_BYTES_PER_POINT = 7_000
# One point's share of a recorded result set: x, y, u, v, zncc, ux, uy, vx, vy (float64), point id,
# status, iterations and ok.
_RESULT_BYTES_PER_POINT = 90


def _size(n_bytes):
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def check_point_count(n_points, max_points, *, how, frames=None, recording=True):
    """ValueError (one line, with the cost) when ``n_points`` is more than ``max_points``."""
    if n_points <= max_points:
        return
    cost = f"about {_size(n_points * _TRACKER_BYTES_PER_POINT)} of memory"
    if frames and recording:
        cost += f" and {_size(n_points * _RESULT_BYTES_PER_POINT * frames)} of results recorded over {frames} frames"
    raise ValueError(f"{how} gives {n_points:,} points, more than livedic run tracks live (--max-points "
                     f"{max_points:,}; {cost}, and frames are dropped when tracking takes longer than a frame "
                     f"period): use a larger --step, fewer --n-points or a smaller --roi, or raise --max-points")


def run_session(args):
    """Run ``livedic run`` with parsed ``args`` (see ``add_run_arguments``); returns the exit code.

    Everything that can be checked before the session is: options, every output
    (``--record``, ``--viewer save``, ``--summary-json``: writable?), a ``--viewer
    connect`` viewer (listening?), then, on the first frame, the points (``--roi``,
    ``--p0``, ``--points`` inside the image, no more than ``--max-points``) and P0
    (placed on the specimen's texture, or a warning when the given one is weak). Only
    then are the recording and the Rerun stream opened, so bad input leaves no file.

    Raises
    ------
    ValueError
        Bad options or an output that cannot be written (one line, for the CLI to print).
    SourceError
        The source cannot be opened, or failed before its first frame.
    SourceLost
        The source failed mid-session (and, with ``--reconnect``, did not come back
        within ``--reconnect-timeout``); raised after the recording is closed and the
        summary printed.
    """
    from livedic.stream.rerun_log import parse_viewer

    roi_arg, p0_arg = _check_args(args)
    given_points = _read_points(args.points) if args.points else None
    stem = _session_stem()
    record_path = None if args.no_record else (args.record or _unique(stem + ".mcap"))
    viewer_mode, viewer_target, viewer_note = parse_viewer(
        args.viewer, os.path.splitext(record_path)[0] + ".rrd" if record_path else _unique(stem + ".rrd"))
    _check_outputs(args, record_path, viewer_mode, viewer_target)
    if viewer_mode == "connect":
        check_viewer_reachable(viewer_target)
    show_progress = args.progress == "on" or (args.progress == "auto" and sys.stderr.isatty())

    def say(message):
        if show_progress:
            sys.stderr.write("\r\033[K")
        print(f"livedic: {message}", file=sys.stderr, flush=True)

    import numba
    previous_threads = numba.get_num_threads()
    numba.set_num_threads(args.threads)
    try:
        with _Interrupt() as interrupt:
            return _run(args, roi_arg, p0_arg, given_points, record_path, viewer_mode, viewer_target,
                        viewer_note, show_progress, stem, say, interrupt)
    finally:
        numba.set_num_threads(previous_threads)


def _points_how(args, step):
    if args.points:
        return f"--points {args.points}"
    if args.step is not None:
        return f"--step {args.step}"
    return f"--n-points {args.n_points} (grid step {step} px)"


def _run(args, roi_arg, p0_arg, given_points, record_path, viewer_mode, viewer_target, viewer_note, show_progress,
         stem, say, interrupt):
    from livedic.acquire.base import SourceError, SourceLost
    from livedic.acquire.sources import open_source, parse_scheme
    from livedic.dic.tracking import Tracker
    from livedic.stream.acquisition import AcquisitionThread, Reconnect
    from livedic.stream.csv_output import json_text, write_text_atomic
    from livedic.stream.frame_queue import FrameQueue
    from livedic.stream.rerun_log import RerunLogger
    from livedic.stream.tracker_loop import TrackerLoop

    scheme = parse_scheme(args.source)
    if args.reconnect and scheme not in _CAMERA_SCHEMES:
        raise ValueError(f"--reconnect applies to cameras (aravis:, v4l2:); {args.source} is a {scheme} source")
    options = {}
    if scheme == "synthetic" and args.frames is not None and "frames=" not in args.source:
        options["frames"] = max(args.frames, 2)
    source = None
    recorder = None
    logger = None
    acquisition = None
    phase = "opening the source"
    try:
        source = open_source(args.source, **options)
        phase = "compiling the tracking kernels"
        _warm_up(args)
        # Imported now (~0.5 s together), not between the first frame and the next: frames that come
        # meanwhile queue up and a paced source delivers them late, in a burst.
        if viewer_mode != "none":
            import rerun  # noqa: F401
        if record_path:
            try:
                import livedic.stream.recorder  # noqa: F401
            except ImportError:
                pass                    # _open_recorder says so
        total = args.frames
        if getattr(source, "frames", None) and isinstance(source.frames, int):
            total = min(total, source.frames) if total else source.frames
        if hasattr(source, "prepare"):
            phase = "rendering the simulated test"
            rendered = getattr(source, "rendered_frames", source.frames)
            bar = ProgressBar(rendered, enabled=show_progress)
            started = time.perf_counter()
            try:
                source.prepare(progress=lambda done, n: bar.update(done, "rendering the simulated test"))
            finally:
                bar.close()
            cycling = f", cycled to make {source.frames}" if rendered != source.frames else ""
            pacing = f"delivery paced at {source.fps:g} fps" if source.options.get("pace", True) else "delivery unpaced"
            say(f"simulator: {rendered} frames rendered ahead in {time.perf_counter() - started:.1f} s{cycling}; "
                f"{pacing}")
        roi = roi_arg if roi_arg is not None else (None if given_points is not None else _default_roi(source))
        policy = _drop_policy(args.drop, source, scheme)

        # The first frame: its size checks the points before any output exists.
        phase = "waiting for the first frame"
        ahead = _FirstFrameAhead(source, args.source)
        phase = "checking the points"
        first = ahead.frame
        preview, _, preview_step = build_points(first.image.shape, roi=roi, step=args.step, n_points=args.n_points,
                                                subset=args.subset, p0=p0_arg, points=given_points)
        check_point_count(len(preview), args.max_points, how=_points_how(args, preview_step), frames=total,
                          recording=record_path is not None)
        p0_choice = choose_p0(first.image, roi, args.subset, p0=p0_arg)

        settings = _safe_settings(source)
        metadata = {
            "command": "livedic run", "source_uri": args.source, "source_settings": settings,
            "roi": list(roi) if roi else "full image", "step": args.step, "n_points_wanted": args.n_points,
            "points_file": args.points, "p0": list(p0_choice.xy), "p0_choice": p0_choice.describe(),
            "subset": args.subset,
            "search": args.search, "subpixel": args.subpixel, "seed_radius": args.seed_radius,
            "refind_radius": args.refind_radius, "refind_zncc": args.refind_zncc, "min_zncc": args.min_zncc,
            "seed": args.seed,
            "queue_size": args.queue, "drop_policy": policy, "point_ids": "P0 is point 0",
            "threads": args.threads, "reconnect": args.reconnect, "reconnect_timeout_s": args.reconnect_timeout,
        }
        phase = "opening the outputs"
        if record_path:
            # The simulator's clock starts at 0 ns; cameras keep the recorder's default (Unix time).
            def recording_stopped(message):
                say(f"warning: {message}")        # the recorder's message starts "recording stopped: ..."
                if logger is not None:
                    logger.event(message, level="error")

            recorder = _open_recorder(record_path, metadata, say, on_error=recording_stopped,
                                      start_time_ns=0 if scheme == "synthetic" else None)
        if viewer_note:
            say(viewer_note)
        logger = RerunLogger(viewer_mode, viewer_target, recording_name=os.path.basename(stem),
                             image_max_side=args.image_max_side, color_range=parse_color_range(args.color_range),
                             low_zncc=args.refind_zncc)
        p0_warning = p0_choice.warning()

        session = {}

        def make_tracker(frame):
            points, roi_used, step_used = build_points(
                frame.image.shape, roi=roi, step=args.step, n_points=args.n_points, subset=args.subset,
                p0=p0_choice.xy, points=given_points)
            tracker = Tracker(frame.image, points, subset=args.subset, search=args.search, subpixel=args.subpixel,
                              seed_radius=args.seed_radius, refind_radius=args.refind_radius,
                              refind_zncc=args.refind_zncc, seed=args.seed, gates=Gates(min_zncc=args.min_zncc))
            session.update(points=points, roi=roi_used, step=step_used, shape=frame.image.shape)
            note = (f"reference frame {frame.index}: {len(points)} points"
                    + (f", grid step {step_used} px over ROI {','.join(map(str, roi_used))}" if given_points is None
                       else f" from {args.points}")
                    + f"; {p0_choice.describe()}")
            has_truth = callable((frame.metadata or {}).get("truth"))
            logger.start(image_shape=frame.image.shape, roi=roi_used, p0_index=0, points=points,
                         has_truth=has_truth, title=f"livedic run: {args.source}", source_settings=settings)
            logger.event(note)
            if recorder is not None:
                recorder.write_event("note", note)
            if p0_warning:
                say(f"warning: {p0_warning}")
                logger.event(p0_warning, level="warning")
                if recorder is not None:
                    recorder.write_event("p0_weak", p0_warning, level="warning")
            return tracker

        queue = FrameQueue(args.queue, policy)
        on_frame = (lambda item: recorder.write_frame(_for_recording(item.frame))) if recorder is not None else None

        def source_event(kind, message, level):
            say(("warning: " if level != "info" else "") + message)
            logger.event(message, level=level)
            if recorder is not None:
                recorder.write_event(kind, message, level=level)

        reconnect = None
        if args.reconnect:
            reconnect = Reconnect(reopen=lambda: open_source(args.source, **options), retry_s=1.0,
                                  timeout_s=args.reconnect_timeout, on_event=source_event)
        acquisition = AcquisitionThread(ahead, queue, max_frames=args.frames, on_frame=on_frame,
                                        reconnect=reconnect)
        stop_event = threading.Event()
        bar = ProgressBar(total, enabled=show_progress)
        method = f"{args.search}+{args.subpixel}"

        def record_results(result, stats):
            m = result.measurement
            frame = result.frame
            recorder.write_results(
                frame.index, frame.timestamp_ns, np.arange(m.u.size, dtype=np.uint32), m.x, m.y, m.u, m.v,
                m.zncc, m.ok, ux=m.ux, uy=m.uy, vx=m.vx, vy=m.vy, status=m.status.astype(np.int32),
                iterations=m.iterations, method=method, processing_ns=result.processing_ns,
                latency_ns=result.latency_ns, reference_frame_index=loop.reference_frame.index,
                dropped_frames=result.dropped_since_last)
            if result.dropped_since_last:
                recorder.write_event("drop", f"{result.dropped_since_last} frame(s) dropped by the queue before "
                                     f"frame {frame.index} (total {result.dropped_total})", level="warning")

        p0_watch = {"warned": False}

        def watch_p0(result, stats):
            """Warn once when P0 is lost or its ZNCC falls below --refind-zncc: its trace is then doubtful."""
            if p0_watch["warned"] or result.is_reference:
                return
            m = result.measurement
            ok, zncc = bool(m.ok[0]), float(m.zncc[0])
            if ok and zncc >= args.refind_zncc:
                return
            p0_watch["warned"] = True
            what = "P0 was lost" if not ok else \
                f"P0's ZNCC fell to {zncc:.2f} (below --refind-zncc {args.refind_zncc:g})"
            message = f"{what} at frame {result.frame.index}: its trace may be wrong from there"
            say(f"warning: {message}")
            logger.event(message, level="warning")
            if recorder is not None:
                recorder.write_event("p0_weak", message, level="warning")

        def progress(result, stats):
            text = (f"{stats.fps:5.1f} fps  latency p50 {stats.latency_ms(50):5.1f} ms  "
                    f"drops {result.dropped_total}")
            if acquisition.reconnects:
                text += f"  reconnected {acquisition.reconnects}x"
            if math.isfinite(result.error_rms_px):
                text += f"  error {result.error_rms_px:.3f} px"
            bar.update(acquisition.frames, text)

        sinks = []
        if recorder is not None:
            sinks.append(record_results)
        if logger.enabled:
            sinks.append(logger)
        sinks.append(watch_p0)
        sinks.append(progress)
        loop = TrackerLoop(queue, make_tracker, sinks=sinks, stop_event=stop_event)

        interrupt.session_started(acquisition.stop)
        acquisition.start()
        try:
            loop.run()
        finally:
            acquisition.stop()
            queue.close()          # frees a put blocked on a full queue ("block" policy)
            acquisition.join(timeout=10.0)
        bar.update(acquisition.frames, bar.last_text, force=True)
        bar.close()
        stats = loop.stats
        for sink, error in loop.sink_errors:
            name = {record_results: "recording", logger: "Rerun display", watch_p0: "P0 check"}.get(sink, "progress")
            say(f"warning: {name} stopped during the session: {type(error).__name__}: {error}")
            if recorder is not None and sink is not record_results:
                recorder.write_event("note", f"{name} stopped: {error}", level="warning")
        if interrupt.received:
            say(f"stopped on {interrupt.received}; the recording is closed properly")
            if recorder is not None:
                recorder.write_event("note", f"session stopped on {interrupt.received}")
        if acquisition.error is not None:
            if recorder is not None:
                recorder.write_event("camera_lost", str(acquisition.error), level="error")
            logger.event(f"source failed: {acquisition.error}", level="error")

        summary = stats.summary()
        summary.update(source=args.source, method=method, acquired=acquisition.frames,
                       lost_upstream=_lost_upstream(acquisition), stopped_by=interrupt.received,
                       source_losses=list(acquisition.losses), reconnects=acquisition.reconnects,
                       outage_s=round(acquisition.outage_s, 3),
                       source_error=str(acquisition.error) if acquisition.error is not None else None,
                       recording=record_path if recorder is not None else None,
                       rerun=f"{viewer_mode} {viewer_target}" if viewer_target else viewer_mode,
                       points_shape=list(session.get("shape", ())), roi=list(session.get("roi", ())) or None,
                       step=session.get("step"), p0=list(p0_choice.xy), p0_choice=p0_choice.reason.name,
                       p0_weak=p0_choice.weak, viewer_log_ms_per_frame=(
                           1e3 * logger.log_seconds / logger.frames_logged if logger.frames_logged else None))
        text = format_summary(summary, stats, session, recorder)
        try:
            logger.log_summary("```\n" + text + "\n```")
        except Exception as error:  # noqa: BLE001 - the viewer is a display: the summary still goes out
            say(f"warning: the Rerun viewer did not take the summary: {type(error).__name__}: {error}")
    except _StoppedBeforeStart as stop:
        # Nothing was tracked: what was opened is closed below; a recording with no session is removed
        # (it is this run's own file: --record refuses an existing one, the default name is unique).
        interrupt.session_started(lambda: None)       # a further signal now changes nothing
        if recorder is not None:
            _close_quietly(recorder.close, "recording", say)
            recorder = None
        if phase == "opening the outputs" and record_path:
            _remove_quietly(record_path)
        say(f"stopped on {stop.signal_name} while {phase}, before the session started: nothing was recorded")
        return 0
    finally:
        if acquisition is not None and acquisition.is_alive():
            acquisition.stop()
            acquisition.join(timeout=10.0)
        elif acquisition is None and source is not None:
            _close_quietly(source.close, "frame source", say)
        if recorder is not None:
            recorder.close()
        if logger is not None:
            _close_quietly(logger.close, "Rerun stream", say)
    print(text, flush=True)
    if args.summary_json:
        write_text_atomic(args.summary_json, json_text(summary))
    if acquisition.error is not None:
        if acquisition.frames:
            # It had delivered: not bad input but a loss mid-session (the CLI's exit code 3).
            raise SourceLost(str(acquisition.error)) from acquisition.error
        raise acquisition.error if isinstance(acquisition.error, SourceError) else SourceError(str(acquisition.error))
    if stats.frames == 0 and not interrupt.received:
        raise SourceError(f"{args.source} delivered no frame")
    return 0


def _close_quietly(close, what, say):
    """``close()``; a failure is one warning line (the session's outcome and summary still go out)."""
    try:
        close()
    except Exception as error:  # noqa: BLE001 - closing a display or a source must not hide the summary
        say(f"warning: closing the {what} failed: {type(error).__name__}: {error}")


def _remove_quietly(path):
    try:
        os.unlink(path)
    except OSError:
        pass


_CAMERA_SCHEMES = ("aravis", "v4l2")


def _default_roi(source):
    """The source's suggested ROI (the simulator's gauge section), a replayed session's ROI, or None."""
    roi = getattr(source, "suggested_roi", None)
    if roi is not None:
        return tuple(int(v) for v in roi)
    session = getattr(source, "session", None)
    if isinstance(session, dict) and isinstance(session.get("roi"), (list, tuple)) and len(session["roi"]) == 4:
        return tuple(int(v) for v in session["roi"])
    return None


def _drop_policy(choice, source, scheme):
    """Queue policy: as chosen, or (auto) drop the oldest for live sources and block for files."""
    from livedic.stream.frame_queue import BLOCK, DROP_NEWEST, DROP_OLDEST
    if choice != "auto":
        return {"oldest": DROP_OLDEST, "newest": DROP_NEWEST, "block": BLOCK}[choice]
    if scheme in ("aravis", "v4l2"):
        return DROP_OLDEST
    if scheme == "synthetic":
        return DROP_OLDEST if source.options.get("pace", True) else BLOCK
    return DROP_OLDEST if getattr(source, "realtime", False) else BLOCK


# Per-process keys that mean nothing in a recording (the host's monotonic clock).
_VOLATILE_METADATA = ("capture_monotonic_ns",)


def _for_recording(frame):
    """``frame`` without the per-process metadata keys (same image, no copy)."""
    metadata = frame.metadata
    if not isinstance(metadata, dict) or not any(key in metadata for key in _VOLATILE_METADATA):
        return frame
    import dataclasses
    kept = {k: v for k, v in metadata.items() if k not in _VOLATILE_METADATA}
    return dataclasses.replace(frame, metadata=kept)


def _safe_settings(source):
    try:
        settings = dict(source.settings)
    except Exception as error:  # noqa: BLE001 - settings are informative only
        settings = {"settings_error": f"{type(error).__name__}: {error}"}
    return settings


def _open_recorder(path, metadata, say, *, on_error, start_time_ns=None):
    try:
        from livedic.stream.recorder import Recorder
    except ImportError as error:
        say(f"warning: not recording ({error}); use --no-record to silence this")
        return None
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    return Recorder(path, metadata, start_time_ns=start_time_ns, on_error=on_error)


def _lost_upstream(acquisition):
    """Frames the source skipped (gaps in its frame indices), not counting queue drops."""
    if acquisition.first_index is None:
        return 0
    return max(0, (acquisition.last_index - acquisition.first_index + 1) - acquisition.frames)


def format_summary(summary, stats, session, recorder):
    """The end-of-run text (plain, a few aligned lines)."""
    def num(value, fmt):
        return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else format(value, fmt)

    lines = [f"livedic run: {summary['source']}  ({summary['method']})"]
    lines.append(f"  frames     {summary['frames']} tracked of {summary['acquired']} acquired; "
                 f"{summary['dropped']} dropped by the queue, {summary['lost_upstream']} lost upstream")
    points = session.get("points")
    if points is not None:
        lines.append(f"  points     {len(points)} (P0 at {points[0, 0]:g}, {points[0, 1]:g}); "
                     f"{num(100 * summary['ok_fraction'], '.1f')} % ok; {summary['refound']} re-found")
    lines.append(f"  rate       {num(summary['fps'], '.1f')} fps, {num(summary['poi_per_s'], ',.0f')} POI/s")
    lines.append(f"  latency    p50 {num(summary['latency_p50_ms'], '.1f')} ms, "
                 f"p99 {num(summary['latency_p99_ms'], '.1f')} ms from frame {summary['latency_from']} to result "
                 f"(tracking p50 {num(summary['processing_p50_ms'], '.1f')} ms, "
                 f"p99 {num(summary['processing_p99_ms'], '.1f')} ms)")
    extra = f"reference set-up {num(summary['setup_ms'], '.0f')} ms"
    if summary.get("delivery_delay_p99_ms") is not None:
        extra += f"; frame delivery delay p99 {num(summary['delivery_delay_p99_ms'], '.1f')} ms"
    if summary.get("viewer_log_ms_per_frame") is not None:
        extra += f"; Rerun logging {num(summary['viewer_log_ms_per_frame'], '.1f')} ms/frame"
    lines.append(f"             {extra}")
    if summary.get("error_rms_px") is not None:
        lines.append(f"  error      RMS {num(summary['error_rms_px'], '.4f')} px, max "
                     f"{num(summary['error_max_px'], '.4f')} px against the truth (ok points)")
    if recorder is not None:
        size = os.path.getsize(recorder.path) if os.path.exists(recorder.path) else 0
        if recorder.error:
            lines.append(f"  recording  {recorder.path} STOPPED EARLY: {recorder.frames_durable} frames kept "
                         f"({size / 1e6:.0f} MB); see the warning above")
        else:
            lines.append(f"  recording  {recorder.path} ({recorder.frames_written} frames, "
                         f"{recorder.results_written} results, {size / 1e6:.0f} MB)")
    if summary.get("source_losses"):
        losses = len(summary["source_losses"])
        lines.append(f"  camera     lost {losses} time(s), back {summary['reconnects']} time(s); "
                     f"{summary['outage_s']:.1f} s without frames")
    lines.append(f"  rerun      {summary['rerun']}")
    if summary.get("stopped_by"):
        lines.append(f"  stopped    on {summary['stopped_by']}")
    return "\n".join(lines)
