"""Tests of acquire/force/simulated.py: the simulated tensile test's force, one sample per frame, on session time."""

import math

import numpy as np
import pytest

from livedic.acquire.force import LoadError, TIME_BASE_SESSION, open_load
from livedic.acquire.force.simulated import SyntheticLoad
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource
from tests.acquire.force.loads import loading


def test_synthetic_load_gives_the_simulators_force_at_frame_times():
    source = SyntheticTensileSource("synthetic:tensile?frames=40&fps=25&size=128x128&pace=0&fracture=1")
    with loading("synthetic", source=source) as load:
        assert load.time_base == TIME_BASE_SESSION and load.specimen == source.specimen
        frame_times = np.arange(40) / 25.0                         # frame i at i / fps since the first frame
        forces = np.array([source.force_N(i) for i in range(40)])
        np.testing.assert_allclose(load.force_at(frame_times), forces, rtol=1e-12, atol=0)
        # Between two frames: linear interpolation (the first elastic frames are a straight line).
        np.testing.assert_allclose(load.force_at([0.01, 0.06]), [0.25 * forces[1], 0.5 * (forces[1] + forces[2])],
                                   rtol=1e-12)
        broken = source.fracture_frame
        assert np.all(load.force_at(frame_times[broken:]) == 0.0) and forces[broken - 1] > 0.0
        assert math.isnan(load.force_at(39 / 25.0 + 1e-6)) and math.isnan(load.force_at(-1e-6))
        assert load.last_sample_time_s == pytest.approx(39 / 25.0)
        assert load.settings["specimen"]["E_GPa"] == 200.0 and load.settings["source"] == source.uri


def test_synthetic_load_from_the_tests_uri_matches_the_cameras_force():
    uri = "synthetic:tensile?frames=30&size=128x128&modulus=70&hardening=0.4"
    with loading(uri) as load:
        camera = SyntheticTensileSource(uri)
        np.testing.assert_array_equal(load.samples()[1], camera.forces_N())
        np.testing.assert_allclose(load.samples()[0], np.arange(30) / 50.0, rtol=1e-15)
        assert load.specimen["Rm_MPa"] == pytest.approx(70e3 * 0.004 * 1.4, rel=1e-12)


def test_synthetic_load_offset_shifts_the_frames_as_a_csvs():
    # export and report pass offset_s (--load-offset) to every load: the same meaning as for csv.
    source = SyntheticTensileSource("synthetic:tensile?frames=10&size=64x64")
    with loading("synthetic", source=source, offset_s=0.5) as load:
        np.testing.assert_allclose(load.force_at(0.5 + np.arange(10) / 50.0), source.forces_N(), rtol=1e-12)
        assert math.isnan(load.force_at(0.49)) and load.settings["offset_s"] == 0.5


def test_synthetic_load_needs_a_simulated_tensile_camera():
    with pytest.raises(LoadError) as error:
        open_load("synthetic", source=SyntheticTranslateSource("synthetic:translate?frames=3&size=64x64"))
    assert "\n" not in str(error.value) and "synthetic:tensile" in str(error.value)
    source = SyntheticTensileSource("synthetic:tensile?frames=3&size=64x64")
    with pytest.raises(LoadError, match="not both"):
        open_load("synthetic:tensile", source=source)
    with pytest.raises(LoadError, match="unknown option"):
        open_load("synthetic", source=source, clock="sender")


class _Law:
    """Anything with frames, fps and forces_N() is a force law."""
    frames, fps, uri = 4, 10.0, "law:"

    def forces_N(self):
        return [0.0, 10.0, 20.0, 40.0]


def test_any_object_with_a_force_law_is_sampled_at_i_over_fps():
    load = SyntheticLoad(_Law(), offset_s=1.0)
    t, f = load.samples()
    np.testing.assert_allclose(t, [1.0, 1.1, 1.2, 1.3], rtol=0, atol=1e-12)
    assert f.tolist() == [0.0, 10.0, 20.0, 40.0] and load.specimen == {} and load.source_uri == "law:"
    assert load.force_at(1.25) == pytest.approx(30.0) and math.isnan(load.force_at(0.99))
    assert load.max_gap_s == pytest.approx(0.5) and SyntheticLoad(_Law(), max_gap_s=0.05).max_gap_s == 0.05


STEREO_VIEW = "synthetic:stereo?view={}&frames=11&size=128x128&focal=1000&strain=0.01&static=2"


def test_the_stereo_tests_force_is_its_law_on_the_uniform_strain():
    """E 200 GPa to 0.4 % strain, then 800 MPa + 10 GPa x plastic strain, on A0 = 20 mm x 2 mm; 0 in the static
    frames; a stereo pair's force is its left view's, and the test's URI gives the same without rendering."""
    from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource
    from livedic.acquire.sources import open_source
    left = SyntheticStereoViewSource(STEREO_VIEW.format("left"))
    e = np.r_[0.0, 0.0, 0.01 * np.arange(11) / 10]                       # 2 static frames, then the test
    plastic = np.maximum(e - 0.004, 0.0) / (1.0 + 10.0 / 200.0)
    law = np.where(e <= 0.004, 200e3 * e, 800.0 + 10e3 * plastic) * 40.0
    np.testing.assert_allclose(left.forces_N(), law, rtol=1e-12, atol=1e-9)
    assert left.specimen["A0_mm2"] == 40.0 and left.specimen["Rp02_MPa"] == pytest.approx(820.0, rel=1e-12)
    pair = open_source(f"stereo:{STEREO_VIEW.format('left')},{STEREO_VIEW.format('right')}")
    with loading("synthetic", source=pair) as load:
        np.testing.assert_allclose(load.samples()[1], law, rtol=1e-12, atol=1e-9)
        assert load.specimen["A0_mm2"] == 40.0
    with loading(STEREO_VIEW.format("right")) as load:
        np.testing.assert_allclose(load.samples()[1], law, rtol=1e-12, atol=1e-9)
    assert left._images is None                                          # nothing was rendered


@pytest.mark.parametrize("source, has_law", [
    ("synthetic:tensile?frames=3", True),
    ("synthetic:", True),
    (f"stereo:{STEREO_VIEW.format('left')},{STEREO_VIEW.format('right')}", True),
    (STEREO_VIEW.format("left"), True),
    ("synthetic:translate", False),
    ("aravis:", False),
    ("images:/nonexistent/*.png", False),
    (f"stereo:{STEREO_VIEW.format('left')},images:/nonexistent/*.png", False),
    ("stereo:synthetic:tensile,synthetic:translate", False),
])
def test_whether_a_source_has_a_force_law_is_read_from_its_uri(source, has_law):
    from livedic.acquire.force.simulated import check_synthetic_load_source
    if has_law:
        check_synthetic_load_source(source)
        return
    with pytest.raises(LoadError) as error:
        check_synthetic_load_source(source)
    assert "\n" not in str(error.value) and "stereo:synthetic:stereo" in str(error.value)
