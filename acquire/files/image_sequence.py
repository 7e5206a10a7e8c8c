"""``images:GLOB`` — a folder or glob of 8/16-bit grey PNG/TIFF files, in natural order.

``images:run1/frame_*.tif`` yields frame_2 before frame_10 (natural sort: digit
runs compare as numbers). ``images:run1`` (a folder) takes every PNG/TIFF in it.
Options go in a query string after the pattern, as for the other sources:
``images:run1/frame_*.tif?frame_rate=5&realtime=1``. ``?`` is also a glob
wildcard, so only a tail of ``name=value`` pairs (``&``-separated) after the last
``?`` is read as options; keyword arguments of :func:`open_uri` override them.

Before the first frame every file's header is read (``read_image_header``: the
size, and the bit depth of grey files): a file of another size or bit depth than
the first, or one that is no image, is refused when the source opens, so the
session never starts on a sequence it cannot finish. Files are then decoded one
at a time by :func:`acquire.files.image_file.read_grey_image`: a truncated or corrupt
file, a float or 32-bit one, or a colour file whose bit depth differs (headers
do not tell it) raises ``SourceError`` naming it when its turn comes. Colour
files are converted to grey with a note logged once.
Timestamps are ``index / frame_rate`` (default 1 fps): files carry no capture time.
"""

from __future__ import annotations

import glob
import logging
import os
import re
import time
from collections.abc import Iterator, Sequence
from typing import Any
from urllib.parse import parse_qsl

import numpy as np

from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.acquire.files.image_file import read_grey_image, read_image_header
from livedic.acquire.options import as_bool, as_float

__all__ = ["ImageSequence", "find_images", "natural_key", "open_uri", "SCHEME", "IMAGE_EXTENSIONS"]

log = logging.getLogger("livedic.acquire.images")

SCHEME = "images"
IMAGE_EXTENSIONS = (".png", ".tif", ".tiff")
_DIGITS = re.compile(r"(\d+)")
# An options tail "name=value&name=value" (a glob's own "?" is followed by anything else).
_QUERY = re.compile(r"\w+=[^&=]*(&\w+=[^&=]*)*")


def natural_key(path: str | os.PathLike[str]) -> list[tuple[int, int, str]]:
    """Sort key where digit runs compare as numbers: frame_2 < frame_10 (case-insensitive)."""
    parts = _DIGITS.split(os.fspath(path).lower())
    return [(0, int(part), part) if part.isdigit() else (1, 0, part) for part in parts]


def find_images(pattern: str) -> list[str]:
    """The image files a folder (its PNG/TIFF files) or a glob names, in natural order (maybe none)."""
    return _find(pattern)


def _find(pattern: str) -> list[str]:
    expanded = os.path.expanduser(pattern)
    if os.path.isdir(expanded):
        names = [os.path.join(expanded, n) for n in os.listdir(expanded)
                 if n.lower().endswith(IMAGE_EXTENSIONS)]
        names = [n for n in names if os.path.isfile(n)]
    else:
        names = [n for n in glob.glob(expanded, recursive=True) if not os.path.isdir(n)]
    return sorted(names, key=natural_key)


def _check_alike(files: Sequence[str]) -> None:
    """SourceError (one line) at the first file whose header differs in size or bit depth from the first's."""
    try:
        first = read_image_header(files[0])
        for path in files[1:]:
            header = read_image_header(path)
            if (header.width, header.height) != (first.width, first.height):
                raise SourceError(
                    f"{path} is {header.width}x{header.height} but the first image {files[0]} is "
                    f"{first.width}x{first.height}: every image of a sequence must have the same size "
                    f"(remove it, or crop all images alike)")
            if None not in (header.bits, first.bits) and header.bits != first.bits:
                raise SourceError(
                    f"{path} is {header.bits}-bit but the first image {files[0]} is {first.bits}-bit: every "
                    f"image of a sequence must have the same bit depth (save them all alike)")
    except ValueError as error:
        raise SourceError(str(error)) from None


class ImageSequence(FrameSource):
    """Frames from image files in natural order.

    Parameters
    ----------
    pattern : str
        A glob (``run/frame_*.png``, ``**`` recursive) or a folder (all PNG/TIFF files in it).
    frame_rate : float
        Sets timestamps (``index / frame_rate``) and, with ``realtime``, the pace.
    realtime : bool
        Deliver frames at ``frame_rate`` like a live camera instead of as fast as possible.
    loop : bool
        Start again after the last file (for demos); indices keep counting.

    Raises
    ------
    SourceError
        No file matches, or a file's header shows another size or bit depth than the
        first's; later, a file that cannot be decoded as an 8/16-bit grey image.
    """

    OPTIONS = {"frame_rate": "frames per second for timestamps (default 1)",
               "realtime": "1 to deliver at frame_rate", "loop": "1 to repeat forever"}

    def __init__(self, pattern: str | os.PathLike[str], *, frame_rate: float = 1.0, realtime: bool = False,
                 loop: bool = False, uri: str | None = None) -> None:
        self.pattern = os.fspath(pattern)
        self.uri = uri or f"{SCHEME}:{self.pattern}"
        self.frame_rate = as_float("frame_rate", frame_rate, low=0, low_open=True)
        self.realtime = as_bool("realtime", realtime)
        self.loop = as_bool("loop", loop)
        self.files = _find(self.pattern)
        if not self.files:
            raise SourceError(f"no image files match '{self.pattern}' (give a glob such as "
                              f"'frames/img_*.png' or a folder of PNG/TIFF files)")
        _check_alike(self.files)
        self.notes: list[str] = []
        self._first: tuple[tuple[int, ...], np.dtype, str] | None = None  # (shape, dtype, name) of the first image
        self._closed = False

    @property
    def live(self) -> bool:
        return self.realtime          # delivered at the frames' own pace, like a camera

    @property
    def settings(self) -> dict[str, Any]:
        out = {"source": SCHEME, "uri": self.uri, "pattern": self.pattern, "n_files": len(self.files),
               "first_file": self.files[0], "last_file": self.files[-1], "frame_rate": self.frame_rate,
               "realtime": self.realtime, "loop": self.loop, "notes": list(self.notes)}
        if self._first is not None:
            shape, dtype, _ = self._first
            out.update({"width": shape[1], "height": shape[0],
                        "pixel_format": "Mono8" if dtype.itemsize == 1 else "Mono16"})
        return out

    def _read(self, path: str) -> tuple[np.ndarray, str | None]:
        try:
            image, note = read_grey_image(path)
        except ValueError as error:
            raise SourceError(str(error)) from None
        if note and note not in self.notes:
            if not self.notes:
                log.warning("%s (further files may be converted too)", note)
            self.notes.append(note)
        if self._first is None:
            self._first = (image.shape, image.dtype, path)
        else:
            shape, dtype, first = self._first
            if image.shape != shape or image.dtype != dtype:
                raise SourceError(
                    f"{path}: {image.shape[1]}x{image.shape[0]} {image.dtype} differs from the first image "
                    f"{first} ({shape[1]}x{shape[0]} {dtype}): every image must have the same size and bit depth")
        return image, note

    def __iter__(self) -> Iterator[Frame]:
        index = 0
        start = time.monotonic()
        while not self._closed:
            for path in self.files:
                if self._closed:
                    return
                image, note = self._read(path)
                timestamp_ns = round(index * 1e9 / self.frame_rate)
                if self.realtime:
                    delay = start + timestamp_ns * 1e-9 - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                metadata: dict[str, Any] = {"path": path}
                if note:
                    metadata["note"] = note
                yield Frame(index=index, timestamp_ns=timestamp_ns, image=image,
                            pixel_format="Mono8" if image.dtype.itemsize == 1 else "Mono16", metadata=metadata)
                index += 1
            if not self.loop:
                return

    def close(self) -> None:
        self._closed = True

    def __len__(self) -> int:
        return len(self.files)


def open_uri(uri: str, **options: Any) -> ImageSequence:
    """``images:PATTERN[?frame_rate=F&realtime=0|1&loop=0|1]`` -> :class:`ImageSequence` (keywords override)."""
    if uri[:len(SCHEME) + 1].lower() != SCHEME + ":":
        raise SourceError(f"not an images URI: {uri!r} (expected 'images:GLOB' or 'images:FOLDER')")
    pattern = uri[len(SCHEME) + 1:]
    glob_part, mark, query = pattern.rpartition("?")
    if mark and _QUERY.fullmatch(query):
        pattern, options = glob_part, {**dict(parse_qsl(query, keep_blank_values=True)), **options}
    if not pattern:
        raise SourceError("images: needs a glob or folder, e.g. 'images:frames/img_*.png'")
    unknown = sorted(set(options) - set(ImageSequence.OPTIONS))
    if unknown:
        raise SourceError(f"unknown images option(s) {', '.join(unknown)}; known: {', '.join(ImageSequence.OPTIONS)}")
    return ImageSequence(pattern, uri=uri, **options)
