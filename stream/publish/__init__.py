"""Strain out: each tracked frame's extensometer strain sent to a machine controller (``--publish URI``).

``stage`` holds it all for now (UDP and Modbus outlets, the register map, ``PublishStage``); this package
re-exports its public names, so ``from livedic.stream.publish import ...`` keeps working.
"""

from livedic.stream.publish.stage import (
    DEFAULT_HOST, DEFAULT_LINGER_S, EXTENSOMETER_MAP, EXTENSOMETER_REGISTERS, HEADER_REGISTERS, MAX_AGE_MS,
    MAX_LINGER_S, REGISTER_MAP, SCHEMES, STATE_ENDED, STATE_RUNNING, STATE_WAITING, FrameValues, ModbusOutlet,
    PublishStage, PublishTarget, UdpOutlet, decode_registers, encode_registers, format_publish_summary,
    frame_values, open_outlet, open_publishers, parse_publish_uri, parse_publish_uris, preload, register_count)

__all__ = ["SCHEMES", "DEFAULT_HOST", "DEFAULT_LINGER_S", "MAX_LINGER_S", "HEADER_REGISTERS", "EXTENSOMETER_REGISTERS",
           "MAX_AGE_MS", "REGISTER_MAP", "EXTENSOMETER_MAP", "STATE_WAITING", "STATE_RUNNING", "STATE_ENDED",
           "register_count", "encode_registers", "decode_registers", "PublishTarget", "parse_publish_uri",
           "parse_publish_uris", "FrameValues", "frame_values", "UdpOutlet", "ModbusOutlet", "preload",
           "open_outlet", "PublishStage", "open_publishers", "format_publish_summary"]
