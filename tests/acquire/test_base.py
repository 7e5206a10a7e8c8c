"""Tests of acquire/base.py: the Frame record, the source errors and what every FrameSource shares."""

import dataclasses

import numpy as np
import pytest

from livedic.acquire.base import Frame, FrameSource, NoFirstFrame, SourceError, SourceLost


class _Counting(FrameSource):
    uri = "count:"

    def __init__(self, n):
        self.n, self.closed = n, 0

    def __iter__(self):
        for i in range(self.n):
            yield Frame(i, i * 10, np.full((2, 3), i, np.uint8), "Mono8")

    def close(self):
        self.closed += 1


def test_a_frame_is_frozen_and_its_metadata_is_its_own():
    first = Frame(0, 5, np.zeros((2, 2), np.uint8), "Mono8")
    second = Frame(1, 6, np.zeros((2, 2), np.uint8), "Mono8")
    first.metadata["truth_u"] = 0.5
    assert second.metadata == {} and first.metadata == {"truth_u": 0.5}
    with pytest.raises(dataclasses.FrozenInstanceError):
        first.index = 3


def test_a_source_closes_on_leaving_its_block_even_on_an_error_and_does_not_swallow_it():
    with pytest.raises(KeyError):
        with _Counting(3) as source:
            assert [f.index for f in source] == [0, 1, 2]
            raise KeyError("consumer failed")
    assert source.closed == 1
    assert not source.live and source.settings == {} and FrameSource.close(source) is None


def test_an_abstract_source_cannot_be_made():
    with pytest.raises(TypeError):
        FrameSource()


def test_the_errors_tell_never_started_from_lost_and_keep_what_to_check():
    error = NoFirstFrame("no frame in 10 s", checks=iter(["the trigger", "the packet size"]))
    assert error.checks == ("the trigger", "the packet size") and str(error) == "no frame in 10 s"
    assert NoFirstFrame("x").checks == ()
    for kind in (NoFirstFrame, SourceLost):
        assert issubclass(kind, SourceError) and issubclass(kind, RuntimeError)
    assert not issubclass(NoFirstFrame, SourceLost) and not issubclass(SourceLost, NoFirstFrame)
