"""The tracking thread and the output thread (stream.pipeline.tracker_loop): who runs where, who waits for whom.

Behaviour, not timings: the sinks run off the tracking thread, in order, on every result; a view that
blocks cannot hold the tracker back; the stage times name each stage; a required sink's error ends the
loop and is raised; an optional one is switched off.
"""

import os
import threading

import numpy as np
import pytest

from livedic.acquire.base import FrameSource
from livedic.acquire.simulator.sources import SyntheticTranslateSource
from livedic.dic.tracking import Tracker
from livedic.stream.pipeline.acquisition import AcquisitionThread
from livedic.stream.pipeline.frame_queue import BLOCK, FrameQueue
from livedic.stream.pipeline.cores import core_split
from livedic.stream.pipeline.frame_result import reference_ready
from livedic.stream.pipeline.stage import Stage
from livedic.stream.pipeline.tracker_loop import OUTPUT_BACKLOG_MAX, TrackerLoop

FRAMES = 12
WAIT_S = 30.0          # generous: a wait that ends by timeout means the behaviour under test is broken


class _Stage(Stage):
    """A stage that runs ``handle(result)`` on each frame."""
    name = "test stage"

    def __init__(self, handle):
        self.handle = handle

    def on_frame(self, result):
        self.handle(result)


def _loop(frames=FRAMES, **options):
    source = SyntheticTranslateSource(f"synthetic:translate?frames={frames}&size=96x96&du=0.3&dv=0.2&pace=0")
    queue = FrameQueue(frames + 1)
    acquisition = AcquisitionThread(source, queue)
    loop = TrackerLoop(queue, lambda frame: Tracker(frame.image, [(40.0, 40.0), (56.0, 56.0)]), **options)
    acquisition.start()
    return loop, acquisition


def test_sinks_run_in_their_own_thread_in_order_and_stages_in_the_tracking_thread():
    threads = {"stage": set(), "sink": set()}
    seen = []

    def stage(result):
        threads["stage"].add(threading.get_ident())
        result.strain = "made by the stage"          # what a stage adds reaches the sinks

    def sink(result, stats):
        threads["sink"].add(threading.get_ident())
        seen.append((result.frame.index, result.strain))

    loop, acquisition = _loop(stages=[_Stage(stage)], sinks=[sink])
    loop.run()
    acquisition.join(5)
    assert threads["stage"] == {threading.get_ident()}
    assert len(threads["sink"]) == 1 and threads["sink"] != threads["stage"]
    assert seen == [(i, "made by the stage") for i in range(FRAMES)]     # every result, in order, complete


def test_a_blocked_view_cannot_hold_the_tracker_back():
    """The view blocks on its first result until the tracker has tracked every frame (an event the
    tracking thread sets): were the tracker to wait for the view, this would never end."""
    assert FRAMES < OUTPUT_BACKLOG_MAX
    all_tracked = threading.Event()
    got = []

    def counting(result):
        if result.frames_done == FRAMES:
            all_tracked.set()

    def blocked_view(result, stats):
        if not all_tracked.wait(WAIT_S):
            raise AssertionError("the tracker did not get through the frames while the view was blocked")
        got.append(result.output_backlog)

    loop, acquisition = _loop(stages=[_Stage(counting)], sinks=[blocked_view])
    stats = loop.run()
    acquisition.join(5)
    assert all_tracked.is_set() and stats.frames == FRAMES and not loop.sink_errors
    assert len(got) == FRAMES
    assert max(got) >= FRAMES // 2 and got[-1] == 0          # the view saw how far behind it was
    assert stats.output_backlog_max >= FRAMES - 1 and stats.output_waits == 0


def test_the_tracker_waits_for_a_view_more_than_the_backlog_behind(monkeypatch):
    """Past OUTPUT_BACKLOG_MAX results behind, the tracking thread waits (bounded memory), and counts it."""
    from livedic.stream.pipeline import tracker_loop as tracker_loop
    monkeypatch.setattr(tracker_loop, "OUTPUT_BACKLOG_MAX", 3)
    tick = threading.Event()

    def slow_view(result, stats):
        # holds the first result until the tracking thread is seen waiting for the output thread
        for _ in range(int(WAIT_S / 0.01)):
            if stats.output_waits or result.frame.index > 0:
                return
            tick.wait(0.01)
        raise AssertionError("the tracking thread never waited for the view")

    loop, acquisition = _loop(sinks=[slow_view])
    stats = loop.run()
    acquisition.join(5)
    assert stats.frames == FRAMES and stats.output_waits >= 1 and not loop.sink_errors
    assert stats.output_backlog_max == 3


def test_stage_times_name_each_tracker_stage_stage_and_sink():
    from livedic.dic.tracking import TRACKER_STAGES

    class Split(Stage):
        name = "strain"
        last_timings = None

        def on_frame(self, result):
            self.last_timings = {"strain": 1000, "extensometers": 2000}

    class Recording:
        name = "recording"
        stage = "record results"

        def __call__(self, result, stats):
            pass

    loop, acquisition = _loop(stages=[Split()], sinks=[Recording()])
    stats = loop.run()
    acquisition.join(5)
    stages = stats.summary()["stages"]
    for name in ("tracker", *TRACKER_STAGES, "strain", "extensometers", "record results"):
        assert name in stages, name
    assert stages["strain"]["frames"] == FRAMES - 1            # the reference frame pays for set-up: left out
    assert stages["record results"]["frames"] == FRAMES
    assert stages["extensometers"]["p50_ms"] == pytest.approx(0.002)
    inside = sum(stages[name]["mean_ms"] for name in TRACKER_STAGES)
    assert inside <= stages["tracker"]["mean_ms"] + 1e-9


def test_a_required_sink_that_fails_ends_the_loop_with_its_error():
    class Output:
        name = "output"
        required = True

        def __call__(self, result, stats):
            if result.frame.index == 2:
                raise OSError("disk full")

    after = []
    loop, acquisition = _loop(frames=200, sinks=[Output(), lambda result, stats: after.append(result.frame.index)])
    with pytest.raises(OSError, match="disk full"):
        loop.run()
    acquisition.stop()
    acquisition.join(5)
    assert after == [0, 1]                  # the sinks after it got nothing more
    assert loop.ended_by in ("output", "source")


def test_an_optional_sink_that_fails_is_switched_off_and_the_others_go_on():
    def broken(result, stats):
        raise OSError("viewer went away")

    seen = []
    loop, acquisition = _loop(sinks=[broken, lambda result, stats: seen.append(result.frame.index)])
    stats = loop.run()
    acquisition.join(5)
    assert stats.frames == FRAMES and seen == list(range(FRAMES))
    assert len(loop.sink_errors) == 1 and "viewer" in str(loop.sink_errors[0][1])
    assert np.isfinite(stats.latency_ms(50))


class _Frames(FrameSource):
    def __init__(self, frames):
        self.frames = frames

    def __iter__(self):
        return iter(self.frames)


def test_frames_are_prefiltered_in_the_acquisition_thread_one_ahead_of_the_tracker_with_the_same_results():
    """The session's ``prepare``: each frame's coefficients made in the acquisition thread (a few buffers, reused),
    the results those of plain ``track``, the time under the stage "prepare ahead"."""
    source = SyntheticTranslateSource(f"synthetic:translate?frames={FRAMES}&size=96x96&du=0.3&dv=0.2&pace=0")
    with source:
        frames = list(source)

    def make_tracker(frame):
        return Tracker(frame.image, [(40.0, 40.0), (56.0, 56.0)])

    queue = FrameQueue(1, BLOCK)            # the acquisition at most a frame or two ahead: buffers come back
    loop = TrackerLoop(queue, make_tracker, reference=reference_ready(make_tracker, frames[0]),
                       sinks=[lambda result, stats: results.append(result.measurement)])
    acquisition = AcquisitionThread(_Frames(frames), queue)
    made_in, buffers, results = set(), set(), []

    def prepare(frame):
        made_in.add(threading.get_ident())
        ahead = loop.coefficients_ahead(frame)
        buffers.add(id(ahead.coefficients.flat))
        return ahead

    acquisition.prepare = prepare
    acquisition.start()
    stats = loop.run()
    acquisition.join(WAIT_S)
    assert made_in == {acquisition.ident} and len(results) == FRAMES
    assert len(buffers) <= 4 and stats.stages.summary()["prepare ahead"]["frames"] == FRAMES
    plain = make_tracker(frames[0])
    for frame, got in zip(frames, results):
        want = plain.track(frame.image)
        np.testing.assert_array_equal(got.u, want.u)
        np.testing.assert_array_equal(got.v, want.v)


def test_no_coefficients_ahead_before_the_tracker_exists():
    loop = TrackerLoop(FrameQueue(2), lambda frame: None)
    assert loop.coefficients_ahead(None) is None


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs Linux's sched_setaffinity and two CPUs")
def test_with_a_core_split_the_tracker_runs_alone_on_its_cpu_and_every_cpu_comes_back():
    every = frozenset(os.sched_getaffinity(0))
    split = core_split(1)
    seen = {"stage": set(), "sink": set()}
    loop, acquisition = _loop(stages=[_Stage(lambda result: seen["stage"].add(frozenset(os.sched_getaffinity(0))))],
                              sinks=[lambda result, stats: seen["sink"].add(frozenset(os.sched_getaffinity(0)))],
                              cores=split)
    loop.run()
    acquisition.join(5)
    assert seen == {"stage": {split.tracking}, "sink": {split.others}}
    assert os.sched_getaffinity(0) == every
