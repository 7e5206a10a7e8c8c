"""Tests of acquire/options.py: source options from URIs or keywords, one set of rules and one-line errors."""

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.options import as_bool, as_float, as_int, parse_bool, parse_number


def test_option_parsing_is_shared_by_every_source():
    """One set of rules (acquire.options) for synthetic, mcap, v4l2 and aravis options."""
    assert as_int("seed", "18446744073709551615", low=0) == 2**64 - 1          # exact, not via float
    assert as_int("frames", "300.0") == 300 and as_float("fps", " 50 ") == 50.0
    assert [as_bool("pace", v) for v in ("1", "yes", "On", "0", "false", "", True)] == [True] * 3 + [False] * 3 + [True]
    for call, words in ((lambda: as_int("frames", "2.5"), "option frames='2.5': not an integer"),
                        (lambda: as_float("fps", "nan"), "option fps='nan': must be finite"),
                        (lambda: as_float("fps", 0, low=0, low_open=True), "option fps=0: must be > 0"),
                        (lambda: as_bool("pace", "maybe"), "option pace='maybe': not a boolean")):
        with pytest.raises(SourceError, match=words):
            call()
    with pytest.raises(ValueError, match="expected a number"):
        parse_number(True)


@pytest.mark.parametrize("value, expected", [
    ("3", 3), (" 7 ", 7), ("1e3", 1000), (4.0, 4), ("-2", -2), (2**70, 2**70),
])
def test_integers_are_exact_and_written_any_way(value, expected):
    number = parse_number(value, integer=True)
    assert number == expected and isinstance(number, int)


@pytest.mark.parametrize("value, limits, reason", [
    ("abc", {}, "not a number"), (None, {}, "not a number"), ("inf", {}, "must be finite"),
    ("-1e400", {}, "must be finite"), ("1.5", {"integer": True}, "not an integer"),
    ("x", {"integer": True}, "not an integer"), (False, {"integer": True}, "expected an integer"),
    (-0.5, {"low": 0}, "must be >= 0"), (1, {"low": 1, "low_open": True}, "must be > 1"),
])
def test_bad_numbers_give_the_reason_only(value, limits, reason):
    with pytest.raises(ValueError) as error:
        parse_number(value, **limits)
    assert str(error.value) == reason and not isinstance(error.value, SourceError)


def test_limits_are_inclusive_unless_open():
    assert parse_number("0", low=0) == 0.0 and parse_number(1e-300, low=0, low_open=True) == 1e-300


@pytest.mark.parametrize("value", ["2", "maybe", "none", "tru"])
def test_only_the_listed_words_are_booleans(value):
    with pytest.raises(ValueError, match="not a boolean"):
        parse_bool(value)
    assert parse_bool(" TRUE ") is True and parse_bool(0) is False and parse_bool("off") is False
