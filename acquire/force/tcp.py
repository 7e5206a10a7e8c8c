"""``tcp://HOST:PORT``: force lines from a TCP server, read and stamped by a background thread."""

import socket
import time
from typing import Any

from livedic.acquire.force.source import (DEFAULT_KEEP_S, DEFAULT_MAX_GAP_S, DEFAULT_MAX_SAMPLES, DEFAULT_RETRY_S,
                                          MAX_LINE_BYTES, LoadError, LoadEventKind, _address_and_options, _option)
from livedic.acquire.force.streaming import StreamingLoad, parse_line

__all__ = ["TcpLoad"]


class TcpLoad(StreamingLoad):
    """Force lines read from a TCP server by a background thread (see docs/guide/tensile-test.md).

    ``connected`` says whether a connection is open now, ``running`` whether the thread is alive.
    """

    def __init__(self, host: str, port: int | str, *, clock: str = "arrival", max_gap_s: float = DEFAULT_MAX_GAP_S,
                 retry_s: float = DEFAULT_RETRY_S, keep_s: float = DEFAULT_KEEP_S,
                 max_samples: int = DEFAULT_MAX_SAMPLES, connect_timeout_s: float = 0.5, poll_s: float = 0.05,
                 offset_s: float = 0.0, uri: str | None = None) -> None:
        super().__init__(max_gap_s=max_gap_s, retry_s=retry_s, keep_s=keep_s, max_samples=max_samples,
                         counts=("garbage_lines", "out_of_order", "superseded"), offset_s=offset_s)
        self.host, self.port = host, int(port)
        self.uri = uri or f"tcp://{host}:{port}" + ("?clock=sender" if clock == "sender" else "")
        self.clock = clock
        self.connect_timeout_s = float(connect_timeout_s)
        self.poll_s = float(poll_s)
        self._socket: socket.socket | None = None
        self._garbage_told = False
        self._start_thread()

    @property
    def settings(self) -> dict[str, Any]:
        return {**super().settings, "clock": self.clock}

    def _wake(self) -> None:
        sock = self._socket
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)    # wakes a blocked recv at once
            except OSError:
                pass

    # -- the reader thread --

    def _connect(self) -> tuple[socket.socket | None, str]:
        try:
            sock = socket.create_connection((self.host, self.port), timeout=self.connect_timeout_s)
        except OSError as error:
            return None, f"cannot connect ({error.strerror or error})"
        self._socket = sock
        self._garbage_told = False
        return sock, "connected"

    def _hang_up(self, sock: socket.socket) -> None:
        self._socket = None
        sock.close()

    @property
    def _outage_is_a_gap(self) -> bool:
        return self.clock == "arrival"      # sender times: the gap shows in the samples' own times

    def _read_until_lost(self, sock: socket.socket) -> str:
        """Read until the stream ends, fails or ``close()``; the reason it ended."""
        sock.settimeout(self.poll_s)
        pending = b""
        last_data = time.monotonic()
        stalled = False
        while not self._stop.is_set():
            try:
                chunk = sock.recv(65536)
            except socket.timeout:
                if not stalled and time.monotonic() - last_data > self.max_gap_s:
                    stalled = True
                    self._event(LoadEventKind.STALLED, f"no data for {self.max_gap_s:g} s: force is NaN until it resumes")
                continue
            except OSError as error:
                return f"connection lost ({error.strerror or error})"
            arrival_ns = time.monotonic_ns()
            if not chunk:
                return "the sender closed the connection"
            last_data = arrival_ns / 1e9
            if stalled:
                stalled = False
                self._event(LoadEventKind.RESUMED, "data again")
            lines = (pending + chunk).split(b"\n")
            pending = lines.pop()
            if len(pending) > MAX_LINE_BYTES:
                self._garbage(f"{pending[:30]!r}... (over {MAX_LINE_BYTES} bytes without a newline)")
                pending = b""
            self._take(lines, arrival_ns)
        return "closed"

    def _garbage(self, text: str, n: int = 1) -> None:
        """Count ``n`` garbage lines; the first of a connection is also a ``BAD_DATA`` event."""
        self._count("garbage_lines", n)
        if not self._garbage_told:
            self._garbage_told = True
            self._event(LoadEventKind.BAD_DATA, f"skipped a line that is not force_N or time_s,force_N: {text}; "
                                                f"further ones are counted (warnings.garbage_lines)")

    def _take(self, lines: list[bytes], arrival_ns: int) -> None:
        parsed: list[tuple[float | None, float]] = []
        garbage = 0
        for raw in lines:
            text = raw.decode("utf-8", "replace").strip()
            if not text:
                continue
            sample = parse_line(text)
            if sample is None:
                if not garbage:
                    first_garbage = text
                garbage += 1
            else:
                parsed.append(sample)
        if garbage:
            self._garbage(repr(first_garbage[:40]), garbage)
        with self._lock:
            if not parsed:
                return
            if self.clock == "arrival":
                self._counts["superseded"] += len(parsed) - 1
                arrival_s = arrival_ns / 1e9
                if arrival_s > self._buffer.last_time:
                    self._buffer.append(arrival_s, parsed[-1][1])
                    self._stored()
                return
            for time_s, force_n in parsed:
                if time_s is None or time_s <= self._buffer.last_time:
                    self._counts["out_of_order" if time_s is not None else "garbage_lines"] += 1
                    continue
                self._buffer.append(time_s, force_n)
            self._stored()


def _open_tcp(uri: str, options: dict[str, Any]) -> TcpLoad:
    host, port, merged = _address_and_options(uri, options, "tcp://HOST:PORT (port 1-65535)[?clock=arrival|sender]")
    clock = str(merged.pop("clock", "arrival")).strip().lower()
    if clock not in ("arrival", "sender"):
        raise LoadError(f"load {uri!r}: clock={clock!r}; use clock=arrival (stamp lines on arrival) "
                        f"or clock=sender (time_s is on the monotonic clock already)")
    kwargs: dict[str, Any] = {}
    for name, low in (("max_gap_s", 0.0), ("retry_s", 0.0), ("keep_s", 0.0), ("connect_timeout_s", 0.0),
                      ("poll_s", 0.0)):
        if name in merged:
            kwargs[name] = _option(name, merged.pop(name), low=low, low_open=True)
    if "offset_s" in merged:
        kwargs["offset_s"] = _option("offset_s", merged.pop("offset_s"))
    if "max_samples" in merged:
        kwargs["max_samples"] = int(_option("max_samples", merged.pop("max_samples"), low=4))
    if merged:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(merged))}; tcp takes clock, "
                        f"max_gap_s, retry_s, keep_s, max_samples, offset_s")
    return TcpLoad(host, port, clock=clock, uri=uri, **kwargs)
