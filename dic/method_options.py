"""Options of the search and sub-pixel methods: checked against each method's defaults, one set of rules.

A method module declares ``DEFAULTS`` (option name -> default value) and
``CHECKS`` (option name -> (predicate, description)); ``resolve_options`` merges
what the caller passed into the defaults after checking names and values, and
the predicates below build the checks. ``seed_to_uint`` turns the seed of the
stochastic methods into the uint64 their per-point random streams start from.

Examples
--------
>>> resolve_options("pso", {"population": 8}, {"population": 20}, {"population": (is_int_at_least(1), "an int >= 1")})
{'population': 8}
"""

import numbers
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

Predicate = Callable[[Any], bool]
"""A check of one option's value: True when the value is acceptable."""
Checks = Mapping[str, tuple[Predicate, str]]
"""Option name -> (predicate, description of what the value must be)."""


def resolve_options(method: str, options: Mapping[str, Any] | None, defaults: Mapping[str, Any],
                    checks: Checks) -> dict[str, Any]:
    """Merge ``options`` into ``defaults`` after checking names and values.

    ``checks`` maps option name -> (predicate, description). Raises ValueError
    naming the valid options (unknown name) or the expected value (bad value).
    """
    merged = dict(defaults)
    for name, value in (options or {}).items():
        if name not in defaults:
            valid = ", ".join(sorted(defaults)) or "none"
            raise ValueError(f"unknown option {name!r} for {method!r}: valid options are {valid}")
        predicate, description = checks[name]
        if not predicate(value):
            raise ValueError(f"option {name!r} of {method!r} must be {description}, got {value!r}")
        merged[name] = value
    return merged


def is_int_at_least(low: int) -> Predicate:
    """Predicate: an integer (not a bool) >= ``low``."""
    return lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool) and int(v) >= low


def is_real_in(low: float, high: float, low_open: bool = False, high_open: bool = False) -> Predicate:
    """Predicate: a finite real number (not a bool) in [low, high], either end open if told."""
    def check(v):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not np.isfinite(v):
            return False
        above = v > low if low_open else v >= low
        below = v < high if high_open else v <= high
        return above and below
    return check


def is_bool(v: Any) -> bool:
    """Predicate: a Python or numpy bool."""
    return isinstance(v, (bool, np.bool_))


def seed_to_uint(seed: int) -> np.uint64:
    """Seed as np.uint64 (any Python int, negative ones wrap)."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    return np.uint64(int(seed) % (1 << 64))
