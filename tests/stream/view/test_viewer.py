"""Tests of stream/view/viewer.py: the --viewer modes, a viewer on loopback only (never spawned here), the .rrd writer."""

import os
import socket
import sys
import threading

import pytest

from livedic.stream.view import viewer
from livedic.stream.view.viewer import RrdFile, has_display, parse_viewer, spawn_viewer


def test_parse_viewer_modes(monkeypatch, tmp_path):
    default = str(tmp_path / "s.rrd")
    assert parse_viewer(["save", "a.rrd"], default) == ("save", "a.rrd", None)
    assert parse_viewer(["save"], default) == ("save", default, None)
    assert parse_viewer(["none"], default) == ("none", None, None)
    assert parse_viewer(["connect"], default) == ("connect", "rerun+http://127.0.0.1:9876/proxy", None)
    assert parse_viewer(["connect", "rerun+http://10.0.0.2:9000/proxy"], default)[1].startswith("rerun+http://10.")
    monkeypatch.setenv("DISPLAY", ":0")
    assert parse_viewer(["spawn"], default) == ("spawn", None, None)
    assert parse_viewer([], default)[0] == "spawn"


def test_spawn_without_a_display_saves_with_a_note(monkeypatch, tmp_path):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    mode, target, note = parse_viewer(["spawn"], str(tmp_path / "s.rrd"))
    assert (mode, target) == ("save", str(tmp_path / "s.rrd"))
    assert "no display" in note
    # the hint opens the file with a viewer on loopback only (plain "rerun FILE" listens on every interface)
    assert f"rerun --bind 127.0.0.1 {target}" in note


@pytest.mark.parametrize("words, message", [
    (["show"], "unknown viewer mode"), (["connect", "http://x:1"], "must start with"),
    (["save", "a.png"], ".rrd"), (["spawn", "extra"], "too many"), (["save", "a.rrd", "b.rrd"], "too many"),
])
def test_bad_viewer_words_raise(words, message):
    with pytest.raises(ValueError, match=message):
        parse_viewer(words, "x.rrd")


def test_spawned_viewer_binds_loopback_only():
    command = viewer._viewer_command(9876)
    assert command[command.index("--bind") + 1] == "127.0.0.1"


def test_a_display_is_either_variable(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert not has_display()
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    assert has_display()
    monkeypatch.delenv("WAYLAND_DISPLAY")
    monkeypatch.setattr(sys, "platform", "darwin")
    assert has_display()


def test_words_may_be_one_string():
    assert parse_viewer("save out.rrd", "x.rrd") == ("save", "out.rrd", None)


def test_a_viewer_already_listening_on_loopback_is_reused_not_spawned():
    listening = socket.socket()
    listening.bind(("127.0.0.1", 0))
    listening.listen(1)
    try:
        assert spawn_viewer(listening.getsockname()[1]) is None
    finally:
        listening.close()


def test_without_the_rerun_program_the_message_says_what_to_do(monkeypatch):
    monkeypatch.setattr(viewer.os.path, "exists", lambda path: False)
    monkeypatch.setattr(viewer.shutil, "which", lambda name: None)
    with pytest.raises(ValueError, match=r"'rerun' program is not installed .*or use --viewer save FILE.rrd$"):
        viewer._viewer_command(9876)


def test_the_rrd_file_gets_every_byte_written_to_the_sink(tmp_path):
    errors = []
    path = tmp_path / "view.rrd"
    rrd = RrdFile(path, errors.append)
    data = os.urandom(3 << 20)                        # more than the pipe and one read hold
    with open(rrd.sink_path, "wb", closefd=True) as sink:
        sink.write(data)
    rrd.close()
    assert path.read_bytes() == data and rrd.bytes_written == len(data) and errors == [] and rrd.error is None


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (a device whose writes fail: disk full)")
def test_a_full_disk_is_one_message_and_the_sink_never_blocks():
    errors = []
    rrd = RrdFile("/dev/full", errors.append)
    done = threading.Event()

    def write():
        with open(os.dup(int(rrd.sink_path.rsplit("/", 1)[1])), "wb") as sink:
            for _ in range(8):
                sink.write(b"x" * (1 << 20))           # 8 MB: far more than a pipe holds, drained all the same
        done.set()

    writer = threading.Thread(target=write)
    writer.start()
    assert done.wait(30), "the sink blocked on a failed file"
    writer.join()
    rrd.close()
    assert len(errors) == 1 and "Rerun view file stopped: cannot write /dev/full" in errors[0]
    assert "the session goes on" in errors[0] and rrd.error.startswith("/dev/full: ")
