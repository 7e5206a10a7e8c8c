"""Poisson's ratio over the elastic range and the plastic contraction ratio (``dic.tensile.poisson``).

The material is the simulator's law (``acquire.simulator.model``): elastic to e_el = 0.4 % with
Poisson's ratio 0.3, then plastic flow at constant volume (contraction ratio 0.5 of the plastic
increments); the force is E e_el + K e_p. Frames: 45 elastic (0-44, then 45 at exactly the yield
strain), 255 plastic.
"""

import json
import math

import numpy as np
import pytest

from livedic.dic.tensile.poisson import Basis, Reason, contraction_ratios, linear_part, series_noise

N_ELASTIC, N_PLASTIC = 45, 255
NU_ELASTIC, NU_PLASTIC = 0.3, 0.5


def law(n_elastic=N_ELASTIC, n_plastic=N_PLASTIC, plastic_strain=0.10):
    """(axial, transverse, force) of the simulator's law, frame by frame."""
    e_el = np.concatenate([np.linspace(0, 0.004, n_elastic, endpoint=False), np.full(n_plastic, 0.004)])
    e_p = np.concatenate([np.zeros(n_elastic), np.linspace(0, plastic_strain, n_plastic)])
    return e_el + e_p, -NU_ELASTIC * e_el - NU_PLASTIC * e_p, 200e3 * e_el + 1000 * e_p


def noisy(values, sigma, seed):
    return values + np.random.default_rng(seed).normal(0.0, sigma, values.size)


def test_exact_law_gives_the_elastic_ratio_over_the_elastic_frames():
    axial, transverse, _ = law()
    nu, plastic = contraction_ratios(axial, transverse)
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-12) and nu.reason is None
    assert nu.basis is Basis.LINEAR_PART and nu.frames == (0, N_ELASTIC)       # frame 45 is still on the line
    assert nu.label == "Poisson's ratio (elastic, frames 0-45, axial strain 0-0.4 %)"
    assert plastic.value == pytest.approx(NU_PLASTIC, abs=1e-12) and not plastic.elastic
    assert plastic.frames == (N_ELASTIC + 1, N_ELASTIC + N_PLASTIC - 1)
    assert plastic.label.startswith("plastic contraction ratio (frames 46-299") and "Poisson" not in plastic.label


def test_with_a_force_the_range_ends_at_the_proportional_limit_and_the_plastic_range_at_maximum_force():
    axial, transverse, force = law()
    nu, plastic = contraction_ratios(axial, transverse, force=force, frames=np.arange(100, 400))
    assert nu.basis is Basis.FORCE and "below the proportional limit" in nu.method
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-12)
    assert nu.frames == (100, 100 + N_ELASTIC) and nu.axial_range == pytest.approx((0.0, 0.004))
    assert plastic.value == pytest.approx(NU_PLASTIC, abs=1e-12) and plastic.frames[1] == 399
    assert plastic.axial_range[0] >= 0.004 + 0.002            # from 0.2 % plastic strain on


@pytest.mark.parametrize("use_force", [False, True])
def test_noisy_strains_give_the_ratio_within_its_standard_error(use_force):
    axial, transverse, force = law()
    sigma = 1e-5                                          # 10 microstrain: a 400 px extensometer
    nu, plastic = contraction_ratios(noisy(axial, sigma, 1), noisy(transverse, sigma, 2),
                                     force=force if use_force else None)
    assert nu.reason is None and 0 < nu.standard_error < 0.02
    assert abs(nu.value - NU_ELASTIC) <= 4 * nu.standard_error
    assert nu.axial_noise == pytest.approx(sigma, rel=0.3)    # measured on the series
    assert abs(plastic.value - NU_PLASTIC) < 0.002
    if not use_force:
        assert N_ELASTIC <= nu.frames[1] <= N_ELASTIC + 3     # the departure is seen within a few frames


def test_a_constant_offset_of_either_strain_leaves_the_ratio():
    axial, transverse, _ = law()
    nu, _ = contraction_ratios(axial + 2e-4, transverse - 3e-4)
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-9) and nu.intercept != 0


def test_frames_without_a_reading_are_skipped():
    axial, transverse, force = law()
    axial[10:13] = np.nan
    transverse[200] = np.nan
    for f in (None, force):
        nu, plastic = contraction_ratios(axial, transverse, force=f)
        assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-9) and plastic.value == pytest.approx(NU_PLASTIC, abs=1e-9)


def test_a_purely_elastic_test_has_no_plastic_range():
    axial, transverse, _ = law(n_plastic=0)
    nu, plastic = contraction_ratios(axial, transverse)
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-12) and nu.frames == (0, N_ELASTIC - 1)
    assert "never departs" in nu.method
    assert math.isnan(plastic.value) and plastic.reason is Reason.NO_PLASTIC_RANGE


def test_noise_larger_than_the_signal_is_nan_with_a_reason():
    rng = np.random.default_rng(3)
    axial = 1e-5 * np.arange(50) / 50 + rng.normal(0, 1e-4, 50)   # 10 microstrain of signal under 100 of noise
    transverse = -0.3 * axial + rng.normal(0, 1e-4, 50)
    nu, _ = contraction_ratios(axial, transverse)
    assert math.isnan(nu.value) and nu.reason is Reason.BELOW_NOISE
    assert nu.n_frames > 0 and nu.frames[0] == 0            # the range is still said


def test_too_few_frames_is_nan_with_a_reason():
    axial, transverse, _ = law()
    nu, plastic = contraction_ratios(axial[:4], transverse[:4])
    assert math.isnan(nu.value) and nu.reason is Reason.TOO_FEW_FRAMES and nu.frames == (-1, -1)
    assert nu.label == "Poisson's ratio (elastic)"
    assert math.isnan(plastic.value) and plastic.reason is Reason.NO_ELASTIC_RANGE
    nu, _ = contraction_ratios([np.nan] * 20, [np.nan] * 20)
    assert nu.reason is Reason.TOO_FEW_FRAMES


def test_a_force_too_short_for_a_line_falls_back_to_transverse_vs_axial_and_says_so():
    axial, transverse, force = law()
    force[:] = np.nan
    force[-3:] = 100.0                                    # a force only at the end: no elastic fit
    nu, _ = contraction_ratios(axial, transverse, force=force)
    assert nu.basis is Basis.LINEAR_PART
    assert nu.method.startswith("the force's linear part gives no ratio (too few frames")
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-12)


def test_as_dict_is_json_ready_and_labelled():
    axial, transverse, _ = law()
    nu, plastic = contraction_ratios(axial, transverse)
    data = json.loads(json.dumps(nu.as_dict()))
    assert data["value"] == pytest.approx(NU_ELASTIC) and data["label"].startswith("Poisson's ratio (elastic")
    assert data["basis"] == "linear_part" and data["reason"] is None and data["frames"] == [0, 45]
    assert plastic.as_dict()["label"].startswith("plastic contraction ratio")


def test_series_noise_measures_white_noise_on_a_curve():
    x = np.linspace(0, 1, 2000)
    values = 0.01 * np.sin(3 * x) + np.random.default_rng(4).normal(0, 2e-5, x.size)
    assert series_noise(values) == pytest.approx(2e-5, rel=0.1)
    assert math.isnan(series_noise([1.0, 2.0]))


def test_linear_part_waits_for_a_known_line_before_testing():
    axial, transverse, _ = law()
    # the noise is as large as the whole elastic span: the line is never known, every frame is "linear"
    count, departed = linear_part(axial[:40], transverse[:40], x_noise=0.01, y_noise=0.01)
    assert (count, departed) == (40, False)


def test_a_plateau_then_a_neck_ends_the_plastic_range_where_the_force_falls():
    """Perfectly plastic (the simulator's default): the force holds at yield, then the neck lowers it while the
    axial strain runs on; the plastic range is the plateau past the proof point, not the neck."""
    axial, transverse, _ = law()
    force = 200e3 * np.minimum(axial, 0.004)
    neck = np.arange(axial.size) >= 250
    force[neck] *= 1.0 - 0.01 * (np.arange(neck.sum()) + 1)          # falls 1 % a frame
    transverse[neck] += -0.2 * (axial[neck] - axial[249])              # the neck's own contraction
    nu, plastic = contraction_ratios(axial, transverse, force=force)
    assert nu.value == pytest.approx(NU_ELASTIC, abs=1e-9)
    assert plastic.value == pytest.approx(NU_PLASTIC, abs=1e-9) and plastic.frames[1] == 249
    assert plastic.axial_range[0] >= 0.004 + 0.002                   # from 0.2 % plastic strain on


def test_dropped_frames_do_not_read_as_noise():
    """A queue that dropped frames leaves gaps: the strain jumps between kept frames, which is no noise."""
    axial, transverse, _ = law()
    kept = np.sort(np.random.default_rng(5).choice(axial.size, 180, replace=False))
    sigma = 1e-5
    a, t = noisy(axial, sigma, 6)[kept], noisy(transverse, sigma, 7)[kept]
    assert series_noise(a, kept) == pytest.approx(sigma, rel=0.3)
    assert series_noise(a) > 5 * sigma                                # as if every frame followed the last
    nu, _ = contraction_ratios(a, t, frames=kept)
    assert abs(nu.value - NU_ELASTIC) <= 4 * nu.standard_error and nu.frames[0] == kept[0]


def test_an_elastic_part_too_short_to_know_its_line_is_not_taken_for_the_plastic_line():
    """Three elastic frames, then plastic flow: the line is known only once plastic frames are in, and it
    runs through them; the first frames lie off it, so they are the elastic part: too few, NaN."""
    axial, transverse, _ = law(n_elastic=3, n_plastic=17)
    nu, plastic = contraction_ratios(noisy(axial, 2e-5, 8), noisy(transverse, 2e-5, 9))
    assert math.isnan(nu.value) and nu.reason is Reason.TOO_FEW_FRAMES and nu.frames[1] <= 4, nu
    assert plastic.value == pytest.approx(NU_PLASTIC, abs=0.01)


def test_a_line_through_a_bend_is_split_where_two_lines_fit_better():
    from livedic.dic.tensile.poisson import bend
    axial, transverse, _ = law(n_elastic=10, n_plastic=20)
    a, t = noisy(axial, 5e-5, 12), noisy(transverse, 5e-5, 13)
    assert bend(a, t) in (9, 10, 11)
    assert bend(a[:10], t[:10]) is None                 # the elastic part alone: one line
    assert bend(axial[:10], transverse[:10]) is None    # exact data: nothing to split
