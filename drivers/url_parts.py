"""The parts of a driver URL, each read or refused with a ``ValueError`` naming the URL.

:mod:`drivers.urls` builds its schemes from these: the scheme, the query parameters (an
unknown one refused, listing the known ones), host and port (1..65535, a scheme's
default port), a bounded integer parameter, a baud rate, a serial device's path and a
register-map file that must exist.
"""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from urllib.parse import SplitResult, parse_qs, urlsplit


def split(url: str) -> SplitResult:
    """``urlsplit(url)``; a URL it cannot split (an unclosed IPv6 bracket) is refused."""
    try:
        return urlsplit(url)
    except ValueError as e:  # e.g. "socket://[::1": an unclosed IPv6 bracket
        raise ValueError(f"bad URL {url!r}: {e}") from None


def scheme_of(url: str) -> str:
    """The URL's scheme, lower-case; anything without ``scheme://`` is refused."""
    if not isinstance(url, str) or "://" not in url:
        raise ValueError(f"bad URL {url!r}: expected scheme://...")
    return url.split("://", 1)[0].lower()


def query(url: str) -> dict[str, str]:
    """The query parameters, name → value (the last one given wins)."""
    text = split(url).query
    try:
        q = parse_qs(text, strict_parsing=False, keep_blank_values=True)
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from e
    return {k: v[-1] for k, v in q.items()}


def check_params(url: str, q: dict[str, str], known: Collection[str]) -> None:
    """Refuse a query parameter not in ``known``, listing the known ones."""
    unknown = sorted(set(q) - set(known))
    if unknown:
        raise ValueError(f"bad URL {url!r}: unknown parameter(s) {unknown}"
                         + (f" (known: {', '.join(sorted(known))})" if known else
                            " (this scheme takes none)"))


def host_port(url: str, default_port: int | None = None) -> tuple[str, int]:
    """(host, port); without a port, ``default_port`` (None: a port is required)."""
    parts = split(url)
    try:
        port = parts.port
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from e
    if not parts.hostname:
        raise ValueError(f"bad URL {url!r}: no host")
    if port is None:
        if default_port is None:
            raise ValueError(f"bad URL {url!r}: no port")
        port = default_port
    if not 1 <= port <= 65535:
        raise ValueError(f"bad URL {url!r}: port {port} is not 1..65535")
    return parts.hostname, port


def int_param(url: str, q: dict[str, str], name: str, default: int, lo: int, hi: int) -> int:
    """The integer parameter ``name`` (``default`` when absent), within ``lo..hi``."""
    text = q.get(name)
    if text is None:
        return default
    try:
        v = int(text)
    except ValueError:
        raise ValueError(f"bad URL {url!r}: {name} must be an integer, got {text!r}") from None
    if not lo <= v <= hi:
        raise ValueError(f"bad URL {url!r}: {name} {v} is not {lo}..{hi}")
    return v


def baud(url: str, q: dict[str, str]) -> int:
    """The ``baud`` parameter of a serial URL (default 115200)."""
    return int_param(url, q, "baud", 115200, 1, 10_000_000)


def serial_path(url: str) -> str:
    """The device path of a serial URL (``serial:///dev/ttyUSB0`` → ``/dev/ttyUSB0``)."""
    path = split(url).path
    if not path or path == "/":
        raise ValueError(f"bad URL {url!r}: no device path")
    return path


def map_file(url: str, q: dict[str, str]) -> str | None:
    """The ``map`` parameter (a register-map file, which must exist), or None."""
    m = q.get("map") or None
    if m is not None and not Path(m).is_file():
        raise ValueError(f"bad URL {url!r}: register map {m}: no such file")
    return m
