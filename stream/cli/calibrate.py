"""``livedic calibrate IMAGES... --target SPEC --square MM -o CAL.json``: a camera calibration from target images;
``livedic calibrate --left IMAGES... --right IMAGES... --target SPEC --square MM -o RIG.json``: a stereo rig's.

Prints each image (target found or not, its reprojection RMS), the intrinsics, the distortion, the overall
RMS and the specimen plane's px/mm (``--plane``); for a rig, each pair's RMS in both views, both cameras,
the baseline and the angle between them, the parameters' standard deviations and those fixed (a narrow field's
principal point, k2, p1, p2) and why. Refuses (one line, exit 2, nothing written) when the fit exceeds
``--max-error``, a parameter stays less certain than ``--max-uncertainty`` / ``--max-focal-uncertainty``, too few
views (pairs) show the target, or the two cameras' lists differ in length. The guide:
docs/guide/calibration.md.
"""

from __future__ import annotations

import argparse
import os
import sys

from livedic.dic.calibration import (DEFAULT_MAX_ERROR_PX, DEFAULT_UNCERTAINTY_BOUNDS, CameraCalibration, Detection,
                                     StereoCalibration, UncertaintyBounds)
from livedic.dic.calibration.solve import TILT_WARNING_DEG
from livedic.stream.session.parsing import UsageError


def add_calibrate_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``livedic calibrate`` arguments to an ``argparse`` (sub)parser."""
    parser.add_argument("images", nargs="*", metavar="IMAGES",
                        help="images of the target at different tilts and places (10-20 is good): files, folders "
                             "or globs (quoted), 8/16-bit grey PNG or TIFF, all of one size")
    parser.add_argument("--left", nargs="+", metavar="IMAGES",
                        help="stereo: the left camera's target images (files, folders or quoted globs); with --right, "
                             "instead of IMAGES. The i-th left and i-th right image in sorted order are one pair, "
                             "taken at the same moment")
    parser.add_argument("--right", nargs="+", metavar="IMAGES",
                        help="stereo: the right camera's target images, as many as --left, in the same order")
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
    parser.add_argument("--max-uncertainty", type=float, default=DEFAULT_UNCERTAINTY_BOUNDS.corner_px, metavar="PX",
                        help="refuse the calibration when a distortion parameter's standard deviation moves the "
                             f"image's corner by more than PX (default {DEFAULT_UNCERTAINTY_BOUNDS.corner_px:g})")
    parser.add_argument("--max-focal-uncertainty", type=float, default=DEFAULT_UNCERTAINTY_BOUNDS.focal_percent,
                        metavar="PERCENT",
                        help="refuse the calibration when a focal length's standard deviation exceeds PERCENT of it "
                             f"(default {DEFAULT_UNCERTAINTY_BOUNDS.focal_percent:g})")
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
    for option, value, example in (("--max-uncertainty", args.max_uncertainty, "1"),
                                   ("--max-focal-uncertainty", args.max_focal_uncertainty, "1")):
        if not value > 0.0:
            raise UsageError(f"{option} {value:g}: must be a number > 0, e.g. {example}")
    if args.left or args.right:
        return _calibrate_stereo(args)
    if not args.images:
        raise UsageError("give the target images (IMAGES), or --left and --right for a stereo rig")
    images = expand_images(args.images)

    def say(outcome: ImageOutcome) -> None:
        found = outcome.found
        text = f"{len(found.ids)} corners" if isinstance(found, Detection) else f"skipped: {found.detail}"
        print(f"  {outcome.name}: {text}", file=sys.stderr)

    print(f"livedic: finding {args.target} in {len(images)} image(s)", file=sys.stderr)
    calibration = calibrate_images(images, args.target, args.square, plane=args.plane,
                                   max_error_px=args.max_error, bounds=_bounds(args), on_image=say)
    write_calibration(args.output, calibration)
    print(describe_calibration(calibration))
    print(f"livedic: wrote {args.output}", file=sys.stderr)
    return 0


def _calibrate_stereo(args: argparse.Namespace) -> int:
    """``livedic calibrate --left ... --right ...``: the rig's CAL.json (arguments checked by the caller)."""
    from livedic.acquire.calibration import PairOutcome, calibrate_image_pairs, expand_images, write_calibration

    if not (args.left and args.right):
        raise UsageError(f"{'--left' if args.left else '--right'} is given without "
                         f"{'--right' if args.left else '--left'}: a stereo calibration needs both cameras' images")
    if args.images:
        raise UsageError(f"{args.images[0]}: give the images either as IMAGES (one camera) or as --left and --right "
                         "(a stereo rig), not both")
    if args.plane:
        raise UsageError("--plane is for one camera: a stereo rig measures the specimen's surface in 3D, no plane "
                         "image is needed")
    lefts, rights = expand_images(args.left), expand_images(args.right)

    def say(outcome: PairOutcome) -> None:
        views = [f"{len(o.found.ids)} corners" if isinstance(o.found, Detection) else f"skipped: {o.found.detail}"
                 for o in (outcome.left, outcome.right)]
        print(f"  {outcome.left.name} | {outcome.right.name}: left {views[0]}; right {views[1]}", file=sys.stderr)

    print(f"livedic: finding {args.target} in {len(lefts)} left and {len(rights)} right image(s)", file=sys.stderr)
    calibration = calibrate_image_pairs(lefts, rights, args.target, args.square, max_error_px=args.max_error,
                                        bounds=_bounds(args), on_pair=say)
    write_calibration(args.output, calibration)
    print(describe_stereo_calibration(calibration))
    print(f"livedic: wrote {args.output}", file=sys.stderr)
    return 0


def _bounds(args: argparse.Namespace) -> UncertaintyBounds:
    return UncertaintyBounds(focal_percent=args.max_focal_uncertainty, corner_px=args.max_uncertainty)


def describe_stereo_calibration(rig: StereoCalibration) -> str:
    """The rig as a few lines for the user: per-pair errors in both views, both cameras, baseline, angle, RMS."""
    lines = [f"stereo calibration from {len(rig.pairs)} pairs of {rig.left.target} (square {rig.left.square_mm:g} mm)"]
    lines += [f"  {fit.left} | {fit.right}: {fit.corners} corners in both, reprojection RMS left {fit.rms_left_px:.3f} "
              f"px, right {fit.rms_right_px:.3f} px" for fit in rig.pairs]
    lines += [f"  not used: {reason}" for reason in rig.skipped]
    for side, camera in (("left", rig.left), ("right", rig.right)):
        lines.append(f"{side} camera ({camera.image_size[0]}x{camera.image_size[1]}): {_intrinsics(camera)}")
        lines.append(f"  {_determinacy(camera)}")
    lines += [f"baseline {rig.baseline_mm:.3f} mm, angle between the cameras {rig.angle_deg:.3f} deg; "
              f"T = ({', '.join(f'{v:.3f}' for v in rig.translation_mm)}) mm (X_right = R X_left + T)",
              f"reprojection RMS {rig.rms_px:.3f} px over all pairs, both views"]
    return "\n".join(lines)


def _intrinsics(camera: CameraCalibration) -> str:
    """Focal lengths, principal point and distortion on one line."""
    K = camera.camera_matrix
    return (f"focal length fx={K[0, 0]:.2f} px, fy={K[1, 1]:.2f} px; principal point ({K[0, 2]:.2f}, {K[1, 2]:.2f}) "
            f"px; distortion {_distortion(camera)}")


def _determinacy(camera: CameraCalibration) -> str:
    """The fitted parameters' standard deviations and what was fixed, and why, on one line."""
    spread = ", ".join(f"{name} +-{value:.3g}" for name, value in camera.std_devs.items())
    fixed = f"fixed: {', '.join(camera.fixed) or 'nothing'}"
    return f"standard deviations (own views) {spread}; {fixed}" + (f" ({camera.fixed_reason})"
                                                                    if camera.fixed_reason else "")


def _distortion(camera: CameraCalibration) -> str:
    return ", ".join(f"{name}={value:.5g}" for name, value in zip(("k1", "k2", "p1", "p2", "k3"), camera.dist_coeffs))


def describe_calibration(calibration: CameraCalibration) -> str:
    """The calibration as a few lines for the user: per-image errors, intrinsics, distortion, scale."""
    K = calibration.camera_matrix
    width, height = calibration.image_size
    lines = [f"calibration of {width}x{height} images from {len(calibration.images)} views of {calibration.target} "
             f"(square {calibration.square_mm:g} mm)"]
    lines += [f"  {fit.name}: {fit.corners} corners, reprojection RMS {fit.rms_px:.3f} px" for fit in calibration.images]
    if calibration.skipped:
        lines.append(f"  not used (no target): {', '.join(calibration.skipped)}")
    lines += [f"focal length fx={K[0, 0]:.2f} px, fy={K[1, 1]:.2f} px; principal point ({K[0, 2]:.2f}, {K[1, 2]:.2f}) px",
              f"distortion {_distortion(calibration)}",
              _determinacy(calibration),
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
