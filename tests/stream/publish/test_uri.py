"""Tests of stream/publish/uri.py: --publish URIs parsed into targets, every error one line naming the option."""

import pytest

from livedic.stream.publish.uri import (DEFAULT_HOST, DEFAULT_LINGER_S, MAX_LINGER_S, PublishTarget,
                                        parse_publish_uri, parse_publish_uris)


@pytest.mark.parametrize("text, scheme, host, port", [
    ("udp://127.0.0.1:9870", "udp", "127.0.0.1", 9870),
    ("udp://:9870", "udp", "127.0.0.1", 9870),                    # no host: loopback, never every interface
    ("UDP://localhost:9870", "udp", "localhost", 9870),
    ("modbus://:5020", "modbus", "127.0.0.1", 5020),
    ("modbus://0.0.0.0:5020", "modbus", "0.0.0.0", 5020),
    ("modbus://[::1]:5020/", "modbus", "::1", 5020),
    ("modbus://127.0.0.1:0", "modbus", "127.0.0.1", 0),            # any free port, said at the start
])
def test_publish_uris_parse(text, scheme, host, port):
    target = parse_publish_uri(text)
    assert (target.scheme, target.host, target.port) == (scheme, host, port)


@pytest.mark.parametrize("text, message", [
    ("127.0.0.1:9870", "expected udp://HOST:PORT or modbus://HOST:PORT"),
    ("tcp://127.0.0.1:9870", "unknown scheme 'tcp'"),
    ("udp://127.0.0.1", "a port is needed"),
    ("udp://127.0.0.1:0", "port must be 1..65535, got 0"),
    ("udp://127.0.0.1:70000", "Port out of range"),
    ("udp://127.0.0.1:abc", "Port could not be cast"),
    ("modbus://127.0.0.1:5020?register=3", "only HOST:PORT may follow modbus://"),
    ("udp://127.0.0.1:9870/strain", "only HOST:PORT may follow udp://"),
])
def test_bad_publish_uris_are_one_line(text, message):
    with pytest.raises(ValueError, match=None) as error:
        parse_publish_uri(text)
    assert message in str(error.value) and "\n" not in str(error.value)
    assert str(error.value).startswith("--publish ")


@pytest.mark.parametrize("text, linger_s", [
    ("modbus://:5020", DEFAULT_LINGER_S),
    ("modbus://:5020?linger_s=2.5", 2.5),
    ("modbus://:5020/?linger_s=0", 0.0),                                   # close at once
    ("udp://:9870", DEFAULT_LINGER_S),                                     # (unused: UDP has no end state)
])
def test_the_modbus_linger_is_a_uri_option(text, linger_s):
    assert parse_publish_uri(text).linger_s == linger_s


@pytest.mark.parametrize("text, message", [
    ("modbus://:5020?linger_s=-1", "linger_s must be seconds in 0..60, got '-1'"),
    ("modbus://:5020?linger_s=61", "linger_s must be seconds in 0..60"),
    ("modbus://:5020?linger_s=nan", "linger_s must be seconds in 0..60"),
    ("modbus://:5020?linger_s=soon", "linger_s must be seconds in 0..60, got 'soon'"),
    ("modbus://:5020?linger=1", "only HOST:PORT may follow modbus://, and ?linger_s=SECONDS"),
    ("modbus://:5020?linger_s=1&register=3", "only HOST:PORT may follow modbus://"),
    ("udp://:9870?linger_s=1", "only HOST:PORT may follow udp://"),
])
def test_bad_linger_options_are_one_line(text, message):
    with pytest.raises(ValueError) as error:
        parse_publish_uri(text)
    assert message in str(error.value) and "\n" not in str(error.value) and str(error.value).startswith("--publish ")



def test_the_same_target_twice_is_refused():
    with pytest.raises(ValueError, match="given twice"):
        parse_publish_uris(["udp://:9870", "udp://127.0.0.1:9870"])
    assert len(parse_publish_uris(["udp://:9870", "modbus://:9870"])) == 2


def test_a_parsed_target_keeps_the_uri_as_given_and_describes_the_host_as_used():
    target = parse_publish_uri("  modbus://[::1]:5020?linger_s=3 ")
    assert target == PublishTarget(uri="modbus://[::1]:5020?linger_s=3", scheme="modbus", host="::1", port=5020,
                                   linger_s=3.0)
    assert target.describe() == "modbus://[::1]:5020"                  # IPv6 in brackets
    assert parse_publish_uri("udp://:9870").describe() == f"udp://{DEFAULT_HOST}:9870"


def test_the_linger_bounds_are_inclusive():
    assert parse_publish_uri(f"modbus://:5020?linger_s={MAX_LINGER_S:g}").linger_s == MAX_LINGER_S
    assert PublishTarget(uri="u", scheme="udp", host="h", port=1).linger_s == DEFAULT_LINGER_S


def test_port_0_may_be_given_twice_and_nothing_given_is_no_target():
    """Port 0 is "any free port": two of them are two servers, never the same one."""
    assert [t.port for t in parse_publish_uris(["modbus://:0", "modbus://127.0.0.1:0"])] == [0, 0]
    assert parse_publish_uris([]) == ()
    with pytest.raises(ValueError, match=r"^--publish modbus://127\.0\.0\.1:5020 is given twice$"):
        parse_publish_uris(["modbus://:5020", "MODBUS://127.0.0.1:5020"])
