"""The run store behind one wall: runs, samples, readings, interruptions, leases' table
and calibrations, in a SQLite file or a PostgreSQL database.

Nothing outside this package imports ``sqlite3`` or ``psycopg`` or asks which backend it
talks to: the address picks it (:mod:`daq.store.addresses`), :func:`open_store` and
:func:`open_if_exists` open it, and every driver error is turned into the store's own
(:class:`StoreError`, :class:`StoreUnavailable`, :class:`StoreFull`) where the database
meets its driver (:mod:`daq.store.sqlite_db`, :mod:`daq.store.postgres_db`).

Modules
    ``runstore``     ``RunStore``, ``open_store``, ``open_if_exists``: the store's
                     operations (SQL written once)
    ``records``      runs as stored: ``Run``, ``RunStatus``, ``Interruption``,
                     ``InterruptionKind``, ``Calibration``, ``Check``
    ``summary``      ``RunSummary``: a run's summary, typed, written back as read
    ``samples``      a run's measurements: ``Sample``, ``Reading``, ``Samples``
    ``queries``      questions the capture service asks (``frame_run``)
    ``leases``       one owner per run and per robot
    ``errors``       ``StoreError``, ``StoreUnavailable``, ``StoreFull``
    ``addresses``    which backend an address names, and how it is printed
    ``dialect``      the two databases behind one small interface (``Database``,
                     ``connect``)
    ``sqlite_db``    a run store file: the SQLite side of ``dialect``
    ``postgres_db``  a run store in a PostgreSQL database: the server side of ``dialect``
    ``dbapi``        what both databases share below ``dialect``: a cursor turning driver
                     errors into the store's, the upsert statement
    ``schema``       the SQL schema and its upgrades, a checked registry of versions
    ``migration``    a store brought to today's schema as it is opened
    ``open_checks``  opening a file as a store: refusing what is not one, read-only
"""

from .addresses import display_address
from .errors import StoreError, StoreFull, StoreUnavailable
from .records import STATUSES, Calibration, Check, Interruption, InterruptionKind, Run, RunStatus
from .runstore import RunStore, open_if_exists, open_store
from .samples import Reading, Sample, Samples
from .summary import (
    Iso9283Point,
    RemeasureSummary,
    RunSummary,
    ValidationVariant,
    WarmupSummary,
)

__all__ = ["STATUSES", "Calibration", "Check", "Interruption", "InterruptionKind", "Iso9283Point",
           "Reading", "RemeasureSummary", "Run", "RunStatus", "RunStore", "RunSummary",
           "Sample", "Samples", "StoreError", "StoreFull", "StoreUnavailable",
           "ValidationVariant", "WarmupSummary", "display_address", "open_if_exists",
           "open_store"]
