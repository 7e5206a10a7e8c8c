"""What Rerun has not: an XY plot (transverse vs axial strain, stress-strain) drawn in a 2D view, and the
plots' values sent as columns a few times a second.

``XYPlot`` keeps a fixed box whose axes grow with the data (docs/guide/live-view.md); ``SeriesColumns`` collects each
frame's scalars and plot segments and sends them with ``send_columns``, the same rows a ``log`` a frame gives
at a fraction of the cost. Both log through the ``rr``/``rec`` they are given, from the logging thread only.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from livedic.stream.view.colour_scale import AXIS_MANTISSAS, grow_to_cover, nice_ceil
from livedic.stream.view.entities import LABEL_TEXT_COLOUR, MARKER_DRAW_ORDER, TIMELINE_FRAME, TIMELINE_TIME, darker

if TYPE_CHECKING:
    import rerun as rerun_sdk
    import rerun.blueprint as rrb

    Point = tuple[float, float]

# The plots' values go out as columns this often (a few frames at once: Rerun's cost is per call).
SERIES_SEND_S = 0.1
MIN_XY_LIMIT_STRAIN = 5e-4       # the transverse-vs-axial axes start at +-0.05 %
MIN_XY_LIMIT_STRESS_MPA = 100.0  # the stress-strain plot's stress axis starts at 0-100 MPa
_XY_BOX = (100.0, 25.0)          # the transverse-vs-axial plot's box (width, height) in scene units
_XY_FRAME_COLOUR = (160, 160, 160)
_XY_ZERO_COLOUR = (210, 210, 210)
_XY_GRID_COLOUR = (75, 75, 75)
_XY_MAX_TICKS = 5


def _ticks(lo: float, hi: float) -> list[float]:
    """At most ``_XY_MAX_TICKS`` + 1 round values from ``lo`` to ``hi`` (lo <= 0 <= hi), 0 among them."""
    step = nice_ceil((hi - lo) / _XY_MAX_TICKS, (1.0, 2.0, 2.5, 5.0, 10.0))
    first = np.ceil(lo / step - 1e-9)
    return [float(f"{k * step:.6g}") + 0.0 for k in np.arange(first, np.floor(hi / step + 1e-9) + 1)]


def _tick_label(value: float) -> str:
    return "0" if value == 0 else f"{value:g}"


class XYPlot:
    """An XY plot in a 2D view (Rerun has no XY plot): a fixed box whose axes grow with the data.

    The curve is logged in data units (x, -y) under ``ROOT/data``, whose transform maps the current
    limits onto the box (``_XY_BOX``; image coordinates run down, hence -y); the limits start at
    ``x_start``/``y_start`` (lo <= 0 <= hi) and only grow, to 1, 2 or 5 times a power of ten, and each
    growth logs one new transform (the whole curve rescales: the segments already logged stay as they
    are) and new axes. One segment a frame, shown up to the time cursor (``history_override``); a
    frame without a value leaves a gap and clears the current point.

    Entities: ``ROOT/data/curve`` (and ``ROOT/data/SECOND`` for a second curve), ``ROOT/now`` (the
    current point, and the numbers above the box), ``ROOT/axes``, ``ROOT/ticks``, and with ``names`` (one
    per curve) ``ROOT/legend``: a short line in each curve's colour with its name, in the box's lower right.
    """

    def __init__(self, root: str, *, x_title: str, y_title: str, x_start: Sequence[float], y_start: Sequence[float],
                 colours: Sequence[tuple[int, int, int]], second: str | None = None, x_title_under_zero: bool = True,
                 mantissas: Sequence[float] = AXIS_MANTISSAS, names: Sequence[str] | None = None) -> None:
        self.root = root
        self.data, self.curve, self.now = f"{root}/data", f"{root}/data/curve", f"{root}/now"
        self.axes, self.ticks = f"{root}/axes", f"{root}/ticks"
        self.second = f"{root}/data/{second}" if second else None
        self.legend, self.names = f"{root}/legend", names
        self.x_title, self.y_title = x_title, y_title
        self.x_title_under_zero = x_title_under_zero     # inside the box, under the x axis; else above the bottom
        self.mantissas = mantissas                        # the nice numbers the limits grow to
        self.colours = colours
        x_lo, x_hi = x_start
        y_lo, y_hi = y_start
        self.limits: dict[str, tuple[float, float]] = {"x": (x_lo, x_hi), "y": (y_lo, y_hi)}
        self._axes_logged: dict[str, tuple[float, float]] | None = None
        # each curve's previous point, None after a gap
        self._last: dict[str | None, Point | None] = {self.curve: None, self.second: None}
        # a SeriesColumns the segments go to (the logger's), else logged one by one
        self.columns: SeriesColumns | None = None
        self.transform = ((1.0, 1.0), (0.0, 0.0))

    def view(self, name: str) -> rrb.Spatial2DView:
        import rerun.blueprint as rrb
        history = rrb.VisibleTimeRanges([
            rrb.VisibleTimeRange(timeline, start=rrb.TimeRangeBoundary.infinite(),
                                 end=rrb.TimeRangeBoundary.cursor_relative())
            for timeline in (TIMELINE_FRAME, TIMELINE_TIME)])
        width, height = _XY_BOX
        curves = [self.curve] + ([self.second] if self.second else [])
        return rrb.Spatial2DView(name=name, origin=self.root, overrides={f"/{c}": history for c in curves},
                                 visual_bounds=rrb.VisualBounds2D(x_range=[-0.08 * width, 1.03 * width],
                                                                  y_range=[-0.4 * height, 1.2 * height]))

    def start(self, rr: ModuleType, rec: rerun_sdk.RecordingStream) -> None:
        """The curves' and the current point's styles (static: logged once)."""
        rec.log(self.curve, rr.LineStrips2D.from_fields(radii=-1.5, colors=[self.colours[0]]), static=True)
        if self.second:
            rec.log(self.second, rr.LineStrips2D.from_fields(radii=-1.5, colors=[self.colours[1]]), static=True)
        rec.log(self.now, rr.Points2D.from_fields(radii=[0.0, -4.0], colors=[LABEL_TEXT_COLOUR, (255, 255, 255)],
                                                  show_labels=True, draw_order=MARKER_DRAW_ORDER), static=True)
        if self.names:
            self._log_legend(rr, rec)

    def _log_legend(self, rr: ModuleType, rec: rerun_sdk.RecordingStream) -> None:
        """Which curve is which: a short line in each curve's colour, its name after it (low in the box, left of
        the x axis' title: a tensile test's stress stays high once it has risen), in a darker shade of the colour."""
        width, height = _XY_BOX
        names = list(self.names or ())
        rows = [0.58 * height + 0.2 * height * k for k in range(len(names))]
        strips = [[(0.32 * width, y), (0.38 * width, y)] for y in rows]
        # a label is drawn centred under its anchor (~1.35 box units a character, ~3 high)
        anchors = [(0.39 * width + 0.68 * len(name), y - 1.6) for name, y in zip(names, rows)]
        colours = self.colours[:len(names)]
        rec.log(self.legend, rr.LineStrips2D(strips, radii=-1.5, colors=colours, draw_order=MARKER_DRAW_ORDER),
                static=True)
        rec.log(f"{self.legend}/names", rr.Points2D(anchors, radii=0.0, labels=names,
                                                    colors=[darker(colour) for colour in colours], show_labels=True,
                                                    draw_order=MARKER_DRAW_ORDER), static=True)

    def add(self, rr: ModuleType, rec: rerun_sdk.RecordingStream, x: float, y: float, text: str,
            second: Point | None = None) -> None:
        """This frame's point (x, y) in data units with its text; ``second``: (x, y) of the second curve or None."""
        self._grow(x, y)
        if second is not None:
            self._grow(*second)
        if self._axes_logged != self.limits:
            self._log_axes(rr, rec)
        point = (x, -y)
        self._segment(rr, rec, self.curve, point)
        if self.second:
            self._segment(rr, rec, self.second, None if second is None else (second[0], -second[1]))
        (kx, ky), (bx, by) = self.transform
        width, height = _XY_BOX
        # two labels for two points (one label alone would go to the middle of both): the numbers above the box,
        # right of its title, then the current point, unlabelled
        rec.log(self.now, rr.Points2D.from_fields(positions=[(0.68 * width, -0.3 * height),
                                                             (kx * point[0] + bx, ky * point[1] + by)],
                                                  labels=[text, ""]))

    def gap(self, rr: ModuleType, rec: rerun_sdk.RecordingStream) -> None:
        """No value this frame: a gap in the curves, the current point cleared."""
        if self._last[self.curve] is not None:
            rec.log(self.now, rr.Clear(recursive=False))
        self._last = {key: None for key in self._last}

    def _segment(self, rr: ModuleType, rec: rerun_sdk.RecordingStream, entity: str,
                 point: Point | None) -> None:
        if point is not None and self._last[entity] is not None:
            if self.columns is not None:
                self.columns.add(entity, [self._last[entity], point], kind="strip")
            else:
                rec.log(entity, rr.LineStrips2D.from_fields(strips=[[self._last[entity], point]]))
        self._last[entity] = point

    def _grow(self, x: float, y: float) -> None:
        self.limits = {"x": grow_to_cover(self.limits["x"], x, self.mantissas),
                       "y": grow_to_cover(self.limits["y"], y, self.mantissas)}

    def _log_axes(self, rr: ModuleType, rec: rerun_sdk.RecordingStream) -> None:
        """The box for the current limits: frame, zero lines, grid and tick labels, and the transform."""
        width, height = _XY_BOX
        (x_lo, x_hi), (y_lo, y_hi) = self.limits["x"], self.limits["y"]
        kx, ky = width / (x_hi - x_lo), height / (y_hi - y_lo)
        bx, by = -kx * x_lo, ky * y_hi                    # box X = kx * x + bx, box Y = ky * (-y) + by
        self.transform = ((kx, ky), (bx, by))
        rec.log(self.data, rr.Transform3D(translation=[bx, by, 0.0], scale=[kx, ky, 1.0]))
        x_ticks, y_ticks = _ticks(x_lo, x_hi), _ticks(y_lo, y_hi)
        strips: list[list[Point]] = []
        colours: list[tuple[int, int, int]] = []
        for tick in x_ticks:
            x = kx * tick + bx
            strips.append([(x, 0.0), (x, height)])
            colours.append(_XY_ZERO_COLOUR if tick == 0 else _XY_GRID_COLOUR)
        for tick in y_ticks:
            y = -ky * tick + by
            strips.append([(0.0, y), (width, y)])
            colours.append(_XY_ZERO_COLOUR if tick == 0 else _XY_GRID_COLOUR)
        strips.append([(0.0, 0.0), (width, 0.0), (width, height), (0.0, height), (0.0, 0.0)])
        colours.append(_XY_FRAME_COLOUR)
        rec.log(self.axes, rr.LineStrips2D(strips, radii=-0.75, colors=colours, draw_order=0.0))
        positions = [(kx * tick + bx, height + 0.02 * height) for tick in x_ticks]
        positions += [(-0.04 * width, -ky * tick + by - 0.07 * height) for tick in y_ticks]
        labels = [_tick_label(tick) for tick in x_ticks] + [_tick_label(tick) for tick in y_ticks]
        # the axis titles: y's above the box's left side; x's inside the box at the right, under the zero line
        # (a tensile test's transverse-vs-axial curve runs down and right from 0, far from there), or just above
        # the bottom (a stress-strain curve is high up at large strains)
        x_title_y = by + 0.04 * height if self.x_title_under_zero else 0.78 * height
        positions += [(0.06 * width, -0.3 * height), (0.92 * width, x_title_y)]
        labels += [self.y_title, self.x_title]
        rec.log(self.ticks, rr.Points2D(positions, radii=0.0, labels=labels, show_labels=True,
                                        colors=[LABEL_TEXT_COLOUR]))
        self._axes_logged = dict(self.limits)


class SeriesColumns:
    """Every frame's scalars and plot segments, sent to Rerun as columns (``send_columns``) a few times a second.

    One ``rr.Scalars`` a series a frame (and one ``rr.LineStrips2D`` a curve a frame) cost the view most of its
    per-frame time (Rerun's Python layer builds each archetype): here a frame's values are appended to lists
    at the frame being logged (``now``), and each series goes out as one column of many frames, on the same
    timelines, the same rows a ``log`` per frame gives. A gap (``clear``) sends what waits first. Not
    thread-safe: the logging thread's alone.
    """

    def __init__(self, rr: ModuleType, rec: rerun_sdk.RecordingStream) -> None:
        self.rr, self.rec = rr, rec
        self.now = (0, 0.0)            # the frame being logged: (index, seconds since the first)
        # path -> (kind, [frame], [time s], [values])
        self._rows: dict[str, tuple[str, list[int], list[float], list[Any]]] = {}
        self._last_sent = time.monotonic()

    def add(self, path: str, values: Any, kind: str = "scalars") -> None:
        """``values`` of the series ``path`` at ``now``: scalars, or one 2-D strip (``kind="strip"``)."""
        rows = self._rows.get(path)
        if rows is None:
            rows = self._rows[path] = (kind, [], [], [])
        rows[1].append(self.now[0])
        rows[2].append(self.now[1])
        rows[3].append(values)

    def clear(self, path: str) -> None:
        """A gap in the series at the current time: what waits goes first."""
        self.send(path)
        self.rec.log(path, self.rr.Clear(recursive=False))

    def send_when_due(self) -> None:
        if time.monotonic() - self._last_sent >= SERIES_SEND_S:
            self.send()

    def send(self, path: str | None = None) -> None:
        rr = self.rr
        for key in [path] if path is not None else list(self._rows):
            rows = self._rows.pop(key, None)
            if not rows:
                continue
            kind, frames, seconds, values = rows
            array = np.asarray(values, dtype=np.float64)
            columns = rr.Scalars.columns(scalars=array) if kind == "scalars" else rr.LineStrips2D.columns(
                strips=array)
            rr.send_columns(key, indexes=[rr.TimeColumn(TIMELINE_FRAME, sequence=frames),
                                          rr.TimeColumn(TIMELINE_TIME, duration=seconds)],
                            columns=columns, recording=self.rec)
        if path is None:
            self._last_sent = time.monotonic()
