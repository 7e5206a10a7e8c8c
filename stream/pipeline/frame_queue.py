"""A bounded, thread-safe frame queue with an explicit drop policy.

The camera side never waits: when the queue is full, ``put`` drops a frame
instead of blocking, counts it, and returns at once (CRAPPY's ``Link`` does
the same on Linux). Two policies:

``"drop-oldest"`` (default)
    Evict the oldest queued frame and queue the new one, so the consumer
    always works on the newest frames (a live monitor wants "now").
``"drop-newest"``
    Keep the queue as it is and discard the incoming frame, so the consumer
    sees an unbroken run of older frames followed by a gap.

Either way ``dropped`` counts every discarded frame and ``dropped_indices``
keeps the frame indices of the most recent ones (bounded). The first frame put is
never dropped: it is the session's reference (its frame 0 and the start of its
clock), and a tracker slow to take it (set-up, a server starting) must not move the
reference to a later, already-deformed frame; the frame after it goes instead.

A third policy, ``"block"``, makes ``put`` wait for room instead: for sources
where waiting loses nothing (a recording or image files replayed as fast as
they can be read, an unpaced simulator). Never use it for a live camera.
"""

from __future__ import annotations

import collections
import threading
from typing import Any

DROP_OLDEST = "drop-oldest"
DROP_NEWEST = "drop-newest"
BLOCK = "block"
DROP_POLICIES = (DROP_OLDEST, DROP_NEWEST, BLOCK)


class QueueClosed(Exception):
    """``get`` on a queue that is closed and empty: no frame will ever come."""


class FrameQueue:
    """Bounded FIFO between the acquisition thread and the tracker.

    Parameters
    ----------
    maxsize : int
        Frames held at most (>= 1).
    policy : str
        ``"drop-oldest"`` or ``"drop-newest"``: which frame goes when full;
        ``"block"``: wait for room (files, not cameras).

    Notes
    -----
    ``put`` never blocks (except with ``"block"``). ``get`` blocks until a frame arrives, the timeout
    passes (returns None) or the queue is closed and drained (raises
    ``QueueClosed``). ``close`` wakes every waiting ``get``.
    """

    def __init__(self, maxsize: int = 4, policy: str = DROP_OLDEST) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"queue size must be a positive integer number of frames, got {maxsize!r}")
        if policy not in DROP_POLICIES:
            raise ValueError(f"unknown drop policy {policy!r}: choose one of {', '.join(DROP_POLICIES)}")
        self.maxsize = maxsize
        self.policy = policy
        self._items: collections.deque[Any] = collections.deque()      # QueuedFrame, or what a test puts
        lock = threading.Lock()
        self._cond = threading.Condition(lock)
        self._waiters_changed = threading.Condition(lock)   # for callers watching who waits, not for frames
        self.waiting_puts = 0           # ``put`` calls waiting for room ("block" policy)
        self.waiting_gets = 0           # ``get`` calls waiting for a frame
        self._closed = False
        self.put_count = 0
        self.dropped = 0
        self.dropped_indices: collections.deque[int | None] = collections.deque(maxlen=1000)
        self.max_depth = 0
        self._first: Any = None              # the first frame put, until it is taken: never dropped
        self._first_seen = False

    def put(self, item: Any) -> Any:
        """Queue ``item``; returns the item dropped to make room (or ``item`` itself), else None.

        Raises ``QueueClosed`` if the queue was closed.
        """
        with self._cond:
            if self.policy == BLOCK:
                while len(self._items) >= self.maxsize and not self._closed:
                    self._wait_for_room()
            if self._closed:
                raise QueueClosed("frame queue is closed")
            self.put_count += 1
            if not self._first_seen:
                self._first, self._first_seen = item, True
            victim = None
            if len(self._items) >= self.maxsize:
                protected = self._items[0] is self._first and self._first is not None
                if self.policy == DROP_OLDEST and not (protected and len(self._items) < 2):
                    victim = self._items[1] if protected else self._items[0]
                    del self._items[1 if protected else 0]
                    self._items.append(item)
                else:
                    victim = item
                self.dropped += 1
                self.dropped_indices.append(_index_of(victim))
            else:
                self._items.append(item)
            self.max_depth = max(self.max_depth, len(self._items))
            self._cond.notify_all()
            return victim

    def get(self, timeout: float | None = None) -> Any:
        """The oldest queued item; None after ``timeout`` seconds; ``QueueClosed`` once closed and empty."""
        with self._cond:
            if not self._items and not self._closed:
                self._wait_for_frame(timeout)
            if self._items:
                item = self._items.popleft()
                if item is self._first:
                    self._first = None
                self._cond.notify_all()   # room for a blocked put
                return item
            if self._closed:
                raise QueueClosed("frame queue is closed and empty")
            return None

    def close(self) -> None:
        """No more frames will be put; waiting and later ``get`` calls drain what is left, then raise."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    def _wait_for_room(self) -> None:
        self.waiting_puts += 1
        self._waiters_changed.notify_all()
        try:
            self._cond.wait()
        finally:
            self.waiting_puts -= 1

    def _wait_for_frame(self, timeout: float | None) -> None:
        self.waiting_gets += 1
        self._waiters_changed.notify_all()
        try:
            self._cond.wait(timeout)
        finally:
            self.waiting_gets -= 1

    def wait_for_waiting(self, *, puts: int = 0, gets: int = 0, timeout: float | None = None) -> bool:
        """Wait until at least ``puts`` puts and ``gets`` gets are waiting in the queue; False on timeout.

        For a caller that must know a producer is held back or a consumer is idle (a watchdog, a test)
        without guessing with a sleep.
        """
        with self._cond:
            return self._waiters_changed.wait_for(
                lambda: self.waiting_puts >= puts and self.waiting_gets >= gets, timeout)

    @property
    def closed(self) -> bool:
        return self._closed

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)


def _index_of(item: Any) -> int | None:
    frame = getattr(item, "frame", item)
    return getattr(frame, "index", None)
