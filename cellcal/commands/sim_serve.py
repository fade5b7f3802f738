"""``cellcal sim serve``: run the simulated cell behind its wire protocols until stopped.

Prints one driver URL per line (Modbus robot, line robot, tracker over TCP, tracker over
a pty, emScon tracker, with ``--abb`` the ABB robot over Robot Web Services, then the
read-only RTDE robot when port 30004 was free), then a
ready-to-paste ``export R=... T=...`` line (the Modbus robot, with ``--abb`` the ABB robot,
and the TCP tracker), then
serves until Ctrl-C or SIGTERM and stops cleanly (exit code 0). A port in use is an
error (exit 2) unless ``--any-port``. The simulated tracker's line of sight is honest
(:mod:`sim_drivers.beam`): ``--tracker-at`` places it, ``--cell`` adds fixtures.
"""

from __future__ import annotations

import signal
import sys
import threading

from ..flags.choices import THERMAL_STARTS
from ..flags.sim_ports import ABB_PORT, ABB_PORT_FLAG, DEFAULT_PORTS, PORT_FLAGS
from .common import bounded_float, bounded_int, nonneg_float, seed_int
from .parsers import add_subcommands, command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "sim", help="simulated cell: serve it over the real wire protocols",
        description="The simulated cell: a robot with realistic hidden errors (and hidden "
        "physical effects) and a laser tracker, behind the same wire protocols as the "
        "hardware. `cellcal sim serve --help` for the options.")
    ssub = add_subcommands(p, "sim_command", "SIM_COMMAND")
    s = command_parser(
        ssub, "serve", help="start the simulated servers and print their URLs",
        description="Serve the simulated cell on loopback until Ctrl-C: prints one driver URL "
        "per line (Modbus robot, line-protocol robot, line-protocol tracker over TCP and "
        "over a pty, emScon tracker; with --abb the ABB robot over Robot Web Services; the "
        "read-only RTDE robot when port 30004 is free), then an `export R=... T=...` line "
        "to paste into the shell that captures (R: the Modbus robot, with --abb the ABB "
        "robot).\n\n"
        "Ports: Modbus robot 15020, line robot 15021, tracker 15700, emScon 15701, ABB "
        "robot 15080 by default; --port-base N serves them on N, N+1, N+2, N+3, N+4; a port "
        "flag sets one (0: any free port). A port in use is an error (exit 2) unless "
        "--any-port.")
    s.add_argument("--seed", type=seed_int, default=0,
                   help="random seed of the cell (default 0)")
    s.add_argument("--model", default="ur10e", metavar="NAME|PATH",
                   help="the true robot: a model name or YAML with realistic hidden errors "
                        "(default ur10e), or 'toy' for a 3-joint stand-in arm")
    s.add_argument("--tracker-at", metavar="X,Y,Z", default=None,
                   help="where the simulated tracker stands, robot base frame, mm (default "
                   "2500,0,500; write --tracker-at=-2500,0,500 for a negative first value)")
    s.add_argument("--cell", metavar="cell.yaml", default=None,
                   help="the simulated cell: fixtures that break the beam, the SMR axis and "
                   "acceptance, the tracker position (docs/formats.md section 7)")
    s.add_argument("--hidden", default=None, metavar="EFFECTS",
                   help="hidden physical effects of the true robot, e.g. compliance:3 "
                   "(docs/formats.md §3)")
    s.add_argument("--thermal", choices=THERMAL_STARTS, default=None,
                   help="the robot warms up with its work and reports its joint "
                   "temperatures; its links grow and its joint zeros move with them "
                   "(hidden): from cold or already warm (default: no thermal model; the "
                   "joints report the air's temperature, constant)")
    s.add_argument("--faults", default=None, metavar="SPEC",
                   help="fault spec, e.g. 'beam=0.05,slow=0.02,drop@3,delay=2'; "
                   "'blunder=0.03': 3 %% of tracker readings off by 0.5-5 mm")
    s.add_argument("--time-scale", type=nonneg_float, default=0.0, metavar="S",
                   help="wall seconds per simulated second (default 0: instantaneous)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback)")
    s.add_argument("--port-base", type=bounded_int(0, 65532), default=None, metavar="N",
                   help="serve on ports N (Modbus robot), N+1 (line robot), N+2 (tracker), "
                   "N+3 (emScon), N+4 (ABB robot, with --abb); 0: any free ports")
    for name, flag in PORT_FLAGS.items():
        s.add_argument(flag, type=bounded_int(0, 65535), default=None, metavar="PORT",
                       help=f"port of the {name.replace('_', ' ')} server (default "
                       f"{DEFAULT_PORTS[name]}; 0: any free port)")
    s.add_argument(ABB_PORT_FLAG, type=bounded_int(0, 65535), default=None, metavar="PORT",
                   help=f"port of the ABB robot server, with --abb (default {ABB_PORT}; 0: "
                   "any free port)")
    s.add_argument("--any-port", action="store_true",
                   help="serve on a free port instead of a port in use (the printed URLs "
                   "are the truth)")
    s.add_argument("--abb", action="store_true",
                   help="also serve the robot as an ABB IRC5 over Robot Web Services 1.0 "
                   "(abb://, the RAPID server module CellcalServer running; docs/abb.md)")
    s.add_argument("--no-pty", action="store_true", help="no tracker on a pseudo-terminal")
    s.add_argument("--no-rtde", action="store_true",
                   help="no RTDE receive server on port 30004 (ur://, read-only)")
    s.add_argument("--no-weather-station", action="store_true",
                   help="the tracker has no weather station (give it the air: capture --meteo)")
    s.add_argument("--tracker-collimation-urad", type=bounded_float(-1e4, 1e4), default=0.0,
                   metavar="URAD",
                   help="the tracker's two-face (collimation) error, µrad (default 0)")
    s.add_argument("--tracker-warmup-s", type=nonneg_float, default=0.0, metavar="S",
                   help="simulated seconds until the tracker is warmed up (default 0)")
    s.add_argument("--six-dof", nargs="?", const="0,0,0", default=None, metavar="RX,RY,RZ",
                   help="mount a simulated 6-DoF target (a T-Mac, orientation noise 0.01 deg) "
                   "on the tool at this nominal orientation in the flange (rotation vector, "
                   "deg; default 0,0,0), turned by a hidden mounting error; measured over "
                   "emScon (ES_MM_6DStationary) and the line protocol (MEAS6D)")
    s.set_defaults(func=run)


def export_line(urls: list[str]) -> str:
    """``export R='modbus+tcp://...' T='tracker+tcp://...'``: the robot and tracker URLs the
    README's commands use, ready to paste; the ABB robot when it is served (``--abb``: the
    user asked for an ABB cell)."""
    robot = next((u for u in urls if u.startswith("abb://")),
                 next(u for u in urls if u.startswith("modbus+tcp://")))
    tracker = next(u for u in urls if u.startswith("tracker+tcp://"))
    return f"export R='{robot}' T='{tracker}'"


def run(args) -> int:
    from ..usecases.sim_serve import SimServeRequest, serve_cell

    req = SimServeRequest.from_args(args)

    def ready(urls: list[str], notes: list[str]) -> None:
        for url in urls:
            print(url)
        print(export_line(urls))
        for note in notes:
            print(f"cellcal sim: {note}", file=sys.stderr)
        sys.stdout.flush()

    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        serve_cell(req, stop, ready)
    finally:
        signal.signal(signal.SIGTERM, previous)
    print("cellcal sim: stopped", file=sys.stderr)
    return 0
