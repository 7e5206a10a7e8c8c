"""The ``livedic`` command line: run, measure, replay, export, report, recover, cameras.

Every failure caused by input (files, options, cameras) ends with one line on
stderr and exit code 2 (argparse's own errors too); a camera lost mid-session
(recording kept) with exit code 3; set LIVEDIC_DEBUG=1 to see a traceback instead.

Commands of the layers above (``livedic bench ...``) are added by the program
that sits above them: ``livedic.bench.cli`` passes ``extensions`` to ``main``
(stream never imports bench).
"""

import argparse
import logging
import os
import signal
import sys
import threading

from livedic.stream.session.parsing import UsageError, search_method, subpixel_method
from livedic.stream.export.field_export import add_field_arguments
from livedic.stream.session.points import add_region_arguments, read_points_table
from livedic.stream.session.preview import add_preview_arguments, preview_command
from livedic.stream.pipeline.progress import add_progress_argument
from livedic.stream.replay.replay import add_replay_arguments, replay_command
from livedic.stream.cli.run import add_run_arguments, run_session
from livedic.stream.stages.strain import add_strain_arguments
from livedic.stream.stages.stress import add_stress_arguments

EXIT_BAD_INPUT = 2
EXIT_SOURCE_LOST = 3

# Options whose value may start with a minus sign and a digit ("-2,2"), which argparse would
# otherwise take for an option and answer "expected one argument".
_SIGNED_LIST_OPTIONS = ("--color-range",)


class LivedicParser(argparse.ArgumentParser):
    """argparse with livedic's one-line errors: ``livedic: error: ...`` on stderr, exit 2 (no usage block)."""

    def error(self, message):
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


def main(argv=None, *, extensions=()):
    """Parse ``argv`` (default: the process's), run the command; returns the exit code.

    ``extensions``: callables ``add(commands)`` that add subcommands (see ``build_parser``).
    """
    parser = build_parser(extensions)
    try:
        args = parser.parse_args(_attach_signed_values(argv))
    except SystemExit as done:        # --help (0), or a bad option: argparse said so in one line (2)
        return done.code
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


def entry_point(extensions=()):
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

    def format(self, record):
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


def build_parser(extensions=()):
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

    from livedic.dic import SEARCH_METHODS, SUBPIXEL_METHODS
    from livedic.dic.quality import MIN_ZNCC
    from livedic.dic.strain import MEASURES

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
    measure.add_argument("reference", metavar="REF", help="reference image (8/16-bit grey PNG or TIFF)")
    measure.add_argument("deformed", metavar="DEF", help="deformed image, same size")
    where = measure.add_mutually_exclusive_group(required=True)
    where.add_argument("--grid", type=int, metavar="STEP", help="points on a grid every STEP pixels")
    where.add_argument("--points", metavar="FILE.csv",
                       help="CSV with header x,y (other columns are carried through to the output)")
    add_region_arguments(measure, points=False)
    _add_method_options(measure, SEARCH_METHODS, SUBPIXEL_METHODS)
    measure.add_argument("-o", "--output", metavar="OUT.csv",
                         help="output CSV (default: stdout): x,y,u,v,zncc,ok,status, then the method's columns, "
                              "then the points file's other columns (e.g. id, label)")
    measure.add_argument("--min-zncc", type=float, default=MIN_ZNCC, metavar="Z",
                         help=f"a point is ok only if its ZNCC is at least Z (default {MIN_ZNCC}, measured: no "
                              "correct point of a low-contrast, noisy pair falls below it); the other quality gates "
                              "(texture, neighbours, border) always apply")
    measure.add_argument("--no-guided", dest="guided", action="store_false",
                         help="search every point over the full radius instead of a few seeds whose results are "
                              "propagated to their neighbours (reliability-guided, the default)")
    measure.add_argument("--strain-window", type=int, metavar="N",
                         help="add the strain columns exx,eyy,exy: plane fits of u and v over N x N points "
                              "(odd, >= 3; pointwise least squares; VSG = (N - 1) x step + subset, step = --grid "
                              "or the points' spacing)")
    measure.add_argument("--strain-measure", choices=MEASURES,
                         help="strain measure of those columns: engineering (small strain, the default), green "
                              "(Green-Lagrange) or true (logarithmic, Hencky); implies --strain-window 5 when "
                              "that is not given")
    measure.add_argument("--progress", choices=("auto", "on", "off"), default="auto",
                         help="say on stderr how long a measurement has run once it takes over 1.5 s: on = one "
                              "line redrawn in place; auto (default) = that on a terminal, else a line every 15 s; "
                              "off = nothing")
    measure.set_defaults(handler=_cmd_measure)

    cameras = commands.add_parser("cameras", help="list GenICam cameras (GigE Vision, USB3 Vision) Aravis can see")
    cameras.add_argument("--fake", action="store_true", help="also list Aravis's in-process fake camera")
    cameras.set_defaults(handler=_cmd_cameras)

    recover = commands.add_parser("recover", help="rewrite a crashed recording into a complete, indexed MCAP")
    recover.add_argument("recording", metavar="FILE.mcap", help="recording cut short (crash, power loss, kill)")
    recover.add_argument("-o", "--output", required=True, metavar="FIXED.mcap", help="new file to write")
    recover.add_argument("--overwrite", action="store_true", help="replace FIXED.mcap if it exists")
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
    export.add_argument("recording", metavar="FILE.mcap", help="a recording made by livedic run (may be truncated)")
    export.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write (created if missing)")
    export.add_argument("--overwrite", action="store_true", help="replace the files if DIR already holds them")
    add_strain_arguments(export, recorded=True)
    add_stress_arguments(export)
    add_field_arguments(export)
    add_progress_argument(export)
    export.set_defaults(handler=_cmd_export)

    report = commands.add_parser("report", help="tensile test report: E, Rp0.2, Rm, Ag, A (ISO 6892-1) from a "
                                                "recording and the machine's force",
                                 description="Write DIR/report.md, DIR/report.json and DIR/stress_strain.png: "
                                             "the stress-strain curve of the axial extensometer and the force "
                                             "file, and the tensile properties read from it by the methods of "
                                             "ISO 6892-1.")
    report.add_argument("recording", metavar="FILE.mcap", help="a recording made by livedic run (may be truncated)")
    report.add_argument("-o", "--output", required=True, metavar="DIR", help="folder to write (created if missing)")
    report.add_argument("--overwrite", action="store_true", help="replace the files if DIR already holds them")
    add_stress_arguments(report)
    add_strain_arguments(report, recorded=True)
    report.set_defaults(handler=_cmd_report)

    for extend in extensions:
        extend(commands)
    return parser


def _add_method_options(parser, searches, subpixels, *, subpixel_default="improved-surface-fit"):
    from livedic.dic import DEFAULT_SUBSET
    from livedic.dic.search import DEFAULT_RADIUS, DEFAULT_SEARCH
    parser.add_argument("--subset", type=int, default=DEFAULT_SUBSET, metavar="N",
                        help=f"odd subset side, pixels (default {DEFAULT_SUBSET})")
    parser.add_argument("--search", type=search_method, default=DEFAULT_SEARCH, metavar="NAME",
                        help=f"integer search: {', '.join(searches)} (default {DEFAULT_SEARCH})")
    parser.add_argument("--subpixel", type=subpixel_method, default=subpixel_default, metavar="NAME",
                        help=f"sub-pixel method: {', '.join(subpixels)} (default {subpixel_default})")
    parser.add_argument("--radius", type=int, default=DEFAULT_RADIUS, metavar="R",
                        help=f"search radius, pixels (default {DEFAULT_RADIUS})")
    parser.add_argument("--seed", type=int, default=0, help="seed of the stochastic searches (default 0)")


def _cmd_measure(args):
    import numpy as np

    from livedic.acquire.files.image_file import read_grey_image
    from livedic.stream.output.files import check_output_file, write_csv
    from livedic.stream.pipeline.sinks import bit_depth_change

    to_file = args.output not in (None, "-")
    strain = _measure_strain_config(args)            # bad values: one line, before anything is read
    if to_file:
        check_output_file(args.output, "-o")          # before the images are read and the work is done
    reference, note_ref = read_grey_image(args.reference)
    deformed, note_def = read_grey_image(args.deformed)
    for note in (note_ref, note_def):
        if note:
            print(f"livedic: note: {note}", file=sys.stderr)
    depths = bit_depth_change(reference.dtype, deformed.dtype, f"the reference {args.reference}", args.deformed)
    if depths:
        print(f"livedic: warning: {depths}", file=sys.stderr)
    if reference.shape != deformed.shape:
        raise UsageError(f"{args.reference} is {reference.shape[1]}x{reference.shape[0]} but {args.deformed} is "
                         f"{deformed.shape[1]}x{deformed.shape[0]}: both images must have the same size")
    extras = {}
    points, extras, left_out = _measure_points(args, reference)
    if left_out:
        print(f"livedic: {left_out}", file=sys.stderr)
    progress = None
    if args.progress != "off":
        in_place = args.progress == "on" or sys.stderr.isatty()
        progress = MeasureProgress(len(points), f"{args.search} + {args.subpixel}", in_place=in_place)
    from livedic.dic.quality import Gates
    if not -1.0 <= args.min_zncc <= 1.0:
        raise UsageError(f"--min-zncc must be between -1 and 1, got {args.min_zncc}")
    result = measure_with_progress(reference, deformed, points, subset=args.subset, search=args.search,
                                   subpixel=args.subpixel, radius=args.radius, seed=args.seed, progress=progress,
                                   guided=args.guided, gates=Gates(min_zncc=args.min_zncc))
    columns = {"x": result.x, "y": result.y, "u": result.u, "v": result.v,
               "zncc": result.zncc, "ok": result.ok, "status": result.status.astype(np.int64)}
    for name in ("ux", "uy", "vx", "vy", "iterations", "evaluations"):
        value = getattr(result, name)
        if value is not None:
            columns[name] = value
    if strain is not None:
        field, described = _measure_strain(result, strain, step=args.grid, subset=args.subset)
        columns.update(exx=field.exx, eyy=field.eyy, exy=field.exy)
        print(f"livedic: {described}", file=sys.stderr)
    for name, values in extras.items():              # the points file's own columns, after ours
        columns[name if name not in columns else f"points_{name}"] = np.array(values, dtype=object)
    write_csv(args.output, columns)
    n_ok = int(result.ok.sum())
    if to_file:
        print(f"livedic: {n_ok}/{result.ok.size} points measured, written to {args.output}", file=sys.stderr)
    return 0


def _measure_points(args, reference):
    """``(points (N, 2), extra columns, note or None)``: the grid (``--grid``, over ``--roi``, ``--mask``, less
    ``--exclude``; the whole image by default) or the points file (less those a mask or exclusion leaves out)."""
    from livedic.dic.region import grid_in_region
    from livedic.stream.session.config import PointsConfig
    from livedic.stream.session.parsing import ROI_FULL
    from livedic.stream.session.points import placeable_points, where_points_go
    if args.points is not None and args.roi is not None:
        raise UsageError("--roi places a grid: use it with --grid (with --points, --mask and --exclude leave "
                         "points out)")
    if args.grid is not None and args.grid < 1:
        raise UsageError(f"grid step must be a positive integer number of pixels, got {args.grid}")
    region = PointsConfig.region_from_args(args)
    if region["roi"] is None:
        region["roi"] = ROI_FULL
    wanted = PointsConfig(step=args.grid, **region)
    spec, _, allowed, _, _ = where_points_go(reference, wanted, subset=args.subset)
    if args.grid is not None:
        points = grid_in_region(allowed, args.grid)
        if not len(points):
            raise UsageError(f"{spec.describe()} holds no whole {args.subset}x{args.subset} subset: enlarge the "
                             f"region or use a smaller --subset")
        return points, {}, None
    points, extras = read_points_table(args.points)
    if spec.mask is None and not spec.exclude:
        return points, extras, None
    keep = placeable_points(points, allowed)
    if not keep.any():
        raise UsageError(f"every point's subset reaches outside {spec.describe()}: none is left to measure")
    extras = {name: [value for value, k in zip(values, keep) if k] for name, values in extras.items()}
    note = f"{int((~keep).sum())} of {len(keep)} points left out: their subset reaches outside {spec.describe()}"
    return points[keep], extras, note if not keep.all() else None


def _measure_strain_config(args):
    """The strain settings of ``livedic measure`` (None: no strain columns); ValueError for bad values."""
    if args.strain_window is None and args.strain_measure is None:
        return None
    from livedic.stream.stages.strain import StrainConfig
    given = {"window": args.strain_window, "measure": args.strain_measure}
    return StrainConfig(**{key: value for key, value in given.items() if value is not None})


def _measure_strain(result, config, *, step, subset):
    """(dic.strain.StrainField, one line saying how) of a measurement on its own points.

    The window is laid on the measured points (pixel centres); the grid step is ``step``
    (``--grid``), or the points' typical spacing for a points file.
    """
    import numpy as np

    from livedic.dic.strain import strain_field, strain_window
    points = np.column_stack([result.x, result.y]).astype(np.float64)
    windows = strain_window(points, window=config.window, step=step, subset=subset)
    field = strain_field(windows, result.u, result.v, result.ok, measure=config.measure)
    how = (f"strain: {config.measure}, window {windows.window} points x step {windows.step:g} px + subset "
           f"{windows.subset} = VSG {windows.vsg_px:.0f} px; {int(field.ok.sum())}/{field.ok.size} points with strain")
    return field, how


class MeasureProgress:
    """Progress of one long ``dic.measure`` call on stderr: nothing for the first ``after_s`` seconds.

    ``in_place``: one line redrawn (a terminal); otherwise a line every ``every_s``
    seconds (logs). The measurement is one call (see ``measure_with_progress``),
    so the line says how long it has run, not how far it is.
    """

    def __init__(self, n_points, method, *, in_place=True, after_s=1.5, every_s=15.0, stream=None):
        self.n_points = n_points
        self.method = method
        self.in_place = in_place
        self.after_s = after_s
        self.every_s = every_s
        self.stream = stream or sys.stderr
        self.lines = 0
        self._last_line_s = None

    def tick(self, elapsed_s):
        """Called about every 0.25 s while the measurement runs."""
        if elapsed_s < self.after_s:
            return
        text = f"livedic: measuring {self.n_points:,} points ({self.method}): {elapsed_s:.0f} s"
        if self.in_place:
            self.stream.write(f"\r{text}\033[K")
        elif self._last_line_s is None or elapsed_s - self._last_line_s >= self.every_s:
            self.stream.write(text + "\n")
            self._last_line_s = elapsed_s
        else:
            return
        self.stream.flush()
        self.lines += 1

    def done(self, elapsed_s):
        if self.lines:
            end = f"livedic: measured {self.n_points:,} points ({self.method}) in {elapsed_s:.1f} s"
            self.stream.write(f"\r{end}\033[K\n" if self.in_place else end + "\n")
            self.stream.flush()


def measure_with_progress(reference, deformed, points, *, progress=None, tick_s=0.25, **method):
    """``dic.measure(reference, deformed, points, **method)``, showing ``progress`` while it runs.

    The measurement is one ``dic.measure`` call, run in a worker thread (its
    kernels release the GIL) while this thread reports progress and stays
    responsive to Ctrl-C. It is not split into chunks of points: the stochastic
    searches (PSO, WSO, improved WSO) and surface fits seed each point's random
    stream with its index in the call, so chunks would give other numbers than one
    call. The result is therefore exactly ``dic.measure``'s.
    """
    import time

    from livedic.dic import measure

    outcome = {}

    def work():
        try:
            outcome["result"] = measure(reference, deformed, points, **method)
        except BaseException as error:  # noqa: BLE001 - handed to the calling thread
            outcome["error"] = error

    worker = threading.Thread(target=work, name="livedic-measure", daemon=True)
    started = time.monotonic()
    worker.start()
    while worker.is_alive():
        worker.join(tick_s)
        if progress is not None and worker.is_alive():
            progress.tick(time.monotonic() - started)
    if progress is not None:
        progress.done(time.monotonic() - started)
    if "error" in outcome:
        raise outcome["error"]
    return outcome["result"]


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


def _cmd_export(args):
    from livedic.stream.export.export import export_command
    return export_command(args)


def _cmd_report(args):
    from livedic.stream.export.report import report_command
    return report_command(args)

