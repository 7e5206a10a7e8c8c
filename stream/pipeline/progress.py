"""The progress line of ``livedic run``, ``replay`` and ``export``: one line on stderr, redrawn in place."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TextIO

PROGRESS_CHOICES = ("auto", "on", "off")


def add_progress_argument(parser: argparse.ArgumentParser,
                          help: str = "progress bar on stderr (default auto: when stderr is a terminal)"
                          ) -> argparse.ArgumentParser:
    """Add ``--progress auto|on|off`` to an argparse parser (every command's; ``help`` says what it shows)."""
    parser.add_argument("--progress", choices=PROGRESS_CHOICES, default="auto", help=help)
    return parser


def progress_enabled(choice: str, stream: TextIO | None = None) -> bool:
    """Whether ``--progress choice`` shows the bar: on, or auto and ``stream`` (stderr) is a terminal."""
    return choice == "on" or (choice == "auto" and (stream or sys.stderr).isatty())


class ProgressBar:
    """One line on ``stream`` (stderr), redrawn at most ``hz`` times a second; silent when disabled.

    Parameters
    ----------
    total : int, optional
        What 100 % is; without it the line shows the count only.
    enabled : bool
        False: ``update`` and ``close`` do nothing (``--progress off``, or stderr not a terminal).
    stream : file, optional
        Where the line goes (default ``sys.stderr``).
    hz : float
        Redraws a second at most (``update(..., force=True)`` redraws at once).
    width : int
        Characters of the bar.
    """

    def __init__(self, total: int | None = None, *, enabled: bool = True, stream: TextIO | None = None,
                 hz: float = 8.0, width: int = 24) -> None:
        self.total = total
        self.enabled = enabled
        self.stream = stream or sys.stderr
        self.period = 1.0 / hz
        self.width = width
        self._last = 0.0
        self._shown = False
        self.last_text = ""

    def due(self) -> bool:
        """Whether ``update`` would redraw now (a caller can skip making its text when not)."""
        return self.enabled and time.monotonic() - self._last >= self.period

    def update(self, done: int, text: str = "", force: bool = False) -> None:
        """Show ``done`` (of ``total``) and ``text``, unless the last redraw is too recent."""
        if not self.enabled:
            return
        self.last_text = text
        now = time.monotonic()
        if not force and now - self._last < self.period:
            return
        self._last = now
        if self.total:
            filled = int(self.width * min(done / self.total, 1.0))
            bar = f"[{'#' * filled}{'.' * (self.width - filled)}] {done}/{self.total}"
        else:
            bar = f"{done}"
        self.stream.write(f"\r{bar} {text}\033[K")
        self.stream.flush()
        self._shown = True

    def clear(self) -> None:
        """Wipe the line so that a message can be printed in its place (it comes back on the next update)."""
        if self.enabled:
            self.stream.write("\r\033[K")

    def close(self) -> None:
        """End the line (a newline after the last redraw)."""
        if self.enabled and self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False
