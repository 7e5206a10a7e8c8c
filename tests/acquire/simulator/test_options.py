"""Tests of acquire/simulator/options.py: synthetic: URIs parsed into typed, checked options, declared once."""

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.options import (TENSILE_DEFAULTS, TRANSLATE_DEFAULTS, convert_options,
                                               parse_synthetic_uri, rendered_count, resolve_tensile_options)
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource, open_synthetic


def test_uri_options_are_parsed_and_keywords_override():
    model, options = parse_synthetic_uri("synthetic:tensile?frames=30&fps=25&size=320x256&bit=12&noise=0.5&seed=3")
    assert model == "tensile"
    assert options == {"frames": "30", "fps": "25", "size": "320x256", "bit": "12", "noise": "0.5", "seed": "3"}
    source = SyntheticTensileSource("synthetic:tensile?frames=30&size=320x256", frames=12, pace=False)
    assert source.frames == 12 and source.shape == (256, 320) and source.fps == 50.0
    assert parse_synthetic_uri("synthetic:")[0] == "tensile"
    assert isinstance(open_synthetic("synthetic:translate?size=96x96&frames=3"), SyntheticTranslateSource)


def test_values_are_unquoted_and_empty_parts_skipped():
    model, options = parse_synthetic_uri("synthetic://translate?&jump=40%3A6%3A0&&%20du%20=%200.5%20")
    assert model == "translate" and options == {"jump": "40:6:0", "du": "0.5"}


@pytest.mark.parametrize("uri, words", [
    ("tensile?frames=3", "not a synthetic source URI"),
    ("synthetic:bend", "unknown synthetic model 'bend'"),
    ("synthetic:tensile?frames", "has no value"),
])
def test_bad_uris_are_one_source_error(uri, words):
    with pytest.raises(SourceError, match=words) as error:
        parse_synthetic_uri(uri)
    assert "\n" not in str(error.value)


def test_text_and_python_values_convert_alike_and_none_keeps_the_default():
    as_text = convert_options("tensile", {"size": "128X96", "bit": "12", "pace": "off", "fracture": "yes",
                                          "lateral": " Incompressible ", "seed": "18446744073709551615"})
    as_values = convert_options("tensile", {"size": (128, 96), "bit": 12, "pace": False, "fracture": True,
                                            "lateral": "incompressible", "seed": 2**64 - 1, "noise": None})
    assert as_text == as_values
    assert as_text["size"] == (128, 96) and as_text["fracture"] == 1 and as_text["noise"] == TENSILE_DEFAULTS["noise"]
    assert convert_options("translate", {"jump": "40:6:-1.5"})["jump"] == (40, 6.0, -1.5)
    assert convert_options("translate", {"jump": ""})["jump"] is None
    assert set(convert_options("translate", {})) == set(TRANSLATE_DEFAULTS)


@pytest.mark.parametrize("model, raw, words", [
    ("translate", {"strain": "0.1"}, "unknown option.s. strain for synthetic:translate"),
    ("tensile", {"size": "63x100"}, "size='63x100': width and height must be >= 64"),
    ("tensile", {"fade": "1.5"}, "fade='1.5': must be in 0..1"),
    ("tensile", {"fracture": "-3"}, "write 0 .none., 1"),
    ("tensile", {"view": "top"}, "view='top': choose one of auto, grip, centre"),
    ("translate", {"jump": "0:1:1"}, "the jump frame must be >= 1"),
    ("translate", {"jump": "4:nan:1"}, "U, V finite"),
    ("tensile", {"loop": "1"}, "loop=1: must be 0 .off. or the number of frames"),
    ("tensile", {"radius": "0.4"}, "radius='0.4': must be >= 0.5"),
])
def test_a_bad_value_names_its_model_and_option(model, raw, words):
    with pytest.raises(SourceError, match=words):
        convert_options(model, raw)


def test_auto_laws_keep_the_small_strain_model_up_to_the_default_test():
    small = resolve_tensile_options(convert_options("tensile", {}))
    assert (small["lateral"], small["view"], small["fracture"]) == ("linear", "grip", 0)
    large = resolve_tensile_options(convert_options("tensile", {"strain": "0.3"}))
    assert (large["lateral"], large["view"]) == ("incompressible", "centre")
    chosen = resolve_tensile_options(convert_options("tensile", {"strain": "0.3", "view": "grip", "lateral": "linear"}))
    assert (chosen["lateral"], chosen["view"]) == ("linear", "grip")


def test_fracture_one_breaks_in_the_last_tenth_and_a_frame_is_kept():
    assert resolve_tensile_options(convert_options("tensile", {"frames": "50", "fracture": "1"}))["fracture"] == 45
    assert resolve_tensile_options(convert_options("tensile", {"frames": "3", "fracture": "1"}))["fracture"] == 2
    assert resolve_tensile_options(convert_options("tensile", {"frames": "50", "fracture": "7"}))["fracture"] == 7


@pytest.mark.parametrize("raw, words", [
    ({"frames": "2", "fracture": "1"}, "needs frames >= 3"),
    ({"frames": "10", "fracture": "10"}, "must be in 2..9"),
    ({"frames": "10", "loop": "4", "fracture": "1"}, "cannot be cycled"),
    ({"strain": "1.0", "neck": "0.9", "lateral": "linear"}, "use lateral=incompressible"),
])
def test_impossible_tensile_tests_are_refused(raw, words):
    with pytest.raises(SourceError, match=words):
        resolve_tensile_options(convert_options("tensile", raw))


def test_rendered_frames_are_the_loop_when_it_is_shorter():
    assert rendered_count({"frames": 100, "loop": 0}) == 100
    assert rendered_count({"frames": 100, "loop": 8}) == 8 and rendered_count({"frames": 5, "loop": 8}) == 5
