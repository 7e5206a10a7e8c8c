"""The view's layout: the Rerun blueprint of a session (which views, where, under which names).

``make_blueprint`` lays out the camera and field views with their colour bars, the strain and force plots a
tensile test is watched by, and the small plots; docs/guide/live-view.md shows the result. Imports rerun when called.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE
from livedic.stream.view.entities import (
    CAMERA, CAMERA_RIGHT, DROPS, ERROR, EVENTS, EXTENSOMETER_LINES, EXTENSOMETER_STRAIN, FIELD_EYY, FIELD_U, FIELD_V,
    FORCE, LATENCY, LEGEND_EYY, LEGEND_U, LEGEND_V, LEGEND_W, LOST, LOW_ZNCC, P0, QUALITY, SETUP, SETUP_NOTES, SPACE,
    SPACE_EYY, SPACE_W, SUMMARY, THROUGHPUT, TRACKING)

if TYPE_CHECKING:
    import rerun.blueprint as rrb

    from livedic.stream.stages.force import LoadStage
    from livedic.stream.stages.strain import StrainStage
    from livedic.stream.view.xy_plot import XYPlot

# The small plots' names say which colour is which series: Rerun draws a plot's legend over the plot, where in
# a plot this small it hides the curves, so it is switched off there (the colours are SERIES_STYLE's). Short
# enough (~30 characters) for half of the plot column.
_SMALL_PLOT_NAMES = {
    P0: "P0 (px): u red, v blue",
    QUALITY: "ZNCC: mean green, min orange, ok grey",
    THROUGHPUT: "frames/s blue, kPOI/s orange",
    LATENCY: "latency red, tracking blue (ms)",
    DROPS: "dropped red, queue depth grey",
    ERROR: "px error: RMS purple, max pink",
}


# what a view of a field on the camera image shows besides the field: the image, P0, the flagged points
_FIELD_CONTENTS = ("$origin/image", "$origin/p0", f"/{LOST}", f"/{LOW_ZNCC}")


def _plot_share(view: object) -> float:
    """A strain plot's height in the plot column: the XY plots (stress-strain, transverse vs axial) more than
    the time series, since their box keeps its aspect and their numbers and titles need the room."""
    return 3.5 if type(view).__name__ == "Spatial2DView" else 2.5


def _legend_top_left() -> rrb.PlotLegend:
    """The legend of the strain and force plots: a tensile test's strains and force start at 0 and move away
    from it as time goes right, so the top left corner stays clear of the curves."""
    import rerun.blueprint as rrb
    return rrb.PlotLegend(corner=rrb.Corner2D.LeftTop, visible=True)


def _small_plot(path: str) -> rrb.TimeSeriesView:
    """A small time-series view of ``path``: its name keys the colours, no legend over the curves."""
    import rerun.blueprint as rrb
    return rrb.TimeSeriesView(name=_SMALL_PLOT_NAMES[path], origin=path, plot_legend=rrb.PlotLegend(visible=False))


def _strain_view_name(strain: StrainStage) -> str:
    """The e_yy view's name: the measure and the virtual strain gauge, e.g. "e_yy (%) engineering, VSG 77 px"."""
    return f"e_yy (%) {strain.config.measure}, VSG {strain.vsg_px:.0f} px"


def axial_transverse_pair(strain: StrainStage | None) -> tuple[int, int] | None:
    """(index of "axial", index of "transverse") among the extensometers, or None without the pair."""
    names = [e.name for e in strain.extensometers] if strain is not None else []
    if AXIAL in names and TRANSVERSE in names:
        return names.index(AXIAL), names.index(TRANSVERSE)
    return None


def make_blueprint(has_truth: bool, strain: StrainStage | None = None, load: LoadStage | None = None, *,
                   setup: bool = False, strain_xy: XYPlot | None = None,
                   stress_xy: XYPlot | None = None, stereo: bool = False) -> rrb.Blueprint:
    """The session's layout (docs/guide/live-view.md): ``has_truth`` adds the error plot, ``strain`` (the session's
    ``stream.stages.strain.StrainStage``) the e_yy view and the extensometer plots, ``load`` the force plot,
    ``setup`` the set-up tabs, ``stereo`` the right camera and the 3D views; ``strain_xy`` and ``stress_xy`` are the
    ``xy_plot.XYPlot``s shown (or None)."""
    import rerun.blueprint as rrb
    field = _FIELD_CONTENTS
    extensometers = [f"/{EXTENSOMETER_LINES}"] if strain is not None else []
    camera: Any = rrb.Spatial2DView(name="camera", origin=CAMERA, contents=[*field, "$origin/roi/**", *extensometers])
    if setup:      # the set-up a tab behind the camera: one click away, the live image in front
        camera = rrb.Tabs(camera, rrb.Spatial2DView(name="set-up", origin=SETUP),
                          rrb.TextDocumentView(name="set-up notes", origin=SETUP_NOTES), active_tab=0)
    image_views: list[Any] = [
        camera,
        rrb.Spatial2DView(name="u (px)", origin=CAMERA, contents=[*field, f"/{FIELD_U}"]),
        rrb.Spatial2DView(name="v (px)", origin=CAMERA, contents=[*field, f"/{FIELD_V}"]),
    ]
    legend_views: list[Any] = [
        rrb.Vertical(rrb.TextDocumentView(name="tracking", origin=TRACKING),
                     rrb.TextDocumentView(name="session", origin=SUMMARY), row_shares=[1, 2]),
        rrb.Spatial2DView(name="u colour scale (px)", origin=LEGEND_U),
        rrb.Spatial2DView(name="v colour scale (px)", origin=LEGEND_V),
    ]
    strain_plots: list[Any] = []
    left: Any
    if stereo:
        left = _stereo_views(image_views, legend_views, strain, extensometers)
        strain_plots = _strain_plots(strain, strain_xy) if strain is not None else []
    elif strain is None:
        left = rrb.Vertical(rrb.Horizontal(*image_views), rrb.Horizontal(*legend_views), row_shares=[4, 1])
    else:
        # four fields do not fit in a row: a 2 x 2 grid, each view over its colour bar, camera and e_yy on top
        eyy, eyy_bar = _eyy_views(strain, extensometers)
        _, u_bar, v_bar = legend_views
        texts = rrb.Horizontal(rrb.TextDocumentView(name="tracking", origin=TRACKING),
                               rrb.TextDocumentView(name="session", origin=SUMMARY), column_shares=[1, 2])
        cells = [(image_views[0], texts), (eyy, eyy_bar), (image_views[1], u_bar), (image_views[2], v_bar)]
        left = rrb.Grid(*(rrb.Vertical(view, under, row_shares=[5, 1]) for view, under in cells), grid_columns=2)
        strain_plots = _strain_plots(strain, strain_xy)
    if stress_xy is not None:    # what a tensile test is run for: the first plot
        strain_plots.insert(0, stress_xy.view("stress-strain (MPa, %)"))
    if load is not None:
        strain_plots.append(rrb.TimeSeriesView(name="force (kN)", origin=FORCE, plot_legend=_legend_top_left()))
    small = [_small_plot(path) for path in (P0, QUALITY, THROUGHPUT, LATENCY, DROPS)]
    small += [_small_plot(ERROR)] if has_truth else []
    events = rrb.TextLogView(name="events", origin=EVENTS)
    plots: Any
    if not strain_plots:
        plots = rrb.Vertical(*small, events)
    else:
        # The strain plots are what a test engineer watches: they take the height; the small plots go two to
        # a row below them (ZNCC, with three series to name, the wider), each still tall enough to read.
        pairs = [small[k:k + 2] for k in range(0, len(small), 2)]
        rows = [rrb.Horizontal(*pair, column_shares=([2, 3] if k == 0 else [1, 1])[:len(pair)])
                for k, pair in enumerate(pairs)]
        plots = rrb.Vertical(*strain_plots, *rows, events,
                             row_shares=[_plot_share(view) for view in strain_plots] + [2] * len(rows) + [1.2])
    # a stereo session's seven views take more of the width than a 2D session's three or four
    return rrb.Blueprint(rrb.Horizontal(left, plots, column_shares=[7, 3] if stereo else [3, 2]), collapse_panels=True)


def _eyy_views(strain: StrainStage, extensometers: list[str]) -> tuple[rrb.Spatial2DView, rrb.Spatial2DView]:
    """The e_yy field on the camera image (with the extensometers) and its colour bar."""
    import rerun.blueprint as rrb
    eyy = rrb.Spatial2DView(name=_strain_view_name(strain), origin=CAMERA,
                            contents=[*_FIELD_CONTENTS, f"/{FIELD_EYY}", *extensometers])
    return eyy, rrb.Spatial2DView(name="e_yy colour scale (%)", origin=LEGEND_EYY)


def _stereo_views(image_views: list[Any], legend_views: list[Any], strain: StrainStage | None,
                  extensometers: list[str]) -> rrb.Vertical:
    """A stereo session's views, each over its colour bar or text: the two cameras and the 3D points by W and by
    e_yy on top, the fields on the image below (e_yy, u, v)."""
    import rerun.blueprint as rrb
    camera, u_view, v_view = image_views
    _, u_bar, v_bar = legend_views
    right = rrb.Spatial2DView(name="right camera", origin=CAMERA_RIGHT)
    eye = rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, look_target=[0.0, 0.0, 0.0], eye_up=[0.0, -1.0, 0.0])
    space_w = rrb.Spatial3DView(name="3D by W (mm, out of plane)", origin=SPACE, contents=[f"/{SPACE_W}"],
                                eye_controls=eye)
    w_bar = rrb.Spatial2DView(name="W colour scale (mm)", origin=LEGEND_W)
    top = [(camera, rrb.TextDocumentView(name="tracking", origin=TRACKING)),
           (right, rrb.TextDocumentView(name="session", origin=SUMMARY)), (space_w, w_bar)]
    bottom = [(u_view, u_bar), (v_view, v_bar)]
    if strain is not None:
        space_eyy = rrb.Spatial3DView(name="3D by e_yy (%)", origin=SPACE, contents=[f"/{SPACE_EYY}"],
                                      eye_controls=eye)
        top.append((space_eyy, _eyy_views(strain, extensometers)[1]))
        bottom.insert(0, _eyy_views(strain, extensometers))
    rows = [rrb.Horizontal(*(rrb.Vertical(view, under, row_shares=[5, 1]) for view, under in row))
            for row in (top, bottom)]
    return rrb.Vertical(*rows)


def _strain_plots(strain: StrainStage, strain_xy: XYPlot | None) -> list[Any]:
    """The extensometer strain series and the transverse-vs-axial plot (none without extensometers)."""
    import rerun.blueprint as rrb
    if not strain.extensometers:
        return []
    plots: list[Any] = [rrb.TimeSeriesView(name="extensometer strain (%)", origin=EXTENSOMETER_STRAIN,
                                plot_legend=_legend_top_left())]
    if strain_xy is not None:
        plots.append(strain_xy.view("transverse vs axial strain (%)"))
    return plots
