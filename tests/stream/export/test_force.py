"""Tests of stream/export/force.py: the recorded force per frame, a force file on frame times, and which of them
``livedic export`` / ``report`` use (``stress_from_args``)."""

import math

import numpy as np
import pytest

from livedic.stream.cli.main import build_parser
from livedic.stream.export.force import RecordedForce, _force_label, _force_on_frames, _open_stress_load, \
    stress_from_args
from livedic.stream.stages.stress import RECORDED_FORCE, StressOptions

FORCES = {0: 0.0, 1: 150.0, 3: math.nan}             # frame 2 has no sample; frame 3's load had no value


def _recording(path, forces, metadata):
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        for i in range(4):
            recorder.write_frame(Frame(i, i * 10**8, np.zeros((8, 8), np.uint8), "Mono8"))
            if i in forces:
                recorder.write_force(i, i * 10**8, forces[i], None, source="csv:first.csv" if i < 3 else "")
    return str(path)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    folder = tmp_path_factory.mktemp("force")
    return {"force": _recording(folder / "force.mcap", FORCES, {"command": "test", "area_mm2": 12.5}),
            "none": _recording(folder / "none.mcap", {}, {"command": "test"})}


def _args(recording, *options):
    return build_parser().parse_args(["export", recording, "-o", "unused", *options])


def test_the_recorded_force_per_frame_nan_where_there_is_none(recordings):
    from livedic.acquire.recording.reader import Recording
    recorded = RecordedForce.read(Recording(recordings["force"]))
    assert recorded.source == "csv:first.csv"                  # the last one written that names it
    got = recorded.on_frames([1, 0, 2, 3, 9])
    assert got[:2].tolist() == [150.0, 0.0] and np.isnan(got[2:]).all()
    assert RecordedForce.read(Recording(recordings["none"])).forces == {}


def test_a_force_file_is_interpolated_onto_the_frame_times(tmp_path):
    from livedic.acquire.force import open_load
    path = tmp_path / "force.csv"
    path.write_text("time_s,force_N\n0,0\n1,100\n2,300\n")
    force = _force_on_frames(open_load(f"csv:{path}"), [7, 8, 9], [0.5, 1.5, 2.5])
    assert force[:2].tolist() == [50.0, 200.0] and np.isnan(force[2])      # never extrapolated
    assert _force_on_frames(RecordedForce({7: 1.0}), [7, 8], [0.0, 0.1])[0] == 1.0


def test_the_force_label_names_the_file_or_the_channel():
    assert _force_label(StressOptions("csv:/data/machine.csv", 0.0, 1.0)) == "machine.csv"
    assert _force_label(StressOptions(RECORDED_FORCE, 0.0, 1.0)) == "recorded /machine/force"


def test_the_stress_strain_curve_needs_an_axial_extensometer(recordings):
    from livedic.acquire.recording.reader import Recording
    stress = StressOptions(RECORDED_FORCE, 0.0, 10.0)
    assert _open_stress_load(None, [], Recording(recordings["force"])) is None
    with pytest.raises(ValueError, match=r"needs an 'axial' extensometer, and this recording has only transverse: "
                                         r"add --gauge-length"):
        _open_stress_load(stress, ["transverse"], Recording(recordings["force"]))
    with pytest.raises(ValueError, match="and this recording has none"):
        _open_stress_load(stress, [], Recording(recordings["force"]))
    load = _open_stress_load(stress, ["axial"], Recording(recordings["force"]))
    assert isinstance(load, RecordedForce) and load.forces[1] == 150.0


def test_without_load_the_recorded_force_with_the_sessions_area(recordings):
    stress, notes = stress_from_args(_args(recordings["force"]))
    assert stress == StressOptions(RECORDED_FORCE, 0.0, 12.5) and notes == []
    stress, _ = stress_from_args(_args(recordings["force"], "--area", "4"))
    assert stress.area_mm2 == 4.0
    assert stress_from_args(_args(recordings["none"])) == (None, [])


def test_a_given_load_replaces_the_recorded_force_with_a_note(recordings, tmp_path):
    stress, notes = stress_from_args(_args(recordings["force"], "--load", "csv:f.csv"))
    assert stress.load == "csv:f.csv" and stress.area_mm2 == 12.5            # A0 from the session
    assert notes == ["--load csv:f.csv is the force here, not the one recorded on /machine/force (3 frames)"]
    stress, notes = stress_from_args(_args(recordings["none"], "--load", "csv:f.csv", "--width", "2",
                                           "--thickness", "3"))
    assert stress.area_mm2 == 6.0 and notes == []


def test_bad_options_are_refused_before_the_recording_is_read(tmp_path):
    missing = str(tmp_path / "missing.mcap")
    with pytest.raises(ValueError, match="--load 'tcp://x:1'"):
        stress_from_args(_args(missing, "--load", "tcp://x:1", "--area", "2"))
