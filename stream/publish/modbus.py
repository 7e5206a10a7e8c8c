"""Strain out over Modbus TCP: the holding-register map (``REGISTER_MAP``, ``EXTENSOMETER_MAP``), its encoding,
and ``ModbusOutlet``, the pymodbus server that serves each frame's values whole.
"""

from __future__ import annotations

import asyncio
import errno
import math
import socket
import struct
import threading
import time
from collections.abc import Sequence
from typing import Any

from livedic.stream.publish.uri import PublishTarget
from livedic.stream.publish.values import FrameValues

# Holding registers (0-based addresses, as a request gives them; a PLC's "4xxxx" numbering is address + 40001).
# 32-bit values take two registers, high word first (big-endian words of big-endian bytes: "ABCD").
HEADER_REGISTERS = 16
EXTENSOMETER_REGISTERS = 6       # per extensometer, from HEADER_REGISTERS + k * EXTENSOMETER_REGISTERS
MAX_AGE_MS = 65535
STATE_WAITING, STATE_RUNNING, STATE_ENDED = 0, 1, 2

REGISTER_MAP = (
    # (address, registers, type, name, meaning)
    (0, 2, "uint32", "update_count", "frames published so far: +1 per tracked frame (0 before the first)"),
    (2, 2, "uint32", "frame", "the frame's index"),
    (4, 2, "float32", "time_s", "seconds since the session's first frame"),
    (6, 1, "uint16", "ok", "1 when every extensometer has a valid reading in this frame, else 0"),
    (7, 1, "uint16", "state", "0 waiting for the first frame, 1 running, 2 session ended (values final)"),
    (8, 1, "uint16", "age_ms", "milliseconds since these values were written, when read (65535 at most)"),
    (9, 1, "uint16", "extensometers", "N, the number of extensometer blocks that follow"),
    (10, 6, "-", "reserved", "0"),
)
EXTENSOMETER_MAP = (
    # (offset in the block, registers, type, name, meaning)
    (0, 2, "float32", "eng_strain", "engineering strain (L - L0) / L0; NaN when not valid"),
    (2, 2, "float32", "true_strain", "true strain ln(L / L0); NaN when not valid"),
    (4, 1, "uint16", "valid", "1 when this extensometer has a valid reading in this frame"),
    (5, 1, "-", "reserved", "0"),
)
_AGE_ADDRESS = 8


def register_count(n_extensometers: int) -> int:
    """Holding registers the map takes for ``n_extensometers``."""
    return HEADER_REGISTERS + EXTENSOMETER_REGISTERS * n_extensometers


def _words(fmt: str, value: float) -> list[int]:
    """``value`` packed big-endian as ``fmt`` ("I" or "f"), as 16-bit registers, high word first."""
    raw = struct.pack(">" + fmt, value)
    return [int.from_bytes(raw[i:i + 2], "big") for i in range(0, len(raw), 2)]


def _float32(value: float | None) -> list[int]:
    """``value`` as float32 registers; NaN stays NaN (a legitimate float32 a PLC can test)."""
    value = float(value) if value is not None else math.nan
    return _words("f", value if math.isfinite(value) else math.nan)


def encode_registers(values: FrameValues, *, update_count: int, state: int = STATE_RUNNING) -> list[int]:
    """One frame's ``FrameValues`` as the holding registers of ``REGISTER_MAP`` (``age_ms`` 0).

    Parameters
    ----------
    values : FrameValues
    update_count : int
        Frames published so far, this one included.
    state : int
        ``STATE_RUNNING`` or ``STATE_ENDED``.

    Returns
    -------
    list of int
        ``register_count(len(values.names))`` values, 0..65535 each.
    """
    registers = (_words("I", update_count & 0xFFFFFFFF) + _words("I", values.frame & 0xFFFFFFFF)
                 + _float32(values.time_s) + [int(values.ok), state, 0, len(values.names)] + [0] * 6)
    for eng, true, valid in zip(values.eng_strain, values.true_strain, values.valid):
        registers += _float32(eng if valid else math.nan) + _float32(true if valid else math.nan) + [int(valid), 0]
    return registers


def decode_registers(registers: Sequence[int]) -> dict[str, Any]:
    """The values a client reads back from ``registers`` (a whole map, address 0 first), as a dict.

    The inverse of ``encode_registers`` as the register map of docs/guide/strain-out.md states it: what a controller
    does with the registers (the tests check the map through it and through pymodbus's own
    decoding).
    """
    def u32(at: int) -> int:
        return (registers[at] << 16) | registers[at + 1]

    def f32(at: int) -> float:
        return struct.unpack(">f", struct.pack(">HH", registers[at], registers[at + 1]))[0]

    n = registers[9]
    blocks = [HEADER_REGISTERS + EXTENSOMETER_REGISTERS * k for k in range(n)]
    return {"update_count": u32(0), "frame": u32(2), "time_s": f32(4), "ok": bool(registers[6]),
            "state": registers[7], "age_ms": registers[_AGE_ADDRESS], "extensometers": n,
            "eng_strain": [f32(at) for at in blocks], "true_strain": [f32(at + 2) for at in blocks],
            "valid": [bool(registers[at + 4]) for at in blocks]}


class ModbusOutlet:
    """A Modbus TCP server (pymodbus) in a background thread serving ``REGISTER_MAP``.

    Attributes
    ----------
    port : int
        The port it listens on (the one asked for, or the one the system chose for port 0).
    where : str
        ``modbus://HOST:PORT`` as it listens.

    Raises
    ------
    ValueError
        The address cannot be listened on (in use, not allowed, not this machine's), when opened.
    """

    def __init__(self, target: PublishTarget, names: Sequence[str]) -> None:
        self.target = target
        self.names = tuple(names)
        self.count = register_count(len(self.names))
        empty = FrameValues(frame=0, time_s=0.0, names=self.names, eng_strain=(math.nan,) * len(self.names),
                            true_strain=(math.nan,) * len(self.names), valid=(False,) * len(self.names))
        # (registers, monotonic ns written): replaced whole by the tracker thread, read once per request.
        self._snapshot = (tuple(encode_registers(empty, update_count=0, state=STATE_WAITING)), time.monotonic_ns())
        self._last: tuple[FrameValues, int] | None = None
        self._ended_ns: int | None = None           # monotonic ns when the session ended (finish)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Any = None              # pymodbus's ModbusTcpServer once it listens
        self._error: str | None = None
        self.port: int = target.port          # the system's choice for port 0, once listening
        self._ready = threading.Event()
        _check_listen(target)
        self._thread = threading.Thread(target=self._serve_thread, name=f"livedic publish {target.describe()}",
                                        daemon=True)
        self._thread.start()
        self._ready.wait(timeout=10.0)
        if self._error is not None or self._server is None:
            self.close()
            raise ValueError(f"--publish {target.uri}: cannot serve Modbus on {target.describe()}: "
                             f"{self._error or 'the server did not start within 10 s'}")
        self.where: str = f"modbus://{_bracketed(target.host)}:{self.port}"

    def note(self) -> str:
        """What the session says at the start: where it listens, where each extensometer's block is."""
        blocks = ", ".join(f"{name} at {HEADER_REGISTERS + EXTENSOMETER_REGISTERS * k}"
                           for k, name in enumerate(self.names))
        return (f"publishing strain on {self.where} (Modbus TCP, holding registers 0..{self.count - 1}: header at 0, "
                f"extensometers {blocks})")

    def send(self, values: FrameValues, update_count: int) -> None:
        """Make ``values`` the registers' content (the next read gets all of them)."""
        self._last = (values, update_count)
        self._snapshot = (tuple(encode_registers(values, update_count=update_count)), time.monotonic_ns())

    def finish(self) -> None:
        """The session ended: the last frame's values stay, with state 2 (ended), ``linger_s`` more seconds."""
        self._ended_ns = time.monotonic_ns()
        if self._last is None:
            registers = list(self._snapshot[0])
            registers[7] = STATE_ENDED
            self._snapshot = (tuple(registers), self._snapshot[1])
            return
        values, update_count = self._last
        self._snapshot = (tuple(encode_registers(values, update_count=update_count, state=STATE_ENDED)),
                          self._snapshot[1])

    async def _fill(self, function_code: int, start_address: int, address: int, count: int,
                    current_registers: list[int], set_values: list[int] | list[bool] | None) -> None:
        """pymodbus's action before every request: the registers become the latest snapshot, whole."""
        registers, written_ns = self._snapshot
        offset = -start_address
        current_registers[offset:offset + len(registers)] = registers
        age = (time.monotonic_ns() - written_ns) // 1_000_000
        current_registers[offset + _AGE_ADDRESS] = min(MAX_AGE_MS, max(0, age))
        return None

    def _serve_thread(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        finally:
            loop.close()

    async def _serve(self) -> None:
        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice
        try:
            device = SimDevice(id=0, simdata=[SimData(address=0, count=self.count, values=0,
                                                      datatype=DataType.REGISTERS, readonly=True)],
                               action=self._fill)
            server = ModbusTcpServer(device, address=(self.target.host, self.target.port))
            if not await server.listen():
                raise OSError(f"cannot listen on {self.target.describe()}")
            # pymodbus types transport as asyncio's BaseTransport; listening, it is the asyncio.Server
            self.port = server.transport.sockets[0].getsockname()[1]  # type: ignore[attr-defined]
        except Exception as error:  # noqa: BLE001 - handed to the opening thread as its one line
            self._error = f"{type(error).__name__}: {error}" if not isinstance(error, OSError) else str(error)
            self._ready.set()
            return
        self._server = server
        self._ready.set()
        await server.serving

    def linger_left_s(self) -> float:
        """Seconds the server still answers before ``close`` stops it: what is left of ``linger_s``
        since ``finish`` (0 when the session did not end: ``close`` after a failure stops at once)."""
        if self._ended_ns is None:
            return 0.0
        return max(0.0, self.target.linger_s - (time.monotonic_ns() - self._ended_ns) / 1e9)

    def close(self) -> None:
        """Stop the server (its port is free afterwards) and its thread, after what is left of the linger."""
        try:
            if self._server is not None:
                time.sleep(self.linger_left_s())
        finally:
            self._shutdown()

    def _shutdown(self) -> None:
        server, loop = self._server, self._loop
        self._server = None
        if server is not None and loop is not None and loop.is_running():
            future = asyncio.run_coroutine_threadsafe(server.shutdown(), loop)
            try:
                future.result(timeout=5.0)
            except Exception:  # noqa: BLE001 - closing: the thread is a daemon and goes with the process
                pass
        self._thread.join(timeout=5.0)


def _bracketed(host: str) -> str:
    return f"[{host}]" if ":" in host else host


def _check_listen(target: PublishTarget) -> None:
    """ValueError (one line) when ``target``'s address cannot be listened on: in use, not allowed, not here.

    A probe bound as pymodbus binds (SO_REUSEADDR) and released: the server's own failure
    is only logged, this says why.
    """
    try:
        infos = socket.getaddrinfo(target.host, target.port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as error:
        raise ValueError(f"--publish {target.uri}: cannot resolve host {target.host!r} ({error.strerror})") from None
    family, kind, proto, _, address = infos[0]
    probe = socket.socket(family, kind, proto)
    try:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(address)
        probe.listen(1)
    except OSError as error:
        why = error.strerror or str(error)
        hint = "; choose another port" if error.errno == errno.EADDRINUSE else ""
        raise ValueError(f"--publish {target.uri}: cannot listen on {_bracketed(target.host)}:{target.port}: "
                         f"{why}{hint}") from None
    finally:
        probe.close()
