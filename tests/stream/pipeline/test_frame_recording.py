"""frame_recording: camera frames written in a thread of their own, in order, none lost; errors reach the caller."""

import threading

import pytest

from livedic.stream.pipeline.frame_recording import FrameRecording

WAIT_S = 30.0


def test_every_item_is_written_in_order_off_the_calling_thread():
    written, threads = [], set()

    def write(item):
        threads.add(threading.get_ident())
        written.append(item)

    recording = FrameRecording(write)
    for item in range(500):
        recording(item)
    recording.close()
    assert written == list(range(500))
    assert threads and threading.get_ident() not in threads


def test_a_slow_writer_never_holds_the_caller_back_until_the_backlog_is_full():
    """The writer blocks on an event: the caller hands over max_waiting items without waiting, the next one waits
    (counted) until the writer moves; nothing is dropped."""
    release = threading.Event()
    started = threading.Event()
    written = []

    def write(item):
        started.set()
        assert release.wait(WAIT_S)
        written.append(item)

    recording = FrameRecording(write, max_waiting=3)
    recording(0)
    assert started.wait(WAIT_S)             # item 0 is being written (blocked); 1-3 wait
    for item in (1, 2, 3):
        recording(item)
    assert recording.waits == 0 and recording.max_backlog == 3
    later = threading.Thread(target=recording, args=(4,))
    later.start()                           # no room: this hand-over waits for the writer
    release.set()
    later.join(WAIT_S)
    recording.close()
    assert written == [0, 1, 2, 3, 4] and recording.waits == 1


def test_a_write_error_is_raised_in_the_caller_at_the_next_hand_over_or_at_close():
    def write(item):
        if item == 1:
            raise OSError("disk gone")

    recording = FrameRecording(write)
    recording(0)
    recording(1)
    with pytest.raises(OSError, match="disk gone"):
        for item in range(2, 10_000):       # raised at a hand-over once the writer has met it
            recording(item)
    recording.close()                        # told once

    failing = FrameRecording(write)
    failing(1)
    with pytest.raises(OSError, match="disk gone"):
        failing.close()
