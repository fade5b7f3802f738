"""Bringing a database to today's schema as a store is opened: the first look at a SQLite
file (:func:`check_file`), a new store created, an old one upgraded (:func:`migrate`) by
the registry of :mod:`daq.store.schema`, one version per transaction.

Each step holds the store's write lock and reads the version again inside it, so two
processes opening an old store upgrade it once. A newer store is refused; a read-only
store is never written: an older SQLite schema is upgraded in a copy in memory, an older
PostgreSQL schema refused.
"""

from __future__ import annotations

import sqlite3
from typing import cast

from .dialect import Database
from .errors import StoreError
from .schema import SCHEMA_V1, SCHEMA_VERSION, UPGRADES
from .sqlite_db import SqliteDatabase


def check_file(con: sqlite3.Connection, address: str, read_only: bool) -> None:
    """A SQLite file's first look (``con``: its ``sqlite3`` connection), before anything is
    written to it: refuse a file of another program, a newer schema, and a damaged file
    opened read-only. (A PostgreSQL database may hold other programs' tables besides the
    store's.)"""
    tables = {r[0] for r in con.execute(
        "SELECT name FROM sqlite_master WHERE type='table' AND name NOT LIKE 'sqlite_%'")}
    if not tables:
        if read_only:
            raise StoreError(f"{address}: an empty database, not a cellcal run store "
                             "(no runs)")
        return
    if not {"runs", "samples"} <= tables:
        shown = ", ".join(sorted(tables)[:5])
        raise StoreError(f"{address}: not a cellcal run store (an SQLite database "
                         f"with the tables {shown}); give the run store of a capture")
    v = int(con.execute("PRAGMA user_version").fetchone()[0])
    if v > SCHEMA_VERSION:
        raise StoreError(f"{address}: schema version {v} is newer than this cellcal "
                         f"({SCHEMA_VERSION}); update cellcal to read it")
    if read_only:  # a damaged file shows on a full read, not always on open
        bad = con.execute("PRAGMA quick_check").fetchone()[0]
        if bad != "ok":
            raise StoreError(f"{address}: damaged run store (SQLite: {bad})")


def _newer(address: str, v: int) -> StoreError:
    return StoreError(f"{address}: schema version {v} is newer than this cellcal "
                      f"({SCHEMA_VERSION})")


def migrate(db: Database, address: str, create: bool) -> None:
    """Bring ``db`` to :data:`SCHEMA_VERSION` (see the module docstring); ``create`` False
    refuses an empty database."""
    v = db.get_version()
    if v == 0 and (not create or db.read_only):
        raise StoreError(f"{address}: no run store here (an empty database)")
    if v > SCHEMA_VERSION:
        raise _newer(address, v)
    if db.read_only and v < SCHEMA_VERSION:
        if db.kind != "sqlite":
            raise StoreError(f"{address}: schema version {v}, this cellcal reads "
                             f"{SCHEMA_VERSION}: open it once with write access (any "
                             "capture, runs or export) to upgrade it")
        if v == 0:
            raise StoreError(f"{address}: not a cellcal run store (no schema version)")
        cast(SqliteDatabase, db).copy_to_memory()  # the file is left alone
    if db.read_only:
        return
    while v < SCHEMA_VERSION:
        with db.transaction(lock=True):
            v = db.get_version()
            if v == 0:
                if db.has_table("runs"):
                    raise StoreError(f"{address}: has a runs table but no schema version")
                for statement in SCHEMA_V1.split(";"):
                    if statement.strip():
                        db.execute(statement)
            elif v < SCHEMA_VERSION:
                UPGRADES[v](db)
            if v < SCHEMA_VERSION:
                db.set_version(v + 1)
                v += 1
    if v > SCHEMA_VERSION:
        raise _newer(address, v)
