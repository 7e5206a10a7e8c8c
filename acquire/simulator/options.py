"""The simulator's URIs: ``synthetic:tensile?...``, ``synthetic:translate?...`` and ``synthetic:stereo?...`` parsed
into typed options.

Every option, its default and its check is declared here once (``TENSILE_DEFAULTS``, ``TRANSLATE_DEFAULTS``,
``STEREO_DEFAULTS``);
a bad value is one ``SourceError`` line naming the option. The options' meaning: docs/guide/sources.md.
"""

from __future__ import annotations

import math
import urllib.parse
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

from livedic.acquire.base import SourceError
from livedic.acquire.options import parse_bool, parse_number

MODELS = ("tensile", "translate", "stereo")
FULL_SCALE = {8: 255, 12: 4095}

# The force law's defaults (docs/guide/sources.md, Force): a steel-like modulus, a 2 mm sheet, 10 px per mm.
DEFAULT_MODULUS_GPA = 200.0
DEFAULT_THICKNESS_MM = 2.0
DEFAULT_SCALE_PX_PER_MM = 10.0
# The simulated lens (docs/guide/calibration.md): OpenCV's distortion k1, k2, p1, p2 of a pinhole camera with
# focal length LENS_FOCAL_WIDTHS x the image width (a normal lens) and the principal point at the image centre.
LENS_FOCAL_WIDTHS = 1.0
LENS_OPTIONS = ("k1", "k2", "p1", "p2")
# static: frames after the reference with only the camera's noise (the session's --static-frames sets it).
_COMMON_DEFAULTS = {"fps": 50.0, "bit": 8, "noise": 1.0, "seed": 0, "radius": 4.0, "pace": True, "loop": 0,
                    "static": 0, "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0}
TENSILE_DEFAULTS = dict(_COMMON_DEFAULTS, frames=300, size=(1024, 1024), strain=0.05, neck=0.15, lateral="auto",
                        view="auto", fade=0.0, fracture=0, modulus=DEFAULT_MODULUS_GPA,
                        thickness=DEFAULT_THICKNESS_MM, scale=DEFAULT_SCALE_PX_PER_MM, hardening=0.0,
                        upper_yield=0.0)
# Laws of the lateral contraction and camera views of the tensile test (docs/guide/sources.md).
LATERAL_LAWS = ("linear", "incompressible")
VIEWS = ("grip", "centre")
# Up to these (the default test's), ``lateral=auto`` and ``view=auto`` keep the small-strain model.
SMALL_STRAIN_LIMITS = {"strain": 0.05, "neck": 0.15}
TRANSLATE_DEFAULTS = dict(_COMMON_DEFAULTS, frames=100, size=(512, 512), du=0.3, dv=-0.2, jump=None)
# The stereo coupon (docs/guide/sources.md, "The stereo test"): one camera of a rig `angle` degrees apart, both
# `distance` mm from the coupon, focal length `focal` px (a 50 mm lens on a 1 MP camera), mild barrel distortion;
# `strain`, `neck` (extra strain at the neck's centre), `w0` (mm, + away from the cameras), `rotx`, `roty`
# (degrees) reached at the last frame; `facing`: the coupon's normal bisects the cameras or faces the left one.
STEREO_VIEWS = ("left", "right")
STEREO_FACINGS = ("middle", "left")
STEREO_DEFAULTS = dict(_COMMON_DEFAULTS, frames=100, size=(1024, 1024), k1=-0.05, view="left", strain=0.01,
                       neck=0.02, w0=0.0, rotx=0.0, roty=0.0, distance=300.0, angle=25.0, focal=8000.0,
                       thickness=DEFAULT_THICKNESS_MM, facing="middle", supersample=1)
_MODEL_DEFAULTS: dict[str, dict[str, Any]] = {"tensile": TENSILE_DEFAULTS, "translate": TRANSLATE_DEFAULTS, "stereo": STEREO_DEFAULTS}


# --------------------------------------------------------------------------- #
# URI parsing
# --------------------------------------------------------------------------- #

def _usage() -> str:
    return ("synthetic:tensile?frames=300&fps=50&size=1024x1024&bit=8&noise=1.0&seed=0&radius=4&pace=1"
            "&loop=0&static=0&strain=0.05&neck=0.15&lateral=auto&view=auto&fade=0&fracture=0"
            "&modulus=200&thickness=2&scale=10&hardening=0&upper_yield=0&k1=0&k2=0&p1=0&p2=0, "
            "or synthetic:translate?frames=100&du=0.3&dv=-0.2&jump=40:6:0, "
            "or synthetic:stereo?view=left|right&frames=100&strain=0.01&neck=0.02&w0=0&rotx=0&roty=0"
            "&distance=300&angle=25&focal=8000&facing=middle&supersample=1 "
            "(same common options)")


def parse_synthetic_uri(uri: str) -> tuple[str, dict[str, str]]:
    """Split ``synthetic:MODEL?k=v&...`` into (model, {option: text}); raises SourceError."""
    if not isinstance(uri, str) or not uri.startswith("synthetic:"):
        raise SourceError(f"not a synthetic source URI: {uri!r}; use {_usage()}")
    rest = uri[len("synthetic:"):]
    model, _, query = rest.partition("?")
    model = model.strip("/") or "tensile"
    if model not in MODELS:
        raise SourceError(f"unknown synthetic model {model!r} in {uri!r}: choose one of {', '.join(MODELS)} "
                          f"(e.g. {_usage()})")
    options: dict[str, str] = {}
    if query:
        for part in query.split("&"):
            if not part:
                continue
            key, sep, value = part.partition("=")
            if not sep:
                raise SourceError(f"option {part!r} in {uri!r} has no value: write NAME=VALUE, e.g. frames=300")
            options[urllib.parse.unquote(key).strip()] = urllib.parse.unquote(value).strip()
    return model, options


def convert_options(model: str, raw: Mapping[str, Any]) -> dict[str, Any]:
    """Typed options for ``model`` from text or Python values; SourceError names the bad one."""
    defaults = _MODEL_DEFAULTS[model]
    unknown = sorted(set(raw) - set(defaults))
    if unknown:
        raise SourceError(f"unknown option(s) {', '.join(unknown)} for synthetic:{model}: valid options are "
                          f"{', '.join(sorted(defaults))}")
    out = dict(defaults)
    for key, value in raw.items():
        if value is None:
            continue
        try:
            converter = _MODEL_CONVERTERS.get(model, {}).get(key) or _CONVERTERS[key]
            out[key] = converter(value)
        except (TypeError, ValueError) as error:
            raise SourceError(f"synthetic:{model} option {key}={value!r}: {error}") from None
    if out["loop"] == 1:
        raise SourceError(f"synthetic:{model} option loop=1: must be 0 (off) or the number of frames to "
                          "render and cycle through (>= 2)")
    return out


def resolve_tensile_options(options: Mapping[str, Any]) -> dict[str, Any]:
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
    if fracture and rendered_count(out) < frames:
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


def rendered_count(options: Mapping[str, Any]) -> int:
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
    if bit not in FULL_SCALE:
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


def _to_lens_term(value, *, limit):
    """A distortion coefficient within +-limit (beyond it the simulated lens folds the image's corners)."""
    number = parse_number(value)
    if abs(number) > limit:
        raise ValueError(f"must be within -{limit:g}..{limit:g}")
    return number


_INT = partial(parse_number, integer=True)
_CONVERTERS = {
    "frames": partial(_INT, low=2), "fps": partial(parse_number, low=0, low_open=True), "size": _to_size,
    "bit": _to_bit, "noise": partial(parse_number, low=0), "seed": partial(_INT, low=0),
    "radius": partial(parse_number, low=0.5), "pace": parse_bool, "loop": partial(_INT, low=0),
    "static": partial(_INT, low=0),
    "strain": partial(parse_number, low=0), "neck": partial(parse_number, low=0), "du": parse_number,
    "dv": parse_number, "jump": _to_jump, "lateral": _to_choice(("auto",) + LATERAL_LAWS),
    "view": _to_choice(("auto",) + VIEWS), "fade": _to_fade, "fracture": _to_fracture,
    "modulus": partial(parse_number, low=0, low_open=True), "thickness": partial(parse_number, low=0, low_open=True),
    "scale": partial(parse_number, low=0, low_open=True), "hardening": partial(parse_number, low=0),
    "upper_yield": partial(parse_number, low=0),
    "k1": partial(_to_lens_term, limit=0.5), "k2": partial(_to_lens_term, limit=0.5),
    "p1": partial(_to_lens_term, limit=0.05), "p2": partial(_to_lens_term, limit=0.05),
}


def _to_range(value, *, low, high):
    """A number strictly between ``low`` and ``high``."""
    number = parse_number(value)
    if not low < number < high:
        raise ValueError(f"must be between {low:g} and {high:g}")
    return number


def _to_supersample(value):
    """Samples per pixel along each axis: 1 (the pixel's centre) to 4."""
    number = parse_number(value, integer=True)
    if not 1 <= number <= 4:
        raise ValueError("must be 1 (the pixel's centre) to 4 (4 x 4 samples averaged)")
    return number


def _to_neck(value):
    number = parse_number(value, low=0)
    if number >= 1.0:
        raise ValueError("must be in [0, 1): the extra axial strain at the neck's centre in the last frame")
    return number


# Options of one model whose name another model uses for something else (the stereo test's ``view``, ``strain``,
# ``neck``) or that only it has.
_MODEL_CONVERTERS: dict[str, dict[str, Callable[[Any], Any]]] = {
    "stereo": {
        "view": _to_choice(STEREO_VIEWS), "facing": _to_choice(STEREO_FACINGS),
        "strain": partial(_to_range, low=-0.5, high=1.0), "neck": _to_neck,
        "w0": partial(_to_range, low=-50.0, high=50.0), "rotx": partial(_to_range, low=-30.0, high=30.0),
        "roty": partial(_to_range, low=-30.0, high=30.0), "distance": partial(_to_range, low=20.0, high=1e5),
        "angle": partial(_to_range, low=0.0, high=90.0), "focal": partial(parse_number, low=0, low_open=True),
        "supersample": _to_supersample,
    },
}
