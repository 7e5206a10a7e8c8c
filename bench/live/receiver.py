"""A UDP socket that a thread reads ``--publish`` datagrams from, with each one's arrival time.

``StrainOutReceiver().uri`` is what the session publishes to; ``stop()`` returns (frame, arrival ns, read ns).
"""

import json
import socket
import struct
import sys
import threading
import time

# Linux: SO_TIMESTAMPNS (= SCM_TIMESTAMPNS) stamps each datagram with its arrival (CLOCK_REALTIME, timespec).
_SO_TIMESTAMPNS = 35


class StrainOutReceiver:
    """A UDP socket on 127.0.0.1 that a thread reads the session's ``--publish`` datagrams from.

    Per datagram it keeps the frame, its arrival in the socket (the kernel's timestamp, on the
    monotonic clock; None where the system gives none) and when the thread's read returned.
    """

    def __init__(self):
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.socket.settimeout(0.05)
        self.kernel_stamps = sys.platform.startswith("linux")
        if self.kernel_stamps:
            try:
                self.socket.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            except OSError:
                self.kernel_stamps = False
        self.uri = f"udp://127.0.0.1:{self.socket.getsockname()[1]}"
        self.received = []                  # (datagram, arrival ns or None, read ns), monotonic clock
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name="livedic bench strain-out receiver", daemon=True)
        self._thread.start()

    def _read(self):
        while not self._stop.is_set():
            try:
                data, ancillary, _, _ = self.socket.recvmsg(65536, socket.CMSG_SPACE(16))
            except (socket.timeout, BlockingIOError):
                continue
            read_ns = time.monotonic_ns()
            offset = _wall_minus_monotonic_ns()
            arrival = None
            for level, kind, payload in ancillary:
                if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(payload) >= 16:
                    seconds, nanoseconds = struct.unpack("qq", payload[:16])
                    arrival = seconds * 1_000_000_000 + nanoseconds - offset
            self.received.append((data, arrival, read_ns))

    def stop(self):
        """Stop reading (what arrived is read first); returns [(frame, arrival ns or None, read ns)]."""
        time.sleep(0.1)
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.socket.close()
        return [(json.loads(data)["frame"], arrival, read) for data, arrival, read in self.received]


def _wall_minus_monotonic_ns(tries=5):
    """The wall clock - the monotonic clock, now (ns): the kernel's receive stamp is on the wall clock.

    Read between two monotonic readings, kept from the try where they were closest: a preemption
    between the readings would shift it by the time lost. Read per datagram, so a step of the wall
    clock between datagrams does not matter.
    """
    best = None
    for _ in range(tries):
        before = time.monotonic_ns()
        wall = time.time_ns()
        after = time.monotonic_ns()
        if best is None or after - before < best[0]:
            best = (after - before, wall - (before + after) // 2)
        if after - before < 20_000:
            break
    return best[1]
