"""``modbus://HOST:PORT?register=N``: force polled from one Modbus TCP register by a background thread."""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Sequence
from typing import Any, Literal, cast

from livedic.acquire.force.source import (DEFAULT_KEEP_S, DEFAULT_MAX_GAP_S, DEFAULT_MAX_SAMPLES, DEFAULT_RETRY_S,
                                          LoadError, LoadEventKind, _address_and_options, _exception_name, _first_line,
                                          _option)
from livedic.acquire.force.streaming import StreamingLoad

__all__ = ["ModbusLoad", "decode_registers", "modbus_register_count"]

MODBUS_KINDS = ("holding", "input")
MODBUS_TYPES = ("int16", "uint16", "int32", "uint32", "float32")
MODBUS_WORD_ORDERS = ("big", "little")
DEFAULT_MODBUS_RATE_HZ = 100.0
MAX_MODBUS_RATE_HZ = 1000.0
DEFAULT_MODBUS_TIMEOUT_S = 0.25
MODBUS_FORM = ("modbus://HOST:PORT?register=N[&scale=K&kind=holding|input&type=int16|uint16|int32|uint32|float32"
               "&word_order=big|little&unit=ID&rate=HZ]")


def modbus_register_count(value_type: str) -> int:
    """Registers one value of ``value_type`` takes: 1 for 16-bit types, 2 for 32-bit ones."""
    return 2 if value_type in ("int32", "uint32", "float32") else 1


def decode_registers(registers: Sequence[int], value_type: str,
                     word_order: Literal["big", "little"] = "big") -> int | float:
    """The number held in ``registers`` (16-bit words) as ``value_type``, by pymodbus's own conversion.

    Parameters
    ----------
    registers : sequence of int
        One register (16-bit types) or two (32-bit types), as a read returns them.
    value_type : str
        One of ``MODBUS_TYPES``.
    word_order : str
        ``big`` (the first register holds the high word, the Modbus convention) or ``little``.

    Returns
    -------
    int or float (float32 may be NaN or infinite: the caller decides).
    """
    from pymodbus.client import ModbusTcpClient
    value = ModbusTcpClient.convert_from_registers(list(registers), ModbusTcpClient.DATATYPE[value_type.upper()],
                                                   word_order=word_order)
    return cast("int | float", value)        # one number for the numeric types MODBUS_TYPES holds


def _quiet_pymodbus() -> None:
    """pymodbus logs every refused connection and timeout as an error, with a dump of the last frames;
    livedic says each as one event instead. A NullHandler keeps those records from Python's
    last-resort stderr handler while still passing them to handlers an application configured."""
    import logging
    logger = logging.getLogger("pymodbus")
    if not any(isinstance(handler, logging.NullHandler) for handler in logger.handlers):
        logger.addHandler(logging.NullHandler())


class ModbusLoad(StreamingLoad):
    """Force read from one Modbus TCP register, polled at ``rate_hz`` by a background thread.

    Each answered poll is a sample ``force_N = value x scale`` stamped on the monotonic clock (the
    one that stamps frame arrival) halfway between the request and the answer: the server read
    the register inside that interval, so the stamp is off by at most half the round trip. A poll
    that gets no value (an exception response, no answer within ``timeout_s``, a non-finite
    float32) is counted in ``warnings`` and leaves a NaN marker at its time, so no force is
    interpolated across it; the first of a run of failures is a ``READ_FAILED`` event. After a
    timeout the connection is reopened (a late answer must not be taken for the next poll's).
    No answered poll for ``max_gap_s`` is ``STALLED`` (``RESUMED`` when values come back); a
    refused or lost connection is an event, a NaN marker, and a retry every ``retry_s``.

    Parameters
    ----------
    host, port : str, int
    register : int
        Address of the (first) register as sent in the request, 0-65535 (0-based: the register a
        manual calls 40001 or 30001 is 0).
    scale : float
        Newtons per unit of the register's value (non-zero).
    kind : {"holding", "input"}
        Function 3 (read holding registers) or 4 (read input registers).
    value_type : {"int16", "uint16", "int32", "uint32", "float32"}
        32-bit types read two registers.
    word_order : {"big", "little"}
        Which register of a 32-bit value holds the high word (``big``: the first).
    unit : int
        The device (slave, unit) id, 0-255.
    rate_hz : float
        Polls per second (at most ``MAX_MODBUS_RATE_HZ``); a poll that answers late delays the
        next one rather than bursting to catch up.
    max_gap_s : float, optional
        Default: 5 poll periods, 0.5 s at least.
    timeout_s : float
        Connect and answer timeout of one poll.
    """

    def __init__(self, host: str, port: int | str, *, register: int, scale: float = 1.0, kind: str = "holding",
                 value_type: str = "int16", word_order: Literal["big", "little"] = "big", unit: int = 1,
                 rate_hz: float = DEFAULT_MODBUS_RATE_HZ, max_gap_s: float | None = None,
                 retry_s: float = DEFAULT_RETRY_S, timeout_s: float = DEFAULT_MODBUS_TIMEOUT_S,
                 keep_s: float = DEFAULT_KEEP_S, max_samples: int = DEFAULT_MAX_SAMPLES, offset_s: float = 0.0,
                 uri: str | None = None) -> None:
        rate_hz = float(rate_hz)
        if max_gap_s is None:
            max_gap_s = max(DEFAULT_MAX_GAP_S, 5.0 / rate_hz)
        super().__init__(max_gap_s=max_gap_s, retry_s=retry_s, keep_s=keep_s, max_samples=max_samples,
                         counts=("exception_responses", "timeouts", "bad_values"), offset_s=offset_s)
        self.host, self.port = host, int(port)
        self.register, self.scale, self.kind = int(register), float(scale), kind
        self.value_type, self.word_order, self.unit = value_type, word_order, int(unit)
        self.rate_hz, self.timeout_s = rate_hz, float(timeout_s)
        self.uri = uri or f"modbus://{host}:{port}?register={self.register}&scale={self.scale:g}"
        self._count_registers = modbus_register_count(value_type)
        self.nominal_interval_s = 1.0 / rate_hz
        self._client: Any = None                 # the reader thread's ModbusTcpClient while connected
        _quiet_pymodbus()
        self._start_thread()

    @property
    def settings(self) -> dict[str, Any]:
        return {**super().settings, "register": self.register, "scale": self.scale, "kind": self.kind,
                "type": self.value_type, "word_order": self.word_order, "unit": self.unit, "rate_hz": self.rate_hz,
                "timeout_s": self.timeout_s}

    def _wake(self) -> None:
        client = self._client
        sock = getattr(client, "socket", None)
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)    # an answer being waited for returns at once
            except OSError:
                pass

    # -- the reader thread --

    def _where(self) -> str:
        return f"{self.kind} register {self.register} ({self.value_type}) of unit {self.unit}"

    def _connect(self) -> tuple[Any, str]:
        from pymodbus.client import ModbusTcpClient
        client = ModbusTcpClient(self.host, port=self.port, timeout=self.timeout_s, retries=0)
        if not client.connect():
            client.close()
            return None, "cannot connect to the Modbus server"
        self._client = client
        return client, f"connected; polling the {self._where()} at {self.rate_hz:g} Hz"

    def _hang_up(self, client: Any) -> None:
        self._client = None
        client.close()

    def _read_until_lost(self, client: Any) -> str:
        """Poll until the connection is lost or ``close()``; the reason it ended."""
        from pymodbus.exceptions import ConnectionException, ModbusException
        read = client.read_holding_registers if self.kind == "holding" else client.read_input_registers
        period = 1.0 / self.rate_hz
        due = time.monotonic()
        last_value = due                  # a fresh connection has until max_gap_s to answer
        stalled = failing = False
        while not self._stop.is_set():
            sent_ns = time.monotonic_ns()
            try:
                if not client.connected and not client.connect():
                    return "cannot reconnect after a poll without an answer"
                response = read(self.register, count=self._count_registers, device_id=self.unit)
            except ConnectionException as error:
                if self._stop.is_set():
                    break
                return f"connection lost ({_first_line(error)})"
            except ModbusException as error:          # no answer within timeout_s (or a mismatched one)
                response = error
            except (OSError, ValueError) as error:     # why: whatever the wire does, the thread carries on
                return f"connection lost ({type(error).__name__}: {_first_line(error)})"
            answered_ns = time.monotonic_ns()
            stamp_s = (sent_ns + answered_ns) / 2e9
            problem = self._take(response, stamp_s)
            if problem is None:
                last_value = answered_ns / 1e9
                if stalled:
                    stalled = False
                    self._event(LoadEventKind.RESUMED, "values again")
                failing = False
            else:
                self._append(stamp_s, math.nan)
                if not failing:
                    failing = True
                    self._event(LoadEventKind.READ_FAILED, f"{problem}; force is NaN until a poll answers "
                                                           f"(further failures are counted)")
                if isinstance(response, Exception):
                    client.close()       # why: a late answer would be read as the next poll's
            now = time.monotonic()
            if not stalled and now - last_value > self.max_gap_s:
                stalled = True
                self._event(LoadEventKind.STALLED, f"no value for {self.max_gap_s:g} s: force is NaN until it resumes")
            due = max(due + period, now)
            self._stop.wait(due - now)
        return "closed"

    def _take(self, response: Any, stamp_s: float) -> str | None:
        """Store the sample a poll's answer holds; None, or what went wrong (counted)."""
        if isinstance(response, Exception):
            self._count("timeouts")
            return f"no answer from the {self._where()} within {self.timeout_s:g} s"
        if response.isError():
            self._count("exception_responses")
            return (f"the server answered a read of the {self._where()} with exception "
                    f"{_exception_name(response.exception_code)}: check register=, kind=, type= and unit=")
        try:
            value = decode_registers(response.registers, self.value_type, self.word_order)
        except Exception as error:       # why: a device answering the wrong register count must not end the thread
            self._count("bad_values")
            return f"the answer from the {self._where()} does not decode ({_first_line(error)})"
        force_n = float(value) * self.scale
        if not math.isfinite(force_n):
            self._count("bad_values")
            return f"the {self._where()} holds {value!r}, not a finite force"
        self._append(stamp_s, force_n)
        return None


def _open_modbus(uri: str, options: dict[str, Any]) -> ModbusLoad:
    """``modbus://HOST:PORT?register=N&...`` (see ``ModbusLoad`` and docs/guide/tensile-test.md)."""
    host, port, merged = _address_and_options(uri, options, f"{MODBUS_FORM} (port 1-65535)")
    if "register" not in merged:
        raise LoadError(f"load {uri!r}: register= is required (the force register's 0-based address); "
                        f"expected {MODBUS_FORM}")
    kwargs: dict[str, Any] = {"register": int(_option("register", merged.pop("register"), low=0, integer=True))}
    for name, keyword, allowed in (("kind", "kind", MODBUS_KINDS), ("type", "value_type", MODBUS_TYPES),
                                   ("word_order", "word_order", MODBUS_WORD_ORDERS)):
        if name in merged:
            value = str(merged.pop(name)).strip().lower()
            if value not in allowed:
                raise LoadError(f"load {uri!r}: {name}={value!r}; use {name}={'|'.join(allowed)}")
            kwargs[keyword] = value
    last = 65535 - (modbus_register_count(kwargs.get("value_type", "int16")) - 1)
    if kwargs["register"] > last:
        raise LoadError(f"load {uri!r}: register={kwargs['register']}: must be 0-{last} for this type")
    if "scale" in merged:
        kwargs["scale"] = _option("scale", merged.pop("scale"))
        if kwargs["scale"] == 0:
            raise LoadError(f"load {uri!r}: scale=0 would make every force 0 N; give newtons per register unit")
    if "unit" in merged:
        kwargs["unit"] = int(_option("unit", merged.pop("unit"), low=0, integer=True))
        if kwargs["unit"] > 255:
            raise LoadError(f"load {uri!r}: unit={kwargs['unit']}: a Modbus device id is 0-255")
    if "rate" in merged:
        kwargs["rate_hz"] = _option("rate", merged.pop("rate"), low=0.0, low_open=True)
        if kwargs["rate_hz"] > MAX_MODBUS_RATE_HZ:
            raise LoadError(f"load {uri!r}: rate={kwargs['rate_hz']:g}: at most {MAX_MODBUS_RATE_HZ:g} polls per "
                            f"second (one request and answer each)")
    for name in ("max_gap_s", "retry_s", "keep_s", "timeout_s"):
        if name in merged:
            kwargs[name] = _option(name, merged.pop(name), low=0.0, low_open=True)
    if "offset_s" in merged:
        kwargs["offset_s"] = _option("offset_s", merged.pop("offset_s"))
    if "max_samples" in merged:
        kwargs["max_samples"] = int(_option("max_samples", merged.pop("max_samples"), low=4))
    if merged:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(merged))}; modbus takes register, "
                        f"scale, kind, type, word_order, unit, rate, max_gap_s, retry_s, timeout_s, keep_s, "
                        f"max_samples, offset_s")
    return ModbusLoad(host, port, uri=uri, **kwargs)
