"""Tests of stream/output/files.py: output checks before the work, atomic text, strict JSON and CSV tables."""

import csv
import io
import json
import math
import os

import numpy as np
import pytest

from livedic.stream.output.files import (OutputError, check_output_file, check_output_folder, json_text, write_csv,
                                         write_text_atomic)


def _leftovers(folder):
    return [name for name in os.listdir(folder) if name.startswith(".livedic-")]


def test_check_output_file_accepts_a_new_file_and_leaves_no_probe(tmp_path):
    check_output_file(tmp_path / "out.csv", "-o")
    assert os.listdir(tmp_path) == []


def test_check_output_file_refuses_a_folder_with_an_example_name(tmp_path):
    with pytest.raises(OutputError) as error:
        check_output_file(tmp_path, "--summary-json")
    assert str(error.value) == (f"--summary-json {tmp_path} is a folder: give a file name, e.g. "
                                f"{os.path.join(tmp_path, 'summary.json')}")
    assert isinstance(error.value, ValueError)       # the command line prints ValueErrors as one line, exit 2


def test_check_output_file_missing_folder_is_refused_unless_created(tmp_path):
    target = tmp_path / "a" / "b" / "out.csv"
    with pytest.raises(OutputError, match=f"folder {tmp_path / 'a' / 'b'} does not exist"):
        check_output_file(target, "-o")
    check_output_file(target, "-o", create_folders=True)        # the nearest existing folder is writable
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize("variant", ["denied", "under-a-file"])
def test_check_output_file_in_an_unwritable_folder_is_one_line(variant, unwritable_folder):
    folder = unwritable_folder(variant)
    with pytest.raises(OutputError) as error:
        check_output_file(folder / "out.csv", "-o")
    text = str(error.value)
    assert "\n" not in text and text.startswith(f"cannot write -o {folder / 'out.csv'}")
    assert ("not writable (permission denied)" in text) if variant == "denied" else ("is a file, not a folder" in text)


def test_check_output_file_refuses_a_read_only_file(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root may write read-only files")
    target = tmp_path / "kept.csv"
    target.write_text("x\n")
    target.chmod(0o444)
    with pytest.raises(OutputError, match="the file is read-only"):
        check_output_file(target, "-o")


def test_check_output_folder_accepts_missing_folders_and_refuses_a_file(tmp_path):
    check_output_folder(tmp_path / "new" / "deeper", "-o")
    assert os.listdir(tmp_path) == []
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    with pytest.raises(OutputError, match=r"is an existing file: give a folder"):
        check_output_folder(blocker, "-o")
    with pytest.raises(OutputError, match="is a file, not a folder"):
        check_output_folder(blocker / "sub", "-o")


def test_write_text_atomic_replaces_the_whole_file(tmp_path):
    target = tmp_path / "note.txt"
    target.write_text("old and longer text\n")
    write_text_atomic(target, "new\n")
    assert target.read_text() == "new\n" and _leftovers(tmp_path) == []


def test_json_text_is_strict_json_with_null_for_nan_and_numpy_values():
    text = json_text({"a": math.nan, "b": [1.5, math.inf, -math.inf], "c": np.float32(0.25), "d": np.arange(3),
                      "e": (True, None, "x"), 3: np.int64(7)})

    def refuse(name):
        raise ValueError(name)
    value = json.loads(text, parse_constant=refuse)
    assert value == {"a": None, "b": [1.5, None, None], "c": 0.25, "d": [0, 1, 2], "e": [True, None, "x"], "3": 7}
    assert text.endswith("}\n")


def test_write_csv_round_trips_numbers_bit_for_bit_and_quotes_text(tmp_path):
    values = np.array([0.1, -0.0, 1e-05, np.nan, np.inf, 1.0 / 3.0])
    target = tmp_path / "t.csv"
    write_csv(target, {"x": values, "ok": np.array([True, False, True, True, False, True]),
                       "n": np.arange(6, dtype=np.int64),
                       "name": np.array(["a", "b,c", 'say "hi"', "", "line\nbreak", "z"], dtype=object),
                       'odd,"name': np.zeros(6)})
    with open(target, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == ["x", "ok", "n", "name", 'odd,"name']
    assert len(rows) == 7
    read = np.array([float(row[0]) for row in rows[1:]])
    assert np.array_equal(read.view(np.uint64)[~np.isnan(read)], values.view(np.uint64)[~np.isnan(values)])
    assert [row[0] for row in rows[1:]] == ["0.1", "-0.0", "1e-05", "nan", "inf", repr(1.0 / 3.0)]
    assert [row[1] for row in rows[1:]] == ["1", "0", "1", "1", "0", "1"]
    assert [row[2] for row in rows[1:]] == [str(i) for i in range(6)]
    assert [row[3] for row in rows[1:]] == ["a", "b,c", 'say "hi"', "", "line\nbreak", "z"]
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("path", [None, "-"])
def test_write_csv_to_stdout(path, capsys):
    write_csv(path, {"a": np.array([1.5, 2.0]), "b": np.array([1, 2])})
    assert capsys.readouterr().out == "a,b\n1.5,1\n2.0,2\n"


def test_write_csv_of_no_rows_is_the_header_only(tmp_path):
    target = tmp_path / "empty.csv"
    write_csv(target, {"a": np.array([]), "b": np.array([], dtype=np.int64)})
    assert target.read_text() == "a,b\n"
