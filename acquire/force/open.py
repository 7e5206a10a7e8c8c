"""``open_load(uri)``: the testing machine's force signal, opened from a URI like a frame source.

``csv:FILE``, ``tcp://HOST:PORT``, ``modbus://HOST:PORT?register=N`` or ``synthetic``; every error is one
``LoadError`` line. The forms, options, time bases, interpolation and faults of each source:
docs/guide/tensile-test.md ("The force sources in detail").
"""

from typing import Any

from livedic.acquire.force.csv_file import CsvLoad
from livedic.acquire.force.modbus import _open_modbus
from livedic.acquire.force.simulated import _open_synthetic
from livedic.acquire.force.source import LoadError, LoadSource, _option
from livedic.acquire.force.tcp import _open_tcp

__all__ = ["open_load", "LOAD_USAGE"]

LOAD_USAGE = ("valid loads: csv:FILE (header time_s,force_N), tcp://HOST:PORT[?clock=arrival|sender], "
              "modbus://HOST:PORT?register=N[&scale=K...], "
              "synthetic (with a simulated test's camera: synthetic:tensile, synthetic:stereo) or "
              "synthetic:tensile?... / synthetic:stereo?...")


def open_load(uri: str, **options: Any) -> LoadSource:
    """Open the force signal named by ``uri``.

    Parameters
    ----------
    uri : str
        ``csv:FILE``, ``tcp://HOST:PORT[?clock=arrival|sender]``, ``modbus://HOST:PORT?register=N...``,
        ``synthetic`` or ``synthetic:tensile?...`` / ``synthetic:stereo?...`` (see docs/guide/tensile-test.md).
    **options
        csv: ``offset_s`` (``--load-offset``), ``max_gap_s`` (default: see ``csv_max_gap_s``).
        synthetic: ``source`` (the simulated test's camera, or a stereo pair of its views; required for plain
        ``synthetic``),
        ``offset_s``, ``max_gap_s``.
        tcp: ``clock``, ``max_gap_s``, ``retry_s``, ``keep_s``, ``max_samples``, ``connect_timeout_s``,
        ``poll_s``, ``offset_s``. modbus: ``register``, ``scale``, ``kind``, ``type``, ``word_order``,
        ``unit``, ``rate``, ``max_gap_s``, ``retry_s``, ``timeout_s``, ``keep_s``, ``max_samples``,
        ``offset_s``. They override the query string.

    Returns
    -------
    LoadSource
        A tcp or modbus source is returned at once, connected or not: its ``events()`` say which.

    Raises
    ------
    LoadError
        (a ``ValueError``) one line: malformed or unknown URI, a scheme not built yet, a bad option or file.
    """
    if not isinstance(uri, str) or not uri.strip():
        raise LoadError(f"empty load URI; {LOAD_USAGE}")
    uri = uri.strip()
    scheme, sep, rest = uri.partition(":")
    scheme = scheme.lower()
    if scheme == "synthetic":
        return _open_synthetic(uri, options)
    if not sep or scheme not in ("csv", "tcp", "modbus"):
        raise LoadError(f"unknown load {uri!r}; {LOAD_USAGE}")
    if scheme == "tcp":
        return _open_tcp(uri, options)
    if scheme == "modbus":
        return _open_modbus(uri, options)
    if not rest:
        raise LoadError(f"load {uri!r} names no file; {LOAD_USAGE}")
    offset_s = _option("offset_s", options.pop("offset_s", 0.0))
    max_gap_s = options.pop("max_gap_s", None)
    if max_gap_s is not None:
        max_gap_s = _option("max_gap_s", max_gap_s, low=0.0, low_open=True)
    if options:
        raise LoadError(f"load {uri!r}: unknown option(s) {', '.join(sorted(options))}; csv takes offset_s, max_gap_s")
    return CsvLoad(rest, offset_s=offset_s, max_gap_s=max_gap_s, uri=uri)
