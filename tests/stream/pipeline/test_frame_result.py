"""Tests of stream/pipeline/frame_result.py: per-frame latency, the session's running statistics and stage times."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.stream.pipeline.frame_result import (RESULT_FIELDS, TRACKER_FIELDS, FrameResult, SessionStats, StageTimes,
                                                  reference_ready)


def _result(arrival_ns, done_ns, capture_ns=None):
    return FrameResult(frame=None, arrival_ns=arrival_ns, done_ns=done_ns, processing_ns=0, measurement=None,
                       is_reference=False, frames_done=1, dropped_total=0, dropped_since_last=0, queue_depth=0,
                       capture_ns=capture_ns)


def test_latency_starts_at_capture_when_known_and_earlier_than_arrival():
    assert _result(1_000, 5_000).latency_ns == 4_000 and _result(1_000, 5_000).delivery_delay_ns is None
    captured = _result(1_000, 5_000, capture_ns=400)
    assert captured.origin_ns == 400 and captured.latency_ns == 4_600 and captured.delivery_delay_ns == 600
    # a camera clock ahead of the host's never makes a latency shorter than the host measured
    assert _result(1_000, 5_000, capture_ns=1_500).origin_ns == 1_000


def test_the_tracker_fields_are_fields_of_the_result():
    assert set(TRACKER_FIELDS) <= RESULT_FIELDS and len(set(TRACKER_FIELDS)) == len(TRACKER_FIELDS)
    assert {"strain", "extensometers", "force_N"} <= RESULT_FIELDS - set(TRACKER_FIELDS)


def test_stage_times_give_percentiles_per_stage_in_first_run_order():
    times = StageTimes()
    for ns in range(1, 101):
        times.add("tracker", ns * 1_000_000)                # 1..100 ms
    times.add_all({"strain": 2_000_000, "tracker": 0})
    summary = times.summary()
    assert list(summary) == ["tracker", "strain"]
    tracker = summary["tracker"]
    assert tracker["frames"] == 101 and tracker["max_ms"] == 100.0
    assert tracker["p50_ms"] == pytest.approx(np.percentile(np.r_[np.arange(1, 101), 0], 50))
    assert tracker["mean_ms"] == pytest.approx(5050 / 101)
    assert summary["strain"] == {"frames": 1, "p50_ms": 2.0, "p99_ms": 2.0, "mean_ms": 2.0, "max_ms": 2.0}
    assert StageTimes().summary() == {}


def test_an_empty_session_has_nan_rates_not_zero():
    stats = SessionStats()
    assert stats.elapsed_s == 0.0
    for value in (stats.fps, stats.poi_per_s, stats.latency_ms(50), stats.error_rms_px, stats.ok_fraction,
                  stats.ok_fraction_of_trackable):
        assert math.isnan(value)
    summary = stats.summary()
    assert summary["error_rms_px"] is None and summary["delivery_delay_p99_ms"] is None      # no truth, no capture
    assert summary["points_never_trackable"] == {"count": 0, "by_status": {}}


def test_rates_and_fractions_of_a_session():
    stats = SessionStats(frames=11, first_arrival_ns=0, last_done_ns=2_000_000_000, points_tracked=400,
                         points_placed=500, points_ok=300, error_sq_sum=8.0, error_count=2, truth_frames=1)
    stats.latencies_ns.extend([10_000_000, 30_000_000])
    assert stats.elapsed_s == 2.0 and stats.fps == 5.0 and stats.poi_per_s == 200.0   # (frames - 1) / elapsed
    assert stats.ok_fraction == 0.6 and stats.ok_fraction_of_trackable == 0.75
    assert stats.error_rms_px == 2.0 and stats.latency_ms(50) == 20.0 and stats.latency_ms(100) == 30.0
    summary = stats.summary()
    assert summary["error_rms_px"] == 2.0 and summary["latency_max_ms"] == 30.0
    assert math.isnan(SessionStats(frames=1, first_arrival_ns=0, last_done_ns=10).fps)      # one frame: no rate


def test_point_losses_count_the_never_trackable_and_the_lost_later_by_status():
    stats = SessionStats()
    stats.trackable_at_reference = np.array([True, True, True, False, False])
    stats.reference_status = np.array([0, 0, 0, 2, 1])
    stats.last_status = np.array([0, 11, 7, 2, 1])
    losses = stats.point_losses()
    assert losses["points_never_trackable"] == {"count": 2, "by_status": {"OUTSIDE_REFERENCE": 1,
                                                                         "FLAT_REFERENCE": 1}}
    assert losses["points_lost_later"] == {"count": 2, "by_status": {"LOW_CORRELATION": 1, "SEPARATED": 1}}


def test_reference_ready_builds_the_tracker_and_tracks_the_reference():
    frame = Frame(0, 0, np.zeros((4, 4), np.uint8), "Mono8")
    tracked = []
    tracker = SimpleNamespace(track=lambda image: tracked.append(image) or "measurement")
    ready = reference_ready(lambda f: tracker if f is frame else None, frame)
    assert ready.tracker is tracker and ready.measurement == "measurement" and tracked == [frame.image]
    assert ready.setup_ns >= 0
