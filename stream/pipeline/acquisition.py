"""The acquisition thread: the only code that touches the frame source while a session runs.

It iterates the source, stamps each frame with its arrival time
(``time.monotonic_ns``) and puts it in a ``FrameQueue``, which never blocks:
a slow tracker makes the queue drop frames, never the camera wait. When the
source ends, fails or a stop is requested the thread closes the source and
the queue; a failure is kept in ``error`` for the main thread to raise, so
a lost camera ends the session with a message instead of a silent hang.

With ``reconnect`` (``livedic run --reconnect``) a source that fails mid-run
is closed and reopened every ``retry_s`` until it delivers again, the
session goes on with the same reference, queue and recording. Frames after
a reconnection are renumbered and re-timed to continue the session's
sequence (a power-cycled camera restarts its frame counter and its clock;
the recording and the results need increasing indices and times); the
camera's own values stay in ``metadata["source_index"]`` and
``metadata["source_timestamp_ns"]``. A camera that comes back with another
image size or pixel format cannot continue the session: that ends it with
an error.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from livedic.acquire.base import Frame, SourceError
from livedic.stream.pipeline.frame_queue import FrameQueue, QueueClosed

if TYPE_CHECKING:
    from livedic.acquire.base import FrameSource


@dataclass(frozen=True)
class Reconnect:
    """How to bring a lost source back.

    reopen : callable
        ``reopen() -> FrameSource``, an opened source (raises ``SourceError`` while it cannot).
    retry_s : float
        Seconds between attempts.
    timeout_s : float or None
        Give up (end the session with the loss as its error) after this long; None waits
        until a stop is requested.
    on_event : callable, optional
        ``on_event(kind, message, level)`` from the acquisition thread: ``"camera_lost"``,
        ``"camera_waiting"`` (about every 10 s), ``"camera_reconnected"``, ``"camera_gave_up"``.
    """
    reopen: Callable[[], FrameSource]
    retry_s: float = 1.0
    timeout_s: float | None = None
    on_event: Callable[[str, str, str], None] | None = None


@dataclass(frozen=True)
class QueuedFrame:
    """A frame, when the acquisition thread received it (``time.monotonic_ns``) and what ``prepare`` made of it."""
    frame: Frame
    arrival_ns: int
    ahead: Any = None


class AcquisitionThread(threading.Thread):
    """Owns ``source``: opens nothing, closes it when done.

    Parameters
    ----------
    source : FrameSource
        Already opened; iterated in this thread only and closed at the end.
    queue : FrameQueue
        Receives ``QueuedFrame`` items; closed when the thread ends.
    max_frames : int, optional
        Stop after this many frames.
    prepare : callable, optional
        ``prepare(frame)`` called in this thread before each put, its return value queued with the frame
        (``QueuedFrame.ahead``: the tracker's prefiltered frame, made while it tracks the frame before); an
        exception there stops acquisition and is kept in ``error``.
    on_frame : callable, optional
        ``on_frame(queued_frame)`` called in this thread after each put (e.g. to record
        every frame, dropped or not: the tracker already has it while it is written); an
        exception there stops acquisition and is kept in ``error``.
    reconnect : Reconnect, optional
        Reopen a source that fails mid-run instead of ending (see the module notes).

    Attributes
    ----------
    error : BaseException or None
        Why acquisition stopped early: a ``SourceError`` from the source (or any
        other exception, wrapped in ``SourceError`` with its type named).
    frames : int
        Frames received from the source and queued (or dropped by the queue).
    first_index, last_index : int or None
        ``Frame.index`` of the first and latest of them (gaps = frames lost upstream).
    skipped_before_start : int
        Frames the source skipped between the first (the reference, taken while the session was being
        prepared: points placed, outputs opened) and the second: a camera goes on streaming meanwhile.
    finished_reason : str
        ``"end"`` (source exhausted), ``"limit"`` (max_frames), ``"stopped"`` or ``"error"``.
    reconnects : int
        Times the source came back after a loss.
    outage_s : float
        Seconds without frames (last frame before a loss to reconnection or stop), summed
        over the losses; updated when each one ends.
    losses : list of str
        The messages of the failures that were waited out (or are being waited out).
    waiting : bool
        True while the source is lost and being reopened.
    """

    def __init__(self, source: FrameSource, queue: FrameQueue, *, max_frames: int | None = None,
                 on_frame: Callable[[QueuedFrame], None] | None = None, reconnect: Reconnect | None = None,
                 prepare: Callable[[Frame], Any] | None = None, name: str = "livedic-acquisition") -> None:
        super().__init__(name=name, daemon=True)
        self.source: FrameSource | None = source
        self.queue = queue
        self.max_frames = max_frames
        self.on_frame = on_frame
        self.prepare = prepare
        self.error: BaseException | None = None
        self.frames = 0
        self.first_index: int | None = None
        self.last_index: int | None = None
        self.skipped_before_start = 0
        self.finished_reason: str | None = None
        self.reconnect = reconnect
        self.reconnects = 0
        self.outage_s = 0.0
        self.losses: list[str] = []
        self.waiting = False
        self._stop_requested = threading.Event()
        self._continuity: tuple[int, int] | None = None          # (index offset, timestamp offset) after a reconnection
        self._continuity_pending = False  # reconnected: the next frame sets _continuity
        self._last: tuple[Any, ...] | None = None  # (index, timestamp_ns, arrival_ns, shape, dtype, pixel format)

    def stop(self) -> None:
        """Ask the thread to stop after the frame it is waiting for (does not block)."""
        self._stop_requested.set()

    @property
    def stop_requested(self) -> bool:
        return self._stop_requested.is_set()

    def run(self) -> None:
        reason = "end"
        try:
            if self.max_frames is not None and self.max_frames <= 0:
                reason = "limit"
                return
            while True:
                try:
                    reason = self._pump()
                    break
                except SourceError as error:
                    if self.reconnect is None or isinstance(error, _Incompatible) or self._last is None:
                        raise   # (a source that never delivered is a bad URI or setting, not a lost camera)
                    outcome = self._wait_for_source(error)
                    if outcome == "stopped":
                        reason = "stopped"
                        break
                    if outcome == "gave up":
                        raise SourceError(f"{error}; not back within --reconnect-timeout "
                                          f"{self.reconnect.timeout_s:g} s") from error
        except SourceError as error:
            self.error = error
            reason = "error"
        except Exception as error:  # noqa: BLE001 - a source bug must still reach the main thread
            wrapped = SourceError(f"frame source failed: {type(error).__name__}: {error}")
            wrapped.__cause__ = error
            self.error = wrapped
            reason = "error"
        finally:
            self.finished_reason = reason
            try:
                if self.source is not None:
                    self.source.close()
            except Exception as error:  # noqa: BLE001 - keep the first error, report a close failure otherwise
                if self.error is None:
                    self.error = SourceError(f"closing the frame source failed: {type(error).__name__}: {error}")
                    self.finished_reason = "error"
            self.queue.close()

    def _pump(self) -> str:
        """Move frames from the source to the queue; returns the finish reason."""
        assert self.source is not None          # None only while a lost source is being reopened
        for frame in self.source:
            arrival_ns = time.monotonic_ns()
            if self._stop_requested.is_set():
                return "stopped"
            frame = self._continue_session(frame, arrival_ns)
            item = QueuedFrame(frame, arrival_ns, None if self.prepare is None else self.prepare(frame))
            try:
                self.queue.put(item)
                closed = False
            except QueueClosed:
                closed = True
            if self.on_frame is not None:
                self.on_frame(item)     # after the put: the tracker has the frame while it is written
            if closed:
                return "stopped"
            self.frames += 1
            if self.first_index is None:
                self.first_index = frame.index
            elif self.frames == 2:
                self.skipped_before_start = max(0, frame.index - self.first_index - 1)
            self.last_index = frame.index
            self._last = (frame.index, frame.timestamp_ns, arrival_ns, frame.image.shape, frame.image.dtype,
                          frame.pixel_format)
            if self.max_frames is not None and self.frames >= self.max_frames:
                return "limit"
            if self._stop_requested.is_set():
                return "stopped"
        return "end"

    def _continue_session(self, frame: Frame, arrival_ns: int) -> Frame:
        """After a reconnection: check the image matches, then renumber and re-time the frame."""
        if self._continuity_pending:
            assert self._last is not None       # a reconnection follows a delivered frame
            last_index, last_ts, last_arrival, shape, dtype, pixel_format = self._last
            if (frame.image.shape, frame.image.dtype, frame.pixel_format) != (shape, dtype, pixel_format):
                height, width = frame.image.shape[:2]
                raise _Incompatible(
                    f"the source came back with {width}x{height} {frame.pixel_format} images but the session "
                    f"started with {shape[1]}x{shape[0]} {pixel_format}: start a new session")
            gap_ns = max(arrival_ns - last_arrival, 1)
            self._continuity = (last_index + 1 - frame.index, last_ts + gap_ns - frame.timestamp_ns)
            self._continuity_pending = False
        if self._continuity is None:
            return frame
        index_offset, time_offset = self._continuity
        metadata = dict(frame.metadata) if isinstance(frame.metadata, dict) else {}
        metadata.update(source_index=frame.index, source_timestamp_ns=frame.timestamp_ns)
        return dataclasses.replace(frame, index=frame.index + index_offset,
                                   timestamp_ns=frame.timestamp_ns + time_offset, metadata=metadata)

    def _wait_for_source(self, error: SourceError) -> str:
        """Close the failed source and reopen it until it works: "back", "stopped" or "gave up"."""
        policy = self.reconnect
        last = self._last
        assert policy is not None and last is not None     # run() waits only with a policy, after a frame
        lost_at = time.monotonic()
        message = str(error)
        self.losses.append(message)
        self.waiting = True
        self._event("camera_lost", f"{message}; reconnecting every {policy.retry_s:g} s "
                    + (f"for up to {policy.timeout_s:g} s" if policy.timeout_s else "until stopped"), "error")
        source, self.source = self.source, None
        try:
            if source is not None:
                source.close()
        except Exception:  # noqa: BLE001 - the source is gone anyway
            pass
        attempts = 0
        last_note = lost_at
        try:
            while not self._stop_requested.wait(policy.retry_s if attempts else 0.0):
                now = time.monotonic()
                if policy.timeout_s is not None and now - lost_at > policy.timeout_s:
                    self._event("camera_gave_up", f"the source did not come back within {policy.timeout_s:g} s "
                                f"({attempts} attempts)", "error")
                    return "gave up"
                attempts += 1
                try:
                    self.source = policy.reopen()
                except SourceError as retry_error:
                    if now - last_note >= 10.0:
                        last_note = now
                        self._event("camera_waiting", f"still waiting for the source after {now - lost_at:.0f} s: "
                                    f"{retry_error}", "warning")
                    continue
                self.reconnects += 1
                self._continuity_pending = True
                self._event("camera_reconnected", f"source back after {time.monotonic() - lost_at:.1f} s "
                            f"({attempts} attempt(s)); the session continues from frame {last[0] + 1}",
                            "warning")
                return "back"
            self._event("note", "session stopped while waiting for the source", "warning")
            return "stopped"
        finally:
            # Counted from the last frame received, not from the detection: the frames missed.
            self.outage_s += (time.monotonic_ns() - last[2]) / 1e9
            self.waiting = False

    def _event(self, kind: str, message: str, level: str) -> None:
        callback = self.reconnect.on_event if self.reconnect is not None else None
        if callback is not None:
            try:
                callback(kind, message, level)
            except Exception:  # noqa: BLE001 - a broken reporter must not stop acquisition
                pass

    def raise_error(self) -> None:
        """Raise the source failure in the calling thread, if there was one."""
        if self.error is not None:
            raise self.error


class _Incompatible(SourceError):
    """A reconnected source whose images cannot continue the session."""
