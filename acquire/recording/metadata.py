"""Session and frame metadata as the string->string maps MCAP stores, and back (JSON for what is not a string).

Nothing read is ever unpickled or evaluated: values are decoded with ``json.loads`` only.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import numpy as np

from livedic.acquire.recording.schema import JSON_KEYS_KEY

# ----------------------------------------------------------------------------- metadata as strings

def json_default(value: object) -> Any:
    """``json.dumps`` fallback: numpy values to Python, anything else to its str().

    The format's conversion for ``json.dumps(..., default=json_default)``: session and
    frame metadata go through it (``to_json``). NaN stays NaN here (Python's JSON reads it
    back); strict JSON files are ``stream.output.files.json_text``'s.
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    if hasattr(value, "__fspath__"):
        return str(value.__fspath__())
    return str(value)


def to_json(value: object) -> str:
    """JSON text for ``value``; never raises (unknown types become strings, NaN stays NaN)."""
    try:
        return json.dumps(value, default=json_default, allow_nan=True)
    except (ValueError, TypeError, RecursionError):
        return json.dumps(str(value))


def metadata_to_strings(metadata: Mapping[Any, Any]) -> dict[str, str]:
    """String->string map for MCAP: str values as is, everything else as JSON.

    The keys whose values are JSON are listed (as a JSON list) under ``livedic.json_keys``
    so ``metadata_from_strings`` can give back the original types.
    """
    strings: dict[str, str] = {}
    json_keys: list[str] = []
    for key, value in metadata.items():
        key = str(key)
        if key == JSON_KEYS_KEY:
            continue
        if isinstance(value, str):
            strings[key] = value
        else:
            strings[key] = to_json(value)
            json_keys.append(key)
    strings[JSON_KEYS_KEY] = json.dumps(sorted(json_keys))
    return strings


def metadata_from_strings(strings: Mapping[str, str]) -> dict[str, Any]:
    """Inverse of ``metadata_to_strings``; values that fail to decode stay strings."""
    try:
        json_keys = json.loads(strings.get(JSON_KEYS_KEY, "[]"))
        if not isinstance(json_keys, list):
            json_keys = []
    except (ValueError, RecursionError):
        json_keys = []
    out: dict[str, Any] = {}
    for key, text in strings.items():
        if key == JSON_KEYS_KEY:
            continue
        value: Any = text
        if key in json_keys:
            try:
                value = json.loads(text)
            except (ValueError, RecursionError):
                pass
        out[key] = value
    return out
