"""Tests of stream/view/entities.py: the view's entity paths (its contract with readers) and drawing styles."""

import pytest

from livedic.stream.view import entities
from livedic.stream.view.entities import (EXTENSOMETER_COLOURS, EXTENSOMETER_LOST_COLOUR, LOST_COLOUR,
                                          LOW_ZNCC_COLOUR, SERIES_STYLE, darker, extensometer_colour)

PATHS = {name: value for name, value in vars(entities).items()
         if name.isupper() and isinstance(value, str) and name not in ("TIMELINE_FRAME", "TIMELINE_TIME")}


def test_every_entity_has_its_own_path():
    assert len(set(PATHS.values())) == len(PATHS)
    assert all(path and not path.startswith("/") and not path.endswith("/") for path in PATHS.values())
    assert entities.TIMELINE_FRAME != entities.TIMELINE_TIME


@pytest.mark.parametrize("child, parent", [
    ("CAMERA_IMAGE", "CAMERA"), ("CAMERA_ROI_LABEL", "CAMERA_ROI"), ("FIELD_U", "CAMERA"), ("FIELD_EYY", "CAMERA"),
    ("LOST", "CAMERA"), ("EXTENSOMETER_LINES", "CAMERA"), ("STRAIN_XY_DATA", "STRAIN_XY"),
    ("STRAIN_XY_CURVE", "STRAIN_XY_DATA"), ("STRAIN_XY_FIT", "STRAIN_XY_DATA"), ("STRAIN_XY_NOW", "STRAIN_XY"),
    ("STRESS_STRAIN_CURVE", "STRESS_STRAIN"), ("STRESS_STRAIN_TRUE", "STRESS_STRAIN"),
])
def test_the_tree_nests_as_the_views_need(child, parent):
    """Drawn over the camera image and under one plot's transform: children of their view's origin."""
    assert PATHS[child].startswith(PATHS[parent] + "/")


def test_extensometer_colours_repeat_and_never_mean_lost_or_low_correlation():
    count = len(EXTENSOMETER_COLOURS)
    assert [extensometer_colour(k) for k in range(count)] == list(EXTENSOMETER_COLOURS)
    assert extensometer_colour(count + 1) == extensometer_colour(1)
    assert not {LOST_COLOUR, LOW_ZNCC_COLOUR, EXTENSOMETER_LOST_COLOUR} & set(EXTENSOMETER_COLOURS)
    assert len(set(EXTENSOMETER_COLOURS)) == count


def test_darker_scales_every_channel():
    assert darker((200, 100, 0)) == (90, 45, 0)
    assert darker((255, 255, 255), 1.0) == (255, 255, 255)


def test_each_series_has_a_colour_per_name():
    for path, (names, colours) in SERIES_STYLE.items():
        assert path in PATHS.values() and len(names) == len(colours) == len(set(names))
        assert all(len(c) == 3 and all(0 <= v <= 255 for v in c) for c in colours)
