"""What ``livedic export`` draws of the fields, as the user chose it: the options (``add_field_arguments``,
``FieldOptions``), the files they name, and the quantities with their units and colour ranges.
"""

from __future__ import annotations

import argparse
import os
import re
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from livedic.stream.view.colour_scale import MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_STRAIN, grow_limits


QUANTITIES = ("u", "v", "exx", "eyy", "exy")
DEFAULT_EVERY = 10          # maps of 1 frame in 10: a map costs ~0.1 s and ~0.7 MB at 1 MP (docs/guide/export.md)
DEFAULT_VIDEO = "eyy"
DEFAULT_VIDEO_FPS = 10.0
DEFAULT_OPACITY = 1.0       # the field opaque: its colours read true against the colour bar
STRAIN_UNITS = {"%": 100.0, "microstrain": 1e6}
DEFAULT_STRAIN_UNIT = "%"

MAPS_FOLDER = "maps"
VTK_FOLDER = "vtk"
PVD_FILE = "fields.pvd"
VIDEO_FOURCC = "mp4v"
VIDEO_SUFFIX = ".mp4"
_MAP_NAME = re.compile(r"^(u|v|exx|eyy|exy)_\d+\.png$")
_VTU_NAME = re.compile(r"^frame_\d+\.vtu$")


def video_name(quantity: str) -> str:
    return f"overlay_{quantity}{VIDEO_SUFFIX}"


def map_name(quantity: str, frame_index: int) -> str:
    return os.path.join(MAPS_FOLDER, quantity, f"{quantity}_{int(frame_index):06d}.png")


def vtu_name(frame_index: int) -> str:
    return os.path.join(VTK_FOLDER, f"frame_{int(frame_index):06d}.vtu")


def add_field_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
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
    maps: tuple[str, ...] = QUANTITIES
    every: int = DEFAULT_EVERY
    video: str = DEFAULT_VIDEO          # "" for none
    video_fps: float = DEFAULT_VIDEO_FPS
    vtk: bool = True
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)     # quantity -> (lo, hi), display unit
    strain_unit: str = DEFAULT_STRAIN_UNIT
    opacity: float = DEFAULT_OPACITY

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> FieldOptions:
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
    def wanted(self) -> bool:
        return bool(self.maps or self.video or self.vtk)

    @property
    def coloured(self) -> tuple[str, ...]:
        """The quantities drawn (maps and video), in ``QUANTITIES`` order."""
        return tuple(q for q in QUANTITIES if q in self.maps or q == self.video)

    def outputs(self) -> list[str]:
        """What this export writes into DIR besides the CSV files (top-level names)."""
        names = [MAPS_FOLDER] if self.maps else []
        names += [video_name(self.video)] if self.video else []
        names += [VTK_FOLDER, PVD_FILE] if self.vtk else []
        return names

    def existing(self, directory: str) -> list[str]:
        """The outputs of this export that ``directory`` already holds (names for a message)."""
        found: list[str] = []
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
    def label(self) -> str:
        return f"{self.symbol} ({self.unit})"


def quantities(scale: float | None = None, strain_unit: str = DEFAULT_STRAIN_UNIT, measure: str = "engineering",
               vsg_px: float | None = None) -> dict[str, Quantity]:
    """name -> ``Quantity``: displacements in px (mm with ``scale`` px/mm), strain in ``strain_unit``."""
    length_unit, length_factor = ("mm", 1.0 / scale) if scale else ("px", 1.0)
    strain_factor = STRAIN_UNITS[strain_unit]
    gauge = f", VSG {vsg_px:.0f} px" if vsg_px else ""
    shown = {"u": ("u", "horizontal displacement"), "v": ("v", "vertical displacement"),
             "exx": ("e_xx", f"{measure} strain along x{gauge}"), "eyy": ("e_yy", f"{measure} strain along y{gauge}"),
             "exy": ("e_xy", f"{measure} shear strain (tensor){gauge}")}
    out: dict[str, Quantity] = {}
    for name, (symbol, meaning) in shown.items():
        strain = name.startswith("e")
        factor = strain_factor if strain else length_factor
        start = (MIN_COLOUR_LIMIT_STRAIN if strain else MIN_COLOUR_LIMIT_PX) * factor
        out[name] = Quantity(name, symbol, meaning, strain_unit if strain else length_unit, factor, start)
    return out


class ColourRanges:
    """One colour range per quantity for the whole sequence: the fixed ones, the others grown frame by frame."""

    def __init__(self, shown: Mapping[str, Quantity], fixed: Mapping[str, tuple[float, float]] | None = None,
                 names: tuple[str, ...] = QUANTITIES) -> None:
        self.shown = shown
        self.fixed = dict(fixed or {})
        self.limits = {q: self.fixed.get(q, (-shown[q].start, shown[q].start)) for q in names}

    def add(self, values: Mapping[str, np.ndarray], ok: np.ndarray) -> None:
        """Take one frame's ``values`` (quantity -> recorded values of the points) of the ``ok`` points."""
        for name, limits in self.limits.items():
            if name not in self.fixed:
                self.limits[name] = grow_limits(limits, self.shown[name].factor * np.asarray(values[name])[ok])
