"""A stereo session's own parts: its calibration, its tracker on the reference pair, its summary lines.

A stereo source (``stereo:LEFT_URI,RIGHT_URI``, ``acquire.stereo``) delivers each pair as its left ``Frame`` with
the right one in ``Frame.right``: everything a 2D session does with a frame (queue, drops, recording, the
camera view, P0) it does with the left view, and the right view travels along. The tracker is a
``dic.stereo.StereoTracker`` (both views tracked, triangulated), built on the reference pair after the left ->
right match; the strain stage is ``stream.stages.stereo_strain.StereoStrainStage``. The guide:
docs/guide/stereo.md.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from livedic.dic.calibration import StereoCalibration
from livedic.dic.stereo import StereoStatus, StereoTracker, match_stereo

CALIBRATION_FROM_SOURCE = "the simulator's exact rig (no --calibration given)"
# The session metadata's key of a stereo session: {"calibration": StereoCalibration.to_dict(), "calibration_from"}.
STEREO_KEY = "stereo"


def stereo_calibration(given: StereoCalibration | None, source_settings: dict) -> tuple[StereoCalibration, str]:
    """The rig's calibration and where it came from: ``--calibration`` (a stereo CAL.json, ``SessionConfig.rig``),
    else the simulator's own.

    Raises
    ------
    ValueError
        One line: no calibration for a source that does not know its rig.
    """
    if given is not None:
        return given, "the calibration file"
    views = [source_settings.get(view) or {} for view in ("left", "right")]
    known = [(view.get("stereo") or {}).get("calibration") for view in views]
    if known[0] is not None and known[0] == known[1]:
        return StereoCalibration.from_dict(known[0]), CALIBRATION_FROM_SOURCE
    raise ValueError("a stereo source needs the rig's calibration: --calibration RIG.json (livedic calibrate "
                     "--left ... --right ...)")


def make_stereo_tracker(calibration: StereoCalibration, frame: Any, points: np.ndarray, tracking: Any
                        ) -> tuple[StereoTracker, float]:
    """The ``StereoTracker`` on the reference pair ``frame`` (its ``right``) and the match's seconds.

    ``tracking``: the session's ``TrackingConfig`` (its subset for the match, its ``tracker`` for both views).

    Raises
    ------
    ValueError
        One line: no point matched between the views (``StereoTracker``), or frames of another size than the
        calibration's.
    """
    for view, image in (("left", frame.image), ("right", frame.right.image)):
        camera = getattr(calibration, view)
        camera.check_size(image.shape[1], image.shape[0], f"the {view} camera's frames")
    started = time.perf_counter()
    match = match_stereo(calibration, frame.image, frame.right.image, points, subset=tracking.subset)
    seconds = time.perf_counter() - started
    return StereoTracker(calibration, match, frame.image, frame.right.image, tracking.tracker), seconds


def match_summary(tracker: StereoTracker, seconds: float) -> dict[str, Any]:
    """The reference match in numbers: points matched, why the others were not, the time it took."""
    status = tracker.match.status
    reasons = {StereoStatus(code).name.lower(): int(np.sum(status == code)) for code in np.unique(status)
               if code != StereoStatus.OK}
    return {"points": int(status.size), "matched": int(np.sum(status == StereoStatus.OK)), "not_matched": reasons,
            "match_s": round(seconds, 3), "baseline_mm": tracker.calibration.baseline_mm,
            "angle_deg": tracker.calibration.angle_deg}


def describe_match(match: dict[str, Any]) -> str:
    """The reference match in one line (``match_summary``'s numbers)."""
    return (f"reference match: {match['matched']} of {match['points']} points in {match['match_s']:.1f} s"
            + ("" if not match["not_matched"] else " (not matched: " + ", ".join(
                f"{n} {reason}" for reason, n in match["not_matched"].items()) + ")"))


def stereo_lines(stereo: dict[str, Any]) -> list[str]:
    """The summary's stereo lines: the rig, the reference match, the last frame's 3D points, the pairing."""
    match = stereo["match"]
    lines = [f"  stereo     rig: baseline {match['baseline_mm']:.1f} mm, {match['angle_deg']:.1f} degrees; "
             f"calibration: {stereo['calibration_from']}",
             f"             {describe_match(match)}"]
    last = stereo.get("last")
    if last:
        lines.append(f"             last frame: {last['ok']} of {last['points']} points in 3D; W {last['w_min_mm']:+.4f} "
                     f"to {last['w_max_mm']:+.4f} mm, |U, V, W| max {last['displacement_max_mm']:.4f} mm")
    pairing = stereo.get("pairing")
    if pairing:
        lines.append(f"             pairs: {pairing.get('pairs', 0)} made, {pairing.get('pairs_dropped', 0)} dropped "
                     f"(unmatched frames, never mismatched); worst skew {pairing.get('max_abs_skew_ms', 0.0):.3f} ms")
    return lines


def last_frame_numbers(points: Any) -> dict[str, Any] | None:
    """A frame's 3D points in a few numbers (the summary's "last frame")."""
    ok = points.ok
    if not np.any(ok):
        return {"points": int(ok.size), "ok": 0, "w_min_mm": float("nan"), "w_max_mm": float("nan"),
                "displacement_max_mm": float("nan")}
    w = points.displacement[ok, 2]
    return {"points": int(ok.size), "ok": int(np.sum(ok)), "w_min_mm": float(np.min(w)), "w_max_mm": float(np.max(w)),
            "displacement_max_mm": float(np.max(np.linalg.norm(points.displacement[ok], axis=1)))}
