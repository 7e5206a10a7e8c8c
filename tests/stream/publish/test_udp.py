"""Tests of stream/publish/udp.py: one JSON datagram per frame to the target, a host that does not resolve refused."""

import json
import socket

import pytest

from livedic.stream.publish import udp
from livedic.stream.publish.udp import UdpOutlet
from livedic.stream.publish.uri import parse_publish_uri
from tests.stream.publish.test_values import _values


@pytest.fixture
def receiver():
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(10)
    yield receiver
    receiver.close()


def test_each_send_is_one_datagram_holding_the_frames_json(receiver):
    port = receiver.getsockname()[1]
    outlet = UdpOutlet(parse_publish_uri(f"udp://:{port}"))
    try:
        assert outlet.where == f"udp://127.0.0.1:{port}" and outlet.where in outlet.note()
        assert outlet.socket.getblocking() is False                     # never waits in the tracker thread
        outlet.send(_values(), update_count=1)
        outlet.send(_values(valid=(True, True)), update_count=2)
        first, second = receiver.recv(65536), receiver.recv(65536)
        outlet.finish()                                                 # nothing more goes out
    finally:
        outlet.close()
    assert first == _values().as_json()
    assert second == _values(valid=(True, True)).as_json()             # in order, one frame a datagram
    assert json.loads(second)["strain"]["transverse"] is None
    assert outlet.socket.fileno() == -1


def test_a_name_goes_to_its_ipv4_address_first(monkeypatch, receiver):
    """"localhost" is ::1 first on many systems; a controller most often listens on IPv4."""
    port = receiver.getsockname()[1]
    real = socket.getaddrinfo

    def ipv6_first(host, *args, **kwargs):
        infos = real("127.0.0.1", *args, **kwargs)
        return [(socket.AF_INET6, socket.SOCK_DGRAM, 17, "", ("::1", port, 0, 0))] + list(infos)

    monkeypatch.setattr(udp.socket, "getaddrinfo", ipv6_first)
    outlet = UdpOutlet(parse_publish_uri(f"udp://localhost:{port}"))
    try:
        assert outlet.address == ("127.0.0.1", port) and outlet.socket.family == socket.AF_INET
    finally:
        outlet.close()


def test_a_host_that_does_not_resolve_is_one_line(monkeypatch):
    def fail(*args, **kwargs):
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(udp.socket, "getaddrinfo", fail)
    with pytest.raises(ValueError) as error:
        UdpOutlet(parse_publish_uri("udp://nowhere.invalid:9870"))
    assert str(error.value) == ("--publish udp://nowhere.invalid:9870: cannot resolve host 'nowhere.invalid' "
                                "(Name or service not known)")
