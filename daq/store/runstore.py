"""The durable run store: runs, samples, the readings a capture did not accept,
interruptions, leases (:mod:`daq.store.leases`), calibrations and their checks, in one
SQLite file (one per cell, the default) or in a PostgreSQL database (a plant's central
store).

:func:`open_store` (and :class:`RunStore` itself) picks the backend from the address
(docs/formats.md §5): a ``postgresql://user@host/db`` URL is a server, anything else a
file; :func:`open_if_exists` answers "is there a store yet?" without the caller asking
which. The SQL below is written once; what the two databases spell differently lives
below :mod:`daq.store.dialect`. Runs read back as :class:`~daq.store.records.Run`
(status, summary and interruptions typed: :mod:`daq.store.records`,
:mod:`daq.store.summary`), samples as :mod:`daq.store.samples`.

Durability
    One transaction per sample (:meth:`RunStore.add_sample`); that commit is the
    executor's checkpoint. SQLite runs in WAL mode with ``synchronous=FULL``: in WAL
    mode ``NORMAL`` already survives a killed process (the WAL is written before the
    commit returns) but may lose the last commits on a power cut or OS crash; ``FULL``
    also fsyncs the WAL on every commit. A sample costs the robot seconds of motion and
    measurement, the fsync about a millisecond, and a sample the operator was told is
    stored must stay stored, so ``FULL`` is the default (``synchronous="NORMAL"`` is
    accepted for bulk tests). On PostgreSQL a commit returns once the server has
    flushed its WAL (``synchronous_commit`` on, the server's default; ``NORMAL`` turns
    it off for the session).

Idempotence
    ``samples`` has ``UNIQUE(run_id, point_index)`` and samples are inserted with
    ``ON CONFLICT DO NOTHING``: writing a point twice (a resumed run redoing a point
    whose commit did land, or a commit repeated after the server connection broke
    during it) keeps the first one, so nothing is ever duplicated. A point's rejected
    readings are written only with its sample, and a re-measured point's replacement
    is skipped when the point already holds it: a repeated commit doubles nothing.

Errors
    Every method raises the store's own errors (:mod:`daq.store.errors`), never a
    driver's. A PostgreSQL server that goes away raises :class:`StoreUnavailable` (a
    :class:`StoreError`, transient); :meth:`RunStore.reconnect` opens a new connection.
    The executor waits for the store, then pauses the run (:mod:`daq.executor`). A full
    disk raises :class:`StoreFull` (nothing of the write was stored);
    :meth:`RunStore.release_reserve` then gives up the space a SQLite store keeps so the
    pause and its reason can still be written.

Schema versions
    :meth:`Database.get_version <daq.store.dialect.Database.get_version>` holds
    :data:`~daq.store.schema.SCHEMA_VERSION` (SQLite's ``PRAGMA user_version``, a
    ``schema_version`` table on PostgreSQL). Opening an older store applies the upgrades
    of :mod:`daq.store.schema` in order (:mod:`daq.store.migration`), each in one
    transaction that holds the store's write lock (two processes opening an old store
    upgrade it once); a newer store is refused. A read-only store is never upgraded.

Every run stores its plan, its typed context (:class:`daq.run_context.RunContext`) and
the robot's identity (``robot_id``). Reading turns a run's samples into calibration
inputs: :mod:`daq.run_data`. Calibrations (a params.json per robot and time) and their
checks on new poses (``cellcal check --db``) are read by ``cellcal history``.

Opening read-only and refusing what is not a store
    ``read_only=True`` (the commands that only read: ``runs``, ``export``, ``zero --db``)
    opens a file with SQLite's ``mode=ro``: no WAL switch, nothing written, so a
    read-only file or folder works and the file stays byte for byte the same; an older
    schema is upgraded in a copy in memory. Any open refuses, with one line
    (:class:`StoreError`), a file that is not an SQLite database, a damaged (truncated,
    overwritten) one, an SQLite database of another program (tables that are not a run
    store's; it is never written to) and a store of a newer schema. On PostgreSQL a
    read-only open sets ``default_transaction_read_only``; its database may hold other
    programs' tables.

Units: joints rad (stored as JSON lists), lengths mm, covariances mm², times epoch s,
temperature °C, pressure hPa, humidity %.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from calibration.data.columns import (
    READING_COLUMNS,
    SAMPLE_COLUMNS,
    decode_row,
    encode_row,
    store_columns,
)
from calibration.version import software_version

from ..run_context import RunContext
from .addresses import display_address, is_server_address
from .dialect import Database, connect
from .errors import StoreError, StoreFull, StoreUnavailable
from .migration import check_file, migrate
from .records import (
    STATUSES,
    Calibration,
    Check,
    Interruption,
    InterruptionKind,
    Run,
    RunStatus,
    known,
)
from .samples import Reading, Sample, Samples
from .schema import RESERVE_BYTES
from .summary import RunSummary

if TYPE_CHECKING:
    from ..plans import Plan

__all__ = ["RunStore", "open_if_exists", "open_store"]


def _json(v: Any) -> str | None:
    return None if v is None else json.dumps(v)


def open_store(address: str | Path, *, create: bool = True, read_only: bool = False,
               synchronous: str = "FULL") -> RunStore:
    """The run store at ``address``: a SQLite file path or a ``postgresql://`` URL.

    ``create`` False refuses a store that does not exist yet (a missing file, a
    PostgreSQL database without the store's tables): never create an empty store for a
    mistyped address. ``read_only`` opens without write access and never upgrades (an
    older schema is refused).
    """
    return RunStore(address, synchronous, create=create, read_only=read_only)


def open_if_exists(address: str | Path, *, read_only: bool = False,
                   synchronous: str = "FULL") -> RunStore | None:
    """The existing run store at ``address``, or None when there is none yet: no file at
    the path (or no regular file), or a PostgreSQL database that cannot be opened as a
    store (no store's tables yet). A server that cannot be reached is
    :class:`StoreUnavailable`; a file that is not a store (or a damaged one) is
    :class:`StoreError`."""
    if not is_server_address(address):
        if not Path(address).is_file():
            return None
        return RunStore(address, synchronous, create=False, read_only=read_only)
    try:
        return RunStore(address, synchronous, create=False, read_only=read_only)
    except StoreUnavailable:
        raise
    except StoreError:  # a database without a run store yet
        return None


class RunStore:
    """The run store (see the module docstring).

    Parameters
    ----------
    address : str or Path
        A SQLite file (created with the current schema when absent) or a
        ``postgresql://user[:password]@host[:port]/dbname`` URL (the database must exist;
        the store's tables are created in an empty one).
    synchronous : {"FULL", "NORMAL"}
        Durability of a commit (see the module docstring).
    create, read_only : bool
        As :func:`open_store`.
    """

    def __init__(self, address: str | Path, synchronous: str = "FULL", *,
                 create: bool = True, read_only: bool = False) -> None:
        #: the address as printed (a URL without its password)
        self.address = display_address(address)
        self.db: Database = connect(
            address, create=create, read_only=read_only, synchronous=synchronous,
            check_file=lambda con: check_file(con, self.address, read_only))
        self._open_args = (address, read_only, synchronous)
        try:
            with self.db.opening():
                migrate(self.db, self.address, create)
                self._refill_reserve()
        except StoreFull as e:  # no room to create or upgrade the store
            self.db.close()
            raise StoreError(f"{self.address}: cannot use the run store: {e}") from None
        except BaseException:
            self.db.close()
            raise

    @classmethod
    def open_existing(cls, path: str | Path, synchronous: str = "FULL", *,
                      read_only: bool = False) -> RunStore:
        """An existing store; :class:`StoreError` when there is none at ``path`` (never
        create an empty store for a mistyped path)."""
        return cls(path, synchronous, create=False, read_only=read_only)

    @property
    def path(self) -> Path | str:
        """The SQLite file, or the server's address (no password)."""
        return self.db.path

    @property
    def con(self) -> Any:
        """The driver's connection (sqlite3 or psycopg), for inspection."""
        return self.db.con

    @property
    def kind(self) -> str:
        """``sqlite`` or ``postgresql``."""
        return self.db.kind

    # ------------------------------------------------------------ lifecycle
    def close(self) -> None:
        self.db.close()

    def __enter__(self) -> RunStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def new_connection(self) -> Database:
        """Another connection to this store (:mod:`daq.store.dialect`), for work beside
        this one: e.g. leases renewed by a heartbeat thread (write them in the store's SQL
        spelling; an insert-or-replace is :meth:`Database.upsert
        <daq.store.dialect.Database.upsert>`, a serialised transaction
        ``transaction(lock=True)``)."""
        address, read_only, synchronous = self._open_args
        return connect(address, create=False, read_only=read_only, synchronous=synchronous)

    def reconnect(self) -> None:
        """A new connection after a lost one (:class:`StoreUnavailable` when the server
        is still away)."""
        self.db.reconnect()

    @property
    def version(self) -> int:
        return self.db.get_version()

    # ------------------------------------------------------------- reserve
    def release_reserve(self) -> bool:
        """Give up the reserve of free space (a full disk: SQLite): the pages it held let
        the run's status and the reason still be written. True when there was one (a
        PostgreSQL store keeps none: its server's disk is the server's)."""
        if self.db.kind != "sqlite" or self.db.read_only:
            return False
        try:
            with self.db.transaction():
                cur = self.db.execute("DELETE FROM reserve")
            return cur.rowcount > 0
        except StoreError:
            return False

    def _refill_reserve(self) -> None:
        """Put the reserve back when it was given up and there is space again."""
        if self.db.kind != "sqlite" or self.db.read_only:
            return
        try:
            with self.db.transaction():
                if self.db.execute("SELECT count(*) FROM reserve").fetchone()[0] == 0:
                    self.db.execute("INSERT INTO reserve (id, pad) VALUES (1, zeroblob(?))",
                                    (RESERVE_BYTES,))
        except StoreError:  # still no space (or busy): the capture will say so
            pass

    # ------------------------------------------------------------------ runs
    def create_run(
        self,
        plan: Plan,
        context: RunContext | None = None,
        *,
        robot_desc: str | None = None,
        tracker_desc: str | None = None,
        software: str | None = None,
        robot_id: str | None = None,
        robot_identity: dict | None = None,
        tracker_identity: dict | None = None,
        source_run: int | None = None,
    ) -> int:
        """Store a new run for ``plan`` (a :class:`daq.plans.Plan`); returns its id.

        ``context`` defaults to the plan's routine and model; its model defaults to the
        plan's. The context's URLs, seed and model also fill the run's columns (for
        listing and queries). ``robot_id`` is who the robot is (:class:`Run`);
        ``robot_identity``/``tracker_identity`` are who the devices said they were
        (:meth:`drivers.protocols.DeviceIdentity.to_dict`); ``source_run`` the run whose
        plan this one repeats on another cell.
        """
        if software is None:
            software = software_version()
        if context is None:
            context = RunContext(routine=plan.routine)
        if context.routine != plan.routine:
            raise ValueError(f"context of a {context.routine} run for a {plan.routine} plan")
        if context.model is None and plan.model:
            context = context.model_copy(update={"model": plan.model})
        c = context
        with self.db.transaction():
            row = self.db.execute(
                """INSERT INTO runs (routine, plan_json, plan_hash, n_points, robot_url,
                   tracker_url, robot_desc, tracker_desc, software, seed, model, started,
                   status, context_json, robot_id, robot_identity, tracker_identity,
                   source_run) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)
                   RETURNING id""",
                (plan.routine, plan.to_json(), plan.hash, plan.n_planned, c.robot_url,
                 c.tracker_url, robot_desc, tracker_desc, software, c.seed, c.model,
                 time.time(), "running", c.to_json(), robot_id, _json(robot_identity),
                 _json(tracker_identity), source_run),
            ).fetchone()
        return int(row[0])

    _RUN_COLS = ("id, routine, plan_json, plan_hash, n_points, robot_desc, tracker_desc, "
                 "software, started, stopped, status, reason, frame_json, summary_json, "
                 "context_json, robot_id, robot_identity, tracker_identity, source_run")

    def _row_to_run(self, r: Sequence[Any]) -> Run:
        return Run(
            id=r[0], routine=r[1], plan_json=r[2], plan_hash=r[3], n_points=r[4],
            robot_desc=r[5], tracker_desc=r[6], software=r[7], started=r[8], stopped=r[9],
            status=known(RunStatus, r[10]), reason=r[11],
            frame=json.loads(r[12]) if r[12] else None,
            summary=RunSummary.from_json(r[13]) if r[13] else None,
            context=RunContext.from_json(r[14]), robot_id=r[15],
            robot_identity=json.loads(r[16]) if r[16] else None,
            tracker_identity=json.loads(r[17]) if r[17] else None,
            source_run=r[18],
        )

    def run(self, run_id: int | None = None) -> Run:
        """The run ``run_id`` (default: the latest); :class:`StoreError` when there is none."""
        if run_id is None:
            r = self.db.execute(
                f"SELECT {self._RUN_COLS} FROM runs ORDER BY id DESC LIMIT 1"
            ).fetchone()
            if r is None:
                raise StoreError(f"{self.address}: no runs yet")
        else:
            r = self.db.execute(
                f"SELECT {self._RUN_COLS} FROM runs WHERE id=?", (int(run_id),)
            ).fetchone()
            if r is None:
                raise StoreError(f"{self.address}: no run {run_id}")
        return self._row_to_run(r)

    def runs(self, robot_id: str | None = None) -> list[Run]:
        """Every run in order (only those of ``robot_id`` when given)."""
        if robot_id is None:
            rows = self.db.execute(f"SELECT {self._RUN_COLS} FROM runs ORDER BY id")
        else:
            rows = self.db.execute(f"SELECT {self._RUN_COLS} FROM runs WHERE robot_id=? "
                                   "ORDER BY id", (robot_id,))
        return [self._row_to_run(r) for r in rows.fetchall()]

    def set_status(self, run_id: int, status: RunStatus | str,
                   reason: str | None = None) -> None:
        """Record the run's status (and why); a final status also sets the stop time."""
        if status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
        stopped = None if status == RunStatus.RUNNING else time.time()
        self.db.execute("UPDATE runs SET status=?, reason=?, stopped=? WHERE id=?",
                        (str(status), reason, stopped, run_id))

    def update_run(self, run_id: int, **fields: Any) -> None:
        """Set ``frame`` (a dict), ``summary`` (a :class:`RunSummary`, or a dict of its
        keys), ``robot_identity``/``tracker_identity`` (dicts),
        ``robot_desc``/``tracker_desc``, ``robot_id``, or ``robot_url``/``tracker_url`` (in
        the run's context and its columns)."""
        cols, vals = [], []
        urls = {}
        for k, v in fields.items():
            if k in ("robot_identity", "tracker_identity"):
                cols.append(f"{k}=?")
                vals.append(_json(v))
            elif k == "frame":
                cols.append("frame_json=?")
                vals.append(_json(v))
            elif k == "summary":
                cols.append("summary_json=?")
                vals.append(None if v is None else RunSummary.model_validate(v).dumps())
            elif k in ("robot_desc", "tracker_desc", "robot_id"):
                cols.append(f"{k}=?")
                vals.append(v)
            elif k in ("robot_url", "tracker_url"):
                cols.append(f"{k}=?")
                vals.append(v)
                urls[k] = v
            else:
                raise ValueError(f"cannot update run field {k!r}")
        if not cols:
            return
        with self.db.transaction():
            if urls:
                ctx = self.run(run_id).context.model_copy(update=urls)
                cols.append("context_json=?")
                vals.append(ctx.to_json())
            self.db.execute(f"UPDATE runs SET {', '.join(cols)} WHERE id=?", (*vals, run_id))

    def latest_run(self, routine: str, status: str = "completed",
                   robot_id: str | None = None) -> Run:
        """The latest run of ``routine`` with ``status`` (of ``robot_id`` when given);
        :class:`StoreError` when none."""
        for r in reversed(self.runs(robot_id)):
            if r.routine == routine and r.status == status:
                return r
        of = f" of robot {robot_id}" if robot_id is not None else ""
        raise StoreError(f"{self.address}: no {status} {routine} run{of}")

    # --------------------------------------------------------------- samples
    # Every per-point column is an entry of the column table (calibration.data.columns): its
    # store columns, how a value is written there and read back. Rows are read by name.

    #: the columns a sample and a rejected reading share (besides ``point_index``)
    _MEASURED = tuple(c for c in READING_COLUMNS if c.name != "point_index")

    def add_sample(self, run_id: int, s: Sample, rejected: Iterable[Reading] = (),
                   revisited: Iterable[tuple[Sample, Iterable[Reading]]] = ()) -> bool:
        """Write one sample in one transaction (the checkpoint).

        ``rejected`` are the point's readings that were not accepted (:class:`Reading`),
        written only with the sample. ``revisited`` are earlier points measured again
        while this one was done, ``(sample, rejected readings)`` pairs: each replaces its
        point's stored sample (whose reading becomes one of the rejected), in the same
        transaction.

        Returns True when stored, False when the point was already there (idempotent:
        the first sample of a point wins; its rejected readings are then not written).
        """
        cols = store_columns(SAMPLE_COLUMNS)
        with self.db.transaction():
            cur = self.db.execute(
                f"""INSERT INTO samples (run_id, {", ".join(cols)})
                   VALUES (?,{",".join("?" * len(cols))})
                   ON CONFLICT DO NOTHING""",
                (run_id, *encode_row(s, SAMPLE_COLUMNS)),
            )
            stored = cur.rowcount == 1
            for r in rejected if stored else ():
                self._add_reading(run_id, r)
            for new, old in revisited:
                self._replace_sample(run_id, new, old)
        return stored

    def _add_reading(self, run_id: int, r: Reading) -> None:
        cols = store_columns(READING_COLUMNS)
        self.db.execute(
            f"INSERT INTO readings (run_id, reason, {', '.join(cols)}) "
            f"VALUES (?,?,{','.join('?' * len(cols))})",
            (run_id, r.reason, *encode_row(r.sample, READING_COLUMNS)))

    def _replace_sample(self, run_id: int, s: Sample, rejected: Iterable[Reading]) -> None:
        """Replace a point's sample by ``s`` (a re-measurement, taken later) and add the
        readings it rejected; a no-op when the point already holds ``s`` (the same
        commit repeated after a lost connection)."""
        cols = store_columns(self._MEASURED)
        cur = self.db.execute(
            f"""UPDATE samples SET {", ".join(f"{c}=?" for c in cols)}, verdict=?,
               remeasures=? WHERE run_id=? AND point_index=? AND t<>?""",
            (*encode_row(s, self._MEASURED), s.verdict, int(s.remeasures), run_id,
             int(s.point_index), float(s.t_s)))
        if cur.rowcount != 1:
            if self.db.execute("SELECT count(*) FROM samples WHERE run_id=? AND "
                               "point_index=?", (run_id, int(s.point_index))).fetchone()[0]:
                return  # already replaced by this very sample
            raise StoreError(f"{self.address}: run {run_id} has no point {s.point_index} "
                             "to replace")
        for r in rejected:
            self._add_reading(run_id, r)

    def done_indices(self, run_id: int) -> set[int]:
        """Point indices already stored for the run."""
        rows = self.db.execute("SELECT point_index FROM samples WHERE run_id=?", (run_id,))
        return {int(r[0]) for r in rows.fetchall()}

    def n_samples(self, run_id: int) -> int:
        return int(self.db.execute("SELECT count(*) FROM samples WHERE run_id=?",
                                   (run_id,)).fetchone()[0])

    def samples(self, run_id: int) -> Samples:
        """All samples of a run ordered by point index (:class:`Samples`)."""
        rows = self.db.execute(
            f"SELECT {', '.join(store_columns(SAMPLE_COLUMNS))} FROM samples "
            "WHERE run_id=? ORDER BY point_index", (run_id,)).mappings()
        return Samples(**{c.name: c.kind.column(rows, c.store) for c in SAMPLE_COLUMNS})

    def readings(self, run_id: int) -> list[Reading]:
        """The readings of a run that were not accepted, by point index, in order taken
        (each with its point's ``pose_id`` and ``set_name``)."""
        cols = ", ".join(f"r.{c}" for c in store_columns(READING_COLUMNS))
        rows = self.db.execute(
            f"""SELECT r.reason, s.pose_id, s.set_name, {cols}
               FROM readings r LEFT JOIN samples s
               ON s.run_id = r.run_id AND s.point_index = r.point_index
               WHERE r.run_id=? ORDER BY r.point_index, r.t, r.id""", (run_id,)).mappings()
        return [Reading(Sample(**decode_row(r)), r["reason"]) for r in rows]

    def remeasure_counts(self, run_id: int) -> dict:
        """What the re-measure policy did in a run (from the stored samples and readings).

        ``judged`` samples judged against the running model at capture, ``warmup`` taken
        before there was one, ``suspects`` points re-measured, ``remeasurements`` made,
        ``rejected`` readings not accepted, ``model_disagrees`` points whose
        re-measurements agreed with each other but not with the model, ``unresolved``
        points whose readings agreed with neither.
        """
        rows = self.db.execute(
            "SELECT verdict, count(*), sum(remeasures), "
            "sum(CASE WHEN remeasures > 0 THEN 1 ELSE 0 END) FROM samples "
            "WHERE run_id=? GROUP BY verdict", (run_id,)).fetchall()
        by = {v: int(c) for v, c, _, _ in rows}
        n_rejected = int(self.db.execute("SELECT count(*) FROM readings WHERE run_id=?",
                                         (run_id,)).fetchone()[0])
        return {"judged": sum(c for v, c in by.items() if v not in (None, "warmup")),
                "warmup": by.get("warmup", 0),
                "suspects": sum(int(k or 0) for _, _, _, k in rows),
                "remeasurements": sum(int(m or 0) for _, _, m, _ in rows),
                "rejected": n_rejected, "model_disagrees": by.get("model", 0),
                "unresolved": by.get("unresolved", 0)}

    # --------------------------------------------------------- interruptions
    def add_interruption(self, run_id: int, point_index: int | None, kind: InterruptionKind,
                         message: str) -> None:
        """Record an interruption (fault, retry, pause, Ctrl-C, kill found on resume),
        stored as its kind's string."""
        self.db.execute(
            "INSERT INTO interruptions (run_id, point_index, t, kind, message) "
            "VALUES (?,?,?,?,?)",
            (run_id, point_index, time.time(), str(kind), message),
        )

    def interruptions(self, run_id: int) -> list[Interruption]:
        """Every interruption of the run, in order: (point index, time, kind, message)."""
        rows = self.db.execute("SELECT point_index, t, kind, message FROM interruptions "
                               "WHERE run_id=? ORDER BY id", (run_id,)).fetchall()
        return [Interruption(p, t, known(InterruptionKind, k), m) for p, t, k, m in rows]

    # ---------------------------------------------------------- calibrations
    def add_calibration(self, robot_id: str, params: dict, *, t: float | None = None,
                        source_file: str | None = None, source_run: int | None = None,
                        software: str | None = None) -> tuple[int, bool]:
        """Record a calibration of ``robot_id`` (``params``: the params.json document).

        ``t`` when its data were measured (default: now). Idempotent: the same
        parameters recorded again for the same robot are not stored twice. Returns (its
        id, True when new).
        """
        if not robot_id:
            raise ValueError("a calibration needs a robot id")
        from calibration.files import json_ready

        text = json.dumps(json_ready(params), sort_keys=True, allow_nan=False)
        digest = hashlib.sha256(text.encode()).hexdigest()
        now = time.time()
        with self.db.transaction():
            row = self.db.execute(
                "INSERT INTO calibrations (robot_id, t, recorded, params_json, params_sha256, "
                "source_file, source_run, software) VALUES (?,?,?,?,?,?,?,?) "
                "ON CONFLICT DO NOTHING RETURNING id",
                (robot_id, now if t is None else float(t), now, text, digest, source_file,
                 source_run, software or software_version())).fetchone()
            if row is not None:
                return int(row[0]), True
            row = self.db.execute("SELECT id FROM calibrations WHERE robot_id=? AND "
                                  "params_sha256=?", (robot_id, digest)).fetchone()
        return int(row[0]), False

    def calibrations(self, robot_id: str) -> list[Calibration]:
        """The calibrations of ``robot_id`` in time order."""
        rows = self.db.execute(
            "SELECT id, robot_id, t, recorded, params_json, source_file, source_run, software "
            "FROM calibrations WHERE robot_id=? ORDER BY t, id", (robot_id,)).fetchall()
        return [Calibration(*r) for r in rows]

    def robots(self) -> list[tuple[str, int]]:
        """(robot id, number of calibrations) of every robot with calibrations."""
        rows = self.db.execute("SELECT robot_id, count(*) FROM calibrations GROUP BY robot_id "
                               "ORDER BY robot_id").fetchall()
        return [(r[0], int(r[1])) for r in rows]

    # ---------------------------------------------------------------- checks
    @staticmethod
    def params_digest(params: dict) -> str:
        """The sha256 a params.json document is recorded under (as a calibration)."""
        from calibration.files import json_ready

        text = json.dumps(json_ready(params), sort_keys=True, allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()

    def add_check(self, robot_id: str, params: dict, result: dict, *, t: float | None = None,
                  source_file: str | None = None, source_run: int | None = None,
                  software: str | None = None) -> tuple[int, bool, int | None]:
        """Record a check of ``robot_id``'s calibration ``params`` (the params.json
        document) on new poses: ``result`` is the check's ``--json`` object (``n``,
        ``rms_mm``, ``mean_mm``, ``p95_mm``, ``max_mm``, ``tolerance_mm``,
        ``within_tolerance``, ``refitted``).

        ``t`` when the poses were measured (default: now). The calibration of the same
        robot recorded with the same parameters is linked. Idempotent: the same result
        recorded again for the same robot is not stored twice. Returns (its id, True when
        new, the linked calibration's id or None).
        """
        if not robot_id:
            raise ValueError("a check needs a robot id")
        from calibration.files import json_ready

        digest = self.params_digest(params)
        text = json.dumps(json_ready(result), sort_keys=True, allow_nan=False)
        result_digest = hashlib.sha256(text.encode()).hexdigest()
        ok = result.get("within_tolerance")
        now = time.time()

        def num(key: str) -> float | None:
            v = result.get(key)
            return None if v is None else float(v)

        with self.db.transaction():
            row = self.db.execute("SELECT id FROM calibrations WHERE robot_id=? AND "
                                  "params_sha256=?", (robot_id, digest)).fetchone()
            cal_id = None if row is None else int(row[0])
            row = self.db.execute(
                "INSERT INTO checks (robot_id, t, recorded, params_sha256, calibration_id, n, "
                "rms_mm, mean_mm, p95_mm, max_mm, tolerance_mm, within_tolerance, "
                "refitted_json, result_json, result_sha256, source_file, source_run, software) "
                "VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?) ON CONFLICT DO NOTHING RETURNING id",
                (robot_id, now if t is None else float(t), now, digest, cal_id,
                 int(result.get("n") or 0), num("rms_mm"), num("mean_mm"), num("p95_mm"),
                 num("max_mm"), num("tolerance_mm"), None if ok is None else int(bool(ok)),
                 json.dumps(list(result.get("refitted") or [])), text, result_digest,
                 source_file, source_run, software or software_version())).fetchone()
            if row is not None:
                return int(row[0]), True, cal_id
            row = self.db.execute("SELECT id FROM checks WHERE robot_id=? AND result_sha256=?",
                                  (robot_id, result_digest)).fetchone()
        return int(row[0]), False, cal_id

    def checks(self, robot_id: str) -> list[Check]:
        """The checks of ``robot_id``'s calibrations, in time order."""
        rows = self.db.execute(
            "SELECT id, robot_id, t, recorded, params_sha256, calibration_id, n, rms_mm, "
            "mean_mm, p95_mm, max_mm, tolerance_mm, within_tolerance, refitted_json, "
            "result_json, source_file, source_run, software FROM checks WHERE robot_id=? "
            "ORDER BY t, id", (robot_id,)).fetchall()
        out = []
        for r in rows:
            r = list(r)
            r[12] = None if r[12] is None else bool(r[12])
            r[13] = tuple(json.loads(r[13]))
            out.append(Check(*r))
        return out

    def checked_robots(self) -> list[tuple[str, int]]:
        """(robot id, number of checks) of every robot with checks."""
        rows = self.db.execute("SELECT robot_id, count(*) FROM checks GROUP BY robot_id "
                               "ORDER BY robot_id").fetchall()
        return [(r[0], int(r[1])) for r in rows]

