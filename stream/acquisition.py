"""The acquisition thread: the only code that touches the frame source while a session runs.

It iterates the source, stamps each frame with its arrival time
(``time.monotonic_ns``) and puts it in a ``FrameQueue``, which never blocks:
a slow tracker makes the queue drop frames, never the camera wait. When the
source ends, fails or a stop is requested the thread closes the source and
the queue; a failure is kept in ``error`` for the main thread to raise, so
a lost camera ends the session with a message instead of a silent hang.
"""

import threading
import time
from dataclasses import dataclass

from acquire.base import Frame, SourceError
from stream.frame_queue import QueueClosed


@dataclass(frozen=True)
class QueuedFrame:
    """A frame and when the acquisition thread received it (``time.monotonic_ns``)."""
    frame: Frame
    arrival_ns: int


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
    on_frame : callable, optional
        ``on_frame(queued_frame)`` called in this thread before each put (e.g. to record
        every frame, dropped or not); an exception there stops acquisition and is kept in ``error``.

    Attributes
    ----------
    error : BaseException or None
        Why acquisition stopped early: a ``SourceError`` from the source (or any
        other exception, wrapped in ``SourceError`` with its type named).
    frames : int
        Frames received from the source and queued (or dropped by the queue).
    first_index, last_index : int or None
        ``Frame.index`` of the first and latest of them (gaps = frames lost upstream).
    finished_reason : str
        ``"end"`` (source exhausted), ``"limit"`` (max_frames), ``"stopped"`` or ``"error"``.
    """

    def __init__(self, source, queue, *, max_frames=None, on_frame=None, name="livedic-acquisition"):
        super().__init__(name=name, daemon=True)
        self.source = source
        self.queue = queue
        self.max_frames = max_frames
        self.on_frame = on_frame
        self.error = None
        self.frames = 0
        self.first_index = None
        self.last_index = None
        self.finished_reason = None
        self._stop_requested = threading.Event()

    def stop(self):
        """Ask the thread to stop after the frame it is waiting for (does not block)."""
        self._stop_requested.set()

    @property
    def stop_requested(self):
        return self._stop_requested.is_set()

    def run(self):
        reason = "end"
        try:
            if self.max_frames is not None and self.max_frames <= 0:
                reason = "limit"
                return
            for frame in self.source:
                arrival_ns = time.monotonic_ns()
                if self._stop_requested.is_set():
                    reason = "stopped"
                    break
                item = QueuedFrame(frame, arrival_ns)
                if self.on_frame is not None:
                    self.on_frame(item)
                try:
                    self.queue.put(item)
                except QueueClosed:
                    reason = "stopped"
                    break
                self.frames += 1
                if self.first_index is None:
                    self.first_index = frame.index
                self.last_index = frame.index
                if self.max_frames is not None and self.frames >= self.max_frames:
                    reason = "limit"
                    break
                if self._stop_requested.is_set():
                    reason = "stopped"
                    break
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
                self.source.close()
            except Exception as error:  # noqa: BLE001 - keep the first error, report a close failure otherwise
                if self.error is None:
                    self.error = SourceError(f"closing the frame source failed: {type(error).__name__}: {error}")
                    self.finished_reason = "error"
            self.queue.close()

    def raise_error(self):
        """Raise the source failure in the calling thread, if there was one."""
        if self.error is not None:
            raise self.error
