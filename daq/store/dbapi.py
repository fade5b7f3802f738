"""What the two databases share below :class:`daq.store.dialect.Database`: a cursor that
turns the driver's errors into the store's own, and the upsert statement.

The driver's errors may surface after ``execute`` returned, while rows are fetched (a
damaged SQLite page is read then): :class:`Cursor` runs every fetch inside the same
translation as the statement, so no ``sqlite3`` or ``psycopg`` error escapes a store.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from typing import Any

#: a database's translation of its driver's errors (a context manager factory)
Translation = Callable[[], contextlib.AbstractContextManager]


class Cursor:
    """A driver's cursor whose fetches raise the store's errors (:mod:`daq.store.errors`)."""

    def __init__(self, cursor: Any, errors: Translation) -> None:
        self._cursor = cursor
        self._errors = errors

    @property
    def rowcount(self) -> int:
        return self._cursor.rowcount

    def fetchone(self) -> Any:
        with self._errors():
            return self._cursor.fetchone()

    def fetchall(self) -> list:
        with self._errors():
            return self._cursor.fetchall()

    def mappings(self) -> list[dict[str, Any]]:
        """Every row as a dict of column name to value (rows read by name, never by
        position), on both databases (the DB-API's ``description``)."""
        with self._errors():
            names = [d[0] for d in self._cursor.description or ()]
            return [dict(zip(names, row, strict=True)) for row in self._cursor.fetchall()]

    def __iter__(self) -> Iterator[Any]:
        return iter(self.fetchall())


def upsert_sql(table: str, key: Sequence[str], row: dict) -> tuple[str, tuple]:
    """``INSERT ... ON CONFLICT (key) DO UPDATE`` of ``row`` (the same text on both
    databases), and its parameters."""
    cols = list(row)
    updates = [c for c in cols if c not in key]
    action = ("DO UPDATE SET " + ", ".join(f"{c}=excluded.{c}" for c in updates)
              if updates else "DO NOTHING")
    sql = (f"INSERT INTO {table} ({', '.join(cols)}) VALUES ({','.join('?' * len(cols))}) "
           f"ON CONFLICT ({', '.join(key)}) {action}")
    return sql, tuple(row[c] for c in cols)
