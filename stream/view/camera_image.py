"""The camera image as the view draws it: 8-bit grey, downsampled by an integer factor, and paced.

Pure numpy/OpenCV (no rerun): the session's process prepares the image here before it hands a frame to the
view's process, and ``livedic export`` draws its maps on the same grey.
"""

from __future__ import annotations

import numpy as np

from livedic.acquire.camera.pixel_formats import FRAME_BIT_DEPTH

# A live view draws the camera image at most this often (Hz of the frames' clock): enough to watch, and a
# 100 fps camera's images would cost the process the GIL time the tracker needs; fields go every frame.
IMAGE_MAX_HZ = 25.0
# While results wait for the output thread the view leaves out the camera image (never the fields or the
# numbers), at most this many frames in a row: a view behind still shows the specimen a few times a second.
IMAGE_SKIP_MAX = 4


def display_gray(image: np.ndarray, pixel_format: str = "") -> np.ndarray:
    """A camera image as 8-bit grey for display: the top 8 of its significant bits (a 10- or 12-bit camera's
    uint16 holds 0..1023 or 0..4095; Mono16 and unknown formats 16 bits)."""
    if image.dtype != np.uint8:
        shift = FRAME_BIT_DEPTH.get(pixel_format, 16) - 8
        image = (image >> shift).astype(np.uint8)
    return image


def display_scale(image_shape: tuple[int, ...], max_side: int) -> int:
    """The integer factor the view downsamples a camera image of ``image_shape`` by: its larger side <= max_side."""
    height, width = image_shape[:2]
    scale = 1
    while max(height, width) / scale > max_side:
        scale += 1
    return scale


def display_image(image: np.ndarray, pixel_format: str, scale: int) -> np.ndarray:
    """The camera image as the view draws it: 8-bit grey (``display_gray``), 1/``scale`` of its size."""
    image = display_gray(image, pixel_format)
    if scale > 1:
        import cv2
        h, w = image.shape
        image = cv2.resize(image, (w // scale, h // scale), interpolation=cv2.INTER_AREA)
    return image


class CameraImagePacing:
    """Which frames' camera images the view draws: the costliest part of a frame's view, so a live one is
    paced (every frame's fields, markers and plots are drawn all the same).

    ``image_every``: every this many frames; ``image_max_hz``: at most this many a second of the frames' own
    clock (None: no limit); ``thin_when_behind``: while the view is behind, leave the image out, at most
    ``IMAGE_SKIP_MAX`` frames in a row. ``images_above_rate`` and ``images_left_out`` count what was left out
    by the rate and while behind (the session's summary says both).
    """

    def __init__(self, *, image_every: int = 1, image_max_hz: float | None = None,
                 thin_when_behind: bool = False) -> None:
        self.image_every = max(int(image_every), 1)
        self.image_max_hz = image_max_hz
        self.thin_when_behind = bool(thin_when_behind)
        self._period_ns = int(1e9 / image_max_hz) if image_max_hz else 0
        self._last_image_ns: int | None = None               # the frame time of the last camera image drawn
        self._frames = 0
        self._left_out_in_a_row = 0
        self.images_above_rate = 0
        self.images_left_out = 0

    def due(self, timestamp_ns: int, behind: bool) -> bool:
        """True when this frame's image is drawn (call once per frame, in order)."""
        frame_number, self._frames = self._frames, self._frames + 1
        if self._last_image_ns is not None and timestamp_ns - self._last_image_ns < self._period_ns:
            self.images_above_rate += 1
            return False
        if frame_number % self.image_every:
            return False
        # A view behind the measurement catches up by leaving out the camera image, at most IMAGE_SKIP_MAX
        # frames in a row
        if self.thin_when_behind and behind and self._left_out_in_a_row < IMAGE_SKIP_MAX:
            self._left_out_in_a_row += 1
            self.images_left_out += 1
            return False
        self._left_out_in_a_row = 0
        self._last_image_ns = timestamp_ns
        return True
