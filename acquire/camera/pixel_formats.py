"""The GenICam grey pixel formats livedic reads, and the unpacking of the packed ones.

A camera sends one of ``FORMATS`` (its GenICam name and PFNC code); livedic
hands the tracker a 2-D ``uint8`` (Mono8) or ``uint16`` image whose values are
the camera's grey levels, least significant bit first: a 12-bit camera gives
values in [0, 4095] whatever its packing. ``Frame.pixel_format`` names that
unpacked layout (``frame_format``: Mono8, Mono10, Mono12 or Mono16) and
``bit_depth`` says how many bits are significant.

Packings (2 or 4 pixels per group of 3 or 5 bytes, no padding between groups):

* ``"lsb"``: PFNC's ``Mono10p`` and ``Mono12p`` (USB3 Vision, GigE Vision 2.x):
  one little-endian bit stream, pixel 0 in the lowest bits of byte 0.
* ``"gige"``: GigE Vision's ``Mono10Packed`` and ``Mono12Packed``: byte 0 holds
  pixel 0's high 8 bits, byte 2 pixel 1's, byte 1 their low bits (pixel 0's in
  its low nibble, pixel 1's in its high one).

A packed image is one bit stream over the whole frame (PFNC lines are not
padded to a byte); when the camera pads each line (``row_stride``), each line is
unpacked on its own. ``unpack`` and its inverse ``pack`` are vectorised numpy: a
2048x2048 frame takes 6-9 ms (Mono12p, Mono12Packed) or 14-17 ms (Mono10p) on one
core of the (shared, 2-core) development machine, within a 25 fps frame period.

Examples
--------
>>> import numpy as np
>>> raw = np.array([0xBC, 0x3A, 0x12], np.uint8)     # Mono12p: pixels 0xABC, 0x123
>>> unpack(raw, FORMATS["Mono12p"], 2, 1).tolist()
[[2748, 291]]
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["PixelFormat", "FORMATS", "by_code", "by_name", "unpack", "pack", "FRAME_BIT_DEPTH"]

_PACKINGS = ("none", "lsb", "gige")


@dataclass(frozen=True)
class PixelFormat:
    """One grey pixel format.

    name : str           GenICam name, e.g. "Mono12p"
    code : int           PFNC / GigE Vision code sent in every image leader
    bit_depth : int      significant bits per pixel
    packing : str        "none" (8- or 16-bit containers), "lsb" (PFNC p) or "gige" (GigE ...Packed)
    """
    name: str
    code: int
    bit_depth: int
    packing: str = "none"

    def __post_init__(self):
        if self.packing not in _PACKINGS:
            raise ValueError(f"packing {self.packing!r} is not one of {_PACKINGS}")

    @property
    def packed(self) -> bool:
        return self.packing != "none"

    @property
    def dtype(self) -> np.dtype:
        """The unpacked image's dtype: uint8 for 8 bits, else uint16."""
        return np.dtype(np.uint8 if self.bit_depth <= 8 else np.uint16)

    @property
    def frame_format(self) -> str:
        """``Frame.pixel_format`` of the unpacked image ("Mono12" for Mono12p and Mono12Packed)."""
        return f"Mono{self.bit_depth}"

    @property
    def bits_per_pixel(self) -> int:
        """Bits each pixel takes on the wire: 16 for unpacked 10/12-bit, 12 for Mono10Packed (PFNC code bits 16-23)."""
        return (self.code >> 16) & 0xFF

    def line_bytes(self, width: int) -> int:
        """Bytes of one image line without padding (rounded up to a whole byte)."""
        return -(-width * self.bits_per_pixel // 8)


FORMATS = {f.name: f for f in (
    PixelFormat("Mono8", 0x01080001, 8),
    PixelFormat("Mono10", 0x01100003, 10),
    PixelFormat("Mono12", 0x01100005, 12),
    PixelFormat("Mono16", 0x01100007, 16),
    PixelFormat("Mono10p", 0x010A0046, 10, "lsb"),
    PixelFormat("Mono12p", 0x010C0047, 12, "lsb"),
    PixelFormat("Mono10Packed", 0x010C0004, 10, "gige"),
    PixelFormat("Mono12Packed", 0x010C0006, 12, "gige"),
)}
_BY_CODE = {f.code: f for f in FORMATS.values()}

# Significant bits of each Frame.pixel_format (the unpacked layouts).
FRAME_BIT_DEPTH = {f.frame_format: f.bit_depth for f in FORMATS.values()}


def by_code(code: int) -> PixelFormat | None:
    """The format with this PFNC code, or None when livedic does not read it."""
    return _BY_CODE.get(int(code))


def by_name(name: str) -> PixelFormat | None:
    """The format with this GenICam name (case-insensitive), or None."""
    text = str(name).strip().lower()
    return next((f for f in FORMATS.values() if f.name.lower() == text), None)


# (pixels, bytes) per group of each packing and bit depth
_GROUPS = {("lsb", 10): (4, 5), ("lsb", 12): (2, 3), ("gige", 10): (2, 3), ("gige", 12): (2, 3)}


def _groups(fmt):
    try:
        return _GROUPS[(fmt.packing, fmt.bit_depth)]
    except KeyError:
        raise ValueError(f"{fmt.name} is not a packed format livedic unpacks") from None


def _unpack_stream(data, fmt, count):
    """``count`` pixels (uint16, 1-D) from one packed bit stream ``data`` (uint8, 1-D)."""
    pixels, nbytes = _groups(fmt)
    n_groups = -(-count // pixels)
    need = n_groups * nbytes
    if data.size < need:     # the last group may be partial on the wire
        data = np.concatenate([data, np.zeros(need - data.size, np.uint8)])
    b = data[:need].reshape(n_groups, nbytes).astype(np.uint16)
    out = np.empty((n_groups, pixels), np.uint16)
    if fmt.packing == "lsb" and fmt.bit_depth == 12:
        out[:, 0] = b[:, 0] | (b[:, 1] & 0x0F) << 8
        out[:, 1] = b[:, 1] >> 4 | b[:, 2] << 4
    elif fmt.packing == "lsb":   # Mono10p: 4 pixels in 5 bytes
        out[:, 0] = b[:, 0] | (b[:, 1] & 0x03) << 8
        out[:, 1] = b[:, 1] >> 2 | (b[:, 2] & 0x0F) << 6
        out[:, 2] = b[:, 2] >> 4 | (b[:, 3] & 0x3F) << 4
        out[:, 3] = b[:, 3] >> 6 | b[:, 4] << 2
    else:                        # GigE ...Packed: high bits in bytes 0 and 2, low bits shared in byte 1
        low = fmt.bit_depth - 8
        mask = (1 << low) - 1
        out[:, 0] = b[:, 0] << low | (b[:, 1] & mask)
        out[:, 1] = b[:, 2] << low | (b[:, 1] >> 4 & mask)
    return out.reshape(-1)[:count]


def unpack(data: np.ndarray | bytes | memoryview, fmt: PixelFormat, width: int, height: int,
           row_stride: int | None = None) -> np.ndarray:
    """A packed image as a new ``uint16`` array of shape (height, width), values LSB-aligned.

    Parameters
    ----------
    data : ndarray of uint8, 1-D (or any buffer)
        The image bytes as the camera sent them.
    fmt : PixelFormat
        A packed format (``fmt.packed``).
    width, height : int
        Image size in pixels.
    row_stride : int, optional
        Bytes from one line to the next when the camera pads its lines; None (or the unpadded
        line length): the whole image is one bit stream.

    Raises
    ------
    ValueError
        ``data`` holds fewer bytes than the image needs, or ``fmt`` is not packed.
    """
    data = np.frombuffer(data, np.uint8) if not isinstance(data, np.ndarray) else data.reshape(-1)
    _groups(fmt)
    line = fmt.line_bytes(width)
    stride = line if row_stride is None else row_stride
    padded = stride != line
    need = (height - 1) * stride + line if padded else -(-width * height * fmt.bits_per_pixel // 8)
    if data.size < need:
        raise ValueError(f"a {width}x{height} {fmt.name} image needs {need} bytes, got {data.size}")
    if not padded:
        return _unpack_stream(data, fmt, width * height).reshape(height, width)
    rows = np.lib.stride_tricks.as_strided(data, (height, line), (stride, 1))
    return np.stack([_unpack_stream(row, fmt, width) for row in rows])


def pack(image: np.ndarray, fmt: PixelFormat) -> np.ndarray:
    """The bytes a camera sends for ``image`` (2-D, values below ``2**fmt.bit_depth``) in a packed format.

    The inverse of ``unpack`` (one bit stream over the frame); the fake cameras use it to serve packed
    formats. Returns a 1-D ``uint8`` array.
    """
    pixels, nbytes = _groups(fmt)
    flat = np.asarray(image, np.uint16).reshape(-1)
    if flat.size and int(flat.max()) >> fmt.bit_depth:
        raise ValueError(f"{fmt.name} holds {fmt.bit_depth}-bit values; the image goes up to {int(flat.max())}")
    count = flat.size
    n_groups = -(-count // pixels)
    p = np.zeros(n_groups * pixels, np.uint16)
    p[:count] = flat
    p = p.reshape(n_groups, pixels)
    out = np.empty((n_groups, nbytes), np.uint16)
    if fmt.packing == "lsb" and fmt.bit_depth == 12:
        out[:, 0] = p[:, 0] & 0xFF
        out[:, 1] = p[:, 0] >> 8 | (p[:, 1] & 0x0F) << 4
        out[:, 2] = p[:, 1] >> 4
    elif fmt.packing == "lsb":
        out[:, 0] = p[:, 0] & 0xFF
        out[:, 1] = p[:, 0] >> 8 | (p[:, 1] & 0x3F) << 2
        out[:, 2] = p[:, 1] >> 6 | (p[:, 2] & 0x0F) << 4
        out[:, 3] = p[:, 2] >> 4 | (p[:, 3] & 0x03) << 6
        out[:, 4] = p[:, 3] >> 2
    else:
        low = fmt.bit_depth - 8
        mask = (1 << low) - 1
        out[:, 0] = p[:, 0] >> low
        out[:, 1] = (p[:, 0] & mask) | (p[:, 1] & mask) << 4
        out[:, 2] = p[:, 1] >> low
    size = -(-count * fmt.bits_per_pixel // 8)
    return (out & 0xFF).astype(np.uint8).reshape(-1)[:size]
