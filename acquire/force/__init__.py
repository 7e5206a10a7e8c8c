"""Force sources: the testing machine's force signal (CSV, simulator, TCP, Modbus), read onto frame times."""

from livedic.acquire.force.csv_file import CsvLoad, csv_max_gap_s, read_force_csv
from livedic.acquire.force.modbus import ModbusLoad, decode_registers, modbus_register_count
from livedic.acquire.force.open import LOAD_USAGE, open_load
from livedic.acquire.force.simulated import SyntheticLoad
from livedic.acquire.force.source import (TIME_BASE_MONOTONIC, TIME_BASE_SESSION, LoadError, LoadEvent, LoadEventKind,
                                          LoadSource, LoadWarnings, interpolate_force)
from livedic.acquire.force.streaming import StreamingLoad, parse_line
from livedic.acquire.force.tcp import TcpLoad

__all__ = ["LoadError", "LoadEventKind", "LoadEvent", "LoadWarnings", "LoadSource", "CsvLoad", "StreamingLoad",
           "TcpLoad", "ModbusLoad", "SyntheticLoad",
           "open_load", "interpolate_force", "read_force_csv", "csv_max_gap_s", "parse_line", "decode_registers",
           "modbus_register_count", "TIME_BASE_SESSION", "TIME_BASE_MONOTONIC", "LOAD_USAGE"]
