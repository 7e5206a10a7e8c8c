"""Tests of acquire/recording/errors.py: one error type for readers, subclasses that say the problem."""

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.recording import errors


@pytest.mark.parametrize("name", errors.__all__)
def test_every_error_is_a_recording_error_and_a_value_error(name):
    error_type = getattr(errors, name)
    assert issubclass(error_type, errors.RecordingError) and issubclass(error_type, ValueError)


def test_problems_are_told_apart_by_type():
    problems = (errors.NotMcap, errors.NotLivedic, errors.CorruptRecording, errors.NoSessionMetadata)
    for problem in problems:
        assert [other for other in problems if issubclass(problem, other)] == [problem]
        assert not issubclass(problem, SourceError)


def test_the_source_error_is_caught_by_both_kinds_of_caller():
    error = errors.RecordingSourceError("x.mcap is corrupt")
    for caller_catches in (SourceError, errors.RecordingError, ValueError):
        with pytest.raises(caller_catches, match="x.mcap is corrupt"):
            raise error
