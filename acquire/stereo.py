"""Two frame sources in step: ``stereo:LEFT_URI,RIGHT_URI`` yields ``StereoFrame`` pairs, never a mismatched one.

Contract
--------
* Each view is any frame source (``aravis:...``, ``images:...``, ``synthetic:...``, ...). A pair is one left and
  one right frame of the same trigger: paired by frame id (``Frame.index``, whose gaps are frames lost upstream)
  and checked by timestamp. Their timestamps must agree within ``tolerance_ms`` (default: half the frame period,
  ``DEFAULT_TOLERANCE_PERIODS``), else the frame is dropped and counted, never paired with another trigger's.
* A frame whose partner was lost (a gap in the other view's ids, or no frame of the other view within the
  tolerance) is dropped, counted by view and ``DropReason``; the next frames pair as before. A camera that missed a
  trigger (ids in step but a period apart) shows as timestamps apart: the earlier frame is dropped and the views
  are paired again by timestamp; two frames of one trigger whose times disagree are both dropped, one pair.
* The first pair is found on one clock (``clock=``; the id offset most of each view's first frames agree on):
  ``host`` (default: when this computer received the frame, ``metadata["system_timestamp_ns"]`` where the source
  gives it, else ``Frame.timestamp_ns``) or ``camera``
  (``Frame.timestamp_ns``: only for cameras whose clocks are synchronised, IEEE 1588 PTP). From then on each frame's
  own ``Frame.timestamp_ns`` (the camera's clock: exact, no transfer jitter) is compared, the offset between the two
  cameras' clocks measured on the pairing clock at every pair (``_Skew``).
* Two ``trigger=software`` Aravis cameras are fired together: the pair takes their trigger over and fires both from
  one thread at their ``frame_rate`` (which must agree).
* A view that fails ends the pair with its own error type (``SourceError``, ``NoFirstFrame``, ``SourceLost``), the
  message naming the view; a view that ends (files) ends the pair.
"""

from __future__ import annotations

import enum
import math
import statistics
import threading
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

from livedic.acquire.base import Frame, FrameSource, NoFirstFrame, SourceError, SourceLost

__all__ = ["PairedFrames", "StereoFrame", "StereoSource", "DropReason", "PairingCounts", "pair_frames",
           "pair_by_index", "CLOCKS", "DEFAULT_TOLERANCE_PERIODS", "VIEWS", "CAMERA_INDEX_KEY"]

VIEWS = ("left", "right")
CLOCKS = ("host", "camera")
# Two frames of one trigger are (nearly) simultaneous, the neighbouring trigger's frame a whole period away: half a
# period is the widest tolerance that can never take a neighbour for a partner.
DEFAULT_TOLERANCE_PERIODS = 0.5
_PERIOD_FRAMES = 2          # frames read from each view to measure the frame period when no trigger rate gives it
_OFFSET_PAIRS = 64          # pairs the cameras' clock offset is averaged over (the pairing clock's jitter / 8)
_ALIGN_FRAMES = 5           # frames of each view that vote for the first pair
# ``PairedFrames``' right frame carries the pair's index (both views of a recording pair by it); the right camera's
# own frame id is kept in its metadata under this key.
CAMERA_INDEX_KEY = "camera_frame_index"


class DropReason(enum.Enum):
    """Why a frame was dropped instead of paired (``PairingCounts`` counts the frames and the pairs lost)."""
    PARTNER_LOST = "partner_lost"              # the other view's ids skip this frame's: lost upstream there
    NO_PARTNER_IN_TIME = "no_partner_in_time"  # before the views are in step (the start, after a missed trigger):
                                               # no frame of the other view within the tolerance
    TIMESTAMPS_APART = "timestamps_apart"      # ids in step, timestamps beyond the tolerance (a missed trigger)


@dataclass(frozen=True)
class StereoFrame:
    """One left and one right frame of the same trigger.

    index : int         pair number, 0 for the first pair (the left view's frame number from there: gaps are
                        pairs dropped or lost in both views)
    left, right : Frame each view's frame, as its source delivered it
    skew_ns : int       right minus left timestamp on the pairing clock: the pairing error
    """
    index: int
    left: Frame
    right: Frame
    skew_ns: int

    @property
    def timestamp_ns(self) -> int:
        """The left frame's timestamp (the pair's time)."""
        return self.left.timestamp_ns


@dataclass
class PairingCounts:
    """What pairing did so far: pairs made and dropped, frames dropped by view and reason, the worst skew.

    dropped : Counter of (view, DropReason) -> frames of that view dropped for that reason (a pair whose two
              frames' timestamps disagree drops a frame in each view, one pair)
    """
    pairs: int = 0
    pairs_dropped: int = 0               # triggers that gave a frame in at least one view but no pair
    dropped: Counter = field(default_factory=Counter)
    max_abs_skew_ns: int = 0
    tolerance_ns: int | None = None
    ended_by: str | None = None          # the view whose end ended the pair ("left"/"right"), None while running

    def dropped_from(self, view: str) -> int:
        return sum(n for (side, _), n in self.dropped.items() if side == view)

    def as_dict(self) -> dict[str, Any]:
        """Plain data for the session metadata and summary."""
        return {"pairs": self.pairs, "pairs_dropped": self.pairs_dropped,
                "dropped_left": self.dropped_from("left"), "dropped_right": self.dropped_from("right"),
                "reasons": {f"{side}.{reason.value}": n for (side, reason), n in sorted(
                    self.dropped.items(), key=lambda item: (item[0][0], item[0][1].value))},
                "max_abs_skew_ms": self.max_abs_skew_ns / 1e6,
                "tolerance_ms": None if self.tolerance_ns is None else self.tolerance_ns / 1e6,
                "ended_by": self.ended_by}


def clock_ns(frame: Frame, clock: str) -> int:
    """The frame's time on the pairing clock (see the module notes)."""
    if clock == "host":
        host = (frame.metadata or {}).get("system_timestamp_ns")
        if host is not None:
            return int(host)
    return int(frame.timestamp_ns)


class _View:
    """One view's frames with a look-ahead. Its failure is kept (naming the view) and raised by ``take_error``
    only when the pairing reaches it: the frames before it still pair."""

    def __init__(self, name: str, frames: Iterable[Frame], uri: str) -> None:
        self.name, self.uri = name, uri
        self._frames = iter(frames)
        self.ahead: list[Frame] = []
        self.error: SourceError | None = None
        self._ended = False

    def peek(self, n: int = 0) -> Frame | None:
        """The frame ``n`` ahead, None when the view ended (or failed) first."""
        while len(self.ahead) <= n:
            frame = None if self._ended else self._next()
            if frame is None:
                self._ended = True
                return None
            self.ahead.append(frame)
        return self.ahead[n]

    def take(self) -> Frame:
        return self.ahead.pop(0)

    def _next(self) -> Frame | None:
        try:
            return next(self._frames)
        except StopIteration:
            return None
        except NoFirstFrame as error:
            self.error = NoFirstFrame(self._named(error), checks=error.checks)
        except SourceLost as error:
            self.error = SourceLost(self._named(error))
        except SourceError as error:
            self.error = SourceError(self._named(error))
        return None

    def _named(self, error: Exception) -> str:
        return f"{self.name} view ({self.uri}): {error}"


def _measured_period_ns(left: _View, right: _View, clock: str) -> int | None:
    """The shorter of the two views' first frame intervals (a frame lost at the start lengthens only one)."""
    periods = []
    for view in (left, right):
        first, second = view.peek(0), view.peek(_PERIOD_FRAMES - 1)
        if first is not None and second is not None:
            periods.append(abs(clock_ns(second, clock) - clock_ns(first, clock)))
    return min(periods) if periods else None


class _Skew:
    """Right minus left time of two frames: on the pairing clock until the views are aligned, then on the cameras'
    own clocks (each exact, free of transfer jitter), their offset measured on the pairing clock (``_first_alignment``,
    then at each pair).

    The offset follows the cameras' clock drift (a few ppm) as a running mean over ``_OFFSET_PAIRS`` pairs, which
    also averages the pairing clock's jitter out. Cameras whose clocks are one (``clock=camera``) have offset 0.
    """

    def __init__(self, clock: str) -> None:
        self.clock = clock
        self.offset_ns: float | None = 0.0 if clock == "camera" else None

    def __call__(self, left: Frame, right: Frame) -> int:
        if self.offset_ns is None:
            return clock_ns(right, self.clock) - clock_ns(left, self.clock)
        return int(right.timestamp_ns - left.timestamp_ns - self.offset_ns)

    def paired(self, left: Frame, right: Frame) -> None:
        if self.clock == "camera":
            return
        measured = (right.timestamp_ns - left.timestamp_ns) - (clock_ns(right, self.clock) - clock_ns(left, self.clock))
        self.offset_ns = measured if self.offset_ns is None else self.offset_ns + (measured - self.offset_ns) / \
            _OFFSET_PAIRS


def _first_alignment(left: _View, right: _View, clock: str, tolerance_ns: int) -> tuple[int, float] | None:
    """``(right id - left id, camera clock offset)`` that most frame pairs of the views' first ``_ALIGN_FRAMES``
    frames agree on within the tolerance on the pairing clock; None when no pair does.

    Voting over several frames keeps one frame that reached the host late from setting up every pair after it.
    """
    lefts = [frame for frame in (left.peek(n) for n in range(_ALIGN_FRAMES)) if frame is not None]
    rights = [frame for frame in (right.peek(n) for n in range(_ALIGN_FRAMES)) if frame is not None]
    votes: dict[int, list[tuple[int, int]]] = {}
    for a in lefts:
        for b in rights:
            skew = clock_ns(b, clock) - clock_ns(a, clock)
            if abs(skew) <= tolerance_ns:
                votes.setdefault(b.index - a.index, []).append((skew, b.timestamp_ns - a.timestamp_ns - skew))
    if not votes:
        return None
    id_offset, agreeing = max(votes.items(), key=lambda item: (len(item[1]), -statistics.median(
        abs(skew) for skew, _ in item[1])))
    return id_offset, statistics.median(offset for _, offset in agreeing)


def _missed_a_trigger(earlier: _View, later: _View, skew: _Skew, tolerance_ns: int) -> bool:
    """The earlier view's next frame matches the later view's frame: the later camera missed a trigger (its ids
    stayed in step). Else the two frames are one trigger's whose times disagree."""
    following, other = earlier.peek(1), later.peek(0)
    if following is None or other is None:
        return False
    return abs(skew(following, other) if earlier.name == "left" else skew(other, following)) <= tolerance_ns


def pair_frames(left: Iterable[Frame], right: Iterable[Frame], *, tolerance_ns: int | None = None,
                period_ns: int | None = None, clock: str = "host", counts: PairingCounts | None = None,
                uris: tuple[str, str] = ("", "")) -> Iterator[StereoFrame]:
    """Pair two views' frames (the module notes): yields ``StereoFrame``, updates ``counts`` as it goes.

    Parameters
    ----------
    left, right : iterables of Frame
    tolerance_ns : int, optional
        Largest timestamp difference of a pair. Default: ``DEFAULT_TOLERANCE_PERIODS`` x the frame period.
    period_ns : int, optional
        The frame period (a trigger rate); measured from each view's first frames when not given.
    clock : {"host", "camera"}
    counts : PairingCounts, optional
        Filled in place (a source's summary reads it while pairs come).
    uris : (str, str)
        The views' URIs, for error messages.
    """
    if clock not in CLOCKS:
        raise SourceError(f"stereo option clock={clock!r}: write clock=host or clock=camera")
    views = {"left": _View("left", left, uris[0]), "right": _View("right", right, uris[1])}
    if tolerance_ns is None:
        if period_ns is None:
            period_ns = _measured_period_ns(views["left"], views["right"], clock)
        tolerance_ns = int(DEFAULT_TOLERANCE_PERIODS * (period_ns or 0))
    return _Pairing(views, clock, tolerance_ns, counts if counts is not None else PairingCounts()).pairs()


class _Pairing:
    """The state of ``pair_frames``: each step pairs the views' next frames or drops one (or both) of them."""

    def __init__(self, views: dict[str, _View], clock: str, tolerance_ns: int, counts: PairingCounts) -> None:
        self.views, self.clock, self.tolerance_ns, self.counts = views, clock, tolerance_ns, counts
        counts.tolerance_ns = tolerance_ns
        self.skew = _Skew(clock)
        self.id_offset: int | None = None      # right index - left index while the views' ids are in step
        self.first_index: int | None = None

    def pairs(self) -> Iterator[StereoFrame]:
        left, right = self.views["left"], self.views["right"]
        while True:
            a, b = left.peek(), right.peek()
            if a is None or b is None:
                self._end(left if a is None else right)
                return
            if self.skew.offset_ns is None and not self._aligned(a, b):
                continue
            if self.id_offset is not None and a.index + self.id_offset != b.index:
                # One view's ids skip the other's frame: its partner was lost upstream (before the first pair: the
                # other view had not started).
                self._drop("left" if a.index + self.id_offset < b.index else "right",
                           DropReason.PARTNER_LOST if self.counts.pairs else DropReason.NO_PARTNER_IN_TIME)
                continue
            skew = self.skew(a, b)
            if abs(skew) > self.tolerance_ns:
                self._drop_apart(skew)
                continue
            pair = self._pair(a, b, skew)
            a = b = None               # hold no frame (a camera's lent buffer) while the consumer has the pair
            yield pair

    def _end(self, view: _View) -> None:
        if view.error is not None:
            raise view.error
        self.counts.ended_by = view.name

    def _aligned(self, a: Frame, b: Frame) -> bool:
        """Find the first pair's ids and the cameras' clock offset; else drop the earlier frame (False)."""
        alignment = _first_alignment(self.views["left"], self.views["right"], self.clock, self.tolerance_ns)
        if alignment is None:
            self._drop("left" if self.skew(a, b) > 0 else "right", DropReason.NO_PARTNER_IN_TIME)
            return False
        self.id_offset, self.skew.offset_ns = alignment
        return True

    def _drop_apart(self, skew: int) -> None:
        """Two frames too far apart in time: the earlier has no partner, or (ids in step) a camera missed a
        trigger, or the two are one trigger's whose times cannot be trusted."""
        earlier, later = ("left", "right") if skew > 0 else ("right", "left")
        if self.id_offset is None:
            self._drop(earlier, DropReason.NO_PARTNER_IN_TIME)
        elif _missed_a_trigger(self.views[earlier], self.views[later], self.skew, self.tolerance_ns):
            self._drop(earlier, DropReason.TIMESTAMPS_APART)
        else:
            self._drop("left", DropReason.TIMESTAMPS_APART, pair=False)
            self._drop("right", DropReason.TIMESTAMPS_APART)
        self.id_offset = None          # ids no longer vouch for the pairing: the next pair is found by time

    def _drop(self, side: str, reason: DropReason, pair: bool = True) -> None:
        self.views[side].take()
        self.counts.dropped[(side, reason)] += 1
        self.counts.pairs_dropped += pair

    def _pair(self, a: Frame, b: Frame, skew: int) -> StereoFrame:
        self.id_offset = b.index - a.index
        self.views["left"].take()
        self.views["right"].take()
        self.skew.paired(a, b)
        self.first_index = a.index if self.first_index is None else self.first_index
        self.counts.pairs += 1
        self.counts.max_abs_skew_ns = max(self.counts.max_abs_skew_ns, abs(skew))
        return StereoFrame(index=a.index - self.first_index, left=a, right=b, skew_ns=skew)


def pair_by_index(left: Iterable[Frame], right: Iterable[Frame], counts: PairingCounts | None = None
                  ) -> Iterator[Frame]:
    """Frames of two views that carry their pair's index (a recording's, ``PairedFrames``), paired by index.

    Each view's indices increase. A frame whose index the other view lacks (lost, or cut off the end of a file)
    is dropped and counted (``DropReason.PARTNER_LOST``), never paired with another index's: yields each pair as
    its left ``Frame`` with the right one in ``Frame.right``. ``counts`` is filled as it goes.
    """
    counts = counts if counts is not None else PairingCounts()
    lefts, rights = iter(left), iter(right)
    a, b = next(lefts, None), next(rights, None)
    while a is not None and b is not None:
        if a.index == b.index:
            counts.pairs += 1
            yield Frame(a.index, a.timestamp_ns, a.image, a.pixel_format, a.metadata, right=b)
            a, b = next(lefts, None), next(rights, None)
            continue
        side = "left" if a.index < b.index else "right"
        counts.dropped[(side, DropReason.PARTNER_LOST)] += 1
        counts.pairs_dropped += 1
        if side == "left":
            a = next(lefts, None)
        else:
            b = next(rights, None)
    counts.ended_by = "left" if a is None else "right"
    for side, first, rest in (("left", a, lefts), ("right", b, rights)):
        if first is not None:                   # the other view ended first: the rest of this one has no partner
            lost = 1 + sum(1 for _ in rest)
            counts.dropped[(side, DropReason.PARTNER_LOST)] += lost
            counts.pairs_dropped += lost


class _TriggerClock(threading.Thread):
    """Fires TriggerSoftware on both cameras of a pair at one rate; the first failure stops it (``error``)."""

    def __init__(self, cameras: tuple[Any, Any], rate_hz: float) -> None:
        super().__init__(name="livedic-stereo-trigger", daemon=True)
        self.cameras, self.period_s = cameras, 1.0 / rate_hz
        self.error: SourceError | None = None
        self.fired = 0
        self._stop_event = threading.Event()

    def run(self) -> None:
        due = time.monotonic()
        while not self._stop_event.wait(max(0.0, due - time.monotonic())):
            try:
                for camera in self.cameras:
                    camera.fire_software_trigger()
            except SourceError as error:
                self.error = error
                return
            self.fired += 1
            # paced from the last tick; after a stall start again from now, no burst
            due = max(due + self.period_s, time.monotonic())

    def stop(self) -> None:
        self._stop_event.set()
        if self.is_alive() and self is not threading.current_thread():
            self.join(timeout=2.0)


class StereoSource:
    """Two frame sources in step, yielding ``StereoFrame`` (a context manager like ``FrameSource``).

    Parameters
    ----------
    left, right : FrameSource
        The views, already open; closed with the pair.
    tolerance_ms : float, optional
        Largest timestamp difference of a pair (default half the frame period).
    clock : {"host", "camera"}
        The clock timestamps are compared on (module notes).
    uri : str
        The ``stereo:`` URI, for settings and messages.
    """

    def __init__(self, left: FrameSource, right: FrameSource, *, tolerance_ms: float | None = None,
                 clock: str = "host", uri: str = "") -> None:
        if clock not in CLOCKS:
            raise SourceError(f"stereo option clock={clock!r}: write clock=host or clock=camera")
        self.left, self.right, self.uri, self.clock = left, right, uri, clock
        self.tolerance_ms = tolerance_ms
        self.counts = PairingCounts()
        self._trigger: _TriggerClock | None = None
        self.trigger_rate_hz = self._take_software_trigger()

    def _take_software_trigger(self) -> float | None:
        """Both views ``trigger=software`` Aravis cameras: one clock fires both (their frame_rate must agree)."""
        handing = [hasattr(view, "hand_over_software_trigger") and (view.settings.get("requested") or {}).get(
            "trigger") == "software" for view in (self.left, self.right)]
        if not any(handing):
            return None
        if not all(handing):
            one = VIEWS[handing.index(True)]
            raise SourceError(f"stereo: only the {one} view has trigger=software: give both cameras the same "
                              "trigger (trigger=software&frame_rate=F on both, or trigger=line:N on both)")
        cameras: tuple[Any, Any] = (self.left, self.right)       # AravisCamera, checked above
        rates = [camera.hand_over_software_trigger() for camera in cameras]
        if not math.isclose(rates[0], rates[1], rel_tol=1e-6):
            raise SourceError(f"stereo: the views' software trigger rates differ (frame_rate={rates[0]:g} and "
                              f"{rates[1]:g}): one trigger fires both, give both the same frame_rate")
        return rates[0]

    @property
    def live(self) -> bool:
        return self.left.live or self.right.live

    @property
    def settings(self) -> dict[str, Any]:
        """Both views' settings and the pairing counters (session metadata and summary)."""
        return {"source": "stereo", "uri": self.uri, "clock": self.clock,
                "software_trigger_rate": self.trigger_rate_hz,
                "software_triggers": self._trigger.fired if self._trigger else 0,
                "pairing": self.counts.as_dict(),
                "left": dict(self.left.settings or {}), "right": dict(self.right.settings or {})}

    def __iter__(self) -> Iterator[StereoFrame]:
        period_ns = None
        if self.trigger_rate_hz is not None and self._trigger is None:
            for view in (self.left, self.right):
                view.start_acquisition()          # type: ignore[attr-defined]  # both armed before the first trigger
            self._trigger = _TriggerClock((self.left, self.right), self.trigger_rate_hz)
            self._trigger.start()
            period_ns = int(1e9 / self.trigger_rate_hz)
        tolerance_ns = None if self.tolerance_ms is None else int(self.tolerance_ms * 1e6)
        pairs = pair_frames(self.left, self.right, tolerance_ns=tolerance_ns, period_ns=period_ns,
                            clock=self.clock, counts=self.counts, uris=(self.left.uri, self.right.uri))
        try:
            yield from pairs
        except SourceError:
            trigger_error = self._trigger.error if self._trigger else None
            if trigger_error is not None:       # the camera that failed to fire says more than its frame timeout
                raise SourceError(f"stereo software trigger: {trigger_error}") from None
            raise

    def close(self) -> None:
        if self._trigger is not None:
            self._trigger.stop()
        try:
            self.left.close()
        finally:
            self.right.close()

    def __enter__(self) -> StereoSource:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close()
        return False


class PairedFrames(FrameSource):
    """A ``StereoSource`` as a ``FrameSource``: each pair as its left ``Frame`` with the right one in ``Frame.right``.

    What a live session takes (``open_source("stereo:...")``): the queue, drops, recording and the camera view
    handle the pair as one frame of the left view; the tracker reads both. The frame's index is the pair's,
    its timestamp the left one's, ``metadata["stereo_skew_ns"]`` the pairing error. ``stereo`` marks it. The right
    frame has the pair's index too (a recording's views pair by it, ``pair_by_index``), its camera's own frame id
    in ``metadata[CAMERA_INDEX_KEY]``.
    """

    stereo = True

    def __init__(self, pairs: StereoSource) -> None:
        self.pairs = pairs
        self.uri = pairs.uri
        views = (pairs.left, pairs.right)
        if all(hasattr(view, "prepare") for view in views):
            # two simulated views: both rendered before the session's clock, not the right one while the left's
            # clock runs (its first frames then came seconds late, a burst the queue dropped)
            left: Any = pairs.left
            self.prepare = self._prepare_views
            self.frames = min(int(getattr(view, "frames")) for view in views)
            self.rendered_frames = int(getattr(left, "rendered_frames", left.frames))     # per view, as the test's
            # the test's frames, less the static ones (which frames counts)
            self.test_frames = min(int(getattr(view, "test_frames", getattr(view, "frames"))) for view in views)
            self.static = int(getattr(left, "static", 0) or 0)
            self.fps, self.options = left.fps, dict(left.options)      # the pair's: paced as the views were asked
            # one clock for both (as one trigger fires two cameras): the pairing reads a few frames of each view
            # ahead to align them, which would start each view's own clock before the session is ready
            self._pace = bool(left.options.get("pace", True))
            for view in views:
                view.options["pace"] = False                                        # type: ignore[attr-defined]

    def _prepare_views(self, progress: Any = None) -> None:
        """Render both simulated views ahead (``progress(done, total)``: a view's frames, both views' halves)."""
        left: Any = self.pairs.left
        right: Any = self.pairs.right
        if progress is None:
            left.prepare()
            right.prepare()
            return
        left.prepare(progress=lambda done, total: progress(done // 2, total))
        right.prepare(progress=lambda done, total: progress((total + done) // 2, total))

    @property
    def live(self) -> bool:
        return self._pace or self.pairs.live

    @property
    def settings(self) -> dict[str, Any]:
        return self.pairs.settings

    _pace = False

    def __iter__(self) -> Iterator[Frame]:
        period_ns = 1e9 / self.fps if self._pace else 0.0
        start_ns = time.monotonic_ns()
        for k, pair in enumerate(self.pairs):
            capture = None
            if self._pace:
                if k == 1:          # the clock starts when the second pair is asked for, as a simulated view's does
                    start_ns = time.monotonic_ns() - int(round(period_ns))
                capture = start_ns + int(round(k * period_ns))
                wait = capture - time.monotonic_ns()
                if wait > 0:
                    time.sleep(wait / 1e9)
            left = pair.left
            metadata = dict(left.metadata) if isinstance(left.metadata, dict) else {}
            metadata["stereo_skew_ns"] = pair.skew_ns
            if capture is not None:
                metadata["capture_monotonic_ns"] = capture
            right = pair.right
            right_metadata = dict(right.metadata) if isinstance(right.metadata, dict) else {}
            right_metadata[CAMERA_INDEX_KEY] = right.index
            right = Frame(pair.index, right.timestamp_ns, right.image, right.pixel_format, right_metadata)
            yield Frame(pair.index, left.timestamp_ns, left.image, left.pixel_format, metadata, right=right)

    def discard_buffered(self) -> int:
        """Both views' frames sent while the session was prepared (cameras), dropped; how many."""
        dropped = 0
        for view in (self.pairs.left, self.pairs.right):
            discard = getattr(view, "discard_buffered", None)
            if discard is not None:
                dropped += int(discard() or 0)
        return dropped

    def close(self) -> None:
        self.pairs.close()
