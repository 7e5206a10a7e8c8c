"""CSV text of numeric columns at full precision, formatted a column at a time.

``csv_rows(columns, n)`` is the text every long CSV of livedic is written in (``replay -o OUT.csv``,
``export``'s ``fields.csv``, ``p0_trace.csv``, ``extensometers.csv``, ``stress_strain.csv``): a float is
Python's ``repr`` of it as a float64 (the shortest text that reads back as the same double: ``0.1``,
``1.0``, ``-0.0``, ``1e-05``, ``1e+16``, ``nan``, ``inf``), an integer its decimal digits, a boolean
``1``/``0``, text as given (the caller quotes it where CSV needs it); a scalar column repeats on every row.

Why not ``repr`` cell by cell: at ~0.4 us a float that was ~30 ms a frame of 2,000 points, as long as
tracking it. Arrow's cast float64 -> string (``pyarrow.compute``, C++) finds the same shortest digits
several times faster but lays some of them out otherwise (``1`` for ``1.0``, ``1e-7`` for ``1e-07``,
``0.00001`` for ``1e-05``, ``1e+10`` for ``10000000000.0``); a few rewrites (an appended ``.0``, three
regular expressions), each on the values whose text differs only, turn its text into Python's, and the
values Arrow writes in exponent form where Python does not (1e10 <= |x| < 1e16, rare in a measurement)
are written by ``repr``. Whether the installed Arrow still lays numbers out that way is
checked once, on values of every decimal exponent, against ``repr``; where it does not, every float is
written by ``repr`` (slower, the same text).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.compute as pc

__all__ = ["csv_rows", "float_texts", "scalar_text"]

# Where Arrow's layout of a float64 differs from Python's repr (the digits are the same: both write the
# shortest digits that read back as the same double, the nearest of them to it):
# - an integral value (below 1e10, where Arrow writes it positionally) lacks the ".0": 100 -> 100.0;
# - decimal exponents -9 to -7 have one digit: 1e-7 -> 1e-07;
# - decimal exponents -6 and -5 are positional: 0.00001 -> 1e-05;
# - decimal exponents 10 to 15 are in exponent form (1e+10), Python's positional: repr writes these.
# The magnitude ranges below only choose which values each rewrite runs on (with a wide margin: the
# patterns themselves are exact); outside them Arrow's text is already Python's.
_INTEGRAL_BELOW = 1e10
_ONE_DIGIT_EXPONENT = (5e-11, 2e-6)
_POSITIONAL_SMALL = (5e-7, 2e-4)
_REPR_RANGE = (1e10, 1e16)              # exact bounds: both are doubles, so the text's exponent is 10..15


def scalar_text(value: object) -> str:
    """One cell: a float as its ``repr`` (``nan``, ``inf``), a boolean 1/0, anything else its ``str``."""
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def float_texts(values: npt.ArrayLike) -> pa.StringArray:
    """``values`` (any real array) as float64 texts, each Python's ``repr`` of the float64."""
    values = np.ascontiguousarray(values, dtype=np.float64).ravel()
    if not _arrow_lays_out_as_expected():
        return pa.array([repr(value) for value in values.tolist()], type=pa.string())
    return _arrow_float_texts(values)


def _arrow_float_texts(values):
    text = pc.cast(pa.array(values), pa.string())
    magnitude = np.abs(values)
    with np.errstate(invalid="ignore"):
        integral = (values == np.floor(values)) & (magnitude < _INTEGRAL_BELOW)
    one_digit = _within(magnitude, _ONE_DIGIT_EXPONENT)
    small = _within(magnitude, _POSITIONAL_SMALL)
    large = (magnitude >= _REPR_RANGE[0]) & (magnitude < _REPR_RANGE[1])
    differs = integral | one_digit | small | large
    # the rewrites on the values whose text differs only, merged back once
    return _rewrite(text, differs, lambda part: _to_python(part, values[differs], integral[differs],
                                                           one_digit[differs], small[differs], large[differs]))


def _to_python(text, values, integral, one_digit, small, large):
    text = _rewrite(text, integral, lambda part: pc.binary_join_element_wise(part, ".0", ""))
    text = _rewrite(text, one_digit, lambda part: pc.replace_substring_regex(part, pattern=r"e-(\d)$",
                                                                             replacement=r"e-0\1"))
    text = _rewrite(text, small, _exponent_form)
    return _rewrite(text, large, lambda part: pa.array([repr(value) for value in values[large].tolist()],
                                                       pa.string()))


def _within(magnitude, bounds):
    return (magnitude > bounds[0]) & (magnitude < bounds[1])


def _exponent_form(text):
    """Arrow's positional 0.0000ddd (exponent -5) and 0.00000ddd (-6) as Python writes them: d.dde-05."""
    text = pc.replace_substring_regex(text, pattern=r"^(-?)0\.00000([1-9])(\d*)$", replacement=r"\1\2.\3e-06")
    text = pc.replace_substring_regex(text, pattern=r"^(-?)0\.0000([1-9])(\d*)$", replacement=r"\1\2.\3e-05")
    return pc.replace_substring(text, pattern=".e", replacement="e")          # one digit: 1.e-05 -> 1e-05


def _rewrite(text, where, rewrite):
    """``text`` with its elements at ``where`` (a boolean array) replaced by ``rewrite(those elements)``."""
    if not where.any():
        return text
    if where.all():
        return rewrite(text)
    mask = pa.array(where)
    return pc.replace_with_mask(text, mask, rewrite(pc.filter(text, mask)))


@functools.lru_cache(maxsize=1)
def _arrow_lays_out_as_expected() -> bool:
    """True when ``_arrow_float_texts`` gives ``repr``'s text for values of every decimal exponent."""
    mantissas = np.array([1.0, 1.5, 1.2345678901234567, 9.999999999999998, 3.0000000000000004])
    exponents = np.arange(-320, 308)
    values = (mantissas[:, None] * 10.0 ** exponents[None, :].astype(np.float64)).ravel()
    rng = np.random.default_rng(20)
    scattered = rng.standard_normal(4000) * 10.0 ** rng.integers(-12, 18, 4000)
    any_bits = rng.integers(0, 2 ** 64, 1000, dtype=np.uint64).view(np.float64)
    special = [0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, 1.7976931348623157e308, 123.0, 0.0001,
               9.999999999999999e-05, 9999999999.999998]
    values = np.concatenate([values, -values, scattered, any_bits, special])
    return _arrow_float_texts(values).to_pylist() == [repr(value) for value in values.tolist()]


def _column_text(array):
    """A column that is not float as a string array of its texts (or one string scalar: the join repeats it)."""
    if array.ndim == 0:
        return pa.scalar(scalar_text(array.item()), pa.string())
    if array.dtype == bool:
        return pa.array(np.where(array, "1", "0"), pa.string())
    if array.dtype.kind in "OUS":
        return pa.array([scalar_text(value) for value in array.tolist()], pa.string())
    return pc.cast(pa.array(array), pa.string())


def _is_float_column(array):
    return array.ndim == 1 and array.dtype.kind not in "biuOUS"


def csv_rows(columns: Mapping[str, Any], n: int) -> str:
    """CSV lines (no header, each ending in a newline) for ``columns``: ordered name -> scalar or (n,) array."""
    if n == 0:
        return ""
    arrays = [np.asarray(values) for values in columns.values()]
    lengths = {name: len(array) for name, array in zip(columns, arrays) if array.ndim}
    if any(length != n for length in lengths.values()):
        raise ValueError(f"CSV columns of other lengths than {n} rows: {lengths}")
    floats = [array for array in arrays if _is_float_column(array)]
    # every float column in one call: the rewrites' fixed cost once a frame, not once a column
    float_text = float_texts(np.concatenate(floats)) if floats else None
    texts: list[Any] = []
    start = 0
    for array in arrays:
        if _is_float_column(array):
            assert float_text is not None     # a float column was among those concatenated
            texts.append(float_text.slice(start, n))
            start += n
        else:
            texts.append(_column_text(array))
    if all(isinstance(text, pa.Scalar) for text in texts):
        texts[0] = pa.array([texts[0].as_py()] * n, pa.string())      # the join needs one array to repeat along
    # the newline ends the last cell (a pass over one column, not over the lines)
    last = texts[-1]
    texts[-1] = pa.scalar(last.as_py() + "\n") if isinstance(last, pa.Scalar) \
        else pc.binary_join_element_wise(last, "\n", "")
    return _concatenated(pc.binary_join_element_wise(*texts, ","))


def _concatenated(strings: pa.StringArray) -> str:
    """The texts of ``strings`` one after another (its data buffer, no Python string per element)."""
    _, offsets, data = strings.buffers()
    bounds = np.frombuffer(offsets, dtype=np.int32)[strings.offset: strings.offset + len(strings) + 1]
    return memoryview(data)[bounds[0]:bounds[-1]].tobytes().decode("utf-8")
