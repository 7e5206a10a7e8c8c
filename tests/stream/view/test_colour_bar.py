"""Tests of stream/view/colour_bar.py: the colour bar's gradient, its limits written in black, and the legends."""

import numpy as np

from livedic.stream.view import colour_bar, entities
from livedic.stream.view.colour_bar import LEGENDS, colour_bar_image
from livedic.stream.view.colour_scale import colormap_lut


def test_colour_bar_labels_are_dark_on_a_white_strip():
    """Drawn into the image, the labels read the same in the viewer's light and dark themes."""
    lut = colormap_lut()
    bar = colour_bar_image(lut, -2.5, 4.0)
    strip = bar[colour_bar._BAR_GRADIENT_HEIGHT:]
    dark = (strip.max(axis=2) < 80)
    white = (strip.min(axis=2) == 255)
    assert dark.sum() > 200 and white.mean() > 0.7            # black text on white
    assert not np.array_equal(bar, colour_bar_image(lut, -2.5, 5.0))   # the labels are in the pixels


# --------------------------------------------------------------------------- lost and weak points


def test_the_gradient_runs_the_whole_colour_map_between_the_margins():
    lut = colormap_lut()
    bar = colour_bar_image(lut, -1.0, 1.0)
    row = bar[colour_bar._BAR_GRADIENT_HEIGHT // 2]
    first, last = colour_bar._BAR_MARGIN, colour_bar._BAR_WIDTH - 1 - colour_bar._BAR_MARGIN
    assert (row[first] == lut[0]).all() and (row[last] == lut[-1]).all()
    assert (row[:first] == 255).all() and (row[last + 1:] == 255).all()       # white margins apart
    assert bar.shape == (colour_bar._BAR_GRADIENT_HEIGHT + colour_bar._BAR_TEXT_HEIGHT, colour_bar._BAR_WIDTH, 3)


def test_a_zero_tick_only_when_zero_lies_inside_and_labels_scale_with_the_factor():
    lut = colormap_lut()
    tick_row = colour_bar._BAR_GRADIENT_HEIGHT + 2
    inside = colour_bar_image(lut, -1.0, 1.0)[tick_row]
    outside = colour_bar_image(lut, 1.0, 3.0)[tick_row]
    middle = colour_bar._BAR_WIDTH // 2
    assert (inside[middle - 2:middle + 2] < 80).any() and not (outside[middle - 2:middle + 2] < 80).any()
    # the strain bar writes 100 x its limits in %: the same pixels as a px bar of the scaled limits and unit
    strain = colour_bar_image(lut, -0.01, 0.02, unit="%", factor=100.0)
    assert np.array_equal(strain, colour_bar_image(lut, -1.0, 2.0, unit="%"))
    assert colour_bar._fmt(float("nan")) == "n/a" and colour_bar._fmt(12345.6) == "+12346"


def test_each_legend_names_its_limits_entity_and_unit():
    assert LEGENDS[entities.LEGEND_EYY] == (entities.LIMITS_EYY, "%", 100.0)
    assert LEGENDS[entities.LEGEND_W] == (entities.LIMITS_W, "mm", 1.0)
    assert {limits for limits, _, _ in LEGENDS.values()} == {entities.LIMITS_U, entities.LIMITS_V,
                                                              entities.LIMITS_EYY, entities.LIMITS_W}
