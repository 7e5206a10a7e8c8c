"""Read one 8- or 16-bit grey image file (PNG, TIFF, anything OpenCV decodes) with clear errors.

Shared by the ``images:`` source and the ``livedic measure`` command.
``read_image_header`` gives a file's size (and the bit depth of a grey file) from
its header alone, through Pillow, which reads only the first bytes (OpenCV cannot:
it decodes the whole image), so a sequence of a thousand files is checked in a
fraction of a second before the session starts. DIC needs
the camera's grey levels untouched, so nothing is rescaled: 8-bit files give
``uint8`` arrays, 16-bit files ``uint16``. Colour files are converted to grey
(with a note for the caller to show once); a colour file whose channels are all equal (a
palette TIFF or PNG of grey entries) is a grey image and needs no note. Everything else — a missing,
empty, truncated or corrupt file, float, 32-bit or signed pixels — raises
``ValueError`` whose message is one line naming the file and the problem.

OpenCV (``cv2.imdecode`` with ``IMREAD_UNCHANGED``) returns ``None`` rather than
raising for files it cannot decode, including truncated PNG and TIFF files
(checked with OpenCV 5.0: PNG stops with "input buffer is incomplete", TIFF
with a directory/strip read error); the cause is then worked out here from
the file's signature so the message says *truncated or corrupt PNG* rather
than *unreadable*.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

__all__ = ["read_grey_image", "read_image_header", "ImageHeader", "SIGNATURES"]

# File signatures, used to name the format in error messages.
SIGNATURES = (
    (b"\x89PNG\r\n\x1a\n", "PNG"),
    (b"II*\x00", "TIFF"),
    (b"MM\x00*", "TIFF"),
    (b"II+\x00", "BigTIFF"),
    (b"MM\x00+", "BigTIFF"),
    (b"\xff\xd8\xff", "JPEG"),
    (b"BM", "BMP"),
)

_SAVE_AS = "save as 8- or 16-bit grey"

# Pillow modes whose header fixes the bit depth livedic reads them at (palette and bilevel files decode
# to 8 bits). Colour modes do not: Pillow opens a 16-bit RGB PNG as "RGB", which OpenCV reads as 16-bit.
_HEADER_BITS = {"1": 8, "L": 8, "P": 8, "LA": 8, "PA": 8, "I;16": 16, "I;16B": 16, "I;16L": 16, "I;16N": 16}


def _format_of(data: bytes) -> str | None:
    for signature, name in SIGNATURES:
        if data.startswith(signature):
            return name
    return None


def _fail(path: str, problem: str) -> NoReturn:
    raise ValueError(f"{path}: {problem}")


def _channels_equal(image: np.ndarray) -> bool:
    """True when every channel of ``image`` (H, W, C) equals the first: grey stored as colour."""
    first = image[:, :, 0]
    return all(np.array_equal(first, image[:, :, k]) for k in range(1, image.shape[2]))


def _decode(data: bytes) -> np.ndarray | str | None:
    """``cv2.imdecode(..., IMREAD_UNCHANGED)`` with OpenCV's own stderr warnings silenced."""
    import cv2

    logging = getattr(getattr(cv2, "utils", None), "logging", None)
    previous = None
    if logging is not None:
        try:
            previous = logging.getLogLevel()
            logging.setLogLevel(logging.LOG_LEVEL_SILENT)
        except Exception:  # noqa: BLE001 - logging control is cosmetic
            logging = None
    try:
        return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error as error:  # some decoders raise instead of returning None
        return str(error).strip().splitlines()[-1] if str(error).strip() else "decoder error"
    finally:
        if logging is not None and previous is not None:
            logging.setLogLevel(previous)


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header says (``read_image_header``).

    width, height : int   pixels
    bits : int or None    8 or 16 for a grey file; None where only decoding tells (colour files)
    """
    width: int
    height: int
    bits: int | None = None


def read_image_header(path: str | os.PathLike[str]) -> ImageHeader:
    """The size (and, for a grey file, the bit depth) of an image file, from its header.

    Pillow reads the header only (about 0.2 ms a file); a file Pillow cannot
    identify is decoded by ``read_grey_image`` instead, whose error then names
    the problem.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    ImageHeader

    Raises
    ------
    ValueError
        One line ``"<path>: <problem>"`` for a file that is no readable image (see ``read_grey_image``).
    """
    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)   # a big camera frame is no bomb
            with Image.open(path) as image:
                return ImageHeader(image.width, image.height, _HEADER_BITS.get(image.mode))
    except Exception:  # noqa: BLE001 - not for Pillow (or too big for its guard): OpenCV decides, and says why
        pass
    pixels, _ = read_grey_image(path)
    return ImageHeader(pixels.shape[1], pixels.shape[0], pixels.dtype.itemsize * 8)


def read_grey_image(path: str | os.PathLike[str]) -> tuple[np.ndarray, str | None]:

    """Read an 8- or 16-bit grey image file.

    Parameters
    ----------
    path : str or os.PathLike
        PNG or TIFF file (any format OpenCV decodes is accepted).

    Returns
    -------
    image : ndarray, shape (H, W), uint8 or uint16
        The grey levels as stored in the file (no rescaling).
    note : str or None
        A one-line note when the file needed converting (colour to grey,
        alpha dropped), for the caller to show once; ``None`` otherwise.

    Raises
    ------
    ValueError
        One line ``"<path>: <problem>"``: the file is missing, a directory,
        unreadable, empty, truncated or corrupt, not an image, or holds float,
        32-bit or signed pixels.

    Examples
    --------
    >>> import cv2, numpy as np, tempfile, os
    >>> name = os.path.join(tempfile.mkdtemp(), "a.png")
    >>> _ = cv2.imwrite(name, np.full((4, 5), 7, np.uint16))
    >>> image, note = read_grey_image(name)
    >>> image.dtype, image.shape, note
    (dtype('uint16'), (4, 5), None)
    """
    name = os.fspath(path)
    data = _read_file(name)
    image = _decoded(name, data)
    image, note = _as_grey(name, image)
    _check_pixels(name, image)
    return np.ascontiguousarray(image), note


def read_same_size_images(paths: list[str], what: str = "images") -> tuple[list[np.ndarray], list[str]]:
    """Every image of ``paths`` read (``read_grey_image``) and checked against the first one's size, before any
    work is done on them; returns the images and the notes of those that needed converting.

    Raises
    ------
    ValueError
        One line: a file ``read_grey_image`` refuses, or an image of another size than the first
        ("... : ``what`` must have the same size").
    """
    images: list[np.ndarray] = []
    notes: list[str] = []
    for path in paths:
        image, note = read_grey_image(path)
        if note:
            notes.append(note)
        if images and image.shape != images[0].shape:
            raise ValueError(f"{path} is {image.shape[1]}x{image.shape[0]} but the reference {paths[0]} is "
                             f"{images[0].shape[1]}x{images[0].shape[0]}: {what} must have the same size")
        images.append(image)
    return images, notes


def _read_file(name: str) -> bytes:
    """The file's bytes; the one-line ValueError of ``read_grey_image`` when it cannot be read or is empty."""
    try:
        with open(name, "rb") as file:
            data = file.read()
    except FileNotFoundError:
        _fail(name, "file not found")
    except IsADirectoryError:
        _fail(name, "is a directory, not an image file")
    except PermissionError:
        _fail(name, "cannot read the file: permission denied")
    except OSError as error:
        _fail(name, f"cannot read the file: {error.strerror or error}")
    if not data:
        _fail(name, "empty file (0 bytes)")
    return data


def _decoded(name: str, data: bytes) -> np.ndarray:
    """The decoded pixels, as stored; a file OpenCV cannot decode, a cut PNG or an image without pixels fail."""
    kind = _format_of(data)
    decoded = _decode(data)
    if decoded is None or isinstance(decoded, str):
        detail = f" ({decoded})" if isinstance(decoded, str) else ""
        if kind is None:
            _fail(name, f"not an image OpenCV can read (unknown format, {len(data)} bytes){detail}")
        _fail(name, f"truncated or corrupt {kind} file, OpenCV could not decode it{detail}")
    image = decoded
    if kind == "PNG" and b"IEND" not in data[-64:]:
        _fail(name, "truncated PNG file (no IEND chunk at the end)")
    if image.size == 0 or image.ndim < 2:
        _fail(name, f"image has no pixels (shape {image.shape})")
    return image


def _as_grey(name: str, image: np.ndarray) -> tuple[np.ndarray, str | None]:
    """One channel from a multi-channel image, and the note saying what was dropped or converted.

    Float and wider-than-16-bit colour images are left as they are: ``_check_pixels`` names their type.
    """
    import cv2

    if image.ndim != 3:
        return image, None
    note = None
    channels = image.shape[2]
    if channels == 1:
        image = image[:, :, 0]
    elif channels in (3, 4):
        if image.dtype.kind == "f" or image.dtype.itemsize > 2 or image.dtype.kind == "i":
            pass  # reported by _check_pixels, before any conversion
        elif _channels_equal(image[:, :, :3]):
            # A grey image stored as colour: a palette (indexed) TIFF or PNG whose entries are all
            # grey decodes to three equal channels. Its grey levels are exact: no conversion, no note.
            image = np.ascontiguousarray(image[:, :, 0])
            if channels == 4:
                note = f"{name}: grey + alpha image: alpha channel dropped"
        else:
            code = cv2.COLOR_BGR2GRAY if channels == 3 else cv2.COLOR_BGRA2GRAY
            image = cv2.cvtColor(image, code)
            note = (f"{name}: colour image ({channels} channels) converted to grey "
                    f"(0.299 R + 0.587 G + 0.114 B{', alpha dropped' if channels == 4 else ''}); "
                    f"save grey images to avoid this")
    elif channels == 2:
        image = np.ascontiguousarray(image[:, :, 0])
        note = f"{name}: grey + alpha image: alpha channel dropped"
    else:
        _fail(name, f"{channels}-channel images are not supported: {_SAVE_AS}")
    return image, note


def _check_pixels(name: str, image: np.ndarray) -> None:
    """ValueError unless ``image`` is 2-D, unsigned 8 or 16 bits: the pixel types DIC reads untouched."""
    dtype = image.dtype
    if dtype.kind == "f":
        _fail(name, f"{dtype.itemsize * 8}-bit float images are not supported: {_SAVE_AS}")
    if dtype.kind == "b":
        _fail(name, f"1-bit (bilevel) images are not supported: {_SAVE_AS}")
    if dtype.itemsize > 2:
        _fail(name, f"{dtype.itemsize * 8}-bit integer images are not supported: {_SAVE_AS}")
    if dtype.kind == "i":
        _fail(name, f"signed {dtype.itemsize * 8}-bit images are not supported: {_SAVE_AS} (unsigned)")
    if dtype not in (np.uint8, np.uint16):
        _fail(name, f"pixel type {dtype} is not supported: {_SAVE_AS}")
    if image.ndim != 2:
        _fail(name, f"unexpected image shape {image.shape}: {_SAVE_AS}")
