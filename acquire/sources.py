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
    stereo:LEFT_URI,RIGHT_URI[,tolerance_ms=T][,clock=host|camera]   two views in step (``open_stereo_source``)

A bare path ending in ``.mcap`` is read as ``mcap:PATH``. Keyword options
override those in the query string. Malformed or unknown URIs raise
``SourceError`` listing these forms. ``stereo:`` yields pairs of frames (``acquire.stereo``):
``open_stereo_source`` opens it as ``StereoFrame`` pairs, ``open_source`` as ``PairedFrames`` (each pair its
left frame with the right one in ``Frame.right``: what a session takes).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl

from livedic.acquire.base import FrameSource, SourceError

if TYPE_CHECKING:
    from livedic.acquire.stereo import StereoSource


SCHEMES = ("synthetic", "aravis", "v4l2", "video", "images", "mcap", "stereo")
STEREO_SCHEME = "stereo"
_VIEW_SCHEMES = tuple(scheme for scheme in SCHEMES if scheme != STEREO_SCHEME)
STEREO_OPTIONS = ("tolerance_ms", "clock")     # the pair's own options, written after the right view
STEREO_FORM = "stereo:LEFT_URI,RIGHT_URI[,tolerance_ms=T][,clock=host|camera] (e.g. stereo:aravis:CAM_L,aravis:CAM_R)"

USAGE = ("valid sources: synthetic:[tensile|translate|stereo][?frames=N&fps=F&size=WxH&bit=8|12&noise=S&seed=K], "
         "aravis:[DEVICE_ID][?options], v4l2:/dev/videoN[?options], video:FILE, images:GLOB_OR_FOLDER[?frame_rate=F], "
         f"mcap:FILE.mcap[?realtime=1], {STEREO_FORM}")


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
    if scheme == STEREO_SCHEME:            # each pair as its left frame with the right one attached
        from livedic.acquire.stereo import PairedFrames
        return PairedFrames(open_stereo_source(uri, **options))
    return _open_mcap(uri, options)


def _starts_a_view(segment: str) -> bool:
    scheme, sep, _ = segment.strip().partition(":")
    return (bool(sep) and scheme.lower() in _VIEW_SCHEMES) or segment.strip().partition("?")[0].endswith(".mcap")


def _is_pair_option(segment: str) -> bool:
    name, sep, _ = segment.partition("=")
    return bool(sep) and name.strip().isidentifier()


def parse_stereo_uri(uri: str) -> tuple[str, str, dict[str, str]]:
    """``(left URI, right URI, pair options)`` of ``stereo:LEFT_URI,RIGHT_URI[,name=value...]``; SourceError otherwise.

    The right view starts at the one comma followed by a source scheme (``aravis:``, ``images:``...), so the views'
    own commas (``roi=0,0,640,480``) stay theirs; ``name=value`` segments after it are the pair's options.
    """
    body = uri.strip()[len(STEREO_SCHEME) + 1:]
    segments = body.split(",")
    starts = [i for i, segment in enumerate(segments) if i > 0 and _starts_a_view(segment)]
    if not body.strip() or len(starts) != 1:
        found = "one source" if not starts else f"{len(starts) + 1} sources"
        raise SourceError(f"{uri!r}: {found} given, a stereo pair takes two: {STEREO_FORM}")
    first_option = next((i for i in range(starts[0] + 1, len(segments)) if _is_pair_option(segments[i])),
                        len(segments))
    left, right = ",".join(segments[:starts[0]]).strip(), ",".join(segments[starts[0]:first_option]).strip()
    options: dict[str, str] = {}
    for segment in segments[first_option:]:
        name, sep, value = segment.partition("=")
        name = name.strip()
        if not sep or name not in STEREO_OPTIONS:
            raise SourceError(f"{uri!r}: unknown stereo option {segment.strip()!r} after the right view; the pair's "
                              f"options are {', '.join(STEREO_OPTIONS)}: {STEREO_FORM}")
        options[name] = value.strip()
    for side, view in (("left", left), ("right", right)):
        if parse_scheme(view) == STEREO_SCHEME:
            raise SourceError(f"{uri!r}: the {side} view is itself a stereo pair: {STEREO_FORM}")
    if left == right:
        raise SourceError(f"{uri!r}: both views are {left}: name two sources (two cameras): {STEREO_FORM}")
    return left, right, options


def pair_options(options: dict[str, Any]) -> tuple[float | None, str]:
    """``(tolerance_ms or None for the default, clock)`` from a stereo pair's options; SourceError naming a bad one."""
    from livedic.acquire.options import as_float
    from livedic.acquire.stereo import CLOCKS
    unknown = sorted(set(options) - set(STEREO_OPTIONS))
    if unknown:
        raise SourceError(f"unknown stereo option(s) {', '.join(unknown)}: the pair's options are "
                          f"{', '.join(STEREO_OPTIONS)}")
    tolerance = options.get("tolerance_ms")
    tolerance_ms = None if tolerance in (None, "") else as_float("tolerance_ms", tolerance, low=0)
    clock = str(options.get("clock") or CLOCKS[0]).strip().lower()
    if clock not in CLOCKS:
        raise SourceError(f"stereo option clock={clock}: write {' or '.join(f'clock={c}' for c in CLOCKS)}")
    return tolerance_ms, clock


def open_stereo_source(uri: str, *, static: int | None = None, **options: Any) -> StereoSource:
    """Open ``stereo:LEFT_URI,RIGHT_URI``: both views, paired (``acquire.stereo.StereoSource``).

    Keyword options (``tolerance_ms``, ``clock``) override those in the URI. ``static``: the static frames each
    simulated view renders before its test (a session's ``--static-frames``; other views hold what they hold). A
    view that cannot be opened raises ``SourceError`` naming it; the other view is closed.
    """
    from livedic.acquire.stereo import StereoSource
    if parse_scheme(uri) != STEREO_SCHEME:
        raise SourceError(f"{uri!r} is not a stereo pair: {STEREO_FORM}")
    left_uri, right_uri, merged = parse_stereo_uri(uri)
    tolerance_ms, clock = pair_options({**merged, **options})
    opened: list[FrameSource] = []
    try:
        for side, view in (("left", left_uri), ("right", right_uri)):
            try:
                simulated = static is not None and parse_scheme(view) == "synthetic"
                opened.append(open_source(view, **({"static": static} if simulated else {})))
            except SourceError as error:
                raise SourceError(f"{side} view ({view}): {error}") from None
        return StereoSource(opened[0], opened[1], tolerance_ms=tolerance_ms, clock=clock, uri=uri.strip())
    except BaseException:
        for source in opened:
            source.close()
        raise


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
