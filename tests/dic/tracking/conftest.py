"""Shared by the tracking tests: frames of the simulated translation source and the error against its truth."""

import numpy as np

from livedic.acquire.simulator.sources import SyntheticTranslateSource


def translate_frames(query):
    """The source and its frames for a ``synthetic:translate`` query (paced off)."""
    source = SyntheticTranslateSource(f"synthetic:translate?pace=0&{query}")
    with source:
        return source, list(source)


def errors_to_truth(frame, m):
    """Distance of each point's displacement from the frame's true one, px."""
    tu, tv = frame.metadata["truth"](m.x, m.y)
    return np.hypot(m.u - tu, m.v - tv)
