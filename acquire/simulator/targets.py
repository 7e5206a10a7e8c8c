"""Calibration target images through the simulated lens: chessboard and ChArUco boards at known poses.

``render_target`` draws a board (a raster of ``RASTER_PX_PER_MM``) seen by the pinhole camera K at
pose (R, t), through the lens's distortion, ``SUPERSAMPLE`` x ``SUPERSAMPLE`` samples per pixel
averaged (an area-integrating sensor), then adds noise and rounds to 8 bits. ``calibration_views``
gives a set of tilted views that Zhang's method needs; ``plane_view`` the specimen plane's pose at a
known scale (px/mm), fronto-parallel or tilted, where a target laid on the specimen lies; ``scene_on_plane``
puts a speckle pattern on that plane for ``lens.render_through_lens`` (one pose for both: the truth of a
calibration's ``--plane``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens
from livedic.dic.calibration.targets import TargetSpec

RASTER_PX_PER_MM_SAMPLES = 4.0     # raster pixels per image sample at the board's nearest point
SUPERSAMPLE = 3
PAPER, INK, BACKDROP = 0.85, 0.08, 0.40    # grey levels (fraction of full scale)
# (tilt about x, tilt about y, roll about z) in degrees and the board centre's place in the image (fractions).
# Tilted views with the board reaching each corner and edge of the image, where distortion is largest and
# a calibration without views there would extrapolate.
DEFAULT_VIEWS = ((0.0, 0.0, 0.0, 0.5, 0.5), (25.0, 15.0, 5.0, 0.33, 0.33), (-25.0, 15.0, -5.0, 0.67, 0.33),
                 (25.0, -15.0, 10.0, 0.33, 0.67), (-25.0, -15.0, -10.0, 0.67, 0.67), (30.0, 0.0, 30.0, 0.5, 0.36),
                 (-30.0, 0.0, -25.0, 0.5, 0.64), (0.0, 30.0, 15.0, 0.36, 0.5), (0.0, -30.0, -35.0, 0.64, 0.5))
# The board's width in the image as a fraction of the image's width, for the calibration views.
VIEW_FILL = 0.55


@dataclass(frozen=True)
class Pose:
    """Board -> camera: rotation vector (rad) and translation (mm), as OpenCV's rvec, tvec."""

    rvec: np.ndarray
    tvec: np.ndarray


def board_extent(spec: TargetSpec, square_mm: float) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) of the printed board in the target's coordinates (mm), one square of white around.

    The coordinates are those of ``TargetSpec.object_points``: a chessboard's first inner corner is at the
    origin, a ChArUco board's outer corner (OpenCV's convention).
    """
    cols, rows = spec.inner_corners
    shift = square_mm if spec.kind == "charuco" else 0.0
    return (-2.0 * square_mm + shift, -2.0 * square_mm + shift, (cols + 1) * square_mm + shift,
            (rows + 1) * square_mm + shift)


def pose_looking_at(spec: TargetSpec, square_mm: float, lens: Lens, angles_deg: tuple[float, float, float],
                    centre_frac: tuple[float, float], px_per_mm: float) -> Pose:
    """The pose putting the board's centre at ``centre_frac`` of the image, rotated by ``angles_deg``
    (about x, y, z), at the distance where the untilted board shows ``px_per_mm`` ideal px per mm."""
    centre = spec.object_points(square_mm).mean(axis=0)
    rx, ry, rz = (math.radians(a) for a in angles_deg)
    R = (cv2.Rodrigues(np.array([rx, 0.0, 0.0]))[0] @ cv2.Rodrigues(np.array([0.0, ry, 0.0]))[0]
         @ cv2.Rodrigues(np.array([0.0, 0.0, rz]))[0])
    K = lens.camera_matrix
    width, height = lens.size
    u, v = centre_frac[0] * (width - 1), centre_frac[1] * (height - 1)
    distance = K[0, 0] / px_per_mm
    ray = np.array([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], 1.0])
    tvec = distance * ray - R @ centre
    return Pose(cv2.Rodrigues(R)[0].ravel(), tvec)


def calibration_views(spec: TargetSpec, square_mm: float, lens: Lens) -> list[Pose]:
    """Poses of ``DEFAULT_VIEWS``: the board filling ``VIEW_FILL`` of the image's width, tilted and rolled."""
    x0, _, x1, _ = board_extent(spec, square_mm)
    px_per_mm = VIEW_FILL * lens.size[0] / (x1 - x0)
    return [pose_looking_at(spec, square_mm, lens, view[:3], view[3:], px_per_mm) for view in DEFAULT_VIEWS]


def plane_view(spec: TargetSpec, square_mm: float, lens: Lens, px_per_mm: float, tilt_deg: float = 0.0) -> Pose:
    """The board lying on the specimen plane, centred, at ``px_per_mm`` (untilted): fronto-parallel, or tilted by
    ``tilt_deg`` about the image's x axis (lengths along y foreshortened, the scale varying along y)."""
    return pose_looking_at(spec, square_mm, lens, (tilt_deg, 0.0, 0.0), (0.5, 0.5), px_per_mm)


def pose_homography(lens: Lens, pose: Pose) -> np.ndarray:
    """Board (mm) -> ideal px of the board at ``pose``: K [r1 r2 t]."""
    R = cv2.Rodrigues(np.asarray(pose.rvec, dtype=np.float64))[0]
    return lens.camera_matrix @ np.column_stack([R[:, 0], R[:, 1], np.asarray(pose.tvec, dtype=np.float64)])


def scene_on_plane(homography: np.ndarray, centre_mm: tuple[float, float], pattern_centre: tuple[float, float],
                   pattern_px_per_mm: float, motion: Callable[[np.ndarray, np.ndarray], tuple] | None = None
                   ) -> Callable[[np.ndarray, np.ndarray], tuple]:
    """``scene_of`` for ``render_through_lens``: a speckle pattern printed on the plane of ``homography``
    (board mm -> ideal px), ``pattern_px_per_mm`` of its px a mm, its point ``pattern_centre`` at the board's
    ``centre_mm``; ``motion(X, Y)``: where the material now at board point (X, Y) mm was in the reference."""
    inverse = np.linalg.inv(homography)

    def scene_of(x: np.ndarray, y: np.ndarray) -> tuple:
        w = inverse[2, 0] * x + inverse[2, 1] * y + inverse[2, 2]
        X = (inverse[0, 0] * x + inverse[0, 1] * y + inverse[0, 2]) / w
        Y = (inverse[1, 0] * x + inverse[1, 1] * y + inverse[1, 2]) / w
        if motion is not None:
            X, Y = motion(X, Y)
        return (pattern_centre[0] + (X - centre_mm[0]) * pattern_px_per_mm,
                pattern_centre[1] + (Y - centre_mm[1]) * pattern_px_per_mm)
    return scene_of


def board_raster(spec: TargetSpec, square_mm: float, px_per_mm: float) -> np.ndarray:
    """The printed board (float32, PAPER / INK) covering ``board_extent`` at ``px_per_mm``."""
    x0, y0, x1, y1 = board_extent(spec, square_mm)
    width, height = int(round((x1 - x0) * px_per_mm)), int(round((y1 - y0) * px_per_mm))
    if spec.kind == "charuco":
        margin = int(round(square_mm * px_per_mm))
        image = spec.charuco_board(square_mm).generateImage((width, height), marginSize=margin, borderBits=1)
        return np.where(image > 127, PAPER, INK).astype(np.float32)
    # Chessboard: squares of alternating colour; the first inner corner at the board coordinates' origin.
    bx = (np.arange(width) + 0.5) / px_per_mm + x0
    by = (np.arange(height) + 0.5) / px_per_mm + y0
    col = np.floor(bx / square_mm).astype(int)
    row = np.floor(by / square_mm).astype(int)
    cols, rows = spec.inner_corners
    inside_x = (col >= -1) & (col <= cols - 1)
    inside_y = (row >= -1) & (row <= rows - 1)
    dark = ((col[None, :] + row[:, None]) % 2 == 0) & inside_x[None, :] & inside_y[:, None]
    return np.where(dark, INK, PAPER).astype(np.float32)


def render_target(spec: TargetSpec, square_mm: float, lens: Lens, pose: Pose, *, noise: float = 1.0,
                  seed: int = 0) -> np.ndarray:
    """An 8-bit image of the board at ``pose`` through ``lens`` (``noise``: SD in grey levels)."""
    H = pose_homography(lens, pose)
    ideal = lens.ideal_pixels(SUPERSAMPLE)
    board = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), np.linalg.inv(H)).reshape(ideal.shape)
    x0, y0, _, _ = board_extent(spec, square_mm)
    # Raster fine enough for the nearest point of the board (the largest scale), as the sensor samples it.
    scale = float(np.max(np.abs(np.linalg.svd(H[:2, :2] / H[2, 2], compute_uv=False))))
    px_per_mm = RASTER_PX_PER_MM_SAMPLES * SUPERSAMPLE * max(scale, 1.0)
    raster = board_raster(spec, square_mm, px_per_mm)
    map_x = ((board[..., 0] - x0) * px_per_mm - 0.5).astype(np.float32)
    map_y = ((board[..., 1] - y0) * px_per_mm - 0.5).astype(np.float32)
    samples = cv2.remap(raster, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=BACKDROP)
    width, height = lens.size
    image = samples.reshape(height, SUPERSAMPLE, width, SUPERSAMPLE).mean(axis=(1, 3)) * 255.0
    image += np.random.default_rng(seed).normal(0.0, noise, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
