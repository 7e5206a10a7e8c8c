"""Moved: the recording format lives in ``livedic.acquire.recording_schema``.

Kept only for ``bench/soak.py`` until it imports ``livedic.acquire.recording_schema``;
delete this module then.
"""

from livedic.acquire.recording_schema import *  # noqa: F401,F403
