"""A run store file: the SQLite side of :mod:`daq.store.dialect`.

Every ``sqlite3`` error becomes one of the store's own here (:func:`store_error`): a full
disk (``SQLITE_FULL``) is :class:`StoreFull` (nothing of the write was stored), anything
else a :class:`StoreError` worded for the user: while a store is being opened, what the
file is (not a store, damaged, unusable: :func:`daq.store.open_checks.describe_error`);
afterwards a page that cannot be read is a ``damaged run store`` found late.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from .dbapi import Cursor, upsert_sql
from .errors import StoreError, StoreFull
from .open_checks import connect_read_only, describe_error


def store_error(e: sqlite3.Error, address: str, opening: bool = False) -> StoreError:
    """The store's error for ``e``, met on the store ``address`` (``opening``: while the
    store is opened and upgraded)."""
    if (getattr(e, "sqlite_errorcode", 0) or 0) & 0xFF == sqlite3.SQLITE_FULL:
        return StoreFull(str(e))
    if not opening and type(e) is sqlite3.DatabaseError:  # corrupt, not a database
        return StoreError(f"{address}: damaged run store (SQLite: {e})")
    return StoreError(f"{address}: {describe_error(e)}")


class SqliteDatabase:
    """A run store file: WAL, ``synchronous`` FULL or NORMAL, foreign keys on."""

    kind = "sqlite"

    def __init__(self, path: Path, *, read_only: bool, synchronous: str,
                 timeout_s: float,
                 check_file: Callable[[sqlite3.Connection], None] | None = None) -> None:
        self.path = Path(path)
        self.address = str(path)
        self.read_only = read_only
        self._synchronous = synchronous
        self._timeout_s = timeout_s
        self._in_memory = False  # see copy_to_memory
        self._opening = False  # see opening
        self.con = self._open(check_file)

    def _open(self, check_file: Callable[[sqlite3.Connection], None] | None = None
              ) -> sqlite3.Connection:
        try:
            if self.read_only:  # nothing written, not even side files (open_checks)
                con = connect_read_only(self.path, self._timeout_s)
            else:
                con = sqlite3.connect(str(self.path), timeout=self._timeout_s,
                                      isolation_level=None, check_same_thread=False)
        except sqlite3.Error as e:
            raise StoreError(f"{self.address}: cannot open the run store: {e}") from None
        try:
            if check_file is not None:
                check_file(con)
            if not self.read_only:
                con.execute("PRAGMA journal_mode=WAL")
                con.execute(f"PRAGMA synchronous={self._synchronous}")
            con.execute("PRAGMA foreign_keys=ON")
        except sqlite3.Error as e:
            con.close()
            raise store_error(e, self.address, opening=True) from None
        except BaseException:
            con.close()
            raise
        return con

    @contextlib.contextmanager
    def _errors(self) -> Iterator[None]:
        try:
            yield
        except sqlite3.Error as e:
            raise store_error(e, self.address, self._opening) from e

    @contextlib.contextmanager
    def opening(self) -> Iterator[None]:
        """Errors in this block word what the file is (the store is being opened)."""
        self._opening = True
        try:
            yield
        finally:
            self._opening = False

    def execute(self, sql: str, params: Sequence = ()) -> Cursor:
        with self._errors():
            return Cursor(self.con.execute(sql, tuple(params)), self._errors)

    def executemany(self, sql: str, rows: Sequence[Sequence[Any]]) -> None:
        with self._errors():
            self.con.executemany(sql, rows)

    @contextlib.contextmanager
    def transaction(self, lock: bool = False) -> Iterator[None]:
        # every write transaction takes the write lock at once: two deferred ones that
        # both want to write would fail to upgrade (SQLITE_BUSY) instead of waiting
        self.execute("BEGIN IMMEDIATE")
        try:
            yield
        except BaseException:
            if self.con.in_transaction:  # SQLite may have rolled back itself (a full disk)
                with contextlib.suppress(sqlite3.Error):
                    self.con.execute("ROLLBACK")
            raise
        try:
            self.execute("COMMIT")
        except StoreError:
            if self.con.in_transaction:
                with contextlib.suppress(sqlite3.Error):
                    self.con.execute("ROLLBACK")
            raise

    def upsert(self, table: str, key: Sequence[str], row: dict) -> None:
        self.execute(*upsert_sql(table, key, row))

    def get_version(self) -> int:
        return int(self.execute("PRAGMA user_version").fetchone()[0])

    def set_version(self, version: int) -> None:
        self.execute(f"PRAGMA user_version={int(version)}")

    def has_table(self, name: str) -> bool:
        return self.execute("SELECT count(*) FROM sqlite_master WHERE type='table' AND "
                            "name=?", (name,)).fetchone()[0] > 0

    def columns(self, table: str) -> list[str]:
        return [r[1] for r in self.execute(f"PRAGMA table_info({table})").fetchall()]

    def copy_to_memory(self) -> None:
        """Go on with a copy of the file in memory, writable (an old schema opened
        read-only is upgraded there); the file is left alone, never reopened."""
        with self._errors():
            mem = sqlite3.connect(":memory:", isolation_level=None, check_same_thread=False)
            self.con.backup(mem)
        self.con.close()
        self.con, self.read_only, self._in_memory = mem, False, True

    def reconnect(self) -> None:
        if self._in_memory:
            return  # the copy is the store: nothing to reconnect to
        with contextlib.suppress(sqlite3.Error):
            self.con.close()
        self.con = self._open()

    def close(self) -> None:
        with self._errors():
            self.con.close()
