"""Strain and virtual extensometers in a session: settings, placement on the points, the per-frame stage.

``StrainConfig`` holds what the user asked for (``--strain-window``,
``--strain-measure``, ``--gauge-length``, ``--extensometer``, ``--scale``);
``StrainConfig.place(points, p0, roi, step, subset)`` turns it into a
``StrainStage`` on the reference points (the strain windows found, the
extensometers' ends placed and checked), once, before any output opens. The
stage is the session's first stage: per frame it computes the strain field and
the extensometer readings from the tracked displacements, attaches them to the
``FrameResult`` (``result.strain``, ``result.extensometers``) for the sinks after
it (recording, Rerun view, progress line), and keeps the last readings and its
own cost for the summary. ``livedic export`` and ``livedic replay`` rebuild the
same stage from the recording's metadata (``StrainConfig.from_metadata``), so a
recording's strain is computed one way everywhere. It is a ``stream.pipeline.stage.Stage``: it reads the
tracker's measurement (and a fracture), provides ``strain`` and ``extensometers``, and gives the summary's
strain lines (``format_strain_summary``, with Poisson's ratio when the session fits one on its pair).

Extensometers:

``--gauge-length L[,W]``
    ``axial``: length L along y (image rows, the pulling axis of the simulator),
    centred on P0; ``transverse``: length W along x through P0 (default 0.8 x
    the ROI width, shortened if needed to keep its ends on the tracked points).
``--extensometer NAME=x1,y1,x2,y2``
    any other, between two reference image positions in px (repeatable).

Lengths are in px, or in mm with ``--scale PX_PER_MM`` (image positions stay in px).

With ``--calibration CAL.json`` (``livedic calibrate``) the lens's distortion is removed first: reference
points and their current positions (points + u, v) are undistorted to ideal pixels, and, when the
calibration measured the specimen plane (``--plane``), mapped through the plane's homography to plane
pixels (mm on the plane x px/mm, axes as the image's at its centre: ``dic.calibration.PlaneFrame``), so a
tilted plane's foreshortening is removed too; the strain windows' offsets, the displacements they fit
and the extensometers' ends and lengths are in those ("ideal" below) px (the strain windows keep the
tracked grid's neighbours). The calibration's px/mm on the specimen plane is
the scale; ``--scale`` with a calibration that has one is refused (two scales), and gives the scale of a
calibration without one. Extensometer ends given or recorded are image positions (what the user sees).
"""

import math
import re
import time
from array import array
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np

from livedic.dic.calibration import CameraCalibration, image_points, plane_points
from livedic.dic.strain.extensometer import (AXIAL, BAND, END_FITS, LOCAL, TRANSVERSE, Extensometer,
                                              ExtensometerOffPoints, end_displacements, place_extensometers,
                                              read_extensometers,
                                              strain_noise)
from livedic.dic.strain import DEFAULT_MEASURE, DEFAULT_WINDOW, MEASURES, strain_field, strain_window
from livedic.stream.pipeline.frame_result import FrameResult
from livedic.stream.pipeline.stage import Stage
from livedic.stream.stages.contraction import format_poisson

TRANSVERSE_FRACTION = 0.8
# The axial extensometer's ends: the band of points across the specimen (a gauge-mark line) averages 2-4x less
# noise than the local fit at the same neck bias (docs/guide/extensometer-class.md, measured). The transverse's
# ends are on the specimen's edges, where no band across exists: local.
DEFAULT_AXIAL_END_FIT = BAND
# An extensometer's expected noise at placement, for the warning below: the point displacement noise of IC-GN on
# good 8-bit speckle is 0.01-0.02 px (0.006 px measured on the simulator); the low end, so that the warning is
# never a false alarm. dic.strain.extensometer.strain_noise turns it into strain: sigma_e = 0.01 px |w2 - w1| / L0
# (w: the ends' fit weights), about 0.007 px / L0 on a 10-14 px grid (17 microstrain at L0 = 400 px); on the
# simulator's rigid translation the readings' scatter matched it within 0.8-1.4 x for L0 = 12-384 px.
EXPECTED_POINT_NOISE_PX = 0.01
# ISO 9513 class 1 (what ISO 6892-1 asks for Rp0.2, the small-strain property an axial extensometer serves;
# class 0.5 is for E, which a DIC session fits over many frames) allows 1 % of the reading; at the 0.2 % strain
# of the proof point that is 20 microstrain, and the expected noise must stay within it: sigma_e <= 0.01 x 0.002;
# sigma_e falls as 1 / L0, so the length needed is L0 x sigma_e / 2e-5. (Its other limit, 3 um of displacement,
# is 0.03 px at 10 px/mm: any length meets it, so it cannot tell a usable extensometer from a 12 px one.)
CLASS_1_RELATIVE_ERROR = 0.01
SMALL_STRAIN = 0.002
NOISE_LIMIT = CLASS_1_RELATIVE_ERROR * SMALL_STRAIN
MIN_AUTO_TRANSVERSE_SUBSETS = 3    # an automatic transverse shorter than this many subsets is no extensometer
_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,40}$")


def add_strain_arguments(parser, *, recorded=False):
    """Add ``--strain-window --strain-measure --gauge-length --extensometer --scale`` to an argparse parser.

    ``recorded``: for commands that read a recording (replay, export): the defaults are then the
    recorded settings (None here), which ``StrainConfig.from_metadata(..., **overrides)`` fills in.
    """
    group = parser.add_argument_group("strain and extensometers" + (" (default: the recorded settings)"
                                                                     if recorded else ""))
    group.add_argument("--strain-window", type=int, default=None if recorded else DEFAULT_WINDOW, metavar="N",
                       help="odd number of grid points a side of the strain window (pointwise least squares; "
                            f"VSG = (N - 1) x step + subset){'' if recorded else f'; default {DEFAULT_WINDOW}'}")
    group.add_argument("--strain-measure", choices=MEASURES, default=None if recorded else DEFAULT_MEASURE,
                       help="engineering (small strain), green (Green-Lagrange) or true (logarithmic, Hencky)"
                            + ("" if recorded else f"; default {DEFAULT_MEASURE}"))
    group.add_argument("--gauge-length", metavar="L[,W]",
                       help="virtual extensometers 'axial' (length L along y, centred on P0) and 'transverse' "
                            "(length W along x through P0; default 0.8 x the ROI width); px, or mm with --scale")
    group.add_argument("--extensometer-ends", choices=END_FITS, default=None if recorded else DEFAULT_AXIAL_END_FIT,
                       help="how the axial extensometer's ends follow the material: 'band', the points on a line "
                            "across the specimen at each end (a gauge-mark line: less noise); 'local', a quadratic "
                            "surface over the points around each end" + ("" if recorded
                                                                          else f"; default {DEFAULT_AXIAL_END_FIT}"))
    group.add_argument("--extensometer", action="append", metavar="NAME=x1,y1,x2,y2",
                       help="another virtual extensometer between two reference image positions, px "
                            "(repeatable)")
    group.add_argument("--scale", type=float, metavar="PX_PER_MM",
                       help="pixels per millimetre: --gauge-length in mm, lengths also reported in mm")
    group.add_argument("--calibration", metavar="CAL.json",
                       help="camera calibration from livedic calibrate: points undistorted before strain and "
                            "extensometers; its px/mm (from --plane) is the scale"
                            + (" (default: the recorded one, if any)" if recorded else ""))
    return parser


def parse_gauge_length(text):
    """``L`` or ``L,W`` (positive numbers) -> (L, W or None); ValueError with an example otherwise."""
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) not in (1, 2) or not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"--gauge-length {text!r}: give L or L,W, positive lengths (px, or mm with --scale), "
                         f"e.g. 400 or 400,200")
    return values[0], (values[1] if len(values) == 2 else None)


def parse_extensometer(text):
    """``NAME=x1,y1,x2,y2`` -> ``Extensometer``; ValueError with an example otherwise."""
    name, sep, coords = str(text).partition("=")
    name = name.strip()
    example = "e.g. --extensometer upper=400,200,400,500"
    if not sep or not _NAME.match(name):
        raise ValueError(f"--extensometer {text!r}: give NAME=x1,y1,x2,y2 with a NAME of letters, digits, "
                         f"_ . - ({example})")
    try:
        values = [float(v) for v in coords.split(",")]
    except ValueError:
        values = []
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        raise ValueError(f"--extensometer {text!r}: give four numbers x1,y1,x2,y2 in px ({example})")
    if values[:2] == values[2:]:
        raise ValueError(f"--extensometer {text!r}: its two ends coincide")
    return Extensometer(name, *values)


@dataclass(frozen=True)
class StrainConfig:
    """What strain and which extensometers a session computes (see the module notes).

    Attributes
    ----------
    window : int
        Points a side of the strain window (odd, >= 3).
    measure : str
        One of ``dic.strain.MEASURES``.
    gauge_length : float or None
        Axial extensometer length (px, or mm with ``scale``); None: no axial/transverse pair.
    gauge_width : float or None
        Transverse extensometer length; None: 0.8 x the ROI width.
    axial_end_fit : str
        How the axial extensometer's ends are fitted (``dic.strain.extensometer.END_FITS``).
    extensometers : tuple of dic.strain.extensometer.Extensometer
        More, in reference px.
    scale : float or None
        Pixels per millimetre as given (``--scale``); ``px_per_mm`` is the one used.
    calibration : dic.calibration.CameraCalibration or None
        The camera's calibration: positions are undistorted before strain and extensometers.
    """
    window: int = DEFAULT_WINDOW
    measure: str = DEFAULT_MEASURE
    gauge_length: float | None = None
    gauge_width: float | None = None
    axial_end_fit: str = DEFAULT_AXIAL_END_FIT
    extensometers: tuple = ()
    scale: float | None = None
    calibration: CameraCalibration | None = None

    def __post_init__(self):
        if not isinstance(self.window, int) or self.window < 3 or self.window % 2 == 0:
            raise ValueError(f"--strain-window must be an odd number of points >= 3, got {self.window}")
        if self.measure not in MEASURES:
            raise ValueError(f"--strain-measure {self.measure!r}: choose one of {', '.join(MEASURES)}")
        if self.scale is not None and not (math.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"--scale must be a positive number of pixels per mm, got {self.scale}")
        if self.scale is not None and self.calibration is not None and self.calibration.px_per_mm is not None:
            raise ValueError(f"--scale {self.scale:g} and --calibration, which gives {self.calibration.px_per_mm:.4f} "
                             "px/mm on the specimen plane: give one of them")
        if self.gauge_width is not None and self.gauge_length is None:
            raise ValueError("a transverse gauge width needs --gauge-length L,W")
        if self.axial_end_fit not in END_FITS:
            raise ValueError(f"--extensometer-ends {self.axial_end_fit!r}: choose one of {', '.join(END_FITS)}")
        object.__setattr__(self, "extensometers", tuple(self.extensometers))
        names = [e.name for e in self.extensometers]
        reserved = [n for n in names if self.gauge_length is not None and n in (AXIAL, TRANSVERSE)]
        if reserved:
            raise ValueError(f"--extensometer {reserved[0]}: that name is --gauge-length's; choose another")
        if len(set(names)) != len(names):
            raise ValueError(f"--extensometer names must differ: {', '.join(names)}")

    @classmethod
    def from_args(cls, args, *, recorded_metadata=None):
        """From options added by ``add_strain_arguments``; with ``recorded_metadata`` the options given
        replace the recorded settings (``from_metadata``), the others stay as recorded."""
        given = overrides_from_args(args)
        if recorded_metadata is not None:
            return cls.from_metadata(recorded_metadata, **given)
        return cls(**given)

    @property
    def px_per_mm(self) -> float | None:
        """The scale used: ``--scale``, else the calibration's on the specimen plane, else None."""
        if self.scale is not None:
            return self.scale
        return None if self.calibration is None else self.calibration.px_per_mm

    def to_px(self, length):
        """A length as given (mm with a scale, else px) in px."""
        scale = self.px_per_mm
        return length * scale if scale else length

    def in_mm(self, length_px):
        """A length in px in mm (float), or None without a scale."""
        scale = self.px_per_mm
        return float(length_px) / scale if scale else None

    def ideal(self, xy):
        """Image positions (..., 2) as the strain uses them: with a calibration undistorted (and on its plane,
        in plane px), else themselves."""
        xy = np.asarray(xy, dtype=np.float64)
        return xy if self.calibration is None else plane_points(self.calibration, xy)

    def image(self, xy):
        """Ideal positions (..., 2) back to image positions (``ideal``'s inverse)."""
        xy = np.asarray(xy, dtype=np.float64)
        return xy if self.calibration is None else image_points(self.calibration, xy)

    def resolve_extensometers(self, p0, roi, x_range=None):
        """The extensometers in reference px: the axial/transverse pair on ``p0`` (x, y), then the others.

        The default transverse length is 0.8 x the ROI width, shortened where needed to keep both
        ends within ``x_range`` (the tracked points' x extent across P0's row: a specimen narrower there
        than the ROI, P0 not at the ROI's centre).
        """
        placed = []
        if self.gauge_length is not None:
            x0, y0 = (float(v) for v in p0)
            half = 0.5 * self.to_px(self.gauge_length)
            if self.gauge_width is not None:
                width = self.to_px(self.gauge_width)
            else:
                width = TRANSVERSE_FRACTION * roi[2]
                if x_range is not None:
                    width = min(width, 2.0 * min(x0 - x_range[0], x_range[1] - x0))
            placed.append(Extensometer(AXIAL, x0, y0 - half, x0, y0 + half, self.axial_end_fit))
            placed.append(Extensometer(TRANSVERSE, x0 - 0.5 * width, y0, x0 + 0.5 * width, y0))
        return tuple(placed) + self.extensometers

    def place(self, points, *, p0, roi, step, subset, image_size=None):
        """The ``StrainStage`` on the reference ``points`` (N, 2); ValueError (one line) for an end off the points.

        ``roi`` is (x, y, w, h) of the points' region (the transverse default width); ``step``
        the grid step (None: the points' typical spacing); ``image_size`` (W, H) of the frames, checked
        against the calibration's. With a calibration the windows are found on the tracked grid and
        their offsets, P0 and the extensometers' ends taken in ideal px.
        """
        if self.calibration is not None and image_size is not None:
            self.calibration.check_size(*image_size)
        points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        windows = strain_window(points, window=self.window, step=step, subset=subset)
        ideal = self.ideal(points)
        if self.calibration is not None:
            centre = np.repeat(np.arange(len(points)), np.diff(windows.start))
            windows = replace(windows, dx=ideal[windows.index, 0] - ideal[centre, 0],
                              dy=ideal[windows.index, 1] - ideal[centre, 1])
            p0 = self.ideal(np.asarray(p0, dtype=np.float64))
        x_range = _row_extent(ideal, p0, windows.step)
        resolved = self._ideal_ends(self.resolve_extensometers(p0, roi, x_range))
        self._check_automatic_transverse(resolved, p0, x_range, subset)
        unit = f" ({self.px_per_mm:g} px/mm)" if self.px_per_mm else ""
        try:
            extensometers = place_extensometers(resolved, ideal, step=windows.step)
        except ExtensometerOffPoints as error:
            raise ExtensometerOffPoints(f"{error}{unit}", error.name) from None
        except ValueError as error:
            raise ValueError(f"{error}{unit}") from None
        return StrainStage(self, points, windows, extensometers, ideal_points=ideal)

    def _ideal_ends(self, extensometers):
        """The extensometers given in image px (``--extensometer``, recorded ones) with their ends undistorted;
        the automatic pair, built on the undistorted P0, stays as it is."""
        if self.calibration is None:
            return extensometers
        given = {e.name for e in self.extensometers}
        out = []
        for e in extensometers:
            if e.name in given:
                (x1, y1), (x2, y2) = self.ideal(np.array([[e.x1, e.y1], [e.x2, e.y2]]))
                e = Extensometer(e.name, float(x1), float(y1), float(x2), float(y2), e.end_fit)
            out.append(e)
        return tuple(out)

    def _check_automatic_transverse(self, resolved, p0, x_range, subset):
        """ValueError (one line) when the automatic transverse is shorter than one subset: its two ends would
        be measured from the same points (``StrainStage.noise_warnings`` warns below a few subsets)."""
        if self.gauge_length is None or self.gauge_width is not None:
            return
        transverse = next(e for e in resolved if e.name == TRANSVERSE)
        if transverse.length_px < subset:
            raise ValueError(f"the automatic transverse extensometer would be {transverse.length_px:.0f} px, less than "
                             f"one subset ({subset} px): P0 at x {p0[0]:g} and the tracked points at x "
                             f"{x_range[0]:g}..{x_range[1]:g}; widen the ROI, move P0 (--p0) towards its middle, or "
                             f"give --gauge-length L,W")

    def as_metadata(self):
        """The settings as a recording's session metadata keys (``from_metadata`` reads them back).

        ``scale_px_per_mm`` is the scale used (``px_per_mm``); ``calibration`` the whole CAL.json document.
        """
        from livedic.acquire.calibration import calibration_document
        return {"strain_window": self.window, "strain_measure": self.measure, "scale_px_per_mm": self.px_per_mm,
                "gauge_length": self.gauge_length, "gauge_width": self.gauge_width,
                "axial_end_fit": self.axial_end_fit,
                "extensometers_given": [[e.name, e.x1, e.y1, e.x2, e.y2] for e in self.extensometers],
                "calibration": None if self.calibration is None else calibration_document(self.calibration)}

    @classmethod
    def from_metadata(cls, metadata, **overrides):
        """The settings a recording was made with (defaults for an older recording), ``overrides`` replacing them.

        The recorded extensometers are taken as placed (the ``extensometers`` key: name and ends in
        reference px), so a replay or an export measures between the same material points whatever
        points it tracks; a ``gauge_length``/``extensometers`` override replaces them all. Each keeps its recorded
        end fit (``extensometer_end_fits``; local in recordings made before there was a choice); an
        ``axial_end_fit`` override applies to the recorded axial one.
        """
        def get(key, default):
            value = metadata.get(key, default)
            return default if value in (None, "") else value
        placed = metadata.get("extensometers")
        if not isinstance(placed, (list, tuple)):
            placed = metadata.get("extensometers_given") or ()
        calibration = recorded_calibration(metadata)
        fits = dict(metadata.get("extensometer_end_fits") or {})
        if "axial_end_fit" in overrides:
            fits[AXIAL] = overrides["axial_end_fit"]
        recorded = dict(window=int(get("strain_window", DEFAULT_WINDOW)),
                        measure=str(get("strain_measure", DEFAULT_MEASURE)),
                        axial_end_fit=str(get("axial_end_fit", DEFAULT_AXIAL_END_FIT)),
                        extensometers=tuple(Extensometer(str(e[0]), *(float(v) for v in e[1:5]),
                                                         str(fits.get(str(e[0]), LOCAL))) for e in placed),
                        scale=_float_or_none(metadata.get("scale_px_per_mm")), calibration=calibration)
        recorded.update(overrides)
        if recorded["calibration"] is not None and recorded["calibration"].px_per_mm is not None \
                and "scale" not in overrides:
            recorded["scale"] = None       # the recorded scale is the calibration's own
        return cls(**recorded)


def recorded_calibration(metadata) -> CameraCalibration | None:
    """The calibration a recording was made with (its session metadata's ``calibration``), or None."""
    from livedic.acquire.calibration import calibration_from_document
    document = metadata.get("calibration")
    return None if document is None else calibration_from_document(document, "the recording's calibration")


def _row_extent(points, p0, step):
    """(x_min, x_max) of the points on P0's row (within half a grid step of it), else of all points; None if none."""
    if not len(points):
        return None
    row = points[np.abs(points[:, 1] - float(p0[1])) <= 0.5 * float(step)]
    chosen = row if len(row) >= 2 else points
    return float(chosen[:, 0].min()), float(chosen[:, 0].max())


def rig_and_overrides(args) -> tuple[Any, dict]:
    """``(rig, strain settings)`` from the command line, ``--calibration`` read once: a stereo rig's file is the rig
    (a ``dic.calibration.StereoCalibration``; the strain settings then have no calibration), a camera's goes to the
    strain settings (``overrides_from_args``; rig None). CalibrationError: a file neither can use."""
    path = getattr(args, "calibration", None)
    if path is None:
        return None, overrides_from_args(args)
    from livedic.acquire.calibration import read_any_calibration
    calibration = read_any_calibration(path)
    if isinstance(calibration, CameraCalibration):
        return None, overrides_from_args(args, calibration=calibration)
    return calibration, overrides_from_args(args, calibration=None)


_FROM_ARGS = object()


def overrides_from_args(args, *, calibration=_FROM_ARGS):
    """The strain settings given on the command line (a dict for ``StrainConfig``; absent ones left out).

    A ``--gauge-length`` or ``--extensometer`` given replaces all the recorded extensometers. ``calibration``: the
    one ``--calibration`` names, already read (``rig_and_overrides``; None: none for the strain), else read here.
    """
    given = {}
    if getattr(args, "strain_window", None) is not None:
        given["window"] = args.strain_window
    if getattr(args, "strain_measure", None) is not None:
        given["measure"] = args.strain_measure
    if getattr(args, "scale", None) is not None:
        given["scale"] = args.scale
    if getattr(args, "extensometer_ends", None) is not None:
        given["axial_end_fit"] = args.extensometer_ends
    if calibration is _FROM_ARGS and getattr(args, "calibration", None) is not None:
        from livedic.acquire.calibration import read_calibration
        calibration = read_calibration(args.calibration)
    if calibration is not None and calibration is not _FROM_ARGS:
        given["calibration"] = calibration
    length = parse_gauge_length(getattr(args, "gauge_length", None))
    extra = tuple(parse_extensometer(t) for t in (getattr(args, "extensometer", None) or ()))
    if length is not None or extra:
        given.update(gauge_length=length[0] if length else None, gauge_width=length[1] if length else None,
                     extensometers=extra)
    return given


def format_length(length_px, length_mm=None):
    """``"400.0 px"``, or ``"400.0 px (32.00 mm)"`` with the length in mm (``--scale``)."""
    return f"{length_px:.1f} px" + (f" ({length_mm:.2f} mm)" if length_mm is not None else "")


def _float_or_none(value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


@dataclass
class StrainStage(Stage):
    """The per-frame strain and extensometer computation on one set of reference points (a session stage).

    Give it a ``FrameResult`` (``on_frame``) or use ``compute(u, v, ok)`` directly. It is placed on the points
    in the session's preparation (``StrainConfig.place``: an extensometer off the points fails before any
    output opens), so it has nothing to set up on the reference.
    """
    needs: ClassVar[tuple[str, ...]] = ("frame", "measurement", "fracture")
    provides: ClassVar[tuple[str, ...]] = ("strain", "extensometers")

    config: StrainConfig
    points: np.ndarray               # the tracked reference points, image px
    windows: Any                     # dic.strain.StrainWindow (offsets in ideal px with a calibration)
    placed: Any                      # dic.strain.extensometer.ExtensometerSet (ends in ideal px with a calibration)
    ideal_points: Any = None         # the points undistorted (``points`` without a calibration)
    name: str = "strain"
    required: bool = False
    last_strain: Any = None          # the last frame's StrainField
    last_readings: Any = None        # ... and ExtensometerReadings
    seconds: array = field(default_factory=lambda: array("d"))
    point_labels: np.ndarray | None = None  # the side of each crack each point is on (after a fracture)
    end_labels: np.ndarray | None = None
    truth_errors: dict = field(default_factory=dict)   # name -> max |eng strain error| against the truth
    last_timings: dict | None = None  # the last frame's {"strain": ns, "extensometers": ns} (the stage times)
    # Poisson's ratio fitted on the axial/transverse pair (stream.stages.contraction.ContractionWatch, a sink of
    # the session's output thread), summarised with the strain
    contraction: Any = None

    @property
    def extensometers(self):
        return self.placed.extensometers

    @property
    def vsg_px(self):
        return self.windows.vsg_px

    def compute(self, u, v, ok):
        """(StrainField, ExtensometerReadings) of one frame's displacements of ``points``.

        After a fracture (``add_fracture``) windows and extensometer ends use the points of their own
        side of the crack only: a plane across a crack would read its opening as strain.
        The time each took is ``last_timings``.
        """
        started = time.perf_counter_ns()
        u, v = self.ideal_displacements(u, v)
        strain = strain_field(self.windows, u, v, ok, measure=self.config.measure, labels=self.point_labels)
        middle = time.perf_counter_ns()
        readings = read_extensometers(self.placed, self._ideal_points(), u, v, ok, point_labels=self.point_labels,
                                      end_labels=self.end_labels)
        self.last_timings = {"strain": middle - started, "extensometers": time.perf_counter_ns() - middle}
        return strain, readings

    def _ideal_points(self):
        return self.points if self.ideal_points is None else self.ideal_points

    def ideal_displacements(self, u, v):
        """Image displacements (u, v) of the points as displacements in ideal px (themselves without a
        calibration): undistort(points + (u, v)) - undistort(points); NaN stays NaN."""
        if self.config.calibration is None:
            return u, v
        moved = self.config.ideal(self.points + np.column_stack([u, v]))
        ideal = self._ideal_points()
        return moved[:, 0] - ideal[:, 0], moved[:, 1] - ideal[:, 1]

    def displacements_mm(self, u, v):
        """Image displacements (u, v) of the points as displacements on the specimen plane in mm
        (``ideal_displacements`` / ``px_per_mm``); None without a scale."""
        scale = self.config.px_per_mm
        if not scale:
            return None
        iu, iv = self.ideal_displacements(u, v)
        return np.asarray(iu) / scale, np.asarray(iv) / scale

    @property
    def image_ends(self) -> np.ndarray:
        """The extensometers' reference ends (2E, 2) in image px (where to draw them on the camera's image)."""
        ends = self.placed.ends
        return self.config.image(ends) if len(ends) else ends

    @property
    def image_extensometers(self) -> tuple:
        """The extensometers with their ends in image px (their ``length_px`` is then the image's, not L0)."""
        ends = self.image_ends
        return tuple(replace(e, x1=float(ends[2 * k, 0]), y1=float(ends[2 * k, 1]), x2=float(ends[2 * k + 1, 0]),
                             y2=float(ends[2 * k + 1, 1])) for k, e in enumerate(self.extensometers))

    def end_positions(self, u, v, ok) -> np.ndarray:
        """The extensometers' ends (2E, 2) in this frame, image px (NaN where an end is lost)."""
        iu, iv = self.ideal_displacements(u, v)
        eu, ev = end_displacements(self.placed, self._ideal_points(), iu, iv, ok)
        return self.config.image(self.placed.ends + np.column_stack([eu, ev]))

    def add_fracture(self, fracture):
        """Split the points (and the extensometer ends) by the crack of a ``dic.tensile.fracture.Fracture``."""
        def sides(where):
            offset = (where - np.asarray(fracture.centre)) @ np.array([-fracture.direction[1], fracture.direction[0]])
            return (offset > 0).astype(np.int64)
        count = 0 if self.point_labels is None else int(self.point_labels.max()) + 1
        base = np.zeros(len(self.points), dtype=np.int64) if self.point_labels is None else self.point_labels
        ends = np.zeros(len(self.placed.ends), dtype=np.int64) if self.end_labels is None else self.end_labels
        scale = max(count, 1)
        self.point_labels = base + scale * sides(self.points)
        self.end_labels = ends + scale * sides(self.config.image(self.placed.ends))     # the crack is in image px

    def exact_readings(self, truth):
        """Exact engineering strain of every extensometer from a truth ``truth(x, y) -> (u, v)``."""
        ends = self.placed.ends
        if self.config.calibration is None:
            tu, tv = truth(ends[:, 0], ends[:, 1])
        else:       # the truth is in image px: the ends' image positions moved, then undistorted
            seen = self.config.image(ends)
            su, sv = truth(seen[:, 0], seen[:, 1])
            moved = self.config.ideal(seen + np.column_stack([su, sv]))
            tu, tv = moved[:, 0] - ends[:, 0], moved[:, 1] - ends[:, 1]
        first, second = slice(0, None, 2), slice(1, None, 2)
        length = np.hypot(ends[second, 0] + tu[second] - ends[first, 0] - tu[first],
                          ends[second, 1] + tv[second] - ends[first, 1] - tv[first])
        l0 = np.hypot(ends[second, 0] - ends[first, 0], ends[second, 1] - ends[first, 1])
        return length / l0 - 1.0

    def on_frame(self, result: FrameResult) -> None:
        """The frame's strain field and extensometer readings into ``result`` (``strain``, ``extensometers``)."""
        started = time.perf_counter_ns()
        if result.fracture is not None:
            self.add_fracture(result.fracture)
        m = result.measurement
        strain, readings = self.compute(m.u, m.v, m.ok)
        self.seconds.append((time.perf_counter_ns() - started) / 1e9)
        result.strain = strain
        result.extensometers = readings
        self.last_strain, self.last_readings = strain, readings
        truth = result.frame.metadata.get("truth") if isinstance(result.frame.metadata, dict) else None
        if callable(truth) and len(readings.names):
            error = np.abs(readings.eng_strain - self.exact_readings(truth))
            for name, e, ok in zip(readings.names, error, readings.ok):
                if ok:
                    self.truth_errors[name] = max(self.truth_errors.get(name, 0.0), float(e))

    def ms_per_frame(self, percentile=50):
        return float(np.percentile(np.array(self.seconds), percentile)) * 1e3 if self.seconds else float("nan")

    def expected_noise(self, point_noise_px=EXPECTED_POINT_NOISE_PX):
        """Each extensometer's expected strain noise (standard deviation) for a point noise, in order."""
        return strain_noise(self.placed, self.points, point_noise_px)

    def noise_warnings(self, point_noise_px=EXPECTED_POINT_NOISE_PX):
        """One line per extensometer too short for ISO 9513 class 1 at small strain (see NOISE_LIMIT), or an
        automatic transverse shorter than MIN_AUTO_TRANSVERSE_SUBSETS subsets: its noise and the length needed."""
        lines = []
        subset = self.windows.subset
        automatic = self.config.gauge_length is not None and self.config.gauge_width is None
        apart = strain_noise(self.placed, self.points, point_noise_px, independent_ends=True)
        for e, noise, noise_apart in zip(self.extensometers, self.expected_noise(point_noise_px), apart):
            # the length whose ends, apart, would meet the limit (a short one's shared points make it look better)
            needed = e.length_px * max(noise, noise_apart) / NOISE_LIMIT
            short_auto = automatic and e.name == TRANSVERSE and e.length_px < MIN_AUTO_TRANSVERSE_SUBSETS * subset
            if not (noise > NOISE_LIMIT or short_auto):
                continue
            text = (f"extensometer {e.name}: L0 {self._length(e.length_px)} expects ~{1e6 * noise:.0f} microstrain "
                    f"of noise ({point_noise_px:g} px point noise), above ISO 9513 class 1's "
                    f"{1e6 * NOISE_LIMIT:.0f} microstrain at {100 * SMALL_STRAIN:g} % strain; it needs L0 >= "
                    f"{self._length(needed)}")
            if short_auto:
                text += (f"; the automatic transverse (0.8 x the ROI width, kept on the points) is shorter than "
                         f"{MIN_AUTO_TRANSVERSE_SUBSETS} subsets ({MIN_AUTO_TRANSVERSE_SUBSETS * subset} px): widen "
                         f"the ROI or give --gauge-length L,W")
            elif e.name in (AXIAL, TRANSVERSE):
                text += "; lengthen it with --gauge-length L,W where the specimen allows"
            else:
                text += "; move its ends apart"
            lines.append(text)
        return lines

    def _length(self, px):
        scale = self.config.px_per_mm
        return f"{px:.0f} px" + (f" ({px / scale:.2f} mm)" if scale else "")

    def describe(self):
        """One line: the strain window, VSG and measure, and the extensometers."""
        text = (f"strain: {self.config.measure}, window {self.windows.window} points x step {self.windows.step:g} px "
                f"+ subset {self.windows.subset} = VSG {self.vsg_px:.0f} px")
        calibration = self.config.calibration
        if calibration is not None:
            text += (f"; lens distortion removed (calibration {calibration.target}, k1 {calibration.dist_coeffs[0]:.4g}, "
                     f"reprojection RMS {calibration.rms_px:.3f} px)")
        if self.extensometers:
            text += "; extensometers " + ", ".join(
                f"{e.name} L0 {format_length(e.length_px, self.config.in_mm(e.length_px))} ({e.end_fit} ends)"
                for e in self.extensometers)
        return text

    def summary(self):
        """Numbers for the session summary (a dict, NaN where missing)."""
        readings = self.last_readings
        final = {}
        if readings is not None:
            for i, name in enumerate(readings.names):
                final[name] = {"L0_px": float(readings.l0_px[i]), "L0_mm": self.config.in_mm(readings.l0_px[i]),
                               "L_px": float(readings.length_px[i]),
                               "eng_strain": float(readings.eng_strain[i]),
                               "true_strain": float(readings.true_strain[i]), "ok": bool(readings.ok[i]),
                               "error_max_vs_truth": self.truth_errors.get(name)}
        return {"strain_measure": self.config.measure, "strain_window": self.windows.window,
                "vsg_px": self.vsg_px, "strain_ms_p50": self.ms_per_frame(50),
                "strain_ms_p99": self.ms_per_frame(99), "extensometers": final}

    def summary_lines(self) -> list[str]:
        """The summary's strain lines (``format_strain_summary``), Poisson's ratio among them when fitted."""
        return format_strain_summary({**self.summary(),
                                      **(self.contraction.summary() if self.contraction is not None else {})})

    def metadata(self) -> dict[str, Any]:
        """The VSG and the extensometers as placed (name and ends in reference image px: with a calibration
        their ideal ends distorted back, so ``from_metadata`` and the calibration place them again exactly)."""
        return {"vsg_px": self.vsg_px,
                "extensometers": [[e.name, e.x1, e.y1, e.x2, e.y2] for e in self.image_extensometers],
                "extensometer_end_fits": {e.name: e.end_fit for e in self.extensometers}}


def format_strain_summary(strain: dict | None) -> list[str]:
    """The summary's strain lines (none without strain): window, VSG, final extensometer readings."""
    if not strain:
        return []
    surface = f" (VSG {strain['vsg_mm']:.2f} mm on the specimen's surface)" if strain.get("vsg_mm") else ""
    lines = [f"  strain     {strain['strain_measure']}, window {strain['strain_window']} points, VSG "
             f"{strain['vsg_px']:.0f} px{surface}; {strain['strain_ms_p50']:.2f} ms/frame "
             f"(p99 {strain['strain_ms_p99']:.2f})"]
    for name, final in strain["extensometers"].items():
        reading = (f"{100 * final['eng_strain']:.3f} % engineering, {100 * final['true_strain']:.3f} % true"
                   if final["ok"] else "no reading in the last frame (an end lost)")
        error = final.get("error_max_vs_truth")
        versus = f"; max error vs truth {1e6 * error:.0f} microstrain" if error is not None else ""
        length = (f"{final['L0_mm']:.3f} mm in space" if strain.get("in_space")
                  else format_length(final['L0_px'], final.get('L0_mm')))
        lines.append(f"  extensom.  {name}: L0 {length}, final {reading}{versus}")
    if strain.get("poisson_ratio"):
        lines.append(f"  Poisson    {format_poisson(strain['poisson_ratio'])}")
    return lines
