"""Tracker: seeded frame-to-frame tracking against a reference (re-finding: test_refind)."""

import time

import numpy as np
import pytest

from livedic.dic.image_filter import Prefilter
from livedic.dic.status import Status
from livedic.dic.tracking.key_frames import KeyFrameTracker
from livedic.dic.tracking import TRACKER_STAGES, Tracker, grid_in_roi
from tests.dic.tracking.conftest import errors_to_truth, translate_frames


# --------------------------------------------------------------------------- tracking

@pytest.mark.parametrize("search, subpixel", [("improved-wso", "icgn"), ("none", "icgn"),
                                              ("improved-wso", "improved-surface-fit")])
def test_follows_a_translation_sequence(search, subpixel):
    source, frames = translate_frames("frames=16&size=160x160&du=0.35&dv=-0.2&noise=1")
    points = grid_in_roi(source.shape, source.suggested_roi, 16, 21)
    tracker = Tracker(frames[0].image, points, search=search, subpixel=subpixel)
    first = tracker.track(frames[0].image)
    assert first.ok.all() and np.allclose(first.u, 0, atol=0.005) and np.allclose(first.v, 0, atol=0.005)
    for frame in frames[1:]:
        m = tracker.track(frame.image)
        assert m.ok.all()
        assert np.max(errors_to_truth(frame, m)) < 0.05
    assert tracker.frames_tracked == len(frames)


def test_seeded_search_runs_only_for_doubtful_points_with_icgn():
    """IC-GN from the previous result for all; the seed box only where that is doubtful (an 8.5 px jump)."""
    source, frames = translate_frames("frames=7&size=224x224&du=0.2&dv=0.1&jump=4:8:-3&noise=1")
    points = grid_in_roi(source.shape, (56, 56, 112, 112), 16, 21)
    tracker = Tracker(frames[0].image, points, search="improved-wso", seed_radius=10, refind_radius=20)
    plain = Tracker(frames[0].image, points, search="none", seed_radius=10, refind_radius=20)
    surface = Tracker(frames[0].image, points, search="improved-wso", subpixel="improved-surface-fit", seed_radius=10)
    for k, frame in enumerate(frames):
        m = tracker.track(frame.image)
        assert m.ok.all() and np.max(errors_to_truth(frame, m)) < 0.05
        assert tracker.last_refind_attempts == 0          # the seed box was enough: no wide search
        if k == 4:
            assert tracker.last_seed_searches >= 0.5 * len(points)
        else:
            assert tracker.last_seed_searches == 0
            reference = plain.track(frame.image)
            assert np.array_equal(m.u, reference.u) and np.array_equal(m.v, reference.v)
        surface.track(frame.image)
        assert surface.last_seed_searches == len(points)  # surface fits need the integer peak every frame
        if k == 4:
            break


def _timed_track(tracker, image):
    started = time.perf_counter_ns()
    result = tracker.track(image)
    return result, time.perf_counter_ns() - started


@pytest.mark.parametrize("kind", [Tracker, KeyFrameTracker])
def test_stage_timings_are_every_stage_within_the_call(kind):
    """``last_timings``: every stage of TRACKER_STAGES, ns >= 0, together at most the call's wall time; the
    stages that ran are timed (the frame prepared, the kernel; the searches on the frame that jumps)."""
    source, frames = translate_frames("frames=7&size=224x224&du=0.2&dv=0.1&jump=4:14:-6&noise=1")
    points = grid_in_roi(source.shape, (56, 56, 112, 112), 16, 21)
    tracker = kind(frames[0].image, points, seed_radius=2, refind_radius=20)
    assert tuple(tracker.last_timings) == TRACKER_STAGES and not any(tracker.last_timings.values())
    for k, frame in enumerate(frames[:6]):
        m, wall = _timed_track(tracker, frame.image)
        timings = tracker.last_timings
        assert tuple(timings) == TRACKER_STAGES
        assert all(isinstance(ns, int) and ns >= 0 for ns in timings.values())
        assert sum(timings.values()) <= wall
        assert timings["prepare"] > 0 and timings["kernel"] > 0 and timings["gates"] > 0
        assert (timings["reference_update"] > 0) == (kind is KeyFrameTracker)
        if k == 4:                                   # the 15 px jump: searched, re-found
            assert tracker.last_refind_attempts > 0 and timings["seeded_search"] > 0 and timings["refind"] > 0
        assert m.ok.all()


def test_kernel_job_is_the_kernel_stage_on_the_same_points_and_start():
    """``kernel_job``: what the next ``track`` runs in its kernel stage; alone, it gives the tracker's own
    numbers where nothing after the kernel changed them (bit for bit)."""
    source, frames = translate_frames("frames=6&size=192x192&du=0.3&dv=-0.2&noise=1")
    points = grid_in_roi(source.shape, (40, 40, 112, 112), 14, 21)
    tracker = KeyFrameTracker(frames[0].image, points, reference_update="every:2")
    for frame in frames:
        job = tracker.kernel_job()
        bare = job.run(job.coefficients(frame.image))
        m = tracker.track(frame.image)
        assert m.ok.all() and job.points.size == len(points)
        if tracker.last_update is None and tracker.key_frame == 0:
            np.testing.assert_array_equal(bare.u, m.u)
            np.testing.assert_array_equal(bare.vy, m.vy)
    assert Tracker(frames[0].image, points, subpixel="improved-surface-fit").kernel_job() is None


@pytest.mark.parametrize("prefilter, interpolation", [("none", "bspline3"), ("gaussian:0.6", "bspline3"),
                                                       ("none", "bspline5")])
def test_coefficients_made_ahead_give_the_same_result_bit_for_bit(prefilter, interpolation, monkeypatch):
    """``track(image, ahead=coefficients_ahead(image))`` (the live session's prefilter in the acquisition thread,
    one frame ahead of the tracker) is ``track(image)``, bit for bit; coefficients made on a window the tracker
    has grown since are made again, not misread; a frame is pre-filtered once (ahead), not again in ``track``."""
    filtered_in_track = []
    apply = Prefilter.apply

    def counted(self, image):
        filtered_in_track.append(self.active)
        return apply(self, image)
    source, frames = translate_frames("frames=12&size=256x256&du=4&dv=-3&noise=0.5")
    points = grid_in_roi(source.shape, (100, 100, 56, 56), 14, 21)
    plain = KeyFrameTracker(frames[0].image, points, reference_update="every:4", prefilter=prefilter,
                            interpolation=interpolation)
    ahead = KeyFrameTracker(frames[0].image, points, reference_update="every:4", prefilter=prefilter,
                            interpolation=interpolation)
    made = ahead.coefficients_ahead(frames[1].image)
    assert made.coefficients.degree == int(interpolation[-1])
    stale = 0
    for i, frame in enumerate(frames[1:], 1):
        current = made
        if i + 1 < len(frames):        # the next frame's, made before this one is tracked (another buffer)
            made = ahead.coefficients_ahead(frames[i + 1].image, None if i == 1 else previous.coefficients)
        want = plain.track(frame.image)
        monkeypatch.setattr(Prefilter, "apply", counted)
        got = ahead.track(frame.image, ahead=current)
        monkeypatch.setattr(Prefilter, "apply", apply)
        for name in ("u", "v", "ux", "vy", "zncc", "status"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
        stale += current.window != ahead.window
        previous = current
    assert stale >= 1                   # the window grew at least once between a frame's coefficients and its track
    assert not any(filtered_in_track)   # no frame given with its coefficients was filtered again
    assert (made.filtered is not None) == (prefilter != "none")
    assert Tracker(frames[0].image, points, subpixel="improved-surface-fit").coefficients_ahead(frames[1].image) is None
    blank = np.full_like(frames[0].image, 100)           # no texture: no point to refine, no coefficients made
    assert Tracker(blank, points).coefficients_ahead(blank) is None


def test_points_without_texture_are_reported_never_searched():
    source, frames = translate_frames("frames=3&size=128x128&du=0.5&dv=0&noise=0")
    reference = frames[0].image.copy()
    reference[:, :40] = 100                        # a flat band (no speckle)
    moved = frames[1].image.copy()
    moved[:, :40] = 100
    tracker = Tracker(reference, [(20.0, 64.0), (80.0, 64.0), (3.0, 3.0)])
    assert tracker.trackable.tolist() == [False, True, False]
    m = tracker.track(moved)
    assert m.status[0] == Status.FLAT_REFERENCE and m.status[2] == Status.OUTSIDE_REFERENCE
    assert m.ok.tolist() == [False, True, False] and np.isnan(m.u[0])
    assert abs(m.u[1] - 0.5) < 0.05 and tracker.last_refind_attempts == 0


def test_icgn_window_grows_with_large_displacements():
    """IC-GN reads only a window of each frame; a displacement beyond its room re-prepares a bigger one."""
    source, frames = translate_frames("frames=12&size=256x256&du=4&dv=-3&noise=0.5")
    points = grid_in_roi(source.shape, (100, 100, 56, 56), 14, 21)
    tracker = Tracker(frames[0].image, points, seed_radius=3)
    start = tracker.window
    assert start[1] - start[0] < 256
    for frame in frames[1:]:
        m = tracker.track(frame.image)
        assert m.ok.all() and np.max(errors_to_truth(frame, m)) < 0.05
    grown = tracker.window
    assert (grown[1] - grown[0]) > (start[1] - start[0])


@pytest.mark.parametrize("subpixel", ["icgn", "icgn2"])
@pytest.mark.parametrize("roi", [(100, 100, 56, 56), (2, 150, 60, 60)], ids=["inside", "at the image edge"])
def test_a_grown_window_keeps_the_prepared_subsets_bit_for_bit(subpixel, roi, monkeypatch):
    """Growing the IC-GN window moves the prepared subsets instead of preparing them again: every array is the one
    a preparation on the grown window gives, for points well inside and for points at the image's edge."""
    import dataclasses

    from livedic.dic.subpixel.icgn import prepare_reference
    from livedic.dic.tracking import tracker as tracker_module
    source, frames = translate_frames("frames=2&size=256x256")
    points = grid_in_roi(source.shape, roi, 14, 21)
    tracker = Tracker(frames[0].image, points, subpixel=subpixel)
    before = tracker.window
    monkeypatch.setattr(tracker_module, "prepare_reference", None)      # not prepared again
    tracker._ensure_window(tracker._allowance + 10)
    y0, y1, x0, x1 = tracker.window
    assert (y1 - y0, x1 - x0) > (before[1] - before[0], before[3] - before[2])
    window = np.ascontiguousarray(tracker.reference[y0:y1, x0:x1])
    fresh = tracker.method.reference_data(prepare_reference(window, tracker._xs - x0, tracker._ys - y0, tracker.half),
                                          **tracker._reference_options)

    def arrays(data):
        return {f.name: getattr(data, f.name) for f in dataclasses.fields(data)}
    moved, expected = arrays(tracker._prep), arrays(fresh)
    if subpixel == "icgn2":
        moved.update(arrays(moved.pop("first")))
        expected.update(arrays(expected.pop("first")))
    for name, value in expected.items():
        assert np.array_equal(moved[name], value), name
        assert np.asarray(moved[name]).tobytes() == np.asarray(value).tobytes(), name


@pytest.mark.parametrize("kwargs, words", [
    ({"search": "bogus"}, "unknown search"), ({"subpixel": "bogus"}, "unknown sub-pixel"),
    ({"subset": 8}, "odd"), ({"seed_radius": -1}, "radius"), ({"refind_zncc": "high"}, "refind_zncc"),
    ({"refind_search": "none"}, "re-find search"), ({"refind_fallback": "bogus"}, "fallback"),
])
def test_bad_arguments_raise(kwargs, words):
    image = np.random.default_rng(0).uniform(0, 255, (64, 64))
    with pytest.raises(ValueError, match=words):
        Tracker(image, [(32, 32)], **kwargs)


def test_frame_of_another_size_raises():
    image = np.random.default_rng(0).uniform(0, 255, (64, 64))
    tracker = Tracker(image, [(32, 32)], search="none")
    with pytest.raises(ValueError, match="frames must keep the size"):
        tracker.track(image[:60])


# --------------------------------------------------------------------------- quality gates while tracking

def test_points_on_a_blank_background_are_never_ok_and_a_knock_is_not_trusted():
    """The specimen (speckle) moves; the blank background beside it does not. Points on the background
    are POOR_TEXTURE from the start; a point whose neighbours disagree after a sudden knock is
    re-found from them, and every ok point is right (within 0.05 px)."""
    from livedic.dic.speckle import SpecklePattern, render

    pattern = SpecklePattern((200, 240), n_speckles=700, radius=4.0, seed=6)
    rng = np.random.default_rng(2)

    def frame(u, v):
        image = 200.0 * render(pattern, (u, v), bit_depth=None)
        image[:, 170:] = 60.0 + rng.normal(0, 1.0, (200, 70))      # static blank background on the right
        return image

    axis_x, axis_y = np.arange(30, 221, 12.0), np.arange(30, 171, 12.0)
    points = np.column_stack([a.ravel() for a in np.meshgrid(axis_x, axis_y)])
    background = points[:, 0] > 190
    clear = points[:, 0] + 10 < 170 - 6                                 # subset clear of the edge, any motion
    tracker = Tracker(frame(0, 0), points, subpixel="icgn")
    assert np.all(tracker.track(frame(0, 0)).status[background] == Status.POOR_TEXTURE)
    motion = [(0.3 * k, -0.2 * k) for k in range(1, 6)] + [(4.5, 3.2), (4.8, 3.0)]    # a knock at frame 6
    for u, v in motion:
        m = tracker.track(frame(u, v))
        specimen = points[:, 0] + u < 150
        err = np.hypot(m.u - u, m.v - v)
        assert not m.ok[background].any()
        assert np.all(err[m.ok & clear] < 0.05), (u, v)
        assert m.ok[specimen].mean() > 0.95, (u, v)


def test_gates_reject_a_wrong_but_converged_point():
    """A point forced onto a wrong start (a side lobe) is flagged, not reported ok."""
    source, frames = translate_frames("frames=3&size=160x160&du=0.3&dv=-0.2&noise=1")
    points = grid_in_roi(source.shape, source.suggested_roi, 14, 21)
    tracker = Tracker(frames[0].image, points, search="none", subpixel="icgn", refind_fallback=None,
                      refind_radius=0)
    tracker.track(frames[1].image)
    tracker._prev["u"][5] += 7.0          # as if the previous frame had gone wrong for this point
    m = tracker.track(frames[2].image)
    err = errors_to_truth(frames[2], m)
    assert np.all(err[m.ok] < 0.05)


def test_zncc_stays_within_one_for_a_frame_tracked_against_itself():
    """The reference frame tracked against itself scored up to 1.0000002 (CSV showed 1.000000095): ZNCC is
    clipped to [-1, 1] where the measurement is assembled, and every point stays ok."""
    source, frames = translate_frames("frames=2&size=160x160&noise=1")
    points = grid_in_roi(source.shape, source.suggested_roi, 8, 21)
    first = Tracker(frames[0].image, points).track(frames[0].image)
    assert first.ok.all() and first.zncc.dtype == np.float64
    assert np.all(first.zncc <= 1.0) and np.all(first.zncc > 0.999)


@pytest.mark.parametrize("name, degree", [("bspline5", 5), ("bspline7", 7)])
def test_higher_degree_interpolation_tracks_and_refuses_methods_without_it(name, degree):
    """``interpolation="bspline5"`` or ``"bspline7"``: the kernel job and the window coefficients are of that
    degree (the septic's prefilter guard the widest), the sequence is followed; icgn2 and the surface fits
    refuse it in one line."""
    source, frames = translate_frames("frames=6&size=160x160&du=0.35&dv=-0.2&noise=0")
    points = grid_in_roi(source.shape, source.suggested_roi, 16, 21)
    tracker = Tracker(frames[0].image, points, interpolation=name)
    assert str(tracker.interpolation) == name
    for frame in frames[1:]:
        m = tracker.track(frame.image)
        assert m.ok.all() and np.max(errors_to_truth(frame, m)) < 0.05
    assert tracker.kernel_job().degree == degree
    for subpixel in ("icgn2", "improved-surface-fit"):
        with pytest.raises(ValueError, match=f"--interpolation {name} is not available"):
            Tracker(frames[0].image, points, subpixel=subpixel, interpolation=name)

