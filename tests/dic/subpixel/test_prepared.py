"""The checks every prepared IC-GN order shares (dic.subpixel.prepared): orders, starts, status, caps."""

import numpy as np
import pytest

from livedic.dic.status import Status
from livedic.dic.subpixel.prepared import check_iterations, point_orders, start_status, start_values


def test_one_order_for_all_or_one_per_point_up_to_the_methods_highest():
    orders, per_point = point_orders(1, 3, max_order=1)
    assert orders.tolist() == [1, 1, 1] and orders.dtype == np.int64 and not per_point
    orders, per_point = point_orders([0, 2, 1], 3, max_order=2)
    assert orders.tolist() == [0, 2, 1] and per_point


@pytest.mark.parametrize("order, max_order, words", [
    (2, 1, "order must be 0 (shift) or 1 (affine), or one of them per point, got 2"),
    (True, 2, "order must be 0 (shift), 1 (affine) or 2 (quadratic), or one of them per point, got True"),
    ([0, 3], 2, "got [0, 3]"),
    ([0, 1, 1], 1, "got [0, 1, 1]"),          # three orders for two points
])
def test_a_bad_order_is_one_line_naming_the_allowed_ones(order, max_order, words):
    with pytest.raises(ValueError) as error:
        point_orders(order, 2, max_order=max_order)
    assert words in str(error.value) and "\n" not in str(error.value)


def test_start_values_default_broadcast_or_one_per_point():
    assert np.isnan(start_values(None, 2, "u0", np.nan)).all()
    assert start_values(None, 2, "ux0", 0.0).tolist() == [0.0, 0.0]
    assert start_values(1.5, 3, "v0", np.nan).tolist() == [1.5, 1.5, 1.5]
    assert start_values([1, 2], 2, "v0", np.nan).dtype == np.float64
    with pytest.raises(ValueError, match=r"u0 must have shape \(3,\)"):
        start_values([1.0, 2.0], 3, "u0", np.nan)


def test_the_callers_status_overrides_only_where_it_is_not_ok():
    prepared = np.array([Status.OK, Status.FLAT_REFERENCE, Status.OK], np.int8)
    assert start_status(prepared, None, 3).tolist() == prepared.tolist()
    caller = np.array([Status.BAD_GUESS, Status.OK, Status.OK], np.int8)
    merged = start_status(prepared, caller, 3)
    assert merged.tolist() == [Status.BAD_GUESS, Status.FLAT_REFERENCE, Status.OK] and merged.dtype == np.int8
    with pytest.raises(ValueError, match=r"status must have shape \(3,\)"):
        start_status(prepared, caller[:2], 3)


@pytest.mark.parametrize("caps, words", [((0, 0.001, 4, 0.02), "max_iterations must be >= 1"),
                                          ((50, 0.001, -1, 0.02), "translation_iterations must be >= 0"),
                                          ((50, 0.0, 4, 0.02), "tolerances must be > 0")])
def test_iteration_caps_and_tolerances_are_checked(caps, words):
    check_iterations(50, 0.001, 0, 0.02)
    with pytest.raises(ValueError, match=words):
        check_iterations(*caps)
