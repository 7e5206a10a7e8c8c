"""Aravis fake cameras serving OUR images, for tests and the live benchmark.

Two fakes, both driven through the real Aravis stack:

* :class:`InProcessFakeCamera` — Aravis's in-process ``Fake_1`` device. While the
  context is active, opening ``aravis:Fake_1`` serves ``image_fn(k)``.
* :class:`GigEFakeCamera` — an ``Aravis.GvFakeCamera`` (GigE Vision simulator)
  in a child Python process on 127.0.0.1 (GVCP port 3956, loopback only), found
  by discovery like a real GigE camera. ``kill()`` simulates a lost camera.

``image_fn(k)`` returns frame k's image (uint8 or uint16, 2-D); ``k`` counts
the frames the camera has produced since the device was opened (in-process)
or since the simulator started or ``reset_count()`` (GigE), so it equals
``Frame.index`` for a freshly opened camera (GigE: after ``reset_count()``).
:class:`SpeckleMotion` is a picklable ``image_fn``: a
speckle pattern translated by a known integer displacement per frame, so
measured displacements can be checked against the truth.

How images get in: ``FakeCamera.set_fill_pattern`` through gi segfaults (gi frees
the callback on return), so ``arv_fake_camera_set_fill_pattern`` is called from
``libaravis-0.8.so.0`` through ctypes, with the ``CFUNCTYPE`` object kept
referenced for the camera's whole life (released only after the stream and the
camera are destroyed). The callback copies the image into the buffer Aravis
hands it: the camera's ROI offset crops a larger image like a real sensor; a
smaller image is zero-padded; :func:`served_as` converts it to the pixel format's
bit depth (uint8 x 257 for Mono16, uint16 >> 8 for Mono8) and packed formats are
packed (``acquire.camera.pixel_formats.pack``).

Aravis's fakes offer Mono8 and Mono16 only and no user sets;
:func:`extended_genicam_xml` adds the 10/12-bit formats (packed and unpacked),
more trigger entries and a user set selector for tests (``genicam=`` of each fake).

Run a GigE fake camera by hand (Ctrl-C stops it)::

    python -m acquire.camera.fake_genicam --size 1024x1024 --step 1,-1
    livedic cameras        # lists Aravis-Fake-LIVEDIC0 at 127.0.0.1
"""

import argparse
import contextlib
import ctypes
import errno
import fcntl
import json
import logging
import os
import pickle
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time

import numpy as np

from livedic.acquire.base import SourceError
from livedic.acquire.camera import aravis as _aravis
from livedic.acquire.camera import pixel_formats

__all__ = ["SpeckleMotion", "InProcessFakeCamera", "GigEFakeCamera", "ArvFakeGvCamera", "FillPattern", "GVCP_PORT",
           "ARV_FAKE_GV_CAMERA", "extended_genicam_xml", "served_as"]

log = logging.getLogger("livedic.acquire.camera.fake_genicam")

GVCP_PORT = 3956


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

    def __init__(self, shape=(512, 512), *, step=(1, -1), max_displacement=32, bit_depth=8, seed=0,
                 speckle_px=2.0, pattern="blur"):
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
        self._canvas = None

    def __getstate__(self):  # pickled into the GigE child: send parameters, not pixels
        state = dict(self.__dict__)
        state["_canvas"] = None
        return state

    def __repr__(self):
        return (f"SpeckleMotion(shape={self.shape}, step={self.step}, max_displacement={self.max_displacement}, "
                f"bit_depth={self.bit_depth}, seed={self.seed})")

    @property
    def dtype(self):
        return np.uint8 if self.bit_depth == 8 else np.uint16

    def displacement(self, k):
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
_LIB = None


def _libaravis():
    global _LIB
    if _LIB is None:
        _aravis.load_aravis()  # the same library gi loaded
        lib = ctypes.CDLL("libaravis-0.8.so.0")
        lib.arv_fake_camera_set_fill_pattern.argtypes = [ctypes.c_void_p, _FILL_TYPE, ctypes.c_void_p]
        lib.arv_fake_camera_set_fill_pattern.restype = None
        lib.arv_buffer_get_data.argtypes = [ctypes.c_void_p, ctypes.POINTER(ctypes.c_size_t)]
        lib.arv_buffer_get_data.restype = ctypes.c_void_p
        for name in ("arv_buffer_get_image_width", "arv_buffer_get_image_height",
                     "arv_buffer_get_image_x", "arv_buffer_get_image_y"):
            getattr(lib, name).argtypes = [ctypes.c_void_p]
            getattr(lib, name).restype = ctypes.c_int
        _LIB = lib
    return _LIB


def _set_fake_genicam(path):
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

    Keep this object referenced until the camera that uses it is destroyed:
    the C side holds a bare pointer to the callback.
    """

    def __init__(self, image_fn):
        self.image_fn = image_fn
        self.frames_served = 0
        self.errors = 0
        self.last_error = None
        self._callback = _FILL_TYPE(self._fill)

    def install(self, fake_camera):
        """Attach to a gi ``Aravis.FakeCamera``."""
        _libaravis().arv_fake_camera_set_fill_pattern(_gobject_address(fake_camera), self._callback, None)

    def _fill(self, buffer, _data, _exposure_us, _gain, pixel_format):
        # Runs in an Aravis thread: an exception must not cross into C.
        try:
            k = self.frames_served
            self.frames_served += 1
            lib = _LIB
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


def served_as(image, bit_depth):
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


# --------------------------------------------------------------------------- #
# A GenICam description with what Aravis's fake lacks
# --------------------------------------------------------------------------- #

_EXTRA_PIXEL_FORMATS = ("Mono10", "Mono12", "Mono10p", "Mono12p", "Mono10Packed", "Mono12Packed")
# Registers of the added user-set features: free in the fake's memory (its own end at TestRegister 0x1f0).
USER_SET_SELECTOR_REGISTER = 0x1F4
USER_SET_LOAD_REGISTER = 0x1F8


def _int_reg(name, address):
    return (f'\t<IntReg Name="{name}" NameSpace="Custom">\n\t\t<Address>0x{address:x}</Address>\n'
            "\t\t<Length>4</Length>\n\t\t<AccessMode>RW</AccessMode>\n\t\t<pPort>Device</pPort>\n"
            "\t\t<Sign>Unsigned</Sign>\n\t\t<Endianess>BigEndian</Endianess>\n\t</IntReg>\n\n")


def _entry(name, value):
    return f'\t\t<EnumEntry Name="{name}" NameSpace="Standard">\n\t\t\t<Value>{value}</Value>\n\t\t</EnumEntry>\n'


def _insert_before(xml, anchor, text):
    if anchor not in xml:
        raise SourceError(f"Aravis's fake-camera XML has changed: {anchor.strip()!r} not found")
    return xml.replace(anchor, text + anchor, 1)


def extended_genicam_xml():
    """Aravis's fake-camera GenICam XML (this Aravis's own) with more for tests.

    Added: the pixel formats Mono10, Mono12, Mono10p, Mono12p, Mono10Packed and Mono12Packed (the
    fakes size and stamp each frame by the code, and :class:`FillPattern` packs it); TriggerSource
    Line1 and TriggerActivation FallingEdge; UserSetSelector (Default, UserSet1) and UserSetLoad on
    registers that only store what is written (``UserSetLoadRegister`` reads 1 once a set was loaded).
    The registers are the fake's, so both fakes serve it (``genicam=`` of each).
    """
    Aravis, _ = _aravis.load_aravis()
    xml = Aravis.FakeCamera.new("XML").get_genicam_xml()[0]
    formats = "".join(_entry(name, pixel_formats.FORMATS[name].code) for name in _EXTRA_PIXEL_FORMATS)
    xml = _insert_before(xml, "\t\t<pValue>PixelFormatRegister</pValue>", formats)
    xml = _insert_before(xml, "\t\t<pValue>TriggerSourceRegister</pValue>", _entry("Line1", 2))
    xml = _insert_before(xml, "\t\t<pValue>TriggerActivationRegister</pValue>", _entry("FallingEdge", 1))
    user_sets = (
        '\t<Enumeration Name="UserSetSelector" NameSpace="Standard">\n' + _entry("Default", 0)
        + _entry("UserSet1", 1) + "\t\t<pValue>UserSetSelectorRegister</pValue>\n\t</Enumeration>\n\n"
        + _int_reg("UserSetSelectorRegister", USER_SET_SELECTOR_REGISTER)
        + '\t<Command Name="UserSetLoad" NameSpace="Standard">\n\t\t<pValue>UserSetLoadRegister</pValue>\n'
        "\t\t<CommandValue>1</CommandValue>\n\t</Command>\n\n"
        + _int_reg("UserSetLoadRegister", USER_SET_LOAD_REGISTER))
    return _insert_before(xml, "\t<!-- Port -->", user_sets)


# --------------------------------------------------------------------------- #
# In-process Fake camera
# --------------------------------------------------------------------------- #

class InProcessFakeCamera:
    """While active, ``aravis:Fake_1`` serves ``image_fn(k)`` (Aravis's in-process Fake device).

    Sensor 2048x2048 (ROI default 512x512), Mono8 and Mono16 (more with
    ``genicam=`` a file holding :func:`extended_genicam_xml`). Each time an
    ``AravisCamera`` opens the device it is a new device in its power-on state and
    a fresh :class:`FillPattern` is attached (``k`` restarts at 0), kept alive by
    that source until it is closed.

    Examples
    --------
    >>> from acquire.camera.aravis import open_uri
    >>> with InProcessFakeCamera(SpeckleMotion((512, 512))) as fake:       # doctest: +SKIP
    ...     with open_uri(fake.uri, frame_rate=100) as camera:
    ...         frame = next(iter(camera))
    """

    def __init__(self, image_fn=None, *, device_id="Fake_1", genicam=None):
        self.image_fn = image_fn if image_fn is not None else SpeckleMotion()
        self.device_id = device_id
        self.genicam = genicam
        self.patterns = []  # one FillPattern per open, newest last

    @property
    def uri(self):
        return f"{_aravis.SCHEME}:{self.device_id}"

    def _attach(self, camera):
        pattern = FillPattern(self.image_fn)
        pattern.install(camera.get_device().get_fake_camera())
        self.patterns.append(pattern)
        return pattern

    def start(self):
        Aravis, _ = _aravis.load_aravis()
        Aravis.enable_interface("Fake")
        if self.genicam is not None:
            _set_fake_genicam(str(self.genicam))   # read by each new Fake device
        _aravis.FAKE_FILL_HOOKS[self.device_id] = self._attach
        return self

    def stop(self):
        if _aravis.FAKE_FILL_HOOKS.get(self.device_id) == self._attach:
            del _aravis.FAKE_FILL_HOOKS[self.device_id]
        if self.genicam is not None:
            _set_fake_genicam(None)                # Aravis's own XML again

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
        return False


# --------------------------------------------------------------------------- #
# GigE Vision fake camera in a child process
# --------------------------------------------------------------------------- #

def _serve_gige_child():
    """Child process body (``python -m acquire.camera.fake_genicam --child``).

    stdin: 8-byte length + pickle of ``(image_fn, address, serial, genicam)``, then command
    lines (``stats``, ``reset``, ``stop``); EOF (the parent died) also stops. stdout: one
    JSON line per answer, the first being ``{"ready": ...}`` or ``{"error": ...}``.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    stdin, stdout = sys.stdin.buffer, sys.stdout

    def answer(**message):
        stdout.write(json.dumps(message) + "\n")
        stdout.flush()

    camera = pattern = None
    try:
        size = int.from_bytes(stdin.read(8), "little")
        image_fn, address, serial, genicam = pickle.loads(stdin.read(size))
        Aravis, _ = _aravis.load_aravis()
        camera = Aravis.GvFakeCamera.new_full(address, serial, genicam)
        if camera is None or not camera.is_running():
            answer(error=f"Aravis.GvFakeCamera did not start on {address}:{GVCP_PORT}")
            return 1
        pattern = FillPattern(image_fn)
        pattern.install(camera.get_fake_camera())
        answer(ready=True, pid=os.getpid())
        for line in stdin:
            command = line.strip()
            if command == b"stop":
                break
            if command == b"stats":
                answer(frames_served=pattern.frames_served, errors=pattern.errors, last_error=pattern.last_error)
            if command == b"reset":
                pattern.frames_served = 0
                answer(reset=True)
    except BaseException as error:  # noqa: BLE001 - reported to the parent
        with contextlib.suppress(Exception):
            answer(error=f"{type(error).__name__}: {error}")
        return 1
    finally:
        del camera   # stops the simulator thread before the callback goes
        del pattern
    return 0


def _port_in_use(address, port):
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.bind((address, port))
    except OSError as error:
        return error.errno == errno.EADDRINUSE
    finally:
        probe.close()
    return False


class _GvcpAddressLock:
    """Who may run a GigE simulator on ``address``: one at a time on this machine (GVCP port 3956).

    A lock file in the temp folder serialises livedic's simulators (waits up to ``timeout_s``); a port probe
    catches one started by other means. ``acquire()`` also waits for the teardown of a camera lost earlier
    in this process (its GVCP writes time out for ~7 s) so that they cannot reach the new simulator.
    """

    def __init__(self, address, timeout_s):
        self.address = address
        self.timeout_s = timeout_s
        self._file = None

    def acquire(self):
        path = os.path.join(tempfile.gettempdir(), f"livedic-fake-gige-{self.address}.lock")
        lock_file = open(path, "a+")
        deadline = time.monotonic() + self.timeout_s
        while True:
            try:
                fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    lock_file.close()
                    raise SourceError(f"another livedic fake GigE camera holds {self.address}:{GVCP_PORT} "
                                      f"(lock {path}) for more than {self.timeout_s:g} s") from None
                time.sleep(0.1)
        self._file = lock_file
        try:
            for thread in list(_aravis._TEARDOWN_THREADS):
                thread.join(timeout=15)
            if _port_in_use(self.address, GVCP_PORT):
                raise SourceError(f"UDP {self.address}:{GVCP_PORT} is already in use (another GigE Vision "
                                  "camera simulator, e.g. arv-fake-gv-camera-0.8?): stop it first")
        except BaseException:
            self.release()
            raise

    def release(self):
        if self._file is not None:
            try:
                fcntl.flock(self._file, fcntl.LOCK_UN)
            finally:
                self._file.close()
                self._file = None


def _stop_process(process, polite):
    """End a simulator process: ``polite()`` (may be None), then SIGTERM, then SIGKILL; waits for it."""
    steps = ([polite] if polite is not None else []) + [process.terminate, process.kill]
    for step in steps:
        if process.poll() is not None:
            break
        with contextlib.suppress(OSError, ValueError):
            step()
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=5)
    for pipe in (process.stdin, process.stdout, process.stderr):
        if pipe is not None:
            with contextlib.suppress(OSError, ValueError):
                pipe.close()


def _load_prctl():
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


_PRCTL = _load_prctl()           # looked up here: the forked child only calls it
_PR_SET_PDEATHSIG = 1


def _die_with_parent():
    """``preexec_fn``: the kernel kills the child when the thread that started it dies (a killed test run
    leaves no simulator holding port 3956). Linux only; elsewhere a no-op."""
    if _PRCTL is not None:
        _PRCTL(_PR_SET_PDEATHSIG, int(signal.SIGKILL))


class _Simulator:
    """A GigE simulator process (``serial``, ``_process``): ``with simulator:`` starts it and stops it;
    dropping it stops it too (the address is freed)."""

    @property
    def device_id(self):
        """The Aravis id discovery lists it by."""
        return f"Aravis-Fake-{self.serial}"

    @property
    def alive(self):
        return self._process is not None and self._process.poll() is None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
        return False

    def __del__(self):
        with contextlib.suppress(Exception):
            self.stop()


class GigEFakeCamera(_Simulator):
    """A GigE Vision fake camera on 127.0.0.1, in a child process, serving ``image_fn(k)``.

    Only one can listen on an address (GVCP port 3956): a lock file in the
    temp folder serialises users on this machine (waits up to ``lock_timeout_s``),
    and a port probe catches a simulator started by other means
    (``arv-fake-gv-camera-0.8``).

    Parameters
    ----------
    image_fn : picklable callable ``k -> ndarray``
        Defaults to ``SpeckleMotion()``. Pickled to a child Python
        (``python -m acquire.camera.fake_genicam --child``), so it must be picklable and
        importable there (a module-level function or an object such as SpeckleMotion).
    serial : str
        Serial number; the Aravis device id is ``"Aravis-Fake-" + serial``.
    address : str
        IPv4 address of a local interface to listen on (loopback by default).
    genicam : str, optional
        A GenICam XML file to serve instead of Aravis's (e.g. :func:`extended_genicam_xml`).

    Notes
    -----
    Loopback throughput depends on the packet size: livedic opens a loopback camera with
    9000-byte packets unless ``packet_size`` says otherwise (the camera's default is 1400).
    """

    def __init__(self, image_fn=None, *, serial="LIVEDIC0", address="127.0.0.1", genicam=None,
                 start_timeout_s=20.0, lock_timeout_s=60.0):
        self.image_fn = image_fn if image_fn is not None else SpeckleMotion()
        self.serial = serial
        self.address = address
        self.genicam = None if genicam is None else str(genicam)
        self.start_timeout_s = start_timeout_s
        self.lock_timeout_s = lock_timeout_s
        self._process = None
        self._lock = _GvcpAddressLock(address, lock_timeout_s)

    @property
    def uri(self):
        """``aravis:<address>``: opening by address skips matching the discovered list."""
        return f"{_aravis.SCHEME}:{self.address}"

    @property
    def pid(self):
        return self._process.pid if self._process is not None else None

    def start(self):
        """Start the child and wait until the camera listens; returns self."""
        if self._process is not None:
            return self
        self._lock.acquire()
        try:
            payload = pickle.dumps((self.image_fn, self.address, self.serial, self.genicam))
            root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
            env = dict(os.environ)
            env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
            self._process = subprocess.Popen(
                [sys.executable, "-m", "livedic.acquire.camera.fake_genicam", "--child"], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, cwd=root, env=env, start_new_session=True, preexec_fn=_die_with_parent)
            self._process.stdin.write(len(payload).to_bytes(8, "little") + payload)
            self._process.stdin.flush()
            message = self._read_answer(self.start_timeout_s)
            if message is None:
                raise SourceError(f"fake GigE camera did not start within {self.start_timeout_s:g} s")
            if "ready" not in message:
                raise SourceError(f"fake GigE camera failed to start: {message.get('error', message)}")
        except BaseException:
            self.stop()
            raise
        return self

    def _read_answer(self, timeout_s):
        stdout = self._process.stdout
        ready, _, _ = select.select([stdout], [], [], timeout_s)
        if not ready:
            return None
        line = stdout.readline()
        if not line:
            return {"error": f"child exited (code {self._process.poll()})"}
        return json.loads(line)

    def served(self):
        """``{"frames_served", "errors", "last_error"}`` from the child, or ``None`` if it is gone."""
        if not self.alive:
            return None
        try:
            self._process.stdin.write(b"stats\n")
            self._process.stdin.flush()
            return self._read_answer(2.0)
        except (OSError, ValueError):
            return None

    def reset_count(self):
        """Restart ``k`` at 0: call it before opening a stream so ``Frame.index`` equals ``k``."""
        if not self.alive:
            raise SourceError("the fake GigE camera is not running")
        self._process.stdin.write(b"reset\n")
        self._process.stdin.flush()
        if self._read_answer(2.0) != {"reset": True}:
            raise SourceError("the fake GigE camera did not acknowledge reset")

    def kill(self):
        """SIGKILL the child: the camera vanishes mid-stream, like a pulled cable."""
        if self.alive:
            self._process.kill()
            self._process.wait(timeout=5)

    def stop(self):
        """Stop the child (politely, then by force) and free the address."""
        process, self._process = self._process, None
        try:
            if process is not None:
                def ask():
                    process.stdin.write(b"stop\n")
                    process.stdin.flush()
                _stop_process(process, ask)
        finally:
            self._lock.release()



# --------------------------------------------------------------------------- #
# Aravis's own GigE Vision simulator (arv-fake-gv-camera-0.8)
# --------------------------------------------------------------------------- #

ARV_FAKE_GV_CAMERA = "arv-fake-gv-camera-0.8"


class ArvFakeGvCamera(_Simulator):
    """Aravis's GigE Vision simulator program, ``arv-fake-gv-camera-0.8 -i ADDRESS -s SERIAL``, as a user runs it.

    Its images are Aravis's own (a diagonal ramp), not ours; it is what a user tries first, and the
    camera livedic must open exactly as ``livedic cameras`` lists it. ``start()`` returns once GigE
    discovery finds the camera (not after a sleep); ``stop()`` ends it (SIGTERM, then SIGKILL) and the
    kernel kills it if this process dies. One simulator per address: it shares
    :class:`GigEFakeCamera`'s lock.

    Parameters
    ----------
    serial : str
        ``-s``: the Aravis id is ``"Aravis-Fake-" + serial``.
    address : str
        ``-i``: the address to listen on (loopback by default).
    genicam : str, optional
        ``-g``: a GenICam XML file to serve instead of the built-in one (its registers must be the fake's).
    program : str
        The simulator executable (looked up on PATH).

    Raises
    ------
    SourceError
        The program is missing, the address is taken, or discovery does not find it within
        ``start_timeout_s`` (its stderr is quoted).
    """

    def __init__(self, *, serial="GV01", address="127.0.0.1", genicam=None, program=ARV_FAKE_GV_CAMERA,
                 start_timeout_s=20.0, lock_timeout_s=60.0):
        self.serial = serial
        self.address = address
        self.genicam = genicam
        self.program = program
        self.start_timeout_s = start_timeout_s
        self._lock = _GvcpAddressLock(address, lock_timeout_s)
        self._process = None
        self._log = None
        self.listing = None            # the list_cameras() entry that found it

    def start(self):
        """Run the program and wait until GigE discovery lists it; returns self."""
        import shutil
        if self._process is not None:
            return self
        executable = shutil.which(self.program)
        if executable is None:
            raise SourceError(f"{self.program} is not installed (Debian package aravis-tools; "
                              "scripts/install_system.sh installs it)")
        self._lock.acquire()
        try:
            command = [executable, "-i", self.address, "-s", self.serial]
            if self.genicam:
                command += ["-g", str(self.genicam)]
            self._log = tempfile.TemporaryFile()
            self._process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=self._log,
                                             stderr=subprocess.STDOUT, start_new_session=True,
                                             preexec_fn=_die_with_parent)
            self.listing = self._wait_for_discovery()
        except BaseException:
            self.stop()
            raise
        return self

    def _wait_for_discovery(self):
        deadline = time.monotonic() + self.start_timeout_s
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise SourceError(f"{self.program} exited with code {self._process.returncode}: {self.output()}")
            # each discovery listens for answers until 1 s of silence: this is the wait
            found = [c for c in _aravis.list_cameras() if c["id"] == self.device_id]
            if found and found[0]["address"] == self.address:
                return found[0]
        raise SourceError(f"GigE discovery did not find {self.device_id} on {self.address} within "
                          f"{self.start_timeout_s:g} s; {self.program} said: {self.output() or 'nothing'}")

    def output(self):
        """What the program printed (stdout and stderr), for error messages."""
        if self._log is None:
            return ""
        self._log.seek(0)
        return self._log.read().decode(errors="replace").strip()[-2000:]

    def stop(self):
        """End the program and free the address."""
        process, self._process = self._process, None
        try:
            if process is not None:
                _stop_process(process, None)
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None
            self._lock.release()



# --------------------------------------------------------------------------- #
# Command line: run a GigE fake camera until Ctrl-C
# --------------------------------------------------------------------------- #

def _pair(text):
    parts = text.lower().replace("x", ",").split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected two integers, got {text!r}")
    return tuple(int(p) for p in parts)


def main(argv=None):
    if (sys.argv[1:] if argv is None else argv) == ["--child"]:
        return _serve_gige_child()
    parser = argparse.ArgumentParser(prog="python -m acquire.camera.fake_genicam",
                                     description="Run a GigE Vision fake camera on 127.0.0.1 serving a "
                                                 "moving speckle pattern (Ctrl-C stops it).")
    parser.add_argument("--size", type=_pair, default=(512, 512), metavar="WxH")
    parser.add_argument("--step", type=_pair, default=(1, -1), metavar="DU,DV",
                        help="integer displacement per frame (default 1,-1)")
    parser.add_argument("--max-displacement", type=int, default=32)
    parser.add_argument("--bit-depth", type=int, choices=(8, 16), default=8)
    parser.add_argument("--serial", default="LIVEDIC0")
    args = parser.parse_args(argv)
    width, height = args.size
    motion = SpeckleMotion((height, width), step=args.step, max_displacement=args.max_displacement,
                           bit_depth=args.bit_depth)
    with GigEFakeCamera(motion, serial=args.serial) as camera:
        print(f"fake GigE camera {camera.device_id} on {camera.address}: open "
              f"'{camera.uri}?roi=0,0,{width},{height}&pixel_format=Mono{8 if args.bit_depth == 8 else 16}"
              f"&packet_size=9000' (Ctrl-C stops)", flush=True)
        try:
            while camera.alive:
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
