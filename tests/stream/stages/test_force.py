"""The load stage's warning for a force stream on the wrong clock: samples arrive, none lies at the frames' times.

A fake stream answers like ``acquire.force``'s live sources: NaN at a frame's time with no sample around it,
its newest sample time growing as samples arrive. Frames every 20 ms; the misaligned sender's clock is
1,000 s ahead. A stalled stream (no new samples) is a stall, said by the source itself, not this warning.
"""

import math
from types import SimpleNamespace

from livedic.stream.stages.force import MISALIGNED_FRAMES, LoadStage


class FakeStream:
    uri = "tcp://fake"

    def __init__(self, offset_s, arriving=True):
        self.offset_s, self.arriving, self.now = offset_s, arriving, 0.0
        self.warnings = SimpleNamespace()

    def frame_time_s(self, *, since_first_frame_s=None, arrival_ns=None):
        return since_first_frame_s

    def force_when_known(self, when):
        self.now = when
        return 100.0 * when if self.offset_s == 0 else math.nan

    @property
    def last_sample_time_s(self):
        return self.now + self.offset_s if self.arriving else 5.0

    def events(self, since=0):
        return []


def _run(stream, frames=2 * MISALIGNED_FRAMES):
    said = []
    stage = LoadStage(stream, 10.0, lambda kind, message, level: said.append((level, message)))
    for i in range(frames):
        result = SimpleNamespace(frame=SimpleNamespace(timestamp_ns=i * 20_000_000), arrival_ns=0,
                                 extensometers=None)
        stage.on_frame(result)
    return said


def test_samples_on_another_clock_are_warned_about_once():
    said = _run(FakeStream(offset_s=1000.0))
    assert len(said) == 1 and said[0][0] == "warning"
    assert "none lies at the frames' times" in said[0][1] and "clock=sender" in said[0][1]


def test_a_stall_or_an_aligned_stream_is_not_this_warning():
    assert _run(FakeStream(offset_s=1000.0, arriving=False)) == []      # nothing new arrives: a stall
    assert _run(FakeStream(offset_s=0.0)) == []                         # every frame has its force
