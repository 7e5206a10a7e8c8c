"""Tests of stream/export/stop.py: a stop signal noted and raised at the next check, with the folder's state."""

import os
import signal
import threading

import pytest

from livedic.stream.export.stop import ExportStopped, StopSignals, _stopped_in


def test_a_signal_is_noted_and_raised_at_the_next_check_and_the_handlers_are_restored():
    before = signal.getsignal(signal.SIGTERM)
    with StopSignals() as signals:
        signals.check()                                     # nothing received: goes on
        os.kill(os.getpid(), signal.SIGTERM)                # the handler only takes note
        assert signals.received is signal.SIGTERM
        with pytest.raises(ExportStopped) as stopped:
            signals.check()
    assert (stopped.value.signal_name, stopped.value.signum, stopped.value.state) == ("SIGTERM", 15, "")
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_second_signal_gives_up_at_once():
    with StopSignals() as signals:
        signals._handle(signal.SIGINT, None)
        with pytest.raises(KeyboardInterrupt):
            signals._handle(signal.SIGINT, None)
        assert signals.received is signal.SIGINT


def test_outside_the_main_thread_no_handler_is_installed():
    seen = {}

    def run():
        with StopSignals() as signals:
            seen["installed"] = dict(signals._previous)
    worker = threading.Thread(target=run)
    worker.start()
    worker.join()
    assert seen["installed"] == {}


def test_the_innermost_block_says_the_state_and_a_callable_is_asked_when_stopped():
    progress = {"frame": 1}
    with pytest.raises(ExportStopped) as stopped:
        with _stopped_in("outer"):
            with _stopped_in(lambda: f"at frame {progress['frame']}"):
                progress["frame"] = 5
                raise ExportStopped("SIGINT", signal.SIGINT)
    assert stopped.value.state == "at frame 5"
    with pytest.raises(ValueError):                      # other errors pass through untouched
        with _stopped_in("never"):
            raise ValueError("x")
