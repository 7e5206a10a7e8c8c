"""Fixtures for the acquisition tests: physical camera, Aravis's GigE simulator, displacement checks (time limits and
Aravis are in tests/conftest.py).

The Aravis fake cameras are not hardware: tests using them always run and
FAIL (not skip) when Aravis is missing, with the command that installs it.
Only tests marked ``camera`` (a physical camera) are skipped unless
``LIVEDIC_CAMERA`` names one.
"""

import os

import numpy as np
import pytest


def integer_displacements(reference, image, points, radius):
    """Integer (u, v) per point between two images: dic.measure (exhaustive ZNCC), else dic.correlation.zncc.

    Returns arrays ``u, v`` (content at (x, y) in ``reference`` is at (x+u, y+v) in ``image``).
    """
    points = np.asarray(points, np.float64)
    try:
        from livedic.dic import measure
    except ImportError:
        measure = None
    if measure is not None:
        result = measure(reference, image, points, subset=21, search="exhaustive", subpixel="none", radius=radius)
        assert bool(np.all(result.ok)), f"dic.measure flagged points: {result.status}"
        return np.asarray(result.u), np.asarray(result.v)
    from livedic.dic.correlation import zncc
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
    """The ``integer_displacements(reference, image, points, radius)`` helper, its kernels compiled.

    Compiled here, once, on a known shift of 8- and 16-bit noise: a session-scoped fixture runs before a test's
    ``time_limit`` starts, so a fresh installation's numba compilation (a minute on a cold CI machine) is not
    charged to the first camera test that measures.
    """
    rng = np.random.default_rng(0)
    for dtype, top in ((np.uint8, 255), (np.uint16, 65535)):
        reference = rng.integers(0, top, (128, 160)).astype(dtype)
        image = np.roll(reference, (2, 1), axis=(0, 1))
        u, v = integer_displacements(reference, image, grid(reference.shape, step=24, margin=30), 4)
        assert np.all(u == 1) and np.all(v == 2)
    return integer_displacements


@pytest.fixture(scope="session")
def grid_points():
    """The ``grid(shape, step=48, margin=40)`` helper: (x, y) points inside an image."""
    return grid


@pytest.fixture(scope="session")
def extended_xml(aravis, tmp_path_factory):
    """A file with ``extended_genicam_xml()``: Aravis's fake camera plus 10/12-bit formats, user sets, Line1."""
    from livedic.acquire.camera.fake_genicam import extended_genicam_xml
    path = tmp_path_factory.mktemp("genicam") / "livedic-fake-camera.xml"
    path.write_text(extended_genicam_xml())
    return str(path)


@pytest.fixture(scope="module")
def arv_fake_gv(aravis):
    """Aravis's own GigE Vision simulator, ``arv-fake-gv-camera-0.8 -i 127.0.0.1``, for one test module.

    Started once per module (GVCP's port 3956 is fixed: one simulator per address on this machine),
    ready when GigE discovery finds it, stopped at the end of the module. Skipped only when the
    program is not installed (``scripts/install_system.sh`` installs it).
    """
    import shutil

    from livedic.acquire.camera.fake_gige import ARV_FAKE_GV_CAMERA, ArvFakeGvCamera
    if shutil.which(ARV_FAKE_GV_CAMERA) is None:
        pytest.skip(f"{ARV_FAKE_GV_CAMERA} is not installed (Debian package aravis-tools: "
                    "run scripts/install_system.sh)")
    with ArvFakeGvCamera() as camera:
        yield camera
