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
