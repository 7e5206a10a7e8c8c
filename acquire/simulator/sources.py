"""Simulated cameras with exactly known motion: a tensile test and plain translations.

URIs (options after ``?``, joined with ``&``; every option is optional)::

    synthetic:tensile?frames=300&fps=50&size=1024x1024&bit=8&noise=1.0&seed=0
    synthetic:translate?frames=100&du=0.3&dv=-0.2&jump=40:6:0

Options of both models

========  ==========================================================  ===================
frames    number of frames (>= 2), frame 0 is the undeformed reference  300 / 100
fps       frame rate of the simulated camera, frames per second       50
size      WIDTHxHEIGHT in pixels (each >= 64)                          1024x1024 / 512x512
bit       8 (Mono8, uint8) or 12 (Mono12, uint16 below 4096)          8
noise     camera noise, standard deviation in 8-bit grey levels       1.0
          (scaled by 4095/255 for 12 bit); 0 for none
seed      seed of the speckle pattern, grip jitter and noise          0
radius    speckle radius R in px (Zhou-Goodson exp(-d^2/R^2))         4
pace      1: deliver at ``fps`` in real time; 0: as fast as read      1
loop      K >= 2: render only K frames of the test and cycle through  0 (off)
          them forward and back (see below); 0: render every frame
========  ==========================================================  ===================

Options of ``synthetic:tensile`` (a test to fracture:
``synthetic:tensile?strain=0.30&neck=1.0&fade=0.2&fracture=1``)

========  ==========================================================  ===================
strain    uniform plastic strain when the neck starts (>= 0)          0.05
neck      extra peak strain at the neck centre in the last frame      0.15
          before any fracture (>= 0)
lateral   law of the lateral contraction: ``linear`` (small strain:   auto
          Poisson 0.3 elastic, 0.5 plastic, linearised),
          ``incompressible`` (plastic flow keeps the volume at any
          strain) or ``auto``: linear while strain <= 0.05 and
          neck <= 0.15 (the default test's frames stay as they
          were), incompressible beyond
view      ``grip``: the bottom grip line stays put in the image;      auto
          ``centre``: the camera keeps the deformed gauge section
          centred (its two ends' mid-point stays where it was), so a
          30 % / 100 % test stays in view; ``auto``: grip under the
          same limits as ``lateral``, centre beyond
fade      0..1: the speckles fade as the paint strains plastically,   0 (none)
          each at its own seeded rate; F is the share of their
          density lost on average at the most strained point (below)
fracture  0: none; 1: the specimen breaks across the neck centre in   0 (none)
          the last 10 % of the frames (frame frames - round(0.1
          frames)); F >= 2: the first broken frame is F (< frames).
          Not with ``loop``.
modulus   Young's modulus E in GPa of the force law (below, Force)    200
thickness coupon thickness in mm (the cross-section's depth)          2
scale     camera scale in px per mm (the gauge width in mm)           10
hardening h >= 0: linear hardening, the stress grows to (1 + h) x     0 (perfectly
          the yield stress over the uniform plastic phase; this        plastic)
          changes the elastic strain, so the displacement and the
          images (0 keeps every image as it was)
========  ==========================================================  ===================

``synthetic:translate`` adds ``du``, ``dv`` (shift per
frame in px, default 0.3 and -0.2) and ``jump=F:U:V`` (from frame F on, add a
sudden extra shift (U, V) px; default none). ``synthetic:`` alone is the tensile test.
A bad value is one ``SourceError`` line naming the option and what it takes.

The simulator renders ahead; delivery is paced. Every frame of the test is
rendered into memory before the first frame is delivered (``prepare``; about
50 ms per 1024 x 1024 frame on one core here, so ~15 s for the default 300
frames; the large-strain, fade and fracture options cost the same), then frames are handed out at ``fps`` from memory,
so the rate a consumer sees is the camera's, not the renderer's. Frame
timestamps are the simulated camera clock, ``index * 1e9 / fps`` ns.

Long runs (soak tests): with ``loop=K`` (K < frames) only K frames are
rendered, the test's schedule spanning those K frames, and the ``frames``
delivered frames cycle through them forward and back, 0, 1 ... K-1, K-2 ... 1,
0, 1 ... (a cyclic load-unload test, so the motion between two frames stays
small). Frame indices and timestamps keep increasing; ``truth(i, ...)`` and
the frame metadata are those of the rendered frame ``rendered_index(i)``.
Memory is K frames, whatever ``frames`` is.

The tensile test
----------------
A dog-bone coupon filmed face-on, pulled along y (image rows, the vertical
axis): a speckled gauge section of width 0.4 W between two wider shoulders
(0.7 W) joined by smooth fillets, on a darker, untextured background, so a
region of interest must be chosen. The bottom grip line (image bottom row) is
fixed up to a small rigid motion; the top grip pulls upward (negative v). The
axial engineering strain along the specimen is

    e_yy(Y) = e_el(t) [a + (1 - a) g(Y)] + e_pl(t) g(Y) + e_n(t) sech^2((Y - Y_n) / s)

with ``g`` a smooth box that is 1 over the gauge section and 0 in the
shoulders, ``a`` = gauge/shoulder width (the shoulders strain less
elastically, as stress = force / area) and a neck at ``Y_n`` = 0.06 H above
the centre, of width ``s`` = 0.07 H (FWHM 0.12 H, a diffuse neck about a third
of the gauge width long). The plastic zone's ends have the fillets' width
(0.035 H). Schedule over the normalised time
``tau = i / (frames - 1)`` (``i / (F - 1)`` with a fracture at frame F):
elastic loading to ``e_el`` = 0.004 at tau = 0.15,
uniform plastic strain growing linearly to ``strain`` at tau = 0.6, then the
neck grows quadratically to ``neck`` at tau = 1 while the rest unloads
elastically by 20 %. The displacement is the exact integral,
``V(Y) = -int_Y^{Y_b} e_yy`` (closed form with tanh and log cosh): engineering
strain is dy/dY - 1, so it stays exact at any strain. The lateral contraction
is ``U = -L(Y) (X - X_c)``: with ``lateral=linear``
``L = 0.3 e_el(...) + 0.5 e_p`` (Poisson ratio 0.3 elastic, 0.5 plastic), where
``e_p = e_pl g + e_n sech^2`` is the plastic strain; at large strain that is
wrong (at 100 % it would halve the width), so ``lateral=incompressible`` takes
the width's stretch ``1 - L = (1 - 0.3 e_el(...)) / sqrt(1 + e_p)``: the plastic
part keeps the volume (width^2 x length), the small elastic part keeps its
Poisson ratio. Rigid motion: both grips drift by
a fraction of a pixel over the test and jitter by 0.03 px per frame
(seeded), and the top grip drifts sideways by 0.4 px, a small shear; with
``view=centre`` the whole image also moves by ``-(V(top) + V(bottom)) / 2`` of
the gauge ends, so the deformed gauge stays centred (at 30 % / 100 % it spans
~97 % of the height before the fracture). The
model keeps ``y`` a function of ``Y`` alone, so each image row is the
reference sampled along one horizontal line at affinely mapped columns: the
inverse map is solved per row (Newton, safeguarded by bisection for very
large strains, to 1e-12 px) and the Zhou-Goodson sum
of the ``dic.speckle`` pattern is evaluated there exactly (same centres, same
5R cutoff as ``SpecklePattern.intensity``; no image interpolation). Intensity:
white paint darkened by the speckle, ``full * (0.06 + 0.88 exp(-I))``, a
pointwise map that keeps the motion exact.

Surface change (``fade=F``): the paint cracks as it strains, so each speckle k
loses optical density with the plastic strain at its centre,
``I = sum_k a_k exp(-d_k^2 / R^2)``,
``a_k = max(0, 1 - F r_k e_p(y_k) / (strain + neck))``, with ``r_k`` a seeded
rate uniform in 0..2 (mean 1): the spots' density falls by F on average at the
most strained point and the pattern itself changes (spots fade unequally), which a
correlation coefficient notices and an intensity scaling would not. Irreversible
(the plastic strain never decreases) and attached to the material, so the
motion stays exact. Nothing fades in the elastic phase or outside the plastic
zone. At the neck centre of ``strain=0.30&neck=1.0`` (last frame before the
fracture), the ZNCC of a 21 px subset between the faded and unfaded images
of the same deformation is about 0.997 (F = 0.2), 0.95 (0.5), 0.5 (1).

Fracture (``fracture``): in frame F the specimen separates across the neck
centre, reference row ``Y_n`` (a material point with Y < Y_n belongs to the
upper half). The loading (strains, drift, camera) stops at frame F - 1, where
the neck has reached ``neck``; from F on the load is gone, so both halves unload
elastically (``e_el`` = 0; plastic strain stays) and the upper half moves away
by the crack's opening, ``gap = 3 px + 2 px per frame after F``: V of the
upper half is that of the lower half's formula minus ``gap``. The rows between
the two faces show the background (a 1 px coverage ramp at each face, as at
the coupon's sides). ``source.fracture_frame`` (None without one) and
``metadata["fracture_frame"]`` (in every frame's metadata, only with a
fracture) say when; ``metadata["phase"]`` is ``"fractured"`` from then on and
``metadata["nominal_strain"]`` includes the gap; ``model.crack_faces(i)``
gives the faces' rows.
``source.visible(i, x, y, half_width)`` (and ``metadata["truth"].visible(x, y,
half_width)``) says which reference points' square subsets of that half-width
are fully seen in frame i: all specimen, entirely on one side of the crack
(once broken: Y - d >= Y_n or Y + d < Y_n) and inside the image in the
reference and in frame i (a large strain carries parts of the coupon out of
view). The truth stays exact for every material point, visible or not.

Force (``source.force_N(i)``, ``metadata["force_N"]``, ``source.specimen``): the
model's elastic strain is the stress over E, so the gauge section's engineering
stress is ``E e_el(t)`` and the force ``F = E e_el(t) A0``, with ``A0`` = gauge
width (0.4 W px) / ``scale`` x ``thickness`` (default 1024 px wide: 40.96 mm x
2 mm = 81.92 mm^2). The shoulders strain ``a e_el``: the same force over the
wider section. Yield at ``e_el`` = 0.004: 800 MPa at E = 200 GPa. Without
``hardening`` the material is perfectly plastic (``e_el`` stays 0.004 during
the uniform plastic flow), so Rp0.2 = Rm = yield exactly; the neck then unloads
by 20 % (the engineering stress falls). With ``hardening=h``, ``e_el = 0.004
(1 + h e_pl / strain)`` during the uniform flow (linear hardening, slope
``h yield / strain`` against plastic strain), Rm = ``(1 + h)`` yield when the
neck starts and Rp0.2 = yield ``(1 + 0.002 h / strain)`` (None for
``strain`` < 0.002). From the fracture frame on the force is 0.
``livedic.acquire.force.open_load("synthetic", source=SOURCE)`` gives it as a
force signal.

Exact truth is the displacement of material points. A subset-based method with
a first-order shape function cannot follow the curvature of the field inside a
subset, so where the strain changes fast (the neck's flanks late in the test)
it shows a systematic error of up to ~0.1 px at 1024 x 1024 with 21 px subsets
(~0.25 px at 512 x 512): that is the method's, not the truth's.

``truth(frame_index, x, y)`` gives the exact (u, v) of reference points and
``Frame.metadata["truth"]`` holds the same for that frame as a callable
``truth(x, y) -> (u, v)``, with ``truth.visible(x, y, half_width)`` (the
source's ``visible``; for ``synthetic:translate``: the subset inside the image
in the reference and in that frame). Paced frames also carry
``metadata["capture_monotonic_ns"]``: when the simulated camera produced the
frame, on the host's ``time.monotonic_ns`` clock (a consumer that holds the GIL
can make the frame *arrive* later than that; latency is honest from capture).
"""

import math
import threading
import time
import urllib.parse
from functools import partial

import numpy as np
from numba import njit, prange

from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.acquire.options import parse_bool, parse_number

MODELS = ("tensile", "translate")
_FULL_SCALE = {8: 255, 12: 4095}
_PIXEL_FORMAT = {8: "Mono8", 12: "Mono12"}
# Memory cap for the frames rendered ahead.
MAX_RENDER_BYTES = 4 << 30
# Speckles per pixel: the paper's 1000 spots on 256 x 256.
SPECKLE_DENSITY = 1000.0 / 65536.0
# Paint model: pixel = full * (PAINT_FLOOR + PAINT_GAIN * exp(-I)), I the Zhou-Goodson sum.
PAINT_FLOOR = 0.06
PAINT_GAIN = 0.88
BACKGROUND_LEVEL = 0.10

# The force law's defaults (module notes, Force): a steel-like modulus, a 2 mm sheet, 10 px per mm.
DEFAULT_MODULUS_GPA = 200.0
DEFAULT_THICKNESS_MM = 2.0
DEFAULT_SCALE_PX_PER_MM = 10.0
_COMMON_DEFAULTS = {"fps": 50.0, "bit": 8, "noise": 1.0, "seed": 0, "radius": 4.0, "pace": True, "loop": 0}
TENSILE_DEFAULTS = dict(_COMMON_DEFAULTS, frames=300, size=(1024, 1024), strain=0.05, neck=0.15, lateral="auto",
                        view="auto", fade=0.0, fracture=0, modulus=DEFAULT_MODULUS_GPA,
                        thickness=DEFAULT_THICKNESS_MM, scale=DEFAULT_SCALE_PX_PER_MM, hardening=0.0)
# Laws of the lateral contraction and camera views of the tensile test (module notes).
LATERAL_LAWS = ("linear", "incompressible")
VIEWS = ("grip", "centre")
# Up to these (the default test's), ``lateral=auto`` and ``view=auto`` keep the small-strain model.
SMALL_STRAIN_LIMITS = {"strain": 0.05, "neck": 0.15}
# Seeds the speckles' fading rates (independent of the pattern, the jitter and the noise).
_FADE_SEED = 2025
TRANSLATE_DEFAULTS = dict(_COMMON_DEFAULTS, frames=100, size=(512, 512), du=0.3, dv=-0.2, jump=None)


# --------------------------------------------------------------------------- #
# URI parsing
# --------------------------------------------------------------------------- #

def _usage():
    return ("synthetic:tensile?frames=300&fps=50&size=1024x1024&bit=8&noise=1.0&seed=0&radius=4&pace=1"
            "&loop=0&strain=0.05&neck=0.15&lateral=auto&view=auto&fade=0&fracture=0"
            "&modulus=200&thickness=2&scale=10&hardening=0, "
            "or synthetic:translate?frames=100&du=0.3&dv=-0.2&jump=40:6:0 "
            "(same common options)")


def parse_synthetic_uri(uri):
    """Split ``synthetic:MODEL?k=v&...`` into (model, {option: text}); raises SourceError."""
    if not isinstance(uri, str) or not uri.startswith("synthetic:"):
        raise SourceError(f"not a synthetic source URI: {uri!r}; use {_usage()}")
    rest = uri[len("synthetic:"):]
    model, _, query = rest.partition("?")
    model = model.strip("/") or "tensile"
    if model not in MODELS:
        raise SourceError(f"unknown synthetic model {model!r} in {uri!r}: choose one of {', '.join(MODELS)} "
                          f"(e.g. {_usage()})")
    options = {}
    if query:
        for part in query.split("&"):
            if not part:
                continue
            key, sep, value = part.partition("=")
            if not sep:
                raise SourceError(f"option {part!r} in {uri!r} has no value: write NAME=VALUE, e.g. frames=300")
            options[urllib.parse.unquote(key).strip()] = urllib.parse.unquote(value).strip()
    return model, options


def _convert_options(model, raw):
    """Typed options for ``model`` from text or Python values; SourceError names the bad one."""
    defaults = TENSILE_DEFAULTS if model == "tensile" else TRANSLATE_DEFAULTS
    unknown = sorted(set(raw) - set(defaults))
    if unknown:
        raise SourceError(f"unknown option(s) {', '.join(unknown)} for synthetic:{model}: valid options are "
                          f"{', '.join(sorted(defaults))}")
    out = dict(defaults)
    for key, value in raw.items():
        if value is None:
            continue
        try:
            out[key] = _CONVERTERS[key](value)
        except (TypeError, ValueError) as error:
            raise SourceError(f"synthetic:{model} option {key}={value!r}: {error}") from None
    if out["loop"] == 1:
        raise SourceError(f"synthetic:{model} option loop=1: must be 0 (off) or the number of frames to "
                          "render and cycle through (>= 2)")
    return out


def _resolve_tensile_options(options):
    """The tensile options with ``lateral``/``view`` chosen and ``fracture`` as a frame (0: none).

    ``auto`` keeps the small-strain model (linear lateral law, bottom grip fixed in view) up to the
    default test's strains, so those frames stay as they were, and takes the large-strain one beyond.
    """
    out = dict(options)
    small = all(out[key] <= limit for key, limit in SMALL_STRAIN_LIMITS.items())
    if out["lateral"] == "auto":
        out["lateral"] = "linear" if small else "incompressible"
    if out["view"] == "auto":
        out["view"] = "grip" if small else "centre"
    contraction = 0.5 * (out["strain"] + out["neck"])
    if out["lateral"] == "linear" and contraction >= 0.9:
        raise SourceError(f"synthetic:tensile option lateral=linear: the linear law narrows the neck to "
                          f"1 - 0.5 (strain + neck) = {1 - contraction:.2f} of its width (must stay above 0.1); "
                          "use lateral=incompressible")
    frames, fracture = out["frames"], out["fracture"]
    if fracture and _rendered_count(out) < frames:
        raise SourceError(f"synthetic:tensile option fracture={fracture}: a broken specimen cannot be cycled "
                          f"with loop={out['loop']}; use loop=0")
    if fracture == 1:
        fracture = frames - max(1, round(0.1 * frames))
        if fracture < 2:
            raise SourceError(f"synthetic:tensile option fracture=1: needs frames >= 3 (frames={frames})")
    elif fracture and fracture > frames - 1:
        raise SourceError(f"synthetic:tensile option fracture={fracture}: the frame it breaks at must be in "
                          f"2..{frames - 1} (frames={frames}), or 1 for the last 10 % of the frames")
    out["fracture"] = fracture
    return out


def _rendered_count(options):
    """Frames actually rendered: ``loop`` when it is on and below ``frames``, else ``frames``."""
    loop = options["loop"]
    return min(loop, options["frames"]) if loop else options["frames"]


def _to_size(value):
    if isinstance(value, str):
        parts = value.lower().split("x")
        if len(parts) != 2:
            raise ValueError("write WIDTHxHEIGHT, e.g. 1024x1024")
        width, height = int(parts[0]), int(parts[1])
    else:
        width, height = (int(v) for v in value)
    if width < 64 or height < 64:
        raise ValueError("width and height must be >= 64 px")
    return (width, height)


def _to_bit(value):
    bit = int(value)
    if bit not in _FULL_SCALE:
        raise ValueError("bit depth must be 8 or 12")
    return bit


def _to_jump(value):
    if value is None or value == "":
        return None
    if isinstance(value, str):
        parts = value.split(":")
        if len(parts) != 3:
            raise ValueError("write FRAME:U:V, e.g. 40:6:0")
        frame, u, v = int(parts[0]), float(parts[1]), float(parts[2])
    else:
        frame, u, v = value
        frame, u, v = int(frame), float(u), float(v)
    if frame < 1 or not (math.isfinite(u) and math.isfinite(v)):
        raise ValueError("the jump frame must be >= 1 and U, V finite")
    return (frame, u, v)


def _to_choice(choices):
    def convert(value):
        text = str(value).strip().lower()
        if text not in choices:
            raise ValueError(f"choose one of {', '.join(choices)}")
        return text
    return convert


def _to_fade(value):
    fade = parse_number(value, low=0)
    if fade > 1.0:
        raise ValueError("must be in 0..1 (the share of the speckles' density lost, on average, at the most "
                         "strained point)")
    return fade


def _to_fracture(value):
    """0 (off), 1 (on, at the default frame) or the frame F >= 2 at which the specimen breaks."""
    try:
        return int(parse_bool(value))
    except ValueError:
        pass
    try:
        return parse_number(value, integer=True, low=0)
    except ValueError:
        raise ValueError("write 0 (none), 1 (in the last 10 % of the frames) or the frame it breaks at, "
                         ">= 2") from None


_INT = partial(parse_number, integer=True)
_CONVERTERS = {
    "frames": partial(_INT, low=2), "fps": partial(parse_number, low=0, low_open=True), "size": _to_size,
    "bit": _to_bit, "noise": partial(parse_number, low=0), "seed": partial(_INT, low=0),
    "radius": partial(parse_number, low=0.5), "pace": parse_bool, "loop": partial(_INT, low=0),
    "strain": partial(parse_number, low=0), "neck": partial(parse_number, low=0), "du": parse_number,
    "dv": parse_number, "jump": _to_jump, "lateral": _to_choice(("auto",) + LATERAL_LAWS),
    "view": _to_choice(("auto",) + VIEWS), "fade": _to_fade, "fracture": _to_fracture,
    "modulus": partial(parse_number, low=0, low_open=True), "thickness": partial(parse_number, low=0, low_open=True),
    "scale": partial(parse_number, low=0, low_open=True), "hardening": partial(parse_number, low=0),
}


# --------------------------------------------------------------------------- #
# The tensile model (pure maths, no pixels)
# --------------------------------------------------------------------------- #

def _logcosh(z):
    a = np.abs(z)
    return a + np.log1p(np.exp(-2.0 * a)) - math.log(2.0)


def _sech2(z):
    return 1.0 / np.cosh(np.clip(z, -350.0, 350.0)) ** 2


class TensileModel:
    """Exact Lagrangian displacement of a dog-bone coupon under tension (see module notes).

    Parameters
    ----------
    shape : tuple of int, (H, W)
        Image size, rows and columns.
    frames : int
        Frames of the test; frame 0 is the undeformed reference, the last one the deepest neck
        (or, with ``fracture_frame``, the last one before the fracture).
    strain : float
        Uniform plastic strain reached when the neck starts.
    neck : float
        Extra peak strain at the centre of the neck in the last frame (before the fracture).
    seed : int
        Seed of the grip jitter.
    lateral : {"linear", "incompressible"}
        Law of the lateral contraction: ``linear`` (dU/dX = -(0.3 e_el + 0.5 e_p), the small-strain
        law of the default test) or ``incompressible`` (width stretch (1 - 0.3 e_el) / sqrt(1 + e_p):
        plastic flow keeps the volume at any strain).
    view : {"grip", "centre"}
        ``grip``: the bottom grip line stays put in the image; ``centre``: the camera keeps the
        deformed gauge section centred (the mid-point of its two ends stays where it was).
    fracture_frame : int or None
        First frame in which the specimen is broken across the neck centre (2 <= F < frames), or
        None for no fracture.
    modulus_gpa : float
        Young's modulus E (GPa): the gauge section's engineering stress is E x e_el (module notes, Force).
    hardening : float
        h >= 0: e_el grows linearly with the uniform plastic strain to (1 + h) x 0.004 when the neck
        starts (linear hardening; it changes the displacement, so the images). 0: perfectly plastic.
    thickness_mm, scale_px_per_mm : float
        Thickness of the coupon and the camera's scale: A0 = gauge width (px) / scale x thickness.

    Attributes
    ----------
    x_centre, y_neck, neck_width, gauge_top, gauge_bottom, gauge_half, shoulder_half, y_grip : float
        Geometry in reference pixels (``y_grip`` is the fixed bottom grip line). ``y_neck`` is also
        the reference row of the crack.
    fracture_frame : int or None
    """

    NU_ELASTIC = 0.3
    NU_PLASTIC = 0.5
    YIELD_STRAIN = 0.004
    TAU_YIELD = 0.15
    TAU_NECK = 0.6
    UNLOAD = 0.2           # elastic strain lost outside the neck once it forms (fraction)
    JITTER_PX = 0.03       # grip jitter, standard deviation per frame and axis
    DRIFT_PX = (0.25, 0.15)  # (u, v) drift of both grips over the whole test
    SHEAR_PX = -0.4        # extra sideways drift of the top grip over the whole test
    GAP_START_PX = 3.0     # opening of the crack in the fracture frame
    GAP_RATE_PX = 2.0      # further opening per frame after it
    LATERAL_LAWS = LATERAL_LAWS
    VIEWS = VIEWS

    def __init__(self, shape, frames, *, strain=0.05, neck=0.15, seed=0, lateral="linear", view="grip",
                 fracture_frame=None, modulus_gpa=DEFAULT_MODULUS_GPA, hardening=0.0,
                 thickness_mm=DEFAULT_THICKNESS_MM, scale_px_per_mm=DEFAULT_SCALE_PX_PER_MM):
        H, W = int(shape[0]), int(shape[1])
        self.shape = (H, W)
        self.frames = int(frames)
        self.plastic_strain = float(strain)
        self.neck_strain = float(neck)
        self.seed = int(seed)
        if lateral not in self.LATERAL_LAWS:
            raise ValueError(f"lateral must be one of {', '.join(self.LATERAL_LAWS)}, got {lateral!r}")
        if view not in self.VIEWS:
            raise ValueError(f"view must be one of {', '.join(self.VIEWS)}, got {view!r}")
        if fracture_frame is not None and not 2 <= int(fracture_frame) <= self.frames - 1:
            raise ValueError(f"the fracture frame must be in 2..{self.frames - 1} (frames={self.frames}), "
                             f"got {fracture_frame}")
        for name, value in (("modulus_gpa", modulus_gpa), ("thickness_mm", thickness_mm),
                            ("scale_px_per_mm", scale_px_per_mm)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not (math.isfinite(hardening) and hardening >= 0.0):
            raise ValueError(f"hardening must be a finite number >= 0, got {hardening!r}")
        self.modulus_gpa = float(modulus_gpa)
        self.hardening = float(hardening)
        self.thickness_mm = float(thickness_mm)
        self.scale_px_per_mm = float(scale_px_per_mm)
        self.lateral = lateral
        self.view = view
        self.fracture_frame = None if fracture_frame is None else int(fracture_frame)
        self.x_centre = (W - 1) / 2.0
        self.gauge_half = 0.20 * W
        self.shoulder_half = 0.35 * W
        self.gauge_top = 0.18 * H
        self.gauge_bottom = 0.82 * H
        self.fillet = 0.035 * H        # tanh width of the gauge/shoulder transition (outline)
        self.box_edge = 0.035 * H      # tanh width of the plastic zone's ends (as the fillet)
        self.y_neck = 0.44 * H         # neck centre: 0.06 H above the image centre
        self.neck_width = 0.07 * H     # s in sech^2((Y - Y_n) / s)
        self.y_grip = H - 1.0
        self.area_ratio = self.gauge_half / self.shoulder_half
        rng = np.random.default_rng([self.seed, 2024])
        jitter = rng.normal(0.0, self.JITTER_PX, size=(self.frames, 2))
        jitter[0] = 0.0
        self._jitter = jitter

    # -- schedule ---------------------------------------------------------
    def tau(self, i):
        """Normalised time of the loading schedule: 0 at frame 0, 1 at the last frame before any fracture."""
        if self.fracture_frame is None:
            return i / max(self.frames - 1, 1)
        return min(i, self.fracture_frame - 1) / (self.fracture_frame - 1)

    def fractured(self, i):
        """Whether frame ``i`` shows the specimen broken."""
        return self.fracture_frame is not None and i >= self.fracture_frame

    def state(self, i):
        """Strains and rigid motion of frame ``i`` (a dict of floats; ``gap`` is the crack opening, px)."""
        tau = self.tau(i)
        if tau <= self.TAU_YIELD:
            e_el = self.YIELD_STRAIN * tau / self.TAU_YIELD
            e_pl = 0.0
            e_n = 0.0
            phase = "elastic"
        elif tau <= self.TAU_NECK:
            progress = (tau - self.TAU_YIELD) / (self.TAU_NECK - self.TAU_YIELD)
            e_el = self.YIELD_STRAIN
            if self.hardening:
                # Only with the option, so the default test's frames stay bit for bit as they were.
                e_el = self.YIELD_STRAIN * (1.0 + self.hardening * progress)
            e_pl = self.plastic_strain * (tau - self.TAU_YIELD) / (self.TAU_NECK - self.TAU_YIELD)
            e_n = 0.0
            phase = "plastic"
        else:
            s = (tau - self.TAU_NECK) / (1.0 - self.TAU_NECK)
            e_el = self.YIELD_STRAIN * (1.0 - self.UNLOAD * s)
            if self.hardening:
                e_el = self.YIELD_STRAIN * (1.0 + self.hardening) * (1.0 - self.UNLOAD * s)
            e_pl = self.plastic_strain
            e_n = self.neck_strain * s * s
            phase = "necking"
        u_r = self.DRIFT_PX[0] * tau + self._jitter[i, 0]
        v_r = self.DRIFT_PX[1] * tau + self._jitter[i, 1]
        st = {"frame": int(i), "tau": tau, "phase": phase, "e_el": e_el, "e_pl": e_pl, "e_neck": e_n,
              "u_rigid": u_r, "v_rigid": v_r, "shear_top": self.SHEAR_PX * tau, "gap": 0.0}
        if self.view == "centre":
            # The camera follows the stretch of the loading (frozen from the fracture on).
            st["v_rigid"] = v_r - 0.5 * (self._axial(st, self.gauge_top) + self._axial(st, self.gauge_bottom))
        if self.fractured(i):
            # The load drops to zero: both halves unload elastically; the crack opens.
            st.update(phase="fractured", e_el=0.0,
                      gap=self.GAP_START_PX + self.GAP_RATE_PX * (i - self.fracture_frame))
        return st

    # -- force (module notes, Force) ------------------------------------------
    @property
    def area_mm2(self):
        """A0: the gauge section's initial cross-section, gauge width (px) / scale (px/mm) x thickness (mm)."""
        return 2.0 * self.gauge_half / self.scale_px_per_mm * self.thickness_mm

    def stress_mpa(self, i):
        """Engineering stress of the gauge section in frame ``i`` (MPa): E x e_el, 0 once broken."""
        return self.modulus_gpa * 1e3 * self.state(i)["e_el"]

    def force_n(self, i):
        """Force on the coupon in frame ``i`` (N): stress x A0; 0 from the fracture frame on."""
        return self.stress_mpa(i) * self.area_mm2

    @property
    def specimen(self):
        """The coupon and its exact material law (dict; module notes, Force).

        ``A0_mm2``, ``gauge_width_px``, ``thickness_mm``, ``scale_px_per_mm``, ``E_GPa``,
        ``hardening``, ``yield_MPa`` (E x 0.004), ``Rm_MPa`` (the largest engineering stress:
        yield x (1 + hardening), reached when the neck starts), ``Rp02_MPa`` (stress at 0.2 %
        uniform plastic strain; None when hardening > 0 and the uniform strain stays below 0.2 %)
        and ``yield_strain``.
        """
        sigma_y = self.modulus_gpa * 1e3 * self.YIELD_STRAIN
        if not self.hardening:
            rp02 = sigma_y
        elif self.plastic_strain >= 0.002:
            rp02 = sigma_y * (1.0 + self.hardening * 0.002 / self.plastic_strain)
        else:
            rp02 = None
        return {"A0_mm2": self.area_mm2, "gauge_width_px": 2.0 * self.gauge_half, "thickness_mm": self.thickness_mm,
                "scale_px_per_mm": self.scale_px_per_mm, "E_GPa": self.modulus_gpa, "hardening": self.hardening,
                "yield_strain": self.YIELD_STRAIN, "yield_MPa": sigma_y, "Rp02_MPa": rp02,
                "Rm_MPa": sigma_y * (1.0 + self.hardening)}

    # -- 1-D profiles -----------------------------------------------------
    def _box(self, Y):
        d = self.box_edge
        return 0.5 * (np.tanh((Y - self.gauge_top) / d) - np.tanh((Y - self.gauge_bottom) / d))

    def _box_integral(self, Y):
        d = self.box_edge
        return 0.5 * d * (_logcosh((Y - self.gauge_top) / d) - _logcosh((Y - self.gauge_bottom) / d))

    def half_width(self, Y):
        """Half-width of the undeformed coupon at reference row Y (px)."""
        f = self.fillet
        shoulder = 1.0 + 0.5 * (np.tanh((self.gauge_top - Y) / f) + np.tanh((Y - self.gauge_bottom) / f))
        return self.gauge_half + (self.shoulder_half - self.gauge_half) * shoulder

    def strain_yy(self, i, Y):
        """Exact axial engineering strain dV/dY at reference rows Y for frame ``i`` (away from a crack)."""
        st = self.state(i)
        Y = np.asarray(Y, dtype=np.float64)
        a = self.area_ratio
        g = self._box(Y)
        return (st["e_el"] * (a + (1.0 - a) * g) + st["e_pl"] * g
                + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width))

    def plastic_strain_yy(self, i, Y):
        """The plastic part of the axial strain at reference rows Y for frame ``i`` (never decreases)."""
        st = self.state(i)
        Y = np.asarray(Y, dtype=np.float64)
        return st["e_pl"] * self._box(Y) + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)

    def _antiderivative(self, st, Y):
        a = self.area_ratio
        G = self._box_integral(Y)
        s = self.neck_width
        return (st["e_el"] * (a * Y + (1.0 - a) * G) + st["e_pl"] * G
                + st["e_neck"] * s * np.tanh((Y - self.y_neck) / s))

    def _lateral(self, st, Y):
        """L(Y): lateral contraction factor, dU/dX = -L (the width's stretch is 1 - L)."""
        a = self.area_ratio
        g = self._box(Y)
        if self.lateral == "linear":
            return (self.NU_ELASTIC * st["e_el"] * (a + (1.0 - a) * g)
                    + self.NU_PLASTIC * (st["e_pl"] * g
                                         + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)))
        elastic = self.NU_ELASTIC * st["e_el"] * (a + (1.0 - a) * g)
        plastic = st["e_pl"] * g + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)
        return 1.0 - (1.0 - elastic) / np.sqrt(1.0 + plastic)

    def _axial(self, st, Y):
        """V(Y) without rigid motion: minus the stretch of the material between Y and the grip."""
        return -(self._antiderivative(st, self.y_grip) - self._antiderivative(st, Y))

    def _shear(self, st, Y):
        return st["shear_top"] * (self.y_grip - Y) / self.y_grip

    def displacement(self, i, X, Y):
        """Exact (U, V) of reference points (X, Y) in frame ``i`` (float64 arrays, broadcast).

        Once broken, points with Y < ``y_neck`` belong to the upper half (moved away by the gap).
        """
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64))
        st = self.state(i)
        U = st["u_rigid"] + self._shear(st, Y) - self._lateral(st, Y) * (X - self.x_centre)
        V = st["v_rigid"] + self._axial(st, Y)
        if st["gap"]:
            V = V - st["gap"] * (Y < self.y_neck)
        return U, V

    def crack_faces(self, i):
        """Deformed rows (upper face, lower face) of the crack in frame ``i``; None before the fracture."""
        st = self.state(i)
        if not st["gap"]:
            return None
        lower = self.y_neck + st["v_rigid"] + float(self._axial(st, self.y_neck))
        return lower - st["gap"], lower

    def row_cover(self, i, rows):
        """Fraction of each deformed row's pixel covered by material along y: 1, or less at and in the crack."""
        y = np.asarray(rows, dtype=np.float64)
        faces = self.crack_faces(i)
        if faces is None:
            return np.ones(y.shape)
        upper, lower = faces
        below = np.clip(y + 0.5 - lower, 0.0, 1.0)
        above = np.clip(upper - (y - 0.5), 0.0, 1.0)
        return np.maximum(below, above)

    def _crack_shift(self, st, y):
        """Shift of deformed rows into the lower half's map: the gap for rows of the upper half, else 0."""
        upper = self.y_neck + st["v_rigid"] + float(self._axial(st, self.y_neck)) - st["gap"]
        return st["gap"] * (y < upper + 0.5 * st["gap"])

    def inverse_rows(self, i, rows):
        """For deformed rows y: the reference row Y and the column map X = alpha + beta * x.

        Solves ``y = Y + V(Y)`` by safeguarded Newton (a bracket kept from f' >= 1, bisection when a
        step leaves it) to 1e-12 px, then inverts the row's affine column map ``x = X + U(X, Y)``.
        Once broken, rows above the middle of the crack are mapped through the upper half, the others
        through the lower one (the rows in the crack get ``row_cover`` 0).
        """
        st = self.state(i)
        y = np.asarray(rows, dtype=np.float64)
        if st["gap"]:
            y = y + self._crack_shift(st, y)     # the upper half is the lower half's map shifted by the gap
        Y = y - st["v_rigid"] - self._axial(st, y)   # fixed-point start
        low = np.full(Y.shape, -np.inf)
        high = np.full(Y.shape, np.inf)
        previous = np.full(Y.shape, np.inf)
        for _ in range(100):
            residual = Y + st["v_rigid"] + self._axial(st, Y) - y
            slope = 1.0 + self.strain_yy(i, Y)
            size = np.abs(residual)
            # f(Y) = Y + V(Y) - y has f' = 1 + e_yy >= 1, so the root lies within |f(Y)| of Y.
            high = np.where(residual > 0.0, np.minimum(high, Y), np.minimum(high, Y - residual))
            low = np.where(residual > 0.0, np.maximum(low, Y - residual), np.maximum(low, Y))
            step = Y - residual / slope
            # Bisect where Newton leaves the bracket or fails to halve the residual (a cycle, at very large
            # strain); never near the root, where rounding sets the residual and Newton's step is kept.
            bisect = ((step <= low) | (step >= high) | (size > 0.5 * previous)) & (size > 1e-9)
            Y = np.where(bisect, 0.5 * (low + high), step)
            previous = size
            if np.max(size) < 1e-12:
                break
        else:
            residual = Y + st["v_rigid"] + self._axial(st, Y) - y
            if np.max(np.abs(residual)) > 1e-9 * max(1.0, float(np.max(np.abs(y)))):  # pragma: no cover
                raise SourceError("tensile model: could not invert the axial displacement")
        L = self._lateral(st, Y)
        offset = st["u_rigid"] + self._shear(st, Y)
        # x = X + offset - L (X - xc)  ->  X = xc + (x - offset - xc) / (1 - L)
        beta = 1.0 / (1.0 - L)
        alpha = self.x_centre - (offset + self.x_centre) * beta
        return Y, alpha, beta

    def nominal_strain(self, i):
        """Mean axial strain over the gauge section (what an extensometer would read; with the crack's gap)."""
        st = self.state(i)
        top, bottom = self.gauge_top, self.gauge_bottom
        return float((self._antiderivative(st, bottom) - self._antiderivative(st, top) + st["gap"])
                     / (bottom - top))

    def visible(self, i, X, Y, half_width=0.0):
        """Whether the square subset of half-width ``half_width`` around each reference point (X, Y) is fully seen.

        True where the subset is all specimen (inside the coupon's outline), on one side of the crack
        (from the fracture on: Y - d >= ``y_neck`` or Y + d < ``y_neck``) and, in the reference and in
        frame ``i``, inside the image (pixel centres 0..W-1, 0..H-1).
        """
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64))
        d = float(half_width)
        H, W = self.shape
        edge = np.minimum(np.minimum(self.half_width(Y - d), self.half_width(Y)), self.half_width(Y + d))
        seen = np.abs(X - self.x_centre) + d <= edge
        if self.fractured(i):
            seen &= (Y - d >= self.y_neck) | (Y + d < self.y_neck)
        for frame in (0, i):
            # U is affine in X on a row and V depends on Y alone: the corners bound the deformed subset.
            for dy in (-d, d):
                for dx in (-d, d):
                    u, v = self.displacement(frame, X + dx, Y + dy)
                    x, y = X + dx + u, Y + dy + v
                    seen &= (x >= 0.0) & (x <= W - 1.0) & (y >= 0.0) & (y <= H - 1.0)
        return seen


class FrameTruth:
    """Exact displacement of reference points in one frame: ``truth(x, y) -> (u, v)`` arrays.

    ``truth.visible(x, y, half_width)`` says which reference points' subsets are fully seen in
    that frame (the source's ``visible``; all of them when the source gives none).
    """

    def __init__(self, function, frame_index, description, visible=None):
        self._function = function
        self._visible = visible
        self.frame_index = int(frame_index)
        self.description = description

    def __call__(self, x, y):
        return self._function(self.frame_index, x, y)

    def visible(self, x, y, half_width=0.0):
        """Boolean array: the subset of half-width ``half_width`` px around each reference point is fully seen."""
        if self._visible is None:
            return np.ones(np.broadcast(np.asarray(x), np.asarray(y)).shape, dtype=bool)
        return self._visible(self.frame_index, x, y, half_width)

    def __repr__(self):
        return f"FrameTruth({self.description}, frame={self.frame_index})"


# --------------------------------------------------------------------------- #
# Rendering kernels
# --------------------------------------------------------------------------- #

@njit(cache=True)
def _row_intensity(xs, ys, amp, inv_r, reach2, delta, q, Yr, a, b, lo, hi, c_lo, c_hi, acc):
    """acc[c - c_lo] = sum_k amp_k exp(-((a + b c - x_k)^2 + (Yr - y_k)^2) / R^2) over |d| < reach.

    Centres k in [lo, hi) (those within reach of the row); ``amp`` is 1 for
    every spot of unfaded paint (an exact product: the sum is then bit for bit
    the plain one). Along the row the
    Gaussian is stepped by the exact recurrence g(c+1) = g(c) s(c),
    s(c+1) = s(c) q with q = exp(-2 delta^2), delta = b / R: two exp per spot,
    relative rounding drift below 1e-14 over a spot's width.
    """
    for c in range(c_hi - c_lo):
        acc[c] = 0.0
    inv_r2 = inv_r * inv_r
    for k in range(lo, hi):
        dy = ys[k] - Yr
        d2y = dy * dy
        if d2y >= reach2:
            continue
        half = math.sqrt(reach2 - d2y)
        xk = xs[k]
        # columns with (a + b c - xk)^2 < half^2
        first = max(int(math.floor((xk - half - a) / b)) + 1, c_lo)
        last = min(int(math.ceil((xk + half - a) / b)) - 1, c_hi - 1)
        if last < first:
            continue
        t = (a + b * first - xk) * inv_r
        g = amp[k] * math.exp(-(t * t + d2y * inv_r2))
        step = math.exp(-(2.0 * t * delta + delta * delta))
        for c in range(first - c_lo, last - c_lo + 1):
            acc[c] += g
            g *= step
            step *= q


@njit(cache=True, parallel=True)
def _render_rows(xs, ys, radius, reach, Y, alpha, beta, col_lo, col_hi, out):
    """Zhou-Goodson intensity sampled at X = alpha_r + beta_r c, Y = Y_r (float64 out, (H, W)).

    ``ys`` sorted ascending; only columns col_lo[r] <= c < col_hi[r] are written.
    Equal (to rounding) to ``SpecklePattern.intensity`` at the same points.
    """
    H, W = out.shape
    inv_r = 1.0 / radius
    reach2 = reach * reach
    amp = np.ones(xs.shape[0])
    for r in prange(H):
        c_lo, c_hi = col_lo[r], col_hi[r]
        if c_hi <= c_lo:
            continue
        delta = beta[r] * inv_r
        lo = np.searchsorted(ys, Y[r] - reach)
        hi = np.searchsorted(ys, Y[r] + reach, side="right")
        _row_intensity(xs, ys, amp, inv_r, reach2, delta, math.exp(-2.0 * delta * delta), Y[r], alpha[r], beta[r],
                       lo, hi, c_lo, c_hi, out[r, c_lo:c_hi])


@njit(cache=True, parallel=True)
def _render_specimen(xs, ys, amp, radius, reach, Y, alpha, beta, left, right, row_cover, background, full, floor,
                     gain, out):
    """Grey image (float32 out, (H, W)) of the coupon: painted speckle inside [left, right], background outside.

    Each row r: background[r] everywhere, blended towards the paint
    ``full (floor + gain exp(-I))`` by the pixel's coverage of the specimen
    (1 px linear ramp at the deformed edges ``left[r]``, ``right[r]``, times
    ``row_cover[r]``: 1, or less at a crack face, 0 in the crack). Spot k's
    optical density is scaled by ``amp[k]`` (1: unfaded).
    """
    H, W = out.shape
    inv_r = 1.0 / radius
    reach2 = reach * reach
    for r in prange(H):
        bg = background[r]
        for c in range(W):
            out[r, c] = bg
        rc = row_cover[r]
        if rc <= 0.0:
            continue
        c_lo = max(int(math.floor(left[r])) - 1, 0)
        c_hi = min(int(math.ceil(right[r])) + 2, W)
        if c_hi <= c_lo:
            continue
        acc = np.empty(c_hi - c_lo)
        delta = beta[r] * inv_r
        lo = np.searchsorted(ys, Y[r] - reach)
        hi = np.searchsorted(ys, Y[r] + reach, side="right")
        _row_intensity(xs, ys, amp, inv_r, reach2, delta, math.exp(-2.0 * delta * delta), Y[r], alpha[r], beta[r],
                       lo, hi, c_lo, c_hi, acc)
        for c in range(c_lo, c_hi):
            cover = min(c - left[r], right[r] - c) + 0.5
            if cover <= 0.0:
                continue
            if cover > 1.0:
                cover = 1.0
            cover *= rc
            paint = full * (floor + gain * math.exp(-acc[c - c_lo]))
            out[r, c] = bg + cover * (paint - bg)


@njit(cache=True, parallel=True)
def _quantise_into(image, noise, sigma, full, out):
    """out = rint(clip(image + sigma * noise, 0, full)) (noise may be empty for none)."""
    H, W = image.shape
    with_noise = noise.shape[0] == H
    for r in prange(H):
        for c in range(W):
            value = image[r, c]
            if with_noise:
                value += sigma * noise[r, c]
            if value < 0.0:
                value = 0.0
            elif value > full:
                value = full
            out[r, c] = np.rint(value)


def _paint(intensity, full):
    """Grey level of speckled paint for the Zhou-Goodson intensity (float)."""
    return full * (PAINT_FLOOR + PAINT_GAIN * np.exp(-intensity))


def _quantise(image, bit, noise_sigma, noise_seed):
    """Add camera noise (seeded), clip and round to Mono8 / Mono12."""
    full = _FULL_SCALE[bit]
    out = np.empty(image.shape, dtype=np.uint8 if bit == 8 else np.uint16)
    if noise_sigma > 0.0:
        noise = np.random.default_rng(noise_seed).standard_normal(image.shape, dtype=np.float32)
    else:
        noise = np.empty((0, 0), dtype=np.float32)
    _quantise_into(np.ascontiguousarray(image, dtype=np.float32), noise, np.float32(noise_sigma),
                   np.float32(full), out)
    return out


# --------------------------------------------------------------------------- #
# Sources
# --------------------------------------------------------------------------- #

class _PrerenderedSource(FrameSource):
    """Renders every frame ahead (``prepare``), then delivers them paced at ``fps``."""

    model_name = ""

    def __init__(self, options, uri):
        self.options = options
        self.uri = uri
        width, height = options["size"]
        self.shape = (height, width)
        self.frames = options["frames"]
        self.rendered_frames = _rendered_count(options)
        self.fps = options["fps"]
        self.bit = options["bit"]
        self.pixel_format = _PIXEL_FORMAT[self.bit]
        nbytes = self.rendered_frames * width * height * (1 if self.bit == 8 else 2)
        if nbytes > MAX_RENDER_BYTES:
            raise SourceError(
                f"{uri}: {self.rendered_frames} frames of {width}x{height} at {self.bit} bit need "
                f"{nbytes / 2**30:.1f} GiB rendered ahead (limit {MAX_RENDER_BYTES / 2**30:.0f} GiB): "
                "lower frames= or size=, or render fewer and cycle them with loop=K")
        self._images = None
        self._lock = threading.Lock()
        self._closed = False
        self.render_seconds = None
        from livedic.dic.speckle import SpecklePattern
        self.pattern = SpecklePattern(self.shape, density=SPECKLE_DENSITY, radius=options["radius"],
                                      seed=options["seed"], margin=self._pattern_margin())

    def _pattern_margin(self):
        return None

    @property
    def live(self):
        return bool(self.options.get("pace", True))     # paced: a simulated camera

    @property
    def full_scale(self):
        return _FULL_SCALE[self.bit]

    def _noise_sigma(self):
        return self.options["noise"] * self.full_scale / 255.0

    def prepare(self, progress=None):
        """Render the frames into memory (idempotent); ``progress(done, total)`` after each.

        ``rendered_frames`` of them: all ``frames``, or ``loop`` when cycling.
        """
        with self._lock:
            if self._images is not None:
                return
            start = time.perf_counter()
            images = []
            for i in range(self.rendered_frames):
                if self._closed:
                    raise SourceError(f"{self.uri}: closed while rendering")
                images.append(self._render(i))
                if progress is not None:
                    progress(i + 1, self.rendered_frames)
            self._images = images
            self.render_seconds = time.perf_counter() - start

    def rendered_index(self, i):
        """The rendered frame delivered as frame ``i``: ``i``, or its place in the forward-back cycle (loop)."""
        k = self.rendered_frames
        if k >= self.frames:
            return i
        m = i % (2 * (k - 1))
        return m if m < k else 2 * (k - 1) - m

    def _check_index(self, frame_index):
        if not 0 <= frame_index < self.frames:
            raise ValueError(f"frame index {frame_index} outside 0..{self.frames - 1}")
        return self.rendered_index(frame_index)

    def frame_metadata(self, i):
        return {"synthetic": self.model_name,
                "truth": FrameTruth(self.truth, i, f"synthetic:{self.model_name}", visible=self.visible)}

    def visible(self, frame_index, x, y, half_width=0.0):
        """Whether the square subset of half-width ``half_width`` px around each reference point (x, y)
        lies inside the image in the reference and in frame ``frame_index`` (boolean array)."""
        j = self._check_index(frame_index)
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        H, W = self.shape
        d = float(half_width)
        seen = np.ones(x.shape, dtype=bool)
        for dy in (-d, d):
            for dx in (-d, d):
                u, v = self.truth(j, x + dx, y + dy)
                for px, py in ((x + dx, y + dy), (x + dx + u, y + dy + v)):
                    seen &= (px >= 0.0) & (px <= W - 1.0) & (py >= 0.0) & (py <= H - 1.0)
        return seen

    def __iter__(self):
        self.prepare()
        period_ns = 1e9 / self.fps
        start_ns = time.monotonic_ns()
        for i in range(self.frames):
            image = self._images[self.rendered_index(i)]
            if self._closed:
                return
            metadata = self.frame_metadata(i)
            if i == 1:
                # the clock starts when the second frame is asked for: a session takes the first (its
                # reference) and prepares (points, outputs) before it asks for more, as a camera is started
                # when its consumer is ready; pacing from the first would hand the frames due meanwhile out
                # in a burst, which a dropping queue drops
                start_ns = time.monotonic_ns() - int(round(period_ns))
            if self.options["pace"]:
                due = start_ns + int(round(i * period_ns))
                wait = due - time.monotonic_ns()
                if wait > 0:
                    time.sleep(wait / 1e9)
                metadata["capture_monotonic_ns"] = due
            yield Frame(index=i, timestamp_ns=int(round(i * period_ns)), image=image,
                        pixel_format=self.pixel_format, metadata=metadata)

    def close(self):
        self._closed = True

    @property
    def settings(self):
        width, height = self.options["size"]
        settings = {key: value for key, value in self.options.items() if key != "size"}
        settings.update({"model": self.model_name, "width": width, "height": height,
                         "pixel_format": self.pixel_format, "uri": self.uri,
                         "delivery": "rendered ahead, paced at fps" if self.options["pace"]
                         else "rendered ahead, as fast as read"})
        if self.rendered_frames < self.frames:
            settings["delivery"] += f"; {self.rendered_frames} rendered frames cycled forward and back"
        return settings


class SyntheticTensileSource(_PrerenderedSource):
    """Simulated tensile test of a speckled dog-bone coupon (module notes), exact truth.

    Parameters
    ----------
    uri : str, optional
        ``synthetic:tensile?...``; keyword options override the URI's.
    **options
        frames, fps, size (W, H) or "WxH", bit, noise, seed, radius, pace, loop, strain, neck, lateral,
        view, fade, fracture, modulus, thickness, scale, hardening.

    Attributes
    ----------
    model : TensileModel
    suggested_roi : tuple of int, (x, y, w, h)
        The gauge section, inset so subsets stay on the specimen while it narrows.
    fracture_frame : int or None
        The first frame showing the specimen broken (``fracture`` option), None without one.
    specimen : dict
        A0 (mm^2), scale, E and the exact yield, Rp0.2 and Rm (``TensileModel.specimen``).
    """

    model_name = "tensile"

    def __init__(self, uri="synthetic:tensile", **options):
        model, raw = parse_synthetic_uri(uri)
        if model != "tensile":
            raise SourceError(f"{uri!r} is not a tensile URI: use synthetic:tensile?...")
        raw.update({k: v for k, v in options.items() if v is not None})
        opts = _resolve_tensile_options(_convert_options("tensile", raw))
        fracture = opts["fracture"] or None
        self.model = TensileModel((opts["size"][1], opts["size"][0]), _rendered_count(opts), strain=opts["strain"],
                                  neck=opts["neck"], seed=opts["seed"], lateral=opts["lateral"], view=opts["view"],
                                  fracture_frame=fracture, modulus_gpa=opts["modulus"], hardening=opts["hardening"],
                                  thickness_mm=opts["thickness"], scale_px_per_mm=opts["scale"])
        self.fracture_frame = fracture
        super().__init__(opts, uri)
        self._rows = np.arange(self.shape[0], dtype=np.float64)
        H = self.shape[0]
        self._background = BACKGROUND_LEVEL * (1.0 + 0.15 * (self._rows / H - 0.5))
        self._xs = np.ascontiguousarray(self.pattern.centres[:, 0])
        self._ys = np.ascontiguousarray(self.pattern.centres[:, 1])
        self._unfaded = np.ones(self._xs.shape[0])
        # Each speckle fades at its own rate (uniform 0..2 x the mean): the pattern changes, not only its contrast.
        self._fade_rates = (np.random.default_rng([opts["seed"], _FADE_SEED]).uniform(0.0, 2.0, self._xs.shape[0])
                            if opts["fade"] > 0.0 else None)

    @property
    def suggested_roi(self):
        m = self.model
        inset = 0.15 * m.gauge_half + 8.0
        x0 = int(math.ceil(m.x_centre - m.gauge_half + inset))
        x1 = int(math.floor(m.x_centre + m.gauge_half - inset))
        y0 = int(math.ceil(m.gauge_top))
        y1 = int(math.floor(m.gauge_bottom))
        return (x0, y0, x1 - x0 + 1, y1 - y0 + 1)

    def truth(self, frame_index, x, y):
        """Exact (u, v) at reference points (x, y) in frame ``frame_index``."""
        return self.model.displacement(self._check_index(frame_index), x, y)

    def force_N(self, frame_index):  # noqa: N802 (the unit is part of the name, as in force_N columns)
        """Force on the coupon in frame ``frame_index`` (N): E x e_el x A0, 0 from the fracture frame on."""
        return self.model.force_n(self._check_index(frame_index))

    def forces_N(self):  # noqa: N802
        """Force (N) of every delivered frame 0 .. frames - 1 (float64 array; cycled with ``loop``)."""
        rendered = np.array([self.model.force_n(j) for j in range(self.rendered_frames)])
        k = self.rendered_frames
        index = np.arange(self.frames)
        if k < self.frames:
            cycle = index % (2 * (k - 1))
            index = np.where(cycle < k, cycle, 2 * (k - 1) - cycle)
        return rendered[index]

    @property
    def specimen(self):
        return self.model.specimen

    def visible(self, frame_index, x, y, half_width=0.0):
        """Whether the square subset of half-width ``half_width`` px around each reference point (x, y) is
        fully seen in frame ``frame_index``: all specimen, on one side of the crack (once broken), inside
        the image in the reference and in that frame (boolean array; ``TensileModel.visible``)."""
        return self.model.visible(self._check_index(frame_index), x, y, half_width)

    def frame_metadata(self, i):
        meta = super().frame_metadata(i)
        j = self.rendered_index(i)
        st = self.model.state(j)
        meta.update({"phase": st["phase"], "nominal_strain": self.model.nominal_strain(j),
                     "force_N": self.model.force_n(j)})
        if self.fracture_frame is not None:
            meta["fracture_frame"] = self.fracture_frame
        return meta

    def fade_amplitudes(self, i):
        """Optical density factor of every speckle in frame ``i``: 1 - fade r_k e_p(y_k) / (strain + neck), >= 0.

        ``r_k`` is the spot's seeded rate (uniform 0..2), ``e_p(y_k)`` the plastic strain at its centre's
        reference row; all ones without ``fade``.
        """
        fade = self.options["fade"]
        peak = self.model.plastic_strain + self.model.neck_strain
        if self._fade_rates is None or peak <= 0.0:
            return self._unfaded
        damage = self.model.plastic_strain_yy(i, self._ys) / peak
        return np.maximum(1.0 - fade * self._fade_rates * damage, 0.0)

    def _render(self, i):
        full = float(self.full_scale)
        Y, alpha, beta = self.model.inverse_rows(i, self._rows)
        hw = self.model.half_width(Y)
        # Deformed columns of the specimen edges on each row (X = xc -+ hw).
        left = (self.model.x_centre - hw - alpha) / beta
        right = (self.model.x_centre + hw - alpha) / beta
        row_cover = self.model.row_cover(i, self._rows)
        image = np.empty(self.shape, dtype=np.float32)
        _render_specimen(self._xs, self._ys, self.fade_amplitudes(i), float(self.pattern.radius),
                         float(self.pattern.cutoff_px), Y, alpha, beta, left, right, row_cover,
                         full * self._background, full, PAINT_FLOOR, PAINT_GAIN, image)
        return _quantise(image, self.bit, self._noise_sigma(), self.options["seed"] * 1_000_003 + i + 1)


class SyntheticTranslateSource(_PrerenderedSource):
    """Speckle over the whole image, shifted by ``(du, dv)`` px per frame plus an optional jump.

    ``truth(i, x, y)`` is the same (u, v) for every point: ``(i du, i dv)``, plus
    ``(U, V)`` from frame F on when ``jump=F:U:V``.
    """

    model_name = "translate"

    def __init__(self, uri="synthetic:translate", **options):
        model, raw = parse_synthetic_uri(uri)
        if model != "translate":
            raise SourceError(f"{uri!r} is not a translate URI: use synthetic:translate?...")
        raw.update({k: v for k, v in options.items() if v is not None})
        opts = _convert_options("translate", raw)
        self._opts_for_margin = opts
        super().__init__(opts, uri)

    def _pattern_margin(self):
        opts = self._opts_for_margin
        n = _rendered_count(opts) - 1
        extent = max(abs(opts["du"]), abs(opts["dv"])) * n
        if opts["jump"] is not None:
            extent += max(abs(opts["jump"][1]), abs(opts["jump"][2]))
        reach = 5.0 * opts["radius"]
        return math.ceil(reach) + 16 + math.ceil(extent)

    def shift(self, frame_index):
        """(u, v) of every point in frame ``frame_index``."""
        u = frame_index * self.options["du"]
        v = frame_index * self.options["dv"]
        jump = self.options["jump"]
        if jump is not None and frame_index >= jump[0]:
            u += jump[1]
            v += jump[2]
        return u, v

    def truth(self, frame_index, x, y):
        j = self._check_index(frame_index)
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        u, v = self.shift(j)
        return np.full(x.shape, u), np.full(y.shape, v)

    @property
    def suggested_roi(self):
        H, W = self.shape
        margin = 32
        return (margin, margin, W - 2 * margin, H - 2 * margin)

    def _render(self, i):
        from livedic.dic.speckle import render
        u, v = self.shift(i)
        intensity = render(self.pattern, (u, v) if (u or v) else None, bit_depth=None)
        image = _paint(intensity, float(self.full_scale)).astype(np.float32)
        return _quantise(image, self.bit, self._noise_sigma(), self.options["seed"] * 1_000_003 + i + 1)


def open_synthetic(uri, **options):
    """The source named by ``uri``: ``synthetic:``, ``synthetic:tensile?...`` or ``synthetic:translate?...``."""
    model, _ = parse_synthetic_uri(uri)
    if model == "translate":
        return SyntheticTranslateSource(uri, **options)
    return SyntheticTensileSource(uri, **options)
