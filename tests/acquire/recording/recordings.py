"""Small recordings and error checks shared by the recording tests (helpers, not tests)."""

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.acquire.recording.errors import RecordingError
from livedic.acquire.recording.writer import Recorder

T0 = 1_700_000_000_000_000_000


def record(path, n=6, shape=(16, 24), dtype=np.uint8, dt_ns=20_000_000, chunk_bytes=1 << 20, compression=None,
           with_strain=False):
    """Write a small livedic recording at ``path``: ``n`` random frames, two points' results each, an event;
    returns the images."""
    rng = np.random.default_rng(7)
    if with_strain:                      # dic.strain's kernels load only for the recordings that need them
        from livedic.dic.strain.extensometer import ExtensometerReadings
        from livedic.dic.strain import strain_field, strain_window
        windows = strain_window(np.array([[x, y] for y in range(3) for x in range(3)], float), window=3, step=1.0)
    images = [rng.integers(0, 200, size=shape, dtype=dtype) for _ in range(n)]
    with Recorder(path, {"source_uri": "synthetic://", "points": [[1, 2]]}, chunk_bytes=chunk_bytes,
                  compression=compression) as rec:
        for i, image in enumerate(images):
            rec.write_frame(Frame(i, T0 + i * dt_ns, image, "Mono8" if dtype == np.uint8 else "Mono16"))
            rec.write_results(i, T0 + i * dt_ns, [1, 2], [3.0, 4.0], [5.0, 6.0], [0.1 * i, 0.0], [0.0, -0.1 * i],
                              [0.99, 0.5], [True, False])
            if with_strain:
                rec.write_strain(i, T0 + i * dt_ns, strain_field(windows, np.full(9, 0.1 * i), np.zeros(9),
                                                                 np.ones(9, bool)))
                rec.write_extensometers(i, T0 + i * dt_ns, ExtensometerReadings(
                    ("axial", "side"), np.array([10.0, 5.0]), np.array([10.0 + i, np.nan]), np.array([0.1 * i, np.nan]),
                    np.array([np.log1p(0.1 * i), np.nan]), np.array([0, 1], np.int32)))
        rec.write_event("recording_stopped", "end of test")
    return images


def one_line_error(call, error_type=RecordingError):
    """The message of the ``error_type`` that ``call()`` raises, checked to be one non-empty line."""
    with pytest.raises(error_type) as caught:
        call()
    message = str(caught.value)
    assert "\n" not in message and message
    return message
