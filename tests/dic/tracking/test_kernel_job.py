"""Tests of dic/tracking/kernel_job.py: a frame window's B-spline coefficients, and one prepared IC-GN kernel run
(a ``KernelJob``) that measures a known motion on its own."""

import dataclasses

import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.status import Status
from livedic.dic.subpixel.icgn import prepare_target
from livedic.dic.tracking import KernelJob, Tracker, window_coefficients

PATTERN = SpecklePattern((128, 128), n_speckles=400, radius=3.0, seed=2)
POINTS = [(x, y) for x in range(44, 85, 20) for y in range(44, 85, 20)]
SHIFT = (0.35, -0.6)


@pytest.fixture(scope="module")
def job():
    """The kernel job of a tracker's first frame (from zero displacement) and that frame, moved by SHIFT."""
    tracker = Tracker(render(PATTERN), POINTS)
    return tracker.kernel_job(), render(PATTERN, SHIFT)


def test_window_coefficients_are_those_of_the_window_cut_out():
    image = render(PATTERN, (1.0, 2.0))
    window = (10, 90, 20, 110)
    got = window_coefficients(image, window)
    expected = prepare_target(image[10:90, 20:110])
    assert got.shape == (80, 90)
    np.testing.assert_array_equal(got.coefficients, expected.coefficients)


def test_an_earlier_frames_coefficients_are_overwritten_with_the_same_values():
    first, second = render(PATTERN), render(PATTERN, (0.5, 0.5))
    window = (0, 64, 0, 64)
    reused = window_coefficients(first, window)
    buffer = reused.flat
    again = window_coefficients(second, window, out=reused)
    assert again.flat is buffer
    np.testing.assert_array_equal(again.coefficients, window_coefficients(second, window).coefficients)


def test_a_job_run_on_its_own_measures_the_motion(job):
    job, frame = job
    assert isinstance(job, KernelJob) and job.points.size == len(POINTS)
    result = job.run(job.coefficients(frame))
    assert np.all(result.status == Status.OK)
    np.testing.assert_allclose(result.u, SHIFT[0], atol=0.02)
    np.testing.assert_allclose(result.v, SHIFT[1], atol=0.02)
    np.testing.assert_allclose(np.column_stack([result.ux, result.uy, result.vx, result.vy]), 0.0, atol=2e-3)


def test_a_job_is_frozen_and_runs_the_same_twice(job):
    job, frame = job
    with pytest.raises(dataclasses.FrozenInstanceError):
        job.u0 = np.zeros(3)
    a, b = job.run(job.coefficients(frame)), job.run(job.coefficients(frame))
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)
