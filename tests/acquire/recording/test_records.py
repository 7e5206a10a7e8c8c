"""Tests of acquire/recording/records.py: recorded messages as frozen records, their views and checks."""

import dataclasses

import numpy as np
import pytest

from livedic.acquire.recording import records, schema as rs, wire
from livedic.acquire.recording.records import RecordedExtensometerSample, RecordingInfo
from livedic.dic.strain.extensometer import ExtensometerStatus


def _decoded(n=4, with_gradients=True):
    values = {"frame_index": 7, "timestamp_ns": 123, "point_id": np.arange(n, dtype=np.uint32),
              "x": np.arange(n) * 10.0, "y": np.arange(n) * 5.0, "u": np.full(n, 0.25), "v": np.full(n, -0.5),
              "zncc": np.linspace(0.9, 0.99, n), "ok": np.ones(n, bool), "status": np.zeros(n, np.int32),
              "method": "wso+icgn1", "processing_ns": 10, "latency_ns": -3, "reference_frame_index": 2,
              "dropped_frames": 1}
    if with_gradients:
        values.update(ux=np.full(n, 0.01), uy=np.zeros(n), vx=np.zeros(n), vy=np.full(n, -0.003),
                      iterations=np.full(n, 3, np.uint32))
    return wire.decode_results(wire.encode_results(values))


def test_results_record_carries_every_field_and_its_measurement():
    record = records.recorded_results(_decoded(), publish_time_ns=999)
    assert (record.frame_index, record.timestamp_ns, record.method, record.publish_time_ns) == (7, 123, "wso+icgn1", 999)
    assert (record.latency_ns, record.reference_frame_index, record.dropped_frames) == (-3, 2, 1)
    assert record.measurement.evaluations is None                      # not recorded
    for name in ("x", "y", "u", "v", "zncc", "ok", "ux", "vy", "iterations"):
        assert getattr(record, name) is getattr(record.measurement, name), name
    assert np.array_equal(record.u, np.full(4, 0.25)) and record.vy[0] == -0.003
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.frame_index = 8


def test_optional_arrays_not_recorded_are_none():
    record = records.recorded_results(_decoded(with_gradients=False), publish_time_ns=0)
    assert record.ux is None and record.uy is None and record.iterations is None
    assert np.array_equal(record.status, np.zeros(4))


def test_strain_record_from_a_protobuf_message():
    message = rs.StrainField(frame_index=3, timestamp_ns=-4, point_id=[5, 6, 7], exx=[0.01, float("nan"), 0.02],
                             eyy=[0, 0, 0], exy=[0, 0, 0], e1=[0.01, float("nan"), 0.02], e2=[0, 0, 0],
                             status=[0, 2, 0], measure="green", window=5, vsg_px=61.0)
    strain = records.recorded_strain(message)
    assert (strain.frame_index, strain.timestamp_ns, strain.measure, strain.window, strain.vsg_px) == (3, -4, "green",
                                                                                                  5, 61.0)
    assert strain.point_id.dtype == np.uint32 and strain.status.dtype == np.int32 and strain.exx.dtype == np.float64
    assert strain.ok.tolist() == [True, False, True] and np.isnan(strain.exx[1])


def test_strain_arrays_of_different_lengths_are_a_wire_error():
    message = rs.StrainField(point_id=[1, 2, 3], exx=[0.1, 0.2])
    with pytest.raises(wire.WireError, match="point_id 3, status 0, exx 2"):
        records.recorded_strain(message)


def test_empty_strain_message_is_an_empty_field():
    strain = records.recorded_strain(rs.StrainField())
    assert len(strain.point_id) == 0 and len(strain.ok) == 0 and strain.window == 0


def test_frame_readings_keep_the_recorded_order_and_status():
    bad = int(ExtensometerStatus.OK) + 1
    samples = [RecordedExtensometerSample(1, 10, "axial", 100.0, 101.0, 0.01, np.log(1.01), True,
                                          int(ExtensometerStatus.OK)),
               RecordedExtensometerSample(1, 10, "transverse", 50.0, np.nan, np.nan, np.nan, False, bad)]
    readings = records.frame_readings(samples)
    assert readings.names == ("axial", "transverse")
    assert readings.l0_px.tolist() == [100.0, 50.0] and readings.length_px[0] == 101.0
    assert readings.ok.tolist() == [True, False] and readings.status.dtype == np.int32
    assert np.isnan(readings.eng_strain[1]) and readings.true_strain[0] == np.log(1.01)
    empty = records.frame_readings([])
    assert empty.names == () and empty.eng_strain.shape == (0,)


def test_recording_info_counts_frames_from_the_image_topic():
    info = RecordingInfo(path="a.mcap", size_bytes=10)
    assert info.frames == 0 and info.note == "" and not info.truncated and info.start_ns is None
    info.message_counts.update({rs.TOPIC_IMAGE: 5, rs.TOPIC_RESULTS: 4})
    assert info.frames == 5
    assert RecordingInfo(path="b", size_bytes=0).message_counts == {}     # not shared between instances
