"""Which CPUs the tracking thread runs on: a core of its own while it tracks (issue 20 item 4).

On a Linux machine of two CPUs or more, ``CoreSplit.pin`` (called by the tracking thread once every other
thread of the session has started) keeps the tracking thread on the last CPU it may use and moves every
other thread of this process (acquisition, outputs, recorder, view writer, the Rerun and strain-out threads)
and of the view's process to the others; ``release`` gives everything its CPUs back. The tracking thread
then never waits for the scheduler to take a CPU back from the session's own outputs, and its caches stay
its own (the acquisition's prefilter streams ~2 MB a frame). Where a thread may not be moved (another
user's, ended, no ``sched_setaffinity``), it is left where it is: the split is a placement, never a
condition of the session. With ``--threads N > 1`` numba's worker threads, shared by the tracking and the
acquisition threads, would be split from the kernels they serve: no split then.
Measured and explained in docs/guide/performance.md ("The live pipeline: threads, and who waits for whom").
"""

from __future__ import annotations

import os
import sys
import threading
from dataclasses import dataclass, field

# The outputs' niceness (Linux, per thread; the view's whole process): when the cores are busy the scheduler gives
# the tracking and acquisition threads (and numba's workers) the CPU first; the outputs catch up in the gaps. The
# output thread, the frame recorder, the view writer and the view's process run at it.
OUTPUT_NICE = 10


def lower_priority(nice: int) -> None:
    """Raise the calling thread's niceness by ``nice`` where the system allows it per thread (Linux); else nothing."""
    if not sys.platform.startswith("linux"):
        return
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + nice)
    except OSError:
        pass


def _tasks(pid: int | str) -> list[int]:
    """The thread ids of process ``pid`` ("self": this one); [] when it has ended or /proc is not there."""
    try:
        return [int(name) for name in os.listdir(f"/proc/{pid}/task")]
    except OSError:
        return []


def _place(tid: int, cpus: frozenset[int]) -> bool:
    """Thread ``tid`` on ``cpus``; False where it cannot be moved (ended, not ours)."""
    try:
        os.sched_setaffinity(tid, cpus)
    except OSError:
        return False
    return True


@dataclass
class CoreSplit:
    """The tracking thread on ``tracking``, the session's other threads and ``child_pids``' on ``others``.

    ``every``: the CPUs the process had, given back by ``release``. ``moved``: the threads ``pin`` moved.
    """

    tracking: frozenset[int]
    others: frozenset[int]
    every: frozenset[int]
    child_pids: list[int] = field(default_factory=list)
    moved: list[int] = field(default_factory=list)

    def describe(self) -> str:
        """One line for the summary: which CPUs tracked and which served the rest."""
        return (f"tracking thread on CPU {_cpus(self.tracking)}, the session's other threads and the view on "
                f"CPU {_cpus(self.others)}")

    def pin(self) -> None:
        """Called by the tracking thread: it moves to ``tracking``, every other thread to ``others``."""
        me = threading.get_native_id()
        for tid in _tasks("self"):
            if tid != me and _place(tid, self.others):
                self.moved.append(tid)
        for pid in self.child_pids:
            self.moved.extend(tid for tid in _tasks(pid) if _place(tid, self.others))
        if _place(me, self.tracking):
            self.moved.append(me)

    def release(self) -> None:
        """Every thread ``pin`` moved back on ``every`` (those still there)."""
        for tid in self.moved:
            _place(tid, self.every)
        self.moved = []


def core_split(threads: int, child_pids: list[int] | None = None) -> CoreSplit | None:
    """A ``CoreSplit`` for a session of ``threads`` numba threads, or None where there is nothing to split.

    None without ``os.sched_setaffinity`` (not Linux), with fewer than two CPUs allowed, or with
    ``threads > 1`` (module notes). The tracking thread gets the highest-numbered CPU allowed.
    """
    if threads != 1 or not hasattr(os, "sched_getaffinity"):
        return None
    every = frozenset(os.sched_getaffinity(0))
    if len(every) < 2:
        return None
    tracking = frozenset({max(every)})
    return CoreSplit(tracking=tracking, others=every - tracking, every=every, child_pids=list(child_pids or []))


def _cpus(cpus: frozenset[int]) -> str:
    """``{0, 1, 2, 5}`` as "0-2,5"."""
    ordered = sorted(cpus)
    runs: list[list[int]] = []
    for cpu in ordered:
        if runs and cpu == runs[-1][-1] + 1:
            runs[-1].append(cpu)
        else:
            runs.append([cpu])
    return ",".join(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]) for run in runs)
