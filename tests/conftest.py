import faulthandler
import signal
import sys
import threading

import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def blurred_noise(shape, seed=0, sigma=2.0):
    """A random texture that is not the simulator: keeps correlation tests independent of it."""
    import cv2
    noise = np.random.default_rng(seed).uniform(0, 255, size=shape).astype(np.float32)
    return cv2.GaussianBlur(noise, (0, 0), sigma)


def pytest_configure(config):
    config.addinivalue_line("markers", "time_limit(seconds): fail the test after this many seconds "
                                       "(with the time_limit fixture; default 60)")


@pytest.fixture
def time_limit(request):
    """Bound one test's duration: soft (SIGALRM -> TimeoutError), then hard (faulthandler exits)."""
    marker = request.node.get_closest_marker("time_limit")
    seconds = float(marker.args[0]) if marker else 60.0
    if not hasattr(signal, "SIGALRM") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(_signum, _frame):
        raise TimeoutError(f"{request.node.name} exceeded its {seconds:g} s time limit")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    faulthandler.dump_traceback_later(seconds + 30, exit=True, file=sys.stderr)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        faulthandler.cancel_dump_traceback_later()


@pytest.fixture(scope="session")
def aravis():
    """``(Aravis, GLib)``; fails with the install command when Aravis is not importable."""
    from livedic.acquire.aravis import load_aravis
    from livedic.acquire.base import SourceError
    try:
        return load_aravis()
    except SourceError as error:
        pytest.fail(f"Aravis is required for the fake-camera tests: {error}", pytrace=False)
