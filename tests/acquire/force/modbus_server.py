"""A real pymodbus TCP server in the test process, on 127.0.0.1 and a free port, for the force tests.

``ModbusTestServer`` runs pymodbus's own ``ModbusTcpServer`` in an event loop on a background
thread. Device ``UNIT`` has 200 holding registers and 200 input registers (separate blocks, all 0
but input register 0, which holds ``INPUT_MARK``); any other address or unit is answered with an
exception response, as a PLC answers a wrong address. ``write(address, registers)`` changes
holding registers while it serves, ``write_value(address, value, type)`` through pymodbus's
``convert_to_registers``; ``stop()`` closes the listener and every connection (a PLC switched
off), ``start()`` listens again on the same port with the registers written so far; ``silent =
True`` makes it hold every answer for longer than a client waits (a hung PLC); ``close()`` ends
the loop and its thread.
"""

import asyncio
import threading

from pymodbus.client import ModbusTcpClient
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

UNIT = 1
REGISTERS = 200
INPUT_MARK = 4321
HOLD_ANSWER_S = 2.0          # the answer delay when silent: longer than any client timeout in the tests


class ModbusTestServer:
    """See the module notes. A context manager: ``with ModbusTestServer() as server: server.port``."""

    def __init__(self):
        self.silent = False
        self.polls = 0
        self.held = 0                # polls being held unanswered (silent)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="modbus-test-server", daemon=True)
        self._thread.start()
        self._server = None
        self._written = {}
        self.port = 0
        self.start()

    def _call(self, coroutine, timeout_s=5.0):
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop).result(timeout_s)

    async def _action(self, function_code, start_address, address, count, current_registers, set_values):
        self.polls += set_values is None
        if self.silent and set_values is None:
            self.held += 1
            try:
                await asyncio.sleep(HOLD_ANSWER_S)
            finally:
                self.held -= 1
        return None

    async def _listen(self):
        bits = [SimData(0, count=16, values=False, datatype=DataType.BITS)]
        device = SimDevice(id=UNIT, action=self._action, simdata=(
            bits, list(bits),
            [SimData(0, count=REGISTERS, values=0, datatype=DataType.REGISTERS)],
            [SimData(0, values=INPUT_MARK, datatype=DataType.REGISTERS),
             SimData(1, count=REGISTERS - 1, values=0, datatype=DataType.REGISTERS)]))
        server = ModbusTcpServer(device, address=("127.0.0.1", self.port))
        await server.serve_forever(background=True)
        return server

    def start(self):
        """Listen (again) on ``port`` (a free one the first time)."""
        if self._server is None:
            self._server = self._call(self._listen())
            self.port = self._server.transport.sockets[0].getsockname()[1]
            for address, registers in self._written.items():
                self._set(address, registers)

    def stop(self):
        """Close the listener and every open connection; ``start()`` brings the server back."""
        if self._server is not None:
            server, self._server = self._server, None
            self._call(server.shutdown())

    def write(self, address, registers):
        """Set holding registers from ``address`` (ints 0-65535); kept over ``stop()`` and ``start()``."""
        registers = [int(r) for r in registers]
        self._written[address] = registers
        if self._server is not None:
            self._set(address, registers)

    def _set(self, address, registers):
        self._call(self._server.context.async_setValues(UNIT, 16, address, registers))

    def write_value(self, address, value, value_type="int16", word_order="big"):
        """Set the holding register(s) at ``address`` to ``value`` encoded as ``value_type`` by pymodbus."""
        data_type = ModbusTcpClient.DATATYPE[value_type.upper()]
        self.write(address, ModbusTcpClient.convert_to_registers(value, data_type, word_order=word_order))

    async def _cancel_pending(self):
        """Cancel answers still held (silent) so the loop closes with no task pending."""
        tasks = [task for task in asyncio.all_tasks() if task is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    def close(self):
        self.silent = False
        try:
            self.stop()
        finally:
            self._call(self._cancel_pending())
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(5)
            self._loop.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
