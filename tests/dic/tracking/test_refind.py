"""Tests of dic/tracking/refind.py: weak points found again after a jump, points whose material left the view
not searched for, and the back-off of points that stay lost."""

import numpy as np

from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.status import Status
from livedic.dic.tracking import Tracker, grid_in_roi
from tests.dic.tracking.conftest import errors_to_truth, translate_frames

PATTERN = SpecklePattern((160, 160), n_speckles=900, radius=3.0, seed=4)


def test_refinds_points_after_a_jump():
    """A 14 px jump is far beyond the 2 px seed box: the wide search must bring the points back."""
    source, frames = translate_frames("frames=14&size=224x224&du=0.2&dv=0.1&jump=10:14:-6&noise=1")
    points = grid_in_roi(source.shape, (56, 56, 112, 112), 16, 21)
    tracker = Tracker(frames[0].image, points, seed_radius=2, refind_radius=20)
    for frame in frames[:10]:
        tracker.track(frame.image)
        assert tracker.last_refind_attempts <= 2
    m = tracker.track(frames[10].image)
    assert tracker.last_refound.sum() >= 0.8 * len(points)
    assert m.ok.all() and np.max(errors_to_truth(frames[10], m)) < 0.05
    for frame in frames[11:]:
        m = tracker.track(frame.image)
        assert m.ok.all() and np.max(errors_to_truth(frame, m)) < 0.05
        assert tracker.last_refind_attempts == 0      # back to cheap seeded tracking


def test_points_whose_material_left_the_view_are_not_searched_for():
    """The left column moves out of the image: OUTSIDE_TARGET, and no wide search that could only find
    something else."""
    points = [(x, y) for y in (44, 80, 116) for x in (20, 80, 116)]
    tracker = Tracker(render(PATTERN), points)
    left = np.array([x == 20 for x, _ in points])
    for k in range(1, 7):
        m = tracker.track(render(PATTERN, (-2.0 * k, 0.3 * k)))
        assert tracker.last_refind_attempts == 0
        assert m.ok[~left].all() and np.allclose(m.u[~left], -2.0 * k, atol=0.02)
    assert np.all(m.status[left] == Status.OUTSIDE_TARGET) and np.isnan(m.u[left]).all()


def test_a_point_that_stays_lost_is_retried_after_1_2_4_frames_and_comes_back():
    """The centre point's subset is blanked for 11 frames: its wide search runs at frames 1, 3, 6 and 11
    (waits of 1, 2 and 4 frames), and it is measured again once its texture is back."""
    points = [(x, y) for y in (44, 80, 116) for x in (44, 80, 116)]
    tracker = Tracker(render(PATTERN), points)
    attempts = []
    for k in range(1, 15):
        frame = render(PATTERN, (0.1 * k, 0.05 * k))
        if k <= 11:
            frame[69:92, 69:92] = 120
        m = tracker.track(frame)
        attempts.append(tracker.last_refind_attempts)
        others = np.arange(9) != 4
        assert m.ok[others].all()
        assert m.ok[4] == (k > 11)
    assert [k + 1 for k, n in enumerate(attempts) if n] == [1, 3, 6, 11]
    assert abs(m.u[4] - 1.4) < 0.02 and abs(m.v[4] - 0.7) < 0.02
