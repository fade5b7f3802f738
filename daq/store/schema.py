"""The run store's schema and the upgrades between its versions, for both databases.

The database holds the version (SQLite's ``PRAGMA user_version``, a ``schema_version``
table on PostgreSQL: :mod:`daq.store.dialect`). A new store is created at version 1
(:data:`SCHEMA_V1`) and brought to :data:`SCHEMA_VERSION` by the same upgrade functions
an old one goes through (:data:`UPGRADES`, each run in one transaction by
:func:`daq.store.migration.migrate`). An upgrade function is frozen once released: it writes
plain SQL and JSON, never through today's classes, so an old store upgrades the same
way whatever the code around it has become.

An upgrade gets a :class:`daq.store.dialect.Database` and writes SQLite's spelling
(``?`` placeholders; ``INTEGER PRIMARY KEY AUTOINCREMENT``, ``INTEGER``, ``REAL``,
``TEXT`` in ``CREATE TABLE`` and ``ALTER TABLE ... ADD COLUMN``); the PostgreSQL
database translates it, so one upgrade runs on both.

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
       (:mod:`daq.store.leases`); per run the robot's and the tracker's identity (JSON of
       :class:`drivers.protocols.DeviceIdentity`) and ``source_run`` (the run whose plan a
       run repeats on another cell); run contexts gain ``motion`` (no floor for the runs
       made before: none was recorded). Additive: new table, new nullable columns.
    6. re-measured blunders (:mod:`daq.remeasure`): per sample the ``verdict`` on its
       reading, the ``remeasures`` made at the point and the reading's distance from the
       running model with its threshold; the ``readings`` table keeps every reading that
       was not accepted, with its reason (and, as a sample, the tracker's reflector, face
       and covariance). Additive: older rows read as never judged.
    7. who the robot is and its calibration history (additive): ``runs.robot_id`` and the
       ``calibrations`` table (robot id, time, params.json, source file/run, software).
    8. the ``reserve`` table: one row of zeros (:data:`RESERVE_BYTES`) a SQLite store gives
       up when the disk is full, so that the run can still be marked paused with the
       reason (:meth:`daq.store.RunStore.release_reserve`); empty on PostgreSQL.
    9. the robot's thermal state and full-pose readings, per sample and per rejected
       reading (additive, NULL where not measured): ``joint_temp_json`` (the joints'
       temperatures as the controller reports them, JSON list, °C), the orientation of a
       6-DoF target (``qw``, ``qx``, ``qy``, ``qz``: unit quaternion of the target frame in
       the tracker frame) with its standard uncertainty ``sigma_deg``, and ``tool_id`` (which
       target on the tool was measured, when a pose measures several).
    10. the ``checks`` table (additive): a robot's calibration checked against new poses
       (``cellcal check --db``): when the poses were measured, the params.json checked (its
       sha256, and the calibration of the same robot recorded with it, when there is one),
       the error statistics, the tolerance and the verdict, what was refitted, the source
       and the whole ``--json`` result.

The versions are :data:`UPGRADES` alone, a registry keyed by the version each upgrade
starts from and checked when this module is imported (:func:`checked_upgrades`:
contiguous from 1, one upgrade per version, each with a one-line description);
:data:`SCHEMA_VERSION` is the last one's target. A new upgrade is one function, named for
what it adds, and one :class:`Upgrade` entry from today's version: two made on parallel
branches claim the same version and are refused until one is renumbered.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: what an upgrade gets: a daq.store.dialect.Database (anything with ``execute(sql, params)``)
Connection = Any
#: the free space a SQLite store keeps in reserve for a full disk (bytes)
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


def _upgrade_1_to_2(con: Connection) -> None:
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


def _upgrade_2_to_3(con: Connection) -> None:
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


def _upgrade_3_to_4(con: Connection) -> None:
    """v4: per-sample tracker metadata (reflector, face, covariance); NULL in old rows."""
    for col in _V4_SAMPLE_COLUMNS:
        con.execute(f"ALTER TABLE samples ADD COLUMN {col}")


def _upgrade_4_to_5(con: Connection) -> None:
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


def _upgrade_5_to_6(con: Connection) -> None:
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


def _upgrade_robot_history(con: Connection) -> None:
    """v7 (additive): who the robot of a run is (``runs.robot_id``: the controller's
    ``MODEL/SERIAL`` or a name given at the cell) and the ``calibrations`` table: one row
    per calibration of a robot, its params.json as recorded (``params_sha256`` makes
    recording the same one twice a no-op), when its data were measured (``t``) and
    recorded, where they came from and which software fitted them."""
    con.execute("ALTER TABLE runs ADD COLUMN robot_id TEXT")
    con.execute("CREATE INDEX runs_robot ON runs(robot_id)")
    con.execute(
        """CREATE TABLE calibrations (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            robot_id TEXT NOT NULL,
            t REAL NOT NULL,
            recorded REAL NOT NULL,
            params_json TEXT NOT NULL,
            params_sha256 TEXT NOT NULL,
            source_file TEXT,
            source_run INTEGER,
            software TEXT,
            UNIQUE(robot_id, params_sha256)
        )"""
    )
    con.execute("CREATE INDEX calibrations_robot ON calibrations(robot_id, t)")


def _upgrade_reserve(con: Connection) -> None:
    """v8 (additive): a reserve of space for a full disk: one new table, and on SQLite its
    one row of zeros (a PostgreSQL server's disk is not the store's to manage)."""
    con.execute("CREATE TABLE reserve (id INTEGER PRIMARY KEY, pad BLOB NOT NULL)")
    if getattr(con, "kind", "sqlite") == "sqlite":
        con.execute("INSERT INTO reserve (id, pad) VALUES (1, zeroblob(?))", (RESERVE_BYTES,))


#: v9's columns, on samples and on readings
THERMAL_FULL_POSE_COLUMNS = ("joint_temp_json TEXT", "qw REAL", "qx REAL", "qy REAL", "qz REAL",
                             "sigma_deg REAL", "tool_id TEXT")


def _upgrade_thermal_full_pose(con: Connection) -> None:
    """v9 (additive): joint temperatures, a 6-DoF target's orientation and its uncertainty,
    and the tool target's id, per sample and per rejected reading (NULL: not measured)."""
    for table in ("samples", "readings"):
        for column in THERMAL_FULL_POSE_COLUMNS:
            con.execute(f"ALTER TABLE {table} ADD COLUMN {column}")


def _upgrade_checks(con: Connection) -> None:
    """v10 (additive): the ``checks`` table: one row per check of a robot's calibration on
    new poses; ``result_sha256`` (of the result without its times) makes recording the same
    check twice a no-op."""
    con.execute(
        """CREATE TABLE checks (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            robot_id TEXT NOT NULL,
            t REAL NOT NULL,
            recorded REAL NOT NULL,
            params_sha256 TEXT NOT NULL,
            calibration_id INTEGER,
            n INTEGER NOT NULL,
            rms_mm REAL, mean_mm REAL, p95_mm REAL, max_mm REAL,
            tolerance_mm REAL,
            within_tolerance INTEGER,
            refitted_json TEXT NOT NULL,
            result_json TEXT NOT NULL,
            result_sha256 TEXT NOT NULL,
            source_file TEXT,
            source_run INTEGER,
            software TEXT,
            UNIQUE(robot_id, result_sha256)
        )"""
    )
    con.execute("CREATE INDEX checks_robot ON checks(robot_id, t)")


@dataclass(frozen=True)
class Upgrade:
    """One step of the schema: ``apply(con)`` takes a database from ``version`` to
    ``version + 1``; ``description`` says in one line what it adds."""

    version: int
    description: str
    apply: Callable[[Connection], None]

    def __call__(self, con: Connection) -> None:
        self.apply(con)


def checked_upgrades(upgrades: list[Upgrade]) -> dict[int, Upgrade]:
    """The upgrades keyed by the version they upgrade from, refused (``ValueError``)
    unless they are contiguous from version 1, one per version, each described in one
    line."""
    out: dict[int, Upgrade] = {}
    for up in upgrades:
        if up.version in out:
            raise ValueError(f"two upgrades from schema version {up.version}: "
                             f"{out[up.version].apply.__name__} and {up.apply.__name__}")
        if not up.description.strip() or "\n" in up.description:
            raise ValueError(f"the upgrade from version {up.version} needs a one-line "
                             "description")
        out[up.version] = up
    missing = sorted(set(range(1, len(out) + 1)) - set(out))
    if missing:
        raise ValueError(f"no upgrade from schema version {missing[0]} (the upgrades "
                         f"start at 1 and leave no gap; given {sorted(out)})")
    return dict(sorted(out.items()))


#: the schema's versions: UPGRADES[v] takes a database from version v to v + 1
UPGRADES: dict[int, Upgrade] = checked_upgrades([
    Upgrade(1, "frame, summary, interruptions", _upgrade_1_to_2),
    Upgrade(2, "run contexts", _upgrade_2_to_3),
    Upgrade(3, "reflector, face, covariance per sample", _upgrade_3_to_4),
    Upgrade(4, "leases, device identities", _upgrade_4_to_5),
    Upgrade(5, "re-measure (verdicts, readings)", _upgrade_5_to_6),
    Upgrade(6, "runs.robot_id, calibrations", _upgrade_robot_history),
    Upgrade(7, "the reserve for a full disk", _upgrade_reserve),
    Upgrade(8, "joint temperatures, 6-DoF orientation, tool target per sample",
            _upgrade_thermal_full_pose),
    Upgrade(9, "checks of calibrations on new poses", _upgrade_checks),
])

#: current schema version (SQLite's PRAGMA user_version, PostgreSQL's schema_version)
SCHEMA_VERSION = max(UPGRADES) + 1
