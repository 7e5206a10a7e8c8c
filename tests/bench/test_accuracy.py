"""``livedic bench accuracy``: the resolution crossing, the noise arithmetic, the bias table, the CLI's bad input.

No data set is read here: the Star arithmetic runs on analytic fields with known answers and the bias table
on a translation rendered by livedic's own pattern generators.
"""

import math

import numpy as np
import pytest

from livedic.bench import patterns
from livedic.bench.accuracy import (AMPLITUDE, CrossingStatus, amplitude_error, efficiency_indicator, noise_sd,
                                    predicted_noise, resolution_period, running_mean, shift_bias, star_period,
                                    star_v, worst_bias)
from livedic.bench.cli import main


def _boxcar_attenuation(period, width):
    """A subset average of width ``width`` on cos(2 pi y / p) at its crest: sinc(width / p)."""
    return np.sinc(width / period)


def _sinc_root(width, limit=0.1):
    """The period where 1 - sinc(width / p) = limit, by bisection (sinc decreases on (0, 1))."""
    low, high = 1e-6, 1.0
    for _ in range(200):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if 1.0 - np.sinc(mid) < limit else (low, mid)
    return width / (0.5 * (low + high))


def test_star_truth_is_plus_amplitude_on_the_centre_row_and_zero_a_quarter_period_away():
    x = np.array([0.0, 999.0, 1999.0])
    assert star_period(x) == pytest.approx([10.07, 80.0, 150.0])
    assert star_v(x, 250.0) == pytest.approx(AMPLITUDE)
    assert star_v(x, 250.0 + star_period(x) / 4) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("width", [15.0, 21.0, 31.0])
def test_the_resolution_is_the_period_where_a_boxcar_star_attenuates_by_ten_percent(width):
    x = np.arange(0.0, 2000.0, 1.0)
    periods = star_period(x)
    v = AMPLITUDE * _boxcar_attenuation(periods, width)
    crossing = resolution_period(periods, amplitude_error(v))
    assert crossing.status is CrossingStatus.FOUND
    # linear interpolation between neighbours 0.07 px of period apart
    assert crossing.period == pytest.approx(_sinc_root(width), abs=0.01)
    assert crossing.period == pytest.approx(3.9 * width, rel=0.05)      # the classic "about 4 subsets"


def test_the_crossing_is_the_last_from_the_large_periods_and_survives_noise_after_smoothing():
    x = np.arange(0.0, 2000.0, 1.0)
    periods = star_period(x)
    v = AMPLITUDE * _boxcar_attenuation(periods, 21.0)
    v[periods < 30] = -0.3                       # garbage at small periods (aliasing) must not matter
    noisy = v + np.random.default_rng(1).normal(0.0, 0.01, v.size)
    raw = resolution_period(periods, amplitude_error(noisy))
    smoothed = resolution_period(periods, running_mean(amplitude_error(noisy), 15))
    assert smoothed.period == pytest.approx(_sinc_root(21.0), abs=1.0)
    assert raw.period >= smoothed.period - 1.0    # unsmoothed noise can only push the last crossing outwards


def test_crossing_statuses_when_the_limit_is_never_or_always_reached():
    periods = np.linspace(10, 150, 50)
    assert resolution_period(periods, np.full(50, 0.02)).status is CrossingStatus.BELOW_RANGE
    assert resolution_period(periods, np.full(50, 0.5)).status is CrossingStatus.ABOVE_RANGE
    missing = resolution_period(periods, np.full(50, np.nan))
    assert missing.status is CrossingStatus.NO_DATA and math.isnan(missing.period)


def test_running_mean_skips_missing_values():
    values = np.array([1.0, np.nan, 3.0, 5.0, np.nan])
    assert running_mean(values, 3) == pytest.approx([1.0, 2.0, 4.0, 4.0, 5.0])


def test_noise_and_efficiency_indicator_arithmetic():
    residual = np.array([0.01, -0.01, 0.03, -0.03, np.nan])
    assert noise_sd(residual) == pytest.approx(np.std([0.01, -0.01, 0.03, -0.03], ddof=1))
    assert math.isnan(noise_sd(np.array([0.1, np.nan])))
    assert efficiency_indicator(80.0, 0.0125) == pytest.approx(1.0)
    assert math.isnan(efficiency_indicator(math.nan, 0.01))


def test_predicted_noise_follows_sigma_and_grows_with_the_shape_function_order():
    reference = patterns.fft_blurred((96, 96), seed=3)[0]
    xs, ys = np.array([40, 48, 56]), np.array([48, 40, 56])
    first = predicted_noise(reference, xs, ys, 21, 1, 2.0)
    assert predicted_noise(reference, xs, ys, 21, 1, 4.0) == pytest.approx(2.0 * first)
    assert np.all(predicted_noise(reference, xs, ys, 21, 2, 2.0) > first)
    assert np.all(predicted_noise(reference, xs, ys, 31, 1, 2.0) < first)


def test_predicted_noise_matches_the_scatter_of_icgn_on_noisy_translations():
    from livedic.dic import measure

    size, sigma, shift = 160, 3.0, (0.3, 0.6)
    points = np.array([(x, y) for x in range(40, 121, 20) for y in range(40, 121, 20)], dtype=float)
    clean = patterns.fft_blurred((size, size), shift, seed=4)
    errors = []
    for seed in range(12):
        rng = np.random.default_rng(seed)
        ref, dfm = (image + rng.normal(0.0, sigma, image.shape) for image in clean)
        m = measure(ref, dfm, points, subset=21, subpixel="icgn")
        errors.append(m.v - shift[1])
    scatter = np.nanstd(np.array(errors), axis=0, ddof=1)
    predicted = predicted_noise(clean[0], points[:, 0], points[:, 1], 21, 1, sigma)
    # 12 repeats: the SD estimate itself scatters by about 20 %
    assert np.sqrt(np.mean(scatter ** 2)) == pytest.approx(np.sqrt(np.mean(predicted ** 2)), rel=0.3)


def test_shift_bias_counts_only_ok_points():
    u = np.array([0.31, 0.29, 0.33, 5.0, np.nan])
    v = np.array([0.60, 0.62, 0.61, -5.0, 0.6])
    ok = np.array([True, True, True, False, True])
    row = shift_bias(u, v, ok, 0.3, 0.6)
    assert (row.points, row.ok) == (5, 3)
    assert row.bias_u == pytest.approx(0.01) and row.bias_v == pytest.approx(0.01)
    assert row.sd_u == pytest.approx(np.std([0.01, -0.01, 0.03], ddof=1))
    assert worst_bias([row, shift_bias(u, v, ok, 0.32, 0.6)]) == pytest.approx(0.01)


def test_bias_table_of_a_rendered_translation_is_small_and_centred():
    from livedic.dic import measure

    points = np.array([(x, y) for x in range(30, 131, 10) for y in range(30, 131, 10)], dtype=float)
    rows = []
    for k, shift in enumerate(((0.0, 0.0), (0.25, 0.25), (0.5, 0.5))):
        ref, dfm = patterns.pair("fft-filtered noise", (160, 160), shift, noise_sigma=1.0, seed=20 + k)
        m = measure(ref, dfm, points, subset=21, subpixel="icgn")
        rows.append(shift_bias(m.u, m.v, m.ok, *shift))
    assert all(row.ok == row.points == len(points) for row in rows)
    assert worst_bias(rows) < 0.01                       # interpolation bias of IC-GN: a few thousandths
    assert all(max(row.sd_u, row.sd_v) < 0.02 for row in rows)


def test_cli_missing_data_folder_is_one_line_exit_2(tmp_path, capsys):
    assert main(["bench", "accuracy", "--data", str(tmp_path / "absent")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--data" in err[0] and "not a folder" in err[0]
    assert main(["bench", "accuracy", "--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dicc2_star" in err[0]


def test_cli_bad_interpolation_is_one_line_exit_2(tmp_path, capsys):
    assert main(["bench", "accuracy", "--data", str(tmp_path), "--interpolation", "bspline4"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown interpolation 'bspline4'" in err[0]
