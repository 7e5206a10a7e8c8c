"""The ``livedic`` program: stream's commands and ``livedic bench paper|speed|live|validate|accuracy|peers|stereo|soak|strain|fracture|tracker|extensometer``.

The layers run one way, dic <- acquire <- stream <- bench, so the command line of
stream (``livedic.stream.cli``) cannot name the benchmarks; this module, on top,
adds them to it. It is the console script (``livedic = "livedic.bench.cli:entry_point"``);
``python -m livedic.bench.cli`` works too.
"""

import os
import sys

from livedic.stream import cli as stream_cli
from livedic.stream.cli import UsageError
from livedic.stream.session.parsing import subpixel_method


def add_bench_commands(commands):
    """Add ``livedic bench ...`` to the ``livedic`` subparsers ``commands`` (a ``stream.cli`` extension)."""
    bench = commands.add_parser("bench", help="benchmarks: paper reproduction, speed, live pipeline, soak, strain, "
                                             "fracture, tensile, replay, tracker, extensometer, accuracy, peers, stereo")
    bench_commands = bench.add_subparsers(metavar="BENCH")
    for add in (_add_paper_command, _add_speed_command, _add_live_command, _add_validate_command, _add_soak_command,
                _add_strain_command, _add_fracture_command, _add_replay_command, _add_tracker_command,
                _add_tensile_command, _add_extensometer_command, _add_calibration_command, _add_accuracy_command, _add_peers_command, _add_stereo_command):
        add(bench_commands)


def _add_paper_command(bench_commands):
    """``livedic bench paper``'s options."""
    paper = bench_commands.add_parser("paper", help="reproduce the improved-WSO paper's figures and tables")
    paper.add_argument("--quick", action="store_true", help="small version (minutes) for CI")
    paper.add_argument("-o", "--output", default="results/paper", metavar="DIR", help="results folder")
    paper.set_defaults(handler=_cmd_bench_paper)


def _add_speed_command(bench_commands):
    """``livedic bench speed``'s options."""
    speed = bench_commands.add_parser("speed", help="points per second per method on a 1024x1024 image")
    speed.add_argument("--points", type=int, default=10_000, help="number of points (default 10000)")
    speed.add_argument("--size", type=int, default=1024, help="image side in pixels (default 1024)")
    speed.add_argument("--repeat", type=int, default=3, help="timed repetitions, best kept (default 3)")
    speed.add_argument("--quick", action="store_true", help="fewer points and methods, for CI")
    speed.set_defaults(handler=_cmd_bench_speed)


def _add_live_command(bench_commands):
    """``livedic bench live``'s options."""
    live = bench_commands.add_parser("live", help="the live pipeline on 1 MP simulated frames: fps, latency, drops, "
                                                  "the time of each stage",
                                     description="The main job (livedic run --gauge-length 400 --load synthetic: "
                                                 "recording, Rerun .rrd, strain, extensometers, force, strain out) "
                                                 "at 50 and 100 fps and unpaced (its points and 2,000): frames, "
                                                 "drops, latency, p50/p99 of every stage per frame and the tracker "
                                                 "against its IC-GN kernel, with the verdicts (every frame, p99 <= "
                                                 "25 ms, >= 200 and 100 fps unpaced); then livedic run (recording "
                                                 "on, no viewer) for 400/1000/2500 points, improved surface fit and "
                                                 "IC-GN.")
    live.add_argument("--quick", action="store_true", help="512x512, 40 frames, 1000 points only (CI)")
    live.add_argument("--frames", type=int, metavar="N", help="frames per case (default 150; quick 40)")
    live.add_argument("--fps", type=float, default=50.0, help="rate of the simulated camera (default 50)")
    live.add_argument("--threads", type=int, default=1, metavar="N", help="numba threads (default 1, as livedic run)")
    live.add_argument("--verbose", action="store_true", help="also print each session's own summary")
    live.set_defaults(handler=_cmd_bench_live)


def _add_validate_command(bench_commands):
    """``livedic bench validate``'s options."""
    validate = bench_commands.add_parser(
        "validate", help="is every point marked ok right? wrong-but-ok points on other generators and the DIC "
                         "Challenge sets", description="Counts the points dic.measure reports as ok that are more "
                         "than 0.5 px from the truth (target: 0 in every row), on shifts up to 30 px from four "
                         "pattern generators and, with --data, DIC Challenge Samples 3 and 12 and Stars 1/2. "
                         "Exit code 1 if any row has one.")
    validate.add_argument("--data", metavar="DIR",
                          help="folder with dicc1_sample3_translation, dicc1_sample12_oht_cfrp and dicc2_star "
                               "(e.g. ../shared/datasets); without it only the synthetic cases run")
    validate.add_argument("--quick", action="store_true", help="fewer shifts, points and searches (minutes)")
    validate.set_defaults(handler=_cmd_bench_validate)


def _add_accuracy_command(bench_commands):
    """``livedic bench accuracy``'s options."""
    accuracy = bench_commands.add_parser(
        "accuracy", help="spatial resolution, noise and their product on the DIC Challenge 2.0 Stars; Sample 3's bias",
        description="On DIC Challenge 2.0 Stars 1 and 2: the period at which the v amplitude error on the centre "
                    "row reaches 10 % (spatial resolution), the noise (SD of v - truth where the period is large), "
                    "their product (metrological efficiency indicator) and the first-order noise prediction, for "
                    "subsets 15/21/31 and icgn/icgn2. On DIC Challenge 1.0 Sample 3: the mean bias and SD of u and v "
                    "per shift (subset 21, grid 10, icgn) against the 0.001 px target (exit code 1 above it).")
    accuracy.add_argument("--data", required=True, metavar="DIR",
                          help="folder with dicc2_star and dicc1_sample3_translation (e.g. ../shared/datasets)")
    accuracy.add_argument("--quick", action="store_true", help="subset 21 and icgn only, every 2 px (about a minute)")
    accuracy.add_argument("-o", "--output", metavar="OUT.json", help="also write the tables as JSON")
    from livedic.stream.session.config import MeasureConfig
    from livedic.stream.session.options import add_config_arguments
    add_config_arguments(accuracy, MeasureConfig, names=("interpolation", "prefilter"))   # measure's defaults
    accuracy.set_defaults(handler=_cmd_bench_accuracy)


def _add_stereo_command(bench_commands):
    """``livedic bench stereo``'s options."""
    stereo = bench_commands.add_parser(
        "stereo", help="stereo DIC against the simulator's 3D truth (U, V, W, strain in space), 2D beside it, and "
                       "the live rate at 2 x 1 MP",
        description="The simulated coupon stretched 1 %, moved 0.5 mm away from the cameras and turned 1 degree, "
                    "seen by a 25 degree rig: U, V, W RMSE, the extensometers in space and on the surface against "
                    "the exact strain, the same extensometers of a 2D session on one camera, and the live rate "
                    "(paced at 25 fps and unpaced).")
    stereo.add_argument("--quick", action="store_true", help="512x512 views, 8 frames (about a minute)")
    stereo.add_argument("-o", "--output", metavar="OUT.json", help="also write the figures as JSON")
    stereo.add_argument("--peer-python", metavar="PATH",
                        help="the python of a separate environment where pyALDIC-3D (pip install al-dic-3d) is "
                             "installed: it runs on the same pairs, its U, V, W RMSE beside livedic's (left out: "
                             "not installed)")
    stereo.set_defaults(handler=_cmd_bench_stereo)


def _cmd_bench_stereo(args):
    from livedic.bench.stereo import check_peer_python, run_stereo_benchmark
    from livedic.stream.output.files import check_output_file
    try:
        if args.peer_python is not None:
            check_peer_python(args.peer_python)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.output is not None:
        check_output_file(args.output, "-o")
    return run_stereo_benchmark(quick=args.quick, output=args.output, peer_python=args.peer_python)


def _add_peers_command(bench_commands):
    """``livedic bench peers``'s options."""
    peers = bench_commands.add_parser(
        "peers", help="RMSE against open DIC codes (SUN-DIC, OpenCorr) on other generators' 8- and 12-bit shifts",
        description="Rigid sub-pixel shifts rendered by pattern generators other than livedic's simulator, 8 and "
                    "12 bit, noise sigma 2 grey levels, exact truth: the RMSE of u and v over every ok point for "
                    "livedic's icgn with bspline3/bspline5 and no or a Gaussian pre-filter, and for the peers given "
                    "(run here on the same images), with livedic's ratio to the best peer against the 0.9x target "
                    "(exit code 1 when peers ran and no setting meets it).")
    peers.add_argument("--quick", action="store_true", help="one generator, one shift, 256x256 (about a minute)")
    peers.add_argument("-o", "--output", metavar="OUT.json", help="also write the tables as JSON")
    peers.add_argument("--sundic-python", metavar="PATH",
                       help="the python of a separate environment with SUN-DIC installed (pip install sun-dic); "
                            "without it SUN-DIC is reported not installed")
    peers.add_argument("--opencorr-bin", metavar="PATH",
                       help="OpenCorr's FFT-CC + IC-GN driver built as docs/guide/measure.md says; without it "
                            "OpenCorr is reported not installed")
    peers.set_defaults(handler=_cmd_bench_peers)


def _add_soak_command(bench_commands):
    """``livedic bench soak``'s options."""
    soak = bench_commands.add_parser("soak", help="20,000 frames through the full pipeline: RSS growth, frames "
                                                  "produced vs recorded vs tracked vs dropped")
    soak.add_argument("--frames", type=int, default=20_000, metavar="N", help="frames to produce (default 20000)")
    soak.add_argument("--size", type=int, default=512, metavar="PX",
                      help="square image side (default 512: 20000 frames record 5.2 GB; 1024 would be 21 GB)")
    soak.add_argument("--fps", type=float, default=50.0, help="paced rate of the simulated camera (default 50)")
    soak.add_argument("--points", type=int, default=1000, metavar="N", help="points wanted (default 1000)")
    soak.add_argument("--subpixel", type=subpixel_method, default="icgn", metavar="NAME",
                      help="sub-pixel method (default icgn)")
    soak.add_argument("--loop", type=int, default=200, metavar="K",
                      help="frames rendered and cycled forward and back (default 200)")
    soak.add_argument("--dir", metavar="DIR", help="folder for the recording (default: a temporary folder)")
    soak.add_argument("--keep", action="store_true", help="keep the recording (deleted by default)")
    soak.set_defaults(handler=_cmd_bench_soak)


def _add_strain_command(bench_commands):
    """``livedic bench strain``'s options."""
    strain = bench_commands.add_parser(
        "strain", help="strain fields and virtual extensometers against exact values: uniform strain, the simulated "
                       "tensile test, the real dog-bone", description="Strain error RMS on uniform strain fields "
                       "(two pattern generators, 8-bit, noise sigma 1) against the VSG, e_yy RMSE inside and outside "
                       "the neck of the simulated tensile test, extensometer errors against ISO 9513 class 0.5 "
                       "(50 microstrain + 0.5 % of the reading) and, with --data, the real muDIC dog-bone sequence. "
                       "Prints the tables and the verdict on each target; writes CSVs and strain.png.")
    strain.add_argument("--quick", action="store_true", help="smaller images, one subset, 60 frames (about a minute)")
    strain.add_argument("--data", metavar="DIR", help="folder with mudic_tensile_dogbone (e.g. ../shared/datasets); "
                                                      "without it the real sequence is skipped")
    strain.add_argument("-o", "--output", default="results/strain", metavar="DIR", help="results folder")
    strain.set_defaults(handler=_cmd_bench_strain)


def _add_fracture_command(bench_commands):
    """``livedic bench fracture``'s options."""
    fracture = bench_commands.add_parser(
        "fracture", help="a tensile test to fracture: reference updates, accumulated error, fracture detection",
        description="The simulated test to 30 % uniform / 100 % neck strain with fading paint and a fracture, "
                    "tracked with --reference-update never and auto: visible points ok, RMSE and extensometer "
                    "error against the truth, wrong-but-ok points, the fracture frame, jumps at updates, update "
                    "time; with --data the real muDIC dog-bone's re-finds. Prints the verdict on each target; "
                    "writes fracture.csv and fracture.png.")
    fracture.add_argument("--quick", action="store_true", help="512x512, 120 frames (a minute or two)")
    fracture.add_argument("--data", metavar="DIR", help="folder with mudic_tensile_dogbone (e.g. ../shared/datasets)")
    fracture.add_argument("-o", "--output", default="results/fracture", metavar="DIR", help="results folder")
    fracture.set_defaults(handler=_cmd_bench_fracture)


def _add_replay_command(bench_commands):
    """``livedic bench replay``'s options."""
    replay = bench_commands.add_parser(
        "replay", help="offline replay: what writing CSV / Parquet costs, sequential vs Dask --workers 1 and 2 "
                       "(frames/s, overhead per frame)",
        description="Replays one recording sequentially with no output, with the CSV formatted as before "
                    "(cell by cell), with the CSV as now and with Parquet (frames/s, writing time per frame and "
                    "its share); then on local Dask clusters of 1 and 2 worker processes "
                    "(the largest also with --shared-path): frames/s, the ratio to sequential, the tracking, CSV "
                    "and scheduling time per frame. Without --recording it records the simulated tensile test first.")
    replay.add_argument("--recording", metavar="FILE.mcap",
                        help="replay this recording (default: one made here by livedic run)")
    replay.add_argument("--frames", type=int, default=60, metavar="N",
                        help="frames of the recording made here (default 60)")
    replay.add_argument("--size", default="1024x1024", metavar="WxH",
                        help="image size of the recording made here (default 1024x1024)")
    replay.add_argument("--points", type=int, default=2000, metavar="N", help="points wanted (default 2000)")
    replay.add_argument("--workers", default="1,2", metavar="N,M",
                        help="worker processes of each local cluster timed (default 1,2; 0: none, the "
                             "sequential replays only)")
    replay.add_argument("--quick", action="store_true", help="30 frames of 256x256, 300 points (about 20 s)")
    replay.add_argument("-o", "--output", default="results/replay", metavar="DIR",
                        help="results folder (replay.json; default results/replay)")
    replay.set_defaults(handler=_cmd_bench_replay)


def _add_tracker_command(bench_commands):
    """``livedic bench tracker``'s options."""
    tracker = bench_commands.add_parser(
        "tracker", help="the tracker's own cost per frame by stage, against the bare IC-GN kernel on the same points",
        description="Tracks the main job's frames (synthetic:tensile 1024x1024, its points, TrackingConfig's "
                    "defaults) and prints the p50/p99 ms of each stage of KeyFrameTracker.track, the bare IC-GN "
                    "kernel on the same points from the same start, and the tracker / kernel ratio (goal <= 1.5).")
    tracker.add_argument("--frames", type=int, default=300, metavar="N", help="frames of the simulated test (300)")
    tracker.add_argument("--size", type=int, default=1024, metavar="PX",
                         help="square image side (default 1024, the main job's)")
    tracker.add_argument("--points", type=int, metavar="N", help="points wanted (default: the main job's)")
    tracker.add_argument("--threads", type=int, default=1, metavar="N", help="numba threads (default 1, as livedic run)")
    tracker.add_argument("--save", metavar="FILE.npz", help="also write every frame's result")
    tracker.add_argument("--compare", metavar="FILE.npz",
                         help="check the results against a --save file bit for bit (exit code 1 if any differs)")
    tracker.add_argument("--stacks", metavar="PROFILE.txt",
                         help="only summarise a py-spy raw profile: where the samples inside the tracker end")
    from livedic.stream.session.config import TrackingConfig
    from livedic.stream.session.options import add_config_arguments
    add_config_arguments(tracker, TrackingConfig, names=("interpolation",))
    tracker.set_defaults(handler=_cmd_bench_tracker)


def _add_extensometer_command(bench_commands):
    """``livedic bench extensometer``'s options."""
    from livedic.bench.extensometer import (BIT_DEPTHS, DEFAULT_FRAMES_PER_STEP, DEFAULT_GAUGE_LENGTHS,
                                            DEFAULT_NOISE, DEFAULT_STRAINS, DEFAULT_SCALE_PX_PER_MM,
                                            default_test_width)
    from livedic.dic.strain.extensometer import END_FITS
    from livedic.stream.stages.strain import DEFAULT_AXIAL_END_FIT
    lengths = ",".join(f"{v:g}" for v in DEFAULT_GAUGE_LENGTHS)
    strains = ",".join(f"{100 * v:g}" for v in DEFAULT_STRAINS)
    bench = bench_commands.add_parser(
        "extensometer", help="the virtual extensometer's ISO 9513 class from known elongations (bias, resolution)",
        description="Renders exact known motions on a speckle strip (rigid translations for zero elongation, then "
                    "uniform stretches), each held for several frames with independent noise, tracks them as "
                    "livedic run does and reads an axial extensometer of each gauge length: per step the true "
                    "elongation, mean reading, bias and resolution (half the range of the held readings), and the "
                    "ISO 9513:2012 class met (0.2, 0.5, 1, 2). -o writes the JSON that livedic report "
                    "--verification takes.")
    bench.add_argument("--gauge-length", type=_positive_list, default=DEFAULT_GAUGE_LENGTHS, metavar="L[,L...]",
                       help=f"gauge lengths, px (default {lengths})")
    bench.add_argument("--scale", type=_scale, default=DEFAULT_SCALE_PX_PER_MM, metavar="PX_PER_MM",
                       help=f"scale on the specimen, px/mm, for the absolute (um) limits (default "
                            f"{DEFAULT_SCALE_PX_PER_MM:g}, the simulated test's; none: relative limits only)")
    bench.add_argument("--steps", type=_positive_list, default=tuple(100 * v for v in DEFAULT_STRAINS),
                       metavar="PERCENT[,...]", help=f"strain steps, %% engineering strain (default {strains}); "
                                                    "the rigid zero steps always come first")
    bench.add_argument("--frames-per-step", type=int, default=DEFAULT_FRAMES_PER_STEP, metavar="M",
                       help=f"frames held at each step, each with its own noise (default {DEFAULT_FRAMES_PER_STEP})")
    bench.add_argument("--noise", type=float, default=DEFAULT_NOISE, metavar="SIGMA",
                       help=f"Gaussian noise SD, grey levels of an 8-bit image (scaled with --bit; default "
                            f"{DEFAULT_NOISE:g})")
    bench.add_argument("--bit", type=int, choices=BIT_DEPTHS, default=8, help="bit depth of the frames (default 8)")
    bench.add_argument("--extensometer-ends", choices=END_FITS, default=DEFAULT_AXIAL_END_FIT,
                       help=f"how the ends are fitted, as livedic run's option (default {DEFAULT_AXIAL_END_FIT})")
    bench.add_argument("--width", type=_positive_number, default=None, metavar="PX",
                       help="the specimen's width, px: points fill it across, and the axial extensometer's band "
                            "ends are fitted over them (default: the default simulated test's gauge width, "
                            f"{default_test_width():g} px)")
    bench.add_argument("--seed", type=int, default=0, help="speckle pattern and noise (default 0): the class near a "
                                                           "border varies with the noise drawn")
    from livedic.stream.session.config import TrackingConfig
    from livedic.stream.session.options import add_config_arguments
    add_config_arguments(bench, TrackingConfig, names=("subpixel",))
    bench.add_argument("-o", "--output", metavar="FILE.json", help="write the verification (for livedic report "
                                                                   "--verification)")
    bench.set_defaults(handler=_cmd_bench_extensometer)


def _positive_list(text):
    """"100,400" -> (100.0, 400.0); argparse reports a ValueError as one line."""
    import argparse
    import math
    try:
        values = tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of numbers") from None
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: every value must be a number > 0")
    return values


def _positive_number(text):
    """One number > 0 (argparse reports the error as one line)."""
    values = _positive_list(text)
    if len(values) != 1:
        import argparse
        raise argparse.ArgumentTypeError(f"{text!r}: one number > 0")
    return values[0]


def _scale(text):
    """A scale in px/mm, or ``none``."""
    if text.strip().lower() == "none":
        return None
    return _positive_number(text)


def _add_tensile_command(bench_commands):
    """``livedic bench tensile``'s options."""
    tensile = bench_commands.add_parser(
        "tensile", help="E, Rp0.2, Rm, Ag, A recovered from the simulated tensile test with a known law",
        description="Runs the simulated tensile test (E 200 GPa, Rp0.2 816 MPa, Rm 1200 MPa, fracture) through "
                    "livedic run --load synthetic and livedic report, and prints each property against the law "
                    "and against the same methods on the exact strain, with the targets (E 2 %, Rp0.2 and Rm "
                    "1 %). Writes tensile.csv, the recording and the report.")
    tensile.add_argument("--quick", action="store_true", help="512x512, 150 frames (about 15 s) instead of 1 MP")
    tensile.add_argument("-o", "--output", default="results/tensile", metavar="DIR", help="results folder")
    tensile.set_defaults(handler=_cmd_bench_tensile)


def _add_calibration_command(bench_commands):
    """``livedic bench calibration``'s options."""
    calibration = bench_commands.add_parser(
        "calibration", help="a calibration recovered from simulated targets against the known lens, and the strain "
                            "error of a 1 %% stretch with and without the correction, centre and corners",
        description="Renders chessboard views through a known lens (f = image width, k1 ...), calibrates, prints "
                    "the recovered parameters against the truth, then measures a uniform 1 % stretch filmed "
                    "through the lens and prints the strain error near the centre and the corners: uncorrected, "
                    "with the recovered calibration, with the true lens.")
    calibration.add_argument("--size", type=int, default=1024, metavar="PX", help="image side (default 1024)")
    calibration.add_argument("--k1", type=float, default=-0.12, help="the lens's k1 (default -0.12)")
    calibration.add_argument("--k2", type=float, default=0.0, help="k2 (default 0)")
    calibration.add_argument("--views", metavar="DIR",
                             help="also write the target images there, for livedic calibrate")
    calibration.set_defaults(handler=_cmd_bench_calibration)


def _cmd_bench_calibration(args):
    from livedic.bench.calibration import run_calibration_benchmark
    if args.size < 256:
        raise UsageError(f"--size {args.size}: give an image side of at least 256 px")
    run_calibration_benchmark(size=args.size, k1=args.k1, k2=args.k2, views=args.views,
                              say=lambda line: print(line, flush=True))
    return 0


def build_parser():
    """The whole ``livedic`` parser, benchmarks included."""
    return stream_cli.build_parser(extensions=(add_bench_commands,))


def main(argv=None):
    """``livedic`` with ``argv`` (default: the process's); returns the exit code."""
    return stream_cli.main(argv, extensions=(add_bench_commands,))


def entry_point():
    """The ``livedic`` console script (see ``stream.cli.entry_point``)."""
    return stream_cli.entry_point(extensions=(add_bench_commands,))


def _cmd_bench_paper(args):
    from livedic.bench.paper import run_paper_benchmark
    return run_paper_benchmark(args.output, quick=args.quick)


def _cmd_bench_speed(args):
    from livedic.bench.speed import run_speed_benchmark
    return run_speed_benchmark(n_points=args.points, size=args.size, repeat=args.repeat, quick=args.quick)


def _cmd_bench_live(args):
    from livedic.bench.live import run_live_benchmark
    if args.frames is not None and args.frames < 2:
        raise UsageError(f"--frames must be >= 2, got {args.frames}")
    if not args.fps > 0:
        raise UsageError(f"--fps must be > 0, got {args.fps}")
    run_live_benchmark(quick=args.quick, frames=args.frames, fps=args.fps, threads=args.threads,
                       echo_sessions=args.verbose, log=lambda line: print(line, flush=True))
    return 0


def _cmd_bench_tracker(args):
    from livedic.bench.tracker_cost import run_tracker_benchmark, stack_summary
    if args.stacks is not None:
        if not os.path.isfile(args.stacks):
            raise UsageError(f"--stacks {args.stacks} is not a file: give a py-spy profile recorded with --format raw")
        stack_summary(args.stacks)
        return 0
    if args.frames < 5 or args.size < 64 or (args.points is not None and args.points < 1):
        raise UsageError("--frames >= 5, --size >= 64 and --points >= 1 please")
    if args.compare is not None:
        import numpy as np
        try:
            np.load(args.compare).close()
        except (OSError, ValueError):
            raise UsageError(f"--compare {args.compare} is not a results file: give one written by --save") from None
    import numba
    if not 1 <= args.threads <= numba.config.NUMBA_NUM_THREADS:
        raise UsageError(f"--threads must be between 1 and {numba.config.NUMBA_NUM_THREADS}, got {args.threads}")
    return run_tracker_benchmark(frames=args.frames, size=args.size, n_points=args.points, threads=args.threads,
                                 save=args.save, compare=args.compare, say=lambda line: print(line, flush=True),
                                 interpolation=args.interpolation)


def _cmd_bench_validate(args):
    from livedic.bench.validate import run_validate_benchmark
    if args.data is not None and not os.path.isdir(args.data):
        raise UsageError(f"--data {args.data} is not a folder: give the folder holding the DIC Challenge sets")
    return run_validate_benchmark(data=args.data, quick=args.quick, log=lambda line: print(line, flush=True))


def _cmd_bench_accuracy(args):
    from livedic.bench.accuracy import check_data, run_accuracy_benchmark
    from livedic.stream.output.files import check_output_file
    if not os.path.isdir(args.data):
        raise UsageError(f"--data {args.data} is not a folder: give the folder holding the DIC Challenge sets "
                         "(e.g. ../shared/datasets)")
    try:
        check_data(args.data)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.output is not None:
        check_output_file(args.output, "-o")
    return run_accuracy_benchmark(data=args.data, quick=args.quick, output=args.output,
                                  log=lambda line: print(line, flush=True), interpolation=args.interpolation,
                                  prefilter=args.prefilter)


def _cmd_bench_peers(args):
    from livedic.bench.peers import check_peer_location, check_sundic_python, run_peers_benchmark
    from livedic.stream.output.files import check_output_file
    try:
        if args.sundic_python is not None:
            check_sundic_python(args.sundic_python)
        if args.opencorr_bin is not None:
            check_peer_location("--opencorr-bin", args.opencorr_bin)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.output is not None:
        check_output_file(args.output, "-o")
    return run_peers_benchmark(quick=args.quick, output=args.output, sundic_python=args.sundic_python,
                               opencorr_bin=args.opencorr_bin, log=lambda line: print(line, flush=True))


def _cmd_bench_soak(args):
    from livedic.bench.soak import run_soak_benchmark
    if args.frames < 2 or args.size < 64 or not args.fps > 0 or args.points < 1 or args.loop < 2:
        raise UsageError("--frames >= 2, --size >= 64, --fps > 0, --points >= 1 and --loop >= 2 please")
    result = run_soak_benchmark(frames=args.frames, size=args.size, fps=args.fps, n_points=args.points,
                                subpixel=args.subpixel, loop=args.loop, directory=args.dir, keep=args.keep,
                                log=lambda line: print(line, flush=True))
    return 0 if result["passed_rss"] and result["passed_accounting"] else 1


def _cmd_bench_strain(args):
    from livedic.bench.strain import DOGBONE, run_strain_benchmark
    if args.data is not None and not os.path.isdir(os.path.join(args.data, DOGBONE)):
        raise UsageError(f"--data {args.data} has no {DOGBONE} folder: give the folder holding it "
                         "(e.g. ../shared/datasets)")
    _check_results_folder(args.output)
    run_strain_benchmark(quick=args.quick, data=args.data, output=args.output,
                         log=lambda line: print(line, flush=True))
    return 0


def _cmd_bench_fracture(args):
    from livedic.bench.fracture import run
    _check_results_folder(args.output)
    try:
        run(quick=args.quick, data=args.data, output=args.output, say=lambda line: print(line, flush=True))
    except ValueError as error:
        raise UsageError(str(error)) from None
    return 0


def _cmd_bench_replay(args):
    from livedic.bench.replay import parse_workers, run_replay_benchmark
    try:
        workers = parse_workers(args.workers)
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.frames < 2 or args.points < 1:
        raise UsageError("--frames >= 2 and --points >= 1 please")
    if args.recording is not None and not os.path.isfile(args.recording):
        raise UsageError(f"--recording {args.recording} is not a file")
    _check_results_folder(args.output)
    run_replay_benchmark(recording=args.recording, frames=args.frames, size=args.size, points=args.points,
                         workers=workers, output=args.output, quick=args.quick,
                         log=lambda line: print(line, flush=True))
    return 0


def _cmd_bench_extensometer(args):
    from livedic.bench.extensometer import default_steps, run_extensometer_bench
    from livedic.stream.export.report_verification import write_verification
    from livedic.stream.output.files import check_output_file
    if args.frames_per_step < 2:
        raise UsageError("--frames-per-step must be at least 2: the resolution is read from the readings' fluctuation")
    if not (args.noise >= 0):
        raise UsageError(f"--noise must be >= 0 grey levels, got {args.noise:g}")
    if args.output is not None:
        check_output_file(args.output, "-o")
    result = run_extensometer_bench(gauge_lengths=args.gauge_length, steps=default_steps([v / 100 for v in args.steps]),
                                    frames_per_step=args.frames_per_step, noise=args.noise, bit=args.bit,
                                    scale_px_per_mm=args.scale, seed=args.seed, end_fit=args.extensometer_ends,
                                    width=args.width, subpixel=args.subpixel, say=lambda line: print(line, flush=True))
    if args.output is not None:
        write_verification(args.output, result)
        print(f"written: {args.output}", flush=True)
    return 0


def _cmd_bench_tensile(args):
    from livedic.bench.tensile import run_tensile_benchmark
    _check_results_folder(args.output)
    run_tensile_benchmark(quick=args.quick, output=args.output, say=lambda line: print(line, flush=True))
    return 0


def _check_results_folder(path):
    """UsageError (one line) unless the results folder exists or can be made, and takes files."""
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as error:
        raise UsageError(f"-o {path}: cannot create the results folder ({error.strerror})") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise UsageError(f"-o {path}: the results folder is not writable; choose another")


if __name__ == "__main__":
    sys.exit(entry_point())
