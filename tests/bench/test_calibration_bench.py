"""``livedic bench calibration`` on a small image: the correction removes the lens's strain bias at the corners."""

from livedic.bench.calibration import run_calibration_benchmark


def test_the_benchmark_shows_the_corrections_gain():
    lines = []
    numbers = run_calibration_benchmark(size=384, say=lines.append)
    strain = numbers["strain"]
    # measured at 384 px (mean over the corner points, microstrain): eyy -731 uncorrected, 81 with the recovered
    # calibration, 46 with the true lens (the rest is the few corner points' noise); exx -282, 4, -13
    assert strain["uncorrected"]["eyy_corners"] < -400 and strain["uncorrected"]["exx_corners"] < -150
    for name in ("recovered calibration", "true lens"):
        assert abs(strain[name]["eyy_corners"]) < 150 and abs(strain[name]["exx_corners"]) < 100
    k1_truth, k1 = numbers["parameters"]["k1"]
    assert abs(k1 - k1_truth) < 0.02
    assert any("recovered calibration" in line for line in lines)
