"""Camera frames written to the recording in a thread of their own, in order, behind the acquisition (issue 20).

The acquisition thread hands each frame to ``FrameRecording`` after queueing it for the tracker and goes back
to the camera at once. Writing is fast until a 4 MiB chunk leaves for the kernel: at 100 fps of 1 MP frames
(100 MB/s) that call can wait tens of milliseconds for the page cache, and while it waited in the acquisition
thread the next frames reached the tracker that much later (docs/guide/performance.md, "Recording").

Nothing is lost: at most ``max_waiting`` frames wait (the default ``RECORD_BACKLOG_MAX``: 2 s at 100 fps, their
buffers held); beyond that the acquisition thread waits for the writer, counted in ``waits``, and frames are then
dropped at the tracker's queue (counted there), never in the recording. An error in ``write`` is raised in the
acquisition thread at its next hand-over (and by ``close``), as if it had written the frame itself.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from typing import Any

from livedic.stream.pipeline.cores import OUTPUT_NICE, lower_priority

RECORD_BACKLOG_MAX = 200         # frames waiting to be written before the acquisition thread waits


class FrameRecording:
    """``write(item)`` for each item handed over (``__call__``), in order, in the thread ``livedic-frame-recorder``.

    ``max_backlog``: the most items that waited at once; ``waits``: hand-overs that waited for room.
    """

    def __init__(self, write: Callable[[Any], None], *, max_waiting: int = RECORD_BACKLOG_MAX) -> None:
        if max_waiting < 1:
            raise ValueError(f"max_waiting must be >= 1, got {max_waiting}")
        self._write = write
        self._waiting: queue.Queue[Any] = queue.Queue(maxsize=max_waiting)
        self._error: BaseException | None = None
        self._closed = False
        self.max_backlog = 0
        self.waits = 0
        self._thread = threading.Thread(target=self._run, name="livedic-frame-recorder", daemon=True)
        self._thread.start()

    def __call__(self, item: Any) -> None:
        """Hand ``item`` over (the acquisition thread's ``on_frame``); waits only while ``max_waiting`` wait."""
        self._raise_error()
        if self._closed:
            raise RuntimeError("FrameRecording is closed")
        try:
            self._waiting.put_nowait(item)
        except queue.Full:
            self.waits += 1
            self._waiting.put(item)
        self.max_backlog = max(self.max_backlog, self._waiting.qsize())

    def close(self) -> None:
        """Write what waits, end the thread; raises the writer's error if one came. Idempotent."""
        if not self._closed:
            self._closed = True
            self._waiting.put(None)
            self._thread.join()
        self._raise_error()

    def _raise_error(self) -> None:
        error, self._error = self._error, None
        if error is not None:
            raise error

    def _run(self) -> None:
        lower_priority(OUTPUT_NICE)     # an output: the acquisition thread on the same core comes first
        while True:
            item = self._waiting.get()
            if item is None:
                return
            if self._error is not None:
                continue                # the error is told once; what follows is not written after it
            try:
                self._write(item)
            except BaseException as error:  # noqa: BLE001 - raised in the acquisition thread instead
                self._error = error
