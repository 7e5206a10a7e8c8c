"""Tests of acquire/camera/aravis_settings.py: each camera option parsed, checked against the camera, applied, read back."""

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera.aravis import open_uri
from livedic.acquire.camera.aravis_settings import (NO_USER_SET, SETTINGS, SUPPORTED_PIXEL_FORMATS, _as_binning,
                                                    _as_pixel_format, _as_roi, _check_range, as_user_set, shown)
from livedic.acquire.camera.fake_genicam import InProcessFakeCamera
from livedic.acquire.camera.fake_motion import SpeckleMotion

pytestmark = pytest.mark.usefixtures("time_limit")

MOTION8 = SpeckleMotion((256, 320), step=(1, -1), max_displacement=6, bit_depth=8, seed=3)
MOTION16 = SpeckleMotion((256, 320), step=(-1, 2), max_displacement=6, bit_depth=16, seed=4)


def test_settings_are_applied_then_read_back(aravis):
    with InProcessFakeCamera(MOTION16):
        with open_uri("aravis:Fake_1?exposure_us=2500&gain_db=3.3&frame_rate=123.4&roi=16,8,200,120"
                      "&pixel_format=Mono16") as camera:
            settings = camera.settings
            frame = next(iter(camera))
    assert settings["exposure_us"] == pytest.approx(2500)
    assert settings["gain_db"] == 3.0                               # integer GainRaw on the fake: read back
    assert settings["frame_rate"] == pytest.approx(123.4, rel=1e-3)  # frame period in whole us
    assert settings["frame_rate"] != 123.4 and settings["requested"]["frame_rate"] == 123.4
    assert any(n.startswith("gain_db: asked 3.3, camera set 3") for n in settings["notes"])
    assert settings["roi"] == [16, 8, 200, 120] and settings["pixel_format"] == "Mono16"
    assert settings["sensor_size"] == [2048, 2048] and settings["protocol"] == "Fake"
    assert settings["vendor"] == "Aravis" and settings["model"] == "Fake"
    assert frame.image.shape == (120, 200) and frame.image.dtype == np.uint16
    # the ROI offset crops the served image like a sensor
    assert np.array_equal(frame.image, MOTION16(frame.index)[8:128, 16:216])


def test_mono12_listed_among_supported_formats_when_camera_lacks_it(aravis):
    with InProcessFakeCamera(MOTION8), pytest.raises(SourceError) as caught:
        open_uri("aravis:Fake_1?pixel_format=mono12")
    text = str(caught.value)
    assert "Mono12" in text and "supported here Mono8, Mono16" in text and "camera offers" in text


@pytest.mark.parametrize("value, roi", [
    ("16,8,200,120", (16, 8, 200, 120)), ("16x8x200x120", (16, 8, 200, 120)), (" 0 0 64 48 ", (0, 0, 64, 48)),
    ([0, 0, "64", 48.0], (0, 0, 64, 48)),
])
def test_a_region_is_four_integers_written_any_way(value, roi):
    assert _as_roi("roi", value) == roi


@pytest.mark.parametrize("value, words", [
    ("1,2,3", "must be 4 integers x,y,w,h"), (7, "must be 4 integers"), ("-1,0,64,48", "need x >= 0"),
    ("0,0,0,48", "w > 0"), ("0,0,64,4.5", "not an integer"),
])
def test_a_bad_region_is_one_source_error(value, words):
    with pytest.raises(SourceError, match=words):
        _as_roi("roi", value)


def test_binning_is_h_or_h_and_v_at_least_one():
    assert _as_binning("binning", "2") == (2, 2) and _as_binning("binning", "2x4") == (2, 4)
    assert _as_binning("binning", (1, 3)) == (1, 3) and _as_binning("binning", 2) == (2, 2)
    for bad, words in (("1,2,3", "write H or H,V"), ("0", ">= 1")):
        with pytest.raises(SourceError, match=words):
            _as_binning("binning", bad)


def test_pixel_formats_by_any_case_and_user_sets():
    assert _as_pixel_format("pixel_format", " mono12p ") == "Mono12p"
    with pytest.raises(SourceError, match="'RGB8' is not supported: livedic reads Mono8"):
        _as_pixel_format("pixel_format", "RGB8")
    assert as_user_set("user_set", " UserSet1 ") == "UserSet1" and as_user_set("user_set", "NONE") == NO_USER_SET
    with pytest.raises(SourceError, match="name a user set"):
        as_user_set("user_set", "  ")
    assert SUPPORTED_PIXEL_FORMATS[0] == "Mono8"


def test_ranges_name_the_setting_its_bounds_and_unit():
    _check_range("gain_db", 0.0, 0.0, 12.0, "dB")                     # bounds included
    with pytest.raises(SourceError, match=r"^gain_db=12.5 is outside this camera's range \[0, 12\] dB$"):
        _check_range("gain_db", 12.5, 0.0, 12.0, "dB")
    with pytest.raises(SourceError, match=r"range \[1, 4\]$"):
        _check_range("binning (BinningHorizontal)", 8, 1, 4, "")


def test_notes_show_settings_as_a_user_writes_them():
    assert shown((0, 0, 64, 48)) == "0,0,64,48" and shown(2500.0) == "2500" and shown(0.125) == "0.125"
    assert shown({"mode": "On", "source": "Line0", "activation": None}) == "mode=On source=Line0"
    assert shown("Mono8") == "Mono8"


def test_settings_are_declared_once_in_the_order_an_open_applies_them():
    names = [setting.name for setting in SETTINGS]
    assert len(set(names)) == len(names) and all(setting.doc for setting in SETTINGS)
    # the format and binning change the sensor's size in pixels: before the region; the rate comes last
    assert names.index("pixel_format") < names.index("roi") and names.index("binning") < names.index("roi")
    assert names[-1] == "frame_rate"
