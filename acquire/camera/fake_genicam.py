"""Aravis's in-process fake camera serving OUR images, and a GenICam description with what Aravis's fake lacks.

* :class:`InProcessFakeCamera` — Aravis's in-process ``Fake_1`` device. While the
  context is active, opening ``aravis:Fake_1`` serves ``image_fn(k)``, ``k`` counting
  the frames the camera has produced since the device was opened (``Frame.index``).
* Aravis's fakes offer Mono8 and Mono16 only and no user sets;
  :func:`extended_genicam_xml` adds the 10/12-bit formats (packed and unpacked),
  more trigger entries and a user set selector for tests (``genicam=`` of each fake).

The GigE Vision fakes are ``acquire.camera.fake_gige``'s; the images, ``acquire.camera.fake_motion``'s.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, Literal

from livedic.acquire.base import SourceError
from livedic.acquire.camera import pixel_formats
from livedic.acquire.camera.aravis import FAKE_FILL_HOOKS
from livedic.acquire.camera.aravis_discovery import SCHEME, load_aravis
from livedic.acquire.camera.fake_motion import FillPattern, SpeckleMotion, set_fake_genicam

__all__ = ["InProcessFakeCamera", "extended_genicam_xml"]


# --------------------------------------------------------------------------- #
# A GenICam description with what Aravis's fake lacks
# --------------------------------------------------------------------------- #

_EXTRA_PIXEL_FORMATS = ("Mono10", "Mono12", "Mono10p", "Mono12p", "Mono10Packed", "Mono12Packed")
# Registers of the added user-set features: free in the fake's memory (its own end at TestRegister 0x1f0).
USER_SET_SELECTOR_REGISTER = 0x1F4
USER_SET_LOAD_REGISTER = 0x1F8


def _int_reg(name, address) -> str:
    return (f'\t<IntReg Name="{name}" NameSpace="Custom">\n\t\t<Address>0x{address:x}</Address>\n'
            "\t\t<Length>4</Length>\n\t\t<AccessMode>RW</AccessMode>\n\t\t<pPort>Device</pPort>\n"
            "\t\t<Sign>Unsigned</Sign>\n\t\t<Endianess>BigEndian</Endianess>\n\t</IntReg>\n\n")


def _entry(name, value) -> str:
    return f'\t\t<EnumEntry Name="{name}" NameSpace="Standard">\n\t\t\t<Value>{value}</Value>\n\t\t</EnumEntry>\n'


def _insert_before(xml, anchor, text):
    if anchor not in xml:
        raise SourceError(f"Aravis's fake-camera XML has changed: {anchor.strip()!r} not found")
    return xml.replace(anchor, text + anchor, 1)


def extended_genicam_xml() -> str:
    """Aravis's fake-camera GenICam XML (this Aravis's own) with more for tests.

    Added: the pixel formats Mono10, Mono12, Mono10p, Mono12p, Mono10Packed and Mono12Packed (the
    fakes size and stamp each frame by the code, and :class:`FillPattern` packs it); TriggerSource
    Line1 and TriggerActivation FallingEdge; UserSetSelector (Default, UserSet1) and UserSetLoad on
    registers that only store what is written (``UserSetLoadRegister`` reads 1 once a set was loaded).
    The registers are the fake's, so both fakes serve it (``genicam=`` of each).
    """
    Aravis, _ = load_aravis()
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
    ``genicam=`` a file holding :func:`extended_genicam_xml`). With ``tick_hz``, a camera in trigger mode
    exposes at ``tick_hz`` on the wall clock's multiples of its period (Aravis's in-process fake ignores
    TriggerSoftware; its GigE fake obeys it) and ``image_fn`` gets the tick number: every open of the device
    sees the same scene at the same tick, as cameras on one hardware trigger line do (a stereo pair). Each time an
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

    def __init__(self, image_fn: Callable[[int], Any] | None = None, *, device_id: str = "Fake_1",
                 genicam: str | os.PathLike[str] | None = None, tick_hz: float | None = None) -> None:
        self.image_fn = image_fn if image_fn is not None else SpeckleMotion()
        self.device_id = device_id
        self.genicam = genicam
        self.tick_hz = tick_hz
        self.patterns: list[FillPattern] = []  # one FillPattern per open, newest last

    @property
    def uri(self) -> str:
        return f"{SCHEME}:{self.device_id}"

    def _attach(self, camera: Any) -> FillPattern:
        fake = camera.get_device().get_fake_camera()
        pattern = FillPattern(self.image_fn, tick_s=None if self.tick_hz is None else 1.0 / self.tick_hz)
        if self.tick_hz is not None:
            fake.set_trigger_frequency(float(self.tick_hz))
        pattern.install(fake)
        self.patterns.append(pattern)
        return pattern

    def start(self) -> InProcessFakeCamera:
        Aravis, _ = load_aravis()
        Aravis.enable_interface("Fake")
        if self.genicam is not None:
            set_fake_genicam(str(self.genicam))   # read by each new Fake device
        FAKE_FILL_HOOKS[self.device_id] = self._attach
        return self

    def stop(self) -> None:
        if FAKE_FILL_HOOKS.get(self.device_id) == self._attach:
            del FAKE_FILL_HOOKS[self.device_id]
        if self.genicam is not None:
            set_fake_genicam(None)                # Aravis's own XML again

    def __enter__(self) -> InProcessFakeCamera:
        return self.start()

    def __exit__(self, *exc: object) -> Literal[False]:
        self.stop()
        return False
