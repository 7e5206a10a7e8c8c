"""The session's warm-up compiles every kernel the tracker uses, so none compiles mid-session.

On a fresh installation (no numba disk cache) a kernel first met during a session
compiles there, several seconds for the parallel ones: frames queue up and are dropped
(seen: a 6.4 s stall, 6 of 150 frames dropped, in the main job's first run). Counted
here as compiled signatures, not time.
"""

import sys

import numpy as np
from numba.core.registry import CPUDispatcher

from livedic.acquire.simulator.sources import SyntheticTensileSource
from livedic.dic.tracking import grid_in_roi, step_for_count
from livedic.stream.cli import build_parser
from livedic.stream.session.config import SessionConfig
from livedic.stream.session.session import warm_up


def _compiled():
    counts = {}
    for name, module in list(sys.modules.items()):
        if name.startswith("livedic.dic") or name.startswith("livedic.stream"):
            for attr, obj in vars(module).items():
                if isinstance(obj, CPUDispatcher):
                    counts[f"{name}.{attr}"] = len(obj.signatures)
    return counts


def test_no_tracking_kernel_compiles_after_the_warm_up():
    config = SessionConfig.from_args(build_parser().parse_args(["run"]))
    source = SyntheticTensileSource("synthetic:tensile?frames=40&size=384x384&pace=0")
    source.prepare()
    frames = list(source)
    warm_up(config.tracking)
    before = _compiled()
    roi = source.suggested_roi
    points = grid_in_roi(frames[0].image.shape, roi, step_for_count(roi, 400, 21), 21)
    tracker = config.tracking.tracker(frames[0].image, points)
    for frame in frames:
        tracker.track(frame.image)
    tracker.track(np.roll(frames[-1].image, (6, -5), axis=(0, 1)))      # a knock: re-finds
    new = {name: count for name, count in _compiled().items() if count > before.get(name, 0)}
    assert not new, f"compiled during the session, not in the warm-up: {sorted(new)}"
