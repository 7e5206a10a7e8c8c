"""``stream.output.csv_text``: the column-at-a-time CSV text is, byte for byte, the text livedic wrote cell by cell.

The contract (``replay -o OUT.csv``, ``export``'s CSV files): a float is Python's ``repr`` of it as a float64,
an integer its digits, a boolean 1/0, a scalar repeated on every row. The references here are that contract
written out cell by cell, and the formatter livedic used before (numpy's float -> str per cell, kept as
``livedic bench replay``'s baseline).
"""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from livedic.bench.replay import per_cell_csv_rows
from livedic.stream.output import csv_text as csv_text
from livedic.stream.output.csv_text import csv_rows, float_texts

SPECIAL = [0.0, -0.0, np.nan, -np.nan, np.inf, -np.inf, 5e-324, -5e-324, 2.2250738585072014e-308,
           1.7976931348623157e308, 1e-4, 9.999999999999999e-05, 1e-5, 1e-6, 1e-7, 1e-9, 1e-10, 1e-11, 1e10,
           9999999999.999998, 1e15, 1e16, 9999999999999998.0, 1e16 + 2, 123.0, -7.0, 0.1, 1.0 / 3.0, 2.0 ** 53]


def _repr_rows(columns, n):
    """The contract, cell by cell."""
    def cell(values, row):
        value = np.asarray(values)
        value = value.item() if value.ndim == 0 else value[row].item()
        if isinstance(value, bool):
            return "1" if value else "0"
        return repr(float(value)) if isinstance(value, float) else str(value)
    return "".join(",".join(cell(values, row) for values in columns.values()) + "\n" for row in range(n))


def _random_floats(rng, n):
    """n doubles of every kind: the special ones first (as many as fit), then random bit patterns (subnormals,
    huge, NaN payloads), values at every decimal exponent from 1e-12 to 1e18, rounded decimals, integral values."""
    bits = rng.integers(0, 2 ** 64, n, dtype=np.uint64).view(np.float64)
    scattered = rng.standard_normal(n) * 10.0 ** rng.integers(-12, 19, n)
    rounded = np.round(rng.standard_normal(n) * 1000.0, 3)
    integral = np.round(rng.standard_normal(n) * 10.0 ** rng.integers(0, 12, n))
    random = rng.permutation(np.concatenate([bits, scattered, rounded, integral]))
    return rng.permutation(np.concatenate([SPECIAL, -np.asarray(SPECIAL), random])[:n])


def _frame_like(rng, n):
    """A replay frame's columns, its floats of every kind, its integers and booleans, scalars among them."""
    floats = _random_floats(rng, n)
    with np.errstate(invalid="ignore"):                 # signalling NaN among the random bit patterns
        rounded = np.round(floats * 1e-3)
    return {
        "frame": 17, "timestamp_ns": 1_700_000_000_123_456_789,
        "point_id": np.arange(n, dtype=np.uint32),
        "x": floats, "y": rounded,
        "zncc": rng.uniform(-1.0, 1.0, n).astype(np.float32),
        "ok": rng.uniform(size=n) > 0.3,
        "status": rng.integers(-3, 9, n).astype(np.int64),
        "iterations": rng.integers(0, 2 ** 31 - 1, n).astype(np.int32),
        "big": rng.integers(0, 2 ** 64 - 1, n, dtype=np.uint64),
        "strain": rng.standard_normal(n) * 10.0 ** rng.integers(-9, -2, n),
        "force_N": float("nan"), "eng_stress_MPa": 12.5, "tiny": -3.0e-7, "flag": True,
    }


def test_random_frames_have_the_text_of_the_cell_by_cell_formatters(rng):
    for n in (1, 7, 4001):
        columns = _frame_like(rng, n)
        text = csv_rows(columns, n)
        assert text == per_cell_csv_rows(columns, n) == _repr_rows(columns, n)
        assert text.count("\n") == n


def test_every_kind_of_double_is_written_as_its_repr(rng):
    values = _random_floats(rng, 200_000)
    expected = [repr(value) for value in values.tolist()]
    assert float_texts(values).to_pylist() == expected
    assert [float(text) for text in expected[:1000]] == pytest.approx(values[:1000].tolist(), nan_ok=True)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True), min_size=1, max_size=60))
def test_any_list_of_floats_is_written_as_its_reprs(values):
    assert float_texts(np.array(values, dtype=np.float64)).to_pylist() == [repr(value) for value in values]


def test_float32_columns_are_the_repr_of_their_float64_value(rng):
    values = (rng.standard_normal(5000) * 10.0 ** rng.integers(-8, 8, 5000)).astype(np.float32)
    assert float_texts(values).to_pylist() == [repr(value) for value in values.astype(np.float64).tolist()]


def test_the_installed_arrow_passes_the_layout_check():
    """Else every float would go through repr: the same text, several times slower."""
    assert csv_text._arrow_lays_out_as_expected()


def test_where_arrow_lays_numbers_out_otherwise_repr_writes_them(rng, monkeypatch):
    monkeypatch.setattr(csv_text, "_arrow_lays_out_as_expected", lambda: False)
    columns = _frame_like(rng, 500)
    assert csv_rows(columns, 500) == _repr_rows(columns, 500)


def test_text_columns_scalars_alone_and_no_rows():
    names = np.array(["axial", '"transverse, left"', "résumé"], dtype=object)      # as given (the caller quotes)
    columns = {"frame": 3, "name": names, "L_px": np.array([1.0, np.nan, -0.0])}
    assert csv_rows(columns, 3) == '3,axial,1.0\n3,"transverse, left",nan\n3,résumé,-0.0\n'
    assert csv_rows({"frame": 3, "time_s": 0.5}, 2) == "3,0.5\n3,0.5\n"
    assert csv_rows({"u": np.array([])}, 0) == ""
