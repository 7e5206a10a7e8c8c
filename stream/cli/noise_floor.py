"""``livedic noise-floor IMAGES...``: the noise floor of static images a user brings (the first is the reference).

Each later image is measured against the first on a grid (``dic.measure``, as ``livedic measure`` does, with
the sub-pixel method, interpolant and pre-filter a session tracks with: ``livedic run``'s defaults), the strain computed on the same window a session uses
(``--strain-window``), and the table of ``dic.noise_floor`` printed: the spatial SD over the points, the
temporal SD of each point over the images, the mean (bias), for u, v (px, and mm with ``--scale``) and exx,
eyy, exy (microstrain), as ``livedic run`` prints it for its static frames. ``-o FILE.json`` also writes it.

Bad input (fewer than two images, an unreadable one, images of different sizes, an output that cannot be
written) is one line and exit 2, before anything is written.
"""

from __future__ import annotations

import argparse
import sys

from livedic.stream.session.config import MeasureConfig, TrackingConfig
from livedic.stream.session.options import add_config_arguments, config_values, option_fields
from livedic.stream.session.parsing import UsageError
from livedic.stream.session.points import add_region_arguments

DEFAULT_GRID_STEP = 10


def add_noise_floor_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic noise-floor`` options to an ``argparse`` (sub)parser."""
    from livedic.dic.strain import DEFAULT_WINDOW
    parser.add_argument("images", nargs="+", metavar="IMAGE",
                        help="static images of the speckled specimen, nothing moving (8/16-bit grey PNG or TIFF); "
                             "the first is the reference")
    parser.add_argument("--grid", type=int, default=DEFAULT_GRID_STEP, metavar="STEP",
                        help=f"points on a grid every STEP pixels (default {DEFAULT_GRID_STEP})")
    add_region_arguments(parser, points=False)
    # the interpolant and pre-filter a session samples with (their defaults and help are run's, not measure's
    # offline ones): the noise floor of what livedic run measures
    sampling = ("prefilter", "interpolation")
    add_config_arguments(parser, MeasureConfig, names=tuple(f.name for f in option_fields(MeasureConfig)
                                                            if f.name not in sampling))
    add_config_arguments(parser, TrackingConfig, names=sampling)
    # and the sub-pixel method it tracks with
    parser.set_defaults(subpixel=TrackingConfig().subpixel, points=None)
    parser.add_argument("--strain-window", type=int, default=DEFAULT_WINDOW, metavar="N",
                        help=f"odd number of grid points a side of the strain window (default {DEFAULT_WINDOW}, "
                             "as livedic run)")
    parser.add_argument("--scale", type=float, metavar="PX_PER_MM", help="pixels per millimetre: u and v in mm too")
    parser.add_argument("-o", "--output", metavar="FILE.json", help="also write the table as JSON")


def noise_floor_command(args: argparse.Namespace) -> int:
    """``livedic noise-floor`` with parsed ``args``; returns the exit code (bad input: ``UsageError``)."""
    import numpy as np

    from livedic.acquire.files.image_file import read_same_size_images
    from livedic.dic.quality import Gates
    from livedic.stream.cli.measure import _measure_points, _measure_strain
    from livedic.stream.output.files import check_output_file, json_text, write_text_atomic
    from livedic.stream.stages.noise_floor import StaticFrames, noise_floor_lines, noise_floor_summary
    from livedic.stream.stages.strain import StrainConfig

    if len(args.images) < 2:
        raise UsageError(f"noise-floor needs at least 2 images (a reference and static images of the same "
                         f"view), got {len(args.images)}")
    if args.scale is not None and not (np.isfinite(args.scale) and args.scale > 0):
        raise UsageError(f"--scale must be a positive number of pixels per mm, got {args.scale}")
    config = MeasureConfig(**config_values(MeasureConfig, args))
    strain = StrainConfig(window=args.strain_window)
    if args.output is not None:
        check_output_file(args.output, "-o")
    images, notes = read_same_size_images(args.images, "static images")    # every image checked before the work
    for note in notes:
        print(f"livedic: note: {note}", file=sys.stderr)
    points, _, left_out = _measure_points(args, images[0])
    if left_out:
        print(f"livedic: {left_out}", file=sys.stderr)
    from livedic.dic.measure import measure
    kept = StaticFrames(args.scale)
    described = ""
    for k, image in enumerate(images[1:], start=1):
        result = measure(images[0], image, points, subset=config.subset, search=config.search,
                         subpixel=config.subpixel, radius=config.radius, seed=config.seed, guided=config.guided,
                         gates=Gates(min_zncc=config.min_zncc), prefilter=config.prefilter,
                         interpolation=config.interpolation)
        field, described = _measure_strain(result, strain, step=args.grid, subset=config.subset)
        kept.add(k, result.u, result.v, result.ok, field)
    summary = noise_floor_summary(len(images) - 1, kept.frame_indices, kept.table())
    print(f"livedic noise-floor: {len(images) - 1} static image(s) against {args.images[0]}; {len(points)} points, "
          f"grid {args.grid} px, subset {config.subset} px, {config.method}, pre-filter {config.prefilter}, "
          f"interpolation {config.interpolation}; "
          f"{described}")
    print("\n".join(noise_floor_lines(summary)))
    if args.output is not None:
        summary.update(images=list(args.images), grid_step=args.grid, subset=config.subset, method=config.method,
                       prefilter=config.prefilter, interpolation=config.interpolation, strain_window=strain.window, scale_px_per_mm=args.scale)
        write_text_atomic(args.output, json_text(summary))
        print(f"livedic: written to {args.output}", file=sys.stderr)
    return 0
