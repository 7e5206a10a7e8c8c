"""Tests of stream/session/config.py: each setting checked once when a config is built, one line naming the option."""

import numpy as np
import pytest

from livedic.dic.region import Polygon, Rectangle
from livedic.stream.cli import LivedicParser
from livedic.stream.cli.run import add_run_arguments
from livedic.stream.session.config import (DEFAULT_MAX_POINTS, DEFAULT_POINTS, OFFLINE_INTERPOLATION, OFFLINE_PREFILTER,
                                           MeasureConfig, PointsConfig, SessionConfig, TrackingConfig, ViewerConfig,
                                           session_name, unique_path)
from livedic.stream.stages.strain import StrainConfig


def _one_line_error(make, words):
    with pytest.raises(ValueError) as error:
        make()
    assert words in str(error.value) and "\n" not in str(error.value), str(error.value)


# --------------------------------------------------------------------------- tracking and measure


@pytest.mark.parametrize("config", [TrackingConfig, MeasureConfig])
def test_interpolation_is_canonical_and_checked_against_the_method(config):
    assert config(subpixel="icgn", interpolation="BSPLINE5").interpolation == "bspline5"
    assert config().interpolation == "bspline3"
    _one_line_error(lambda: config(subpixel="icgn2", interpolation="bspline5"),
                    "--interpolation bspline5 is not available with --subpixel icgn2: use it with icgn")
    _one_line_error(lambda: config(interpolation="bspline2"), "unknown interpolation 'bspline2'")


def test_measure_defaults_to_the_septic_and_its_prefilter_where_the_method_samples_it_run_keeps_the_cubic():
    """``measure``'s offline defaults (``measure_defaults``); what is given is kept; ``run``/``replay`` unchanged."""
    assert (MeasureConfig(subpixel="icgn").interpolation, MeasureConfig(subpixel="icgn").prefilter) == \
        (OFFLINE_INTERPOLATION, OFFLINE_PREFILTER) == ("bspline7", "gaussian:0.45")
    for subpixel in ("icgn2", "newton-raphson", "improved-surface-fit"):      # they sample no septic
        assert (MeasureConfig(subpixel=subpixel).interpolation, MeasureConfig(subpixel=subpixel).prefilter) == \
            ("bspline3", "none"), subpixel
    assert MeasureConfig(subpixel="icgn", interpolation="bspline3").prefilter == "none"   # goes with the septic
    assert MeasureConfig(subpixel="icgn", prefilter="none").interpolation == "bspline7"
    assert MeasureConfig(subpixel="icgn", prefilter="gaussian:0.80").prefilter == "gaussian:0.8"
    assert (TrackingConfig().interpolation, TrackingConfig().prefilter) == ("bspline3", "none")
    _one_line_error(lambda: MeasureConfig(subpixel="icgn", prefilter="box:1"), "unknown pre-filter 'box:1'")


def test_measure_defaults_round_trip_through_the_command_line_and_the_config():
    """Not given: resolved once; the resolved values given back make the same config; --help names the rule."""
    import argparse

    from livedic.stream.session.options import add_config_arguments, config_values
    parser = argparse.ArgumentParser()
    add_config_arguments(parser, MeasureConfig)
    config = MeasureConfig(**config_values(MeasureConfig, parser.parse_args(["--subpixel", "icgn"])))
    assert (config.interpolation, config.prefilter) == ("bspline7", "gaussian:0.45")
    again = parser.parse_args(["--subpixel", "icgn", "--interpolation", config.interpolation,
                               "--prefilter", config.prefilter])
    assert MeasureConfig(**config_values(MeasureConfig, again)) == config
    search = config.search
    assert config.described() == f"{search} + icgn, pre-filter gaussian:0.45, interpolation bspline7"
    assert MeasureConfig(subpixel="surface-fit").described() == f"{search} + surface-fit, pre-filter none"
    text = " ".join(parser.format_help().split())
    assert "(default bspline7 with the methods that sample it (icgn), else bspline3)" in text
    assert "(default gaussian:0.45 with bspline7, else none)" in text


def test_measure_defaults_cut_the_bias_of_a_rendered_sub_pixel_shift():
    """Sample 3's physics on a pattern rendered here: fine speckles (content near Nyquist) shifted 0.3 and 0.7 px,
    8-bit. The cubic without a filter reads a bias of 0.002-0.003 px; measure's defaults (septic, gaussian:0.45)
    stay under 0.001 px (measured 0.0005), at the same scatter."""
    from livedic.dic import measure
    from livedic.dic.speckle import SpecklePattern, render
    pattern = SpecklePattern((160, 160), n_speckles=1900, radius=1.5, seed=3)
    reference = render(pattern, bit_depth=8)
    axis = np.arange(30.0, 131.0, 10.0)
    points = np.column_stack([a.ravel() for a in np.meshgrid(axis, axis)])
    offline = MeasureConfig(subpixel="icgn")
    worst, scatter = {}, {}
    for shift in (0.3, 0.7):
        deformed = render(pattern, (shift, shift), bit_depth=8)
        for name, settings in (("today", dict(interpolation="bspline3", prefilter="none")),
                               ("default", dict(interpolation=offline.interpolation, prefilter=offline.prefilter))):
            m = measure(reference, deformed, points, subpixel="icgn", subset=21, **settings)
            assert m.ok.all(), name
            errors = np.concatenate([m.u - shift, m.v - shift])
            worst[name] = max(worst.get(name, 0.0), abs(np.mean(m.u - shift)), abs(np.mean(m.v - shift)))
            scatter[name] = max(scatter.get(name, 0.0), float(np.std(errors)))
    assert worst["today"] > 0.002 and worst["default"] < 0.001
    assert scatter["default"] < 1.1 * scatter["today"]


@pytest.mark.parametrize("settings, words", [
    (dict(subset=20), "--subset must be an odd integer >= 3, got 20"),
    (dict(subset=1), "--subset must be an odd integer >= 3, got 1"),
    (dict(subpixel="none"), "--subpixel none gives integer displacements only"),
    (dict(seed_radius=-1), "--seed-radius must be >= 0, got -1"),
    (dict(refind_radius=-2), "--refind-radius must be >= 0, got -2"),
    (dict(refind_zncc=1.01), "--refind-zncc must be between -1 and 1"),
    (dict(min_zncc=-1.5), "--min-zncc must be between -1 and 1"),
    (dict(reference_update="sometimes"), "--reference-update 'sometimes'"),
])
def test_tracking_settings_are_validated_in_one_line(settings, words):
    _one_line_error(lambda: TrackingConfig(**settings), words)


def test_tracking_limits_are_inclusive_and_the_update_policy_is_normalised():
    config = TrackingConfig(subset=3, seed_radius=0, refind_radius=0, refind_zncc=-1.0, min_zncc=1.0,
                            reference_update=" Every:5 ")
    assert config.reference_update == "every:5"
    assert config.method == f"{config.search}+{config.subpixel}"
    assert TrackingConfig.keys() == tuple(config.as_dict())
    assert TrackingConfig.keys()[:3] == ("subset", "search", "subpixel")


def test_a_tracker_gets_the_settings_the_gate_and_the_overrides(monkeypatch):
    import livedic.dic.tracking.key_frames as key_frames
    made = {}

    def capture(image, points, **settings):
        made.update(settings, image=image, points=points)
        return "tracker"

    monkeypatch.setattr(key_frames, "KeyFrameTracker", capture)
    image, points = np.zeros((8, 8), np.uint8), np.zeros((1, 2))
    assert TrackingConfig(subset=11, min_zncc=0.5, seed=3).tracker(image, points, subset=7) == "tracker"
    assert made["image"] is image and made["points"] is points
    assert made["subset"] == 7 and made["seed"] == 3 and "min_zncc" not in made
    assert made["gates"].min_zncc == 0.5
    assert set(made) == set(TrackingConfig.keys()) - {"min_zncc"} | {"gates", "image", "points"}


@pytest.mark.parametrize("settings, words", [(dict(subset=20), "--subset must be an odd integer >= 3"),
                                             (dict(radius=-1), "--radius must be >= 0"),
                                             (dict(min_zncc=1.5), "--min-zncc must be between -1 and 1"),
                                             (dict(search="magic"), "unknown search method 'magic'"),
                                             (dict(subpixel="magic"), "unknown sub-pixel method 'magic'")])
def test_measure_settings_are_validated_in_one_line(settings, words):
    with pytest.raises(ValueError) as error:
        MeasureConfig(**settings)
    assert words in str(error.value) and "\n" not in str(error.value)


def test_measure_method_names_both_parts():
    assert MeasureConfig(subpixel="none").method == f"{MeasureConfig().search} + none"


# --------------------------------------------------------------------------- points

def test_a_roi_tuple_becomes_a_rectangle_and_p0_floats():
    points = PointsConfig(roi=(10.7, 20, 30, 40), p0=(5, 6))
    assert points.roi == Rectangle(10, 20, 30, 40) and points.p0 == (5.0, 6.0)
    assert points.region.outline == Rectangle(10, 20, 30, 40)
    assert PointsConfig(roi="auto").region.outline is None and PointsConfig(roi="full").region.outline is None
    assert (PointsConfig().n_points, PointsConfig().max_points) == (DEFAULT_POINTS, DEFAULT_MAX_POINTS)


@pytest.mark.parametrize("settings, words", [
    (dict(roi=(1, 2, 3)), "--roi must be 4 comma-separated numbers"),
    (dict(roi=(1, 2, 0, 5)), "--roi width and height must be positive, got '1,2,0,5'"),
    (dict(roi="everywhere"), "--roi 'everywhere': give X,Y,W,H, polygon:X1,Y1,..., auto or full"),
    (dict(step=0), "--step must be a positive number of pixels, got 0"),
    (dict(n_points=0), "--n-points must be >= 1, got 0"),
    (dict(max_points=0), "--max-points must be >= 1, got 0"),
])
def test_points_settings_are_validated_in_one_line(settings, words):
    _one_line_error(lambda: PointsConfig(**settings), words)


def test_how_the_points_were_asked_for():
    assert PointsConfig(points_file="p.csv", xy=np.zeros((1, 2))).how(None) == "--points p.csv"
    assert PointsConfig(xy=np.zeros((1, 2))).how(None) == "the given points"
    assert PointsConfig(step=7).how(7) == "--step 7"
    assert PointsConfig(n_points=50).how(12.5) == "--n-points 50 (grid step 12.5 px)"
    assert PointsConfig(xy=np.zeros((1, 2))).given and not PointsConfig().given
    polygon = Polygon(((0, 0), (10, 0), (0, 10)))
    assert PointsConfig(roi=polygon).roi is polygon


# --------------------------------------------------------------------------- viewer and file names

def test_viewer_parse_and_describe(tmp_path):
    save = ViewerConfig.parse(["save"], str(tmp_path / "default.rrd"))
    assert save == ViewerConfig("save", str(tmp_path / "default.rrd"), None)
    assert save.describe() == f"save {tmp_path / 'default.rrd'}" and ViewerConfig().describe() == "none"
    with pytest.raises(ValueError, match="unknown viewer mode"):
        ViewerConfig.parse(["show"], "x.rrd")


def test_unique_path_never_names_an_existing_file(tmp_path):
    path = str(tmp_path / "run.mcap")
    assert unique_path(path) == path
    open(path, "w").close()
    assert unique_path(path) == str(tmp_path / "run-2.mcap")
    open(str(tmp_path / "run-2.mcap"), "w").close()
    assert unique_path(path) == str(tmp_path / "run-3.mcap")
    name = session_name()
    assert name.startswith("session-") and len(name) == len("session-YYYYmmdd-HHMMSS")


# --------------------------------------------------------------------------- the session

@pytest.mark.parametrize("settings, words", [
    (dict(frames=0), "--frames must be >= 1, got 0"),
    (dict(queue=0), "--queue must be >= 1 frame, got 0"),
    (dict(drop="random"), "unknown --drop 'random': choose one of auto, oldest, newest, block"),
    (dict(image_max_side=15), "--image-max-side must be >= 16 pixels, got 15"),
    (dict(record="x.mp4"), "--record file 'x.mp4' must end in .mcap"),
    (dict(color_range=(2, -2)), "--color-range 2,-2: LO must be below HI"),
    (dict(color_range=(0, float("inf"))), "LO must be below HI"),
    (dict(threads=0), "--threads must be between 1 and"),
    (dict(reconnect_timeout=5.0), "--reconnect-timeout needs --reconnect"),
    (dict(reconnect=True, source="aravis:", reconnect_timeout=0.0), "--reconnect-timeout must be a positive number"),
    (dict(reconnect=True), "--reconnect applies to cameras (aravis:, v4l2:); synthetic:tensile is a synthetic source"),
    (dict(publish=("tcp://:1",)), "--publish tcp://:1: unknown scheme 'tcp'"),
])
def test_session_settings_are_validated_in_one_line(settings, words):
    _one_line_error(lambda: SessionConfig(**settings), words)


def test_session_values_are_normalised():
    config = SessionConfig(color_range=[-1, 2], publish=["udp://:9870"], strain=StrainConfig(gauge_length=100))
    assert config.color_range == (-1.0, 2.0) and config.publish == ("udp://:9870",)
    assert [t.port for t in config.publish_targets] == [9870] and config.scheme == "synthetic"


def test_publish_needs_extensometers():
    with pytest.raises(ValueError, match="--publish sends extensometer strain: add --gauge-length"):
        SessionConfig(source="synthetic:tensile", publish=("udp://:9870",))
    assert SessionConfig(source="synthetic:tensile", publish=["udp://:9870"], strain=StrainConfig(gauge_length=200)).publish == \
        ("udp://:9870",)


def _parse(argv):
    parser = LivedicParser(prog="livedic run")
    add_run_arguments(parser)
    return parser.parse_args(argv + ["--progress", "off"])


def test_from_args_names_the_recording_and_the_view_beside_it(tmp_path):
    stem = str(tmp_path / "session-x")
    config = SessionConfig.from_args(_parse(["--viewer", "save", "--roi", "1,2,30,40", "--p0", "5,6"]), stem=stem)
    assert config.record == stem + ".mcap" and not config.record_named and config.name == "session-x"
    assert config.viewer == ViewerConfig("save", stem + ".rrd", None)
    assert config.points.roi == Rectangle(1, 2, 30, 40) and config.points.p0 == (5.0, 6.0)
    assert config.show_progress is False
    open(stem + ".mcap", "w").close()                                 # never an existing file
    assert SessionConfig.from_args(_parse([]), stem=stem).record == stem + "-2.mcap"
    unrecorded = SessionConfig.from_args(_parse(["--no-record", "--viewer", "save"]), stem=stem)
    assert unrecorded.record is None and unrecorded.viewer.target == stem + ".rrd"


def test_from_args_refuses_an_existing_record_file(tmp_path):
    existing = tmp_path / "kept.mcap"
    existing.write_bytes(b"data")
    _one_line_error(lambda: SessionConfig.from_args(_parse(["--record", str(existing)])),
                    "exists: choose a new name (recordings are never overwritten)")
    assert existing.read_bytes() == b"data"


@pytest.mark.parametrize("argv, words", [
    (["--area", "20"], "--area/--width/--thickness without --load"),
    (["--load-offset", "0.5"], "--load-offset without --load"),
    (["--load", "synthetic", "--load-offset", "nan"], "--load-offset nan: must be a finite number of seconds"),
])
def test_load_options_need_each_other(tmp_path, argv, words):
    _one_line_error(lambda: SessionConfig.from_args(_parse(argv + ["--no-record"]), stem=str(tmp_path / "s")), words)


def test_load_options_give_the_cross_section(tmp_path):
    config = SessionConfig.from_args(_parse(["--no-record", "--load", "synthetic", "--width", "4", "--thickness",
                                             "2.5", "--load-offset", "-0.25"]), stem=str(tmp_path / "s"))
    assert (config.load, config.area_mm2, config.load_offset) == ("synthetic", 10.0, -0.25)


@pytest.mark.parametrize("source", [
    "synthetic:translate?frames=3",
    "stereo:synthetic:stereo?view=left&frames=60,images:/nonexistent/*.png",
])
def test_load_synthetic_without_a_simulated_test_is_refused_before_any_work(tmp_path, monkeypatch, capsys, source):
    """--load synthetic with a source that has no force law: one line, exit 2, from the options alone: no source
    opened, no frame rendered (the check used to come after the simulator had rendered its whole test)."""
    from livedic.acquire import sources
    from livedic.acquire.simulator.sources import _PrerenderedSource
    from livedic.stream.cli.main import main

    def never(*args, **kwargs):
        raise AssertionError("the source was opened or rendered before the options were checked")
    monkeypatch.setattr(sources, "open_source", never)
    monkeypatch.setattr(_PrerenderedSource, "prepare", never)
    code = main(["run", "--viewer", "none", "--record", str(tmp_path / "s.mcap"), "--progress", "off",
                 "--source", source, "--load", "synthetic"])
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("livedic: error")]
    assert code == 2 and len(errors) == 1, errors
    assert "--load synthetic" in errors[0] and "no simulated test with a force law" in errors[0]
    assert not (tmp_path / "s.mcap").exists()
