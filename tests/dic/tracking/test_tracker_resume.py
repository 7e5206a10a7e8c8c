"""``Tracker.resume``: a frame measured on its own, started from the earlier results, equals the frame tracked in
sequence (what ``livedic replay --workers`` relies on)."""

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.tracking import Tracker, last_good_after

POINTS = [(x, y) for x in range(40, 121, 20) for y in range(40, 121, 20)]


@pytest.fixture(scope="module")
def frames():
    pattern = SpecklePattern((160, 160), n_speckles=700, seed=3)
    return [render(pattern, (0.3 * k, -0.2 * k)) for k in range(8)]


def test_each_frame_resumed_on_its_own_equals_the_sequence_bit_for_bit(frames):
    sequence = Tracker(frames[0], POINTS)
    expected = [sequence.track(frame) for frame in frames]
    alone = Tracker(frames[0], POINTS)
    previous = last_good = None
    for k in reversed(range(len(frames))):         # any order: each frame carries its own start
        previous = expected[k - 1] if k else None
        last_good = None
        for result in expected[:k]:
            last_good = last_good_after(last_good, result)
        alone.resume(previous, last_good=last_good)
        m = alone.track(frames[k])
        for name in ("u", "v", "zncc", "ux", "uy", "vx", "vy"):
            assert np.array_equal(getattr(m, name), getattr(expected[k], name), equal_nan=True), (k, name)
        assert np.array_equal(m.ok, expected[k].ok) and np.array_equal(m.status, expected[k].status)


def test_resume_refuses_another_number_of_points(frames):
    tracker = Tracker(frames[0], POINTS)
    other = Tracker(frames[0], POINTS[:3]).track(frames[1])
    with pytest.raises(ValueError, match="3 points, the tracker 25"):
        tracker.resume(other)


def test_key_frame_tracker_resumed_per_frame_moves_and_measures_as_in_sequence(frames):
    """``KeyFrameTracker.resume`` on a copy of the tracker as the last move left it: each frame measured on its own
    moves the reference at the same frames (every 3) and gives the sequence's numbers bit for bit (the sequence
    starts each frame from its result mapped onto the key frame, as ``resume`` does)."""
    import copy

    from livedic.dic.tracking.key_frames import KeyFrameTracker
    sequence = KeyFrameTracker(frames[0], POINTS, reference_update="every:3")
    expected = [sequence.track(frame) for frame in frames]
    assert [update.frame for update in sequence.updates] == [2, 5]
    segment, start, moves = KeyFrameTracker(frames[0], POINTS, reference_update="every:3"), -1, []
    for k, frame in enumerate(frames):
        tracker = copy.deepcopy(segment)
        last_good = None
        for result in expected[start + 1:k]:
            last_good = last_good_after(last_good, result)
        tracker.resume(expected[k - 1] if k else None, last_good=last_good, frames_tracked=k,
                          frames_since_key=k - start - 1, frames_since_rebuild=k - start - 1)
        m = tracker.track(frame)
        assert np.array_equal(m.ok, expected[k].ok) and np.array_equal(m.status, expected[k].status)
        for name in ("u", "v", "zncc", "ux", "uy", "vx", "vy"):
            assert np.array_equal(getattr(m, name), getattr(expected[k], name), equal_nan=True), (k, name)
        if tracker.last_update is not None:
            moves.append(tracker.last_update.frame)
            segment, start = tracker, k
    assert moves == [2, 5]


def test_key_frame_state_changes_exactly_when_the_inner_tracker_is_rebuilt(frames):
    from livedic.dic.tracking.key_frames import KeyFrameTracker
    tracker = KeyFrameTracker(frames[0], POINTS, reference_update="every:3")
    changed = []
    for k, frame in enumerate(frames):
        before = tracker.state
        tracker.track(frame)
        changed.append(tracker.state is not before)
    assert [k for k, c in enumerate(changed) if c] == [2, 5]          # the moves
    before = tracker.state
    tracker.stop_tracking(np.arange(len(POINTS)) < 3)                # what a fracture (or its widening) does
    assert tracker.state is not before
