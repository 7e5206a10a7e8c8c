"""Tests of stream/export/field_options.py: the field options, their file names, quantities and colour ranges."""

import argparse
import os

import numpy as np
import pytest

from livedic.stream.export.field_options import (DEFAULT_EVERY, NO_FIELDS, PVD_FILE, QUANTITIES, ColourRanges,
                                                 FieldOptions, add_field_arguments, map_name, quantities, video_name,
                                                 vtu_name)
from livedic.stream.view.colour_scale import MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_STRAIN


def _options(*argv):
    return FieldOptions.from_args(add_field_arguments(argparse.ArgumentParser()).parse_args(list(argv)))


def test_the_defaults_are_the_dataclass_defaults():
    assert _options() == FieldOptions()
    assert FieldOptions().maps == QUANTITIES and FieldOptions().every == DEFAULT_EVERY and FieldOptions().vtk


def test_options_are_read_in_quantity_order_with_none_and_all():
    options = _options("--maps", " eyy, u ,", "--video", "none", "--no-vtk", "--every", "3", "--map-range",
                       "u=-2,2.5", "--map-range", "eyy=0,20", "--strain-unit", "microstrain", "--map-opacity", "0.7")
    assert options.maps == ("u", "eyy") and options.video == "" and not options.vtk and options.every == 3
    assert options.ranges == {"u": (-2.0, 2.5), "eyy": (0.0, 20.0)}
    assert options.strain_unit == "microstrain" and options.opacity == 0.7
    assert _options("--maps", "ALL").maps == QUANTITIES and _options("--maps", "None").maps == ()


@pytest.mark.parametrize("argv, words", [
    (["--maps", ""], "--maps '': give quantities from u,v,exx,eyy,exy"),
    (["--maps", "u,e1"], "--maps 'u,e1': give quantities"),
    (["--video", "u,v"], "--video 'u,v': give one of u, v, exx, eyy, exy, or none"),
    (["--every", "-1"], "--every -1: give a whole number of frames >= 1"),
    (["--video-fps", "nan"], "--video-fps nan: give frames a second between 0 and 1000"),
    (["--video-fps", "1001"], "--video-fps 1001: give frames a second"),
    (["--map-opacity", "1.5"], "--map-opacity 1.5: give a number in (0, 1]"),
    (["--map-range", "u=1,1"], "--map-range 'u=1,1': give Q=LO,HI"),
    (["--map-range", "u=a,b"], "--map-range 'u=a,b': give Q=LO,HI"),
    (["--map-range", "u=0,inf"], "--map-range 'u=0,inf': give Q=LO,HI"),
    (["--map-range", "u0,1"], "--map-range 'u0,1': give Q=LO,HI"),
])
def test_bad_options_are_one_line(argv, words):
    with pytest.raises(ValueError) as error:
        _options(*argv)
    assert str(error.value).startswith(words) and "\n" not in str(error.value)


def test_what_is_written_and_the_file_names():
    assert FieldOptions().outputs() == ["maps", "overlay_eyy.mp4", "vtk", PVD_FILE]
    assert NO_FIELDS.outputs() == [] and not NO_FIELDS.wanted and FieldOptions(maps=(), video="", vtk=True).wanted
    assert FieldOptions(maps=("eyy",), video="u").coloured == ("u", "eyy")
    assert map_name("exy", 12) == os.path.join("maps", "exy", "exy_000012.png")
    assert vtu_name(3) == os.path.join("vtk", "frame_000003.vtu") and video_name("v") == "overlay_v.mp4"


def test_existing_finds_only_this_exports_own_files(tmp_path):
    options = FieldOptions(maps=("u",), video="eyy", vtk=True)
    (tmp_path / "maps" / "u").mkdir(parents=True)
    (tmp_path / "maps" / "u" / "notes.png").write_bytes(b"")          # not a map name: not ours
    (tmp_path / "maps" / "v").mkdir()
    (tmp_path / "maps" / "v" / "v_000000.png").write_bytes(b"")      # a map, but of a quantity not drawn
    (tmp_path / "vtk").mkdir()
    assert options.existing(str(tmp_path)) == []
    (tmp_path / "maps" / "u" / "u_000004.png").write_bytes(b"")
    (tmp_path / "vtk" / "frame_000000.vtu").write_bytes(b"")
    (tmp_path / "overlay_eyy.mp4").write_bytes(b"")
    (tmp_path / PVD_FILE).write_text("")
    assert options.existing(str(tmp_path)) == ["maps/u/", "overlay_eyy.mp4", "vtk/", PVD_FILE]
    assert FieldOptions(maps=(), video="", vtk=False).existing(str(tmp_path)) == []


def test_quantities_units_and_factors():
    shown = quantities()
    assert (shown["u"].unit, shown["u"].factor, shown["exx"].unit, shown["exx"].factor) == ("px", 1.0, "%", 100.0)
    assert shown["exy"].label == "e_xy (%)" and shown["u"].start == MIN_COLOUR_LIMIT_PX
    scaled = quantities(scale=20.0, strain_unit="microstrain", measure="true", vsg_px=41.0)
    assert scaled["v"].unit == "mm" and scaled["v"].factor == pytest.approx(0.05)
    assert scaled["eyy"].factor == 1e6 and scaled["eyy"].start == pytest.approx(MIN_COLOUR_LIMIT_STRAIN * 1e6)
    assert scaled["eyy"].meaning == "true strain along y, VSG 41 px"


def test_colour_ranges_grow_over_the_ok_points_only_and_fixed_ones_stay():
    shown = quantities()
    ranges = ColourRanges(shown, fixed={"eyy": (0.0, 6.0)})
    assert ranges.limits["u"] == (-MIN_COLOUR_LIMIT_PX, MIN_COLOUR_LIMIT_PX)
    values = {name: np.zeros(4) for name in QUANTITIES}
    values["u"] = np.array([0.3, -0.2, 0.1, 50.0])          # the 50 px point is not ok
    values["eyy"] = np.array([0.2, 0.3, 0.1, 0.0])          # 30 %: beyond the fixed range, kept fixed
    ranges.add(values, np.array([True, True, True, False]))
    lo, hi = ranges.limits["u"]
    assert -1.0 < lo <= -0.2 and 0.3 <= hi < 1.0
    assert ranges.limits["eyy"] == (0.0, 6.0)
    assert ranges.limits["exx"] == (-MIN_COLOUR_LIMIT_STRAIN * 100, MIN_COLOUR_LIMIT_STRAIN * 100)
    ranges.add({name: np.zeros(4) for name in QUANTITIES}, np.ones(4, dtype=bool))
    assert ranges.limits["u"] == (lo, hi)                  # one range for the sequence: never shrinks
