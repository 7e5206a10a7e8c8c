"""Incremental correlation with key frames (``dic.tracking.key_frames``): updates keep results Lagrangian.

Frames are rendered exactly by ``dic.speckle.render`` under growing homogeneous stretches, so the
displacement of every material point is known; the tolerances are stated per test (8-bit images,
no added noise: IC-GN's error is the rounding noise, ~0.005 px here).
"""

import numpy as np
import pytest

from livedic.dic.tracking.key_frames import KeyFrameTracker
from livedic.dic.speckle import SpecklePattern, affine, render
from livedic.dic.status import Status
from livedic.dic.tracking import Tracker

SHAPE = (192, 192)
CENTRE = (96.0, 96.0)
PATTERN = SpecklePattern(SHAPE, n_speckles=700, radius=3.0, seed=3)
POINTS = np.array([(x, y) for y in range(56, 137, 8) for x in range(56, 137, 8)], dtype=np.float64)


def stretch(strain):
    """Uniaxial stretch along y with Poisson contraction, about the image centre."""
    return affine(vy=strain, ux=-0.3 * strain, centre=CENTRE)


def exact(strain, points=POINTS):
    return -0.3 * strain * (points[:, 0] - CENTRE[0]), strain * (points[:, 1] - CENTRE[1])


@pytest.fixture(scope="module")
def frames():
    strains = np.linspace(0.0, 0.16, 17)          # 1 % per frame, to 16 %
    return strains, [render(PATTERN)] + [render(PATTERN, stretch(e)) for e in strains[1:]]


def run(tracker, images):
    return [tracker.track(image) for image in images]


def test_never_equals_the_plain_tracker_bit_for_bit(frames):
    _, images = frames
    plain = run(Tracker(images[0], POINTS), images[:6])
    keyed = run(KeyFrameTracker(images[0], POINTS, reference_update="never"), images[:6])
    for a, b in zip(plain, keyed):
        for name in ("u", "v", "zncc", "ok", "status", "ux", "vy"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_updates_compose_back_to_the_first_frame(frames):
    """every:3 to 16 % strain: u, v of the frame-0 points within 0.02 px of the exact displacement (up to
    6 px here) at every frame, gradients as accurate as one subset's (RMS < 1.5e-3 of the exact strain),
    and the updates recorded."""
    strains, images = frames
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="every:3")
    for strain, m in zip(strains, run(tracker, images)):
        tu, tv = exact(strain)
        assert m.ok.all()
        np.testing.assert_array_equal(m.x, POINTS[:, 0])          # always the first frame's points
        assert np.max(np.hypot(m.u - tu, m.v - tv)) < 0.02
        for error in (m.vy - strain, m.ux + 0.3 * strain):     # one subset's gradient: ~1e-3 noise
            assert np.sqrt(np.mean(error ** 2)) < 1.5e-3 and np.max(np.abs(error)) < 4e-3
    assert [u.frame for u in tracker.updates] == [2, 5, 8, 11, 14]
    assert all(u.carried == len(POINTS) and u.lost == 0 for u in tracker.updates)
    assert tracker.key_frame == 14


def test_auto_moves_the_reference_when_the_strain_since_it_grows(frames):
    strains, images = frames
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="auto")
    results = run(tracker, images)
    assert tracker.updates, "16 % strain: the first-order subsets need a nearer reference"
    assert all("strain since the key frame" in u.reason for u in tracker.updates)
    tu, tv = exact(strains[-1])
    assert np.max(np.hypot(results[-1].u - tu, results[-1].v - tv)) < 0.02


def _patched(image, half):
    """``image`` with the paint around the middle point replaced by paint from elsewhere (a flake)."""
    x, y = (int(v) for v in POINTS[len(POINTS) // 2])
    out = image.copy()
    out[y - half:y + half + 1, x - half:x + half + 1] = np.roll(image, (40, 40), axis=(0, 1))[
        y - half:y + half + 1, x - half:x + half + 1]
    return out


def test_an_occluded_key_frame_passes_on_no_error_and_its_points_come_back(frames):
    """every:2 forces a move onto a frame where paint from elsewhere covers the middle (a pasted patch):
    the plain tracker itself reports some points ok there up to several px off (subsets straddling the
    patch: the known limit of subsets across a discontinuity). Nothing of that may pass on: points not
    trusted in the key frame (failed, ZNCC < refind_zncc, or a failure within a subset's width) are left
    out (NOT_IN_KEY_FRAME, NaN) instead of carried, and re-measured from frame 0 at the next moves where
    nothing around them fails. From the next frame on every ok point is within 0.02 px of the truth,
    and by the third move every point is back."""
    strains, images = frames
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="every:2")
    sequence = [images[0], _patched(images[1], 10)] + images[2:7]
    for i, image in enumerate(sequence):
        m = tracker.track(image)
        if i == 1:
            first = tracker.last_update
            assert first.lost > 0 and first.carried + first.lost == len(POINTS)
        if i >= 2:
            tu, tv = exact(strains[i])
            assert np.max(np.hypot(m.u - tu, m.v - tv)[m.ok]) < 0.02, i
            assert np.all(np.isnan(m.u[m.status == Status.NOT_IN_KEY_FRAME]))
    assert len(tracker.updates) == 3 and tracker.updates[-1].lost == 0
    assert m.ok.all()


def test_stop_tracking_reports_separated_points(frames):
    _, images = frames
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="never")
    tracker.track(images[0])
    band = np.abs(POINTS[:, 1] - 96) < 5
    tracker.stop_tracking(band)
    m = tracker.track(images[1])
    assert np.all(m.status[band] == Status.SEPARATED) and not m.ok[band].any()
    assert np.all(np.isnan(m.u[band]))
    assert m.ok[~band].all() and not tracker.trackable[band].any()


class _HeldBuilds:
    """An executor whose builds run on its own thread only once ``release`` is set: shows what waits for them."""

    def __init__(self):
        import threading
        from concurrent.futures import ThreadPoolExecutor
        self.pool = ThreadPoolExecutor(1)
        self.release = threading.Event()
        self.release.set()                  # builds run at once until a test holds them back
        self.submitted = 0

    def submit(self, fn, *args, **kwargs):
        self.submitted += 1
        return self.pool.submit(self._held, fn, *args, **kwargs)

    def _held(self, fn, *args, **kwargs):
        self.release.wait()
        return fn(*args, **kwargs)


def _same(a, b):
    for name in ("u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_key_frames_built_on_an_executor_give_the_same_results_and_do_not_hold_the_move(frames):
    """The frame that moves the reference returns before the new key frame's tracker is built (its build is held
    back here), the next frame waits for it, and every result is bit for bit the one of a tracker that builds in
    its own call; a copy taken while a build is held holds the built tracker and goes on the same way."""
    import copy
    _, images = frames
    inline = run(KeyFrameTracker(images[0], POINTS, reference_update="every:3"), images[:9])
    builds = _HeldBuilds()
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="every:3")
    tracker.build_on(builds)
    results, copies = [], []
    for image in images[:9]:
        builds.release.clear()
        results.append(tracker.track(image))
        if tracker.last_update is not None:
            assert builds.submitted >= 1 and not tracker._slot.done()     # the move did not wait for its build
            assert tracker.last_trackable.all()
            assert tracker.coefficients_ahead(image) is None              # nor does a frame's acquisition
            builds.release.set()
            copies.append((len(results), copy.deepcopy(tracker)))
    assert len(copies) == 3
    for a, b in zip(inline, results):
        _same(a, b)
    at, copied = copies[0]
    for a, b in zip(inline[at:at + 3], run(copied, images[at:at + 3])):
        _same(a, b)
    tracker.build_on(None)
    builds.pool.shutdown()


def test_last_refound_and_trackable_belong_to_the_frame_just_tracked(frames):
    """After a reference move, ``last_refound``, ``last_refind_attempts`` and ``last_trackable`` still describe the
    frame just tracked (not the new key frame's tracker, which has tracked nothing yet)."""
    _, images = frames
    tracker = KeyFrameTracker(images[0], POINTS, reference_update="every:2")
    for image in images[:4]:
        m = tracker.track(image)
        if tracker.last_update is not None:
            break
    assert tracker.last_update is not None
    assert tracker.last_trackable.shape == m.ok.shape and tracker.last_trackable.all()
    assert tracker.last_refound.shape == m.ok.shape
    assert tracker.last_refind_attempts == int(tracker.last_refound.sum()) == 0
