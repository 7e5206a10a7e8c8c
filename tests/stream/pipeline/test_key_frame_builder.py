"""``stream.pipeline.key_frame_builder``: one thread builds the key frames' trackers, and it ends with the session."""

import threading

import numpy as np

from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.tracking import Tracker
from livedic.dic.tracking.key_frames import KeyFrameTracker
from livedic.stream.pipeline.key_frame_builder import KeyFrameBuilder

PATTERN = SpecklePattern((128, 128), n_speckles=300, radius=3.0, seed=5)
POINTS = np.array([(x, y) for y in range(40, 89, 12) for x in range(40, 89, 12)], dtype=np.float64)


def _builder_threads():
    return [t for t in threading.enumerate() if t.name.startswith("livedic-key-frames")]


def test_the_builder_builds_moves_on_its_thread_and_ends_with_close():
    reference = render(PATTERN)
    tracker = KeyFrameTracker(reference, POINTS, reference_update="every:2")
    built_on = []
    original = Tracker.__init__

    def recording_init(self, *args, **kwargs):
        built_on.append(threading.current_thread().name)
        original(self, *args, **kwargs)

    builder = KeyFrameBuilder(1)
    assert len(_builder_threads()) == 1                   # started at once, before any move
    Tracker.__init__ = recording_init
    try:
        builder.attach(tracker)
        builder.attach(Tracker(reference, POINTS))        # a plain tracker has no key frames: left alone
        for strain in (0.0, 0.005, 0.01, 0.015):
            tracker.track(render(PATTERN, affine(vy=strain, centre=(64.0, 64.0))))
        builder.close()                                   # waits for the last move's build
    finally:
        Tracker.__init__ = original
    assert len(tracker.updates) >= 1
    # build_on's two first builds, then one per move, every one on the builder's thread (the plain tracker's
    # own construction above ran here, in this thread)
    assert built_on[0:2] == [built_on[0]] * 2 and built_on[0].startswith("livedic-key-frames")
    assert [name for name in built_on[2:] if not name.startswith("livedic-key-frames")] == ["MainThread"]
    assert len(built_on) == 2 + 1 + len(tracker.updates)
    assert not _builder_threads()                         # ended
    assert tracker._executor is None                      # builds in its own calls again
    tracker.track(render(PATTERN, affine(vy=0.02, centre=(64.0, 64.0))))
