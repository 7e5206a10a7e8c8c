"""``v4l2:/dev/videoN`` and ``video:FILE`` through ``cv2.VideoCapture``, grey 8/16-bit frames.

Both open with ``CAP_PROP_CONVERT_RGB = 0`` so a grey stream (V4L2 ``GREY``/``Y16``,
FFV1 ``gray``/``gray16le``) arrives as one channel at its own bit depth, never
expanded to BGR. Any other pixel format (YUV, MJPEG, colour) is re-opened with
conversion on and turned into grey by OpenCV (0.299 R + 0.587 G + 0.114 B), with
a one-time note. Which case applies is decided on the first frame: a 2-D
uint8/uint16 frame of the announced size whose codec pixel format is grey is
kept as is.

Everything runs in :class:`OpenCVCapture`; :class:`V4L2Camera` only adds the
device settings (size, fps, fourcc, exposure, gain), applied then read back.
It is tested here on video files through the FFmpeg backend (no V4L2 device on
the test machines). Lossless grey recordings: FFV1 in .mkv, 8-bit and 16-bit
(``cv2.VideoWriter(..., cv2.VideoWriter_fourcc(*"FFV1"), fps, (w, h),
[cv2.VIDEOWRITER_PROP_IS_COLOR, 0, cv2.VIDEOWRITER_PROP_DEPTH, cv2.CV_16U])``).

URIs: ``video:PATH`` (path verbatim; options as keywords), ``v4l2:/dev/video0``
or ``v4l2:0`` with options in a query string
(``v4l2:/dev/video0?width=1280&height=1024&fourcc=GREY&frame_rate=30``).
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Sequence
from typing import Any, Literal, cast
from urllib.parse import parse_qsl

import numpy as np

from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.acquire.options import as_bool, as_float, as_int

__all__ = ["OpenCVCapture", "VideoFile", "V4L2Camera", "open_uri", "GREY_PIXEL_FORMATS"]

log = logging.getLogger("livedic.acquire.opencv")

# Codec / V4L2 fourccs of single-channel grey formats (FFmpeg GRAY8 is "Y800", GRAY16LE "Y1\0\x10").
GREY_PIXEL_FORMATS = {b"Y800", b"GREY", b"Y8  ", b"Y16 ", b"Y1\x00\x10", b"Y10 ", b"Y12 ", b"Y1\x00\x0a",
                      b"Y1\x00\x0c"}
_UNKNOWN_FORMAT = b"\x00\x00\x00\x00"


def _fourcc_bytes(value):
    try:
        code = int(value)
    except (TypeError, ValueError, OverflowError):
        return _UNKNOWN_FORMAT
    if code <= 0:
        return _UNKNOWN_FORMAT
    return code.to_bytes(4, "little", signed=False) if code < 2 ** 32 else _UNKNOWN_FORMAT


def _quiet_ffmpeg() -> None:
    """Silence FFmpeg's own stderr lines ("moov atom not found" ...): livedic says what went wrong, in one line.

    OpenCV reads ``OPENCV_FFMPEG_LOGLEVEL`` (an FFmpeg ``AV_LOG_*`` level; -8 is ``AV_LOG_QUIET``) when it first
    uses FFmpeg, so this must run before the first capture opens. A value the user set (to debug) is kept.
    """
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


def _quiet(cv2):
    """Context manager silencing OpenCV's own log lines (e.g. the CONVERT_RGB=0 warning)."""
    class _Quiet:
        def __enter__(self) -> None:
            self.logging = getattr(getattr(cv2, "utils", None), "logging", None)
            self.level = None
            if self.logging is not None:
                try:
                    self.level = self.logging.getLogLevel()
                    self.logging.setLogLevel(self.logging.LOG_LEVEL_ERROR)
                except Exception:  # noqa: BLE001 - cosmetic
                    self.logging = None

        def __exit__(self, *exc: object) -> Literal[False]:
            if self.logging is not None and self.level is not None:
                self.logging.setLogLevel(self.level)
            return False
    return _Quiet()


class OpenCVCapture(FrameSource):
    """Frames from a ``cv2.VideoCapture`` (file or device), grey, 8 or 16 bit.

    Parameters
    ----------
    target : str or int
        File path, device path or index.
    api : int
        ``cv2.CAP_*`` backend (``CAP_FFMPEG`` for files, ``CAP_V4L2`` for devices).
    kind : str
        ``"video"`` or ``"v4l2"``: names the source in messages and settings.
    open_params : list of int
        Extra ``cv2.VideoCapture`` open parameters (property id, value, ...).
    realtime : bool
        Files only: deliver frames at their timestamps instead of as fast as possible.
    """

    is_device = False

    def __init__(self, target: str | int, *, api: int, kind: str, open_params: Sequence[int] = (),
                 realtime: bool = False, uri: str | None = None) -> None:
        import cv2

        self._cv2 = cv2
        self.target = target
        self.kind = kind
        self.uri = uri or f"{kind}:{target}"
        self.realtime = bool(realtime)
        self._api = api
        self._open_params = list(open_params)
        self._convert = False   # True once the stream is known to need BGR -> grey
        self._note: str | None = None
        self._first: tuple[np.ndarray, int, Any] | None = None   # (first frame already read) for the iterator
        self._index = 0
        self._closed = False
        self._capture: Any = None              # the cv2.VideoCapture while open
        self._stream_info: dict[str, Any] = {}
        self._pixel_format_code = _UNKNOWN_FORMAT
        try:
            self._open(convert_rgb=False)
            self._probe_first_frame()
        except BaseException:
            self.close()
            raise
        first_image = cast(tuple[np.ndarray, int, Any], self._first)[0]      # set by _probe_first_frame
        self._pixel_format = "Mono8" if first_image.dtype == np.uint8 else "Mono16"
        self._describe_stream()

    # ------------------------------------------------------------------ open
    def _describe(self) -> str:
        return f"{self.kind} source {self.target}"

    def _open(self, *, convert_rgb):
        cv2 = self._cv2
        if self._capture is not None:
            self._capture.release()
        params = [cv2.CAP_PROP_CONVERT_RGB, 1 if convert_rgb else 0] + self._open_params
        _quiet_ffmpeg()
        with _quiet(cv2):
            capture = cv2.VideoCapture(self.target, self._api, params)
        if not capture.isOpened():
            capture.release()
            raise SourceError(self._open_failure())
        self._capture = capture
        self._after_open(capture)

    def _open_failure(self) -> str:
        if not os.path.exists(str(self.target)):
            return f"{self._describe()}: file not found"
        return f"{self._describe()}: OpenCV could not open it (not a video, or a codec FFmpeg lacks)"

    def _after_open(self, capture) -> None:
        """Device settings go here (V4L2Camera)."""

    def _probe_first_frame(self):
        capture = self._capture
        ok, frame = capture.read()
        if not ok or frame is None:
            raise SourceError(f"{self._describe()}: no frame could be read (empty or corrupt)")
        width = int(capture.get(self._cv2.CAP_PROP_FRAME_WIDTH))
        height = int(capture.get(self._cv2.CAP_PROP_FRAME_HEIGHT))
        self._pixel_format_code = self._stream_pixel_format()
        grey = (frame.ndim == 2 and frame.dtype in (np.uint8, np.uint16)
                and (width, height) in ((frame.shape[1], frame.shape[0]), (0, 0))
                and self._pixel_format_code in GREY_PIXEL_FORMATS | {_UNKNOWN_FORMAT})
        if grey:
            self._first = (frame, self._timestamp_ns(), self._position())
            return
        if frame.ndim == 3 and frame.shape[2] in (3, 4) and frame.shape[:2] == (height, width):
            self._convert = True   # already BGR(A): convert here, no need to re-open
            self._first = (self._to_grey(frame), self._timestamp_ns(), self._position())
        else:
            # YUV / MJPEG raw data: let OpenCV decode to BGR, then convert to grey.
            self._open(convert_rgb=True)
            ok, frame = self._capture.read()
            if not ok or frame is None:
                raise SourceError(f"{self._describe()}: no frame could be read after colour conversion")
            self._convert = True
            self._first = (self._to_grey(frame), self._timestamp_ns(), self._position())
        self._note = (f"{self._describe()}: {self._pixel_format_code.decode('latin-1').strip() or 'colour'} "
                      f"frames converted to grey (0.299 R + 0.587 G + 0.114 B); record grey for exact levels")
        log.warning("%s", self._note)

    def _stream_pixel_format(self):
        cv2 = self._cv2
        code = _fourcc_bytes(self._capture.get(cv2.CAP_PROP_CODEC_PIXEL_FORMAT)) \
            if hasattr(cv2, "CAP_PROP_CODEC_PIXEL_FORMAT") else _UNKNOWN_FORMAT
        if code == _UNKNOWN_FORMAT and self.is_device:
            code = _fourcc_bytes(self._capture.get(cv2.CAP_PROP_FOURCC))
        return code

    def _to_grey(self, frame):
        cv2 = self._cv2
        if frame.ndim == 2:
            return frame
        code = cv2.COLOR_BGR2GRAY if frame.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        return cv2.cvtColor(frame, code)

    def _timestamp_ns(self):
        msec = self._capture.get(self._cv2.CAP_PROP_POS_MSEC)
        if not math.isfinite(msec) or (msec <= 0 and self.is_device):
            return time.monotonic_ns()
        return int(round(msec * 1e6))

    def _position(self):
        return None

    # ------------------------------------------------------------- settings
    @property
    def live(self) -> bool:
        return self.is_device or self.realtime     # a camera, or a file delivered at its timestamps

    @property
    def settings(self) -> dict[str, Any]:
        """Source description; stays available after close (taken when the stream was probed)."""
        out: dict[str, Any] = {"source": self.kind, "uri": self.uri, "target": str(self.target)}
        out.update(self._describe_stream())
        out["pixel_format"] = self._pixel_format
        out["converted_to_grey"] = self._convert
        out["notes"] = [self._note] if self._note else []
        return out

    def _describe_stream(self):
        cv2 = self._cv2
        capture = self._capture
        if capture is None:
            return dict(self._stream_info)
        self._stream_info = {
            "width": int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)),
            "height": int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)),
            "frame_rate": float(capture.get(cv2.CAP_PROP_FPS)),
            "backend": capture.getBackendName(),
            "codec_pixel_format": self._pixel_format_code.decode("latin-1"),
        }
        return dict(self._stream_info)

    # ------------------------------------------------------------ streaming
    def __iter__(self):
        start_wall = None
        while not self._closed:
            if self._first is not None:
                image, timestamp_ns, _ = self._first
                self._first = None
            else:
                capture = self._capture
                if capture is None:
                    return
                ok, frame = capture.read()
                if not ok or frame is None:
                    self._at_end()
                    return
                image = self._to_grey(frame) if self._convert else frame
                timestamp_ns = self._timestamp_ns()
            if image.ndim != 2 or image.dtype not in (np.uint8, np.uint16):
                raise SourceError(f"{self._describe()}: frame {self._index} is {image.dtype} "
                                  f"{image.shape}, not a grey 8/16-bit image")
            if self.realtime and not self.is_device:
                if start_wall is None:
                    start_wall = time.monotonic() - timestamp_ns * 1e-9
                delay = start_wall + timestamp_ns * 1e-9 - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            metadata = {"note": self._note} if (self._note and self._index == 0) else {}
            frame = Frame(index=self._index, timestamp_ns=timestamp_ns, image=image,
                          pixel_format="Mono8" if image.dtype == np.uint8 else "Mono16", metadata=metadata)
            self._index += 1
            yield frame

    def _at_end(self):
        if self.is_device and not self._closed:
            raise SourceError(f"{self._describe()}: the device stopped delivering frames (unplugged?)")
        expected = int(self._capture.get(self._cv2.CAP_PROP_FRAME_COUNT) or 0) if self._capture else 0
        if expected > self._index:
            log.warning("%s: video ended after %d of %d frames announced (truncated file?)",
                        self._describe(), self._index, expected)

    def close(self) -> None:
        self._closed = True
        capture, self._capture = self._capture, None
        if capture is not None:
            capture.release()


class VideoFile(OpenCVCapture):
    """``video:FILE`` — frames of a video file (FFV1 .mkv keeps 8/16-bit grey exactly).

    Timestamps come from the container (``CAP_PROP_POS_MSEC``). The iteration
    ends at the end of the file; a file shorter than announced logs a warning.
    """

    OPTIONS = {"realtime": "1 to deliver frames at the file's pace"}

    def __init__(self, path: str | os.PathLike[str], *, realtime: bool = False, uri: str | None = None) -> None:
        import cv2

        path = os.path.expanduser(os.fspath(path))
        if os.path.isdir(path):
            raise SourceError(f"video source {path}: is a directory, not a video file (use images: for a folder)")
        super().__init__(path, api=cv2.CAP_FFMPEG, kind="video", realtime=as_bool("realtime", realtime), uri=uri)

    def _describe_stream(self):
        info = super()._describe_stream()
        if self._capture is not None:
            info["n_frames"] = int(self._capture.get(self._cv2.CAP_PROP_FRAME_COUNT))
            self._stream_info = dict(info)
        return info


class V4L2Camera(OpenCVCapture):
    """``v4l2:/dev/videoN`` — a V4L2 camera (UVC webcam, V4L2 machine-vision camera).

    Parameters (``None`` leaves the driver's value; all are read back in ``settings``)
    ----------
    width, height : int
        Frame size.
    frame_rate : float
        Frames per second.
    fourcc : str
        Pixel format, e.g. ``"GREY"`` or ``"Y16 "`` for grey cameras, ``"MJPG"``.
    exposure_us : float
        Manual exposure (V4L2 ``exposure_time_absolute`` is in 100 us units; auto exposure off).
    gain : float
        Driver gain units (not dB).
    api : int
        Backend, ``cv2.CAP_V4L2`` unless testing the code path on a file.
    """

    is_device = True
    OPTIONS = {"width": "frame width", "height": "frame height", "frame_rate": "frames per second",
               "fourcc": "pixel format, e.g. GREY, Y16, MJPG", "exposure_us": "manual exposure, microseconds",
               "gain": "gain, driver units"}

    def __init__(self, device: str | int, *, width: object = None, height: object = None, frame_rate: object = None,
                 fourcc: object = None, exposure_us: object = None, gain: object = None, api: int | None = None,
                 uri: str | None = None) -> None:
        import cv2

        if isinstance(device, str) and device.isdigit():
            device = int(device)
        self._requested: dict[str, Any] = {k: v for k, v in dict(width=width, height=height, frame_rate=frame_rate,
                                                   fourcc=fourcc, exposure_us=exposure_us, gain=gain).items()
                           if v not in (None, "")}
        # Checked before opening; applied after (set() while not streaming, what the V4L2 backend expects).
        if fourcc not in (None, ""):
            text = str(fourcc)
            if not 1 <= len(text) <= 4:
                raise SourceError(f"fourcc={fourcc!r} must be 1 to 4 characters, e.g. GREY, Y16, MJPG")
            self._requested["fourcc"] = text.ljust(4)
        for name, value in (("width", width), ("height", height)):
            if value not in (None, ""):
                self._requested[name] = as_int(name, value, low=1)
        for name in ("frame_rate", "exposure_us"):
            if name in self._requested:
                self._requested[name] = as_float(name, self._requested[name], low=0, low_open=True)
        if "gain" in self._requested:
            self._requested["gain"] = as_float("gain", self._requested["gain"])
        super().__init__(device, api=cv2.CAP_V4L2 if api is None else api, kind="v4l2", uri=uri)

    def _open_failure(self) -> str:
        target = self.target
        if isinstance(target, str) and target.startswith("/dev/") and not os.path.exists(target):
            present = sorted(n for n in os.listdir("/dev") if n.startswith("video")) if os.path.isdir("/dev") else []
            listing = ", ".join("/dev/" + n for n in present) or "none"
            return f"{self._describe()}: no such device (video devices here: {listing})"
        return (f"{self._describe()}: OpenCV's V4L2 backend could not open it (busy in another program, "
                f"no permission — add the user to the 'video' group — or not a capture device)")

    def _after_open(self, capture) -> None:
        cv2 = self._cv2
        requested = self._requested
        if "fourcc" in requested:
            capture.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*requested["fourcc"]))
        if "width" in requested:
            capture.set(cv2.CAP_PROP_FRAME_WIDTH, requested["width"])
        if "height" in requested:
            capture.set(cv2.CAP_PROP_FRAME_HEIGHT, requested["height"])
        if "frame_rate" in requested:
            capture.set(cv2.CAP_PROP_FPS, requested["frame_rate"])
        if "exposure_us" in requested:
            capture.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1)          # V4L2 "manual mode" in OpenCV's mapping
            capture.set(cv2.CAP_PROP_EXPOSURE, requested["exposure_us"] / 100.0)  # 100 us units
        if "gain" in requested:
            capture.set(cv2.CAP_PROP_GAIN, requested["gain"])

    def _describe_stream(self):
        info = super()._describe_stream()
        cv2 = self._cv2
        if self._capture is not None:
            exposure = self._capture.get(cv2.CAP_PROP_EXPOSURE)
            info.update({
                "fourcc": _fourcc_bytes(self._capture.get(cv2.CAP_PROP_FOURCC)).decode("latin-1"),
                "exposure_us": exposure * 100.0 if exposure > 0 else None,
                "gain": self._capture.get(cv2.CAP_PROP_GAIN),
            })
            self._stream_info = dict(info)
        return info

    @property
    def settings(self) -> dict[str, Any]:
        out = super().settings
        out["requested"] = dict(self._requested)
        return out


def open_uri(uri: str, **options: Any) -> VideoFile | V4L2Camera:
    """``video:PATH`` -> :class:`VideoFile`; ``v4l2:DEVICE[?opts]`` -> :class:`V4L2Camera`."""
    scheme, _, rest = uri.partition(":")
    scheme = scheme.lower()
    if scheme == "video":
        if not rest:
            raise SourceError("video: needs a file, e.g. 'video:test.mkv'")
        known = VideoFile.OPTIONS
        cls: type[VideoFile] | type[V4L2Camera] = VideoFile
        target, query = rest, {}
    elif scheme == "v4l2":
        device, _, query_text = rest.partition("?")
        if device.startswith("//"):
            device = device[2:]
        target = device or "/dev/video0"
        query = dict(parse_qsl(query_text, keep_blank_values=True)) if query_text else {}
        known = V4L2Camera.OPTIONS
        cls = V4L2Camera
    else:
        raise SourceError(f"not an OpenCV URI: {uri!r} (expected 'video:FILE' or 'v4l2:/dev/videoN')")
    merged = {**query, **options}
    unknown = sorted(set(merged) - set(known))
    if unknown:
        raise SourceError(f"unknown {scheme} option(s) {', '.join(unknown)}; known: {', '.join(known)}")
    return cls(target, uri=uri, **merged)
