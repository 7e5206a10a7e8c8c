"""Tests of stream/view/setup_view.py: the set-up logged once, static, at the view's scale, read back from an .rrd."""

import numpy as np
import pytest
import rerun as rr

from livedic.dic.region import Circle
from livedic.stream.session.config import PointsConfig
from livedic.stream.session.points import place_points
from livedic.stream.session.preview import setup_overlay
from livedic.stream.stages.strain import StrainConfig
from livedic.stream.view import entities
from livedic.stream.view.colour_scale import colormap_lut
from livedic.stream.view.setup_view import SetupView
from tests.conftest import specimen_scene
from tests.stream.view.test_logger import _rows

SUBSET, SCALE = 21, 2


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A strip's set-up, one exclusion, with the axial/transverse pair, logged at half size; (path, overlay)."""
    image, _ = specimen_scene(seed=3)
    placement = place_points(image, PointsConfig(step=12, exclude=(Circle(125, 340, 6),)), subset=SUBSET)
    stage = StrainConfig(gauge_length=100.0).place(placement.points, p0=placement.points[0],
                                                   roi=placement.bounds, step=placement.step, subset=SUBSET)
    overlay = setup_overlay(image, placement, stage, subset=SUBSET)
    path = tmp_path_factory.mktemp("setup") / "setup.rrd"
    rec = rr.RecordingStream("livedic-test")
    rec.save(str(path))
    SetupView(rr, rec, SCALE, colormap_lut(), max(image.shape)).log(overlay)
    rec.flush(timeout_sec=5.0)
    rec.disconnect()
    return path, overlay


def test_points_and_p0_are_drawn_at_the_display_scale(saved):
    path, overlay = saved
    points = _rows(path, f"/{entities.SETUP}/points", "Points2D:positions")
    assert list(points) == ["static"]                               # logged once, for the whole session
    np.testing.assert_allclose(points["static"], overlay.placement.points / SCALE)
    mins = _rows(path, f"/{entities.SETUP}/p0", "Boxes2D:half_sizes")["static"]
    np.testing.assert_allclose(mins, [[SUBSET / 2 / SCALE, SUBSET / 2 / SCALE]])     # P0's subset, to scale


def test_the_region_and_the_exclusion_go_on_both_views_with_their_labels(saved):
    path, overlay = saved
    for entity in (f"/{entities.CAMERA_ROI}", f"/{entities.SETUP}/region"):
        strips = _rows(path, entity, "LineStrips2D:strips")["static"]
        assert len(strips) == len(overlay.outlines) + len(overlay.exclusions) >= 2
    labels = _rows(path, f"/{entities.SETUP}/labels", "Points2D:labels")["static"]
    assert "excluded" in labels and f"P0 ({SUBSET} px subset)" in labels
    assert sum(label.startswith(("axial", "transverse")) for label in labels) == 2
    extensometers = _rows(path, f"/{entities.SETUP}/extensometers", "LineStrips2D:strips")["static"]
    assert len(extensometers) == 2
    region = _rows(path, f"/{entities.CAMERA_ROI_LABEL}", "Points2D:labels")["static"]
    assert region == [overlay.region_label]


def test_the_notes_list_the_set_up_and_what_to_check(saved):
    path, overlay = saved
    text = _rows(path, f"/{entities.SETUP_NOTES}", "TextDocument:text")["static"][0]
    assert text.startswith("# set-up\n\n") and all(f"- {line}" in text for line in overlay.lines())
    advice = overlay.advice()
    assert ("**check:**" in text) is bool(advice) and all(f"- {line}" in text for line in advice)


def test_the_roi_label_sits_above_the_top_left_corner_clear_of_the_region():
    view = SetupView(rr, None, 2, colormap_lut(), 400)
    label = view.roi_label((100, 60, 50, 50), "ROI")
    x, y = np.asarray(label.positions.as_arrow_array().to_pylist()[0])
    assert y < 60 / 2 - 0.5 and x > 100 / 2 - 0.5                 # above the top edge, right of the left one
