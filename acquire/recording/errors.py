"""The one error type a recording reader raises (``RecordingError``, a ``ValueError`` of one line naming the
file) and its subclasses, which say the problem for callers that act on it.
"""

from livedic.acquire.base import SourceError

__all__ = ["CorruptRecording", "NoSessionMetadata", "NotLivedic", "NotMcap", "RecordingError", "RecordingSourceError"]


class RecordingError(ValueError):
    """A recording that cannot be read as asked; the message is one line naming the file."""


class NotMcap(RecordingError):
    """Not an MCAP file: empty, other content, or cut inside the MCAP header."""


class NotLivedic(RecordingError):
    """An MCAP file that livedic did not write (no ``/camera/image`` RawImage channel)."""


class CorruptRecording(RecordingError):
    """A record, chunk or message that does not decode; ``recover`` can rewrite what is readable."""


class NoSessionMetadata(RecordingError):
    """A livedic recording without its ``livedic.session`` metadata."""


class RecordingSourceError(SourceError, RecordingError):
    """``RecordingError`` raised by ``McapSource``: also a ``SourceError`` for the live pipeline."""
