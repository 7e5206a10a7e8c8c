"""The machine's force channel of a recording: /machine/force (livedic.ForceSample).

Written by ``acquire.recording.writer.Recorder.write_force``, read back by ``acquire.recording.reader``
(``Recording.force_samples``, ``read_force_samples``), and decodable without livedic from the
schema stored in the file."""

import math
import os

import numpy as np
import pytest

from livedic.acquire.recording import schema as rs
from livedic.acquire.base import Frame
from livedic.acquire.recording.reader import Recording, read_force_samples, read_results
from livedic.acquire.recording.recover import recover
from livedic.acquire.recording.writer import Recorder

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SAMPLE = os.path.join(REPO, "recordings", "sample-tensile.mcap")
T0 = 1_700_000_000_000_000_000
DT = 20_000_000
AREA_MM2 = 20.0
SOURCE = "csv:/data/machine.csv"
# force per frame; frame 3 had no value from the load (a late stream): NaN
FORCES = [0.0, 1234.5, 2469.0, math.nan, 4938.0, -12.25]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("force") / "force.mcap"
    with Recorder(path, {"source_uri": "test:force"}, chunk_bytes=4096) as rec:
        for i, force in enumerate(FORCES):
            rec.write_frame(Frame(i, T0 + i * DT, np.zeros((8, 8), np.uint8), "Mono8"))
            assert rec.write_results(i, T0 + i * DT, np.arange(3), np.zeros(3), np.zeros(3), np.zeros(3),
                                     np.zeros(3), np.ones(3), np.ones(3, bool))
            stress = force / AREA_MM2 if i != 5 else math.nan          # frame 5: no cross-section known
            assert rec.write_force(i, T0 + i * DT, force, stress, source=SOURCE)
    assert (rec.force_written, rec.force_dropped) == (len(FORCES), 0)
    return str(path)


def _same(a, b):
    """Equal bit for bit, NaN included."""
    return (math.isnan(a) and math.isnan(b)) or a == b


def test_force_round_trip_is_exact(recorded):
    samples = read_force_samples(recorded)
    assert [(s.frame_index, s.timestamp_ns) for s in samples] == [(i, T0 + i * DT) for i in range(len(FORCES))]
    for sample, force in zip(samples, FORCES):
        assert _same(sample.force_N, force) and sample.source == SOURCE
        assert sample.ok == (not math.isnan(force))                     # ok is "force is a number"
    assert samples[2].stress_MPa == 2469.0 / AREA_MM2 == 123.45
    assert math.isnan(samples[3].stress_MPa) and math.isnan(samples[5].stress_MPa) and samples[5].ok
    again = list(Recording(recorded).force_samples())
    assert [(s.frame_index, s.force_N) for s in again if s.ok] == [(s.frame_index, s.force_N) for s in samples if s.ok]
    assert len(read_results(recorded)) == len(FORCES)                   # the other channels as before


def test_protobuf_decodes_the_force_channel_from_the_stored_schema(recorded):
    """Foxglove, rerun and mcap-protobuf-support read it without livedic."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    decoded_all = []
    with open(recorded, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(topics=[rs.TOPIC_FORCE]):
            assert schema.name == "livedic.ForceSample" and channel.topic == "/machine/force"
            assert message.log_time == decoded.timestamp_ns and message.sequence == decoded.frame_index
            decoded_all.append(decoded)
    assert [d.frame_index for d in decoded_all] == list(range(len(FORCES)))
    assert decoded_all[1].force_N == 1234.5 and decoded_all[1].stress_MPa == 1234.5 / AREA_MM2
    assert math.isnan(decoded_all[3].force_N) and not decoded_all[3].ok and decoded_all[4].ok
    assert {d.source for d in decoded_all} == {SOURCE}


def test_recordings_without_force_read_empty():
    """The shipped sample predates the channel: no force samples, results as before."""
    assert read_force_samples(SAMPLE) == [] and list(Recording(SAMPLE).force_samples()) == []
    assert len(read_results(SAMPLE)) > 0


def test_recovered_and_truncated_recordings_keep_the_force(recorded, tmp_path):
    fixed = tmp_path / "fixed.mcap"
    summary = recover(recorded, fixed)
    assert summary["message_counts"][rs.TOPIC_FORCE] == len(FORCES)
    assert [s.force_N for s in read_force_samples(fixed)][:3] == FORCES[:3]
    data = open(recorded, "rb").read()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:int(len(data) * 0.6)])
    recording = Recording(cut)
    partial = list(recording.force_samples())
    assert not recording.info.indexed and [s.frame_index for s in partial] == list(range(len(partial)))
    assert [s.force_N for s in partial][:3] == FORCES[:min(3, len(partial))]


def test_none_is_nan_and_bad_values_raise_at_once(tmp_path):
    with Recorder(tmp_path / "r.mcap", {}) as rec:
        with pytest.raises(ValueError, match="write_force: force_N must be a number or NaN"):
            rec.write_force(0, T0, "12 kN", 1.0)
        with pytest.raises(ValueError, match="write_force: frame_index must be >= 0"):
            rec.write_force(-1, T0, 1.0, 1.0)
        with pytest.raises(ValueError, match="timestamp_ns"):
            rec.write_force(0, -5, 1.0, 1.0)
        assert rec.write_force(0, T0, None, None) and rec.write_force(1, T0 + DT, np.float32(2.5), 0.125)
    assert rec.error is None and rec.force_written == 2
    first, second = read_force_samples(rec.path)
    assert math.isnan(first.force_N) and math.isnan(first.stress_MPa) and not first.ok and first.source == ""
    assert (second.force_N, second.stress_MPa, second.ok) == (2.5, 0.125, True)


def test_a_stopped_recorder_counts_dropped_force(tmp_path):
    rec = Recorder(tmp_path / "r.mcap", {})
    assert rec.write_force(0, T0, 10.0, 0.5)
    rec.close()
    assert not rec.write_force(1, T0 + DT, 11.0, 0.55)
    assert (rec.force_written, rec.force_dropped) == (1, 1)
    assert [s.force_N for s in read_force_samples(rec.path)] == [10.0]
