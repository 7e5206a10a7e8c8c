#!/usr/bin/env python3
"""A stereo calibration's accuracy on target pairs rendered through a known rig, with the cameras' intrinsics fixed
at each camera's own fit or refined with R and T (the choice of ``dic.calibration.DEFAULT_STEREO_FLAGS``).

For each noise seed: renders ``STEREO_VIEWS`` pairs (``acquire.simulator.targets``), calibrates both ways, and
prints the errors against the truth: R (deg), T (mm), focal lengths (%), and what a measurement sees: points of a
flat specimen at the aim point projected through the true rig and triangulated with the calibration, their
position error (mm RMS) and the false strain when it moves rigidly (0.5 mm, 1 degree; microstrain RMS). ``--write DIR`` also writes
the images (DIR/left, DIR/right) for ``livedic calibrate --left DIR/left --right DIR/right``:

    .venv/bin/python scripts/stereo_calibration_accuracy.py [--size 640x480] [--focal 640] [--angle 25]
        [--target chessboard:9x6] [--fill 0.45] [--seeds 0 100 200] [--write DIR]
"""

from __future__ import annotations

import argparse
import os

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.targets import (rig_aim_mm, render_target_pair, stereo_calibration_views,
                                               stereo_square_mm)
from livedic.dic.calibration import (DEFAULT_STEREO_FLAGS, Detection, StereoCalibration, TargetPair,
                                     calibrate_stereo, detect_target, parse_target, undistort_points)

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
    parser.add_argument("--focal", type=float, default=640.0, help="left focal length (px)")
    parser.add_argument("--angle", type=float, default=25.0)
    parser.add_argument("--distance", type=float, default=300.0)
    parser.add_argument("--target", default="chessboard:9x6")
    parser.add_argument("--fill", type=float, default=0.45, help="board width / left image width at the aim point")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--write", metavar="DIR", help="write the (first seed's) images to DIR/left, DIR/right")
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    rig = rig_of(size, args.focal, args.angle, args.distance)  # type: ignore[arg-type]
    truth = rig.calibration()
    spec = parse_target(args.target)
    square = stereo_square_mm(spec, rig, args.fill)
    poses = stereo_calibration_views(spec, square, rig)
    print(f"rig {args.size}, f {args.focal:g}/{1.03 * args.focal:g} px, {args.angle:g} deg, baseline "
          f"{truth.baseline_mm:.1f} mm; {len(poses)} pairs of {spec.text}, square {square:.4g} mm")
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
        for name, flags in CHOICES.items():
            fit = calibrate_stereo(pairs, rig.left.size, rig.right.size, spec=spec, square_mm=square, flags=flags)
            turn = fit.rotation @ truth.rotation.T
            angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))
            focal = [100 * (getattr(fit, s).camera_matrix[0, 0] / getattr(truth, s).camera_matrix[0, 0] - 1)
                     for s in ("left", "right")]
            position, strain = measured_points(rig, fit)
            print(f"seed {seed} {name:8s} RMS {fit.rms_px:.3f} px  R {angle:.3f} deg  T "
                  f"{np.linalg.norm(fit.translation_mm - truth.translation_mm):.3f} mm  f {focal[0]:+.2f}/"
                  f"{focal[1]:+.2f} %  points {position:.3f} mm RMS  rigid-motion strain {strain:.0f} microstrain RMS", flush=True)


if __name__ == "__main__":
    main()
