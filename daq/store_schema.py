"""The run store's SQLite schema and the upgrades between its versions.

``PRAGMA user_version`` holds the version. A new file is created at version 1
(:data:`SCHEMA_V1`) and brought to :data:`SCHEMA_VERSION` by the same upgrade functions
an old file goes through (:data:`UPGRADES`, each run in one transaction by
:class:`daq.store.RunStore`). An upgrade function is frozen once released: it writes
plain SQL and JSON, never through today's classes, so an old file upgrades the same
way whatever the code around it has become.

Versions
    1. runs and samples.
    2. per run: frame, summary and a loose ``options`` JSON dict; per sample: pressure,
       humidity, the controller's nominal TCP, approach directions, attempts, the
       joints' time; the interruptions table.
    3. ``options_json`` becomes ``context_json``: a versioned run context
       (:class:`daq.run_context.RunContext`, version 1).
    4. per sample: the reflector measured, the tracker face and the covariance of the
       measured point (``cov_xx`` … ``cov_zz``, mm²), NULL where the tracker did not say.
    5. one owner per run and per robot, and who the devices were: the ``leases`` table
       (:mod:`daq.leases`); per run the robot's and the tracker's identity (JSON of
       :class:`drivers.protocols.DeviceIdentity`) and ``source_run`` (the run whose plan a
       run repeats on another cell); run contexts gain ``motion`` (no floor for the runs
       made before: none was recorded). Additive: new table, new nullable columns.
    6. re-measured blunders (:mod:`daq.remeasure`): per sample the ``verdict`` on its
       reading, the ``remeasures`` made at the point and the reading's distance from the
       running model with its threshold; the ``readings`` table keeps every reading that
       was not accepted, with its reason (and, as a sample, the tracker's reflector, face
       and covariance). Additive: older rows read as never judged.
    7. the ``reserve`` table: one row of zeros (:data:`RESERVE_BYTES`) the store gives up
       when the disk is full, so that the run can still be marked paused with the reason
       (:meth:`daq.store.RunStore.release_reserve`).
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable

#: current schema version (PRAGMA user_version)
SCHEMA_VERSION = 7
#: the free space the store keeps in reserve for a full disk (bytes)
RESERVE_BYTES = 1 << 20

SCHEMA_V1 = """
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


#: schema 2's executor options (its ``ExecutorOptions`` fields besides the zero-point
#: loop's and ``extra``): kept under ``executor`` in the v1 context
_V2_EXECUTOR_KEYS = ("speed_rad_s", "speed_mm_s", "move_timeout_s", "io_timeout_s",
                     "connect_timeout_s", "dwell_s", "measure_s", "measure_timeout_s",
                     "max_std_mm", "max_remeasure", "max_retries", "backoff_s",
                     "backoff_max_s", "dir_deadband_rad")
#: schema 2's zero-point loop options -> zero20's acquisition options in the v1 context
_V2_ZERO_KEYS = {"zero_tol_mm": "tol_mm", "zero_max_iter": "max_iter",
                 "zero_damping_mm": "damping_mm", "zero_probe_mm": "probe_mm",
                 "zero_noise_k": "noise_k", "zero_average": "average",
                 "zero_confirm_step_mm": "confirm_step_mm"}


def context_from_v2(routine: str, model: str | None, robot_url: str | None,
                    tracker_url: str | None, seed: int | None, options: dict) -> dict:
    """The version-1 run context (a JSON-ready dict) of a schema-2 run.

    ``options`` is schema 2's ``options_json``: executor options, ``tool_mm``,
    ``frame_run``, ``tracker_T_base`` and its redundant rotation ``tracker_R_base``
    (dropped: it is ``tracker_T_base[:3, :3]``).
    """
    ctx: dict = {"version": 1, "routine": routine, "model": model, "tool_mm": None,
                 "robot_url": robot_url, "tracker_url": tracker_url, "seed": seed,
                 "frame_run": options.get("frame_run"),
                 "tracker_T_base": options.get("tracker_T_base"),
                 "executor": {k: options[k] for k in _V2_EXECUTOR_KEYS if k in options},
                 "acquire": {}}
    if options.get("tool_mm") is not None:
        ctx["tool_mm"] = [float(v) for v in options["tool_mm"]]
    if routine == "zero20":
        ctx["acquire"] = {new: options[old] for old, new in _V2_ZERO_KEYS.items()
                          if old in options}
    return ctx


def _upgrade_2_to_3(con: sqlite3.Connection) -> None:
    """v3: the loose ``options_json`` becomes a versioned run context (``context_json``)."""
    con.execute("ALTER TABLE runs ADD COLUMN context_json TEXT")
    rows = con.execute("SELECT id, routine, model, robot_url, tracker_url, seed, options_json "
                       "FROM runs").fetchall()
    for rid, routine, model, robot_url, tracker_url, seed, options in rows:
        ctx = context_from_v2(routine, model, robot_url, tracker_url, seed,
                              json.loads(options) if options else {})
        con.execute("UPDATE runs SET context_json=? WHERE id=?", (json.dumps(ctx), rid))
    con.execute("ALTER TABLE runs DROP COLUMN options_json")


#: the sample columns of schema 4: reflector, face, covariance (upper triangle, mm²)
_V4_SAMPLE_COLUMNS = ("reflector TEXT", "face INTEGER", "cov_xx REAL", "cov_xy REAL",
                      "cov_xz REAL", "cov_yy REAL", "cov_yz REAL", "cov_zz REAL")


def _upgrade_3_to_4(con: sqlite3.Connection) -> None:
    """v4: per-sample tracker metadata (reflector, face, covariance); NULL in old rows."""
    for col in _V4_SAMPLE_COLUMNS:
        con.execute(f"ALTER TABLE samples ADD COLUMN {col}")


def _upgrade_4_to_5(con: sqlite3.Connection) -> None:
    """v5 (additive): the ``leases`` table; per run ``robot_identity``,
    ``tracker_identity`` (JSON) and ``source_run``; each run context gets the motion
    limits its moves were made under before v5: no floor (the executor checked none,
    and the dry run's floor was not recorded), the other limits' defaults."""
    for col in ("robot_identity TEXT", "tracker_identity TEXT", "source_run INTEGER"):
        con.execute(f"ALTER TABLE runs ADD COLUMN {col}")
    for rid, text in con.execute("SELECT id, context_json FROM runs").fetchall():
        ctx = json.loads(text) if text else None
        if isinstance(ctx, dict) and "motion" not in ctx:
            ctx["motion"] = {"floor_z_mm": None}
            con.execute("UPDATE runs SET context_json=? WHERE id=?", (json.dumps(ctx), rid))
    con.execute(
        """CREATE TABLE leases (
            key TEXT PRIMARY KEY,
            owner_pid INTEGER NOT NULL,
            owner_host TEXT NOT NULL,
            owner_token TEXT NOT NULL,
            acquired REAL NOT NULL,
            heartbeat REAL NOT NULL,
            what TEXT
        )"""
    )


def _upgrade_5_to_6(con: sqlite3.Connection) -> None:
    """v6 (additive): the verdict on each sample's reading and the readings not accepted."""
    for col in ("verdict TEXT", "remeasures INTEGER DEFAULT 0", "model_residual_mm REAL",
                "model_threshold_mm REAL"):
        con.execute(f"ALTER TABLE samples ADD COLUMN {col}")
    con.execute(
        """CREATE TABLE readings (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            run_id INTEGER NOT NULL REFERENCES runs(id),
            point_index INTEGER NOT NULL,
            q_json TEXT NOT NULL,
            x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL,
            sx REAL, sy REAL, sz REAL, n INTEGER,
            t REAL, temp_c REAL, pressure_hpa REAL, humidity_pct REAL,
            cmd_x REAL, cmd_y REAL, cmd_z REAL, dir_json TEXT,
            model_residual_mm REAL, model_threshold_mm REAL,
            reflector TEXT, face INTEGER, cov_xx REAL, cov_xy REAL, cov_xz REAL,
            cov_yy REAL, cov_yz REAL, cov_zz REAL,
            reason TEXT NOT NULL
        )"""
    )
    con.execute("CREATE INDEX readings_run ON readings(run_id, point_index)")


def _upgrade_6_to_7(con: sqlite3.Connection) -> None:
    """v7: a reserve of space for a full disk (additive: one new table and its row)."""
    con.execute("CREATE TABLE reserve (id INTEGER PRIMARY KEY, pad BLOB NOT NULL)")
    con.execute("INSERT INTO reserve (id, pad) VALUES (1, zeroblob(?))", (RESERVE_BYTES,))


#: UPGRADES[k] takes a database from version k+1 to k+2
UPGRADES: list[Callable[[sqlite3.Connection], None]] = [_upgrade_1_to_2, _upgrade_2_to_3,
                                                        _upgrade_3_to_4, _upgrade_4_to_5,
                                                        _upgrade_5_to_6, _upgrade_6_to_7]
