"""``synthetic``: the simulated test's force, one sample per frame of the simulated camera.

The tensile test's (``synthetic:tensile``, its law in acquire.simulator.model) or the stereo test's
(``synthetic:stereo``, a stereo pair's left view: acquire.simulator.stereo_force). ``check_synthetic_load_source``
says from the source's URI alone, before anything is rendered, whether it has one.
"""

from typing import Any

import numpy as np

from livedic.acquire.force.csv_file import _KnownSamples, csv_max_gap_s
from livedic.acquire.force.source import LoadError, _option

__all__ = ["SyntheticLoad", "check_synthetic_load_source", "SIMULATED_TESTS"]


class SyntheticLoad(_KnownSamples):
    """The simulated tensile test's force: one sample per frame, frame i at ``i / fps`` s (session time).

    Parameters
    ----------
    source : SyntheticTensileSource
        The simulated camera (or any object with ``frames``, ``fps`` and ``forces_N()``).
    uri : str, optional
        How the session names it (default ``synthetic``).
    offset_s : float, optional
        Added to every sample's time, as a csv's (``--load-offset``); 0 for the simulator's own frames.
    max_gap_s : float, optional
        Default: ``csv_max_gap_s`` of the frame times (5 frame periods, 0.5 s at least).

    Attributes
    ----------
    specimen : dict
        The source's ``specimen`` (A0, E, yield, Rp0.2, Rm): what the stress-strain curve needs.
    """

    def __init__(self, source: Any, *, uri: str = "synthetic", offset_s: float = 0.0,
                 max_gap_s: float | None = None) -> None:
        self.uri = uri
        self.source_uri = getattr(source, "uri", None)
        self.offset_s = float(offset_s)
        self.specimen = dict(getattr(source, "specimen", {}) or {})
        self._time = np.arange(int(source.frames), dtype=np.float64) / float(source.fps) + self.offset_s
        self._force = np.asarray(source.forces_N(), dtype=np.float64)
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(self._time)

    @property
    def settings(self) -> dict[str, Any]:
        return {**super().settings, "source": self.source_uri, "offset_s": self.offset_s, "specimen": self.specimen}


# Which sources have a force law: the simulated tests. Said by the early check and by open_load alike.
SIMULATED_TESTS = ("--source synthetic:tensile?... or a stereo pair of the stereo test, "
                   "stereo:synthetic:stereo?view=left&...,synthetic:stereo?view=right&...")


def check_synthetic_load_source(source_uri: str) -> None:
    """Whether ``--load synthetic`` can use the session's source ``source_uri``: a simulated test with a force law
    (``synthetic:tensile``, or a stereo pair of ``synthetic:stereo`` views), read from the URI alone, before
    anything is opened or rendered.

    Raises
    ------
    LoadError
        One line: the source has no force law; what to give instead.
    """
    from livedic.acquire.base import SourceError
    from livedic.acquire.simulator.options import parse_synthetic_uri
    from livedic.acquire.sources import STEREO_SCHEME, parse_scheme, parse_stereo_uri
    try:
        views = (parse_stereo_uri(source_uri)[:2] if parse_scheme(source_uri) == STEREO_SCHEME else (source_uri,))
        models = {parse_synthetic_uri(view)[0] if parse_scheme(view) == "synthetic" else None for view in views}
    except SourceError:
        return                          # the source's own check says what is wrong with it, in its words
    if models not in ({"tensile"}, {"stereo"}):
        raise LoadError(f"--load synthetic is the simulated test's own force and {source_uri!r} is no simulated "
                        f"test with a force law: give {SIMULATED_TESTS}, or the machine's force (--load csv:FILE, "
                        f"tcp://HOST:PORT or modbus://HOST:PORT?register=N)")


def _simulated_test(source: Any) -> Any:
    """The simulated camera whose law gives the force: ``source``, or a stereo pair's left view (both views show
    one test, ``acquire.stereo.PairedFrames``)."""
    pairs = getattr(source, "pairs", None)
    return pairs.left if getattr(source, "stereo", False) and pairs is not None else source


def _open_synthetic(uri: str, options: dict[str, Any]) -> SyntheticLoad:
    """``synthetic`` with ``source=`` (the session's simulated camera) or ``synthetic:tensile?...`` /
    ``synthetic:stereo?...``."""
    source = options.pop("source", None)
    offset_s = _option("offset_s", options.pop("offset_s", 0.0))
    max_gap_s = options.pop("max_gap_s", None)
    if max_gap_s is not None:
        max_gap_s = _option("max_gap_s", max_gap_s, low=0.0, low_open=True)
    if options:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(options))}; synthetic takes source, "
                        f"offset_s, max_gap_s")
    if uri.lower() == "synthetic":
        if source is None:
            raise LoadError(f"load {uri!r}: the simulator's force needs the simulated camera: pass source= "
                            f"(a synthetic:tensile or synthetic:stereo source), or name the test: "
                            f"synthetic:tensile?... or synthetic:stereo?...")
        camera = _simulated_test(source)
        if not callable(getattr(camera, "forces_N", None)):
            raise LoadError(f"load {uri!r}: the camera {getattr(source, 'uri', type(source).__name__)!r} is not a "
                            f"simulated test with a force law; --load synthetic needs {SIMULATED_TESTS}")
        return SyntheticLoad(camera, uri=uri, offset_s=offset_s, max_gap_s=max_gap_s)
    if source is not None:
        raise LoadError(f"load {uri!r}: give either source= with load synthetic, or the test's URI, not both")
    from livedic.acquire.base import SourceError
    from livedic.acquire.simulator.options import parse_synthetic_uri
    from livedic.acquire.simulator.sources import SyntheticTensileSource
    from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource
    try:
        model, _ = parse_synthetic_uri(uri)
        if model not in ("tensile", "stereo"):
            raise SourceError(f"synthetic:{model} has no force; use synthetic:tensile?... or synthetic:stereo?...")
        source = SyntheticTensileSource(uri) if model == "tensile" else SyntheticStereoViewSource(uri)
    except SourceError as error:
        raise LoadError(f"load {uri!r}: {error}") from None
    return SyntheticLoad(source, uri=uri, offset_s=offset_s, max_gap_s=max_gap_s)
