"""Waiting in tests for a condition, never for a time.

A test that needs another thread or process to get somewhere waits here on what it can observe (a counter,
a file, a line printed) until it holds; the limit only guards against a hang and is generous, because a
loaded machine is slow, not wrong. The one place the tests poll (``time.sleep`` stays out of the tests
themselves, which wait on events where the code offers one).
"""

import time

POLL_S = 0.005


def wait_until(predicate, timeout_s=30.0, what="the condition"):
    """Return once ``predicate()`` is true; fail the test naming ``what`` after ``timeout_s`` seconds."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() >= deadline:
            raise AssertionError(f"{what} not met within {timeout_s:g} s")
        time.sleep(POLL_S)
