"""Tests of acquire/simulator/open.py: each simulated test opens its own source."""

from livedic.acquire.simulator.open import open_simulator
from livedic.acquire.simulator.sources import SyntheticTranslateSource
from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource


def test_each_model_opens_its_own_source():
    with open_simulator("synthetic:stereo?view=right&frames=2&size=64x64") as right:
        assert isinstance(right, SyntheticStereoViewSource) and right.view == "right"
    with open_simulator("synthetic:translate?frames=2&size=64x64") as translate:
        assert isinstance(translate, SyntheticTranslateSource)
