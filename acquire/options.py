"""Source options as written in URIs (``?fps=50&pace=0``) or passed as keywords: one set of rules.

``parse_bool`` and ``parse_number`` raise ``ValueError`` with the reason only, for
callers that add their own context; ``as_bool``, ``as_int`` and ``as_float`` name the
option in a one-line ``SourceError`` (``option fps='abc': not a number``).

Examples
--------
>>> as_int("width", "640", low=1), as_float("gain_db", 3), as_bool("pace", "0")
(640, 3.0, False)
"""

import math
from collections.abc import Callable
from typing import Any

from livedic.acquire.base import SourceError

__all__ = ["parse_bool", "parse_number", "as_bool", "as_int", "as_float"]

_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off", "")


def parse_bool(value: object) -> bool:
    """``True``/``False`` from a bool or 1/0, true/false, yes/no, on/off (empty is False)."""
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    raise ValueError("not a boolean: write 1 or 0 (true/false)")


def parse_number(value: object, *, integer: bool = False, low: float | None = None,
                 low_open: bool = False) -> float:
    """A finite float (or an int with ``integer``), at least ``low`` (above it with ``low_open``)."""
    kind = "an integer" if integer else "a number"
    if isinstance(value, bool):
        raise ValueError(f"expected {kind}")
    text: Any = value.strip() if isinstance(value, str) else value     # int()/float() judge the rest
    number: float | None = None
    if integer:
        try:
            number = int(text)            # exact for large integers (seeds), unlike float
        except (TypeError, ValueError):
            number = None
    if number is None:
        try:
            number = float(text)
        except (TypeError, ValueError):
            raise ValueError(f"not {kind}") from None
        if not math.isfinite(number):
            raise ValueError("must be finite")
        if integer:
            if not number.is_integer():
                raise ValueError("not an integer")
            number = int(number)
    if low is not None and (number < low or (low_open and number == low)):
        raise ValueError(f"must be {'>' if low_open else '>='} {low:g}")
    return number


def _named(name: str, value: object, parse: Callable[..., Any], **limits: Any) -> Any:
    try:
        return parse(value, **limits)
    except ValueError as error:
        raise SourceError(f"option {name}={value!r}: {error}") from None


def as_bool(name: str, value: object) -> bool:
    """``parse_bool`` with the option named in a ``SourceError``."""
    return _named(name, value, parse_bool)


def as_int(name: str, value: object, *, low: float | None = None) -> int:
    """``parse_number(integer=True)`` with the option named in a ``SourceError``."""
    return _named(name, value, parse_number, integer=True, low=low)


def as_float(name: str, value: object, *, low: float | None = None, low_open: bool = False) -> float:
    """``parse_number`` with the option named in a ``SourceError``."""
    return _named(name, value, parse_number, low=low, low_open=low_open)
