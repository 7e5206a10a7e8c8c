"""The configuration of a tracking session, validated once and frozen.

``livedic run`` builds it from its command line (``SessionConfig.from_args``),
``livedic replay`` from a recording's metadata and the options given, and the
benchmarks directly; ``stream.session.session.Session`` runs it. Every check is made
here (one value at a time: ``stream.session.parsing``), when a config is built, and a bad value is a ``ValueError`` with one line
that names the option as the command line spells it (the CLI prints it and
exits 2). Nothing downstream re-checks a value or reads an argparse Namespace.

The pieces:

* ``TrackingConfig``: how points are tracked (subset, search, sub-pixel method,
  radii, gates, seed): what a recording must give for a replay to repeat it;
* ``PointsConfig``: which points (ROI, grid step or count, a points file, P0, the
  most points a live session takes);
* ``ViewerConfig``: where the live view goes (``--viewer``);
* ``SessionConfig``: the source, those three, and the session's outputs and
  pipeline settings.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
import math
import os
from dataclasses import asdict, dataclass, field, fields
from datetime import datetime
from typing import TYPE_CHECKING, Any

import numpy as np

from livedic.dic import DEFAULT_SUBSET, SEARCH_METHODS
from livedic.dic.subpixel.method import METHODS as SUBPIXEL
from livedic.dic.quality import MIN_ZNCC
from livedic.dic.region import Polygon, Rectangle, Region
from livedic.dic.search import DEFAULT_RADIUS, DEFAULT_SEARCH
from livedic.dic.tracking.tracker import REFIND_ZNCC
from livedic.dic.image_filter import DEFAULT_PREFILTER, MAX_SIGMA
from livedic.dic.interpolation import BSPLINE7, DEFAULT_INTERPOLATION, INTERPOLATIONS
from livedic.stream.session.parsing import (ROI_AUTO, ROI_FULL, check_interpolation, check_prefilter, check_search,
                                           check_subpixel, interpolation_name, parse_color_range, prefilter_text,
                                           search_method, subpixel_method,
                                           parse_exclusion, parse_p0, parse_roi, read_mask)
from livedic.stream.pipeline.progress import progress_enabled
from livedic.stream.session.options import add_config_arguments, config_values, option
from livedic.stream.stages.strain import StrainConfig, rig_and_overrides

if TYPE_CHECKING:
    from livedic.dic.tracking.key_frames import KeyFrameTracker

DEFAULT_SOURCE = "synthetic:tensile"
DEFAULT_POINTS = 1000
# Points a live session tracks at most unless --max-points says otherwise: 20,000 points take ~140 MB in
# the tracker and ~0.15 s a frame on one core (IC-GN, 1 MP), a few frames a second; --step 1 on 1 MP
# (198,120 points) took 2.8 GB, dropped half the frames and lost a fifth of the points (issue 8).
DEFAULT_MAX_POINTS = 20_000
RECORDINGS_DIR = "recordings"
# Sources that can be lost and come back (--reconnect).
CAMERA_SCHEMES = ("aravis", "v4l2")
# --drop: "auto" picks oldest for live sources and block for files (``Session`` decides, knowing the source).
DROP_CHOICES = ("auto", "oldest", "newest", "block")
CORES_CHOICES = ("split", "shared")     # --cores: stream.pipeline.cores
VIEWER_NONE = "none"
# Static frames after the reference for the noise floor, where the session does not say (--static-frames): 10
# give each point's temporal SD to about 1 / sqrt(2 x 9) = 24 % and the mean over points much better, in 0.2 s
# at 50 fps (docs/guide/noise-floor.md). Sources that film (cameras) or simulate a test take them; files and
# recordings hold what they hold: none unless asked.
DEFAULT_STATIC_FRAMES = 10
STATIC_FRAME_SCHEMES = ("synthetic",) + CAMERA_SCHEMES


def _check_threads(threads):
    import numba
    if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"--threads must be between 1 and {numba.config.NUMBA_NUM_THREADS}, got {threads}")


def _option(name):
    return "--" + name.replace("_", "-")


# ----------------------------------------------------------------------------- tracking

SUBSET_HELP = "odd subset side, pixels (default {default})"


# ``measure``'s defaults (offline: no frame rate to keep): the biseptic B-spline wherever the sub-pixel method
# samples it (icgn) and, with it, the Gaussian pre-filter chosen with it on DIC Challenge 1.0 Sample 3 and the
# Stars (docs/guide/measure.md, "The defaults"). ``run`` and ``replay`` keep the library's (bspline3, none): the
# higher degrees double IC-GN's kernel or more, which the live rate cannot spare.
OFFLINE_INTERPOLATION = BSPLINE7
OFFLINE_PREFILTER = "gaussian:0.45"
_MEASURE_INTERPOLATION = (f"{OFFLINE_INTERPOLATION} with the methods that sample it (icgn), else "
                          f"{DEFAULT_INTERPOLATION}")
_MEASURE_PREFILTER = f"{OFFLINE_PREFILTER} with {OFFLINE_INTERPOLATION}, else {DEFAULT_PREFILTER}"


def _prefilter_option(default: str | None = DEFAULT_PREFILTER, shown: str = "{default}"):
    """``--prefilter``, declared here once for ``run``/``replay`` (``TrackingConfig``) and ``measure``
    (``MeasureConfig``: ``default`` None, resolved by ``measure_defaults``; ``shown`` says what it becomes)."""
    return option(default, f"image pre-filter applied to the reference and every frame before correlation: "
                           f"none or gaussian:SIGMA, a Gaussian low-pass of SIGMA px (0 < SIGMA <= "
                           f"{MAX_SIGMA:g}; 0.4-0.8 px cuts the interpolation bias, Pan et al. 2013; "
                           f"docs/guide/measure.md) (default {shown})",
                  brief="image pre-filter: none or gaussian:SIGMA", metavar="FILTER", type=prefilter_text)


def _interpolation_option(default: str | None = DEFAULT_INTERPOLATION, shown: str = "{default}"):
    """``--interpolation``, declared here once for ``run``/``replay`` (``TrackingConfig``) and ``measure``
    (``MeasureConfig``: ``default`` None, resolved by ``measure_defaults``; ``shown`` says what it becomes)."""
    return option(default, f"grey-level interpolant IC-GN samples each frame with: "
                           f"{', '.join(INTERPOLATIONS)} (bicubic, biquintic or biseptic B-spline; the "
                           f"higher degrees cut the sub-pixel interpolation bias on DIC Challenge images for 2-3x "
                           f"the kernel time, icgn only; docs/guide/measure.md) (default {shown})",
                  brief=f"interpolant: {', '.join(INTERPOLATIONS)}", metavar="NAME", type=interpolation_name)


def _checked_interpolation(name: str, subpixel: str) -> str:
    """``--interpolation``'s canonical name, checked against the sub-pixel method (ValueError, one line)."""
    return str(SUBPIXEL[subpixel].checked_interpolation(check_interpolation(name)))


def measure_defaults(subpixel: str, interpolation: str | None, prefilter: str | None) -> tuple[str, str]:
    """``measure``'s (interpolation, prefilter), each as given or, when None, its offline default: the
    ``OFFLINE_INTERPOLATION`` where ``subpixel`` samples it, and ``OFFLINE_PREFILTER`` with that interpolant."""
    if interpolation is None:
        able = OFFLINE_INTERPOLATION in SUBPIXEL[subpixel].interpolations
        interpolation = OFFLINE_INTERPOLATION if able else DEFAULT_INTERPOLATION
    if prefilter is None:
        chosen = check_interpolation(interpolation)
        prefilter = OFFLINE_PREFILTER if chosen == OFFLINE_INTERPOLATION else DEFAULT_PREFILTER
    return interpolation, prefilter


# The sub-pixel methods a tracking session takes (not "none": a live session needs sub-pixel values).
_SUBPIXEL_REFINING = tuple(name for name, method in SUBPIXEL.items() if method.refines)

@dataclass(frozen=True)
class TrackingConfig:
    """How points are tracked frame to frame (``dic.tracking.Tracker``'s settings).

    Attributes
    ----------
    subset : int
        Odd subset side, pixels (>= 3).
    search : str
        Integer search seeded by the previous frame (``dic.SEARCH_METHODS``).
    subpixel : str
        Sub-pixel method (``dic.SUBPIXEL_METHODS`` but ``none``: a live session needs sub-pixel values).
    prefilter : str
        Image pre-filter of the reference and every frame (``dic.image_filter``): ``none`` or ``gaussian:SIGMA``,
        kept in its canonical text.
    interpolation : str
        The B-spline IC-GN samples each frame with (``dic.interpolation``): ``bspline3`` or ``bspline5``.
    seed_radius, refind_radius : int
        Search radius around the previous result, and for re-finding lost points, pixels (>= 0).
    refind_zncc : float
        Points whose ZNCC falls below it are re-found (-1..1).
    min_zncc : float
        The correlation gate: a point is ok only if its ZNCC is at least this (-1..1).
    seed : int
        Seed of the stochastic searches.
    reference_update : str
        When the reference moves to a recent frame (``dic.tracking.key_frames``): ``auto``, ``never`` or ``every:N``.
    """
    subset: int = option(DEFAULT_SUBSET, SUBSET_HELP, brief="odd subset side, pixels", metavar="N")
    search: str = option(
        DEFAULT_SEARCH, f"integer search seeded by the previous frame: {', '.join(SEARCH_METHODS)} (default "
        "{default}; with icgn or newton-raphson it runs only for the points the sub-pixel method, started from the "
        "previous result, leaves doubtful; none = never)", brief=f"integer search: {', '.join(SEARCH_METHODS)}",
        metavar="NAME", type=search_method)
    subpixel: str = option("icgn", f"sub-pixel method: {', '.join(_SUBPIXEL_REFINING)} (default {{default}})",
                           brief=f"sub-pixel method: {', '.join(_SUBPIXEL_REFINING)}", metavar="NAME",
                           type=subpixel_method)
    prefilter: str = _prefilter_option()
    interpolation: str = _interpolation_option()
    seed_radius: int = option(2, "search radius around the previous result, pixels (default {default}: covers "
                                 "1.5 px of motion between two frames; faster motion is caught by the re-find search)",
                              brief="search radius around the previous result, px", metavar="R")
    refind_radius: int = option(DEFAULT_RADIUS, "search radius for re-finding lost points, pixels (default {default})",
                                brief="search radius for re-finding lost points, px", metavar="R")
    refind_zncc: float = option(REFIND_ZNCC, "re-find points whose ZNCC falls below Z (default {default})",
                                brief="re-find points whose ZNCC falls below Z", metavar="Z")
    min_zncc: float = option(MIN_ZNCC, "a point is ok only if its ZNCC is at least Z (default {default}); the other "
                                       "quality gates (texture, neighbours, border) always apply",
                             brief="a point is ok only if its ZNCC is at least Z", metavar="Z")
    seed: int = option(0, "seed of the stochastic searches (default {default})",
                       brief="seed of the stochastic searches")
    reference_update: str = option(
        "auto", "move the reference to a recent frame as the specimen deforms (results stay displacements from the "
        "first frame): auto (default: when correlation falls, points fail or the strain since the reference passes "
        "0.05), never, or every:N frames", brief="auto, never or every:N (reference updates)", metavar="WHEN")

    def __post_init__(self):
        if self.subset < 3 or self.subset % 2 == 0:
            raise ValueError(f"--subset must be an odd integer >= 3, got {self.subset}")
        check_search(self.search)
        check_subpixel(self.subpixel)
        if not SUBPIXEL[self.subpixel].refines:
            raise ValueError(f"--subpixel {self.subpixel} gives integer displacements only: choose a sub-pixel method "
                             f"(e.g. icgn)")
        object.__setattr__(self, "prefilter", check_prefilter(self.prefilter))
        object.__setattr__(self, "interpolation", _checked_interpolation(self.interpolation, self.subpixel))
        for name in ("seed_radius", "refind_radius"):
            if getattr(self, name) < 0:
                raise ValueError(f"{_option(name)} must be >= 0, got {getattr(self, name)}")
        for name in ("refind_zncc", "min_zncc"):
            if not -1.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{_option(name)} must be between -1 and 1, got {getattr(self, name)}")
        from livedic.dic.tracking.update_policy import UpdatePolicy
        object.__setattr__(self, "reference_update", str(UpdatePolicy.parse(self.reference_update)))

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        """The parameter names, in order (the keys a recording's session metadata holds them under)."""
        return tuple(f.name for f in fields(cls))

    @property
    def method(self) -> str:
        """``"search+subpixel"``, as recorded with every result."""
        return f"{self.search}+{self.subpixel}"

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def tracker(self, image: np.ndarray, points: np.ndarray, **overrides: Any) -> KeyFrameTracker:
        """A ``dic.tracking.key_frames.KeyFrameTracker`` on reference ``image`` for ``points`` with these settings.

        ``overrides`` replace settings for this tracker only (the warm-up's smaller subset and radius).
        """
        from livedic.dic.tracking.key_frames import KeyFrameTracker
        from livedic.dic.quality import Gates
        settings = dict(self.as_dict(), **overrides)
        min_zncc = settings.pop("min_zncc")
        return KeyFrameTracker(image, points, gates=Gates(min_zncc=min_zncc), **settings)


@dataclass(frozen=True)
class MeasureConfig:
    """How ``livedic measure`` measures one pair of images (``dic.measure``'s settings), validated.

    Attributes
    ----------
    subset : int
        Odd subset side, pixels (>= 3).
    search, subpixel : str
        Integer search and sub-pixel method (``dic.SEARCH_METHODS``, ``dic.SUBPIXEL_METHODS``).
    prefilter : str
        Image pre-filter of both images (``dic.image_filter``): ``none`` or ``gaussian:SIGMA``; None (not given):
        see ``measure_defaults``.
    interpolation : str
        The B-spline IC-GN samples the deformed image with (``dic.interpolation``): ``bspline3`` or ``bspline5``;
        None (not given): see ``measure_defaults``.
    radius : int
        Search radius, pixels (>= 0).
    seed : int
        Seed of the stochastic searches.
    min_zncc : float
        The correlation gate (-1..1).
    guided : bool
        Reliability-guided (a few seeds, propagated) rather than every point searched over the radius.
    """
    subset: int = option(DEFAULT_SUBSET, SUBSET_HELP, metavar="N")
    search: str = option(DEFAULT_SEARCH, f"integer search: {', '.join(SEARCH_METHODS)} (default {{default}})",
                         metavar="NAME", type=search_method)
    subpixel: str = option("improved-surface-fit", f"sub-pixel method: {', '.join(SUBPIXEL)} (default {{default}})",
                           metavar="NAME", type=subpixel_method)
    prefilter: str | None = _prefilter_option(None, _MEASURE_PREFILTER)
    interpolation: str | None = _interpolation_option(None, _MEASURE_INTERPOLATION)
    radius: int = option(DEFAULT_RADIUS, "search radius, pixels (default {default})", metavar="R")
    seed: int = option(0, "seed of the stochastic searches (default {default})")
    min_zncc: float = option(MIN_ZNCC, "a point is ok only if its ZNCC is at least Z (default {default}, measured: no "
                                       "correct point of a low-contrast, noisy pair falls below it); the other quality "
                                       "gates (texture, neighbours, border) always apply", metavar="Z")
    guided: bool = option(True, "search every point over the full radius instead of a few seeds whose results are "
                                "propagated to their neighbours (reliability-guided, the default)",
                          flag="--no-guided", action="store_false")

    def __post_init__(self):
        if self.subset < 3 or self.subset % 2 == 0:
            raise ValueError(f"--subset must be an odd integer >= 3, got {self.subset}")
        check_search(self.search)
        check_subpixel(self.subpixel)
        interpolation, prefilter = measure_defaults(self.subpixel, self.interpolation, self.prefilter)
        object.__setattr__(self, "prefilter", check_prefilter(prefilter))
        object.__setattr__(self, "interpolation", _checked_interpolation(interpolation, self.subpixel))
        if self.radius < 0:
            raise ValueError(f"--radius must be >= 0, got {self.radius}")
        if not -1.0 <= self.min_zncc <= 1.0:
            raise ValueError(f"--min-zncc must be between -1 and 1, got {self.min_zncc}")

    @property
    def method(self) -> str:
        """``"search + subpixel"``, as the progress line names it."""
        return f"{self.search} + {self.subpixel}"

    def described(self) -> str:
        """The method, pre-filter and (for the methods that sample one) interpolant, as ``measure`` reports them."""
        sampled = f", interpolation {self.interpolation}" if SUBPIXEL[self.subpixel].interpolations else ""
        return f"{self.method}, pre-filter {self.prefilter}{sampled}"


def add_subset_argument(parser: argparse.ArgumentParser) -> None:
    """``--subset`` for ``preview``, as ``TrackingConfig`` declares it for ``run``."""
    add_config_arguments(parser, TrackingConfig, names=("subset",))


# ----------------------------------------------------------------------------- points

@dataclass(frozen=True)
class PointsConfig:
    """Which points a session tracks (P0, the traced point, is always point 0); ``stream.session.points.place_points``.

    Attributes
    ----------
    roi : dic.region Rectangle or Polygon, "auto", "full", or None
        Where the grid goes (``--roi``): a rectangle (an ``(x, y, w, h)`` tuple is taken as one) or a
        polygon; ``auto`` the speckled specimen found in the image; ``full`` the whole image. None:
        the source's suggestion (the simulator's gauge section, a replayed recording's ROI), else auto.
    mask : ndarray (H, W) of bool, or None
        ``--mask``: True on the specimen (read from ``mask_file``).
    mask_file : str or None
        The mask's file, for messages and the metadata.
    exclude : tuple of dic.region shapes
        ``--exclude``: areas no subset may reach into.
    points_file : str or None
        Track the points of this CSV (header x, y) instead of a grid.
    xy : array (N, 2) or None
        Track these points instead of a grid (already read: a points file, or a
        recording's points); ``points_file`` then only names where they come from.
    step : int or None
        Grid step, pixels; None: about ``n_points`` points over the region.
    n_points : int
        Points wanted when ``step`` is None.
    p0 : (x, y) or None
        P0; None: the best-textured point near the region's centre (``stream.session.p0``).
    max_points : int
        A live session refuses to start with more points (their cost is in the message).
    """
    roi: Any = None
    mask: np.ndarray | None = field(default=None, compare=False, repr=False)
    mask_file: str | None = None
    exclude: tuple = ()
    points_file: str | None = None
    xy: np.ndarray | None = field(default=None, compare=False, repr=False)
    step: int | None = None
    n_points: int = DEFAULT_POINTS
    p0: Sequence[float] | None = None
    max_points: int = DEFAULT_MAX_POINTS

    def __post_init__(self):
        roi = self.roi
        if isinstance(roi, (tuple, list)):
            if len(roi) != 4:
                raise ValueError(f"--roi must be 4 comma-separated numbers, e.g. 100,50,400,800; got {roi!r}")
            if int(roi[2]) <= 0 or int(roi[3]) <= 0:
                raise ValueError(f"--roi width and height must be positive, got {','.join(map(str, roi))!r}")
            object.__setattr__(self, "roi", Rectangle(*(int(v) for v in roi)))
        elif not (roi is None or roi in (ROI_AUTO, ROI_FULL) or isinstance(roi, (Rectangle, Polygon))):
            raise ValueError(f"--roi {roi!r}: give X,Y,W,H, polygon:X1,Y1,..., auto or full")
        object.__setattr__(self, "exclude", tuple(self.exclude or ()))
        if self.p0 is not None:
            object.__setattr__(self, "p0", tuple(float(v) for v in self.p0))
        if self.step is not None and self.step < 1:
            raise ValueError(f"--step must be a positive number of pixels, got {self.step}")
        if self.n_points < 1:
            raise ValueError(f"--n-points must be >= 1, got {self.n_points}")
        if self.max_points < 1:
            raise ValueError(f"--max-points must be >= 1, got {self.max_points}")

    @classmethod
    def region_from_args(cls, args: Any) -> dict:
        """``roi``, ``mask``, ``mask_file``, ``exclude`` from ``--roi --mask --exclude`` (``add_region_arguments``).

        Raises
        ------
        ValueError
            A malformed region or exclusion, an unreadable mask (one line).
        """
        mask_file = getattr(args, "mask", None)
        return {"roi": parse_roi(getattr(args, "roi", None)),
                "mask": read_mask(mask_file) if mask_file else None, "mask_file": mask_file,
                "exclude": tuple(parse_exclusion(t) for t in (getattr(args, "exclude", None) or ()))}

    @property
    def region(self) -> Region:
        """What the user gave as a ``dic.region.Region`` (outline, mask, exclusions)."""
        outline = self.roi if self.roi not in (None, ROI_AUTO, ROI_FULL) else None
        return Region(outline=outline, mask=self.mask, mask_name=self.mask_file, exclude=self.exclude)

    @property
    def given(self) -> bool:
        """Whether the points come from a file or a list rather than a grid."""
        return self.xy is not None or self.points_file is not None

    def how(self, step: float | None) -> str:
        """How the points were asked for, for messages (``step``: the grid step used)."""
        if self.points_file:
            return f"--points {self.points_file}"
        if self.xy is not None:
            return "the given points"
        if self.step is not None:
            return f"--step {self.step}"
        return f"--n-points {self.n_points} (grid step {step} px)"


# ----------------------------------------------------------------------------- viewer

@dataclass(frozen=True)
class ViewerConfig:
    """Where the live view goes: ``mode`` spawn, connect (``target`` URL), save (``target`` .rrd) or none.

    ``note`` says why a requested mode was changed (spawn without a display saves instead).
    """
    mode: str = VIEWER_NONE
    target: str | None = None
    note: str | None = None

    @classmethod
    def parse(cls, words: list[str], default_save_path: str) -> ViewerConfig:
        """From ``--viewer`` words (``stream.view.viewer.parse_viewer``); ValueError for a bad mode or URL."""
        from livedic.stream.view.viewer import parse_viewer
        return cls(*parse_viewer(words, default_save_path))

    def describe(self) -> str:
        """For the summary: the mode and where it goes."""
        return f"{self.mode} {self.target}" if self.target else self.mode


# ----------------------------------------------------------------------------- the session

def session_name() -> str:
    """``session-YYYYmmdd-HHMMSS``, the default name of a session's files."""
    return "session-" + datetime.now().strftime("%Y%m%d-%H%M%S")


def _strain_and_rig_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """``strain`` (StrainConfig) and ``rig`` (a stereo rig's ``--calibration``, else None): ``rig_and_overrides``."""
    rig, given = rig_and_overrides(args)
    return {"strain": StrainConfig(**given), "rig": rig}


def _load_from_args(args):
    """``load``, ``load_offset``, ``area_mm2`` from ``--load --load-offset --area --width --thickness``."""
    from livedic.stream.stages.stress import cross_section_mm2
    section = {name: getattr(args, name, None) for name in ("area", "width", "thickness")}
    load = getattr(args, "load", None)
    area = cross_section_mm2(**section) if any(v is not None for v in section.values()) else None
    if area is not None and load is None:
        raise ValueError("--area/--width/--thickness without --load: the stress needs the machine's force")
    offset = float(getattr(args, "load_offset", 0.0) or 0.0)
    if not math.isfinite(offset):
        raise ValueError(f"--load-offset {offset!r}: must be a finite number of seconds")
    if offset and load is None:
        raise ValueError("--load-offset without --load: it shifts the machine's force, give --load URI")
    return {"load": load, "load_offset": offset, "area_mm2": area}


def unique_path(path: str) -> str:
    """``path``, or ``path`` with -2, -3 ... before the extension if it exists."""
    if not os.path.exists(path):
        return path
    stem, ext = os.path.splitext(path)
    k = 2
    while os.path.exists(f"{stem}-{k}{ext}"):
        k += 1
    return f"{stem}-{k}{ext}"


@dataclass(frozen=True)
class SessionConfig:
    """Everything a session runs with (see the module notes), checked when built.

    Attributes
    ----------
    source : str
        Frame source URI (``acquire.sources``).
    frames : int or None
        Stop after this many frames (synthetic: also the length of the test).
    points : PointsConfig
    tracking : TrackingConfig
    record : str or None
        The recording's path (.mcap, must not exist); None: not recorded.
    record_named : bool
        Whether ``record`` was named by the user (``--record``) or is the default name (messages).
    viewer : ViewerConfig
    name : str
        The session's name (the Rerun recording's name).
    queue : int
        Frames the queue holds.
    drop : str
        When the queue is full (``DROP_CHOICES``).
    color_range : (lo, hi) or None
        Fixed colour limits of the u and v views, px.
    image_max_side : int
        Camera image in the view downsampled to at most this many pixels a side.
    show_progress : bool
        The progress line on stderr.
    threads : int
        numba threads while the session runs.
    summary_json : str or None
        Also write the summary as JSON here.
    reconnect : bool
        Reopen a lost camera instead of ending (cameras only).
    reconnect_timeout : float or None
        Give up after this many seconds without the camera (needs ``reconnect``).
    warm_up : bool
        Compile the tracking kernels on a tiny image before the source starts (live sources:
        the first frames must not wait for the compiler).
    command : str
        What made the session, in the recording's metadata.
    strain : stream.stages.strain.StrainConfig
        The strain window and measure, and the virtual extensometers.
    load : str or None
        The machine's force (``--load``: ``csv:FILE``, ``tcp://HOST:PORT``, ``synthetic``), or None.
    load_offset : float
        Seconds added to the load's times (``--load-offset``).
    area_mm2 : float or None
        Original cross-section A0 (``--area``, or ``--width`` x ``--thickness``); None: the simulated
        test's own with ``--load synthetic``, else no stress.
    publish : tuple of str
        Where each frame's extensometer strain goes out (``--publish udp://HOST:PORT`` or
        ``modbus://HOST:PORT``, ``stream.publish``); needs extensometers.
    static_frames : int or None
        Frames after the reference in which nothing moves, measured for the noise floor (``--static-frames``);
        None: ``DEFAULT_STATIC_FRAMES`` for the simulator and cameras, 0 for files and recordings
        (``static_frames_wanted``).
    """
    source: str = DEFAULT_SOURCE
    frames: int | None = None
    points: PointsConfig = field(default_factory=PointsConfig)
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    record: str | None = None
    record_named: bool = True
    viewer: ViewerConfig = field(default_factory=ViewerConfig)
    name: str = "livedic session"
    queue: int = 4
    drop: str = "auto"
    color_range: tuple | None = None
    image_max_side: int = 512
    show_progress: bool = False
    threads: int = 1
    summary_json: str | None = None
    reconnect: bool = False
    reconnect_timeout: float | None = None
    warm_up: bool = True
    command: str = "livedic run"
    strain: StrainConfig = field(default_factory=StrainConfig)
    load: str | None = None
    load_offset: float = 0.0
    area_mm2: float | None = None
    publish: tuple = ()
    rig: Any = None                     # a stereo source's StereoCalibration (--calibration with a stereo file)
    static_frames: int | None = option(
        None, f"frames after the reference in which nothing moves, measured for the noise floor (displacement and "
        f"strain SDs; docs/guide/noise-floor.md): default {DEFAULT_STATIC_FRAMES} for the simulator (rendered before "
        f"its test) and cameras (hold the specimen still), 0 for files and recordings; 0: none", metavar="N", type=int)
    cores: str = option(
        "split", "split (default): while it tracks, the tracking thread has a CPU of its own and the session's other "
        "threads and the view's process share the rest (Linux, --threads 1, two CPUs or more; else as shared); "
        "shared: the system places them (measured on 2 cores, split as good at 50 fps, far fewer frames dropped at "
        "100: docs/guide/performance.md)", metavar="split|shared", type=str)

    def __post_init__(self):
        if self.frames is not None and self.frames < 1:
            raise ValueError(f"--frames must be >= 1, got {self.frames}")
        _check_threads(self.threads)
        if self.cores not in CORES_CHOICES:
            raise ValueError(f"unknown --cores {self.cores!r}: choose one of {', '.join(CORES_CHOICES)}")
        if self.static_frames is not None and self.static_frames < 0:
            raise ValueError(f"--static-frames must be >= 0 (0: no noise floor), got {self.static_frames}")
        if self.queue < 1:
            raise ValueError(f"--queue must be >= 1 frame, got {self.queue}")
        if self.drop not in DROP_CHOICES:
            raise ValueError(f"unknown --drop {self.drop!r}: choose one of {', '.join(DROP_CHOICES)}")
        if self.image_max_side < 16:
            raise ValueError(f"--image-max-side must be >= 16 pixels, got {self.image_max_side}")
        if self.record is not None and not self.record.endswith(".mcap"):
            raise ValueError(f"--record file {self.record!r} must end in .mcap")
        if self.color_range is not None:
            lo, hi = (float(v) for v in self.color_range)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"--color-range {lo:g},{hi:g}: LO must be below HI, e.g. -2,2")
            object.__setattr__(self, "color_range", (lo, hi))
        if self.reconnect_timeout is not None:
            if not self.reconnect:
                raise ValueError("--reconnect-timeout needs --reconnect")
            if not (math.isfinite(self.reconnect_timeout) and self.reconnect_timeout > 0):
                raise ValueError(f"--reconnect-timeout must be a positive number of seconds, got "
                                 f"{self.reconnect_timeout}")

        object.__setattr__(self, "publish", tuple(self.publish or ()))
        if self.publish:
            from livedic.stream.publish import parse_publish_uris
            parse_publish_uris(self.publish)      # now: a bad URI is one line before anything opens
            if self.strain.gauge_length is None and not self.strain.extensometers:
                raise ValueError("--publish sends extensometer strain: add --gauge-length L[,W] or --extensometer "
                                 "NAME=x1,y1,x2,y2")

        if self.load is not None and str(self.load).strip().lower() == "synthetic":
            from livedic.acquire.force.simulated import check_synthetic_load_source
            check_synthetic_load_source(self.source)    # now: before the simulator renders its test

        if self.reconnect and self.scheme not in CAMERA_SCHEMES:
            raise ValueError(f"--reconnect applies to cameras (aravis:, v4l2:); {self.source} is a {self.scheme} "
                             f"source")

    @property
    def publish_targets(self) -> tuple:
        """``publish`` parsed (``stream.publish.PublishTarget``); ValueError (one line) for a bad URI."""
        from livedic.stream.publish import parse_publish_uris
        return parse_publish_uris(self.publish)

    @property
    def static_frames_wanted(self) -> int:
        """``static_frames``, or its default for this source (``DEFAULT_STATIC_FRAMES`` or 0, see the field)."""
        if self.static_frames is not None:
            return self.static_frames
        return DEFAULT_STATIC_FRAMES if self.scheme in STATIC_FRAME_SCHEMES else 0

    @property
    def scheme(self) -> str:
        """The source's scheme (``acquire.sources.SCHEMES``); SourceError for an unknown or malformed URI."""
        from livedic.acquire.sources import parse_scheme
        return parse_scheme(self.source)

    @classmethod
    def from_args(cls, args: argparse.Namespace, *, stem: str | None = None) -> SessionConfig:
        """From ``livedic run``'s parsed options (``stream.cli.run.add_run_arguments``).

        Resolves what the options leave open: the recording's default name
        (``recordings/session-YYYYmmdd-HHMMSS.mcap``, never an existing file), the
        viewer (spawn without a display saves next to the recording) and the progress
        line (``auto``: when stderr is a terminal).

        Raises
        ------
        ValueError
            A bad option (one line); an existing ``--record`` file.
        """
        tracking = TrackingConfig(**config_values(TrackingConfig, args))
        points = PointsConfig(points_file=args.points, step=args.step, n_points=args.n_points, p0=parse_p0(args.p0),
                              max_points=args.max_points, **PointsConfig.region_from_args(args))
        if args.record is not None and args.record.endswith(".mcap") and os.path.exists(args.record):
            raise ValueError(f"--record file {args.record} exists: choose a new name (recordings are never "
                             f"overwritten)")
        stem = stem or os.path.join(RECORDINGS_DIR, session_name())
        record = None if args.no_record else (args.record or unique_path(stem + ".mcap"))
        default_rrd = os.path.splitext(record)[0] + ".rrd" if record else unique_path(stem + ".rrd")
        viewer = ViewerConfig.parse(args.viewer, default_rrd)
        return cls(
            source=args.source, frames=args.frames, points=points, tracking=tracking, record=record,
            record_named=args.record is not None, viewer=viewer, name=os.path.basename(stem),
            queue=args.queue, drop=args.drop, color_range=parse_color_range(args.color_range),
            image_max_side=args.image_max_side,
            show_progress=progress_enabled(args.progress),
            threads=args.threads, summary_json=args.summary_json, reconnect=args.reconnect,
            reconnect_timeout=args.reconnect_timeout, **_strain_and_rig_from_args(args),
            publish=tuple(getattr(args, "publish", None) or ()), **_load_from_args(args),
            **config_values(SessionConfig, args))
