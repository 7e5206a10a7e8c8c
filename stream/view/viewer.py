"""Where the view goes: the ``--viewer`` modes, the local viewer spawned on loopback, and the .rrd file writer.

``parse_viewer`` turns ``--viewer`` words into (mode, argument, note); ``spawn_viewer`` starts ``rerun`` bound
to 127.0.0.1 (or reuses one listening there); ``RrdFile`` writes the .rrd of mode "save" so that a full disk
costs one message, never a hung session. Nothing here listens on a non-loopback interface (docs/guide/live-view.md).
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence

APPLICATION_ID = "livedic"
DEFAULT_PORT = 9876
DEFAULT_CONNECT_URL = f"rerun+http://127.0.0.1:{DEFAULT_PORT}/proxy"
VIEWER_MODES = ("spawn", "connect", "save", "none")


def has_display() -> bool:
    """True unless on Linux/BSD with neither $DISPLAY nor $WAYLAND_DISPLAY set."""
    if sys.platform.startswith(("win", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def parse_viewer(values: Sequence[str] | str | None,
                 default_save_path: str | os.PathLike[str]) -> tuple[str, str | None, str | None]:
    """``--viewer`` words -> (mode, argument, note).

    ``["spawn"]``, ``["connect"]``, ``["connect", URL]``, ``["save", FILE]``,
    ``["save"]`` (to ``default_save_path``) or ``["none"]``. "spawn" without a
    display becomes ("save", default_save_path) with a note saying so.

    Raises
    ------
    ValueError
        Unknown mode, missing or extra argument, or a bad URL.
    """
    if not values:
        values = ["spawn"]
    if isinstance(values, str):
        values = values.split()
    mode, args = values[0], list(values[1:])
    usage = "use --viewer spawn | connect [URL] | save FILE.rrd | none"
    if mode not in VIEWER_MODES:
        raise ValueError(f"unknown viewer mode {mode!r}: {usage}")
    if len(args) > 1 or (mode in ("spawn", "none") and args):
        raise ValueError(f"--viewer {' '.join(values)}: too many arguments; {usage}")
    if mode == "connect":
        url = args[0] if args else DEFAULT_CONNECT_URL
        if not url.startswith(("rerun://", "rerun+http://", "rerun+https://")):
            raise ValueError(f"viewer URL {url!r} must start with rerun://, rerun+http:// or rerun+https:// "
                             f"(e.g. {DEFAULT_CONNECT_URL})")
        return "connect", url, None
    if mode == "save":
        path = args[0] if args else str(default_save_path)
        if not str(path).endswith(".rrd"):
            raise ValueError(f"Rerun file {path!r} must end in .rrd")
        return "save", path, None
    if mode == "spawn" and not has_display():
        return "save", str(default_save_path), (f"no display ($DISPLAY and $WAYLAND_DISPLAY are unset): "
                                                f"saving the Rerun stream to {default_save_path} instead "
                                                f"(open it later with: rerun --bind 127.0.0.1 {default_save_path})")
    return mode, None, None


def _port_open(host: str, port: int, timeout: float = 0.2) -> bool:
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False


def _viewer_command(port: int) -> list[str]:
    beside = os.path.join(os.path.dirname(sys.executable), "rerun")
    exe = beside if os.path.exists(beside) else shutil.which("rerun")
    if exe is None:
        raise ValueError("cannot spawn a viewer: the 'rerun' program is not installed (pip install rerun-sdk), "
                         "or use --viewer save FILE.rrd")
    return [exe, "--bind", "127.0.0.1", "--port", str(port)]


class RrdFile:
    """The .rrd of ``--viewer save``: Rerun's own file sink writes into a pipe, a thread here into the file.

    Rerun's file sink (``RecordingStream.save``), when its file cannot be written (a full disk), logs its
    own error lines and then hangs ``disconnect`` for good (rerun-sdk 0.41): the session would never end
    nor print its summary. Through a pipe the sink never fails; a write that fails here is one
    ``on_error(message)`` line, the file keeps the bytes written (Rerun's viewer opens such a cut
    stream up to the cut), and the rest of the stream is read and dropped. ``sink_path`` is what to
    give ``save``; ``close`` after the recording stream's ``disconnect``.
    """

    def __init__(self, path: str | os.PathLike[str], on_error: Callable[[str], None]) -> None:
        self.path = path
        self.on_error = on_error
        self.error: str | None = None
        self.bytes_written = 0
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self._read_end, self._write_end = os.pipe()
        self.sink_path = f"/dev/fd/{self._write_end}"
        self._thread = threading.Thread(target=self._copy, name="livedic-rrd-writer", daemon=True)
        self._thread.start()

    def _copy(self) -> None:
        while data := os.read(self._read_end, 1 << 20):
            if self.error is not None:
                continue                  # drained, so the sink never waits on a full pipe
            try:
                view = memoryview(data)
                while view:
                    written = os.write(self._fd, view)
                    self.bytes_written += written
                    view = view[written:]
            except OSError as error:
                self.error = f"{self.path}: {error.strerror or error}"
                self.on_error(f"Rerun view file stopped: cannot write {self.error}; the session goes on, the file "
                              f"keeps its first {self.bytes_written / 1e6:.1f} MB")
        os.close(self._read_end)

    def close(self) -> None:
        """After the sink let go of the pipe: the copy ends at the pipe's end, the file is closed."""
        os.close(self._write_end)
        self._thread.join(timeout=30.0)
        os.close(self._fd)


def spawn_viewer(port: int = DEFAULT_PORT) -> subprocess.Popen[bytes] | None:
    """Start a local viewer bound to 127.0.0.1:``port``; its process, or None when one listens there already.

    Raises
    ------
    ValueError
        The ``rerun`` program is missing, exits at start, or does not listen within 10 s.
    """
    if _port_open("127.0.0.1", port):
        return None  # a viewer (or proxy) already listens on loopback: reuse it
    command = _viewer_command(port)
    try:
        process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.DEVNULL, start_new_session=True)
    except OSError as error:
        raise ValueError(f"cannot start the Rerun viewer ({command[0]}): {error}; "
                         "use --viewer save FILE.rrd instead") from None
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        if _port_open("127.0.0.1", port):
            return process
        if process.poll() is not None:
            raise ValueError(f"the Rerun viewer exited at start (code {process.returncode}); "
                             "use --viewer save FILE.rrd instead")
        time.sleep(0.1)
    raise ValueError(f"the Rerun viewer did not start listening on 127.0.0.1:{port} within 10 s; "
                     "use --viewer save FILE.rrd instead")
