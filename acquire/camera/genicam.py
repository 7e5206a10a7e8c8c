"""GenICam features of an Aravis camera: any feature by name, triggers and user sets.

The functions take an opened ``Aravis.Camera`` (gi) and a ``call(what, function,
*args)`` that runs an Aravis call and turns its ``GLib.Error`` into a one-line
``SourceError`` naming the camera (``AravisCamera._call``); bad values raise
``SourceError`` before anything is written.

* ``set_feature(camera, call, name, text)``: a feature set from its URI text by
  its GenICam type (integer, float, boolean, enumeration, string), checked
  against the camera's bounds or entries, then READ BACK (what the camera uses).
* ``parse_trigger`` / ``apply_trigger`` / ``read_trigger``: ``free``,
  ``software`` or ``line:N[:rising|falling]`` through the standard features
  TriggerSelector=FrameStart, TriggerMode, TriggerSource, TriggerActivation.
  Every trigger is switched off first (Aravis's ``clear_triggers``), so a trigger
  left on by another program never stays active.
* ``load_user_set``: UserSetSelector + UserSetLoad, when the camera has user sets.

Examples
--------
>>> parse_trigger("trigger", "line:1:falling")
Trigger(mode='line', line=1, edge='falling')
>>> str(parse_trigger("trigger", "software")), parse_trigger("trigger", "line:2").activation
('software', 'RisingEdge')
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

from livedic.acquire.base import SourceError
from livedic.acquire.options import parse_bool, parse_number

__all__ = ["Trigger", "FREE_RUNNING", "parse_trigger", "apply_trigger", "read_trigger", "feature_kind", "set_feature",
           "read_feature", "load_user_set", "DEFAULT_USER_SET", "TRIGGER_SELECTOR"]

TRIGGER_SELECTOR = "FrameStart"      # the trigger livedic sets: one exposure per trigger
DEFAULT_USER_SET = "Default"         # the factory settings (SFNC UserSetSelector entry)
_EDGES = {"rising": "RisingEdge", "falling": "FallingEdge"}
_TRIGGER_FORMS = "trigger=free, trigger=software or trigger=line:N[:rising|falling] (e.g. line:1:rising)"

Camera = Any                     # an opened Aravis.Camera (gi objects come without type stubs)
Call = Callable[..., Any]        # call(what, function, *args): AravisCamera._call, GLib.Error -> SourceError


@dataclass(frozen=True)
class Trigger:
    """What starts each exposure.

    mode : str          "free" (the camera's own frame rate), "software" (livedic fires TriggerSoftware)
                        or "line" (a hardware input)
    line : int or None  the input line number for "line" (TriggerSource=Line<N>)
    edge : str or None  "rising" or "falling" for "line"
    """
    mode: str
    line: int | None = None
    edge: str | None = None

    @property
    def source(self) -> str | None:
        """The TriggerSource entry, None for free running."""
        return {"software": "Software", "line": f"Line{self.line}"}.get(self.mode)

    @property
    def activation(self) -> str | None:
        """The TriggerActivation entry (line triggers only)."""
        return _EDGES[cast(str, self.edge)] if self.mode == "line" else None     # a line trigger has an edge

    def __str__(self) -> str:
        return f"line:{self.line}:{self.edge}" if self.mode == "line" else self.mode


FREE_RUNNING = Trigger("free")


def parse_trigger(name: str, value: object) -> Trigger:
    """A ``Trigger`` from ``free``, ``software`` or ``line:N[:rising|falling]``; ``SourceError`` otherwise."""
    if isinstance(value, Trigger):
        return value
    parts = str(value).strip().lower().split(":")
    if parts == ["free"] or parts == ["off"]:
        return FREE_RUNNING
    if parts == ["software"]:
        return Trigger("software")
    if parts[0] == "line" and len(parts) in (2, 3) and parts[1].isdigit():
        edge = parts[2] if len(parts) == 3 else "rising"
        if edge in _EDGES:
            return Trigger("line", int(parts[1]), edge)
    raise SourceError(f"option {name}={value!r}: write {_TRIGGER_FORMS}")


def _entries(camera: Camera, call: Call, feature: str) -> list[str]:
    return list(call(f"read the entries of {feature}", camera.dup_available_enumerations_as_strings, feature) or [])


def _set_entry(camera: Camera, call: Call, feature: str, entry: str | None, asked: str) -> None:
    """Set enumeration ``feature`` to ``entry`` (it must be offered); ``asked`` names the option in errors."""
    offered = _entries(camera, call, feature)
    if entry not in offered:
        raise SourceError(f"{asked}: this camera's {feature} offers {', '.join(offered) or 'nothing'}, "
                          f"not {entry}")
    call(f"set {feature}={entry}", camera.set_string, feature, entry)


def apply_trigger(camera: Camera, call: Call, trigger: Trigger) -> None:
    """Switch every trigger off, then set ``trigger`` (TriggerSelector=FrameStart, mode, source, activation).

    A camera without trigger features runs free; asking it for a trigger raises ``SourceError``.
    """
    asked = f"trigger={trigger}"
    has_mode = camera.is_feature_available("TriggerMode")
    if not has_mode:
        if trigger.mode != "free":
            raise SourceError(f"{asked}: this camera has no TriggerMode feature (no trigger input)")
        return
    call("switch the triggers off", camera.clear_triggers)
    if trigger.mode == "free":
        return
    if camera.is_feature_available("TriggerSelector"):
        _set_entry(camera, call, "TriggerSelector", TRIGGER_SELECTOR, asked)
    call("set TriggerMode=On", camera.set_string, "TriggerMode", "On")
    _set_entry(camera, call, "TriggerSource", trigger.source, asked)
    if trigger.activation is not None:
        if camera.is_feature_available("TriggerActivation"):
            _set_entry(camera, call, "TriggerActivation", trigger.activation, asked)
        elif trigger.edge != "rising":
            raise SourceError(f"{asked}: this camera has no TriggerActivation feature (rising edge only)")
    if trigger.mode == "software" and camera.is_feature_available("AcquisitionFrameRateEnable"):
        # livedic paces the frames: a frame-rate limit in the camera would drop triggers (as Aravis's set_trigger)
        call("set AcquisitionFrameRateEnable=false", camera.set_boolean, "AcquisitionFrameRateEnable", False)


def read_trigger(camera: Camera, call: Call) -> dict[str, Any]:
    """The FrameStart trigger as the camera reports it: mode, source, activation, selector (None if absent)."""
    out: dict[str, Any] = {}
    if camera.is_feature_available("TriggerSelector"):
        if TRIGGER_SELECTOR in _entries(camera, call, "TriggerSelector"):
            call(f"select the {TRIGGER_SELECTOR} trigger", camera.set_string, "TriggerSelector", TRIGGER_SELECTOR)
        out["selector"] = call("read TriggerSelector", camera.get_string, "TriggerSelector")
    for key, feature in (("mode", "TriggerMode"), ("source", "TriggerSource"), ("activation", "TriggerActivation")):
        out[key] = call(f"read {feature}", camera.get_string, feature) if camera.is_feature_available(feature) else None
    return out


# --------------------------------------------------------------------------- features by name

_KINDS = (("enumeration", "GcEnumeration"), ("boolean", "GcBoolean"), ("command", "GcCommand"),
          ("integer", "GcInteger"), ("float", "GcFloat"), ("string", "GcString"))


def feature_kind(camera: Camera, name: str) -> str | None:
    """The GenICam type of feature ``name``: integer, float, boolean, enumeration, string, command; None if absent."""
    node = camera.get_device().get_feature(name)
    if node is None:
        return None
    # The node's gi classes and interfaces by name (GcIntegerNode implements GcInteger; an enumeration is a
    # GcInteger too, so the order of _KINDS matters): this module does not import Aravis itself.
    types = {cls.__name__ for cls in type(node).__mro__}
    return next((kind for kind, type_name in _KINDS if type_name in types), "other")


def _parse_value(kind: str, option: str, text: object) -> Any:
    try:
        if kind == "integer":
            stripped = str(text).strip()
            return int(stripped, 0) if stripped.lower().startswith(("0x", "-0x")) else parse_number(text, integer=True)
        if kind == "float":
            return parse_number(text)
        if kind == "boolean":
            return parse_bool(text)
    except ValueError as error:
        raise SourceError(f"option {option}={text!r}: {error} (the camera's {kind} feature)") from None
    return str(text)


def read_feature(camera: Camera, call: Call, name: str, kind: str | None = None) -> Any:
    """The value of feature ``name`` as the camera reports it (int, float, bool or str)."""
    kind = kind or feature_kind(camera, name)
    getters: dict[str | None, Call] = {"integer": camera.get_integer, "float": camera.get_float,
                                       "boolean": camera.get_boolean}
    getter = getters.get(kind, camera.get_string)
    return call(f"read {name}", getter, name)


def _check_writable(camera: Camera, option: str, name: str) -> None:
    node = camera.get_device().get_feature(name)
    if getattr(node.get_actual_access_mode(), "value_nick", "") == "ro":
        raise SourceError(f"option {option}: {name} is read-only on this camera")
    if not node.is_available() or node.is_locked():
        raise SourceError(f"option {option}: {name} cannot be written now (locked or unavailable on this camera; "
                          "it may depend on another feature)")


def set_feature(camera: Camera, call: Call, name: str, text: object) -> tuple[Any, Any, str | None]:
    """Set GenICam feature ``name`` from ``text`` by its type, then read it back.

    Returns
    -------
    (value asked, value read back, note or None)
        The note says when the camera set another value (rounded to its increment, ...).

    Raises
    ------
    SourceError
        No such feature, a command, read-only or locked, a value out of bounds or not an entry,
        or a value the camera did not keep (enumeration, boolean, string).
    """
    option = f"feature.{name}={text}"
    kind = feature_kind(camera, name)
    if kind is None:
        raise SourceError(f"option {option}: this camera has no GenICam feature {name!r} "
                          "('arv-tool-0.8 -n DEVICE_ID features' lists them; names are case-sensitive)")
    if kind not in ("integer", "float", "boolean", "enumeration", "string"):
        raise SourceError(f"option {option}: {name} is a {kind}, not a value livedic can set")
    value = _parse_value(kind, f"feature.{name}", text)
    _check_writable(camera, option, name)
    if kind == "enumeration":
        offered = _entries(camera, call, name)
        match = next((entry for entry in offered if entry.lower() == value.strip().lower()), None)
        if match is None:
            raise SourceError(f"option {option}: {name} offers {', '.join(offered) or 'nothing'}")
        value = match
    elif kind in ("integer", "float"):
        bounds = call(f"read the bounds of {name}",
                      camera.get_integer_bounds if kind == "integer" else camera.get_float_bounds, name)
        if not bounds.min <= value <= bounds.max:
            raise SourceError(f"option {option}: outside {name}'s range [{bounds.min:g}, {bounds.max:g}] "
                              "on this camera")
    setter = {"integer": camera.set_integer, "float": camera.set_float, "boolean": camera.set_boolean}.get(
        kind, camera.set_string)
    call(f"set {name}={value}", setter, name, value)
    got = read_feature(camera, call, name, kind)
    note = None
    if kind == "float":
        if not math.isclose(got, value, rel_tol=1e-3, abs_tol=1e-9):
            note = f"feature.{name}: asked {value:g}, camera set {got:g}"
    elif kind == "integer":
        if got != value:
            note = f"feature.{name}: asked {value}, camera set {got}"
    elif got != value:
        raise SourceError(f"option {option}: the camera did not keep it ({name} reads {got!r})")
    return value, got, note


# --------------------------------------------------------------------------- user sets

def user_sets(camera: Camera, call: Call) -> list[str]:
    """The UserSetSelector entries, [] when the camera cannot load user sets."""
    if not (camera.is_feature_available("UserSetSelector") and camera.is_feature_available("UserSetLoad")):
        return []
    return _entries(camera, call, "UserSetSelector")


def load_user_set(camera: Camera, call: Call, name: str) -> bool:
    """Load user set ``name`` (UserSetSelector, then UserSetLoad); False when the camera has no such set."""
    if name not in user_sets(camera, call):
        return False
    call(f"select user set {name}", camera.set_string, "UserSetSelector", name)
    call(f"load user set {name}", camera.execute_command, "UserSetLoad")
    return True
