"""The method parameters of a replay: the recorded ones, the user's, and ``livedic run``'s defaults.

``resolve_parameters`` takes each of ``METHOD_KEYS`` from the user, else from the recording (its session
metadata, else its results' method text), else from ``livedic run``'s default, and says so;
``check_parameters`` checks them as ``livedic run`` does.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from livedic.stream.session.config import DEFAULT_POINTS, SessionConfig, TrackingConfig


METHOD_KEYS = TrackingConfig.keys()
_INT_KEYS = ("subset", "seed_radius", "refind_radius", "seed")
# What a recording made before a parameter existed did (replayed that way, not with today's default).
_BEFORE_KEY = {"reference_update": "never", "prefilter": "none", "interpolation": "bspline3"}


def run_defaults() -> dict[str, Any]:
    """The ``livedic run`` defaults of the method options (and ``n_points``): ``stream.session.config``'s."""
    return dict(TrackingConfig().as_dict(), n_points=DEFAULT_POINTS)


def _recorded_value(key: str, value: object) -> Any:
    """``value`` as the type of ``key``, or None when it is missing or of the wrong type."""
    if isinstance(value, bool) or value is None:
        return None
    if key in _INT_KEYS:
        if isinstance(value, (int, np.integer)):
            return int(value)
        if isinstance(value, float) and value.is_integer():
            return int(value)
        return None
    if key in ("refind_zncc", "min_zncc"):
        return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None
    return value if isinstance(value, str) and value else None


def resolve_parameters(metadata: Mapping[str, Any], given: Mapping[str, Any],
                       method_text: str = "") -> tuple[dict[str, Any], dict[str, Any], list[str]]:
    """(parameters used, recorded parameters found, notes).

    ``given``: the user's values (None = not given). A recorded value is taken
    from the session metadata, else for search/sub-pixel from the results' method
    text ("search+subpixel"), else ``livedic run``'s default (with a note).
    """
    defaults = run_defaults()
    from_method: dict[str, str] = {}
    if isinstance(method_text, str) and method_text.count("+") == 1:
        from_method = dict(zip(("search", "subpixel"), method_text.split("+")))
    used: dict[str, Any] = {}
    recorded: dict[str, Any] = {}
    notes: list[str] = []
    for key in METHOD_KEYS:
        value = _recorded_value(key, metadata.get(key))
        if value is None:
            value = _recorded_value(key, from_method.get(key))
        if value is not None:
            recorded[key] = value
        if given.get(key) is not None:
            used[key] = given[key]
        elif value is not None:
            used[key] = value
        elif key in _BEFORE_KEY:
            used[key] = _BEFORE_KEY[key]          # recorded before the option existed: what it did then
        else:
            used[key] = defaults[key]
            notes.append(f"the recording does not say which {key} it used: using livedic run's default "
                         f"{defaults[key]}")
    return used, recorded, notes


def check_parameters(params: Mapping[str, Any], threads: int | None = None) -> TrackingConfig:
    """ValueError (one line, as ``livedic run`` words it) for a bad method parameter or thread count.

    The checks are ``stream.session.config``'s (``TrackingConfig``, ``SessionConfig``): returns the ``TrackingConfig``.
    """
    tracking = TrackingConfig(**{key: params[key] for key in METHOD_KEYS})
    if threads is not None:
        SessionConfig(threads=threads)
    return tracking
