"""Fixtures for the acquisition tests: time limits, Aravis, fake cameras, displacement checks.

The Aravis fake cameras are not hardware: tests using them always run and
FAIL (not skip) when Aravis is missing, with the command that installs it.
Only tests marked ``camera`` (a physical camera) are skipped unless
``LIVEDIC_CAMERA`` names one.
"""

import faulthandler
import os
import signal
import sys
import threading

import numpy as np
import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "time_limit(seconds): fail the test after this many seconds "
                                       "(tests/acquire, default 60)")


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
    from acquire.aravis import load_aravis
    from acquire.base import SourceError
    try:
        return load_aravis()
    except SourceError as error:
        pytest.fail(f"Aravis is required for the fake-camera tests: {error}", pytrace=False)


def integer_displacements(reference, image, points, radius):
    """Integer (u, v) per point between two images: dic.measure (exhaustive ZNCC), else dic.correlation.zncc.

    Returns arrays ``u, v`` (content at (x, y) in ``reference`` is at (x+u, y+v) in ``image``).
    """
    points = np.asarray(points, np.float64)
    try:
        from dic import measure
    except ImportError:
        measure = None
    if measure is not None:
        result = measure(reference, image, points, subset=21, search="exhaustive", subpixel="none", radius=radius)
        assert bool(np.all(result.ok)), f"dic.measure flagged points: {result.status}"
        return np.asarray(result.u), np.asarray(result.v)
    from dic.correlation import zncc
    shifts = [(u, v) for v in range(-radius, radius + 1) for u in range(-radius, radius + 1)]
    best_u, best_v = np.zeros(len(points)), np.zeros(len(points))
    best = np.full(len(points), -np.inf)
    for u, v in shifts:
        scores = np.asarray(zncc(reference, image, points, np.tile([u, v], (len(points), 1)), subset=21))
        scores = scores[0] if isinstance(scores, tuple) else scores
        better = scores > best
        best[better], best_u[better], best_v[better] = scores[better], u, v
    return best_u, best_v


def grid(shape, step=48, margin=40):
    height, width = shape
    return [(x, y) for y in range(margin, height - margin + 1, step) for x in range(margin, width - margin + 1, step)]


@pytest.fixture(scope="session")
def physical_camera_id():
    """The device id in LIVEDIC_CAMERA (empty: first camera); tests marked ``camera`` skip without it."""
    value = os.environ.get("LIVEDIC_CAMERA")
    if value is None:
        pytest.skip("no physical camera: set LIVEDIC_CAMERA=<device id> (or '' for the first one)")
    return value


@pytest.fixture(scope="session")
def measure_integer():
    """The ``integer_displacements(reference, image, points, radius)`` helper."""
    return integer_displacements


@pytest.fixture(scope="session")
def grid_points():
    """The ``grid(shape, step=48, margin=40)`` helper: (x, y) points inside an image."""
    return grid
