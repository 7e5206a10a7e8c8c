"""stream.pipeline.sinks: each watch reports what it is for, once where it says once, and sums up what it saw.

The sinks read a handful of a result's fields, so the results here are stand-ins holding just those.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from livedic.dic.status import Status
from livedic.stream.pipeline.sinks import BitDepthWatch, FractureWatch, FunctionSink, P0Watch, ProgressLine, ReferenceUpdates


class Events:
    """The session's ``report(kind, message, level)``, kept."""

    def __init__(self):
        self.seen = []

    def __call__(self, kind, message, level):
        self.seen.append((kind, message, level))


def _result(index, *, reference=False, ok=True, zncc=0.95, status=Status.OK, dtype=np.uint8, **fields):
    measurement = SimpleNamespace(ok=np.array([ok]), zncc=np.array([zncc]), x=np.array([120.0]),
                                  y=np.array([80.0]), status=np.array([int(status)]))
    frame = SimpleNamespace(index=index, image=np.zeros((2, 2), dtype))
    base = dict(frame=frame, measurement=measurement, is_reference=reference, reference_update=None, fracture=None)
    base.update(fields)
    return SimpleNamespace(**base)


# --------------------------------------------------------------------------- P0

def test_p0_watch_warns_once_when_p0_falls_below_the_refind_zncc():
    events = Events()
    watch = P0Watch(0.8, events)
    watch(_result(0, reference=True), None)
    watch(_result(1, zncc=0.85), None)
    assert events.seen == []
    watch(_result(2, zncc=0.6), None)
    watch(_result(3, ok=False), None)                     # already warned: said once
    assert len(events.seen) == 1
    kind, message, level = events.seen[0]
    assert kind == "p0_weak" and level == "warning"
    assert "0.60" in message and "frame 2" in message


def test_p0_watch_names_a_lost_p0():
    events = Events()
    watch = P0Watch(0.8, events)
    watch(_result(0, reference=True), None)
    watch(_result(5, ok=False, zncc=float("nan")), None)
    assert events.seen and events.seen[0][1].startswith("P0 was lost at frame 5")


def test_p0_not_ok_in_the_reference_is_said_once_and_never_again():
    events = Events()
    watch = P0Watch(0.8, events)
    watch(_result(0, reference=True, ok=False, status=Status.FLAT_REFERENCE), None)
    watch(_result(1, ok=False), None)
    assert len(events.seen) == 1
    assert "not ok in the reference frame" in events.seen[0][1]
    assert Status.FLAT_REFERENCE.description in events.seen[0][1]


# --------------------------------------------------------------------------- bit depth

def test_bit_depth_watch_warns_once_when_a_frame_differs_from_the_reference():
    events = Events()
    watch = BitDepthWatch(events)
    watch(_result(1, dtype=np.uint16), None)              # no reference yet: nothing to compare with
    watch(_result(2, reference=True), None)
    watch(_result(3), None)
    assert events.seen == []
    watch(_result(4, dtype=np.uint16), None)
    watch(_result(5, dtype=np.float32), None)
    assert len(events.seen) == 1
    kind, message, level = events.seen[0]
    assert (kind, level) == ("bit_depth", "warning")
    assert message.startswith("frame 4 is 16-bit but the reference frame 2 is 8-bit")


# --------------------------------------------------------------------------- reference updates, fracture

class _Update:
    def __init__(self, frame, lost, seconds):
        self.frame, self.lost, self.seconds = frame, lost, seconds

    def describe(self):
        return f"reference moved to tracked frame {self.frame}, {self.lost} points lost"


def test_reference_updates_are_reported_and_summed_up():
    events = Events()
    sink = ReferenceUpdates(events)
    sink(_result(10), None)
    sink(_result(11, reference_update=_Update(7, 0, 0.004)), None)
    sink(_result(12, reference_update=_Update(8, 3, 0.010)), None)
    assert [level for _, _, level in events.seen] == ["info", "warning"]          # a loss is a warning
    assert events.seen[0][1] == "reference moved to frame 11, 0 points lost"     # the session's frame number
    assert sink.summary() == {"reference_updates": 2, "reference_update_lost": 3,
                              "reference_update_max_ms": pytest.approx(10.0)}
    assert ReferenceUpdates(events).summary()["reference_update_max_ms"] is None


def test_a_fracture_is_reported_and_listed_in_the_summary():
    events = Events()
    sink = FractureWatch(events)
    fracture = SimpleNamespace(lost=12, jump_px=3.5, separated=np.array([True, False, True]),
                               describe=lambda: "the specimen broke")
    sink(_result(20), None)
    sink(_result(21, fracture=fracture), None)
    assert events.seen == [("fracture", "frame 21: the specimen broke", "warning")]
    assert sink.summary() == {"fractures": [{"frame": 21, "lost": 12, "jump_px": 3.5, "separated": 2}]}


# --------------------------------------------------------------------------- progress line, function sink

def test_the_progress_line_shows_what_is_known_and_says_what_is_not():
    stats = SimpleNamespace(fps=49.96, latency_ms=lambda q: 12.34)
    acquisition = SimpleNamespace(reconnects=1, frames=100)
    readings = SimpleNamespace(names=["axial", "transverse"], eng_strain=np.array([0.01234, -0.003]),
                               ok=np.array([True, False]))
    result = _result(99, dropped_total=2, error_rms_px=0.0123, extensometers=readings, force_N=float("nan"),
                     stress_MPa=None)
    text = ProgressLine(bar=None, acquisition=acquisition).text(result, stats)
    assert text == (" 50.0 fps  latency p50  12.3 ms  drops 2  reconnected 1x  error 0.012 px  axial 1.234 %  "
                    "transverse lost  force n/a")


def test_a_function_sink_calls_its_function_with_the_result_and_stats():
    calls = []
    sink = FunctionSink(lambda result, stats: calls.append((result, stats)), "soak monitor", required=True)
    sink("r", "s")
    assert calls == [("r", "s")] and sink.name == "soak monitor" and sink.required
