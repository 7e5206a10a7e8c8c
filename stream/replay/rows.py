"""The rows of ``livedic replay``: one frame's columns, and the writers of ``-o OUT.csv`` and ``-o OUT.parquet``.

``frame_rows`` gives a frame's ``FrameRows`` wherever the frame was measured: the sequential
replay in its own process, the parallel one (``stream.replay.parallel_replay``) on the worker that
measured the frame, which for a CSV also formats its lines there (``FrameRows.as_text``), so the
replaying process, the serial part of a parallel replay, only writes them. One function either
way, so the files are the same.

The output format follows the suffix of ``-o`` (``output_format``): ``.csv`` (also stdout, no
``-o`` or ``-o -``) or ``.parquet`` (``.pq``). Both hold the same columns in the same order,
one row per frame and point; the CSV as ``stream.output.csv_text`` writes numbers (full precision),
the Parquet file typed (``column_type``: the integers int64, ``ok`` bool, the rest float64, NaN
kept as NaN), zstd-compressed, in row groups of about ``ROW_GROUP_ROWS`` rows (whole frames), so
pandas (``read_parquet``), polars (``read_parquet``/``scan_parquet``), DuckDB and Arrow read it
as it is, and a reader can take a column or a range of frames without reading the rest.
``rows_output`` writes either through a ``StagedFile``: complete, or not at all.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Any, Iterator, TextIO

import numpy as np
import pyarrow as pa

from livedic.stream.output.files import OutputError, check_output_file
from livedic.stream.output.csv_text import csv_rows, scalar_text
from livedic.stream.export.columns import (EXTRA_COLUMNS, FIELD_MM_COLUMNS, LEADING_COLUMNS, STRAIN_COLUMNS, StagedFile,
                                          mm_columns, result_columns, stereo_columns)
from livedic.stream.pipeline.sinks import stereo_arrays

if TYPE_CHECKING:
    from livedic.dic.result import Measurement
    from livedic.dic.strain.field import StrainField
    from livedic.stream.stages.strain import StrainStage

_GRADIENTS = ("ux", "uy", "vx", "vy", "iterations")
FORCE_COLUMNS = ("force_N", "eng_stress_MPa")
_INTEGER_COLUMNS = ("frame", "timestamp_ns", "point_id", "status", "iterations", "stereo_status")
_BOOLEAN_COLUMNS = ("ok",)
# Output formats by suffix of -o (lower case); anything else is refused.
OUTPUT_SUFFIXES = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}
# Rows a Parquet row group gathers before it is written (whole frames: 128 frames of 2,000 points): what a
# reader skips or reads at once; the rows waiting take ~40 MB at most.
ROW_GROUP_ROWS = 1 << 18
PARQUET_COMPRESSION = "zstd"


def column_type(name: str) -> pa.DataType:
    """The Parquet type of replay column ``name``."""
    if name in _INTEGER_COLUMNS:
        return pa.int64()
    if name in _BOOLEAN_COLUMNS:
        return pa.bool_()
    return pa.float64()


@dataclass
class FrameRows:
    """One frame's rows: the column names, and the columns (name -> scalar or (n,) array) or their CSV lines.

    A frame measured on a worker for a CSV comes back with its lines only (``as_text``); else with
    its columns, whose lines ``csv_lines`` formats on first use.
    """
    header: list[str]
    n: int
    columns: dict[str, Any] | None = None
    lines: str | None = None

    def csv_lines(self) -> str:
        """One CSV line per point, each ending in a newline."""
        if self.lines is None:
            assert self.columns is not None, "a frame's rows hold their columns or their lines"
            self.lines = csv_rows(self.columns, self.n)
        return self.lines

    def as_text(self) -> "FrameRows":
        """The same rows as CSV lines only (what a worker sends back for a CSV: no columns travel)."""
        return FrameRows(list(self.header), self.n, lines=self.csv_lines())

    def with_force(self, force_N: float | None, stress_MPa: float | None) -> FrameRows:
        """These rows with the frame's force and engineering stress (``FORCE_COLUMNS``) on every row.

        ``livedic replay --load``: one value per frame, repeated on its points' rows (the long format of
        the other per-frame columns, frame and timestamp_ns); NaN where unknown (no sample around the frame).
        """
        values = [_known(force_N), _known(stress_MPa)]
        header = list(self.header) + list(FORCE_COLUMNS)
        if self.columns is None:
            assert self.lines is not None             # rows are columns or lines
            cells = ",".join(scalar_text(value) for value in values)
            return FrameRows(header, self.n, lines=self.lines.replace("\n", f",{cells}\n"))
        return FrameRows(header, self.n, columns={**self.columns, **dict(zip(FORCE_COLUMNS, values))},
                         lines=None)

    def record_batch(self) -> pa.RecordBatch:
        """The rows as an Arrow record batch typed by ``column_type`` (needs the columns)."""
        if self.columns is None:
            raise ValueError("these rows were formatted as CSV lines: their columns did not travel")
        arrays = []
        for name in self.header:
            values = np.asarray(self.columns[name])
            dtype = column_type(name).to_pandas_dtype()
            arrays.append(pa.array(np.full(self.n, values, dtype=dtype) if values.ndim == 0
                                   else values.astype(dtype, copy=False)))
        return pa.RecordBatch.from_arrays(arrays, schema=_schema(self.header))


def _known(value: float | None) -> float:
    """A per-frame number, NaN where unknown (None, NaN or infinite)."""
    return float(value) if value is not None and np.isfinite(value) else float("nan")


def _schema(header: list[str]) -> pa.Schema:
    return pa.schema([(name, column_type(name)) for name in header])


def frame_rows(frame_index: int, timestamp_ns: int, point_ids: np.ndarray, measurement: Measurement,
               strain: StrainField, stage: StrainStage | None = None) -> FrameRows:
    """The rows of one frame of the replay output.

    Parameters
    ----------
    frame_index, timestamp_ns : int
    point_ids : ndarray (N,)
    measurement : dic.result.Measurement
        Its ``status`` and, when it has them, ``ux, uy, vx, vy, iterations`` become columns.
    strain : dic.strain.StrainField
        ``exx, eyy, exy`` at the points (recomputed on the replayed displacements).
    stage : stream.stages.strain.StrainStage, optional
        The strain stage that computed ``strain``: with a scale (``--scale`` or the calibration's px/mm) the
        displacements on the specimen plane in mm (``FIELD_MM_COLUMNS``, as ``livedic export``'s fields.csv).

    Returns
    -------
    FrameRows
        Columns ``LEADING_COLUMNS``, then the extras in ``EXTRA_COLUMNS`` order, then ``STRAIN_COLUMNS``, then
        ``STEREO_COLUMNS`` for a stereo measurement (``dic.stereo.StereoMeasurement``), else ``FIELD_MM_COLUMNS``
        when ``stage`` has a scale.
    """
    m = measurement
    extras = {"status": np.asarray(m.status, dtype=np.int64)}
    for name in _GRADIENTS:
        value = getattr(m, name)
        if value is not None:
            extras[name] = value
    columns = result_columns(frame_index, timestamp_ns, point_ids, m.x, m.y, m.u, m.v, m.zncc, m.ok, extras)
    columns.update(exx=strain.exx, eyy=strain.eyy, exy=strain.exy)
    header = list(LEADING_COLUMNS) + [name for name in EXTRA_COLUMNS if name in extras] + list(STRAIN_COLUMNS)
    in_space = stereo_columns(stereo_arrays(m))
    in_mm = None if in_space or stage is None else stage.displacements_mm(m.u, m.v)
    columns.update(in_space or zip(FIELD_MM_COLUMNS, in_mm or ()))
    header += list(mm_columns(bool(in_space), in_mm is not None))
    return FrameRows(header, len(m.u), columns={name: columns[name] for name in header})


# ----------------------------------------------------------------------------- writers

def output_format(output: str | None) -> str:
    """``"csv"`` or ``"parquet"``, from the suffix of ``-o`` (None or ``-``: CSV on stdout); else ``OutputError``."""
    if output in (None, "-"):
        return "csv"
    suffix = os.path.splitext(os.fspath(output))[1].lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise OutputError(f"-o {output}: the suffix chooses the format: give a file ending in .csv or .parquet "
                          f"(e.g. replay.csv, replay.parquet)")
    return OUTPUT_SUFFIXES[suffix]


def check_rows_output(output: str | None, recording: str) -> None:
    """Refuse an ``-o`` that would destroy the recording, has no known format or cannot be written
    (``OutputError``, one line), before anything is read."""
    if output in (None, "-"):
        return
    if os.path.isdir(output):
        raise OutputError(f"-o {output} is a folder: give a file name, e.g. {os.path.join(output, 'replay.csv')}")
    if output.lower().endswith(".mcap"):
        raise OutputError(f"-o {output} ends in .mcap: the output is CSV or Parquet (e.g. replay.csv, "
                          f"replay.parquet); recordings are never written over")
    output_format(output)
    if os.path.exists(output) and os.path.exists(recording) and os.path.samefile(output, recording):
        raise OutputError(f"-o {output} is the recording itself: choose another file")
    check_output_file(output, "-o")


class CsvRows:
    """Writes the rows to a text stream: the header with the first frame, then every frame's lines."""
    csv_text = True                 # the parallel replay formats the lines on its workers

    def __init__(self, out: TextIO | StagedFile) -> None:
        self.out = out
        self.header: list[str] | None = None

    def __call__(self, rows: FrameRows) -> None:
        if self.header is None:
            self.header = list(rows.header)
            self.out.write(",".join(self.header) + "\n")
        self.out.write(self.lines_of(rows))

    def lines_of(self, rows: FrameRows) -> str:
        """The CSV lines of ``rows``."""
        return rows.csv_lines()

    def close(self) -> None:
        pass

    def abandon(self) -> None:
        pass


class ParquetRows:
    """Writes the rows to a binary stream as a Parquet file, a row group every ``ROW_GROUP_ROWS`` rows or so."""
    csv_text = False                # the workers send the columns

    def __init__(self, handle: IO[bytes], row_group_rows: int = ROW_GROUP_ROWS) -> None:
        self.handle = handle
        self.row_group_rows = int(row_group_rows)
        self.writer: Any = None                 # a pyarrow.parquet.ParquetWriter once the schema is known
        self.waiting: list[pa.RecordBatch] = []
        self.waiting_rows = 0

    def __call__(self, rows: FrameRows) -> None:
        batch = rows.record_batch()
        if self.writer is None:
            self._open(batch.schema)
        elif not batch.schema.equals(self.writer.schema):
            raise ValueError(f"frame rows with other columns than the first frame's: {batch.schema.names} after "
                             f"{self.writer.schema.names}")
        self.waiting.append(batch)
        self.waiting_rows += batch.num_rows
        if self.waiting_rows >= self.row_group_rows:
            self._write_waiting()

    def _open(self, schema) -> None:
        import pyarrow.parquet as pq        # here: every livedic command imports this module, few write Parquet
        self.writer = pq.ParquetWriter(self.handle, schema, compression=PARQUET_COMPRESSION)

    def _write_waiting(self) -> None:
        if self.waiting:
            table = pa.Table.from_batches(self.waiting)
            self.writer.write_table(table, row_group_size=table.num_rows)
        self.waiting, self.waiting_rows = [], 0

    def close(self) -> None:
        """Write what waits and the file's footer (a file of the leading columns and no rows if no frame came)."""
        if self.writer is None:
            self._open(_schema(list(LEADING_COLUMNS) + list(STRAIN_COLUMNS)))
        self._write_waiting()
        self.writer.close()

    def abandon(self) -> None:
        """After a failure: close without raising (the staged file is removed anyway)."""
        if self.writer is not None:
            try:
                self.writer.close()
            except Exception:
                pass
            self.writer.is_open = False       # its destructor would try again


@contextmanager
def rows_output(path: str) -> Iterator[CsvRows | ParquetRows]:
    """The writer of ``livedic replay -o path`` (``CsvRows`` or ``ParquetRows`` by ``output_format``), on a
    ``StagedFile``: renamed into place when the block ends normally, removed on an error or Ctrl-C."""
    parquet = output_format(path) == "parquet"
    with StagedFile(path, binary=parquet) as staged:
        writer = ParquetRows(staged.handle) if parquet else CsvRows(staged)
        try:
            yield writer
        except BaseException:
            writer.abandon()
            raise
        writer.close()
        staged.commit()
