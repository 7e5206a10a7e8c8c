"""Tests of stream/stages/strain.py: strain settings, extensometers placed on the points, the per-frame stage."""

import argparse
import math
from types import SimpleNamespace

import numpy as np
import pytest

from livedic.dic.strain.extensometer import AXIAL, BAND, LOCAL, TRANSVERSE, Extensometer, ExtensometerOffPoints
from livedic.stream.stages.strain import (NOISE_LIMIT, StrainConfig, add_strain_arguments, format_length,
                                          format_strain_summary, parse_extensometer, parse_gauge_length)

STEP, SUBSET = 10.0, 11
ROI = (0, 0, 200, 300)


def _grid():
    xs, ys = np.meshgrid(np.arange(0.0, 201.0, STEP), np.arange(0.0, 301.0, STEP))
    return np.column_stack([xs.ravel(), ys.ravel()])


@pytest.fixture(scope="module")
def stage():
    """Axial 200 px and transverse 100 px through P0 (100, 150), plus one more, on a 10 px grid."""
    config = StrainConfig(gauge_length=200.0, gauge_width=100.0,
                          extensometers=(Extensometer("upper", 50.0, 50.0, 150.0, 50.0),))
    return config.place(_grid(), p0=(100.0, 150.0), roi=ROI, step=STEP, subset=SUBSET)


def test_gauge_length_in_mm_with_a_scale():
    config = StrainConfig(gauge_length=20.0, scale=10.0)
    extensometers = config.resolve_extensometers((100.0, 200.0), (0, 0, 150, 400))
    assert extensometers[0].length_px == pytest.approx(200.0)
    assert extensometers[1].length_px == pytest.approx(0.8 * 150)


def test_option_parsing():
    assert parse_gauge_length("400") == (400.0, None)
    assert parse_gauge_length("400,120") == (400.0, 120.0)
    e = parse_extensometer("upper=1,2,3,4.5")
    assert (e.name, e.x1, e.y1, e.x2, e.y2) == ("upper", 1.0, 2.0, 3.0, 4.5)
    for bad in ("0", "-3", "a,b", "1,2,3"):
        with pytest.raises(ValueError, match="--gauge-length"):
            parse_gauge_length(bad)
    for bad in ("nameonly", "x=1,2,3", "x=1,2,1,2", "bad name=1,2,3,4"):
        with pytest.raises(ValueError, match="--extensometer"):
            parse_extensometer(bad)
    with pytest.raises(ValueError, match="--strain-window"):
        StrainConfig(window=4)
    with pytest.raises(ValueError, match="that name is --gauge-length's"):
        StrainConfig(gauge_length=100, extensometers=(parse_extensometer("axial=1,2,3,4"),))


def test_the_pair_is_placed_on_p0_then_the_others():
    config = StrainConfig(gauge_length=200.0, extensometers=(parse_extensometer("e=1,2,3,4"),))
    placed = config.resolve_extensometers((100.0, 150.0), ROI)
    assert [e.name for e in placed] == [AXIAL, TRANSVERSE, "e"]
    assert (placed[0].x1, placed[0].y1, placed[0].x2, placed[0].y2) == (100.0, 50.0, 100.0, 250.0)
    assert (placed[1].x1, placed[1].x2, placed[1].y1) == (20.0, 180.0, 150.0)      # 0.8 x the ROI width
    # kept on the points: P0 30 px from the points' left end gives a 60 px transverse
    narrow = config.resolve_extensometers((100.0, 150.0), ROI, x_range=(70.0, 200.0))
    assert narrow[1].length_px == pytest.approx(60.0)
    assert StrainConfig().resolve_extensometers((1.0, 2.0), ROI) == ()


def test_a_uniform_stretch_reads_exactly_on_every_extensometer_and_in_the_field(stage):
    """v = e y, u = -nu e x: axial reads e, transverse -nu e, the field e_yy = e (engineering)."""
    points = stage.points
    e, nu = 0.004, 0.3
    u, v, ok = -nu * e * points[:, 0], e * points[:, 1], np.ones(len(points), dtype=bool)
    strain, readings = stage.compute(u, v, ok)
    assert readings.names == (AXIAL, TRANSVERSE, "upper") and readings.ok.all()
    np.testing.assert_allclose(readings.eng_strain, [e, -nu * e, -nu * e], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(readings.true_strain, np.log1p(readings.eng_strain), rtol=1e-12)
    assert np.nanmax(np.abs(strain.eyy[strain.ok] - e)) < 1e-9 and strain.ok.sum() > 0.5 * len(points)
    assert set(stage.last_timings) == {"strain", "extensometers"}


def test_exact_readings_of_a_truth(stage):
    exact = stage.exact_readings(lambda x, y: (0.0 * x, 0.01 * y))
    np.testing.assert_allclose(exact, [0.01, 0.0, 0.0], atol=1e-12)


def test_after_a_fracture_the_opening_is_no_strain_on_either_side(stage):
    """A crack across y = 145: the upper part moves 5 px up rigidly; windows and ends use their own side only."""
    config = StrainConfig(window=3, extensometers=(Extensometer("low", 100.0, 170.0, 100.0, 250.0),
                                                  Extensometer("across", 100.0, 100.0, 100.0, 200.0)))
    cracked = config.place(_grid(), p0=(100.0, 150.0), roi=ROI, step=STEP, subset=SUBSET)
    points = cracked.points
    v = np.where(points[:, 1] < 145, -5.0, 0.0)
    u, ok = np.zeros(len(points)), np.ones(len(points), dtype=bool)
    cracked.add_fracture(SimpleNamespace(centre=(100.0, 145.0), direction=(1.0, 0.0)))
    strain, readings = cracked.compute(u, v, ok)
    assert readings.reading("low")[0] == pytest.approx(0.0, abs=1e-12)
    assert np.nanmax(np.abs(strain.eyy)) < 1e-9                    # no window reads the opening
    assert set(np.unique(cracked.point_labels)) == {0, 1}


def test_an_end_off_the_points_is_one_line_naming_it():
    config = StrainConfig(extensometers=(Extensometer("far", 100.0, 100.0, 100.0, 900.0),), scale=5.0)
    with pytest.raises(ExtensometerOffPoints) as error:
        config.place(_grid(), p0=(100.0, 150.0), roi=ROI, step=STEP, subset=SUBSET)
    assert "far" in str(error.value) and str(error.value).endswith("(5 px/mm)") and "\n" not in str(error.value)


@pytest.mark.parametrize("settings, words", [
    (dict(window=4), "--strain-window must be an odd number of points >= 3, got 4"),
    (dict(window=1), "--strain-window must be an odd number"),
    (dict(measure="cauchy"), "--strain-measure 'cauchy': choose one of"),
    (dict(scale=0.0), "--scale must be a positive number of pixels per mm"),
    (dict(scale=math.inf), "--scale must be a positive number"),
    (dict(gauge_width=50.0), "a transverse gauge width needs --gauge-length L,W"),
    (dict(extensometers=(Extensometer("a", 0, 0, 1, 1), Extensometer("a", 2, 2, 3, 3))), "names must differ: a, a"),
])
def test_strain_settings_are_validated_in_one_line(settings, words):
    with pytest.raises(ValueError, match=None) as error:
        StrainConfig(**settings)
    assert words in str(error.value) and "\n" not in str(error.value)


def test_the_end_fit_is_recorded_and_replayed_and_older_recordings_keep_the_local_fit(stage):
    # the session's axial uses the band, its transverse the local fit; the metadata says which, per extensometer
    assert {e.name: e.end_fit for e in stage.extensometers} == {AXIAL: BAND, TRANSVERSE: LOCAL, "upper": LOCAL}
    recorded = {**stage.config.as_metadata(), **stage.metadata()}
    assert recorded["extensometer_end_fits"] == {AXIAL: BAND, TRANSVERSE: LOCAL, "upper": LOCAL}
    again = StrainConfig.from_metadata(recorded)
    assert {e.name: e.end_fit for e in again.extensometers} == {AXIAL: BAND, TRANSVERSE: LOCAL, "upper": LOCAL}
    # a recording made before the choice existed was measured with the local fit: replayed so
    older = {k: v for k, v in recorded.items() if k not in ("extensometer_end_fits", "axial_end_fit")}
    assert {e.end_fit for e in StrainConfig.from_metadata(older).extensometers} == {LOCAL}
    # --extensometer-ends on a replay applies to the recorded axial one
    chosen = StrainConfig.from_metadata(recorded, axial_end_fit=LOCAL)
    assert {e.name: e.end_fit for e in chosen.extensometers}[AXIAL] == LOCAL
    assert StrainConfig(gauge_length=100.0, axial_end_fit=LOCAL).resolve_extensometers(
        (300.0, 300.0), (0, 0, 600, 600))[0].end_fit == LOCAL
    with pytest.raises(ValueError, match="--extensometer-ends 'disk': choose one of local, band"):
        StrainConfig(axial_end_fit="disk")


def test_metadata_round_trip_and_an_older_recording_gets_the_defaults(stage):
    config = StrainConfig(window=7, measure="green", gauge_length=10.0, scale=4.0,
                          extensometers=(Extensometer("e", 1.0, 2.0, 3.0, 4.0),))
    again = StrainConfig.from_metadata(config.as_metadata())
    assert (again.window, again.measure, again.scale) == (7, "green", 4.0)
    assert again.extensometers == config.extensometers and again.gauge_length is None   # placed ones, as given
    # the placed extensometers (metadata) are what a replay measures between, not the given options
    placed = StrainConfig.from_metadata({**config.as_metadata(), **stage.metadata()})
    assert [e.name for e in placed.extensometers] == [AXIAL, TRANSVERSE, "upper"]
    assert StrainConfig.from_metadata({}) == StrainConfig()
    assert StrainConfig.from_metadata({"scale_px_per_mm": "nan", "strain_window": ""}) == StrainConfig()
    assert StrainConfig.from_metadata({"strain_window": 9}, window=3).window == 3        # an override wins


def test_options_parse_into_the_config_and_recorded_commands_keep_the_recording():
    parser = add_strain_arguments(argparse.ArgumentParser())
    args = parser.parse_args(["--gauge-length", "40,20", "--scale", "2", "--extensometer", "e=1,2,3,4"])
    config = StrainConfig.from_args(args)
    assert (config.gauge_length, config.gauge_width, config.scale) == (40.0, 20.0, 2.0)
    assert config.to_px(40.0) == 80.0 and config.in_mm(80.0) == 40.0 and StrainConfig().in_mm(80.0) is None
    recorded = add_strain_arguments(argparse.ArgumentParser(), recorded=True)
    kept = StrainConfig.from_args(recorded.parse_args([]), recorded_metadata={"strain_window": 9,
                                                                            "strain_measure": "true"})
    assert (kept.window, kept.measure) == (9, "true")


def test_summary_and_its_lines(stage):
    points = stage.points
    stage.on_frame(SimpleNamespace(fracture=None, measurement=SimpleNamespace(
        u=np.zeros(len(points)), v=0.01 * points[:, 1], ok=np.ones(len(points), dtype=bool)),
        frame=SimpleNamespace(metadata={"truth": lambda x, y: (0.0 * x, 0.01 * y)}), strain=None, extensometers=None))
    summary = stage.summary()
    axial = summary["extensometers"][AXIAL]
    assert axial["L0_px"] == pytest.approx(200.0) and axial["eng_strain"] == pytest.approx(0.01) and axial["ok"]
    assert axial["error_max_vs_truth"] == pytest.approx(0.0, abs=1e-9) and axial["L0_mm"] is None
    lines = format_strain_summary(summary)
    assert lines[1] == "  extensom.  axial: L0 200.0 px, final 1.000 % engineering, 0.995 % true; " \
                       "max error vs truth 0 microstrain"
    assert format_strain_summary(None) == [] and format_length(400.0, 32.0) == "400.0 px (32.00 mm)"
    assert stage.describe().startswith(f"strain: engineering, window 5 points x step 10 px + subset {SUBSET}")


# --------------------------------------------------------------------------- extensometer noise and room

def _wide_grid(width, step):
    xs, ys = np.meshgrid(np.arange(300.0, 300 + width + 1, step), np.arange(100.0, 701.0, step))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    p0 = points[np.argmin(np.hypot(points[:, 0] - (300 + width / 2), points[:, 1] - 400))]
    return points, p0


def test_expected_noise_falls_as_one_over_the_length_and_warns_below_class_1():
    points, p0 = _wide_grid(600, 10)
    stage = StrainConfig(extensometers=[parse for parse in (
        _ext("short", 560, 400, 600, 400), _ext("long", 400, 400, 800, 400))]).place(
        points, p0=p0, roi=(300, 100, 600, 600), step=10, subset=21)
    short, long_ = stage.expected_noise()
    assert short / long_ == pytest.approx(400 / 40, rel=0.25)         # same ends' fits: 1 / L0
    assert long_ < NOISE_LIMIT < short
    warnings = stage.noise_warnings()
    assert len(warnings) == 1 and warnings[0].startswith("extensometer short: L0 40 px expects ~")
    # the length needed is that of ends sharing no point (a short one's shared points cancel in the difference)
    from livedic.dic.strain.extensometer import strain_noise
    apart = strain_noise(stage.placed, stage.points, 0.01, independent_ends=True)[0]
    assert apart >= short
    needed = 40 * apart / NOISE_LIMIT
    assert f"it needs L0 >= {needed:.0f} px; move its ends apart" in warnings[0]


def test_a_very_short_extensometer_is_not_told_it_needs_less_than_a_long_one():
    """Its ends share most of their points, whose errors cancel: its own noise says little of the length needed
    (a new user's trial read 'a 5 px one needs >= 79 px' beside 'a 244 px one needs >= 373 px')."""
    points, p0 = _wide_grid(600, 10)
    stage = StrainConfig(extensometers=[_ext("tiny", 600, 400, 605, 400), _ext("long", 400, 400, 800, 400)]).place(
        points, p0=p0, roi=(300, 100, 600, 600), step=10, subset=21)
    tiny = next(line for line in stage.noise_warnings() if line.startswith("extensometer tiny"))
    needed = float(tiny.split("it needs L0 >= ")[1].split(" px")[0])
    assert needed > 300


def _ext(name, x1, y1, x2, y2):
    from livedic.dic.strain.extensometer import Extensometer
    return Extensometer(name, x1, y1, x2, y2)


def test_an_automatic_transverse_shorter_than_a_subset_is_refused_in_one_line():
    points, _ = _wide_grid(40, 7)
    edge = np.array([points[:, 0].max(), 401.0])             # P0 on the points' right edge: no room on one side
    with pytest.raises(ValueError, match=r"^the automatic transverse extensometer would be 0 px, less than one "
                                         r"subset \(21 px\): P0 at x 335 and the tracked points at x 300..335; .*give "
                                         r"--gauge-length L,W$"):
        StrainConfig(gauge_length=200).place(points, p0=edge, roi=(300, 100, 40, 600), step=7, subset=21)
    StrainConfig(gauge_length=200, gauge_width=20).place(points, p0=edge - (20, 0), roi=(300, 100, 40, 600), step=7,
                                                         subset=21)      # a given width is the user's
