#!/usr/bin/env python3
"""A stereo calibration's accuracy on target pairs rendered through a known rig, at one or several focal lengths, with
the cameras' intrinsics fixed at each camera's own fit or refined with R and T (``--intrinsics``; the choice of
``dic.calibration.DEFAULT_STEREO_FLAGS``).

For each focal length and noise seed: renders the pairs (``STEREO_VIEWS``, or ``NARROW_STEREO_VIEWS`` under a 10 degree
field: ``acquire.simulator.targets.stereo_view_plan``), calibrates, and prints the errors against the truth: R (deg),
T (mm), each camera's focal length (%), principal point, k1, k2, which parameters the narrow-field rule fixed
(``dic.calibration.determinacy``) and the parameters' standard deviations; and what a measurement sees: points of a
flat specimen at the aim point projected through the true rig and triangulated with the calibration, their
position error (mm RMS) and the false strain when it moves rigidly (0.5 mm, 1 degree; microstrain RMS). ``--write DIR`` also writes
the images (DIR/left, DIR/right) for ``livedic calibrate --left DIR/left --right DIR/right``:

    .venv/bin/python scripts/stereo_calibration_accuracy.py [--size 640x480] [--focal 640 [2000 ...]] [--angle 25]
        [--lens two|simulator] [--views auto|default|narrow] [--intrinsics refined fixed]
        [--target chessboard:9x6] [--fill 0.45] [--seeds 0 100 200] [--write DIR]
"""

from __future__ import annotations

import argparse
import os
from dataclasses import replace

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.targets import (NARROW_STEREO_VIEW_FILL, NARROW_STEREO_VIEWS,
                                               STEREO_VIEWS, render_target_pair, rig_aim_mm, stereo_calibration_views,
                                               stereo_square_mm, stereo_view_plan)
from livedic.dic.calibration import (DEFAULT_STEREO_FLAGS, CalibrationRefused, Detection, StereoCalibration,
                                     TargetPair, calibrate_stereo, detect_target, parse_target, undistort_points)

# The board's width for STEREO_VIEWS here (the guide's tables): a larger board than the simulator's STEREO_VIEW_FILL.
WIDE_FILL = 0.45
CHOICES = {"fixed": cv2.CALIB_FIX_INTRINSIC, "refined": DEFAULT_STEREO_FLAGS}


def rig_of(size: tuple[int, int], focal: float, angle: float, distance: float) -> StereoRig:
    """Two different distorting lenses (the right 3 % longer), ``angle`` apart, aimed at ``distance`` mm."""
    left = Lens(size, k1=-0.1, k2=0.02, p1=0.0004, p2=-0.0002, focal_px=focal)
    right = Lens(size, k1=-0.08, p1=-0.0003, p2=0.0002, focal_px=1.03 * focal)
    return StereoRig.symmetric(left, right, distance_mm=distance, angle_deg=angle)


def triangulated(rig: StereoRig, calibration: StereoCalibration, world: np.ndarray) -> np.ndarray:
    """Points ``world`` (mm, left camera frame) seen through the true rig, triangulated with ``calibration``."""
    seen = []
    for lens, R, T in ((rig.left, np.eye(3), np.zeros(3)), (rig.right, rig.rotation, rig.translation_mm)):
        image, _ = cv2.projectPoints(world, cv2.Rodrigues(R)[0], T, lens.camera_matrix, lens.dist_coeffs)
        seen.append(image.reshape(-1, 2))
    P_left, P_right = calibration.projection_matrices()
    found = cv2.triangulatePoints(P_left, P_right, undistort_points(calibration.left, seen[0]).T,
                                  undistort_points(calibration.right, seen[1]).T)
    return (found[:3] / found[3]).T


def measured_points(rig: StereoRig, calibration: StereoCalibration, count: int = 400) -> tuple[float, float]:
    """What a measurement sees of the calibration's errors, on a flat specimen facing the rig's bisector at its aim
    point (a third of the field across): (position RMS mm; false strain RMS in microstrain when the specimen moves
    rigidly 0.5 mm towards the cameras and turns 1 degree about its vertical axis, issue 24's benchmark motion).
    A uniform scale error leaves strain alone; what varies across the field and with depth does not."""
    aim = rig_aim_mm(rig)
    half = rig.left.size[0] * aim[2] / rig.left.camera_matrix[0, 0] / 6.0
    rng = np.random.default_rng(7)
    bisector = np.array([0.0, 0.0, 1.0]) + rig.rotation.T @ np.array([0.0, 0.0, 1.0])
    across = np.cross([0.0, 1.0, 0.0], bisector)
    across /= np.linalg.norm(across)
    plane = rng.uniform(-half, half, (count, 2))
    world = aim + plane[:, :1] * across + plane[:, 1:] * np.array([0.0, 1.0, 0.0])
    turn = cv2.Rodrigues(np.array([0.0, np.radians(1.0), 0.0]))[0]
    moved = (world - aim) @ turn.T + aim - 0.5 * bisector / np.linalg.norm(bisector)
    before, after = triangulated(rig, calibration, world), triangulated(rig, calibration, moved)
    i, j = np.triu_indices(count, 1)
    keep = np.linalg.norm(world[i] - world[j], axis=1) > half / 4
    strain = np.linalg.norm(after[i] - after[j], axis=1) / np.linalg.norm(before[i] - before[j], axis=1) - 1.0
    return (float(np.sqrt(np.mean(np.sum((before - world) ** 2, axis=1)))),
            float(np.sqrt(np.mean(strain[keep] ** 2)) * 1e6))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480")
    parser.add_argument("--focal", type=float, nargs="+", default=[640.0],
                        help="left focal length(s) (px): one rig each, e.g. 2000 4000 8000 12000")
    parser.add_argument("--lens", choices=("two", "simulator"), default="two",
                        help="two: two different distorting lenses (rig_of); simulator: the stereo source's lens "
                             "(k1 -0.05) in both cameras")
    parser.add_argument("--views", choices=("auto", "default", "narrow"), default="auto",
                        help="auto: stereo_view_plan (steeper tilts, a larger board under a 10 degree field)")
    parser.add_argument("--intrinsics", nargs="+", choices=tuple(CHOICES), default=["refined"])
    parser.add_argument("--centre-offset", type=float, nargs=2, default=(0.0, 0.0), metavar=("DX", "DY"),
                        help="the left lens's principal point this far (px) from the image's centre, the right's "
                             "as far the other way (the truth a fixed principal point then misses)")
    parser.add_argument("--angle", type=float, default=25.0)
    parser.add_argument("--distance", type=float, default=300.0)
    parser.add_argument("--target", default="chessboard:9x6")
    parser.add_argument("--fill", type=float, help="board width / left image width at the aim point (default: the "
                                                   "views' own)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--write", metavar="DIR", help="write the (first seed's) images to DIR/left, DIR/right")
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    for focal in args.focal:
        rig = (rig_of(size, focal, args.angle, args.distance) if args.lens == "two"  # type: ignore[arg-type]
               else simulator_rig(size, focal, args.angle, args.distance))  # type: ignore[arg-type]
        dx, dy = args.centre_offset
        rig = replace(rig, left=replace(rig.left, centre_offset_px=(dx, dy), _grid={}),
                      right=replace(rig.right, centre_offset_px=(-dx, -dy), _grid={}))
        views, fill = {"auto": stereo_view_plan(rig), "default": (STEREO_VIEWS, WIDE_FILL),
                       "narrow": (NARROW_STEREO_VIEWS, NARROW_STEREO_VIEW_FILL)}[args.views]
        measure(rig, args, views, args.fill or (WIDE_FILL if views is STEREO_VIEWS else fill))


def simulator_rig(size: tuple[int, int], focal: float, angle: float, distance: float) -> StereoRig:
    """The stereo source's rig (``synthetic:stereo``): one lens with k1 -0.05 in both cameras."""
    lens = Lens(size, k1=-0.05, focal_px=focal)
    return StereoRig.symmetric(lens, lens, distance_mm=distance, angle_deg=angle)


def measure(rig: StereoRig, args: argparse.Namespace, views: tuple, fill: float) -> None:
    """Render the views' pairs for each seed, calibrate, print the errors against the truth."""
    truth = rig.calibration()
    spec = parse_target(args.target)
    square = stereo_square_mm(spec, rig, fill)
    poses = stereo_calibration_views(spec, square, rig, views)
    focal = rig.left.camera_matrix[0, 0]
    field = np.degrees(2 * np.arctan(rig.left.size[0] / 2 / focal))
    print(f"rig {args.size}, f {focal:g}/{rig.right.camera_matrix[0, 0]:g} px ({field:.1f} degree field), "
          f"{args.angle:g} deg, baseline {truth.baseline_mm:.1f} mm; {len(poses)} pairs of {spec.text}, square "
          f"{square:.4g} mm ({fill:g} of the field), tilts up to {max(max(abs(v[0]), abs(v[1])) for v in views):g} deg")
    for seed in args.seeds:
        pairs = []
        for i, pose in enumerate(poses):
            images = render_target_pair(spec, square, rig, pose, seed=seed + i)
            if args.write and seed == args.seeds[0]:
                for side, image in zip(("left", "right"), images):
                    os.makedirs(os.path.join(args.write, side), exist_ok=True)
                    cv2.imwrite(os.path.join(args.write, side, f"view_{i:02d}.png"), image)
            found = [detect_target(image, spec, square) for image in images]
            pairs.append(TargetPair(f"left_{i}", f"right_{i}",
                                    *(f if isinstance(f, Detection) else None for f in found)))
        for name in args.intrinsics:
            try:
                fit = calibrate_stereo(pairs, rig.left.size, rig.right.size, spec=spec, square_mm=square,
                                       flags=CHOICES[name])
            except CalibrationRefused as refused:
                print(f"seed {seed} {name:8s} refused: {refused}")
                continue
            turn = fit.rotation @ truth.rotation.T
            angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))
            position, strain = measured_points(rig, fit)
            print(f"seed {seed} {name:8s} RMS {fit.rms_px:.3f} px  R {angle:.3f} deg  T "
                  f"{np.linalg.norm(fit.translation_mm - truth.translation_mm):.3f} mm  rig angle "
                  f"{fit.angle_deg:.3f} deg  points {position:.3f} mm RMS  rigid-motion strain {strain:.0f} "
                  "microstrain RMS", flush=True)
            for side in ("left", "right"):
                camera, true = getattr(fit, side), getattr(truth, side)
                K, dist = camera.camera_matrix, camera.dist_coeffs
                spread = ", ".join(f"{k} {v:.3g}" for k, v in camera.std_devs.items())
                print(f"    {side:5s} f {100 * (K[0, 0] / true.camera_matrix[0, 0] - 1):+.2f} % "
                      f"principal point ({K[0, 2]:.1f}, {K[1, 2]:.1f}) for ({true.camera_matrix[0, 2]:.1f}, "
                      f"{true.camera_matrix[1, 2]:.1f}), k1 {dist[0]:.4f} ({true.dist_coeffs[0]:g}), k2 {dist[1]:.3g} "
                      f"({true.dist_coeffs[1]:g}); fixed {', '.join(camera.fixed)}; std dev (own views) {spread}")


if __name__ == "__main__":
    main()
