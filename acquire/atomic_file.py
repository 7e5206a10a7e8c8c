"""Files written whole or not at all: a temporary file beside the target, renamed into place when complete.

Every file livedic writes for the user goes through ``AtomicFile``: the CSV and
JSON outputs of ``measure``, ``replay``, ``export`` and ``run --summary-json``
(text, through ``stream.output.files``) and the MCAP file ``recover`` rewrites
(binary). The file gets the permissions a plain ``open(path, "w")`` would give it
(``0666 & ~umask``), so an error or an interruption never leaves a partial file
and all commands create files alike. It lives here, in ``acquire``, because
``recover`` (the recording format's repair) is its lowest user.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Collection, Iterator, Mapping
from typing import IO, Any, Literal

__all__ = ["AtomicFile", "OutputError", "current_umask"]

TEMP_PREFIX = ".livedic-"


class OutputError(ValueError):
    """An output path that cannot be written; the message is one line for the user."""


def current_umask() -> int:
    """The process umask, read without changing it where the system allows (Linux: /proc)."""
    try:
        with open("/proc/self/status") as handle:
            for line in handle:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)        # elsewhere: set and restore (not thread-safe, but only as a fallback)
    os.umask(mask)
    return mask


class AtomicFile:
    """A file written under a temporary name beside ``path``; ``commit()`` renames it into place.

    Parameters
    ----------
    path : str or os.PathLike
        The file to create or replace.
    binary : bool
        Open the temporary file for bytes (``"wb"``) instead of text (``"w"``, no newline
        translation).
    suffix : str
        Ending of the temporary name after ``.partial`` (e.g. ``".mp4"``), for writers that
        take a path (``tmp``) and choose the format by its extension, such as OpenCV's video
        writer.

    The file gets the permissions ``open(path, "w")`` would give it (``0666 & ~umask``;
    ``tempfile.mkstemp`` alone makes 0600). ``discard()``, or leaving the ``with``
    block on an error or without ``commit()``, removes the temporary file. ``handle``
    is the open temporary file, for writers that take a stream.

    Raises
    ------
    OutputError
        The folder does not exist, or ``path`` is a folder.
    """

    tmp: str | None           # None once committed or discarded
    handle: IO[Any]


    def __init__(self, path: str | os.PathLike[str], *, binary: bool = False, suffix: str = "") -> None:
        self.path = os.fspath(path)
        if os.path.isdir(self.path):
            raise OutputError(f"{self.path} is a folder: give a file name")
        directory = os.path.dirname(os.path.abspath(self.path))
        if not os.path.isdir(directory):
            raise OutputError(f"cannot write {self.path}: folder {directory} does not exist")
        fd, self.tmp = tempfile.mkstemp(prefix=TEMP_PREFIX, suffix=".partial" + suffix, dir=directory)
        try:
            os.fchmod(fd, 0o666 & ~current_umask())
            self.handle = os.fdopen(fd, "wb") if binary else os.fdopen(fd, "w", newline="")
        except BaseException:
            os.close(fd)
            os.unlink(self.tmp)
            raise

    def write(self, data: str | bytes) -> None:
        self.handle.write(data)

    def commit(self, *, sync: bool = False) -> None:
        """Flush, close and rename into place; ``sync`` also fsyncs the data first (survives a power cut)."""
        if sync:
            self.handle.flush()
            os.fsync(self.handle.fileno())
        self.handle.close()
        try:
            os.replace(self.tmp, self.path)  # type: ignore[arg-type]  # None only after a commit: fails as before
        except IsADirectoryError:
            # A folder of that name appeared since the check: say so without the temporary name.
            self.discard()
            raise OutputError(f"{self.path} is a folder: give a file name") from None
        self.tmp = None

    def discard(self) -> None:
        if not self.handle.closed:
            self.handle.close()
        if self.tmp is not None and os.path.exists(self.tmp):
            os.unlink(self.tmp)
        self.tmp = None

    def __enter__(self) -> AtomicFile:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> Literal[False]:
        if exc_type is not None or self.tmp is not None:
            self.discard()
        return False


@contextlib.contextmanager
def atomic_files(paths: Mapping[str, str | os.PathLike[str]], *,
                 binary: Collection[str] = ()) -> Iterator[dict[str, AtomicFile]]:
    """All of ``paths`` (name -> path) written whole, or none: yields name -> ``AtomicFile``.

    The folder is created if missing. On leaving normally every file is committed; on an error
    every one is discarded and a folder this call created is removed again (if still empty).
    ``binary``: the names opened in binary mode.
    """
    folders = {os.path.dirname(os.path.abspath(p)) for p in paths.values()}
    created = [folder for folder in folders if not os.path.isdir(folder)]
    for folder in folders:
        os.makedirs(folder, exist_ok=True)
    staged = {}
    try:
        for name, path in paths.items():
            staged[name] = AtomicFile(path, binary=name in binary)
        yield staged
        for item in staged.values():
            item.commit()
    except BaseException:
        for item in staged.values():
            item.discard()
        for folder in created:
            try:
                os.rmdir(folder)          # only if still empty
            except OSError:
                pass
        raise
