"""``livedic calibrate IMAGES... --target SPEC --square MM -o CAL.json``: a camera calibration from target images.

Prints each image (target found or not, its reprojection RMS), the intrinsics, the distortion, the overall
RMS and the specimen plane's px/mm (``--plane``); refuses (one line, exit 2, nothing written) when the fit
exceeds ``--max-error`` or too few views show the target. The guide: docs/guide/calibration.md.
"""

from __future__ import annotations

import argparse
import os
import sys

from livedic.dic.calibration import DEFAULT_MAX_ERROR_PX, CameraCalibration, Detection
from livedic.dic.calibration.solve import TILT_WARNING_DEG
from livedic.stream.session.parsing import UsageError


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic calibrate`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("images", nargs="+", metavar="IMAGES",
                        help="images of the target at different tilts and places (10-20 is good): files, folders "
                             "or globs (quoted), 8/16-bit grey PNG or TIFF, all of one size")
    parser.add_argument("--target", required=True, metavar="SPEC",
                        help="chessboard:COLSxROWS (INNER corners, as OpenCV counts: a board of 10 x 7 squares is "
                             "chessboard:9x6) or charuco:COLSxROWS[:DICT[:MARKER]] (SQUARES; ArUco dictionary DICT, "
                             "default DICT_5X5_100; markers MARKER x the square, default 0.75)")
    parser.add_argument("--square", required=True, type=float, metavar="MM", help="the target's square side (mm)")
    parser.add_argument("-o", "--output", required=True, metavar="CAL.json", help="calibration file to write")
    parser.add_argument("--plane", metavar="IMAGE",
                        help="an image of the target lying flat on the specimen's surface (may be one of IMAGES): "
                             "gives the scale px/mm on the specimen plane; without it lengths stay in px unless "
                             "the measurement is given --scale")
    parser.add_argument("--max-error", type=float, default=DEFAULT_MAX_ERROR_PX, metavar="PX",
                        help=f"refuse the calibration when the reprojection RMS, overall or of any image, exceeds "
                             f"PX (default {DEFAULT_MAX_ERROR_PX:g})")
    parser.add_argument("--overwrite", action="store_true", help="replace CAL.json if it exists")


def calibrate_command(args: argparse.Namespace) -> int:
    """``livedic calibrate`` with parsed ``args``; returns the exit code (errors: one line, exit 2)."""
    from livedic.acquire.calibration import ImageOutcome, calibrate_images, expand_images, write_calibration
    from livedic.stream.output.files import check_output_file

    if os.path.lexists(args.output) and not args.overwrite:
        raise UsageError(f"{args.output} already exists: choose a new name, or add --overwrite to replace it")
    check_output_file(args.output, "-o")
    if not args.max_error > 0.0:
        raise UsageError(f"--max-error {args.max_error:g}: must be a number of pixels > 0, e.g. 0.5")
    images = expand_images(args.images)

    def say(outcome: ImageOutcome) -> None:
        found = outcome.found
        text = f"{len(found.ids)} corners" if isinstance(found, Detection) else f"skipped: {found.detail}"
        print(f"  {outcome.name}: {text}", file=sys.stderr)

    print(f"livedic: finding {args.target} in {len(images)} image(s)", file=sys.stderr)
    calibration = calibrate_images(images, args.target, args.square, plane=args.plane,
                                   max_error_px=args.max_error, on_image=say)
    write_calibration(args.output, calibration)
    print(describe_calibration(calibration))
    print(f"livedic: wrote {args.output}", file=sys.stderr)
    return 0


def describe_calibration(calibration: CameraCalibration) -> str:
    """The calibration as a few lines for the user: per-image errors, intrinsics, distortion, scale."""
    K = calibration.camera_matrix
    width, height = calibration.image_size
    lines = [f"calibration of {width}x{height} images from {len(calibration.images)} views of {calibration.target} "
             f"(square {calibration.square_mm:g} mm)"]
    lines += [f"  {fit.name}: {fit.corners} corners, reprojection RMS {fit.rms_px:.3f} px" for fit in calibration.images]
    if calibration.skipped:
        lines.append(f"  not used (no target): {', '.join(calibration.skipped)}")
    dist = ", ".join(f"{name}={value:.5g}" for name, value in zip(("k1", "k2", "p1", "p2", "k3"),
                                                                      calibration.dist_coeffs))
    lines += [f"focal length fx={K[0, 0]:.2f} px, fy={K[1, 1]:.2f} px; principal point ({K[0, 2]:.2f}, {K[1, 2]:.2f}) px",
              f"distortion {dist}",
              f"reprojection RMS {calibration.rms_px:.3f} px over all views"]
    plane = calibration.plane
    if plane is None:
        lines.append("scale: none (no --plane image): lengths stay in px unless a measurement is given --scale")
    else:
        x, y = plane.px_per_mm_xy
        lines.append(f"scale on the specimen plane ({plane.image}): {plane.px_per_mm:.4f} px/mm "
                     f"(x {x:.4f}, y {y:.4f}); plane tilted {plane.tilt_deg:.2f} deg from the camera axis")
        if plane.tilt_deg > TILT_WARNING_DEG:
            lines.append(f"warning: the plane is tilted {plane.tilt_deg:.1f} deg (> {TILT_WARNING_DEG:g}): strain and "
                         "lengths are taken on the plane through its homography, but the target must lie exactly on "
                         "the specimen and any out-of-plane motion reads as strain; set the camera square to the "
                         "specimen")
    return "\n".join(lines)
