"""Tests of acquire/sources.py: ``open_source`` picks the backend by the URI scheme; bad URIs are one SourceError."""

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.recording.source import McapSource
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource
from livedic.acquire.sources import SCHEMES, USAGE, open_source, parse_scheme
from tests.acquire.recording.recordings import record


def test_open_source_dispatches_on_the_scheme(tmp_path):
    source = open_source("synthetic:translate?frames=2&size=64x64")
    assert isinstance(source, SyntheticTranslateSource)
    assert isinstance(open_source("synthetic:", frames=3, size=(96, 96)), SyntheticTensileSource)
    assert parse_scheme("recordings/x.mcap") == "mcap" and parse_scheme("VIDEO:a.mkv") == "video"
    with pytest.raises(SourceError, match="valid sources: synthetic"):
        open_source("webcam:0")
    with pytest.raises(SourceError, match="no scheme"):
        open_source("frames/*.png")
    with pytest.raises(SourceError, match="empty"):
        open_source("  ")
    with pytest.raises(SourceError, match="needs a recording"):
        open_source("mcap:")
    with pytest.raises(SourceError, match="realtime"):
        open_source(f"mcap:{tmp_path / 'a.mcap'}?speed=2")
    with pytest.raises(SourceError):
        open_source(f"mcap:{tmp_path / 'missing.mcap'}")
    with pytest.raises(SourceError):
        open_source(f"images:{tmp_path / 'nothing_here_*.png'}")


@pytest.mark.parametrize("uri, scheme", [
    ("synthetic:", "synthetic"), (" Aravis:cam-1 ", "aravis"), ("v4l2:/dev/video0", "v4l2"), ("video:a.mkv", "video"),
    ("images:frames/*.png", "images"), ("mcap:x.mcap", "mcap"), ("x.mcap", "mcap"), ("/data/run 1.mcap", "mcap"),
])
def test_every_scheme_is_recognised_whatever_its_case(uri, scheme):
    assert parse_scheme(uri) == scheme and scheme in SCHEMES


@pytest.mark.parametrize("uri", ["", None, "webcam:0", "frames.png", "C:/data/x.png"])
def test_bad_uris_list_the_valid_sources(uri):
    with pytest.raises(SourceError) as error:
        parse_scheme(uri)
    assert str(error.value).endswith(USAGE) and "\n" not in str(error.value)


def test_a_recording_opens_by_its_path_or_uri_with_its_realtime_option(tmp_path):
    path = tmp_path / "run.mcap"
    record(path, n=2)
    for uri, options, realtime in ((str(path), {}, False), (f"mcap:{path}?realtime=1", {}, True),
                                   (f"mcap://{path}?realtime=1", {"realtime": "0"}, False)):
        with open_source(uri, **options) as source:
            assert isinstance(source, McapSource) and source.realtime is realtime, uri
            assert source.path == str(path)
    with pytest.raises(SourceError, match="realtime='sometimes'"):
        open_source(f"mcap:{path}", realtime="sometimes")
