"""The camera as a user first meets it: Aravis's own simulator, ``arv-fake-gv-camera-0.8 -i 127.0.0.1``.

One simulator for the module (``arv_fake_gv``: GVCP's port is fixed). It keeps its registers between
connections like a real camera, so what one session leaves behind (a ROI, binning, a trigger, a
stream still running) is met by the next. Its images are Aravis's diagonal ramp: pixel (x, y) of the
frame with GigE block id ``i`` is ``(x + y + i) % 255`` (gain 0, exposure 10 ms), so every frame's
content is checked exactly.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from livedic.acquire.camera.aravis import open_uri
from livedic.acquire.camera.aravis_discovery import list_cameras
from livedic.acquire.base import NoFirstFrame, SourceError

pytestmark = pytest.mark.usefixtures("time_limit", "aravis")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
RAMP = "exposure_us=10000&gain_db=0"          # the simulator's ramp without scaling


def ramp(frame_id, shape):
    """Aravis's fake image (``arv_fake_camera_diagonal_ramp``, Mono8, unit scale)."""
    y, x = np.indices(shape)
    return ((x + y + frame_id) % 255).astype(np.uint8)


def grab(camera, n):
    frames = []
    for frame in camera:
        frames.append(frame)
        if len(frames) == n:
            break
    return frames


def livedic(*argv, cwd, timeout=180):
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          cwd=str(cwd), env=env, timeout=timeout)


def uris(arv_fake_gv):
    """The camera by its listed id, by address, and as the first camera."""
    return [arv_fake_gv.listing["uri"], f"aravis:{arv_fake_gv.address}", "aravis:"]


def test_discovery_lists_the_simulator_by_the_id_a_user_types(arv_fake_gv):
    cameras = {camera["id"]: camera for camera in list_cameras()}
    listed = cameras[arv_fake_gv.device_id]
    assert listed["uri"] == "aravis:Aravis-Fake-GV01" and listed["address"] == "127.0.0.1"
    assert listed["protocol"] == "GigEVision" and listed["serial"] == "GV01"


@pytest.mark.time_limit(120)
def test_every_form_of_the_uri_streams_the_camera_frames(arv_fake_gv):
    for uri in uris(arv_fake_gv):
        with open_uri(f"{uri}?{RAMP}") as camera:
            settings = camera.settings
            frames = grab(camera, 6)
        assert settings["device_id"] == ("Aravis-Fake-GV01" if uri != "aravis:127.0.0.1" else "127.0.0.1"), uri
        assert settings["address"] == "127.0.0.1" and settings["serial"] == "GV01"
        # the stream comes to this computer's address on the camera's subnet (opened by its id alone, Aravis
        # took the first interface whose discovery got an answer, eth0 here, and no frame ever came; this
        # process has run discovery already, so the user's fresh-process case is the livedic run test below)
        assert settings["interface_address"] == "127.0.0.1", (uri, settings["interface_address"])
        assert settings["roi"] == [0, 0, 2048, 2048] and settings["packet_size"] == 9000
        ids = [frame.metadata["frame_id"] for frame in frames]
        for frame in frames:
            assert frame.image.shape == (2048, 2048) and frame.pixel_format == "Mono8"
            assert np.array_equal(frame.image, ramp(frame.metadata["frame_id"], (2048, 2048))), (uri, frame.index)
        assert [frame.index - frames[0].index for frame in frames] == [(i - ids[0]) % 65535 for i in ids]


@pytest.mark.time_limit(300)
def test_livedic_run_streams_every_uri_livedic_cameras_prints(arv_fake_gv, tmp_path):
    listing = livedic("cameras", cwd=tmp_path)
    assert listing.returncode == 0, listing.stderr
    printed = [line.split()[0] for line in listing.stdout.splitlines()[1:] if line.startswith("aravis:")]
    assert "aravis:Aravis-Fake-GV01" in printed, listing.stdout
    for uri in [*printed, "aravis:", "aravis:127.0.0.1"]:
        summary = tmp_path / "summary.json"
        # the simulator's picture is a ramp, not speckle: the points go over the whole image (--roi full)
        done = livedic("run", "--source", uri, "--frames", "6", "--drop", "block", "--n-points", "50", "--roi", "full",
                       "--no-record", "--viewer", "none", "--progress", "off", "--summary-json", str(summary),
                       cwd=tmp_path)
        assert done.returncode == 0, (uri, done.stderr)
        result = json.loads(summary.read_text())
        assert result["acquired"] == 6 and result["frames"] == 6, (uri, result)
        summary.unlink()


def test_a_camera_left_in_another_state_opens_in_the_known_one(arv_fake_gv):
    """ROI, binning, pixel format and trigger from an earlier session never stay active silently."""
    with open_uri("aravis:Aravis-Fake-GV01?roi=16,8,64,48&binning=2&pixel_format=Mono16&trigger=software"
                  "&frame_rate=20") as camera:
        left = camera.settings
        assert next(iter(camera)).image.shape == (48, 64)
    with open_uri(f"aravis:Aravis-Fake-GV01?{RAMP}") as camera:
        settings = camera.settings
        frame = next(iter(camera))
    assert left["roi"] == [16, 8, 64, 48] and left["binning"] == [2, 2] and left["trigger"]["mode"] == "On"
    assert settings["found_at_open"]["roi"] == [16, 8, 64, 48]          # what the last session left ...
    assert settings["roi"] == [0, 0, 2048, 2048] and settings["binning"] == [1, 1]   # ... reset
    assert settings["pixel_format"] == "Mono8" and settings["trigger"]["mode"] == "Off"
    assert frame.image.shape == (2048, 2048) and np.array_equal(frame.image, ramp(frame.metadata["frame_id"],
                                                                                   (2048, 2048)))
    note = next(note for note in settings["notes"] if "not in livedic's default state" in note)
    assert "roi 16,8,64,48 -> 0,0,2048,2048" in note and "binning 2,2 -> 1,1" in note, note
    assert "pixel_format Mono16 -> Mono8" in note, note


def test_a_stream_left_running_is_stopped_before_the_camera_is_set_up(arv_fake_gv, aravis):
    """A session that ended without AcquisitionStop leaves the simulator acquiring: a new controller would
    get the stream at the old session's address (port 0 once its stream is gone), depending on who wins
    a race. The open stops it first (the acquisition register reads 0 before livedic starts it again)."""
    Aravis, _ = aravis
    camera = Aravis.Camera.new("127.0.0.1")
    stream = camera.create_stream(None, None)
    camera.start_acquisition()
    assert camera.get_integer("AcquisitionCommandRegister") == 1
    del stream, camera                    # Aravis gives up control; the simulator still acquires
    with open_uri(f"aravis:127.0.0.1?{RAMP}&roi=0,0,256,128") as source:
        stopped = source._camera.get_integer("AcquisitionCommandRegister")
        frames = grab(source, 5)
        stats = source.settings["stream"]
    assert stopped == 0
    assert stats["n_missing_packets"] == 0 and len(frames) == 5
    assert all(np.array_equal(f.image, ramp(f.metadata["frame_id"], (128, 256))) for f in frames)


@pytest.mark.time_limit(60)
def test_a_software_trigger_paces_the_frames(arv_fake_gv):
    # free running, the simulator sends 25 frames/s; triggered at 8/s it must send one frame per trigger
    with open_uri(f"aravis:Aravis-Fake-GV01?{RAMP}&roi=0,0,128,96&trigger=software&frame_rate=8") as camera:
        frames = grab(camera, 6)
        settings = camera.settings
    assert settings["trigger"]["mode"] == "On" and settings["trigger"]["source"] == "Software"
    assert settings["frame_rate"] == pytest.approx(25)        # the camera's own rate, left as it was
    ids = [frame.metadata["frame_id"] for frame in frames]
    assert [(b - a) % 65535 for a, b in zip(ids, ids[1:])] == [1] * 5, ids     # none lost, none extra
    assert len(frames) <= settings["software_triggers"] <= len(frames) + 1    # one frame per trigger
    assert all(np.array_equal(f.image, ramp(f.metadata["frame_id"], (96, 128))) for f in frames)


@pytest.mark.time_limit(60)
def test_a_line_trigger_that_never_comes_is_no_frame_not_a_lost_camera(arv_fake_gv):
    camera = open_uri("aravis:Aravis-Fake-GV01?trigger=line:0&timeout_s=0.3&roi=0,0,64,48")
    try:
        with pytest.raises(NoFirstFrame) as caught:
            next(iter(camera))
    finally:
        camera.close()
    error = caught.value
    assert error.checks[0].startswith("the trigger (trigger=line:0:rising waits for a rising edge on Line0")
    assert any("packet size" in check for check in error.checks)
    assert "never started streaming (not a lost camera)" in str(error) and " lost:" not in str(error), str(error)


@pytest.mark.time_limit(180)
def test_livedic_run_says_no_frame_came_and_what_to_check(arv_fake_gv, tmp_path):
    done = livedic("run", "--source", "aravis:Aravis-Fake-GV01?trigger=line:0&timeout_s=0.3&roi=0,0,64,48",
                   "--frames", "3", "--no-record", "--viewer", "none", "--progress", "off", cwd=tmp_path)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert done.returncode == 2 and len(errors) == 1 and "Traceback" not in done.stderr, done.stderr
    assert "opened but sent no frame since acquisition started" in errors[0] and " lost:" not in errors[0]
    assert "check (1) the trigger" in errors[0] and "(2) the GigE packet size" in errors[0], errors[0]


@pytest.mark.time_limit(180)
@pytest.mark.parametrize("option, message", [
    ("feature.NoSuchFeature=1", "this camera has no GenICam feature 'NoSuchFeature'"),
    ("trigger=line:0:falling", "TriggerActivation offers RisingEdge, not FallingEdge"),
    ("pixel_format=Mono12p", "pixel format Mono12p is not offered"),
])
def test_refused_camera_options_are_one_line_exit_2(arv_fake_gv, tmp_path, option, message):
    record = tmp_path / "refused.mcap"
    done = livedic("run", "--source", f"aravis:Aravis-Fake-GV01?{option}", "--record", str(record),
                   "--viewer", "none", "--progress", "off", cwd=tmp_path)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert done.returncode == 2 and len(errors) == 1 and "Traceback" not in done.stderr, done.stderr
    assert message in errors[0] and not record.exists(), errors[0]


@pytest.mark.time_limit(180)
def test_the_recording_keeps_what_the_camera_reported(arv_fake_gv, tmp_path):
    from livedic.acquire.recording.reader import read_session
    record = tmp_path / "camera.mcap"
    done = livedic("run", "--source", f"aravis:Aravis-Fake-GV01?{RAMP}&roi=0,0,256,192&feature.GainRaw=0"
                   "&feature.TestBoolean=true", "--frames", "4", "--n-points", "30", "--roi", "full", "--record", str(record),
                   "--viewer", "none", "--progress", "off", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    settings = read_session(str(record))["source_settings"]
    assert settings["model"] == "Fake" and settings["serial"] == "GV01" and settings["sensor_size"] == [2048, 2048]
    assert settings["roi"] == [0, 0, 256, 192] and settings["bit_depth"] == 8 and settings["binning"] == [1, 1]
    assert settings["features"] == {"GainRaw": {"asked": 0, "read": 0}, "TestBoolean": {"asked": True, "read": True}}
    assert settings["trigger"]["mode"] == "Off" and settings["exposure_us"] == 10000


def test_a_missing_camera_is_a_clean_source_error(arv_fake_gv):
    listed = r"available: .*Aravis-Fake-GV01 \(GigEVision, 127.0.0.1\)"
    with pytest.raises(SourceError, match=r"camera 'Aravis-Fake-NOPE' not found .*" + listed):
        open_uri("aravis:Aravis-Fake-NOPE")


@pytest.mark.time_limit(180)
def test_a_triggered_camera_says_it_waits_and_stops_on_ctrl_c(arv_fake_gv, tmp_path):
    """trigger=line:0 with no timeout_s waits for its trigger without a limit: the run says it is waiting
    (it sat silent) and a Ctrl-C ends it at once, nothing recorded."""
    import signal

    from tests.stream.conftest import _signal_when
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    record = tmp_path / "waited.mcap"
    process = subprocess.Popen([sys.executable, "-m", "livedic.stream.cli", "run", "--source",
                                "aravis:Aravis-Fake-GV01?trigger=line:0&roi=0,0,64,48", "--frames", "3",
                                "--record", str(record), "--viewer", "none", "--progress", "off"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=str(tmp_path), env=env)
    err, _ = _signal_when(process, lambda text: b"waiting for the first frame" in text, signal.SIGINT)
    assert "a triggered camera waits for its trigger" in err, err
    assert process.returncode == 0 and "nothing was recorded" in err and "Traceback" not in err, err
    assert not record.exists()
