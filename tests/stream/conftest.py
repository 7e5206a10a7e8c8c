"""Fixtures and helpers shared by the stream tests."""

import os
import subprocess
import sys
import threading

import numpy as np
import pytest

from tests.conftest import specimen_scene


@pytest.fixture
def unwritable_folder(tmp_path, monkeypatch):
    """``unwritable_folder(variant)``: a folder where no file can be created (see ``_make``)."""
    return lambda variant: _make(tmp_path, variant, monkeypatch)


def _make(tmp_path, variant, monkeypatch):
    """A folder where no file can be created: read-only (0555; root ignores permission bits, so skipped for
    root), permission denied as the system says it (simulated where it matters, in the only call that
    creates files, so it runs as root too), or a path 'under' a regular file (fails for root too)."""
    if variant == "read-only":
        if os.geteuid() == 0:
            pytest.skip("root ignores permission bits; the denied and under-a-file variants cover root")
        folder = tmp_path / "read-only"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    if variant == "denied":
        import tempfile

        import livedic.stream.output.files as csv_output
        folder = tmp_path / "denied"
        folder.mkdir()
        real = tempfile.mkstemp

        def mkstemp(*args, dir=None, **kwargs):
            if dir is not None and os.path.abspath(dir) == str(folder):
                raise PermissionError(13, "Permission denied", str(folder))
            return real(*args, dir=dir, **kwargs)

        monkeypatch.setattr(csv_output.tempfile, "mkstemp", mkstemp)
        return folder
    blocker = tmp_path / "file.txt"
    blocker.write_text("a file, not a folder\n")
    return blocker


@pytest.fixture
def signal_when():
    """``signal_when(process, ready, signum)``: see ``_signal_when``."""
    return _signal_when


def _signal_when(process, ready, signum, *, timeout_s=120):
    """Read ``process``'s stderr until ``ready(stderr bytes so far)``, send it ``signum``, wait for it to end.

    Returns ``(stderr text, stdout bytes)``; kills the child if it does not end.
    """
    err = bytearray()
    reached = threading.Event()

    def read_stderr():
        while True:
            chunk = process.stderr.read1(256)
            if not chunk:
                return
            err.extend(chunk)
            if ready(bytes(err)):
                reached.set()

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        assert reached.wait(timeout_s), bytes(err).decode(errors="replace")
        process.send_signal(signum)
        out = process.stdout.read()
        process.wait(60)
        reader.join(10)
    finally:
        if process.poll() is None:
            process.kill()
    return bytes(err).decode(errors="replace"), out


def refused_run(tmp_path, extra, *, source="synthetic:tensile?size=192x256&frames=3&fps=1000"):
    """``livedic run ... extra`` in a subprocess, which must refuse: exit 2, exactly one ``livedic: error``
    line (returned), no traceback, and no recording left at the ``--record`` path it was given."""
    record = tmp_path / "refused.mcap"
    argv = ["run", "--viewer", "none", "--record", str(record), "--progress", "off", "--source", source, *extra]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          timeout=120)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert done.returncode == 2, done.stderr
    assert len(errors) == 1 and "Traceback" not in done.stderr, done.stderr
    assert not record.exists()
    return errors[0]


# An open-hole specimen: P0's choice (stream/session/p0.py) and a run on it (tests/stream/cli).
HOLE_CENTRE, HOLE_RADIUS = (120, 100), 34


def holed_image(shift=(0.0, 0.0), seed=4):
    """A 200x240 speckle image with a dark, flat hole over its centre (an open-hole specimen)."""
    from livedic.dic.speckle import SpecklePattern, render
    pattern = SpecklePattern((200, 240), n_speckles=900, radius=3.0, seed=seed)
    image = render(pattern, shift if any(shift) else None, bit_depth=8, noise_sigma=1.0,
                   noise_seed=int(100 * shift[0]) + 7)
    yy, xx = np.mgrid[:200, :240]
    cx, cy = HOLE_CENTRE[0] + shift[0], HOLE_CENTRE[1] + shift[1]
    hole = (xx - cx) ** 2 + (yy - cy) ** 2 <= HOLE_RADIUS ** 2
    image[hole] = np.clip(12 + np.random.default_rng(seed).normal(0, 1, hole.sum()), 0, 255).astype(np.uint8)
    return image


# A strip specimen with a hole: livedic preview's set-up (tests/stream/cli, tests/stream/session).
STRIP_HOLE = (150, 200, 20)     # x, y, r of the hole in ``strip_images``


@pytest.fixture(scope="module")
def strip_images(tmp_path_factory):
    """A folder of two images (f0.png, f1.png) of a strip specimen with a hole at ``STRIP_HOLE``, stretched 0.2 %
    between them (``tests.conftest.specimen_scene``): an ``images:`` source for the set-up tests."""
    import cv2
    folder = tmp_path_factory.mktemp("holed")
    for k in range(2):
        image, _ = specimen_scene(seed=3, hole=STRIP_HOLE, strain=0.002 * k)
        cv2.imwrite(str(folder / f"f{k}.png"), image)
    return folder
