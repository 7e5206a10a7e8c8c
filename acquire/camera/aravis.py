"""GenICam cameras (GigE Vision, USB3 Vision, Aravis's Fake camera) through Aravis 0.8 and gi.

URIs: ``aravis:`` opens the first camera found, ``aravis:DEVICE_ID`` a given one (its Aravis
id as ``livedic cameras`` lists it, serial number, MAC or, for GigE, IP address). Options ride
in a query string (``aravis:Fake_1?exposure_us=2000&roi=0,0,640,480&feature.GainRaw=3``) or
as keyword arguments of :func:`open_uri`; see ``AravisCamera.OPTIONS``.

Guarantees: a GigE camera is opened by its IP address (found by discovery), so it streams to
a reachable interface. Every open starts from a known state: an acquisition left running is
stopped, the ``Default`` user set loaded (``user_set=``), then continuous acquisition,
triggers off, binning 1, Mono8 and the full sensor unless asked otherwise. Every setting is
checked against the camera's bounds, applied, then READ BACK; ``settings`` reports what the
camera actually uses. Mono10/12/16 (unpacked or packed) arrive as uint16 with the camera's
grey levels, ``bit_depth`` in ``settings`` and each frame's metadata. A ``Frame.image`` is a
zero-copy view *lent* from the stream's buffer pool (``copy=True`` hands out copies);
``trigger=software`` / ``trigger=line:N`` as in the options. No frame within ``timeout_s``
plus 2 s raises ``NoFirstFrame``; a camera lost after delivering raises ``SourceError``
("lost"); ``close()`` returns at once, an ``atexit`` hook closes forgotten sources.

Why each of these, and the buffer pool: docs/guide/sources.md ("GenICam cameras: how
``aravis:`` behaves"). Finding cameras and their URIs: ``aravis_discovery``; the declared
settings: ``aravis_settings``.
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import logging
import math
import threading
import time
import weakref
from typing import Any

import numpy as np

from livedic.acquire.base import Frame, FrameSource, NoFirstFrame, SourceError
from livedic.acquire.camera import genicam
from livedic.acquire.camera import pixel_formats
from livedic.acquire.camera.aravis_discovery import (SCHEME, address_text, find_listed, gerror_message, interface_name,
                                                     is_ip_address, list_cameras, load_aravis, parse_uri)
from livedic.acquire.camera.aravis_settings import NO_USER_SET, SETTINGS, SUPPORTED_PIXEL_FORMATS, as_user_set, shown
from livedic.acquire.options import as_bool, as_float, as_int

__all__ = ["AravisCamera", "open_uri", "FEATURE_PREFIX"]

log = logging.getLogger("livedic.acquire.camera.aravis")

FEATURE_PREFIX = "feature."      # feature.NAME=VALUE: any GenICam feature by name

_POP_SLICE_US = 100_000          # wait for buffers in 100 ms slices so close() is honoured quickly
_MIN_FREE_BUFFERS = 2           # grow the pool when the consumer leaves fewer buffers than this
_FIRST_FRAME_EXTRA_S = 2.0       # start-up allowance added to timeout_s for the first frame
# Shortest default timeout_s: a lost camera is reported within a second (0.5 s + one 0.1 s pop slice),
# while a scheduling hiccup of a few hundred ms on a loaded machine is not taken for a loss.
_LOST_FLOOR_S = 0.5
_GV_ID_WRAP = 65535              # GigE Vision 16-bit block ids go 65535 -> 1 (0 is skipped)

# In-process Fake devices: device id -> attach(arv_camera) -> keep-alive object.
# ``acquire.camera.fake_genicam.InProcessFakeCamera`` registers here so that opening
# ``aravis:Fake_1`` serves its images; the keep-alive (the ctypes fill callback)
# is released only after the stream and camera are gone.
FAKE_FILL_HOOKS: dict = {}

_OPEN_SOURCES: weakref.WeakSet[AravisCamera] = weakref.WeakSet()
_TEARDOWN_THREADS: list[threading.Thread] = []


def open_uri(uri: str, **options: Any) -> AravisCamera:
    """Open an ``aravis:`` URI; keyword options override those in the query string."""
    device_id, query = parse_uri(uri)
    merged = {**query, **options}
    return AravisCamera(device_id, uri=uri, **merged)


class AravisCamera(FrameSource):
    """A GenICam camera through Aravis, yielding ``Frame`` objects (zero copy).

    Parameters
    ----------
    device_id : str or None
        Aravis device id (``livedic cameras``), serial, MAC or GigE IP address;
        ``None`` opens the first camera found.
    exposure_us, gain_db, frame_rate : float, optional
        Applied (auto modes switched off) and read back; ``None`` leaves the camera's value
        (as its user set has it). With ``trigger=software``, ``frame_rate`` is the trigger rate.
    roi : (x, y, w, h) or "x,y,w,h", optional
        Sensor region (in binned pixels); the camera may round to its increments (read back).
        Default: the full sensor.
    binning : (h, v) or "H[,V]", optional
        BinningHorizontal, BinningVertical (default 1, 1 where the camera bins).
    pixel_format : str, optional
        One of ``SUPPORTED_PIXEL_FORMATS`` (default Mono8, or the first the camera offers).
    trigger : str, optional
        ``free`` (default), ``software`` or ``line:N[:rising|falling]`` (``genicam.parse_trigger``).
    user_set : str, optional
        The user set loaded at open (default ``Default`` when the camera has one; ``none``: no user set).
    packet_size : int, optional
        GigE Vision packet size in bytes (jumbo frames need the NIC MTU; 9000 on loopback).
    n_buffers : int
        Buffers in the pool (default 10); frames held by the consumer hold buffers.
    timeout_s : float, optional
        No complete frame for this long means the camera is lost
        (default ``max(0.5, 3 / frame_rate + exposure)``; 1 s + exposure when the
        camera has no frame rate control; no limit for a line trigger).
    copy : bool
        Hand out copies and re-queue each buffer at once (default False: zero copy).
    **features
        ``feature.NAME=VALUE``: GenICam feature NAME set by its type and read back (after the
        settings above, so an explicit feature wins).

    Raises
    ------
    SourceError
        Aravis missing, unknown device (the message lists available ids),
        unsupported pixel format (lists the supported ones), a setting out of
        the camera's range, an unknown feature or a refused value, or the camera
        lost while streaming.
    NoFirstFrame
        The camera opened but never delivered a frame (a ``SourceError``).
    """

    SETTINGS = SETTINGS
    # Other options: how the source opens and streams rather than one camera setting.
    OPTIONS = {s.name: s.doc for s in SETTINGS} | {
        "user_set": "user set loaded at open (default Default where the camera has one; none: no user set)",
        f"{FEATURE_PREFIX}NAME": "any GenICam feature by name, set by its type and read back",
        "n_buffers": "buffers in the pool (default 10)",
        "timeout_s": "seconds without a frame before the camera counts as lost (line trigger: no limit)",
        "copy": "1 to copy frames out of the pool (default 0: zero copy)",
    }

    def __init__(self, device_id: str | None = None, *, uri: str | None = None, n_buffers: int | str = 10,
                 timeout_s: float | str | None = None, copy: bool | str = False,
                 user_set: str = genicam.DEFAULT_USER_SET, **settings: Any) -> None:
        features = {key[len(FEATURE_PREFIX):]: value for key, value in settings.items()
                    if key.startswith(FEATURE_PREFIX)}
        unknown = sorted(set(settings) - {s.name for s in self.SETTINGS} - {FEATURE_PREFIX + f for f in features})
        if unknown or "" in features:
            raise SourceError(f"unknown aravis option(s) {', '.join(unknown) or FEATURE_PREFIX}; "
                              f"known: {', '.join(self.OPTIONS)}")
        requested: dict[str, Any] = {}
        for setting in self.SETTINGS:
            value = settings.get(setting.name)
            if value is not None and value != "":
                requested[setting.name] = setting.parse(setting.name, value)
        self._requested = requested
        self._features_asked = {name: str(value) for name, value in features.items()}
        self._user_set_asked = as_user_set("user_set", user_set)
        self._software_trigger = requested.get("trigger", genicam.FREE_RUNNING).mode == "software"
        self._n_buffers = as_int("n_buffers", n_buffers)
        if self._n_buffers < 2:
            raise SourceError(f"n_buffers={self._n_buffers}: need at least 2")
        self._max_buffers = 4 * self._n_buffers
        self._timeout_option = None if timeout_s in (None, "") else as_float("timeout_s", timeout_s)
        if self._timeout_option is not None and self._timeout_option <= 0:
            raise SourceError(f"timeout_s={timeout_s}: must be > 0")
        self._copy = as_bool("copy", copy)
        self.uri = uri or f"{SCHEME}:{device_id or ''}"

        self._lock = threading.RLock()          # guards camera/stream calls and teardown
        self._recycle_lock = threading.RLock()  # guards push_buffer from lease finalizers
        # gi objects (Aravis.Camera, Aravis.Device, Aravis.Stream) while open: no type stubs, hence Any
        self._camera: Any = None
        self._device: Any = None
        self._stream: Any = None
        self._stream_alive = False
        self._keepalive: Any = None
        self._lost_handler: int | None = None
        self._control_lost = False
        self._lost = False
        self._closed = False
        self._closing = False
        self._started = False
        self._pool: dict[int, tuple[np.ndarray, Any]] = {}        # hash(buffer) -> (numpy array, Aravis.Buffer)
        self._n_leased = 0
        self._payload = 0
        self._grow_warned = False
        self._notes: list[str] = []
        self._frames = 0
        self._dropped = 0
        self._incomplete = 0
        self._copied = 0
        self._last_status = None
        self._first_id = None
        self._last_id = None
        self._index = -1
        self._waiting_first = True
        self._trigger_period_s = None
        self._next_trigger_t = 0.0
        self._triggers_fired = 0
        self._trigger_fired_by_caller = False    # hand_over_software_trigger: a stereo pair fires both cameras
        self._label = device_id or "(first camera)"
        self._info: dict[str, Any] = {}
        self._applied: dict[str, Any] = {}
        self._found: dict[str, Any] = {}
        self._features: dict[str, dict[str, Any]] = {}
        self._user_set: str | None = None
        try:
            self._open(device_id)
        except BaseException as error:
            self._teardown(background=False)
            _, GLib = load_aravis()
            if isinstance(error, GLib.Error):
                message = f"camera {self._label}: {gerror_message(error)}"
                error = None  # type: ignore[assignment]  # drops the traceback's frames before the raise
                raise SourceError(message) from None
            raise
        _OPEN_SOURCES.add(self)

    # ----------------------------------------------------------------- open
    def _call(self, what, function, *args):
        """Call an Aravis function; a GLib.Error becomes a SourceError naming the camera and step."""
        _, GLib = load_aravis()
        try:
            return function(*args)
        except GLib.Error as error:
            message = f"camera {self._label}: {what} failed: {gerror_message(error)}"
        # No gi object may stay referenced from the traceback's frames: whoever keeps the
        # exception would keep the camera alive and finalize it later, in some other thread.
        function = args = None
        raise SourceError(message)

    def _camera_new(self, device_id, *, asked, cameras=None):
        """``Aravis.Camera.new(device_id)``; SourceError naming ``asked`` and what is available."""
        Aravis, GLib = load_aravis()
        try:
            return Aravis.Camera.new(device_id)
        except GLib.Error as error:
            reason = gerror_message(error)
        if cameras is None:
            try:
                cameras = list_cameras(include_fake=asked is not None and asked.lower().startswith("fake"))
            except Exception:  # noqa: BLE001 - the open error is the one to report
                cameras = []
        ids = ", ".join(f"{c['id']} ({c['protocol']}, {c['address']})" for c in cameras) or "none found"
        if asked is None:
            raise SourceError(
                f"no GenICam camera found by Aravis ({reason}): check power and cable; "
                "a GigE camera must be on this computer's subnet; 'livedic cameras' lists what is seen")
        raise SourceError(f"camera '{asked}' not found ({reason}); available: {ids}")

    def _connect(self, device_id):
        """Open the camera ``device_id`` names: (Aravis.Camera, its listing entry or None); see the module notes."""
        Aravis, _ = load_aravis()
        if device_id is not None and device_id.lower().startswith("fake"):
            Aravis.enable_interface("Fake")
            return self._camera_new(device_id, asked=device_id), None
        if device_id is not None and is_ip_address(device_id):
            return self._camera_new(device_id, asked=device_id), None
        cameras = list_cameras()
        listed = find_listed(cameras, device_id)
        if listed is None:
            # Not listed by id, serial or MAC (a user-defined name, a host name): Aravis may still know it.
            return self._camera_new(device_id, asked=device_id, cameras=cameras), None
        by = listed["address"] if listed["protocol"] == "GigEVision" and listed["address"] else listed["id"]
        return self._camera_new(by, asked=device_id, cameras=cameras), listed

    def _describe(self, device_id, listed) -> None:
        """``self._info``: what the camera says it is (model, serial, firmware, sensor, address)."""
        cam = self._camera
        protocol = "GigEVision" if cam.is_gv_device() else "USB3Vision" if cam.is_uv_device() else "Fake"
        address = interface_address = None
        if cam.is_gv_device():
            address = address_text(self._device.get_device_address)
            interface_address = address_text(self._device.get_interface_address)   # where it streams to
        vendor, model, serial = cam.get_vendor_name(), cam.get_model_name(), cam.get_device_serial_number()
        # the id it was opened with (or found by, for the first camera), else Aravis's "vendor-model-serial"
        name = device_id or (listed or {}).get("id") or f"{vendor}-{model}-{serial}"
        info = {"device_id": name, "vendor": vendor, "model": model, "serial": serial, "protocol": protocol,
                "interface": interface_name(protocol), "address": address, "interface_address": interface_address}
        for key, feature in (("firmware", "DeviceFirmwareVersion"), ("device_version", "DeviceVersion")):
            info[key] = self._call(f"read {feature}", cam.get_string, feature) \
                if cam.is_feature_available(feature) else None
        sensor = cam.get_sensor_size()
        info["sensor_size"] = [sensor.width, sensor.height]
        self._info = info
        self._label = f"{name} ({vendor} {model} #{serial}, {protocol})"
        self._wrap16 = protocol == "GigEVision"

    def _open(self, device_id) -> None:
        self._camera, listed = self._connect(device_id)
        cam = self._camera
        self._device = cam.get_device()
        self._describe(device_id, listed)
        hook = FAKE_FILL_HOOKS.get(device_id) if device_id else None
        if hook is not None:
            self._keepalive = hook(cam)
        self._known_state()
        self._apply_features()
        for setting in self.SETTINGS:
            self._applied[setting.name] = setting.read(self)
        for name in self._features:      # a later feature may have changed an earlier one
            self._features[name]["read"] = genicam.read_feature(cam, self._call, name)
        self._check_applied()
        self._start_stream()

    def _known_state(self):
        """Stop, load the user set, reset what the session depends on, apply the settings asked (module notes)."""
        cam = self._camera
        # A session that ended without stopping the camera leaves it sending to that session's address;
        # the next AcquisitionStart would not make it take the new one.
        self._call("stop a running acquisition", cam.stop_acquisition)
        self._found = {setting.name: setting.read(self) for setting in self.SETTINGS}
        if self._user_set_asked != NO_USER_SET:
            if genicam.load_user_set(cam, self._call, self._user_set_asked):
                self._user_set = self._user_set_asked
            elif self._user_set_asked != genicam.DEFAULT_USER_SET:
                offered = genicam.user_sets(cam, self._call)
                raise SourceError(f"user_set={self._user_set_asked}: camera {self._label} "
                                  + (f"offers {', '.join(offered)}" if offered else "has no user sets"))
        if cam.is_feature_available("AcquisitionMode"):
            self._call("set AcquisitionMode=Continuous", cam.set_string, "AcquisitionMode", "Continuous")
        for setting in self.SETTINGS:
            value = self._requested[setting.name] if setting.name in self._requested else setting.default(self)
            if value is not None:
                setting.apply(self, value)
        changed = []
        for setting in self.SETTINGS:
            was, now = self._found[setting.name], setting.read(self)
            if setting.name not in self._requested and now != was:
                changed.append(f"{setting.name} {shown(was)} -> {shown(now)}")
        if changed:
            self._note("the camera was not in livedic's default state; set at open: " + "; ".join(changed))

    def _apply_features(self) -> None:
        for name, text in self._features_asked.items():
            asked, got, note = genicam.set_feature(self._camera, self._call, name, text)
            self._features[name] = {"asked": asked, "read": got}
            if note:
                self._note(note)

    def _check_applied(self):
        pixel_format = self._applied["pixel_format"]
        if pixel_formats.by_name(pixel_format) is None:
            raise SourceError(f"camera {self._label} streams {pixel_format}, not one of "
                              f"{', '.join(SUPPORTED_PIXEL_FORMATS)}")
        for name, asked in self._requested.items():
            got = self._applied.get(name)
            if got is None or name == "frame_rate" and self._software_trigger:
                continue
            if isinstance(asked, float) and not math.isclose(asked, got, rel_tol=1e-3, abs_tol=1e-6):
                self._note(f"{name}: asked {asked:g}, camera set {got:g}")
            elif isinstance(asked, tuple) and tuple(got) != asked:
                self._note(f"{name}: asked {asked}, camera set {tuple(got)}")

    def _start_stream(self):
        cam = self._camera
        trigger = self._requested.get("trigger", genicam.FREE_RUNNING)
        exposure_s = (self._applied.get("exposure_us") or 0.0) * 1e-6
        frame_rate = self._applied.get("frame_rate") or 0.0
        if self._software_trigger:
            frame_rate = self._requested.get("frame_rate") or frame_rate
            if not frame_rate > 0:
                raise SourceError(f"trigger=software: give frame_rate=F, the rate livedic fires the trigger at "
                                  f"(camera {self._label} has no frame rate to take it from)")
            self._trigger_period_s = 1.0 / frame_rate
        if self._timeout_option is not None:
            self._timeout_s = self._timeout_option
        elif trigger.mode == "line":
            self._timeout_s = None   # the hardware decides when frames come
        else:
            period = 3.0 / frame_rate if frame_rate > 0 else 1.0
            self._timeout_s = max(_LOST_FLOOR_S, period + exposure_s)

        if cam.is_gv_device():
            self._lost_handler = self._device.connect("control-lost", self._on_control_lost)

        self._stream = self._call("create stream", cam.create_stream, None, None)
        if self._stream is None:
            raise SourceError(f"camera {self._label}: Aravis could not create a stream")
        self._stream_alive = True
        self._payload = int(cam.get_payload())
        for _ in range(self._n_buffers):
            self._add_buffer()

    def _note(self, text) -> None:
        self._notes.append(text)
        log.info("%s: %s", self._label, text)

    def _on_control_lost(self, *_args) -> None:
        self._control_lost = True

    def _add_buffer(self) -> None:
        Aravis, _ = load_aravis()
        array = np.empty(self._payload, np.uint8)
        buffer = Aravis.Buffer.new_full(self._payload, array.ctypes.data, None, None)
        self._pool[hash(buffer)] = (array, buffer)
        self._stream.push_buffer(buffer)

    # ------------------------------------------------------------- settings
    @property
    def live(self) -> bool:
        return True          # a camera: frames at its own pace

    @property
    def settings(self) -> dict[str, Any]:
        """What the camera reports (read back), what was asked, and stream counters (the session metadata)."""
        out = {"source": SCHEME, "uri": self.uri, **self._info}
        out.update({k: _plain(v) for k, v in self._applied.items()})
        fmt = pixel_formats.by_name(self._applied.get("pixel_format") or "")
        out["bit_depth"] = fmt.bit_depth if fmt is not None else None
        out["frame_pixel_format"] = fmt.frame_format if fmt is not None else None
        out["requested"] = {k: _plain(v) for k, v in self._requested.items()}
        out.update({
            "user_set": self._user_set,
            "features": {name: dict(values) for name, values in self._features.items()},
            "software_trigger_rate": 1.0 / self._trigger_period_s if self._trigger_period_s else None,
            "software_triggers": self._triggers_fired,
            "found_at_open": {k: _plain(v) for k, v in self._found.items()},
            "n_buffers": len(self._pool) or self._n_buffers,
            "payload_bytes": self._payload,
            "timeout_s": getattr(self, "_timeout_s", None),
            "copy": self._copy,
            "frames_delivered": self._frames,
            "frames_dropped": self._dropped,
            "incomplete_buffers": self._incomplete,
            "frames_copied": self._copied,
            "stream": self.stream_statistics(),
            "notes": list(self._notes),
        })
        return out

    def stream_statistics(self) -> dict[str, Any]:
        """Aravis stream counters: completed, failures, underruns, missing/resent packets (GigE)."""
        with self._recycle_lock:
            stream = self._stream if self._stream_alive else None
            if stream is None:
                return dict(getattr(self, "_last_stats", {}))
            return self._stats(stream)

    def _stats(self, stream):
        Aravis, _ = load_aravis()
        completed, failures, underruns = Aravis.Stream.get_statistics(stream)
        stats = {"n_completed": int(completed), "n_failures": int(failures), "n_underruns": int(underruns),
                 "n_missing_packets": 0, "n_resent_packets": 0}
        if self._wrap16:
            stats["n_missing_packets"] = int(stream.get_info_uint64_by_name("n_missing_packets"))
            stats["n_resent_packets"] = int(stream.get_info_uint64_by_name("n_resent_packets"))
        self._last_stats = stats
        return stats

    # ------------------------------------------------------------ streaming
    def __iter__(self):
        return _FrameIterator(self)

    def start_acquisition(self) -> None:
        """Start streaming now (iterating starts it too): a caller firing triggers needs the camera armed first."""
        self._start()

    def hand_over_software_trigger(self) -> float:
        """With ``trigger=software``: stop firing while waiting for frames, the caller fires (``fire_software_trigger``).

        Two cameras of a stereo pair must expose on the same trigger: one clock fires both. Returns the trigger
        rate asked (``frame_rate``), which the caller fires at and ``settings`` keep reporting.
        """
        if not self._software_trigger or self._trigger_period_s is None:
            raise SourceError(f"camera {self._label}: only a trigger=software camera hands over its trigger")
        self._trigger_fired_by_caller = True
        return 1.0 / self._trigger_period_s

    def fire_software_trigger(self) -> None:
        """Fire TriggerSoftware once (acquisition started first); SourceError naming the camera on failure.

        Not under the stream lock: a consumer waiting for a frame holds it for up to a pop slice.
        """
        camera = self._camera
        if self._closing or self._closed or camera is None:
            return
        self._start()
        self._call("software trigger", camera.software_trigger)
        self._triggers_fired += 1

    def _start(self) -> None:
        with self._lock:
            if not self._started and self._camera is not None and not self._closed:
                self._call("start acquisition", self._camera.start_acquisition)
                self._started = True
                self._waiting_first = True
                self._next_trigger_t = time.monotonic()

    def _fire_trigger(self, now):
        """With trigger=software: fire TriggerSoftware when due; the seconds until the next one."""
        if now >= self._next_trigger_t:
            self._call("software trigger", self._camera.software_trigger)
            self._triggers_fired += 1
            # Paced from the last trigger; after a pause (the consumer busy) start again, no burst.
            self._next_trigger_t = max(self._next_trigger_t + self._trigger_period_s, now)
        return self._next_trigger_t - now

    def _next_frame(self):
        """The next complete frame, ``None`` once closed; ``NoFirstFrame`` or ``SourceError`` (lost) on failure.

        The time limit counts from this call (a consumer that paused, e.g. between the first frame and
        the session's start, is no camera failure), or from the last frame while frames come.
        """
        Aravis, _ = load_aravis()
        success = Aravis.BufferStatus.SUCCESS
        error = None
        waiting_since = time.monotonic()
        while error is None:
            if self._closing or self._closed:
                return None
            if self._control_lost:
                error = self._failure("GigE control channel lost (heartbeat unanswered)")
                break
            with self._lock:
                stream = self._stream
                if stream is None:
                    return None
                if len(self._pool) - self._n_leased < _MIN_FREE_BUFFERS:
                    self._grow_pool()  # the consumer holds (almost) every buffer
                wait_us = _POP_SLICE_US
                if self._trigger_period_s is not None and not self._trigger_fired_by_caller:
                    try:
                        wait_us = min(wait_us, max(1000, int(1e6 * self._fire_trigger(time.monotonic()))))
                    except SourceError as trigger_error:
                        error = self._failure(f"{trigger_error}")
                        break
                buffer = stream.timeout_pop_buffer(wait_us)
                now = time.monotonic()
                waited = now - waiting_since
                limit = None if self._timeout_s is None else \
                    self._timeout_s + (_FIRST_FRAME_EXTRA_S if self._waiting_first else 0.0)
                if buffer is None:
                    if limit is not None and waited > limit:
                        error = self._failure(f"no frame for {waited:.1f} s")
                    continue
                if buffer.get_status() != success:
                    self._incomplete += 1
                    status = buffer.get_status()
                    self._last_status = getattr(status, "value_nick", str(status))
                    stream.push_buffer(buffer)
                    if limit is not None and waited > limit:
                        error = self._failure(f"no complete frame for {waited:.1f} s")
                    continue
                self._waiting_first = False
                return self._make_frame(buffer, stream)
        # As in _call: drop gi references before raising (the traceback keeps this frame).
        stream = buffer = None
        raise error

    def discard_buffered(self) -> int:
        """Give back to the camera every frame it has sent and no one has taken yet; returns how many.

        A session takes the first frame, prepares (points, set-up, outputs), then starts: the frames the
        camera sent meanwhile are stale, and read at once they would come in a burst the frame queue drops
        from (and, holding the buffers, starve the camera: frames lost upstream). Their frame ids leave a
        gap after the reference, which the session counts as sent while it was prepared.
        """
        discarded = 0
        with self._lock:
            stream = self._stream
            while stream is not None:
                buffer = stream.try_pop_buffer()
                if buffer is None:
                    break
                stream.push_buffer(buffer)
                discarded += 1
        return discarded

    def _grow_pool(self) -> None:
        """Add a buffer when the consumer holds almost all of them (up to the cap)."""
        if len(self._pool) >= self._max_buffers:
            return  # at the cap: _make_frame hands out copies instead of leases
        if not self._grow_warned:
            log.warning("%s: the consumer holds %d of %d buffers; growing the pool (max %d, then frames "
                        "are copied)", self._label, self._n_leased, len(self._pool), self._max_buffers)
            self._grow_warned = True
        with self._recycle_lock:
            if self._stream_alive:
                self._add_buffer()

    def _stream_counts(self) -> str:
        stats = self.stream_statistics()
        status = f", last incomplete buffer status {self._last_status}" if self._last_status else ""
        return (f"stream: {stats.get('n_completed', 0)} completed, {stats.get('n_failures', 0)} failed, "
                f"{stats.get('n_underruns', 0)} underruns, {stats.get('n_missing_packets', 0)} missing packets, "
                f"{self._incomplete} incomplete buffers{status}")

    def _failure(self, why):
        """The error for a stream that stopped: ``NoFirstFrame`` before any frame, else a loss."""
        self._lost = True
        timeout = "no limit" if self._timeout_s is None else f"timeout_s={self._timeout_s:g}"
        if self._waiting_first:
            return self._no_first_frame(why, timeout)
        hint = ("check power, cable and network (is the camera still on the same subnet?)"
                if self._info.get("protocol") == "GigEVision" else "check power and cable")
        return SourceError(f"camera {self._label} lost: {why} ({timeout}); {self._stream_counts()}; {hint}, "
                           "or raise timeout_s for slow triggers")

    def _no_first_frame(self, why, timeout):
        trigger = self._requested.get("trigger", genicam.FREE_RUNNING)
        checks = []
        if trigger.mode == "line":
            checks.append(f"the trigger (trigger={trigger} waits for a {trigger.edge} edge on {trigger.source}; "
                          "trigger=free runs without one)")
        elif trigger.mode == "software":
            checks.append(f"the trigger ({self._triggers_fired} software triggers fired, no frame came back)")
        if self._info.get("protocol") == "GigEVision":
            checks.append(f"the GigE packet size (packet_size={self._applied.get('packet_size')}: at most the "
                          "network's MTU) and a firewall letting the camera's UDP stream in")
        checks.append("that no other program (arv-viewer, the vendor's viewer) holds the camera")
        wait = "" if self._timeout_s is None else f" + {_FIRST_FRAME_EXTRA_S:g} s start-up"
        listed = "; ".join(f"({i}) {check}" for i, check in enumerate(checks, 1))
        return NoFirstFrame(
            f"camera {self._label} opened but sent no frame since acquisition started: {why} ({timeout}{wait}); "
            f"{self._stream_counts()}; it never started streaming (not a lost camera); check {listed}",
            checks=tuple(checks))

    def _frame_index(self, frame_id):
        if self._first_id is None:
            self._first_id = frame_id
            self._last_id = frame_id
            self._index = 0
            return 0, 0
        delta = frame_id - self._last_id
        if delta <= 0:
            if self._wrap16 and frame_id < 65536 and self._last_id < 65536:
                delta = (frame_id - self._last_id) % _GV_ID_WRAP or _GV_ID_WRAP
            else:
                delta = 1  # the camera restarted its counter: no way to count what was lost
        self._last_id = frame_id
        self._index += delta
        return self._index, delta - 1

    def _make_frame(self, buffer, stream):
        key = hash(buffer)
        array, _ = self._pool[key]
        code = buffer.get_image_pixel_format()
        fmt = pixel_formats.by_code(code)
        if fmt is None:
            stream.push_buffer(buffer)
            raise SourceError(f"camera {self._label} sent pixel format 0x{code:08x}, not one of "
                              f"{', '.join(SUPPORTED_PIXEL_FORMATS)}")
        width, height = buffer.get_image_width(), buffer.get_image_height()
        x_padding = buffer.get_image_padding()[0] if hasattr(buffer, "get_image_padding") else 0
        row_bytes = fmt.line_bytes(width) + x_padding
        size = row_bytes * height if x_padding or not fmt.packed else -(-width * height * fmt.bits_per_pixel // 8)
        if size > self._payload:
            stream.push_buffer(buffer)
            raise SourceError(f"camera {self._label} sent a {width}x{height} {fmt.name} image larger than "
                              f"the {self._payload}-byte buffers")
        frame_id = buffer.get_frame_id()
        timestamp = buffer.get_timestamp()
        system_ts = buffer.get_system_timestamp()
        index, dropped = self._frame_index(frame_id)
        self._dropped += dropped
        stats = self._stats(stream)
        if fmt.packed:
            # Unpacked into a new array: the buffer goes back to the camera at once.
            image = pixel_formats.unpack(array[:size], fmt, width, height, row_bytes if x_padding else None)
            stream.push_buffer(buffer)
        else:
            image = self._image_view(buffer, stream, array, (height, width), fmt.dtype, row_bytes)
        self._frames += 1
        metadata = {"frame_id": int(frame_id), "system_timestamp_ns": int(system_ts),
                    "dropped_before": int(dropped), "bit_depth": fmt.bit_depth, "stream": stats}
        return Frame(index=index, timestamp_ns=int(timestamp or system_ts), image=image,
                     pixel_format=fmt.frame_format, metadata=metadata)

    def _image_view(self, buffer, stream, array, shape, dtype, row_bytes):
        """The image in ``buffer``: a view lent to the consumer (zero copy), or a copy (see the module notes)."""
        height, width = shape
        must_copy = not self._copy and len(self._pool) - self._n_leased < _MIN_FREE_BUFFERS
        if must_copy:
            # Pool at its cap and the consumer keeps every frame: copy rather than starve the camera.
            self._copied += 1
            if self._copied == 1:
                log.warning("%s: all %d buffers are held by the consumer: copying frames from now on while "
                            "that lasts (copy the frames you keep, or open with copy=1)", self._label, len(self._pool))
        if self._copy or must_copy:
            flat = array[: row_bytes * height]
            image = np.ndarray(shape, dtype, flat, 0, (row_bytes, dtype.itemsize)).copy()
            stream.push_buffer(buffer)
            return image
        lease = _lease_type(self._payload).from_address(array.ctypes.data)
        lease.owner = self
        lease.buffer = buffer
        lease.array = array
        with self._recycle_lock:
            self._n_leased += 1
        return np.ndarray(shape, dtype, lease, 0, (row_bytes, dtype.itemsize))

    def _recycle(self, buffer) -> None:
        with self._recycle_lock:
            self._n_leased -= 1
            if self._stream_alive and self._stream is not None:
                self._stream.push_buffer(buffer)

    # ------------------------------------------------------------- teardown
    def close(self) -> None:
        """Stop acquisition, drop the stream then the camera. Safe to call twice, from any thread."""
        if self._closed:
            return
        self._closing = True
        with self._lock:
            if self._closed:
                return
            self._closed = True
            _OPEN_SOURCES.discard(self)
            self._teardown(background=self._lost and self._frames > 0)

    def _teardown(self, *, background) -> None:
        with self._recycle_lock:
            stream, camera, device = self._stream, self._camera, self._device
            if stream is not None:
                try:
                    self._stats(stream)  # keep the final counters for settings
                except Exception:  # noqa: BLE001 - informative only
                    pass
            self._stream_alive = False
            self._stream = None
            self._camera = None
            self._device = None
        pool, self._pool = self._pool, {}
        handler, self._lost_handler = self._lost_handler, None
        keepalive, self._keepalive = self._keepalive, None
        # A camera lost mid-stream would make the stop wait on register writes; one that never delivered answers.
        stop = self._started and not (self._lost and self._frames)
        label = self._label
        objects: list[Any] = [stream, camera, device, keepalive, pool]
        del stream, camera, device, keepalive, pool

        def work() -> None:
            stream, camera, device, keepalive, pool = objects
            objects.clear()
            if camera is not None and stop:
                try:
                    camera.stop_acquisition()
                except Exception as error:  # noqa: BLE001 - teardown goes on
                    log.warning("%s: stop acquisition failed: %s", label, gerror_message(error))
            if device is not None and handler is not None:
                try:
                    device.disconnect(handler)
                except Exception:  # noqa: BLE001
                    pass
            # Order matters: the stream (its thread writes into the pool and, for the
            # in-process Fake camera, calls the fill callback), then the camera, then
            # the device, then the fill callback and the pool memory.
            del stream
            del camera
            del device
            del keepalive
            del pool

        if background and any(o is not None for o in objects[:2]):
            def run() -> None:
                try:
                    work()
                finally:
                    with contextlib.suppress(ValueError):
                        _TEARDOWN_THREADS.remove(threading.current_thread())
            thread = threading.Thread(target=run, name="livedic-aravis-teardown", daemon=False)
            _TEARDOWN_THREADS.append(thread)
            thread.start()
        else:
            work()

    def __del__(self) -> None:
        try:
            if not self._closed and self._camera is not None:
                self.close()
        except Exception:  # noqa: BLE001 - never raise from a finalizer
            pass

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return f"<AravisCamera {self._label} {state}>"


class _FrameIterator:
    """Iterator over an AravisCamera that keeps no reference to the frames it returned.

    (A generator would hold its last frame, and so one buffer, until the next ``next``.)
    """

    def __init__(self, source) -> None:
        self._source = source

    def __iter__(self):
        return self

    def __next__(self):
        source = self._source
        if source._closed:
            raise StopIteration
        source._start()
        frame = source._next_frame()
        if frame is None:
            raise StopIteration
        return frame


# --------------------------------------------------------------------------- #
# Buffer leases: the numpy view's base object; dropping it re-queues the buffer.
# --------------------------------------------------------------------------- #

_LEASE_TYPES: dict[int, type] = {}          # nbytes -> BufferLease class


def _plain(value):
    """A setting for JSON metadata: tuples as lists, a trigger as its URI text."""
    if isinstance(value, genicam.Trigger):
        return str(value)
    return list(value) if isinstance(value, tuple) else value


def _lease_del(self) -> None:
    owner = getattr(self, "owner", None)
    if owner is not None:
        self.owner = None
        try:
            owner._recycle(self.buffer)
        except Exception:  # noqa: BLE001 - a finalizer must not raise
            pass


def _lease_type(nbytes):
    """A ctypes byte array type over an existing pool array, whose finalizer re-queues its buffer."""
    lease = _LEASE_TYPES.get(nbytes)
    if lease is None:
        lease = type("BufferLease", (ctypes.c_uint8 * nbytes,), {"__del__": _lease_del})
        _LEASE_TYPES[nbytes] = lease
    return lease


@atexit.register
def _close_all_at_exit() -> None:
    """Close sources left open, in the right order, before the interpreter tears modules down."""
    for source in list(_OPEN_SOURCES):
        try:
            source.close()
        except Exception:  # noqa: BLE001
            pass
    for thread in list(_TEARDOWN_THREADS):
        thread.join(timeout=15)
