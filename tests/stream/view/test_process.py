"""The Rerun view in its own process: the same .rrd as in the session's process, a view that stops cannot hold
the session back, a view that dies is said with its reason, a session that dies leaves a complete .rrd."""

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from livedic.stream.view import entities
from livedic.stream.view.camera_image import IMAGE_SKIP_MAX
from livedic.stream.view.logger import RerunLogger
from livedic.stream.pipeline.frame_result import SessionStats
from livedic.stream.view.process import BEHIND, ViewProcess, ViewProcessError
from tests.stream.view.test_logger_entities import _result, _scalars, _store_summary
from tests.waiting import wait_until

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
START = dict(image_shape=(96, 128), roi=(10, 20, 60, 40), p0_index=0, points=np.zeros((12, 2)), has_truth=True,
             title="test", source_settings={"model": "tensile"})


def _entities(path):
    return sorted(line.split()[0] for line in _store_summary(path).splitlines() if line.strip().startswith("/"))


def _log(view, frames):
    view.start(**START)
    for i in range(frames):
        view(_result(i), SessionStats())       # the frame's metadata holds a lambda: it stays in this process
    view.event("a note")
    view.log_summary("done")


def test_the_view_process_writes_what_the_logger_writes_in_the_session(tmp_path):
    here, there = tmp_path / "here.rrd", tmp_path / "there.rrd"
    logger = RerunLogger("save", str(here), image_max_side=64)
    _log(logger, 8)
    logger.close()
    view = ViewProcess("save", str(there), image_max_side=64)
    _log(view, 8)
    view.flush()
    assert view.frames_logged == 8 and view.log_seconds > 0 and view.file_error is None
    view.close()
    assert _entities(there) == _entities(here)
    for entity in ("/p0", "/quality", "/perf/latency", "/perf/drops", "/error"):
        np.testing.assert_allclose(_scalars(there, entity), _scalars(here, entity), rtol=0, atol=0, err_msg=entity)
    assert f"/{entities.CAMERA_IMAGE} " in _store_summary(there)


@pytest.mark.time_limit(120)
def test_a_stopped_view_never_holds_the_session_back_and_draws_every_frame_once_it_goes_on(tmp_path):
    path = tmp_path / "stopped.rrd"
    view = ViewProcess("save", str(path), image_max_side=64, thin_when_behind=True)
    view.start(**START)
    os.kill(view._process.pid, signal.SIGSTOP)
    try:
        for i in range(40):
            view(_result(i), SessionStats())   # returns at once: nothing here waits for the child
        assert view.backlog == 40                  # no frame drawn while it was stopped
        # the camera image is what a view behind leaves out, at most IMAGE_SKIP_MAX frames in a row
        shown = 40 - view.images.images_left_out
        assert view.images.images_left_out > 0 and shown >= (40 - BEHIND - 1) // (IMAGE_SKIP_MAX + 1)
    finally:
        os.kill(view._process.pid, signal.SIGCONT)
    view.flush()
    assert view.frames_logged == 40 and view.backlog == 0 and view.frames_left_out == 0
    view.close()
    assert len(_scalars(path, "/p0")) == 40      # every frame's numbers reached the view


def test_a_killed_view_switches_off_with_its_reason(tmp_path):
    view = ViewProcess("save", str(tmp_path / "killed.rrd"), image_max_side=64)
    view.start(**START)
    view(_result(0), SessionStats())
    view._process.kill()
    view._process.wait()
    with pytest.raises(ViewProcessError, match="exit code -9"):
        for i in range(1, 5):                   # the writer may still take one frame before it sees the end
            view(_result(i), SessionStats())
    assert not view.enabled
    view.close()                                # says nothing more, waits for nothing


def test_a_bad_colour_range_is_refused_before_a_process_starts():
    with pytest.raises(ValueError, match="LO below HI"):
        ViewProcess("save", "unused.rrd", color_range=(2.0, -2.0))


@pytest.mark.time_limit(120)
def test_the_rrd_is_complete_when_the_session_process_dies(tmp_path):
    """The session's process ends without closing the view (killed): the child finds its pipe closed, draws
    what it was given and closes the .rrd, footer included."""
    path = tmp_path / "orphan.rrd"
    code = f"""
import os, sys
sys.path.insert(0, {REPO!r}); sys.path.insert(0, {HERE!r})
from tests.stream.view.test_logger_entities import _result
from livedic.stream.view.process import ViewProcess
from livedic.stream.pipeline.frame_result import SessionStats
view = ViewProcess("save", {str(path)!r}, image_max_side=64)
view.start(image_shape=(96, 128), p0_index=0, points=None)
for i in range(20):
    view(_result(i), SessionStats())
print(view._process.pid, flush=True)
view._outgoing.put(None)                    # the writer thread stops after the frames before it ...
view._writer.join()                         # ... are in the pipe (not yet drawn), the pipe left open: then die
os._exit(1)
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=100, cwd=str(tmp_path))
    child = int(run.stdout.split()[0])
    _wait_gone(child)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")         # "RRD file has no footer" would mean a file cut short
        assert len(_scalars(path, "/p0")) == 20


def _wait_gone(pid, timeout_s=60.0):
    """Until the process ``pid`` has ended (it is not our child: poll its /proc entry)."""
    wait_until(lambda: not os.path.exists(f"/proc/{pid}") or _state(pid) == "Z", timeout_s,
               "the view's process ending after the session's died")


def _state(pid):
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "gone"
