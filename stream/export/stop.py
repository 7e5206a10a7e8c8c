"""Stopping ``livedic export`` cleanly: SIGINT and SIGTERM end it at the next frame (``StopSignals``), with
``ExportStopped`` saying what the output folder holds at that moment.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Literal


class ExportStopped(Exception):
    """A stop signal ended the export; ``state`` (one line) says what the folder holds."""

    def __init__(self, signal_name: str, signum: int) -> None:
        super().__init__(signal_name)
        self.signal_name = signal_name
        self.signum = int(signum)
        self.state = ""


class StopSignals:
    """SIGINT (Ctrl-C) and SIGTERM during ``livedic export``: the first stops the export at the next frame.

    The handler only takes note; ``check`` (called once per frame) raises ``ExportStopped``, so a
    stop never lands inside a library call that is writing a file. A second signal gives up at
    once (``KeyboardInterrupt``). Installed only in the main thread (signals reach no other).
    """

    def __init__(self) -> None:
        self.received: signal.Signals | None = None
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def _handle(self, signum: int, _frame: object) -> None:
        if self.received is not None:
            raise KeyboardInterrupt
        self.received = signal.Signals(signum)

    def check(self) -> None:
        if self.received is not None:
            raise ExportStopped(self.received.name, self.received.value)

    def __exit__(self, *exc: object) -> Literal[False]:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        return False


@contextmanager
def _stopped_in(state: str | Callable[[], str]) -> Iterator[None]:
    """Give an ``ExportStopped`` leaving this block its ``state`` (text, or a callable for the text at that time)."""
    try:
        yield
    except ExportStopped as stopped:
        if not stopped.state:
            stopped.state = state() if callable(state) else state
        raise
