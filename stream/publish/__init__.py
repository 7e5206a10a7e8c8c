"""Strain out: each tracked frame's extensometer strain sent to a machine controller (``--publish URI``).

``uri`` parses the targets, ``values`` makes one frame's values, ``udp`` and ``modbus`` send them (``modbus`` also
holds the register map), and ``stage`` is the session sink (``PublishStage``; its notes describe the feature). This
package re-exports their public names, so ``from livedic.stream.publish import ...`` keeps working.
"""

from livedic.stream.publish.modbus import (EXTENSOMETER_MAP, EXTENSOMETER_REGISTERS, HEADER_REGISTERS, MAX_AGE_MS,
                                           REGISTER_MAP, STATE_ENDED, STATE_RUNNING, STATE_WAITING, ModbusOutlet,
                                           decode_registers, encode_registers, register_count)
from livedic.stream.publish.stage import PublishStage, format_publish_summary, open_outlet, open_publishers, preload
from livedic.stream.publish.udp import UdpOutlet
from livedic.stream.publish.uri import (DEFAULT_HOST, DEFAULT_LINGER_S, MAX_LINGER_S, SCHEMES, PublishTarget,
                                        parse_publish_uri, parse_publish_uris)
from livedic.stream.publish.values import FrameValues, frame_values

__all__ = ["SCHEMES", "DEFAULT_HOST", "DEFAULT_LINGER_S", "MAX_LINGER_S", "HEADER_REGISTERS", "EXTENSOMETER_REGISTERS",
           "MAX_AGE_MS", "REGISTER_MAP", "EXTENSOMETER_MAP", "STATE_WAITING", "STATE_RUNNING", "STATE_ENDED",
           "register_count", "encode_registers", "decode_registers", "PublishTarget", "parse_publish_uri",
           "parse_publish_uris", "FrameValues", "frame_values", "UdpOutlet", "ModbusOutlet", "preload",
           "open_outlet", "PublishStage", "open_publishers", "format_publish_summary"]
