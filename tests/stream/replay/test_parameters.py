"""Tests of stream/replay/parameters.py: which method parameters a replay uses (given, recorded, default)."""

import pytest

from livedic.stream.replay.parameters import METHOD_KEYS, check_parameters, resolve_parameters, run_defaults
from livedic.stream.session.config import DEFAULT_POINTS, TrackingConfig

RECORDED = {"subset": 31, "search": "fft-cc", "subpixel": "icgn", "seed_radius": 3, "refind_radius": 12,
            "refind_zncc": 0.7, "min_zncc": 0.6, "seed": 5, "reference_update": "never",
            "prefilter": "gaussian:0.6", "interpolation": "bspline5"}


def test_run_defaults_are_the_tracking_configs_and_the_default_point_count():
    defaults = run_defaults()
    assert set(defaults) == set(METHOD_KEYS) | {"n_points"} and defaults["n_points"] == DEFAULT_POINTS
    assert all(defaults[key] == getattr(TrackingConfig(), key) for key in METHOD_KEYS)


def test_recorded_values_are_used_and_given_ones_replace_them():
    used, recorded, notes = resolve_parameters(RECORDED, {"subset": 41, "seed": None})
    assert recorded == RECORDED and notes == []
    assert used == dict(RECORDED, subset=41)


def test_search_and_subpixel_come_from_the_method_text_when_the_metadata_lacks_them():
    metadata = {key: value for key, value in RECORDED.items() if key not in ("search", "subpixel")}
    used, recorded, notes = resolve_parameters(metadata, {}, method_text="improved-wso+newton-raphson")
    assert (used["search"], used["subpixel"]) == ("improved-wso", "newton-raphson") and notes == []
    assert recorded["subpixel"] == "newton-raphson"


def test_missing_values_take_run_defaults_with_a_note_each_but_reference_update_and_prefilter_as_before():
    used, recorded, notes = resolve_parameters({}, {}, method_text="not a method text")
    defaults = run_defaults()
    assert recorded == {}
    assert used["reference_update"] == "never"          # recordings from before the option never moved it
    assert used["prefilter"] == "none"                  # ... nor filtered their images, whatever the default now
    assert used["interpolation"] == "bspline3"          # ... and sampled with the cubic B-spline
    before = ("reference_update", "prefilter", "interpolation")
    assert all(used[key] == defaults[key] for key in METHOD_KEYS if key not in before)
    assert len(notes) == len(METHOD_KEYS) - len(before)
    assert "the recording does not say which subset it used: using livedic run's default 21" in notes


@pytest.mark.parametrize("key, value, read", [
    ("subset", 31.0, 31), ("subset", 31.5, None), ("subset", True, None), ("subset", "31", None),
    ("refind_zncc", float("nan"), None), ("refind_zncc", 1, 1.0), ("search", "", None), ("search", 3, None),
])
def test_recorded_values_of_the_wrong_type_are_not_used(key, value, read):
    _, recorded, _ = resolve_parameters({key: value}, {})
    assert recorded.get(key) == read and type(recorded.get(key)) is type(read)


def test_check_parameters_returns_the_tracking_config_and_refuses_bad_values_in_one_line():
    used, _, _ = resolve_parameters(RECORDED, {})
    assert check_parameters(used) == TrackingConfig(**RECORDED)
    with pytest.raises(ValueError) as error:
        check_parameters(dict(used, subset=20))
    assert "\n" not in str(error.value) and "subset" in str(error.value)
    with pytest.raises(ValueError, match="thread"):
        check_parameters(used, threads=0)
