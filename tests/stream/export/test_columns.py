"""Tests of stream/export/columns.py: the export's column tables, file names and one frame's columns."""

import csv
import io

import numpy as np

from livedic.dic.strain.extensometer import ExtensometerReadings, ExtensometerStatus
from livedic.stream.export.columns import (EXPORT_FILES, EXTENSOMETER_COLUMNS, EXTRA_COLUMNS, LEADING_COLUMNS,
                                           P0_COLUMNS, STRESS_FILES, BINARY_FILES, extensometer_columns,
                                           result_columns)
from livedic.stream.output.csv_text import csv_rows


def test_the_column_tables_have_no_repeated_name_and_the_binary_files_are_pngs():
    for table in (LEADING_COLUMNS + EXTRA_COLUMNS, P0_COLUMNS, EXTENSOMETER_COLUMNS, EXPORT_FILES + STRESS_FILES):
        assert len(set(table)) == len(table)
    assert all(name.endswith(".png") for name in BINARY_FILES)
    assert set(BINARY_FILES) <= set(EXPORT_FILES + STRESS_FILES)


def test_result_columns_lead_with_the_fixed_columns_then_the_extras_in_their_order():
    n = 3
    extras = {"iterations": np.array([4, 5, 6]), "ux": np.zeros(n), "unknown": np.ones(n), "status": np.zeros(n)}
    columns = result_columns(7, 123, np.arange(n), np.ones(n), np.ones(n), np.zeros(n), np.zeros(n), np.ones(n),
                             np.array([1, 0, 1]), extras)
    assert tuple(columns) == LEADING_COLUMNS + ("status", "ux", "iterations")
    assert columns["frame"] == 7 and columns["timestamp_ns"] == 123
    assert columns["ok"].dtype == bool and columns["ok"].tolist() == [True, False, True]


def test_extensometer_columns_one_row_each_with_names_quoted_for_csv():
    ok, lost = int(ExtensometerStatus.OK), int(next(s for s in ExtensometerStatus if s != ExtensometerStatus.OK))
    readings = ExtensometerReadings(names=("axial", 'odd, "name"'), l0_px=np.array([200.0, 48.0]),
                                    length_px=np.array([202.0, np.nan]), eng_strain=np.array([0.01, np.nan]),
                                    true_strain=np.array([np.log(1.01), np.nan]), status=np.array([ok, lost]))
    columns = extensometer_columns(4, 0.5, readings)
    assert tuple(columns) == EXTENSOMETER_COLUMNS
    text = ",".join(EXTENSOMETER_COLUMNS) + "\n" + csv_rows(columns, 2)
    rows = list(csv.DictReader(io.StringIO(text)))
    assert [row["name"] for row in rows] == ["axial", 'odd, "name"']
    assert [row["ok"] for row in rows] == ["1", "0"] and rows[1]["L_px"] == "nan"
    assert rows[0]["frame"] == "4" and rows[0]["time_s"] == "0.5" and float(rows[0]["eng_strain"]) == 0.01
