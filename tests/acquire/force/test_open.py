"""Tests of acquire/force/open.py: a load URI opens the source it names; every bad URI or option is one line."""

import pytest

from livedic.acquire.force import LoadError, open_load
from livedic.acquire.force.csv_file import CsvLoad
from livedic.acquire.force.open import LOAD_USAGE
from livedic.acquire.force.simulated import SyntheticLoad
from livedic.acquire.force.tcp import TcpLoad
from tests.acquire.force.loads import free_port, loading, write_csv


@pytest.mark.parametrize("uri, where", [
    ("modbus://127.0.0.1:502?scale=0.1", "register= is required"),
    ("synthetic", "pass source="),
    ("synthetic:translate", "has no force"),
    ("synthetic:tensile?frames=1", "frames"),
    ("synthetic:tensile?hardening=-1", "hardening"),
    ("udp://host:1", "unknown load"),
    ("", "empty"),
    ("csv:", "names no file"),
    ("tcp://localhost", "tcp://HOST:PORT"),
    ("tcp://localhost:99999", "tcp://HOST:PORT"),
    ("tcp://localhost:5000?clock=camera", "clock="),
    ("tcp://localhost:5000?rate=3", "unknown option"),
    ("tcp://localhost:5000?max_gap_s=-1", "max_gap_s"),
])
def test_bad_load_uris_are_one_line(uri, where):
    with pytest.raises(LoadError) as error:
        open_load(uri)
    assert "\n" not in str(error.value) and where in str(error.value), str(error.value)


@pytest.mark.parametrize("uri", ["udp://host:1", "", "   ", "file.csv"])
def test_unknown_or_empty_uris_list_the_valid_loads(uri):
    with pytest.raises(LoadError) as error:
        open_load(uri)
    assert str(error.value).endswith(LOAD_USAGE)


def test_each_scheme_opens_its_source_and_options_override_the_query(tmp_path):
    path = write_csv(tmp_path / "f.csv", [(0, 0), (1, 10)])
    with loading(f"  CSV:{path} ", offset_s="0.5", max_gap_s=2) as load:
        assert isinstance(load, CsvLoad) and load.offset_s == 0.5 and load.max_gap_s == 2.0
        assert load.uri == f"CSV:{path}"
    with loading(f"tcp://127.0.0.1:{free_port()}?max_gap_s=2", max_gap_s=0.25) as load:
        assert isinstance(load, TcpLoad) and load.max_gap_s == 0.25
    with loading("synthetic:tensile?frames=5&size=64x64") as load:
        assert isinstance(load, SyntheticLoad)


@pytest.mark.parametrize("options, where", [
    (dict(offset_s="soon"), "offset_s='soon'"),
    (dict(max_gap_s=0), "max_gap_s=0"),
    (dict(clock="sender"), "unknown option(s) clock; csv takes offset_s, max_gap_s"),
])
def test_bad_csv_options_are_one_line(tmp_path, options, where):
    path = write_csv(tmp_path / "f.csv", [(0, 0), (1, 10)])
    with pytest.raises(LoadError) as error:
        open_load(f"csv:{path}", **options)
    assert "\n" not in str(error.value) and where in str(error.value), str(error.value)
