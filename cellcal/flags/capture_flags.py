"""The flags ``capture`` and ``resume`` share: the run store and the devices, the
executor's settings, the tracker's setup; and :func:`flag_values`, the settings given.

Free of heavy imports (the parser is built from it at start-up).
"""

from __future__ import annotations

import argparse

#: executor options settable on the command line: (flag, attribute, type, help)
EXEC_FLAGS = [
    ("--speed", "speed_rad_s", float, "joint speed, rad/s (default 0.5)"),
    ("--linear-speed", "speed_mm_s", float, "TCP speed of linear moves, mm/s (default 100)"),
    ("--dwell", "dwell_s", float, "extra wait after the robot settled, s (default 0)"),
    ("--measure-s", "measure_s", float, "tracker averaging time, s (default 0.5)"),
    ("--max-std-mm", "max_std_mm", float,
     "remeasure when the tracker's per-axis std exceeds this, mm (default 0.05)"),
    ("--max-retries", "max_retries", int, "retries per point after transient faults (default 8)"),
    ("--io-timeout", "io_timeout_s", float, "timeout of reads, s (default 1)"),
    ("--remeasure", "remeasure", int,
     "re-measure a reading out of line with the model fitted so far up to N times, moving "
     "away and back (default 2; 0: no model check)"),
    ("--store-wait", "store_wait_s", float,
     "a lost run store connection (PostgreSQL): wait this long for it, holding the robot, "
     "before pausing the run, s (default 30)"),
    ("--six-dof", "six_dof", bool,
     "measure a 6-DoF target's pose (a T-Mac: emscon://, or MEAS6D of tracker+tcp://): "
     "every point keeps its orientation (qw..qz, sigma_deg in the export)"),
]


def metavar(typ) -> str:
    """``N`` for a count, ``X`` for a quantity (the help says its unit)."""
    return "N" if typ is int else "X"


def add_flag_table(p, flags) -> None:
    """Options from a ``(flag, attribute, type, help)`` table (default None: not given; a
    ``bool`` is a switch)."""
    for flag, _, typ, hlp in flags:
        if typ is bool:  # a switch
            p.add_argument(flag, action="store_const", const=True, default=None, help=hlp)
        else:
            p.add_argument(flag, type=typ, default=None, help=hlp, metavar=metavar(typ))


def flag_values(args, flags) -> dict:
    """``{attribute: value}`` of the flags of a ``(flag, attribute, type, help)`` table
    given on the command line (others left out)."""
    out = {}
    for flag, attr, _, _ in flags:
        v = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if v is not None:
            out[attr] = v
    return out


def add_common(p, *, resume: bool = False) -> None:
    """``--db``, ``--robot``, ``--tracker``, ``--yes``, ``--json``, ``--robot-id``."""
    from .choices import DB_HELP

    p.add_argument("--db", required=True, metavar="cell.db|URL",
                   help=DB_HELP + ("; a file is created when missing" if not resume else ""))
    p.add_argument("--robot", required=not resume, metavar="URL",
                   help="robot driver URL, e.g. modbus+tcp://127.0.0.1:15020?unit=1 (README: "
                   "At the cell)" + (" (default: the run's)" if resume else ""))
    p.add_argument("--tracker", required=not resume, metavar="URL",
                   help="tracker driver URL, e.g. tracker+tcp://127.0.0.1:15700"
                   + (" (default: the run's)" if resume else ""))
    p.add_argument("--yes", action="store_true",
                   help="do not ask before moving devices that did not identify themselves "
                   "as simulators (any real controller, whatever its address)")
    p.add_argument("--json", action="store_true", help="print one JSON object, no progress")
    p.add_argument("--robot-id", metavar="NAME", default=None,
                   help="who the robot is, recorded with the run (default: the controller's "
                   "MODEL/SERIAL when its protocol reports one)")
    p.add_argument("--synchronous", choices=("FULL", "NORMAL"), default="FULL",
                   help=argparse.SUPPRESS)


def add_tracker_flags(p, *, resume: bool = False) -> None:
    """The tracker's setup and checks (:class:`~daq.run_context.TrackerSetup`)."""
    p.add_argument("--meteo", metavar="T,P,H", default=None,
                   help="the air at the cell (°C, hPa, %%RH) for a tracker without a weather "
                   "station (refused when one reports); recorded with every point"
                   + ("; replaces the run's for this session" if resume else ""))
    if resume:
        return
    p.add_argument("--reflector", metavar="NAME", default=None,
                   help="select the tracker's reflector by name (case-insensitive; an unknown "
                   "name lists the known ones); recorded with every point")
    p.add_argument("--two-face-tol-mm", type=float, default=None, metavar="MM",
                   help="two-face check before the run: the largest difference between the "
                   "faces beyond the measurements' noise, mm (default 0.05)")
    p.add_argument("--no-two-face-check", action="store_true",
                   help="skip the two-face check before the run")


def add_thermal_flags(p) -> None:
    """Drift checks during the run and the warm-up it requires (``capture``)."""
    p.add_argument("--drift-check", metavar="N|Nmin", default=None,
                   help="measure a reference pose again every N points (or every N minutes "
                   "of the estimated capture time: 5min), first and last too; stored as "
                   "set=drift, shown by `cellcal runs RUN`")
    p.add_argument("--drift-references", type=int, default=1, metavar="K",
                   help="with --drift-check: reference poses measured each time, spread over "
                   "the plan (default 1: its first posture)")
    p.add_argument("--drift-bound-mm", type=float, default=None, metavar="MM",
                   help="with --drift-check: flag a drift above this, mm (default 4x the "
                   "tracker's sigma, at least 0.02)")
    p.add_argument("--require-warm", type=float, default=None, metavar="MIN",
                   help="refuse to start (exit 2) unless the robot's last `capture warmup` "
                   "ended at most MIN minutes ago and its joints have not cooled since")


def add_plan_flags(p) -> None:
    """The dry run's limits and the run's frame: ``--floor-z-mm``, ``--no-floor``,
    ``--keepout-mm``, ``--check-paths``, ``--frame-run``, ``--dry-run``."""
    p.add_argument("--floor-z-mm", type=float, default=0.0, metavar="MM",
                   help="dry run: lowest z of link origins and tool, mm (default 0)")
    p.add_argument("--no-floor", action="store_true", help="dry run: no floor check")
    p.add_argument("--keepout-mm", action="append", default=[],
                   metavar="X0,Y0,Z0,X1,Y1,Z1",
                   help="a box (base frame, mm) no link origin or tool point may enter, "
                   "checked by the dry run and before every move (repeatable)")
    p.add_argument("--check-paths", action="store_true",
                   help="also check the floor, keep-out boxes and reach along every joint "
                   "move, not only where it ends")
    p.add_argument("--frame-run", type=int, default=None, metavar="RUN",
                   help="measurement frame from this frame run (default: the latest "
                   "completed one in the store, if any)")
    p.add_argument("--dry-run", action="store_true",
                   help="check and print the plan (the points the tracker would not see, "
                   "the estimated capture time), do not move")


def add_sight_flags(p) -> None:
    """The tracker's line of sight: ``--cell``, ``--no-visibility``."""
    p.add_argument("--cell", metavar="cell.yaml", default=None,
                   help="the cell: tracker position, SMR axis and reflector, margins, "
                   "fixtures (docs/formats.md section 7)")
    p.add_argument("--no-visibility", action="store_true",
                   help="plan without the tracker's line of sight, also when its "
                   "position is unknown (refused otherwise); the dry run still lists "
                   "the points it would not see when the position is known")
