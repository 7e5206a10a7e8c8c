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


def specimen_scene(shape=(400, 300), noise=2.0, seed=0, hole=None, gain=1.0, strain=0.0, poisson=0.4):
    """A strip of blurred-noise texture (not the simulator's speckle) on a smooth, unevenly lit, noisy background.

    The strip (columns 100..199 of the reference, a hole ``(x, y, r)`` in it) is stretched along y by
    ``strain`` about row 0 and narrows by ``poisson * strain`` about its axis, as a tensile specimen between
    a fixed top grip and a moving bottom one; the background stays still. Returns the image (uint8, or
    uint16 scaled by ``gain``) and the exact specimen mask of that image.
    """
    import cv2
    rng = np.random.default_rng(seed + 1000 * int(round(1e4 * strain)))
    height, width = shape
    texture = blurred_noise(shape, seed=seed, sigma=1.5)
    texture = 40 + (texture - texture.min()) / np.ptp(texture) * 180
    rows, cols = np.indices(shape, dtype=np.float32)
    # where each pixel of this image comes from in the reference (the inverse of the stretch)
    axis = 149.5
    source_rows = rows / (1.0 + strain)
    source_cols = axis + (cols - axis) / (1.0 - poisson * strain)
    warped = cv2.remap(texture.astype(np.float32), source_cols, source_rows, cv2.INTER_CUBIC,
                       borderMode=cv2.BORDER_REFLECT)
    specimen = (source_cols >= 99.5) & (source_cols < 199.5)
    in_hole = np.zeros(shape, dtype=bool)
    if hole is not None:
        x, y, r = hole
        in_hole = (source_cols - x) ** 2 + (source_rows - y) ** 2 <= r * r
        specimen &= ~in_hole
    background = 120 + 30 * np.sin(rows / 90.0) + 0.1 * cols
    image = np.where(specimen, warped, np.where(in_hole, 15.0, background))
    image = image + rng.normal(0, noise, shape)
    image = np.clip(np.round(image * gain), 0, 255 * gain)
    return image.astype(np.uint8 if gain == 1.0 else np.uint16), specimen


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
    from livedic.acquire.camera.aravis_discovery import load_aravis
    from livedic.acquire.base import SourceError
    try:
        return load_aravis()
    except SourceError as error:
        pytest.fail(f"Aravis is required for the fake-camera tests: {error}", pytrace=False)
