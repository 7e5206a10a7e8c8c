"""``open_load(uri)``: the testing machine's force signal, opened from a URI like a frame source.

Valid forms::

    csv:FILE                         a file exported by the machine's software (header ``time_s,force_N``)
    tcp://HOST:PORT[?clock=arrival|sender]   text lines ``force_N`` or ``time_s,force_N`` over TCP
    modbus://HOST:PORT?register=N[&scale=K&...]   one register of a PLC, polled (Modbus TCP, pymodbus)
    synthetic                        the simulator's force: ``open_load("synthetic", source=SOURCE)``
                                     with SOURCE the session's ``synthetic:tensile`` camera
    synthetic:tensile?...            the same force for a simulated test named by its camera URI
                                     (nothing is rendered: the force needs only the model)

Every error is a ``LoadError`` (a ``ValueError``) of one line, naming the file and line or the
option at fault.

Time bases (``LoadSource.time_base``)
-------------------------------------
Each source gives force at times on one clock, in seconds:

* ``"session"`` (``csv:``, ``synthetic``): seconds since the session's first frame, as the machine's software
  exports them, shifted by ``offset_s`` (the CLI's ``--load-offset S``): a sample written at
  ``time_s`` belongs to frame time ``time_s + offset_s``. The session passes each frame's
  timestamp relative to the first frame: ``(frame.timestamp_ns - first.timestamp_ns) / 1e9``.
  ``synthetic`` has one sample per frame of the simulated camera, frame i at ``i / fps``: its
  ``force_N(i)`` (``acquire.simulator.sources``, module notes, Force), exact at frame times; between two
  frames the force is interpolated linearly (so across the fracture it falls from the last loaded
  frame's force to 0). ``max_gap_s`` is 5 frame periods (0.5 s at least), as a csv's.
* ``"monotonic"`` (``tcp://``, ``modbus://``): ``time.monotonic_ns() / 1e9``, the clock that stamps frame
  arrival (``stream.pipeline.tracker_loop``'s ``arrival_ns``). Each line is stamped when it arrives, unless
  ``?clock=sender`` says its ``time_s`` is already on that clock (a sender on the same host that
  stamps with ``time.monotonic()``: the exact time of the reading, not of its delivery); each
  Modbus value halfway between its request and the answer. The session passes each frame's
  arrival: ``arrival_ns / 1e9``. ``offset_s`` (``--load-offset``) is added to a stream's sample
  times too (a known delay of the sender, negative), 0 by default.

``LoadSource.frame_time_s(since_first_frame_s=..., arrival_ns=...)`` picks the one its base needs.

Interpolation (``force_at``)
----------------------------
Linear between the two samples around each frame time; NaN before the first sample, after the
last one (never extrapolated), and where the two samples are more than ``max_gap_s`` apart (a
stream that stalled: a stale value is never used), or around a NaN marker (a stream leaves one
where a connection was lost or a Modbus poll got no value, so nothing is interpolated across it).
``max_gap_s`` defaults to 0.5 s for tcp, for modbus to 0.5 s or 5 poll periods, and for csv to
0.5 s or 5 median sample intervals of the file, whichever is longer.

A live frame usually arrives before the stream's next sample: ``force_when_known(time_s)`` waits
for it, bounded (until ``time_s`` plus two recent sample intervals and the delivery lag, at most
``max_gap_s``, on the monotonic clock; not at all when the stream has stalled), and is
``force_at`` for a file or the simulator.

TCP source
----------
A background thread connects (client), reads lines and stamps them; a line that is not one or
two finite numbers is counted (``warnings.garbage_lines``) and skipped, the first of a
connection also a ``bad_data`` event. Lines that arrive in one
read share one arrival instant: with arrival stamping only the last of them is kept (the
freshest reading; the others are counted in ``warnings.superseded``), so a fast DAQ stream is
thinned to the rate of reads: use ``?clock=sender`` for every sample with its true time. With
sender times a sample not later than the previous one is counted (``warnings.out_of_order``) and
skipped, and a bare ``force_N`` line (no time) is garbage. No data for ``max_gap_s`` is a ``stalled`` event (``resumed`` when data comes back); a
refused or lost connection is an event (and, with arrival stamping, a NaN marker) and the thread
reconnects every ``retry_s`` (1 s). ``close()`` stops the thread (joined with a timeout).

Modbus source
-------------
``modbus://HOST:PORT?register=N&scale=K`` polls one value with a pymodbus ``ModbusTcpClient``
from a background thread (``ModbusLoad``). Options in the query (or as keywords of ``open_load``):

==============  ==========================================================  =================
option          meaning                                                     default
==============  ==========================================================  =================
``register``    address of the (first) register, 0-based as sent on the      required
                wire (the register a manual calls 40001 or 30001 is 0)
``scale``       newtons per unit: ``force_N = value x scale`` (non-zero)     1
``kind``        ``holding`` (function 3) or ``input`` (function 4)           holding
``type``        ``int16``, ``uint16``, ``int32``, ``uint32``, ``float32``;     int16
                32-bit types read 2 registers
``word_order``  ``big`` (first register = high word) or ``little``           big
``unit``        the device (slave, unit) id, 0-255                           1
``rate``        polls per second, at most 1000                               100
``max_gap_s``   a longer hole between values is a stall (NaN)                 max(0.5, 5/rate)
``timeout_s``   connect and answer timeout of one poll                        0.25
``retry_s``     reconnect period after a lost or refused connection           1
``keep_s``, ``max_samples``, ``offset_s``: as for tcp
==============  ==========================================================  =================

Values are decoded by pymodbus (``convert_from_registers``). Each answered poll is a sample
stamped halfway between request and answer. A poll answered with a Modbus exception (a wrong
register, kind or unit), not answered within ``timeout_s``, or holding a non-finite float32 is
counted (``warnings.exception_responses``, ``timeouts``, ``bad_values``), leaves a NaN marker
(no force is interpolated across it) and, first of a run of failures, is a ``read_failed``
event; after a timeout the connection is reopened (a late answer must not pass for the next
poll's). Stall, resume, refused and lost connections are events as for tcp, never an exception
in the session; pymodbus's own log records are kept off stderr (a ``NullHandler`` on the
``pymodbus`` logger) since each is said once as an event.

Memory is bounded: the last ``keep_s`` seconds (600) are kept, and at most ``max_samples``
(2,000,000 samples, 32 MB: 600 s at 3.3 kHz); older samples are dropped (counted in
``warnings.trimmed``, not an error). A 20,000-frame session at 50 fps lasts 400 s.
"""

from livedic.acquire.force.csv_file import CsvLoad
from livedic.acquire.force.modbus import _open_modbus
from livedic.acquire.force.simulated import _open_synthetic
from livedic.acquire.force.source import LoadError, _option
from livedic.acquire.force.tcp import _open_tcp

__all__ = ["open_load", "LOAD_USAGE"]

LOAD_USAGE = ("valid loads: csv:FILE (header time_s,force_N), tcp://HOST:PORT[?clock=arrival|sender], "
              "modbus://HOST:PORT?register=N[&scale=K...], "
              "synthetic (with the synthetic:tensile camera) or synthetic:tensile?...")


def open_load(uri, **options):
    """Open the force signal named by ``uri``.

    Parameters
    ----------
    uri : str
        ``csv:FILE``, ``tcp://HOST:PORT[?clock=arrival|sender]``, ``modbus://HOST:PORT?register=N...``,
        ``synthetic`` or ``synthetic:tensile?...`` (see the module notes).
    **options
        csv: ``offset_s`` (``--load-offset``), ``max_gap_s`` (default: see ``csv_max_gap_s``).
        synthetic: ``source`` (the ``synthetic:tensile`` camera; required for plain ``synthetic``),
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
