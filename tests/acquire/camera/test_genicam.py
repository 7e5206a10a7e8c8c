"""Camera control on Aravis's in-process Fake camera: features by name, triggers, user sets, binning, bit depths.

The Fake camera's node map is Aravis's own (GainRaw, ExposureTimeAbs, TestBoolean, TestStringReg,
AcquisitionMode, TriggerSelector/Mode/Source/Activation, Binning*); ``extended_xml`` adds what it lacks
(10/12-bit formats, Line1, FallingEdge, user sets). Each open of ``aravis:Fake_1`` is a new device in its
power-on state, so what an earlier session leaves behind is tested on the GigE simulator
(tests/acquire/camera/test_aravis_gige_simulator.py). The in-process fake streams in trigger mode whether or not a
trigger comes, so triggers are checked here as settings read back and on the simulator as frames.
"""

import numpy as np
import pytest

from livedic.acquire.camera.aravis import open_uri
from livedic.acquire.base import SourceError
from livedic.acquire.camera.fake_genicam import InProcessFakeCamera
from livedic.acquire.camera.fake_motion import SpeckleMotion, served_as
from livedic.acquire.camera.genicam import Trigger, parse_trigger
from livedic.acquire.camera.pixel_formats import FORMATS

pytestmark = pytest.mark.usefixtures("time_limit", "aravis")

SHAPE = (96, 128)
ROI = (0, 0, SHAPE[1], SHAPE[0])
MOTION16 = SpeckleMotion(SHAPE, step=(1, 2), max_displacement=5, bit_depth=16, seed=7)


@pytest.mark.parametrize("text, trigger", [
    ("free", Trigger("free")), ("software", Trigger("software")), ("line:1", Trigger("line", 1, "rising")),
    ("Line:0:FALLING", Trigger("line", 0, "falling")),
])
def test_trigger_forms(text, trigger):
    assert parse_trigger("trigger", text) == trigger


@pytest.mark.parametrize("text", ["hardware", "line", "line:x", "line:1:both", "software:2", ""])
def test_bad_trigger_forms_name_the_valid_ones(text):
    with pytest.raises(SourceError, match=r"trigger=free, trigger=software or trigger=line:N\[:rising\|falling\]"):
        parse_trigger("trigger", text)


def test_features_are_set_by_their_type_read_back_and_reported():
    with InProcessFakeCamera(MOTION16):
        options = {"feature.GainRaw": "7", "feature.ExposureTimeAbs": "2500.5", "feature.TestBoolean": "1",
                   "feature.GainAuto": "off", "feature.TestStringReg": "specimen-12"}
        with open_uri("aravis:Fake_1", roi=ROI, **options) as camera:
            features = camera.settings["features"]
            direct = (camera._camera.get_integer("GainRaw"), camera._camera.get_float("ExposureTimeAbs"),
                      camera._camera.get_boolean("TestBoolean"), camera._camera.get_string("GainAuto"),
                      camera._camera.get_string("TestStringReg"))
            frame = next(iter(camera))
    assert features == {"GainRaw": {"asked": 7, "read": 7}, "ExposureTimeAbs": {"asked": 2500.5, "read": 2500.0},
                        "TestBoolean": {"asked": True, "read": True}, "GainAuto": {"asked": "Off", "read": "Off"},
                        "TestStringReg": {"asked": "specimen-12", "read": "specimen-12"}}
    assert direct == (7, 2500.0, True, "Off", "specimen-12")      # the camera holds what was read back
    assert frame.image.shape == SHAPE
    # the exposure register holds whole microseconds: a note, not an error
    assert camera.settings["exposure_us"] == 2500.0


@pytest.mark.parametrize("option, message", [
    ("feature.NoSuchFeature=1", "this camera has no GenICam feature 'NoSuchFeature'"),
    ("feature.TriggerSoftware=1", "TriggerSoftware is a command, not a value"),
    ("feature.SensorWidth=100", "SensorWidth is read-only"),
    ("feature.GainRaw=50", "outside GainRaw's range [0, 10]"),
    ("feature.GainRaw=high", "not an integer"),
    ("feature.TestBoolean=maybe", "not a boolean"),
    ("feature.AcquisitionMode=Forever", "AcquisitionMode offers Continuous, SingleFrame, MultiFrame"),
    ("feature.=1", "unknown aravis option(s) feature."),
])
def test_an_unknown_feature_or_refused_value_is_one_clear_error(option, message):
    with InProcessFakeCamera(MOTION16), pytest.raises(SourceError) as caught:
        open_uri(f"aravis:Fake_1?{option}").close()
    text = str(caught.value)
    assert message in text and "\n" not in text, text


@pytest.mark.parametrize("pixel_format", ["Mono8", "Mono10", "Mono12", "Mono16", "Mono10p", "Mono12p",
                                          "Mono10Packed", "Mono12Packed"])
def test_every_bit_depth_and_packing_arrives_as_the_camera_sent_it(pixel_format, extended_xml):
    fmt = FORMATS[pixel_format]
    with InProcessFakeCamera(MOTION16, genicam=extended_xml) as fake:
        with open_uri(fake.uri, roi=ROI, pixel_format=pixel_format, frame_rate=100) as camera:
            settings = camera.settings
            frames = [frame for frame, _ in zip(camera, range(3))]
    assert settings["pixel_format"] == pixel_format and settings["bit_depth"] == fmt.bit_depth
    assert settings["frame_pixel_format"] == f"Mono{fmt.bit_depth}"
    for frame in frames:
        assert frame.pixel_format == f"Mono{fmt.bit_depth}" and frame.metadata["bit_depth"] == fmt.bit_depth
        assert frame.image.dtype == fmt.dtype and frame.image.shape == SHAPE
        expected = served_as(MOTION16(frame.index), fmt.bit_depth)           # 12-bit: values 0..4095
        assert np.array_equal(frame.image, expected), f"{pixel_format} frame {frame.index}"
        assert int(frame.image.max()) < 1 << fmt.bit_depth


def test_user_set_default_is_loaded_and_another_can_be_asked(extended_xml):
    with InProcessFakeCamera(MOTION16, genicam=extended_xml) as fake:
        with open_uri(fake.uri, roi=ROI) as camera:
            loaded = (camera.settings["user_set"], camera._camera.get_integer("UserSetLoadRegister"),
                      camera._camera.get_string("UserSetSelector"))
        with open_uri(fake.uri, roi=ROI, user_set="UserSet1") as camera:
            chosen = (camera.settings["user_set"], camera._camera.get_string("UserSetSelector"))
        with open_uri(fake.uri, roi=ROI, user_set="none") as camera:
            skipped = (camera.settings["user_set"], camera._camera.get_integer("UserSetLoadRegister"))
        with pytest.raises(SourceError, match="user_set=Factory: camera .* offers Default, UserSet1"):
            open_uri(fake.uri, user_set="Factory")
    assert loaded == ("Default", 1, "Default")      # UserSetSelector=Default, then UserSetLoad executed
    assert chosen == ("UserSet1", "UserSet1")
    assert skipped == (None, 0)


def test_a_camera_without_user_sets_is_reset_setting_by_setting():
    with InProcessFakeCamera(MOTION16):
        with open_uri("aravis:Fake_1") as camera:
            settings = camera.settings
        with pytest.raises(SourceError, match="user_set=UserSet1: camera .* has no user sets"):
            open_uri("aravis:Fake_1", user_set="UserSet1")
    assert settings["user_set"] is None
    # the power-on ROI of the Fake camera is 512x512: livedic opens the full sensor, binning 1, Mono8, free running
    assert settings["roi"] == [0, 0, 2048, 2048] and settings["found_at_open"]["roi"] == [0, 0, 512, 512]
    assert settings["binning"] == [1, 1] and settings["pixel_format"] == "Mono8" and settings["bit_depth"] == 8
    assert settings["trigger"]["mode"] == "Off"
    assert any("roi 0,0,512,512 -> 0,0,2048,2048" in note for note in settings["notes"]), settings["notes"]


def test_binning_is_set_and_read_back():
    with InProcessFakeCamera(MOTION16):
        with open_uri("aravis:Fake_1?binning=2&roi=0,0,64,48") as camera:
            square = camera.settings["binning"]
        with open_uri("aravis:Fake_1?binning=4,1&roi=0,0,64,48") as camera:
            wide = camera.settings["binning"]
        with pytest.raises(SourceError, match="option binning='0': must be >= 1"):
            open_uri("aravis:Fake_1?binning=0")
        with pytest.raises(SourceError, match=r"binning \(BinningHorizontal\)=17 is outside"):
            open_uri("aravis:Fake_1?binning=17")
        with pytest.raises(SourceError, match="exceed the sensor 1024x1024 \\(binned 2x2\\)"):
            open_uri("aravis:Fake_1?binning=2&roi=1000,0,100,100")
    assert square == [2, 2] and wide == [4, 1]


def test_triggers_are_set_through_the_standard_features_and_read_back(extended_xml):
    with InProcessFakeCamera(MOTION16, genicam=extended_xml) as fake:
        with open_uri(fake.uri, roi=ROI, trigger="line:1:falling") as camera:
            line = camera.settings
        with open_uri(fake.uri, roi=ROI, trigger="software", frame_rate=40) as camera:
            software = camera.settings
    assert line["trigger"] == {"selector": "FrameStart", "mode": "On", "source": "Line1", "activation": "FallingEdge"}
    assert line["requested"]["trigger"] == "line:1:falling" and line["timeout_s"] is None   # waits for the hardware
    assert software["trigger"]["mode"] == "On" and software["trigger"]["source"] == "Software"
    assert software["software_trigger_rate"] == 40 and software["timeout_s"] == 0.5


@pytest.mark.parametrize("trigger, message", [
    ("line:0:falling", "trigger=line:0:falling: this camera's TriggerActivation offers RisingEdge, not FallingEdge"),
    ("line:3", "trigger=line:3:rising: this camera's TriggerSource offers Line0, Software, not Line3"),
])
def test_a_trigger_the_camera_lacks_is_refused(trigger, message):
    with InProcessFakeCamera(MOTION16), pytest.raises(SourceError) as caught:
        open_uri("aravis:Fake_1", trigger=trigger)
    assert message in str(caught.value)


def test_the_metadata_records_what_the_camera_reported():
    with InProcessFakeCamera(MOTION16):
        with open_uri("aravis:Fake_1?roi=0,0,128,96&exposure_us=3000&feature.GainRaw=2") as camera:
            settings = camera.settings
    for key in ("vendor", "model", "serial", "firmware", "device_version", "sensor_size", "pixel_format",
                "bit_depth", "exposure_us", "gain_db", "frame_rate", "trigger", "binning", "roi", "features",
                "user_set", "notes"):
        assert key in settings, key
    assert settings["model"] == "Fake" and settings["serial"] == "1" and settings["sensor_size"] == [2048, 2048]
    assert settings["exposure_us"] == 3000 and settings["gain_db"] == 2 and settings["features"]["GainRaw"]["read"] == 2
    assert settings["device_version"] and settings["firmware"] is None     # the fake has no DeviceFirmwareVersion
