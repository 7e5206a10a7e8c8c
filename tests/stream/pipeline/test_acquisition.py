"""Live pipeline: frame queue, acquisition thread, tracker loop, ``livedic run`` end to end."""

import itertools
import json
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from livedic.stream.session.config import DEFAULT_STATIC_FRAMES
from livedic.acquire.base import Frame, FrameSource, SourceError, SourceLost
from livedic.acquire.simulator.sources import SyntheticTranslateSource
from livedic.stream.pipeline.acquisition import AcquisitionThread, QueuedFrame
from livedic.stream.pipeline.frame_queue import BLOCK, DROP_NEWEST, DROP_OLDEST, FrameQueue, QueueClosed
from livedic.stream.cli import LivedicParser
from livedic.stream.session.points import build_points
from livedic.stream.cli.run import add_run_arguments, run_session
from livedic.stream.pipeline.tracker_loop import TrackerLoop



def _item(i):
    return QueuedFrame(Frame(i, i * 1000, np.zeros((2, 2), np.uint8), "Mono8"), i)


class ListSource(FrameSource):
    """Frames 0..n-1 (endless if ``n`` is None; optionally failing at ``fail_after``), records whether it was
    closed."""

    def __init__(self, n, *, fail_after=None, error=None):
        self.n, self.fail_after, self.error = n, fail_after, error
        self.closed = False

    def __iter__(self):
        for i in range(self.n) if self.n is not None else itertools.count():
            if self.fail_after is not None and i == self.fail_after:
                raise self.error
            yield Frame(i, i * 1_000_000, np.full((4, 4), i % 256, np.uint8), "Mono8")

    def close(self):
        self.closed = True


# --------------------------------------------------------------------------- frame queue

def test_drop_oldest_keeps_the_newest_and_counts():
    queue = FrameQueue(3, DROP_OLDEST)
    assert queue.put(_item(0)) is None and queue.get().frame.index == 0    # the first frame taken: no longer special
    victims = [queue.put(_item(i)) for i in range(1, 11)]
    assert queue.dropped == 7 and queue.put_count == 11
    assert [v.frame.index for v in victims if v is not None] == list(range(1, 8))
    assert [queue.get().frame.index for _ in range(3)] == [8, 9, 10]
    assert list(queue.dropped_indices) == list(range(1, 8))


def test_the_first_frame_is_never_dropped_it_is_the_reference():
    """A tracker slow to take the first frame (set-up, a server starting) must not lose the reference: the
    frames after it go instead, and once it is taken the oldest goes as usual."""
    queue = FrameQueue(3, DROP_OLDEST)
    victims = [queue.put(_item(i)) for i in range(10)]
    assert [v.frame.index for v in victims if v is not None] == list(range(1, 8))
    assert [queue.get().frame.index for _ in range(3)] == [0, 8, 9]
    single = FrameQueue(1, DROP_OLDEST)
    assert single.put(_item(0)) is None and single.put(_item(1)).frame.index == 1     # the incoming one goes
    assert single.get().frame.index == 0
    assert single.put(_item(2)) is None and single.put(_item(3)).frame.index == 2


def test_drop_newest_keeps_the_oldest_and_counts():
    queue = FrameQueue(3, DROP_NEWEST)
    for i in range(10):
        queue.put(_item(i))
    assert queue.dropped == 7
    assert [queue.get().frame.index for _ in range(3)] == [0, 1, 2]


def test_block_policy_waits_for_room_and_close_releases_it():
    queue = FrameQueue(2, BLOCK)
    queue.put(_item(0))
    queue.put(_item(1))
    done = []
    producer = threading.Thread(target=lambda: done.append(queue.put(_item(2))))
    producer.start()
    assert queue.wait_for_waiting(puts=1, timeout=30)
    assert not done and queue.waiting_puts == 1      # held back: the queue is full
    assert queue.get().frame.index == 0
    producer.join(30)
    assert done == [None] and queue.dropped == 0 and len(queue) == 2 and queue.max_depth == 2
    assert queue.waiting_puts == 0
    raised = []
    blocked = threading.Thread(target=lambda: raised.append(pytest.raises(QueueClosed, queue.put, _item(3))))
    blocked.start()
    assert queue.wait_for_waiting(puts=1, timeout=30)
    queue.close()
    blocked.join(30)
    assert not blocked.is_alive() and len(raised) == 1


def test_get_times_out_then_drains_and_raises_after_close():
    queue = FrameQueue(2)
    start = time.monotonic()
    assert queue.get(timeout=0.05) is None
    assert time.monotonic() - start >= 0.04
    queue.put(_item(1))
    queue.close()
    assert queue.get().frame.index == 1
    with pytest.raises(QueueClosed):
        queue.get(timeout=1.0)
    with pytest.raises(QueueClosed):
        queue.put(_item(2))


def test_close_wakes_a_waiting_consumer():
    queue = FrameQueue(2)
    outcome = []

    def consume():
        try:
            queue.get(timeout=5.0)
        except QueueClosed:
            outcome.append("closed")

    thread = threading.Thread(target=consume)
    thread.start()
    assert queue.wait_for_waiting(gets=1, timeout=30)
    queue.close()
    thread.join(30)
    assert outcome == ["closed"] and queue.waiting_gets == 0


def test_bad_queue_settings_raise():
    with pytest.raises(ValueError, match="positive"):
        FrameQueue(0)
    with pytest.raises(ValueError, match="drop policy"):
        FrameQueue(2, "drop-random")


@pytest.mark.parametrize("policy", [DROP_OLDEST, DROP_NEWEST])
def test_a_stalled_consumer_never_blocks_the_producer(policy):
    """No consumer at all: every put on the full queue returns at once (a dropping put never waits), so the
    producer finishes; a put that waited for room would hang here until the join's limit."""
    queue = FrameQueue(4, policy)
    finished = threading.Event()

    def produce():
        for i in range(300):
            queue.put(_item(i))
        finished.set()

    producer = threading.Thread(target=produce, daemon=True)
    producer.start()
    producer.join(30)                  # a liveness limit for slow machines, not a timing measurement
    assert finished.is_set(), "put waited for a consumer that never came"
    assert queue.dropped == 296 and len(queue) == 4 and queue.put_count == 300
    kept = [queue.get().frame.index for _ in range(4)]
    assert kept == ([0, 297, 298, 299] if policy == DROP_OLDEST else [0, 1, 2, 3])    # the first: the reference


@pytest.mark.parametrize("policy", [DROP_OLDEST, DROP_NEWEST])
def test_slow_consumer_never_blocks_the_producer(policy):
    """A consumer ten times slower than the producer (it takes one frame per ten put, in lock-step, so the
    outcome does not depend on the machine's speed): every frame is either consumed, dropped or left over."""
    queue = FrameQueue(4, policy)
    produced, consumed = 300, []
    take, taken = threading.Semaphore(0), threading.Semaphore(0)

    def consume():
        while True:
            take.acquire()
            try:
                item = queue.get(timeout=30)
            except QueueClosed:
                return
            consumed.append(item.frame.index)
            taken.release()

    consumer = threading.Thread(target=consume)
    consumer.start()
    for i in range(produced):
        assert queue.waiting_puts == 0
        queue.put(_item(i))
        if i % 10 == 9:
            take.release()
            assert taken.acquire(timeout=30)
    left = len(queue)
    queue.close()
    for _ in range(left + 1):            # drain what is left, then the consumer meets the closed queue
        take.release()
    consumer.join(30)
    assert not consumer.is_alive()
    assert len(consumed) == produced // 10 + left and len(consumed) + queue.dropped == produced
    assert queue.dropped > 0
    assert consumed == sorted(consumed)
    if policy == DROP_OLDEST:
        assert consumed[-1] == produced - 1      # the newest frame is always processed


# --------------------------------------------------------------------------- acquisition thread

def test_acquisition_surfaces_a_source_error():
    source = ListSource(10, fail_after=3, error=SourceError("camera lost: cable unplugged"))
    queue = FrameQueue(8)
    thread = AcquisitionThread(source, queue)
    thread.start()
    thread.join(5)
    assert not thread.is_alive()
    assert isinstance(thread.error, SourceError) and "cable" in str(thread.error)
    assert thread.finished_reason == "error" and thread.frames == 3
    assert source.closed and queue.closed
    assert [queue.get().frame.index for _ in range(3)] == [0, 1, 2]
    with pytest.raises(SourceError, match="cable"):
        thread.raise_error()


def test_acquisition_wraps_an_unexpected_exception():
    thread = AcquisitionThread(ListSource(5, fail_after=1, error=ZeroDivisionError("boom")), FrameQueue(4))
    thread.start()
    thread.join(5)
    assert isinstance(thread.error, SourceError) and "ZeroDivisionError" in str(thread.error)


def test_acquisition_stops_on_request_and_at_the_limit():
    source = ListSource(None)                 # endless: only the stop ends it
    queue = FrameQueue(4)
    seen, six_frames = [], threading.Event()

    def on_frame(item):
        seen.append(item.arrival_ns)
        if len(seen) == 6:
            six_frames.set()

    thread = AcquisitionThread(source, queue, on_frame=on_frame)
    thread.start()
    assert six_frames.wait(30)
    thread.stop()
    thread.join(30)
    assert not thread.is_alive() and thread.finished_reason == "stopped" and source.closed and queue.closed
    assert thread.frames >= 6 and len(seen) >= thread.frames
    assert seen == sorted(seen)
    limited = AcquisitionThread(ListSource(100), FrameQueue(200), max_frames=7)
    limited.start()
    limited.join(2)
    assert limited.frames == 7 and limited.finished_reason == "limit"
    assert (limited.first_index, limited.last_index) == (0, 6)


# --------------------------------------------------------------------------- reconnection

class Reopener:
    """Hands out sources in turn: an exception instance is raised, a source is returned."""

    def __init__(self, *outcomes, signal_at=None):
        self.outcomes = list(outcomes)
        self.calls = 0
        self.signal_at, self.reached = signal_at, threading.Event()    # set once ``signal_at`` calls were made

    def __call__(self):
        self.calls += 1
        if self.calls == self.signal_at:
            self.reached.set()
        outcome = self.outcomes.pop(0)
        if isinstance(outcome, BaseException):
            raise outcome
        return outcome


def _run_acquisition(source, reconnect, *, max_frames=None, timeout=10):
    from livedic.stream.pipeline.acquisition import Reconnect
    queue = FrameQueue(1000, BLOCK)
    events = []
    policy = Reconnect(reopen=reconnect, retry_s=0.01, on_event=lambda *e: events.append(e)) \
        if callable(reconnect) else reconnect
    if isinstance(policy, Reconnect) and policy.on_event is None:
        policy = Reconnect(reopen=policy.reopen, retry_s=policy.retry_s, timeout_s=policy.timeout_s,
                           on_event=lambda *e: events.append(e))
    thread = AcquisitionThread(source, queue, reconnect=policy, max_frames=max_frames)
    thread.start()
    thread.join(timeout)
    assert not thread.is_alive()
    frames = []
    while True:
        try:
            frames.append(queue.get(timeout=0).frame)
        except QueueClosed:
            break
    return thread, frames, events


def test_reconnect_continues_the_session_with_increasing_indices_and_times():
    first = ListSource(10, fail_after=6, error=SourceError("camera lost: no frame for 1.0 s"))
    back = ListSource(5)                       # a power-cycled camera: counter and clock start again
    reopen = Reopener(SourceError("camera not found"), SourceError("camera not found"), back)
    thread, frames, events = _run_acquisition(first, reopen)
    assert thread.error is None and thread.finished_reason == "end"
    assert first.closed and back.closed and reopen.calls == 3
    assert [f.index for f in frames] == list(range(11))
    times = [f.timestamp_ns for f in frames]
    assert all(b > a for a, b in zip(times, times[1:]))
    assert [f.metadata.get("source_index") for f in frames[6:]] == list(range(5))
    assert [f.metadata.get("source_timestamp_ns") for f in frames[6:]] == [i * 1_000_000 for i in range(5)]
    assert np.array_equal(frames[8].image, np.full((4, 4), 2, np.uint8))      # the camera's frame 2
    assert thread.reconnects == 1 and len(thread.losses) == 1 and thread.outage_s > 0
    assert [e[0] for e in events] == ["camera_lost", "camera_reconnected"]
    assert "no frame for 1.0 s" in events[0][1] and "continues from frame 6" in events[1][1]
    assert thread.frames == 11 and (thread.first_index, thread.last_index) == (0, 10)


def test_reconnect_counts_frames_against_the_limit_across_losses():
    sources = [ListSource(100, fail_after=4, error=SourceError("lost")) for _ in range(3)]
    thread, frames, events = _run_acquisition(sources[0], Reopener(*sources[1:]), max_frames=10)
    assert thread.finished_reason == "limit" and thread.reconnects == 2
    assert [f.index for f in frames] == list(range(10))
    assert [f.metadata["source_index"] for f in frames[4:]] == [0, 1, 2, 3, 0, 1]


def test_reconnect_refuses_a_camera_that_comes_back_with_other_images():
    class Bigger(ListSource):
        def __iter__(self):
            yield Frame(0, 0, np.zeros((8, 8), np.uint8), "Mono8")

    thread, frames, events = _run_acquisition(ListSource(5, fail_after=2, error=SourceError("lost")),
                                              Reopener(Bigger(1)))
    assert thread.finished_reason == "error" and len(frames) == 2
    assert "came back with 8x8 Mono8 images but the session started with 4x4 Mono8" in str(thread.error)


def test_reconnect_gives_up_after_its_timeout_and_keeps_the_loss_as_the_error():
    from livedic.stream.pipeline.acquisition import Reconnect
    policy = Reconnect(reopen=Reopener(*[SourceError("camera not found")] * 1000), retry_s=0.01, timeout_s=0.2)
    thread, frames, events = _run_acquisition(ListSource(5, fail_after=3, error=SourceError("cable pulled")), policy)
    assert thread.finished_reason == "error" and len(frames) == 3
    assert "cable pulled" in str(thread.error) and "not back within --reconnect-timeout 0.2 s" in str(thread.error)
    assert [e[0] for e in events] == ["camera_lost", "camera_gave_up"]
    assert 0.2 <= thread.outage_s < 10      # at least the timeout; the upper bound is the join's limit


def test_reconnect_waits_until_stopped_and_a_stop_ends_cleanly():
    from livedic.stream.pipeline.acquisition import Reconnect
    queue = FrameQueue(100)
    reopen = Reopener(*[SourceError("camera not found")] * 10_000, signal_at=5)
    thread = AcquisitionThread(ListSource(5, fail_after=3, error=SourceError("lost")), queue,
                               reconnect=Reconnect(reopen=reopen, retry_s=0.01))
    thread.start()
    assert reopen.reached.wait(30)
    assert thread.is_alive() and thread.waiting and not queue.closed
    thread.stop()
    thread.join(2)
    assert not thread.is_alive() and thread.finished_reason == "stopped" and thread.error is None
    assert queue.closed and thread.losses == ["lost"]


def test_no_reconnect_for_a_source_that_never_delivered():
    thread, frames, events = _run_acquisition(ListSource(5, fail_after=0, error=SourceError("bad exposure")),
                                              Reopener(ListSource(5)))
    assert thread.finished_reason == "error" and "bad exposure" in str(thread.error) and not frames and not events


# --------------------------------------------------------------------------- tracker loop

def test_tracker_loop_tracks_times_and_scores_against_the_truth():
    from livedic.dic.tracking import Tracker
    source = SyntheticTranslateSource("synthetic:translate?frames=12&size=128x128&du=0.3&dv=0.2&pace=0")
    queue = FrameQueue(32)
    acquisition = AcquisitionThread(source, queue)
    seen = []

    def make_tracker(frame):
        points, _, _ = build_points(frame.image.shape, roi=(32, 32, 64, 64), step=16, n_points=0, subset=21)
        return Tracker(frame.image, points)

    loop = TrackerLoop(queue, make_tracker, sinks=[lambda result, stats: seen.append(result)])
    acquisition.start()
    stats = loop.run()
    acquisition.join(5)
    assert stats.frames == 12 and loop.ended_by == "source" and loop.reference_frame.index == 0
    assert seen[0].is_reference and not seen[1].is_reference
    assert len(stats.latencies_ns) == 11 and all(lat > 0 for lat in stats.latencies_ns)
    assert stats.error_rms_px < 0.02 and stats.error_max < 0.06 and stats.truth_frames == 11
    summary = stats.summary()
    assert summary["points"] == 10 and summary["dropped"] == 0
    assert summary["latency_p99_ms"] >= summary["latency_p50_ms"]
    assert seen[-1].error_rms_px < 0.05


def test_session_stats_keep_per_frame_numbers_packed_with_the_same_percentiles():
    from array import array
    from livedic.stream.pipeline.frame_result import SessionStats
    stats = SessionStats()
    assert np.isnan(stats.latency_ms(50)) and np.isnan(stats.processing_ms(99))
    assert np.isnan(stats.delivery_delay_ms(99)) and stats.summary()["delivery_delay_p99_ms"] is None
    rng = np.random.default_rng(1)
    values = [int(v) for v in rng.integers(1, 10**10, 1001)]     # ns, beyond 32 bits
    for v in values:
        stats.latencies_ns.append(v)
        stats.processing_ns.append(v // 3)
        stats.delivery_delays_ns.append(v % 1_000_000)
    for name in ("latencies_ns", "processing_ns", "delivery_delays_ns"):
        packed = getattr(stats, name)
        assert isinstance(packed, array) and packed.itemsize == 8 and len(packed) == 1001
    for q in (0, 50, 99, 100):                                    # what a list of Python ints gave
        assert stats.latency_ms(q) == float(np.percentile(np.asarray(values), q)) / 1e6
        assert stats.processing_ms(q) == float(np.percentile(np.asarray([v // 3 for v in values]), q)) / 1e6
        assert stats.delivery_delay_ms(q) == \
            float(np.percentile(np.asarray([v % 1_000_000 for v in values]), q)) / 1e6
    assert stats.latencies_ns[-2:].tolist() == values[-2:]
    assert SessionStats().latencies_ns is not stats.latencies_ns


def test_a_failing_sink_is_switched_off_not_fatal():
    from livedic.dic.tracking import Tracker
    source = SyntheticTranslateSource("synthetic:translate?frames=4&size=96x96&pace=0")
    queue = FrameQueue(8)
    acquisition = AcquisitionThread(source, queue)

    def broken(result, stats):
        raise OSError("viewer went away")

    loop = TrackerLoop(queue, lambda f: Tracker(f.image, [(48.0, 48.0)]), sinks=[broken])
    acquisition.start()
    stats = loop.run()
    assert stats.frames == 4 and len(loop.sink_errors) == 1 and "viewer" in str(loop.sink_errors[0][1])


# --------------------------------------------------------------------------- livedic run

def _parse(argv):
    parser = LivedicParser(prog="livedic run")
    add_run_arguments(parser)
    return parser.parse_args(argv)


def test_run_session_end_to_end(tmp_path, capsys):
    from rerun.chunk import RrdReader
    rrd = tmp_path / "session.rrd"
    mcap = tmp_path / "session.mcap"
    summary_path = tmp_path / "summary.json"
    # Paced like a camera, but the queue blocks instead of dropping: every frame is tracked on any machine
    # (how many a slow machine would drop is not what this test is about; the queue tests cover drops).
    args = _parse(["--source", "synthetic:tensile?size=192x256&fps=25&noise=0.5", "--frames", "40",
                   "--n-points", "60", "--viewer", "save", str(rrd), "--record", str(mcap), "--drop", "block",
                   "--summary-json", str(summary_path), "--progress", "off"])
    assert run_session(args) == 0
    out = capsys.readouterr().out
    assert "frames" in out and "POI/s" in out and "p99" in out and "against the truth" in out
    summary = json.loads(summary_path.read_text())
    # the test's 40 frames after the simulator's static ones (--static-frames' default for it)
    frames = 40 + DEFAULT_STATIC_FRAMES
    assert summary["acquired"] == frames and summary["frames"] == frames and summary["dropped"] == 0
    assert 40 <= summary["points"] <= 90
    assert summary["error_rms_px"] < 0.05 and summary["error_max_px"] < 0.3 and summary["ok_fraction"] > 0.97
    assert summary["fps"] > 0 and summary["latency_p50_ms"] > 0 and summary["poi_per_s"] > 0
    assert summary["rerun"] == f"save {rrd}" and summary["recording"] == str(mcap)
    # Rerun: the entities are there, and P0's u and v were logged for every tracked frame.
    store = RrdReader(str(rrd)).stream().collect()
    text = str(store.summary())
    for path in ("/camera/image", "/camera/field_u", "/camera/field_v", "/camera/p0", "/p0", "/quality",
                 "/perf/throughput", "/perf/latency", "/perf/drops", "/error", "/legend/u/bar", "/summary"):
        assert f"{path} " in text, path
    p0_rows = [row for c in RrdReader(str(rrd)).stream().to_chunks()
               if str(c.entity_path) == "/p0" and not c.is_static
               for row in c.to_record_batch().column("Scalars:scalars").to_pylist()]
    assert len(p0_rows) == summary["frames"] and all(len(row) == 2 for row in p0_rows)   # u and v per frame
    # The recording holds every acquired frame and one result per tracked frame, P0 first.
    from livedic.acquire.recording.reader import inspect_recording, read_events, read_results
    info = inspect_recording(str(mcap))
    assert info.indexed and not info.truncated and info.frames == frames
    results = read_results(str(mcap))
    assert len(results) == summary["frames"] and results[0].frame_index == 0
    assert results[-1].point_id[0] == 0 and results[-1].method == "improved-wso+icgn"
    assert any(event.kind == "note" and "P0" in event.message for event in read_events(str(mcap)))
    # Replaying the recording tracks every frame (files block instead of dropping) over the recorded ROI.
    replay_json = tmp_path / "replay.json"
    args = _parse(["--source", f"mcap:{mcap}", "--frames", "12", "--no-record", "--viewer", "none",
                   "--progress", "off", "--summary-json", str(replay_json)])
    assert run_session(args) == 0
    replay = json.loads(replay_json.read_text())
    assert replay["frames"] == 12 and replay["dropped"] == 0 and replay["roi"] == summary["roi"]
    assert replay["ok_fraction"] > 0.97 and replay["error_rms_px"] is None


def test_run_session_options_are_checked(tmp_path):
    for argv, words in ((["--subset", "20"], "odd"), (["--roi", "1,2,3"], "4 comma"),
                        (["--record", str(tmp_path / "x.txt")], ".mcap"), (["--viewer", "save", "x.png"], ".rrd"),
                        (["--viewer", "show"], "viewer mode"), (["--subpixel", "none"], "sub-pixel")):
        extra = [] if "--record" in argv else ["--no-record"]
        with pytest.raises(ValueError, match=words):
            run_session(_parse(argv + extra + ["--progress", "off"]))
    with pytest.raises(SourceError, match="valid sources"):
        run_session(_parse(["--source", "camera:1", "--no-record", "--viewer", "none"]))


def test_method_names_are_checked_by_the_parser_and_the_config(capsys):
    """An unknown method name is refused by argparse (one line, exit 2) and by the config itself (API users)."""
    from livedic.stream.session.config import TrackingConfig
    for option, words in (("--search", "unknown search method 'magic'"), ("--subpixel", "unknown sub-pixel method")):
        with pytest.raises(SystemExit) as stop:
            _parse([option, "magic"])
        assert stop.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("livedic: error: argument " + option) and words in err[0], err
    with pytest.raises(ValueError, match="unknown search method 'magic'"):
        TrackingConfig(search="magic")
    with pytest.raises(ValueError, match="unknown sub-pixel method 'magic'"):
        TrackingConfig(subpixel="magic")


def test_run_session_raises_a_source_failure_after_closing_the_recording(tmp_path, monkeypatch):
    import livedic.stream.cli.run as run_module
    from livedic.acquire import sources

    def failing(uri, **options):
        return ListSource(30, fail_after=12, error=SourceError("camera lost after 12 frames"))

    monkeypatch.setattr(sources, "open_source", failing)
    mcap = tmp_path / "lost.mcap"
    args = _parse(["--source", "aravis:Fake_1", "--record", str(mcap), "--viewer", "none", "--progress", "off",
                   "--roi", "0,0,4,4", "--subset", "3", "--step", "1"])
    with pytest.raises(SourceLost, match="camera lost"):
        run_module.run_session(args)
    from livedic.acquire.recording.reader import inspect_recording, read_events
    assert inspect_recording(str(mcap)).frames == 12
    assert any(e.kind == "camera_lost" for e in read_events(str(mcap)))


def test_run_session_with_reconnect_goes_on_in_the_same_recording(tmp_path, monkeypatch):
    import livedic.stream.cli.run as run_module
    from livedic.acquire import sources

    opened = []

    def camera(uri, **options):
        if len(opened) == 1:
            opened.append("refused")
            raise SourceError("camera 'Fake_1' not found")
        source = ListSource(40 if opened else 12, fail_after=None if opened else 8,
                            error=SourceError("camera lost: no frame for 1.0 s"))
        opened.append(source)
        return source

    monkeypatch.setattr(sources, "open_source", camera)
    mcap, summary = tmp_path / "reconnected.mcap", tmp_path / "summary.json"
    args = _parse(["--source", "aravis:Fake_1", "--record", str(mcap), "--viewer", "none", "--progress", "off",
                   "--roi", "0,0,4,4", "--subset", "3", "--step", "1", "--reconnect", "--frames", "30",
                   "--drop", "block", "--summary-json", str(summary)])
    assert run_module.run_session(args) == 0
    from livedic.acquire.recording.reader import read_events, read_results
    from livedic.acquire.recording.source import McapSource
    with McapSource(str(mcap)) as replay:
        recorded = [(frame.index, frame.timestamp_ns) for frame in replay]
    assert [index for index, _ in recorded] == list(range(30))
    assert all(b[1] > a[1] for a, b in zip(recorded, recorded[1:]))
    assert [r.frame_index for r in read_results(str(mcap))] == list(range(30))
    kinds = [e.kind for e in read_events(str(mcap))]
    assert kinds.index("camera_lost") < kinds.index("camera_reconnected")
    data = json.loads(summary.read_text())
    assert data["reconnects"] == 1 and data["source_losses"] == ["camera lost: no frame for 1.0 s"]
    assert data["source_error"] is None and data["frames"] == 30


def test_reconnect_is_refused_for_files_and_simulators():
    with pytest.raises(ValueError, match="--reconnect applies to cameras"):
        run_session(_parse(["--source", "synthetic:tensile", "--reconnect", "--no-record", "--viewer", "none"]))
    with pytest.raises(ValueError, match="needs --reconnect"):
        run_session(_parse(["--reconnect-timeout", "5", "--no-record", "--viewer", "none"]))


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_stop_signal_ends_cleanly_and_finalises_the_recording(tmp_path, stop_signal, signal_when):
    """The signal goes once the progress bar shows 10 frames acquired (not after a fixed time: a slow
    machine takes longer to get there), in the middle of a 400-frame session."""
    import re
    mcap = tmp_path / "interrupted.mcap"
    code = ("import argparse, sys; from livedic.stream.cli.run import add_run_arguments, run_session; "
            "p = argparse.ArgumentParser(); add_run_arguments(p); "
            "sys.exit(run_session(p.parse_args(sys.argv[1:])))")
    process = subprocess.Popen(
        [sys.executable, "-c", code, "--source", "synthetic:tensile?size=128x128&fps=20", "--frames", "400",
         "--n-points", "20", "--roi", "0,0,128,128", "--record", str(mcap), "--viewer", "none", "--progress", "on"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=str(tmp_path))

    def ten_frames(err):
        done = re.findall(rb"\] (\d+)/400 +[\d.]+ fps", err[-400:])      # the session's bar
        return bool(done) and int(done[-1]) >= 10

    text, out = signal_when(process, ten_frames, stop_signal)
    out = out.decode()
    assert process.returncode == 0, text
    name = signal.Signals(stop_signal).name
    assert f"stopped on {name}" in text and f"stopped    on {name}" in out
    from livedic.acquire.recording.reader import inspect_recording, read_results
    info = inspect_recording(str(mcap))
    assert info.indexed and not info.truncated and 10 <= info.frames < 400
    assert 1 <= len(read_results(str(mcap))) <= info.frames


def test_prepare_runs_in_the_acquisition_thread_before_the_put_and_its_failure_stops_acquisition():
    queue = FrameQueue(8)
    threads = set()

    def prepare(frame):
        threads.add(threading.get_ident())
        if frame.index == 3:
            raise ValueError("no coefficients")
        return frame.index * 10

    thread = AcquisitionThread(ListSource(6), queue, prepare=prepare)
    thread.start()
    thread.join(5)
    assert threads == {thread.ident}
    assert [queue.get().ahead for _ in range(3)] == [0, 10, 20]
    assert isinstance(thread.error, SourceError) and "no coefficients" in str(thread.error) and thread.frames == 3
