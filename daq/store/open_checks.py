"""Opening a file as a run store: the checks made before SQLite touches it, and the
read-only connection.

:func:`check_store_file` refuses, in one line, what cannot be a run store (a directory,
a device, an empty or non-SQLite file, a file shorter than its header says) before
SQLite opens it (SQLite would otherwise create, convert or half-read it);
:func:`connect_read_only` opens without writing anything next to the file;
:func:`describe_error` words an SQLite error for the user.
"""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from calibration.files import SQLITE_MAGIC

from .errors import StoreError


def check_store_file(path: Path, must_exist: bool) -> None:
    """Refuse, before SQLite opens it, a path that cannot be a run store."""
    if not path.exists():
        if path.is_symlink():
            raise StoreError(f"{path}: a broken symbolic link, not a run store")
        if not path.parent.is_dir():
            raise StoreError(f"{path}: no such run store (the folder {path.parent} does not "
                             "exist)")
        if must_exist:
            raise StoreError(f"{path}: no such run store")
        return
    if path.is_dir():
        raise StoreError(f"{path}: is a directory, not a run store (an SQLite file)")
    if not path.is_file():
        raise StoreError(f"{path}: not a regular file, not a run store")
    size = path.stat().st_size
    if size == 0:
        if must_exist:
            raise StoreError(f"{path}: an empty file, not a cellcal run store")
        return
    with open(path, "rb") as f:
        head = f.read(100)
    if not head.startswith(SQLITE_MAGIC):
        raise StoreError(f"{path}: not a cellcal run store (not an SQLite database)")
    if len(head) < 100:
        raise StoreError(f"{path}: damaged run store (truncated to {size} bytes)")
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    pages = int.from_bytes(head[28:32], "big")
    valid = head[24:28] == head[92:96]  # the in-header size is trustworthy
    if valid and pages and size < pages * page:
        raise StoreError(f"{path}: damaged run store (truncated: {size} bytes, the header "
                         f"says {pages * page})")


def connect_read_only(path: Path, timeout_s: float = 30.0) -> sqlite3.Connection:
    """A read-only connection that creates nothing next to the file.

    With a ``-wal`` file present (a capture is writing, or one was killed) the store is
    opened ``mode=ro``, which reads the WAL's commits too (the side files already exist).
    Without one, the file holds every commit and is opened ``immutable``: SQLite then
    neither creates the ``-wal``/``-shm`` files a WAL store's readers otherwise leave
    behind, nor needs a writable folder."""
    uri = path.resolve().as_uri()
    if Path(f"{path}-wal").exists():
        con = sqlite3.connect(f"{uri}?mode=ro", uri=True, timeout=timeout_s,
                              isolation_level=None, check_same_thread=False)
        try:
            con.execute("SELECT count(*) FROM sqlite_master").fetchone()
            return con
        except sqlite3.OperationalError:
            con.close()
            if os.access(path.parent, os.W_OK):
                raise
    return sqlite3.connect(f"{uri}?immutable=1", uri=True, isolation_level=None,
                           check_same_thread=False)


def describe_error(e: sqlite3.Error) -> str:
    text = str(e)
    if "not a database" in text:
        return "not a cellcal run store (not an SQLite database)"
    if "malformed" in text or "corrupt" in text:
        return f"damaged run store (SQLite: {text})"
    return f"cannot use the run store: {text}"
