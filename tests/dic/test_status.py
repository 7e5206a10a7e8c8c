"""Tests of dic/status.py: the per-point codes, their int twins for numba kernels and their descriptions."""

import numpy as np

from livedic.dic import status as status_module
from livedic.dic.status import Status


def test_every_code_has_an_int_twin_of_its_value():
    for member in Status:
        twin = getattr(status_module, member.name)
        assert type(twin) is int and twin == member.value


def test_codes_are_distinct_small_and_ok_is_zero():
    values = [member.value for member in Status]
    assert len(set(values)) == len(values) and Status.OK == 0
    assert all(0 <= v <= np.iinfo(np.int8).max for v in values)      # they live in int8 arrays
    assert Status(np.int8(Status.OUTLIER)) is Status.OUTLIER


def test_every_code_has_a_one_line_description():
    for member in Status:
        text = member.description
        assert text and "\n" not in text
    assert len({m.description for m in Status}) == len(Status)
    assert Status.OK.description == "measured"
