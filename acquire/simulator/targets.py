"""Calibration target images through the simulated lens: chessboard and ChArUco boards at known poses.

``render_target`` draws a board (a raster of ``RASTER_PX_PER_MM``) seen by the pinhole camera K at
pose (R, t), through the lens's distortion, ``SUPERSAMPLE`` x ``SUPERSAMPLE`` samples per pixel
averaged (an area-integrating sensor), then adds noise and rounds to 8 bits. ``calibration_views``
gives a set of tilted views that Zhang's method needs; ``plane_view`` the specimen plane's pose at a
known scale (px/mm), fronto-parallel or tilted, where a target laid on the specimen lies; ``scene_on_plane``
puts a speckle pattern on that plane for ``lens.render_through_lens`` (one pose for both: the truth of a
calibration's ``--plane``). For a ``StereoRig``: ``stereo_calibration_views`` gives tilted poses around the point
both cameras aim at, each seen whole by both (``stereo_square_mm``: a board that fits; ``stereo_view_plan``: steeper
tilts and a larger board for a long lens), and ``render_target_pair`` renders one pose in both cameras (the truth of a
stereo calibration).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

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
# Stereo views: (tilt about x, tilt about y, roll about z) in degrees, the board turned from facing the bisector of
# the two cameras' axes, and the direction (x, y) in which its centre is moved from the point both cameras aim at:
# as far as the board stays whole in both images, so the views reach the images' corners and edges, where the
# distortion is largest. Tilts of 20-25 degrees on top of half the rig's angle keep both views within the ~45
# degrees a corner detector resolves.
STEREO_VIEWS = ((0.0, 0.0, 0.0, 0.0, 0.0), (25.0, 0.0, 10.0, -1.0, -1.0), (-25.0, 0.0, -10.0, 1.0, -1.0),
                (0.0, 25.0, 5.0, -1.0, 1.0), (0.0, -25.0, -5.0, 1.0, 1.0), (20.0, 20.0, 30.0, 0.0, -1.0),
                (-20.0, -20.0, -30.0, 0.0, 1.0), (20.0, -20.0, 20.0, -1.0, 0.0), (-20.0, 20.0, -20.0, 1.0, 0.0),
                (-20.0, 0.0, 0.0, -1.0, -1.0), (20.0, 0.0, 0.0, 1.0, 1.0), (0.0, 20.0, 0.0, 1.0, -1.0),
                (0.0, -20.0, 0.0, -1.0, 1.0))
# The board's width as a fraction of the left image's width at the aim point (``stereo_square_mm``): smaller than
# VIEW_FILL, as the board must stay whole in both views, tilted and moved.
STEREO_VIEW_FILL = 0.35
# A long lens (a horizontal field under NARROW_FIELD_DEG: a 50 mm lens on a 1 MP camera sees ~7 degrees) sees little
# perspective, so its focal length needs steeper tilts: those of STEREO_VIEWS x 1.5 (30-37.5 degrees, and half the
# rig's angle more to one camera), and a board half the field wide, as a lab would print for a 40 mm field
# (measured on the simulator's f 8000 px rig: the focal length's standard deviation 0.19 % against 0.46 % with
# STEREO_VIEWS at 0.35; T 0.30 mm against 0.47 mm, docs/guide/calibration.md). A 15 degree field (f 4000 px) keeps
# STEREO_VIEWS: there they locate the principal point better (R 0.02 against 0.1 deg).
NARROW_FIELD_DEG = 10.0
NARROW_STEREO_VIEWS = tuple((1.5 * tx, 1.5 * ty, rz, dx, dy) for tx, ty, rz, dx, dy in STEREO_VIEWS)
NARROW_STEREO_VIEW_FILL = 0.5
# The offsets tried, as fractions of the field of view at the aim point, largest first.
_STEREO_OFFSETS = np.linspace(0.5, 0.0, 26)


@dataclass(frozen=True)
class Pose:
    """Board -> camera: rotation vector (rad) and translation (mm), as OpenCV's rvec, tvec."""

    rvec: np.ndarray
    tvec: np.ndarray


class StereoRig(Protocol):
    """What the stereo views need of ``stereo_rig.StereoRig`` (which imports ``Pose`` from here)."""

    @property
    def left(self) -> Lens: ...
    @property
    def right(self) -> Lens: ...
    @property
    def rotation(self) -> np.ndarray: ...
    @property
    def translation_mm(self) -> np.ndarray: ...
    def right_pose(self, pose: Pose) -> Pose: ...


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
    # A whole number of raster pixels per square: the board is drawn exactly, and OpenCV's ChArUco drawing (which
    # fails on some sizes otherwise: 473 x 379 px with a margin of 47) has no rounding to do.
    px_per_mm = math.ceil(RASTER_PX_PER_MM_SAMPLES * SUPERSAMPLE * max(scale, 1.0) * square_mm) / square_mm
    raster = board_raster(spec, square_mm, px_per_mm)
    map_x = ((board[..., 0] - x0) * px_per_mm - 0.5).astype(np.float32)
    map_y = ((board[..., 1] - y0) * px_per_mm - 0.5).astype(np.float32)
    samples = cv2.remap(raster, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                        borderValue=BACKDROP)
    width, height = lens.size
    image = samples.reshape(height, SUPERSAMPLE, width, SUPERSAMPLE).mean(axis=(1, 3)) * 255.0
    image += np.random.default_rng(seed).normal(0.0, noise, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def rig_aim_mm(rig: StereoRig) -> np.ndarray:
    """The point (mm, left camera frame) nearest both cameras' optical axes: where a convergent rig looks.

    Raises
    ------
    ValueError
        The axes are (nearly) parallel: such a rig has no point it aims at.
    """
    centre_right = -rig.rotation.T @ rig.translation_mm
    axis_left, axis_right = np.array([0.0, 0.0, 1.0]), rig.rotation.T @ np.array([0.0, 0.0, 1.0])
    # closest points of the two lines s * axis_left and centre_right + t * axis_right
    a = np.column_stack([axis_left, -axis_right])
    if np.linalg.norm(np.cross(axis_left, axis_right)) < math.sin(math.radians(1.0)):
        raise ValueError("the rig's optical axes are parallel: its cameras aim at no common point")
    s, t = np.linalg.lstsq(a, centre_right, rcond=None)[0]
    return (s * axis_left + centre_right + t * axis_right) / 2.0


def stereo_square_mm(spec: TargetSpec, rig: StereoRig, fill: float = STEREO_VIEW_FILL) -> float:
    """The square side (mm) of a board ``spec`` spanning ``fill`` of the left image's width at the rig's aim point
    (a lab chooses its target to match the field of view in the same way)."""
    x0, _, x1, _ = board_extent(spec, 1.0)
    field_mm = rig.left.size[0] * float(rig_aim_mm(rig)[2]) / rig.left.camera_matrix[0, 0]
    return fill * field_mm / (x1 - x0)


def stereo_view_plan(rig: StereoRig) -> tuple[tuple[tuple[float, float, float, float, float], ...], float]:
    """(views, board fill) suiting the rig's lenses: ``NARROW_STEREO_VIEWS`` and ``NARROW_STEREO_VIEW_FILL`` when the
    left camera's horizontal field is under ``NARROW_FIELD_DEG``, else ``STEREO_VIEWS`` and ``STEREO_VIEW_FILL``."""
    field_deg = math.degrees(2.0 * math.atan(rig.left.size[0] / 2.0 / rig.left.camera_matrix[0, 0]))
    if field_deg < NARROW_FIELD_DEG:
        return NARROW_STEREO_VIEWS, NARROW_STEREO_VIEW_FILL
    return STEREO_VIEWS, STEREO_VIEW_FILL


def stereo_calibration_views(spec: TargetSpec, square_mm: float, rig: StereoRig,
                             views: tuple[tuple[float, float, float, float, float], ...] = STEREO_VIEWS) -> list[Pose]:
    """Board -> left camera poses of ``views`` (``STEREO_VIEWS``; ``NARROW_STEREO_VIEWS`` for a long lens) around
    the rig's aim point (``rig_aim_mm``), each board moved in its direction as far as it stays whole in both images
    (to 0.02 of the field of view).

    Raises
    ------
    ValueError
        A view's board is not whole in both images (a board too large for the field: see ``stereo_square_mm``).
    """
    aim = rig_aim_mm(rig)
    bisector = np.array([0.0, 0.0, 1.0]) + rig.rotation.T @ np.array([0.0, 0.0, 1.0])
    bisector /= np.linalg.norm(bisector)
    # the board's normal turned from the left camera's axis onto the bisector, about their common perpendicular
    turn = np.cross([0.0, 0.0, 1.0], bisector)
    size = float(np.linalg.norm(turn))
    facing = cv2.Rodrigues(turn / max(size, 1e-12) * math.atan2(size, float(bisector[2])))[0]
    field = np.array(rig.left.size, dtype=np.float64) * aim[2] / rig.left.camera_matrix[0, 0]
    centre = spec.object_points(square_mm).mean(axis=0)
    poses = []
    for index, (tx, ty, rz, dx, dy) in enumerate(views):
        R = (facing @ cv2.Rodrigues(np.array([math.radians(tx), 0.0, 0.0]))[0]
             @ cv2.Rodrigues(np.array([0.0, math.radians(ty), 0.0]))[0]
             @ cv2.Rodrigues(np.array([0.0, 0.0, math.radians(rz)]))[0])
        for offset in _STEREO_OFFSETS:
            middle = aim + offset * (facing[:, 0] * dx * field[0] + facing[:, 1] * dy * field[1])
            pose = Pose(cv2.Rodrigues(R)[0].ravel(), middle - R @ centre)
            if (board_in_view(spec, square_mm, rig.left, pose)
                    and board_in_view(spec, square_mm, rig.right, rig.right_pose(pose))):
                break
        else:
            raise ValueError(f"stereo view {index}: the board of {square_mm:g} mm squares is not whole in both "
                             f"cameras: use smaller squares (stereo_square_mm: {stereo_square_mm(spec, rig):.3g} mm)")
        poses.append(pose)
    return poses


def board_in_view(spec: TargetSpec, square_mm: float, lens: Lens, pose: Pose, margin_px: float = 4.0) -> bool:
    """Whether the whole printed board (``board_extent``) lies in front of the camera and ``margin_px`` inside its
    image (its outline sampled along each edge, through the lens)."""
    x0, y0, x1, y1 = board_extent(spec, square_mm)
    steps = np.linspace(0.0, 1.0, 21)
    outline = np.concatenate([np.c_[x0 + (x1 - x0) * steps, np.full(21, y0)],
                              np.c_[x0 + (x1 - x0) * steps, np.full(21, y1)],
                              np.c_[np.full(21, x0), y0 + (y1 - y0) * steps],
                              np.c_[np.full(21, x1), y0 + (y1 - y0) * steps]])
    R = cv2.Rodrigues(np.asarray(pose.rvec, dtype=np.float64))[0]
    camera = np.c_[outline, np.zeros(len(outline))] @ R.T + np.asarray(pose.tvec, dtype=np.float64)
    if np.any(camera[:, 2] <= 0.0):
        return False
    seen = lens.distort((camera[:, :2] / camera[:, 2:]) @ lens.camera_matrix[:2, :2].T + lens.camera_matrix[:2, 2])
    width, height = lens.size
    return bool(np.all((seen >= margin_px) & (seen <= np.array([width - 1 - margin_px, height - 1 - margin_px]))))


def render_target_pair(spec: TargetSpec, square_mm: float, rig: StereoRig, pose: Pose, *, noise: float = 1.0,
                       seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The board at ``pose`` (board -> left camera) as the rig's left and right cameras see it (8 bit each, with
    independent noise)."""
    return (render_target(spec, square_mm, rig.left, pose, noise=noise, seed=2 * seed),
            render_target(spec, square_mm, rig.right, rig.right_pose(pose), noise=noise, seed=2 * seed + 1))
