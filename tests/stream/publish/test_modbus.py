"""Tests of stream/publish/modbus.py: the register map's encoding, and the Modbus TCP server serving it whole."""

import math
import socket
import struct

import numpy as np
import pytest

from livedic.stream.publish.modbus import (EXTENSOMETER_MAP, EXTENSOMETER_REGISTERS, HEADER_REGISTERS, REGISTER_MAP,
                                           STATE_ENDED, STATE_RUNNING, STATE_WAITING, ModbusOutlet, decode_registers,
                                           encode_registers, register_count)
from livedic.stream.publish.uri import parse_publish_uri
from tests.stream.publish.conftest import assert_port_free
from tests.stream.publish.test_values import _values


def test_register_map_round_trip_as_the_readme_states_it():
    registers = encode_registers(_values(), update_count=70_000)
    assert len(registers) == register_count(2) == HEADER_REGISTERS + 2 * EXTENSOMETER_REGISTERS == 28
    assert all(0 <= r <= 0xFFFF for r in registers)
    back = decode_registers(registers)
    assert back["update_count"] == 70_000 and registers[0:2] == [1, 70_000 - 65_536]    # high word first
    assert back["frame"] == 41 and back["ok"] is False and back["state"] == 1 and back["extensometers"] == 2
    assert back["time_s"] == np.float32(0.82) and registers[10:16] == [0] * 6           # reserved
    assert back["eng_strain"][0] == np.float32(0.00123) and math.isnan(back["eng_strain"][1])
    assert back["valid"] == [True, False]
    # Big-endian bytes in big-endian words: the float's 4 bytes in order across two registers.
    assert struct.pack(">HH", *registers[16:18]) == struct.pack(">f", 0.00123)


def test_the_map_tables_tile_their_blocks_without_gaps():
    for table, size in ((REGISTER_MAP, HEADER_REGISTERS), (EXTENSOMETER_MAP, EXTENSOMETER_REGISTERS)):
        address = 0
        for start, count, kind, _, _ in table:
            assert start == address and count == {"uint32": 2, "float32": 2, "uint16": 1}.get(kind, count)
            address += count
        assert address == size


def test_the_ended_state_and_large_counts_round_trip():
    values = _values(valid=(False, True))
    back = decode_registers(encode_registers(values, update_count=2**32 + 5, state=STATE_ENDED))
    assert back["state"] == STATE_ENDED and back["update_count"] == 5              # wraps at 32 bits
    assert back["valid"] == [False, True] and back["ok"] is False
    assert math.isnan(back["eng_strain"][0]) and math.isnan(back["true_strain"][0])   # not valid: NaN, not 0.00123


def _read(port, count):
    from pymodbus.client import ModbusTcpClient
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=5)
    assert client.connect()
    try:
        response = client.read_holding_registers(0, count=count)
        assert not response.isError(), response
        return decode_registers(response.registers)
    finally:
        client.close()


@pytest.fixture
def outlet():
    outlet = ModbusOutlet(parse_publish_uri("modbus://127.0.0.1:0?linger_s=0"), ("axial", "transverse"))
    yield outlet
    outlet.close()


def test_the_server_answers_waiting_then_each_frame_then_ended(outlet):
    count = register_count(2)
    assert outlet.port > 0 and outlet.where == f"modbus://127.0.0.1:{outlet.port}"
    assert "holding registers 0..27" in outlet.note() and "axial at 16, transverse at 22" in outlet.note()
    before = _read(outlet.port, count)
    assert before["state"] == STATE_WAITING and before["update_count"] == 0 and before["valid"] == [False, False]
    outlet.send(_values(), update_count=3)
    running = _read(outlet.port, count)
    assert running["state"] == STATE_RUNNING and running["update_count"] == 3 and running["frame"] == 41
    assert running["eng_strain"][0] == np.float32(0.00123) and 0 <= running["age_ms"] <= 65535
    outlet.finish()
    ended = _read(outlet.port, count)
    assert ended["state"] == STATE_ENDED and ended["update_count"] == 3 and ended["frame"] == 41
    assert ended["eng_strain"][0] == np.float32(0.00123)                 # the last values stay


def test_a_session_that_ended_before_any_frame_says_ended_and_closing_frees_the_port():
    outlet = ModbusOutlet(parse_publish_uri("modbus://127.0.0.1:0?linger_s=0"), ("axial",))
    port = outlet.port
    try:
        outlet.finish()
        assert outlet.linger_left_s() == 0.0
        read = _read(port, register_count(1))
        assert read["state"] == STATE_ENDED and read["update_count"] == 0
    finally:
        outlet.close()
    assert_port_free(port)


def test_the_linger_left_is_zero_until_the_end_then_counts_down(monkeypatch):
    from livedic.stream.publish import modbus
    outlet = ModbusOutlet(parse_publish_uri("modbus://127.0.0.1:0?linger_s=5"), ("axial",))
    now = [10**12]
    try:
        assert outlet.linger_left_s() == 0.0              # not finished: a failure closes at once
        monkeypatch.setattr(modbus.time, "monotonic_ns", lambda: now[0])
        outlet.finish()
        assert outlet.linger_left_s() == 5.0
        now[0] += 2 * 10**9
        assert outlet.linger_left_s() == pytest.approx(3.0)
        now[0] += 10 * 10**9                              # the linger has passed: close stops at once
        assert outlet.linger_left_s() == 0.0
    finally:
        monkeypatch.undo()
        outlet.close()


def test_a_port_in_use_is_one_line_naming_the_uri():
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    port = busy.getsockname()[1]
    try:
        with pytest.raises(ValueError) as error:
            ModbusOutlet(parse_publish_uri(f"modbus://127.0.0.1:{port}"), ("axial",))
    finally:
        busy.close()
    message = str(error.value)
    assert message.startswith(f"--publish modbus://127.0.0.1:{port}: cannot listen on 127.0.0.1:{port}")
    assert message.endswith("choose another port") and "\n" not in message
