"""``livedic replay`` and ``livedic export`` of a stereo recording: the replay re-runs the stereo measurement (both
views paired by frame index, the recorded rig, the same tracker) and gives the recorded 3D points and surface
strain back; a right
frame missing from the file drops that pair, counted, never mismatched; export writes the recorded 3D columns;
bad input is one line and exit 2."""

import json

import numpy as np
import pytest

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording.reader import Recording, read_results, read_session
from livedic.stream.cli import main
from livedic.stream.export.columns import STEREO_COLUMNS
from tests.stream.replay.test_replay import _one_error_line, _rows

VIEW = "synthetic:stereo?view={}&frames=3&size=384x384&focal=3000&w0=0.5&pace=0"
PAIR = f"stereo:{VIEW.format('left')},{VIEW.format('right')}"
SPACE = ("X_mm", "Y_mm", "Z_mm", "U_mm", "V_mm", "W_mm")
TOLERANCE_MM = 1e-9          # same frames, same rig, same tracker: the same numbers but for the last digits


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A short stereo session recorded by ``livedic run`` in-process."""
    path = tmp_path_factory.mktemp("stereo") / "s.mcap"
    assert main(["run", "--source", PAIR, "--gauge-length", "15", "--viewer", "none", "--record", str(path),
                 "--progress", "off"]) == 0
    return str(path)


def _frame(rows, index):
    return [row for row in rows if int(row["frame"]) == index]


def _assert_3d_as_recorded(rows, result):
    """The rows of one frame hold its recorded 3D points, displacements and status."""
    assert [int(row["point_id"]) for row in rows] == result.point_id.tolist()
    for name in SPACE:
        got = np.array([float(row[name]) for row in rows])
        recorded = np.asarray(result.stereo[name.lower()], dtype=np.float64)
        assert np.array_equal(np.isnan(got), np.isnan(recorded)), name
        assert np.nanmax(np.abs(got - recorded)) <= TOLERANCE_MM, name
    assert [int(row["stereo_status"]) for row in rows] == result.stereo["stereo_status"].tolist()


def test_replay_gives_the_recorded_3d_results_back_with_the_3d_columns(recording, tmp_path, capsys):
    out = tmp_path / "replay.csv"
    capsys.readouterr()
    assert main(["replay", recording, "-o", str(out), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    header, rows = _rows(out)
    assert header[-len(STEREO_COLUMNS):] == list(STEREO_COLUMNS) and header[:3] == ["frame", "timestamp_ns", "point_id"]
    assert "u_mm" not in header                 # the 2D displacements in mm are a stereo session's U_mm, V_mm
    results = read_results(recording)
    assert sorted({int(row["frame"]) for row in rows}) == [r.frame_index for r in results] == [0, 1, 2]
    for result in results:
        _assert_3d_as_recorded(_frame(rows, result.frame_index), result)
    for strain in Recording(recording).strain_fields():      # the strain on the surface, as live
        part = _frame(rows, strain.frame_index)
        for name in ("exx", "eyy", "exy"):
            got = np.array([float(row[name]) for row in part])
            assert np.array_equal(np.isnan(got), np.isnan(getattr(strain, name)))
            assert np.nanmax(np.abs(got - getattr(strain, name))) <= 1e-12, name
    moved = np.array([float(row["W_mm"]) for row in _frame(rows, 2) if row["stereo_status"] == "0"])
    assert moved.size > 0.9 * len(_frame(rows, 2)) and np.all(np.abs(moved - 0.5) < 0.05)   # w0=0.5 mm towards
    assert "replay matches the recording exactly" in err
    assert "the recorded rig, which came from the simulator's exact rig" in err
    assert "3 pairs by frame index, 0 left and 0 right frame(s) without a partner dropped" in err


def test_replay_to_parquet_types_the_3d_columns(recording, tmp_path, capsys):
    pq = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "replay.parquet"
    assert main(["replay", recording, "-o", str(out), "--progress", "off"]) == 0
    table = pq.read_table(out)
    assert table.column_names[-len(STEREO_COLUMNS):] == list(STEREO_COLUMNS)
    assert str(table.schema.field("stereo_status").type) == "int64"
    assert str(table.schema.field("W_mm").type) == "double"
    last = read_results(recording)[-1]
    rows = table.to_pydict()
    w = np.array([w for frame, w in zip(rows["frame"], rows["W_mm"]) if frame == last.frame_index], dtype=float)
    assert np.array_equal(np.isnan(w), np.isnan(last.stereo["w_mm"]))
    assert np.nanmax(np.abs(w - last.stereo["w_mm"])) <= TOLERANCE_MM


def _without_right_frame(path, out, index):
    """A copy of recording ``path`` whose right view lacks frame ``index`` (lost on its way to the disk)."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    with open(path, "rb") as f:
        reader = make_reader(f)
        header, summary = reader.get_header(), reader.get_summary()
        metadata = [(record.name, dict(record.metadata)) for record in reader.iter_metadata()]
        messages = [(channel, message) for _, channel, message in reader.iter_messages(log_time_order=False)]
    with open(out, "wb") as handle:
        writer = Writer(handle)
        writer.start(profile=header.profile, library=header.library)
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(c.topic, c.message_encoding, schemas.get(c.schema_id, 0), c.metadata)
                    for cid, c in summary.channels.items()}
        for name, values in metadata:
            writer.add_metadata(name, values)
        for channel, message in messages:
            if channel.topic in rs.VIEW_TOPICS["right"] and message.sequence == index:
                continue
            writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time,
                               message.sequence)
        writer.finish()
    return str(out)


def test_a_right_frame_missing_drops_that_pair_counted_never_mismatched(recording, tmp_path, capsys):
    cut = _without_right_frame(recording, tmp_path / "cut.mcap", 1)
    out = tmp_path / "replay.csv"
    capsys.readouterr()
    assert main(["replay", cut, "-o", str(out), "--progress", "off"]) == 0
    err = capsys.readouterr().err
    _, rows = _rows(out)
    assert sorted({int(row["frame"]) for row in rows}) == [0, 2]            # frame 1's left view has no partner
    assert "0 left and 1 right" not in err and "1 left and 0 right frame(s) have no frame of the same index" in err
    assert "2 pairs by frame index, 1 left and 0 right frame(s) without a partner dropped" in err
    assert "1 recorded result set(s) have no image" in err
    results = read_results(recording)
    _assert_3d_as_recorded(_frame(rows, 0), results[0])
    # frame 2 paired with its own right view: its points in space are the recorded ones, to the tracker's
    # convergence (it starts from frame 0's displacements, not frame 1's)
    recorded = results[2].stereo
    got = np.array([[float(row[name]) for name in ("X_mm", "Y_mm", "Z_mm")] for row in _frame(rows, 2)])
    both = np.isfinite(got[:, 0]) & np.isfinite(recorded["x_mm"])
    assert both.sum() > 0.9 * len(got)
    xyz = np.column_stack([recorded["x_mm"], recorded["y_mm"], recorded["z_mm"]])
    assert np.max(np.linalg.norm(got[both] - xyz[both], axis=1)) < 1e-3


def test_export_writes_the_recorded_3d_columns(recording, tmp_path, capsys):
    out = tmp_path / "export"
    capsys.readouterr()
    assert main(["export", recording, "-o", str(out)]) == 0
    assert "the session's 3D results as recorded" in capsys.readouterr().err    # strain in space, as recorded
    header, rows = _rows(out / "fields.csv")
    assert header[-len(STEREO_COLUMNS):] == list(STEREO_COLUMNS) and "u_mm" not in header
    for result in read_results(recording):
        part = _frame(rows, result.frame_index)
        for name in SPACE:          # written at full precision: read back bit for bit
            assert np.array_equal(np.array([float(row[name]) for row in part]), result.stereo[name.lower()],
                                  equal_nan=True), name
        assert [int(row["stereo_status"]) for row in part] == result.stereo["stereo_status"].tolist()
    session = json.loads((out / "session.json").read_text())
    assert session["stereo"]["calibration"]["stereo"] is True


def test_a_2d_export_has_no_3d_columns(tmp_path, capsys):
    path = tmp_path / "flat.mcap"
    assert main(["run", "--source", "synthetic:tensile?size=128x256&frames=3&pace=0", "--record", str(path),
                 "--viewer", "none", "--n-points", "30", "--progress", "off"]) == 0
    assert main(["export", str(path), "-o", str(tmp_path / "out")]) == 0
    header, _ = _rows(tmp_path / "out" / "fields.csv")
    assert not set(STEREO_COLUMNS) & set(header)
    assert "stereo" not in read_session(str(path))


@pytest.mark.parametrize("case", ["rig-for-2d", "one-camera-file", "parallel", "missing-rig-file"])
def test_bad_stereo_input_is_one_line_and_exit_2(case, recording, tmp_path, capsys):
    from livedic.acquire.calibration import write_calibration
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.stereo_rig import StereoRig

    flat = tmp_path / "flat.mcap"
    if case == "rig-for-2d":
        assert main(["run", "--source", "synthetic:tensile?size=128x256&frames=2&pace=0", "--record", str(flat),
                     "--viewer", "none", "--n-points", "30", "--progress", "off"]) == 0
    rig = StereoRig.symmetric(Lens((384, 384), focal_px=3000.0), Lens((384, 384), focal_px=3000.0),
                              distance_mm=300.0, angle_deg=25.0).calibration()
    rig_file = tmp_path / "rig.json"
    write_calibration(rig_file, rig)
    one_camera = tmp_path / "left.json"
    write_calibration(one_camera, rig.left)
    out = tmp_path / "out.csv"
    argv, words = {
        "rig-for-2d": (["replay", str(flat), "--calibration", str(rig_file)], "recorded with one camera"),
        "one-camera-file": (["replay", recording, "--calibration", str(one_camera)], "one camera's calibration"),
        "parallel": (["replay", recording, "--workers", "2"], "stereo recording"),
        "missing-rig-file": (["replay", recording, "--calibration", str(tmp_path / "nope.json")], "does not exist"),
    }[case]
    capsys.readouterr()
    assert main(argv + ["-o", str(out), "--progress", "off"]) == 2
    assert words in _one_error_line(capsys.readouterr().err)
    assert not out.exists()


def test_calibration_replaces_the_recorded_rig(recording, tmp_path, capsys):
    """The recorded rig given as a file replays exactly; a rig 1 % wider places the points elsewhere in space
    (the views' tracking unchanged) and the verdict says by how much."""
    from dataclasses import replace

    from livedic.acquire.calibration import write_calibration
    from livedic.dic.calibration import StereoCalibration

    rig = StereoCalibration.from_dict(read_session(recording)["stereo"]["calibration"])
    same, wider = tmp_path / "same.json", tmp_path / "wider.json"
    write_calibration(same, rig)
    write_calibration(wider, replace(rig, translation_mm=np.asarray(rig.translation_mm) * 1.01))
    capsys.readouterr()
    assert main(["replay", recording, "--calibration", str(same), "-o", str(tmp_path / "a.csv"),
                 "--progress", "off"]) == 0
    err = capsys.readouterr().err
    assert "replay matches the recording exactly" in err and "calibration the calibration file given" in err
    assert main(["replay", recording, "--calibration", str(wider), "-o", str(tmp_path / "b.csv"),
                 "--progress", "off"]) == 0
    err = capsys.readouterr().err
    assert "replay differs from the recording" in err and "in space max" in err
    _, rows = _rows(tmp_path / "b.csv")
    z = np.array([float(row["Z_mm"]) for row in _frame(rows, 0)])
    recorded_z = read_results(recording)[0].stereo["z_mm"]
    assert np.nanmedian(z / recorded_z) == pytest.approx(1.01, abs=2e-3)    # depth scales with the baseline
