"""What the offline commands say, and how they read a recording's metadata: the reader's notes collected
as lines (``reader_notes``), the session metadata or a note of its absence (``session_or_note``), one
line on stderr (``say``), and counted words (``plural``).
"""

from __future__ import annotations

import logging
import os
import sys
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Iterator

if TYPE_CHECKING:
    from livedic.acquire.recording.reader import Recording


_READER_LOGGER = "livedic.acquire.recording.reader"


@contextmanager
def reader_notes() -> Iterator[list[str]]:
    """Collect the notes ``acquire.recording.reader`` logs (truncated file ...) instead of printing them raw.

    Yields a list that fills with one line per distinct note ("note: " prefix removed).
    The lines are for people; what a program acts on is the reader's ``RecordingInfo``.
    """
    notes: list[str] = []

    class _Collect(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            text = record.getMessage()
            text = text[len("note: "):] if text.startswith("note: ") else text
            if text not in notes:
                notes.append(text)

    logger = logging.getLogger(_READER_LOGGER)
    handler = _Collect(level=logging.INFO)
    previous = logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield notes
    finally:
        logger.removeHandler(handler)
        logger.propagate = previous


def session_or_note(recording: Recording) -> tuple[dict[str, Any], str]:
    """(session metadata dict, note or "") of a ``Recording``: one without metadata gives {} and a note."""
    from livedic.acquire.recording.errors import NoSessionMetadata
    try:
        return recording.session(), ""
    except NoSessionMetadata as missing:
        return {}, str(missing)


def read_session_or_note(path: str | os.PathLike[str]) -> tuple[dict[str, Any], str]:
    """``session_or_note`` of the recording at ``path`` (``RecordingError`` if it is not one)."""
    from livedic.acquire.recording.reader import Recording
    return session_or_note(Recording(path))


def say(message: str) -> None:
    print(f"livedic: {message}", file=sys.stderr, flush=True)


def plural(count: int, word: str) -> str:
    """``"1 frame"``, ``"3 frames"``."""
    return f"{count} {word}" + ("" if count == 1 else "s")
