"""Strain out over UDP: one JSON datagram per tracked frame, from a socket that never blocks the tracker."""

from __future__ import annotations

import socket
from typing import Any

from livedic.stream.publish.uri import PublishTarget
from livedic.stream.publish.values import FrameValues


class UdpOutlet:
    """Sends each frame's JSON datagram to ``target`` (non-blocking socket, never connected).

    Raises
    ------
    ValueError
        The host does not resolve (one line), when opened.
    """

    def __init__(self, target: PublishTarget) -> None:
        self.target = target
        try:
            infos = socket.getaddrinfo(target.host, target.port, type=socket.SOCK_DGRAM)
        except socket.gaierror as error:
            raise ValueError(f"--publish {target.uri}: cannot resolve host {target.host!r} ({error.strerror})") \
                from None
        # A name goes to its first IPv4 address when it has one: "localhost" is ::1 first on many systems,
        # and a controller on this machine most often listens on 127.0.0.1 or 0.0.0.0.
        infos.sort(key=lambda info: info[0] != socket.AF_INET)
        family, kind, proto, _, address = infos[0]
        self.address: Any = address      # (host, port), or IPv6's (host, port, flow, scope)
        self.socket = socket.socket(family, kind, proto)
        # Never wait in the tracker thread: a datagram the system cannot take now is counted as not sent.
        self.socket.setblocking(False)
        self.where = target.describe()

    def note(self) -> str:
        """What the session says at the start."""
        return f"publishing strain to {self.where} (one UDP JSON datagram per tracked frame)"

    def send(self, values: FrameValues, update_count: int) -> None:
        """Send one frame; OSError when the system refuses it."""
        self.socket.sendto(values.as_json(), self.address)

    def finish(self) -> None:
        """The session ended: nothing to say over UDP (the datagrams stop)."""

    def close(self) -> None:
        self.socket.close()
