"""The strain and extensometer channels of a recording: /dic/strain and /dic/extensometers.

Written by ``acquire.recording.writer.Recorder.write_strain`` / ``write_extensometers``, read back by
``acquire.recording.reader``, and decodable without livedic from the schema stored in the file."""

import os

import numpy as np
import pytest

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.base import Frame
from livedic.acquire.recording.errors import CorruptRecording
from livedic.acquire.recording.reader import Recording, read_extensometer_samples, read_results, read_strain_fields
from livedic.acquire.recording.recover import recover
from livedic.dic.strain.extensometer import ExtensometerStatus
from livedic.dic.strain import StrainStatus
from livedic.acquire.recording.writer import Recorder
from livedic.stream.stages.strain import StrainConfig

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SAMPLE = os.path.join(REPO, "recordings", "sample-tensile.mcap")
T0 = 1_700_000_000_000_000_000
DT = 20_000_000


def _grid(step=10.0, n=12):
    xs, ys = np.meshgrid(np.arange(n) * step + 40.0, np.arange(n) * step + 30.0)
    points = np.column_stack([xs.ravel(), ys.ravel()])
    p0 = np.array([[40.0 + step * (n - 1) / 2, 30.0 + step * (n - 1) / 2]])
    return np.vstack([p0, points])


def _frames(points, stage, n_frames=5):
    """(u, v, ok, StrainField, ExtensometerReadings) per frame of a uniform stretch, one end lost in the last."""
    out = []
    for i in range(n_frames):
        u = 1e-3 * i * (points[:, 0] - 100.0)
        v = 3e-3 * i * (points[:, 1] - 90.0)
        ok = np.ones(len(points), bool)
        if i == n_frames - 1:
            ok[(points[:, 1] < 70) & (points[:, 0] > 60)] = False      # the top of the grid lost
            u[~ok] = v[~ok] = np.nan
        strain, readings = stage.compute(u, v, ok)
        out.append((u, v, ok, strain, readings))
    return out


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    points = _grid()
    stage = StrainConfig(window=5, measure="green", gauge_length=80.0, gauge_width=60.0).place(
        points, p0=points[0], roi=(40, 30, 110, 110), step=10.0, subset=21)
    frames = _frames(points, stage)
    path = tmp_path_factory.mktemp("strain") / "strain.mcap"
    with Recorder(path, {"source_uri": "test:strain"}, chunk_bytes=4096) as rec:
        for i, (u, v, ok, strain, readings) in enumerate(frames):
            rec.write_frame(Frame(i, T0 + i * DT, np.zeros((8, 8), np.uint8), "Mono8"))
            assert rec.write_results(i, T0 + i * DT, np.arange(len(points)), points[:, 0], points[:, 1], u, v,
                                     np.ones(len(points)), ok)
            assert rec.write_strain(i, T0 + i * DT, strain, window=stage.windows.window)
            assert rec.write_extensometers(i, T0 + i * DT, readings)
    assert (rec.strain_written, rec.extensometers_written, rec.strain_dropped) == (5, 5, 0)
    return str(path), points, stage, frames


def _same(a, b):
    """Equal bit for bit, NaN included."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return a.shape == b.shape and bool(np.all((a.view(np.uint64) == b.view(np.uint64)) | (np.isnan(a) & np.isnan(b))))


def test_strain_round_trip_is_exact(recorded):
    path, points, stage, frames = recorded
    strain = read_strain_fields(path)
    assert [s.frame_index for s in strain] == list(range(5))
    assert [s.timestamp_ns for s in strain] == [T0 + i * DT for i in range(5)]
    for got, (_, _, _, want, _) in zip(strain, frames):
        assert got.point_id.tolist() == list(range(len(points))) and got.point_id.dtype == np.uint32
        for name in ("exx", "eyy", "exy", "e1", "e2"):
            assert _same(getattr(got, name), getattr(want, name)), name
        assert np.array_equal(got.status, want.status) and got.status.dtype == np.int32
        assert (got.measure, got.window, got.vsg_px) == ("green", 5, stage.vsg_px) == ("green", 5, 61.0)
    last = strain[-1]
    # The lost points carry their reason, and no strain (NaN, never 0).
    assert np.any(last.status == int(StrainStatus.POINT_NOT_OK)) and np.all(np.isnan(last.exx[~last.ok]))
    # Green strain of the uniform stretch: exx = ux + ux^2 / 2 with ux = 1e-3 i, within rounding.
    assert np.allclose(strain[2].exx[strain[2].ok], 2e-3 + 0.5 * 2e-3 ** 2, rtol=0, atol=1e-12)
    assert np.allclose(strain[2].eyy[strain[2].ok], 6e-3 + 0.5 * 6e-3 ** 2, rtol=0, atol=1e-12)


def test_extensometer_round_trip_is_exact_and_one_message_each(recorded):
    path, _, _, frames = recorded
    samples = read_extensometer_samples(path)
    assert [(s.frame_index, s.name) for s in samples] == [(i, n) for i in range(5) for n in ("axial", "transverse")]
    readings = list(Recording(path).extensometer_readings())
    assert [(f, t) for f, t, _ in readings] == [(i, T0 + i * DT) for i in range(5)]
    for (_, _, got), (_, _, _, _, want) in zip(readings, frames):
        assert got.names == want.names
        for name in ("l0_px", "length_px", "eng_strain", "true_strain"):
            assert _same(getattr(got, name), getattr(want, name)), name
        assert np.array_equal(got.status, want.status)
    axial = [s for s in samples if s.name == "axial"]
    assert [s.ok for s in axial] == [True] * 4 + [False]          # its top end lost in the last frame
    assert axial[-1].status == int(ExtensometerStatus.END_LOST) and np.isnan(axial[-1].eng_strain)
    assert axial[-1].l0_px == 80.0 and abs(axial[3].eng_strain - 9e-3) < 1e-12     # v = 3e-3 i (y - 90)
    transverse = [s for s in samples if s.name == "transverse"]
    assert abs(transverse[3].eng_strain - 3e-3) < 1e-12 and abs(transverse[3].true_strain - np.log1p(3e-3)) < 1e-12


def test_a_stereo_sessions_lengths_in_space_round_trip_and_2d_ones_have_none(recorded, tmp_path):
    """l0_mm / length_mm (stereo: lengths in space, image lengths NaN) come back exactly, a lost end's NaN too;
    a 2D recording's samples have none."""
    from livedic.dic.strain.extensometer import ExtensometerReadings
    path = tmp_path / "stereo.mcap"
    nan = np.full(2, np.nan)
    readings = ExtensometerReadings(("axial", "transverse"), nan, nan, np.array([0.01, np.nan]),
                                    np.array([np.log1p(0.01), np.nan]),
                                    np.array([0, int(ExtensometerStatus.END_LOST)], dtype=np.int32),
                                    l0_mm=np.array([30.0, 12.5]), length_mm=np.array([30.3, np.nan]))
    with Recorder(path, {"source_uri": "stereo:a,b"}, stereo=True) as rec:
        assert rec.write_extensometers(0, T0, readings)
    ((_, _, got),) = list(Recording(path).extensometer_readings())
    assert np.array_equal(got.l0_mm, [30.0, 12.5]) and got.length_mm[0] == 30.3 and np.isnan(got.length_mm[1])
    assert np.isnan(got.l0_px).all() and got.eng_strain[0] == 0.01
    assert all(s.l0_mm is None and s.l_mm is None for s in read_extensometer_samples(recorded[0]))
    assert next(iter(Recording(recorded[0]).extensometer_readings()))[2].l0_mm is None


def test_protobuf_decodes_the_new_channels_from_the_stored_schema(recorded):
    """Foxglove, rerun and mcap-protobuf-support read them without livedic."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    path, points, _, frames = recorded
    strain, samples = [], []
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                topics=[rs.TOPIC_STRAIN, rs.TOPIC_EXTENSOMETERS]):
            assert message.log_time == decoded.timestamp_ns and message.sequence == decoded.frame_index
            if channel.topic == rs.TOPIC_STRAIN:
                assert schema.name == "livedic.StrainField"
                strain.append(decoded)
            else:
                assert schema.name == "livedic.ExtensometerSample"
                samples.append(decoded)
    assert len(strain) == 5 and len(samples) == 10
    assert list(strain[1].point_id) == list(range(len(points))) and strain[1].measure == "green"
    assert _same(np.array(strain[1].eyy), frames[1][3].eyy) and list(strain[4].status) == frames[4][3].status.tolist()
    axial = [s for s in samples if s.name == "axial"]
    assert [s.ok for s in axial] == [True] * 4 + [False] and axial[2].eng_strain == frames[2][4].eng_strain[0]


def test_recordings_without_the_channels_still_read():
    """The shipped sample predates them: no strain, no extensometers, results as before."""
    assert read_strain_fields(SAMPLE) == [] and read_extensometer_samples(SAMPLE) == []
    assert list(Recording(SAMPLE).extensometer_readings()) == []
    assert len(read_results(SAMPLE)) > 0


def test_truncated_and_recovered_recordings_keep_the_channels(recorded, tmp_path):
    path, _, _, _ = recorded
    data = open(path, "rb").read()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:int(len(data) * 0.6)])
    recording = Recording(cut)
    partial = list(recording.strain_fields())
    assert recording.info.truncated and len(partial) < 5
    assert [s.frame_index for s in partial] == list(range(len(partial)))
    fixed = tmp_path / "fixed.mcap"
    summary = recover(path, fixed)
    assert summary["message_counts"][rs.TOPIC_STRAIN] == 5 and summary["message_counts"][rs.TOPIC_EXTENSOMETERS] == 10
    assert len(read_strain_fields(fixed)) == 5 and len(read_extensometer_samples(fixed)) == 10


def test_a_corrupt_strain_message_is_one_clean_error(tmp_path):
    from livedic.acquire.recording.chunked_writer import ChunkedWriter

    path = tmp_path / "bad.mcap"
    with open(path, "wb") as handle:
        writer = ChunkedWriter(handle, chunk_bytes=1 << 20, compression=None, library="livedic/test")
        image = writer.register(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA, rs.schema_data(rs.RAW_IMAGE_SCHEMA))
        strain = writer.register(rs.TOPIC_STRAIN, rs.STRAIN_FIELD_SCHEMA, rs.schema_data(rs.STRAIN_FIELD_SCHEMA))
        writer.add("image", image, 5, wire.encode_raw_image(np.zeros((4, 6), np.uint8), 5))
        uneven = wire.encode_strain({"point_id": np.arange(3, dtype=np.uint32), "exx": np.zeros(2)})
        writer.add("data", strain, 5, uneven)
        writer.finish()
    with pytest.raises(CorruptRecording, match="strain message at log time 5 .*differ in length"):
        read_strain_fields(path)


def test_no_extensometers_writes_nothing_and_stopped_recorder_counts_drops(tmp_path):
    points = _grid()
    stage = StrainConfig().place(points, p0=points[0], roi=(40, 30, 110, 110), step=10.0, subset=21)
    (u, v, ok, strain, readings), = _frames(points, stage, n_frames=1)
    assert readings.names == ()
    path = tmp_path / "plain.mcap"
    rec = Recorder(path, {})
    assert rec.write_extensometers(0, T0, readings) and rec.write_strain(0, T0, strain)
    rec.close()
    assert not rec.write_strain(1, T0 + DT, strain) and not rec.write_extensometers(1, T0 + DT, readings)
    assert (rec.strain_written, rec.strain_dropped, rec.extensometers_written, rec.extensometers_dropped) == (1, 1, 1, 1)
    assert read_extensometer_samples(path) == [] and len(read_strain_fields(path)) == 1
    assert read_strain_fields(path)[0].window == 0          # not given: 0, as the schema says


def test_bad_calls_raise_at_once_and_leave_the_recorder_working(tmp_path):
    points = _grid()
    stage = StrainConfig(gauge_length=80.0).place(points, p0=points[0], roi=(40, 30, 110, 110), step=10.0,
                                                  subset=21)
    (_, _, _, strain, readings), = _frames(points, stage, n_frames=1)
    from dataclasses import replace
    with Recorder(tmp_path / "r.mcap", {}) as rec:
        with pytest.raises(ValueError, match="write_strain: eyy has 3 entries but exx has"):
            rec.write_strain(0, T0, replace(strain, eyy=np.zeros(3)))
        with pytest.raises(ValueError, match="frame_index must be >= 0"):
            rec.write_strain(-1, T0, strain)
        with pytest.raises(ValueError, match="write_extensometers: eng_strain has 1 entries for 2 names"):
            rec.write_extensometers(0, T0, replace(readings, eng_strain=np.zeros(1)))
        with pytest.raises(ValueError, match="timestamp_ns"):
            rec.write_extensometers(0, -5, readings)
        assert rec.write_strain(0, T0, strain) and rec.write_extensometers(0, T0, readings)
    assert rec.error is None and len(read_strain_fields(rec.path)) == 1
