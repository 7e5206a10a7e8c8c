"""Strain out: each tracked frame's extensometer strain sent to a machine controller (``--publish URI``).

``livedic run --publish URI`` (repeatable) hands every tracked frame's extensometer readings
out as soon as the frame's result exists:

``udp://HOST:PORT``
    One UDP datagram per tracked frame, a UTF-8 JSON object::

        {"frame": 41, "time_s": 0.82, "strain": {"axial": 0.00123, "transverse": -0.00037},
         "ok": true, "true_strain": {"axial": 0.00122925, "transverse": -0.00037007}}

    ``null`` where an extensometer has no valid reading (NaN is never written); ``ok`` true
    only when every extensometer has one. The socket never blocks the tracker.
``modbus://HOST:PORT``
    A Modbus TCP server (pymodbus) serving the same values as holding registers
    (``REGISTER_MAP``); writes refused; a read of one block is one frame's values, never half
    of two; after the session the last values stay, state 2, for ``linger_s``.

``PublishStage`` is a session stage placed right after the strain stage, before the load
stage, the recording and the view, so the values leave as early as they exist; no force goes
out. A send that fails is a warning event once, counted, and publishing goes on; it never costs
the session or its recording. ``preload`` imports pymodbus before the first frame;
``latency_ms`` keeps, per frame, the time from the tracker's result to the send returning.
The formats, the register map and why: docs/guide/strain-out.md.
"""

import math
import time
from array import array
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np

from livedic.stream.publish.modbus import ModbusOutlet
from livedic.stream.publish.udp import UdpOutlet
from livedic.stream.pipeline.frame_result import FrameResult
from livedic.stream.pipeline.stage import Reference, Stage
from livedic.stream.publish.values import frame_values


def preload(targets: Sequence[Any]) -> None:
    """Import now what opening ``targets`` needs (pymodbus and asyncio for a Modbus server).

    The session calls it before it reads its first frame: the imports take ~0.1-0.2 s, and
    between the first frame and the start a paced source's frames pile up and come late, in a
    burst the queue drops from. ``open_outlet`` afterwards takes a few ms.
    """
    if any(target.scheme == "modbus" for target in targets):
        import asyncio  # noqa: F401
        from pymodbus.server import ModbusTcpServer  # noqa: F401
        from pymodbus.simulator import DataType, SimData, SimDevice  # noqa: F401


def open_outlet(target: Any, names: Sequence[str]) -> UdpOutlet | ModbusOutlet:
    """The outlet for ``target``: ``UdpOutlet`` or ``ModbusOutlet`` (ValueError, one line, when it cannot open)."""
    if target.scheme == "udp":
        return UdpOutlet(target)
    return ModbusOutlet(target, names)


# ----------------------------------------------------------------------------- the session stage

class PublishStage(Stage):
    """Sends every tracked frame's extensometer strain to one outlet (a session stage; see the module notes).

    Parameters
    ----------
    outlet : UdpOutlet or ModbusOutlet
    names : sequence of str
        The session's extensometers, in order (the JSON keys, the register blocks).
    report : callable
        ``report(kind, message, level)``: the session's event.

    Attributes
    ----------
    sent, failed : int
        Frames sent, and frames not sent (the system refused the datagram).
    latencies_ns : array of int
        Per frame sent: the send returning - the tracker's result (``FrameResult.done_ns``),
        monotonic clock; the strain stage before this one is inside it.
    upstream_ns : array of int
        Per frame sent: this stage's start - the tracker's result (the part of the latency spent
        before it: the loop's bookkeeping, on the simulator its error against the truth, the
        strain stage).
    """
    required = False
    stage = "publish"                  # its row in the session's stage times
    # what it sends; it sets nothing (an outlet: the summary gives its line after the measurement's)
    needs: ClassVar[tuple[str, ...]] = ("frame", "done_ns", "extensometers")
    provides: ClassVar[tuple[str, ...]] = ()

    def __init__(self, outlet: Any, names: Sequence[str], report: Callable[[str, str, str], None]) -> None:
        self.outlet = outlet
        self.names = tuple(names)
        self.report = report
        self.name = f"publish {outlet.where}"
        self.first_ns: int | None = None
        self.sent = 0
        self.failed = 0
        self.latencies_ns = array("q")
        self.upstream_ns = array("q")
        self._failing: int | None = None   # the first frame not sent while sends fail

    def on_reference(self, reference: Reference) -> None:
        """``time_s`` counts from the reference frame's timestamp."""
        if reference.timestamp_ns is not None:
            self.first_ns = reference.timestamp_ns

    def on_frame(self, result: FrameResult) -> None:
        """Send the frame's extensometer strain (a refused send is counted, warned about once)."""
        entered = time.monotonic_ns()
        frame = result.frame
        if self.first_ns is None:
            self.first_ns = frame.timestamp_ns
        values = frame_values(result, self.names, (frame.timestamp_ns - self.first_ns) / 1e9)
        try:
            self.outlet.send(values, self.sent + 1)
        except OSError as error:
            self.failed += 1
            if self._failing is None:
                self._failing = frame.index
                self.report("publish", f"{self.outlet.where}: frame {frame.index} not sent ({error}); "
                                       f"trying every frame, failures counted in the summary", "warning")
            return
        self.latencies_ns.append(time.monotonic_ns() - result.done_ns)
        self.upstream_ns.append(entered - result.done_ns)
        self.sent += 1
        if self._failing is not None:
            self.report("publish", f"{self.outlet.where}: sending again from frame {frame.index} "
                                   f"(not sent since frame {self._failing})", "info")
            self._failing = None

    def latency_ms(self, percentile: float, *, part: str = "all") -> float:
        """The strain-out latency's ``percentile`` (ms), NaN before any frame was sent.

        ``part``: ``"all"`` (result -> sent), ``"upstream"`` (result -> this stage's start) or
        ``"stage"`` (this stage's start -> sent: the message built and sent).
        """
        if not self.latencies_ns:
            return math.nan
        values = {"all": lambda: np.array(self.latencies_ns, np.int64),
                  "upstream": lambda: np.array(self.upstream_ns, np.int64),
                  "stage": lambda: np.array(self.latencies_ns, np.int64) - np.array(self.upstream_ns, np.int64)}
        return float(np.percentile(values[part](), percentile)) / 1e6

    def finish(self) -> None:
        """The session ended (a Modbus map says so; the last values stay)."""
        self.outlet.finish()

    def close(self) -> None:
        self.outlet.close()

    def summary(self) -> dict[str, Any]:
        """This outlet's numbers for the session summary."""
        return {"uri": self.outlet.where, "sent": self.sent, "failed": self.failed,
                "latency_p50_ms": self.latency_ms(50), "latency_p99_ms": self.latency_ms(99),
                "latency_max_ms": self.latency_ms(100),
                "upstream_p50_ms": self.latency_ms(50, part="upstream"),
                "upstream_p99_ms": self.latency_ms(99, part="upstream"),
                "stage_p50_ms": self.latency_ms(50, part="stage"), "stage_p99_ms": self.latency_ms(99, part="stage")}

    def summary_lines(self) -> list[str]:
        """The summary's line for this outlet."""
        return format_publish_summary([self.summary()])


def open_publishers(targets: Sequence[Any], names: Sequence[str],
                    report: Callable[[str, str, str], None]) -> list[PublishStage]:
    """A ``PublishStage`` per target, opened (sockets, servers listening); closes them all if one fails.

    Raises
    ------
    ValueError
        A target cannot open (one line); nothing stays open.
    """
    stages = []
    try:
        for target in targets:
            stages.append(PublishStage(open_outlet(target, names), names, report))
    except BaseException:
        for stage in stages:
            stage.close()
        raise
    return stages


def format_publish_summary(publish: Sequence[dict] | None) -> list[str]:
    """The summary's lines for the outlets (none without ``--publish``)."""
    def num(value):
        return "n/a" if value is None or not math.isfinite(value) else f"{value:.2f}"
    return [f"  publish    {entry['uri']}: {entry['sent']} frames sent"
            + (f", {entry['failed']} NOT sent" if entry["failed"] else "")
            + f"; result -> sent p50 {num(entry['latency_p50_ms'])} ms, p99 {num(entry['latency_p99_ms'])} ms"
            for entry in publish or ()]
