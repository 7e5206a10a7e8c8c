"""The simulated tensile test's force (issue 13): a stress-strain law consistent with its displacement.

The model's elastic strain is the stress over E, so F = E e_el A0 with A0 = gauge width / scale x
thickness. Exact values are compared to 1e-12 (float rounding); values read back from the strain
field go through the smooth box g (1 - 2e-8 at the gauge centre, 3e-5 in the shoulder rows), hence
the looser tolerances stated there.
"""

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.model import TensileModel
from livedic.acquire.simulator.sources import SyntheticTensileSource

EXACT = 1e-12
SHAPE = (1024, 1024)                     # default coupon: A0 = 409.6 px / 10 px/mm x 2 mm = 81.92 mm^2
A0_DEFAULT = 81.92
YIELD_MPA = 200e3 * 0.004                # E x yield strain = 800 MPa


def centre_row(model):
    return 0.5 * (model.gauge_top + model.gauge_bottom)


def curve(model):
    """(total axial strain, engineering stress MPa) of the gauge section's centre, every frame."""
    frames = range(model.frames)
    strain = np.array([float(model.strain_yy(i, centre_row(model))) for i in frames])
    stress = np.array([model.stress_mpa(i) for i in frames])
    return strain, stress


def test_force_at_known_frames_is_the_law_exactly():
    # frames=21: tau = i / 20, so frame 1 is elastic (tau 0.05), 6 uniform plastic, 20 the deepest neck.
    model = TensileModel(SHAPE, 21)
    assert model.area_mm2 == pytest.approx(A0_DEFAULT, rel=EXACT)
    assert model.force_n(0) == 0.0
    assert model.force_n(1) == pytest.approx(YIELD_MPA * A0_DEFAULT / 3.0, rel=EXACT)
    assert model.force_n(6) == pytest.approx(YIELD_MPA * A0_DEFAULT, rel=EXACT)          # 65536 N
    assert model.force_n(20) == pytest.approx(0.8 * YIELD_MPA * A0_DEFAULT, rel=EXACT)   # the neck unloads 20 %
    for i in range(21):
        assert model.force_n(i) == pytest.approx(200e3 * model.state(i)["e_el"] * A0_DEFAULT, rel=EXACT, abs=0)


def test_the_stated_modulus_thickness_and_scale_set_the_force():
    source = SyntheticTensileSource("synthetic:tensile?frames=21&size=320x256&modulus=70&thickness=1.5&scale=20")
    area = 0.4 * 320 / 20.0 * 1.5                                         # 9.6 mm^2
    spec = source.specimen
    assert spec["A0_mm2"] == pytest.approx(area, rel=EXACT) and spec["E_GPa"] == 70.0
    assert spec["scale_px_per_mm"] == 20.0 and spec["thickness_mm"] == 1.5
    assert spec["yield_MPa"] == pytest.approx(70e3 * 0.004, rel=EXACT)
    assert source.force_N(6) == pytest.approx(70e3 * 0.004 * area, rel=EXACT)


def test_elastic_slope_of_stress_against_the_exact_gauge_strain_is_E():
    model = TensileModel(SHAPE, 201, modulus_gpa=123.0)
    strain, stress = curve(model)
    elastic = np.array([model.state(i)["phase"] == "elastic" for i in range(model.frames)])
    assert elastic.sum() >= 20
    slope, intercept = np.polyfit(strain[elastic], stress[elastic], 1)
    assert slope == pytest.approx(123e3, rel=1e-7)          # g = 1 - 2e-8 at the gauge centre
    assert abs(intercept) < 1e-6


def test_the_shoulders_carry_the_same_force_over_their_wider_section():
    model = TensileModel(SHAPE, 21)
    Y = 0.0                                                  # top shoulder row: the box g is 3e-5 there
    width_mm = 2.0 * float(model.half_width(Y)) / model.scale_px_per_mm
    for i in (1, 2):                                         # elastic: the shoulders have no plastic strain
        shoulder_stress = 200e3 * float(model.strain_yy(i, Y))
        assert shoulder_stress * width_mm * model.thickness_mm == pytest.approx(model.force_n(i), rel=2e-4)


def rp02_from_curve(strain, stress, modulus_mpa):
    """Stress where the plastic strain (total - stress / E) first reaches 0.2 %, linear between frames."""
    plastic = strain - stress / modulus_mpa
    k = int(np.argmax(plastic >= 0.002))
    assert plastic[k] >= 0.002 and k > 0
    w = (0.002 - plastic[k - 1]) / (plastic[k] - plastic[k - 1])
    return stress[k - 1] + w * (stress[k] - stress[k - 1])


def test_perfectly_plastic_default_has_rp02_equal_to_rm_equal_to_yield():
    model = TensileModel(SHAPE, 301)
    spec = model.specimen
    assert spec["hardening"] == 0.0
    assert spec["yield_MPa"] == spec["Rp02_MPa"] == spec["Rm_MPa"] == pytest.approx(YIELD_MPA, rel=EXACT)
    strain, stress = curve(model)
    assert stress.max() == pytest.approx(spec["Rm_MPa"], rel=EXACT)
    assert rp02_from_curve(strain, stress, 200e3) == pytest.approx(spec["Rp02_MPa"], rel=1e-9)
    plastic_phase = [model.state(i)["phase"] == "plastic" for i in range(model.frames)]
    np.testing.assert_allclose(stress[plastic_phase], YIELD_MPA, rtol=EXACT)   # flat: no hardening


def test_hardening_gives_the_stated_rm_and_rp02():
    h, strain_u = 0.5, 0.05
    model = TensileModel(SHAPE, 21, hardening=h, strain=strain_u)    # frame 12: tau = 0.6, the neck starts
    spec = model.specimen
    assert spec["Rm_MPa"] == pytest.approx(YIELD_MPA * 1.5, rel=EXACT)
    assert spec["Rp02_MPa"] == pytest.approx(YIELD_MPA * (1 + h * 0.002 / strain_u), rel=EXACT)
    strain, stress = curve(model)
    assert stress.max() == pytest.approx(spec["Rm_MPa"], rel=EXACT) and int(np.argmax(stress)) == 12
    # Stress and plastic strain are both linear in time in the uniform phase: interpolation is exact.
    assert rp02_from_curve(strain, stress, 200e3) == pytest.approx(spec["Rp02_MPa"], rel=1e-9)
    assert np.all(np.diff(stress[:13]) > 0) and np.all(np.diff(stress[12:]) < 0)
    assert TensileModel(SHAPE, 21, hardening=h, strain=0.001).specimen["Rp02_MPa"] is None


def test_hardening_changes_the_displacement_only_when_asked():
    plain = TensileModel(SHAPE, 21)
    zero = TensileModel(SHAPE, 21, hardening=0.0)
    hard = TensileModel(SHAPE, 21, hardening=0.5)
    X, Y = np.meshgrid(np.linspace(200, 800, 7), np.linspace(100, 900, 9))
    for i in range(21):
        for a, b in zip(plain.displacement(i, X, Y), zero.displacement(i, X, Y)):
            np.testing.assert_array_equal(a, b)
    _, v_plain = plain.displacement(12, X, Y)
    _, v_hard = hard.displacement(12, X, Y)
    assert np.abs(v_hard - v_plain).max() > 0.5        # 0.002 more strain over ~800 px: the truth follows


def test_force_is_zero_from_the_fracture_frame_on_and_in_the_metadata():
    source = SyntheticTensileSource("synthetic:tensile?frames=20&size=128x160&pace=0&fracture=1")
    broken = source.fracture_frame
    assert broken == 18
    forces = [source.force_N(i) for i in range(20)]
    assert forces[broken - 1] == pytest.approx(0.8 * source.specimen["yield_MPa"] * source.specimen["A0_mm2"],
                                               rel=EXACT)
    assert all(f == 0.0 for f in forces[broken:])
    np.testing.assert_array_equal(source.forces_N(), forces)
    seen = [frame.metadata["force_N"] for frame in source]
    np.testing.assert_array_equal(seen, forces)


def test_a_looped_source_cycles_the_force_with_its_frames():
    source = SyntheticTensileSource("synthetic:tensile?frames=13&loop=4&size=128x128&pace=0")
    expected = [source.model.force_n(source.rendered_index(i)) for i in range(13)]
    np.testing.assert_array_equal(source.forces_N(), expected)
    assert [source.force_N(i) for i in range(13)] == expected


def test_upper_yield_point_peaks_then_drops_to_the_yield_stress_and_is_off_by_default():
    plain, zero = TensileModel(SHAPE, 301), TensileModel(SHAPE, 301, upper_yield=0.0)
    assert [plain.stress_mpa(i) for i in range(301)] == [zero.stress_mpa(i) for i in range(301)]
    source = SyntheticTensileSource("synthetic:tensile?frames=301&size=128x160&pace=0&upper_yield=0.1")
    stress = np.array([source.model.stress_mpa(i) for i in range(301)])
    peak = int(np.argmax(stress))
    assert source.specimen["ReH_MPa"] == pytest.approx(1.1 * YIELD_MPA, rel=EXACT)
    assert stress[peak] == pytest.approx(1.1 * YIELD_MPA, rel=0.01)                # frame 45 samples the peak
    assert source.model.state(peak)["phase"] in ("elastic", "plastic")
    plastic_phase = [source.model.state(i)["phase"] == "plastic" for i in range(301)]
    np.testing.assert_allclose(stress[plastic_phase][5:], YIELD_MPA, rtol=EXACT)   # then the plateau


@pytest.mark.parametrize("option", ["modulus=0", "thickness=-1", "scale=abc", "hardening=-0.1", "modulus=nan",
                                    "upper_yield=-1"])
def test_bad_force_options_are_one_line(option):
    with pytest.raises(SourceError) as error:
        SyntheticTensileSource(f"synthetic:tensile?frames=5&size=64x64&{option}")
    message = str(error.value)
    assert "\n" not in message and option.split("=")[0] in message, message
