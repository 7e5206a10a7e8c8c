"""Tests of stream/session/summary.py: the end-of-session text from the summary dict, n/a for what is unknown."""

from types import SimpleNamespace

import numpy as np

from livedic.dic.status import Status
from livedic.stream.pipeline.stage import Reference
from livedic.stream.pipeline.tracker_loop import OUTPUT_BACKLOG_MAX
from livedic.stream.session.summary import format_pipeline, format_point_losses, format_summary


def _summary(**more):
    summary = {"source": "synthetic:tensile", "method": "ncc+icgn", "frames": 10, "acquired": 12, "dropped": 2,
               "lost_upstream": 0, "ok_fraction": 0.955, "refound": 3, "fps": 50.0, "poi_per_s": 12345.6,
               "processing_p50_ms": 4.0, "processing_p99_ms": 9.5, "latency_p50_ms": 6.0, "latency_p99_ms": 12.25,
               "latency_from": "capture", "setup_ms": 120.0, "rerun": "none", "live": True}
    summary.update(more)
    return summary


def _reference():
    return Reference(frame_index=0, points=np.array([[100.5, 200.0], [110.0, 200.0]]), roi=(0, 0, 10, 10),
                     step=10, shape=(20, 20))


def test_the_headline_lines():
    text = format_summary(_summary(), _reference(), None, stage_lines=["  strain     line"])
    lines = text.splitlines()
    assert lines[0] == "livedic run: synthetic:tensile  (ncc+icgn)"
    assert lines[1] == "  frames     10 tracked of 12 acquired; 2 dropped by the queue, 0 lost upstream"
    assert lines[2] == "  points     2 (P0 at 100.5, 200); 95.5 % ok over all of them and all frames; 3 re-found"
    assert lines[3] == "  rate       50.0 fps, 12,346 POI/s"
    assert lines[4] == ("  latency    p50 6.0 ms, p99 12.2 ms from frame capture to result (tracking p50 4.0 ms, "
                        "p99 9.5 ms)")
    assert "  strain     line" in lines and lines[-1] == "  rerun      none"
    assert "  error" not in text and "  recording" not in text


def test_the_headline_names_the_interpolant_and_the_prefilter_the_session_sampled_with():
    """``run`` and ``measure`` default differently (docs/guide/measure.md): the summary says which ``run`` used."""
    text = format_summary(_summary(interpolation="bspline3", prefilter="none"), None, None)
    assert text.splitlines()[0] == "livedic run: synthetic:tensile  (ncc+icgn; interpolation bspline3, pre-filter none)"


def test_unknown_numbers_are_na_and_a_file_has_processing_not_latency():
    text = format_summary(_summary(fps=float("nan"), poi_per_s=None, live=False), None, None)
    assert "  rate       n/a fps, n/a POI/s achieved (a file: frames taken as fast as tracked)" in text
    assert "  processing tracking p50 4.0 ms, p99 9.5 ms a frame (no latency" in text
    assert "  latency" not in text and "  points" not in text          # no reference: no points line


def test_optional_lines_appear_with_their_numbers(tmp_path):
    path = tmp_path / "r.mcap"
    path.write_bytes(b"x" * 3_000_000)
    recorder = SimpleNamespace(path=str(path), error=None, frames_written=10, results_written=9, frames_durable=10)
    text = format_summary(_summary(error_rms_px=0.01234, error_max_px=0.05, reference_updates=2,
                                   reference_update="auto", reference_update_max_ms=3.25, reference_update_lost=4,
                                   fractures=[{"frame": 7, "lost": 30, "jump_px": 2.5, "separated": 12}],
                                   source_losses=[1], reconnects=1, outage_s=0.5, stopped_by="SIGINT",
                                   delivery_delay_p99_ms=1.5, rerun_error="disk full"), _reference(), recorder)
    assert "  error      RMS 0.0123 px, max 0.0500 px against the truth (ok points)" in text
    assert "  reference  moved 2 times (auto; longest 3.2 ms; 4 points could not be placed)" in text
    assert "  fracture   at frame 7: 30 points lost at once, the sides 2.5 px apart; 12 points" in text
    assert f"  recording  {path} (10 frames, 9 results, 3 MB)" in text
    assert "  camera     lost 1 time(s), back 1 time(s); 0.5 s without frames" in text
    assert "frame delivery delay p99 1.5 ms" in text and "  stopped    on SIGINT" in text
    assert "  rerun      none STOPPED EARLY (disk full); see the warning above" in text
    stopped = SimpleNamespace(path=str(tmp_path / "gone.mcap"), error="full", frames_durable=4)
    assert "STOPPED EARLY: 4 frames kept (0 MB)" in format_summary(_summary(), None, stopped)


def test_point_losses_name_each_status():
    losses = {"points_never_trackable": {"count": 3, "by_status": {"FLAT_REFERENCE": 3}},
              "points_lost_later": {"count": 0, "by_status": {}}}
    assert format_point_losses(losses) == f"3 never trackable (3 {Status.FLAT_REFERENCE.description})"
    assert format_point_losses({}) == ""
    text = format_summary(_summary(**losses), _reference(), None)
    assert f"             3 never trackable (3 {Status.FLAT_REFERENCE.description})" in text.splitlines()


def test_the_pipeline_line():
    stages = {"tracker": {"p50_ms": 6.0}, "kernel": {"p50_ms": 4.0}}
    line = format_pipeline({"stages": stages, "output_backlog_max": 2, "output_waits": 5, "viewer_process": True,
                            "frames": 100, "viewer_images_above_rate": 30, "viewer_image_max_hz": 25.0,
                            "viewer_images_left_out": 4, "viewer_frames_left_out": 0})
    parts = line.split("; ")
    assert parts[0] == "tracker p50 6.0 ms = 1.5x its sub-pixel kernel (4.0 ms)"
    assert parts[1] == ("outputs in their own thread, the view in its own process, at most 2 result(s) behind")
    assert parts[2] == (f"the tracker waited 5 time(s) for them (more than {OUTPUT_BACKLOG_MAX} behind)")
    assert parts[3].startswith("camera image left out of the view in 34 of 100 frames (30 above the view's 25 "
                               "images/s, 4 while the view was behind")
    assert format_pipeline({}) == "" and format_pipeline({"stages": {"kernel": {"p50_ms": 0.0},
                                                                     "tracker": {"p50_ms": 1.0}}}) == ""
