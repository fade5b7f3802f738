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
    ``PRAGMA user_version`` holds :data:`SCHEMA_VERSION`. Opening an older file
    applies the functions of :data:`UPGRADES` in order, each in one
    transaction; a newer file is refused.

Units: joints rad (stored as JSON lists), lengths mm, times epoch s,
temperature °C, pressure hPa, humidity %.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: current schema version (PRAGMA user_version)
SCHEMA_VERSION = 2

#: run statuses: ``running`` (or killed while running), ``paused`` (protective stop,
#: retries exhausted: resumable), ``stopped`` (Ctrl-C: resumable), ``completed``,
#: ``failed`` (refused or broken: resumable once the cause is fixed)
STATUSES = ("running", "paused", "stopped", "completed", "failed")

_SCHEMA_V1 = """
CREATE TABLE runs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    routine TEXT NOT NULL,
    plan_json TEXT NOT NULL,
    plan_hash TEXT NOT NULL,
    n_points INTEGER NOT NULL,
    robot_url TEXT, tracker_url TEXT, robot_desc TEXT, tracker_desc TEXT,
    software TEXT, seed INTEGER, model TEXT,
    started REAL, stopped REAL,
    status TEXT NOT NULL, reason TEXT
);
CREATE TABLE samples (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    run_id INTEGER NOT NULL REFERENCES runs(id),
    point_index INTEGER NOT NULL,
    pose_id TEXT, set_name TEXT,
    target_json TEXT,
    q_json TEXT NOT NULL,
    x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL,
    sx REAL, sy REAL, sz REAL, n INTEGER,
    t REAL, temp_c REAL,
    UNIQUE(run_id, point_index)
);
"""


def _upgrade_1_to_2(con: sqlite3.Connection) -> None:
    """v2: frame/summary/options per run; pressure, humidity, commanded TCP, approach
    directions and attempts per sample; the interruptions table."""
    for col in ("frame_json TEXT", "summary_json TEXT", "options_json TEXT"):
        con.execute(f"ALTER TABLE runs ADD COLUMN {col}")
    for col in ("pressure_hpa REAL", "humidity_pct REAL", "cmd_x REAL", "cmd_y REAL",
                "cmd_z REAL", "dir_json TEXT", "attempts INTEGER DEFAULT 1",
                "joints_t REAL"):
        con.execute(f"ALTER TABLE samples ADD COLUMN {col}")
    con.execute(
        """CREATE TABLE interruptions (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            run_id INTEGER NOT NULL REFERENCES runs(id),
            point_index INTEGER,
            t REAL NOT NULL,
            kind TEXT NOT NULL,
            message TEXT
        )"""
    )
    con.execute("CREATE INDEX interruptions_run ON interruptions(run_id)")


#: UPGRADES[k] takes a database from version k+1 to k+2
UPGRADES: list[Callable[[sqlite3.Connection], None]] = [_upgrade_1_to_2]


class StoreError(Exception):
    """The store cannot be used (newer schema, unknown run...)."""


@dataclass
class Run:
    """One row of ``runs`` (plan and frame decoded)."""

    id: int
    routine: str
    plan_json: str
    plan_hash: str
    n_points: int
    robot_url: str | None
    tracker_url: str | None
    robot_desc: str | None
    tracker_desc: str | None
    software: str | None
    seed: int | None
    model: str | None
    started: float | None
    stopped: float | None
    status: str
    reason: str | None
    frame: dict | None
    summary: dict | None
    options: dict


@dataclass
class Sample:
    """One measured point, as the executor hands it to :meth:`RunStore.add_sample`.

    ``q`` joints read (rad, (N,)), ``xyz`` measured (mm, tracker frame), ``std``
    per-axis std reported by the tracker (mm), ``n`` samples averaged, ``t``
    measurement time (epoch s), ``cmd`` controller's nominal TCP (mm, base
    frame) or None, ``dirs`` approach direction per joint (-1/0/+1) or None.
    """

    point_index: int
    q: np.ndarray
    xyz: np.ndarray
    std: np.ndarray
    n: int
    t: float
    pose_id: str = ""
    set_name: str = "calib"
    target: dict | None = None
    temp_c: float | None = None
    pressure_hpa: float | None = None
    humidity_pct: float | None = None
    cmd: np.ndarray | None = None
    dirs: np.ndarray | None = None
    attempts: int = 1
    joints_t: float | None = None


def _f(v) -> float | None:
    return None if v is None else float(v)


class RunStore:
    """The run store in one SQLite file.

    Parameters
    ----------
    path : str or Path
        Database file (created with the current schema when absent).
    synchronous : {"FULL", "NORMAL"}
        SQLite's ``synchronous`` pragma (see the module docstring).
    """

    def __init__(self, path: str | Path, synchronous: str = "FULL") -> None:
        if synchronous.upper() not in ("FULL", "NORMAL"):
            raise ValueError(f"synchronous must be FULL or NORMAL, got {synchronous!r}")
        self.path = Path(path)
        self.con = sqlite3.connect(str(self.path), timeout=30.0, isolation_level=None)
        try:
            self.con.execute("PRAGMA journal_mode=WAL")
            self.con.execute(f"PRAGMA synchronous={synchronous.upper()}")
            self.con.execute("PRAGMA foreign_keys=ON")
            self._migrate()
        except BaseException:
            self.con.close()
            raise

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
        if v == 0:
            has = self.con.execute(
                "SELECT count(*) FROM sqlite_master WHERE type='table' AND name='runs'"
            ).fetchone()[0]
            if has:
                raise StoreError(f"{self.path}: has a runs table but no schema version")
            # one script, one transaction: a new file is either complete v1 or empty
            self.con.executescript(f"BEGIN; {_SCHEMA_V1} PRAGMA user_version=1; COMMIT;")
            v = 1
        if v > SCHEMA_VERSION:
            raise StoreError(
                f"{self.path}: schema version {v} is newer than this cellcal ({SCHEMA_VERSION})"
            )
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

    # ------------------------------------------------------------------ runs
    def create_run(
        self,
        plan,
        *,
        robot_url: str | None = None,
        tracker_url: str | None = None,
        robot_desc: str | None = None,
        tracker_desc: str | None = None,
        software: str | None = None,
        seed: int | None = None,
        model: str | None = None,
        options: dict | None = None,
    ) -> int:
        """Store a new run for ``plan`` (a :class:`daq.plans.Plan`); returns its id."""
        if software is None:
            software = _software_version()
        with self.con:
            self.con.execute("BEGIN IMMEDIATE")
            cur = self.con.execute(
                """INSERT INTO runs (routine, plan_json, plan_hash, n_points, robot_url,
                   tracker_url, robot_desc, tracker_desc, software, seed, model, started,
                   status, options_json) VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?)""",
                (plan.routine, plan.to_json(), plan.hash, len(plan), robot_url, tracker_url,
                 robot_desc, tracker_desc, software, seed, model or plan.model, time.time(),
                 "running", json.dumps(options or {})),
            )
        return int(cur.lastrowid)

    def _row_to_run(self, r) -> Run:
        return Run(
            id=r[0], routine=r[1], plan_json=r[2], plan_hash=r[3], n_points=r[4],
            robot_url=r[5], tracker_url=r[6], robot_desc=r[7], tracker_desc=r[8],
            software=r[9], seed=r[10], model=r[11], started=r[12], stopped=r[13],
            status=r[14], reason=r[15],
            frame=json.loads(r[16]) if r[16] else None,
            summary=json.loads(r[17]) if r[17] else None,
            options=json.loads(r[18]) if r[18] else {},
        )

    _RUN_COLS = ("id, routine, plan_json, plan_hash, n_points, robot_url, tracker_url, "
                 "robot_desc, tracker_desc, software, seed, model, started, stopped, status, "
                 "reason, frame_json, summary_json, options_json")

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
        """Set ``frame``, ``summary`` (dicts), ``robot_url``/``tracker_url``/descs."""
        cols, vals = [], []
        for k, v in fields.items():
            if k in ("frame", "summary", "options"):
                cols.append(f"{k}_json=?")
                vals.append(json.dumps(v) if v is not None else None)
            elif k in ("robot_url", "tracker_url", "robot_desc", "tracker_desc"):
                cols.append(f"{k}=?")
                vals.append(v)
            else:
                raise ValueError(f"cannot update run field {k!r}")
        if cols:
            with self.con:
                self.con.execute(f"UPDATE runs SET {', '.join(cols)} WHERE id=?", (*vals, run_id))

    # --------------------------------------------------------------- samples
    def add_sample(self, run_id: int, s: Sample) -> bool:
        """Write one sample in one transaction (the checkpoint).

        Returns True when stored, False when the point was already there (idempotent:
        the first sample of a point wins).
        """
        cmd = s.cmd if s.cmd is not None else (None, None, None)
        with self.con:
            cur = self.con.execute(
                """INSERT OR IGNORE INTO samples (run_id, point_index, pose_id, set_name,
                   target_json, q_json, x, y, z, sx, sy, sz, n, t, temp_c, pressure_hpa,
                   humidity_pct, cmd_x, cmd_y, cmd_z, dir_json, attempts, joints_t)
                   VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)""",
                (run_id, int(s.point_index), s.pose_id, s.set_name,
                 json.dumps(s.target) if s.target is not None else None,
                 json.dumps([float(v) for v in np.asarray(s.q, float)]),
                 *(float(v) for v in s.xyz), *(float(v) for v in s.std), int(s.n),
                 float(s.t), _f(s.temp_c), _f(s.pressure_hpa), _f(s.humidity_pct),
                 *(_f(v) for v in cmd),
                 json.dumps([int(v) for v in s.dirs]) if s.dirs is not None else None,
                 int(s.attempts), _f(s.joints_t)),
            )
        return cur.rowcount == 1

    def done_indices(self, run_id: int) -> set[int]:
        """Point indices already stored for the run."""
        rows = self.con.execute("SELECT point_index FROM samples WHERE run_id=?", (run_id,))
        return {int(r[0]) for r in rows}

    def n_samples(self, run_id: int) -> int:
        return int(self.con.execute("SELECT count(*) FROM samples WHERE run_id=?",
                                    (run_id,)).fetchone()[0])

    def samples(self, run_id: int) -> dict[str, np.ndarray | list]:
        """All samples of a run ordered by point index, as column arrays.

        Keys: ``point_index`` (n,), ``pose_id``, ``set`` (lists), ``q`` (n, N) rad,
        ``xyz`` (n, 3) mm, ``std`` (n, 3) mm, ``n`` (n,), ``t`` (n,) s, ``temp_c``,
        ``pressure_hpa``, ``humidity_pct`` (n,) with NaN where unknown, ``cmd`` (n, 3)
        with NaN where unknown, ``dirs`` (n, N) or None, ``target`` list of dicts.
        """
        rows = self.con.execute(
            """SELECT point_index, pose_id, set_name, q_json, x, y, z, sx, sy, sz, n, t,
               temp_c, pressure_hpa, humidity_pct, cmd_x, cmd_y, cmd_z, dir_json, target_json
               FROM samples WHERE run_id=? ORDER BY point_index""", (run_id,)
        ).fetchall()

        def col(k, dtype=float):
            return np.array([np.nan if r[k] is None else r[k] for r in rows], dtype)

        q = np.array([json.loads(r[3]) for r in rows], float)
        dirs = [r[18] for r in rows]
        return {
            "point_index": np.array([r[0] for r in rows], int),
            "pose_id": [r[1] or str(r[0] + 1) for r in rows],
            "set": [r[2] or "calib" for r in rows],
            "q": q.reshape(len(rows), -1) if rows else np.zeros((0, 0)),
            "xyz": np.column_stack([col(4), col(5), col(6)]) if rows else np.zeros((0, 3)),
            "std": np.column_stack([col(7), col(8), col(9)]) if rows else np.zeros((0, 3)),
            "n": col(10, float),
            "t": col(11),
            "temp_c": col(12),
            "pressure_hpa": col(13),
            "humidity_pct": col(14),
            "cmd": np.column_stack([col(15), col(16), col(17)]) if rows else np.zeros((0, 3)),
            "dirs": (np.array([json.loads(d) for d in dirs], int)
                     if rows and all(d is not None for d in dirs) else None),
            "target": [json.loads(r[19]) if r[19] else None for r in rows],
        }

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


def _software_version() -> str:
    try:
        from importlib.metadata import version

        return f"cellcal {version('cellcal')}"
    except Exception:  # noqa: BLE001 - not installed: still record something
        return "cellcal (unknown version)"


def dataset_from_run(store: RunStore, run_id: int, *, sigma_mode: str = "std"):
    """The run's samples as a :class:`calibration.Dataset` (for the measurement CSV).

    ``sigma_mm`` per point: with ``sigma_mode="std"`` (default) the RMS over the axes of
    the per-axis std the tracker reports for the measurement; with ``"mean"`` that
    divided by sqrt(n) (the standard error of the average). The default is the
    conservative one: a stationary tracker measurement's error is dominated by
    effects that are correlated over its samples (interferometer, angle encoders,
    air), which averaging does not reduce as 1/sqrt(n).

    ``cmd``, ``temp_c`` and ``dirs`` are set only when every sample has them.
    """
    from calibration import Dataset

    if sigma_mode not in ("std", "mean"):
        raise ValueError(f"sigma_mode must be std or mean, got {sigma_mode!r}")
    run = store.run(run_id)
    s = store.samples(run_id)
    if len(s["point_index"]) == 0:
        raise StoreError(f"{store.path}: run {run_id} has no samples")
    sigma = np.sqrt(np.mean(s["std"] ** 2, axis=1))
    if sigma_mode == "mean":
        sigma = sigma / np.sqrt(np.maximum(s["n"], 1))
    ids = list(s["pose_id"])
    if len(set(ids)) != len(ids):
        ids = [f"{p}#{i}" for p, i in zip(ids, s["point_index"], strict=True)]
    cmd = s["cmd"] if np.all(np.isfinite(s["cmd"])) else None
    temp = s["temp_c"] if np.all(np.isfinite(s["temp_c"])) else None
    meta = {"run": str(run.id), "routine": run.routine, "plan_hash": run.plan_hash,
            "model": run.model or "", "robot": run.robot_url or "",
            "tracker": run.tracker_url or "", "software": run.software or "",
            "sigma_mm": ("tracker std, RMS over axes" if sigma_mode == "std"
                         else "tracker std / sqrt(n), RMS over axes")}
    return Dataset(
        q=s["q"], tracker_p_smr=s["xyz"], pose_id=ids, cmd=cmd, temp_c=temp, t_s=s["t"],
        sigma_mm=sigma, dirs=s["dirs"], is_valid=np.array([v == "valid" for v in s["set"]]),
        meta=meta, source=f"{store.path} run {run_id}",
    )


def latest_run(store: RunStore, routine: str, status: str = "completed") -> Run:
    """The latest run of ``routine`` with ``status``; :class:`StoreError` when there is none."""
    for r in reversed(store.runs()):
        if r.routine == routine and r.status == status:
            return r
    raise StoreError(f"{store.path}: no {status} {routine} run")


def postures_from_run(store: RunStore, run_id: int | None = None, *, to_base: bool = True):
    """The zero-point postures of a ``zero20`` run (default: the latest completed one).

    Built with :func:`calibration.zero_point.postures_from_dataset`: the joints read
    (rad), the plane of every posture from the plan's targets (``info.plane``) and the
    measured tips (mm). The tips are in the tracker frame (``tracker_p_tip``),
    or, with ``to_base`` and a run that knows its measurement frame
    (``tracker_T_base`` from a frame run, in its options), in the robot base frame.

    Returns
    -------
    postures : Postures
    run : Run
        The run they come from.
    """
    from calibration.zero_point import postures_from_dataset

    run = latest_run(store, "zero20") if run_id is None else store.run(run_id)
    if run.routine != "zero20":
        raise StoreError(f"{store.path}: run {run.id} is a {run.routine} run, not zero20")
    n = store.n_samples(run.id)
    if n != run.n_points:
        raise StoreError(f"{store.path}: run {run.id} has {n}/{run.n_points} postures stored "
                         f"(status {run.status}); finish it with `cellcal resume {run.id}`")
    data = dataset_from_run(store, run.id)
    targets = store.samples(run.id)["target"]
    try:
        plane = np.array([int(t["info"]["plane"]) for t in targets])
    except (TypeError, KeyError) as e:
        raise StoreError(f"{store.path}: run {run.id}: a target has no plane ({e})") from None
    post = postures_from_dataset(data, plane)
    T = run.options.get("tracker_T_base")
    if to_base and T is not None:
        T = np.asarray(T, float)
        post = post.tips_in_base(T[:3, :3], T[:3, 3])
    return post, run
