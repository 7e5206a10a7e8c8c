"""Tests of stream/view/xy_plot.py: the XY plot's growing axes and segments, and the columns, read back from an .rrd."""

import numpy as np
import pytest
import rerun as rr

from livedic.stream.view import xy_plot
from livedic.stream.view.entities import TIMELINE_FRAME, TIMELINE_TIME
from livedic.stream.view.xy_plot import SeriesColumns, XYPlot
from tests.stream.view.test_logger import _rows

WIDTH, HEIGHT = xy_plot._XY_BOX


def _stream(path):
    rec = rr.RecordingStream("livedic-test")
    rec.save(str(path))
    return rec


def _close(rec):
    rec.flush(timeout_sec=5.0)
    rec.disconnect()


def _at(rec, frame):
    rec.set_time(TIMELINE_FRAME, sequence=frame)
    rec.set_time(TIMELINE_TIME, duration=0.1 * frame)


@pytest.mark.parametrize("lo, hi", [(-0.3, 1.0), (0.0, 5.0), (-2e-4, 5e-4), (-100.0, 0.0)])
def test_ticks_are_few_round_and_include_zero(lo, hi):
    ticks = xy_plot._ticks(lo, hi)
    assert 0.0 in ticks and 2 <= len(ticks) <= xy_plot._XY_MAX_TICKS + 1
    assert all(lo - 1e-12 <= t <= hi + 1e-12 for t in ticks)
    steps = np.diff(ticks)
    assert np.allclose(steps, steps[0]) and steps[0] >= (hi - lo) / xy_plot._XY_MAX_TICKS * (1 - 1e-9)
    assert xy_plot._tick_label(0.0) == "0" and xy_plot._tick_label(0.25) == "0.25"


def _plot(**options):
    return XYPlot("plot", x_title="x", y_title="y", x_start=(-1.0, 1.0), y_start=(0.0, 1.0),
                  colours=[(255, 0, 0), (0, 0, 255)], **options)


def test_the_axes_grow_to_nice_numbers_and_the_transform_maps_them_on_the_box(tmp_path):
    rec = _stream(tmp_path / "plot.rrd")
    plot = _plot()
    plot.start(rr, rec)
    for frame, (x, y) in enumerate([(0.5, 0.5), (1.3, 0.7), (-2.6, 30.0), (0.1, 0.1)]):
        _at(rec, frame)
        plot.add(rr, rec, x, y, f"frame {frame}")
    _close(rec)
    assert plot.limits == {"x": (-5.0, 2.0), "y": (0.0, 50.0)}            # 1, 2 or 5 x 10^k; never shrink
    (kx, ky), (bx, by) = plot.transform
    assert kx * -5.0 + bx == pytest.approx(0.0) and kx * 2.0 + bx == pytest.approx(WIDTH)
    assert ky * -50.0 + by == pytest.approx(0.0) and ky * -0.0 + by == pytest.approx(HEIGHT)   # y runs down
    scales = _rows(tmp_path / "plot.rrd", "/plot/data", "Transform3D:scale")
    assert sorted(scales) == [0, 1, 2]                   # a new transform only when the limits grew
    strips = _rows(tmp_path / "plot.rrd", "/plot/data/curve", "LineStrips2D:strips")
    assert sorted(strips) == [1, 2, 3]                   # one segment a frame from the second on, in data units
    assert np.allclose(strips[2][0], [(1.3, -0.7), (-2.6, -30.0)])
    labels = _rows(tmp_path / "plot.rrd", "/plot/now", "Points2D:labels")
    assert labels[3] == ["frame 3", ""]


def test_a_gap_breaks_the_curve_and_clears_the_point_and_the_second_curve_has_its_own(tmp_path):
    rec = _stream(tmp_path / "gap.rrd")
    plot = _plot(second="true", names=["engineering", "true"])
    plot.start(rr, rec)
    _at(rec, 0)
    plot.add(rr, rec, 0.1, 0.1, "a", second=(0.1, 0.2))
    _at(rec, 1)
    plot.gap(rr, rec)
    _at(rec, 2)
    plot.add(rr, rec, 0.2, 0.2, "b", second=None)
    _at(rec, 3)
    plot.add(rr, rec, 0.3, 0.3, "c", second=(0.3, 0.4))
    _close(rec)
    path = tmp_path / "gap.rrd"
    assert sorted(_rows(path, "/plot/data/curve", "LineStrips2D:strips")) == [3]      # none across the gap
    assert _rows(path, "/plot/data/true", "LineStrips2D:strips") == {}              # its gap at frame 2
    assert _rows(path, "/plot/legend/names", "Points2D:labels") == {"static": ["engineering", "true"]}
    assert _rows(path, "/plot/now", "Clear:is_recursive") == {1: [False]}         # the point cleared at the gap
    assert sorted(_rows(path, "/plot/now", "Points2D:labels")) == [0, 2, 3]


def test_columns_send_the_same_rows_a_log_per_frame_gives(tmp_path):
    rec = _stream(tmp_path / "columns.rrd")
    columns = SeriesColumns(rr, rec)
    for frame in range(5):
        columns.now = (frame, 0.1 * frame)
        columns.add("series/a", [float(frame), 2.0 * frame])
        if frame == 2:
            columns.clear("series/b")                    # a gap: what waits goes first
        columns.add("series/b", [10.0 + frame])
    columns.add("series/strip", [(0.0, 0.0), (1.0, 1.0)], kind="strip")
    columns.send()
    _close(rec)
    path = tmp_path / "columns.rrd"
    assert _rows(path, "/series/a", "Scalars:scalars") == {k: [float(k), 2.0 * k] for k in range(5)}
    assert _rows(path, "/series/b", "Scalars:scalars") == {k: [10.0 + k] for k in range(5)}
    assert np.allclose(_rows(path, "/series/strip", "LineStrips2D:strips")[4][0], [(0, 0), (1, 1)])
