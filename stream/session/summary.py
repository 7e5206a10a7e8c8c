"""The end-of-session text: ``format_summary`` turns ``Session.summary()`` (a dict) into a few aligned lines.

``format_pipeline`` and ``format_point_losses`` are its parts; the stages give their own lines
(``stream.pipeline.stage.Stage.summary_lines``: strain, force, strain out). ``format_strain_summary`` (the strain
stage's, used by replay too) is re-exported here.
"""

import math
import os
from collections.abc import Sequence
from typing import Any

from livedic.dic.status import Status
from livedic.stream.session.stereo import stereo_lines
from livedic.stream.pipeline.stage import Reference
from livedic.stream.pipeline.tracker_loop import OUTPUT_BACKLOG_MAX
from livedic.stream.stages.strain import format_strain_summary
from livedic.stream.view.process import BACKLOG_MAX as VIEW_BACKLOG_MAX

__all__ = ["format_summary", "format_pipeline", "format_point_losses", "format_strain_summary"]


def _sampling(summary: dict[str, Any]) -> str:
    """``"; interpolation bspline3, pre-filter none"``: how the frames were sampled (empty if not recorded)."""
    if "interpolation" not in summary:
        return ""
    return f"; interpolation {summary['interpolation']}, pre-filter {summary['prefilter']}"


def format_summary(summary: dict[str, Any], reference: Reference | None, recorder: Any,
                   stage_lines: Sequence[str] = ()) -> str:
    """The end-of-run text (plain, a few aligned lines); ``stage_lines``: the stages' own, after the error's."""
    def num(value, fmt):
        return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else format(value, fmt)

    lines = [f"livedic run: {summary['source']}  ({summary['method']}{_sampling(summary)})"]
    lines.append(f"  frames     {summary['frames']} tracked of {summary['acquired']} acquired; "
                 f"{summary['dropped']} dropped by the queue, {summary['lost_upstream']} lost upstream"
                 + (f" ({summary['skipped_before_start']} more sent by the camera while the session was prepared, "
                    f"after the reference)" if summary.get("skipped_before_start") else ""))
    if reference is not None:
        points = reference.points
        lines.append(f"  points     {len(points)} (P0 at {points[0, 0]:g}, {points[0, 1]:g}); "
                     f"{num(100 * summary['ok_fraction'], '.1f')} % ok over all of them and all frames; "
                     f"{summary['refound']} re-found")
        losses = format_point_losses(summary)
        if losses:
            lines.append(f"             {losses}")
    lines.append(f"  rate       {num(summary['fps'], '.1f')} fps, {num(summary['poi_per_s'], ',.0f')} POI/s"
                 + ("" if summary.get("live", True) else " achieved (a file: frames taken as fast as tracked)"))
    tracking = (f"tracking p50 {num(summary['processing_p50_ms'], '.1f')} ms, "
                f"p99 {num(summary['processing_p99_ms'], '.1f')} ms")
    if summary.get("live", True):
        lines.append(f"  latency    p50 {num(summary['latency_p50_ms'], '.1f')} ms, "
                     f"p99 {num(summary['latency_p99_ms'], '.1f')} ms from frame {summary['latency_from']} to "
                     f"result ({tracking})")
    else:
        lines.append(f"  processing {tracking} a frame (no latency: the source is not paced by a clock)")
    extra = f"reference set-up {num(summary['setup_ms'], '.0f')} ms"
    if summary.get("delivery_delay_p99_ms") is not None:
        extra += f"; frame delivery delay p99 {num(summary['delivery_delay_p99_ms'], '.1f')} ms"
    if summary.get("viewer_log_ms_per_frame") is not None:
        extra += f"; Rerun logging {num(summary['viewer_log_ms_per_frame'], '.1f')} ms/frame"
    lines.append(f"             {extra}")
    pipeline = format_pipeline(summary)
    if pipeline:
        lines.append(f"  pipeline   {pipeline}")
    if summary.get("reference_updates"):
        lost = summary.get("reference_update_lost") or 0
        lines.append(f"  reference  moved {summary['reference_updates']} times ({summary['reference_update']}; "
                     f"longest {summary['reference_update_max_ms']:.1f} ms"
                     + (f"; {lost} points could not be placed" if lost else "") + "); results from the first frame")
    for fracture in summary.get("fractures") or ():
        lines.append(f"  fracture   at frame {fracture['frame']}: {fracture['lost']} points lost at once, the sides "
                     f"{fracture['jump_px']:.1f} px apart; {fracture['separated']} points across the crack no "
                     f"longer tracked, the rest tracked on")
    if summary.get("error_rms_px") is not None:
        lines.append(f"  error      RMS {num(summary['error_rms_px'], '.4f')} px, max "
                     f"{num(summary['error_max_px'], '.4f')} px against the truth (ok points"
                     + (", left view" if summary.get("stereo") else "") + ")")
    if summary.get("stereo"):
        lines.extend(stereo_lines(summary["stereo"]))
    lines.extend(stage_lines)
    if recorder is not None:
        size = os.path.getsize(recorder.path) if os.path.exists(recorder.path) else 0
        if recorder.error:
            lines.append(f"  recording  {recorder.path} STOPPED EARLY: {recorder.frames_durable} frames kept "
                         f"({size / 1e6:.0f} MB); see the warning above")
        else:
            right = getattr(recorder, "right_frames_written", 0)
            right = f" + {right} right" if right else ""
            lines.append(f"  recording  {recorder.path} ({recorder.frames_written} frames{right}, "
                         f"{recorder.results_written} results, {size / 1e6:.0f} MB)")
    if summary.get("source_losses"):
        lost = len(summary["source_losses"])
        lines.append(f"  camera     lost {lost} time(s), back {summary['reconnects']} time(s); "
                     f"{summary['outage_s']:.1f} s without frames")
    lines.append(f"  rerun      {summary['rerun']}"
                 + (f" STOPPED EARLY ({summary['rerun_error']}); see the warning above" if summary.get("rerun_error")
                    else ""))
    if summary.get("stopped_by"):
        lines.append(f"  stopped    on {summary['stopped_by']}")
    return "\n".join(lines)


_POINT_LOSSES = (("points_never_trackable", "never trackable"),
                 ("points_lost_later", "lost later, not ok in the last frame"))


def format_pipeline(summary: dict[str, Any]) -> str:
    """How the tracking thread and the output thread did: the tracker against its kernel, the outputs' lag."""
    stages = summary.get("stages") or {}
    parts = []
    tracker, kernel = stages.get("tracker"), stages.get("kernel")
    if tracker and kernel and kernel["p50_ms"] > 0:
        parts.append(f"tracker p50 {tracker['p50_ms']:.1f} ms = {tracker['p50_ms'] / kernel['p50_ms']:.1f}x its "
                     f"sub-pixel kernel ({kernel['p50_ms']:.1f} ms)")
    backlog = summary.get("output_backlog_max")
    if backlog is not None:
        text = (f"outputs in their own thread{', the view in its own process' if summary.get('viewer_process') else ''}"
                f", at most {backlog} result(s) behind")
        if summary.get("output_waits"):
            text += (f"; the tracker waited {summary['output_waits']} time(s) for them (more than "
                     f"{OUTPUT_BACKLOG_MAX} behind)")
        parts.append(text)
    if summary.get("cores"):
        parts.append(summary["cores"])
    left_out = summary.get("viewer_images_left_out")
    above = summary.get("viewer_images_above_rate")
    if left_out or above:
        why = ([f"{above} above the view's {summary['viewer_image_max_hz']:g} images/s"] if above else []) + \
              ([f"{left_out} while the view was behind"] if left_out else [])
        drawn = "every frame's fields and numbers drawn" if not summary.get("viewer_frames_left_out") else ""
        parts.append(f"camera image left out of the view in {(left_out or 0) + (above or 0)} of {summary['frames']} "
                     f"frames ({'; '.join(filter(None, [', '.join(why), drawn]))})")
    if summary.get("viewer_frames_left_out"):
        parts.append(f"{summary['viewer_frames_left_out']} whole frame(s) left out of the view: its process was "
                     f"{VIEW_BACKLOG_MAX} frames behind")
    return "; ".join(parts)


def format_point_losses(summary: dict[str, Any]) -> str:
    """"12 never trackable (8 reference subset has no texture, ...); 5 lost later (...)", or "" when none."""
    parts = []
    for key, what in _POINT_LOSSES:
        item = summary.get(key) or {}
        if item.get("count"):
            reasons = ", ".join(f"{n} {Status[name].description}" for name, n in item["by_status"].items())
            parts.append(f"{item['count']} {what} ({reasons})")
    return "; ".join(parts)
