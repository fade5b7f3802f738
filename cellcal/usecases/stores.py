"""Opening a run store for a command: a missing store or an unreachable server becomes a
:class:`~cellcal.cli.UsageError` (exit 2) naming the store.

Imports nothing heavy at load (the store is imported when one is opened).
"""

from __future__ import annotations

import contextlib

from ..errors import UsageError


def open_store(address, synchronous: str = "FULL", *, read_only: bool = False):
    """An existing run store (a file or a ``postgresql://`` URL); a missing or unreadable
    store, or a server that cannot be reached, is a UsageError (never create an empty
    store for a mistyped address). ``read_only``: for commands that only read (no WAL
    switch, no upgrade written, works on a read-only file)."""
    from daq.store import StoreError
    from daq.store import open_store as open_run_store

    try:
        return open_run_store(address, create=False, read_only=read_only,
                              synchronous=synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None

@contextlib.contextmanager
def store_errors(path):
    """Turn a store that cannot be read (damage found late: ``PATH: damaged run store``)
    into a UsageError; a server gone away is left to say so itself (transient). ``path``
    is the store as given: the store's own message names it already."""
    from daq.store import StoreError, StoreUnavailable

    del path

    try:
        yield
    except StoreUnavailable:
        raise
    except StoreError as e:
        raise UsageError(str(e)) from None
