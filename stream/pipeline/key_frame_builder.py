"""New key frames' trackers built by the tracking thread between frames, after the moving frame's result is out.

When the reference moves (``dic.tracking.key_frames``), the new key frame's ``Tracker`` (its reference prepared for
IC-GN, ~5-10 ms at 1,059 points) used to be built in the call that moved it: that frame's result, and the frames
queued behind it, came out late. ``KeyFrameTracker.build_on(builder)`` hands the build to ``KeyFrameBuilder``: the
frame that moves the reference returns once the points are placed, its result goes to the outputs, and the tracking
loop then builds the tracker (``run_pending``) before it takes the next frame, in the time it would spend waiting for
it. The results are the same either way (the same tracker from the same data).

Why not a thread of its own (the previous design): on two cores, the other core carries the acquisition and
every output; a build there took 8-43 ms of wall time for 6-16 ms of CPU, and the next frame waited for it (10-40 ms
at 100 fps, measured at each move). Between frames, on the tracking thread's own core, it takes its CPU time and no
more, and at 50 fps it fits in the ~13 ms the thread has between frames. Measured in docs/guide/performance.md ("The
live pipeline: threads, and who waits for whom").
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any


class DeferredBuild(Future):
    """A build that runs when ``run`` is called, or in the first ``result`` call if nobody ran it before.

    ``done()`` is False until it has run: a caller that must not wait (a camera's acquisition thread) asks it first.
    """

    def __init__(self, build: Callable[..., Any], args: tuple, kwargs: dict) -> None:
        super().__init__()
        self._build: tuple[Callable[..., Any], tuple, dict] | None = (build, args, kwargs)
        self._running = threading.Lock()

    def run(self) -> None:
        """Run the build here (once: later calls, and calls while another thread runs it, return at once)."""
        with self._running:
            if self._build is None:
                return
            build, args, kwargs = self._build
            self._build = None
        if not self.set_running_or_notify_cancel():
            return
        try:
            self.set_result(build(*args, **kwargs))
        except BaseException as error:  # noqa: BLE001 - handed to whoever takes the result, as an executor does
            self.set_exception(error)

    def result(self, timeout: float | None = None) -> Any:
        self.run()
        return super().result(timeout)

    def exception(self, timeout: float | None = None) -> BaseException | None:
        self.run()
        return super().exception(timeout)


class KeyFrameBuilder(Executor):
    """An executor whose builds (``submit``) the tracking loop runs between frames (``run_pending``), for the trackers
    ``attach`` gives it; ``close`` hands the trackers back their own builds."""

    def __init__(self) -> None:
        self._pending: deque[DeferredBuild] = deque()
        self._attached: list[Any] = []

    def submit(self, build: Callable[..., Any], /, *args: Any, **kwargs: Any) -> DeferredBuild:
        """``build(*args, **kwargs)`` to run at the next ``run_pending`` (or when its result is first asked for)."""
        deferred = DeferredBuild(build, args, kwargs)
        self._pending.append(deferred)
        return deferred

    def run_pending(self) -> None:
        """Run the builds submitted since the last call (the tracking loop, once a frame's result is out)."""
        while self._pending:
            self._pending.popleft().run()

    def attach(self, tracker: Any) -> None:
        """``tracker`` submits its key frames' builds here, if it has any (``build_on``; a plain ``Tracker`` has
        none)."""
        build_on = getattr(tracker, "build_on", None)
        if build_on is not None:
            build_on(self)
            self._attached.append(tracker)

    def close(self) -> None:
        """The attached trackers build in their own calls again; a build still pending runs when it is needed."""
        for tracker in self._attached:
            tracker.build_on(None)
        self._attached.clear()
        self._pending.clear()
