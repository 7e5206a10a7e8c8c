"""Tests of dic/tracking/update_policy.py: when the reference moves (auto, never, every:N) and what a move reports."""

import numpy as np
import pytest

from livedic.dic.result import Measurement
from livedic.dic.status import Status
from livedic.dic.tracking.update_policy import (AUTO_OK, AUTO_STRAIN, AUTO_ZNCC, ReferenceUpdate, UpdatePolicy,
                                                _percentile_may_pass)

N = 200


def measurement(zncc=0.99, strain=0.01, ok=None, status=None, gradients=True):
    """A result of N points, all ok at ``zncc`` with gradients of ``strain`` unless told otherwise."""
    ok = np.ones(N, dtype=bool) if ok is None else ok
    status = np.where(ok, int(Status.OK), int(Status.LOW_CORRELATION)).astype(np.int8) if status is None else status
    grads = {name: np.full(N, strain) for name in ("ux", "uy", "vx", "vy")} if gradients else {}
    return Measurement(x=np.arange(N, dtype=float), y=np.zeros(N), u=np.zeros(N), v=np.zeros(N),
                       zncc=np.broadcast_to(zncc, (N,)).astype(float), ok=ok, status=status, **grads)


ALL = np.ones(N, dtype=bool)


def test_auto_keeps_a_good_frame_with_little_strain():
    assert UpdatePolicy().reason(10, measurement(), ALL) is None


def test_auto_moves_when_the_5th_percentile_of_zncc_falls_below_its_limit():
    zncc = np.full(N, 0.99)
    zncc[: N // 10] = AUTO_ZNCC - 0.05              # 10 % of the points below the limit
    reason = UpdatePolicy().reason(3, measurement(zncc=zncc), ALL)
    assert reason is not None and reason.startswith("ZNCC 5th percentile")
    zncc[: N // 10] = 0.99
    zncc[: N // 50] = AUTO_ZNCC - 0.05              # 2 %: the 5th percentile stays above
    assert UpdatePolicy().reason(3, measurement(zncc=zncc), ALL) is None


def test_auto_moves_when_the_strain_since_the_key_frame_grows_past_its_limit():
    reason = UpdatePolicy().reason(3, measurement(strain=-(AUTO_STRAIN + 0.01)), ALL)   # compression counts too
    assert reason is not None and reason.startswith("strain since the key frame")
    assert UpdatePolicy().reason(3, measurement(strain=AUTO_STRAIN - 0.01), ALL) is None
    assert UpdatePolicy().reason(3, measurement(strain=1.0, gradients=False), ALL) is None   # no gradients: no rule


def test_auto_never_moves_to_a_frame_with_too_few_ok_points():
    ok = ALL.copy()
    ok[: int(np.ceil((1 - AUTO_OK) * N)) + 1] = False
    assert UpdatePolicy().reason(3, measurement(zncc=0.5, strain=0.5, ok=ok), ALL) is None


def test_points_that_left_the_image_do_not_count_against_the_frame():
    ok = ALL.copy()
    ok[:20] = False                                   # 10 % not ok, but all of them left the image
    status = np.where(ok, int(Status.OK), int(Status.OUTSIDE_TARGET)).astype(np.int8)
    reason = UpdatePolicy().reason(3, measurement(strain=0.2, ok=ok, status=status), ALL)
    assert reason is not None and reason.startswith("strain")


def test_no_trackable_point_never_moves_the_reference():
    nothing = np.zeros(N, dtype=bool)
    for policy in ("auto", "every:1"):
        assert UpdatePolicy.parse(policy).reason(5, measurement(zncc=0.1, strain=0.5), nothing) is None


def test_never_and_every_n():
    assert UpdatePolicy.parse("never").reason(1000, measurement(zncc=0.1, strain=0.5), ALL) is None
    every = UpdatePolicy.parse("every:4")
    assert [every.reason(k, measurement(), ALL) for k in (1, 3)] == [None, None]
    assert every.reason(4, measurement(), ALL) == "every 4 frames"
    assert every.reason(6, measurement(), ALL) == "every 4 frames"


def test_a_reference_update_describes_what_was_carried_placed_and_lost():
    plain = ReferenceUpdate(frame=7, reason="every 5 frames", carried=120, estimated=0, lost=0, seconds=0.0123)
    assert plain.describe() == "reference moved to tracked frame 7 (every 5 frames): 120 points carried, 12.3 ms"
    full = ReferenceUpdate(frame=2, reason="r", carried=10, estimated=3, lost=1, seconds=0.001)
    assert full.describe() == ("reference moved to tracked frame 2 (r): 10 points carried, 3 placed from their "
                               "neighbours, 1 lost, 1.0 ms")


def test_the_policy_skips_a_percentile_only_where_it_cannot_pass():
    """The auto policy counts values beyond its limit before it sorts: wherever it skips np.percentile, the
    percentile is on the safe side of the limit (ties, repeated values and limits at the values included)."""
    rng = np.random.default_rng(2)
    skipped = 0
    for _ in range(3000):
        n = int(rng.integers(1, 60))
        values = np.round(rng.uniform(0.8, 1.0, n), int(rng.integers(1, 4)))
        limit = float(rng.choice(values)) if rng.random() < 0.5 else float(rng.uniform(0.8, 1.0))
        for q, below in ((5, True), (99, False), (50, True), (50, False)):
            if not _percentile_may_pass(values, q, limit, below=below):
                skipped += 1
                p = np.percentile(values, q)
                assert (p >= limit) if below else (p <= limit)
    assert skipped > 1000


@pytest.mark.parametrize("text, policy", [("auto", UpdatePolicy("auto")), ("never", UpdatePolicy("never")),
                                          ("every:5", UpdatePolicy("every", 5)), ("EVERY:1", UpdatePolicy("every", 1))])
def test_policy_parsing(text, policy):
    assert UpdatePolicy.parse(text) == policy
    assert UpdatePolicy.parse(str(policy)) == policy


@pytest.mark.parametrize("text", ["sometimes", "every:0", "every:x", "every", ""])
def test_bad_policy_is_one_line(text):
    with pytest.raises(ValueError, match="--reference-update"):
        UpdatePolicy.parse(text)
