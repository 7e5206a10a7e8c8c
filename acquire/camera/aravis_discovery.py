"""Finding GenICam cameras through Aravis 0.8: ``load_aravis`` (gi, once), ``list_cameras`` and ``parse_uri``
(``aravis:[DEVICE_ID][?key=value&...]``). ``aravis.open_uri`` opens what they find.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable, Sequence
from typing import Any
from urllib.parse import parse_qsl

from livedic.acquire.base import SourceError

__all__ = ["SCHEME", "list_cameras", "load_aravis", "parse_uri"]

SCHEME = "aravis"
_ARAVIS: tuple[Any, Any] | None = None          # (Aravis, GLib) gi modules once loaded

# --------------------------------------------------------------------------- #
# Loading Aravis
# --------------------------------------------------------------------------- #

def load_aravis() -> tuple[Any, Any]:
    """Import ``gi.repository.Aravis`` 0.8 (and GLib) once; ``SourceError`` with the fix if missing."""
    global _ARAVIS
    if _ARAVIS is None:
        try:
            import gi
            gi.require_version("Aravis", "0.8")
            from gi.repository import Aravis, GLib
        except (ImportError, ValueError) as error:
            raise SourceError(
                f"Aravis 0.8 is not importable from this Python ({error}): run "
                "'scripts/install_system.sh .venv' (Debian packages gir1.2-aravis-0.8, python3-gi "
                "and a link to Debian's gi in the venv)") from error
        _ARAVIS = (Aravis, GLib)
    return _ARAVIS


def gerror_message(error: BaseException) -> str:
    return getattr(error, "message", None) or str(error)


# --------------------------------------------------------------------------- #
# Listing cameras and parsing URIs
# --------------------------------------------------------------------------- #

def list_cameras(*, include_fake: bool = False) -> list[dict[str, Any]]:
    """Cameras Aravis can see now (GigE discovery takes about 1 s).

    Parameters
    ----------
    include_fake : bool
        Also list Aravis's in-process ``Fake_1`` camera (enables the Fake interface).

    Returns
    -------
    list of dict
        One per camera: ``id`` (what ``aravis:ID`` takes), ``vendor``, ``model``,
        ``serial``, ``protocol`` (``GigEVision``, ``USB3Vision``, ``Fake``),
        ``interface`` (``gige``, ``usb3``, ``fake``), ``address`` (IP for GigE),
        ``physical_id`` (MAC for GigE), ``uri`` (``aravis:ID``: opens this camera).
    """
    Aravis, _ = load_aravis()
    if include_fake:
        Aravis.enable_interface("Fake")
    Aravis.update_device_list()
    cameras: list[dict[str, Any]] = []
    for i in range(Aravis.get_n_devices()):
        protocol = Aravis.get_device_protocol(i) or ""
        device_id = Aravis.get_device_id(i)
        cameras.append({
            "id": device_id,
            "vendor": Aravis.get_device_vendor(i),
            "model": Aravis.get_device_model(i),
            "serial": Aravis.get_device_serial_nbr(i),
            "protocol": protocol,
            "interface": interface_name(protocol),
            "address": Aravis.get_device_address(i),
            "physical_id": Aravis.get_device_physical_id(i),
            "uri": f"{SCHEME}:{device_id}",
        })
    return cameras


def interface_name(protocol: str | None) -> str:
    return {"GigEVision": "gige", "USB3Vision": "usb3", "Fake": "fake"}.get(protocol or "", (protocol or "?").lower())


def is_ip_address(text: str) -> bool:
    try:
        ipaddress.ip_address(text)
    except ValueError:
        return False
    return True


def address_text(get: Callable[[], Any]) -> str | None:
    """``get()``'s IP address as text (a GInetSocketAddress without its port), None if unreadable."""
    try:
        address = get()
        if hasattr(address, "get_address"):
            address = address.get_address()
        return address.to_string()
    except Exception:  # noqa: BLE001 - informative only
        return None


def find_listed(cameras: Sequence[dict[str, Any]], device_id: str | None) -> dict[str, Any] | None:
    """The listed camera ``device_id`` names (its id, serial or MAC); the first one (not a fake) for None."""
    if device_id is None or not device_id.strip():
        real = [c for c in cameras if c["protocol"] != "Fake"]
        return real[0] if real else (cameras[0] if cameras else None)
    wanted = device_id.strip().lower()
    for camera in cameras:
        # Blank fields name nothing: a camera without a MAC is not the one a blank id asks for.
        if wanted in {str(camera.get(key) or "").lower() for key in ("id", "serial", "physical_id")} - {""}:
            return camera
    return None


def parse_uri(uri: str) -> tuple[str | None, dict[str, str]]:
    """Split ``aravis:[DEVICE_ID][?key=value&...]`` into ``(device_id or None, {key: str})``."""
    if not isinstance(uri, str) or not uri[:len(SCHEME) + 1].lower() == SCHEME + ":":
        raise SourceError(f"not an Aravis URI: {uri!r} (expected 'aravis:' or 'aravis:DEVICE_ID')")
    rest = uri[len(SCHEME) + 1:]
    device, _, query = rest.partition("?")
    if device.startswith("//"):
        device = device[2:]
    options: dict[str, str] = {}
    if query:
        for key, value in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
            options[key] = value
    return (device or None), options
