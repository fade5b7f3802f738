"""Where a run store lives: a SQLite file path or a PostgreSQL URL (docs/formats.md §5).

The backend is chosen here, from the address alone, and nowhere else: a ``postgresql://``
(or ``postgres://``) URL is a server, anything else a file. Code outside :mod:`daq.store`
never asks; it opens the address (:func:`daq.store.open_store`,
:func:`daq.store.open_if_exists`) and prints it with :func:`display_address`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TypeGuard
from urllib.parse import urlsplit, urlunsplit

#: address schemes of a PostgreSQL server
PG_SCHEMES = ("postgresql", "postgres")


def is_server_address(address: object) -> TypeGuard[str]:
    """True for a ``postgresql://`` (or ``postgres://``) URL."""
    return isinstance(address, str) and urlsplit(address).scheme.lower() in PG_SCHEMES


def display_address(address: str | Path) -> str:
    """The address as printed: a path as given, a URL without its password."""
    if not is_server_address(address):
        return str(address)
    parts = urlsplit(address)
    if parts.password is None:
        return address
    netloc = parts.netloc.replace(f":{parts.password}@", ":***@", 1)
    return urlunsplit(parts._replace(netloc=netloc))
