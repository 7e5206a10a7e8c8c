"""Tests of stream/publish/values.py: one frame's extensometer values and their JSON datagram (null, never NaN)."""

import dataclasses
import json
import math

import numpy as np

from livedic.acquire.base import Frame
from livedic.dic.strain.extensometer import ExtensometerReadings, ExtensometerStatus
from livedic.stream.publish.values import FrameValues, frame_values


def _values(valid=(True, False)):
    return FrameValues(frame=41, time_s=0.82, names=("axial", "transverse"), eng_strain=(0.00123, math.nan),
                       true_strain=(math.log1p(0.00123), math.nan), valid=valid)


def test_json_has_the_contract_keys_and_null_never_nan():
    message = json.loads(_values().as_json().decode("utf-8"))
    assert list(message)[:4] == ["frame", "time_s", "strain", "ok"]
    assert message["frame"] == 41 and message["time_s"] == 0.82
    assert message["strain"] == {"axial": 0.00123, "transverse": None}
    assert message["ok"] is False                        # one extensometer without a reading
    assert b"NaN" not in _values().as_json()
    both = FrameValues(frame=1, time_s=0.0, names=("axial",), eng_strain=(0.5,), true_strain=(0.4,), valid=(True,))
    message = json.loads(both.as_json())
    assert message["ok"] is True and message["strain"] == {"axial": 0.5}
    # A value marked valid but NaN is still null: NaN is never serialised.
    odd = dataclasses.replace(both, eng_strain=(math.nan,))
    assert json.loads(odd.as_json())["strain"] == {"axial": None}


def _result(readings, index=7):
    """A FrameResult-like object: ``frame_values`` reads only its frame and extensometer readings."""
    from types import SimpleNamespace
    return SimpleNamespace(frame=Frame(index, 0, np.zeros((2, 2), np.uint8), "Mono8"), extensometers=readings)


def _readings(eng, status):
    eng = np.asarray(eng, dtype=float)
    return ExtensometerReadings(names=("axial", "transverse", "upper"), l0_px=np.full(3, 100.0),
                                length_px=100.0 * (1 + eng), eng_strain=eng, true_strain=np.log1p(eng),
                                status=np.asarray(status, dtype=np.int64))


def test_frame_values_follow_the_asked_names_not_the_readings_order():
    lost = int(ExtensometerStatus.END_LOST)
    readings = _readings([0.01, -0.003, math.nan], [0, 0, lost])
    values = frame_values(_result(readings), ("upper", "axial", "missing"), time_s=1.5)
    assert (values.frame, values.time_s, values.names) == (7, 1.5, ("upper", "axial", "missing"))
    assert values.valid == (False, True, False)         # lost end; ok; no such extensometer
    assert values.eng_strain[1] == 0.01 and values.true_strain[1] == math.log1p(0.01)
    assert math.isnan(values.eng_strain[2]) and math.isnan(values.true_strain[2])
    assert values.ok is False


def test_an_ok_status_with_a_nan_strain_is_not_valid():
    readings = _readings([math.nan, 0.0, 0.0], [0, 0, 0])
    values = frame_values(_result(readings), ("axial", "transverse"), time_s=0.0)
    assert values.valid == (False, True)


def test_without_readings_nothing_is_valid_and_no_extensometer_is_not_ok():
    values = frame_values(_result(None), ("axial",), time_s=0.25)
    assert values.valid == (False,) and math.isnan(values.eng_strain[0]) and values.ok is False
    none = frame_values(_result(_readings([0.0] * 3, [0] * 3)), (), time_s=0.0)
    assert none.names == () and none.ok is False                 # nothing to publish is not "all ok"
    assert json.loads(none.as_json()) == {"frame": 7, "time_s": 0.0, "strain": {}, "ok": False, "true_strain": {}}
