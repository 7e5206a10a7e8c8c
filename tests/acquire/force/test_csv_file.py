"""Tests of acquire/force/csv_file.py: a machine's force export read, checked and interpolated on session time."""

import math

import numpy as np
import pytest

from livedic.acquire.force import LoadError, open_load
from livedic.acquire.force.csv_file import CsvLoad, csv_max_gap_s, read_force_csv
from livedic.acquire.force.source import DEFAULT_MAX_GAP_S, TIME_BASE_SESSION
from tests.acquire.force.loads import loading, write_csv


def test_csv_round_trip_interpolates_linear_force_exactly(tmp_path):
    t = np.arange(0, 41) * 0.025                       # 40 Hz machine export
    path = write_csv(tmp_path / "force.csv", zip(t, 12.0 + 800.0 * t))
    frames = np.arange(0, 51) * 0.02                   # 50 fps, the last frame (1.0 s) exactly on the last sample
    with loading(f"csv:{path}") as load:
        assert load.time_base == TIME_BASE_SESSION
        got = load.force_at(frames)
        np.testing.assert_allclose(got, 12.0 + 800.0 * frames, rtol=0, atol=1e-9)
        assert math.isnan(load.force_at(1.0 + 1e-9))    # past the last sample: never extrapolated
        assert math.isnan(load.force_at(-0.001))
        assert load.last_sample_time_s == pytest.approx(1.0)
        assert load.events() == [] and load.warnings.garbage_lines == 0


def test_csv_offset_shifts_the_samples_onto_frame_time(tmp_path):
    path = write_csv(tmp_path / "force.csv", [(0.0, 0.0), (1.0, 100.0), (2.0, 200.0)])
    with loading(f"csv:{path}", offset_s=0.25) as load:
        np.testing.assert_allclose(load.force_at([0.25, 0.75, 2.25]), [0.0, 50.0, 200.0], atol=1e-9)
        assert math.isnan(load.force_at(0.2)) and math.isnan(load.force_at(2.3))
        assert load.settings["offset_s"] == 0.25


def test_csv_extra_columns_and_blank_lines_are_allowed(tmp_path):
    path = tmp_path / "force.csv"
    path.write_text("time_s,force_N,crosshead_mm\n0,1,0.0\n\n1,3,0.1\n")
    with loading(f"csv:{path}") as load:
        np.testing.assert_allclose(load.force_at(0.5), 2.0)


@pytest.mark.parametrize("content, where", [
    (None, "cannot be read"),
    ("", "line 1"),
    ("time,force\n0,1\n", "line 1"),
    ("force_N,time_s\n0,1\n", "line 1"),
    ("time_s,force_N\n", "no samples"),
    ("time_s,force_N\n0,1\n0.1,abc\n", "line 3"),
    ("time_s,force_N\n0,1\n0.1,nan\n", "line 3"),
    ("time_s,force_N\n0,1\n0.1\n", "line 3"),
    ("time_s,force_N\n0,1\n0.2,2\n0.2,3\n", "line 4"),
    ("time_s,force_N\n0,1\n0.2,2\n0.1,3\n", "line 4"),
])
def test_a_bad_csv_is_one_line_naming_file_and_line(tmp_path, content, where):
    path = tmp_path / "bad.csv"
    if content is not None:
        path.write_text(content)
    with pytest.raises(LoadError) as error:
        open_load(f"csv:{path}")
    message = str(error.value)
    assert "\n" not in message and str(path) in message and where in message, message
    assert isinstance(error.value, ValueError)


def test_a_spreadsheets_bom_and_spaces_in_the_header_are_accepted(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes("\ufefftime_s , force_N\r\n0,1\r\n2,5\r\n".encode("utf-8"))
    t, f = read_force_csv(path)
    assert t.tolist() == [0.0, 2.0] and f.tolist() == [1.0, 5.0] and t.dtype == np.float64


def test_binary_content_is_one_line(tmp_path):
    path = tmp_path / "force.csv"
    path.write_bytes(b"time_s,force_N\n\xff\xfe\x00\x01\n")
    with pytest.raises(LoadError, match="not a text CSV"):
        read_force_csv(path)


def test_the_default_gap_follows_the_sampling_of_the_file():
    assert csv_max_gap_s(np.array([0.0])) == DEFAULT_MAX_GAP_S
    assert csv_max_gap_s(np.arange(100) * 0.01) == DEFAULT_MAX_GAP_S          # 100 Hz: 5 intervals < 0.5 s
    assert csv_max_gap_s(np.arange(10) * 1.0) == pytest.approx(5.0)           # 1 Hz export: not a stall per sample


def test_a_slow_export_is_interpolated_and_its_holes_are_not(tmp_path):
    t = np.r_[np.arange(0, 10.0), np.arange(20.0, 25.0)]                      # 1 Hz, then a 11 s hole
    path = write_csv(tmp_path / "slow.csv", zip(t, 10 * t))
    load = CsvLoad(path)
    assert load.max_gap_s == pytest.approx(5.0) and load.time_base == TIME_BASE_SESSION
    assert load.force_at(3.5) == pytest.approx(35.0) and math.isnan(load.force_at(15.0))
    assert CsvLoad(path, max_gap_s=20.0).force_at(15.0) == pytest.approx(150.0)
    assert load.uri == f"csv:{path}" and load.settings["uri"] == f"csv:{path}"


def test_samples_are_copies(tmp_path):
    load = CsvLoad(write_csv(tmp_path / "f.csv", [(0, 1), (1, 2)]), offset_s=1.0)
    t, f = load.samples()
    t[:], f[:] = 0.0, 0.0
    assert load.samples()[0].tolist() == [1.0, 2.0] and load.force_at(1.5) == pytest.approx(1.5)
