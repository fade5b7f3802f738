"""The durable run store: one SQLite file holds runs, samples and interruptions.

Durability
    The database runs in WAL mode with ``synchronous=FULL``. Each sample is
    written in one transaction (:meth:`RunStore.add_sample`); that commit is the
    executor's checkpoint. In WAL mode ``NORMAL`` already survives a killed
    process (the WAL is written before the commit returns) but may lose the
    last commits on a power cut or OS crash; ``FULL`` also fsyncs the WAL on
    every commit. A sample costs the robot seconds of motion and measurement,
    the fsync about a millisecond, and a sample the operator was told is
    stored must stay stored, so ``FULL`` is the default (``synchronous="NORMAL"``
    is accepted for bulk tests).

Idempotence
    ``samples`` has ``UNIQUE(run_id, point_index)`` and samples are inserted
    with ``INSERT OR IGNORE``: writing a point twice (a resumed run redoing a
    point whose commit did land) keeps the first one, so nothing is ever
    duplicated.

Schema versions
    ``PRAGMA user_version`` holds :data:`~daq.store_schema.SCHEMA_VERSION`. Opening an
    older file applies the upgrades of :mod:`daq.store_schema` in order, each in one
    transaction; a newer file is refused.

Opening read-only and refusing what is not a store
    ``read_only=True`` (the commands that only read: ``runs``, ``export``, ``zero --db``)
    opens the file with SQLite's ``mode=ro``: no WAL switch, nothing written, so a
    read-only file or folder works and the file stays byte for byte the same; an older
    schema is upgraded in a copy in memory. Any open refuses, with one line
    (:class:`StoreError`), a file that is not an SQLite database, a damaged (truncated,
    overwritten) one, an SQLite database of another program (tables that are not a run
    store's; it is never written to) and a store of a newer schema.

Every run stores its plan and its typed context (:class:`daq.run_context.RunContext`).
Reading turns a run's samples into calibration inputs: :mod:`daq.run_data`.

Units: joints rad (stored as JSON lists), lengths mm, covariances mm², times epoch s,
temperature °C, pressure hPa, humidity %.
"""

from __future__ import annotations

import json
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .run_context import RunContext
from .store_open import StoreError, check_store_file, connect_read_only, describe_error
from .store_schema import RESERVE_BYTES, SCHEMA_V1, SCHEMA_VERSION, UPGRADES

#: run statuses: ``running`` (or killed while running), ``paused`` (protective stop,
#: retries exhausted: resumable), ``stopped`` (Ctrl-C: resumable), ``completed``,
#: ``failed`` (refused or broken: resumable once the cause is fixed)
STATUSES = ("running", "paused", "stopped", "completed", "failed")


@dataclass
class Run:
    """One row of ``runs``: plan, frame, summary and context decoded.

    ``robot_url``, ``tracker_url``, ``seed`` and ``model`` are the context's.
    """

    id: int
    routine: str
    plan_json: str
    plan_hash: str
    n_points: int
    robot_desc: str | None
    tracker_desc: str | None
    software: str | None
    started: float | None
    stopped: float | None
    status: str
    reason: str | None
    frame: dict | None
    summary: dict | None
    context: RunContext
    #: who the devices said they were (DeviceIdentity dicts), None when not recorded
    robot_identity: dict | None = None
    tracker_identity: dict | None = None
    #: the run whose plan this run repeats on another cell (``resume --other-cell``)
    source_run: int | None = None

    @property
    def robot_url(self) -> str | None:
        return self.context.robot_url

    @property
    def tracker_url(self) -> str | None:
        return self.context.tracker_url

    @property
    def seed(self) -> int | None:
        return self.context.seed

    @property
    def model(self) -> str | None:
        return self.context.model


@dataclass
class Sample:
    """One measured point, as the executor hands it to :meth:`RunStore.add_sample`.

    ``joints_rad`` joints read (rad, (N,)), ``tracker_p_smr`` the reflector measured (mm,
    tracker frame), ``std_mm`` per-axis std reported by the tracker (mm), ``n`` samples
    averaged, ``t`` measurement time (epoch s), ``base_p_tcp_cmd`` the controller's
    nominal TCP (mm, base frame) or None, ``dirs`` approach direction per joint
    (-1/0/+1) or None; ``reflector`` the reflector measured, ``face`` the tracker face
    (1 or 2) and ``cov_mm2`` the (3, 3) covariance of ``tracker_p_smr`` (mm²), each None
    when the tracker did not say.
    """

    point_index: int
    joints_rad: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n: int
    t: float
    pose_id: str = ""
    set_name: str = "calib"
    target: dict | None = None
    temp_c: float | None = None
    pressure_hpa: float | None = None
    humidity_pct: float | None = None
    base_p_tcp_cmd: np.ndarray | None = None
    dirs: np.ndarray | None = None
    attempts: int = 1
    joints_t: float | None = None
    reflector: str | None = None
    face: int | None = None
    cov_mm2: np.ndarray | None = None
    #: how the reading was judged (:data:`daq.remeasure.VERDICTS`); None: not judged
    verdict: str | None = None
    #: re-measurements made at the point (the readings not accepted are :class:`Reading`)
    remeasures: int = 0
    #: 3-D distance from the running model's prediction and the threshold there (mm)
    model_residual_mm: float | None = None
    model_threshold_mm: float | None = None


@dataclass
class Reading:
    """A reading of a point that was not accepted (the ``readings`` table): the sample it
    would have been (its joints, measurement, distance from the model) and why not."""

    sample: Sample
    reason: str


@dataclass(frozen=True)
class Samples:
    """Every sample of a run ordered by point index, as named columns (``n`` rows).

    Attributes
    ----------
    point_index : (n,) int
    pose_id, set_name : list of str (``set_name`` ``calib`` or ``valid``)
    joints_rad : (n, N) rad, the joints read
    tracker_p_smr : (n, 3) mm, the reflector measured in the tracker frame
    std_mm : (n, 3) mm, the tracker's per-axis std
    n_averaged : (n,) samples the tracker averaged
    t : (n,) epoch s, the measurement times
    temp_c, pressure_hpa, humidity_pct : (n,), NaN where unknown
    base_p_tcp_cmd : (n, 3) mm, the controller's nominal TCP (base frame), NaN where unknown
    dirs : (n, N) int approach directions, or None unless every sample has them
    targets : list of dict (the plan's targets, JSON) or None
    reflector : list of str or None (None where unknown)
    face : (n,) int, the tracker face (1 or 2), 0 where unknown
    cov_mm2 : (n, 3, 3) mm², the covariance of ``tracker_p_smr``, NaN where unknown
    verdict : list of str or None, how each reading was judged (:data:`daq.remeasure.VERDICTS`)
    remeasures : (n,) int, re-measurements made at each point
    """

    point_index: np.ndarray
    pose_id: list[str]
    set_name: list[str]
    joints_rad: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n_averaged: np.ndarray
    t: np.ndarray
    temp_c: np.ndarray
    pressure_hpa: np.ndarray
    humidity_pct: np.ndarray
    base_p_tcp_cmd: np.ndarray
    dirs: np.ndarray | None
    targets: list[dict | None]
    reflector: list[str | None]
    face: np.ndarray
    cov_mm2: np.ndarray
    verdict: list[str | None]
    remeasures: np.ndarray

    def __len__(self) -> int:
        return len(self.point_index)

    def sample(self, i: int) -> Sample:
        """Row ``i`` as a :class:`Sample` (NaN columns as None)."""
        def opt(a):
            v = float(a[i])
            return None if np.isnan(v) else v

        cmd = self.base_p_tcp_cmd[i]
        return Sample(
            point_index=int(self.point_index[i]), joints_rad=self.joints_rad[i].copy(),
            tracker_p_smr=self.tracker_p_smr[i].copy(), std_mm=self.std_mm[i].copy(),
            n=int(np.nan_to_num(self.n_averaged[i])), t=float(self.t[i]),
            pose_id=self.pose_id[i],
            set_name=self.set_name[i], target=self.targets[i], temp_c=opt(self.temp_c),
            pressure_hpa=opt(self.pressure_hpa), humidity_pct=opt(self.humidity_pct),
            base_p_tcp_cmd=None if np.isnan(cmd).any() else cmd.copy(),
            dirs=None if self.dirs is None else self.dirs[i].copy(),
            reflector=self.reflector[i], face=int(self.face[i]) or None,
            cov_mm2=None if np.isnan(self.cov_mm2[i]).all() else self.cov_mm2[i].copy(),
            verdict=self.verdict[i], remeasures=int(self.remeasures[i]))


def _f(v) -> float | None:
    return None if v is None else float(v)


#: the covariance's upper triangle as stored (``cov_xx`` … ``cov_zz``): (row, column)
_COV = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _cov_cols(cov) -> tuple:
    if cov is None:
        return (None,) * len(_COV)
    c = np.asarray(cov, float)
    return tuple(float(c[i, j]) for i, j in _COV)


def _cov_matrix(rows: list, k: int) -> np.ndarray:
    """(n, 3, 3) from the six columns starting at ``k`` (NaN where NULL)."""
    out = np.full((len(rows), 3, 3), np.nan)
    for m, (i, j) in enumerate(_COV):
        v = np.array([np.nan if r[k + m] is None else r[k + m] for r in rows], float)
        out[:, i, j] = out[:, j, i] = v
    return out


def _json(v) -> str | None:
    return None if v is None else json.dumps(v)


class RunStore:
    """The run store in one SQLite file.

    Parameters
    ----------
    path : str or Path
        Database file (created with the current schema when absent).
    synchronous : {"FULL", "NORMAL"}
        SQLite's ``synchronous`` pragma (see the module docstring).
    """

    def __init__(self, path: str | Path, synchronous: str = "FULL", *,
                 read_only: bool = False) -> None:
        if synchronous.upper() not in ("FULL", "NORMAL"):
            raise ValueError(f"synchronous must be FULL or NORMAL, got {synchronous!r}")
        self.path = Path(path)
        self.read_only = read_only
        check_store_file(self.path, must_exist=read_only)
        try:
            if read_only:
                self.con = connect_read_only(self.path)
            else:
                self.con = sqlite3.connect(str(self.path), timeout=30.0, isolation_level=None)
        except sqlite3.Error as e:
            raise StoreError(f"{self.path}: cannot open the run store: {e}") from None
        try:
            self._check_tables()
            if not read_only:
                self.con.execute("PRAGMA journal_mode=WAL")
                self.con.execute(f"PRAGMA synchronous={synchronous.upper()}")
                self.con.execute("PRAGMA foreign_keys=ON")
            self._migrate()
            if not self.read_only:
                self._refill_reserve()
        except sqlite3.DatabaseError as e:
            self.con.close()
            raise StoreError(f"{self.path}: {describe_error(e)}") from None
        except BaseException:
            self.con.close()
            raise

    @classmethod
    def open_existing(cls, path: str | Path, synchronous: str = "FULL", *,
                      read_only: bool = False) -> RunStore:
        """An existing store; :class:`StoreError` when there is no such file (never create
        an empty store for a mistyped path) or it is no run store."""
        check_store_file(Path(path), must_exist=True)
        return cls(path, synchronous=synchronous, read_only=read_only)

    def _check_tables(self) -> None:
        """Refuse an SQLite file of another program (before anything is written to it)."""
        tables = {r[0] for r in self.con.execute(
            "SELECT name FROM sqlite_master WHERE type='table' AND name NOT LIKE 'sqlite_%'")}
        if not tables:
            if self.read_only:
                raise StoreError(f"{self.path}: an empty database, not a cellcal run store "
                                 "(no runs)")
            return
        if not {"runs", "samples"} <= tables:
            shown = ", ".join(sorted(tables)[:5])
            raise StoreError(f"{self.path}: not a cellcal run store (an SQLite database with "
                             f"the tables {shown}); give the run store of a capture")
        v = self.version
        if v > SCHEMA_VERSION:
            raise StoreError(f"{self.path}: schema version {v} is newer than this cellcal "
                             f"({SCHEMA_VERSION}); update cellcal to read it")
        if self.read_only:  # a damaged file shows on a full read, not always on open
            bad = self.con.execute("PRAGMA quick_check").fetchone()[0]
            if bad != "ok":
                raise StoreError(f"{self.path}: damaged run store (SQLite: {bad})")

    # ------------------------------------------------------------ lifecycle
    def close(self) -> None:
        self.con.close()

    def __enter__(self) -> RunStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def version(self) -> int:
        return int(self.con.execute("PRAGMA user_version").fetchone()[0])

    def _migrate(self) -> None:
        v = self.version
        if self.read_only and v < SCHEMA_VERSION:
            self._upgrade_in_memory()
            v = self.version
        if v == 0:
            has = self.con.execute(
                "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='runs'"
            ).fetchone()[0]
            if has:
                raise StoreError(f"{self.path}: not a cellcal run store (a runs table but no "
                                 "schema version)")
            # one script, one transaction: a new file is either complete v1 or empty
            self.con.executescript(f"BEGIN; {SCHEMA_V1} PRAGMA user_version=1; COMMIT;")
            v = 1
        while v < SCHEMA_VERSION:
            self.con.execute("BEGIN IMMEDIATE")
            try:
                UPGRADES[v - 1](self.con)
                self.con.execute(f"PRAGMA user_version={v + 1}")
                self.con.execute("COMMIT")
            except BaseException:
                self.con.execute("ROLLBACK")
                raise
            v += 1

    # ------------------------------------------------------------- reserve
    def release_reserve(self) -> bool:
        """Give up the reserve of free space (the disk is full): the pages it held let the
        run's status and the reason still be written. True when there was one."""
        try:
            with self.con:
                cur = self.con.execute("DELETE FROM reserve")
            return cur.rowcount > 0
        except sqlite3.Error:
            return False

    def _refill_reserve(self) -> None:
        """Put the reserve back when it was given up and there is space again."""
        try:
            with self.con:
                if self.con.execute("SELECT count(*) FROM reserve").fetchone()[0] == 0:
                    self.con.execute("INSERT INTO reserve (id, pad) VALUES (1, zeroblob(?))",
                                     (RESERVE_BYTES,))
        except sqlite3.OperationalError:  # still no space: the capture will say so
            pass

    def _upgrade_in_memory(self) -> None:
        """An older schema opened read-only: work on an upgraded copy in memory."""
        if self.version == 0:
            raise StoreError(f"{self.path}: not a cellcal run store (no schema version)")
        mem = sqlite3.connect(":memory:", isolation_level=None)
        self.con.backup(mem)
        self.con.close()
        self.con = mem
        self.read_only = False  # the copy may be upgraded; the file is left alone

    # ------------------------------------------------------------------ runs
    def create_run(
        self,
        plan,
        context: RunContext | None = None,
        *,
        robot_desc: str | None = None,
        tracker_desc: str | None = None,
        software: str | None = None,
        robot_identity: dict | None = None,
        tracker_identity: dict | None = None,
        source_run: int | None = None,
    ) -> int:
        """Store a new run for ``plan`` (a :class:`daq.plans.Plan`); returns its id.

        ``context`` defaults to the plan's routine and model; its model defaults to the
        plan's. The context's URLs, seed and model also fill the run's columns (for
        listing and queries). ``robot_identity``/``tracker_identity`` are who the devices
        said they were (:meth:`drivers.protocols.DeviceIdentity.to_dict`).
        """
        if software is None:
            from .cli import software_version

            software = software_version()
        if context is None:
            context = RunContext(routine=plan.routine)
        if context.routine != plan.routine:
            raise ValueError(f"context of a {context.routine} run for a {plan.routine} plan")
        if context.model is None and plan.model:
            context = context.model_copy(update={"model": plan.model})
        c = context
        with self.con:
            self.con.execute("BEGIN IMMEDIATE")
            cur = self.con.execute(
                """INSERT INTO runs (routine, plan_json, plan_hash, n_points, robot_url,
                   tracker_url, robot_desc, tracker_desc, software, seed, model, started,
                   status, context_json, robot_identity, tracker_identity, source_run)
                   VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)""",
                (plan.routine, plan.to_json(), plan.hash, plan.n_planned, c.robot_url,
                 c.tracker_url, robot_desc, tracker_desc, software, c.seed, c.model,
                 time.time(), "running", c.to_json(), _json(robot_identity),
                 _json(tracker_identity), source_run),
            )
        return int(cur.lastrowid)

    _RUN_COLS = ("id, routine, plan_json, plan_hash, n_points, robot_desc, tracker_desc, "
                 "software, started, stopped, status, reason, frame_json, summary_json, "
                 "context_json, robot_identity, tracker_identity, source_run")

    def _row_to_run(self, r) -> Run:
        return Run(
            id=r[0], routine=r[1], plan_json=r[2], plan_hash=r[3], n_points=r[4],
            robot_desc=r[5], tracker_desc=r[6], software=r[7], started=r[8], stopped=r[9],
            status=r[10], reason=r[11],
            frame=json.loads(r[12]) if r[12] else None,
            summary=json.loads(r[13]) if r[13] else None,
            context=RunContext.from_json(r[14]),
            robot_identity=json.loads(r[15]) if r[15] else None,
            tracker_identity=json.loads(r[16]) if r[16] else None,
            source_run=r[17],
        )

    def run(self, run_id: int | None = None) -> Run:
        """The run ``run_id`` (default: the latest); :class:`StoreError` when there is none."""
        if run_id is None:
            r = self.con.execute(
                f"SELECT {self._RUN_COLS} FROM runs ORDER BY id DESC LIMIT 1"
            ).fetchone()
            if r is None:
                raise StoreError(f"{self.path}: no runs yet")
        else:
            r = self.con.execute(
                f"SELECT {self._RUN_COLS} FROM runs WHERE id=?", (int(run_id),)
            ).fetchone()
            if r is None:
                raise StoreError(f"{self.path}: no run {run_id}")
        return self._row_to_run(r)

    def runs(self) -> list[Run]:
        rows = self.con.execute(f"SELECT {self._RUN_COLS} FROM runs ORDER BY id").fetchall()
        return [self._row_to_run(r) for r in rows]

    def set_status(self, run_id: int, status: str, reason: str | None = None) -> None:
        """Record the run's status (and why); a final status also sets the stop time."""
        if status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {status!r}")
        stopped = None if status == "running" else time.time()
        with self.con:
            self.con.execute("UPDATE runs SET status=?, reason=?, stopped=? WHERE id=?",
                             (status, reason, stopped, run_id))

    def update_run(self, run_id: int, **fields) -> None:
        """Set ``frame``, ``summary``, ``robot_identity``/``tracker_identity`` (dicts),
        ``robot_desc``/``tracker_desc``, or ``robot_url``/``tracker_url`` (in the run's
        context and its columns)."""
        cols, vals = [], []
        urls = {}
        for k, v in fields.items():
            if k in ("robot_identity", "tracker_identity"):
                cols.append(f"{k}=?")
                vals.append(_json(v))
            elif k in ("frame", "summary"):
                cols.append(f"{k}_json=?")
                vals.append(json.dumps(v) if v is not None else None)
            elif k in ("robot_desc", "tracker_desc"):
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
        with self.con:
            self.con.execute("BEGIN IMMEDIATE")
            if urls:
                ctx = self.run(run_id).context.model_copy(update=urls)
                cols.append("context_json=?")
                vals.append(ctx.to_json())
            self.con.execute(f"UPDATE runs SET {', '.join(cols)} WHERE id=?", (*vals, run_id))

    # --------------------------------------------------------------- samples
    #: the measurement columns a sample and a reading share, and their values
    _MEASURED = ("q_json, x, y, z, sx, sy, sz, n, t, temp_c, pressure_hpa, humidity_pct, "
                 "cmd_x, cmd_y, cmd_z, dir_json, model_residual_mm, model_threshold_mm, "
                 "reflector, face, cov_xx, cov_xy, cov_xz, cov_yy, cov_yz, cov_zz")

    @staticmethod
    def _measured(s: Sample) -> tuple:
        cmd = s.base_p_tcp_cmd if s.base_p_tcp_cmd is not None else (None, None, None)
        return (json.dumps([float(v) for v in np.asarray(s.joints_rad, float)]),
                *(float(v) for v in s.tracker_p_smr), *(float(v) for v in s.std_mm),
                int(s.n), float(s.t), _f(s.temp_c), _f(s.pressure_hpa), _f(s.humidity_pct),
                *(_f(v) for v in cmd),
                json.dumps([int(v) for v in s.dirs]) if s.dirs is not None else None,
                _f(s.model_residual_mm), _f(s.model_threshold_mm), s.reflector or None,
                int(s.face) if s.face else None, *_cov_cols(s.cov_mm2))

    def add_sample(self, run_id: int, s: Sample, rejected=(), revisited=()) -> bool:
        """Write one sample in one transaction (the checkpoint).

        ``rejected`` are the point's readings that were not accepted (:class:`Reading`),
        written only with the sample. ``revisited`` are earlier points measured again
        while this one was done, ``(sample, rejected readings)`` pairs: each replaces its
        point's stored sample (whose reading becomes one of the rejected), in the same
        transaction.

        Returns True when stored, False when the point was already there (idempotent:
        the first sample of a point wins; its rejected readings are then not written).
        """
        ins = self._MEASURED.count(",") + 1
        with self.con:
            self.con.execute("BEGIN IMMEDIATE")
            cur = self.con.execute(
                f"""INSERT OR IGNORE INTO samples (run_id, point_index, pose_id, set_name,
                   target_json, attempts, joints_t, verdict, remeasures, {self._MEASURED})
                   VALUES (?,?,?,?,?,?,?,?,?,{",".join("?" * ins)})""",
                (run_id, int(s.point_index), s.pose_id, s.set_name,
                 json.dumps(s.target) if s.target is not None else None, int(s.attempts),
                 _f(s.joints_t), s.verdict, int(s.remeasures), *self._measured(s)),
            )
            stored = cur.rowcount == 1
            for r in rejected if stored else ():
                self._add_reading(run_id, r)
            for new, old in revisited:
                self._replace_sample(run_id, new, old)
        return stored

    def _add_reading(self, run_id: int, r: Reading) -> None:
        n = self._MEASURED.count(",") + 1
        self.con.execute(
            f"INSERT INTO readings (run_id, point_index, reason, {self._MEASURED}) "
            f"VALUES (?,?,?,{','.join('?' * n)})",
            (run_id, int(r.sample.point_index), r.reason, *self._measured(r.sample)))

    def _replace_sample(self, run_id: int, s: Sample, rejected) -> None:
        cols = [c.strip() for c in self._MEASURED.split(",")]
        cur = self.con.execute(
            f"""UPDATE samples SET {", ".join(f"{c}=?" for c in cols)}, verdict=?,
               remeasures=? WHERE run_id=? AND point_index=?""",
            (*self._measured(s), s.verdict, int(s.remeasures), run_id, int(s.point_index)))
        if cur.rowcount != 1:
            raise StoreError(f"{self.path}: run {run_id} has no point {s.point_index} to "
                             "replace")
        for r in rejected:
            self._add_reading(run_id, r)

    def done_indices(self, run_id: int) -> set[int]:
        """Point indices already stored for the run."""
        rows = self.con.execute("SELECT point_index FROM samples WHERE run_id=?", (run_id,))
        return {int(r[0]) for r in rows}

    def n_samples(self, run_id: int) -> int:
        return int(self.con.execute("SELECT count(*) FROM samples WHERE run_id=?",
                                    (run_id,)).fetchone()[0])

    def samples(self, run_id: int) -> Samples:
        """All samples of a run ordered by point index (:class:`Samples`)."""
        rows = self.con.execute(
            """SELECT point_index, pose_id, set_name, q_json, x, y, z, sx, sy, sz, n, t,
               temp_c, pressure_hpa, humidity_pct, cmd_x, cmd_y, cmd_z, dir_json, target_json,
               reflector, face, cov_xx, cov_xy, cov_xz, cov_yy, cov_yz, cov_zz,
               verdict, remeasures
               FROM samples WHERE run_id=? ORDER BY point_index""", (run_id,)
        ).fetchall()

        def col(k, dtype=float):
            return np.array([np.nan if r[k] is None else r[k] for r in rows], dtype)

        def xyz(k):
            return np.column_stack([col(k), col(k + 1), col(k + 2)]) if rows else np.zeros((0, 3))

        q = np.array([json.loads(r[3]) for r in rows], float)
        dirs = [r[18] for r in rows]
        return Samples(
            point_index=np.array([r[0] for r in rows], int),
            pose_id=[r[1] or str(r[0] + 1) for r in rows],
            set_name=[r[2] or "calib" for r in rows],
            joints_rad=q.reshape(len(rows), -1) if rows else np.zeros((0, 0)),
            tracker_p_smr=xyz(4),
            std_mm=xyz(7),
            n_averaged=col(10, float),
            t=col(11),
            temp_c=col(12),
            pressure_hpa=col(13),
            humidity_pct=col(14),
            base_p_tcp_cmd=xyz(15),
            dirs=(np.array([json.loads(d) for d in dirs], int)
                  if rows and all(d is not None for d in dirs) else None),
            targets=[json.loads(r[19]) if r[19] else None for r in rows],
            reflector=[r[20] or None for r in rows],
            face=np.array([r[21] or 0 for r in rows], int),
            cov_mm2=_cov_matrix(rows, 22),
            verdict=[r[28] for r in rows],
            remeasures=np.array([r[29] or 0 for r in rows], int),
        )

    def readings(self, run_id: int) -> list[Reading]:
        """The readings of a run that were not accepted, by point index, in order taken."""
        rows = self.con.execute(
            f"""SELECT r.point_index, r.reason, s.pose_id, s.set_name, {
                ", ".join(f"r.{c.strip()}" for c in self._MEASURED.split(","))}
               FROM readings r LEFT JOIN samples s
               ON s.run_id = r.run_id AND s.point_index = r.point_index
               WHERE r.run_id=? ORDER BY r.point_index, r.t, r.id""", (run_id,)).fetchall()
        out = []
        for r in rows:
            (q, x, y, z, sx, sy, sz, n, t, temp, pres, hum, cx, cy, cz, dirs, res,
             thr, reflector, face) = r[4:24]
            out.append(Reading(Sample(
                point_index=int(r[0]), joints_rad=np.array(json.loads(q), float),
                tracker_p_smr=np.array([x, y, z], float), std_mm=np.array([sx, sy, sz], float),
                n=int(n or 0), t=float(t), pose_id=r[2] or str(r[0] + 1),
                set_name=r[3] or "calib", temp_c=temp, pressure_hpa=pres, humidity_pct=hum,
                base_p_tcp_cmd=None if cx is None else np.array([cx, cy, cz], float),
                dirs=None if dirs is None else np.array(json.loads(dirs), int),
                model_residual_mm=res, model_threshold_mm=thr, reflector=reflector or None,
                face=face or None, cov_mm2=None if r[24] is None else _cov_matrix([r], 24)[0]),
                r[1]))
        return out

    def remeasure_counts(self, run_id: int) -> dict:
        """What the re-measure policy did in a run (from the stored samples and readings).

        ``judged`` samples judged against the running model at capture, ``warmup`` taken
        before there was one, ``suspects`` points re-measured, ``remeasurements`` made,
        ``rejected`` readings not accepted, ``model_disagrees`` points whose
        re-measurements agreed with each other but not with the model, ``unresolved``
        points whose readings agreed with neither.
        """
        rows = self.con.execute(
            "SELECT verdict, count(*), sum(remeasures), sum(remeasures > 0) FROM samples "
            "WHERE run_id=? GROUP BY verdict", (run_id,)).fetchall()
        by = {v: int(c) for v, c, _, _ in rows}
        n_rejected = int(self.con.execute("SELECT count(*) FROM readings WHERE run_id=?",
                                          (run_id,)).fetchone()[0])
        return {"judged": sum(c for v, c in by.items() if v not in (None, "warmup")),
                "warmup": by.get("warmup", 0),
                "suspects": sum(int(k or 0) for _, _, _, k in rows),
                "remeasurements": sum(int(m or 0) for _, _, m, _ in rows),
                "rejected": n_rejected, "model_disagrees": by.get("model", 0),
                "unresolved": by.get("unresolved", 0)}

    # --------------------------------------------------------- interruptions
    def add_interruption(self, run_id: int, point_index: int | None, kind: str,
                         message: str) -> None:
        """Record an interruption (fault, retry, pause, Ctrl-C, kill found on resume)."""
        with self.con:
            self.con.execute(
                "INSERT INTO interruptions (run_id, point_index, t, kind, message) "
                "VALUES (?,?,?,?,?)",
                (run_id, point_index, time.time(), kind, message),
            )

    def interruptions(self, run_id: int) -> list[tuple[int | None, float, str, str]]:
        """(point index, time, kind, message) of every interruption of the run, in order."""
        return [tuple(r) for r in self.con.execute(
            "SELECT point_index, t, kind, message FROM interruptions WHERE run_id=? ORDER BY id",
            (run_id,))]

    def latest_run(self, routine: str, status: str = "completed") -> Run:
        """The latest run of ``routine`` with ``status``; :class:`StoreError` when none."""
        for r in reversed(self.runs()):
            if r.routine == routine and r.status == status:
                return r
        raise StoreError(f"{self.path}: no {status} {routine} run")
