"""``livedic replay -o OUT.parquet``: the CSV's columns and values, typed; whole or no file; the format by the suffix.

The Parquet file is read back with pyarrow (pandas and polars read the same file through it or their own
reader); its values are compared bit for bit with the CSV the same replay writes.
"""

import csv
import os

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from livedic.stream.cli import main
from livedic.stream.replay.rows import FrameRows, ParquetRows, rows_output
from tests.stream.replay.test_replay import recording  # noqa: F401 - the fixture: a 12-frame session after 10 static frames

INTEGERS = ("frame", "timestamp_ns", "point_id", "status", "iterations")


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def csv_like(table):
    """A Parquet table as the rows ``csv.reader`` gives for the CSV: header, then each row's texts."""
    columns = []
    for name in table.column_names:
        values = table[name].to_numpy(zero_copy_only=False)
        if values.dtype == bool:
            columns.append(np.where(values, "1", "0").tolist())
        else:
            columns.append([repr(value) for value in values.tolist()])
    return [table.column_names] + [list(row) for row in zip(*columns)]


def _read_csv(path):
    with open(path, newline="") as handle:
        return list(csv.reader(handle))


def _no_staged_files(folder):
    return not [name for name in os.listdir(folder) if name.startswith(".livedic-")]


def test_parquet_holds_the_csvs_columns_and_values_typed(recording, tmp_path, capsys):  # noqa: F811
    """A grid of points and one in the image's corner, whose subset leaves the image: NaN where it has no value."""
    points = tmp_path / "points.csv"
    grid = [(x, y) for x in range(34, 95, 15) for y in range(40, 221, 20)]
    points.write_text("x,y\n" + "".join(f"{x},{y}\n" for x, y in grid + [(2, 2)]))
    for name in ("replay.csv", "replay.parquet"):
        assert main(["replay", recording, "--points", str(points), "-o", str(tmp_path / name), "--progress",
                     "off"]) == 0
    assert "wrote " + str(tmp_path / "replay.parquet") in capsys.readouterr().err
    rows = _read_csv(tmp_path / "replay.csv")
    header, cells = rows[0], rows[1:]
    table = pq.read_table(tmp_path / "replay.parquet")
    assert table.column_names == header and table.num_rows == len(cells) == 22 * (1 + len(grid) + 1)    # P0 first; 10 static + 12 frames
    for index, name in enumerate(header):
        column = table[name]
        texts = [row[index] for row in cells]
        if name in INTEGERS:
            assert column.type == pa.int64() and column.to_pylist() == [int(text) for text in texts], name
        elif name == "ok":
            assert column.type == pa.bool_() and column.to_pylist() == [text == "1" for text in texts]
        else:
            assert column.type == pa.float64(), name
            values = column.to_numpy()
            from_csv = np.array([float(text) for text in texts])
            assert np.array_equal(np.isnan(values), np.isnan(from_csv)), name
            assert np.array_equal(values.view(np.uint64)[~np.isnan(values)],
                                  from_csv.view(np.uint64)[~np.isnan(from_csv)]), name
    for name in ("u", "zncc", "exx"):                         # the corner point: NaN kept (not null), the rest not
        values = table[name].to_numpy()
        assert table[name].null_count == 0 and 0 < np.isnan(values).sum() < len(values)
    assert csv_like(table) == rows                            # and the same texts, so the CSV is the table


def _frame(index, n, rng):
    columns = {"frame": index, "timestamp_ns": 20_000_000 * index, "point_id": np.arange(n, dtype=np.uint32),
               "x": rng.uniform(0, 100, n), "y": rng.uniform(0, 100, n), "u": rng.standard_normal(n),
               "v": rng.standard_normal(n), "zncc": rng.uniform(0, 1, n).astype(np.float32),
               "ok": rng.uniform(size=n) > 0.2, "status": rng.integers(0, 5, n),
               "exx": np.where(rng.uniform(size=n) > 0.5, np.nan, rng.standard_normal(n)),
               "eyy": rng.standard_normal(n), "exy": rng.standard_normal(n)}
    return FrameRows(list(columns), n, columns=columns)


def test_row_groups_are_whole_frames_and_force_columns_are_typed(tmp_path, rng):
    frames = [_frame(index, 7, rng).with_force(None if index == 2 else 10.0 * index, 1.5 * index)
              for index in range(10)]
    path = tmp_path / "rows.parquet"
    with open(path, "wb") as handle:
        writer = ParquetRows(handle, row_group_rows=20)
        for rows in frames:
            writer(rows)
        writer.close()
    metadata = pq.ParquetFile(path).metadata
    sizes = [metadata.row_group(i).num_rows for i in range(metadata.num_row_groups)]
    assert sizes == [21, 21, 21, 7]                            # frames gathered until 20 rows, never split
    table = pq.read_table(path)
    assert table["force_N"].type == table["eng_stress_MPa"].type == pa.float64()
    force = table["force_N"].to_numpy().reshape(10, 7)
    assert np.isnan(force[2]).all() and np.array_equal(force[3], np.full(7, 30.0))
    assert table["frame"].type == pa.int64() and table["zncc"].type == pa.float64()
    # the same rows as CSV lines: the table's texts
    text = "".join(rows.csv_lines() for rows in frames)
    assert csv_like(table)[1:] == [line.split(",") for line in text.splitlines()]


def test_force_added_to_lines_or_to_columns_gives_the_same_text(rng):
    rows = _frame(4, 5, rng)
    for force, stress in ((12.5, 1.25), (None, float("nan")), (float("inf"), -0.0)):
        assert rows.with_force(force, stress).csv_lines() == rows.as_text().with_force(force, stress).csv_lines()


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_a_failure_mid_replay_leaves_no_file(recording, tmp_path, monkeypatch, suffix):  # noqa: F811
    """Ctrl-C at the fourth frame's rows: exit 130 and nothing written, not even the staged file."""
    from livedic.stream.replay import rows as replay_rows
    calls = []
    writer = replay_rows.ParquetRows if suffix == ".parquet" else replay_rows.CsvRows
    original = writer.__call__

    def interrupted(self, rows):
        calls.append(rows.n)
        if len(calls) == 4:
            raise KeyboardInterrupt
        original(self, rows)

    monkeypatch.setattr(writer, "__call__", interrupted)
    out = tmp_path / f"replay{suffix}"
    assert main(["replay", recording, "-o", str(out), "--progress", "off"]) == 130
    assert len(calls) == 4 and not out.exists() and _no_staged_files(tmp_path)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_an_error_in_the_block_removes_the_staged_file(tmp_path, rng, suffix):
    out = tmp_path / f"rows{suffix}"
    with pytest.raises(RuntimeError):
        with rows_output(out) as write:
            write(_frame(0, 6, rng))
            raise RuntimeError("the replay failed")
    assert not out.exists() and _no_staged_files(tmp_path)


@pytest.mark.parametrize("name", ["replay.txt", "replay", "replay.csv.gz", "replay.feather"])
def test_an_unknown_suffix_is_one_line_exit_2_and_no_file(recording, tmp_path, capsys, name):  # noqa: F811
    capsys.readouterr()
    out = tmp_path / name
    assert main(["replay", recording, "-o", str(out), "--progress", "off"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "livedic: error:" in err and ".csv or .parquet" in err, err
    assert not out.exists() and os.listdir(tmp_path) == []
