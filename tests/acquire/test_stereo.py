"""Tests of acquire/stereo.py and the ``stereo:`` URI of acquire/sources.py: frames paired by id and timestamp, a
frame without a partner dropped and counted (never paired with another trigger's), errors naming the view."""

import numpy as np
import pytest

from livedic.acquire.base import Frame, FrameSource, NoFirstFrame, SourceError, SourceLost
from livedic.acquire.sources import SCHEMES, open_source, open_stereo_source, parse_scheme, parse_stereo_uri
from livedic.acquire.stereo import (CAMERA_INDEX_KEY, DEFAULT_TOLERANCE_PERIODS, DropReason, PairedFrames, PairingCounts, StereoSource, pair_by_index,
                                    pair_frames)

PERIOD_NS = 20_000_000            # 50 fps


def frames(triggers, *, first_id=0, jitter_ns=(), late_ns=(), lost=(), renumber=False, camera_offset_ns=0):
    """One view's frames for trigger numbers ``triggers``: index = id counter, image stamped with the trigger.

    ``lost`` triggers never arrive (the id counter skips them, as a camera's does) unless ``renumber`` (a camera
    that missed the trigger: no frame and no id). Frame k is exposed at k periods plus ``jitter_ns[k]`` and reaches
    the host (``system_timestamp_ns``) ``late_ns[k]`` after that; the camera's own clock starts elsewhere
    (``camera_offset_ns``).
    """
    def at(values, k):
        return values[k] if k < len(values) else 0
    out, index = [], first_id
    for k in triggers:
        if k in lost:
            if not renumber:
                index += 1
            continue
        exposed = k * PERIOD_NS + at(jitter_ns, k)
        host = exposed + at(late_ns, k)
        out.append(Frame(index=index, timestamp_ns=exposed + camera_offset_ns, image=np.full((2, 3), k, np.uint16),
                         pixel_format="Mono8", metadata={"system_timestamp_ns": host}))
        index += 1
    return out


def trigger_of(frame):
    return int(frame.image[0, 0])


def pair_all(left, right, **options):
    counts = PairingCounts()
    pairs = list(pair_frames(left, right, counts=counts, **options))
    assert all(trigger_of(p.left) == trigger_of(p.right) for p in pairs), "a mismatched pair"
    return pairs, counts


def test_views_in_step_pair_frame_by_frame_whatever_their_id_counters():
    pairs, counts = pair_all(frames(range(10), first_id=65401), frames(range(10), first_id=7,
                                                                        camera_offset_ns=10**12))
    assert [trigger_of(p.left) for p in pairs] == list(range(10)) and [p.index for p in pairs] == list(range(10))
    assert counts.pairs == 10 and counts.pairs_dropped == 0 and counts.ended_by in ("left", "right")
    # the default tolerance: half the frame period measured from the frames (host clock, camera clocks unrelated)
    assert counts.tolerance_ns == DEFAULT_TOLERANCE_PERIODS * PERIOD_NS == 10_000_000


def test_a_frame_lost_in_one_view_drops_that_pair_only_and_is_counted():
    pairs, counts = pair_all(frames(range(12)), frames(range(12), lost={4, 9}))
    assert [trigger_of(p.left) for p in pairs] == [k for k in range(12) if k not in (4, 9)]
    assert [p.index for p in pairs] == [k for k in range(12) if k not in (4, 9)]     # gaps: the pairs dropped
    assert counts.dropped == {("left", DropReason.PARTNER_LOST): 2}
    assert counts.as_dict()["dropped_left"] == 2 and counts.as_dict()["reasons"] == {"left.partner_lost": 2}
    pairs, counts = pair_all(frames(range(8), lost={0, 3}), frames(range(8)))      # the left view's first, too
    assert [trigger_of(p.left) for p in pairs] == [1, 2, 4, 5, 6, 7] and pairs[0].index == 0
    assert counts.dropped_from("right") == 2 and counts.pairs == 6


def test_a_missed_trigger_without_an_id_gap_is_caught_by_the_timestamps_and_the_views_pair_again():
    # the right camera missed trigger 3: its ids stay in step with the left's but its frames are a period late
    pairs, counts = pair_all(frames(range(10)), frames(range(10), lost={3}, renumber=True))
    assert [trigger_of(p.left) for p in pairs] == [0, 1, 2, 4, 5, 6, 7, 8, 9]
    assert counts.dropped == {("left", DropReason.TIMESTAMPS_APART): 1} and counts.pairs_dropped == 1


def test_frames_pair_within_the_tolerance_and_never_beyond_it():
    jitter = [0, 3_000_000, -4_000_000, 9_000_000, 0, 0]
    pairs, counts = pair_all(frames(range(6)), frames(range(6), jitter_ns=jitter), tolerance_ns=5_000_000)
    assert [trigger_of(p.left) for p in pairs] == [0, 1, 2, 4, 5]      # 9 ms apart: dropped, not paired
    assert counts.pairs_dropped == 1 and counts.max_abs_skew_ns == 4_000_000      # one pair: a frame from each
    assert counts.dropped == {("left", DropReason.TIMESTAMPS_APART): 1, ("right", DropReason.TIMESTAMPS_APART): 1}
    assert [p.skew_ns for p in pairs] == [0, 3_000_000, -4_000_000, 0, 0]
    pairs, _ = pair_all(frames(range(6)), frames(range(6), jitter_ns=jitter))   # default 10 ms: all pair
    assert len(pairs) == 6


def test_views_started_at_different_triggers_are_paired_by_time_first():
    # the right camera was armed three triggers later: its first frame pairs with the left's fourth
    pairs, counts = pair_all(frames(range(10)), frames(range(3, 10)))
    assert [trigger_of(p.left) for p in pairs] == list(range(3, 10))
    assert counts.dropped == {("left", DropReason.NO_PARTNER_IN_TIME): 3}


def test_a_frame_that_reached_the_host_late_is_timed_by_its_cameras_clock():
    late = [0, 0, 15_000_000, 15_000_000, 0, 0]      # two right frames reached the host 15 ms (3/4 period) late
    for clock in ("host", "camera"):
        pairs, counts = pair_all(frames(range(6)), frames(range(6), late_ns=late), clock=clock)
        assert len(pairs) == 6 and counts.max_abs_skew_ns < 1_000_000, clock   # (the offset averages 1/64 in)


def test_camera_clocks_pair_only_when_synchronised():
    pairs, counts = pair_all(frames(range(5)), frames(range(5), camera_offset_ns=10**12), clock="host")
    assert len(pairs) == 5                            # unrelated camera clocks: the host clock finds the first pair
    pairs, counts = pair_all(frames(range(5)), frames(range(5), camera_offset_ns=10**12), clock="camera")
    assert pairs == [] and counts.pairs_dropped == 5  # clock=camera takes them for one clock: nothing pairs


@pytest.mark.parametrize("error_type", [SourceError, SourceLost])
def test_a_lost_view_ends_the_pair_with_an_error_naming_it(error_type):
    def failing():
        yield from frames(range(3))
        raise error_type("camera X lost: no frame for 0.6 s")
    pairs = pair_frames(frames(range(5)), failing(), uris=("aravis:L", "aravis:R"))
    assert len([next(pairs) for _ in range(3)]) == 3
    with pytest.raises(error_type, match=r"^right view \(aravis:R\): camera X lost") as raised:
        next(pairs)
    assert type(raised.value) is error_type
    never = pair_frames(iter(()), frames(range(2)), uris=("a", "b"))
    assert list(never) == []


def test_a_view_that_never_started_keeps_its_checks():
    def silent():
        raise NoFirstFrame("camera L opened but sent no frame", checks=("the trigger",))
        yield
    with pytest.raises(NoFirstFrame, match=r"^left view \(aravis:L\)") as raised:
        list(pair_frames(silent(), frames(range(2)), uris=("aravis:L", "aravis:R")))
    assert raised.value.checks == ("the trigger",)


def test_a_stereo_source_pairs_two_sources_and_reports_its_counters():
    uri = ("stereo:synthetic:translate?frames=6&size=64x64&pace=0,"
           "synthetic:translate?frames=6&size=64x64&pace=0&seed=3,tolerance_ms=2")
    with open_stereo_source(uri) as pair_source:
        assert isinstance(pair_source, StereoSource) and pair_source.left.uri != pair_source.right.uri
        pairs = list(pair_source)
        settings = pair_source.settings
    assert [p.index for p in pairs] == list(range(6))
    assert all(p.left.index == p.right.index and p.skew_ns == 0 for p in pairs)
    assert not np.array_equal(pairs[0].left.image, pairs[0].right.image)           # two sources, not one twice
    assert settings["pairing"]["pairs"] == 6 and settings["pairing"]["tolerance_ms"] == 2.0
    assert settings["source"] == "stereo" and settings["left"]["uri"] == pair_source.left.uri


def test_the_stereo_uri_splits_at_the_right_views_scheme_keeping_the_views_commas():
    left, right, options = parse_stereo_uri(
        "stereo:aravis:A?roi=0,0,640,480&gain_db=2,aravis:B?roi=8,0,640,480,tolerance_ms=3,clock=camera")
    assert (left, right) == ("aravis:A?roi=0,0,640,480&gain_db=2", "aravis:B?roi=8,0,640,480")
    assert options == {"tolerance_ms": "3", "clock": "camera"}
    assert parse_stereo_uri("stereo:left.mcap,right.mcap")[:2] == ("left.mcap", "right.mcap")
    assert parse_scheme("Stereo:a.mcap,b.mcap") == "stereo" and "stereo" in SCHEMES


@pytest.mark.parametrize("uri, message", [
    ("stereo:", "a stereo pair takes two"),
    ("stereo:aravis:A", "one source given, a stereo pair takes two"),
    ("stereo:aravis:A,aravis:B,aravis:C", "3 sources given"),
    ("stereo:aravis:A,aravis:A", "both views are aravis:A"),
    ("stereo:aravis:A,aravis:B,speed=2", "unknown stereo option 'speed=2'"),
    ("stereo:aravis:A,aravis:B,clock=sun", "clock=sun: write clock=host or clock=camera"),
    ("stereo:aravis:A,aravis:B,tolerance_ms=-1", "option tolerance_ms=.-1.: must be >= 0"),
    ("stereo:webcam:0,aravis:B", "unknown source scheme 'webcam'"),
])
def test_a_bad_stereo_uri_is_one_line_naming_the_problem(uri, message):
    with pytest.raises(SourceError, match=message) as raised:
        open_stereo_source(uri)
    assert "\n" not in str(raised.value)


def test_open_source_gives_each_pair_as_its_left_frame_with_the_right_attached():
    """What a session takes: the pair's index, the left frame's image and timestamp, the right frame in
    ``Frame.right``, the pairing error in the metadata; the pairing counters in the settings."""
    uri = "stereo:synthetic:translate?frames=4&size=64x64&pace=0,synthetic:translate?frames=4&size=64x64&pace=0&seed=2"
    with open_source(uri) as paired, open_stereo_source(uri) as pairs:
        assert isinstance(paired, PairedFrames) and paired.stereo and not paired.live
        frames, expected = list(paired), list(pairs)
    assert [f.index for f in frames] == [p.index for p in expected] == [0, 1, 2, 3]
    for frame, pair in zip(frames, expected):
        assert np.array_equal(frame.image, pair.left.image) and np.array_equal(frame.right.image, pair.right.image)
        assert frame.timestamp_ns == pair.left.timestamp_ns and frame.metadata["stereo_skew_ns"] == pair.skew_ns
        assert not np.array_equal(frame.image, frame.right.image)       # two views, not one twice
    assert paired.settings["pairing"]["pairs"] == 4
    with pytest.raises(SourceError, match="is not a stereo pair"):
        open_stereo_source("synthetic:translate")


def test_a_view_that_cannot_open_is_named_and_the_other_is_closed(monkeypatch):
    closed = []
    monkeypatch.setattr("livedic.acquire.simulator.sources.SyntheticTranslateSource.close",
                        lambda self: closed.append(self))
    with pytest.raises(SourceError, match=r"^right view \(images:/nonexistent/\*.png\): "):
        open_stereo_source("stereo:synthetic:translate?frames=2&size=64x64,images:/nonexistent/*.png")
    assert len(closed) == 1


@pytest.mark.parametrize("seed", range(20))
def test_random_losses_late_arrivals_and_jitter_never_make_a_mismatched_pair(seed):
    """Lost frames (odd seeds: missed triggers, no id gap), host arrivals up to 0.9 period late, exposures up to
    0.3 period off (a free-running camera's phase)."""
    rng = np.random.default_rng(seed)
    n = 300

    def view():
        lost = set(np.flatnonzero(rng.random(n) < 0.05).tolist())
        late = np.where(rng.random(n) < 0.1, rng.uniform(0, 0.9 * PERIOD_NS, n), rng.uniform(0, 1e6, n))
        jitter = np.where(rng.random(n) < 0.05, rng.uniform(-0.3, 0.3, n) * PERIOD_NS, rng.uniform(0, 1e5, n))
        return frames(range(n), lost=lost, renumber=bool(seed % 2), late_ns=late.astype(int).tolist(),
                      jitter_ns=jitter.astype(int).tolist())
    pairs, counts = pair_all(view(), view())          # pair_all fails on any mismatched pair
    assert counts.pairs == len(pairs) > 0.6 * n        # ~0.73 of triggers have both frames in time
    assert len({p.index for p in pairs}) == len(pairs)


class _Listed(FrameSource):
    """Listed frames as a source."""
    uri = "listed:"

    def __init__(self, listed):
        self.listed = listed

    def __iter__(self):
        return iter(self.listed)


def test_paired_frames_give_the_right_frame_the_pairs_index_keeping_the_cameras_own():
    """A recording's views pair by index: the right frame carries the pair's, its camera's id in the metadata."""
    pairs = PairedFrames(StereoSource(_Listed(frames(range(4), first_id=10)), _Listed(frames(range(4), first_id=70)),
                                      tolerance_ms=1.0))
    delivered = list(pairs)
    assert [f.index for f in delivered] == [f.right.index for f in delivered] == [0, 1, 2, 3]
    assert [f.right.metadata[CAMERA_INDEX_KEY] for f in delivered] == [70, 71, 72, 73]


def test_recorded_views_pair_by_index_and_a_frame_without_its_partner_is_dropped_and_counted():
    left = [f for f in frames(range(8)) if f.index not in (2, 7)]       # the left view lost 2 and was cut at 7
    right = [f for f in frames(range(8)) if f.index not in (0, 5)]      # the right one lost 0 and 5
    counts = PairingCounts()
    pairs = list(pair_by_index(left, right, counts))
    assert [p.index for p in pairs] == [1, 3, 4, 6]
    assert all(p.right is not None and p.right.index == p.index for p in pairs)
    assert all(np.array_equal(p.image, q.image) for p, q in zip(pairs, (f for f in left if f.index in (1, 3, 4, 6))))
    assert counts.pairs == 4 and counts.pairs_dropped == 4
    assert counts.dropped == {("left", DropReason.PARTNER_LOST): 2, ("right", DropReason.PARTNER_LOST): 2}
    assert counts.ended_by == "left"


def test_two_simulated_views_are_rendered_ahead_and_paced_by_one_clock():
    """A pair of paced simulated views: both rendered by ``prepare`` (before any clock), the pair live, each pair
    stamped on one clock that starts when the second pair is asked for (the pairing's look-ahead no longer starts
    the views' own clocks while the session prepares), a period apart."""
    import time

    fps = 50.0
    view = "synthetic:translate?frames=5&size=64x64&fps=50"
    with open_source(f"stereo:{view},{view}&seed=2") as paired:
        assert paired.live and hasattr(paired, "prepare")
        paired.prepare()
        frames = iter(paired)
        first = next(frames)
        asked = time.monotonic_ns()
        rest = list(frames)
    stamps = [frame.metadata["capture_monotonic_ns"] for frame in [first, *rest]]
    assert stamps[1] >= asked - 1e9 / fps                    # the clock started at the second request
    np.testing.assert_allclose(np.diff(stamps[1:]), 1e9 / fps, atol=1.0)
    assert all(frame.right is not None for frame in rest) and paired.pairs.counts.pairs == 5
