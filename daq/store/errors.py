"""The run store's own errors: whatever the backend, a caller sees these; each with the
exit code the command line gives it (docs/formats.md §6)."""

from __future__ import annotations


class StoreError(Exception):
    """The store cannot be used (no such store, newer schema, unknown run...): exit 2."""

    exit_code = 2


class StoreUnavailable(StoreError):  # noqa: N818 - a StoreError, named for what happened
    """The database server cannot be reached or the connection was lost (transient): exit 1."""

    transient = True
    exit_code = 1


class StoreFull(StoreUnavailable):  # noqa: N818 - a StoreError, named for what happened
    """The disk under the store is full: nothing of the write was stored (the run pauses
    and ``resume`` completes it once there is room)."""
