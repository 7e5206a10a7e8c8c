"""Tests of stream/replay/points.py: a replay's points, recorded or rebuilt from the options and the metadata."""

import numpy as np
import pytest

from livedic.dic.region import Circle, Rectangle
from livedic.stream.replay.points import PointOptions, build_replay_points, recorded_region, replay_points_config
from livedic.stream.session.config import DEFAULT_POINTS
from livedic.stream.session.parsing import ROI_AUTO, ROI_FULL


def test_point_options_say_what_was_given():
    assert not PointOptions().given and not PointOptions().region_given
    assert PointOptions(step=10).given and not PointOptions(step=10).region_given
    assert PointOptions(exclude=("circle:5,5,2",)).region_given
    assert PointOptions(roi="10,20,30,40").region()["roi"] == Rectangle(10, 20, 30, 40)


@pytest.mark.parametrize("options, words", [
    (PointOptions(step=0), "--step"), (PointOptions(n_points=0), "--n-points"), (PointOptions(roi="1,2,3"), "--roi"),
])
def test_bad_point_options_are_one_line(options, words):
    with pytest.raises(ValueError) as error:
        options.check()
    assert words in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize("metadata, roi", [
    ({}, ROI_FULL),
    ({"roi": [10, 20, 30, 40]}, (10, 20, 30, 40)),
    ({"roi": "ROI centre"}, ROI_FULL),
    ({"roi": [10, 20, float("nan"), 40]}, ROI_FULL),
    ({"region": {"placed_by": "specimen"}}, ROI_AUTO),
    ({"region": {"placed_by": "given_region", "roi": "10,20,30,40"}}, Rectangle(10, 20, 30, 40)),
    ({"region": {"placed_by": "given_region", "mask": "/nowhere/mask.png", "bounds": [1, 2, 3, 4]}}, (1, 2, 3, 4)),
])
def test_recorded_region(metadata, roi):
    region = recorded_region(metadata)
    assert region["roi"] == roi and region["exclude"] == () and "mask" not in region


def test_recorded_exclusions_are_parsed_again():
    region = recorded_region({"region": {"placed_by": "specimen", "exclude": ["circle:50,60,5"]}})
    assert region["exclude"] == (Circle(50.0, 60.0, 5.0),)


def test_what_is_not_given_comes_from_the_metadata():
    metadata = {"roi": [10, 20, 100, 80], "step": 12, "n_points_wanted": 200, "p0": [40.0, 50.0]}
    config = replay_points_config(metadata, PointOptions(), None)
    assert (config.roi, config.step, config.n_points, config.p0) == (Rectangle(10, 20, 100, 80), 12, 200, (40.0, 50.0))
    given = replay_points_config(metadata, PointOptions(roi="0,0,50,50", p0="5,6"), None)
    assert given.roi == Rectangle(0, 0, 50, 50) and given.step is None and given.p0 == (5.0, 6.0)
    bare = replay_points_config({}, PointOptions(n_points=50), None)
    assert bare.roi == ROI_FULL and bare.step is None and bare.n_points == 50
    assert replay_points_config({}, PointOptions(), None).n_points == DEFAULT_POINTS


def test_a_recording_from_a_points_file_keeps_its_points_or_asks_for_the_file():
    metadata = {"points_file": "mine.csv"}
    xy = np.array([[30.0, 30.0], [40.0, 35.0]])
    config = replay_points_config(metadata, PointOptions(), xy)
    assert config.points_file == "mine.csv" and np.array_equal(config.xy, xy)
    with pytest.raises(ValueError, match="the recording tracked points from mine.csv: give --points FILE.csv"):
        replay_points_config(metadata, PointOptions(), None)


def test_build_replay_points_puts_the_recorded_or_given_p0_first(tmp_path):
    points = tmp_path / "points.csv"
    points.write_text("x,y\n40,40\n60,50\n")
    image = np.random.default_rng(0).uniform(0, 255, (100, 120)).astype(np.uint8)
    recorded = build_replay_points(image, {"p0": [60.0, 50.0]}, 21, PointOptions(points=str(points)), None)
    given = build_replay_points(image, {"p0": [40.0, 40.0]}, 21, PointOptions(points=str(points), p0="60,50"), None)
    assert np.array_equal(recorded, [[60.0, 50.0], [40.0, 40.0]]) and np.array_equal(given, recorded)
    placed = build_replay_points(image, {}, 21, PointOptions(points=str(points)), None)   # older: P0 placed anew
    assert len(placed) == 3 and np.array_equal(placed[1:], [[40.0, 40.0], [60.0, 50.0]])
