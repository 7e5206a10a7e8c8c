"""The set-up drawn before a test (stream/session/preview.py), placed exactly as ``livedic run`` places it; the
``livedic preview`` command itself: tests/stream/cli/test_preview.py.

Images: ``strip_images`` (tests/stream/conftest.py), a strip of blurred-noise texture with a hole at ``STRIP_HOLE``.
"""

import cv2
import numpy as np
import pytest

from livedic.bench.cli import main
from livedic.stream.session.config import PointsConfig
from livedic.stream.session.points import place_points
from livedic.stream.session.preview import region_outlines, setup_overlay, shape_outline
from livedic.dic.region import Circle
from tests.stream.conftest import STRIP_HOLE as HOLE



def test_preview_places_the_points_as_run_does(strip_images, tmp_path):
    """The preview's points are the session's: the same function, the same options, the same frame."""
    image = cv2.imread(str(strip_images / "f0.png"), cv2.IMREAD_GRAYSCALE)
    wanted = PointsConfig(n_points=300, exclude=(Circle(*HOLE),))
    placement = place_points(image, wanted, subset=21)
    overlay = setup_overlay(image, placement, subset=21, source="test")
    assert len(overlay.exclusions) == 1 and len(overlay.outlines) >= 2       # the strip's edge and the hole's
    assert np.allclose(shape_outline(Circle(*HOLE))[0], (HOLE[0] + HOLE[2], HOLE[1]))
    from livedic.bench.cli import main as cli
    record = tmp_path / "r.mcap"
    assert cli(["run", "--source", f"images:{strip_images}", "--n-points", "300", "--exclude", "circle:150,200,20",
                "--viewer", "none", "--record", str(record)]) == 0
    from livedic.acquire.recording.reader import read_results
    first = next(iter(read_results(str(record))))
    assert np.array_equal(np.column_stack([first.x, first.y]), placement.points)


def test_region_outlines_follow_a_mask_and_its_holes():
    mask = np.zeros((60, 80), dtype=bool)
    mask[10:50, 10:70] = True
    mask[25:35, 30:40] = False
    outlines = region_outlines(mask)
    assert len(outlines) == 2
    spans = sorted((float(np.ptp(line[:, 0])), float(np.ptp(line[:, 1]))) for line in outlines)
    assert spans[1] == (59.0, 39.0)                     # the pixel centres along the outer edge
    assert spans[0][0] <= 11 and spans[0][1] <= 11     # the hole


def test_run_logs_the_same_set_up_to_the_view(strip_images, tmp_path):
    from tests.stream.view.test_logger import _rows
    rrd = tmp_path / "v.rrd"
    assert main(["run", "--source", f"images:{strip_images}", "--n-points", "300", "--exclude", "circle:150,200,20",
                 "--gauge-length", "200", "--viewer", "save", str(rrd), "--no-record"]) == 0
    labels = _rows(rrd, "/setup/labels", "Points2D:labels")["static"] + \
        _rows(rrd, "/setup/region/label", "Points2D:labels")["static"]
    assert "specimen (found)" in str(_rows(rrd, "/camera/roi/label", "Points2D:labels")["static"])
    text = " ".join(str(t) for t in labels)
    assert "specimen (found)" in text and "excluded" in text and "axial L0 200 px" in text and "P0" in text
    points = _rows(rrd, "/setup/points", "Points2D:positions")["static"]
    assert len(points) >= 250
    assert _rows(rrd, "/camera/roi", "LineStrips2D:strips")["static"]
    notes = _rows(rrd, "/setup_notes", "TextDocument:text")["static"]
    assert "mean intensity gradient" in str(notes)


def test_a_given_region_across_the_specimens_edge_is_pointed_out(strip_images):
    """The whole image as ROI: the points whose subset lies across the strip's edges or the hole's are named."""
    image = cv2.imread(str(strip_images / "f0.png"), cv2.IMREAD_GRAYSCALE)
    placement = place_points(image, PointsConfig(roi="full", step=10), subset=21)
    overlay = setup_overlay(image, placement, subset=21)
    x, y = placement.points[:, 0], placement.points[:, 1]
    near_edge = (np.abs(x - 99.5) < 8) | (np.abs(x - 199.5) < 8) | (np.abs(np.hypot(x - HOLE[0], y - HOLE[1]) - HOLE[2]) < 6)
    assert overlay.straddle[near_edge].all()
    assert not overlay.straddle[(np.abs(x - 150) < 25) & (np.hypot(x - HOLE[0], y - HOLE[1]) > HOLE[2] + 20)].any()
    assert any("across the specimen's edge" in line for line in overlay.advice())
    found = setup_overlay(image, place_points(image, PointsConfig(step=10), subset=21), subset=21)
    assert not found.straddle.any()
