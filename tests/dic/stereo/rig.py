"""A rendered stereo scene for the stereo tests: a speckled plane seen by a simulated 25 degree rig.

A planar surface is exactly a homography per view (board mm -> ideal px: ``pose_homography``), rendered pixel
by pixel through each lens (``render_through_lens``), so every truth here is exact: a point's board position,
its image in both views, its 3D position in the left camera's frame.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens, render_through_lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.targets import Pose, pose_homography, scene_on_plane
from livedic.dic.speckle import SpecklePattern

SIZE = (480, 360)
DISTANCE_MM = 300.0
FOCAL_PX = 2400.0          # 8 px/mm at 300 mm: a 60 x 45 mm field
PATTERN_PX_PER_MM = 8.0


def rig(angle_deg: float = 25.0) -> StereoRig:
    """Two lenses with different focal lengths and distortions, aimed at one point 300 mm away."""
    return StereoRig.symmetric(Lens(SIZE, k1=-0.05, focal_px=FOCAL_PX),
                               Lens(SIZE, k1=0.04, p2=5e-4, focal_px=0.98 * FOCAL_PX),
                               distance_mm=DISTANCE_MM, angle_deg=angle_deg)


def facing_pose(stereo: StereoRig, angle_deg: float = 25.0, tilt_deg: float = 0.0) -> Pose:
    """The plane at the aim point, its normal along the rig's bisector, tilted by ``tilt_deg`` about x."""
    rotation = cv2.Rodrigues(np.array([math.radians(tilt_deg), -math.radians(angle_deg / 2), 0.0]))[0]
    return Pose(cv2.Rodrigues(rotation)[0].ravel(), np.array([0.0, 0.0, DISTANCE_MM]))


def moved(pose: Pose, rotation_vector=(0.0, 0.0, 0.0), translation_mm=(0.0, 0.0, 0.0)) -> Pose:
    """The plane turned by ``rotation_vector`` about its own axes (at its centre), then shifted (camera frame)."""
    turn = cv2.Rodrigues(np.asarray(rotation_vector, dtype=np.float64))[0]
    R = cv2.Rodrigues(np.asarray(pose.rvec, dtype=np.float64))[0] @ turn
    return Pose(cv2.Rodrigues(R)[0].ravel(), np.asarray(pose.tvec, dtype=np.float64) + translation_mm)


def pattern() -> SpecklePattern:
    return SpecklePattern((600, 800), density=0.02, radius=2.5, seed=3)


def render(stereo: StereoRig, pose: Pose, speckle: SpecklePattern, motion=None) -> tuple[np.ndarray, np.ndarray]:
    """The left and right images of the plane at ``pose``; ``motion``: current board mm -> reference board mm."""
    images = []
    for lens, view_pose in ((stereo.left, pose), (stereo.right, stereo.right_pose(pose))):
        scene = scene_on_plane(pose_homography(lens, view_pose), (0.0, 0.0),
                               (speckle.shape[1] / 2, speckle.shape[0] / 2), PATTERN_PX_PER_MM, motion)
        images.append(render_through_lens(speckle, lens, scene))
    return images[0], images[1]


def board_of_left(stereo: StereoRig, pose: Pose, left_xy: np.ndarray) -> np.ndarray:
    """Board points (mm) the left image shows at ``left_xy`` (px)."""
    ideal = stereo.left.undistort(left_xy)
    h = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(pose_homography(stereo.left, pose)).T
    return h[:, :2] / h[:, 2:3]


def world(pose: Pose, board: np.ndarray) -> np.ndarray:
    """3D points (mm, left camera frame) of board points (N, 2) at ``pose``."""
    R = cv2.Rodrigues(np.asarray(pose.rvec, dtype=np.float64))[0]
    return np.column_stack([board, np.zeros(len(board))]) @ R.T + pose.tvec


def right_of_board(stereo: StereoRig, pose: Pose, board: np.ndarray) -> np.ndarray:
    """Right image positions (px) of board points."""
    H = pose_homography(stereo.right, stereo.right_pose(pose))
    h = np.column_stack([board, np.ones(len(board))]) @ H.T
    return stereo.right.distort(h[:, :2] / h[:, 2:3])


def grid(step: int = 20, margin: int = 40) -> np.ndarray:
    xs, ys = np.meshgrid(np.arange(margin, SIZE[0] - margin + 1, step), np.arange(margin, SIZE[1] - margin + 1, step))
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(np.float64)
