"""ISO 9513:2012 classification: the table's invariants and each class boundary, in both regimes and without a scale."""

import math

import numpy as np
import pytest

from livedic.dic.strain.iso9513 import (CLASS_NAMES, CLASSES, Limitation, StepReason, class_for_gauge_length_error,
                                        classify, classify_step, limiting_step)

SCALE = 10.0            # px/mm: 1 px = 100 um
UM = SCALE / 1000.0     # px per um
INSIDE, OUTSIDE = 0.98, 1.02


def held(mean, resolution, frames=5):
    """``frames`` readings with this mean and half-range."""
    return mean + resolution * np.linspace(-1.0, 1.0, frames)


def test_table_invariants():
    assert CLASS_NAMES == ("0.2", "0.5", "1", "2")
    for limits in CLASSES:
        assert limits.gauge_length_relative == pytest.approx(float(limits.name) / 100)
        assert limits.bias_relative == pytest.approx(float(limits.name) / 100)
        assert limits.resolution_relative == pytest.approx(limits.bias_relative / 2)
        assert limits.bias_um == pytest.approx(3 * limits.resolution_um)
    for better, worse in zip(CLASSES, CLASSES[1:]):
        for name in ("gauge_length_relative", "resolution_relative", "resolution_um", "bias_relative", "bias_um"):
            assert getattr(better, name) < getattr(worse, name)


@pytest.mark.parametrize("limits", CLASSES, ids=CLASS_NAMES)
def test_absolute_regime_boundaries(limits):
    # 10 um of elongation: every relative limit is far below the absolute one
    true = 10 * UM
    bias, resolution = limits.bias_um * UM, limits.resolution_um * UM
    assert classify_step(true, held(true + INSIDE * bias, INSIDE * resolution), scale_px_per_mm=SCALE).best_class \
        == limits.name
    worse = classify_step(true, held(true + OUTSIDE * bias, 0.0), scale_px_per_mm=SCALE).best_class
    assert worse != limits.name and (worse is None or CLASS_NAMES.index(worse) > CLASS_NAMES.index(limits.name))
    noisier = classify_step(true, held(true, OUTSIDE * resolution), scale_px_per_mm=SCALE).best_class
    assert noisier != limits.name and (noisier is None or CLASS_NAMES.index(noisier) > CLASS_NAMES.index(limits.name))


@pytest.mark.parametrize("limits", CLASSES, ids=CLASS_NAMES)
def test_relative_regime_boundaries(limits):
    # 40 px = 4 mm of elongation: every absolute limit is far below the relative one
    true = 40.0
    bias = limits.bias_relative * true
    inside = classify_step(true, held(true + INSIDE * bias, 0.0), scale_px_per_mm=SCALE)
    assert inside.best_class == limits.name and inside.relative_bias == pytest.approx(INSIDE * limits.bias_relative)
    assert classify_step(true, held(true - OUTSIDE * bias, 0.0), scale_px_per_mm=SCALE).best_class != limits.name
    resolution = limits.resolution_relative * true
    assert classify_step(true, held(true, INSIDE * resolution), scale_px_per_mm=SCALE).best_class == limits.name
    assert classify_step(true, held(true, OUTSIDE * resolution), scale_px_per_mm=SCALE).best_class != limits.name


def test_whichever_is_greater_at_the_crossover():
    # class 0.5: 1.5 um bias = 0.5 % of 300 um; below 300 um the absolute limit holds, above it the relative one
    step = classify_step(200 * UM, held(200 * UM + 1.4 * UM, 0.0), scale_px_per_mm=SCALE)
    assert step.best_class == "0.5" and step.bias_um == pytest.approx(1.4)
    assert classify_step(600 * UM, held(600 * UM + 2.9 * UM, 0.0), scale_px_per_mm=SCALE).best_class == "0.5"
    assert classify_step(600 * UM, held(600 * UM + 3.1 * UM, 0.0), scale_px_per_mm=SCALE).best_class == "1"


def test_beyond_class_2_has_no_class_and_says_why():
    step = classify_step(40.0, held(41.0, 0.0), scale_px_per_mm=SCALE)
    assert step.best_class is None and step.reason is StepReason.OUTSIDE_CLASSES
    result = classify([0.0, 40.0], [held(0.0, 0.0), held(41.0, 0.0)], 400.0, scale_px_per_mm=SCALE)
    assert result.met_class is None and result.reason is StepReason.OUTSIDE_CLASSES


def test_without_scale_relative_only_and_zero_not_classified():
    true = 4.0
    result = classify([0.0, true], [held(0.0, 0.001), held(true * 1.004, 0.0)], 400.0)
    zero, stretched = result.steps
    assert zero.best_class is None and zero.reason is StepReason.ZERO_NEEDS_SCALE
    assert math.isnan(zero.bias_um) and math.isnan(stretched.resolution_um)
    assert stretched.best_class == "0.5"
    assert result.met_class == "0.5"
    assert Limitation.NO_SCALE in result.limitations and Limitation.ZERO_STEPS_NOT_CLASSIFIED in result.limitations
    # relative only is stricter: 1 um of bias on 10 um meets class 2 with the absolute limits, none without
    assert classify_step(10 * UM, held(11 * UM, 0.0)).best_class is None
    assert classify_step(10 * UM, held(11 * UM, 0.0), scale_px_per_mm=SCALE).best_class == "0.5"


def test_only_zero_steps_without_scale_cannot_be_classified():
    result = classify([0.0, 0.0], [held(0.0, 0.001), held(0.0, 0.001)], 400.0)
    assert result.met_class is None and result.reason is StepReason.ZERO_NEEDS_SCALE


def test_only_zero_steps_claim_no_class_but_state_the_zero_point():
    # 0.4 um bias, 0.3 um resolution at zero: inside class 0.5's absolute limits (1.5, 0.5 um), not 0.2's (0.6, 0.2)
    result = classify([0.0, 0.0], [held(0.4 * UM, 0.3 * UM), held(-0.2 * UM, 0.1 * UM)], 400.0, scale_px_per_mm=SCALE)
    assert [s.best_class for s in result.steps] == ["0.5", "0.2"]
    assert result.met_class is None and result.reason is StepReason.NO_ELONGATION
    assert result.zero_point_class == "0.5" and not result.elongation_verified
    assert result.as_dict()["zero_point_class"] == "0.5" and result.as_dict()["elongation_verified"] is False
    # one known elongation verifies the class; the zero point is still stated
    both = classify([0.0, 40.0], [held(0.4 * UM, 0.3 * UM), held(40.0, 0.0)], 400.0, scale_px_per_mm=SCALE)
    assert both.met_class == "0.5" and both.zero_point_class == "0.5" and both.elongation_verified


def test_the_limiting_step_names_the_limit_it_exceeds():
    # step 1: 4 px true, bias 0.012 px = 0.3 %: class 0.5; class 0.2 allows 0.008 px (0.2 %) of bias
    result = classify([0.0, 4.0], [held(0.0, 0.001), held(4.012, 0.001)], 400.0)
    index, text = limiting_step(result)
    assert index == 1 and result.met_class == "0.5"
    assert "|bias| 0.012 px > 0.008 px (the class 0.2 limit)" in text and "resolution" not in text
    lost = classify([4.0, 8.0], [held(4.0, 0.0), [8.0, math.nan]], 400.0, scale_px_per_mm=SCALE)
    assert limiting_step(lost) == (1, StepReason.READINGS_LOST.value)


def test_lost_or_single_readings_block_the_class():
    lost = classify([0.0, 4.0], [held(0.0, 0.0), [4.0, math.nan, 4.0]], 400.0, scale_px_per_mm=SCALE)
    assert lost.met_class is None and lost.reason is StepReason.READINGS_LOST
    single = classify([4.0], [[4.0]], 400.0, scale_px_per_mm=SCALE)
    assert single.met_class is None and single.reason is StepReason.TOO_FEW_READINGS


def test_overall_is_the_worst_step_and_the_gauge_length_error_counts():
    true = [0.0, 4.0, 40.0]
    readings = [held(0.0, 0.1 * UM), held(4.0, 0.0), held(40.0 * 1.008, 0.0)]
    result = classify(true, readings, 400.0, scale_px_per_mm=SCALE)
    assert [s.best_class for s in result.steps] == ["0.2", "0.2", "1"] and result.met_class == "1"
    assert Limitation.GAUGE_LENGTH_NOT_ASSESSED in result.limitations
    assert classify(true, readings, 400.0, scale_px_per_mm=SCALE, l0_relative_error=0.015).met_class == "2"
    assert classify(true, readings, 400.0, scale_px_per_mm=SCALE, l0_relative_error=0.03).reason \
        is StepReason.GAUGE_LENGTH_OUTSIDE
    assert class_for_gauge_length_error(0.002) == "0.2" and class_for_gauge_length_error(0.0021) == "0.5"
    assert result.l0_mm == pytest.approx(40.0)


def test_json_has_no_nan():
    import json
    result = classify([0.0, 4.0], [held(0.0, 0.001), held(4.0, 0.0)], 400.0)
    text = json.dumps(result.as_dict(), allow_nan=False)
    assert "ZERO_NEEDS_SCALE" in text


def test_bad_arguments_raise_one_line():
    with pytest.raises(ValueError, match="one set per step"):
        classify([0.0, 1.0], [[0.0, 0.0]], 400.0)
    with pytest.raises(ValueError, match="gauge length"):
        classify([1.0], [[1.0, 1.0]], 0.0)
    with pytest.raises(ValueError, match="scale"):
        classify([1.0], [[1.0, 1.0]], 400.0, scale_px_per_mm=-1.0)
