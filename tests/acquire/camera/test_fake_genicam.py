"""Tests of acquire/camera/fake_genicam.py: the in-process fake serves our images; the extended GenICam description."""

import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera import fake_genicam, pixel_formats
from livedic.acquire.camera.aravis import FAKE_FILL_HOOKS, open_uri
from livedic.acquire.camera.fake_genicam import InProcessFakeCamera, extended_genicam_xml

pytestmark = pytest.mark.usefixtures("time_limit", "aravis")


def _enumeration(root, name):
    node = next(n for n in root.iter() if n.tag.endswith("Enumeration") and n.get("Name") == name)
    return {entry.get("Name"): int(entry.find("{*}Value").text, 0) for entry in node if entry.tag.endswith("EnumEntry")}


def test_the_extended_description_adds_formats_triggers_and_user_sets_to_the_fakes_own():
    root = ElementTree.fromstring(extended_genicam_xml().encode())
    formats = _enumeration(root, "PixelFormat")
    assert {"Mono8", "Mono16"} <= set(formats)                          # the fake's own are kept
    for name in ("Mono10", "Mono12", "Mono10p", "Mono12p", "Mono10Packed", "Mono12Packed"):
        assert formats[name] == pixel_formats.FORMATS[name].code, name
    assert _enumeration(root, "TriggerSource")["Line1"] == 2
    assert _enumeration(root, "TriggerActivation")["FallingEdge"] == 1
    assert _enumeration(root, "UserSetSelector") == {"Default": 0, "UserSet1": 1}
    assert any(n.get("Name") == "UserSetLoad" for n in root.iter() if n.tag.endswith("Command"))


def test_a_changed_aravis_description_is_named_not_silently_unextended():
    with pytest.raises(SourceError, match="Aravis's fake-camera XML has changed: '<missing/>' not found"):
        fake_genicam._insert_before("<xml/>", "<missing/>", "<added/>")


def test_each_open_gets_its_own_pattern_counting_from_zero(extended_xml):
    served = lambda k: np.full((48, 64), 40 + k, np.uint8)            # noqa: E731 - the image of frame k
    with InProcessFakeCamera(served, genicam=extended_xml) as fake:
        assert FAKE_FILL_HOOKS["Fake_1"] == fake._attach and fake.uri == "aravis:Fake_1"
        for _ in range(2):
            with open_uri(fake.uri, roi=(0, 0, 64, 48), pixel_format="Mono12") as camera:
                frame = next(iter(camera))
            assert frame.image.dtype == np.uint16 and int(frame.image[0, 0]) == (40 + frame.index) * 4095 // 255
        assert len(fake.patterns) == 2 and all(p.frames_served >= 1 and p.errors == 0 for p in fake.patterns)
    assert "Fake_1" not in FAKE_FILL_HOOKS
    with InProcessFakeCamera(served) as fake, pytest.raises(SourceError, match="not offered"):
        open_uri(fake.uri, pixel_format="Mono12")                      # Aravis's own description again
