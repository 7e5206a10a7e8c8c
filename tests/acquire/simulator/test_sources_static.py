"""The simulator's static frames (``static=N``): the reference again with new noise, zero truth, the test after."""

import numpy as np

from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource


def test_static_frames_repeat_the_reference_with_new_noise_and_the_test_follows_unchanged():
    plain = list(SyntheticTensileSource("synthetic:tensile?size=128x128&frames=6&pace=0&fracture=4"))
    source = SyntheticTensileSource("synthetic:tensile?size=128x128&frames=6&pace=0&fracture=4&static=3")
    frames = list(source)
    assert source.frames == len(frames) == 9 and [f.index for f in frames] == list(range(9))
    reference = frames[0].image.astype(float)
    assert np.array_equal(frames[0].image, plain[0].image)
    for k in (1, 2, 3):
        difference = frames[k].image.astype(float) - reference
        # two independent draws of sigma = 1 grey level, rounded: SD about sqrt(2) x 1, never the same image
        assert 1.1 < difference.std() < 1.8 and abs(difference.mean()) < 0.1
        u, v = frames[k].metadata["truth"](np.array([40.0, 64.0]), np.array([50.0, 70.0]))
        assert not u.any() and not v.any()
        assert frames[k].metadata["nominal_strain"] == 0.0
        assert frames[k].metadata["force_N"] == plain[0].metadata["force_N"]
    assert not np.array_equal(frames[1].image, frames[2].image)
    # the test's own frames, their truth, force and fracture frame: as without the static frames, 3 frames later
    for i in range(1, 6):
        assert np.array_equal(frames[i + 3].image, plain[i].image)
        assert frames[i + 3].metadata["force_N"] == plain[i].metadata["force_N"]
    assert source.fracture_frame == 4 + 3
    assert np.array_equal(source.forces_N()[4:], SyntheticTensileSource(
        "synthetic:tensile?size=128x128&frames=6&pace=0&fracture=4").forces_N()[1:])
    assert source.forces_N()[1:4].tolist() == [source.forces_N()[0]] * 3


def test_static_frames_of_a_translation_do_not_move():
    source = SyntheticTranslateSource("synthetic:translate?size=96x96&frames=4&pace=0&static=2&du=0.5")
    frames = list(source)
    assert len(frames) == 6
    assert [source.shift(source.model_index(i))[0] for i in range(6)] == [0.0, 0.0, 0.0, 0.5, 1.0, 1.5]
    u, _ = frames[5].metadata["truth"](np.array([48.0]), np.array([48.0]))
    assert u[0] == 1.5
