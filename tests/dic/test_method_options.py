"""Tests of dic/method_options.py: options merged into a method's defaults after checks, the predicates, the seed."""

import numpy as np
import pytest

from livedic.dic.method_options import is_bool, is_int_at_least, is_real_in, resolve_options, seed_to_uint

DEFAULTS = {"population": 20, "tolerance": 0.01, "polish": True}
CHECKS = {"population": (is_int_at_least(1), "an integer >= 1"), "tolerance": (is_real_in(0.0, 1.0, low_open=True),
                                                                               "a number in (0, 1]"),
          "polish": (is_bool, "true or false")}


def test_options_replace_defaults_and_nothing_else_changes():
    merged = resolve_options("m", {"population": 8}, DEFAULTS, CHECKS)
    assert merged == {"population": 8, "tolerance": 0.01, "polish": True}
    assert DEFAULTS["population"] == 20                       # the defaults are not changed
    assert resolve_options("m", None, DEFAULTS, CHECKS) == DEFAULTS


def test_an_unknown_option_names_the_valid_ones():
    with pytest.raises(ValueError, match=r"unknown option 'popsize' for 'm': valid options are polish, population, "
                                         r"tolerance"):
        resolve_options("m", {"popsize": 3}, DEFAULTS, CHECKS)
    with pytest.raises(ValueError, match="valid options are none"):
        resolve_options("m", {"x": 1}, {}, {})


def test_a_bad_value_names_what_it_must_be():
    with pytest.raises(ValueError, match=r"option 'tolerance' of 'm' must be a number in \(0, 1\], got 0.0"):
        resolve_options("m", {"tolerance": 0.0}, DEFAULTS, CHECKS)


@pytest.mark.parametrize("value, ok", [(1, True), (np.int64(5), True), (0, False), (True, False), (1.0, False),
                                       ("2", False)])
def test_integer_predicate(value, ok):
    assert is_int_at_least(1)(value) is ok


@pytest.mark.parametrize("value, ok", [(0.0, True), (1.0, True), (0.5, True), (2, True), (-0.1, False),
                                       (1.01, False), (float("nan"), False), (float("inf"), False), (True, False),
                                       ("0.5", False)])
def test_closed_interval_predicate(value, ok):
    assert is_real_in(0.0, 2.0 if value == 2 else 1.0)(value) == ok


def test_open_ends():
    assert not is_real_in(0.0, 1.0, low_open=True)(0.0) and is_real_in(0.0, 1.0, low_open=True)(1.0)
    assert not is_real_in(0.0, 1.0, high_open=True)(1.0) and is_real_in(0.0, 1.0, high_open=True)(0.0)


def test_bool_predicate():
    assert is_bool(True) and is_bool(np.bool_(False)) and not is_bool(1) and not is_bool("true")


def test_seeds_wrap_to_uint64_and_non_integers_are_refused():
    assert seed_to_uint(5) == np.uint64(5) and isinstance(seed_to_uint(5), np.uint64)
    assert seed_to_uint(-1) == np.uint64(2 ** 64 - 1)
    assert seed_to_uint(2 ** 64 + 3) == np.uint64(3)
    for bad in (1.5, True, "3"):
        with pytest.raises(ValueError, match="seed must be an integer"):
            seed_to_uint(bad)
