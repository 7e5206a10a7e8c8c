"""``stream.pipeline.key_frame_builder``: key frames' trackers built between frames by whoever runs the pending
builds (the tracking loop), never in the call that moves the reference, never by the acquisition."""

import threading

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.tracking import Tracker
from livedic.dic.tracking.key_frames import KeyFrameTracker
from livedic.stream.pipeline.key_frame_builder import DeferredBuild, KeyFrameBuilder

PATTERN = SpecklePattern((128, 128), n_speckles=300, radius=3.0, seed=5)
POINTS = np.array([(x, y) for y in range(40, 89, 12) for x in range(40, 89, 12)], dtype=np.float64)


def _frames(n):
    return [render(PATTERN, affine(vy=0.005 * i, centre=(64.0, 64.0))) for i in range(n)]


def test_a_deferred_build_runs_once_when_run_or_when_its_result_is_asked_for():
    calls = []
    builder = KeyFrameBuilder()
    first = builder.submit(lambda x: calls.append(x) or x * 2, 3)
    second = builder.submit(lambda: calls.append("second") or "b")
    assert not first.done() and not second.done() and calls == []
    assert second.result() == "b" and calls == ["second"]         # asked for: built in the asking call
    builder.run_pending()
    assert first.done() and first.result() == 6 and calls == ["second", 3]   # each built once
    failing = builder.submit(lambda: 1 / 0)
    builder.run_pending()
    with pytest.raises(ZeroDivisionError):
        failing.result()


def test_a_build_run_by_two_threads_at_once_runs_once():
    started, release, calls = threading.Event(), threading.Event(), []

    def slow():
        calls.append(1)
        started.set()
        release.wait(5)
        return "built"

    deferred = DeferredBuild(slow, (), {})
    runner = threading.Thread(target=deferred.run)
    runner.start()
    started.wait(5)
    deferred.run()                                   # the other thread is building it: returns at once
    assert not deferred.done()
    release.set()
    assert deferred.result(timeout=5) == "built" and calls == [1]
    runner.join(5)


def test_moves_are_built_between_frames_with_the_same_results():
    """The frame that moves the reference returns before the new tracker is built, ``coefficients_ahead`` does not
    build it (None), ``run_pending`` does; every result is bit for bit the one of a tracker building in its calls."""
    frames = _frames(7)
    inline = KeyFrameTracker(frames[0], POINTS, reference_update="every:2")
    tracker = KeyFrameTracker(frames[0], POINTS, reference_update="every:2")
    builder = KeyFrameBuilder()
    builder.attach(tracker)
    builder.attach(Tracker(frames[0], POINTS))        # a plain tracker has no key frames: left alone
    built_by = []
    original = Tracker.__init__

    def recording_init(self, *args, **kwargs):
        built_by.append("run_pending" if running.is_set() else "elsewhere")
        original(self, *args, **kwargs)

    running = threading.Event()
    Tracker.__init__ = recording_init
    try:
        for image in frames:
            expected = inline.track(image)
            got = tracker.track(image)
            for name in ("u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy"):
                np.testing.assert_array_equal(getattr(got, name), getattr(expected, name), err_msg=name)
            if tracker.last_update is not None:
                assert not tracker._slot.done()                       # the move did not build
                assert tracker.coefficients_ahead(image) is None      # nor does a frame's acquisition
            running.set()
            builder.run_pending()
            running.clear()
    finally:
        Tracker.__init__ = original
    moves = len(tracker.updates)
    assert moves >= 2
    assert built_by.count("run_pending") == moves      # every move's tracker built by run_pending
    builder.close()
    assert tracker._executor is None                   # builds in its own calls again
    tracker.track(frames[-1])
