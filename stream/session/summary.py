"""The end-of-session text: ``format_summary`` turns ``Session.summary()`` (a dict) into a few aligned lines.

``format_strain_summary`` (used by replay too), ``format_pipeline`` and ``format_point_losses`` are its parts.
"""

import math
import os

from livedic.dic.status import Status
from livedic.stream.pipeline.tracker_loop import OUTPUT_BACKLOG_MAX
from livedic.stream.publish import format_publish_summary
from livedic.stream.stages.contraction import format_poisson
from livedic.stream.stages.force import format_force_summary
from livedic.stream.stages.strain import format_length
from livedic.stream.view.process import BACKLOG_MAX as VIEW_BACKLOG_MAX


def format_summary(summary, reference, recorder):
    """The end-of-run text (plain, a few aligned lines)."""
    def num(value, fmt):
        return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else format(value, fmt)

    lines = [f"livedic run: {summary['source']}  ({summary['method']})"]
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
                     f"{num(summary['error_max_px'], '.4f')} px against the truth (ok points)")
    lines.extend(format_strain_summary(summary.get("strain")))
    lines.extend(format_force_summary(summary.get("force")))
    lines.extend(format_publish_summary(summary.get("publish")))
    if recorder is not None:
        size = os.path.getsize(recorder.path) if os.path.exists(recorder.path) else 0
        if recorder.error:
            lines.append(f"  recording  {recorder.path} STOPPED EARLY: {recorder.frames_durable} frames kept "
                         f"({size / 1e6:.0f} MB); see the warning above")
        else:
            lines.append(f"  recording  {recorder.path} ({recorder.frames_written} frames, "
                         f"{recorder.results_written} results, {size / 1e6:.0f} MB)")
    if summary.get("source_losses"):
        losses = len(summary["source_losses"])
        lines.append(f"  camera     lost {losses} time(s), back {summary['reconnects']} time(s); "
                     f"{summary['outage_s']:.1f} s without frames")
    lines.append(f"  rerun      {summary['rerun']}"
                 + (f" STOPPED EARLY ({summary['rerun_error']}); see the warning above" if summary.get("rerun_error")
                    else ""))
    if summary.get("stopped_by"):
        lines.append(f"  stopped    on {summary['stopped_by']}")
    return "\n".join(lines)


_POINT_LOSSES = (("points_never_trackable", "never trackable"),
                 ("points_lost_later", "lost later, not ok in the last frame"))


def format_pipeline(summary):
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


def format_point_losses(summary):
    """"12 never trackable (8 reference subset has no texture, ...); 5 lost later (...)", or "" when none."""
    parts = []
    for key, what in _POINT_LOSSES:
        item = summary.get(key) or {}
        if item.get("count"):
            reasons = ", ".join(f"{n} {Status[name].description}" for name, n in item["by_status"].items())
            parts.append(f"{item['count']} {what} ({reasons})")
    return "; ".join(parts)


def format_strain_summary(strain):
    """The summary's strain lines (none without strain): window, VSG, final extensometer readings."""
    if not strain:
        return []
    lines = [f"  strain     {strain['strain_measure']}, window {strain['strain_window']} points, VSG "
             f"{strain['vsg_px']:.0f} px; {strain['strain_ms_p50']:.2f} ms/frame (p99 {strain['strain_ms_p99']:.2f})"]
    for name, final in strain["extensometers"].items():
        reading = (f"{100 * final['eng_strain']:.3f} % engineering, {100 * final['true_strain']:.3f} % true"
                   if final["ok"] else "no reading in the last frame (an end lost)")
        error = final.get("error_max_vs_truth")
        versus = f"; max error vs truth {1e6 * error:.0f} microstrain" if error is not None else ""
        lines.append(f"  extensom.  {name}: L0 {format_length(final['L0_px'], final.get('L0_mm'))}, final "
                     f"{reading}{versus}")
    if strain.get("poisson_ratio"):
        lines.append(f"  Poisson    {format_poisson(strain['poisson_ratio'])}")
    return lines
