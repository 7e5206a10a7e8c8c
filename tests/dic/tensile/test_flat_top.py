"""Ag and Agt on a flat-topped curve (``dic.tensile.flat_top``): at the middle of the plateau at maximum force.

The material: elastic (E = 200 GPa) to 300 MPa, linear hardening (K = 1 GPa in the plastic strain) to
Rm = 450 MPa at ep = 15 %, then either a flat top (the stress holds Rm from ep = 15 % to 15 % + L) or
none, then a falling branch (necking, -700 MPa per unit strain) and fracture. With the flat top the
plateau's middle is at ep = 15 % + L / 2, exactly: ISO 6892-1 reads Ag there. Noise: a class 0.5 load
cell's, 0.1 % of the reading (1 SD), seeded.
"""

import numpy as np
import pytest

from livedic.dic.tensile.flat_top import MIN_FLAT_TOP_EXTENSION, AgRule
from livedic.dic.tensile.properties import tensile_properties
from livedic.dic.tensile.yielding import CurveShape

E_MPA = 200_000.0
YIELD, K, EP_U, RM = 300.0, 1_000.0, 0.15, 450.0
FALL = 700.0                     # MPa per unit strain, necking
STEP = 0.0005                    # plastic strain per frame past yield
LOAD_CELL_NOISE = 0.001          # class 0.5: ~0.1 % of the reading


def curve(flat=0.0, noise=0.0, seed=0):
    """(strain, stress) of the analytic test with a flat top ``flat`` (strain) long at Rm."""
    elastic = np.linspace(0.0, YIELD, 100, endpoint=False)
    ep = np.arange(0.0, EP_U + flat + 0.08 + STEP / 2, STEP)
    stress = np.where(ep <= EP_U, YIELD + K * ep, np.where(ep <= EP_U + flat, RM, RM - FALL * (ep - EP_U - flat)))
    stress = np.concatenate([elastic, stress, np.full(20, 0.5)])         # broken: ~0 force
    plastic = np.concatenate([np.zeros(elastic.size), ep, np.full(20, ep[-1])])
    if noise:
        stress = stress * (1.0 + np.random.default_rng(seed).normal(0.0, noise, stress.size))
    return plastic + stress / E_MPA, stress


def test_exact_flat_top_gives_ag_at_its_middle():
    flat = 0.03
    strain, stress = curve(flat)
    props = tensile_properties(strain, stress)
    ag = props.Ag_percent
    assert props.curve_shape is CurveShape.CONTINUOUS
    assert ag.rule is AgRule.PLATEAU_MIDDLE and ag.reason is None
    # the stretch within the tolerance adds the shoulders (0.9 MPa over the slopes either side): ~0.1 % of strain
    assert ag.value == pytest.approx(100 * (EP_U + flat / 2), abs=0.1)
    assert ag.total == pytest.approx(100 * (EP_U + flat / 2 + RM / E_MPA), abs=0.1)
    assert ag.top.strains[1] - ag.top.strains[0] == pytest.approx(flat, abs=0.003)
    assert "middle of the plateau" in ag.method
    assert props.Rm_MPa.value == pytest.approx(RM, rel=1e-12)            # Rm itself is unchanged
    # the first frame at Rm, where Ag was read before, lies half the plateau earlier
    first_at_rm = 100 * (props.Rm_MPa.strain - RM / E_MPA)
    assert first_at_rm == pytest.approx(100 * EP_U, abs=1e-9)


def test_sharp_maximum_keeps_ag_at_the_maximum_exactly():
    strain, stress = curve(0.0)
    ag = tensile_properties(strain, stress).Ag_percent
    assert ag.rule is AgRule.AT_MAXIMUM
    assert ag.value == pytest.approx(100 * EP_U, rel=1e-9)
    assert ag.total == pytest.approx(100 * (EP_U + RM / E_MPA), rel=1e-9)
    assert ag.top.strains[1] - ag.top.strains[0] < MIN_FLAT_TOP_EXTENSION      # the peak's rounding only


def test_a_plateau_shorter_than_the_minimum_is_a_maximum():
    strain, stress = curve(0.005)      # 0.5 % flat + ~0.2 % of shoulders: under the 1 % minimum
    ag = tensile_properties(strain, stress).Ag_percent
    assert ag.rule is AgRule.AT_MAXIMUM
    assert ag.value == pytest.approx(100 * EP_U, rel=1e-9)


@pytest.mark.parametrize("seed", range(10))
def test_noisy_sharp_maximum_is_no_plateau(seed):
    strain, stress = curve(0.0, noise=LOAD_CELL_NOISE, seed=seed)
    ag = tensile_properties(strain, stress).Ag_percent
    assert ag.rule is AgRule.AT_MAXIMUM
    # the noisiest reading near the peak decides the frame: within the stretch a 0.45 MPa noise reaches
    assert ag.value == pytest.approx(100 * EP_U, abs=0.5)


@pytest.mark.parametrize("seed", range(10))
def test_noisy_flat_top_gives_its_middle(seed):
    flat = 0.03
    strain, stress = curve(flat, noise=LOAD_CELL_NOISE, seed=seed)
    ag = tensile_properties(strain, stress).Ag_percent
    assert ag.rule is AgRule.PLATEAU_MIDDLE
    assert ag.value == pytest.approx(100 * (EP_U + flat / 2), abs=0.2)
    # without the rule the noisiest frame of the plateau decides: anywhere along its 3 %
    assert ag.top.strains[1] - ag.top.strains[0] == pytest.approx(flat, abs=0.006)


def test_rule_follows_the_frames_after_discontinuous_yielding():
    """A yield plateau is no flat top: the top is searched from the start of work hardening."""
    elastic = np.linspace(0.0, YIELD, 100, endpoint=False)
    ep_yield = np.arange(0.0, 0.02, STEP)                               # Lueders plateau at 300 MPa
    ep_hard = np.arange(STEP, EP_U + STEP / 2, STEP)
    ep_fall = np.arange(STEP, 0.05, STEP)
    stress = np.concatenate([elastic, np.full(ep_yield.size, YIELD), YIELD + K * ep_hard, RM - FALL * ep_fall,
                             np.full(10, 0.5)])
    plastic = np.concatenate([np.zeros(100), ep_yield, 0.02 + ep_hard, 0.02 + EP_U + ep_fall,
                              np.full(10, 0.02 + EP_U + 0.05)])
    props = tensile_properties(plastic + stress / E_MPA, stress)
    assert props.curve_shape is CurveShape.PLATEAU
    assert props.Ag_percent.rule is AgRule.AT_MAXIMUM
    assert props.Ag_percent.value == pytest.approx(100 * (0.02 + EP_U), rel=1e-9)


def test_report_says_where_ag_was_read():
    """report.json's ``Ag_rule`` and report.md's line name the rule and the plateau (``stream.export.report``)."""
    import json

    from livedic.stream.export.report import AG_RULE_KEY, report_json, report_markdown
    specimen = {"area_mm2": 20.0, "gauge_length_px": 400.0}
    source = {"recording": "r.mcap", "truncated": False, "load": "csv:f.csv", "load_offset_s": 0.0, "frames": 1,
              "frames_with_force": 1, "strain": "", "generated_at": "now"}
    flat = json.loads(json.dumps(report_json(tensile_properties(*curve(0.03)), specimen, source), allow_nan=False))
    rule = flat[AG_RULE_KEY]
    assert rule["value"] == "plateau_middle" and rule["plateau_strain"][1] - rule["plateau_strain"][0] > 0.029
    assert rule["Agt_percent"] == pytest.approx(100 * (EP_U + 0.015 + RM / E_MPA), abs=0.1)
    assert set(flat["Ag_percent"]) == {"value", "method", "reason"}           # the property's entry keeps its keys
    text = report_markdown(flat, "plot.png", "r.mcap")
    assert "Ag and Agt read at the middle of the plateau at maximum force" in text and "plateau from" in text
    sharp = report_json(tensile_properties(*curve(0.0)), specimen, source)
    assert sharp[AG_RULE_KEY]["value"] == "at_maximum" and sharp[AG_RULE_KEY]["plateau_strain"] is None
    assert "Ag and Agt read at maximum force" in report_markdown(sharp, "plot.png", "r.mcap")
