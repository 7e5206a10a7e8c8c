"""Where a session's points go: the given region, a mask, exclusions, or the speckled specimen it finds.

The images are a strip of blurred-noise texture on a smooth noisy background (``tests.conftest.specimen_scene``),
not the simulator's speckle. The whole-session test stretches that strip as a tensile test does, its edges
narrowing past the still background: no fracture, every specimen point ok, both extensometers reading.
"""

import json
import os

import cv2
import numpy as np
import pytest

from livedic.dic.region import Circle, Polygon, Rectangle
from livedic.stream.session.config import PointsConfig, SessionConfig, ViewerConfig
from livedic.stream.session.parsing import parse_roi
from livedic.stream.session.points import PlacedBy, place_points
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import StrainConfig
from tests.conftest import specimen_scene

SUBSET = 21
HALF = SUBSET // 2


def subsets_inside(points, mask):
    """Whether every point's whole subset lies on True pixels of ``mask``."""
    return all(mask[int(y) - HALF:int(y) + HALF + 1, int(x) - HALF:int(x) + HALF + 1].all() and
               int(y) - HALF >= 0 and int(x) - HALF >= 0 for x, y in points)


@pytest.fixture(scope="module")
def scene():
    return specimen_scene(noise=2.5, seed=11)


def test_without_a_region_the_points_go_on_the_speckled_specimen(scene):
    image, truth = scene
    placed = place_points(image, PointsConfig(n_points=150), subset=SUBSET)
    assert placed.placed_by is PlacedBy.SPECIMEN
    assert subsets_inside(placed.points, truth)
    assert 120 <= len(placed.points) <= 180
    assert 95 <= placed.bounds[0] <= 103 and 94 <= placed.bounds[2] <= 104       # the strip, columns 100..199
    assert "speckled specimen" in placed.describe()
    assert placed.as_metadata()["placed_by"] == "specimen"


def test_a_source_region_is_used_unless_auto_is_asked(scene):
    image, _ = scene
    placed = place_points(image, PointsConfig(n_points=50), subset=SUBSET, suggested_roi=(110, 40, 80, 300))
    assert placed.placed_by is PlacedBy.SOURCE and placed.bounds == (110, 40, 80, 300)
    auto = place_points(image, PointsConfig(roi="auto", n_points=50), subset=SUBSET, suggested_roi=(110, 40, 80, 300))
    assert auto.placed_by is PlacedBy.SPECIMEN


def test_full_is_the_whole_image(scene):
    image, _ = scene
    placed = place_points(image, PointsConfig(roi="full", step=30), subset=SUBSET)
    assert placed.placed_by is PlacedBy.WHOLE_IMAGE
    assert placed.points[:, 0].min() == HALF + 1 or placed.points[:, 0].min() <= 30


def test_no_subset_reaches_into_an_exclusion(scene):
    image, _ = scene
    hole = Circle(150, 200, 18)
    placed = place_points(image, PointsConfig(roi="auto", exclude=(hole,), step=6), subset=SUBSET)
    x, y = placed.points[:, 0], placed.points[:, 1]
    # the nearest pixel of a subset square to the circle's centre is farther than the radius
    dx = np.maximum(np.abs(x - hole.x) - HALF, 0)
    dy = np.maximum(np.abs(y - hole.y) - HALF, 0)
    assert np.all(np.hypot(dx, dy) > hole.r)
    assert np.min(np.hypot(x - hole.x, y - hole.y)) < hole.r + HALF * 1.5 + 6    # but they come close
    assert "excluding circle:150,200,18" in placed.describe()


def test_a_polygon_roi_keeps_every_subset_inside_it(scene):
    image, _ = scene
    polygon = parse_roi("polygon:110,30,190,30,170,380,130,380")
    assert isinstance(polygon, Polygon)
    placed = place_points(image, PointsConfig(roi=polygon, step=8), subset=SUBSET)
    inside = np.zeros(image.shape, dtype=bool)
    polygon.fill(inside)
    assert placed.placed_by is PlacedBy.GIVEN_REGION and subsets_inside(placed.points, inside)


def test_a_mask_and_an_roi_both_bound_the_points(scene):
    image, _ = scene
    mask = np.zeros(image.shape, dtype=bool)
    mask[50:350, 120:180] = True
    placed = place_points(image, PointsConfig(roi=Rectangle(0, 0, 300, 200), mask=mask, mask_file="m.png", step=5),
                          subset=SUBSET)
    both = mask.copy()
    both[200:] = False
    assert subsets_inside(placed.points, both)


def test_given_points_that_an_exclusion_reaches_are_left_out(scene):
    image, _ = scene
    given = np.array([[150.0, 100.0], [150.0, 200.0], [150.0, 300.0], [138.0, 205.0], [128.0, 205.0]])
    placed = place_points(image, PointsConfig(xy=given, exclude=(Circle(150, 200, 5),)), subset=SUBSET)
    kept = {tuple(p) for p in placed.points} & {tuple(p) for p in given}
    assert kept == {(150.0, 100.0), (150.0, 300.0), (128.0, 205.0)}     # 138: its subset reaches x = 148
    assert placed.dropped == 2
    with pytest.raises(ValueError, match="none is left"):
        place_points(image, PointsConfig(xy=given[1:2], exclude=(Circle(150, 200, 5),)), subset=SUBSET)


def test_a_region_beyond_the_image_is_refused(scene):
    image, _ = scene
    with pytest.raises(ValueError, match="extends beyond the 300x400 image"):
        place_points(image, PointsConfig(roi=(200, 10, 200, 50)), subset=SUBSET)


# ----------------------------------------------------------------------------- a whole session

@pytest.fixture(scope="module")
def stretched_sequence(tmp_path_factory):
    """A strip stretched to 6 % in 13 frames (0.5 % a frame), narrowing by 0.4 x that past the still background."""
    folder = tmp_path_factory.mktemp("stretch")
    for k in range(13):
        image, _ = specimen_scene(noise=2.0, seed=7, strain=0.005 * k, poisson=0.4)
        cv2.imwrite(str(folder / f"frame_{k:03d}.png"), image)
    return folder


def test_a_narrowing_specimen_with_defaults_tracks_to_the_end_with_no_fracture(stretched_sequence, tmp_path):
    """The issue's real dog-bone in miniature: no --roi, the edges narrow past the background.

    Every point whose subset stays in the image is ok and right in every frame (the bottom rows' material
    leaves the image as it stretches: those are OUTSIDE_TARGET, never ok).
    """
    config = SessionConfig(source=f"images:{stretched_sequence}", viewer=ViewerConfig("none"), record=None,
                           warm_up=False, strain=StrainConfig(gauge_length=240))
    results = []
    with Session(config) as session:
        session.prepare()
        session._extra_sinks.append(lambda result, stats: results.append(result))
        session.start()
        session.run()
    summary = session.summary()
    assert session.placement.placed_by is PlacedBy.SPECIMEN
    assert summary["fractures"] == [] and summary["frames"] == 13
    x, y = session.points[:, 0], session.points[:, 1]
    for k, result in enumerate(results):
        strain = 0.005 * k
        m = result.measurement
        in_view = y * (1 + strain) + HALF + 3 < 399
        assert m.ok[in_view].all(), f"frame {k}: {int((~m.ok[in_view]).sum())} points in view not ok"
        assert not m.ok[~in_view].any()
        u_true, v_true = -(x - 149.5) * 0.4 * strain, y * strain        # the stretch specimen_scene renders
        error = np.hypot(m.u - u_true, m.v - v_true)[m.ok]       # the rendering's cubic interpolation and noise
        assert error.max() < 0.15 and np.sqrt(np.mean(error ** 2)) < 0.05     # a subset over an edge: tenths
    readings = summary["strain"]["extensometers"]
    assert set(readings) == {"axial", "transverse"}
    assert readings["axial"]["eng_strain"] == pytest.approx(0.06, abs=5e-4)
    assert readings["transverse"]["eng_strain"] == pytest.approx(-0.4 * 0.06, abs=2e-3)


def test_run_records_where_the_points_went(stretched_sequence, tmp_path):
    from livedic.bench.cli import main
    record = tmp_path / "r.mcap"
    code = main(["run", "--source", f"images:{stretched_sequence}", "--frames", "3", "--viewer", "none",
                 "--record", str(record), "--exclude", "circle:150,200,20", "--n-points", "200"])
    assert code == 0
    from livedic.acquire.recording.reader import read_session
    session = read_session(str(record))
    region = session["region"]
    assert region["placed_by"] == "specimen" and region["exclude"] == ["circle:150,200,20"]
    assert 95 <= region["bounds"][0] <= 103


def test_replay_in_another_region_places_points_there_or_says_what_to_do(stretched_sequence, tmp_path, capsys):
    from livedic.bench.cli import main
    record = tmp_path / "g.mcap"
    assert main(["run", "--source", f"images:{stretched_sequence}", "--frames", "3", "--viewer", "none",
                 "--record", str(record), "--gauge-length", "240", "--n-points", "300"]) == 0
    capsys.readouterr()
    out = tmp_path / "r.csv"
    # the recorded extensometers reach beyond a smaller region: one line saying how to place new ones
    assert main(["replay", str(record), "--roi", "110,150,80,100", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the recording's axial extensometer does not fit" in err and "--gauge-length" in err
    assert main(["replay", str(record), "--roi", "110,150,80,100", "--gauge-length", "60", "-o", str(out)]) == 0
    import csv
    rows = list(csv.DictReader(open(out)))
    xs, ys = np.array([float(r["x"]) for r in rows]), np.array([float(r["y"]) for r in rows])
    assert xs.min() >= 110 + HALF and xs.max() <= 189 - HALF and ys.min() >= 150 + HALF and ys.max() <= 249 - HALF
