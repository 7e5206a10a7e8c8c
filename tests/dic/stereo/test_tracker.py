"""Tests of dic/stereo/tracker.py: a stereo pair tracked by two key-frame trackers and triangulated recovers a known
3D motion of a rendered plane over several frames; the left view's 2D fields are the left tracker's; unmatched
points are never ok; a pair without any match is refused in one line."""

import math

import cv2
import numpy as np
import pytest

from livedic.dic.result import Measurement
from livedic.dic.stereo import StereoStatus, match_stereo
from livedic.dic.stereo.tracker import StereoMeasurement, StereoTracker
from livedic.dic.tracking.key_frames import KeyFrameTracker
from tests.dic.stereo.rig import board_of_left, facing_pose, grid, moved, pattern, render, rig, world


def _tracker(reference, points):
    return KeyFrameTracker(reference, points)


@pytest.fixture(scope="module")
def scene():
    stereo = rig()
    pose = facing_pose(stereo)
    speckle = pattern()
    left, right = render(stereo, pose, speckle)
    points = grid(20, margin=60)
    return stereo, pose, speckle, left, right, match_stereo(stereo.calibration(), left, right, points)


def test_a_3d_motion_over_frames_is_tracked_in_both_views_and_triangulated(scene):
    """Three pairs: the plane moving towards the cameras (0.25 mm a frame) while it stretches along its x
    (0.2 % a frame) and turns about its y (0.3 degree a frame); U, V, W within 3 um RMS of the truth each frame,
    98 % of the points ok in 3D; the 2D fields are the left tracker's own."""
    stereo, pose, speckle, left, right, match = scene
    tracker = StereoTracker(stereo.calibration(), match, left, right, _tracker)
    assert tracker.right.x.size == int(np.sum(match.ok)) < tracker.left.x.size + 1
    normal = cv2.Rodrigues(pose.rvec)[0][:, 2]
    board = board_of_left(stereo, pose, match.left)
    for k in (1, 2, 3):
        stretch = 1.0 + 0.002 * k
        now = moved(pose, (0.0, math.radians(0.3 * k), 0.0), -0.25 * k * normal)
        left_now, right_now = render(stereo, now, speckle, motion=lambda X, Y, s=stretch: (X / s, Y))
        got = tracker.track(left_now, right_now)
        assert isinstance(got, StereoMeasurement) and isinstance(got, Measurement)
        assert np.mean(got.points.ok) > 0.98
        truth = world(now, board * [stretch, 1.0]) - world(pose, board)
        rmse = np.sqrt(np.nanmean((got.points.displacement - truth) ** 2, axis=0))
        assert np.all(rmse < 0.003), (k, rmse)
        assert np.all(got.points.ok <= (got.ok & got.right_ok))     # 3D ok needs both views ok
    assert tracker.frames_tracked == 3


def test_unmatched_points_are_never_ok_and_no_match_at_all_is_refused(scene):
    stereo, pose, speckle, left, right, match = scene
    # one point matched into an unrelated place: the right tracker does not track it, the 3D point is flagged
    forced = match.status.copy()
    forced[0] = StereoStatus.LOW_CORRELATION
    partial = type(match)(**{**match.__dict__, "status": forced})
    tracker = StereoTracker(stereo.calibration(), partial, left, right, _tracker)
    got = tracker.track(left, right)
    assert not got.right_ok[0] and np.isnan(got.right_xy[0]).all() and not got.points.ok[0]
    assert got.points.status[0] == StereoStatus.LOW_CORRELATION
    assert np.all(np.abs(got.points.displacement[got.points.ok]) < 1e-3)    # the reference pair again: no motion
    unrelated = np.ascontiguousarray(np.rot90(right, 2))
    nothing = match_stereo(stereo.calibration(), left, unrelated, match.left)
    with pytest.raises(ValueError, match="no point of the left view was matched"):
        StereoTracker(stereo.calibration(), nothing, left, unrelated, _tracker)


def test_key_frames_built_on_an_executor_give_the_same_3d_results(scene):
    """``build_on`` hands both views' key frames to the executor (as a live session's builder thread); every frame's
    3D result is bit for bit that of the pair building them in its own calls, over frames that move both references."""
    from concurrent.futures import ThreadPoolExecutor
    stereo, pose, speckle, left, right, match = scene

    def every_frame(reference, points):
        return KeyFrameTracker(reference, points, reference_update="every:1")
    normal = cv2.Rodrigues(pose.rvec)[0][:, 2]
    pairs = [render(stereo, moved(pose, (0.0, 0.0, 0.0), -0.2 * k * normal), speckle) for k in (1, 2, 3)]
    inline = StereoTracker(stereo.calibration(), match, left, right, every_frame)
    elsewhere = StereoTracker(stereo.calibration(), match, left, right, every_frame)
    with ThreadPoolExecutor(1) as executor:
        elsewhere.build_on(executor)
        assert elsewhere.left._executor is executor and elsewhere.right._executor is executor
        for pair in pairs:
            a, b = inline.track(*pair), elsewhere.track(*pair)
            assert elsewhere.last_update is not None and elsewhere.last_trackable.shape == a.ok.shape
            np.testing.assert_array_equal(a.points.displacement, b.points.displacement)
            np.testing.assert_array_equal(a.points.ok, b.points.ok)
        elsewhere.build_on(None)
