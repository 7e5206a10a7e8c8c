"""Fixtures of the recording tests: one small recording shared by a test module."""

import pytest

from tests.acquire.recording.recordings import record


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """Six small frames; 128-byte chunks make the layout of a long recording in miniature: every frame
    in its own image chunk, the results (~100 bytes each) in a data chunk every two frames."""
    path = tmp_path_factory.mktemp("rec") / "small.mcap"
    images = record(path, shape=(48, 64), chunk_bytes=128)
    return path, images
