"""Tests of acquire/camera/aravis_discovery.py: aravis: URIs split, listed cameras found by id, serial or MAC."""

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera.aravis_discovery import (address_text, find_listed, interface_name, is_ip_address,
                                                     load_aravis, parse_uri)

pytestmark = pytest.mark.usefixtures("time_limit")


def test_uri_parsing():
    assert parse_uri("aravis:") == (None, {})
    assert parse_uri("aravis:Fake_1?exposure_us=2000&roi=0,0,64,64") == (
        "Fake_1", {"exposure_us": "2000", "roi": "0,0,64,64"})
    assert parse_uri("aravis://192.168.1.20?packet_size=8000") == ("192.168.1.20", {"packet_size": "8000"})
    with pytest.raises(SourceError, match="not an Aravis URI"):
        parse_uri("v4l2:/dev/video0")


def test_uri_scheme_case_blank_values_and_a_missing_scheme():
    assert parse_uri("ARAVIS:cam?trigger=&roi=1%2C2%2C3%2C4") == ("cam", {"trigger": "", "roi": "1,2,3,4"})
    for bad in (None, "aravis", "genicam:cam"):
        with pytest.raises(SourceError, match="not an Aravis URI"):
            parse_uri(bad)


CAMERAS = [
    {"id": "Aravis-Fake-1", "serial": "1", "physical_id": None, "protocol": "Fake"},
    {"id": "Basler-acA1920-4031", "serial": "4031", "physical_id": "00:30:53:AA:BB:CC", "protocol": "GigEVision"},
    {"id": "FLIR-BFS-77", "serial": "77", "physical_id": "", "protocol": "USB3Vision"},
]


@pytest.mark.parametrize("device_id, found", [
    (None, "Basler-acA1920-4031"), ("basler-aca1920-4031", "Basler-acA1920-4031"), (" 77 ", "FLIR-BFS-77"),
    ("00:30:53:aa:bb:cc", "Basler-acA1920-4031"), ("Aravis-Fake-1", "Aravis-Fake-1"), ("nobody", None),
    ("", "Basler-acA1920-4031"), ("  ", "Basler-acA1920-4031"),
])
def test_a_camera_is_found_by_id_serial_or_mac_and_the_first_real_one_by_default(device_id, found):
    camera = find_listed(CAMERAS, device_id)
    assert (camera["id"] if camera else None) == found


def test_with_only_a_fake_or_nothing_listed():
    assert find_listed(CAMERAS[:1], None)["id"] == "Aravis-Fake-1" and find_listed([], None) is None


def test_interfaces_addresses_and_the_gi_modules():
    assert [interface_name(p) for p in ("GigEVision", "USB3Vision", "Fake", "CoaXPress", None)] == [
        "gige", "usb3", "fake", "coaxpress", "?"]
    assert is_ip_address("192.168.1.20") and is_ip_address("::1") and not is_ip_address("cam-1")

    class _Inet:
        def get_address(self):
            return self

        def to_string(self):
            return "10.0.0.7"

    assert address_text(_Inet) == "10.0.0.7" and address_text(lambda: 1 / 0) is None


def test_aravis_is_loaded_once(aravis):
    assert load_aravis() is load_aravis() and load_aravis()[0].__name__.endswith("Aravis")
