"""``open_simulator(uri)``: the simulated camera any ``synthetic:`` URI names (the 2D tests of sources.py and one
camera of the stereo test, stereo_source.py, which builds on them: one place that knows both)."""

from __future__ import annotations

from typing import Any

from livedic.acquire.base import FrameSource
from livedic.acquire.simulator.options import parse_synthetic_uri


def open_simulator(uri: str, **options: Any) -> FrameSource:
    """``synthetic:``, ``synthetic:tensile?...``, ``synthetic:translate?...`` or ``synthetic:stereo?view=left|right&...``
    (keyword options override the URI's); SourceError names a bad one."""
    model, _ = parse_synthetic_uri(uri)
    if model == "stereo":
        from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource
        return SyntheticStereoViewSource(uri, **options)
    from livedic.acquire.simulator.sources import open_synthetic
    return open_synthetic(uri, **options)
