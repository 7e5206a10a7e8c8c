"""``livedic run``: acquire, track, record and display a live session.

With no options it runs the simulated tensile test (``synthetic:tensile``),
tracks about 1,000 points over the gauge section, records into
``recordings/session-YYYYmmdd-HHMMSS.mcap``, shows the session in Rerun (or
saves a .rrd next to the recording when there is no display), and prints a
summary: frames, fps, POI/s, latency p50/p99, drops and, for synthetic
sources, the error against the exact displacement.

This module is the command: its options (``add_run_arguments``), the
``SessionConfig`` they make (``stream.session.config``), the stop signals, and what is
printed and raised at the end. The session itself, source -> queue -> tracker
-> sinks, is ``stream.session.session.Session``.

Ctrl-C (SIGINT) or SIGTERM stops acquisition, tracks what is already queued,
and closes the recording properly. A camera lost mid-run ends the session
(recording closed, summary, ``SourceLost``) or, with ``--reconnect``, is
reopened until it is back while the session, its reference and its recording
stay open (``stream.pipeline.acquisition.Reconnect``).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import signal
import threading

from livedic.acquire.base import SourceError, SourceLost
from livedic.stream.pipeline.progress import add_progress_argument
from livedic.stream.session.config import DEFAULT_SOURCE, DROP_CHOICES, RECORDINGS_DIR, SessionConfig, TrackingConfig
from livedic.stream.session.options import add_config_arguments
from livedic.stream.output.files import json_text, write_text_atomic
from livedic.stream.session.points import add_point_arguments
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import add_strain_arguments
from livedic.stream.stages.stress import add_stress_arguments


def add_run_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the ``livedic run`` options to an ``argparse`` (sub)parser (defaults: ``stream.session.config``)."""
    parser.add_argument("--source", default=DEFAULT_SOURCE, metavar="URI",
                        help="frame source (default synthetic:tensile): synthetic:[tensile|translate][?opts], "
                             "aravis:[ID], v4l2:/dev/videoN, video:FILE, images:GLOB, mcap:FILE")
    parser.add_argument("--frames", type=int, metavar="N",
                        help="stop after N frames (synthetic: the length of the test, taken after its "
                             "--static-frames; default 300)")
    add_point_arguments(parser)
    add_config_arguments(parser, TrackingConfig)
    record = parser.add_mutually_exclusive_group()
    record.add_argument("--record", metavar="FILE.mcap",
                        help=f"recording file (default {RECORDINGS_DIR}/session-YYYYmmdd-HHMMSS.mcap)")
    record.add_argument("--no-record", action="store_true", help="do not record")
    parser.add_argument("--viewer", nargs="+", default=["spawn"], metavar="MODE",
                        help="spawn | connect [URL] | save FILE.rrd | none (default spawn; without a display "
                             "the stream is saved next to the recording)")
    parser.add_argument("--queue", type=int, default=4, metavar="N", help="frames the queue holds (default 4)")
    parser.add_argument("--drop", choices=DROP_CHOICES, default="auto",
                        help="when the queue is full: drop the oldest queued frame, drop the newest, or block "
                             "(wait; for files only). Default auto: oldest for cameras and paced sources, "
                             "block for recordings, files and the unpaced simulator")
    parser.add_argument("--color-range", metavar="LO,HI",
                        help="fixed colour limits of the u and v fields in the viewer, px (e.g. -2,2). Default: "
                             "automatic, starting at -0.05,0.05 and only growing, to round numbers, to cover the "
                             "0.5-99.5 percentiles of the ok points")
    parser.add_argument("--image-max-side", type=int, default=512, metavar="PX",
                        help="camera image shown in Rerun downsampled to at most PX pixels a side (default 512)")
    add_progress_argument(parser)
    parser.add_argument("--threads", type=int, default=1, metavar="N",
                        help="numba threads for rendering and tracking (default 1: the other core serves "
                             "acquisition, recording and display, and parallel regions stall when cores are shared)")
    parser.add_argument("--summary-json", metavar="FILE.json", help="also write the summary as JSON")
    add_strain_arguments(parser)
    add_config_arguments(parser, SessionConfig)         # --static-frames
    add_stress_arguments(parser)
    parser.add_argument("--publish", action="append", metavar="URI",
                        help="send each tracked frame's extensometer strain to a machine controller as soon as it "
                             "exists (needs --gauge-length or --extensometer; repeatable): udp://HOST:PORT, one JSON "
                             "datagram per frame {frame, time_s, strain: {name: value or null}, ok}; "
                             "modbus://HOST:PORT, a Modbus TCP server with the values in holding registers (map in "
                             "docs/guide/strain-out.md). Without a host: 127.0.0.1; modbus://0.0.0.0:PORT listens on every "
                             "interface")
    parser.add_argument("--reconnect", action="store_true",
                        help="cameras (aravis:, v4l2:): when the camera is lost, keep the session and the recording "
                             "open and reopen it every second until it is back (or Ctrl-C); the session then goes on "
                             "with the same reference and points")
    parser.add_argument("--reconnect-timeout", type=float, metavar="S",
                        help="with --reconnect: give up after S seconds without the camera (default: wait until "
                             "stopped)")
    return parser


# ----------------------------------------------------------------------------- stop signals

class _StoppedBeforeStart(Exception):
    """A stop signal arrived before the session started (nothing was recorded)."""

    def __init__(self, signal_name: str):
        super().__init__(signal_name)
        self.signal_name = signal_name


class _Interrupt:
    """SIGINT/SIGTERM over the whole of ``livedic run`` (installed only in the main thread).

    Before the session starts (checking the outputs, opening the source, compiling the
    kernels, rendering the simulated test, waiting for the first frame, opening the
    outputs) a signal ends the run at once: the handler raises ``_StoppedBeforeStart``.
    Once ``session_started`` is called it is a stop request instead (``on_signal``):
    acquisition stops, the queued frames are tracked and the recording is closed
    properly. A second Ctrl-C gives up at once (``KeyboardInterrupt``).
    """

    def __init__(self) -> None:
        self.on_signal: Callable[[str], None] | None = None
        self.received = None
        self._previous: dict[int, Any] = {}

    def session_started(self, on_signal: Callable[[str], None]) -> None:
        self.on_signal = on_signal

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, _frame):
        name = signal.Signals(signum).name
        if self.on_signal is None:
            self.received = name
            raise _StoppedBeforeStart(name)
        if self.received is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt   # a second Ctrl-C: give up on the clean stop
        self.received = name
        self.on_signal(name)

    def __exit__(self, *exc):
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        return False


# ----------------------------------------------------------------------------- the command

def write_summary_json(path: str, summary: dict, say: Callable[[str], None]) -> None:
    """``--summary-json``: written whole or not at all; a failure (a full disk) is one warning, not an error.

    The outputs were checked before the session; what fails now is the disk, and the summary has been
    printed already: the session's outcome (its exit code) stays what the measurement made it.
    """
    try:
        write_text_atomic(path, json_text(summary))
    except OSError as error:
        say(f"warning: the summary JSON was not written: {path}: {error.strerror or error} "
            f"(the summary is printed above)")


def run_session(args: argparse.Namespace) -> int:
    """Run ``livedic run`` with parsed ``args`` (see ``add_run_arguments``); returns the exit code.

    Everything that can be checked before the session is: options (``SessionConfig``),
    every output (``--record``, ``--viewer save``, ``--summary-json``: writable?), a
    ``--viewer connect`` viewer (listening?), then, on the first frame, the points
    (``--roi``, ``--p0``, ``--points`` inside the image, no more than ``--max-points``)
    and P0 (placed on the specimen's texture, or a warning when the given one is weak).
    Only then are the recording and the Rerun stream opened, so bad input leaves no file.

    Raises
    ------
    ValueError
        Bad options or an output that cannot be written (one line, for the CLI to print).
    SourceError
        The source cannot be opened, or failed before its first frame.
    SourceLost
        The source failed mid-session (and, with ``--reconnect``, did not come back
        within ``--reconnect-timeout``); raised after the recording is closed and the
        summary printed.
    """
    config = SessionConfig.from_args(args)
    with _Interrupt() as interrupt, Session(config) as session:
        try:
            session.prepare()
            interrupt.session_started(session.stop)
        except _StoppedBeforeStart as stop:
            # Nothing was tracked: what was opened is closed; a recording with no session is removed
            # (it is this run's own file: --record refuses an existing one, the default name is unique).
            interrupt.session_started(lambda name: None)       # a further signal now changes nothing
            phase = session.phase
            session.abandon()
            session.say(f"stopped on {stop.signal_name} while {phase.value}, before the session started: "
                        f"nothing was recorded")
            return 0
        session.start()
        session.run()
    print(session.summary_text(), flush=True)
    if config.summary_json:
        write_summary_json(config.summary_json, session.summary() or {}, session.say)
    error = session.source_error
    if error is not None:
        if session.acquisition.frames:
            # It had delivered: not bad input but a loss mid-session (the CLI's exit code 3).
            raise SourceLost(str(error)) from error
        raise error if isinstance(error, SourceError) else SourceError(str(error))
    stats = session.stats
    if stats is not None and stats.frames == 0 and not session.stopped_by:
        raise SourceError(f"{config.source} delivered no frame")
    return 0
