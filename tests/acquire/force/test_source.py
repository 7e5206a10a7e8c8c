"""Tests of acquire/force/source.py: force interpolated between samples, frame times on two clocks, the base class."""

import math

import numpy as np
import pytest

from livedic.acquire.force.source import (TIME_BASE_MONOTONIC, TIME_BASE_SESSION, LoadError, LoadEventKind,
                                          LoadSource, LoadWarnings, interpolate_force)
from tests.acquire.force.loads import free_port, loading, write_csv


# --- interpolation -----------------------------------------------------------------------------

def test_interpolation_is_exact_on_linear_force_and_never_extrapolates():
    t = np.array([0.0, 0.1, 0.25, 0.4])
    f = 3.0 + 250.0 * t
    times = np.array([-0.01, 0.0, 0.05, 0.1, 0.17, 0.33, 0.4, 0.4000001, 1.0])
    got = interpolate_force(t, f, times, max_gap_s=1.0)
    inside = (times >= 0.0) & (times <= 0.4)
    np.testing.assert_allclose(got[inside], 3.0 + 250.0 * times[inside], rtol=0, atol=1e-9)
    assert np.isnan(got[~inside]).all()


def test_interpolation_gives_nan_across_a_gap_wider_than_max_gap():
    t = np.array([0.0, 0.1, 0.9, 1.0])
    f = np.array([0.0, 1.0, 9.0, 10.0])
    got = interpolate_force(t, f, [0.05, 0.5, 0.95], max_gap_s=0.5)
    np.testing.assert_allclose(got[[0, 2]], [0.5, 9.5], atol=1e-12)
    assert math.isnan(got[1])


def test_interpolation_of_one_or_no_sample():
    assert np.isnan(interpolate_force([], [], [0.0, 1.0], 1.0)).all()
    np.testing.assert_array_equal(interpolate_force([2.0], [7.0], [1.0, 2.0, 3.0], 1.0), [np.nan, 7.0, np.nan])


def test_interpolation_keeps_the_shape_of_the_times():
    t, f = np.array([0.0, 1.0]), np.array([0.0, 10.0])
    got = interpolate_force(t, f, np.array([[0.1, 0.2], [0.5, 2.0]]), max_gap_s=5.0)
    assert got.shape == (2, 2)
    np.testing.assert_allclose(got[0], [1.0, 2.0], atol=1e-12)
    assert got[1, 0] == 5.0 and math.isnan(got[1, 1])
    assert interpolate_force(t, f, 0.25, max_gap_s=5.0).shape == () and interpolate_force(t, f, 0.25, 5.0) == 2.5


def test_a_sample_time_gives_that_sample_even_beside_a_gap():
    t, f = np.array([0.0, 10.0]), np.array([1.0, 2.0])
    np.testing.assert_array_equal(interpolate_force(t, f, [0.0, 5.0, 10.0], max_gap_s=1.0), [1.0, np.nan, 2.0])


def test_frame_time_convention(tmp_path):
    path = write_csv(tmp_path / "force.csv", [(0.0, 0.0), (1.0, 1.0)])
    with loading(f"csv:{path}") as load:
        assert load.frame_time_s(since_first_frame_s=0.5, arrival_ns=123) == 0.5
        with pytest.raises(LoadError):
            load.frame_time_s(arrival_ns=123)
    with loading(f"tcp://127.0.0.1:{free_port()}") as load:
        assert load.time_base == TIME_BASE_MONOTONIC
        assert load.frame_time_s(since_first_frame_s=0.5, arrival_ns=2_500_000_000) == 2.5
        with pytest.raises(LoadError):
            load.frame_time_s(since_first_frame_s=0.5)


class _Samples(LoadSource):
    def __init__(self, t, f):
        self.t, self.f, self.uri, self.closed = np.asarray(t, float), np.asarray(f, float), "test:", False

    def samples(self):
        return self.t.copy(), self.f.copy()

    def close(self):
        self.closed = True


def test_the_base_class_interpolates_its_samples_and_closes_as_a_context():
    with _Samples([0.0, 0.2, 0.4], [0.0, 2.0, 4.0]) as load:
        assert load.force_when_known(0.3) == pytest.approx(3.0) and math.isnan(load.force_when_known(0.5))
        assert load.last_sample_time_s == 0.4 and load.events() == [] and load.warnings == LoadWarnings()
        assert load.settings == {"uri": "test:", "time_base": TIME_BASE_SESSION, "max_gap_s": 0.5}
    assert load.closed and math.isnan(_Samples([], []).last_sample_time_s)


def test_warning_total_counts_samples_lost_but_not_old_ones_trimmed():
    warnings = LoadWarnings(garbage_lines=1, out_of_order=2, superseded=40, trimmed=1000, exception_responses=3,
                            timeouts=4, bad_values=5)
    assert warnings.total() == 15 and LoadWarnings().total() == 0


def test_only_news_events_are_not_trouble():
    assert {kind for kind in LoadEventKind if not kind.is_trouble} == {LoadEventKind.CONNECTED, LoadEventKind.RESUMED}
    assert LoadEventKind("stalled") is LoadEventKind.STALLED and LoadEventKind.STALLED == "stalled"
