"""``livedic noise-floor IMAGES...``: the noise floor of static images a user brings (the first is the reference).

Each later image is measured against the first on a grid (``dic.measure``, as ``livedic measure`` does, with
the sub-pixel method, interpolant and pre-filter a session tracks with: ``livedic run``'s defaults), the strain computed on the same window a session uses
(``--strain-window``), and the table of ``dic.noise_floor`` printed: the spatial SD over the points, the
temporal SD of each point over the images, the mean (bias), for u, v (px, and mm with ``--scale``) and exx,
eyy, exy (microstrain), as ``livedic run`` prints it for its static frames. ``-o FILE.json`` also writes it.

``livedic noise-floor --left 'L/*.png' --right 'R/*.png' --calibration RIG.json``: static pairs of a stereo rig
(the first pair the reference; pairs as ``livedic calibrate --left/--right`` takes them: the i-th left and i-th
right image in sorted order). The reference pair is matched left -> right (``dic.stereo.match_stereo``), each
later pair's views measured against their reference images and triangulated (``dic.stereo.StereoTracker``), the
strain computed on the specimen's surface (``dic.stereo.surface_strain``); the table adds U, V, W (mm, the
specimen's axes) to the left view's u, v (px) and gives the surface strain (microstrain).

Bad input (fewer than two images or pairs, an unreadable one, images of different sizes, left and right counts
that differ, a one-camera calibration for pairs, an output that cannot be written) is one line and exit 2,
before anything is written.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from livedic.stream.session.config import MeasureConfig, TrackingConfig
from livedic.stream.session.options import add_config_arguments, config_values, option_fields
from livedic.stream.session.parsing import UsageError
from livedic.stream.session.points import add_region_arguments

DEFAULT_GRID_STEP = 10


def add_noise_floor_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic noise-floor`` options to an ``argparse`` (sub)parser."""
    from livedic.dic.strain import DEFAULT_WINDOW
    parser.add_argument("images", nargs="*", metavar="IMAGE",
                        help="static images of the speckled specimen, nothing moving (8/16-bit grey PNG or TIFF); "
                             "the first is the reference")
    parser.add_argument("--left", nargs="+", metavar="IMAGES",
                        help="stereo: the left camera's static images (files, folders or quoted globs), instead of "
                             "IMAGES; the i-th left and i-th right image in sorted order are one pair, the first "
                             "pair the reference")
    parser.add_argument("--right", nargs="+", metavar="IMAGES",
                        help="stereo: the right camera's static images, as many as --left, in the same order")
    parser.add_argument("--calibration", metavar="RIG.json",
                        help="stereo: the rig's calibration (livedic calibrate --left ... --right ...)")
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

    if args.left or args.right or args.calibration:
        return _stereo_noise_floor(args)
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


def _stereo_noise_floor(args: argparse.Namespace) -> int:
    """``livedic noise-floor --left ... --right ... --calibration RIG.json``: the floor of static pairs."""
    import numpy as np

    from livedic.acquire.calibration import check_image_pairs, expand_images, read_stereo_calibration
    from livedic.acquire.files.image_file import read_same_size_images
    from livedic.dic.stereo import SURFACE_MEASURE, StereoTracker, match_stereo, surface_strain, surface_window
    from livedic.stream.cli.measure import _measure_points
    from livedic.stream.output.files import check_output_file, json_text, write_text_atomic
    from livedic.stream.session.stereo import describe_match, match_summary
    from livedic.stream.stages.noise_floor import StaticFrames, noise_floor_lines, noise_floor_summary

    if not (args.left and args.right):
        given, missing = ("--left", "--right") if args.left else ("--right", "--left") if args.right else \
            ("--calibration", "--left and --right")
        raise UsageError(f"{given} is given without {missing}: static pairs of a stereo rig need both cameras' "
                         "images and the rig's calibration (--left IMAGES --right IMAGES --calibration RIG.json)")
    if args.images:
        raise UsageError(f"{args.images[0]}: give the static images either as IMAGES (one camera) or as --left and "
                         "--right (a stereo rig), not both")
    if args.calibration is None:
        raise UsageError("static pairs need the rig's calibration: --calibration RIG.json (livedic calibrate --left "
                         "... --right ...)")
    if args.scale is not None:
        raise UsageError("--scale is for one camera: a stereo rig measures U, V, W in mm from its calibration")
    config = MeasureConfig(**config_values(MeasureConfig, args))
    if args.output is not None:
        check_output_file(args.output, "-o")
    rig = read_stereo_calibration(args.calibration)           # a one-camera file: one line
    lefts, rights = expand_images(args.left), expand_images(args.right)
    check_image_pairs(lefts, rights, "moments")
    if len(lefts) < 2:
        raise UsageError(f"noise-floor needs at least 2 pairs (a reference and static pairs), got {len(lefts)}")
    views = {}
    for side, names in (("left", lefts), ("right", rights)):
        images, notes = read_same_size_images(names, f"the {side} camera's static images")
        for note in notes:
            print(f"livedic: note: {note}", file=sys.stderr)
        getattr(rig, side).check_size(images[0].shape[1], images[0].shape[0], f"the {side} camera's images")
        views[side] = images
    left, right = views["left"], views["right"]
    points, _, left_out = _measure_points(args, left[0])
    if left_out:
        print(f"livedic: {left_out}", file=sys.stderr)
    started = time.perf_counter()
    match = match_stereo(rig, left[0], right[0], points, subset=config.subset)
    tracker = StereoTracker(rig, match, left[0], right[0],
                            lambda reference, at: _AgainstReference(reference, at, config))
    matched = describe_match(match_summary(tracker, time.perf_counter() - started))
    surface = surface_window(points, match.xyz, window=args.strain_window, step=args.grid, subset=config.subset)
    kept = StaticFrames(stereo=True)
    for k in range(1, len(left)):
        pair = tracker.track(left[k], right[k])
        assert pair.points is not None
        strain = surface_strain(surface, match.xyz, pair.points.xyz, pair.points.ok, measure=SURFACE_MEASURE)
        kept.add(k, pair.u, pair.v, pair.ok, strain, points=pair.points)
    summary = noise_floor_summary(len(left) - 1, kept.frame_indices, kept.table())
    print(f"livedic noise-floor: {len(left) - 1} static pair(s) against {lefts[0]} | {rights[0]}; rig: baseline "
          f"{rig.baseline_mm:.1f} mm, {rig.angle_deg:.1f} degrees; {len(points)} points, grid {args.grid} px, "
          f"subset {config.subset} px, {config.method}, pre-filter {config.prefilter}, interpolation "
          f"{config.interpolation}; {matched}; strain: on the specimen's surface, {SURFACE_MEASURE}, window "
          f"{args.strain_window} points = VSG {surface.vsg_px:.0f} px ({surface.vsg_mm:.2f} mm)")
    print("\n".join(noise_floor_lines(summary)))
    if args.output is not None:
        summary.update(left_images=lefts, right_images=rights, calibration=args.calibration, grid_step=args.grid,
                       subset=config.subset, method=config.method, prefilter=config.prefilter,
                       interpolation=config.interpolation, strain_window=args.strain_window,
                       strain_measure=SURFACE_MEASURE, points=len(points), matched=int(np.sum(match.ok)))
        write_text_atomic(args.output, json_text(summary))
        print(f"livedic: written to {args.output}", file=sys.stderr)
    return 0


class _AgainstReference:
    """A view's "tracker" for ``dic.stereo.StereoTracker``: each static image measured against the view's
    reference afresh (``dic.measure``, as the one-camera command), nothing carried from image to image."""

    def __init__(self, reference: Any, points: Any, config: MeasureConfig) -> None:
        self.reference, self.points, self.config = reference, points, config

    def track(self, image: Any) -> Any:
        from livedic.dic.measure import measure
        from livedic.dic.quality import Gates
        config = self.config
        return measure(self.reference, image, self.points, subset=config.subset, search=config.search,
                       subpixel=config.subpixel, radius=config.radius, seed=config.seed, guided=config.guided,
                       gates=Gates(min_zncc=config.min_zncc), prefilter=config.prefilter,
                       interpolation=config.interpolation)
