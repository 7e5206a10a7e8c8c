"""The ``livedic`` command line: run, measure, replay, export, report, recover, cameras.

Every failure caused by input (files, options, cameras) ends with one line on
stderr and exit code 2 (argparse's own errors too); a camera lost mid-session
(recording kept) with exit code 3; set LIVEDIC_DEBUG=1 to see a traceback instead.

Commands of the layers above (``livedic bench ...``) are added by the program
that sits above them: ``livedic.bench.cli`` passes ``extensions`` to ``main``
(stream never imports bench).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NoReturn

import argparse
import logging
import os
import signal
import sys
import threading

from livedic.stream.cli.calibrate import add_calibrate_arguments, calibrate_command
from livedic.stream.cli.export import add_export_arguments, export_command
from livedic.stream.cli.measure import add_measure_arguments, measure_command
from livedic.stream.cli.noise_floor import add_noise_floor_arguments, noise_floor_command
from livedic.stream.cli.preview import add_preview_arguments, preview_command
from livedic.stream.cli.replay import add_replay_arguments, replay_command
from livedic.stream.cli.report import add_report_arguments, report_command
from livedic.stream.cli.run import add_run_arguments, run_session
from livedic.stream.cli.verify import add_verify_arguments, verify_command
from livedic.stream.session.parsing import UsageError

EXIT_BAD_INPUT = 2
EXIT_SOURCE_LOST = 3

# Options whose value may start with a minus sign and a digit ("-2,2"), which argparse would
# otherwise take for an option and answer "expected one argument".
_SIGNED_LIST_OPTIONS = ("--color-range",)


class LivedicParser(argparse.ArgumentParser):
    """argparse with livedic's one-line errors: ``livedic: error: ...`` on stderr, exit 2 (no usage block)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_BAD_INPUT, f"livedic: error: {message} (see {self.prog} --help)\n")


def _attach_signed_values(argv):
    """``--color-range -2,2`` -> ``--color-range=-2,2`` (argparse reads "-2.5" but not "-2,2" as a value)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    joined = []
    i = 0
    while i < len(argv):
        word = argv[i]
        if (word in _SIGNED_LIST_OPTIONS and i + 1 < len(argv) and len(argv[i + 1]) > 1
                and argv[i + 1][0] == "-" and (argv[i + 1][1].isdigit() or argv[i + 1][1] == ".")):
            joined.append(f"{word}={argv[i + 1]}")
            i += 2
            continue
        joined.append(word)
        i += 1
    return joined


def main(argv: Sequence[str] | None = None, *, extensions: Sequence[Callable] = ()) -> int:
    """Parse ``argv`` (default: the process's), run the command; returns the exit code.

    ``extensions``: callables ``add(commands)`` that add subcommands (see ``build_parser``).
    """
    parser = build_parser(extensions)
    try:
        args = parser.parse_args(_attach_signed_values(argv))
    except SystemExit as done:        # --help (0), or a bad option: argparse said so in one line (2)
        return done.code if isinstance(done.code, int) else EXIT_BAD_INPUT
    if hasattr(signal, "SIGXFSZ") and threading.current_thread() is threading.main_thread():
        # A file-size limit (ulimit -f) must fail a write with EFBIG, which stops a recording
        # cleanly, rather than kill livedic (and the measurement) with SIGXFSZ.
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    if not getattr(args, "handler", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    try:
        return args.handler(args) or 0
    except KeyboardInterrupt:
        print("livedic: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # noqa: BLE001 - turned into one line unless debugging
        if os.environ.get("LIVEDIC_DEBUG"):
            raise
        from livedic.acquire.base import SourceLost
        kind = _error_kind(error)
        print(f"livedic: error: {kind}{error}", file=sys.stderr)
        if isinstance(error, SourceLost):
            return EXIT_SOURCE_LOST
        return EXIT_BAD_INPUT if kind == "" else 1


def entry_point(extensions: Sequence[Callable] = ()) -> int:
    """The ``livedic`` console script: ``main()``, then exit without waiting for a dead camera.

    After a GigE camera is lost, Aravis's teardown of it waits on register writes
    that time out (about 7 s in Aravis 0.8) in a background thread, which would hold
    the process open after the summary. By then every file of ours is closed and
    synced, so the process ends at once instead (``os._exit``, after flushing the
    standard streams). ``main()`` itself never does this: tests and scripts call it.
    """
    _say_log_lines()
    code = main(extensions=extensions)
    aravis = sys.modules.get("livedic.acquire.camera.aravis")
    pending = [thread for thread in getattr(aravis, "_TEARDOWN_THREADS", ()) if thread.is_alive()]
    for thread in pending:
        thread.join(timeout=0.5)
    if any(thread.is_alive() for thread in pending):
        import logging
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


class _LogLine(logging.StreamHandler):
    """What livedic's modules log (a truncated recording's note, a colour file converted ...), said as
    ``livedic: MESSAGE`` like every other line livedic writes, not as Python's bare last-resort output."""

    def format(self, record: logging.LogRecord) -> str:
        clear = "\r\033[K" if self.stream.isatty() else ""     # clear of an in-place progress line
        return f"{clear}livedic: {record.getMessage()}"


def _say_log_lines():
    """Send the ``livedic`` loggers' warnings to stderr through ``_LogLine`` (once per process)."""
    logger = logging.getLogger("livedic")
    if not any(isinstance(handler, _LogLine) for handler in logger.handlers):
        logger.addHandler(_LogLine(sys.stderr))


def _error_kind(error):
    from livedic.acquire.base import SourceError
    if isinstance(error, (ValueError, SourceError, FileNotFoundError, PermissionError, IsADirectoryError)):
        return ""
    return f"internal {type(error).__name__}: "


def _add_metrology_commands(commands: Any) -> None:
    """``calibrate``, ``noise-floor`` and ``verify``: what a lab measures of its set-up before it trusts a test."""
    calibrate = commands.add_parser("calibrate", help="camera calibration (intrinsics, lens distortion, px/mm) from "
                                                      "chessboard or ChArUco target images, or a stereo rig's "
                                                      "(--left, --right)",
                                    description="Find the target in each image, solve the camera (OpenCV), check "
                                                "the reprojection error and write CAL.json, used by run, replay, export and report "
                                                "--calibration; with --left and --right, both cameras of a stereo "
                                                "rig and the pose between them (docs/guide/calibration.md).")
    add_calibrate_arguments(calibrate)
    calibrate.set_defaults(handler=calibrate_command)

    noise = commands.add_parser("noise-floor", help="the measurement's noise floor from static images (u, v, "
                                                    "strain: SD over points and over images)")
    add_noise_floor_arguments(noise)
    noise.set_defaults(handler=noise_floor_command)

    verify = commands.add_parser("verify", help="the axial extensometer's ISO 9513 class from your own frames of "
                                                "known elongation (static, rigid motions, known grip moves)",
                                 description="Track the images against the reference as livedic run does, read the "
                                             "axial extensometer at each, and classify its bias and resolution per "
                                             "known elongation by ISO 9513:2012 Table 2 (in situ, as EN 4861:2020); "
                                             "-o writes the file livedic report --verification reads "
                                             "(docs/guide/extensometer-class.md).")
    add_verify_arguments(verify)
    verify.set_defaults(handler=verify_command)


def build_parser(extensions: Sequence[Callable] = ()) -> LivedicParser:
    """The ``livedic`` parser: this layer's commands, then those ``extensions`` add.

    Parameters
    ----------
    extensions : sequence of callables
        ``add(commands)`` with the ``argparse`` subparsers object: each adds its commands
        (``livedic.bench.cli.add_bench_commands`` adds ``livedic bench ...``).
    """
    parser = LivedicParser(
        prog="livedic", description="Real-time digital image correlation: measure, track, record, replay.")
    commands = parser.add_subparsers(metavar="COMMAND")

    run = commands.add_parser("run", help="live tracking of a camera or the simulated tensile test")
    add_run_arguments(run)
    run.set_defaults(handler=run_session)

    preview = commands.add_parser("preview", help="draw a test's set-up before it starts: region, points, P0, "
                                                  "extensometers, and what the image offers DIC",
                                  description="Take the source's first frame, place the points, P0 and the "
                                              "extensometers as livedic run would with the same options, and draw "
                                              "them over it, beside the speckle contrast per subset (mean "
                                              "intensity gradient) and the clipped pixels; the figures and any "
                                              "advice are printed too.")
    add_preview_arguments(preview)
    preview.set_defaults(handler=preview_command)

    measure = commands.add_parser("measure", help="displacements of points between two images")
    add_measure_arguments(measure)
    measure.set_defaults(handler=measure_command)

    _add_metrology_commands(commands)

    cameras = commands.add_parser("cameras", help="list GenICam cameras (GigE Vision, USB3 Vision) Aravis can see")
    cameras.add_argument("--fake", action="store_true", help="also list Aravis's in-process fake camera")
    cameras.set_defaults(handler=_cmd_cameras)

    recover = commands.add_parser("recover", help="rewrite a crashed recording into a complete, indexed MCAP")
    add_recover_arguments(recover)
    recover.set_defaults(handler=_cmd_recover)

    replay = commands.add_parser("replay", help="re-run tracking offline on a recording's frames (CSV out)",
                                 description="Track a recording's frames again. Options not given are the "
                                             "recorded ones; with them the numbers equal the recorded ones "
                                             "exactly. Truncated recordings replay what can be recovered.")
    add_replay_arguments(replay)
    replay.set_defaults(handler=replay_command)

    export = commands.add_parser("export", help="write a recording's results as CSV (P0 trace, fields, strain, "
                                                "extensometers, events), maps, an overlay video and VTK",
                                 description="Write DIR/p0_trace.csv, DIR/fields.csv (with the strain exx,eyy,exy), "
                                             "DIR/events.csv, DIR/session.json, DIR/extensometers.csv and "
                                             "DIR/extensometers.png from a recording (complete or truncated). "
                                             "Strain and extensometers are recomputed from the recorded "
                                             "displacements with the recorded settings, or the options below. "
                                             "With --load csv:FILE and the cross-section (--area, or --width and "
                                             "--thickness) also DIR/stress_strain.csv and DIR/stress_strain.png "
                                             "(strain of the axial extensometer). Then the fields as pictures: "
                                             "PNG maps over the camera images (DIR/maps/), an overlay video "
                                             "(DIR/overlay_eyy.mp4) and VTK for ParaView (DIR/vtk/, "
                                             "DIR/fields.pvd). Ctrl-C or SIGTERM stops it: the files finished "
                                             "are kept whole, exit 130 or 143.")
    add_export_arguments(export)
    export.set_defaults(handler=export_command)

    report = commands.add_parser("report", help="tensile test report: E, Rp0.2, Rm, Ag, A (ISO 6892-1) from a "
                                                "recording and the machine's force",
                                 description="Write DIR/report.md, DIR/report.json and DIR/stress_strain.png: "
                                             "the stress-strain curve of the axial extensometer and the force "
                                             "file, and the tensile properties read from it by the methods of "
                                             "ISO 6892-1.")
    add_report_arguments(report)
    report.set_defaults(handler=report_command)

    for extend in extensions:
        extend(commands)
    return parser



def add_recover_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic recover`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("recording", metavar="FILE.mcap", help="recording cut short (crash, power loss, kill)")
    parser.add_argument("-o", "--output", required=True, metavar="FIXED.mcap", help="new file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace FIXED.mcap if it exists")


def _cmd_cameras(args):
    from livedic.acquire.camera.aravis_discovery import list_cameras

    cameras = list_cameras(include_fake=args.fake)
    if not cameras:
        print("no GenICam camera found (GigE cameras must be on this computer's subnet; "
              "USB3 cameras need read access to the device)", file=sys.stderr)
        return 0
    print(f"{'URI':40s} {'vendor':16s} {'model':20s} {'serial':14s} {'protocol':11s} address")
    for camera in cameras:
        print(f"{camera['uri']:40s} {camera['vendor'] or '':16s} {camera['model'] or '':20s} "
              f"{camera['serial'] or '':14s} {camera['protocol']:11s} {camera.get('address') or ''}")
    if len(cameras) >= 2:
        left, right = (camera["uri"] for camera in cameras[:2])
        print(f"livedic: a stereo pair of two of them: --source 'stereo:{left},{right}' (on one hardware trigger: "
              "?trigger=line:N on both; fired together by livedic: ?trigger=software&frame_rate=F on both)",
              file=sys.stderr)
    return 0


def _cmd_recover(args):
    from livedic.acquire.recording.recover import recover

    if os.path.lexists(args.output) and not args.overwrite:
        raise UsageError(f"{args.output} already exists: choose a new name, or add --overwrite to replace it")
    summary = recover(args.recording, args.output, overwrite=args.overwrite)
    state = "was cut short" if summary["truncated"] else "was complete"
    print(f"livedic: {args.recording} {state}; wrote {args.output} with {summary['frames']} frames, "
          f"{summary['results']} result sets and {summary['events']} events"
          + (f" ({summary['note']})" if summary.get("note") else ""), file=sys.stderr)
    return 0



