"""``--publish URI``: ``udp://HOST:PORT`` or ``modbus://HOST:PORT[?linger_s=SECONDS]`` parsed into a ``PublishTarget``.

Every error is one line naming the option (see ``stream.publish.stage`` for what each scheme sends).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from urllib.parse import urlsplit

SCHEMES = ("udp", "modbus")
DEFAULT_HOST = "127.0.0.1"
DEFAULT_LINGER_S = 1.0       # a controller polling every 5-100 ms reads the ended state several times
MAX_LINGER_S = 60.0


@dataclass(frozen=True)
class PublishTarget:
    """Where strain goes out: ``scheme`` udp or modbus, ``host`` and ``port`` (see ``stream.publish.stage``'s notes).

    ``linger_s``: how long a Modbus server keeps answering after the session ended.
    """
    uri: str
    scheme: str
    host: str
    port: int
    linger_s: float = DEFAULT_LINGER_S

    def describe(self) -> str:
        """``udp://127.0.0.1:9870`` (the host as used; an IPv6 one in brackets)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{self.scheme}://{host}:{self.port}"


def parse_publish_uri(text: str) -> PublishTarget:
    """``--publish`` ``udp://HOST:PORT`` or ``modbus://HOST:PORT`` -> ``PublishTarget``.

    No host (``udp://:9870``) means 127.0.0.1. A modbus port may be 0 (any free port); a modbus
    URI may end in ``?linger_s=SECONDS`` (0..60, default ``DEFAULT_LINGER_S``).

    Raises
    ------
    ValueError
        Anything else (one line naming the option).
    """
    raw = str(text).strip()
    example = "e.g. udp://127.0.0.1:9870 or modbus://127.0.0.1:5020"
    if "://" not in raw:
        raise ValueError(f"--publish {raw!r}: expected udp://HOST:PORT or modbus://HOST:PORT, {example}")
    try:
        parts = urlsplit(raw)
        port = parts.port
    except ValueError as error:
        raise ValueError(f"--publish {raw}: {error} ({example})") from None
    scheme = parts.scheme.lower()
    if scheme not in SCHEMES:
        raise ValueError(f"--publish {raw}: unknown scheme {parts.scheme!r}: use udp://HOST:PORT or "
                         f"modbus://HOST:PORT")
    linger_s = _linger_option(raw, scheme, parts.query)
    if parts.path not in ("", "/") or parts.fragment or parts.username or parts.password or linger_s is None:
        also = ", and ?linger_s=SECONDS" if scheme == "modbus" else ""
        raise ValueError(f"--publish {raw}: only HOST:PORT may follow {scheme}://{also} ({example})")
    if port is None:
        raise ValueError(f"--publish {raw}: a port is needed, {example}")
    lowest = 0 if scheme == "modbus" else 1
    if not lowest <= port <= 65535:
        raise ValueError(f"--publish {raw}: port must be {lowest}..65535, got {port}")
    return PublishTarget(uri=raw, scheme=scheme, host=parts.hostname or DEFAULT_HOST, port=port, linger_s=linger_s)


def _linger_option(raw: str, scheme: str, query: str) -> float | None:
    """A URI's ``linger_s`` (the default without a query); None for a query that is not one modbus ``linger_s``.

    Raises
    ------
    ValueError
        ``linger_s`` not a number in 0..60 (one line).
    """
    if not query:
        return DEFAULT_LINGER_S
    key, _, text = query.partition("=")
    if scheme != "modbus" or key != "linger_s" or "&" in text:
        return None
    try:
        linger_s = float(text)
    except ValueError:
        linger_s = math.nan
    if not 0.0 <= linger_s <= MAX_LINGER_S:
        raise ValueError(f"--publish {raw}: linger_s must be seconds in 0..{MAX_LINGER_S:g}, got {text!r}")
    return linger_s


def parse_publish_uris(texts: Iterable[str]) -> tuple[PublishTarget, ...]:
    """Every ``--publish`` given, parsed (``parse_publish_uri``); ValueError for one given twice."""
    targets = tuple(parse_publish_uri(text) for text in texts)
    seen = set()
    for target in targets:
        key = (target.scheme, target.host, target.port)
        if key in seen and target.port != 0:
            raise ValueError(f"--publish {target.describe()} is given twice")
        seen.add(key)
    return targets
