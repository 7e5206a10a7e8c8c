"""The thread that builds a new key frame's tracker while the tracking thread goes on (issue 20 item 4).

When the reference moves (``dic.tracking.key_frames``), the new key frame's ``Tracker`` (its reference prepared for
IC-GN) used to be built in the tracking thread, in the frame that moved it: that frame, and the frames queued behind
it, came out late. ``KeyFrameTracker.build_on`` hands the build to this thread: the frame that moves the reference
returns once the points are placed, and the next frame waits for the new tracker only if it is not built yet. The
results are the same either way (the same tracker from the same data).

The thread is started at once, not at the first build: ``--cores split`` places the session's threads when tracking
starts (``stream.pipeline.cores``), and a thread started later from the tracking thread would share its CPU. ``attach``
has it build a first tracker (``KeyFrameTracker.build_on``) before the session's frames come: a thread's first build
maps its memory and sets up its OpenMP team (~20-30 ms measured here), which would otherwise fall on the first move.
Measured in docs/guide/performance.md ("The live pipeline: threads, and who waits for whom").
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba


class KeyFrameBuilder:
    """One thread building key frames' trackers for the trackers ``attach`` gives it; ``close`` ends it.

    ``numba_threads``: numba's threads for the builds (numba counts them per thread: the session's).
    """

    def __init__(self, numba_threads: int) -> None:
        self._executor = ThreadPoolExecutor(1, thread_name_prefix="livedic-key-frames",
                                            initializer=numba.set_num_threads, initargs=(int(numba_threads),))
        self._executor.submit(int).result()       # the thread exists from now on (module notes)
        self._attached: list[Any] = []

    def attach(self, tracker: Any) -> None:
        """``tracker`` builds its key frames here, if it can (``build_on``; a plain ``Tracker`` has none); returns once
        this thread has built a first tracker like it (module notes)."""
        build_on = getattr(tracker, "build_on", None)
        if build_on is not None:
            build_on(self._executor)
            self._attached.append(tracker)

    def close(self) -> None:
        """Wait for a build in progress and end the thread; the trackers build in their own calls again."""
        for tracker in self._attached:
            tracker.build_on(None)
        self._attached.clear()
        self._executor.shutdown(wait=True)

