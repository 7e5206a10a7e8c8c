"""Images for Aravis's fake cameras: ``SpeckleMotion`` (a speckle pattern translated by a known integer
displacement per frame, a picklable ``image_fn``) and ``FillPattern``, which serves ``image_fn(k)`` to a fake.

How images get in: ``FakeCamera.set_fill_pattern`` through gi segfaults (gi frees
the callback on return), so ``arv_fake_camera_set_fill_pattern`` is called from
``libaravis-0.8.so.0`` through ctypes, with the ``CFUNCTYPE`` object kept
referenced for the camera's whole life (released only after the stream and the
camera are destroyed). The callback copies the image into the buffer Aravis
hands it: the camera's ROI offset crops a larger image like a real sensor; a
smaller image is zero-padded; :func:`served_as` converts it to the pixel format's
bit depth (uint8 x 257 for Mono16, uint16 >> 8 for Mono8) and packed formats are
packed (``acquire.camera.pixel_formats.pack``).
"""

from __future__ import annotations

import ctypes
import logging
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.acquire.camera import pixel_formats
from livedic.acquire.camera.aravis_discovery import load_aravis

__all__ = ["FillPattern", "SpeckleMotion", "served_as"]

log = logging.getLogger("livedic.acquire.camera.fake_motion")


# --------------------------------------------------------------------------- #
# Images with a known motion
# --------------------------------------------------------------------------- #

def _triangle(t, amplitude):
    """Integer triangle wave: 0 at t=0, slope +-1, bounded by +-amplitude."""
    if amplitude <= 0:
        return 0
    return amplitude - abs((t + amplitude) % (4 * amplitude) - 2 * amplitude)


class SpeckleMotion:
    """Frame k is one speckle pattern translated by an integer ``(u_k, v_k)``.

    ``u`` is along x (columns), ``v`` along y (rows); content at ``(x, y)`` in
    frame 0 appears at ``(x + u_k, y + v_k)`` in frame k. Each component follows
    a triangle wave of slope ``step`` px/frame bounded by ``max_displacement``,
    so frames can run forever. Frames are crops of one larger pattern: integer
    shifts are exact and nothing wraps around.

    Parameters
    ----------
    shape : (H, W)
        Image size.
    step : (du, dv)
        Integer displacement per frame along x and y.
    max_displacement : int
        Bound of |u| and |v|.
    bit_depth : {8, 16}
        uint8 or uint16 images.
    seed : int
        Pattern seed (the same seed gives the same images in every process).
    speckle_px : float
        Speckle grain: Gaussian blur sigma of white noise ("blur"), spot radius ("dic").
    pattern : {"blur", "dic"}
        "blur": blurred white noise (fast, self-contained). "dic": rendered by
        ``dic.speckle`` (Gaussian spots, Zhou & Goodson 2001; first use compiles numba kernels).

    Examples
    --------
    >>> motion = SpeckleMotion((64, 80), step=(2, -1), max_displacement=8)
    >>> motion.displacement(3)
    (6, -3)
    >>> a, b = motion(0), motion(3)
    >>> bool((b[10:50, 20:60] == a[13:53, 14:54]).all())
    True
    """

    def __init__(self, shape: tuple[int, int] = (512, 512), *, step: tuple[int, int] = (1, -1),
                 max_displacement: int = 32, bit_depth: int = 8, seed: int = 0, speckle_px: float = 2.0,
                 pattern: str = "blur") -> None:
        height, width = (int(shape[0]), int(shape[1]))
        if height <= 0 or width <= 0:
            raise ValueError(f"shape {shape} must be positive")
        du, dv = (int(step[0]), int(step[1]))
        if (du, dv) != tuple(step):
            raise ValueError(f"step {step} must be integers (exact shifts)")
        if bit_depth not in (8, 16):
            raise ValueError(f"bit_depth {bit_depth} must be 8 or 16")
        if pattern not in ("blur", "dic"):
            raise ValueError(f"pattern {pattern!r} must be 'blur' or 'dic'")
        self.shape = (height, width)
        self.step = (du, dv)
        self.max_displacement = int(max_displacement)
        self.bit_depth = bit_depth
        self.seed = seed
        self.speckle_px = float(speckle_px)
        self.pattern = pattern
        self._canvas: np.ndarray | None = None

    def __getstate__(self) -> dict[str, Any]:  # pickled into the GigE child: send parameters, not pixels
        state = dict(self.__dict__)
        state["_canvas"] = None
        return state

    def __repr__(self) -> str:
        return (f"SpeckleMotion(shape={self.shape}, step={self.step}, max_displacement={self.max_displacement}, "
                f"bit_depth={self.bit_depth}, seed={self.seed})")

    @property
    def dtype(self) -> type[np.unsignedinteger]:
        return np.uint8 if self.bit_depth == 8 else np.uint16

    def displacement(self, k: int) -> tuple[int, int]:
        """Integer ``(u, v)`` of frame k relative to frame 0."""
        m = self.max_displacement
        return (_triangle(k * self.step[0], m), _triangle(k * self.step[1], m))

    def _build(self):
        margin = self.max_displacement
        height, width = self.shape
        size = (height + 2 * margin, width + 2 * margin)
        if self.pattern == "dic":
            from livedic.dic.speckle import SpecklePattern, render
            base = render(SpecklePattern(shape=size, radius=self.speckle_px, seed=self.seed),
                          displacement=(0.0, 0.0), bit_depth=self.bit_depth)
            return np.ascontiguousarray(base, self.dtype)
        import cv2
        rng = np.random.default_rng(self.seed)
        noise = rng.random(size, dtype=np.float32)
        blurred = cv2.GaussianBlur(noise, (0, 0), self.speckle_px)
        low, high = float(blurred.min()), float(blurred.max())
        full = 255 if self.bit_depth == 8 else 65535
        scaled = (blurred - low) / max(high - low, 1e-12) * (0.9 * full) + 0.05 * full
        return np.rint(scaled).astype(self.dtype)

    def __call__(self, k):
        if self._canvas is None:
            self._canvas = self._build()
        u, v = self.displacement(k)
        m = self.max_displacement
        height, width = self.shape
        return self._canvas[m - v:m - v + height, m - u:m - u + width]


# --------------------------------------------------------------------------- #
# The fill-pattern callback (ctypes)
# --------------------------------------------------------------------------- #

_FILL_TYPE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint32, ctypes.c_uint32,
                              ctypes.c_uint32)
_LIB: Any = None        # libaravis through ctypes, once loaded


def _libaravis():
    global _LIB
    if _LIB is None:
        load_aravis()  # the same library gi loaded
        lib = ctypes.CDLL("libaravis-0.8.so.0")
        lib.arv_fake_camera_set_fill_pattern.argtypes = [ctypes.c_void_p, _FILL_TYPE, ctypes.c_void_p]
        lib.arv_fake_camera_set_fill_pattern.restype = None
        lib.arv_buffer_get_data.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)]
        lib.arv_buffer_get_data.restype = ctypes.c_void_p
        lib.arv_buffer_get_timestamp.argtypes = [ctypes.c_void_p]
        lib.arv_buffer_get_timestamp.restype = ctypes.c_uint64
        lib.arv_buffer_set_timestamp.argtypes = [ctypes.c_void_p, ctypes.c_uint64]
        lib.arv_buffer_set_timestamp.restype = None
        for name in ("arv_buffer_get_image_width", "arv_buffer_get_image_height",
                     "arv_buffer_get_image_x", "arv_buffer_get_image_y"):
            getattr(lib, name).argtypes = [ctypes.c_void_p]
            getattr(lib, name).restype = ctypes.c_int
        _LIB = lib
    return _LIB


def set_fake_genicam(path: str | None) -> None:
    """``arv_set_fake_camera_genicam_filename`` (through ctypes: gi refuses None, which restores Aravis's XML)."""
    lib = _libaravis()
    lib.arv_set_fake_camera_genicam_filename.argtypes = [ctypes.c_char_p]
    lib.arv_set_fake_camera_genicam_filename.restype = None
    lib.arv_set_fake_camera_genicam_filename(None if path is None else path.encode())


def _gobject_address(obj):
    """C address of the GObject behind a gi wrapper."""
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype = ctypes.c_void_p
    get.argtypes = [ctypes.py_object, ctypes.c_char_p]
    return get(obj.__gpointer__, None)


class FillPattern:
    """Serves ``image_fn(k)`` into an ``ArvFakeCamera``'s buffers through a ctypes callback.

    ``k`` counts the frames served, or with ``tick_s`` is the number of the clock tick the frame was taken at
    (the frame's timestamp becomes that tick's time): Aravis's fake exposes on the wall clock's multiples of its
    frame period, so fakes with one period show one scene state per tick, as cameras on one trigger line do.
    Keep this object referenced until the camera that uses it is destroyed:
    the C side holds a bare pointer to the callback.
    """

    def __init__(self, image_fn: Callable[[int], Any], *, tick_s: float | None = None) -> None:
        self.image_fn = image_fn
        self.tick_s = tick_s
        self._tick_ns = None if tick_s is None else round(tick_s * 1e9)
        self.frames_served = 0
        self.errors = 0
        self.last_error: str | None = None
        self._callback = _FILL_TYPE(self._fill)

    def install(self, fake_camera: Any) -> None:
        """Attach to a gi ``Aravis.FakeCamera``."""
        _libaravis().arv_fake_camera_set_fill_pattern(_gobject_address(fake_camera), self._callback, None)

    def _stamp_tick(self, buffer: int, tick_ns: int) -> int:
        """The tick this frame was taken at; its timestamp set to the tick's time, as a camera stamps the exposure
        (Aravis stamps the fill, a little after the tick; the system timestamp keeps that arrival time)."""
        lib = _LIB
        tick = lib.arv_buffer_get_timestamp(buffer) // tick_ns      # filled after its tick, within a period
        lib.arv_buffer_set_timestamp(buffer, tick * tick_ns)
        return tick

    def _fill(self, buffer, _data, _exposure_us, _gain, pixel_format) -> None:
        # Runs in an Aravis thread: an exception must not cross into C.
        try:
            lib = _LIB
            k = self.frames_served if self._tick_ns is None else self._stamp_tick(buffer, self._tick_ns)
            self.frames_served += 1
            width = lib.arv_buffer_get_image_width(buffer)
            height = lib.arv_buffer_get_image_height(buffer)
            x0 = lib.arv_buffer_get_image_x(buffer)
            y0 = lib.arv_buffer_get_image_y(buffer)
            fmt = pixel_formats.by_code(pixel_format)
            address = lib.arv_buffer_get_data(buffer, None)  # (its size out-param reads 0 while filling)
            if fmt is None or not address or width <= 0 or height <= 0:
                return
            nbytes = -(-width * height * fmt.bits_per_pixel // 8)
            raw = np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctypes.c_uint8)), (nbytes,))
            image = served_as(np.asarray(self.image_fn(k)), fmt.bit_depth)
            crop = image[y0:y0 + height, x0:x0 + width]
            if crop.shape != (height, width):    # a smaller image is zero-padded
                padded = np.zeros((height, width), image.dtype)
                padded[:crop.shape[0], :crop.shape[1]] = crop
                crop = padded
            if fmt.packed:
                raw[...] = pixel_formats.pack(crop, fmt)
            else:
                np.copyto(raw.view(fmt.dtype).reshape(height, width), crop)
        except BaseException as error:  # noqa: BLE001
            self.errors += 1
            if self.last_error is None:
                log.error("fake camera fill pattern failed: %r", error)
            self.last_error = repr(error)


def served_as(image: npt.ArrayLike, bit_depth: int) -> np.ndarray:
    """``image`` (uint8 or uint16) as a ``bit_depth``-bit camera sends it: uint8 for 8 bits, else uint16.

    8-bit images are stretched to the full range (x 257 for 16 bits: 255 -> 65535), 16-bit ones keep
    their top bits (>> 4 for 12 bits). What the fake cameras serve in each pixel format.
    """
    image = np.asarray(image)
    source_bits = 8 if image.dtype == np.uint8 else 16
    if bit_depth == source_bits:
        values = image
    elif source_bits == 16:
        values = image >> (16 - bit_depth)
    else:
        values = image.astype(np.uint32) * ((1 << bit_depth) - 1) // 255
    return values.astype(np.uint8 if bit_depth <= 8 else np.uint16)
