"""``open_source(uri)``: one entry point for every frame source, chosen by the URI scheme.

Valid forms (backends are imported only when their scheme is used, so a
missing optional dependency such as Aravis only matters to its own URIs)::

    synthetic:[tensile|translate][?frames=300&fps=50&size=1024x1024&bit=8&noise=1.0&seed=0...]
    synthetic:stereo?view=left|right[&w0=0.5&rotx=1...]       one camera of the simulated stereo test
    aravis:[DEVICE_ID][?exposure_us=2000&frame_rate=50&...]   GenICam camera through Aravis
    v4l2:[/dev/videoN|N][?width=..&height=..&fourcc=GREY&frame_rate=..]
    video:FILE                                                 a video file (FFV1 .mkv is lossless)
    images:GLOB_OR_FOLDER[?frame_rate=1&realtime=0&loop=0]    PNG/TIFF files in natural order
    mcap:FILE.mcap[?realtime=1]                                replay of a livedic recording

A bare path ending in ``.mcap`` is read as ``mcap:PATH``. Keyword options
override those in the query string. Malformed or unknown URIs raise
``SourceError`` listing these forms.
"""

from typing import Any
from urllib.parse import parse_qsl

from livedic.acquire.base import FrameSource, SourceError


SCHEMES = ("synthetic", "aravis", "v4l2", "video", "images", "mcap")

USAGE = ("valid sources: synthetic:[tensile|translate|stereo][?frames=N&fps=F&size=WxH&bit=8|12&noise=S&seed=K], "
         "aravis:[DEVICE_ID][?options], v4l2:/dev/videoN[?options], video:FILE, images:GLOB_OR_FOLDER[?frame_rate=F], "
         "mcap:FILE.mcap[?realtime=1]")


def parse_scheme(uri: str) -> str:
    """The scheme of ``uri`` (one of ``SCHEMES``) or SourceError."""
    if not isinstance(uri, str) or not uri.strip():
        raise SourceError(f"empty source URI; {USAGE}")
    uri = uri.strip()
    scheme, sep, _ = uri.partition(":")
    if not sep:
        if uri.endswith(".mcap"):
            return "mcap"
        raise SourceError(f"source {uri!r} has no scheme; {USAGE}")
    scheme = scheme.lower()
    if scheme not in SCHEMES:
        raise SourceError(f"unknown source scheme {scheme!r} in {uri!r}; {USAGE}")
    return scheme


def open_source(uri: str, **options: Any) -> FrameSource:
    """Open the frame source named by ``uri``.

    Parameters
    ----------
    uri : str
        See the module notes for the forms.
    **options
        Backend options (override the URI's query string).

    Returns
    -------
    FrameSource

    Raises
    ------
    SourceError
        Malformed or unknown URI, unknown option, or a source that cannot be opened.
    """
    scheme = parse_scheme(uri)
    uri = uri.strip()
    if scheme == "synthetic":
        from livedic.acquire.simulator.open import open_simulator
        return open_simulator(uri, **options)
    if scheme == "aravis":
        from livedic.acquire.camera.aravis import open_uri as open_aravis
        return open_aravis(uri, **options)
    if scheme in ("v4l2", "video"):
        from livedic.acquire.camera.opencv import open_uri as open_opencv
        return open_opencv(uri, **options)
    if scheme == "images":
        from livedic.acquire.files.image_sequence import open_uri as open_images
        return open_images(uri, **options)
    return _open_mcap(uri, options)


def _open_mcap(uri, options):
    from livedic.acquire.recording.source import McapSource
    path = uri[len("mcap:"):] if uri.lower().startswith("mcap:") else uri
    path, _, query = path.partition("?")
    if path.startswith("//"):
        path = path[2:]
    if not path:
        raise SourceError(f"mcap: needs a recording file, e.g. mcap:recordings/session.mcap; {USAGE}")
    merged = dict(parse_qsl(query, keep_blank_values=True)) if query else {}
    merged.update(options)
    unknown = sorted(set(merged) - {"realtime"})
    if unknown:
        raise SourceError(f"unknown mcap option(s) {', '.join(unknown)}: the only option is realtime=0|1")
    from livedic.acquire.options import as_bool
    return McapSource(path, realtime=as_bool("realtime", merged.get("realtime", False)))
