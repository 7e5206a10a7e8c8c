"""Tests of stream/stages/contraction.py: Poisson's ratio fitted live on the axial/transverse pair, and its text."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE, Extensometer, ExtensometerReadings
from livedic.stream.stages.contraction import REFIT_INTERVAL_S, REFIT_SHARE, ContractionWatch, format_poisson, has_pair


def _readings(axial, transverse, transverse_ok=True):
    eng = np.array([axial, transverse])
    return ExtensometerReadings(names=(AXIAL, TRANSVERSE), l0_px=np.array([200.0, 100.0]), length_px=np.zeros(2),
                                eng_strain=eng, true_strain=np.log1p(eng),
                                status=np.array([0, 0 if transverse_ok else 2]))


def _result(index, readings, force=None, fps=1.0):
    return SimpleNamespace(frame=SimpleNamespace(index=index, timestamp_ns=round(index * 1e9 / fps)),
                           extensometers=readings, force_N=force, poisson=None, is_reference=index == 0)


def test_the_pair_is_needed():
    def stage(*names):
        return SimpleNamespace(extensometers=[Extensometer(n, 0, 0, 1, 1) for n in names])
    assert has_pair(stage(AXIAL, TRANSVERSE, "other")) and not has_pair(stage(AXIAL, "other")) and not has_pair(None)


def test_poisson_ratio_of_an_elastic_then_plastic_series():
    """Elastic to 0.2 % with nu = 0.3 (the force linear), then plastic with a contraction ratio of 0.5."""
    rng = np.random.default_rng(0)
    watch = ContractionWatch()
    axial = np.r_[np.linspace(0.0, 0.002, 60), np.linspace(0.0021, 0.03, 60)]
    transverse = np.where(axial <= 0.002, -0.3 * axial, -0.3 * 0.002 - 0.5 * (axial - 0.002))
    force = np.where(axial <= 0.002, 2e5 * axial, 400.0 + 1e3 * (axial - 0.002))
    for k, (a, t, f) in enumerate(zip(axial + 2e-6 * rng.standard_normal(120),
                                      transverse + 2e-6 * rng.standard_normal(120), force)):
        result = _result(k, _readings(a, t), f)
        watch(result, None)
        assert result.poisson is watch.current
    nu, plastic = watch.fit()
    assert nu.value == pytest.approx(0.3, abs=0.02) and nu.elastic
    assert plastic.value == pytest.approx(0.5, abs=0.05)
    summary = watch.summary()
    assert summary["poisson_ratio"]["value"] == pytest.approx(nu.value)
    assert set(summary) == {"poisson_ratio", "plastic_contraction_ratio"}


def test_a_frame_without_a_reading_or_force_is_nan_never_the_last_value():
    watch = ContractionWatch()
    watch(_result(0, _readings(0.001, -0.0003)), None)
    watch(_result(1, _readings(0.002, -0.0006, transverse_ok=False), 5.0), None)
    watch(_result(2, None), None)
    assert list(watch.frames) == [0, 1, 2]
    assert watch.axial[1] == 0.002 and math.isnan(watch.transverse[1])
    assert math.isnan(watch.axial[2]) and math.isnan(watch.transverse[2])
    assert math.isnan(watch.force[0]) and watch.force[1] == 5.0


def test_the_live_fit_is_redone_every_frame_at_first_then_every_n_over_refit_share(monkeypatch):
    watch = ContractionWatch()
    fits = []
    monkeypatch.setattr(watch, "fit", lambda: (fits.append(len(watch.frames)) or len(fits), None))
    for k in range(3 * REFIT_SHARE):
        watch(_result(k, _readings(0.0, 0.0)), None)
    assert fits[:REFIT_SHARE] == list(range(1, REFIT_SHARE + 1))           # every frame while n < REFIT_SHARE
    gaps = np.diff([n for n in fits if n >= 2 * REFIT_SHARE])
    assert gaps.size and (gaps == 2).all()                                  # then every n / REFIT_SHARE frames



def test_at_a_camera_rate_the_live_fit_waits_for_the_display_interval(monkeypatch):
    fps = 100.0
    watch = ContractionWatch()
    fits = []
    monkeypatch.setattr(watch, "fit", lambda: (fits.append(len(watch.frames)) or len(fits), None))
    for k in range(300):
        watch(_result(k, _readings(0.0, 0.0), fps=fps), None)
    every = round(REFIT_INTERVAL_S * fps)
    assert fits == list(range(1, 301, every))          # the first frame, then one fit an interval of frames' time
    assert watch.summary is not None and len(watch.frames) == 300           # every frame kept for the final fit


def test_the_text_of_a_ratio_and_of_none():
    fitted = {"label": "Poisson's ratio (elastic, frames 0-59)", "value": 0.3012, "stderr": 0.0021, "basis": "force"}
    assert format_poisson(fitted) == ("Poisson's ratio (elastic, frames 0-59) = 0.301 +- 0.002 (range: below the "
                                      "proportional limit, where force vs axial strain is linear)")
    assert format_poisson({**fitted, "stderr": None, "basis": "other"}, digits=2) == \
        "Poisson's ratio (elastic, frames 0-59) = 0.30"
    assert format_poisson({**fitted, "linear_to_end": True}).endswith("(range: every frame: transverse vs axial never "
                                                                      "left its line, nothing tells elastic from "
                                                                      "plastic)")
    assert format_poisson({"label": "Poisson's ratio", "value": None, "reason": "too few frames"}) == \
        "Poisson's ratio: n/a (too few frames)"
    assert format_poisson({"label": "L", "value": float("nan"), "reason": "r"}) == "L: n/a (r)"


def test_the_static_frames_after_the_reference_are_left_out_of_the_fit():
    watch = ContractionWatch(static_frames=3)
    for k in range(6):
        result = _result(k, _readings(0.0001 * k, -0.00003 * k), 10.0 * k)
        watch(result, None)
        assert result.poisson is watch.current
    assert list(watch.frames) == [0, 4, 5]          # the reference, then the test's frames
