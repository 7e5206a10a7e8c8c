"""stream.pipeline.frame_queue: what tests/stream/pipeline/test_acquisition.py leaves out (depth, bounded drop log, block policy
without loss, closing twice, odd sizes). Events and joins, no sleeps."""

import threading

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.stream.pipeline.frame_queue import BLOCK, DROP_NEWEST, DROP_OLDEST, FrameQueue, QueueClosed


def _frame(i):
    return Frame(i, i * 1_000_000, np.zeros((2, 2), np.uint8), "Mono8")


@pytest.mark.parametrize("policy", [DROP_OLDEST, DROP_NEWEST])
def test_the_queue_never_holds_more_than_its_size_and_reports_its_deepest(policy):
    queue = FrameQueue(3, policy)
    depths = []
    for i in range(20):
        queue.put(_frame(i))
        depths.append(len(queue))
        if i % 5 == 4:
            queue.get()
    assert max(depths) == 3 and queue.max_depth == 3
    assert queue.put_count == 20 and queue.put_count == queue.dropped + len(queue) + 4      # 4 taken


def test_every_drop_is_counted_but_only_the_latest_indices_are_kept():
    queue = FrameQueue(1, DROP_OLDEST)
    queue.put(_frame(0))
    assert queue.get().index == 0                          # the reference taken: every later put evicts
    for i in range(1, 1502):
        queue.put(_frame(i))
    assert queue.dropped == 1500
    assert len(queue.dropped_indices) == 1000 and list(queue.dropped_indices) == list(range(501, 1501))
    assert queue.get().index == 1501


def test_items_without_a_frame_index_are_dropped_and_logged_as_none():
    queue = FrameQueue(1, DROP_NEWEST)
    reference, late = object(), object()
    queue.put(reference)
    assert queue.put(late) is late                         # drop-newest: the incoming item is the one returned
    assert queue.dropped == 1 and list(queue.dropped_indices) == [None]


def test_block_policy_loses_nothing_and_keeps_the_order():
    queue = FrameQueue(2, BLOCK)
    received, finished = [], threading.Event()

    def consume():
        while True:
            try:
                item = queue.get(timeout=10.0)
            except QueueClosed:
                finished.set()
                return
            if item is not None:
                received.append(item.index)

    consumer = threading.Thread(target=consume, daemon=True)
    consumer.start()
    for i in range(300):
        assert queue.put(_frame(i)) is None               # a blocking put never returns a victim
    queue.close()
    assert finished.wait(30), "the consumer never saw the queue closed"     # a liveness limit, not a timing
    assert received == list(range(300))
    assert queue.dropped == 0 and queue.max_depth <= 2


def test_close_is_idempotent_and_drains_in_order_before_raising():
    queue = FrameQueue(4, DROP_OLDEST)
    for i in range(3):
        queue.put(_frame(i))
    queue.close()
    queue.close()
    assert queue.closed and len(queue) == 3
    assert [queue.get().index for _ in range(3)] == [0, 1, 2]
    with pytest.raises(QueueClosed):
        queue.get(timeout=0)
    with pytest.raises(QueueClosed):
        queue.put(_frame(3))
    assert queue.put_count == 3


@pytest.mark.parametrize("size", [True, 2.0, "4", -1])
def test_a_size_that_is_not_a_positive_integer_is_refused(size):
    with pytest.raises(ValueError, match="positive integer"):
        FrameQueue(size)
