"""The Rerun view reads as a person needs it (issue 19): small plots tall enough, their colours named and no
legend over the curves; the ROI's name legible on speckle; extensometer labels apart; the stress-strain curves
named. Read from the blueprint and the saved .rrd (the pictures were looked at with
/work/shared/tools/rrd_screenshot.py; what is checked here is what they showed)."""

from types import SimpleNamespace

import numpy as np
import pytest

from livedic.stream.view import blueprint, colour_scale, entities
from livedic.stream.view import logger as view_logger
from livedic.stream.view.logger import RerunLogger
from tests.stream.view.test_logger_stress import AREA
from tests.stream.view.test_logger_stress import _session as _stress_session
from tests.stream.view.test_logger_strain import ROI, _points, _stage
from tests.stream.view.test_logger import SHAPE, _rows

SMALL = (entities.P0, entities.QUALITY, entities.THROUGHPUT, entities.LATENCY, entities.DROPS, entities.ERROR)
# Reference hues for the colour words the plot names use.
COLOUR_WORDS = {"red": (220, 50, 50), "blue": (50, 110, 230), "green": (40, 170, 80), "orange": (220, 130, 30),
                "grey": (120, 120, 120), "purple": (130, 60, 170), "pink": (230, 120, 200)}


def _blueprint(strain=True, load=True):
    points = _points()
    return RerunLogger("save", "unused.rrd")._make_blueprint(
        True, _stage(points) if strain else None, SimpleNamespace(area_mm2=AREA) if load else None)


def _walk(item, share=1.0):
    """(view, its share of the plot column's height) for every view, the column being the root's second child."""
    from rerun.blueprint.api import Container
    if not isinstance(item, Container):
        yield item, share
        return
    shares = item.row_shares if getattr(item, "row_shares", None) else None
    total = sum(shares) if shares else None
    vertical = type(item).__name__ == "Vertical"
    for k, child in enumerate(item.contents):
        part = (shares[k] / total if shares else 1.0 / len(item.contents)) if vertical else 1.0
        yield from _walk(child, share * part)


@pytest.mark.parametrize("strain", [True, False], ids=["strain-and-force", "plain"])
def test_small_plots_are_tall_enough_name_their_colours_and_have_no_legend_over_the_curves(strain):
    column = _blueprint(strain=strain, load=strain).root_container.contents[1]
    views = {str(view.origin): (view, share) for view, share in _walk(column)}
    for path in SMALL:
        view, share = views[path]
        assert share >= 0.1, (path, share)        # >= 80 px of a plot column ~800 px high (it was 1/17)
        assert not view.properties["PlotLegend"].visible.as_arrow_array().to_pylist()[0]
        name = str(view.name)
        assert name == blueprint._SMALL_PLOT_NAMES[path] and len(name) <= 38
        # each series' colour is named, in the series' order
        words = [word.strip(",;()") for word in name.split() if word.strip(",;()") in COLOUR_WORDS]
        _, colours = entities.SERIES_STYLE[path]
        nearest = [min(COLOUR_WORDS, key=lambda w: np.abs(np.subtract(COLOUR_WORDS[w], c)).sum()) for c in colours]
        assert words == nearest, (name, nearest)


def test_strain_and_force_plots_keep_their_legend_in_the_top_left_corner():
    column = _blueprint().root_container.contents[1]
    views = {str(view.origin): view for view, _ in _walk(column)}
    for path in (entities.EXTENSOMETER_STRAIN, entities.FORCE):
        legend = views[path].properties["PlotLegend"]
        assert legend.corner.as_arrow_array().to_pylist() == [1]          # Corner2D.LeftTop
        assert legend.visible.as_arrow_array().to_pylist() == [True]


def _label_box(anchor, text, side):
    """(x0, y0, x1, y1) of a label as Rerun draws it: centred under its anchor (sizes: entities.LABEL_*)."""
    half = 0.5 * len(text) * entities.LABEL_CHARACTER * side
    return anchor[0] - half, anchor[1], anchor[0] + half, anchor[1] + entities.LABEL_HEIGHT * side


def _overlap(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@pytest.mark.parametrize("transverse_px", [12, 40, 150, 300])
@pytest.mark.parametrize("side", [512, 410])
def test_extensometer_labels_never_meet_each_other_or_p0s_label(transverse_px, side):
    """Axial and transverse cross at P0; however short the transverse one (12 px in a narrow image), the three
    labels stay apart, and each sits beyond its line's second end (the axial under, the transverse above)."""
    p0 = np.array([200.0, 250.0])
    first = np.array([[200.0, 50.0], [200.0 - transverse_px / 2, 250.0]])
    second = np.array([[200.0, 450.0], [200.0 + transverse_px / 2, 250.0]])
    labels = ["axial 10.615 %", "transverse -7.584 %"]
    anchors = view_logger._label_anchors(first, second, labels, side)
    axial, transverse = (_label_box(a, text, side) for a, text in zip(anchors, labels))
    p0_label = _label_box(p0 + [0.0, 4.0], "P0", side)
    assert not _overlap(axial, transverse) and not _overlap(axial, p0_label) and not _overlap(transverse, p0_label)
    assert axial[1] > second[0, 1]                                    # under the axial's lower end
    assert transverse[0] >= second[1, 0] and transverse[3] < second[1, 1]    # beyond the right end, above the line


def test_the_roi_is_named_above_its_box_in_dark_text(tmp_path):
    path = tmp_path / "roi.rrd"
    logger = RerunLogger("save", str(path), image_max_side=max(SHAPE))
    logger.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=_points())
    logger.close()
    assert not _rows(path, f"/{entities.CAMERA_ROI}", "Boxes2D:labels")     # not the box's yellow text
    assert _rows(path, f"/{entities.CAMERA_ROI_LABEL}", "Points2D:labels") == {"static": ["ROI"]}
    (x, y), = _rows(path, f"/{entities.CAMERA_ROI_LABEL}", "Points2D:positions")["static"]
    box = _label_box((x, y), "ROI", max(SHAPE))
    assert box[3] < ROI[1] - 0.5 and box[0] >= ROI[0] - 0.5 - 1e-9           # above the box, from its left edge
    colour, = _rows(path, f"/{entities.CAMERA_ROI_LABEL}", "Points2D:colors")["static"]
    assert max((colour >> shift) & 255 for shift in (24, 16, 8)) < 64        # dark text on Rerun's light box


def test_the_stress_strain_plot_names_its_engineering_and_true_curves(tmp_path):
    path = tmp_path / "stress.rrd"
    _stress_session(path)
    legend = f"/{entities.STRESS_STRAIN}/legend"
    assert _rows(path, f"{legend}/names", "Points2D:labels") == {"static": ["engineering", "true (to max. force)"]}
    colours = _rows(path, legend, "LineStrips2D:colors")["static"]
    assert colours == [int(c) for c in colour_scale.pack_colours(entities.STRESS_COLOURS)]   # the curves' colours
