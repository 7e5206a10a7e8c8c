"""``livedic measure REF DEF``: displacements of points between two images, as a CSV (one ``dic.measure`` call).

``add_measure_arguments`` declares the command's options, ``measure_command`` runs it; ``measure_with_progress``
shows ``MeasureProgress`` on stderr while the measurement runs.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    import numpy as np

    from livedic.dic.result import Measurement

import sys
import threading

from livedic.stream.pipeline.progress import add_progress_argument, progress_enabled
from livedic.stream.session.config import MeasureConfig
from livedic.stream.session.options import add_config_arguments, config_values
from livedic.stream.session.parsing import UsageError
from livedic.stream.session.points import add_region_arguments, read_points_table


def add_measure_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic measure`` options to an ``argparse`` (sub)parser."""
    from livedic.dic.strain import MEASURES

    parser.add_argument("reference", metavar="REF", help="reference image (8/16-bit grey PNG or TIFF)")
    parser.add_argument("deformed", metavar="DEF", help="deformed image, same size")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--grid", type=int, metavar="STEP", help="points on a grid every STEP pixels")
    where.add_argument("--points", metavar="FILE.csv",
                       help="CSV with header x,y (other columns are carried through to the output)")
    add_region_arguments(parser, points=False)
    add_config_arguments(parser, MeasureConfig)
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="output CSV (default: stdout): x,y,u,v,zncc,ok,status, then the method's columns, "
                              "then the points file's other columns (e.g. id, label)")
    parser.add_argument("--strain-window", type=int, metavar="N",
                        help="add the strain columns exx,eyy,exy: plane fits of u and v over N x N points "
                              "(odd, >= 3; pointwise least squares; VSG = (N - 1) x step + subset, step = --grid "
                              "or the points' spacing)")
    parser.add_argument("--strain-measure", choices=MEASURES,
                        help="strain measure of those columns: engineering (small strain, the default), green "
                              "(Green-Lagrange) or true (logarithmic, Hencky); implies --strain-window 5 when "
                              "that is not given")
    add_progress_argument(parser, help="say on stderr how long a measurement has run once it takes over 1.5 s: "
                                       "on = one line redrawn in place; auto (default) = that on a terminal, else a "
                                       "line every 15 s; off = nothing")


def measure_command(args: argparse.Namespace) -> int:
    """``livedic measure`` with parsed ``args`` (see ``add_measure_arguments``); returns the exit code."""
    import numpy as np

    from livedic.acquire.files.image_file import read_grey_image
    from livedic.stream.output.files import check_output_file, write_csv
    from livedic.stream.pipeline.sinks import bit_depth_change

    to_file = args.output not in (None, "-")
    config = MeasureConfig(**config_values(MeasureConfig, args))   # bad values: one line, before anything is read
    strain = _measure_strain_config(args)
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
        in_place = progress_enabled(args.progress)
        progress = MeasureProgress(len(points), config.method, in_place=in_place)
    from livedic.dic.quality import Gates
    result = measure_with_progress(reference, deformed, points, subset=config.subset, search=config.search,
                                   subpixel=config.subpixel, radius=config.radius, seed=config.seed,
                                   progress=progress, guided=config.guided, gates=Gates(min_zncc=config.min_zncc),
                                   prefilter=config.prefilter, interpolation=config.interpolation)
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
        print(f"livedic: {n_ok}/{result.ok.size} points measured ({config.described()}), written to {args.output}",
              file=sys.stderr)
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

    def __init__(self, n_points: int, method: str, *, in_place: bool = True, after_s: float = 1.5,
                 every_s: float = 15.0, stream: TextIO | None = None):
        self.n_points = n_points
        self.method = method
        self.in_place = in_place
        self.after_s = after_s
        self.every_s = every_s
        self.stream = stream or sys.stderr
        self.lines = 0
        self._last_line_s: float | None = None

    def tick(self, elapsed_s: float) -> None:
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

    def done(self, elapsed_s: float) -> None:
        if self.lines:
            end = f"livedic: measured {self.n_points:,} points ({self.method}) in {elapsed_s:.1f} s"
            self.stream.write(f"\r{end}\033[K\n" if self.in_place else end + "\n")
            self.stream.flush()


def measure_with_progress(reference: np.ndarray, deformed: np.ndarray, points: np.ndarray, *,
                          progress: MeasureProgress | None = None, tick_s: float = 0.25, **method: Any) -> Measurement:
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
