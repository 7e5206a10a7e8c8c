"""``livedic replay FILE.mcap``: a recording tracked again, its rows as CSV or Parquet, the verdict on stderr.

``add_replay_arguments`` declares its options, ``replay_command`` runs it (``stream.replay.replay.replay``);
``describe_parallel`` is the line a replay on Dask adds.
"""

from __future__ import annotations

import argparse
from typing import Any

import os
import sys

from livedic.stream.export.notes import say
from livedic.stream.pipeline.progress import ProgressBar, add_progress_argument, progress_enabled
from livedic.stream.replay.replay import PointOptions, replay
from livedic.stream.replay.rows import CsvRows, check_rows_output, rows_output
from livedic.stream.session.config import TrackingConfig
from livedic.stream.session.options import add_config_arguments, config_values
from livedic.stream.session.points import add_region_arguments
from livedic.stream.session.summary import format_strain_summary
from livedic.stream.stages.noise_floor import noise_floor_lines
from livedic.stream.stages.force import format_force_summary
from livedic.stream.stages.strain import add_strain_arguments, rig_and_overrides
from livedic.stream.stages.stress import add_stress_arguments, stress_options_from_args


def add_replay_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the ``livedic replay`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("recording", metavar="FILE.mcap", help="a recording made by livedic run (may be truncated)")
    parser.add_argument("-o", "--output", metavar="OUT.csv",
                        help="output file, its format by the suffix: .csv, or .parquet (typed columns, for pandas, "
                             "polars, DuckDB) (default: CSV on stdout)")
    method = parser.add_argument_group("method options (default: the recorded value)")
    add_config_arguments(method, TrackingConfig, with_defaults=False)
    points = parser.add_argument_group("point options (default: the recorded points)")
    add_region_arguments(points)
    points.add_argument("--step", type=int, metavar="S", help="grid step in pixels")
    points.add_argument("--n-points", type=int, metavar="N", help="points wanted when --step is not given")
    points.add_argument("--p0", metavar="X,Y", help="the traced point P0 (point 0)")
    parser.add_argument("--all-frames", action="store_true",
                        help="track every recorded frame from the reference on, also those the live run dropped "
                             "(default: exactly the frames with recorded results, in order: the replay then "
                             "equals the recording bit for bit)")
    parser.add_argument("--threads", type=int, default=1, metavar="N", help="numba threads (default 1)")
    parallel = parser.add_argument_group("parallel replay on Dask (default: sequential, in this process)")
    where = parallel.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N",
                       help="measure the frames in parallel on a local Dask cluster of N worker processes "
                            "(1 thread each), seeded by the recorded results")
    where.add_argument("--cluster", metavar="ADDRESS",
                       help="... on the Dask scheduler at ADDRESS (tcp://HOST:8786), its workers started with "
                            "`dask worker` (livedic installed there)")
    parallel.add_argument("--shared-path", nargs="?", const="", metavar="PATH",
                          help="the workers read the frames from the recording themselves (a shared file system; "
                               "PATH: the recording as the workers see it, default the same path) instead of "
                               "receiving each image from this process")
    add_progress_argument(parser)
    add_strain_arguments(parser, recorded=True)
    add_stress_arguments(parser)
    return parser


def describe_parallel(stats: Any) -> str:
    """One line: where the frames were measured, the tracker's own time and what travelled."""
    per_frame = stats.image_bytes / stats.frames if stats.frames else 0.0
    images = f"{per_frame / 1e6:.2f} MB of image (as recorded)" if stats.shared_path is None \
        else f"the images read by the workers from {stats.shared_path}"
    moves = ""
    if stats.segments > 1:
        moves = (f"; {stats.segments - 1} reference move(s) or fracture(s): {stats.resubmitted} frame(s) measured "
                 f"ahead against the earlier reference were measured again")
    return (f"parallel: {stats.frames} frames measured on {stats.where} ({stats.workers} worker thread(s)): "
            f"{stats.compute_seconds:.1f} s of tracking in the tasks; {images} and "
            f"{stats.seed_bytes / max(stats.frames, 1) / 1e3:.1f} kB of seed per frame sent{moves}")


def describe_stereo(stereo: dict[str, Any]) -> str:
    """One line: a stereo replay's rig, where its calibration came from, and how the views paired."""
    pairing = stereo.get("pairing") or {}
    return (f"stereo: rig baseline {stereo['baseline_mm']:.1f} mm, {stereo['angle_deg']:.1f} degrees, calibration "
            f"{stereo['calibration_from']}; {pairing.get('pairs', 0)} pairs by frame index, "
            f"{pairing.get('dropped_left', 0)} left and {pairing.get('dropped_right', 0)} right frame(s) without a "
            f"partner dropped")


def replay_command(args: argparse.Namespace) -> int:
    """``livedic replay`` with parsed ``args`` (see ``add_replay_arguments``); returns the exit code."""
    check_rows_output(args.output, args.recording)
    given = config_values(TrackingConfig, args)
    options = PointOptions(roi=args.roi, points=args.points, step=args.step, n_points=args.n_points, p0=args.p0,
                           mask=args.mask, exclude=tuple(args.exclude) if args.exclude else None)
    rig, strain = rig_and_overrides(args)
    stress = stress_options_from_args(args)            # bad --load/--area: one line, before anything is read
    to_file = args.output not in (None, "-")
    bar = ProgressBar(None, enabled=progress_enabled(args.progress))
    def progress(done):
        bar.update(done, "frames replayed")

    try:
        if to_file:
            with rows_output(args.output) as write_rows:
                report = replay(args.recording, given, point_options=options, all_frames=args.all_frames,
                                on_rows=write_rows, progress=progress, threads=args.threads, strain=strain,
                                workers=args.workers, cluster=args.cluster, shared_path=args.shared_path,
                                stress=stress, rig=rig)
        else:
            report = replay(args.recording, given, point_options=options, all_frames=args.all_frames,
                            on_rows=CsvRows(sys.stdout), progress=progress, threads=args.threads, strain=strain,
                            workers=args.workers, cluster=args.cluster, shared_path=args.shared_path,
                            stress=stress, rig=rig)
            sys.stdout.flush()
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())        # keep Python's exit flush quiet
        bar.close()
        say("output closed early (broken pipe); replay stopped")
        return 1
    finally:
        bar.close()
    for note in report.notes:
        say(f"note: {note}")
    rate = f"{1e3 * report.seconds / report.frames:.0f} ms/frame" if report.frames else ""
    where = f"; wrote {args.output}" if to_file else ""
    frames_text = "every recorded frame from the reference on" if args.all_frames else "the recorded frame set"
    say(f"replayed {report.frames} frames x {report.points} points ({frames_text}; "
        f"{report.params['search']}+{report.params['subpixel']}) in {report.seconds:.1f} s ({rate}){where}")
    say(report.verdict())
    if report.stereo is not None:
        say(describe_stereo(report.stereo))
    if report.parallel is not None:
        say(describe_parallel(report.parallel))
    floor = noise_floor_lines(report.noise_floor) if report.noise_floor is not None else []
    for line in format_strain_summary(report.strain) + format_force_summary(report.force) + floor:
        say(line.strip())
    return 0
