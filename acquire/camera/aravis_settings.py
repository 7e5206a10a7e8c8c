"""The camera settings an ``AravisCamera`` declares (``SETTINGS``): each option parsed, checked against the
camera's bounds, applied and read back, with the default that gives a known state. Their functions take the
open camera (``source._camera``, ``source._call``).
"""

import ipaddress
from dataclasses import dataclass
from typing import Callable

from livedic.acquire.base import SourceError
from livedic.acquire.camera import genicam
from livedic.acquire.camera import pixel_formats
from livedic.acquire.camera.aravis_discovery import is_ip_address, load_aravis
from livedic.acquire.options import as_float, as_int

__all__ = ["SETTINGS", "SUPPORTED_PIXEL_FORMATS", "Setting"]

# The formats livedic reads, by GenICam name (acquire.camera.pixel_formats).
SUPPORTED_PIXEL_FORMATS = tuple(pixel_formats.FORMATS)
# GigE packet size on the loopback address (a simulator) unless asked: a full 2048x2048 Mono8 frame from
# arv-fake-gv-camera-0.8 came at 12 fps with its 1400-byte default and 24-25 fps (its 25 fps) with 9000.
_LOOPBACK_PACKET_SIZE = 9000
NO_USER_SET = "none"            # user_set=none: load no user set


# --------------------------------------------------------------------------- #
# Option parsing (strings from URIs, values from Python)
# --------------------------------------------------------------------------- #

def _as_roi(name, value):
    if isinstance(value, str):
        parts = [p for p in value.replace("x", ",").replace(" ", ",").split(",") if p]
    else:
        try:
            parts = list(value)
        except TypeError:
            parts = [value]
    if len(parts) != 4:
        raise SourceError(f"option {name}={value!r} must be 4 integers x,y,w,h")
    x, y, w, h = (as_int(name, p) for p in parts)
    if x < 0 or y < 0 or w <= 0 or h <= 0:
        raise SourceError(f"option {name}={value!r}: need x >= 0, y >= 0, w > 0, h > 0")
    return (x, y, w, h)


def _as_binning(name, value):
    parts = [p for p in str(value).replace("x", ",").split(",") if p.strip()] if isinstance(value, str) \
        else list(value) if isinstance(value, (tuple, list)) else [value]
    if len(parts) not in (1, 2):
        raise SourceError(f"option {name}={value!r}: write H or H,V (pixels binned across, down)")
    numbers = [as_int(name, p, low=1) for p in parts]
    return (numbers[0], numbers[-1])


def _as_pixel_format(name, value):
    fmt = pixel_formats.by_name(value)
    if fmt is None:
        raise SourceError(f"pixel format {str(value).strip()!r} is not supported: livedic reads "
                          f"{', '.join(SUPPORTED_PIXEL_FORMATS)} (10 to 16 bits as uint16)")
    return fmt.name


def as_user_set(name: str, value: object) -> str:
    text = str(value).strip()
    if not text:
        raise SourceError(f"option {name}=: name a user set (e.g. Default, UserSet1) or none")
    return NO_USER_SET if text.lower() == NO_USER_SET else text


# --------------------------------------------------------------------------- #
# Declared settings
# --------------------------------------------------------------------------- #

@dataclass(frozen=True)
class Setting:
    """A camera setting: parsed, checked against bounds, applied, then read back.

    ``default(source)`` is what an open sets when the option is not given (the known
    state), None to leave the camera's value (after its user set).
    """
    name: str
    parse: Callable
    apply: Callable      # apply(source, value) -> None, raises SourceError with bounds
    read: Callable       # read(source) -> value actually in use
    doc: str
    default: Callable = lambda source: None


def _check_range(name, value, low, high, unit):
    if not (low <= value <= high):
        raise SourceError(f"{name}={value:g} is outside this camera's range [{low:g}, {high:g}] {unit}".rstrip())


def _offered_pixel_formats(source):
    return list(source._camera.dup_available_pixel_formats_as_strings() or [])


def _default_pixel_format(source):
    """Mono8, else the first format livedic reads that the camera offers (a 12-bit-only camera)."""
    offered = _offered_pixel_formats(source)
    return next((name for name in SUPPORTED_PIXEL_FORMATS if name in offered), "Mono8")


def _apply_pixel_format(source, value):
    cam = source._camera
    offered = _offered_pixel_formats(source)
    if value not in offered:
        usable = [f for f in SUPPORTED_PIXEL_FORMATS if f in offered]
        raise SourceError(
            f"pixel format {value} is not offered by camera {source._label}: supported here "
            f"{', '.join(usable) or 'none of ' + ', '.join(SUPPORTED_PIXEL_FORMATS)} "
            f"(camera offers {', '.join(offered) or 'nothing'})")
    source._call(f"set pixel_format={value}", cam.set_pixel_format_from_string, value)


def _read_pixel_format(source):
    return source._camera.get_pixel_format_as_string()


def _default_binning(source):
    return (1, 1) if source._camera.is_binning_available() else None


def _apply_binning(source, value):
    cam = source._camera
    if not cam.is_binning_available():
        raise SourceError(f"binning={value[0]},{value[1]}: camera {source._label} has no binning control")
    for feature, factor in (("BinningHorizontal", value[0]), ("BinningVertical", value[1])):
        bounds = source._call(f"read the bounds of {feature}", cam.get_integer_bounds, feature)
        _check_range(f"binning ({feature})", factor, bounds.min, bounds.max, "")
    source._call(f"set binning={value[0]},{value[1]}", cam.set_binning, *value)


def _read_binning(source):
    cam = source._camera
    if not cam.is_binning_available():
        return None
    binning = cam.get_binning()
    return (binning.dx, binning.dy)


_FULL_SENSOR = "full"            # the roi default: the whole sensor (at the binning in use)


def _default_roi(source):
    return _FULL_SENSOR


def _apply_roi(source, value):
    cam = source._camera
    if value == _FULL_SENSOR:
        # Offsets to 0 first: the widest Width a camera allows shrinks with OffsetX.
        region = cam.get_region()
        source._call("set roi offsets to 0", cam.set_region, 0, 0, region.width, region.height)
        value = (0, 0, cam.get_width_bounds().max, cam.get_height_bounds().max)
        source._call(f"set roi to the full sensor {value}", cam.set_region, *value)
        return
    x, y, w, h = value
    sensor = cam.get_sensor_size()
    binning = _read_binning(source) or (1, 1)
    wide, high = sensor.width // binning[0], sensor.height // binning[1]
    wb, hb = cam.get_width_bounds(), cam.get_height_bounds()
    problems = []
    if not (wb.min <= w <= wb.max):
        problems.append(f"width {w} not in [{wb.min}, {wb.max}]")
    if not (hb.min <= h <= hb.max):
        problems.append(f"height {h} not in [{hb.min}, {hb.max}]")
    if x + w > wide or y + h > high:
        problems.append(f"x + w = {x + w}, y + h = {y + h} exceed the sensor {wide}x{high}"
                        + (f" (binned {binning[0]}x{binning[1]})" if binning != (1, 1) else ""))
    if problems:
        raise SourceError(f"roi={value} does not fit camera {source._label}: {'; '.join(problems)}")
    # Offsets first to 0 so a larger width fits, then size, then offsets (what set_region does).
    source._call(f"set roi={value}", cam.set_region, x, y, w, h)


def _read_roi(source):
    region = source._camera.get_region()
    return (region.x, region.y, region.width, region.height)


def _apply_exposure(source, value):
    cam = source._camera
    if not cam.is_exposure_time_available():
        raise SourceError(f"camera {source._label} has no exposure time control")
    if cam.is_exposure_auto_available():
        Aravis, _ = load_aravis()
        source._call("exposure auto off", cam.set_exposure_time_auto, Aravis.Auto.OFF)
    bounds = cam.get_exposure_time_bounds()
    _check_range("exposure_us", value, bounds.min, bounds.max, "us")
    source._call(f"set exposure_us={value:g}", cam.set_exposure_time, float(value))


def _read_exposure(source):
    cam = source._camera
    return cam.get_exposure_time() if cam.is_exposure_time_available() else None


def _apply_gain(source, value):
    cam = source._camera
    if not cam.is_gain_available():
        raise SourceError(f"camera {source._label} has no gain control")
    if cam.is_gain_auto_available():
        Aravis, _ = load_aravis()
        source._call("gain auto off", cam.set_gain_auto, Aravis.Auto.OFF)
    bounds = cam.get_gain_bounds()
    _check_range("gain_db", value, bounds.min, bounds.max, "dB")
    source._call(f"set gain_db={value:g}", cam.set_gain, float(value))


def _read_gain(source):
    cam = source._camera
    return cam.get_gain() if cam.is_gain_available() else None


def _apply_frame_rate(source, value):
    if source._software_trigger:
        return   # the rate livedic fires the trigger at; the camera's own limit is off (genicam.apply_trigger)
    cam = source._camera
    if not cam.is_frame_rate_available():
        raise SourceError(f"camera {source._label} has no frame rate control")
    bounds = cam.get_frame_rate_bounds()
    _check_range("frame_rate", value, bounds.min, bounds.max, "fps")
    source._call(f"set frame_rate={value:g}", cam.set_frame_rate, float(value))


def _read_frame_rate(source):
    cam = source._camera
    return cam.get_frame_rate() if cam.is_frame_rate_available() else None


def _default_packet_size(source):
    address = source._info.get("address")
    loopback = address is not None and is_ip_address(address) and ipaddress.ip_address(address).is_loopback
    return _LOOPBACK_PACKET_SIZE if loopback and source._camera.is_gv_device() else None


def _apply_packet_size(source, value):
    cam = source._camera
    if not cam.is_gv_device():
        raise SourceError("packet_size applies to GigE Vision cameras only")
    source._call(f"set packet_size={value}", cam.gv_set_packet_size, int(value))


def _read_packet_size(source):
    cam = source._camera
    return cam.gv_get_packet_size() if cam.is_gv_device() else None


def _apply_trigger(source, value) -> None:
    genicam.apply_trigger(source._camera, source._call, value)


def _read_trigger(source):
    return genicam.read_trigger(source._camera, source._call)


def shown(value: object) -> str:
    """A setting as a note shows it: 0,0,64,48 for a region, mode=On source=Line0 for a trigger."""
    if isinstance(value, (tuple, list)):
        return ",".join(str(v) for v in value)
    if isinstance(value, dict):
        return " ".join(f"{key}={item}" for key, item in value.items() if item is not None)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)

# What an open applies, in this order, and reads back (``AravisCamera.SETTINGS``).
SETTINGS = (
    Setting("pixel_format", _as_pixel_format, _apply_pixel_format, _read_pixel_format,
            "Mono8, Mono10, Mono12, Mono16 or packed Mono10p, Mono12p, Mono10Packed, Mono12Packed (default Mono8)",
            _default_pixel_format),
    Setting("binning", _as_binning, _apply_binning, _read_binning, "H[,V] pixels binned (default 1)",
            _default_binning),
    Setting("roi", _as_roi, _apply_roi, _read_roi, "sensor region x,y,w,h in pixels (default: full sensor)",
            _default_roi),
    Setting("packet_size", as_int, _apply_packet_size, _read_packet_size, "GigE packet size, bytes",
            _default_packet_size),
    Setting("exposure_us", as_float, _apply_exposure, _read_exposure, "exposure time, microseconds"),
    Setting("gain_db", as_float, _apply_gain, _read_gain, "analog gain, dB"),
    Setting("trigger", genicam.parse_trigger, _apply_trigger, _read_trigger,
            "free, software (fired at frame_rate) or line:N[:rising|falling] (default free)",
            lambda source: genicam.FREE_RUNNING),
    Setting("frame_rate", as_float, _apply_frame_rate, _read_frame_rate,
            "frames per second (with trigger=software: the trigger rate)"),
)
