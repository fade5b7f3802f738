"""The run store behind one wall: runs, samples, readings, interruptions, leases'
table and calibrations, in a SQLite file or a PostgreSQL database.

Nothing outside this package imports ``sqlite3`` or ``psycopg`` or asks which backend
it talks to; it raises its own errors (:mod:`daq.store.errors`).

Modules
    ``runstore``     ``RunStore``, ``open_store``: the store's operations (SQL written once)
    ``records``      the store's typed records: ``Run``, ``Sample``, ``Samples``,
                     ``Reading``, ``Calibration``
    ``errors``       ``StoreError``, ``StoreUnavailable``, ``StoreFull``
    ``dialect``      the two databases (SQLite, PostgreSQL) behind one small interface
    ``schema``       the SQL schema and its upgrades, a checked registry of versions
    ``open_checks``  opening a file as a store: refusing what is not one, read-only
"""

from .dialect import display_address, is_server_address
from .errors import StoreError, StoreFull, StoreUnavailable
from .records import STATUSES, Calibration, Reading, Run, Sample, Samples
from .runstore import RunStore, open_store

__all__ = ["STATUSES", "Calibration", "Reading", "Run", "RunStore", "Sample", "Samples",
           "StoreError", "StoreFull", "StoreUnavailable", "display_address",
           "is_server_address", "open_store"]
