"""The machine's force in a live session: the load source opened, the force and stress of every frame.

``--load URI`` opens a force source (``acquire.force``: ``csv:FILE``, ``tcp://HOST:PORT``,
``synthetic`` for the simulated test's own law); ``--area MM2`` (or ``--width MM --thickness
MM``) gives the original cross-section A0 (the simulated test's own when ``--load synthetic``).
``LoadStage`` is a session stage (``stream.pipeline.stage.Stage``) placed after the strain stage: per frame
it takes the force at the frame's time (seconds since the first frame for files and the simulator, the arrival on the
monotonic clock for a stream), interpolated, never extrapolated, NaN where the source has none
(a stalled or lost stream: never a stale value), and the engineering stress F / A0, attaches both
to the ``FrameResult`` (``result.force_N``, ``result.stress_MPa``) for the sinks after it
(recording, Rerun's stress-strain curve, progress line), with the true strain and true stress of
the ``axial`` extensometer while the elongation may be uniform (``result.true_strain``,
``result.true_stress_MPa``; ``stream.stages.stress.UniformElongationWatch``), reports the source's
events (connected, stalled, lost) and keeps the numbers for the summary (``format_force_summary``).
"""

import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any, ClassVar

from livedic.acquire.force import open_load
from livedic.dic.strain.extensometer import AXIAL
from livedic.stream.pipeline.frame_result import FrameResult
from livedic.stream.pipeline.stage import Reference, Stage
from livedic.stream.stages.stress import UniformElongationWatch


MISALIGNED_FRAMES = 25    # frames without force while samples arrive before the misalignment warning (0.5 s at 50 fps)


def open_session_load(uri: str, *, offset_s: float | None, camera: Any) -> Any:
    """The load source for ``uri`` (``--load``): ``synthetic`` uses the session's simulated camera.

    Raises ValueError (``acquire.force.LoadError``: one line) for a bad URI or file.
    """
    text = str(uri).strip()
    if text.lower() == "synthetic":
        return open_load("synthetic", source=camera, offset_s=offset_s)
    return open_load(text, offset_s=offset_s)


class LoadStage(Stage):
    """Force and stress per frame (a session stage; see the module notes).

    Parameters
    ----------
    load : acquire.force.LoadSource
    area_mm2 : float or None
        A0; None: force only (stress NaN).
    report : callable
        ``report(kind, message, level)``: the session's event.
    """
    name = "force"
    required = False
    needs: ClassVar[tuple[str, ...]] = ("frame", "arrival_ns", "extensometers")
    provides: ClassVar[tuple[str, ...]] = ("force_N", "stress_MPa", "true_strain", "true_stress_MPa")

    def __init__(self, load: Any, area_mm2: float | None, report: Callable[[str, str, str], None]) -> None:
        self.load = load
        self.area_mm2 = area_mm2
        self.report = report
        self.first_ns: int | None = None
        self.frames = 0
        self.frames_without_force = 0
        self.max_force_N = -math.inf
        self.last_force_N = math.nan
        self.last_stress_MPa = math.nan
        self.seconds = 0.0
        self._events_seen = 0
        self.uniform = UniformElongationWatch(area_mm2) if area_mm2 else None
        self._arriving_without_force = 0       # frames in a row with no force while new samples kept arriving
        self._last_sample_s = math.nan
        self.misaligned_warned = False

    def on_reference(self, reference: Reference) -> None:
        """The frames' time counts from the reference frame's (files and the simulator)."""
        if reference.timestamp_ns is not None:
            self.first_ns = reference.timestamp_ns

    def on_frame(self, result: FrameResult) -> None:
        """The force at the frame's time, the stress (and true strain and stress) into ``result``."""
        started = time.perf_counter()
        frame = result.frame
        if self.first_ns is None:
            self.first_ns = frame.timestamp_ns
        when = self.load.frame_time_s(since_first_frame_s=(frame.timestamp_ns - self.first_ns) / 1e9,
                                      arrival_ns=result.arrival_ns)
        force = self.load.force_when_known(float(when))     # a live stream: waits (bounded) for its next sample
        stress = force / self.area_mm2 if self.area_mm2 and math.isfinite(force) else math.nan
        result.force_N, result.stress_MPa = force, stress
        if self.uniform is not None:
            result.true_strain, result.true_stress_MPa = self.uniform(force, axial_strain(result))
        self.frames += 1
        if math.isfinite(force):
            self.max_force_N = max(self.max_force_N, force)
        else:
            self.frames_without_force += 1
        self.last_force_N, self.last_stress_MPa = force, stress
        self._check_alignment(force, when)
        events = self.load.events(since=self._events_seen)
        self._events_seen += len(events)
        for event in events:
            self.report("load", f"force source: {event.message}", "warning" if event.kind.is_trouble else "info")
        self.seconds += time.perf_counter() - started

    def _check_alignment(self, force, when):
        """Warn once when samples keep arriving but none lies at the frames' times (a stall sends none).

        A sender whose ``time_s`` is on another clock than livedic's (``?clock=sender`` with the time since
        its own start) or a wrong ``--load-offset`` otherwise gives NaN at every frame without a word.
        """
        newest = self.load.last_sample_time_s
        arriving = math.isfinite(newest) and newest != self._last_sample_s
        self._last_sample_s = newest
        self._arriving_without_force = self._arriving_without_force + 1 \
            if (not math.isfinite(force) and arriving) else 0
        if self._arriving_without_force >= MISALIGNED_FRAMES and not self.misaligned_warned:
            self.misaligned_warned = True
            self.report("load", f"force source: samples keep arriving but none lies at the frames' times (newest "
                                f"sample at {newest:.3f} s, this frame at {when:.3f} s on the same clock): no force "
                                f"for {MISALIGNED_FRAMES} frames; check the stream's ?clock=sender and --load-offset",
                        "warning")

    def summary(self) -> dict[str, Any]:
        """The force numbers for the session summary (NaN/None where missing)."""
        top = self.max_force_N if math.isfinite(self.max_force_N) else math.nan
        counts = dataclasses.asdict(self.load.warnings)
        return {"load": self.load.uri, "area_mm2": self.area_mm2, "max_force_N": top,
                "max_stress_MPa": top / self.area_mm2 if self.area_mm2 and math.isfinite(top) else math.nan,
                "final_force_N": self.last_force_N, "final_stress_MPa": self.last_stress_MPa,
                "frames_without_force": self.frames_without_force, "frames": self.frames,
                "source_warnings": {name: n for name, n in counts.items() if n and name != "trimmed"}}

    def summary_lines(self) -> list[str]:
        """The summary's force line."""
        return format_force_summary(self.summary())

    def metadata(self) -> dict[str, Any]:
        """A0 as used (given, or the load source's specimen)."""
        return {"area_mm2": self.area_mm2}


def axial_strain(result: FrameResult) -> float:
    """The ``axial`` extensometer's engineering strain in ``result`` (NaN without one or without a reading)."""
    readings = result.extensometers
    if readings is None or AXIAL not in readings.names:
        return math.nan
    strain, _, ok = readings.reading(AXIAL)
    return strain if ok else math.nan


def format_force_summary(force: dict | None) -> list[str]:
    """The summary's force line (none without a load)."""
    if not force:
        return []

    def known(value):
        return value is not None and math.isfinite(value)
    missing = force["frames_without_force"]
    if known(force["max_force_N"]):
        text = f"  force      {force['load']}: max {force['max_force_N']:,.0f} N"
        text += (f" = {force['max_stress_MPa']:.1f} MPa on A0 {force['area_mm2']:g} mm^2" if force["area_mm2"]
                 else " (no --area: no stress)")
        final = force["final_force_N"]
        text += f"; final {final:,.0f} N" if known(final) else "; no force at the last frame"
    else:
        text = f"  force      {force['load']}: no force at any frame"
    if missing:
        text += f"; {missing} of {force['frames']} frames without force (NaN)"
    skipped = force.get("source_warnings") or {}
    if skipped:
        text += "; source: " + ", ".join(f"{n} {name.replace('_', ' ')}" for name, n in sorted(skipped.items()))
    return [text]
