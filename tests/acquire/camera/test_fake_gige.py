"""Tests of acquire/camera/fake_gige.py: GigE simulators started, found, serialised per address and stopped."""

import argparse
import socket
import subprocess
import sys

import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera import fake_gige
from livedic.acquire.camera.fake_gige import GVCP_PORT, ArvFakeGvCamera, GigEFakeCamera

pytestmark = pytest.mark.usefixtures("time_limit")


def test_the_running_simulator_is_listed_alive_and_holds_its_address(arv_fake_gv):
    assert arv_fake_gv.alive and arv_fake_gv.device_id == "Aravis-Fake-GV01"
    assert arv_fake_gv.listing["id"] == arv_fake_gv.device_id and arv_fake_gv.listing["address"] == "127.0.0.1"
    assert fake_gige._port_in_use("127.0.0.1", GVCP_PORT)
    # a second simulator on the address waits for the first one's lock, then says who holds it: none starts
    for second in (GigEFakeCamera(lock_timeout_s=0.2), ArvFakeGvCamera(serial="GV02", lock_timeout_s=0.2)):
        with pytest.raises(SourceError, match=f"another livedic fake GigE camera holds 127.0.0.1:{GVCP_PORT}"):
            second.start()
        assert not second.alive and second._process is None


def test_a_missing_program_is_named_with_its_package():
    camera = ArvFakeGvCamera(program="no-such-arv-fake-gv-camera")
    with pytest.raises(SourceError, match="no-such-arv-fake-gv-camera is not installed .Debian package aravis-tools"):
        camera.start()
    assert camera.output() == "" and not camera.alive


def test_a_stopped_camera_answers_nothing_and_refuses_a_reset():
    camera = GigEFakeCamera(serial="XYZ")
    assert camera.device_id == "Aravis-Fake-XYZ" and camera.uri == "aravis:127.0.0.1" and camera.pid is None
    assert camera.served() is None and not camera.alive
    with pytest.raises(SourceError, match="is not running"):
        camera.reset_count()
    camera.stop()                                               # stopping a stopped camera is harmless
    camera.kill()


def test_a_port_in_use_is_told_from_a_free_one():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", 0))
        port = held.getsockname()[1]
        assert fake_gige._port_in_use("127.0.0.1", port)
    assert not fake_gige._port_in_use("127.0.0.1", port)


def _waiting_child():
    """A child that runs until its stdin closes."""
    return subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE)


def test_a_process_is_stopped_politely_first_then_by_signal():
    polite = _waiting_child()
    fake_gige._stop_process(polite, polite.stdin.close)            # EOF: it ends by itself
    assert polite.returncode == 0 and polite.stdout.closed
    rude = _waiting_child()
    fake_gige._stop_process(rude, None)
    assert rude.returncode == -15 and rude.stdin.closed            # SIGTERM


def test_size_and_step_arguments_are_two_integers():
    assert fake_gige._pair("1024x768") == (1024, 768) and fake_gige._pair("1,-1") == (1, -1)
    with pytest.raises(argparse.ArgumentTypeError, match="expected two integers"):
        fake_gige._pair("5")
    with pytest.raises(SystemExit) as exit_code:
        fake_gige.main(["--bit-depth", "12"])
    assert exit_code.value.code == 2
