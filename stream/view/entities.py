"""The view's entity paths and drawing styles: where each thing is logged in Rerun, and in which colour.

The paths are the view's contract with its readers (the tests read the .rrd back by them; docs/guide/live-view.md
describes the tree); the styles are shared by the panels that draw (``logger``, ``xy_plot``).
"""

from __future__ import annotations

from collections.abc import Sequence

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
STRESS_STRAIN = "stress_strain"                  # the stress-strain plot, an XYPlot like strain_xy
STRESS_STRAIN_CURVE = "stress_strain/data/curve"   # engineering stress (MPa) against axial strain (%)
STRESS_STRAIN_TRUE = "stress_strain/data/true"     # true stress against true strain, up to Ag
STRESS_STRAIN_NOW = "stress_strain/now"
# stereo (only in a stereo session: ``start(stereo=True)``)
CAMERA_RIGHT = "camera_right"
CAMERA_RIGHT_IMAGE = "camera_right/image"
CAMERA_RIGHT_POINTS = "camera_right/points"      # each point where the right view sees it, coloured by W
SPACE = "space"                                  # the 3D points, mm, in the specimen's best-fit plane's frame
SPACE_W = "space/points_w"                       # coloured by W, the displacement along the plane's normal
SPACE_EYY = "space/points_eyy"                   # coloured by the surface strain e_yy
LEGEND_W = "legend/w"
LIMITS_W = "colour_scale/w"

TIMELINE_FRAME = "frame"
TIMELINE_TIME = "time"

# drawing styles (colours are RGB; BLACK is packed 0xRRGGBBAA)
LOST_COLOUR = (230, 0, 0)
LOW_ZNCC_COLOUR = (255, 220, 0)
MARKER_DRAW_ORDER = 40.0        # above the field discs (Points2D default 30)
NO_STRAIN_COLOUR = (150, 150, 150)   # an ok point without a strain (too few valid neighbours): grey
# Extensometer colours, in order of definition (axial, transverse, then the others): not red (a lost one),
# yellow (low ZNCC) or magenta (P0); lines and series share them.
EXTENSOMETER_COLOURS = ((0, 220, 255), (70, 240, 70), (255, 150, 0), (185, 125, 255), (255, 255, 255))
EXTENSOMETER_LOST_COLOUR = (230, 0, 0)
BLACK = 0x000000FF              # packed opaque black
# Label sizes as fractions of the image side, for an image view ~300 px across (a quarter of a screen): Rerun
# draws a label centred under its anchor, in UI points (~7 a character, ~16 high) whatever the zoom.
LABEL_CHARACTER = 0.024
LABEL_HEIGHT = 0.055
LABEL_GAP = 0.015
EXTENSOMETER_DRAW_ORDER = 50.0  # above the lost/low-ZNCC squares and P0
STRESS_COLOURS = ((255, 150, 0), (255, 90, 200))   # engineering, true: apart from the extensometers' colours
FIT_COLOUR = (25, 25, 25)       # the elastic fit, drawn over the transverse-vs-axial curve on the light plot
LABEL_TEXT_COLOUR = (20, 20, 20)   # labels are drawn on a light box: dark text reads best
SERIES_STYLE = {
    P0: (["u (px)", "v (px)"], [(230, 80, 60), (60, 120, 230)]),
    QUALITY: (["ZNCC mean", "ZNCC min", "fraction ok"], [(40, 160, 90), (200, 140, 30), (120, 120, 120)]),
    THROUGHPUT: (["frames/s", "kPOI/s"], [(40, 120, 200), (230, 140, 20)]),
    LATENCY: (["latency (ms)", "tracking (ms)"], [(200, 50, 50), (80, 80, 200)]),
    DROPS: (["dropped frames", "queue depth"], [(200, 40, 40), (110, 110, 110)]),
    ERROR: (["RMS error (px)", "max error (px)"], [(130, 60, 170), (220, 120, 200)]),
    LIMITS_U: (["u low (px)", "u high (px)"], [(48, 18, 59), (122, 4, 3)]),
    LIMITS_V: (["v low (px)", "v high (px)"], [(48, 18, 59), (122, 4, 3)]),
}
LIMITS_W_STYLE = (["W low (mm)", "W high (mm)"], [(48, 18, 59), (122, 4, 3)])   # a stereo session's only


def extensometer_colour(index: int) -> tuple[int, int, int]:
    """The RGB colour of the extensometer ``index`` (in order of definition; the colours repeat)."""
    return EXTENSOMETER_COLOURS[index % len(EXTENSOMETER_COLOURS)]


def darker(rgb: Sequence[int], factor: float = 0.45) -> tuple[int, ...]:
    """A darker shade of ``rgb``: label text in a line's colour, legible on Rerun's light label box."""
    return tuple(int(c * factor) for c in rgb)
