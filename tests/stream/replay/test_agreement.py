"""Tests of stream/replay/agreement.py: a replay's comparison with the recording and the verdict it gives."""

from types import SimpleNamespace

import numpy as np
import pytest

from livedic.stream.pipeline.sinks import stereo_arrays
from livedic.stream.replay.agreement import (ROUNDING_TOLERANCE_PX, ROUNDING_TOLERANCE_ZNCC, Agreement, ReplayReport,
                                             _Comparison)

X = np.array([10.0, 20.0, 30.0])
Y = np.array([5.0, 5.0, 5.0])


def _values(u=(0.5, 1.0, np.nan), v=(0.0, -0.25, np.nan), zncc=(0.99, 0.98, np.nan), ok=(True, True, False)):
    return SimpleNamespace(x=X.copy(), y=Y.copy(), u=np.array(u, dtype=float), v=np.array(v, dtype=float),
                           zncc=np.array(zncc, dtype=float), ok=np.array(ok))


def _result(index, measurement, reference=False):
    return SimpleNamespace(measurement=measurement, is_reference=reference,
                           frame=SimpleNamespace(index=index, timestamp_ns=1000 * index))


def _replayed(recorded, replayed, recorded_xy=np.column_stack([X, Y])):
    """The report after replaying frames 0.. (``replayed`` measurements) against ``recorded`` results."""
    report = ReplayReport(path="p.mcap", params={}, recorded_params={}, changed=[], recorded_frames=len(recorded))
    sink = _Comparison(report, {(i, 1000 * i): r for i, r in enumerate(recorded)}, recorded_xy)
    stats = SimpleNamespace(n_points=len(X))
    for i, m in enumerate(replayed):
        sink(_result(i, m, reference=i == 0), stats)
    return report


def test_identical_results_are_exact():
    report = _replayed([_values(), _values()], [_values(), _values()])
    assert report.same_points and report.compared_frames == 2 and report.mismatched_frames == 0
    assert report.agreement is Agreement.EXACT and report.exact
    assert report.verdict() == "replay matches the recording exactly: 2 frames x 3 points"


def test_a_difference_below_the_tolerance_is_within_rounding_with_the_largest_difference():
    shifted = _values(u=(0.5 + 0.4 * ROUNDING_TOLERANCE_PX, 1.0, np.nan),
                      zncc=(0.99, 0.98 - 0.5 * ROUNDING_TOLERANCE_ZNCC, np.nan))
    report = _replayed([_values(), _values()], [_values(), shifted])
    assert report.mismatched_frames == 1 and not report.exact
    assert report.max_du == pytest.approx(0.4 * ROUNDING_TOLERANCE_PX, rel=1e-6) and report.max_dv == 0.0
    assert report.agreement is Agreement.WITHIN_ROUNDING
    assert report.verdict().startswith("replay agrees with the recording within floating-point rounding (max 4e-05 "
                                       "px <= 1e-4 px tolerance): 2 frames x 3 points")


@pytest.mark.parametrize("change, counter", [
    (dict(u=(0.5 + 3 * ROUNDING_TOLERANCE_PX, 1.0, np.nan)), "max_du"),
    (dict(zncc=(0.99, 0.98 - 2 * ROUNDING_TOLERANCE_ZNCC, np.nan)), "max_dzncc"),
    (dict(ok=(True, False, False)), "ok_differs"),
    (dict(v=(0.0, np.nan, np.nan)), "nan_differs"),
])
def test_beyond_rounding_or_a_changed_ok_or_nan_differs(change, counter):
    report = _replayed([_values(), _values()], [_values(), _values(**change)])
    assert report.agreement is Agreement.DIFFERS and getattr(report, counter) > 0
    assert report.verdict().startswith("replay differs from the recording on 1 of 2 frames x 3 points")


def test_nan_on_both_sides_is_the_same_and_not_a_difference():
    report = _replayed([_values()], [_values()])
    assert report.nan_differs == 0 and np.isnan(_values().u[2]) and report.agreement is Agreement.EXACT


def test_a_frame_with_other_points_is_a_layout_difference():
    moved = _values()
    moved.x = X + 1.0
    report = _replayed([_values(), _values()], [_values(), moved])
    assert report.layout_differs == 1 and report.mismatched_frames == 1 and report.agreement is Agreement.DIFFERS


def test_not_compared_when_the_points_differ_or_nothing_was_recorded():
    other = _replayed([_values()], [_values()], recorded_xy=np.column_stack([X + 1, Y]))
    assert not other.same_points and other.compared_frames == 0 and other.agreement is Agreement.NOT_COMPARED
    assert "the points differ from the recorded ones" in other.verdict()
    empty = _replayed([], [_values(), _values()])
    assert empty.extra_frames == 2 and empty.agreement is Agreement.NOT_COMPARED
    assert empty.verdict() == "the recording holds no results to compare with"


def test_a_frame_replayed_twice_is_compared_once_and_extra_frames_are_counted():
    report = ReplayReport(path="p", params={}, recorded_params={}, changed=[], recorded_frames=1, all_frames=True)
    sink = _Comparison(report, {(0, 0): _values()}, np.column_stack([X, Y]))
    stats = SimpleNamespace(n_points=3)
    sink(_result(0, _values(), reference=True), stats)
    sink(_result(0, _values()), stats)
    sink(_result(1, _values()), stats)
    assert (report.frames, report.compared_frames, report.extra_frames) == (3, 1, 2)


def test_missing_frames_still_allow_exact_but_an_uncompared_recorded_frame_does_not():
    report = _replayed([_values(), _values(), _values()], [_values(), _values()])
    assert report.compared_frames == 2 and not report.exact and report.agreement is Agreement.DIFFERS
    report.missing_frames = 1                 # the third frame's image is not in the file
    assert report.exact and report.agreement is Agreement.EXACT


def test_the_verdict_names_changed_parameters():
    report = _replayed([_values()], [_values()])
    report.changed = [("subset", 21, 31), ("seed", None, 4)]
    assert report.verdict() == ("replay with changed parameters (subset 21 -> 31, seed ? -> 4) still equals the "
                                "recording exactly: 1 frames x 3 points")


def _in_space(values, dz=0.0, status=(0, 0, 1)):
    """``values`` as a stereo measurement: points 300 mm away, moved ``dz`` mm in depth, their 3D status."""
    n = len(values.u)
    xyz = np.column_stack([values.x * 0.1, values.y * 0.1, np.full(n, 300.0 + dz)])
    xyz[np.asarray(status) != 0] = np.nan
    values.points = SimpleNamespace(xyz=xyz, displacement=xyz - xyz[0], status=np.array(status, dtype=np.int32))
    values.right_xy = np.column_stack([values.x - 40.0, values.y])
    return values


def _stereo_replayed(dz, status=(0, 0, 1)):
    recorded = [_in_space(_values()), _in_space(_values())]
    for r in recorded:
        r.stereo = stereo_arrays(r)
    shifted = _in_space(_values(u=(0.5 + 0.4 * ROUNDING_TOLERANCE_PX, 1.0, np.nan)), dz=dz, status=status)
    report = _replayed(recorded, [_in_space(_values()), shifted])
    report.stereo = {"angle_deg": 25.0, "mm_per_px": 0.1}
    return report


def test_stereo_within_rounding_needs_the_points_in_space_within_what_rounding_moves_them():
    tolerance = _stereo_replayed(0.0).rounding_tolerance_mm
    assert tolerance == pytest.approx(ROUNDING_TOLERANCE_PX * 0.1 * (1 + 1 / np.sin(np.radians(25.0))))
    assert _stereo_replayed(0.5 * tolerance).agreement is Agreement.WITHIN_ROUNDING
    far = _stereo_replayed(3.0)                          # the 2D tracking within rounding, the 3D points 3 mm off
    assert far.agreement is Agreement.DIFFERS and far.max_d_mm == pytest.approx(3.0)
    assert "in space max 3 mm in X..W" in far.verdict()
    flagged = _stereo_replayed(0.0, status=(0, 2, 1))    # a point no longer ok in 3D
    assert flagged.stereo_status_differs == 1 and flagged.agreement is Agreement.DIFFERS
