"""``livedic bench calibration`` on a small image: the correction removes the lens's strain bias at the corners,
and on a tilted plane the homography the perspective's and the foreshortened L0."""

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
    # the plane tilted 8 deg (measured at 384 px): mean |eyy - 1 %| at the top and bottom 989 microstrain with
    # one px/mm, 59 through the homography; the centre extensometer's L0 in mm -0.57 % and 0.011 % off the
    # length on the plane
    tilted = numbers["tilted"]
    assert tilted["one px/mm"]["abs_eyy_far"] > 500 and tilted["plane homography"]["abs_eyy_far"] < 200
    assert abs(tilted["one px/mm"]["l0_error_pct"]) > 0.3 and abs(tilted["plane homography"]["l0_error_pct"]) < 0.1
