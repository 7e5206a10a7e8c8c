"""The Rerun view in a process of its own: a live session's sink whose logging never takes the GIL from tracking.

``RerunLogger`` spends ~3 ms of Python a frame building Rerun's arrays (more with strain and the plots); in
the session's process that time holds the GIL the tracking thread needs, and at 100 fps it was the largest
part of the tracker's latency tail (docs/guide/performance.md). ``ViewProcess`` has the same interface as
``RerunLogger`` (a sink, plus ``start``, ``event``, ``log_summary``, ``flush``, ``close`` and the counters the
summary reads) and runs a ``RerunLogger`` in a child process:

- the session's output thread hands each frame over (``__call__``): the result without its camera frame (the
  arrays of the measurement, strain, extensometers, force and timings), plus the camera image (and a stereo
  pair's right one) when this frame's is drawn, chosen (``camera_image.CameraImagePacing``) and downsampled (``camera_image.display_image``)
  here. A thread of this process pickles and writes them to the child's pipe (a
  ``multiprocessing.connection.Connection``); the output thread only appends to a queue.
- every frame's fields reach the view: none is left out while the child keeps up; while it is behind (more
  than ``BEHIND`` frames handed over and not yet drawn) the camera image is left out (at most
  ``camera_image.IMAGE_SKIP_MAX`` frames in a row). A child that stops taking frames for good (more than
  ``BACKLOG_MAX`` waiting) would hold the frames in memory: then whole frames are left out, counted in
  ``frames_left_out`` (the summary says it), never silently.
- ``start``, ``flush`` and ``close`` wait for the child's answer: ``start`` raises the ``ValueError`` the
  logger raised there (a viewer that cannot be started), ``flush`` brings back the child's counters for the
  summary (``frames_logged``, ``log_seconds``, ``file_error``), ``close`` returns once the .rrd is complete.
- the child is ``python -m livedic.stream.view.process`` in a session of its own (Ctrl-C goes to the session,
  which closes it; nothing of the caller's ``__main__`` runs again, as it would under ``multiprocessing``);
  when the session's process dies without closing it, its pipe ends and the child closes the .rrd itself:
  the file keeps every frame it was given. What the child prints goes to a temporary file, whose last line
  names the cause when it fails.
- a child that fails (an error in the logger, the process killed) switches the view off: the next frame
  handed over raises ``ViewProcessError`` and the session reports it as for any sink that fails; the
  measurement goes on.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, cast
from multiprocessing.connection import Connection

from livedic.acquire.base import Frame
from livedic.stream.view.camera_image import CameraImagePacing, display_image, display_scale
from livedic.stream.view.logger import RerunLogger
from livedic.stream.pipeline.frame_result import StageTimes
from livedic.stream.pipeline.cores import OUTPUT_NICE, lower_priority

if TYPE_CHECKING:
    import numpy as np

    from livedic.stream.pipeline.frame_result import FrameResult, SessionStats
    from livedic.stream.stages.force import LoadStage

BEHIND = 1                 # frames handed over and not yet drawn, the one being drawn included, that are not "behind"
BACKLOG_MAX = 2000         # frames waiting for the child beyond which whole frames are left out (~20 s at 100 fps)
START_TIMEOUT_S = 60.0     # the child imports rerun, numpy and OpenCV (~2 s) and opens the stream
CLOSE_TIMEOUT_S = 60.0     # the child draws what it was given, then flushes and closes the .rrd
DRAW_STAGE = "view drawing"   # the child's time per frame, a row of the session's stage times


class ViewProcessError(RuntimeError):
    """The view's process failed or ended: the message says why."""


@dataclass(frozen=True)
class LoadForView:
    """What the view reads of the session's load stage (``stream.stages.force.LoadStage``): its cross-section."""
    area_mm2: float | None = None


def _counters(logger: RerunLogger, times: StageTimes) -> dict[str, Any]:
    return dict(frames_logged=logger.frames_logged, log_seconds=logger.log_seconds, file_error=logger.file_error,
                stages=times.summary())


def _tell(outbox: Connection, message: tuple[str, Any]) -> None:
    """An answer to the session; lost once the session's process has ended, and the child goes on drawing what
    it was given (a failed answer must not stop the drawing: the .rrd keeps every frame handed over)."""
    try:
        outbox.send(message)
    except OSError:
        pass


def serve(inbox: Connection, outbox: Connection) -> None:
    """The child: a ``RerunLogger`` fed from the connection ``inbox`` until "close" or the end of the pipe (the
    session's process ended); answers and counts on ``outbox``."""
    try:
        _, options = inbox.recv()
    except EOFError:
        return                                       # never used (``ViewChild.close``)
    logger = RerunLogger(**options, on_error=lambda message: _tell(outbox, ("file_error", message)))
    failed = False
    times = StageTimes()
    while True:
        try:
            kind, payload = inbox.recv()
        except (EOFError, OSError):
            break       # the session's process died (maybe mid-message): close the .rrd with what it has
        if kind == "close":
            break
        if failed and kind != "flush":
            continue
        try:
            if kind == "frame":
                result, camera_image, right_image = payload
                started = time.perf_counter_ns()
                logger.log_frame(result, None, camera_image=camera_image, right_image=right_image)
                times.add(DRAW_STAGE, time.perf_counter_ns() - started)
                _tell(outbox, ("drawn", 1))
            elif kind == "start":
                logger.start(**payload)
                _tell(outbox, ("started", None))
            elif kind == "event":
                logger.event(*payload)
            elif kind == "summary":
                logger.log_summary(payload)
            elif kind == "flush":
                logger.flush()
                _tell(outbox, ("counters", _counters(logger, times)))
        except Exception as error:  # noqa: BLE001 - told to the session, which switches the view off
            failed = True
            _tell(outbox, ("start_failed" if kind == "start" else "failed", f"{type(error).__name__}: {error}"))
    try:
        logger.close()
    except Exception as error:  # noqa: BLE001 - the session says it ("closing the Rerun stream failed")
        _tell(outbox, ("close_failed", f"{type(error).__name__}: {error}"))
    _tell(outbox, ("closed", _counters(logger, times)))


class ViewChild:
    """The child process, started: ``python -m livedic.stream.view.process`` importing rerun, numpy and OpenCV
    (~2 s) until its first message; ``ViewProcess`` takes it over. ``close`` ends one that was never used."""

    def __init__(self) -> None:
        child_in, to_child = os.pipe()
        from_child, child_out = os.pipe()
        self.output = tempfile.TemporaryFile()
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "livedic.stream.view.process", str(child_in), str(child_out)],
                pass_fds=(child_in, child_out), stdin=subprocess.DEVNULL, stdout=self.output,
                stderr=subprocess.STDOUT, start_new_session=True)
        finally:
            os.close(child_in)
            os.close(child_out)
        self.to_child = Connection(to_child, readable=False)
        self.from_child = Connection(from_child, writable=False)

    def close(self) -> None:
        """End the child (its pipe closes: it finds no options and exits)."""
        for end in (self.to_child, self.from_child):
            end.close()
        try:
            self.process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self.output.close()


class ViewProcess:
    """``stream.view.logger.RerunLogger`` in a child process (module notes); the same parameters as it.

    ``image_every``, ``image_max_hz`` and ``thin_when_behind`` pace the camera image here, in the session's
    process; the others go to the child's logger. ``on_error(message)`` is called (from the thread that hands
    a frame over, or from ``flush``/``close``) when the .rrd cannot be written. ``child``: a ``ViewChild``
    started earlier (the session starts it before it renders or opens the camera); None: one started now.
    """

    name = "Rerun view"
    stage = "view"
    required = False

    def __init__(self, mode: str, target: str | None = None, *, image_every: int = 1,
                 image_max_hz: float | None = None, thin_when_behind: bool = False,
                 on_error: Callable[[str], None] | None = None, child: ViewChild | None = None,
                 **logger_options: Any) -> None:
        if logger_options.get("color_range") is not None:
            RerunLogger("none", color_range=logger_options["color_range"])   # the same check, raised here
        self.mode = mode
        self.target = target
        self.image_max_hz = image_max_hz
        self.image_max_side = int(logger_options.get("image_max_side", 512))
        self.images = CameraImagePacing(image_every=image_every, image_max_hz=image_max_hz,
                                        thin_when_behind=thin_when_behind)
        self.on_error = on_error
        self.frames_handed = 0
        self.frames_drawn = 0
        self.frames_left_out = 0             # whole frames left out: the child had BACKLOG_MAX waiting
        self._counters: dict[str, Any] = dict(frames_logged=0, log_seconds=0.0, file_error=None, stages={})
        self._scale = 1
        self._error: str | None = None                   # why the child failed (ViewProcessError at the next frame)
        self._close_error: str | None = None             # why the child's logger failed to close (raised by close)
        self._closed = False
        self._file_error_told = False
        self._child = child if child is not None else ViewChild()
        self._process, self._output = self._child.process, self._child.output
        self._to_child, self._from_child = self._child.to_child, self._child.from_child
        self._outgoing: queue.SimpleQueue[tuple[str, Any] | None] = queue.SimpleQueue()
        # imports in the background while the session prepares; the writer sends in order, off the output thread
        self._outgoing.put(("options", dict(logger_options, mode=mode, target=target)))
        self._writer = threading.Thread(target=self._write_loop, name="livedic-view-writer", daemon=True)
        self._writer.start()

    # ------------------------------------------------------------ what the summary reads
    @property
    def pid(self) -> int:
        """The view's process id (``stream.pipeline.cores`` places it)."""
        return self._process.pid

    @property
    def enabled(self) -> bool:
        return not self._closed and self._error is None and self._counters["file_error"] is None

    @property
    def file_error(self) -> str | None:
        return self._counters["file_error"]

    @property
    def frames_logged(self) -> int:
        return self._counters["frames_logged"]

    @property
    def log_seconds(self) -> float:
        """The child's time logging (``RerunLogger.log_seconds``), as of the last ``flush``."""
        return self._counters["log_seconds"]

    @property
    def stages(self) -> dict[str, Any]:
        """The child's stage times (``DRAW_STAGE``: p50/p99 ms a frame), as of the last ``flush``."""
        return self._counters["stages"]

    @property
    def backlog(self) -> int:
        """Frames handed over that the child has not drawn yet (as far as its answers have come back)."""
        return self.frames_handed - self.frames_drawn

    # ------------------------------------------------------------ the pipes
    def _write_loop(self) -> None:
        lower_priority(OUTPUT_NICE)     # an output: the acquisition thread on the same core comes first
        while True:
            message = self._outgoing.get()
            if message is None:
                return
            try:
                self._to_child.send(message)
            except OSError as error:              # the child ended: _take_answers says why
                self._fail(f"the view's process stopped taking frames ({error.strerror or error})")
                return

    def _send(self, kind: str, payload: Any = None) -> None:
        if self._error is None and not self._closed:
            self._outgoing.put((kind, payload))

    def _take_answers(self, wanted: Sequence[str] | None = None, timeout_s: float = 0.0) -> str | None:
        """Read the child's answers; with ``wanted``, until one of those kinds (returned) or the timeout."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                ready = self._from_child.poll(max(deadline - time.monotonic(), 0.0) if wanted else 0.0)
                answer = self._from_child.recv() if ready else None
            except (EOFError, OSError):
                answer = None
                ready = False
                if wanted is not None or self._process.poll() is not None:
                    self._fail(self._ended())
                return None
            if answer is None:
                if wanted is not None:
                    self._fail(f"the view's process did not answer in {timeout_s:.0f} s ({self._ended()})")
                return None
            kind, payload = answer
            if kind == "drawn":
                self.frames_drawn += payload
            elif kind == "file_error":
                self._counters["file_error"] = payload
                if self.on_error is not None and not self._file_error_told:
                    self._file_error_told = True
                    self.on_error(payload)
            elif kind in ("failed", "start_failed"):
                self._fail(payload)
            elif kind == "close_failed":
                self._close_error = payload
            elif kind in ("counters", "closed"):
                self._counters.update({k: v for k, v in payload.items() if k != "file_error" or v is not None})
            if wanted is not None and kind in wanted:
                return kind

    def _ended(self) -> str:
        """Why the child ended: its exit code and the last line it printed."""
        try:
            code = self._process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            return "the view's process stopped answering"
        self._output.seek(0)
        lines = [line.strip() for line in self._output.read().decode(errors="replace").splitlines() if line.strip()]
        return f"the view's process ended (exit code {code})" + (f": {lines[-1]}" if lines else "")

    def _fail(self, why: str) -> None:
        if self._error is None:
            self._error = why

    # ------------------------------------------------------------ the session's calls
    def start(self, *, image_shape: tuple[int, ...], load: LoadStage | None = None, **options: Any) -> None:
        """``RerunLogger.start`` in the child; waits for it and raises its ValueError (a viewer that cannot be
        started or reached) or a ``ViewProcessError`` (the child failed)."""
        self._scale = display_scale(image_shape, self.image_max_side)
        for_view = None if load is None else LoadForView(area_mm2=load.area_mm2)
        self._send("start", dict(options, image_shape=image_shape, load=for_view))
        kind = self._take_answers(wanted=("started", "start_failed"), timeout_s=START_TIMEOUT_S)
        if kind == "start_failed":
            assert self._error is not None       # the answer "start_failed" sets it
            raise ValueError(self._error.split(": ", 1)[-1])
        if self._error is not None:
            raise ViewProcessError(f"the Rerun view could not start: {self._error}")

    def __call__(self, result: FrameResult, stats: SessionStats | None) -> None:
        """Hand one ``FrameResult`` to the child (a sink: see module notes)."""
        self._take_answers()
        if self._error is not None:
            raise ViewProcessError(f"the view stopped: {self._error}")
        if self._counters["file_error"] is not None:
            return
        backlog = self.backlog
        if backlog >= BACKLOG_MAX:
            self.frames_left_out += 1
            return
        frame = cast(Frame, result.frame)         # (FrameResult's field is untyped)
        image: np.ndarray | None = None
        right_image: np.ndarray | None = None
        if self.images.due(frame.timestamp_ns, backlog > BEHIND):
            image = display_image(frame.image, frame.pixel_format, self._scale)
            right = frame.right                  # a stereo pair's right camera: drawn with the left one
            if right is not None and right.image is not None:
                right_image = display_image(right.image, right.pixel_format, self._scale)
        # the frame's metadata and full images (the right one's too) stay here: the view draws from the
        # measurement's arrays (the image None: Frame's type says a frame has one, this one goes over the pipe without)
        light = replace(result, frame=Frame(frame.index, frame.timestamp_ns,
                                            None, frame.pixel_format))  # type: ignore[arg-type]
        self._send("frame", (light, image, right_image))
        self.frames_handed += 1

    log_frame = __call__

    def event(self, message: str, level: str = "info") -> None:
        """A line in the viewer's event log, after the frames handed over so far."""
        self._send("event", (message, level))

    def log_summary(self, text: str) -> None:
        self._send("summary", text)

    def flush(self) -> None:
        """Wait until the child has drawn every frame handed over and flushed; brings back its counters."""
        if self._error is None and not self._closed:
            self._send("flush")
            self._take_answers(wanted=("counters",), timeout_s=CLOSE_TIMEOUT_S)

    def close(self) -> None:
        """The child draws what it was given, closes the stream (the .rrd complete) and ends; raises
        ``ViewProcessError`` when its logger failed to close."""
        if self._closed:
            return
        if self._error is None:
            self._outgoing.put(("close", None))
            self._take_answers(wanted=("closed",), timeout_s=CLOSE_TIMEOUT_S)
        self._closed = True
        self._outgoing.put(None)
        self._writer.join(timeout=5.0)
        self._child.close()
        if self._close_error is not None:
            raise ViewProcessError(self._close_error)


def _warm_up() -> None:
    """Load the numba kernel the view calls (the extensometers' end fit, ``dic.strain.field_fit``) while the session
    still prepares: a fresh process spends ~1 s on its first numba call, which would land on the view's start."""
    import numpy as np

    from livedic.dic.strain import field_fit
    grid = 10.0 * np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0)), axis=-1).reshape(-1, 2)
    still = np.zeros(len(grid))
    field_fit.displacement_at(grid[12:13], grid, still, still, np.ones(len(grid), dtype=bool), 10.0)


def main(argv: Sequence[str] | None = None) -> None:
    """``python -m livedic.stream.view.process IN_FD OUT_FD``: the child (``ViewProcess`` starts it)."""
    fd_in, fd_out = (int(word) for word in (argv if argv is not None else sys.argv[1:]))
    try:
        os.nice(OUTPUT_NICE)          # as the output thread: on a busy machine the tracking thread has the CPU first
    except OSError:
        pass
    _warm_up()
    serve(Connection(fd_in, writable=False), Connection(fd_out, readable=False))


if __name__ == "__main__":
    main()
