"""cores: the tracking thread on a CPU of its own, the other threads (and a child process) on the rest, and back."""

import os
import subprocess
import sys
import threading

import pytest

from livedic.stream.pipeline.cores import CoreSplit, core_split

linux_smp = pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                               reason="needs Linux's sched_setaffinity and two CPUs")


def test_no_split_with_more_numba_threads_or_one_cpu(monkeypatch):
    assert core_split(2) is None
    if hasattr(os, "sched_getaffinity"):
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {3})
        assert core_split(1) is None


def test_describe_names_the_cpus_in_runs():
    split = CoreSplit(tracking=frozenset({7}), others=frozenset({0, 1, 2, 5}), every=frozenset(range(8)))
    assert split.describe() == ("tracking thread on CPU 7, the session's other threads and the view on CPU 0-2,5")


@linux_smp
def test_pin_places_every_thread_and_a_child_then_release_gives_them_back():
    every = frozenset(os.sched_getaffinity(0))
    release_worker = threading.Event()
    worker = threading.Thread(target=release_worker.wait)
    worker.start()
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"], stdin=subprocess.PIPE)
    try:
        split = core_split(1, [child.pid])
        assert split.tracking == {max(every)} and split.others == every - {max(every)}
        split.pin()
        assert os.sched_getaffinity(0) == split.tracking                        # the calling (tracking) thread
        assert os.sched_getaffinity(worker.native_id) == split.others
        assert os.sched_getaffinity(child.pid) == split.others
        split.release()
        assert os.sched_getaffinity(0) == every
        assert os.sched_getaffinity(worker.native_id) == every
        assert os.sched_getaffinity(child.pid) == every
    finally:
        release_worker.set()
        worker.join()
        child.communicate(b"")


@linux_smp
def test_a_thread_that_ended_or_a_child_gone_is_skipped():
    every = frozenset(os.sched_getaffinity(0))
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    split = core_split(1, [child.pid])
    split.pin()                      # the child's tasks are gone: nothing to place, no error
    try:
        assert os.sched_getaffinity(0) == split.tracking
    finally:
        split.release()
    assert os.sched_getaffinity(0) == every
